//! Frankot–Chellappa solver (periodic boundaries, FFTs; module docs of [`super`]).

use super::fft::{fft_plan, C32, C_ZERO};
use crate::raster::gradient::{Differences, GradientField};
use crate::raster::par::par_column_groups;
use crate::raster::{buf, Plane};
use rayon::prelude::*;
use rustfft::num_complex::Complex;

/// Frequency bins per group of the Frankot–Chellappa column pass (P and Q interleaved: two
/// 64-byte lines per row).
const FFT_COLUMN_GROUP: usize = 8;

/// Frankot–Chellappa: periodic least squares with FFTs (module docs).
///
/// Real-input transforms without waste: (1) each row of `p + i q` is one complex FFT, split
/// into the half spectra (`W/2 + 1` bins) of the `p` and `q` rows, stored interleaved;
/// (2) groups of 8 bins: FFT along y of both, `Ẑ = (ā P̂ + c̄ Q̂)/(|a|² + |c|²)`, inverse FFT
/// along y; (3) two rows of `Ẑ` (Hermitian along x) per inverse FFT of length `W` give two
/// height rows. That is the work of scipy's `rfft2` ×2 + `irfft2`, half the complex 2-D FFTs.
pub(super) fn frankot_chellappa(g: &GradientField, differences: Differences) -> Plane {
    let (w, h) = (g.width, g.height);
    let (fw, iw) = (fft_plan(w, false), fft_plan(w, true));
    let (fh, ih) = (fft_plan(h, false), fft_plan(h, true));
    let hw = w / 2 + 1;
    // (1) Row r of `spec`: [P_0, Q_0, P_1, Q_1, …, P_{hw−1}, Q_{hw−1}].
    let mut spec = vec![C_ZERO; h * 2 * hw];
    // Cancelled: every pass skips its work and the caller discards `z` (crate::cancel).
    let cancel = crate::cancel::Cancel::current();
    spec.par_chunks_mut(2 * hw)
        .zip(g.p.par_chunks(w).zip(g.q.par_chunks(w)))
        .with_min_len(4)
        .for_each_init(
            || (vec![C_ZERO; w], vec![C_ZERO; fw.get_inplace_scratch_len()]),
            |(buf, scratch), (s, (p, q))| {
                if cancel.is_cancelled() {
                    return;
                }
                for ((o, &pv), &qv) in buf.iter_mut().zip(p).zip(q) {
                    *o = Complex::new(pv, qv);
                }
                fw.process_with_scratch(buf, scratch);
                for (k, pq) in s.chunks_exact_mut(2).enumerate() {
                    let c = buf[k];
                    let d = buf[if k == 0 { 0 } else { w - k }].conj();
                    pq[0] = (c + d) * 0.5;
                    pq[1] = (c - d) * Complex::new(0.0, -0.5);
                }
            },
        );
    // (2) ā per x bin, c̄ per y bin (transfer functions of the forward differences), 1/(W·H).
    let tau = std::f64::consts::TAU;
    let abar: Vec<C32> = (0..hw)
        .map(|k| {
            let t = tau * k as f64 / w as f64;
            Complex::new((t.cos() - 1.0) as f32, -t.sin() as f32)
        })
        .collect();
    let cbar: Vec<C32> = (0..h)
        .map(|l| {
            let t = -tau * l as f64 / h as f64;
            Complex::new((t.cos() - 1.0) as f32, -t.sin() as f32)
        })
        .collect();
    // Numerators ā·α, c̄·γ with the data-side transfer functions of the edge model (module
    // docs): averaged, −i sin ω and i sin ω (zero at ω = π: the checkerboard the average
    // cannot see; the denominator |a|² + |c|² only vanishes at (0, 0)).
    let averaged = differences == Differences::Averaged;
    let anum: Vec<C32> = (0..hw)
        .map(|k| {
            if averaged {
                Complex::new(0.0, -(tau * k as f64 / w as f64).sin() as f32)
            } else {
                abar[k]
            }
        })
        .collect();
    let cnum: Vec<C32> = (0..h)
        .map(|l| {
            if averaged {
                Complex::new(0.0, (tau * l as f64 / h as f64).sin() as f32)
            } else {
                cbar[l]
            }
        })
        .collect();
    let scale = (1.0 / (w as f64 * h as f64)) as f32;
    let scratch_len = fh
        .get_inplace_scratch_len()
        .max(ih.get_inplace_scratch_len());
    let g_max = FFT_COLUMN_GROUP;
    par_column_groups(
        &mut spec,
        2 * hw,
        2 * g_max,
        || (vec![C_ZERO; 2 * g_max * h], vec![C_ZERO; scratch_len]),
        |(buf, scratch), grp| {
            if cancel.is_cancelled() {
                return;
            }
            let (k0, bins) = (grp.c0 / 2, grp.cols / 2);
            let (pb, qb) = buf.split_at_mut(g_max * h);
            let (pb, qb) = (&mut pb[..bins * h], &mut qb[..bins * h]);
            for r in 0..h {
                for (j, pq) in grp.row(r).chunks_exact(2).enumerate() {
                    pb[j * h + r] = pq[0];
                    qb[j * h + r] = pq[1];
                }
            }
            fh.process_with_scratch(pb, scratch);
            fh.process_with_scratch(qb, scratch);
            for (j, (pc, qc)) in pb.chunks_exact_mut(h).zip(qb.chunks_exact(h)).enumerate() {
                let kx = k0 + j;
                let (a, na) = (anum[kx], abar[kx].norm_sqr());
                for (l, (pv, qv)) in pc.iter_mut().zip(qc).enumerate() {
                    let den = na + cbar[l].norm_sqr();
                    *pv = if kx == 0 && l == 0 {
                        C_ZERO
                    } else {
                        (a * *pv + cnum[l] * *qv) * (scale / den)
                    };
                }
            }
            ih.process_with_scratch(pb, scratch);
            for r in 0..h {
                for (j, pq) in grp.row(r).chunks_exact_mut(2).enumerate() {
                    pq[0] = pb[j * h + r];
                }
            }
        },
    );
    // (3) Two Hermitian rows per inverse FFT: z_r + i z_{r+1} = IFFT(Ẑ_r + i Ẑ_{r+1}).
    let mut z = buf::zeroed_f32(w * h);
    z.par_chunks_mut(2 * w)
        .zip(spec.par_chunks(4 * hw))
        .with_min_len(4)
        .for_each_init(
            || (vec![C_ZERO; w], vec![C_ZERO; iw.get_inplace_scratch_len()]),
            |(buf, scratch), (out, s)| {
                if cancel.is_cancelled() {
                    return;
                }
                let z1 = |k: usize| s[2 * k];
                let z2 = |k: usize| s.get(2 * hw + 2 * k).copied().unwrap_or(C_ZERO);
                // Ẑ_0 and (W even) Ẑ_{W/2} are real by symmetry: drop their rounding.
                let real = |v: C32| Complex::new(v.re, 0.0);
                let join = |u: C32, v: C32| Complex::new(u.re - v.im, u.im + v.re);
                buf[0] = join(real(z1(0)), real(z2(0)));
                let (lo, hi) = buf.split_at_mut(hw.min(w));
                for (k, o) in lo.iter_mut().enumerate().skip(1) {
                    *o = join(z1(k), z2(k));
                }
                for (k, o) in (hw..w).zip(hi.iter_mut()) {
                    *o = join(z1(w - k).conj(), z2(w - k).conj());
                }
                if w % 2 == 0 && w > 1 {
                    buf[w / 2] = join(real(z1(w / 2)), real(z2(w / 2)));
                }
                iw.process_with_scratch(buf, scratch);
                let (a, b) = out.split_at_mut(w);
                for (x, v) in buf.iter().enumerate() {
                    a[x] = v.re;
                    if let Some(o) = b.get_mut(x) {
                        *o = v.im;
                    }
                }
            },
        );
    Plane::from_vec(w, h, z).expect("sizes match by construction")
}
#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;

    #[test]
    fn frankot_chellappa_matches_a_direct_dft() {
        // Independent expectation: the FC formula with O(N²) DFTs in f64.
        use rustfft::num_complex::Complex64;
        let tau = std::f64::consts::TAU;
        for &(w, h) in &ODD_SIZES {
            let g = rough_field(w, h);
            let dft2 = |v: &dyn Fn(usize) -> Complex64, sign: f64| -> Vec<Complex64> {
                (0..w * h)
                    .map(|o| {
                        let (k, l) = (o % w, o / w);
                        (0..w * h)
                            .map(|i| {
                                let (x, r) = (i % w, i / w);
                                let ph = sign
                                    * tau
                                    * ((k * x) as f64 / w as f64 + (l * r) as f64 / h as f64);
                                v(i) * Complex64::new(ph.cos(), ph.sin())
                            })
                            .sum()
                    })
                    .collect()
            };
            let pf = dft2(&|i| Complex64::new(f64::from(g.p[i]), 0.0), -1.0);
            let qf = dft2(&|i| Complex64::new(f64::from(g.q[i]), 0.0), -1.0);
            let zf: Vec<Complex64> = (0..w * h)
                .map(|o| {
                    let (k, l) = (o % w, o / w);
                    let a = Complex64::from_polar(1.0, tau * k as f64 / w as f64) - 1.0;
                    let c = Complex64::from_polar(1.0, -tau * l as f64 / h as f64) - 1.0;
                    let den = a.norm_sqr() + c.norm_sqr();
                    if o == 0 {
                        Complex64::new(0.0, 0.0)
                    } else {
                        (a.conj() * pf[o] + c.conj() * qf[o]) / den
                    }
                })
                .collect();
            let want: Vec<f64> = dft2(&|i| zf[i], 1.0)
                .into_iter()
                .map(|v| v.re / (w * h) as f64)
                .collect();
            let z = frankot_chellappa(&g, Differences::Forward);
            assert_close(z.data(), &want, 1e-4, &format!("Frankot–Chellappa {w}×{h}"));
            // Averaged: the data side times ½(1 + e^{iω_x}) and ½(1 + e^{−iω_y}).
            let zf: Vec<Complex64> = (0..w * h)
                .map(|o| {
                    let (k, l) = (o % w, o / w);
                    let (tx, ty) = (tau * k as f64 / w as f64, tau * l as f64 / h as f64);
                    let a = Complex64::from_polar(1.0, tx) - 1.0;
                    let c = Complex64::from_polar(1.0, -ty) - 1.0;
                    let al = (Complex64::from_polar(1.0, tx) + 1.0) * 0.5;
                    let ga = (Complex64::from_polar(1.0, -ty) + 1.0) * 0.5;
                    let den = a.norm_sqr() + c.norm_sqr();
                    if o == 0 {
                        Complex64::new(0.0, 0.0)
                    } else {
                        (a.conj() * al * pf[o] + c.conj() * ga * qf[o]) / den
                    }
                })
                .collect();
            let want: Vec<f64> = dft2(&|i| zf[i], 1.0)
                .into_iter()
                .map(|v| v.re / (w * h) as f64)
                .collect();
            let z = frankot_chellappa(&g, Differences::Averaged);
            assert_close(z.data(), &want, 1e-4, &format!("averaged FC {w}×{h}"));
        }
    }

    #[test]
    fn frankot_chellappa_is_exact_for_periodic_discrete_gradients() {
        let (w, h) = (48, 40);
        let z = rough(w, h);
        let d = z.data();
        let mut g = GradientField::zeros(w, h);
        for r in 0..h {
            for x in 0..w {
                let i = r * w + x;
                g.p[i] = d[r * w + (x + 1) % w] - d[i];
                g.q[i] = d[((r + h - 1) % h) * w + x] - d[i];
            }
        }
        let params = IntegrateParams {
            method: IntegrationMethod::FrankotChellappa,
            differences: Differences::Forward,
            ..Default::default()
        };
        let (zi, _) = integrate_gradients(&g, None, &params).unwrap();
        let e = max_err_up_to_constant(&zi, &z, None);
        assert!(e < 2e-3, "max error {e}");
    }
}
