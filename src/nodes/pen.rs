//! The pen of [`crate::ops::pen`] as a node: sculpt a relief along an open or closed path with a
//! profile and an optional pattern along it ([`crate::ops::pen::apply_pen_with`]).

use super::{Coarse, Kind, OpSpec, Operator, RunContext, Scalar};
use crate::error::RgbnError;
use crate::ops::geom::{changed_path_bounds, paths_bounds};
use crate::ops::pen::{apply_pen_with, PenMode, PenParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`PenNode`].
    pub struct PenIn {
        /// Image to draw on.
        pub image: RgbnImage,
        /// Optional height image for pattern: texture (at most 1024 px a side): columns across the stroke, rows along one period (along_period_px); its edge columns are pinned to the surface.
        pub texture: Option<Scalar> => pattern,
    }
}

crate::outputs! {
    /// Outputs of [`PenNode`].
    pub struct PenOut {
        /// Image with the relief added; colour and mask unchanged.
        pub image: RgbnImage,
        /// The pen's height in pixels (its gradients are what was added).
        pub height: Scalar,
        /// RMS(curl) / RMS(|g|) of the result's gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Pen.
pub struct PenNode;

impl Operator for PenNode {
    type Params = PenParams;
    type In = PenIn;
    type Out = PenOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "pen",
            "Pen",
            "draw",
            "Sculpts a relief along a path (Pereira & Velho §V–VI): a profile across an open or closed polyline, added to the image's gradients. Open paths must end at the level they start (bump, ridge, crease, scratch); a step raises the inside of a closed path.",
        )
    }
    fn check(p: &PenParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(p: &PenParams) -> Kind {
        let halo = match p.mode {
            // Heights at the pixel corners around each pixel (integrable), gradients at the
            // pixel centres (analytic): one pixel.
            PenMode::Integrable | PenMode::Analytic => 1,
            // Distances from the rasterised path matter up to the stroke's half width and taper.
            PenMode::DistanceTransform => (p.width_px / 2.0 + p.taper_px).ceil() as usize + 2,
        };
        // Lengths and points are declared in pixels: the level's pen is the declared scaling.
        Kind::Area {
            halo,
            coarse: Coarse::Scaled,
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
    fn run(p: &PenParams, i: PenIn, _: &RunContext) -> Result<PenOut, RgbnError> {
        let (image, rep) = apply_pen_with(&i.image, p, i.texture.as_deref())?;
        let relative_rms_curl = rep.curl_after.relative;
        Ok(PenOut {
            image,
            height: Scalar::new(rep.height),
            relative_rms_curl,
        })
    }
}
