//! The estimate of the shading exponent `k` ([`super`]'s module docs, "Shading exponent"): a
//! search over `1/k` on a regular sample of the masked pixels.

use super::{
    linearise, observe, rank_usable, trimmed_from_ranked, PhotoStack, PhotometricParams,
    PhotometricReport, Scratch, Shading, EXPONENT_SEARCH,
};
use crate::error::RgbnError;
use rayon::prelude::*;

/// Grid step of the search over `1/k`.
const EXPONENT_STEP: f64 = 0.025;

/// Pixels the exponent search solves: a regular sample of the pixels inside the mask.
const EXPONENT_SAMPLES: usize = 4096;

/// Sampled pixels with more than three chosen observations needed before the estimate is
/// trusted (with exactly three every exponent fits exactly); fewer keep Lambert's `k = 1`.
const EXPONENT_MIN_PIXELS: usize = 64;

/// Estimates the shading exponent `k` (module docs, "Shading exponent"): the `k` whose
/// linearised observations `g^(1/k)` the Lambertian model fits best — over a sample of
/// pixels, the smallest fraction of unexplained variance `Σ r² / Σ (g − ḡ)²` of the trimmed
/// solve on the observations it chose (sums pooled over the pixels). A grid over `1/k` in
/// steps of [`EXPONENT_STEP`] across [`EXPONENT_SEARCH`](super::EXPONENT_SEARCH), then a golden-section search
/// around its best point; ties go to the `k` nearest 1.
pub(super) fn estimate_exponent(
    stack: &PhotoStack,
    mask: Option<&[f32]>,
    dirs: &[[f64; 3]],
    inv_e: &[[f32; 3]],
    params: &PhotometricParams,
) -> Result<f32, RgbnError> {
    let n = stack.width * stack.height;
    let inside = |i: &usize| mask.is_none_or(|m| m[*i] >= 0.5);
    let count = (0..n).filter(inside).count();
    let step = count.div_ceil(EXPONENT_SAMPLES).max(1);
    let sample: Vec<usize> = (0..n).filter(inside).step_by(step).collect();
    // The sampled pixels' observations gathered once: every evaluation then reads a few
    // hundred KB in order instead of 3m scattered planes (which cost more than the solves).
    let photos: Vec<[Vec<f32>; 3]> = stack
        .photos
        .iter()
        .map(|p| std::array::from_fn(|c| sample.iter().map(|&i| p[c][i]).collect()))
        .collect();
    let cancel = crate::cancel::Cancel::current();
    let m = dirs.len();
    // What does not depend on `k`, once per sampled pixel (None: dark): the normalised
    // observations, the usable lights and their brightness order — `g^(1/k)` ranks as `g`
    // does, so the trimmed solve's sort is the same at every `k`.
    let lambert = Shading::new(1.0);
    let prepared: Vec<Option<Prepared>> = (0..sample.len())
        .into_par_iter()
        .map_init(
            || Scratch::new(m),
            |s, i| {
                let mut rep = PhotometricReport::default();
                if !observe(s, &photos, i, inv_e, params, lambert, &mut rep) {
                    return None;
                }
                rank_usable(s);
                Some(Prepared {
                    obs: s.obs.clone(),
                    usable: s.usable.clone(),
                    order: s.sel.clone(),
                })
            },
        )
        .collect();
    // (Σ r², Σ (g − ḡ)², pixels with more than three chosen observations).
    let sums = |inv_k: f64| -> (f64, f64, usize) {
        let shading = Shading::new((1.0 / inv_k) as f32);
        prepared
            .par_chunks(256)
            .map_init(
                || Scratch::new(m),
                |s, chunk| {
                    let mut acc = (0.0, 0.0, 0);
                    for p in chunk.iter().flatten() {
                        s.obs.copy_from_slice(&p.obs);
                        linearise(s, shading);
                        s.usable.clone_from(&p.usable);
                        s.sel.clone_from(&p.order);
                        s.chosen.clear();
                        let Some(b) = trimmed_from_ranked(s, dirs, params) else {
                            continue;
                        };
                        if s.chosen.len() <= 3 {
                            continue;
                        }
                        let mean = s
                            .chosen
                            .iter()
                            .map(|&j| f64::from(s.obs[j][3]))
                            .sum::<f64>()
                            / s.chosen.len() as f64;
                        let (mut r2, mut v2) = (0.0, 0.0);
                        for &j in &s.chosen {
                            let g = f64::from(s.obs[j][3]);
                            let d = dirs[j];
                            let r = g - (b[0] * d[0] + b[1] * d[1] + b[2] * d[2]);
                            r2 += r * r;
                            v2 += (g - mean) * (g - mean);
                        }
                        if r2.is_finite() && v2.is_finite() {
                            acc.0 += r2;
                            acc.1 += v2;
                            acc.2 += 1;
                        }
                    }
                    acc
                },
            )
            .reduce(|| (0.0, 0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
    };
    // The fraction of the shading's variance the model leaves unexplained (pooled).
    let unexplained = |(r2, v2, _): (f64, f64, usize)| -> f64 {
        if v2 > 0.0 {
            r2 / v2
        } else {
            f64::INFINITY
        }
    };
    let cost = |inv_k: f64| unexplained(sums(inv_k));
    // Lambert's point, once: its cost, and how many sampled pixels can tell exponents apart.
    let at_one = sums(1.0);
    let (pixels, c1) = (at_one.2, unexplained(at_one));
    cancel.check()?;
    if pixels < EXPONENT_MIN_PIXELS {
        return Ok(1.0);
    }
    let (lo, hi) = (
        1.0 / f64::from(EXPONENT_SEARCH.1),
        1.0 / f64::from(EXPONENT_SEARCH.0),
    );
    // Grid, ties to the point nearest 1/k = 1.
    let mut best = (c1, 1.0f64);
    let steps = ((hi - lo) / EXPONENT_STEP).round() as usize;
    for t in 0..=steps {
        let x = lo + (hi - lo) * t as f64 / steps as f64;
        let c = cost(x);
        cancel.check()?;
        if c < best.0 || (c == best.0 && (x - 1.0).abs() < (best.1 - 1.0).abs()) {
            best = (c, x);
        }
    }
    // An optimum on the band's edge (the fit would go further) means the photos break the
    // model some other way: keep Lambert.
    if best.1 == 1.0 || best.1 - lo < 1e-9 || hi - best.1 < 1e-9 {
        return Ok(1.0);
    }
    // Golden section on the bracket around the grid's best point.
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (
        (best.1 - EXPONENT_STEP).max(lo),
        (best.1 + EXPONENT_STEP).min(hi),
    );
    let (mut x1, mut x2) = (b - phi * (b - a), a + phi * (b - a));
    let (mut f1, mut f2) = (cost(x1), cost(x2));
    while b - a > 2e-3 {
        cancel.check()?;
        if f1 <= f2 {
            (b, x2, f2) = (x2, x1, f1);
            x1 = b - phi * (b - a);
            f1 = cost(x1);
        } else {
            (a, x1, f1) = (x1, x2, f2);
            x2 = a + phi * (b - a);
            f2 = cost(x2);
        }
    }
    let x = if f1.min(f2) <= best.0 {
        if f1 <= f2 {
            x1
        } else {
            x2
        }
    } else {
        best.1
    };
    Ok(((1.0 / x) as f32).clamp(EXPONENT_SEARCH.0, EXPONENT_SEARCH.1))
}

/// A sampled pixel of the exponent search, as [`observe`](super::observe) (at `k = 1`) and [`rank_usable`](super::rank_usable)
/// leave it: what every evaluation of the search starts from.
struct Prepared {
    obs: Vec<[f32; 4]>,
    usable: Vec<usize>,
    order: Vec<usize>,
}
