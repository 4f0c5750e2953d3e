//! A change of a gradient field made integrable inside its support, with the support's border
//! held: the masked projection with a Dirichlet boundary that `combine.rotation`'s
//! `integrable` option uses ([`project_in_support`]).
//!
//! # The problem
//!
//! An edit changes the samples of an image's gradient field by `δ` on a support `S` (0
//! elsewhere). Outside `S` the image must stay as it was, so the nearest field of the form
//! "the image's own gradients plus the gradient of a height change `ζ` that is 0 outside `S`"
//! is wanted. In the averaged edge model of [`super`] (module docs) that is two steps:
//!
//! 1. **Height.** `ζ` minimises `Σ (D ζ − e)²` over the edges with at least one end in `S`
//!    (`e` the averaged edge values of `δ`), with `ζ = 0` on every pixel outside `S`: the
//!    Poisson equation on `S` with a Dirichlet boundary (the base's height, unchanged) on its
//!    border and the natural Neumann boundary where `S` meets the image's edge. When `S` is the
//!    whole image there is no border to hold: the plain least squares of the module docs (DCT
//!    solver), whose free constant changes no gradient.
//! 2. **Samples.** Along each row (for `p`) and column (for `q`), on each run of `S`, the
//!    samples `s` whose averaged edges are the differences of `ζ`, the samples just outside the
//!    run held at 0: `½(s_k + s_{k+1}) = ζ_{k+1} − ζ_k` on every edge that touches the run. A
//!    run held at one end or both has as many or one more equations than samples: `s` is their
//!    least-squares solution (tridiagonal normal equations). A run from image edge to image edge
//!    has one equation fewer: `s` is the solution closest to `δ` (as the unmasked projection
//!    of [`super::gradients_of_height`]).
//!
//! With the whole image as support the result's edge values are exactly `D ζ` added to the
//! image's own: the image plus the change is then as integrable as the image was. A run held
//! at both ends has one equation more than samples: `s` meets the edges exactly when the
//! alternating sum of `D ζ` along the run vanishes (the averaged model cannot make a sample
//! pattern whose edge values alternate), and otherwise leaves that alternating part as the
//! residual, which is small where the change fades out towards the border (a weight that
//! falls to 0 there).
//!
//! # The solver
//!
//! Conjugate gradients on the Dirichlet Laplacian of `S`, preconditioned by one V-cycle of the
//! multigrid of [`super::edges`] built on the edges that touch `S`, with the pixels outside `S`
//! inert on the finest level (held at 0 by its Gauss–Seidel sweeps, as the boundary is), and
//! `f64` Krylov vectors.

use super::edges::par_rows;
use super::multigrid::Multigrid;
use super::{gradients_of_height, integrate_gradients, IntegrateParams, IntegrationMethod};
use crate::error::RgbnError;
use crate::raster::gradient::{normal_of_gradient, Differences, GradientField};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// What [`project_in_support`] made and measured.
#[derive(Clone, Debug, PartialEq)]
pub struct SupportProjection {
    /// The change made integrable: samples (0 outside the support) to add to the image's own.
    pub change: GradientField,
    /// The height change `ζ` (0 outside the support; zero mean when the support is the
    /// whole image).
    pub height: Plane,
    /// Whether the support has a border inside the image (a Dirichlet boundary was held).
    pub held: bool,
    /// Conjugate-gradient iterations (0 without a border: direct solver).
    pub iterations: u32,
    /// Final `‖b − L ζ‖ / ‖b‖` of the conjugate gradients (0 without a border).
    pub relative_residual: f64,
}

