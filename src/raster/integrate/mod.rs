//! Integration of normals / gradients to a height, and the integrability projection.
//!
//! # Discretisation
//!
//! The unknown is a height `z(x, r)` at the pixel centres (`r` = row, downwards; `y` up, see
//! [`gradient`](super::gradient)). Each edge between two neighbouring pixels is one *edge
//! equation*, with the edge values `e` of [`GradientField::edge_values`] for the chosen
//! [`Differences`] model:
//!
//! - horizontal edge `(x, r)`, `x ≤ W−2`: `z(x+1, r) − z(x, r) = e_p(x, r)`,
//! - vertical edge `(x, r)`, `r ≥ 1`: `z(x, r−1) − z(x, r) = e_q(x, r)`.
//!
//! With [`Differences::Averaged`] (the default) `e_p(x, r) = ½(p(x, r) + p(x+1, r))` and
//! `e_q(x, r) = ½(q(x, r) + q(x, r−1))` (trapezoidal rule: the right model for normals sampled
//! at pixel centres); with [`Differences::Forward`] `e = (p, q)`, one pixel's sample per edge
//! (exact for [`GradientField::from_height`]).
//!
//! Writing these as `D z = e`, the least-squares height solves the normal equations
//! `Dᵀ D z = Dᵀ e`. `L = DᵀD` is the graph Laplacian of the grid with *natural Neumann*
//! boundaries, and `b = Dᵀe` is the discrete divergence
//! `b(x,r) = e_p(x−1,r) − e_p(x,r) + e_q(x,r+1) − e_q(x,r)` (terms whose edge does not exist
//! dropped). The model only changes the data side, so the DCT and masked solvers are those of
//! the forward model fed with the edge values. Because `L` is exactly the operator whose range
//! holds every discrete gradient, **integrating the edge values of a height's model gradient
//! returns that height** up to a constant and rounding, and the normals of the result have zero
//! curl (to rounding) in the same model.
//!
//! # Solvers (one submodule each)
//!
//! - [`IntegrationMethod::PoissonDct`] (Simchony, Chellappa & Shao 1990): `L` is diagonalised by
//!   the 2-D DCT-II, with eigenvalues `λ(k,l) = (2 − 2cos(πk/W)) + (2 − 2cos(πl/H))`. So
//!   `z = DCT⁻¹[ DCT(b) / λ ]` with the `(0,0)` term (the free constant) set to 0: the result has
//!   zero mean. Cost: three passes over one buffer — row pairs (divergence fused, DCT-II along
//!   x); groups of 16 columns gathered in cache-line row segments (DCT-II along y, eigenvalue
//!   division, DCT-III along y, scattered back); row pairs (DCT-III along x) — no transposes.
//!   Each real DCT is Makhoul's reordering + one complex FFT, **two sequences per FFT** (packed
//!   as real and imaginary parts: the work of a half-length real FFT each); rustfft plans and
//!   twiddles are cached across calls; rustdct serves as the test oracle.
//!   **Precision: `f32` throughout** (as the input gradients and output heights). It keeps
//!   integration of exact discrete gradients to < 2e-3 px max error and the sum-of-Gaussians
//!   RMSE at ≈ 0.045 px (tests below), and matches an `f64` rustdct reference to 1e-4 of the
//!   amplitude; `f64` would double memory traffic for no visible gain at these tolerances.
//! - [`IntegrationMethod::FrankotChellappa`] (Frankot & Chellappa 1988): the same least squares
//!   but with **periodic** boundaries, solved with FFTs: with `a = e^{2πi k/W} − 1`,
//!   `c = e^{−2πi l/H} − 1` (the transfer functions of the two forward differences) and the
//!   data-side transfer functions of the edge model, `α = ½(1 + e^{2πi k/W})`,
//!   `γ = ½(1 + e^{−2πi l/H})` (averaged; `α = γ = 1` forward),
//!   `Ẑ = (ā α P̂ + c̄ γ Q̂) / (|a|² + |c|²)`. Averaged, `ā α = −i sin(2πk/W)` and
//!   `c̄ γ = i sin(2πl/H)`: central differences. Their zeros at the Nyquist bins (`ω = π`,
//!   even sizes) are zeros of the *data* side only — the checkerboard gradient the average
//!   cannot see contributes nothing there — while the denominator vanishes only at `(0, 0)`
//!   (the free constant, set to 0), so nothing is divided by zero. Every gradient sample is
//!   used, the last column's `p` and the top row's `q` through wrap-around edges. Exact for
//!   periodic heights; for others the wrap-around edges disagree and the error concentrates
//!   at the borders.
//!   Real-input packing (rows of `p + i q` split into half spectra, column FFTs on `W/2 + 1`
//!   bins with the solve fused, two Hermitian rows per inverse FFT): the FFT work of scipy's
//!   `rfft2` ×2 + `irfft2`, `f32`.
//! - [`IntegrationMethod::MaskedPoisson`]: only edges with both ends inside the mask
//!   (coverage ≥ 0.5) are equations (averaged edge values thus only average two samples
//!   inside), so nothing outside the object (background normals, depth discontinuities at the
//!   silhouette) leaks in. The masked Laplacian is solved by conjugate gradients
//!   preconditioned with one geometric-multigrid V-cycle (the weighted-edge solver of the
//!   `edges` source, weight 1 inside the mask: coverage-aggregated coarse levels,
//!   rediscretised Laplacians, red-black Gauss–Seidel, exact pseudo-inverse on the coarsest
//!   level), in `f64` for the Krylov vectors and `f32` inside the V-cycle, warm-started from
//!   the DCT solution of the edge values with the off-domain edges set to 0. Each connected
//!   component of the mask has its own free constant (the warm start's mean on it); the result
//!   has zero mean over the mask. Pixels outside the mask keep the warm start (a smooth fill
//!   carrying no information). A pixel with no edge inside the mask (a single-pixel component)
//!   gets height 0 and is counted in [`IntegrationReport::isolated_pixels`]; a mask with no
//!   edge at all is an error naming the mask.
//!
//! # Sampled normals: averaged vs forward (history)
//!
//! Until issue 17 the only model was the forward one: a forward difference `z(x+1) − z(x)` is
//! a central difference at `x + ½`, so normals sampled *at pixel centres* gave, to second
//! order, the height at `(x − ½, row + ½)`, half a pixel staggered — on steep surfaces (slopes
//! up to 10 px/px) the RMSE against the centre samples was 1.6–2.3 px. The averaged model
//! registers the height at the pixel centres (≈ 0.1 px on the same surfaces). The forward model
//! remains as [`Differences::Forward`] for fields that *are* forward differences of a height
//! (the editing operators' [`GradientField::from_height`]); its tests compare analytic surfaces
//! at the staggered position, those of the default at pixel centres.
//!
//! # Integrability projection
//!
//! [`project_integrable`] replaces a normal field by the normals of its integrated height `z*`
//! in the same edge model: the samples `g'` closest to the input `g` whose edge values are the
//! height's differences, `g' = g + A⁺(D z* − A g)` (`A` the model's sample-to-edge map, applied
//! per row for `p` and per column for `q` over the runs of the domain; a tridiagonal solve
//! per run). With the forward model this is the old rule (forward differences, backward at a
//! run's end). With the averaged model the checkerboard component of `g` (null space of `A`,
//! see [`gradient`](super::gradient)) is kept, so an already integrable field is returned
//! unchanged (to rounding), the output has zero model curl, and projecting twice changes
//! nothing. It reports the model curl before and after.
//!
//! # References
//!
//! - T. Simchony, R. Chellappa, M. Shao, "Direct analytical methods for solving Poisson
//!   equations in computer vision problems", IEEE PAMI 12(5), 1990.
//! - R. T. Frankot, R. Chellappa, "A method for enforcing integrability in shape from shading
//!   algorithms", IEEE PAMI 10(4), 1988.
//! - A. Agrawal, R. Raskar, R. Chellappa, "What is the range of surface reconstructions from a
//!   gradient field?", ECCV 2006 (and Agrawal et al. 2005 for the curl readout).
//! - Y. Quéau, J.-D. Durou, J.-F. Aujol, "Normal integration: a survey", JMIV 60, 2018
//!   (discrete Poisson with Neumann boundaries on non-rectangular domains).

