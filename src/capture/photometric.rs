//! Photometric stereo: photos from one viewpoint under `m ≥ 3` known directional lights →
//! albedo colour + unit normals + mask (inputs: [`super::inputs`]; lights from a chrome sphere:
//! [`super::chrome`]).
//!
//! # Model
//!
//! Lambertian image formation with distant lights: for photo `j`, colour channel `c`,
//! `I_cj = ρ_c · e_cj · max(0, n · l_j)`, with unit light direction `l_j` (frame: `x` right,
//! `y` up, `z` towards the camera — the normal frame of `docs/ARCHITECTURE.md`), per-channel light
//! intensity `e_cj` (1 if not given) and albedo `ρ_c`. Photos must be **linear**:
//! [`Transfer::Srgb`](super::inputs::Transfer::Srgb) undoes the sRGB curve of 8/16-bit files
//! on load.
//!
//! # Least squares (Woodham 1980)
//!
//! With intensity-normalised grey observations `g_j = mean_c(I_cj / e_cj)` and the `m × 3`
//! light matrix `L`, `b = (LᵀL)⁻¹ Lᵀ g` (the pseudo-inverse is computed once), `n = b/‖b‖`.
//! Observations at or above [`PhotometricParams::saturation_level`] (raw, any channel) are
//! excluded; such pixels are solved with their own `3 × 3` normal equations. Then, with `n`
//! fixed, each channel's albedo is the least-squares fit
//! `ρ_c = Σ_j (I_cj/e_cj) s_j / Σ_j s_j²`, `s_j = max(0, n · l_j)`, over the observations used.
//!
//! # Robust: trimmed least squares ([`PsMethod::Trimmed`])
//!
//! Lambertian least squares is biased by *attached shadows* (observed ≈ 0 where the model
//! predicts `n·l < 0`, i.e. the `max(0, ·)` is active) and by *specular highlights* (far
//! brighter than the model). Both are extreme in the ranking of a pixel's observations:
//! shadows are the darkest, highlights the brightest. Per pixel:
//!
//! 1. rank the usable observations by `g_j`; solve least squares on the middle part, without
//!    the darkest [`dark_fraction`](PhotometricParams::dark_fraction) and the brightest
//!    [`bright_fraction`](PhotometricParams::bright_fraction) (if that part is
//!    ill-conditioned, all usable observations are used and the pixel is done);
//! 2. re-select: all observations except the bright trim whose light is in front of that
//!    estimate, `n₀ · l_j ≥ min_shading` (the model itself says the others are shadowed), and
//!    solve again (keeping step 1 if this set is ill-conditioned); repeat with each new
//!    estimate until the set stops changing, at most four times.
//!
//! So the dark trim only protects the first estimate; the final set is "not among the
//! brightest, and lit according to the model". Measured on DiLiGenT "ball" with 13 of its
//! lights (mean angular error inside the mask; test `diligent_ball_angular_error`):
//!
//! | estimator | error |
//! |---|---|
//! | least squares (Woodham) | 4.16° |
//! | drop brightest 10 % only | 3.80° |
//! | **default**: dark 0.25, bright 0.10, min_shading 0.05 | **2.29°** |
//! | dark 0.40 / bright 0.20 / min_shading 0.20 variants | 2.22–2.27° |
//! | dark 0.15 | 2.41° |
//! | the benchmark's own 96-light least squares (`Normal_L2`) | 4.02° (4.10° published) |
//!
//! The shading re-selection (attached shadows) is worth ~1.5°, the bright trim ~0.4°; the
//! result is flat around the defaults, so they are not tuned to this one object.
//! The per-pixel cost is a sort of `m` values and two `3 × 3` solves.
//!
//! # Shading exponent
//!
//! Real surfaces are rarely exactly Lambertian. rgbn fits Minnaert's generalisation
//! `I = ρ (n·l)^k (n·v)^(k−1)` (Minnaert 1941; `k = 1` is Lambert): raising the intensity-
//! normalised grey observations to `1/k` makes them linear in `n · l` again (the view factor
//! is constant per pixel and goes into the albedo), so every estimator above runs unchanged
//! on `g^(1/k)`; the albedo fit uses the shading `max(0, n·l)^k`.
//!
//! `k` is one number for the whole capture. By default ([`PhotometricParams::exponent`]
//! `None`) it is estimated from the photos themselves: the `k` whose linearised observations
//! the Lambertian model explains best, measured on a regular sample of 4096 masked pixels as
//! the fraction of the shading's variance the trimmed solve leaves unexplained,
//! `Σ r² / Σ (g − ḡ)²` over the observations it chose, sums pooled over the pixels (a grid
//! over `1/k`, then a golden-section search). The variance, not `Σ g²`, is the yardstick
//! because a small `1/k` flattens every pixel's observations towards a constant, which a
//! ring of lights fits exactly: normalised by `Σ g²` the search drifts there (on the UW
//! grey sphere it chose `k = 1.41` and doubled the error against the sphere's own normals).
//! The search stays in [`EXPONENT_SEARCH`], `[0.75, 4/3]`, so a scene the model does not
//! describe (cast shadows, interreflections, lights calibrated badly) cannot tilt every
//! normal by much; values outside it can be given by hand. Pure Lambertian data give
//! `k = 1`; a capture whose every pixel has only three usable observations cannot tell and
//! keeps `k = 1`. This is the radiometric self-calibration idea of Shi et al. (CVPR 2010)
//! reduced to one parameter. A wrong `k` biases the polar angle of every normal: on the
//! DiLiGenT ball (13 photos) Lambert leaves the normals about 2° too steep everywhere; the
//! estimate, `k ≈ 1.07`, removes most of that bias (docs/capture.md has the table).
//!
//! # Failures are counted, never NaN
//!
//! A pixel whose brightest grey observation is below [`dark_level`](PhotometricParams::dark_level),
//! or with fewer than 3 usable observations, or whose solution is not finite, gets normal
//! `(0, 0, 1)`, albedo 0 and mask 0, and is counted in [`PhotometricReport`].
//!
//! # References
//!
//! - M. Minnaert, "The reciprocity principle in lunar photometry", Astrophysical Journal 93,
//!   1941.
//! - B. Shi, Y. Matsushita, Y. Wei, C. Xu, P. Tan, "Self-calibrating photometric stereo",
//!   CVPR 2010.
//! - R. J. Woodham, "Photometric method for determining surface orientation from multiple
//!   images", Optical Engineering 19(1), 1980.
//! - B. Shi et al., "A Benchmark Dataset and Evaluation for Non-Lambertian and Uncalibrated
//!   Photometric Stereo" (DiLiGenT), CVPR 2016 / TPAMI 2019.
//! - Y. Quéau, T. Wu, F. Lauze, J.-D. Durou, D. Cremers, "A non-convex variational approach to
//!   photometric stereo under inaccurate lighting", CVPR 2017 (robust estimators for shadows and
//!   highlights).