/// The change `delta` (pixel samples, y up) made the gradient of a height change that is 0
/// outside `support` (module docs), in the averaged edge model. `support[i]` is pixel `i`
/// (row-major) of the field. `params` gives the tolerance and iteration cap of the conjugate
/// gradients.
///
/// # Errors
/// A support of the wrong length, an empty support, non-finite samples in it, or parameters
/// that [`IntegrateParams::validate`] refuses.
pub fn project_in_support(
    delta: &GradientField,
    support: &[bool],
    params: &IntegrateParams,
) -> Result<SupportProjection, RgbnError> {
    params.validate()?;
    let (w, h) = (delta.width, delta.height);
    let n = w * h;
    if support.len() != n || delta.p.len() != n || delta.q.len() != n {
        return Err(RgbnError::param(
            "support",
            format!(
                "{} pixels (field {}×{} with {} and {} samples)",
                support.len(),
                w,
                h,
                delta.p.len(),
                delta.q.len()
            ),
        ));
    }
    if !support.iter().any(|&s| s) {
        return Err(RgbnError::EmptyMask {
            what: "the support of the change",
        });
    }
    if let Some(i) = (0..n).find(|&i| support[i] && !(delta.p[i].is_finite() && delta.q[i].is_finite()))
    {
        return Err(RgbnError::param(
            "support",
            format!("the change at pixel ({}, {}) is not finite", i % w, i / w),
        ));
    }
    if support.iter().all(|&s| s) {
        let whole = IntegrateParams {
            method: IntegrationMethod::PoissonDct,
            differences: Differences::Averaged,
            ..params.clone()
        };
        let (z, _) = integrate_gradients(delta, None, &whole)?;
        let change = gradients_of_height(&z, None, Some(delta), Differences::Averaged);
        return Ok(SupportProjection {
            change,
            height: z,
            held: false,
            iterations: 0,
            relative_residual: 0.0,
        });
    }
    let (z, iterations, relative_residual) = dirichlet_height(delta, support, params)?;
    let change = held_samples(&z, support, delta);
    Ok(SupportProjection {
        change,
        height: Plane::from_vec(w, h, z.iter().map(|&v| v as f32).collect())?,
        held: true,
        iterations,
        relative_residual,
    })
}

/// An edit of `reference`'s normals (`edited`: the same image after the edit) made integrable
/// inside `support` (module docs): the change of the gradients, `g(edited) − g(reference)`
/// on the support, is replaced by [`project_in_support`]'s, and the normals inside the support
/// are those of `g(reference) + change`. Pixels outside the support, colour and mask are those
/// of `edited` (unchanged: the support must contain every pixel the edit changed).
///
/// # Errors
/// Images of different sizes, and as [`project_in_support`].
pub fn integrable_edit(
    reference: &RgbnImage,
    edited: &RgbnImage,
    support: &[bool],
    params: &IntegrateParams,
) -> Result<(RgbnImage, SupportProjection), RgbnError> {
    let (w, h) = (edited.width(), edited.height());
    if (reference.width(), reference.height()) != (w, h) {
        return Err(RgbnError::SizeMismatch {
            what: "reference",
            want_w: w,
            want_h: h,
            got_w: reference.width(),
            got_h: reference.height(),
            path: "".into(),
        });
    }
    let (gr, ge) = (
        GradientField::from_normals(reference),
        GradientField::from_normals(edited),
    );
    let held = |a: &[f32], b: &[f32]| -> Vec<f32> {
        a.par_iter()
            .zip(b)
            .zip(support)
            .map(|((e, r), &s)| if s { e - r } else { 0.0 })
            .collect()
    };
    let delta = GradientField {
        width: w,
        height: h,
        p: held(&ge.p, &gr.p),
        q: held(&ge.q, &gr.q),
        clamped: 0,
    };
    let proj = project_in_support(&delta, support, params)?;
    let mut normal = edited.normal().clone();
    let [nx, ny, nz] = &mut normal;
    nx.par_iter_mut()
        .zip(ny.par_iter_mut())
        .zip(nz.par_iter_mut())
        .enumerate()
        .filter(|(i, _)| support[*i])
        .for_each(|(i, ((x, y), z))| {
            [*x, *y, *z] = normal_of_gradient(gr.p[i] + proj.change.p[i], gr.q[i] + proj.change.q[i]);
        });
    Ok((edited.with_normals(normal)?, proj))
}

