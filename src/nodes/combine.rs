//! The linear combine of [`crate::ops::combine`] as a node (`combine.linear`, with a detail
//! given as normals or as a height); the rotation combine is in [`super::rotate`].

use super::kit::{curl_port, kernel_footprint};
use super::{Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::combine::{linear_combine_height, linear_combine_images, LinearCombineParams};
use crate::raster::gradient::GradientField;

/// Linear combine of gradients.
pub struct LinearCombineNode;

impl Operator for LinearCombineNode {
    type Params = LinearCombineParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "combine.linear",
            "Linear combine",
            "combine",
            "Adds a detail's relief to a base through their gradients (Pereira & Velho §IV): ∇b + α·m·∇h, optionally replacing a band of the base. With weight 1 it is the partial-derivative blend. A detail given as a height adds α·∇(m·h) instead, which stays integrable for any weight.",
        )
        .input(PortSpec::new("base", PortType::Rgbn, "Base image (colour and mask are kept)."))
        .input(
            PortSpec::new(
                "detail",
                PortType::Rgbn,
                "Detail as normals (connect this or detail_height).",
            )
            .optional(),
        )
        .input(
            PortSpec::new(
                "detail_height",
                PortType::Scalar,
                "Detail as a height in pixels (connect this or detail).",
            )
            .optional(),
        )
        .input(
            PortSpec::new(
                "weight",
                PortType::Mask,
                "Per-pixel weight m in [0, 1] (1 everywhere when unconnected).",
            )
            .optional(),
        )
        .output(PortSpec::new("image", PortType::Rgbn, "Combined image."))
        .output(curl_port("combined gradients"))
    }
    fn check(p: &LinearCombineParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn footprint(p: &LinearCombineParams, _input: usize) -> Footprint {
        // A height or a weight is differentiated (one pixel); a replaced band is filtered.
        match p.band() {
            Ok(b) => kernel_footprint(p.border, 1.max(b.map_or(0, |b| b.kernel().support_px()))),
            Err(_) => Footprint::Global,
        }
    }
    fn run(
        p: &LinearCombineParams,
        i: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        p.validate()?;
        let base = i.rgbn("base")?;
        let weight = i.mask("weight")?;
        match (i.rgbn_opt("detail")?, i.scalar("detail_height")?) {
            (Some(detail), None) => {
                let (img, rep) = linear_combine_images(base, detail, weight, p)?;
                Ok(vec![
                    Value::Rgbn(img),
                    Value::Number(rep.curl_after.relative),
                ])
            }
            (None, Some(h)) => {
                let g = linear_combine_height(&GradientField::from_normals(base), h, weight, p)?;
                let mut img = base.clone();
                g.write_normals(&mut img);
                let curl = g.curl_stats(base.mask()).relative;
                Ok(vec![Value::Rgbn(img), Value::Number(curl)])
            }
            _ => Err(RgbnError::param(
                "detail",
                "connect exactly one of the inputs detail (normals) and detail_height (height)",
            )),
        }
    }
}
