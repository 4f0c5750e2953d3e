//! Light calibration from a chrome (mirror) sphere.
//!
//! [`calibrate_chrome`]: the sphere is fitted to the mask (centroid = centre, `√(area/π)` =
//! radius); in each photo the highlight is the brightness-weighted centroid of the pixels inside
//! the mask within [`ChromeParams::highlight_fraction`] of the brightest. Its sphere normal
//! `n = ((x − cx)/r, (cy − y)/r, √(1 − …))` reflects the view direction `v = (0, 0, 1)`
//! (orthographic camera) into the light: `l = 2 (n · v) n − v`.
//!
//! - S. Seitz et al., UW CSE 455 "Photometric stereo" project (chrome-ball light calibration).

use super::inputs::PhotoStack;
use crate::error::RgbnError;
use std::path::PathBuf;

/// Parameters of [`calibrate_chrome`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChromeParams {
    /// Pixels inside the mask at least this fraction of the photo's brightest (inside) value
    /// form the highlight, in (0, 1].
    pub highlight_fraction: f32,
}

impl Default for ChromeParams {
    fn default() -> Self {
        Self {
            highlight_fraction: 0.9,
        }
    }
}

impl ChromeParams {
    /// Checks the range documented on the field.
    pub fn validate(&self) -> Result<(), RgbnError> {
        if !(self.highlight_fraction > 0.0 && self.highlight_fraction <= 1.0) {
            return Err(RgbnError::param("highlight_fraction", "must be in (0, 1]"));
        }
        Ok(())
    }
}

/// Result of [`calibrate_chrome`].
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChromeCalibration {
    /// Sphere centre `(x, row)` in pixels (pixel indices, not corners).
    pub centre_px: [f64; 2],
    pub radius_px: f64,
    /// Highlight centroid `(x, row)` per photo.
    pub highlights_px: Vec<[f64; 2]>,
    /// Unit light direction per photo (`x` right, `y` up, `z` towards the camera).
    pub directions: Vec<[f32; 3]>,
}

/// Estimates light directions from photos of a mirror sphere and its mask (module docs).
///
/// # Errors
/// Invalid parameters, a mask of the wrong length or empty, a photo without any light inside
/// the mask.
pub fn calibrate_chrome(
    stack: &PhotoStack,
    mask: &[f32],
    params: &ChromeParams,
) -> Result<ChromeCalibration, RgbnError> {
    params.validate()?;
    let (w, h) = (stack.width, stack.height);
    if mask.len() != w * h {
        return Err(RgbnError::SizeMismatch {
            what: "chrome mask",
            want_w: w,
            want_h: h,
            got_w: mask.len(),
            got_h: 1,
            path: PathBuf::new(),
        });
    }
    let (mut sx, mut sy, mut area) = (0.0f64, 0.0f64, 0usize);
    for (i, &m) in mask.iter().enumerate() {
        if m >= 0.5 {
            sx += (i % w) as f64;
            sy += (i / w) as f64;
            area += 1;
        }
    }
    if area == 0 {
        return Err(RgbnError::EmptyMask {
            what: "the chrome-sphere mask",
        });
    }
    let (cx, cy) = (sx / area as f64, sy / area as f64);
    let radius = (area as f64 / std::f64::consts::PI).sqrt();
    let mut highlights = Vec::with_capacity(stack.photos.len());
    let mut directions = Vec::with_capacity(stack.photos.len());
    for (j, photo) in stack.photos.iter().enumerate() {
        let grey = |i: usize| (photo[0][i] + photo[1][i] + photo[2][i]) / 3.0;
        let peak = (0..w * h)
            .filter(|&i| mask[i] >= 0.5)
            .map(grey)
            .fold(0.0f32, f32::max);
        if peak.is_nan() || peak <= 0.0 {
            return Err(RgbnError::param(
                "chrome photos",
                format!("photo {j} is black inside the sphere mask"),
            ));
        }
        let t = peak * params.highlight_fraction;
        let (mut wx, mut wy, mut ws) = (0.0f64, 0.0f64, 0.0f64);
        for i in (0..w * h).filter(|&i| mask[i] >= 0.5) {
            let v = grey(i);
            if v >= t {
                let wt = f64::from(v);
                wx += wt * (i % w) as f64;
                wy += wt * (i / w) as f64;
                ws += wt;
            }
        }
        let (hx, hy) = (wx / ws, wy / ws);
        let (nx, ny) = ((hx - cx) / radius, (cy - hy) / radius);
        let nz = (1.0 - nx * nx - ny * ny).max(0.0).sqrt();
        // l = 2 (n·v) n − v with v = (0, 0, 1).
        let l = [2.0 * nz * nx, 2.0 * nz * ny, 2.0 * nz * nz - 1.0];
        let len = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        highlights.push([hx, hy]);
        directions.push(l.map(|c| (c / len) as f32));
    }
    Ok(ChromeCalibration {
        centre_px: [cx, cy],
        radius_px: radius,
        highlights_px: highlights,
        directions,
    })
}
