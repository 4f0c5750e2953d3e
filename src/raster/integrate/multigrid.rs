//! The multigrid preconditioner of [`super::edges`] (see its module docs): the level
//! hierarchy of weighted graph Laplacians, the exact coarsest solve and the V-cycle.

use super::edges::{components, par_rows, zeros, Preconditioner};
use crate::raster::par::SharedMut;
use rayon::prelude::*;

/// Nodes at or below which a level is the coarsest (solved exactly).
pub(super) const COARSEST_NODES: usize = 400;

/// One level of the hierarchy (module docs): a weighted 5-point graph Laplacian and the
/// V-cycle's work vectors.
pub(super) struct Level {
    pub(super) w: usize,
    pub(super) h: usize,
    /// Weight of the edge `i → i+1` (0 in the last column).
    pub(super) wx: Vec<f32>,
    /// Weight of the edge `i → i+w` (0 in the last row).
    pub(super) wy: Vec<f32>,
    /// `1 / Σ_j w_ij`, 0 for a node without edges (kept at 0).
    pub(super) inv_diag: Vec<f32>,
    /// Per row, the columns `lo..hi` from its first to its last node with edges (`0..0`
    /// without one): every kernel works inside these spans only (a mask covering half of
    /// the frame costs about half), and the vectors stay 0 outside them.
    pub(super) spans: Vec<(usize, usize)>,
    pub(super) x: Vec<f32>,
    b: Vec<f32>,
}

/// The spans of [`Level::spans`] from a `w`-wide `inv_diag`.
pub(super) fn spans_of(inv_diag: &[f32], w: usize) -> Vec<(usize, usize)> {
    inv_diag
        .par_chunks(w)
        .map(|row| match row.iter().position(|&d| d > 0.0) {
            Some(lo) => (lo, w - row.iter().rev().position(|&d| d > 0.0).unwrap_or(0)),
            None => (0, 0),
        })
        .collect()
}

impl Level {
    pub(super) fn new(w: usize, h: usize, wx: Vec<f32>, wy: Vec<f32>) -> Self {
        let inv_diag = par_rows(w, h, |r, out| {
            for (xx, o) in out.iter_mut().enumerate() {
                let i = r * w + xx;
                let mut d = wx[i] + wy[i];
                if xx >= 1 {
                    d += wx[i - 1];
                }
                if r >= 1 {
                    d += wy[i - w];
                }
                *o = if d > 0.0 { 1.0 / d } else { 0.0 };
            }
        });
        let spans = spans_of(&inv_diag, w);
        Self {
            w,
            h,
            wx,
            wy,
            inv_diag,
            spans,
            x: zeros(w * h),
            b: zeros(w * h),
        }
    }

    /// The next coarser level: 2 × 2 aggregates, half the crossing fine weights.
    fn coarsen(&self) -> Self {
        let (w, h) = (self.w, self.h);
        let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
        let at = |v: &[f32], x: usize, r: usize| if x < w && r < h { v[r * w + x] } else { 0.0 };
        let wx = par_rows(cw, ch, |cr, out| {
            for (cx, o) in out.iter_mut().enumerate().take(cw - 1) {
                let fx = 2 * cx + 1;
                *o = 0.5 * (at(&self.wx, fx, 2 * cr) + at(&self.wx, fx, 2 * cr + 1));
            }
        });
        let wy = par_rows(cw, ch, |cr, out| {
            if cr + 1 < ch {
                let fr = 2 * cr + 1;
                for (cx, o) in out.iter_mut().enumerate() {
                    *o = 0.5 * (at(&self.wy, 2 * cx, fr) + at(&self.wy, 2 * cx + 1, fr));
                }
            }
        });
        Self::new(cw, ch, wx, wy)
    }

    /// `x = 0`, then the red half-sweep (`b` from `r` first when given): on red nodes
    /// `x = b / diag` (their neighbours are black, still 0), black nodes 0. One pass.
    fn first_sweep(&mut self, r: Option<&[f64]>) {
        let w = self.w;
        let (inv, spans) = (&self.inv_diag, &self.spans);
        self.x
            .par_chunks_mut(w)
            .zip(self.b.par_chunks_mut(w))
            .enumerate()
            .for_each(|(row, (x, b))| {
                let (lo, hi) = spans[row];
                let (x, b) = (&mut x[lo..hi], &mut b[lo..hi]);
                if let Some(r) = r {
                    for (b, &v) in b.iter_mut().zip(&r[row * w + lo..row * w + hi]) {
                        *b = v as f32;
                    }
                }
                let inv = &inv[row * w + lo..row * w + hi];
                for (k, ((x, &b), &d)) in x.iter_mut().zip(b.iter()).zip(inv).enumerate() {
                    *x = if (k + lo + row) % 2 == 0 { b * d } else { 0.0 };
                }
            });
    }

