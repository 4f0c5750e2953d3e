//! Weighted-edge least squares on a grid: [`solve_edges`], conjugate gradients preconditioned
//! by one geometric-multigrid V-cycle ([`Multigrid`]). The masked Poisson solver
//! ([`super::masked`]) is this with weight 1 on the edges inside the mask; bilateral normal
//! integration calls it with its per-edge weights.
//!
//! # The system
//!
//! Minimising `Σ wx_i (z_{i+1} − z_i − ex_i)² + Σ wy_i (z_{i+w} − z_i − ey_i)²` gives the
//! normal equations `A z = b` with `A` the weighted 5-point graph Laplacian
//! `(A z)_i = Σ_j w_ij (z_i − z_j)` and `b_i = Σ_{edges j→i} w e − Σ_{edges i→j} w e`. `A` is
//! symmetric positive semi-definite; its null space is the constants on each connected
//! component (through edges of weight > 0), and `b` is orthogonal to it (consistent), so CG
//! converges on the range; the per-component constants are fixed afterwards (to the means of
//! the start `z0`).
//!
//! # The multigrid preconditioner
//!
//! Level 0 is `A`. A coarse node aggregates 2 × 2 fine nodes; the weight of a coarse edge is
//! **half the sum of the fine weights crossing it** — the Galerkin operator `Pᵀ A P` of
//! piecewise-constant interpolation `P`, halved: a rediscretisation at twice the spacing (for
//! a smooth error the Galerkin operator of constant interpolation is twice too stiff in 2-D).
//! Weights enter the coarse operators as they are (a weak edge stays weak), so strongly varying
//! weights (bilateral integration: 1e-6..1) are seen by every level. Coarse nodes with no edge
//! are inert (kept at 0).
//!
//! The V-cycle: one red-black Gauss–Seidel sweep (red, then black), residual restricted by
//! summing the four children (`Pᵀ`), the coarse correction from the next level, added back to
//! the four children (`P`), one sweep in the reverse order (black, then red), so the cycle is a
//! symmetric linear operator. The **coarsest level (≤ `COARSEST_NODES` nodes) is solved
//! exactly**: per connected component the right-hand side's mean is projected out (a pure
//! Neumann component is singular and only consistent right-hand sides have a solution), one
//! node per component is pinned, the rest solved by a dense Cholesky factorisation (`f64`),
//! and the component means of the solution are projected out: the pseudo-inverse `A_c⁺`, a
//! fixed symmetric positive semi-definite operator whatever the right-hand side (`f32` rounding
//! makes the restricted residuals slightly inconsistent; Gauss–Seidel sweeps on an inconsistent
//! singular system drift along the null space). The V-cycle runs in `f32` (it only needs to be
//! a good approximate inverse), the Krylov vectors in `f64`.
//!
//! # Why (the 4K divergence, issue 17)
//!
//! Until this module the coarsest level was solved by 2 × 40 red-black Gauss–Seidel sweeps
//! from 0, and `b` was the `f32` divergence. On the bench's half-frame ellipse at
//! 1920 × 2160 and 3840 × 2160 MG-PCG fell to 3e-5, then diverged (to 6e7). Measured at
//! 1920 × 2160: the V-cycle was symmetric (`⟨M r₁, r₂⟩` vs `⟨r₁, M r₂⟩` agree to 1e-7 on
//! random consistent vectors) and positive; the cause was the **null space**. The `f32`
//! divergence is consistent only to rounding: the residual kept a fixed component along the
//! constants of 8e-10 · ‖b‖ that CG cannot remove, and the V-cycle amplified constants
//! enormously (restriction sums 4ᵏ children per level, and Gauss–Seidel on the singular
//! coarsest system with an inconsistent right-hand side drifts linearly with the sweep
//! count: `⟨M 1, 1⟩ / ⟨1, 1⟩` ≈ 1e6–1e7 against ≈ 1 on the range). Once the residual
//! reached ≈ 1e-5 (null fraction 3.5e-4, iteration 7) that component dominated
//! `⟨r, M r⟩`, CG's step `α` jumped from ≈ 1.1 to 2, then 28 and 38, and the residual grew.
//! The fix: `b` is projected onto the range in `f64` (component means subtracted, so CG's
//! residual stays consistent to `f64` rounding) and the coarsest level is the exact
//! pseudo-inverse above. MG-PCG now converges by itself there (8 iterations from 0, 6 from
//! the DCT warm start at 3840 × 2160); the Jacobi restart is kept only as a guard ([`pcg`]).