use super::inputs::{Lights, PhotoStack};
use super::linalg::{condition, gram, solve3, MIN_LIGHT_CONDITION};
use super::robust::{is_clean, l1_irls, sbl, RobustParams};
use crate::error::RgbnError;
use crate::raster::fastmath::{exp2_fast, log2_fast};
use crate::raster::{buf, check_size, RgbnImage};
use rayon::prelude::*;
use std::path::PathBuf;

#[path = "photometric_exponent.rs"]
mod exponent;
use exponent::estimate_exponent;

crate::choice_enum! {
    /// The photometric-stereo estimator (module docs; `docs/capture.md` says which to use when).
    #[derive(serde::Serialize, serde::Deserialize)]
    pub enum PsMethod {
        /// Trimmed least squares: drop the darkest and brightest fractions per pixel, then the observations shadowed by the estimate, and re-solve.
        Trimmed = "trimmed",
        /// Woodham's least squares on all unsaturated observations.
        LeastSquares = "ls",
        /// L1 regression by iteratively reweighted least squares, started from least squares (robust to sparse shadows and highlights).
        L1 = "l1",
        /// Sparse Bayesian learning (Ikehata et al. 2012): per-observation error variances learnt by evidence maximisation; outliers weighted out.
        Sbl = "sbl",
    }
}

