//! A change of a gradient field made integrable inside its support, with the support's border
//! held: the masked projection with a Dirichlet boundary that `combine.rotation`'s
//! `integrable` option uses ([`project_in_support`]).
//!
//! # The problem
//!
//! An edit changes the samples of an image's gradient field by `δ` on a support `S` (0
//! elsewhere). Outside `S` the image must stay as it was, so the nearest change of the form
//! "the gradient of a height change `ζ` that is 0 outside `S`" is wanted: added to the image's
//! own gradients it leaves the image exactly as integrable as it was, and the border of `S` at
//! the unedited image's height.
//!
//! - **Without a border** (`S` is the whole image): the least squares of the module docs of
//!   [`super`] in the averaged edge model (DCT solver, Neumann at the image's edge), and the
//!   samples closest to `δ` whose averaged edges are `ζ`'s differences
//!   ([`super::gradients_of_height`]). Exactly integrable; the free constant changes nothing.
//! - **With a border**, in the averaged model a held border cannot be met by pixel samples:
//!   along a row, samples whose neighbours outside are fixed have one equation more than
//!   unknowns, and the leftover is an alternating pattern along the whole row (a visible
//!   streak). So `ζ` lives at the **pixel corners**, as the pen's integrable mode and the
//!   analytic surfaces make their relief ([`GradientField::from_corner_heights`]): a pixel's
//!   change is the 2 × 2 difference of its corners, `p = ½(ζ_tr − ζ_tl + ζ_br − ζ_bl)`,
//!   `q = ½(ζ_tl − ζ_bl + ζ_tr − ζ_br)` (y up), exactly integrable in the averaged model
//!   whatever the corners. A corner is free when every pixel around it is in `S`, else held
//!   at 0, so every pixel outside `S` keeps its samples exactly. The corners minimise
//!   `Σ_{i ∈ S} |G ζ(i) − δ_i|²`, the distance in the samples themselves. With
//!   `u = p + q`, `v = p − q` a pixel's term is `½[(ζ_tr − ζ_bl − u)² + (ζ_br − ζ_tl − v)²]`:
//!   differences along the two diagonals. The corners of even and of odd `X + R` never meet,
//!   so these are two independent Poisson problems, each a 5-point Laplacian on a grid turned
//!   by 45° (corner `(X, R)` ↦ column `(X + R)/2`, row `(X − R)/2` shifted), with a Dirichlet
//!   boundary at the held corners and Neumann at the image's edge. (Their null space — the
//!   corners' checkerboard — gives no samples, so it does not matter.)
//!
//! # The solver
//!
//! Conjugate gradients on each Dirichlet Laplacian, preconditioned by one V-cycle of the
//! multigrid of [`super::edges`] built on its edges, with the held nodes inert on the finest
//! level (kept at 0 by its Gauss–Seidel sweeps, as the boundary is), and `f64` Krylov vectors.

use super::multigrid::Multigrid;
use super::{gradients_of_height, integrate_gradients, IntegrateParams, IntegrationMethod};
use crate::error::RgbnError;
use crate::raster::gradient::{normal_of_gradient, Differences, GradientField};
use crate::raster::par::ordered_dot;
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
    if let Some(i) =
        (0..n).find(|&i| support[i] && !(delta.p[i].is_finite() && delta.q[i].is_finite()))
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
    let (zc, iterations, relative_residual) = held_corners(delta, support, params)?;
    let (mut change, height) = GradientField::from_corner_heights(w, h, &zc);
    change.clamped = 0;
    Ok(SupportProjection {
        change,
        height,
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
            [*x, *y, *z] =
                normal_of_gradient(gr.p[i] + proj.change.p[i], gr.q[i] + proj.change.q[i]);
        });
    Ok((edited.with_normals(normal)?, proj))
}