    /// One Gauss–Seidel half-sweep over the nodes of one colour (`(x + r) % 2 == colour`).
    fn gs_colour(&mut self, colour: usize) {
        let (w, h) = (self.w, self.h);
        let (wx, wy, inv, b) = (&self.wx, &self.wy, &self.inv_diag, &self.b);
        let spans = &self.spans;
        let ptr = SharedMut(self.x.as_mut_ptr());
        (0..h).into_par_iter().with_min_len(8).for_each(|r| {
            let p = ptr.get();
            let (lo, hi) = spans[r];
            if lo >= hi {
                return;
            }
            let first = lo + (lo + r + colour) % 2;
            // SAFETY (both loops): this task writes only nodes (xx, r) of colour `colour` (row
            // r is this task's own); it reads only their four neighbours, which have the other
            // colour and are written by no task during this half-sweep. All indices are inside
            // the buffer: checked by the conditions, or (inner loop) r ∈ 1..h−1 and
            // xx ∈ 1..w−1.
            let checked = |xx: usize| unsafe {
                let i = r * w + xx;
                let mut s = b[i];
                if xx >= 1 {
                    s += wx[i - 1] * *p.add(i - 1);
                }
                if xx + 1 < w {
                    s += wx[i] * *p.add(i + 1);
                }
                if r >= 1 {
                    s += wy[i - w] * *p.add(i - w);
                }
                if r + 1 < h {
                    s += wy[i] * *p.add(i + w);
                }
                // An inert node (d = 0) stays 0 (s is finite).
                *p.add(i) = s * inv[i];
            };
            if r == 0 || r + 1 == h || w < 3 {
                (first..hi).step_by(2).for_each(checked);
                return;
            }
            // Columns 0 and w − 1 checked; the inner ones without branches.
            let start = if first == 0 {
                checked(0);
                2
            } else {
                first
            };
            let end = hi.min(w - 1);
            for xx in (start..end).step_by(2) {
                let i = r * w + xx;
                unsafe {
                    let s = b.get_unchecked(i)
                        + wx.get_unchecked(i - 1) * *p.add(i - 1)
                        + wx.get_unchecked(i) * *p.add(i + 1)
                        + wy.get_unchecked(i - w) * *p.add(i - w)
                        + wy.get_unchecked(i) * *p.add(i + w);
                    *p.add(i) = s * inv.get_unchecked(i);
                }
            }
            if hi == w && (w - 1 + r + colour).is_multiple_of(2) {
                checked(w - 1);
            }
        });
    }

    /// Restricts `b − A x` of this level into `coarse.b` (sum over the 2 × 2 children), right
    /// after a black half-sweep: the black children's residuals are 0 and are not computed.
    fn restrict_residual(&self, coarse: &mut Level) {
        let (w, h) = (self.w, self.h);
        let cw = coarse.w;
        let (x, b, wx, wy, inv) = (&self.x, &self.b, &self.wx, &self.wy, &self.inv_diag);
        let res = |xx: usize, r: usize| -> f32 {
            if xx >= w || r >= h || inv[r * w + xx] == 0.0 {
                return 0.0;
            }
            let i = r * w + xx;
            let xi = x[i];
            let mut s = b[i];
            if xx >= 1 {
                s -= wx[i - 1] * (xi - x[i - 1]);
            }
            if xx + 1 < w {
                s -= wx[i] * (xi - x[i + 1]);
            }
            if r >= 1 {
                s -= wy[i - w] * (xi - x[i - w]);
            }
            if r + 1 < h {
                s -= wy[i] * (xi - x[i + w]);
            }
            s
        };
        let cspans = &coarse.spans;
        coarse
            .b
            .par_chunks_mut(cw)
            .enumerate()
            .for_each(|(cr, out)| {
                let (lo, hi) = cspans[cr];
                for (cx, o) in out.iter_mut().enumerate().take(hi).skip(lo) {
                    let (fx, fr) = (2 * cx, 2 * cr);
                    // The black children (fx + 1, fr) and (fx, fr + 1) were just relaxed: their
                    // residual is 0 (to rounding), so only the red ones are computed.
                    *o = res(fx, fr) + res(fx + 1, fr + 1);
                }
            });
    }

