//! Masked Poisson solver: the weighted-edge least squares of [`super::edges`] with weight 1 on
//! the edges with both ends inside the mask and the model's edge values as targets,
//! warm-started from the DCT solution (module docs of [`super`]).

use super::edges::{par_rows, solve_edges_owned};
use super::{inside, poisson_dct, IntegrateParams};
use crate::error::RgbnError;
use crate::raster::gradient::GradientField;
use crate::raster::par::OrderedReduce;
use crate::raster::Plane;
use rayon::prelude::*;

/// Masked Poisson by multigrid-preconditioned CG (`solve_edges`) from the DCT warm start.
/// Returns the height (isolated domain pixels 0, zero mean over the rest of the domain, each
/// component keeping the warm start's mean before that shift; outside the warm start, shifted
/// by the same constant), iterations and final relative residual.
///
/// # Errors
/// Non-finite gradients on an edge inside the mask.
pub(super) fn masked_poisson(
    g: &GradientField,
    m: &[f32],
    params: &IntegrateParams,
) -> Result<(Plane, u32, f64), RgbnError> {
    let (w, h) = (g.width, g.height);
    let n = w * h;
    let d = params.differences;
    let warm = poisson_dct(g, Some(m), d);
    // Cancelled during the warm start: the caller discards whatever comes back (crate::cancel).
    if crate::cancel::Cancel::current().is_cancelled() {
        return Ok((warm, 0, f64::NAN));
    }
    let e = g.edge_values(d);
    let ins = |i: usize| inside(m[i]);
    let wx = par_rows(w, h, |r, out: &mut [f32]| {
        for (x, o) in out.iter_mut().enumerate() {
            let i = r * w + x;
            *o = f32::from(u8::from(x + 1 < w && ins(i) && ins(i + 1)));
        }
    });
    let wy = par_rows(w, h, |r, out: &mut [f32]| {
        if r + 1 < h {
            for (x, o) in out.iter_mut().enumerate() {
                let i = r * w + x;
                *o = f32::from(u8::from(ins(i) && ins(i + w)));
            }
        }
    });
    // The model's vertical edge (x, r+1)–(x, r) reads z(x, r) − z(x, r+1) = e_q(x, r+1).
    let ey = par_rows(w, h, |r, out: &mut [f32]| {
        if r + 1 < h {
            for (o, &q) in out.iter_mut().zip(&e.q[(r + 1) * w..(r + 2) * w]) {
                *o = -q;
            }
        }
    });
    let (s, _) = solve_edges_owned(
        w,
        h,
        wx,
        &e.p,
        wy,
        &ey,
        Some(warm.data()),
        params.tolerance,
        params.max_iterations,
    )
    .map_err(|err| RgbnError::param("gradients (masked Poisson)", err.to_string()))?;
    // Cancelled during the solve: no post-processing of a result that is discarded.
    if crate::cancel::Cancel::current().is_cancelled() {
        return Ok((warm, 0, f64::NAN));
    }
    let has_edge = |i: usize, x: usize| {
        ins(i)
            && ((x + 1 < w && ins(i + 1))
                || (x >= 1 && ins(i - 1))
                || (i + w < n && ins(i + w))
                || (i >= w && ins(i - w)))
    };
    let (sum, count) = (0..h)
        .into_par_iter()
        .map(|r| {
            let (mut sum, mut count) = (0.0f64, 0usize);
            for x in 0..w {
                let i = r * w + x;
                if has_edge(i, x) {
                    sum += f64::from(s.z[i]);
                    count += 1;
                }
            }
            (sum, count)
        })
        .ordered_reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let mean = if count > 0 { sum / count as f64 } else { 0.0 };
    let warm = warm.data();
    let z = par_rows(w, h, |r, out: &mut [f32]| {
        for (x, o) in out.iter_mut().enumerate() {
            let i = r * w + x;
            *o = if !ins(i) {
                (f64::from(warm[i]) - mean) as f32
            } else if has_edge(i, x) {
                (f64::from(s.z[i]) - mean) as f32
            } else {
                0.0
            };
        }
    });
    Ok((
        Plane::from_vec(w, h, z).expect("sizes match by construction"),
        s.iterations,
        s.relative_residual,
    ))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;

    #[test]
    fn masked_poisson_recovers_the_height_inside_an_irregular_mask() {
        let (w, h) = (96, 80);
        let z = rough(w, h);
        // Two blobs (two components) and a hole; garbage gradients outside.
        let mask = Plane::from_fn(w, h, |x, r| {
            let (u, v) = (x as f32 - 30.0, r as f32 - 40.0);
            let blob1 = u * u + v * v < 25.0 * 25.0 && u * u + v * v > 6.0 * 6.0;
            let blob2 = (x as f32 - 80.0).abs() < 10.0 && (r as f32 - 20.0).abs() < 15.0;
            f32::from(u8::from(blob1 || blob2))
        });
        let mut g = GradientField::from_height(&z);
        for (i, &m) in mask.data().iter().enumerate() {
            if m < 0.5 {
                g.p[i] = 50.0;
                g.q[i] = -70.0;
            }
        }
        let params = IntegrateParams {
            method: IntegrationMethod::MaskedPoisson,
            differences: Differences::Forward,
            ..Default::default()
        };
        let (zi, rep) = integrate_gradients(&g, Some(mask.data()), &params).unwrap();
        eprintln!("masked CG: {rep:?}");
        assert!(rep.relative_residual <= 1e-6, "{rep:?}");
        // Each component has its own constant: check them separately.
        for comp in [|x: usize, _r: usize| x < 60, |x: usize, _r: usize| x >= 60] {
            let sel = Plane::from_fn(w, h, |x, r| {
                f32::from(u8::from(comp(x, r) && mask.at(x, r) > 0.5))
            });
            let e = max_err_up_to_constant(&zi, &z, Some(sel.data()));
            assert!(e < 2e-3, "max error {e}");
        }
        // The DCT solver on the full grid is badly hurt by the garbage outside.
        let dct = IntegrateParams {
            differences: Differences::Forward,
            ..Default::default()
        };
        let (zd, _) = integrate_gradients(&g, None, &dct).unwrap();
        assert!(max_err_up_to_constant(&zd, &z, Some(mask.data())) > 1.0);
    }
}

