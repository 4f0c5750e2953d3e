//! Cached FFT plans, the paired real DCT (Makhoul) and the row-pair driver shared by the DCT
//! Poisson and Frankot–Chellappa solvers.

use parking_lot::{Mutex, MutexGuard};
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

pub(super) type C32 = Complex<f32>;

pub(super) const C_ZERO: C32 = Complex::new(0.0, 0.0);

/// Plans shared by every call: rustfft's planner (it caches its FFTs) and the DCT twiddles.
/// Planning a 4K transform costs about as much as running it once, so caching matters for
/// repeated calls (the editor, batch runs). Bounded: past [`MAX_CACHED_DCT_SIZES`] sizes the DCT
/// map is cleared (the planner's own cache is small: a few twiddle tables per size).
struct Plans {
    planner: FftPlanner<f32>,
    dct: HashMap<usize, Arc<PairedDct>>,
}

/// See [`Plans`].
const MAX_CACHED_DCT_SIZES: usize = 64;

fn plans() -> MutexGuard<'static, Plans> {
    static PLANS: OnceLock<Mutex<Plans>> = OnceLock::new();
    PLANS
        .get_or_init(|| {
            Mutex::new(Plans {
                planner: FftPlanner::new(),
                dct: HashMap::new(),
            })
        })
        .lock()
}

/// The cached [`PairedDct`] of one length.
pub(super) fn dct_plan(len: usize) -> Arc<PairedDct> {
    let mut guard = plans();
    let Plans { planner, dct } = &mut *guard;
    if dct.len() >= MAX_CACHED_DCT_SIZES && !dct.contains_key(&len) {
        dct.clear();
    }
    dct.entry(len)
        .or_insert_with(|| Arc::new(PairedDct::new(len, planner)))
        .clone()
}

/// A cached complex FFT of one length (unnormalised in both directions).
pub(super) fn fft_plan(len: usize, inverse: bool) -> Arc<dyn Fft<f32>> {
    let mut guard = plans();
    if inverse {
        guard.planner.plan_fft_inverse(len)
    } else {
        guard.planner.plan_fft_forward(len)
    }
}

/// Runs `f(r, a, b, buf, scratch)` on pairs of rows (`a` = row `r`, `b` = row `r + 1`, absent
/// for an odd last row) of a row-major buffer of rows of `len`, pairs in parallel, with one
/// complex buffer of `len` and one FFT scratch of `scratch_len` per rayon job.
pub(super) fn for_row_pairs(
    data: &mut [f32],
    len: usize,
    scratch_len: usize,
    f: impl Fn(usize, &mut [f32], Option<&mut [f32]>, &mut [C32], &mut [C32]) + Sync + Send,
) {
    data.par_chunks_mut(2 * len)
        .enumerate()
        .with_min_len(4)
        .for_each_init(
            || (vec![C_ZERO; len], vec![C_ZERO; scratch_len]),
            |(buf, scratch), (i, rows)| {
                let (a, b) = rows.split_at_mut(len);
                let b = (!b.is_empty()).then_some(b);
                f(2 * i, a, b, buf, scratch);
            },
        );
}

/// Unnormalised DCT-II / DCT-III of real sequences of one length, two sequences per complex
/// FFT.
///
/// Makhoul (1980): with the reordering `v[n] = x[2n]`, `v[N−1−n] = x[2n+1]` and `V = FFT(v)`,
/// `DCT-II(x)[k] = Σ x_n cos(π(2n+1)k/2N) = Re(e^{−iπk/2N} V_k)`; conversely
/// `V_k = e^{iπk/2N} (X_k − i X_{N−k})` (`X_N = 0`) and the inverse FFT gives `v` back.
/// Because `v` is real, two sequences `a`, `b` share one FFT of `a + i b`, separated by
/// `A_k = (C_k + C̄_{N−k})/2`, `B_k = (C_k − C̄_{N−k})/2i` — the same work as one real-input FFT
/// of half length per sequence. The DCT-III here is rustdct's convention
/// (`X_0/2 + Σ_{k≥1} X_k cos(…)`), so `DCT-III(DCT-II(x)) = N/2 · x`.
pub(super) struct PairedDct {
    pub(super) len: usize,
    pub(super) fwd: Arc<dyn Fft<f32>>,
    pub(super) inv: Arc<dyn Fft<f32>>,
    /// `e^{−iπk/2N} / 2` (the ½ of the separation folded in).
    pub(super) half_twiddle: Vec<C32>,
    /// `e^{+iπk/2N} / 2` (the ½ of the DCT-III convention folded in).
    pub(super) half_twiddle_inv: Vec<C32>,
    /// Makhoul position of sample `n`: `v[pos[n]] = x[n]`.
    pub(super) pos: Vec<usize>,
    pub(super) scratch_len: usize,
}