    /// Adds the coarse correction to the children of each coarse node that have edges (the
    /// transpose of [`restrict_residual`](Self::restrict_residual), which skips inert nodes).
    fn prolong_add(&mut self, coarse: &Level) {
        let (w, cw) = (self.w, coarse.w);
        let cx = &coarse.x;
        let (inv, spans) = (&self.inv_diag, &self.spans);
        self.x
            .par_chunks_mut(w)
            .zip(inv.par_chunks(w))
            .enumerate()
            .for_each(|(r, (row, ir))| {
                let crow = &cx[(r / 2) * cw..(r / 2 + 1) * cw];
                let (lo, hi) = spans[r];
                for (xx, (v, &d)) in row.iter_mut().zip(ir).enumerate().take(hi).skip(lo) {
                    if d > 0.0 {
                        *v += crow[xx / 2];
                    }
                }
            });
    }
}

/// The exact pseudo-inverse solve of the coarsest level (module docs).
pub(super) struct CoarseSolver {
    /// Component per node (`u32::MAX`: inert).
    label: Vec<u32>,
    count: usize,
    /// Pinned node per component.
    pinned: Vec<bool>,
    /// Cholesky factor (lower, row-major `n × n`) of the pinned matrix.
    chol: Vec<f64>,
}

impl CoarseSolver {
    fn new(l: &Level) -> Self {
        let (w, h) = (l.w, l.h);
        let n = w * h;
        let (label, count) = components(w, h, &l.wx, &l.wy, &l.inv_diag, &l.spans);
        let mut pinned = vec![false; n];
        let mut seen = vec![false; count];
        for i in 0..n {
            if label[i] != u32::MAX && !seen[label[i] as usize] {
                seen[label[i] as usize] = true;
                pinned[i] = true;
            }
        }
        let free = |i: usize| label[i] != u32::MAX && !pinned[i];
        let mut a = vec![0.0f64; n * n];
        for i in 0..n {
            if !free(i) {
                a[i * n + i] = 1.0;
                continue;
            }
            a[i * n + i] = 1.0 / f64::from(l.inv_diag[i]);
            let mut off = |j: usize, wt: f32| {
                if free(j) {
                    a[i * n + j] -= f64::from(wt);
                }
            };
            if i % w >= 1 {
                off(i - 1, l.wx[i - 1]);
            }
            if i % w + 1 < w {
                off(i + 1, l.wx[i]);
            }
            if i >= w {
                off(i - w, l.wy[i - w]);
            }
            if i + w < n {
                off(i + w, l.wy[i]);
            }
        }
        // Cholesky in place (lower triangle). Each component minus its pinned node is a
        // Dirichlet problem: positive definite.
        for j in 0..n {
            let mut d = a[j * n + j];
            for k in 0..j {
                d -= a[j * n + k] * a[j * n + k];
            }
            let d = if d > 0.0 {
                d.sqrt()
            } else {
                f64::MIN_POSITIVE.sqrt()
            };
            a[j * n + j] = d;
            for i in j + 1..n {
                let mut s = a[i * n + j];
                for k in 0..j {
                    s -= a[i * n + k] * a[j * n + k];
                }
                a[i * n + j] = s / d;
            }
        }
        Self {
            label,
            count,
            pinned,
            chol: a,
        }
    }

    /// `x = A⁺ b` (component means of `b` and of `x` projected out).
    fn solve(&self, b: &[f32], x: &mut [f32]) {
        let n = b.len();
        let mut v: Vec<f64> = b.iter().map(|&v| f64::from(v)).collect();
        self.project_means(&mut v);
        for ((v, &pinned), &label) in v.iter_mut().zip(&self.pinned).zip(&self.label) {
            if pinned || label == u32::MAX {
                *v = 0.0;
            }
        }
        let l = &self.chol;
        for i in 0..n {
            let mut s = v[i];
            for k in 0..i {
                s -= l[i * n + k] * v[k];
            }
            v[i] = s / l[i * n + i];
        }
        for i in (0..n).rev() {
            let mut s = v[i];
            for k in i + 1..n {
                s -= l[k * n + i] * v[k];
            }
            v[i] = s / l[i * n + i];
        }
        self.project_means(&mut v);
        for (x, v) in x.iter_mut().zip(v) {
            *x = v as f32;
        }
    }

