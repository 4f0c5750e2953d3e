//! The normalisation of [`crate::ops::normalize`] as a node.

use super::{Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::normalize::{normalize, NormalizeParams};

/// The [`normalize`] node.
pub struct Normalize;

impl Operator for Normalize {
    type Params = NormalizeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "normalize",
            "Normalize",
            "filter",
            "Rescales every normal to unit length (idempotent); optionally repairs bad normals and lifts back-facing ones. Colour and mask are unchanged except for repairs.",
        )
        .version(2)
        .input(PortSpec::new("image", PortType::Rgbn, "Image."))
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Image with unit normals.",
        ))
        .output(PortSpec::new(
            "invalid",
            PortType::Number,
            "Input values that were not finite or normals of zero length (repaired when repair is on).",
        ))
        .output(PortSpec::new(
            "lifted",
            PortType::Number,
            "Normals lifted to n_z = min_z.",
        ))
    }
    fn footprint(_: &NormalizeParams, _input: usize) -> Footprint {
        Footprint::POINT
    }
    fn scaled(p: &NormalizeParams, _: f64) -> Option<NormalizeParams> {
        Some(p.clone())
    }
    fn run(p: &NormalizeParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (img, rep) = normalize(i.rgbn("image")?, p)?;
        let b = rep.before;
        let invalid = b.non_finite_normal + b.zero_length_normal + b.non_finite_color;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(invalid as f64),
            Value::Number(rep.lifted as f64),
        ])
    }
}