/// Step 1 with a border: `ζ` on the support, 0 outside (module docs).
fn dirichlet_height(
    delta: &GradientField,
    support: &[bool],
    params: &IntegrateParams,
) -> Result<(Vec<f64>, u32, f64), RgbnError> {
    let (w, h) = (delta.width, delta.height);
    let n = w * h;
    let e = delta.edge_values(Differences::Averaged);
    // Edges with at least one end in the support, weight 1.
    let wx: Vec<f32> = par_rows(w, h, |r, out: &mut [f32]| {
        for (x, o) in out.iter_mut().enumerate() {
            let i = r * w + x;
            *o = f32::from(u8::from(x + 1 < w && (support[i] || support[i + 1])));
        }
    });
    let wy: Vec<f32> = par_rows(w, h, |r, out: &mut [f32]| {
        if r + 1 < h {
            for (x, o) in out.iter_mut().enumerate() {
                let i = r * w + x;
                *o = f32::from(u8::from(support[i] || support[i + w]));
            }
        }
    });
    // Targets: z[i+1] − z[i] = e_p(i); z[i+w] − z[i] = −e_q(i+w) (module docs of `super`).
    let ex = |i: usize| f64::from(e.p[i]);
    let ey = |i: usize| -f64::from(e.q[i + w]);
    let b: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !support[i] {
                return 0.0;
            }
            let (x, r) = (i % w, i / w);
            let mut s = 0.0;
            if x >= 1 && wx[i - 1] > 0.0 {
                s += ex(i - 1);
            }
            if x + 1 < w && wx[i] > 0.0 {
                s -= ex(i);
            }
            if r >= 1 && wy[i - w] > 0.0 {
                s += ey(i - w);
            }
            if r + 1 < h && wy[i] > 0.0 {
                s -= ey(i);
            }
            s
        })
        .collect();
    // (L z)_i = Σ over the edges touching i of (z_i − z_j), z_j = 0 outside the support.
    let apply = |z: &[f64], out: &mut [f64]| {
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            if !support[i] {
                *o = 0.0;
                return;
            }
            let (x, r) = (i % w, i / w);
            let zi = z[i];
            let mut s = 0.0;
            let mut edge = |wt: f32, j: usize| {
                if wt > 0.0 {
                    s += zi - if support[j] { z[j] } else { 0.0 };
                }
            };
            if x >= 1 {
                edge(wx[i - 1], i - 1);
            }
            if x + 1 < w {
                edge(wx[i], i + 1);
            }
            if r >= 1 {
                edge(wy[i - w], i - w);
            }
            if r + 1 < h {
                edge(wy[i], i + w);
            }
            *o = s;
        });
    };
    let mut mg = Multigrid::new(w, h, wx.clone(), wy.clone());
    // The pixels outside the support are the boundary: inert (kept at 0) on the finest level.
    mg.levels[0]
        .inv_diag
        .par_iter_mut()
        .zip(support.par_iter())
        .for_each(|(d, &s)| {
            if !s {
                *d = 0.0;
            }
        });
    let dot = |a: &[f64], b: &[f64]| a.par_iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let b_norm = dot(&b, &b).sqrt();
    let mut z = vec![0.0f64; n];
    if b_norm == 0.0 {
        return Ok((z, 0, 0.0));
    }
    let precondition = |mg: &mut Multigrid, r: &[f64], out: &mut Vec<f64>| {
        mg.apply(r);
        out.par_iter_mut()
            .zip(mg.levels[0].x.par_iter().zip(support.par_iter()))
            .for_each(|(o, (&v, &s))| *o = if s { f64::from(v) } else { 0.0 });
    };
    let mut r = b.clone();
    let mut y = vec![0.0f64; n];
    precondition(&mut mg, &r, &mut y);
    let mut d = y.clone();
    let mut ry = dot(&r, &y);
    let mut ad = vec![0.0f64; n];
    let mut rel = 1.0;
    let mut iterations = 0u32;
    while iterations < params.max_iterations && rel > params.tolerance && ry > 0.0 {
        apply(&d, &mut ad);
        let dad = dot(&d, &ad);
        if dad <= 0.0 {
            break;
        }
        let alpha = ry / dad;
        z.par_iter_mut().zip(&d).for_each(|(z, d)| *z += alpha * d);
        r.par_iter_mut().zip(&ad).for_each(|(r, a)| *r -= alpha * a);
        iterations += 1;
        rel = dot(&r, &r).sqrt() / b_norm;
        if rel <= params.tolerance {
            break;
        }
        precondition(&mut mg, &r, &mut y);
        let ry_new = dot(&r, &y);
        let beta = ry_new / ry;
        ry = ry_new;
        d.par_iter_mut().zip(&y).for_each(|(d, y)| *d = y + beta * *d);
    }
    // The true residual (the recurrence drifts from it in long runs).
    apply(&z, &mut ad);
    let res: f64 = b.iter().zip(&ad).map(|(b, a)| (b - a).powi(2)).sum::<f64>();
    Ok((z, iterations, res.sqrt() / b_norm))
}