#[cfg(test)]
mod convergence_tests {
    use super::super::*;
    use crate::raster::sample::Surface;

    #[test]
    fn multigrid_cg_needs_few_iterations_on_a_large_irregular_mask() {
        // The bench's setting, scaled down: a wobbly ellipse over half the frame.
        half_frame_ellipse_converges(480, 270);
    }

    #[test]
    fn multigrid_cg_converges_where_it_once_diverged() {
        // At 1920 × 2160 multigrid-preconditioned CG once fell to 3e-5, then diverged to 5e4
        // (the coarsest level was solved by Gauss–Seidel: edges.rs docs), and the Jacobi
        // restart bounded it. Now MG-PCG converges by itself here, in ≤ 30 iterations; the
        // restart is tested where it fires (edges_tests.rs, an indefinite preconditioner).
        half_frame_ellipse_converges(1920, 2160);
    }

    fn half_frame_ellipse_converges(w: usize, h: usize) {
        let (img, _) = Surface::gaussians_for(h).render(w, h);
        let g = GradientField::from_normals(&img);
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        let k = (2.0 / std::f64::consts::PI).sqrt();
        let mask: Vec<f32> = (0..w * h)
            .map(|i| {
                let (u, v) = (((i % w) as f64 - cx) / cx, ((i / w) as f64 - cy) / cy);
                let edge = k * (1.0 + 0.08 * (5.0 * v.atan2(u)).sin());
                f32::from(u8::from(u.hypot(v) < edge))
            })
            .collect();
        let params = IntegrateParams {
            method: IntegrationMethod::MaskedPoisson,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let (z, rep) = integrate_gradients(&g, Some(&mask), &params).unwrap();
        eprintln!(
            "{w}×{h} half mask: {rep:?}, solve {:.3} s",
            t.elapsed().as_secs_f64()
        );
        assert!(rep.relative_residual <= 1e-6, "{rep:?}");
        assert!(rep.iterations <= 30, "{rep:?}");
        assert!(z.data().iter().all(|v| v.is_finite()));
    }
}
