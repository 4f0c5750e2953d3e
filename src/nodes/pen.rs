//! The pen of [`crate::ops::pen`] as a node: sculpt a relief along an open or closed path with a
//! profile and an optional pattern along it ([`crate::ops::pen::apply_pen_with`]).

use super::kit::{curl_port, shift_points};
use super::{
    scale_point, Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value,
};
use crate::error::RgbnError;
use crate::ops::geom::{changed_path_bounds, paths_bounds};
use crate::ops::pen::{apply_pen_with, PenMode, PenParams};
use std::sync::Arc;

/// Pen.
pub struct PenNode;

impl Operator for PenNode {
    type Params = PenParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "pen",
            "Pen",
            "draw",
            "Sculpts a relief along a path (Pereira & Velho §V–VI): a profile across an open or closed polyline, added to the image's gradients. Open paths must end at the level they start (bump, ridge, crease, scratch); a step raises the inside of a closed path.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to draw on."))
        .input(
            PortSpec::new(
                "texture",
                PortType::Scalar,
                "Optional height image for pattern: texture (at most 1024 px a side): columns across the stroke, rows along one period (along_period_px); its edge columns are pinned to the surface.",
            )
            .optional(),
        )
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Image with the relief added; colour and mask unchanged.",
        ))
        .output(PortSpec::new(
            "height",
            PortType::Scalar,
            "The pen's height in pixels (its gradients are what was added).",
        ))
        .output(curl_port("result's gradients"))
    }
    fn check(p: &PenParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn footprint(p: &PenParams, input: usize) -> Footprint {
        if input == 1 {
            // The texture is one period of the pattern, used whole all along the path and
            // sampled in coordinates relative to its size: never reduced at coarse levels.
            return Footprint::Pattern;
        }
        match p.mode {
            // Heights differentiated forward, gradients at staggered points: one pixel.
            PenMode::Integrable | PenMode::Analytic => Footprint::Local { halo: 1 },
            // Distances from the rasterised path matter up to the stroke's half width and taper.
            PenMode::DistanceTransform => Footprint::Local {
                halo: (p.width_px / 2.0 + p.taper_px).ceil() as usize + 2,
            },
        }
    }
    fn scaled(p: &PenParams, s: f64) -> Option<PenParams> {
        Some(PenParams {
            points: p.points.iter().map(|&q| scale_point(q, s)).collect(),
            width_px: p.width_px / s,
            height_px: p.height_px / s,
            samples_px: p.samples_px.iter().map(|v| v / s).collect(),
            taper_px: p.taper_px / s,
            along_period_px: p.along_period_px / s,
            pattern_height_px: p.pattern_height_px / s,
            ..p.clone()
        })
    }
    fn shifted(p: &PenParams, dx: f64, dy: f64) -> PenParams {
        PenParams {
            points: shift_points(&p.points, dx, dy),
            ..p.clone()
        }
    }
    fn damage(
        old: &PenParams,
        new: &PenParams,
        _: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        // The relief reaches half the width from the path (plus a pixel of differencing and
        // half a pixel of rasterisation); a closed path also raises its inside, which its
        // points' bounding box contains.
        let reach = |p: &PenParams| p.width_px / 2.0 + 3.0;
        let same_but_points = PenParams {
            points: new.points.clone(),
            ..old.clone()
        } == *new;
        if same_but_points && !new.closed {
            // Arclength from the start is kept; the end taper moves with the end.
            return Some(changed_path_bounds(
                &old.points,
                &new.points,
                new.taper_px,
                reach(new),
            ));
        }
        paths_bounds(&[&old.points, &new.points], reach(old).max(reach(new))).map(|b| vec![b])
    }
    fn run(p: &PenParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (out, rep) = apply_pen_with(i.rgbn("image")?, p, i.scalar("texture")?)?;
        let curl = rep.curl_after.relative;
        Ok(vec![
            Value::Rgbn(out),
            Value::Scalar(Arc::new(rep.height)),
            Value::Number(curl),
        ])
    }
}
