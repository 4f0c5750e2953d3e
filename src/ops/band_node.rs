//! The band filters of [`super::band`] as a node: keep or remove a low-, high-, band-pass or
//! LoG band of the gradients ([`band_filter_image`]).

use super::band::{band_filter_image, BandOp, BandParams};
use super::node_kit::{border_mode, curl_port, visit_border, BandChoice};
use super::params::{Meta, ParamVisitor, Params};
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;

/// Parameters of [`BandNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct BandNodeParams {
    /// The band.
    pub band: BandChoice,
    /// `keep` or `remove`.
    pub op: &'static str,
    /// Border mode name.
    pub border: &'static str,
}

impl Default for BandNodeParams {
    fn default() -> Self {
        Self {
            band: BandChoice::new("bandpass"),
            op: "keep",
            border: "mirror",
        }
    }
}

impl Params for BandNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        self.band.visit(
            v,
            "band",
            &["lowpass", "highpass", "bandpass", "log"],
            "Which band: lowpass G_σ, highpass I − G_σ, bandpass G_σ − G_coarse (DoG), log −σ²∇²G_σ.",
        );
        v.choice(
            "op",
            &mut self.op,
            &["keep", "remove"],
            &Meta::new("keep: B * g (the band only); remove: g − B * g (everything but the band)."),
        );
        visit_border(v, &mut self.border);
    }
}

impl BandNodeParams {
    fn to_params(&self) -> Result<BandParams, RgbnError> {
        Ok(BandParams {
            band: self.band.band()?.unwrap_or_default(),
            op: if self.op == "remove" {
                BandOp::Remove
            } else {
                BandOp::Keep
            },
            border: border_mode(self.border),
        })
    }
}

/// Keep or remove a frequency band of the relief.
pub struct BandNode;

impl Operator for BandNode {
    type Params = BandNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "band",
            "Band filter",
            "filter",
            "Keeps or removes a frequency band of the gradients (Pereira & Velho §III–IV): keep + remove = the input exactly. Removing a band prepares a base whose band a detail can replace (combine.linear).",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to filter."))
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Filtered normals; colour and mask unchanged.",
        ))
        .output(curl_port("filtered gradients"))
    }
    fn check(p: &BandNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(p: &BandNodeParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (img, curl) = band_filter_image(i.rgbn("image")?, &p.to_params()?)?;
        Ok(vec![Value::Rgbn(img), Value::Number(curl.relative)])
    }
}
