//! The stamp of [`crate::ops::stamp`] as a node: place an RGBN stamp at positions with an affine map
//! ([`stamp_image`]).

use super::kit::{curl_port, shift_points};
use super::{
    scale_point, Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value,
};
use crate::error::RgbnError;
use crate::ops::stamp::{extract, placement_bounds, stamp_image, ExtractParams, StampParams};

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
            "The stamp (at most 512 px a side); its mask limits its relief (feathered over the falloff) and its colour.",
        ))
        .input(
            PortSpec::new(
                "region",
                PortType::Mask,
                "Optional region (the target's size): the stamped relief and colour are multiplied by it, integrably.",
            )
            .optional(),
        )
        .output(PortSpec::new("image", PortType::Rgbn, "Stamped image."))
        .output(curl_port("result's gradients"))
    }
    fn check(p: &StampParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn footprint(_: &StampParams, input: usize) -> Footprint {
        // The stamp is used whole at every placement; target and region are differentiated.
        if input == 1 {
            Footprint::Global
        } else {
            Footprint::Local { halo: 1 }
        }
    }
    fn scaled(p: &StampParams, s: f64) -> Option<StampParams> {
        // The stamp image is reduced with the target: the affine map stays, placements move.
        Some(StampParams {
            positions: p.positions.iter().map(|&q| scale_point(q, s)).collect(),
            falloff_px: p.falloff_px / s,
            ..p.clone()
        })
    }
    fn shifted(p: &StampParams, dx: f64, dy: f64) -> StampParams {
        StampParams {
            positions: shift_points(&p.positions, dx, dy),
            ..p.clone()
        }
    }
    fn damage(
        old: &StampParams,
        new: &StampParams,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        let (sw, sh) = (*inputs.get(1)?)?;
        let same_but_positions = StampParams {
            positions: new.positions.clone(),
            ..old.clone()
        } == *new;
        let (ob, nb) = (placement_bounds(old, sw, sh), placement_bounds(new, sw, sh));
        if !same_but_positions {
            return Some(ob.into_iter().chain(nb).collect());
        }
        // Placements that moved, appeared or went: their old and new footprints.
        let f = |p: &[f64; 2]| p.map(|v| v as f32);
        let mut out = Vec::new();
        for k in 0..ob.len().max(nb.len()) {
            let (o, n) = (old.positions.get(k), new.positions.get(k));
            if o.map(f) != n.map(f) {
                out.extend(ob.get(k).copied());
                out.extend(nb.get(k).copied());
            }
        }
        Some(out)
    }
    fn run(p: &StampParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let region = i.mask("region")?.map(|m| m.data());
        let (img, rep) = stamp_image(i.rgbn("image")?, i.rgbn("stamp")?, region, p)?;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(rep.curl_after.relative),
        ])
    }
}

/// Extract: a piece of an image as a stamp.
pub struct ExtractNode;

impl Operator for ExtractNode {
    type Params = ExtractParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "extract",
            "Extract stamp",
            "combine",
            "Cuts a piece out of an RGBN image to stamp elsewhere (Pereira & Velho Fig. 4): a rectangle, or the bounding box of a region mask whose coverage becomes the piece's mask; optionally high-passed so only its detail is stamped.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to cut from."))
        .input(
            PortSpec::new(
                "region",
                PortType::Mask,
                "Optional region (the image's size): its bounding box is cut, its coverage is the piece's mask.",
            )
            .optional(),
        )
        .output(PortSpec::new("stamp", PortType::Rgbn, "The piece (at most 512 px a side)."))
    }
    fn out_size(p: &ExtractParams, inputs: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        // With a region the size depends on its pixels: at most a stamp's largest side.
        match inputs.get(1) {
            Some(Some(_)) => Some((512, 512)),
            _ => Some((p.width as usize, p.height as usize)),
        }
    }
    fn run(p: &ExtractParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let region = i.mask("region")?.map(|m| m.data());
        Ok(vec![Value::Rgbn(extract(i.rgbn("image")?, region, p)?)])
    }
}
