//! Renormalises every normal to unit length (idempotent).

use super::params::NoParams;
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;

/// Renormalises the normals ([`crate::RgbnImage::normalize`]).
pub struct Normalize;

impl Operator for Normalize {
    type Params = NoParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "normalize",
            "Normalize",
            "filter",
            "Rescales every normal to unit length; colour and mask are unchanged.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image."))
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Image with unit normals.",
        ))
    }
    fn run(_: &NoParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let mut img = i.rgbn("image")?.clone();
        img.normalize();
        Ok(vec![Value::Rgbn(img)])
    }
}
