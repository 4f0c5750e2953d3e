//! Robust per-pixel regressions for photometric stereo ([`super::photometric`]): L1 by
//! iteratively reweighted least squares, and sparse Bayesian learning (SBL).
//!
//! Both solve, per pixel, `g = L b + e` for the scaled normal `b = ρ n` from the `k` usable
//! grey observations `g_j` and unit light directions `l_j` (the rows of `L`), where the error
//! `e` is **sparse**: most observations are Lambertian, a few are shadows (the model predicts
//! light where there is none) or highlights (far brighter than the model). Least squares
//! spreads such errors over every observation; these estimators isolate them.
//!
//! # L1 by IRLS
//!
//! `b = argmin Σ_j |g_j − l_j · b|`, the maximum-likelihood fit under Laplacian errors and the
//! convex relaxation of "fewest outliers" (Ikehata et al. 2012, §3). Iteratively reweighted
//! least squares: start from least squares `b⁰`; at step `t` weight each observation by
//! `w_j = 1 / max(|r_j|, δ)`, `r_j = g_j − l_j · bᵗ`, and solve the weighted normal equations
//! `(Σ w_j l_j l_jᵀ) bᵗ⁺¹ = Σ w_j l_j g_j`. Each step does not increase the L1 cost (a
//! majorise–minimise step; δ = [`RobustParams::l1_delta`] × the pixel's brightest observation
//! keeps the weights finite where a residual is zero). Stop when `‖bᵗ⁺¹ − bᵗ‖ ≤ tol · ‖bᵗ⁺¹‖`
//! or after [`RobustParams::max_iterations`].
//!
//! # Sparse Bayesian learning (Ikehata, Wipf, Matsushita & Aizawa 2012, §4)
//!
//! The model `y = L x + e + ε` with observations scaled by the pixel's brightest one
//! (`y = g / g_max`, so the noise level is relative), dense noise `ε ~ N(0, λ I)`, a flat prior
//! on `x`, and an independent zero-mean Gaussian prior `e_j ~ N(0, γ_j)` per observation whose
//! variances `γ` are learnt by maximising the evidence `p(y | γ)`; at the optimum most `γ_j`
//! are 0 (those observations are inliers) and the rest absorb the outliers. With a flat prior
//! on `x` (the limit of `N(0, αI)`, `α → ∞`), `Σ_y = λI + Γ + α L Lᵀ` and, writing
//! `d_j = 1 / (λ + γ_j)` and `M = Σ_j d_j l_j l_jᵀ`,
//!
//! - `Σ_y⁻¹ → D − D L M⁻¹ Lᵀ D`, so `Σ_y⁻¹ y = D (y − L x̂)` with `x̂ = M⁻¹ Σ_j d_j l_j y_j`,
//!   the weighted least-squares fit: everything per pixel stays `3 × 3`;
//! - the posterior of `e` has mean `μ_j = γ_j d_j r_j` (`r_j = y_j − l_j · x̂`) and variances
//!   `Σ_jj = γ_j − γ_j² (d_j − d_j² l_jᵀ M⁻¹ l_j)`;
//! - the EM update of the variances is `γ_j ← μ_j² + Σ_jj` (Wipf & Rao 2004).
//!
//! A pixel whose least-squares start already fits every observation within
//! [`RobustParams::clean_residual`] of its brightest one (1 %: the noise level of the data) has
//! nothing sparse to remove and keeps the start; the others iterate.
//!
//! So each iteration is one weighted least squares with weights `d_j`; observations whose
//! error variance grows are weighted out, smoothly. `γ` starts at the squared residuals of the
//! least-squares start (plus λ). The result is `b = g_max · x̂`.
//!
//! # References
//!
//! - S. Ikehata, D. Wipf, Y. Matsushita, K. Aizawa, "Robust photometric stereo using sparse
//!   regression", CVPR 2012.
//! - D. Wipf, B. Rao, "Sparse Bayesian learning for basis selection", IEEE Trans. Signal
//!   Processing 52(8), 2004.
//! - M. E. Tipping, "Sparse Bayesian learning and the relevance vector machine", JMLR 1, 2001.
//! - P. W. Holland, R. E. Welsch, "Robust regression using iteratively reweighted
//!   least-squares", Communications in Statistics 6(9), 1977.

use super::linalg::{dot3, inverse3, mul3};

/// Settings of the robust estimators (module docs); the defaults are the measured ones of
/// `docs/capture.md`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RobustParams {
    /// Most reweighting iterations per pixel, ≥ 1.
    pub max_iterations: usize,
    /// Stop when the solution moves less than this, relative to its length, > 0.
    pub tolerance: f64,
    /// L1: the smallest residual in a weight `1 / max(|r|, δ)`, relative to the pixel's
    /// brightest observation, > 0.
    pub l1_delta: f64,
    /// SBL: the dense-noise variance λ, relative to the squared brightest observation, > 0.
    pub sbl_lambda: f64,
    /// A pixel whose least-squares start fits every observation within this fraction of its
    /// brightest one has no outlier to remove: it keeps the start (no iteration), ≥ 0.
    pub clean_residual: f64,
}