/// The held case (module docs): the corner heights, `(W + 1) × (H + 1)` row-major (0 at the
/// held corners), the larger iteration count of the two sublattices and the larger relative
/// residual.
fn held_corners(
    delta: &GradientField,
    support: &[bool],
    params: &IntegrateParams,
) -> Result<(Vec<f64>, u32, f64), RgbnError> {
    let (w, h) = (delta.width, delta.height);
    let cw = w + 1;
    let mut zc = vec![0.0f64; cw * (h + 1)];
    let ins = |x: usize, r: usize| support[r * w + x];
    // A corner is free when every pixel around it (those that exist) is in the support.
    let free_corner = |cx: usize, cr: usize| {
        let (x0, x1) = (cx.saturating_sub(1), cx.min(w - 1));
        let (r0, r1) = (cr.saturating_sub(1), cr.min(h - 1));
        (r0..=r1).all(|r| (x0..=x1).all(|x| ins(x, r)))
    };
    // The turned grid of one parity: corner (X, R) with X + R ≡ parity ↦ column (X + R)/2,
    // row (X − R + H + 1 − shift)/2; both diagonal neighbours are one step along an axis.
    let (gw, gh) = ((w + h) / 2 + 2, (w + h) / 2 + 2);
    let (mut iterations, mut residual) = (0u32, 0.0f64);
    for parity in 0..2 {
        let shift = (parity + h + 1) % 2;
        let map = |cx: usize, cr: usize| -> usize {
            let a = (cx + cr - parity) / 2;
            let b = (cx + h + 1 - cr - shift) / 2;
            b * gw + a
        };
        let n = gw * gh;
        let (mut wx, mut ex) = (vec![0.0f32; n], vec![0.0f64; n]);
        let (mut wy, mut ey) = (vec![0.0f32; n], vec![0.0f64; n]);
        let mut corner_of = vec![usize::MAX; n];
        let mut free = vec![false; n];
        for r in 0..h {
            for x in 0..w {
                if !ins(x, r) {
                    continue;
                }
                let i = r * w + x;
                let (p, q) = (f64::from(delta.p[i]), f64::from(delta.q[i]));
                let mut touch = |cx: usize, cr: usize| {
                    let m = map(cx, cr);
                    corner_of[m] = cr * cw + cx;
                    free[m] = free_corner(cx, cr);
                    m
                };
                if (x + r) % 2 == parity {
                    // tl → br: one step along the turned grid's columns, target v = p − q.
                    let m = touch(x, r);
                    touch(x + 1, r + 1);
                    wx[m] = 1.0;
                    ex[m] = p - q;
                } else {
                    // bl → tr: one step along its rows, target u = p + q.
                    let m = touch(x, r + 1);
                    touch(x + 1, r);
                    wy[m] = 1.0;
                    ey[m] = p + q;
                }
            }
        }
        let (z, it, res) = solve_held(gw, gh, wx, &ex, wy, &ey, &free, params)?;
        iterations = iterations.max(it);
        residual = residual.max(res);
        for (m, &c) in corner_of.iter().enumerate() {
            if c != usize::MAX && free[m] {
                zc[c] = z[m];
            }
        }
    }
    Ok((zc, iterations, residual))
}

