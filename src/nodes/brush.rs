//! The local filter brush of [`crate::ops::brush`] as a node: one linear kernel applied inside a
//! stroke (a polyline swept by a disc with a feather) and/or a mask input ([`brush_image`]).
//! Several strokes: chain brush nodes, or paint them into a mask.

use super::kit::{curl_port, kernel_footprint, shift_points};
use super::{
    scale_point, Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value,
};
use crate::error::RgbnError;
use crate::ops::brush::{brush_image, SimpleBrushParams};
use crate::ops::filter::Kernel;
use crate::ops::geom::{changed_path_bounds, paths_bounds};
use std::sync::Arc;

/// Filter brush.
pub struct BrushNode;

impl Operator for BrushNode {
    type Params = SimpleBrushParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "brush",
            "Filter brush",
            "filter",
            "Applies a linear filter only inside a painted region (Pereira & Velho §III, Fig. 1): g′ = m·K(g) + (1 − m)·g, with m the union of a feathered stroke and the optional mask input. The feather band generally adds curl (reported).",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to edit."))
        .input(
            PortSpec::new(
                "mask",
                PortType::Mask,
                "Extra region in [0, 1] united (max) with the stroke.",
            )
            .optional(),
        )
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Edited normals; colour and mask unchanged.",
        ))
        .output(PortSpec::new(
            "region",
            PortType::Mask,
            "The region weight m actually used.",
        ))
        .output(curl_port("edited gradients"))
    }
    fn check(p: &SimpleBrushParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn footprint(p: &SimpleBrushParams, input: usize) -> Footprint {
        match (input, p.to_params()) {
            (0, Ok(b)) => kernel_footprint(
                b.filter.border,
                b.kernels.iter().map(Kernel::support_px).max().unwrap_or(0),
            ),
            (_, Ok(_)) => Footprint::POINT,
            (_, Err(_)) => Footprint::Global,
        }
    }
    fn scaled(p: &SimpleBrushParams, s: f64) -> Option<SimpleBrushParams> {
        use crate::ops::brush::BrushKernel;
        // Box radii are whole pixels; a LoG's response depends on the grid (as `filter.*`).
        if matches!(p.kernel, BrushKernel::Box | BrushKernel::LoG) {
            return None;
        }
        Some(SimpleBrushParams {
            sigma_px: (p.sigma_px / s).max(0.05),
            sigma_coarse_px: (p.sigma_coarse_px / s).max(0.05),
            points: p.points.iter().map(|&q| scale_point(q, s)).collect(),
            radius_px: p.radius_px / s,
            feather_px: p.feather_px / s,
            ..p.clone()
        })
    }
    fn shifted(p: &SimpleBrushParams, dx: f64, dy: f64) -> SimpleBrushParams {
        SimpleBrushParams {
            points: shift_points(&p.points, dx, dy),
            ..p.clone()
        }
    }
    fn damage(
        old: &SimpleBrushParams,
        new: &SimpleBrushParams,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        // g′ = m·K(g) + (1 − m)·g: only the stroke's weight m moves when only its points do.
        let same_but_points = SimpleBrushParams {
            points: new.points.clone(),
            ..old.clone()
        } == *new;
        let reach = |p: &SimpleBrushParams| p.radius_px + p.feather_px + 2.0;
        if same_but_points {
            return Some(changed_path_bounds(
                &old.points,
                &new.points,
                0.0,
                reach(new),
            ));
        }
        // Another kernel changes the result wherever m > 0: inside the strokes, unless a mask
        // input adds to m.
        if inputs.get(1).is_some_and(Option::is_some) {
            return None;
        }
        paths_bounds(&[&old.points, &new.points], reach(old).max(reach(new))).map(|b| vec![b])
    }
    fn run(p: &SimpleBrushParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let (out, rep) = brush_image(img, i.mask("mask")?, &p.to_params()?)?;
        let region = rep
            .region
            .ok_or_else(|| RgbnError::InvalidImage("brush returned no region".into()))?;
        Ok(vec![
            Value::Rgbn(out),
            Value::Mask(Arc::new(region)),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