/// Step 2 with a border: per run of the support, the samples whose averaged edges are the
/// differences of `z`, held at 0 just outside the run (module docs); `fallback` (the change)
/// where a run spans the whole line.
fn held_samples(z: &[f64], support: &[bool], fallback: &GradientField) -> GradientField {
    let (w, h) = (fallback.width, fallback.height);
    let mut out = GradientField::zeros(w, h);
    out.p.par_chunks_mut(w.max(1)).enumerate().for_each(|(r, pr)| {
        let o = r * w;
        held_line(
            w,
            |k| support[o + k],
            |k| z[o + k + 1] - z[o + k],
            |k| f64::from(fallback.p[o + k]),
            |k, v| pr[k] = v,
        );
    });
    // Columns top to bottom: edge k → k+1 is z(k) − z(k+1) = ½(q(k) + q(k+1)).
    let cols: Vec<Vec<f32>> = (0..w)
        .into_par_iter()
        .map(|x| {
            let mut col = vec![0.0f32; h];
            held_line(
                h,
                |k| support[k * w + x],
                |k| z[k * w + x] - z[(k + 1) * w + x],
                |k| f64::from(fallback.q[k * w + x]),
                |k, v| col[k] = v,
            );
            col
        })
        .collect();
    out.q.par_chunks_mut(w.max(1)).enumerate().for_each(|(r, qr)| {
        for (o, col) in qr.iter_mut().zip(&cols) {
            *o = col[r];
        }
    });
    out
}

/// One line of [`held_samples`]: `len` samples, membership `ins`, edge targets `dz(k)` for the
/// edge `k → k+1`, fallback samples `f`; writes the support's samples through `out` (0
/// elsewhere).
fn held_line(
    len: usize,
    ins: impl Fn(usize) -> bool,
    dz: impl Fn(usize) -> f64,
    f: impl Fn(usize) -> f64,
    mut out: impl FnMut(usize, f32),
) {
    let mut k = 0;
    let (mut diag, mut rhs) = (Vec::new(), Vec::new());
    while k < len {
        if !ins(k) {
            out(k, 0.0);
            k += 1;
            continue;
        }
        let a = k;
        while k < len && ins(k) {
            k += 1;
        }
        let b = k - 1;
        let n = b - a + 1;
        if a == 0 && b == len - 1 {
            // From image edge to image edge: n − 1 equations, the solution closest to f
            // (s = f + Aᵀ y, A Aᵀ y = d − A f with A Aᵀ = tridiag(¼, ½, ¼)).
            if n == 1 {
                out(a, f(a) as f32);
                continue;
            }
            let m = n - 1;
            diag.clear();
            rhs.clear();
            diag.resize(m, 2.0);
            rhs.extend((0..m).map(|j| 4.0 * (dz(a + j) - 0.5 * (f(a + j) + f(a + j + 1)))));
            let y = solve_tridiagonal(&mut diag, &mut rhs);
            for j in 0..n {
                let left = if j >= 1 { y[j - 1] } else { 0.0 };
                let right = if j < m { y[j] } else { 0.0 };
                out(a + j, (f(a + j) + 0.5 * (left + right)) as f32);
            }
            continue;
        }
        // Held at one end or both: the least-squares samples, (AᵀA) s = Aᵀ d, scaled by 4:
        // diagonal = the number of edges touching the sample, off-diagonal 1, right-hand side
        // 2 × the sum of those edges' targets.
        diag.clear();
        rhs.clear();
        for j in a..=b {
            let (left, right) = (j >= 1, j + 1 < len);
            diag.push(f64::from(u8::from(left)) + f64::from(u8::from(right)));
            let mut s = 0.0;
            if left {
                s += dz(j - 1);
            }
            if right {
                s += dz(j);
            }
            rhs.push(2.0 * s);
        }
        let s = solve_tridiagonal(&mut diag, &mut rhs);
        for (j, v) in s.iter().enumerate() {
            out(a + j, *v as f32);
        }
    }
}

