//! The RGBN bilateral filter of [`crate::ops::bilateral`] as a node, with the base/detail split
//! ([`split`]) as its two outputs.

use super::kit::curl_port;
use super::{Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::bilateral::{split, BilateralParams};

/// Bilateral filter and base/detail split.
pub struct BilateralNode;

impl Operator for BilateralNode {
    type Params = BilateralParams;
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
    fn check(p: &BilateralParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn footprint(p: &BilateralParams, _input: usize) -> Footprint {
        // The disc of radius ⌈2σ_s⌉ (sampled or not); the detail is per pixel.
        Footprint::Local {
            halo: (2.0 * p.sigma_spatial_px as f32).ceil() as usize,
        }
    }
    fn run(p: &BilateralParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (base, detail, rep) = split(i.rgbn("image")?, p)?;
        Ok(vec![
            Value::Rgbn(base),
            Value::Rgbn(detail),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