/// Parameters of [`photometric_stereo`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhotometricParams {
    pub method: PsMethod,
    /// Trimmed: fraction of each pixel's observations dropped from the dark end, in [0, 0.8].
    pub dark_fraction: f32,
    /// Trimmed: fraction dropped from the bright end, in [0, 0.8]; with `dark_fraction` < 1.
    pub bright_fraction: f32,
    /// Trimmed: after the first solve, observations with `n · l` below this are dropped as
    /// shadowed, in [−1, 1).
    pub min_shading: f32,
    /// Raw values (any channel, before intensity division) at or above this are saturated and
    /// excluded, in (0, ∞); 1.0 excludes only exactly clipped 1.0 samples.
    pub saturation_level: f32,
    /// A pixel whose brightest grey observation (intensity-normalised) is below this is dark:
    /// no normal is estimated, ≥ 0.
    pub dark_level: f32,
    /// L1 and SBL: observations darker than this fraction of the pixel's brightest usable one
    /// are shadows and left out before the regression, in [0, 1).
    pub shadow_level: f32,
    /// L1 and SBL: after the regression, observations with `n · l` below this are dropped as
    /// attached shadows and the regression runs again from the estimate, in [−1, 1); −1 skips.
    pub robust_min_shading: f32,
    /// L1 and SBL iteration settings.
    pub robust: RobustParams,
    /// The shading exponent `k` of `I ∝ ρ (n·l)^k` (module docs, "Shading exponent"), in
    /// [0.5, 2]; `None` (the default) estimates it from the photos, `Some(1.0)` is Lambert.
    #[serde(default)]
    pub exponent: Option<f32>,
}

impl Default for PhotometricParams {
    fn default() -> Self {
        Self {
            method: PsMethod::Trimmed,
            dark_fraction: 0.25,
            bright_fraction: 0.1,
            min_shading: 0.05,
            saturation_level: 0.995,
            dark_level: 1e-3,
            shadow_level: 0.05,
            robust_min_shading: 0.3,
            robust: RobustParams::default(),
            exponent: None,
        }
    }
}

impl PhotometricParams {
    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<(), RgbnError> {
        let frac = |name: &str, v: f32| {
            if (0.0..=0.8).contains(&v) {
                Ok(())
            } else {
                Err(RgbnError::param(
                    name,
                    format!("must be in [0, 0.8], got {v}"),
                ))
            }
        };
        frac("dark_fraction", self.dark_fraction)?;
        frac("bright_fraction", self.bright_fraction)?;
        if self.dark_fraction + self.bright_fraction >= 1.0 {
            return Err(RgbnError::param(
                "dark_fraction",
                "dark_fraction + bright_fraction must be < 1",
            ));
        }
        if !(-1.0..1.0).contains(&self.min_shading) {
            return Err(RgbnError::param("min_shading", "must be in [-1, 1)"));
        }
        if !(self.saturation_level > 0.0 && self.saturation_level.is_finite()) {
            return Err(RgbnError::param("saturation_level", "must be > 0"));
        }
        if !(self.dark_level >= 0.0 && self.dark_level.is_finite()) {
            return Err(RgbnError::param("dark_level", "must be ≥ 0"));
        }
        if !(0.0..1.0).contains(&self.shadow_level) {
            return Err(RgbnError::param("shadow_level", "must be in [0, 1)"));
        }
        if !(-1.0..1.0).contains(&self.robust_min_shading) {
            return Err(RgbnError::param("robust_min_shading", "must be in [-1, 1)"));
        }
        if let Some(k) = self.exponent {
            if !(EXPONENT_RANGE.0..=EXPONENT_RANGE.1).contains(&k) {
                return Err(RgbnError::param(
                    "exponent",
                    format!(
                        "must be in [{}, {}], got {k}",
                        EXPONENT_RANGE.0, EXPONENT_RANGE.1
                    ),
                ));
            }
        }
        let r = &self.robust;
        if !(r.clean_residual >= 0.0 && r.clean_residual.is_finite()) {
            return Err(RgbnError::param("clean_residual", "must be ≥ 0"));
        }
        if r.max_iterations == 0 {
            return Err(RgbnError::param("max_iterations", "must be ≥ 1"));
        }
        for (name, v) in [
            ("tolerance", r.tolerance),
            ("l1_delta", r.l1_delta),
            ("sbl_lambda", r.sbl_lambda),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(RgbnError::param(name, format!("must be > 0, got {v}")));
            }
        }
        Ok(())
    }
}

