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
mod green;
mod masked;
mod multigrid;
pub mod perspective;
mod projection;
mod support;
#[cfg(test)]
mod test_util;

pub use green::{green_convention, GreenConvention, GreenEvidence, GreenVerdict, Uncertainty};
pub use perspective::{Camera, Pinhole};
pub use projection::{project_integrable, ProjectParams, ProjectionReport};
pub use support::{integrable_edit, project_in_support, SupportProjection};

pub use super::gradient::Differences;
use super::gradient::GradientField;
use super::{Plane, RgbnImage};
use crate::error::RgbnError;
use crate::raster::par::OrderedReduce;
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
    /// Bilateral normal integration (Cao et al. 2022, `bini` source docs): iteratively
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
    /// extrapolated when that lowers the energy (`bini` docs); 1 = the plain steps of the
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
    // Cancelled: the result is discarded, its residual not measured (crate::cancel).
    if crate::cancel::Cancel::current().is_cancelled() {
        return Ok((z, report));
    }
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
/// gradient of a height (to rounding), **√(2/π) ≈ 0.798 for i.i.d. noise samples** (below), 1
/// for a pure curl field. Scale-free: unlike the relative curl it does not fall when an edit
/// only adds gradient energy. A zero field reads 0.
///
/// **F of noise.** Let `p`, `q` be i.i.d. with variance `σ²` on a large grid and work per
/// frequency `(ω₁, ω₂)` (periodic approximation). Write `sᵢ = sin²(ωᵢ/2)`, `cᵢ = cos²(ωᵢ/2)`.
/// The averaged edge values `½(p(x) + p(x+1))`, `½(q(y) + q(y+1))` have transfer functions of
/// squared modulus `c₁`, `c₂`, so their expected energy is `σ²(c₁ + c₂)`. The differences of a
/// height have transfer functions of squared modulus `4s₁`, `4s₂`; the projection of the edge
/// values onto them keeps `σ²(4s₁c₁ + 4s₂c₂)/(4s₁ + 4s₂)`, leaving in the curl part
/// `σ²(c₁s₂ + c₂s₁)/(s₁ + s₂) = σ²(1 − 2s₁s₂/(s₁ + s₂))` (with `c = 1 − s`). Averaged over
/// the frequencies (each `sᵢ` arcsine-distributed on [0, 1]; the energy `c₁ + c₂` averages 1):
/// `F² = 1 − 2·E[s₁s₂/(s₁ + s₂)]`. For fixed `s₁ = a`, `E_{s₂}[a s₂/(a + s₂)] = a −
/// a^{3/2}/√(1 + a)` (from `(1/π)∫₀^π dθ/(a + sin²(θ/2)) = 1/√(a(1 + a))`), and with `a =
/// sin²φ`, `E[a^{3/2}/√(1 + a)] = (2/π)∫₀¹ (1 − c²)/√(2 − c²) dc = (2/π)·½`. So `E[s₁s₂/(s₁ +
/// s₂)] = ½ − 1/π` and **`F² = 2/π`**. (The forward model, whose edge values are the samples
/// themselves, gives `F² = ½`, `F ≈ 0.707`.) Checked: 512 × 512 uniform samples read 0.79–0.80
/// (`tests/it/gallery.rs`, the noise row of `docs/gallery.md`).
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
        .ordered_reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
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
mod tests;