use super::multigrid::{Level, Multigrid};
use crate::error::RgbnError;
use crate::raster::buf::advise_huge_pages;
use crate::raster::par::{ordered_dot, OrderedReduce, SharedMut};
use rayon::prelude::*;

/// Minimise `Σ_i wx[i]·(z[i+1] − z[i] − ex[i])² + Σ_i wy[i]·(z[i+w] − z[i] − ey[i])²`
/// (row-major `w × h`; `wx[i]` is the edge from `i` to its right neighbour, ignored in the
/// last column; `wy[i]` the edge from `i` to the pixel below, ignored in the last row; weight
/// 0 = no edge; weights ≥ 0 and finite, targets finite where the weight is > 0).
pub(crate) struct EdgeSystem<'a> {
    pub w: usize,
    pub h: usize,
    pub wx: &'a [f32],
    pub ex: &'a [f32],
    pub wy: &'a [f32],
    pub ey: &'a [f32],
}

/// The result of [`solve_edges`].
#[derive(Debug)]
pub(crate) struct EdgeSolve {
    /// The heights (module docs of [`solve_edges`] for the constants).
    pub z: Vec<f32>,
    /// Conjugate-gradient iterations.
    pub iterations: u32,
    /// Final `‖b − A z‖ / ‖b‖` (0 when `b = 0`).
    pub relative_residual: f64,
}

/// Solves an [`EdgeSystem`] by multigrid-preconditioned CG (module docs) from `z0` (or 0),
/// until `‖b − A z‖ ≤ tolerance · ‖b‖` or `max_iterations`. Each connected component (through
/// edges of weight > 0) is determined up to a constant: the returned `z` has, per component,
/// the mean of `z0` on it (or 0 without `z0`); pixels with no edge get 0.
///
/// # Errors
/// Slices whose lengths are not `w·h`, negative or non-finite weights, non-finite targets on
/// an edge of positive weight, a non-finite `z0`, or a tolerance outside (0, 1).
// The entry point of bilateral normal integration (`bini.rs`); masked Poisson calls
// [`solve_edges_owned`].
pub(crate) fn solve_edges(
    sys: &EdgeSystem,
    z0: Option<&[f32]>,
    tolerance: f64,
    max_iterations: u32,
) -> Result<EdgeSolve, RgbnError> {
    solve_edges_guarded(sys, z0, tolerance, max_iterations).map(|(s, _)| s)
}

/// [`solve_edges`], and whether the CG guard fired (the Jacobi restart of [`pcg`]).
fn solve_edges_guarded(
    sys: &EdgeSystem,
    z0: Option<&[f32]>,
    tolerance: f64,
    max_iterations: u32,
) -> Result<(EdgeSolve, bool), RgbnError> {
    validate(sys, z0, tolerance)?;
    let copy = |v: &[f32]| {
        let mut c = par_vec(v.len(), |_| 0.0f32);
        c.par_chunks_mut(1 << 14)
            .zip(v.par_chunks(1 << 14))
            .for_each(|(c, v)| c.copy_from_slice(v));
        c
    };
    solve_edges_owned(
        sys.w,
        sys.h,
        copy(sys.wx),
        sys.ex,
        copy(sys.wy),
        sys.ey,
        z0,
        tolerance,
        max_iterations,
    )
}

