//! DCT Poisson solver (Neumann boundaries, Simchony, Chellappa & Shao 1990; module docs of
//! [`super`]).

use super::divergence_row;
use super::fft::{dct_plan, for_row_pairs, C_ZERO};
use crate::raster::gradient::{Differences, GradientField};
use crate::raster::par::par_column_groups;
use crate::raster::{buf, Plane};
use rustfft::num_complex::Complex;

/// Columns per group of the column passes: one 64-byte cache line of `f32` per row.
const DCT_COLUMN_GROUP: usize = 16;

/// Solves `L z = Dᵀ e` (full rectangle, Neumann; `e` the edge values of model `d`, formed
/// inside the divergence) with DCTs; the domain restricts the edges of the divergence only
/// (used for the masked warm start).
///
/// Three passes over one buffer: (1) row pairs: divergence, DCT-II along x; (2) groups of 16
/// columns gathered into pair buffers: DCT-II along y, division by the eigenvalues, DCT-III
/// along y, scattered back; (3) row pairs: DCT-III along x.
pub(super) fn poisson_dct(g: &GradientField, domain: Option<&[f32]>, d: Differences) -> Plane {
    let (w, h) = (g.width, g.height);
    let (dw, dh) = (dct_plan(w), dct_plan(h));
    let mut z = buf::zeroed_f32(w * h);
    // Cancelled: every pass skips its work and the caller discards `z` (crate::cancel).
    let cancel = crate::cancel::Cancel::current();
    for_row_pairs(&mut z, w, dw.scratch_len, |r, a, mut b, buf, s| {
        if cancel.is_cancelled() {
            return;
        }
        divergence_row(g, domain, d, r, a);
        if let Some(b) = b.as_deref_mut() {
            divergence_row(g, domain, d, r + 1, b);
        }
        dw.dct2_pair(a, b, buf, s);
    });
    // Eigenvalues; DCT-III ∘ DCT-II = N/2 per axis, so scale by 4/(W·H).
    let eig = |n: usize| -> Vec<f32> {
        (0..n)
            .map(|k| (2.0 - 2.0 * (std::f64::consts::PI * k as f64 / n as f64).cos()) as f32)
            .collect()
    };
    let (lx, ly) = (eig(w), eig(h));
    let scale = (4.0 / (w as f64 * h as f64)) as f32;
    let divide = |x: &mut [f32], kx: usize| {
        for (v, &l) in x.iter_mut().zip(&ly) {
            let lam = lx[kx] + l;
            *v = if lam > 0.0 { *v * scale / lam } else { 0.0 };
        }
    };
    let pairs_max = DCT_COLUMN_GROUP / 2;
    par_column_groups(
        &mut z,
        w,
        DCT_COLUMN_GROUP,
        || {
            (
                vec![C_ZERO; pairs_max * h],
                vec![C_ZERO; dh.scratch_len],
                buf::zeroed_f32(2 * h),
            )
        },
        |(buf, scratch, x2), grp| {
            if cancel.is_cancelled() {
                return;
            }
            let (c0, cols) = (grp.c0, grp.cols);
            let buf = &mut buf[..cols.div_ceil(2) * h];
            for (r, &pos) in dh.pos.iter().enumerate() {
                let row = grp.row(r);
                let mut pairs = row.chunks_exact(2);
                for (col, pair) in buf.chunks_exact_mut(h).zip(&mut pairs) {
                    col[pos] = Complex::new(pair[0], pair[1]);
                }
                if let [x] = pairs.remainder() {
                    buf[cols / 2 * h + pos] = Complex::new(*x, 0.0);
                }
            }
            dh.fwd.process_with_scratch(buf, scratch);
            let (xa, xb) = x2.split_at_mut(h);
            for (j, col) in buf.chunks_exact_mut(h).enumerate() {
                let has_b = 2 * j + 1 < cols;
                dh.post2(col, xa, has_b.then_some(&mut *xb));
                divide(xa, c0 + 2 * j);
                if has_b {
                    divide(xb, c0 + 2 * j + 1);
                }
                dh.pre3(xa, has_b.then_some(&*xb), col);
            }
            dh.inv.process_with_scratch(buf, scratch);
            for (r, &pos) in dh.pos.iter().enumerate() {
                let row = grp.row(r);
                let mut pairs = row.chunks_exact_mut(2);
                for (col, pair) in buf.chunks_exact(h).zip(&mut pairs) {
                    pair[0] = col[pos].re;
                    pair[1] = col[pos].im;
                }
                if let [x] = pairs.into_remainder() {
                    *x = buf[cols / 2 * h + pos].re;
                }
            }
        },
    );
    for_row_pairs(&mut z, w, dw.scratch_len, |_, a, b, buf, s| {
        if !cancel.is_cancelled() {
            dw.dct3_pair(a, b, buf, s);
        }
    });
    Plane::from_vec(w, h, z).expect("sizes match by construction")
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;

    #[test]
    fn poisson_dct_matches_a_rustdct_reference() {
        // Independent expectation: divergence straight from the edge equations, 2-D DCT-II /
        // DCT-III with rustdct in f64 (columns extracted explicitly), same eigenvalues.
        let mut dp = rustdct::DctPlanner::<f64>::new();
        for &(w, h) in &ODD_SIZES {
            let g = rough_field(w, h);
            let mut b = vec![0.0f64; w * h];
            for r in 0..h {
                for x in 0..w {
                    let i = r * w + x;
                    if x + 1 < w {
                        b[i] -= f64::from(g.p[i]);
                        b[i + 1] += f64::from(g.p[i]);
                    }
                    if r >= 1 {
                        b[i] -= f64::from(g.q[i]);
                        b[i - w] += f64::from(g.q[i]);
                    }
                }
            }
            let (dx, dy) = (dp.plan_dct2(w), dp.plan_dct2(h));
            let (ix, iy) = (dp.plan_dct3(w), dp.plan_dct3(h));
            let cols = |data: &mut [f64], f: &dyn Fn(&mut [f64])| {
                for x in 0..w {
                    let mut c: Vec<f64> = (0..h).map(|r| data[r * w + x]).collect();
                    f(&mut c);
                    for (r, v) in c.into_iter().enumerate() {
                        data[r * w + x] = v;
                    }
                }
            };
            b.chunks_mut(w).for_each(|r| dx.process_dct2(r));
            cols(&mut b, &|c| dy.process_dct2(c));
            for r in 0..h {
                for x in 0..w {
                    let lam = 4.0
                        - 2.0 * (std::f64::consts::PI * x as f64 / w as f64).cos()
                        - 2.0 * (std::f64::consts::PI * r as f64 / h as f64).cos();
                    let v = &mut b[r * w + x];
                    *v = if x + r == 0 {
                        0.0
                    } else {
                        *v / lam * 4.0 / (w * h) as f64
                    };
                }
            }
            cols(&mut b, &|c| iy.process_dct3(c));
            b.chunks_mut(w).for_each(|r| ix.process_dct3(r));
            let z = poisson_dct(&g, None, Differences::Forward);
            assert_close(z.data(), &b, 1e-4, &format!("DCT Poisson {w}×{h}"));
        }
    }

    #[test]
    fn averaged_divergence_is_the_forward_one_of_the_edge_values() {
        // The fused averaged divergence (no edge-value buffer) against the forward solver fed
        // with the edge values of `GradientField::edge_values`.
        for &(w, h) in &ODD_SIZES {
            let g = rough_field(w, h);
            let e = g.edge_values(Differences::Averaged);
            let want = poisson_dct(&e, None, Differences::Forward);
            let want: Vec<f64> = want.data().iter().map(|&v| f64::from(v)).collect();
            let got = poisson_dct(&g, None, Differences::Averaged);
            assert_close(got.data(), &want, 1e-5, &format!("averaged DCT {w}×{h}"));
        }
    }

    #[test]
    fn dct_poisson_recovers_any_height_from_its_discrete_gradient() {
        for &(w, h) in &[(37, 23), (64, 64), (1, 9), (9, 1), (128, 96)] {
            let z = rough(w, h);
            // Each model with the samples of a height in that model: forward differences,
            // and the averaged model's minimum-norm samples (projection of a height).
            for differences in [Differences::Forward, Differences::Averaged] {
                let g = gradients_of_height(&z, None, None, differences);
                if differences == Differences::Forward {
                    assert_eq!(g, GradientField::from_height(&z));
                }
                let params = IntegrateParams {
                    differences,
                    ..Default::default()
                };
                let (zi, rep) = integrate_gradients(&g, None, &params).unwrap();
                let e = max_err_up_to_constant(&zi, &z, None);
                assert!(e < 2e-3, "{w}×{h} {differences:?}: max error {e}");
                assert!(rep.rms_residual < 1e-3, "{rep:?}");
                let mean = zi.data().iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64;
                assert!(mean.abs() < 1e-3, "zero mean, got {mean}");
            }
        }
    }
}
