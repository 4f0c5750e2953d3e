//! Geometric transforms of a whole RGBN image: crop, mirror, flip, rotation by quarter turns and
//! resize, with the normals transformed as the surface is.
//!
//! The steps run in this order: **crop** (a rectangle of the input, in its pixels), **mirror**
//! (left–right), **flip** (top–bottom), **rotate** (counter-clockwise as the image is seen,
//! by 0, 90, 180 or 270°), **resize** (to a width and height). Colour and mask move with their
//! pixels. The normals follow the surface (`+x` right, `+y` up, `+z` to the viewer):
//!
//! - a mirror maps `x → −x`, so `n = (n_x, n_y, n_z) → (−n_x, n_y, n_z)`; a flip
//!   `n → (n_x, −n_y, n_z)`;
//! - a rotation by `θ` counter-clockwise rotates `(n_x, n_y)` by `θ`: by 90°
//!   `(n_x, n_y) → (−n_y, n_x)`, by 180° `→ (−n_x, −n_y)`, by 270° `→ (n_y, −n_x)`.
//!
//! These steps only move samples and change signs, so a field that is the gradient of a height
//! stays one exactly (its curl is the moved curl, up to sign).
//!
//! **Resize** works on the gradients `(p, q) = (−n_x/n_z, −n_y/n_z)`, not on the normals:
//! averaging normals and renormalising is nonlinear, while a linear filter of the gradients
//! of a height is the gradient of the filtered height. The surface is stretched with the
//! image: stretching by `(k_x, k_y)` maps a height `z` to `s·z` with `s = √(k_x k_y)`, so
//! slopes become `p′ = (s/k_x)·p`, `q′ = (s/k_y)·q` (unchanged for a uniform resize, where the
//! relief keeps its look). The filter is a tent (bilinear interpolation when enlarging; when
//! reducing, a tent as wide as the reduction, which averages the pixels each output pixel
//! covers), weighed by the mask where there is one; colour (linear light) is resampled alike.

use crate::error::RgbnError;
use crate::raster::gradient::GradientField;
use crate::raster::{check_size, RgbnImage};
use rayon::prelude::*;

crate::choice_enum! {
    /// A rotation by quarter turns, counter-clockwise as the image is seen.
    pub enum QuarterTurn {
        /// No rotation.
        None = "0",
        /// A quarter turn counter-clockwise.
        Ccw90 = "90",
        /// A half turn.
        Half = "180",
        /// Three quarter turns counter-clockwise (a quarter turn clockwise).
        Ccw270 = "270",
    }
}

crate::params! {
    /// Parameters of [`transform`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct TransformParams {
        /// First column of the crop.
        pub crop_x: i64 = 0 => int.unit("px").range(0.0, 1e9).soft(0.0, 4096.0),
        /// First row of the crop (row 0 at the top).
        pub crop_y: i64 = 0 => int.unit("px").range(0.0, 1e9).soft(0.0, 4096.0),
        /// Columns of the crop; 0 = to the right edge.
        pub crop_width: i64 = 0 => int.unit("px").range(0.0, 1e9).soft(0.0, 4096.0),
        /// Rows of the crop; 0 = to the bottom edge.
        pub crop_height: i64 = 0 => int.unit("px").range(0.0, 1e9).soft(0.0, 4096.0),
        /// Mirror left–right (n_x changes sign).
        pub mirror: bool = false => bool,
        /// Flip top–bottom (n_y changes sign).
        pub flip: bool = false => bool,
        /// Counter-clockwise rotation in degrees: 0, 90, 180 or 270 ((n_x, n_y) rotates with the image).
        pub rotate: QuarterTurn = QuarterTurn::None => choice,
        /// Width after resizing; 0 = keep (or follow resize_height, keeping the aspect ratio).
        pub resize_width: i64 = 0 => int.unit("px").range(0.0, 1e6).soft(0.0, 4096.0),
        /// Height after resizing; 0 = keep (or follow resize_width, keeping the aspect ratio).
        pub resize_height: i64 = 0 => int.unit("px").range(0.0, 1e6).soft(0.0, 4096.0),
    }
}

impl TransformParams {
    /// The crop rectangle `(x, y, w, h)` of a `w × h` input.
    ///
    /// # Errors
    /// A crop that leaves no pixel of the input, naming the parameter.
    pub fn crop_rect(
        &self,
        (w, h): (usize, usize),
    ) -> Result<(usize, usize, usize, usize), RgbnError> {
        let (x, y) = (self.crop_x as usize, self.crop_y as usize);
        if x >= w {
            return Err(RgbnError::param(
                "crop_x",
                format!("{x} is outside the {w}-pixel-wide image"),
            ));
        }
        if y >= h {
            return Err(RgbnError::param(
                "crop_y",
                format!("{y} is outside the {h}-pixel-high image"),
            ));
        }
        let cw = if self.crop_width == 0 {
            w - x
        } else {
            self.crop_width as usize
        };
        let ch = if self.crop_height == 0 {
            h - y
        } else {
            self.crop_height as usize
        };
        if x + cw > w {
            return Err(RgbnError::param(
                "crop_width",
                format!("{cw} columns from column {x} go past the image's {w}"),
            ));
        }
        if y + ch > h {
            return Err(RgbnError::param(
                "crop_height",
                format!("{ch} rows from row {y} go past the image's {h}"),
            ));
        }
        Ok((x, y, cw, ch))
    }