/// Pixel counts of a photometric-stereo run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhotometricReport {
    /// The shading exponent `k` used (given, or estimated from the photos).
    pub exponent: f32,
    /// Pixels considered (inside the input mask, or all).
    pub pixels: usize,
    /// Pixels with an estimated normal (mask 1 in the output).
    pub solved: usize,
    /// Pixels whose brightest observation is below `dark_level` (normal (0,0,1), mask 0).
    pub dark: usize,
    /// Pixels with at least one saturated observation (excluded from their solve).
    pub with_saturated: usize,
    /// Pixels left with fewer than 3 usable (unsaturated, well-conditioned) observations, or a
    /// non-finite solution (normal (0,0,1), mask 0).
    pub unsolvable: usize,
    /// Solved pixels whose normal has `n_z ≤ 0` (kept; they face away from the camera).
    pub back_facing: usize,
}

impl std::ops::Add for PhotometricReport {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            exponent: self.exponent.max(o.exponent),
            pixels: self.pixels + o.pixels,
            solved: self.solved + o.solved,
            dark: self.dark + o.dark,
            with_saturated: self.with_saturated + o.with_saturated,
            unsolvable: self.unsolvable + o.unsolvable,
            back_facing: self.back_facing + o.back_facing,
        }
    }
}

/// Normalised light directions, checked for count and rank.
fn checked_directions(lights: &Lights, photos: usize) -> Result<Vec<[f64; 3]>, RgbnError> {
    let m = lights.directions.len();
    if photos < 3 || m < 3 {
        return Err(RgbnError::TooFewLights {
            count: photos.min(m),
        });
    }
    if m != photos {
        return Err(RgbnError::LightCountMismatch {
            what: "light directions",
            got: m,
            photos,
            path: PathBuf::new(),
        });
    }
    if let Some(i) = &lights.intensities {
        if i.len() != photos {
            return Err(RgbnError::LightCountMismatch {
                what: "light intensities",
                got: i.len(),
                photos,
                path: PathBuf::new(),
            });
        }
        if let Some(j) = i
            .iter()
            .position(|e| e.iter().any(|&v| !(v > 0.0 && v.is_finite())))
        {
            return Err(RgbnError::param(
                "intensities",
                format!("light {j} has a non-positive intensity {:?}", i[j]),
            ));
        }
    }
    let mut dirs = Vec::with_capacity(m);
    for (j, d) in lights.directions.iter().enumerate() {
        let v = d.map(f64::from);
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if !(len > 1e-6 && len.is_finite()) {
            return Err(RgbnError::DegenerateLights {
                detail: format!("light {j} has no direction ({d:?})"),
            });
        }
        dirs.push(v.map(|c| c / len));
    }
    let cond = condition(&gram(dirs.iter().copied()));
    if cond.is_nan() || cond < MIN_LIGHT_CONDITION {
        return Err(RgbnError::DegenerateLights {
            detail: format!(
                "the {m} directions are (nearly) coplanar: det(LᵀL)/(tr/3)³ = {cond:.2e} < \
                 {MIN_LIGHT_CONDITION:e}"
            ),
        });
    }
    Ok(dirs)
}

