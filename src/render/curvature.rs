//! The `curvature` view: mean curvature from the divergence of the normals, as a diverging
//! colour map (red convex, white flat, blue concave — the curl map's colours).
//!
//! `H = ½ (∂nx/∂x + ∂ny/∂y)` in 1/px with y up: at pixel (column c, row r)
//! `∂nx/∂x = (nx[r][c+1] − nx[r][c−1]) / 2` and `∂ny/∂y = (ny[r−1][c] − ny[r+1][c]) / 2` (row
//! r−1 is above). At the image border, or where a neighbour is outside the mask (coverage
//! < 0.5), the one-sided difference with the neighbour that exists is used, 0 if neither
//! exists. A sphere of radius r px bulging towards the viewer has H = +1/r; a cylinder 1/(2r).

use super::inspect::{alpha8, coverage};
use super::{map_pixels, InspectParams};
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// True when pixel `i` is inside the mask (coverage ≥ 0.5, or no mask).
#[inline]
fn inside(mask: Option<&[f32]>, i: usize) -> bool {
    mask.is_none_or(|m| m[i] >= 0.5)
}

/// Mean curvature `H` (1/px, convex positive) of every pixel, row-major.
#[must_use]
pub fn mean_curvature(img: &RgbnImage) -> Vec<f32> {
    let (w, h) = (img.width(), img.height());
    let [nx, ny, _] = img.normal();
    let mask = img.mask();
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(r, row)| {
            for (c, o) in row.iter_mut().enumerate() {
                let i = r * w + c;
                let left = c > 0 && inside(mask, i - 1);
                let right = c + 1 < w && inside(mask, i + 1);
                let dx = match (left, right) {
                    (true, true) => (nx[i + 1] - nx[i - 1]) * 0.5,
                    (false, true) => nx[i + 1] - nx[i],
                    (true, false) => nx[i] - nx[i - 1],
                    (false, false) => 0.0,
                };
                let up = r > 0 && inside(mask, i - w);
                let down = r + 1 < h && inside(mask, i + w);
                let dy = match (up, down) {
                    (true, true) => (ny[i - w] - ny[i + w]) * 0.5,
                    (true, false) => ny[i - w] - ny[i],
                    (false, true) => ny[i] - ny[i + w],
                    (false, false) => 0.0,
                };
                *o = 0.5 * (dx + dy);
            }
        });
    out
}

/// The scale of `H` shown at full colour from a parameter: `param` itself when positive, else
/// automatic: `1 / (99th percentile of |H| over covered pixels)` (nearest rank), or 1 when that
/// percentile is 0. `rgbn render` writes it to the PNG (`rgbn:curvature_scale`) and
/// `rgbn publish` hands it to the viewer, so both show the same colours.
#[must_use]
pub fn curvature_scale(img: &RgbnImage, param: f32) -> f32 {
    scale_of(&mean_curvature(img), img.mask(), param)
}

/// [`curvature_scale`] from an already computed `H`.
pub(super) fn scale_of(hv: &[f32], mask: Option<&[f32]>, param: f32) -> f32 {
    if param > 0.0 && param.is_finite() {
        return param;
    }
    let mut abs: Vec<f32> = hv
        .iter()
        .enumerate()
        .filter(|&(i, v)| inside(mask, i) && v.is_finite())
        .map(|(_, v)| v.abs())
        .collect();
    if abs.is_empty() {
        return 1.0;
    }
    let k = ((0.99 * abs.len() as f64).ceil() as usize).clamp(1, abs.len()) - 1;
    let (_, p99, _) = abs.select_nth_unstable_by(k, f32::total_cmp);
    if *p99 > 0.0 {
        1.0 / *p99
    } else {
        1.0
    }
}

/// [`curvature_scale`]'s automatic scale of an image seen in horizontal strips (exactly the
/// same number): the 99th percentile of `|H|` is among the largest 1 % of values, so only the
/// largest `pixels / 100 + 2` are kept (pruned when twice that many are held).
pub struct ScaleOfStrips {
    keep: usize,
    top: Vec<f32>,
    count: usize,
}

