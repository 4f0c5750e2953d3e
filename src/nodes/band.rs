//! The band filters of [`crate::ops::band`] as a node: keep or remove a low-, high-, band-pass or
//! LoG band of the gradients ([`band_filter_image`]).

use super::kit::{curl_port, kernel_footprint};
use super::{Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::band::{band_filter_image, BandParams};

/// Keep or remove a frequency band of the relief.
pub struct BandNode;

impl Operator for BandNode {
    type Params = BandParams;
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
    fn check(p: &BandParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn footprint(p: &BandParams, _input: usize) -> Footprint {
        match p.band() {
            Ok(b) => kernel_footprint(p.border, b.kernel().support_px()),
            Err(_) => Footprint::Global,
        }
    }
    fn run(p: &BandParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (img, curl) = band_filter_image(i.rgbn("image")?, p)?;
        Ok(vec![Value::Rgbn(img), Value::Number(curl.relative)])
    }
}