mod bini;
mod dct;
mod edges;
mod fft;
mod frankot;
mod masked;
pub mod perspective;
mod projection;
#[cfg(test)]
mod test_util;

pub use perspective::{Camera, Pinhole};
pub use projection::{project_integrable, ProjectParams, ProjectionReport};

pub use super::gradient::Differences;
use super::gradient::GradientField;
use super::{Plane, RgbnImage};
use crate::error::RgbnError;
use dct::poisson_dct;
use frankot::frankot_chellappa;
use masked::masked_poisson;
use rayon::prelude::*;

/// How gradients become a height. See the module docs for the maths of each.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum IntegrationMethod {
    /// Least squares with Neumann boundaries on the full rectangle, DCT solver (fast, exact for
    /// discrete gradients). The mask is ignored.
    #[default]
    PoissonDct,
    /// Least squares with periodic boundaries, FFT solver. The mask is ignored.
    FrankotChellappa,
    /// Least squares over the edges inside the mask, conjugate gradients preconditioned by a
    /// multigrid V-cycle, warm-started from the DCT solution. Without a mask it equals
    /// `PoissonDct`.
    MaskedPoisson,
    /// Bilateral normal integration (Cao et al. 2022, [`bini`] source docs): iteratively
    /// reweighted least squares with one-sided equations, keeping depth discontinuities.
    /// Over the mask (all pixels without one).
    Bilateral,
}

/// Parameters of [`integrate_gradients`] / [`integrate_normals`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IntegrateParams {
    pub method: IntegrationMethod,
    /// Conjugate-gradient iteration cap (masked method only), ≥ 1.
    pub max_iterations: u32,
    /// Stop when `‖b − L z‖ ≤ tolerance · ‖b‖` (masked method only), in (0, 1).
    pub tolerance: f64,
    /// The edge model (module docs); [`Differences::Averaged`] unless named.
    #[serde(default)]
    pub differences: Differences,
    /// The camera (orthographic unless named). With a pinhole camera the log-depth is
    /// integrated and the result is the height `−Z` of a depth `Z` up to scale
    /// ([`perspective`] docs).
    #[serde(default)]
    pub camera: Camera,
    /// Bilateral: the sigmoid sharpness `k` (0 = plain least squares), finite, ≥ 0.
    #[serde(default = "default_sharpness")]
    pub sharpness: f64,
    /// Bilateral: the cap on reweighting (IRLS) iterations, ≥ 1.
    #[serde(default = "default_irls_iterations")]
    pub irls_iterations: u32,
    /// Bilateral: stop when the relative energy change is below this, in (0, 1).
    #[serde(default = "default_irls_tolerance")]
    pub irls_tolerance: f64,
    /// Bilateral: the factor `β` by which each reweighting step's change `u_new − u` is
    /// extrapolated when that lowers the energy ([`bini`] docs); 1 = the plain steps of the
    /// reference implementation. Finite, in [1, 10].
    #[serde(default = "default_over_relaxation")]
    pub over_relaxation: f64,
}

fn default_over_relaxation() -> f64 {
    2.0
}
fn default_sharpness() -> f64 {
    2.0
}
fn default_irls_iterations() -> u32 {
    150
}
fn default_irls_tolerance() -> f64 {
    1e-4
}

impl Default for IntegrateParams {
    fn default() -> Self {
        Self {
            method: IntegrationMethod::PoissonDct,
            max_iterations: 2000,
            tolerance: 1e-6,
            differences: Differences::Averaged,
            camera: Camera::Orthographic,
            sharpness: default_sharpness(),
            irls_iterations: default_irls_iterations(),
            irls_tolerance: default_irls_tolerance(),
            over_relaxation: default_over_relaxation(),
        }
    }
}

impl IntegrateParams {
    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<(), RgbnError> {
        if self.max_iterations == 0 {
            return Err(RgbnError::param("max_iterations", "must be at least 1"));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(RgbnError::param(
                "tolerance",
                format!("must be in (0, 1), got {}", self.tolerance),
            ));
        }
        if !(self.sharpness.is_finite() && self.sharpness >= 0.0) {
            return Err(RgbnError::param(
                "sharpness",
                format!("must be finite and ≥ 0, got {}", self.sharpness),
            ));
        }
        if self.irls_iterations == 0 {
            return Err(RgbnError::param("irls_iterations", "must be at least 1"));
        }
        if !(self.irls_tolerance > 0.0 && self.irls_tolerance < 1.0) {
            return Err(RgbnError::param(
                "irls_tolerance",
                format!("must be in (0, 1), got {}", self.irls_tolerance),
            ));
        }
        if !(self.over_relaxation >= 1.0 && self.over_relaxation <= 10.0) {
            return Err(RgbnError::param(
                "over_relaxation",
                format!("must be in [1, 10], got {}", self.over_relaxation),
            ));
        }
        if let Camera::Pinhole(c) = &self.camera {
            c.validate()?;
        }
        Ok(())
    }
}

/// What an integration did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IntegrationReport {
    pub method: IntegrationMethod,
    /// Pixels in the integration domain (all pixels, or the mask).
    pub domain_pixels: usize,
    /// Conjugate-gradient iterations (0 for the direct solvers).
    pub iterations: u32,
    /// Final `‖b − L z‖ / ‖b‖` of the conjugate gradients (0 for the direct solvers).
    pub relative_residual: f64,
    /// RMS over the domain's edges of `D z − e` (`e` the edge values of the model): how far
    /// the field is from integrable, in height units per pixel (0 for an integrable field).
    pub rms_residual: f64,
    /// Domain pixels with no edge inside the domain (single-pixel components): height 0.
    pub isolated_pixels: usize,
    /// Bilateral: reweighting (IRLS) iterations done (0 for the other methods).
    pub irls_iterations: u32,
    /// Domain pixels whose `n_z` (pinhole: the facing term `d`) was below
    /// [`NZ_EPSILON`](super::gradient::NZ_EPSILON) and clamped (bilateral and pinhole only).
    pub clamped_pixels: usize,
}

/// Coverage ≥ 0.5 counts as inside.
#[inline(always)]
fn inside(m: f32) -> bool {
    m >= 0.5
}

/// Checks a mask's length and that it is not empty.
fn check_mask(mask: Option<&[f32]>, w: usize, h: usize) -> Result<(), RgbnError> {
    if let Some(m) = mask {
        if m.len() != w * h {
            return Err(RgbnError::InvalidImage(format!(
                "mask has {} values for a {w}×{h} field",
                m.len()
            )));
        }
        if !m.par_iter().any(|&v| inside(v)) {
            return Err(RgbnError::EmptyMask {
                what: "the integration domain",
            });
        }
    }
    Ok(())
}