impl ScaleOfStrips {
    /// For an image of `pixels` pixels.
    #[must_use]
    pub fn new(pixels: usize) -> Self {
        Self {
            keep: pixels / 100 + 2,
            top: Vec::new(),
            count: 0,
        }
    }

    /// Adds the `H` of some rows (their values from [`mean_curvature`] over a window with one
    /// row of context each way) with their coverage.
    pub fn add(&mut self, hv: &[f32], mask: Option<&[f32]>) {
        for (i, v) in hv.iter().enumerate() {
            if inside(mask, i) && v.is_finite() {
                self.count += 1;
                self.top.push(v.abs());
            }
        }
        if self.top.len() > 2 * self.keep {
            self.prune(self.keep);
        }
    }

    /// Keeps the `m` largest values.
    fn prune(&mut self, m: usize) {
        if self.top.len() > m {
            let cut = self.top.len() - m;
            self.top.select_nth_unstable_by(cut, f32::total_cmp);
            self.top.drain(..cut);
        }
    }

    /// The scale (as [`curvature_scale`] with an automatic parameter).
    #[must_use]
    pub fn scale(mut self) -> f32 {
        let n = self.count;
        if n == 0 {
            return 1.0;
        }
        let k = ((0.99 * n as f64).ceil() as usize).clamp(1, n) - 1;
        // The value at ascending rank k is the (n − k)-th largest.
        let m = n - k;
        self.prune(m);
        debug_assert_eq!(self.top.len(), m);
        let p99 = self
            .top
            .iter()
            .copied()
            .min_by(f32::total_cmp)
            .unwrap_or(0.0);
        if p99 > 0.0 {
            1.0 / p99
        } else {
            1.0
        }
    }
}

/// The diverging colour of `t ∈ [−1, 1]`: (255, f, f) for t ≥ 0, (f, f, 255) below, with
/// `f = round((1 − |t|)·255)`.
#[inline]
#[must_use]
pub fn diverging(t: f32) -> [u8; 3] {
    let t = if t.is_finite() {
        t.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let f = ((1.0 - t.abs()) * 255.0).round() as u8;
    if t >= 0.0 {
        [255, f, f]
    } else {
        [f, f, 255]
    }
}

/// The curvature view into `out`; returns the scale used (see [`curvature_scale`]).
pub(super) fn curvature_into(img: &RgbnImage, p: &InspectParams, out: &mut [u8]) -> f32 {
    let hv = mean_curvature(img);
    let s = scale_of(&hv, img.mask(), p.curvature_scale as f32);
    map_pixels(out, |i| {
        let [r, g, b] = diverging(hv[i] * s);
        [r, g, b, alpha8(coverage(img, i))]
    });
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_of_strips_is_the_scale_of_the_whole() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for n in [1usize, 7, 100, 1234, 20_000] {
            let hv: Vec<f32> = (0..n)
                .map(|i| {
                    if i % 97 == 5 {
                        f32::NAN
                    } else {
                        rnd() * 2.0 - 1.0
                    }
                })
                .collect();
            let mask: Vec<f32> = (0..n).map(|_| rnd()).collect();
            for m in [None, Some(&mask[..])] {
                let whole = scale_of(&hv, m, 0.0);
                for strip in [1, 3, 64, 5000] {
                    let mut acc = ScaleOfStrips::new(n);
                    let mut y = 0;
                    while y < n {
                        let e = (y + strip).min(n);
                        acc.add(&hv[y..e], m.map(|m| &m[y..e]));
                        y = e;
                    }
                    assert_eq!(
                        acc.scale().to_bits(),
                        whole.to_bits(),
                        "n {n} strip {strip}"
                    );
                }
            }
        }
        assert_eq!(ScaleOfStrips::new(10).scale(), 1.0);
    }
}
