//! Many strokes, one pen: a list of paths sharing the stroke parameters of
//! [`super::pen`] (issue 38: carving a relief takes many strokes, and each was a node).
//!
//! Each path is open or closed and takes its node's stroke parameters, except those it sets
//! for itself ([`PER_PATH`]: its cross-section — width, profile, height, samples, taper). The
//! relief of the list is the **sum** of the reliefs of its strokes: gradients add (so the
//! field of integrable strokes stays a surface), and so do heights — the pen's height is the
//! sum of each stroke's height ([`super::pen::pen_field`]), which far from a stroke is that
//! stroke's outside level `f(−1)` (0 for every built-in profile). One path gives exactly the
//! single stroke of [`super::pen`].
//!
//! **Local work.** A stroke changes nothing beyond half its width from its path (plus the
//! cap, within the same reach), so each stroke is computed only over its path's bounding box
//! grown by that reach (a window of the image, with its points shifted by whole pixels, where
//! the single-stroke maths is exact pixel by pixel) and contributes its outside level
//! everywhere else. A tile far from every path costs a bounding-box test per path, and adding
//! a path changes only the pixels near it ([`crate::nodes::pen`]'s damage is per path).

use super::geom::paths_bounds;
use super::pen::{add_relief, pen_field_with, PenMode, PenOutput, PenParams, PenReport};
use crate::error::RgbnError;
use crate::params::{apply_own, visit_except, Meta, ParamVisitor, Params, PathValue};
use crate::raster::gradient::GradientField;
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// The parameters a path may set for itself; every other one is its node's.
pub const PER_PATH: &[&str] = &["width_px", "profile", "height_px", "samples_px", "taper_px"];

/// The stroke's own fields of [`PenParams`], which a path replaces.
const PATH_FIELDS: &[&str] = &["points", "closed"];

/// Parameters of [`pen_paths_field`]: the paths and the stroke parameters they share.
#[derive(Clone, Debug, PartialEq)]
pub struct PenPathsParams {
    /// The strokes, in drawing order.
    pub paths: Vec<PathValue>,
    /// Every parameter of a stroke but its path (`points` and `closed` here are unused).
    pub stroke: PenParams,
}

impl Default for PenPathsParams {
    fn default() -> Self {
        let stroke = PenParams::default();
        Self {
            paths: vec![PathValue::new(stroke.points.clone(), stroke.closed)],
            stroke,
        }
    }
}

impl Params for PenPathsParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.paths(
            "paths",
            &mut self.paths,
            &Meta::new(
                "The strokes: each path's vertices in pixels (x, row), open or closed (≥ 2 points open, ≥ 3 distinct closed), with the node's stroke parameters or its own width_px, profile, height_px, samples_px and taper_px. Their reliefs add.",
            )
            .unit("px"),
        );
        visit_except(&mut self.stroke, v, PATH_FIELDS);
    }
}

impl PenPathsParams {
    /// One path drawn with these parameters (one stroke).
    #[must_use]
    pub fn single(stroke: PenParams) -> Self {
        Self {
            paths: vec![PathValue::new(stroke.points.clone(), stroke.closed)],
            stroke,
        }
    }

    /// The stroke of path `i`: the node's stroke parameters with the path's points, closure and
    /// own parameters (not validated: see [`PenPathsParams::validate`]).
    pub fn path_stroke(&self, i: usize) -> Result<PenParams, RgbnError> {
        let path = self.paths.get(i).ok_or_else(|| {
            RgbnError::param(
                "paths",
                format!("no path {} of {}", i + 1, self.paths.len()),
            )
        })?;
        let mut p = PenParams {
            points: path.points.clone(),
            closed: path.closed,
            ..self.stroke.clone()
        };
        apply_own(&mut p, &path.params, PER_PATH).map_err(|e| self.path_error(i, e.into()))?;
        Ok(p)
    }

    /// Every path's stroke, in order.
    pub fn strokes(&self) -> Result<Vec<PenParams>, RgbnError> {
        (0..self.paths.len()).map(|i| self.path_stroke(i)).collect()
    }

    /// Checks every path as a stroke of its own ([`PenParams::validate`]); an error names the
    /// path.
    pub fn validate(&self) -> Result<(), RgbnError> {
        for i in 0..self.paths.len() {
            self.path_stroke(i)?
                .validate()
                .map_err(|e| self.path_error(i, e))?;
        }
        Ok(())
    }

    fn path_error(&self, i: usize, e: RgbnError) -> RgbnError {
        let detail = match e {
            RgbnError::InvalidParam { name, detail } => format!("{name}: {detail}"),
            other => other.to_string(),
        };
        RgbnError::param(
            "paths",
            format!("path {} of {}: {detail}", i + 1, self.paths.len()),
        )
    }
}

/// How far from its path a stroke changes anything, in pixels: half its width, plus a pixel
/// of differencing and half a pixel of rasterisation (and a margin).
#[must_use]
pub fn reach_px(stroke: &PenParams) -> f64 {
    stroke.width_px / 2.0 + 3.0
}