/// Integrates a gradient field to a height (pixels, mean 0 over the domain).
///
/// `mask` (coverage per pixel, ≥ 0.5 inside) is used by [`IntegrationMethod::MaskedPoisson`]
/// only; a mask with no pixel inside is an error for every method.
///
/// # Errors
/// Invalid parameters, a field whose planes do not match its size, a mask of the wrong size or
/// an empty mask.
pub fn integrate_gradients(
    g: &GradientField,
    mask: Option<&[f32]>,
    params: &IntegrateParams,
) -> Result<(Plane, IntegrationReport), RgbnError> {
    params.validate()?;
    if let Camera::Pinhole(_) = params.camera {
        return Err(RgbnError::param(
            "camera",
            "a pinhole camera integrates normals (integrate_normals), not a gradient field",
        ));
    }
    if params.method == IntegrationMethod::Bilateral {
        check_field(g)?;
        check_mask(mask, g.width, g.height)?;
        let normal = g.to_normals();
        return bilateral_height(&normal, g, mask, params);
    }
    integrate_field(g, mask, params)
}

/// The field's planes match its size.
fn check_field(g: &GradientField) -> Result<(), RgbnError> {
    let (w, h) = (g.width, g.height);
    if w == 0 || h == 0 || g.p.len() != w * h || g.q.len() != w * h {
        return Err(RgbnError::InvalidImage(format!(
            "gradient field {w}×{h} with {} p and {} q values",
            g.p.len(),
            g.q.len()
        )));
    }
    Ok(())
}

/// Bilateral integration of normal planes (`g` their gradient field in the chosen camera's
/// frame: the log-depth gradients with a pinhole camera), the result `u` (height or
/// log-depth) with zero mean over the domain, 0 outside.
fn bilateral_height(
    normal: &[Vec<f32>; 3],
    g: &GradientField,
    mask: Option<&[f32]>,
    params: &IntegrateParams,
) -> Result<(Plane, IntegrationReport), RgbnError> {
    let (w, h) = (g.width, g.height);
    let (domain, isolated) = match mask {
        Some(m) => domain_counts(m, w, h),
        None => domain_counts(&vec![1.0; w * h], w, h),
    };
    if domain > 1 && isolated == domain {
        return Err(RgbnError::param(
            "mask",
            format!(
                "the integration domain ({domain} pixels) has no two neighbouring pixels \
                 inside: no edge to integrate"
            ),
        ));
    }
    let bp = bini::BilateralParams {
        sharpness: params.sharpness,
        max_irls: params.irls_iterations,
        irls_tolerance: params.irls_tolerance,
        solve_tolerance: params.tolerance,
        solve_max_iterations: params.max_iterations,
        over_relaxation: params.over_relaxation as f32,
    };
    let out = bini::bilateral(normal, w, h, mask, &params.camera, &bp)?;
    if out.clamped == domain {
        return Err(RgbnError::param(
            "image",
            format!(
                "no pixel of the integration domain ({domain} pixels) faces the camera \
                 (every normal is edge-on or turned away): nothing to integrate"
            ),
        ));
    }
    let mut u = out.u;
    let ins = |i: usize| mask.is_none_or(|m| inside(m[i]));
    let mean = u
        .iter()
        .enumerate()
        .filter(|(i, _)| ins(*i))
        .map(|(_, &v)| f64::from(v))
        .sum::<f64>()
        / domain.max(1) as f64;
    for (i, v) in u.iter_mut().enumerate() {
        *v = if ins(i) {
            (f64::from(*v) - mean) as f32
        } else {
            0.0
        };
    }
    let z = Plane::from_vec(w, h, u)?;
    let report = IntegrationReport {
        method: IntegrationMethod::Bilateral,
        domain_pixels: domain,
        iterations: out.solver_iterations,
        relative_residual: out.relative_residual,
        rms_residual: edge_rms(Some(z.data()), g, mask, params.differences),
        isolated_pixels: isolated,
        irls_iterations: out.irls_iterations,
        clamped_pixels: out.clamped,
    };
    Ok((z, report))
}

/// [`integrate_gradients`] for the least-squares methods (orthographic frame).
fn integrate_field(
    g: &GradientField,
    mask: Option<&[f32]>,
    params: &IntegrateParams,
) -> Result<(Plane, IntegrationReport), RgbnError> {
    let (w, h) = (g.width, g.height);
    check_field(g)?;
    check_mask(mask, w, h)?;
    let mut report = IntegrationReport {
        method: params.method,
        domain_pixels: w * h,
        ..Default::default()
    };
    let d = params.differences;
    let z = match (params.method, mask) {
        (IntegrationMethod::FrankotChellappa, _) => frankot_chellappa(g, params.differences),
        (IntegrationMethod::MaskedPoisson, Some(m)) => {
            let (domain, isolated) = domain_counts(m, w, h);
            if domain > 1 && isolated == domain {
                return Err(RgbnError::param(
                    "mask",
                    format!(
                        "the integration domain ({domain} pixels) has no two neighbouring \
                         pixels inside: no edge to integrate"
                    ),
                ));
            }
            report.domain_pixels = domain;
            report.isolated_pixels = isolated;
            let (z, it, rel) = masked_poisson(g, m, params)?;
            report.iterations = it;
            report.relative_residual = rel;
            z
        }
        _ => poisson_dct(g, None, d),
    };
    let dom = if params.method == IntegrationMethod::MaskedPoisson {
        mask
    } else {
        None
    };
    report.rms_residual = edge_rms(Some(z.data()), g, dom, d);
    Ok((z, report))
}