    /// Subtracts each component's mean; inert nodes 0.
    fn project_means(&self, v: &mut [f64]) {
        let mut s = vec![(0.0f64, 0usize); self.count];
        for (i, &l) in self.label.iter().enumerate() {
            if l != u32::MAX {
                s[l as usize].0 += v[i];
                s[l as usize].1 += 1;
            }
        }
        for (i, &l) in self.label.iter().enumerate() {
            if l == u32::MAX {
                v[i] = 0.0;
            } else {
                let (sum, c) = s[l as usize];
                v[i] -= sum / c as f64;
            }
        }
    }
}

/// The multigrid hierarchy, finest first, and the coarsest level's exact solver.
pub(super) struct Multigrid {
    pub(super) levels: Vec<Level>,
    coarse: CoarseSolver,
}

impl Multigrid {
    pub(super) fn new(w: usize, h: usize, wx: Vec<f32>, wy: Vec<f32>) -> Self {
        let mut levels = vec![Level::new(w, h, wx, wy)];
        while let Some(l) = levels.last() {
            if l.w * l.h <= COARSEST_NODES {
                break;
            }
            let c = l.coarsen();
            levels.push(c);
        }
        let coarse = CoarseSolver::new(levels.last().expect("level 0 exists"));
        Self { levels, coarse }
    }

    /// `levels[0].x ≈ M r` for the preconditioner `M`.
    pub(super) fn precondition(&mut self, pre: Preconditioner, r: &[f64]) {
        match pre {
            Preconditioner::Multigrid => self.apply(r),
            Preconditioner::Jacobi => {
                let l0 = &mut self.levels[0];
                l0.x.par_iter_mut()
                    .zip(r.par_iter().zip(&l0.inv_diag))
                    .for_each(|(z, (r, &d))| *z = (r * f64::from(d)) as f32);
            }
            #[cfg(test)]
            Preconditioner::Indefinite => {
                let l0 = &mut self.levels[0];
                let w = l0.w;
                l0.x.iter_mut()
                    .zip(r.iter().zip(&l0.inv_diag))
                    .enumerate()
                    .for_each(|(i, (z, (r, &d)))| {
                        let sign = if (i % w + i / w).is_multiple_of(2) {
                            1.0
                        } else {
                            -1.0
                        };
                        *z = (sign * r * f64::from(d)) as f32;
                    });
            }
        }
    }

    /// `levels[0].x ≈ A⁻¹ r` by one V-cycle (symmetric: module docs).
    pub(super) fn apply(&mut self, r: &[f64]) {
        if self.levels.len() == 1 {
            let l0 = &mut self.levels[0];
            l0.b.par_iter_mut().zip(r).for_each(|(b, &v)| *b = v as f32);
        } else {
            self.levels[0].first_sweep(Some(r));
        }
        // Cancelled: the cycle stops between sweeps and CG, which checks the token after each
        // preconditioning, discards what it holds (crate::cancel).
        let cancel = crate::cancel::Cancel::current();
        self.vcycle(0, &cancel);
    }

    fn vcycle(&mut self, k: usize, cancel: &crate::cancel::Cancel) {
        let last = k + 1 == self.levels.len();
        let l = &mut self.levels[k];
        if last {
            self.coarse.solve(&l.b, &mut l.x);
            return;
        }
        if cancel.is_cancelled() {
            return;
        }
        if k > 0 {
            l.first_sweep(None);
        }
        l.gs_colour(1);
        let (fine, coarse) = self.levels.split_at_mut(k + 1);
        fine[k].restrict_residual(&mut coarse[0]);
        self.vcycle(k + 1, cancel);
        if cancel.is_cancelled() {
            return;
        }
        let (fine, coarse) = self.levels.split_at_mut(k + 1);
        let l = &mut fine[k];
        l.prolong_add(&coarse[0]);
        l.gs_colour(1);
        l.gs_colour(0);
    }
}