impl PairedDct {
    pub(super) fn new(len: usize, planner: &mut FftPlanner<f32>) -> Self {
        let tw = |sign: f64| -> Vec<C32> {
            (0..len)
                .map(|k| {
                    let a = sign * std::f64::consts::PI * k as f64 / (2.0 * len as f64);
                    Complex::new((0.5 * a.cos()) as f32, (0.5 * a.sin()) as f32)
                })
                .collect()
        };
        let fwd = planner.plan_fft_forward(len);
        let inv = planner.plan_fft_inverse(len);
        let scratch_len = fwd
            .get_inplace_scratch_len()
            .max(inv.get_inplace_scratch_len());
        Self {
            len,
            fwd,
            inv,
            half_twiddle: tw(-1.0),
            half_twiddle_inv: tw(1.0),
            pos: (0..len)
                .map(|n| if n % 2 == 0 { n / 2 } else { len - 1 - n / 2 })
                .collect(),
            scratch_len,
        }
    }

    /// Makhoul-reorders `a` (real parts) and `b` (imaginary parts, 0 if absent) into `buf`.
    pub(super) fn load(&self, a: &[f32], b: Option<&[f32]>, buf: &mut [C32]) {
        let n = self.len;
        // lo[m] = x[2m], hi reversed: buf[N−1−m] = x[2m+1].
        let (lo, hi) = buf.split_at_mut(n - n / 2);
        match b {
            Some(b) => {
                for (((l, u), pa), pb) in lo
                    .iter_mut()
                    .zip(hi.iter_mut().rev())
                    .zip(a.chunks_exact(2))
                    .zip(b.chunks_exact(2))
                {
                    *l = Complex::new(pa[0], pb[0]);
                    *u = Complex::new(pa[1], pb[1]);
                }
                if n % 2 == 1 {
                    lo[n / 2] = Complex::new(a[n - 1], b[n - 1]);
                }
            }
            None => {
                for ((l, u), pa) in lo
                    .iter_mut()
                    .zip(hi.iter_mut().rev())
                    .zip(a.chunks_exact(2))
                {
                    *l = Complex::new(pa[0], 0.0);
                    *u = Complex::new(pa[1], 0.0);
                }
                if n % 2 == 1 {
                    lo[n / 2] = Complex::new(a[n - 1], 0.0);
                }
            }
        }
    }

    /// From the forward FFT `buf` of a loaded pair: the DCT-II of the real parts into `xa` and
    /// of the imaginary parts into `xb`.
    pub(super) fn post2(&self, buf: &[C32], xa: &mut [f32], xb: Option<&mut [f32]>) {
        let n = self.len;
        xa[0] = buf[0].re;
        // (C_k, C_{N−k}) for k = 1..N.
        let (t, c) = (&self.half_twiddle[1..n], &buf[1..n]);
        for (((o, t), c), d) in xa[1..n].iter_mut().zip(t).zip(c).zip(c.iter().rev()) {
            *o = t.re * (c.re + d.re) - t.im * (c.im - d.im);
        }
        if let Some(xb) = xb {
            xb[0] = buf[0].im;
            for (((o, t), c), d) in xb[1..n].iter_mut().zip(t).zip(c).zip(c.iter().rev()) {
                *o = t.re * (c.im + d.im) + t.im * (c.re - d.re);
            }
        }
    }

    /// The inverse-FFT input whose result holds the reordered DCT-IIIs of `xa` (real parts) and
    /// `xb` (imaginary parts, 0 if absent).
    pub(super) fn pre3(&self, xa: &[f32], xb: Option<&[f32]>, buf: &mut [C32]) {
        let n = self.len;
        let t = &self.half_twiddle_inv;
        // V_k = t_k·(X_k − i X_{N−k}) (X_N = 0); C = Va + i Vb.
        let v = |t: C32, x: f32, y: f32| Complex::new(t.re * x + t.im * y, t.im * x - t.re * y);
        let join = |va: C32, vb: C32| Complex::new(va.re - vb.im, va.im + vb.re);
        let (ta, xa1) = (&t[1..n], &xa[1..n]);
        match xb {
            Some(xb) => {
                buf[0] = join(v(t[0], xa[0], 0.0), v(t[0], xb[0], 0.0));
                let xb1 = &xb[1..n];
                for ((((o, &t), (&a, &ar)), &b), &br) in buf[1..n]
                    .iter_mut()
                    .zip(ta)
                    .zip(xa1.iter().zip(xa1.iter().rev()))
                    .zip(xb1)
                    .zip(xb1.iter().rev())
                {
                    *o = join(v(t, a, ar), v(t, b, br));
                }
            }
            None => {
                buf[0] = v(t[0], xa[0], 0.0);
                for ((o, &t), (&a, &ar)) in buf[1..n]
                    .iter_mut()
                    .zip(ta)
                    .zip(xa1.iter().zip(xa1.iter().rev()))
                {
                    *o = v(t, a, ar);
                }
            }
        }
    }