/// Pixels inside the mask and those of them with no neighbour inside (4-neighbourhood).
fn domain_counts(m: &[f32], w: usize, h: usize) -> (usize, usize) {
    (0..h)
        .into_par_iter()
        .map(|r| {
            let (mut d, mut iso) = (0usize, 0usize);
            for x in 0..w {
                let i = r * w + x;
                if !inside(m[i]) {
                    continue;
                }
                d += 1;
                let nb = (x >= 1 && inside(m[i - 1]))
                    || (x + 1 < w && inside(m[i + 1]))
                    || (r >= 1 && inside(m[i - w]))
                    || (r + 1 < h && inside(m[i + w]));
                iso += usize::from(!nb);
            }
            (d, iso)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Integrates an image's normals (through [`GradientField::from_normals`]); the image's mask is
/// the domain of [`IntegrationMethod::MaskedPoisson`] and [`IntegrationMethod::Bilateral`].
///
/// With a [pinhole](Camera::Pinhole) camera the log-depth gradients of
/// [`perspective::log_depth_gradients`] are integrated by the chosen method and the result is
/// the height `−Z` of the depth `Z` (geometric mean `fx` over the domain; [`perspective`]
/// docs); `rms_residual` is then in log-depth units.
///
/// # Errors
/// As [`integrate_gradients`]; with a pinhole camera or the bilateral method also a domain in
/// which no normal faces the camera.
pub fn integrate_normals(
    img: &RgbnImage,
    params: &IntegrateParams,
) -> Result<(Plane, IntegrationReport), RgbnError> {
    params.validate()?;
    let (w, h) = (img.width(), img.height());
    let cam = match params.camera {
        Camera::Orthographic => {
            if params.method == IntegrationMethod::Bilateral {
                check_mask(img.mask(), w, h)?;
                let g = GradientField::from_normals(img);
                return bilateral_height(img.normal(), &g, img.mask(), params);
            }
            return integrate_gradients(&GradientField::from_normals(img), img.mask(), params);
        }
        Camera::Pinhole(c) => c,
    };
    check_mask(img.mask(), w, h)?;
    let g = perspective::log_depth_gradients(img.normal(), w, h, &cam);
    let (mut ell, mut report, domain) = if params.method == IntegrationMethod::Bilateral {
        let (z, rep) = bilateral_height(img.normal(), &g, img.mask(), params)?;
        (z, rep, img.mask())
    } else {
        let ortho = IntegrateParams {
            camera: Camera::Orthographic,
            ..params.clone()
        };
        let (z, mut rep) = integrate_field(&g, img.mask(), &ortho)?;
        let dom = (params.method == IntegrationMethod::MaskedPoisson)
            .then_some(img.mask())
            .flatten();
        let ins = |i: usize| dom.is_none_or(|m| inside(m[i]));
        let faces = (0..w * h).filter(|&i| ins(i)).count();
        let clamped = (0..w * h)
            .filter(|&i| ins(i))
            .filter(|&i| {
                let n = [img.normal()[0][i], img.normal()[1][i], img.normal()[2][i]];
                let d = cam.facing(n, i % w, i / w);
                d.is_nan() || d < f64::from(super::gradient::NZ_EPSILON)
            })
            .count();
        if clamped == faces {
            return Err(RgbnError::param(
                "image",
                format!(
                    "no pixel of the integration domain ({faces} pixels) faces the camera \
                     (every normal is edge-on or turned away): nothing to integrate"
                ),
            ));
        }
        rep.clamped_pixels = clamped;
        (z, rep, dom)
    };
    perspective::height_of_log_depth(ell.data_mut(), domain, cam.fx);
    report.method = params.method;
    Ok((ell, report))
}

/// The non-integrable fraction `F = ‖e − D z*‖ / ‖e‖` over the edge equations of the module
/// docs in the default ([`Differences::Averaged`]) model, `e` the edge values, `z*` the
/// least-squares height: [`IntegrationMethod::PoissonDct`] (Neumann borders), or
/// [`IntegrationMethod::MaskedPoisson`] over the mask where there is one. `D z*` is the
/// orthogonal projection of `e` onto the discrete gradients, so `F ∈ [0, 1]`: 0 for the
/// gradient of a height (to rounding), ≈ √(2/π) ≈ 0.80 for white-noise samples (their edge
/// averages are low-pass noise with 2/π of the energy in the curl part), 1 for a pure curl
/// field. Scale-free:
/// unlike the relative curl it does not fall when an edit only adds gradient energy. A zero
/// field reads 0.
///
/// # Errors
/// As [`integrate_gradients`] (a mask of the wrong size, or with no pixel inside).
pub fn non_integrable_fraction(g: &GradientField, mask: Option<&[f32]>) -> Result<f64, RgbnError> {
    let method = if mask.is_some() {
        IntegrationMethod::MaskedPoisson
    } else {
        IntegrationMethod::PoissonDct
    };
    let (_, report) = integrate_gradients(
        g,
        mask,
        &IntegrateParams {
            method,
            ..IntegrateParams::default()
        },
    )?;
    let norm = edge_rms(None, g, mask, Differences::Averaged);
    Ok(if norm > 0.0 {
        (report.rms_residual / norm).min(1.0)
    } else {
        0.0
    })
}

/// The non-integrable fraction of an image's normals read as stored (`[0]`) and with `n_y`
/// negated (`[1]`, the other green convention: OpenGL ↔ DirectX). The height-derived reading
/// is the one with the lower `F`: a normal map read in the wrong convention is the gradient
/// field `(p, −q)`, which belongs to no surface unless the relief is symmetric.
///
/// # Errors
/// As [`non_integrable_fraction`].
pub fn green_convention_fractions(img: &RgbnImage) -> Result<[f64; 2], RgbnError> {
    let g = GradientField::from_normals(img);
    let as_read = non_integrable_fraction(&g, img.mask())?;
    let flipped = GradientField {
        q: g.q.iter().map(|v| -v).collect(),
        ..g
    };
    Ok([as_read, non_integrable_fraction(&flipped, img.mask())?])
}

/// Pixels whose curl stencil (itself, above, right, above-right: every sample the plaquette
/// circulation reads, in both [`Differences`] models) lies inside the mask: the curl readout
/// of a masked field, free of values across the silhouette.
#[must_use]
pub fn curl_interior(mask: &[f32], w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, r) = (i % w, i / w);
            let ok = inside(mask[i])
                && r >= 1
                && inside(mask[i - w])
                && x + 1 < w
                && inside(mask[i + 1])
                && inside(mask[i - w + 1]);
            f32::from(u8::from(ok))
        })
        .collect()
}

/// Pixel-sample gradients of a height restricted to a domain, in an edge model: the
/// integrability projection's output (module docs).
///
/// - [`Differences::Forward`]: without a domain [`GradientField::from_height`]. With one, a
///   pixel inside uses the forward difference if its forward neighbour is inside, else the
///   backward difference if that neighbour is inside, else `fallback`'s value (or 0).
/// - [`Differences::Averaged`]: along each run of domain pixels in a row (for `p`) or column
///   (for `q`), the samples closest to `fallback` (or to 0) whose edge averages are the
///   height's differences: `g + A⁺(D z − A g)`, one tridiagonal solve per run. A run of one
///   pixel keeps `fallback`'s value (or 0).
///
/// Pixels outside take `fallback`'s values (or 0). `fallback` must have the height's size.
#[must_use]
pub fn gradients_of_height(
    z: &Plane,
    domain: Option<&[f32]>,
    fallback: Option<&GradientField>,
    differences: Differences,
) -> GradientField {
    if differences == Differences::Averaged {
        return averaged_gradients_of_height(z, domain, fallback);
    }
    let Some(m) = domain else {
        return GradientField::from_height(z);
    };
    let (w, h) = (z.width(), z.height());
    let d = z.data();
    let mut out = GradientField::zeros(w, h);
    out.p
        .par_chunks_mut(w)
        .zip(out.q.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, (pr, qr))| {
            for x in 0..w {
                let i = r * w + x;
                let (fp, fq) = fallback.map_or((0.0, 0.0), |f| (f.p[i], f.q[i]));
                if !inside(m[i]) {
                    (pr[x], qr[x]) = (fp, fq);
                    continue;
                }
                pr[x] = if x + 1 < w && inside(m[i + 1]) {
                    d[i + 1] - d[i]
                } else if x >= 1 && inside(m[i - 1]) {
                    d[i] - d[i - 1]
                } else {
                    fp
                };
                qr[x] = if r >= 1 && inside(m[i - w]) {
                    d[i - w] - d[i]
                } else if r + 1 < h && inside(m[i + w]) {
                    d[i] - d[i + w]
                } else {
                    fq
                };
            }
        });
    out
}

