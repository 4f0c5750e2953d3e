//! Non-photorealistic inspection views after Toler-Franklin et al. 2007 ("Illustration of
//! complex real-world objects using images with normals"): exaggerated shading, radiance
//! scaling, toon shading and line drawings. All produce sRGB RGBA8 with alpha = mask coverage.

use super::curvature::{mean_curvature, scale_of};
use super::inspect::{alpha8, coverage, srgb_px};
use super::{map_pixels, normalize3, relight_scaled_into, InspectParams, Shading};
use crate::error::RgbnError;
use crate::raster::convolve::{gaussian, BorderMode};
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// Unit light directions and colours of a shading.
fn lights(shading: &Shading) -> Vec<([f32; 3], [f32; 3])> {
    shading
        .lights
        .iter()
        .map(|l| (normalize3(l.direction), l.color))
        .collect()
}

#[inline]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The normals smoothed with a Gaussian of `sigma` px and renormalised (planes x, y, z).
fn smoothed_normals(img: &RgbnImage, sigma: f32) -> [Vec<f32>; 3] {
    let (w, h) = (img.width(), img.height());
    let mut planes = img.normal().clone();
    planes
        .par_iter_mut()
        .for_each(|p| gaussian(p, w, h, sigma, BorderMode::Mirror));
    let [x, y, z] = &mut planes;
    x.par_iter_mut()
        .zip(y.par_iter_mut())
        .zip(z.par_iter_mut())
        .for_each(|((x, y), z)| {
            let l = (*x * *x + *y * *y + *z * *z).sqrt();
            if l > 1e-12 {
                (*x, *y, *z) = (*x / l, *y / l, *z / l);
            } else {
                (*x, *y, *z) = (0.0, 0.0, 1.0);
            }
        });
    planes
}

/// Mean curvature of the normals smoothed with a Gaussian of `sigma` px (none when 0).
fn smoothed_curvature(img: &RgbnImage, sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 {
        return mean_curvature(img);
    }
    let mut s = img.clone();
    *s.normal_mut() = smoothed_normals(img, sigma as f32);
    mean_curvature(&s)
}

#[inline]
fn at(p: &[Vec<f32>; 3], i: usize) -> [f32; 3] {
    [p[0][i], p[1][i], p[2][i]]
}

/// Exaggerated shading (Rusinkiewicz, Burns & DeCarlo, "Exaggerated shading for depicting
/// shape and detail", SIGGRAPH 2006), on the normals instead of a mesh.
///
/// Scales `i = 0 … K` (`K = exag_scales`): `n₀` is the image's normals, `nᵢ` (i ≥ 1) the
/// normals smoothed with σᵢ = `exag_sigma`·2^(i−1). Detail at scale i is lit relative to the
/// next coarser normal: the light `l` projected into the tangent plane of `nᵢ₊₁`,
/// `lᵢ₊₁ = normalize(l − (nᵢ₊₁·l) nᵢ₊₁)` (zero when `l ∥ nᵢ₊₁`), gives
/// `cᵢ = clamp(a · nᵢ·lᵢ₊₁, −1, 1)`; the coarsest scale is lit directly,
/// `c_K = clamp(a · n_K·l, −1, 1)`. Then `E = ½ + ½ Σ kᵢ cᵢ` with weights `kᵢ ∝ σᵢ^(−detail)`
/// (σ₀ = `exag_sigma`/2) summing to 1, `a = exag_clamp`, `detail = exag_detail`. The picture is
/// grey: `2^ev · Σ_lights colour · E` (ambient and specular are not used), alpha = coverage.
/// A plane gives a constant.
pub(super) fn exaggerated_into(
    img: &RgbnImage,
    shading: &Shading,
    p: &InspectParams,
    out: &mut [u8],
) {
    let n = img.len();
    let k_scales = p.exag_scales.max(1) as usize;
    let sigma = |i: usize| p.exag_sigma as f32 * 2f32.powi(i as i32 - 1);
    let mut weights: Vec<f32> = (0..=k_scales)
        .map(|i| sigma(i).powf(-(p.exag_detail as f32)))
        .collect();
    let total: f32 = weights.iter().sum();
    weights.iter_mut().for_each(|k| *k /= total);
    let a = p.exag_clamp as f32;
    let ls = lights(shading);
    // Per light: Σ kᵢ cᵢ, accumulated scale by scale (two normal sets alive at a time).
    let mut acc = vec![vec![0.0f32; n]; ls.len()];
    let mut fine = img.normal().clone();
    for (i, &ki) in weights.iter().enumerate().take(k_scales) {
        let coarse = smoothed_normals(img, sigma(i + 1));
        for (acc, (l, _)) in acc.iter_mut().zip(&ls) {
            acc.par_iter_mut().enumerate().for_each(|(j, a_j)| {
                let nc = at(&coarse, j);
                let d = dot(nc, *l);
                let t = [l[0] - d * nc[0], l[1] - d * nc[1], l[2] - d * nc[2]];
                let tl = dot(t, t).sqrt();
                if tl > 1e-6 {
                    let c = (a * dot(at(&fine, j), t) / tl).clamp(-1.0, 1.0);
                    *a_j += ki * c;
                }
            });
        }
        fine = coarse;
    }
    let kb = weights[k_scales];
    for (acc, (l, _)) in acc.iter_mut().zip(&ls) {
        acc.par_iter_mut().enumerate().for_each(|(j, a_j)| {
            *a_j += kb * (a * dot(at(&fine, j), *l)).clamp(-1.0, 1.0);
        });
    }
    let gain = 2f32.powf(shading.exposure_ev);
    map_pixels(out, |j| {
        let mut rgb = [0.0f32; 3];
        for (acc, (_, color)) in acc.iter().zip(&ls) {
            let e = 0.5 + 0.5 * acc[j];
            for c in 0..3 {
                rgb[c] += color[c] * e;
            }
        }
        srgb_px(img, j, rgb.map(|v| gain * v))
    });
}