/// Solves the symmetric tridiagonal system with diagonal `diag` and every off-diagonal 1
/// (positive definite) for `rhs` in place (Thomas); returns the solution (in `rhs`).
fn solve_tridiagonal<'a>(diag: &mut [f64], rhs: &'a mut [f64]) -> &'a [f64] {
    let m = diag.len();
    for j in 1..m {
        let c = 1.0 / diag[j - 1];
        diag[j] -= c;
        rhs[j] -= c * rhs[j - 1];
    }
    for j in (0..m).rev() {
        let next = if j + 1 < m { rhs[j + 1] } else { 0.0 };
        rhs[j] = (rhs[j] - next) / diag[j];
    }
    rhs
}

#[cfg(test)]
mod tests {
    use super::super::non_integrable_fraction;
    use super::*;

    /// A smooth height, a vortex (curl only) and their gradients' samples.
    fn field(w: usize, h: usize, cx: f64, cy: f64, vortex: f64) -> (GradientField, Plane) {
        let z = Plane::from_fn(w, h, |x, r| {
            let (u, v) = (x as f64 - cx, r as f64 - cy);
            (3.0 * (-(u * u + v * v) / 200.0).exp()) as f32
        });
        let mut g = gradients_of_height(&z, None, None, Differences::Averaged);
        for r in 0..h {
            for x in 0..w {
                let (u, v) = (x as f64 - cx, cy - r as f64);
                let psi = vortex * (-(u * u + v * v) / 128.0).exp();
                let (dpu, dpv) = (-2.0 * u / 128.0 * psi, -2.0 * v / 128.0 * psi);
                g.p[r * w + x] += dpv as f32;
                g.q[r * w + x] -= dpu as f32;
            }
        }
        (g, z)
    }