/// The value a stroke has far from its path, exactly as [`pen_field_with`] computes it there
/// (its outside level `f(−1)` through the mode's own arithmetic).
fn outside_height(stroke: &PenParams) -> f32 {
    let f0 = stroke.shape().eval(-1.0).0;
    match stroke.mode {
        PenMode::Integrable => GradientField::from_corner_heights(1, 1, &[f0; 4])
            .1
            .at(0, 0),
        PenMode::Analytic => f0 as f32,
        PenMode::DistanceTransform => GradientField::of_height(&Plane::filled(3, 3, f0 as f32))
            .1
            .at(1, 1),
    }
}

/// The pixels `[x0, y0, x1, y1)` of a `width × height` image that stroke may change, or
/// `None` when it changes none.
fn window(stroke: &PenParams, width: usize, height: usize) -> Option<[usize; 4]> {
    let b = paths_bounds(&[&stroke.points], reach_px(stroke))?;
    let lo = |v: f64, n: usize| (v.floor().max(0.0) as usize).min(n);
    let hi = |v: f64, n: usize| ((v.ceil() + 1.0).max(0.0) as usize).min(n);
    let w = [
        lo(b[0], width),
        lo(b[1], height),
        hi(b[2], width),
        hi(b[3], height),
    ];
    (w[0] < w[2] && w[1] < w[3]).then_some(w)
}

/// Adds `c` to every value of `plane` (`width` wide) outside the window `win`.
fn add_outside(plane: &mut [f32], width: usize, win: Option<[usize; 4]>, c: f32) {
    if c == 0.0 {
        return;
    }
    plane
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(r, row)| match win {
            Some([x0, y0, x1, y1]) if (y0..y1).contains(&r) => {
                row[..x0].iter_mut().for_each(|v| *v += c);
                row[x1..].iter_mut().for_each(|v| *v += c);
            }
            _ => row.iter_mut().for_each(|v| *v += c),
        });
}

/// Adds the window-sized `src` into `dst` (`width` wide) at the window `[x0, y0, ..]`.
fn add_window(dst: &mut [f32], width: usize, [x0, y0, x1, y1]: [usize; 4], src: &[f32]) {
    let ww = x1 - x0;
    dst.par_chunks_mut(width)
        .skip(y0)
        .take(y1 - y0)
        .zip(src.par_chunks(ww))
        .for_each(|(row, s)| {
            for (d, v) in row[x0..x1].iter_mut().zip(s) {
                *d += v;
            }
        });
}

/// The pen's relief of every path on a `width × height` image: the sum of each stroke's
/// gradients and height (module docs), each computed over its window only.
pub fn pen_paths_field(
    width: usize,
    height: usize,
    params: &PenPathsParams,
    texture: Option<&Plane>,
) -> Result<PenOutput, RgbnError> {
    let strokes = params.strokes()?;
    if let [one] = strokes.as_slice() {
        return pen_field_with(width, height, one, texture).map_err(|e| params.path_error(0, e));
    }
    crate::raster::check_size(width, height, "pen")?;
    let mut gradients = GradientField::zeros(width, height);
    let mut z = vec![0.0f32; width * height];
    let mut drawn = false;
    for (i, s) in strokes.iter().enumerate() {
        let win = window(s, width, height);
        if let Some(w @ [x0, y0, x1, y1]) = win {
            let local = crate::params::shifted(s, x0 as f64, y0 as f64);
            let out = pen_field_with(x1 - x0, y1 - y0, &local, texture)
                .map_err(|e| params.path_error(i, e))?;
            add_window(&mut gradients.p, width, w, &out.gradients.p);
            add_window(&mut gradients.q, width, w, &out.gradients.q);
            add_window(&mut z, width, w, out.height.data());
            drawn = true;
        }
        add_outside(&mut z, width, win, outside_height(s));
    }
    if let (false, Some(first)) = (drawn, strokes.first()) {
        // Nothing near this image: the parameters and the texture are still checked as a
        // drawn stroke checks them, so every part of an image fails alike.
        pen_field_with(1, 1, first, texture).map_err(|e| params.path_error(0, e))?;
    }
    Ok(PenOutput {
        gradients,
        height: Plane::from_vec(width, height, z)?,
    })
}

/// Adds the relief of every path to an image's gradients (colour and mask kept), as
/// [`super::pen::apply_pen_with`] adds one stroke's; the report holds the pen's height.
pub fn apply_pen_paths(
    img: &RgbnImage,
    params: &PenPathsParams,
    texture: Option<&Plane>,
) -> Result<(RgbnImage, PenReport), RgbnError> {
    let pen = pen_paths_field(img.width(), img.height(), params, texture)?;
    Ok(add_relief(img, pen))
}

#[cfg(test)]
#[path = "pen_paths_tests.rs"]
mod tests;
