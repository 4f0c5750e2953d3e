//! The RGBN bilateral filter of [`super::bilateral`] as a node, with the base/detail split
//! ([`split`]) as its two outputs.

use super::bilateral::{split, BilateralParams, NormalMetric, MAX_BILATERAL_SIGMA_PX};
use super::node_kit::{curl_port, FrameChoice};
use super::params::{Meta, ParamVisitor, Params};
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;

/// Parameters of [`BilateralNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct BilateralNodeParams {
    /// Spatial σ.
    pub sigma_spatial_px: f64,
    /// Colour σ (0 = ignore colour).
    pub sigma_color: f64,
    /// Normal σ (0 = ignore normals).
    pub sigma_normal: f64,
    /// `angle` or `one_minus_dot`.
    pub normal_metric: &'static str,
    /// Smooth colour too.
    pub filter_color: bool,
    /// Frame of the detail.
    pub frame: FrameChoice,
}

impl Default for BilateralNodeParams {
    fn default() -> Self {
        let d = BilateralParams::default();
        Self {
            sigma_spatial_px: f64::from(d.sigma_spatial_px),
            sigma_color: d.sigma_color.map_or(0.0, f64::from),
            sigma_normal: d.sigma_normal.map_or(0.0, f64::from),
            normal_metric: "angle",
            filter_color: d.filter_color,
            frame: FrameChoice::default(),
        }
    }
}

impl Params for BilateralNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.float(
            "sigma_spatial_px",
            &mut self.sigma_spatial_px,
            &Meta::new("Spatial σ; the window has radius ⌈2σ⌉.")
                .unit("px")
                .range(0.05, f64::from(MAX_BILATERAL_SIGMA_PX)),
        );
        v.float(
            "sigma_color",
            &mut self.sigma_color,
            &Meta::new("Colour σ (linear RGB distance); 0 ignores colour.").range(0.0, 1e6),
        );
        v.float(
            "sigma_normal",
            &mut self.sigma_normal,
            &Meta::new("Normal-similarity σ (radians for angle, unitless for one_minus_dot); 0 ignores normals.")
                .range(0.0, 1e6),
        );
        v.choice(
            "normal_metric",
            &mut self.normal_metric,
            &["angle", "one_minus_dot"],
            &Meta::new(
                "Normal similarity: the angle between the normals, or 1 − n·n′ (≈ angle²/2).",
            ),
        );
        v.bool(
            "filter_color",
            &mut self.filter_color,
            &Meta::new("Also smooth the base's colour with the same weights."),
        );
        self.frame.visit(v);
    }
}

impl BilateralNodeParams {
    fn to_params(&self) -> Result<BilateralParams, RgbnError> {
        let opt = |s: f64| (s > 0.0).then_some(s as f32);
        let p = BilateralParams {
            sigma_spatial_px: self.sigma_spatial_px as f32,
            sigma_color: opt(self.sigma_color),
            sigma_normal: opt(self.sigma_normal),
            normal_metric: if self.normal_metric == "one_minus_dot" {
                NormalMetric::OneMinusDot
            } else {
                NormalMetric::Angle
            },
            filter_color: self.filter_color,
            frame: self.frame.frame()?,
        };
        p.validate()?;
        Ok(p)
    }
}

/// Bilateral filter and base/detail split.
pub struct BilateralNode;

impl Operator for BilateralNode {
    type Params = BilateralNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "bilateral",
            "Bilateral split",
            "filter",
            "RGBN bilateral filter (Toler-Franklin et al. 2007; Pereira & Velho §VII): base = the edge-preserving smoothing of the normals, detail = the rotation taking the base to the input, as a normal in the base's tangent frame. combine.rotation (blend, same frame) of base and detail gives the input back.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to split."))
        .output(PortSpec::new(
            "base",
            PortType::Rgbn,
            "The filtered image (colour smoothed only with filter_color).",
        ))
        .output(PortSpec::new(
            "detail",
            PortType::Rgbn,
            "Detail normals in the base's frame; the input's colour.",
        ))
        .output(curl_port("base's gradients"))
    }
    fn check(p: &BilateralNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(
        p: &BilateralNodeParams,
        i: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let (base, detail, rep) = split(i.rgbn("image")?, &p.to_params()?)?;
        Ok(vec![
            Value::Rgbn(base),
            Value::Rgbn(detail),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