/// Radiance scaling (Vergne, Pacanowski, Barla, Granier & Schlick, "Radiance scaling for
/// versatile surface enhancement", I3D 2010): the relit radiance (exactly [`super::relight`])
/// multiplied, before the sRGB curve, by a function of the mean curvature that brightens
/// convex and darkens concave places: `× 2^(α · tanh(H · s))`, `α = radiance_alpha`,
/// `s = radiance_scale` (0 = automatic, as the curvature view), H taken from the normals
/// smoothed with σ = `radiance_sigma`. α = 0 is the relit picture. (The paper's scaling
/// function also depends on the light and material; this is its curvature-only core.)
pub(super) fn radiance_scaling_into(
    img: &RgbnImage,
    shading: &Shading,
    p: &InspectParams,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    let hv = smoothed_curvature(img, p.radiance_sigma);
    let s = scale_of(&hv, img.mask(), p.radiance_scale as f32);
    let alpha = p.radiance_alpha as f32;
    let scale: Vec<f32> = hv
        .par_iter()
        .map(|&h| (alpha * (h * s).tanh()).exp2())
        .collect();
    relight_scaled_into(img, shading, Some(&scale), out)
}

/// Toon shading: the diffuse light `d = Σ cᵢ max(0, n·lᵢ)` (per colour channel) quantised into
/// `L = toon_levels` bands, `q = min(⌊d·L⌋, L−1) / (L−1)` (L = 1: 1 where lit, else 0), shown as
/// `2^ev · albedo · (ambient + q)`; black outlines where `n_z < toon_silhouette` (near the
/// silhouette) or `|H| > toon_crease` (strong curvature, from the normals smoothed with
/// σ = `toon_sigma`; 0 = none). Alpha = coverage.
pub(super) fn toon_into(img: &RgbnImage, shading: &Shading, p: &InspectParams, out: &mut [u8]) {
    let ls = lights(shading);
    let levels = p.toon_levels.max(1) as f32;
    let quant = |d: f32| {
        if levels <= 1.0 {
            if d > 0.0 {
                1.0
            } else {
                0.0
            }
        } else {
            (d * levels).floor().clamp(0.0, levels - 1.0) / (levels - 1.0)
        }
    };
    let crease = p.toon_crease as f32;
    let hv = (crease > 0.0).then(|| smoothed_curvature(img, p.toon_sigma));
    let sil = p.toon_silhouette as f32;
    let gain = 2f32.powf(shading.exposure_ev);
    let [cr, cg, cb] = img.color();
    let [nx, ny, nz] = img.normal();
    map_pixels(out, |i| {
        let n = [nx[i], ny[i], nz[i]];
        let edge = n[2] < sil || hv.as_ref().is_some_and(|h| h[i].abs() > crease);
        if edge {
            return [0, 0, 0, alpha8(coverage(img, i))];
        }
        let mut d = [0.0f32; 3];
        for (l, c) in &ls {
            let ndl = dot(n, *l).max(0.0);
            for j in 0..3 {
                d[j] += c[j] * ndl;
            }
        }
        let alb = [cr[i], cg[i], cb[i]];
        let rgb = [0, 1, 2].map(|j| gain * alb[j] * (shading.ambient + quant(d[j])));
        srgb_px(img, i, rgb)
    });
}

/// Line drawing (after Toler-Franklin et al. 2007 and DeCarlo et al.'s ridges/valleys and
/// suggestive contours): black on white. H is taken from the normals smoothed with
/// σ = `lines_sigma`. Ridge and valley lines where `|H| > lines_threshold` (1/px)
/// and `|H|` is a local maximum across the line (not below either neighbour and above one,
/// horizontally or vertically), and contour-like lines where `n_z < lines_contour` (the
/// surface turns away from the viewer). Alpha = coverage. A plane has no lines.
pub(super) fn lines_into(img: &RgbnImage, p: &InspectParams, out: &mut [u8]) {
    let (w, h) = (img.width(), img.height());
    let hv = smoothed_curvature(img, p.lines_sigma);
    let thr = p.lines_threshold as f32;
    let contour = p.lines_contour as f32;
    let nz = &img.normal()[2];
    let ridge = |i: usize| {
        let v = hv[i].abs();
        if v <= thr {
            return false;
        }
        let (r, c) = (i / w, i % w);
        let across = |a: Option<usize>, b: Option<usize>| {
            let av = a.map_or(0.0, |a| hv[a].abs());
            let bv = b.map_or(0.0, |b| hv[b].abs());
            v >= av && v >= bv && (v > av || v > bv)
        };
        across((c > 0).then(|| i - 1), (c + 1 < w).then(|| i + 1))
            || across((r > 0).then(|| i - w), (r + 1 < h).then(|| i + w))
    };
    map_pixels(out, |i| {
        let a = alpha8(coverage(img, i));
        if nz[i] < contour || ridge(i) {
            [0, 0, 0, a]
        } else {
            [255, 255, 255, a]
        }
    });
}

#[cfg(test)]
#[path = "npr_tests.rs"]
mod tests;
