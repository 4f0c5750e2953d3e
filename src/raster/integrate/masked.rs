//! Masked Poisson solver: conjugate gradients with a Jacobi preconditioner on the masked
//! Laplacian, warm-started from the DCT solution (module docs of [`super`]).

use super::{divergence, inside, poisson_dct, IntegrateParams};
use crate::raster::gradient::GradientField;
use crate::raster::Plane;
use rayon::prelude::*;

/// `y = L x` for the masked Laplacian (edges with both ends inside).
fn apply_masked_laplacian(x: &[f64], m: &[f32], w: usize, h: usize, y: &mut [f64]) {
    y.par_chunks_mut(w).enumerate().for_each(|(r, out)| {
        for (xx, o) in out.iter_mut().enumerate() {
            let i = r * w + xx;
            if !inside(m[i]) {
                *o = 0.0;
                continue;
            }
            let mut s = 0.0;
            let xi = x[i];
            if xx >= 1 && inside(m[i - 1]) {
                s += xi - x[i - 1];
            }
            if xx + 1 < w && inside(m[i + 1]) {
                s += xi - x[i + 1];
            }
            if r >= 1 && inside(m[i - w]) {
                s += xi - x[i - w];
            }
            if r + 1 < h && inside(m[i + w]) {
                s += xi - x[i + w];
            }
            *o = s;
        }
    });
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.par_chunks(1 << 14)
        .zip(b.par_chunks(1 << 14))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>())
        .sum()
}

/// Masked Poisson by Jacobi-preconditioned CG from the DCT warm start. Returns the height,
/// iterations and final relative residual.
pub(super) fn masked_poisson(
    g: &GradientField,
    m: &[f32],
    params: &IntegrateParams,
) -> (Plane, u32, f64) {
    let (w, h) = (g.width, g.height);
    let n = w * h;
    let warm = poisson_dct(g, Some(m));
    let b: Vec<f64> = divergence(g, Some(m)).into_iter().map(f64::from).collect();
    let mut x: Vec<f64> = warm.data().iter().map(|&v| f64::from(v)).collect();
    // Inverse node degrees (0 outside and for isolated pixels).
    let inv_deg: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !inside(m[i]) {
                return 0.0;
            }
            let (xx, r) = (i % w, i / w);
            let d = usize::from(xx >= 1 && inside(m[i - 1]))
                + usize::from(xx + 1 < w && inside(m[i + 1]))
                + usize::from(r >= 1 && inside(m[i - w]))
                + usize::from(r + 1 < h && inside(m[i + w]));
            if d == 0 {
                0.0
            } else {
                1.0 / d as f64
            }
        })
        .collect();
    let b_norm = dot(&b, &b).sqrt();
    let mut ax = vec![0.0f64; n];
    apply_masked_laplacian(&x, m, w, h, &mut ax);
    let mut res: Vec<f64> = b.par_iter().zip(&ax).map(|(b, a)| b - a).collect();
    let mut zv: Vec<f64> = res.par_iter().zip(&inv_deg).map(|(r, d)| r * d).collect();
    let mut dir = zv.clone();
    let mut rz = dot(&res, &zv);
    let mut iterations = 0u32;
    let mut rel = if b_norm > 0.0 {
        dot(&res, &res).sqrt() / b_norm
    } else {
        0.0
    };
    while iterations < params.max_iterations && rel > params.tolerance && rz > 0.0 {
        apply_masked_laplacian(&dir, m, w, h, &mut ax);
        let dad = dot(&dir, &ax);
        if dad <= 0.0 {
            break;
        }
        let alpha = rz / dad;
        x.par_iter_mut()
            .zip(&dir)
            .for_each(|(x, d)| *x += alpha * d);
        res.par_iter_mut()
            .zip(&ax)
            .for_each(|(r, a)| *r -= alpha * a);
        zv.par_iter_mut()
            .zip(&res)
            .zip(&inv_deg)
            .for_each(|((z, r), d)| *z = r * d);
        let rz_new = dot(&res, &zv);
        let beta = rz_new / rz;
        rz = rz_new;
        dir.par_iter_mut()
            .zip(&zv)
            .for_each(|(d, z)| *d = z + beta * *d);
        iterations += 1;
        rel = dot(&res, &res).sqrt() / b_norm;
    }
    // Zero mean over the mask; outside keeps the warm start, shifted by the same constant.
    let (s, c) = x
        .iter()
        .zip(m)
        .filter(|(_, &mv)| inside(mv))
        .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
    let mean = if c > 0 { s / c as f64 } else { 0.0 };
    let z: Vec<f32> = x.iter().map(|&v| (v - mean) as f32).collect();
    (
        Plane::from_vec(w, h, z).expect("sizes match by construction"),
        iterations,
        rel,
    )
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
        let (zd, _) = integrate_gradients(&g, None, &IntegrateParams::default()).unwrap();
        assert!(max_err_up_to_constant(&zd, &z, Some(mask.data())) > 1.0);
    }
}