/// Estimates albedo, normals and mask from photos under known lights (module docs).
///
/// The output mask is 1 where a normal was estimated and 0 elsewhere (outside the input mask,
/// dark or unsolvable pixels, which get normal `(0, 0, 1)` and albedo 0).
///
/// # Errors
/// Invalid parameters; fewer than 3 photos/lights; lights or intensities not one per photo;
/// degenerate lights; a mask of the wrong length; [`RgbnError::Cancelled`] when the current
/// cancellation token is set.
pub fn photometric_stereo(
    stack: &PhotoStack,
    lights: &Lights,
    mask: Option<&[f32]>,
    params: &PhotometricParams,
) -> Result<(RgbnImage, PhotometricReport), RgbnError> {
    params.validate()?;
    let (w, h) = (stack.width, stack.height);
    check_size(w, h, "photometric stereo")?;
    let dirs = checked_directions(lights, stack.photos.len())?;
    let n = w * h;
    if let Some(j) = stack
        .photos
        .iter()
        .position(|p| p.iter().any(|c| c.len() != n))
    {
        return Err(RgbnError::InvalidImage(format!(
            "photo {j} does not have {w}×{h} values per channel"
        )));
    }
    if let Some(m) = mask {
        if m.len() != n {
            return Err(RgbnError::SizeMismatch {
                what: "mask",
                want_w: w,
                want_h: h,
                got_w: m.len(),
                got_h: 1,
                path: PathBuf::new(),
            });
        }
    }
    let m = dirs.len();
    // 1/e per light and channel.
    let inv_e: Vec<[f32; 3]> = match &lights.intensities {
        Some(i) => i.iter().map(|e| e.map(|v| 1.0 / v)).collect(),
        None => vec![[1.0; 3]; m],
    };
    let a_all = gram(dirs.iter().copied());
    // Pseudo-inverse rows: P = (LᵀL)⁻¹ Lᵀ, 3 × m.
    let pinv: Vec<[f64; 3]> = dirs.iter().map(|l| solve3(&a_all, *l)).collect();
    let exponent = match params.exponent {
        Some(k) => k,
        None => estimate_exponent(stack, mask, &dirs, &inv_e, params)?,
    };
    let shading = Shading::new(exponent);

    let mut color = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    let mut normal = [
        buf::zeroed_f32(n),
        buf::zeroed_f32(n),
        buf::filled_f32(n, 1.0),
    ];
    let mut out_mask = buf::zeroed_f32(n);
    let photos = &stack.photos;
    // Checked once per row (13 photos × a few thousand pixels: well under 50 ms, robust
    // iterations included); rows after cancellation are skipped and the call returns
    // `Cancelled`.
    let cancel = crate::cancel::Cancel::current();
    let [cr, cg, cb] = &mut color;
    let [nx, ny, nz] = &mut normal;
    let report = cr
        .par_chunks_mut(w)
        .zip(cg.par_chunks_mut(w))
        .zip(cb.par_chunks_mut(w))
        .zip(nx.par_chunks_mut(w))
        .zip(ny.par_chunks_mut(w))
        .zip(nz.par_chunks_mut(w))
        .zip(out_mask.par_chunks_mut(w))
        .enumerate()
        .map_init(
            || Scratch::new(m),
            |s, (r, ((((((cr, cg), cb), nx), ny), nz), om))| {
                let mut rep = PhotometricReport::default();
                if cancel.is_cancelled() {
                    return rep;
                }
                for x in 0..w {
                    let i = r * w + x;
                    if mask.is_some_and(|mm| mm[i] < 0.5) {
                        continue;
                    }
                    rep.pixels += 1;
                    let Some((nn, rho)) = solve_pixel(
                        s, photos, i, &dirs, &inv_e, &pinv, params, shading, &mut rep,
                    ) else {
                        continue;
                    };
                    nx[x] = nn[0];
                    ny[x] = nn[1];
                    nz[x] = nn[2];
                    cr[x] = rho[0];
                    cg[x] = rho[1];
                    cb[x] = rho[2];
                    om[x] = 1.0;
                    rep.solved += 1;
                    rep.back_facing += usize::from(nn[2] <= 0.0);
                }
                rep
            },
        )
        .reduce(PhotometricReport::default, |a, b| a + b);
    cancel.check()?;
    let report = PhotometricReport { exponent, ..report };
    let img = RgbnImage::new(w, h, color, normal, Some(out_mask))?;
    Ok((img, report))
}

/// The range of the shading exponent `k`, estimated or given.
pub const EXPONENT_RANGE: (f32, f32) = (0.5, 2.0);

/// The range the estimate of `k` is searched in: a band around Lambert that bounds what a
/// scene the model does not describe (cast shadows, interreflections, badly calibrated
/// lights) can do to every normal; [`EXPONENT_RANGE`] is for values given by hand.
pub const EXPONENT_SEARCH: (f32, f32) = (0.75, 4.0 / 3.0);

/// Trimmed: how many times the shading re-selection may run (it stops when its set repeats).
const RESELECTIONS: usize = 4;

/// Per-job buffers (no per-pixel allocation).
struct Scratch {
    /// Intensity-normalised observations per light: r, g, b, grey.
    obs: Vec<[f32; 4]>,
    /// Usable (unsaturated) observation indices.
    usable: Vec<usize>,
    /// Ranked / selected indices.
    sel: Vec<usize>,
    /// The observations of the final solve (albedo is fitted on them).
    chosen: Vec<usize>,
    /// Grey observations as `f64` (robust estimators).
    g: Vec<f64>,
    /// Per-light weights of the final robust solve (the albedo fit uses them when `weighted`).
    w: Vec<f64>,
    /// Per-light error variances (SBL).
    gamma: Vec<f64>,
    /// Per-light grey values or shadings on their way through [`pow_fast`] (a separate
    /// array, so that the powers run as one vectorised loop).
    pows: Vec<f32>,
    /// The albedo fit is weighted by `w`.
    weighted: bool,
}