    /// Undoes the Makhoul order of an inverse FFT `buf` into `a` (real parts) and `b`.
    pub(super) fn store(&self, buf: &[C32], a: &mut [f32], b: Option<&mut [f32]>) {
        let n = self.len;
        let (lo, hi) = buf.split_at(n - n / 2);
        for ((l, u), pa) in lo.iter().zip(hi.iter().rev()).zip(a.chunks_exact_mut(2)) {
            pa[0] = l.re;
            pa[1] = u.re;
        }
        if n % 2 == 1 {
            a[n - 1] = lo[n / 2].re;
        }
        if let Some(b) = b {
            for ((l, u), pb) in lo.iter().zip(hi.iter().rev()).zip(b.chunks_exact_mut(2)) {
                pb[0] = l.im;
                pb[1] = u.im;
            }
            if n % 2 == 1 {
                b[n - 1] = lo[n / 2].im;
            }
        }
    }

    /// In-place DCT-II of `a` and (if present) `b`.
    pub(super) fn dct2_pair(
        &self,
        a: &mut [f32],
        b: Option<&mut [f32]>,
        buf: &mut [C32],
        s: &mut [C32],
    ) {
        self.load(a, b.as_deref(), buf);
        self.fwd.process_with_scratch(buf, s);
        self.post2(buf, a, b);
    }

    /// In-place DCT-III (rustdct convention) of `a` and (if present) `b`.
    pub(super) fn dct3_pair(
        &self,
        a: &mut [f32],
        b: Option<&mut [f32]>,
        buf: &mut [C32],
        s: &mut [C32],
    ) {
        self.pre3(a, b.as_deref(), buf);
        self.inv.process_with_scratch(buf, s);
        self.store(buf, a, b);
    }

    /// In-place DCT-II of every row of `data` (rows of `self.len`), rows in parallel.
    #[cfg(test)]
    pub(super) fn dct2_rows(&self, data: &mut [f32]) {
        for_row_pairs(data, self.len, self.scratch_len, |_, a, b, buf, s| {
            self.dct2_pair(a, b, buf, s);
        });
    }

    /// In-place DCT-III (rustdct convention) of every row of `data`.
    #[cfg(test)]
    pub(super) fn dct3_rows(&self, data: &mut [f32]) {
        for_row_pairs(data, self.len, self.scratch_len, |_, a, b, buf, s| {
            self.dct3_pair(a, b, buf, s);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paired_dct_matches_rustdct() {
        let mut fp = FftPlanner::<f32>::new();
        let mut dp = rustdct::DctPlanner::<f32>::new();
        for &n in &[1usize, 2, 3, 5, 8, 15, 64, 100] {
            for rows in [1usize, 2, 3] {
                let x: Vec<f32> = (0..n * rows)
                    .map(|i| ((i * 37 + 11) % 17) as f32 * 0.3 - 2.0)
                    .collect();
                let pd = PairedDct::new(n, &mut fp);
                let oracle = dp.plan_dct2(n);
                let mut want = x.clone();
                for r in want.chunks_mut(n) {
                    oracle.process_dct2(r);
                }
                let mut got = x.clone();
                pd.dct2_rows(&mut got);
                for (a, b) in got.iter().zip(&want) {
                    assert!((a - b).abs() < 1e-3, "dct2 n={n} rows={rows}: {a} vs {b}");
                }
                let mut want3 = x.clone();
                for r in want3.chunks_mut(n) {
                    oracle.process_dct3(r);
                }
                let mut got3 = x.clone();
                pd.dct3_rows(&mut got3);
                for (a, b) in got3.iter().zip(&want3) {
                    assert!((a - b).abs() < 1e-3, "dct3 n={n} rows={rows}: {a} vs {b}");
                }
            }
        }
    }
}
