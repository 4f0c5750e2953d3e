//! The stamp of [`crate::ops::stamp`] as a node: place an RGBN stamp at positions with an affine map
//! ([`stamp_image`]).

use super::kit::curl_port;
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::stamp::{stamp_image, StampParams};

/// Stamp.
pub struct StampNode;

impl Operator for StampNode {
    type Params = StampParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "stamp",
            "Stamp",
            "combine",
            "Places a small RGBN (its relief, optionally its colour) at positions with an affine map (Pereira & Velho §IV, Fig. 4). The stamp is integrated once and its windowed height added, so the stamped relief is integrable for any map.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Target image."))
        .input(PortSpec::new(
            "stamp",
            PortType::Rgbn,
            "The stamp (at most 512 px a side); its mask limits the colour.",
        ))
        .output(PortSpec::new("image", PortType::Rgbn, "Stamped image."))
        .output(curl_port("result's gradients"))
    }
    fn check(p: &StampParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn run(p: &StampParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (img, rep) = stamp_image(i.rgbn("image")?, i.rgbn("stamp")?, p)?;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