/// [`solve_edges_guarded`] taking the weights by value (no copy).
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_edges_owned(
    w: usize,
    h: usize,
    wx: Vec<f32>,
    ex: &[f32],
    wy: Vec<f32>,
    ey: &[f32],
    z0: Option<&[f32]>,
    tolerance: f64,
    max_iterations: u32,
) -> Result<(EdgeSolve, bool), RgbnError> {
    let start = Preconditioner::Multigrid;
    solve_edges_from(w, h, wx, ex, wy, ey, z0, (tolerance, max_iterations), start)
}

/// [`solve_edges_owned`] with CG started on the preconditioner `start` (the tests start one
/// that makes CG diverge, to see the guard recover).
#[allow(clippy::too_many_arguments)]
fn solve_edges_from(
    w: usize,
    h: usize,
    mut wx: Vec<f32>,
    ex: &[f32],
    mut wy: Vec<f32>,
    ey: &[f32],
    z0: Option<&[f32]>,
    (tolerance, max_iterations): (f64, u32),
    start: Preconditioner,
) -> Result<(EdgeSolve, bool), RgbnError> {
    let sys = EdgeSystem {
        w,
        h,
        wx: &wx,
        ex,
        wy: &wy,
        ey,
    };
    validate(&sys, z0, tolerance)?;
    let n = w * h;
    if n == 0 {
        return Ok((
            EdgeSolve {
                z: Vec::new(),
                iterations: 0,
                relative_residual: 0.0,
            },
            false,
        ));
    }
    // The out-of-grid edges dropped.
    wx.par_chunks_mut(w).for_each(|row| row[w - 1] = 0.0);
    wy[n - w..].fill(0.0);
    let mut b = rhs(w, ex, ey, &wx, &wy);
    // Cancelled while the system is set up: the caller discards the zeros (crate::cancel).
    let cancel = crate::cancel::Cancel::current();
    let cancelled = || {
        cancel.is_cancelled().then(|| {
            let z = vec![0.0; n];
            let (iterations, relative_residual) = (0, f64::NAN);
            (
                EdgeSolve {
                    z,
                    iterations,
                    relative_residual,
                },
                false,
            )
        })
    };
    if let Some(r) = cancelled() {
        return Ok(r);
    }
    let mut mg = Multigrid::new(w, h, wx, wy);
    if let Some(r) = cancelled() {
        return Ok(r);
    }
    let l0 = &mg.levels[0];
    let (label, count) = components(w, h, &l0.wx, &l0.wy, &l0.inv_diag, &l0.spans);
    if let Some(r) = cancelled() {
        return Ok(r);
    }
    // b is consistent (zero sum per component) up to rounding; the rounding part is projected
    // out: CG cannot reduce it, and the V-cycle amplifies constants (module docs).
    let means = component_means(&b, &label, count);
    b.par_iter_mut().zip(&label).for_each(|(v, &l)| {
        if l != u32::MAX {
            *v -= means[l as usize];
        }
    });
    let b_norm = dot(&b, &b).sqrt();
    let mut x: Vec<f64> = match z0 {
        Some(z) if b_norm > 0.0 => par_vec(n, |i| f64::from(z[i])),
        _ => zeros(n),
    };
    let (iterations, relative_residual, restarted) = if b_norm > 0.0 {
        pcg(
            &mut mg,
            &b,
            b_norm,
            &mut x,
            tolerance,
            max_iterations,
            start,
        )
    } else {
        (0, 0.0, false)
    };
    if let Some(r) = cancelled() {
        return Ok(r);
    }
    let z = fix_constants(&x, z0, &label, count);
    Ok((
        EdgeSolve {
            z,
            iterations,
            relative_residual,
        },
        restarted,
    ))
}