impl Default for RobustParams {
    fn default() -> Self {
        Self {
            max_iterations: 10,
            tolerance: 1e-3,
            l1_delta: 1e-3,
            sbl_lambda: 1e-3,
            clean_residual: 0.01,
        }
    }
}

/// Whether the fit `b` leaves every residual of `sel` within `p.clean_residual` of the
/// brightest observation (module docs: such a pixel is not iterated).
pub(super) fn is_clean(
    sel: &[usize],
    dirs: &[[f64; 3]],
    g: &[f64],
    b: [f64; 3],
    p: &RobustParams,
) -> bool {
    let gmax = sel.iter().map(|&j| g[j]).fold(0.0, f64::max);
    let tol = p.clean_residual * gmax;
    sel.iter().all(|&j| (g[j] - dot3(dirs[j], b)).abs() <= tol)
}

/// `(Σ w_j l_j l_jᵀ, Σ w_j l_j y_j)` over `sel`, weights and values by light index.
#[allow(clippy::needless_range_loop)]
fn weighted_normal_equations(
    sel: &[usize],
    w: &[f64],
    dirs: &[[f64; 3]],
    y: impl Fn(usize) -> f64,
) -> ([[f64; 3]; 3], [f64; 3]) {
    let mut a = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    for &j in sel {
        let (l, wj) = (dirs[j], w[j]);
        let wy = wj * y(j);
        for r in 0..3 {
            let wl = wj * l[r];
            for c in r..3 {
                a[r][c] += wl * l[c];
            }
            rhs[r] += wy * l[r];
        }
    }
    for r in 1..3 {
        for c in 0..r {
            a[r][c] = a[c][r];
        }
    }
    (a, rhs)
}

fn moved(old: [f64; 3], new: [f64; 3], tol: f64) -> bool {
    let d = [new[0] - old[0], new[1] - old[1], new[2] - old[2]];
    dot3(d, d) > tol * tol * dot3(new, new)
}

/// L1 regression by IRLS from `b0` over the observations `sel` (module docs). `w` (indexed by
/// light) receives the final weights. `None` if the weighted system degenerates at once.
pub(super) fn l1_irls(
    sel: &[usize],
    dirs: &[[f64; 3]],
    g: &[f64],
    b0: [f64; 3],
    w: &mut [f64],
    p: &RobustParams,
) -> Option<[f64; 3]> {
    let gmax = sel.iter().map(|&j| g[j]).fold(0.0, f64::max);
    let delta = (p.l1_delta * gmax).max(f64::MIN_POSITIVE);
    let mut b = b0;
    for _ in 0..p.max_iterations.max(1) {
        for &j in sel {
            w[j] = 1.0 / (g[j] - dot3(dirs[j], b)).abs().max(delta);
        }
        let (a, rhs) = weighted_normal_equations(sel, w, dirs, |j| g[j]);
        let Some(inv) = inverse3(&a) else {
            break;
        };
        let nb = mul3(&inv, rhs);
        let go_on = moved(b, nb, p.tolerance);
        b = nb;
        if !go_on {
            break;
        }
    }
    b.iter().all(|v| v.is_finite()).then_some(b)
}

/// Sparse Bayesian learning from `b0` over the observations `sel` (module docs). `gamma` and
/// `w` (indexed by light) are scratch; `w` receives the final weights `1 / (λ + γ_j)`.
pub(super) fn sbl(
    sel: &[usize],
    dirs: &[[f64; 3]],
    g: &[f64],
    b0: [f64; 3],
    gamma: &mut [f64],
    w: &mut [f64],
    p: &RobustParams,
) -> Option<[f64; 3]> {
    let gmax = sel.iter().map(|&j| g[j]).fold(0.0, f64::max);
    if !(gmax > 0.0 && gmax.is_finite()) {
        return None;
    }
    let s = 1.0 / gmax;
    let lambda = p.sbl_lambda;
    let mut x = b0.map(|v| v * s);
    for &j in sel {
        let r = g[j] * s - dot3(dirs[j], x);
        gamma[j] = r * r;
    }
    for _ in 0..p.max_iterations.max(1) {
        for &j in sel {
            w[j] = 1.0 / (lambda + gamma[j]);
        }
        let (a, rhs) = weighted_normal_equations(sel, w, dirs, |j| g[j] * s);
        let Some(inv) = inverse3(&a) else {
            break;
        };
        let nx = mul3(&inv, rhs);
        for &j in sel {
            let (l, d, gm) = (dirs[j], w[j], gamma[j]);
            let r = g[j] * s - dot3(l, nx);
            let q = dot3(l, mul3(&inv, l));
            let mu = gm * d * r;
            let var = gm - gm * gm * (d - d * d * q);
            gamma[j] = mu * mu + var.max(0.0);
        }
        let go_on = moved(x, nx, p.tolerance);
        x = nx;
        if !go_on {
            break;
        }
    }
    for &j in sel {
        w[j] = 1.0 / (lambda + gamma[j]);
    }
    let b = x.map(|v| v * gmax);
    b.iter().all(|v| v.is_finite()).then_some(b)
}