    /// The output size for a `w × h` input.
    ///
    /// # Errors
    /// As [`Self::crop_rect`]; an output over the pixel limit.
    pub fn out_size(&self, size: (usize, usize)) -> Result<(usize, usize), RgbnError> {
        let (_, _, cw, ch) = self.crop_rect(size)?;
        let (rw, rh) = match self.rotate {
            QuarterTurn::None | QuarterTurn::Half => (cw, ch),
            QuarterTurn::Ccw90 | QuarterTurn::Ccw270 => (ch, cw),
        };
        let (tw, th) = (self.resize_width as usize, self.resize_height as usize);
        let round = |v: f64| (v.round() as usize).max(1);
        let out = match (tw, th) {
            (0, 0) => (rw, rh),
            (0, th) => (round(rw as f64 * th as f64 / rh as f64), th),
            (tw, 0) => (tw, round(rh as f64 * tw as f64 / rw as f64)),
            sized => sized,
        };
        check_size(out.0, out.1, "transform")?;
        Ok(out)
    }
}

/// `img` cropped, mirrored, flipped, rotated and resized (module docs).
///
/// # Errors
/// A crop outside the image ([`TransformParams::crop_rect`]); an output over the pixel limit.
pub fn transform(img: &RgbnImage, p: &TransformParams) -> Result<RgbnImage, RgbnError> {
    let (w, h) = (img.width(), img.height());
    let (x0, y0, cw, ch) = p.crop_rect((w, h))?;
    let (rw, rh) = match p.rotate {
        QuarterTurn::None | QuarterTurn::Half => (cw, ch),
        QuarterTurn::Ccw90 | QuarterTurn::Ccw270 => (ch, cw),
    };
    // For each output pixel (column c, row r) of the rotated grid, the input pixel it comes
    // from. Rows grow downwards and y upwards, so a counter-clockwise turn as seen maps output
    // (c, r) to crop (cw − 1 − r, c); the mirror and flip apply to the crop before it.
    let source = |c: usize, r: usize| -> (usize, usize) {
        let (mut x, mut y) = match p.rotate {
            QuarterTurn::None => (c, r),
            QuarterTurn::Ccw90 => (cw - 1 - r, c),
            QuarterTurn::Half => (cw - 1 - c, ch - 1 - r),
            QuarterTurn::Ccw270 => (r, ch - 1 - c),
        };
        if p.mirror {
            x = cw - 1 - x;
        }
        if p.flip {
            y = ch - 1 - y;
        }
        (x0 + x, y0 + y)
    };
    // The normal's (x, y) after mirror, flip, then the rotation.
    let (sx, sy) = (
        if p.mirror { -1.0f32 } else { 1.0 },
        if p.flip { -1.0f32 } else { 1.0 },
    );
    let turn = |nx: f32, ny: f32| -> (f32, f32) {
        let (nx, ny) = (sx * nx, sy * ny);
        match p.rotate {
            QuarterTurn::None => (nx, ny),
            QuarterTurn::Ccw90 => (-ny, nx),
            QuarterTurn::Half => (-nx, -ny),
            QuarterTurn::Ccw270 => (ny, -nx),
        }
    };
    let gather = |plane: &[f32]| -> Vec<f32> {
        let mut out = vec![0.0f32; rw * rh];
        out.par_chunks_mut(rw).enumerate().for_each(|(r, row)| {
            for (c, o) in row.iter_mut().enumerate() {
                let (x, y) = source(c, r);
                *o = plane[y * w + x];
            }
        });
        out
    };
    let color = img.color().each_ref().map(|c| gather(c));
    let [nx, ny, nz] = img.normal();
    let (mut ox, mut oy) = (gather(nx), gather(ny));
    ox.par_iter_mut().zip(oy.par_iter_mut()).for_each(|(a, b)| {
        (*a, *b) = turn(*a, *b);
    });
    let normal = [ox, oy, gather(nz)];
    let mask = img.mask().map(gather);
    let moved = RgbnImage::new(rw, rh, color, normal, mask)?;
    let (tw, th) = p.out_size((w, h))?;
    if (tw, th) == (rw, rh) {
        return Ok(moved);
    }
    Ok(resize(&moved, tw, th))
}