impl Scratch {
    fn new(m: usize) -> Self {
        Self {
            obs: vec![[0.0; 4]; m],
            usable: Vec::with_capacity(m),
            sel: Vec::with_capacity(m),
            chosen: Vec::with_capacity(m),
            g: vec![0.0; m],
            w: vec![1.0; m],
            gamma: vec![0.0; m],
            pows: vec![0.0; m],
            weighted: false,
        }
    }
}

/// Least squares on a subset: `b = (Σ l lᵀ)⁻¹ Σ l g`; `None` if ill-conditioned.
fn solve_subset(sel: &[usize], dirs: &[[f64; 3]], obs: &[[f32; 4]]) -> Option<[f64; 3]> {
    if sel.len() < 3 {
        return None;
    }
    let a = gram(sel.iter().map(|&j| dirs[j]));
    let cond = condition(&a);
    if cond.is_nan() || cond < MIN_LIGHT_CONDITION {
        return None;
    }
    let mut y = [0.0f64; 3];
    for &j in sel {
        let g = f64::from(obs[j][3]);
        for k in 0..3 {
            y[k] += dirs[j][k] * g;
        }
    }
    Some(solve3(&a, y))
}

/// The shading exponent `k` and the power `1/k` that makes observations linear in `n · l`.
#[derive(Clone, Copy, Debug)]
struct Shading {
    k: f64,
    inv_k: f32,
}

impl Shading {
    fn new(k: f32) -> Self {
        Self {
            k: f64::from(k),
            inv_k: 1.0 / k,
        }
    }

    /// The model's shading `max(0, n·l)^k` for the albedo fit, in place on the cosines.
    fn shade(self, cos: &mut [f32]) {
        if self.k == 1.0 {
            for c in cos {
                *c = c.max(0.0);
            }
        } else {
            let k = self.k as f32;
            for c in cos {
                *c = pow_fast(*c, k);
            }
        }
    }
}

/// `x^p` for `x ≥ 0` (0 below, and for `x` under the smallest normal `f32`), as
/// [`exp2_fast`]`(p · `[`log2_fast`]`(x))`: within 2e-6 relative for `p ≤ 2` and `x` up to
/// 1e3 (test `pow_fast_follows_powf`); branch-free, where `powf` per observation dominated a
/// megapixel's solve.
fn pow_fast(x: f32, p: f32) -> f32 {
    let y = exp2_fast(p * log2_fast(x.max(f32::MIN_POSITIVE)));
    if x >= f32::MIN_POSITIVE {
        y
    } else {
        0.0
    }
}

/// Raises the grey observations of `s.obs` to `1/k` (nothing at `k = 1`), which makes them
/// linear in `n · l` (module docs, "Shading exponent").
fn linearise(s: &mut Scratch, shading: Shading) {
    if shading.inv_k != 1.0 {
        for (p, o) in s.pows.iter_mut().zip(&s.obs) {
            *p = o[3];
        }
        for p in &mut s.pows {
            *p = pow_fast(*p, shading.inv_k);
        }
        for (o, p) in s.obs.iter_mut().zip(&s.pows) {
            o[3] = *p;
        }
    }
}

