//! The pen of [`crate::ops::pen`] as a node: sculpt a relief along open or closed paths with a
//! profile and an optional pattern along them, every stroke of the node in one list of paths
//! ([`crate::ops::pen_paths::apply_pen_paths`]).

use super::{Coarse, Kind, OpSpec, Operator, RunContext, Scalar};
use crate::error::RgbnError;
use crate::ops::geom::{changed_path_bounds, paths_bounds};
use crate::ops::pen::{PenMode, PenParams};
use crate::ops::pen_paths::{apply_pen_paths, reach_px, PenPathsParams};
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
    type Params = PenPathsParams;
    type In = PenIn;
    type Out = PenOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "pen",
            "Pen",
            "draw",
            "Sculpts a relief along paths (Pereira & Velho §V–VI): a profile across each open or closed polyline, added to the image's gradients; the strokes of one node add. Open paths must end at the level they start (bump, ridge, crease, scratch); a step raises the inside of a closed path.",
        )
    }
    fn check(p: &PenPathsParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(p: &PenPathsParams) -> Kind {
        let halo = match p.stroke.mode {
            // Heights at the pixel corners around each pixel (integrable), gradients at the
            // pixel centres (analytic): one pixel.
            PenMode::Integrable | PenMode::Analytic => 1,
            // Distances from the rasterised path matter as far as a stroke reaches (the one
            // definition, `reach_px`; a taper varies the height along the path, not how far
            // across it a stroke reaches).
            PenMode::DistanceTransform => p
                .strokes()
                .unwrap_or_default()
                .iter()
                .chain([&p.stroke])
                .map(|s| reach_px(s).ceil() as usize)
                .max()
                .unwrap_or(0),
        };
        // Lengths and points are declared in pixels: the level's pen is the declared scaling.
        Kind::Area {
            halo,
            coarse: Coarse::Scaled,
        }
    }
    fn damage(
        old: &PenPathsParams,
        new: &PenPathsParams,
        _: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        damage(old, new)
    }
    fn run(p: &PenPathsParams, i: PenIn, _: &RunContext) -> Result<PenOut, RgbnError> {
        let (image, rep) = apply_pen_paths(&i.image, p, i.texture.as_deref())?;
        let relative_rms_curl = rep.curl_after.relative;
        Ok(PenOut {
            image,
            height: Scalar::new(rep.height),
            relative_rms_curl,
        })
    }
}

/// Where the pen's outputs can change from `old` to `new` (GEGL's
/// `get_invalidated_by_change`), path by path: the paths both lists share at their start and
/// at their end are unchanged, so only those between (added, removed or edited) count — each
/// within its reach of its points ([`reach_px`]), and for an open path whose points alone
/// changed, only from where they differ ([`changed_path_bounds`]). A change of the stroke
/// parameters the paths share changes every path that uses them. `None` (anywhere) when a
/// changed stroke's outside level is not 0: the pen's height then moves everywhere.
fn damage(old: &PenPathsParams, new: &PenPathsParams) -> Option<Vec<[f64; 4]>> {
    let (a, b) = (old.strokes().ok()?, new.strokes().ok()?);
    let shared = old.stroke == new.stroke;
    let same = |i: usize, j: usize| shared && old.paths[i] == new.paths[j];
    let n = a.len().min(b.len());
    let head = (0..n).take_while(|&i| same(i, i)).count();
    let tail = (0..n - head)
        .take_while(|&k| same(a.len() - 1 - k, b.len() - 1 - k))
        .count();
    let (a, b) = (&a[head..a.len() - tail], &b[head..b.len() - tail]);
    let level = |s: &PenParams| s.shape().eval(-1.0).0;
    if a.iter().chain(b).any(|s| level(s) != 0.0) {
        return None;
    }
    let mut out = Vec::new();
    for k in 0..a.len().max(b.len()) {
        match (a.get(k), b.get(k)) {
            (Some(o), Some(n))
                if !n.closed
                    && PenParams {
                        points: n.points.clone(),
                        ..o.clone()
                    } == *n =>
            {
                // Arclength from the start is kept; the end taper moves with the end.
                out.extend(changed_path_bounds(
                    &o.points,
                    &n.points,
                    n.taper_px,
                    reach_px(n),
                ));
            }
            (o, n) => {
                for s in o.into_iter().chain(n) {
                    out.extend(paths_bounds(&[&s.points], reach_px(s)));
                }
            }
        }
    }
    Some(out)
}