/// Minimises `Σ wx_i (z_{i+1} − z_i − ex_i)² + Σ wy_i (z_{i+w} − z_i − ey_i)²` (weights 0 or 1,
/// row-major `w × h`, as [`super::edges`]) over the `free` nodes, every other node held at 0:
/// conjugate gradients preconditioned by the multigrid with the held nodes inert (module
/// docs). Returns `z` (0 at held nodes), the iterations and the final relative residual.
#[allow(clippy::too_many_arguments)]
fn solve_held(
    w: usize,
    h: usize,
    wx: Vec<f32>,
    ex: &[f64],
    wy: Vec<f32>,
    ey: &[f64],
    free: &[bool],
    params: &IntegrateParams,
) -> Result<(Vec<f64>, u32, f64), RgbnError> {
    let n = w * h;
    let b: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !free[i] {
                return 0.0;
            }
            let (x, r) = (i % w, i / w);
            let mut s = 0.0;
            if x >= 1 && wx[i - 1] > 0.0 {
                s += ex[i - 1];
            }
            if x + 1 < w && wx[i] > 0.0 {
                s -= ex[i];
            }
            if r >= 1 && wy[i - w] > 0.0 {
                s += ey[i - w];
            }
            if r + 1 < h && wy[i] > 0.0 {
                s -= ey[i];
            }
            s
        })
        .collect();
    if let Some(i) = b.iter().position(|v| !v.is_finite()) {
        return Err(RgbnError::param(
            "support",
            format!("the change near turned-grid node {i} is not finite"),
        ));
    }
    // (L z)_i = Σ over the edges at i of (z_i − z_j), z_j = 0 at held nodes.
    let apply = |z: &[f64], out: &mut [f64]| {
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            if !free[i] {
                *o = 0.0;
                return;
            }
            let (x, r) = (i % w, i / w);
            let zi = z[i];
            let mut s = 0.0;
            let mut edge = |wt: f32, j: usize| {
                if wt > 0.0 {
                    s += zi - if free[j] { z[j] } else { 0.0 };
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
    let dot = ordered_dot;
    let b_norm = dot(&b, &b).sqrt();
    let mut z = vec![0.0f64; n];
    if b_norm == 0.0 {
        return Ok((z, 0, 0.0));
    }
    let mut mg = Multigrid::new(w, h, wx.clone(), wy.clone());
    // The held nodes are the boundary: inert (kept at 0) on the finest level.
    mg.levels[0]
        .inv_diag
        .par_iter_mut()
        .zip(free.par_iter())
        .for_each(|(d, &f)| {
            if !f {
                *d = 0.0;
            }
        });
    let precondition = |mg: &mut Multigrid, r: &[f64], out: &mut Vec<f64>| {
        mg.apply(r);
        out.par_iter_mut()
            .zip(mg.levels[0].x.par_iter().zip(free.par_iter()))
            .for_each(|(o, (&v, &f))| *o = if f { f64::from(v) } else { 0.0 });
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
        d.par_iter_mut()
            .zip(&y)
            .for_each(|(d, y)| *d = y + beta * *d);
    }
    // The true residual (the recurrence drifts from it in long runs).
    apply(&z, &mut ad);
    let res: f64 = b.iter().zip(&ad).map(|(b, a)| (b - a).powi(2)).sum::<f64>();
    Ok((z, iterations, res.sqrt() / b_norm))
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

    /// A change that is already the gradient of a corner height vanishing outside the support
    /// comes back unchanged (to rounding), with its height: the projection keeps what is
    /// already a held surface.
    #[test]
    fn a_held_surface_change_is_kept() {
        let (w, h) = (72, 64);
        let support = disc(w, h, 34.0, 30.0, 24.0);
        // A bump at the pixel corners, 0 (to 1e-8) well inside the disc's border.
        let zc = crate::raster::gradient::corner_samples(w, h, |x, r| {
            let (u, v) = (x as f64 - 0.5 - 34.0, r as f64 - 0.5 - 30.0);
            2.0 * (-(u * u + v * v) / 30.0).exp()
        });
        let (g, z) = GradientField::from_corner_heights(w, h, &zc);
        let delta = GradientField {
            p: g.p
                .iter()
                .zip(&support)
                .map(|(v, &s)| if s { *v } else { 0.0 })
                .collect(),
            q: g.q
                .iter()
                .zip(&support)
                .map(|(v, &s)| if s { *v } else { 0.0 })
                .collect(),
            ..g.clone()
        };
        let out = project_in_support(&delta, &support, &IntegrateParams::default()).unwrap();
        assert!(out.held);
        eprintln!(
            "held surface: {} iterations, residual {:.1e}",
            out.iterations, out.relative_residual
        );
        assert!(out.relative_residual <= 1e-6);
        let worst = (0..w * h)
            .map(|i| {
                (out.change.p[i] - delta.p[i])
                    .abs()
                    .max((out.change.q[i] - delta.q[i]).abs())
            })
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{worst}");
        let dz = (0..w * h)
            .map(|i| (out.height.data()[i] - if support[i] { z.data()[i] } else { 0.0 }).abs())
            .fold(0.0f32, f32::max);
        assert!(dz < 1e-5, "{dz}");
    }

    /// The conjugate gradients' dot products are added in a fixed order: the projection is the
    /// same bits in pools of 1, 2 and 5 threads (rayon's own `sum` is not).
    #[test]
    fn the_projection_is_the_same_bits_at_every_thread_count() {
        let (w, h) = (300, 260);
        let support = disc(w, h, 150.0, 130.0, 110.0);
        let (delta, _) = field(w, h, 150.0, 130.0, 2.0);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool")
                .install(|| project_in_support(&delta, &support, &IntegrateParams::default()))
                .expect("projects")
        };
        let one = run(1);
        assert!(
            one.held && one.iterations > 1,
            "{} iterations",
            one.iterations
        );
        for threads in [2, 5] {
            let many = run(threads);
            assert_eq!(many.iterations, one.iterations, "{threads} threads");
            let bits = |g: &GradientField| -> Vec<u32> {
                g.p.iter().chain(&g.q).map(|v| v.to_bits()).collect()
            };
            assert!(bits(&many.change) == bits(&one.change), "{threads} threads");
        }
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
            p: g.p
                .iter()
                .zip(&support)
                .map(|(v, &s)| if s { *v } else { 0.0 })
                .collect(),
            q: g.q
                .iter()
                .zip(&support)
                .map(|(v, &s)| if s { *v } else { 0.0 })
                .collect(),
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
        for (i, _) in support.iter().enumerate().filter(|(_, inside)| !**inside) {
            assert_eq!((out.change.p[i], out.change.q[i]), (0.0, 0.0));
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
        assert!(f_after < 1e-4, "{f_after}");
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

    /// A change that does not fade out at the border (a constant tilt inside a disc) becomes
    /// a smooth held cap: no alternating pattern along rows or columns, which a per-row
    /// reconstruction in the averaged model would leave (module docs). Second differences
    /// of the change inside the disc stay far below its size.
    #[test]
    fn a_held_change_has_no_streaks() {
        let (w, h) = (72, 64);
        let support = disc(w, h, 36.0, 32.0, 24.0);
        let delta = GradientField {
            p: support.iter().map(|&s| if s { 0.3 } else { 0.0 }).collect(),
            q: vec![0.0; w * h],
            ..GradientField::zeros(w, h)
        };
        let out = project_in_support(&delta, &support, &IntegrateParams::default()).unwrap();
        let inner = disc(w, h, 36.0, 32.0, 21.0);
        let mut worst = 0.0f32;
        for r in 0..h {
            for x in 0..w - 2 {
                let i = r * w + x;
                if inner[i] && inner[i + 1] && inner[i + 2] {
                    for c in [&out.change.p, &out.change.q] {
                        worst = worst.max((c[i] - 2.0 * c[i + 1] + c[i + 2]).abs());
                    }
                }
            }
        }
        eprintln!("held tilt: largest second difference along rows {worst:.2e} (change 0.3)");
        assert!(worst < 0.03, "{worst}");
        assert!(non_integrable_fraction(&out.change, None).unwrap() < 1e-5);
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
        let e = project_in_support(&bad, &[true; 64], &p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("(1, 1)"), "{e}");
    }
}