/// Fills `s.obs` (intensity-normalised colour and the linearised grey value) and `s.usable`
/// (the unsaturated lights) for pixel `i`; `false` (counted) for a dark pixel.
#[allow(clippy::too_many_arguments)]
fn observe(
    s: &mut Scratch,
    photos: &[[Vec<f32>; 3]],
    i: usize,
    inv_e: &[[f32; 3]],
    params: &PhotometricParams,
    shading: Shading,
    rep: &mut PhotometricReport,
) -> bool {
    s.usable.clear();
    let mut brightest = 0.0f32;
    for (j, (photo, e)) in photos.iter().zip(inv_e).enumerate() {
        let raw = [photo[0][i], photo[1][i], photo[2][i]];
        let v = [raw[0] * e[0], raw[1] * e[1], raw[2] * e[2]];
        let g = (v[0] + v[1] + v[2]) / 3.0;
        let g = if g.is_finite() { g } else { 0.0 };
        brightest = brightest.max(g);
        s.obs[j] = [v[0], v[1], v[2], g];
        if raw
            .iter()
            .all(|&c| c < params.saturation_level && c.is_finite())
        {
            s.usable.push(j);
        }
    }
    if brightest.is_nan() || brightest < params.dark_level || brightest <= 0.0 {
        rep.dark += 1;
        return false;
    }
    linearise(s, shading);
    if s.usable.len() < photos.len() {
        rep.with_saturated += 1;
    }
    true
}

#[allow(clippy::too_many_arguments)]
fn solve_pixel(
    s: &mut Scratch,
    photos: &[[Vec<f32>; 3]],
    i: usize,
    dirs: &[[f64; 3]],
    inv_e: &[[f32; 3]],
    pinv: &[[f64; 3]],
    params: &PhotometricParams,
    shading: Shading,
    rep: &mut PhotometricReport,
) -> Option<([f32; 3], [f32; 3])> {
    let m = dirs.len();
    if !observe(s, photos, i, inv_e, params, shading, rep) {
        return None;
    }
    s.chosen.clear();
    s.weighted = false;
    let b = match params.method {
        PsMethod::LeastSquares if s.usable.len() == m => {
            let mut b = [0.0f64; 3];
            for (pj, o) in pinv.iter().zip(&s.obs) {
                let g = f64::from(o[3]);
                for (bk, pk) in b.iter_mut().zip(pj) {
                    *bk += pk * g;
                }
            }
            s.chosen.extend_from_slice(&s.usable);
            Some(b)
        }
        PsMethod::LeastSquares => {
            s.chosen.extend_from_slice(&s.usable);
            solve_subset(&s.usable, dirs, &s.obs)
        }
        PsMethod::Trimmed => trimmed_solve(s, dirs, params),
        PsMethod::L1 | PsMethod::Sbl => robust_solve(s, dirs, params),
    };
    let Some(b) = b else {
        rep.unsolvable += 1;
        return None;
    };
    let len = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    if !(len > 0.0 && len.is_finite()) {
        rep.unsolvable += 1;
        return None;
    }
    let nn = b.map(|c| c / len);
    // Per-channel albedo with n fixed, over the observations of the final solve.
    let (mut num, mut den) = ([0.0f64; 3], 0.0f64);
    let c = s.chosen.len();
    for (p, &j) in s.pows.iter_mut().zip(&s.chosen) {
        let d = dirs[j];
        *p = (nn[0] * d[0] + nn[1] * d[1] + nn[2] * d[2]) as f32;
    }
    shading.shade(&mut s.pows[..c]);
    for (&j, &sh) in s.chosen.iter().zip(&s.pows) {
        let sh = f64::from(sh);
        let wsh = if s.weighted { s.w[j] * sh } else { sh };
        for (nc, &o) in num.iter_mut().zip(&s.obs[j][..3]) {
            *nc += f64::from(o) * wsh;
        }
        den += wsh * sh;
    }
    let rho = if den > 0.0 {
        num.map(|v| (v / den) as f32)
    } else {
        [len as f32; 3]
    };
    Some((nn.map(|c| c as f32), rho))
}

/// The trimmed estimator (module docs); leaves the final selection in `s.chosen`.
fn trimmed_solve(
    s: &mut Scratch,
    dirs: &[[f64; 3]],
    params: &PhotometricParams,
) -> Option<[f64; 3]> {
    rank_usable(s);
    trimmed_from_ranked(s, dirs, params)
}

/// `s.sel`: the usable lights, darkest grey observation first.
fn rank_usable(s: &mut Scratch) {
    let obs = &s.obs;
    s.sel.clear();
    s.sel.extend_from_slice(&s.usable);
    s.sel
        .sort_unstable_by(|&a, &b| obs[a][3].total_cmp(&obs[b][3]));
}