/// One line (row or column, read through `at(k)`) of the averaged projection: `z`, `g`, `ins`
/// give height, sample and membership at index `k`; the height difference of edge
/// `k → k+1` is `dz(k)`. Writes the new samples through `out`.
fn averaged_line(
    n: usize,
    ins: impl Fn(usize) -> bool,
    dz: impl Fn(usize) -> f64,
    g: impl Fn(usize) -> f64,
    mut out: impl FnMut(usize, f32),
    y: &mut Vec<f64>,
    cp: &mut Vec<f64>,
) {
    let mut k = 0;
    while k < n {
        if !ins(k) {
            out(k, g(k) as f32);
            k += 1;
            continue;
        }
        let a = k;
        while k < n && ins(k) {
            k += 1;
        }
        let len = k - a;
        if len == 1 {
            out(a, g(a) as f32);
            continue;
        }
        // Minimum-norm δ with ½(δ_j + δ_{j+1}) = e_j (j < len−1): δ = Aᵀ y with
        // (A Aᵀ) y = e, i.e. tridiag(1, 2, 1) y = 4 e (Thomas; SPD).
        let m = len - 1;
        y.clear();
        cp.clear();
        let mut prev_c = 0.0f64;
        let mut prev_y = 0.0f64;
        for j in 0..m {
            let e = dz(a + j) - 0.5 * (g(a + j) + g(a + j + 1));
            let den = 2.0 - prev_c;
            let c = 1.0 / den;
            let v = (4.0 * e - prev_y) / den;
            cp.push(c);
            y.push(v);
            (prev_c, prev_y) = (c, v);
        }
        for j in (0..m.saturating_sub(1)).rev() {
            let next = y[j + 1];
            y[j] -= cp[j] * next;
        }
        for j in 0..len {
            let left = if j >= 1 { y[j - 1] } else { 0.0 };
            let right = if j < m { y[j] } else { 0.0 };
            out(a + j, (g(a + j) + 0.5 * (left + right)) as f32);
        }
    }
}

fn averaged_gradients_of_height(
    z: &Plane,
    domain: Option<&[f32]>,
    fallback: Option<&GradientField>,
) -> GradientField {
    let (w, h) = (z.width(), z.height());
    let d = z.data();
    let ins = |i: usize| domain.is_none_or(|m| inside(m[i]));
    let fp = |i: usize| fallback.map_or(0.0, |f| f64::from(f.p[i]));
    let fq = |i: usize| fallback.map_or(0.0, |f| f64::from(f.q[i]));
    let mut out = GradientField::zeros(w, h);
    out.p.par_chunks_mut(w.max(1)).enumerate().for_each_init(
        || (Vec::new(), Vec::new()),
        |(y, cp), (r, pr)| {
            let o = r * w;
            averaged_line(
                w,
                |k| ins(o + k),
                |k| f64::from(d[o + k + 1]) - f64::from(d[o + k]),
                |k| fp(o + k),
                |k, v| pr[k] = v,
                y,
                cp,
            );
        },
    );
    // Columns top to bottom: edge k → k+1 is z(k) − z(k+1) = ½(q(k) + q(k+1)).
    let cols: Vec<Vec<f32>> = (0..w)
        .into_par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(y, cp), x| {
                let mut col = vec![0.0f32; h];
                averaged_line(
                    h,
                    |k| ins(k * w + x),
                    |k| f64::from(d[k * w + x]) - f64::from(d[(k + 1) * w + x]),
                    |k| fq(k * w + x),
                    |k, v| col[k] = v,
                    y,
                    cp,
                );
                col
            },
        )
        .collect();
    out.q
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(r, qr)| {
            for (o, col) in qr.iter_mut().zip(&cols) {
                *o = col[r];
            }
        });
    out.clamped = 0;
    out
}

/// The edge value of a horizontal edge `i → i+1` in a model (module docs).
#[inline(always)]
fn edge_p(g: &GradientField, d: Differences, i: usize) -> f32 {
    match d {
        Differences::Forward => g.p[i],
        Differences::Averaged => 0.5 * (g.p[i] + g.p[i + 1]),
    }
}

/// The edge value of a vertical edge `i → i−w` in a model (module docs).
#[inline(always)]
fn edge_q(g: &GradientField, d: Differences, i: usize) -> f32 {
    match d {
        Differences::Forward => g.q[i],
        Differences::Averaged => 0.5 * (g.q[i] + g.q[i - g.width]),
    }
}