fn validate(sys: &EdgeSystem, z0: Option<&[f32]>, tolerance: f64) -> Result<(), RgbnError> {
    let n = sys
        .w
        .checked_mul(sys.h)
        .ok_or_else(|| RgbnError::param("edge system", format!("{}×{} overflows", sys.w, sys.h)))?;
    for (name, s) in [
        ("wx", sys.wx),
        ("ex", sys.ex),
        ("wy", sys.wy),
        ("ey", sys.ey),
    ]
    .into_iter()
    .chain(z0.map(|z| ("z0", z)))
    {
        if s.len() != n {
            return Err(RgbnError::param(
                "edge system",
                format!(
                    "{name} has {} values for a {}×{} grid",
                    s.len(),
                    sys.w,
                    sys.h
                ),
            ));
        }
    }
    for (name, wt, e) in [("x", sys.wx, sys.ex), ("y", sys.wy, sys.ey)] {
        if let Some(i) = wt
            .par_iter()
            .zip(e)
            .position_any(|(&v, &t)| !(v.is_finite() && v >= 0.0) || (v > 0.0 && !t.is_finite()))
        {
            return Err(RgbnError::param(
                "edge system",
                format!(
                    "w{name}/e{name} at pixel ({}, {}): weight {} target {} (weights must be \
                     finite and ≥ 0, targets finite)",
                    i % sys.w,
                    i / sys.w,
                    wt[i],
                    e[i]
                ),
            ));
        }
    }
    if let Some(z) = z0 {
        if let Some(i) = z.par_iter().position_any(|v| !v.is_finite()) {
            return Err(RgbnError::param(
                "z0",
                format!(
                    "non-finite value {} at pixel ({}, {})",
                    z[i],
                    i % sys.w,
                    i / sys.w
                ),
            ));
        }
    }
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(RgbnError::param(
            "tolerance",
            format!("must be in (0, 1), got {tolerance}"),
        ));
    }
    Ok(())
}

/// `n` zeros, untouched until written (huge pages advised: [`advise_huge_pages`]).
pub(super) fn zeros<T: Copy + Default>(n: usize) -> Vec<T> {
    let v = vec![T::default(); n];
    advise_huge_pages(&v);
    v
}

/// A vector of `n` values `f(i)`, filled in parallel (huge pages advised: [`advise_huge_pages`]).
pub(super) fn par_vec<T: Copy + Default + Send + Sync>(
    n: usize,
    f: impl Fn(usize) -> T + Sync + Send,
) -> Vec<T> {
    let mut v = vec![T::default(); n];
    advise_huge_pages(&v);
    v.par_chunks_mut(1 << 14).enumerate().for_each(|(c, out)| {
        for (k, o) in out.iter_mut().enumerate() {
            *o = f((c << 14) + k);
        }
    });
    v
}

/// A `w × h` vector filled row by row in parallel: `f(row, out_row)` (huge pages advised).
pub(super) fn par_rows<T: Copy + Default + Send + Sync>(
    w: usize,
    h: usize,
    f: impl Fn(usize, &mut [T]) + Sync + Send,
) -> Vec<T> {
    let mut v = vec![T::default(); w * h];
    advise_huge_pages(&v);
    if w > 0 {
        v.par_chunks_mut(w)
            .with_min_len(4)
            .enumerate()
            .for_each(|(r, out)| f(r, out));
    }
    v
}

/// `b = Σ_{edges j→i} w e − Σ_{edges i→j} w e` (module docs).
fn rhs(w: usize, ex: &[f32], ey: &[f32], wx: &[f32], wy: &[f32]) -> Vec<f64> {
    // A zero weight times a non-finite target must not poison b.
    let f = |wt: f32, e: f32| {
        if wt > 0.0 {
            f64::from(wt) * f64::from(e)
        } else {
            0.0
        }
    };
    par_rows(w, wx.len() / w.max(1), |r, out| {
        for (x, o) in out.iter_mut().enumerate() {
            let i = r * w + x;
            let mut s = -f(wx[i], ex[i]) - f(wy[i], ey[i]);
            if x >= 1 {
                s += f(wx[i - 1], ex[i - 1]);
            }
            if r >= 1 {
                s += f(wy[i - w], ey[i - w]);
            }
            *o = s;
        }
    })
}