/// [`trimmed_solve`] after [`rank_usable`] (`s.sel` ranked).
fn trimmed_from_ranked(
    s: &mut Scratch,
    dirs: &[[f64; 3]],
    params: &PhotometricParams,
) -> Option<[f64; 3]> {
    let obs = &s.obs;
    let k = s.sel.len();
    let lo = ((params.dark_fraction * k as f32).floor() as usize).min(k);
    let hi = (k - ((params.bright_fraction * k as f32).floor() as usize).min(k)).max(lo);
    let b0 = match solve_subset(&s.sel[lo..hi], dirs, obs) {
        Some(b) => {
            s.chosen.extend_from_slice(&s.sel[lo..hi]);
            b
        }
        None => {
            s.chosen.extend_from_slice(&s.usable);
            return solve_subset(&s.usable, dirs, obs);
        }
    };
    // Re-select among all but the bright trim: lights in front of the estimate; repeated
    // with each new estimate until the set stops changing (at most `RESELECTIONS` times).
    // `s.chosen` holds the current set (the middle part first).
    let mut b = b0;
    for _ in 0..RESELECTIONS {
        let len = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
        if !(len > 0.0 && len.is_finite()) {
            break;
        }
        let n0 = b.map(|c| c / len);
        let lit = |j: &usize| {
            let d = dirs[*j];
            (n0[0] * d[0] + n0[1] * d[1] + n0[2] * d[2]) as f32 >= params.min_shading
        };
        let mark = s.chosen.len();
        s.chosen.extend(s.sel[..hi].iter().copied().filter(lit));
        if s.chosen[mark..] == s.chosen[..mark] {
            s.chosen.truncate(mark);
            break;
        }
        match solve_subset(&s.chosen[mark..], dirs, obs) {
            Some(next) => {
                s.chosen.drain(..mark);
                b = next;
            }
            None => {
                s.chosen.truncate(mark);
                break;
            }
        }
    }
    Some(b)
}

/// The L1 and SBL estimators ([`super::robust`]): shadows below `shadow_level` out, least
/// squares, the regression, then (with `robust_min_shading > −1`) the attached shadows of that
/// estimate out and the regression again. Leaves the final set in `s.chosen`, its weights in
/// `s.w`.
fn robust_solve(
    s: &mut Scratch,
    dirs: &[[f64; 3]],
    params: &PhotometricParams,
) -> Option<[f64; 3]> {
    for &j in &s.usable {
        s.g[j] = f64::from(s.obs[j][3]);
    }
    let gmax = s.usable.iter().map(|&j| s.g[j]).fold(0.0, f64::max);
    let floor = f64::from(params.shadow_level) * gmax;
    s.sel.clear();
    s.sel
        .extend(s.usable.iter().copied().filter(|&j| s.g[j] >= floor));
    let b0 = match solve_subset(&s.sel, dirs, &s.obs) {
        Some(b) => b,
        None => {
            s.sel.clear();
            s.sel.extend_from_slice(&s.usable);
            solve_subset(&s.sel, dirs, &s.obs)?
        }
    };
    let run = |s: &mut Scratch, b0: [f64; 3]| match params.method {
        PsMethod::Sbl => sbl(
            &s.sel,
            dirs,
            &s.g,
            b0,
            &mut s.gamma,
            &mut s.w,
            &params.robust,
        ),
        _ => l1_irls(&s.sel, dirs, &s.g, b0, &mut s.w, &params.robust),
    };
    if is_clean(&s.sel, dirs, &s.g, b0, &params.robust) {
        s.chosen.clear();
        s.chosen.extend_from_slice(&s.sel);
        return Some(b0);
    }
    let mut b = run(s, b0)?;
    if params.robust_min_shading > -1.0 {
        let len = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
        let n = b.map(|c| c / len);
        let t = f64::from(params.robust_min_shading);
        s.chosen.clear();
        s.chosen.extend(s.sel.iter().copied().filter(|&j| {
            let d = dirs[j];
            n[0] * d[0] + n[1] * d[1] + n[2] * d[2] >= t
        }));
        if s.chosen.len() < s.sel.len() && s.chosen.len() >= 3 {
            std::mem::swap(&mut s.chosen, &mut s.sel);
            if let Some(b2) = run(s, b) {
                b = b2;
            }
        }
    }
    s.chosen.clear();
    s.chosen.extend_from_slice(&s.sel);
    s.weighted = true;
    Some(b)
}

#[cfg(test)]
#[path = "photometric_tests.rs"]
mod tests;