/// RMS over the domain's edge equations of `D z − e` (`e` the model's edge values), or of `e`
/// itself when `z` is `None`.
fn edge_rms(z: Option<&[f32]>, g: &GradientField, domain: Option<&[f32]>, d: Differences) -> f64 {
    let (w, h) = (g.width, g.height);
    let dz = |i: usize, j: usize| z.map_or(0.0, |v| v[j] - v[i]);
    let ins = |i: usize| domain.is_none_or(|m| inside(m[i]));
    let (s, n) = (0..h)
        .into_par_iter()
        .map(|r| {
            let (mut s, mut n) = (0.0f64, 0usize);
            for x in 0..w {
                let i = r * w + x;
                if x + 1 < w && ins(i) && ins(i + 1) {
                    let e = f64::from(dz(i, i + 1) - edge_p(g, d, i));
                    s += e * e;
                    n += 1;
                }
                if r >= 1 && ins(i) && ins(i - w) {
                    let e = f64::from(dz(i, i - w) - edge_q(g, d, i));
                    s += e * e;
                    n += 1;
                }
            }
            (s, n)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// Row `r` of the divergence `b = Dᵀ e` (module docs) of the model's edge values into `out`;
/// with a domain only edges inside it count.
fn divergence_row(
    g: &GradientField,
    domain: Option<&[f32]>,
    d: Differences,
    r: usize,
    out: &mut [f32],
) {
    let (w, h) = (g.width, g.height);
    let row = r * w..(r + 1) * w;
    let Some(m) = domain else {
        if d == Differences::Averaged {
            return averaged_divergence_row(g, r, out);
        }
        // Every edge counts: p(x−1) − p(x) (ends dropped), + q below, − q here.
        let p = &g.p[row.clone()];
        out[0] = 0.0;
        out[1..].copy_from_slice(&p[..w - 1]);
        for (o, v) in out[..w - 1].iter_mut().zip(p) {
            *o -= v;
        }
        if r + 1 < h {
            for (o, v) in out.iter_mut().zip(&g.q[row.start + w..row.end + w]) {
                *o += v;
            }
        }
        if r >= 1 {
            for (o, v) in out.iter_mut().zip(&g.q[row]) {
                *o -= v;
            }
        }
        return;
    };
    let ins = |i: usize| inside(m[i]);
    for (x, o) in out.iter_mut().enumerate() {
        let i = r * w + x;
        let mut s = 0.0f32;
        if ins(i) {
            if x >= 1 && ins(i - 1) {
                s += edge_p(g, d, i - 1);
            }
            if x + 1 < w && ins(i + 1) {
                s -= edge_p(g, d, i);
            }
            if r + 1 < h && ins(i + w) {
                s += edge_q(g, d, i + w);
            }
            if r >= 1 && ins(i - w) {
                s -= edge_q(g, d, i);
            }
        }
        *o = s;
    }
}

/// Row `r` of the full-rectangle divergence of the averaged edge values, straight from the
/// samples (no edge-value buffer): inside, `½(p(x−1) − p(x+1)) + ½(q(r+1) − q(r−1))`; the
/// border terms keep their one edge.
fn averaged_divergence_row(g: &GradientField, r: usize, out: &mut [f32]) {
    let (w, h) = (g.width, g.height);
    let p = &g.p[r * w..(r + 1) * w];
    // x: e_p(x−1) − e_p(x) with e_p(x) = ½(p(x) + p(x+1)), x ≤ W−2.
    if w == 1 {
        out[0] = 0.0;
    } else {
        out[0] = -0.5 * (p[0] + p[1]);
        for (x, o) in out.iter_mut().enumerate().take(w - 1).skip(1) {
            *o = 0.5 * (p[x - 1] - p[x + 1]);
        }
        out[w - 1] = 0.5 * (p[w - 2] + p[w - 1]);
    }
    // y: e_q(r+1) − e_q(r) with e_q(r) = ½(q(r) + q(r−1)), r ≥ 1.
    let q = |k: usize| &g.q[k * w..(k + 1) * w];
    let qc = q(r);
    match (r >= 1, r + 1 < h) {
        (true, true) => {
            for ((o, a), b) in out.iter_mut().zip(q(r + 1)).zip(q(r - 1)) {
                *o += 0.5 * (a - b);
            }
        }
        (false, true) => {
            for ((o, a), b) in out.iter_mut().zip(q(r + 1)).zip(qc) {
                *o += 0.5 * (a + b);
            }
        }
        (true, false) => {
            for ((o, a), b) in out.iter_mut().zip(qc).zip(q(r - 1)) {
                *o -= 0.5 * (a + b);
            }
        }
        (false, false) => {}
    }
}
#[cfg(test)]
mod tests {
    use super::test_util::*;
    use super::*;
    use crate::raster::buf;
    use crate::raster::gradient::gradient_of_normal;
    use crate::raster::sample::Surface;

    /// A deterministic uniform noise field in [−1, 1] (64-bit LCG).
    fn noise_field(w: usize, h: usize, seed: u64) -> GradientField {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        let p = (0..w * h).map(|_| next()).collect();
        let q = (0..w * h).map(|_| next()).collect();
        GradientField {
            width: w,
            height: h,
            p,
            q,
            clamped: 0,
        }
    }

    fn disc_mask(w: usize, h: usize) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, r) = (
                    (i % w) as f64 - w as f64 / 2.0,
                    (i / w) as f64 - h as f64 / 2.0,
                );
                f32::from(u8::from(x * x + 1.5 * r * r < (w as f64 * 0.4).powi(2)))
            })
            .collect()
    }

    #[test]
    fn non_integrable_fraction_is_zero_for_a_height_and_near_root_two_over_pi_for_noise() {
        let (w, h) = (96, 80);
        let s = Surface::gaussians_for(96);
        let z = Plane::from_fn(w, h, |x, r| {
            s.height(x as f64 - 48.0, 40.0 - r as f64) as f32
        });
        // The samples of a height in the default (averaged) model: exactly integrable.
        let g = gradients_of_height(&z, None, None, Differences::Averaged);
        let m = disc_mask(w, h);
        for mask in [None, Some(&m[..])] {
            let f = non_integrable_fraction(&g, mask).unwrap();
            assert!(f < 1e-4, "height, mask {}: F = {f}", mask.is_some());
            // White noise samples: their edge averages are low-pass noise (spectrum
            // cos²(ω/2) per axis), of which the gradient part has the fraction 1 − 2/π of
            // the energy (the mean over the frequencies of
            // (s_x c_x + s_y c_y)/(s_x + s_y), s = sin²(ω/2), c = cos²(ω/2)): F ≈ √(2/π) ≈ 0.80
            // (the forward model's √½ for white edge values).
            let n = noise_field(w, h, 7);
            let f = non_integrable_fraction(&n, mask).unwrap();
            assert!(
                (0.74..0.83).contains(&f),
                "noise, mask {}: F = {f}",
                mask.is_some()
            );
            // Scale-free, unlike the relative curl when gradient energy is added.
            let scaled = GradientField {
                p: n.p.iter().map(|v| v * 8.0).collect(),
                q: n.q.iter().map(|v| v * 8.0).collect(),
                ..n.clone()
            };
            let fs = non_integrable_fraction(&scaled, mask).unwrap();
            assert!((fs - f).abs() < 1e-4, "{fs} vs {f}");
        }
        // The sum of a surface and noise of equal energy: between the two.
        let n = noise_field(w, h, 9);
        let rms =
            |v: &[f32]| (v.iter().map(|a| f64::from(a * a)).sum::<f64>() / v.len() as f64).sqrt();
        let k = (rms(&g.p) + rms(&g.q)) / (rms(&n.p) + rms(&n.q));
        let mixed = GradientField {
            p: g.p
                .iter()
                .zip(&n.p)
                .map(|(a, b)| a + k as f32 * b)
                .collect(),
            q: g.q
                .iter()
                .zip(&n.q)
                .map(|(a, b)| a + k as f32 * b)
                .collect(),
            ..g.clone()
        };
        let f = non_integrable_fraction(&mixed, None).unwrap();
        assert!((0.3..0.62).contains(&f), "mixed F = {f}");
        assert_eq!(
            non_integrable_fraction(&GradientField::zeros(8, 8), None).unwrap(),
            0.0
        );
    }

    #[test]
    fn the_wrong_green_convention_reads_as_non_integrable() {
        let (w, h) = (96, 96);
        let s = Surface::gaussians_for(96);
        let z = Plane::from_fn(w, h, |x, r| {
            s.height(x as f64 - 48.0, 48.0 - r as f64) as f32
        });
        let g = gradients_of_height(&z, None, None, Differences::Averaged);
        let mut img = RgbnImage::flat(w, h, [0.5; 3]);
        g.write_normals(&mut img);
        let [gl, dx] = green_convention_fractions(&img).unwrap();
        assert!(gl < 1e-3 && dx > 0.1, "as stored {gl}, flipped {dx}");
        // The same image stored the other way round reads the other way round.
        let [x, y, zz] = img.normal();
        let flipped = img
            .with_normals([x.to_vec(), y.iter().map(|v| -v).collect(), zz.to_vec()])
            .unwrap();
        let [a, b] = green_convention_fractions(&flipped).unwrap();
        assert!((a - dx).abs() < 1e-6 && (b - gl).abs() < 1e-6, "{a} {b}");
    }

    #[test]
    fn forward_differences_recover_analytic_surfaces_at_the_staggered_position() {
        let size = 128;
        let c = size as f64 / 2.0;
        // Sum of Gaussians (zero slope at the borders): DCT and masked solvers.
        let s = Surface::gaussians_for(size);
        let (img, z_centre) = s.render(size, size);
        let z_stag = Plane::from_fn(size, size, |x, r| {
            s.height(x as f64 - 0.5 - c, c - r as f64 - 0.5) as f32
        });
        let amp = z_stag.data().iter().fold(0.0f32, |a, &v| a.max(v.abs()));
        for method in [
            IntegrationMethod::PoissonDct,
            IntegrationMethod::FrankotChellappa,
        ] {
            let params = IntegrateParams {
                method,
                differences: Differences::Forward,
                ..Default::default()
            };
            let (zi, _) = integrate_normals(&img, &params).unwrap();
            let rmse = rmse_up_to_constant(&zi, &z_stag, None);
            let rmse_centre = rmse_up_to_constant(&zi, &z_centre, None);
            eprintln!(
                "gaussians {size}² {method:?}: RMSE {rmse:.5} px (vs centre samples \
                 {rmse_centre:.4} px), amplitude {amp:.1} px"
            );
            assert!(rmse < 0.06, "{method:?}: {rmse}");
            // Normals of the integrated height are integrable.
            let g = GradientField::from_height(&zi);
            assert!(g.curl_stats_forward(None).relative < 1e-5);
        }

        // A spherical cap (radius R, cut at ρ = a) on a flat plane: a kink at the rim.
        let (rr, a) = (0.5 * size as f64, 0.35 * size as f64);
        let cap = |u: f64, v: f64| {
            let rho2 = u * u + v * v;
            if rho2 < a * a {
                (rr * rr - rho2).sqrt() - (rr * rr - a * a).sqrt()
            } else {
                0.0
            }
        };
        let sphere = Surface::Sphere { radius_px: rr };
        let n = size * size;
        let mut normal = [
            buf::zeroed_f32(n),
            buf::zeroed_f32(n),
            buf::filled_f32(n, 1.0),
        ];
        for i in 0..n {
            let (u, v) = ((i % size) as f64 - c, c - (i / size) as f64);
            if u * u + v * v < a * a {
                let [p, q] = sphere.gradient(u, v).unwrap();
                let nn = crate::raster::gradient::normal_of_gradient(p as f32, q as f32);
                for (plane, v) in normal.iter_mut().zip(nn) {
                    plane[i] = v;
                }
            }
        }
        let col = [vec![0.5; n], vec![0.5; n], vec![0.5; n]];
        let img = RgbnImage::new(size, size, col, normal, None).unwrap();
        let z_stag = Plane::from_fn(size, size, |x, r| {
            cap(x as f64 - 0.5 - c, c - r as f64 - 0.5) as f32
        });
        let forward = IntegrateParams {
            differences: Differences::Forward,
            ..Default::default()
        };
        let (zi, _) = integrate_normals(&img, &forward).unwrap();
        let rmse = rmse_up_to_constant(&zi, &z_stag, None);
        let cap_h = cap(0.0, 0.0);
        eprintln!("sphere cap {size}² (height {cap_h:.1} px): DCT forward RMSE {rmse:.4} px");
        assert!(rmse < 0.1, "{rmse}");
        // The default (averaged) model at the pixel centres.
        let z_centre = Plane::from_fn(size, size, |x, r| cap(x as f64 - c, c - r as f64) as f32);
        let (zi, _) = integrate_normals(&img, &IntegrateParams::default()).unwrap();
        let rmse = rmse_up_to_constant(&zi, &z_centre, None);
        eprintln!("sphere cap {size}²: DCT averaged RMSE {rmse:.4} px at pixel centres");
        assert!(rmse < 0.1, "{rmse}");
        let (out, _, rep) = project_integrable(&img, &ProjectParams::default()).unwrap();
        eprintln!(
            "sphere cap projection: relative curl {:.2e} → {:.2e}",
            rep.before.relative, rep.after.relative
        );
        assert!(rep.after.relative < 1e-4 && out.validate().is_clean());
    }

    /// Pixel-centre samples of a surface of revolution `z = f(ρ)` about the image centre
    /// (`u = x − c`, `v = c − row`): the image (normals written from the analytic gradients,
    /// mask given) and the true heights at pixel centres.
    fn revolution(
        size: usize,
        f: &(dyn Fn(f64) -> f64 + Sync),
        df: &(dyn Fn(f64) -> f64 + Sync),
        mask: Option<Vec<f32>>,
    ) -> (RgbnImage, Plane) {
        let c = size as f64 / 2.0;
        let uv = |i: usize| ((i % size) as f64 - c, c - (i / size) as f64);
        let mut g = GradientField::zeros(size, size);
        for i in 0..size * size {
            let (u, v) = uv(i);
            let rho = u.hypot(v);
            if rho > 0.0 {
                g.p[i] = (df(rho) * u / rho) as f32;
                g.q[i] = (df(rho) * v / rho) as f32;
            }
        }
        let col = [
            vec![0.5; size * size],
            vec![0.5; size * size],
            vec![0.5; size * size],
        ];
        let mut img = RgbnImage::new(size, size, col, g.to_normals(), mask).unwrap();
        g.write_normals(&mut img);
        let z = Plane::from_fn(size, size, |x, r| {
            let (u, v) = uv(r * size + x);
            f(u.hypot(v)) as f32
        });
        (img, z)
    }

    /// An irregular mask: a wobbly disc of radius ≤ `rm` with a round hole.
    fn wobbly_mask(size: usize, rm: f64) -> Vec<f32> {
        let c = size as f64 / 2.0;
        (0..size * size)
            .map(|i| {
                let (u, v) = ((i % size) as f64 - c, c - (i / size) as f64);
                let th = v.atan2(u);
                let edge = rm * (0.86 + 0.14 * (3.0 * th + 0.4).sin());
                let hole = (u - 0.3 * rm).hypot(v + 0.2 * rm) < 0.12 * rm;
                f32::from(u8::from(u.hypot(v) < edge && !hole))
            })
            .collect()
    }

    #[test]
    fn steep_surfaces_are_recovered_at_pixel_centres_inside_an_irregular_mask() {
        // Slopes up to 10 px/px, normals sampled at pixel centres, masked_poisson: the averaged
        // model registers the height at the centres; the forward model is half a pixel off.
        let size = 160;
        let (rs, k) = (70.0f64, 1.0 / 14.0);
        let a = rs * 10.0 / 101f64.sqrt(); // sphere slope 10 at ρ = a
        let sphere = |r: f64| (rs * rs - r.min(a).powi(2)).sqrt();
        let dsphere = |r: f64| -r.min(a) / (rs * rs - r.min(a).powi(2)).sqrt();
        let para = |r: f64| k * r * r;
        let dpara = |r: f64| 2.0 * k * r;
        let vase = |r: f64| -30.0 * ((r - 40.0) / 3.0).tanh();
        let dvase = |r: f64| -10.0 / ((r - 40.0) / 3.0).cosh().powi(2);
        type Radial<'a> = &'a (dyn Fn(f64) -> f64 + Sync);
        let cases: [(&str, Radial, Radial, f64); 3] = [
            ("sphere cap", &sphere, &dsphere, a),
            ("paraboloid", &para, &dpara, 70.0),
            ("vase (tanh profile)", &vase, &dvase, 70.0),
        ];
        for (name, f, df, rm) in cases {
            let mask = wobbly_mask(size, rm);
            let (img, z) = revolution(size, f, df, Some(mask.clone()));
            let max_slope = (0..size * size)
                .filter(|&i| mask[i] > 0.5)
                .map(|i| {
                    let [p, q] = gradient_of_normal([
                        img.normal()[0][i],
                        img.normal()[1][i],
                        img.normal()[2][i],
                    ]);
                    p.hypot(q)
                })
                .fold(0.0f32, f32::max);
            let mut rmse = [0.0; 2];
            for (j, differences) in [Differences::Averaged, Differences::Forward]
                .into_iter()
                .enumerate()
            {
                let params = IntegrateParams {
                    method: IntegrationMethod::MaskedPoisson,
                    differences,
                    ..Default::default()
                };
                let (zi, rep) = integrate_normals(&img, &params).unwrap();
                rmse[j] = rmse_up_to_constant(&zi, &z, Some(&mask));
                eprintln!(
                    "{name} {size}² (max slope {max_slope:.2}): masked_poisson {differences:?} \
                     RMSE {:.4} px at pixel centres ({} CG iterations)",
                    rmse[j], rep.iterations
                );
                assert!(rep.relative_residual <= 1e-6, "{rep:?}");
            }
            assert!(max_slope > 9.0, "{name}: {max_slope}");
            assert!(rmse[0] <= 0.15, "{name}: averaged RMSE {}", rmse[0]);
            assert!(
                rmse[1] > 4.0 * rmse[0],
                "{name}: forward {} vs averaged",
                rmse[1]
            );
        }
    }

    #[test]
    fn gentle_surfaces_come_back_within_a_hundredth_of_a_pixel() {
        let size = 128;
        let c = size as f64 / 2.0;
        // Two Gaussian bumps, slopes ≤ 1: DCT (full rectangle) and masked (irregular mask).
        let bump = |u: f64, v: f64, a: f64, s: f64| a * (-(u * u + v * v) / (2.0 * s * s)).exp();
        let f = |u: f64, v: f64| {
            bump(u - 10.0, v + 5.0, 25.0, 20.0) - bump(u + 25.0, v - 20.0, 6.0, 12.0)
        };
        let grad = |u: f64, v: f64| {
            let (a, b) = (
                bump(u - 10.0, v + 5.0, 25.0, 20.0),
                bump(u + 25.0, v - 20.0, 6.0, 12.0),
            );
            [
                -a * (u - 10.0) / 400.0 + b * (u + 25.0) / 144.0,
                -a * (v + 5.0) / 400.0 + b * (v - 20.0) / 144.0,
            ]
        };
        // A periodic surface for Frankot–Chellappa: two periods along x, one along y.
        let tau = std::f64::consts::TAU;
        let (kx, ky) = (2.0 * tau / size as f64, tau / size as f64);
        let per = |u: f64, v: f64| 8.0 * (kx * u).sin() * (ky * v).cos();
        let dper = |u: f64, v: f64| {
            [
                8.0 * kx * (kx * u).cos() * (ky * v).cos(),
                -8.0 * ky * (kx * u).sin() * (ky * v).sin(),
            ]
        };
        type Surf<'a> = (
            &'a (dyn Fn(f64, f64) -> f64 + Sync),
            &'a dyn Fn(f64, f64) -> [f64; 2],
        );
        let mask = wobbly_mask(size, 60.0);
        let cases: [(IntegrationMethod, Surf, bool); 3] = [
            (IntegrationMethod::PoissonDct, (&f, &grad), false),
            (IntegrationMethod::MaskedPoisson, (&f, &grad), true),
            (IntegrationMethod::FrankotChellappa, (&per, &dper), false),
        ];
        for (method, (f, df), masked) in cases {
            let uv = |x: usize, r: usize| (x as f64 - c, c - r as f64);
            let mut g = GradientField::zeros(size, size);
            let mut max_slope = 0.0f64;
            for r in 0..size {
                for x in 0..size {
                    let (u, v) = uv(x, r);
                    let [p, q] = df(u, v);
                    max_slope = max_slope.max(p.hypot(q));
                    g.p[r * size + x] = p as f32;
                    g.q[r * size + x] = q as f32;
                }
            }
            let z = Plane::from_fn(size, size, |x, r| {
                let (u, v) = uv(x, r);
                f(u, v) as f32
            });
            let m = masked.then_some(&mask[..]);
            let params = IntegrateParams {
                method,
                ..Default::default()
            };
            let (zi, _) = integrate_gradients(&g, m, &params).unwrap();
            let rmse = rmse_up_to_constant(&zi, &z, m);
            let max = max_err_up_to_constant(&zi, &z, m);
            eprintln!(
                "gentle {method:?} (max slope {max_slope:.2}): RMSE {rmse:.5} px, max {max:.5} px"
            );
            assert!(max_slope <= 1.0 && max_slope > 0.3);
            assert!(max <= 0.01, "{method:?}: max error {max}");
        }
    }

    #[test]
    fn height_round_trips_through_exr() {
        let z = rough(13, 7);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("h.exr");
        crate::raster::io::save_plane_exr(&z, "Z", &path).unwrap();
        let img = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
        let ch = &img.layer_data.channel_data.list[0];
        assert_eq!(ch.name.to_string(), "Z");
        let back: Vec<f32> = ch.sample_data.values_as_f32().collect();
        assert_eq!(back, z.data());
        assert!(crate::raster::io::save_plane_exr(&z, "Z", &dir.path().join("h.png")).is_err());
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let g = GradientField::zeros(8, 8);
        let empty = buf::zeroed_f32(64);
        for method in [
            IntegrationMethod::PoissonDct,
            IntegrationMethod::FrankotChellappa,
            IntegrationMethod::MaskedPoisson,
        ] {
            let params = IntegrateParams {
                method,
                ..Default::default()
            };
            let e = integrate_gradients(&g, Some(&empty), &params).unwrap_err();
            assert!(matches!(e, RgbnError::EmptyMask { .. }), "{e}");
        }
        let e = integrate_gradients(&g, Some(&[1.0; 10]), &IntegrateParams::default());
        assert!(matches!(e, Err(RgbnError::InvalidImage(_))));
        let bad = IntegrateParams {
            tolerance: 0.0,
            ..Default::default()
        };
        assert!(integrate_gradients(&g, None, &bad).is_err());
        let bad = IntegrateParams {
            max_iterations: 0,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
        for beta in [0.5, 10.5, f64::NAN] {
            let bad = IntegrateParams {
                over_relaxation: beta,
                ..Default::default()
            };
            let e = bad.validate().unwrap_err();
            assert!(
                matches!(e, RgbnError::InvalidParam { ref name, .. } if name == "over_relaxation"),
                "{e}"
            );
        }
        // A single pixel and an isolated masked pixel work.
        let one = GradientField::zeros(1, 1);
        let (z, _) = integrate_gradients(&one, None, &IntegrateParams::default()).unwrap();
        assert_eq!(z.data(), &[0.0]);
        let mut m = buf::zeroed_f32(64);
        m[9] = 1.0;
        let params = IntegrateParams {
            method: IntegrationMethod::MaskedPoisson,
            ..Default::default()
        };
        let (z, _) = integrate_gradients(&g, Some(&m), &params).unwrap();
        assert!(z.data().iter().all(|v| v.is_finite()));
        // A mask of several pixels with no two neighbours inside: no edge, a one-line error
        // naming the mask.
        m[27] = 1.0;
        let e = integrate_gradients(&g, Some(&m), &params).unwrap_err();
        assert!(
            matches!(e, RgbnError::InvalidParam { ref name, .. } if name == "mask"),
            "{e}"
        );
        assert!(!e.to_string().contains('\n'), "{e}");
        // A single-pixel component next to a real one: height 0, counted, never NaN.
        let g = noise_field(8, 8, 3);
        let mut m = buf::zeroed_f32(64);
        for i in [0, 1, 2, 8, 9, 10, 36] {
            m[i] = 1.0;
        }
        let (z, rep) = integrate_gradients(&g, Some(&m), &params).unwrap();
        assert!(z.data().iter().all(|v| v.is_finite()));
        assert_eq!(z.data()[36], 0.0);
        assert_eq!((rep.domain_pixels, rep.isolated_pixels), (7, 1), "{rep:?}");
        let mean = [0, 1, 2, 8, 9, 10]
            .iter()
            .map(|&i| z.data()[i])
            .sum::<f32>();
        assert!(mean.abs() < 1e-4, "{mean}");
    }
}