/// `y = A x` on level 0's weights; returns `⟨x, y⟩`.
fn apply_a(l: &Level, x: &[f64], y: &mut [f64]) -> f64 {
    let (w, h) = (l.w, l.h);
    let (wx, wy) = (&l.wx, &l.wy);
    y.par_chunks_mut(w)
        .enumerate()
        .map(|(r, out)| {
            let mut xy = 0.0;
            let (lo, hi) = l.spans[r];
            if r >= 1 && r + 1 < h && lo < hi {
                // An inner row, without branches: the neighbour left of column 0 and right of
                // column w − 1 are in the rows around, behind edges of weight 0 (the last
                // column's x weights are 0), and x is finite.
                let (a, b) = (r * w + lo, r * w + hi);
                let it = out[lo..hi]
                    .iter_mut()
                    .zip(&x[a..b])
                    .zip(x[a - 1..b - 1].iter().zip(&x[a + 1..b + 1]))
                    .zip(x[a - w..b - w].iter().zip(&x[a + w..b + w]))
                    .zip(wx[a - 1..b - 1].iter().zip(&wx[a..b]))
                    .zip(wy[a - w..b - w].iter().zip(&wy[a..b]));
                for (((((o, &xi), (&xl, &xr)), (&xu, &xd)), (&wl, &wr)), (&wu, &wd)) in it {
                    let s = f64::from(wl) * (xi - xl)
                        + f64::from(wr) * (xi - xr)
                        + f64::from(wu) * (xi - xu)
                        + f64::from(wd) * (xi - xd);
                    *o = s;
                    xy += xi * s;
                }
                return xy;
            }
            for (xx, o) in out.iter_mut().enumerate().take(hi).skip(lo) {
                let i = r * w + xx;
                let xi = x[i];
                let mut s = 0.0;
                if xx >= 1 {
                    s += f64::from(wx[i - 1]) * (xi - x[i - 1]);
                }
                if xx + 1 < w {
                    s += f64::from(wx[i]) * (xi - x[i + 1]);
                }
                if r >= 1 {
                    s += f64::from(wy[i - w]) * (xi - x[i - w]);
                }
                if r + 1 < h {
                    s += f64::from(wy[i]) * (xi - x[i + w]);
                }
                *o = s;
                xy += xi * s;
            }
            xy
        })
        .ordered_sum()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    ordered_dot(a, b)
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Preconditioner {
    Multigrid,
    /// `1 / degree` (the safeguard's fallback; also a test oracle).
    Jacobi,
    /// Jacobi with signs alternating in a checkerboard: symmetric but indefinite, under which
    /// CG is not bound to converge (the guard's test).
    #[cfg(test)]
    Indefinite,
}

/// Preconditioned CG on `A x = b` from `x`; returns (iterations, relative residual, whether
/// the guard restarted with Jacobi).
///
/// Guard: with a fixed symmetric positive semi-definite preconditioner CG's residual cannot
/// run away, but should rounding ever make it grow past 10× the best seen, or CG break down
/// (`r·z ≤ 0` or `d·A d ≤ 0`), CG restarts from the current iterate with the Jacobi
/// preconditioner (which always converges). The tests make it fire with an indefinite
/// preconditioner (`edges_tests.rs`).
///
/// Every vector operation runs over level 0's [spans](Level::spans) only: outside them `b`,
/// the residual, the direction and `A·dir` are 0, and `x` is not read.
fn pcg(
    mg: &mut Multigrid,
    b: &[f64],
    b_norm: f64,
    x: &mut [f64],
    tolerance: f64,
    max_iterations: u32,
    mut pre: Preconditioner,
) -> (u32, f64, bool) {
    let n = b.len();
    let cancel = crate::cancel::Cancel::current();
    let (w, spans) = (mg.levels[0].w, mg.levels[0].spans.clone());
    let mut ax = zeros::<f64>(n);
    let mut res = zeros::<f64>(n);
    let residual = |x: &[f64], ax: &mut [f64], res: &mut [f64], l0: &Level| -> f64 {
        apply_a(l0, x, ax);
        rows_map(w, &spans, res, |r, lo, hi, res| {
            let (b, ax) = (&b[r * w + lo..r * w + hi], &ax[r * w + lo..r * w + hi]);
            let mut s = 0.0;
            for ((r, b), a) in res.iter_mut().zip(b).zip(ax) {
                *r = b - a;
                s += *r * *r;
            }
            s
        })
        .sqrt()
            / b_norm
    };
    let mut rel = residual(x, &mut ax, &mut res, &mg.levels[0]);
    let mut dir = zeros::<f64>(n);
    let mut rz = 0.0;
    let mut iterations = 0u32;
    // The guard watches every preconditioner but its own fallback.
    let mut best = (pre != Preconditioner::Jacobi).then_some(rel);
    let mut restart = true;
    let mut restarted = false;
    // CG broke down (a preconditioned residual with `r·z ≤ 0`, a direction with `d·A d ≤ 0`):
    // under any preconditioner but Jacobi, the guard restarts with Jacobi.
    let mut broke_down = false;
    while iterations < max_iterations && rel > tolerance {
        // Cancelled: the caller discards whatever `x` holds (crate::cancel).
        if cancel.is_cancelled() {
            break;
        }
        if broke_down || best.is_some_and(|best| rel > 10.0 * best) {
            pre = Preconditioner::Jacobi;
            best = None;
            broke_down = false;
            restarted = true;
            rel = residual(x, &mut ax, &mut res, &mg.levels[0]);
            restart = true;
            continue;
        }
        if restart {
            mg.precondition(pre, &res);
            if cancel.is_cancelled() {
                break;
            }
            let zv = &mg.levels[0].x;
            rz = rows_map(w, &spans, &mut dir, |r, lo, hi, d| {
                let (z, res) = (&zv[r * w + lo..r * w + hi], &res[r * w + lo..r * w + hi]);
                let mut s = 0.0;
                for ((d, &z), r) in d.iter_mut().zip(z).zip(res) {
                    *d = f64::from(z);
                    s += r * *d;
                }
                s
            });
            restart = false;
            if rz <= 0.0 {
                if pre == Preconditioner::Jacobi {
                    break;
                }
                broke_down = true;
                continue;
            }
        }
        let dad = apply_a(&mg.levels[0], &dir, &mut ax);
        if dad <= 0.0 {
            if pre == Preconditioner::Jacobi {
                break;
            }
            broke_down = true;
            continue;
        }
        let alpha = rz / dad;
        let rr: f64 = x
            .par_chunks_mut(w)
            .zip(res.par_chunks_mut(w))
            .enumerate()
            .map(|(r, (x, res))| {
                let (lo, hi) = spans[r];
                let (d, a) = (&dir[r * w + lo..r * w + hi], &ax[r * w + lo..r * w + hi]);
                let mut s = 0.0;
                for ((x, r), (d, a)) in x[lo..hi]
                    .iter_mut()
                    .zip(res[lo..hi].iter_mut())
                    .zip(d.iter().zip(a))
                {
                    *x += alpha * d;
                    *r -= alpha * a;
                    s += *r * *r;
                }
                s
            })
            .ordered_sum();
        iterations += 1;
        rel = rr.sqrt() / b_norm;
        if let Some(best) = &mut best {
            *best = best.min(rel);
        }
        if rel <= tolerance {
            break;
        }
        mg.precondition(pre, &res);
        if cancel.is_cancelled() {
            break;
        }
        let zv = &mg.levels[0].x;
        let rz_new = rows_sum(&spans, |r, lo, hi| {
            let (z, res) = (&zv[r * w + lo..r * w + hi], &res[r * w + lo..r * w + hi]);
            res.iter()
                .zip(z)
                .map(|(x, &y)| x * f64::from(y))
                .sum::<f64>()
        });
        if rz_new <= 0.0 {
            if pre == Preconditioner::Jacobi {
                break;
            }
            broke_down = true;
            continue;
        }
        let beta = rz_new / rz;
        rz = rz_new;
        rows_map(w, &spans, &mut dir, |r, lo, hi, d| {
            for (d, &z) in d.iter_mut().zip(&zv[r * w + lo..r * w + hi]) {
                *d = f64::from(z) + beta * *d;
            }
            0.0
        });
    }
    (iterations, rel, restarted)
}

/// Sums `f(row, lo, hi)` over every row's span, rows in parallel.
fn rows_sum(spans: &[(usize, usize)], f: impl Fn(usize, usize, usize) -> f64 + Sync) -> f64 {
    spans
        .par_iter()
        .with_min_len(4)
        .enumerate()
        .map(|(r, &(lo, hi))| f(r, lo, hi))
        .ordered_sum()
}

/// Runs `f(row, lo, hi, out[row·w + lo .. row·w + hi])` on every row's span in parallel and
/// sums what it returns.
fn rows_map<F>(w: usize, spans: &[(usize, usize)], out: &mut [f64], f: F) -> f64
where
    F: Fn(usize, usize, usize, &mut [f64]) -> f64 + Sync,
{
    out.par_chunks_mut(w)
        .with_min_len(4)
        .enumerate()
        .map(|(r, row)| {
            let (lo, hi) = spans[r];
            f(r, lo, hi, &mut row[lo..hi])
        })
        .ordered_sum()
}

/// Per connected component, shifts `x` to the mean of `z0` (or 0); pixels without an edge 0.
fn fix_constants(x: &[f64], z0: Option<&[f32]>, label: &[u32], count: usize) -> Vec<f32> {
    let mut shift = component_means(x, label, count);
    if let Some(z) = z0 {
        for (s, m) in shift.iter_mut().zip(component_means(z, label, count)) {
            *s -= m;
        }
    }
    par_vec(x.len(), |i| match label[i] {
        u32::MAX => 0.0,
        l => (x[i] - shift[l as usize]) as f32,
    })
}

/// The mean of `v` on each component (`label` as from [`components`]): in parallel chunks
/// when there are few components, in one pass otherwise.
fn component_means<T: Copy + Into<f64> + Sync>(v: &[T], label: &[u32], count: usize) -> Vec<f64> {
    let sums = |v: &[T], label: &[u32]| {
        let mut s = vec![(0.0f64, 0usize); count];
        for (&v, &l) in v.iter().zip(label) {
            if l != u32::MAX {
                let e = &mut s[l as usize];
                e.0 += v.into();
                e.1 += 1;
            }
        }
        s
    };
    let s = if count <= 256 {
        v.par_chunks(1 << 16)
            .zip(label.par_chunks(1 << 16))
            .map(|(v, l)| sums(v, l))
            .ordered_reduce(
                || vec![(0.0, 0); count],
                |mut a, b| {
                    for (a, b) in a.iter_mut().zip(b) {
                        a.0 += b.0;
                        a.1 += b.1;
                    }
                    a
                },
            )
    } else {
        sums(v, label)
    };
    s.iter().map(|&(s, c)| s / c.max(1) as f64).collect()
}

/// Connected components through edges of positive weight: a dense label per node with an
/// edge (`u32::MAX` for nodes without one) and the number of components.
pub(super) fn components(
    w: usize,
    h: usize,
    wx: &[f32],
    wy: &[f32],
    inv_diag: &[f32],
    spans: &[(usize, usize)],
) -> (Vec<u32>, usize) {
    let n = w * h;
    // Horizontal runs first: every node of a run of nodes joined by x edges points at the
    // run's first node (its "start"), which is the only node unions and finds ever touch, so
    // a non-start node keeps pointing at its start.
    let mut parent: Vec<u32> = par_rows(w, h, |row, out| {
        let (lo, hi) = spans[row];
        for x in lo..hi {
            let i = row * w + x;
            out[x] = if x > lo && wx[i - 1] > 0.0 {
                out[x - 1]
            } else {
                i as u32
            };
        }
    });
    let is_start = |i: usize| i.is_multiple_of(w) || wx[i - 1] <= 0.0;
    fn find(p: &mut [u32], base: usize, mut i: u32) -> u32 {
        while p[i as usize - base] != i {
            let g = p[p[i as usize - base] as usize - base];
            p[i as usize - base] = g;
            i = g;
        }
        i
    }
    // The smaller index stays root: a root is its component's first node in a forward scan.
    fn union(p: &mut [u32], base: usize, i: usize, j: usize) {
        let (a, b) = (find(p, base, i as u32), find(p, base, j as u32));
        if a != b {
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            p[hi as usize - base] = lo;
        }
    }
    // The y edges of `row` (to `row + 1`): the runs above and below are joined, once per
    // pair of runs met in a row.
    let join_rows = |p: &mut [u32], base: usize, row: usize| {
        let (lo, hi) = spans[row];
        let mut last = (u32::MAX, u32::MAX);
        for i in row * w + lo..row * w + hi {
            if wy[i] > 0.0 {
                let a = if is_start(i) { i as u32 } else { p[i - base] };
                let j = i + w;
                let b = if is_start(j) { j as u32 } else { p[j - base] };
                if (a, b) != last {
                    union(p, base, a as usize, b as usize);
                    last = (a, b);
                }
            }
        }
    };
    // Bands of rows in parallel (every parent inside its band), then the edges between bands.
    let band_rows = h.div_ceil(32).max(1);
    let band = band_rows * w;
    parent.par_chunks_mut(band).enumerate().for_each(|(k, p)| {
        let base = k * band;
        let rows = p.len() / w;
        for r in 0..rows.saturating_sub(1) {
            join_rows(p, base, k * band_rows + r);
        }
    });
    for k in 1..h.div_ceil(band_rows) {
        join_rows(&mut parent, 0, k * band_rows - 1);
    }
    // Roots in parallel (read-only walks), dense labels for the roots in index order, then
    // every node takes its root's label.
    let root: Vec<u32> = par_rows(w, h, |row, out| {
        let (lo, hi) = spans[row];
        for (x, o) in out.iter_mut().enumerate().take(hi).skip(lo) {
            let mut r = (row * w + x) as u32;
            while parent[r as usize] != r {
                r = parent[r as usize];
            }
            *o = r;
        }
    });
    let mut label = vec![u32::MAX; n];
    let mut count = 0usize;
    for (row, &(lo, hi)) in spans.iter().enumerate() {
        for i in row * w + lo..row * w + hi {
            if root[i] == i as u32 && inv_diag[i] != 0.0 {
                label[i] = count as u32;
                count += 1;
            }
        }
    }
    let ptr = SharedMut(label.as_mut_ptr());
    (0..h).into_par_iter().with_min_len(4).for_each(|row| {
        let (lo, hi) = spans[row];
        for i in row * w + lo..row * w + hi {
            let r = root[i] as usize;
            if r != i && inv_diag[i] != 0.0 {
                // SAFETY: each task writes only node i (a non-root) and reads only roots,
                // which no task writes; i < n.
                unsafe { *ptr.get().add(i) = *ptr.get().add(r) };
            }
        }
    });
    (label, count)
}

#[cfg(test)]
#[path = "edges_tests.rs"]
mod tests;