/// Taps of the tent filter that resamples `n` samples to `m`: per output sample, the first
/// input index and its weights (summing to 1).
fn taps(n: usize, m: usize) -> Vec<(usize, Vec<f32>)> {
    let k = m as f64 / n as f64;
    // Half-width of the tent in input samples: 1 when enlarging, 1/k when reducing.
    let r = (1.0 / k).max(1.0);
    (0..m)
        .map(|o| {
            let centre = (o as f64 + 0.5) / k - 0.5;
            let lo = (centre - r).ceil().max(0.0) as usize;
            let hi = ((centre + r).floor() as usize).min(n - 1);
            let mut ws: Vec<f64> = (lo..=hi)
                .map(|i| (1.0 - (i as f64 - centre).abs() / r).max(0.0))
                .collect();
            let sum: f64 = ws.iter().sum();
            if sum > 0.0 {
                ws.iter_mut().for_each(|v| *v /= sum);
            } else {
                // The centre lies past an edge (a tiny output): the nearest sample.
                let near = centre.round().clamp(0.0, (n - 1) as f64) as usize;
                return (near, vec![1.0]);
            }
            (lo, ws.into_iter().map(|v| v as f32).collect())
        })
        .collect()
}

/// Resamples `planes` (`w × h`, with optional weights `m`) to `tw × th`, rows then columns.
/// Each value is the weighted mean of its taps, weighed by the mask where there is one; the
/// mask itself comes back as the plain tent mean.
fn resample(
    planes: &[&[f32]],
    m: Option<&[f32]>,
    (w, h): (usize, usize),
    (tw, th): (usize, usize),
) -> (Vec<Vec<f32>>, Option<Vec<f32>>) {
    let (tx, ty) = (taps(w, tw), taps(h, th));
    // Weighted sums: the planes times the mask, then the mask itself (the denominator).
    let mut src: Vec<Vec<f32>> = match m {
        Some(m) => planes
            .iter()
            .map(|p| p.iter().zip(m).map(|(v, m)| v * m).collect())
            .collect(),
        None => planes.iter().map(|p| p.to_vec()).collect(),
    };
    if let Some(m) = m {
        src.push(m.to_vec());
    }
    let out: Vec<Vec<f32>> = src
        .par_iter()
        .map(|p| {
            // Rows: w → tw.
            let mut mid = vec![0.0f32; tw * h];
            for (y, row) in mid.chunks_mut(tw).enumerate() {
                let s = &p[y * w..(y + 1) * w];
                for (o, (lo, ws)) in row.iter_mut().zip(&tx) {
                    *o = ws.iter().zip(&s[*lo..]).map(|(a, b)| a * b).sum();
                }
            }
            // Columns: h → th.
            let mut out = vec![0.0f32; tw * th];
            for (r, (lo, ws)) in ty.iter().enumerate() {
                let row = &mut out[r * tw..(r + 1) * tw];
                for (k, wgt) in ws.iter().enumerate() {
                    let s = &mid[(lo + k) * tw..(lo + k + 1) * tw];
                    row.iter_mut().zip(s).for_each(|(o, v)| *o += wgt * v);
                }
            }
            out
        })
        .collect();
    match m {
        None => (out, None),
        Some(_) => {
            let mut out = out;
            let mass = out.pop().expect("the mask's plane");
            for p in &mut out {
                p.iter_mut().zip(&mass).for_each(|(v, m)| {
                    *v = if *m > 1e-6 { *v / m } else { 0.0 };
                });
            }
            (out, Some(mass))
        }
    }
}

/// `img` resized to `tw × th` in gradient space (module docs).
fn resize(img: &RgbnImage, tw: usize, th: usize) -> RgbnImage {
    let (w, h) = (img.width(), img.height());
    let g = GradientField::from_normals(img);
    let c = img.color();
    let planes: Vec<&[f32]> = vec![&g.p, &g.q, &c[0], &c[1], &c[2]];
    let (mut out, mask) = resample(&planes, img.mask(), (w, h), (tw, th));
    let (kx, ky) = (tw as f64 / w as f64, th as f64 / h as f64);
    let s = (kx * ky).sqrt();
    let (fp, fq) = ((s / kx) as f32, (s / ky) as f32);
    let blue = out.pop().expect("five planes");
    let green = out.pop().expect("five planes");
    let red = out.pop().expect("five planes");
    let mut q = out.pop().expect("five planes");
    let mut p = out.pop().expect("five planes");
    p.iter_mut().for_each(|v| *v *= fp);
    q.iter_mut().for_each(|v| *v *= fq);
    let g = GradientField {
        width: tw,
        height: th,
        p,
        q,
        clamped: 0,
    };
    let normal = g.to_normals();
    RgbnImage::new(tw, th, [red, green, blue], normal, mask).expect("planes of the output's size")
}

#[cfg(test)]
#[path = "transform_tests.rs"]
mod tests;
