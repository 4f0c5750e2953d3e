//! The rotation combine of [`crate::ops::rotate`] as a node (`combine.rotation`).

use super::kit::curl_port;
use super::{Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::rotate::{rotation_combine, RotateParams};

/// Rotation combine of normals.
pub struct RotationCombineNode;

impl Operator for RotationCombineNode {
    type Params = RotateParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "combine.rotation",
            "Rotation combine",
            "combine",
            "Expresses a detail normal in the tangent frame of a base normal (Pereira & Velho §VII), so the detail keeps its look on a tilted base; industry blends (RNM, UDN, whiteout, partial derivative) as modes. Nonlinear: the curl of the result is reported.",
        )
        .input(PortSpec::new("base", PortType::Rgbn, "Base image (colour and mask are kept)."))
        .input(PortSpec::new(
            "detail",
            PortType::Rgbn,
            "Detail normals, in the base's tangent frame (+z = no detail).",
        ))
        .input(
            PortSpec::new(
                "existing",
                PortType::Rgbn,
                "The normals being edited, fine detail included (§VII's a): replace, blend and rotate act on them; the base when unconnected.",
            )
            .optional(),
        )
        .input(
            PortSpec::new(
                "weight",
                PortType::Mask,
                "Per-pixel weight in [0, 1] (1 everywhere when unconnected).",
            )
            .optional(),
        )
        .output(PortSpec::new("image", PortType::Rgbn, "Combined image."))
        .output(PortSpec::new(
            "saturated",
            PortType::Number,
            "Pixels moved back to n_z = min_z.",
        ))
        .output(curl_port("combined gradients"))
    }
    fn check(p: &RotateParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn footprint(_: &RotateParams, _input: usize) -> Footprint {
        Footprint::POINT
    }
    fn run(p: &RotateParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (img, rep) = rotation_combine(
            i.rgbn("base")?,
            i.rgbn("detail")?,
            i.rgbn_opt("existing")?,
            i.mask("weight")?,
            p,
        )?;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(rep.saturated as f64),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
