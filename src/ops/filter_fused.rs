//! The kernels that combine the gradient with Gaussian smoothings of it — sharpen
//! `g + k·(g − G∗g)`, high-pass `g − G∗g`, edge enhance `g + k·(G_f∗g − G_c∗g)` and the
//! difference of Gaussians `G_f∗g − G_c∗g` — without the unfused path's seven sweeps and six
//! gradient planes: each smoothing is the fused smoother ([`smooth_normals`]: normals in,
//! normals out, two sweeps), and one pointwise pass reads the input normal and the smoothed
//! normals of a pixel, takes their slopes and writes the combination's normal over the first
//! smoothing's planes (no further allocation).
//!
//! The smoothed normal `s = (−p, −q, 1)/‖·‖` gives its slope back as `(−s_x/s_z, −s_y/s_z)`
//! (no clamp: `s_z > 0` always), equal to the filtered slope up to rounding; the input's slope
//! is [`gradient_of_normal`] with its `n_z` clamp, as in the unfused path. The result equals
//! [`super::filter_normals_general`]'s to rounding (`tests::fused_combinations_equal_the_unfused_path`).

use super::Kernel;
use crate::raster::convolve::{self, BorderMode, Fir, IIR_MIN_SIGMA};
use crate::raster::gradient::{gradient_of_normal, normal_of_gradient, CurlSums};
use crate::raster::smooth::{smooth_normals, SmoothedNormals};
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// The normals of `img`'s gradients smoothed by a Gaussian of `sigma` px (the sampled FIR
/// below [`IIR_MIN_SIGMA`], the recursive filter from there, as the Gaussian kernel).
pub(super) fn gaussian_normals(img: &RgbnImage, sigma: f32, border: BorderMode) -> SmoothedNormals {
    let (w, h) = (img.width(), img.height());
    let [nx, ny, nz] = img.normal();
    let n: [&[f32]; 3] = [nx, ny, nz];
    if sigma < IIR_MIN_SIGMA {
        smooth_normals(n, img.mask(), w, h, &Fir::gaussian(sigma), border)
    } else {
        smooth_normals(n, img.mask(), w, h, &convolve::Deriche::new(sigma), border)
    }
}

/// The fused form of `kernel` on `img`: the combined normals, the pixels whose `n_z` was
/// clamped, and the curl sums of the input's field. `None` for the kernels without one.
pub(super) fn combination(
    img: &RgbnImage,
    kernel: &Kernel,
    border: BorderMode,
) -> Option<([Vec<f32>; 3], usize, CurlSums)> {
    let out = match *kernel {
        Kernel::Sharpen { sigma_px, amount } => {
            let s = gaussian_normals(img, sigma_px, border);
            combine(img, s, None, move |g, s, _| g + amount * (g - s))
        }
        Kernel::HighPass { sigma_px } => {
            let s = gaussian_normals(img, sigma_px, border);
            combine(img, s, None, |g, s, _| g - s)
        }
        Kernel::EdgeEnhance {
            sigma_fine_px,
            sigma_coarse_px,
            amount,
        } => {
            let f = gaussian_normals(img, sigma_fine_px, border);
            let c = gaussian_normals(img, sigma_coarse_px, border);
            combine(img, f, Some(c), move |g, f, c| g + amount * (f - c))
        }
        Kernel::DoG {
            sigma_fine_px,
            sigma_coarse_px,
        } => {
            let f = gaussian_normals(img, sigma_fine_px, border);
            let c = gaussian_normals(img, sigma_coarse_px, border);
            combine(img, f, Some(c), |_, f, c| f - c)
        }
        _ => return None,
    };
    Some(out)
}

/// Writes, over `first`'s planes, the normal of `f(g, s₁, s₂)` per component, where `g` is the
/// input's slope and `s₁`, `s₂` the slopes of `first` and `second` (`s₂ = 0` without one).
fn combine<F: Fn(f32, f32, f32) -> f32 + Sync>(
    img: &RgbnImage,
    first: SmoothedNormals,
    second: Option<SmoothedNormals>,
    f: F,
) -> ([Vec<f32>; 3], usize, CurlSums) {
    let w = img.width().max(1);
    let [nx, ny, nz] = img.normal();
    let [mut ox, mut oy, mut oz] = first.normal;
    let none: [&[f32]; 3] = [&[], &[], &[]];
    let two = second.as_ref().map_or(none, |s| {
        [s.normal[0].as_slice(), &s.normal[1], &s.normal[2]]
    });
    let slope = |n: [f32; 3]| [-n[0] / n[2], -n[1] / n[2]];
    ox.par_chunks_mut(w)
        .zip(oy.par_chunks_mut(w))
        .zip(oz.par_chunks_mut(w))
        .enumerate()
        .for_each(|(row, ((ox, oy), oz))| {
            let o = row * w;
            for x in 0..ox.len() {
                let i = o + x;
                let [gp, gq] = gradient_of_normal([nx[i], ny[i], nz[i]]);
                let [ap, aq] = slope([ox[x], oy[x], oz[x]]);
                let [bp, bq] = if two[0].is_empty() {
                    [0.0, 0.0]
                } else {
                    slope([two[0][i], two[1][i], two[2][i]])
                };
                let n = normal_of_gradient(f(gp, ap, bp), f(gq, aq, bq));
                ox[x] = n[0];
                oy[x] = n[1];
                oz[x] = n[2];
            }
        });
    ([ox, oy, oz], first.clamped, first.curl_before)
}