    fn disc(w: usize, h: usize, cx: f64, cy: f64, radius: f64) -> Vec<bool> {
        (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f64 - cx, (i / w) as f64 - cy);
                u * u + v * v <= radius * radius
            })
            .collect()
    }

    /// The tridiagonal solve against a dense elimination.
    #[test]
    fn the_tridiagonal_solve_solves() {
        let diag0 = [2.0, 2.0, 1.0, 2.0, 1.0];
        let rhs0 = [1.0, -2.0, 0.5, 3.0, -1.0];
        let (mut d, mut r) = (diag0, rhs0);
        let s = solve_tridiagonal(&mut d, &mut r).to_vec();
        for j in 0..5 {
            let mut v = diag0[j] * s[j];
            if j >= 1 {
                v += s[j - 1];
            }
            if j + 1 < 5 {
                v += s[j + 1];
            }
            assert!((v - rhs0[j]).abs() < 1e-12, "{j}: {v} vs {}", rhs0[j]);
        }
    }

    /// A change that is already the gradient of a height vanishing outside the support comes
    /// back unchanged (to rounding), with its height: the projection keeps what is already a
    /// held surface.
    #[test]
    fn a_held_surface_change_is_kept() {
        let (w, h) = (72, 64);
        let support = disc(w, h, 34.0, 30.0, 24.0);
        // A bump that is 0 (to 1e-9) well inside the disc's border: its samples vanish on the
        // border runs' held ends.
        let z = Plane::from_fn(w, h, |x, r| {
            let (u, v) = (x as f64 - 34.0, r as f64 - 30.0);
            (2.0 * (-(u * u + v * v) / 30.0).exp()) as f32
        });
        let g = gradients_of_height(&z, None, None, Differences::Averaged);
        let delta = GradientField {
            p: g.p.iter().zip(&support).map(|(v, &s)| if s { *v } else { 0.0 }).collect(),
            q: g.q.iter().zip(&support).map(|(v, &s)| if s { *v } else { 0.0 }).collect(),
            ..g.clone()
        };
        let out = project_in_support(&delta, &support, &IntegrateParams::default()).unwrap();
        assert!(out.held);
        eprintln!("held surface: {} iterations, residual {:.1e}", out.iterations, out.relative_residual);
        assert!(out.relative_residual <= 1e-6);
        let worst = (0..w * h)
            .map(|i| (out.change.p[i] - delta.p[i]).abs().max((out.change.q[i] - delta.q[i]).abs()))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-4, "{worst}");
        let dz = (0..w * h)
            .map(|i| (out.height.data()[i] - if support[i] { z.data()[i] } else { 0.0 }).abs())
            .fold(0.0f32, f32::max);
        assert!(dz < 1e-4, "{dz}");
    }

    /// A vortex (no height at all) added to a held surface change inside a disc: the projection
    /// removes it, keeps the surface part, leaves every pixel outside untouched, and the base
    /// plus the change reads integrable (F) where the change with the vortex did not.
    #[test]
    fn a_vortex_inside_the_support_is_removed_and_the_outside_is_kept() {
        let (w, h) = (80, 72);
        let support = disc(w, h, 40.0, 36.0, 30.0);
        let (with_vortex, _) = field(w, h, 40.0, 36.0, 2.0);
        let (surface, _) = field(w, h, 40.0, 36.0, 0.0);
        let keep = |g: &GradientField| GradientField {
            p: g.p.iter().zip(&support).map(|(v, &s)| if s { *v } else { 0.0 }).collect(),
            q: g.q.iter().zip(&support).map(|(v, &s)| if s { *v } else { 0.0 }).collect(),
            ..g.clone()
        };
        let (delta, clean) = (keep(&with_vortex), keep(&surface));
        // A base: a tilted plane (integrable), plus the change.
        let base = GradientField {
            p: vec![0.2; w * h],
            q: vec![-0.1; w * h],
            ..GradientField::zeros(w, h)
        };
        let add = |a: &GradientField, b: &GradientField| GradientField {
            p: a.p.iter().zip(&b.p).map(|(x, y)| x + y).collect(),
            q: a.q.iter().zip(&b.q).map(|(x, y)| x + y).collect(),
            ..a.clone()
        };
        let out = project_in_support(&delta, &support, &IntegrateParams::default()).unwrap();
        for i in 0..w * h {
            if !support[i] {
                assert_eq!((out.change.p[i], out.change.q[i]), (0.0, 0.0));
            }
        }
        let f_before = non_integrable_fraction(&add(&base, &delta), None).unwrap();
        let f_after = non_integrable_fraction(&add(&base, &out.change), None).unwrap();
        let f_clean = non_integrable_fraction(&add(&base, &clean), None).unwrap();
        eprintln!(
            "vortex in a disc: F {f_before:.3e} → {f_after:.3e} (the surface part alone \
             {f_clean:.3e}); {} CG iterations",
            out.iterations
        );
        assert!(f_before > 0.05, "{f_before}");
        assert!(f_after < 2e-3 && f_after < f_before / 50.0, "{f_after}");
        // The surface part survives: the result is close to it, not to zero.
        let rms = |a: &GradientField, b: &GradientField| {
            let s: f64 = (0..w * h)
                .map(|i| f64::from(a.p[i] - b.p[i]).powi(2) + f64::from(a.q[i] - b.q[i]).powi(2))
                .sum();
            (s / (w * h) as f64).sqrt()
        };
        let zero = GradientField::zeros(w, h);
        let (to_clean, size) = (rms(&out.change, &clean), rms(&clean, &zero));
        eprintln!("RMS from the surface part {to_clean:.3e} (its size {size:.3e})");
        assert!(to_clean < 0.2 * size, "{to_clean} vs {size}");
    }

    /// Without a border (the whole image as support) the projection is the plain least
    /// squares: F of the change made integrable is rounding.
    #[test]
    fn the_whole_image_as_support_is_the_plain_projection() {
        let (w, h) = (64, 48);
        let (g, _) = field(w, h, 30.0, 22.0, 3.0);
        let all = vec![true; w * h];
        let out = project_in_support(&g, &all, &IntegrateParams::default()).unwrap();
        assert!(!out.held);
        let f = non_integrable_fraction(&out.change, None).unwrap();
        assert!(non_integrable_fraction(&g, None).unwrap() > 0.05);
        assert!(f < 1e-5, "{f}");
    }

    #[test]
    fn bad_supports_are_refused() {
        let g = GradientField::zeros(8, 8);
        let p = IntegrateParams::default();
        assert!(project_in_support(&g, &[true; 10], &p)
            .unwrap_err()
            .to_string()
            .contains("support"));
        assert!(project_in_support(&g, &[false; 64], &p)
            .unwrap_err()
            .to_string()
            .contains("empty"));
        let mut bad = g.clone();
        bad.p[9] = f32::NAN;
        let e = project_in_support(&bad, &[true; 64], &p).unwrap_err().to_string();
        assert!(e.contains("(1, 1)"), "{e}");
    }
}
