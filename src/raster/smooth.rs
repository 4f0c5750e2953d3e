//! Fused "normals → gradient → separable smoother → normals" with the curl statistics of the
//! field before and after, in two sweeps over the image instead of seven.
//!
//! The unfused reference is `GradientField::from_normals` → `curl_stats` → `filter_rows` →
//! `filter_columns` → `curl_stats` → `to_normals` (what `ops::filter` runs for masks and
//! compound kernels). Here:
//!
//! 1. **Row sweep** (bands of [`LANES`] rows): each row's `(p, q)` is computed from the normals
//!    (same [`gradient_of_normal`] and `n_z` clamp), its curl sums (averaged model) are taken
//!    with the previous row's `p`, `q` (one extra row per band is recomputed), then the band
//!    is filtered along x. The filtered `p`, `q` are parked in the output `n_x`, `n_y` planes
//!    (no gradient planes are allocated).
//! 2. **Column sweep** (groups of [`LANES`] columns, [`TASK_GROUPS`] neighbouring groups a
//!    task, so each row is read and written a few cache lines at a time): `p`, `q` are filtered
//!    along y, the curl sums of the filtered field are taken from the lane buffers, and
//!    [`normal_of_gradient`] is written straight into the three output planes. The plaquettes at a group's last column
//!    need the next group's first column: each group hands over its first and last columns'
//!    filtered `p`, `q`, and those `height` plaquettes per group are summed afterwards.
//!
//! Filtered values are bit-identical to the unfused path (same line filter, same arithmetic);
//! the curl statistics are the same sums taken in a different order (`f32` partial sums over
//! a row, or over ≤ 64 rows of one column, then `f64`), so they agree to rounding
//! (`tests::fused_equals_the_unfused_reference`).

use super::convolve::{
    lane_splat, lanes_to_rows, load_lane, prefetch_span, rows_to_lanes, store_lane, BorderMode,
    Lane, LineFilter, LANES, PREFETCH_ROWS,
};
use super::gradient::{
    gradient_of_normal, normal_of_gradient, plaquette_covered, CurlSums, NZ_EPSILON,
};
use super::par::SharedMut;
use crate::raster::buf;
use rayon::prelude::*;

/// The result of [`smooth_normals`].
#[derive(Clone, Debug)]
pub struct SmoothedNormals {
    /// The filtered unit normals (x, y, z planes).
    pub normal: [Vec<f32>; 3],
    /// Pixels whose `n_z` was clamped when converting to gradients.
    pub clamped: usize,
    /// Curl sums of the gradient field before filtering.
    pub curl_before: CurlSums,
    /// Curl sums of the filtered gradient field.
    pub curl_after: CurlSums,
}

/// Column groups of [`LANES`] one column-sweep task takes: 4 × 16 floats = 256 contiguous
/// bytes per row and plane.
const TASK_GROUPS: usize = 4;

/// Rows of one column summed in `f32` before going to `f64`.
const F32_RUN: usize = 64;

/// Filters the gradient field of `normal` (`w × h` planes) with `f` along x then y and returns
/// the normals of the result, with curl sums before and after (pixels with `mask < 0.5`
/// skipped in the sums; the mask does not affect the filter).
pub fn smooth_normals<F: LineFilter>(
    normal: [&[f32]; 3],
    mask: Option<&[f32]>,
    w: usize,
    h: usize,
    f: &F,
    border: BorderMode,
) -> SmoothedNormals {
    let n = w * h;
    assert!(normal.iter().all(|p| p.len() == n) && mask.is_none_or(|m| m.len() == n));
    let mut out = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    if n == 0 {
        return SmoothedNormals {
            normal: out,
            clamped: 0,
            curl_before: CurlSums::default(),
            curl_after: CurlSums::default(),
        };
    }
    let sw = Sweep {
        normal,
        mask,
        w,
        h,
        f,
        border,
    };
    let (clamped, curl_before) = row_sweep(&sw, &mut out);
    let curl_after = column_sweep(&sw, &mut out);
    SmoothedNormals {
        normal: out,
        clamped,
        curl_before,
        curl_after,
    }
}

/// Per-thread buffers of the row sweep.
#[derive(Default)]
struct RowScratch {
    lanes: Vec<Lane>,
    filter: Vec<Lane>,
    p_band: Vec<f32>,
    q_band: Vec<f32>,
    q_row: Vec<f32>,
    p_prev: Vec<f32>,
}

/// Per-thread buffers of the column sweep.
#[derive(Default)]
struct ColumnScratch {
    p: Vec<Vec<Lane>>,
    q: Vec<Vec<Lane>>,
    filter: Vec<Lane>,
}

/// `(p, q)` of one row of normals into `p`, `q`; returns the clamped count.
#[inline(always)]
fn gradient_row(nx: &[f32], ny: &[f32], nz: &[f32], p: &mut [f32], q: &mut [f32]) -> usize {
    let w = p.len();
    let (nx, ny, nz, q) = (&nx[..w], &ny[..w], &nz[..w], &mut q[..w]);
    let mut clamped = 0usize;
    for x in 0..w {
        [p[x], q[x]] = gradient_of_normal([nx[x], ny[x], nz[x]]);
        clamped += usize::from(nz[x] < NZ_EPSILON);
    }
    clamped
}

/// The inputs both sweeps share.
struct Sweep<'a, F> {
    normal: [&'a [f32]; 3],
    mask: Option<&'a [f32]>,
    w: usize,
    h: usize,
    f: &'a F,
    border: BorderMode,
}

/// What a column group hands over for the plaquettes at its last column `x` (row by row):
/// `p`, `q` of that column, whether the plaquette counts, and `p`, `q` of its *first* column
/// (which the previous group needs).
#[derive(Clone, Copy, Default)]
struct Seam {
    p_last: f32,
    q_last: f32,
    keep: bool,
    p_first: f32,
    q_first: f32,
}

impl<F: LineFilter> Sweep<'_, F> {
    /// One band of the row sweep (rows `r0..`, `pb`/`qb` = those rows of the output
    /// `n_x`/`n_y` planes); returns (clamped, curl sums before). Dispatches to the AVX2 twin.
    fn band(
        &self,
        s: &mut RowScratch,
        r0: usize,
        pb: &mut [f32],
        qb: &mut [f32],
    ) -> (usize, CurlSums) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: `band_avx512` only requires AVX-512F, whose presence was just checked.
                return unsafe { self.band_avx512(s, r0, pb, qb) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: `band_avx2` only requires AVX2, whose presence was just checked.
                return unsafe { self.band_avx2(s, r0, pb, qb) };
            }
        }
        self.band_portable(s, r0, pb, qb)
    }

    /// [`Self::band_portable`] compiled for AVX2 (no FMA: bit-identical results), as
    /// `convolve::Deriche::run_avx2`: the gradient and curl loops run 8 lanes wide.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn band_avx2(
        &self,
        s: &mut RowScratch,
        r0: usize,
        pb: &mut [f32],
        qb: &mut [f32],
    ) -> (usize, CurlSums) {
        self.band_portable(s, r0, pb, qb)
    }

    /// [`Self::band_portable`] compiled for AVX-512F (one [`Lane`] per register, no FMA).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn band_avx512(
        &self,
        s: &mut RowScratch,
        r0: usize,
        pb: &mut [f32],
        qb: &mut [f32],
    ) -> (usize, CurlSums) {
        self.band_portable(s, r0, pb, qb)
    }

    #[inline(always)]
    fn band_portable(
        &self,
        s: &mut RowScratch,
        r0: usize,
        pb: &mut [f32],
        qb: &mut [f32],
    ) -> (usize, CurlSums) {
        let (w, [nx, ny, nz]) = (self.w, self.normal);
        let rows = pb.len() / w;
        // The band's gradient rows, contiguous (then transposed into lanes as a block).
        s.p_band.resize(rows * w, 0.0);
        s.q_band.resize(rows * w, 0.0);
        s.p_prev.resize(w, 0.0);
        s.q_row.resize(w, 0.0);
        let (p_band, q_band) = (&mut s.p_band[..rows * w], &mut s.q_band[..rows * w]);
        if r0 > 0 {
            let o = (r0 - 1) * w..r0 * w;
            let q_row = &mut s.q_row;
            gradient_row(&nx[o.clone()], &ny[o.clone()], &nz[o], &mut s.p_prev, q_row);
        }
        let (mut clamped, mut sums) = (0usize, CurlSums::default());
        for k in 0..rows {
            let r = r0 + k;
            let o = r * w..(r + 1) * w;
            let (p_done, p_rest) = p_band.split_at_mut(k * w);
            let (q_done, q_rest) = q_band.split_at_mut(k * w);
            let (p_row, q_row) = (&mut p_rest[..w], &mut q_rest[..w]);
            clamped += gradient_row(&nx[o.clone()], &ny[o.clone()], &nz[o.clone()], p_row, q_row);
            if r >= 1 {
                let (p_prev, q_prev) = if k == 0 {
                    (&s.p_prev[..], &s.q_row[..])
                } else {
                    (&p_done[(k - 1) * w..], &q_done[(k - 1) * w..])
                };
                let m = self.mask.map(|m| (&m[(r - 1) * w..r * w], &m[o]));
                sums = sums.merge(CurlSums::of_row(p_prev, q_prev, p_row, q_row, m));
            }
        }
        // p then q through one lane buffer (a smaller working set than both at once).
        for (band, out) in [(&*p_band, pb), (&*q_band, qb)] {
            rows_to_lanes(band, w, &mut s.lanes);
            self.f.run(&mut s.lanes, &mut s.filter, self.border);
            lanes_to_rows(&s.lanes, w, out);
        }
        (clamped, sums)
    }

    /// One task of the column sweep: column groups `t·TASK_GROUPS ..` (at most
    /// [`TASK_GROUPS`], each [`LANES`] columns). Reads the row-filtered `p`, `q` parked in the
    /// output `n_x`, `n_y` planes at `out`, writes the normals there; returns each group's curl
    /// sums and [`Seam`]. Dispatches to the widest vector twin.
    ///
    /// # Safety
    /// `out` must point to the three output planes (`w × h` each); no other task may touch
    /// the task's columns of them.
    unsafe fn task(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: AVX-512F presence was just checked; the rest is the caller's contract.
                return unsafe { self.task_avx512(s, t, out) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 presence was just checked; the rest is the caller's contract.
                return unsafe { self.task_avx2(s, t, out) };
            }
        }
        // SAFETY: the caller's contract.
        unsafe { self.task_portable(s, t, out) }
    }

    /// [`Self::task_portable`] compiled for AVX2 (no FMA: bit-identical results).
    ///
    /// # Safety
    /// As [`Self::task`], and AVX2 must be available.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn task_avx2(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        // SAFETY: the caller's contract.
        unsafe { self.task_portable(s, t, out) }
    }

    /// [`Self::task_portable`] compiled for AVX-512F: a [`Lane`] is one register (no FMA:
    /// bit-identical results).
    ///
    /// # Safety
    /// As [`Self::task`], and AVX-512F must be available.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn task_avx512(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        // SAFETY: the caller's contract.
        unsafe { self.task_portable(s, t, out) }
    }

    /// # Safety
    /// As [`Self::task`].
    #[inline(always)]
    unsafe fn task_portable(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        let (w, h) = (self.w, self.h);
        let g0 = t * TASK_GROUPS;
        let k = TASK_GROUPS.min(w.div_ceil(LANES) - g0);
        let c0 = g0 * LANES;
        let span = (k * LANES).min(w - c0);
        // The task's columns row by row: `span` contiguous floats per row and plane, so each
        // row is read and written as a few neighbouring cache lines instead of one.
        for (buf, src) in [(&mut s.p, out[0]), (&mut s.q, out[1])] {
            buf.resize_with(k, Vec::new);
            for b in buf.iter_mut() {
                b.clear();
                b.resize(h, lane_splat(0.0));
            }
            for r in 0..h {
                prefetch_span(src.get().wrapping_add((r + PREFETCH_ROWS) * w + c0), span);
                for (j, b) in buf.iter_mut().enumerate() {
                    let cols = LANES.min(span - j * LANES);
                    // SAFETY: columns of row r inside the plane that belong to this task alone
                    // (the caller's contract).
                    b[r] = unsafe { load_lane(src.get().add(r * w + c0 + j * LANES), cols) };
                }
            }
        }
        let mut result = Vec::with_capacity(k);
        for j in 0..k {
            let (bp, bq) = (&mut s.p[j], &mut s.q[j]);
            self.f.run(bp, &mut s.filter, self.border);
            self.f.run(bq, &mut s.filter, self.border);
            let cg = c0 + j * LANES;
            let cols = LANES.min(w - cg);
            let sums = group_curl(bp, bq, self.mask, w, cg, cols);
            let last = cols - 1;
            let seam: Vec<Seam> = (0..h)
                .map(|r| Seam {
                    p_last: bp[r][last],
                    q_last: bq[r][last],
                    keep: r >= 1
                        && self.mask.is_none_or(|m| {
                            cg + last + 1 < w && plaquette_covered(m, w, r, cg + last)
                        }),
                    p_first: bp[r][0],
                    q_first: bq[r][0],
                })
                .collect();
            result.push((sums, seam));
        }
        for r in 0..h {
            // The stores go down the strip a row apart: ask for the lines a few rows ahead.
            for dst in &out {
                prefetch_span(dst.get().wrapping_add((r + PREFETCH_ROWS) * w + c0), span);
            }
            for j in 0..k {
                let (p, q) = (&s.p[j][r], &s.q[j][r]);
                let mut nrm = [lane_splat(0.0); 3];
                for l in 0..LANES {
                    [nrm[0][l], nrm[1][l], nrm[2][l]] = normal_of_gradient(p[l], q[l]);
                }
                let cols = LANES.min(span - j * LANES);
                for (dst, lane) in out.iter().zip(&nrm) {
                    // SAFETY: as above; this task has already read these columns.
                    unsafe { store_lane(dst.get().add(r * w + c0 + j * LANES), lane, cols) };
                }
            }
        }
        result
    }
}

/// Step 1 of the module docs; returns (clamped, curl sums before).
fn row_sweep<F: LineFilter>(sw: &Sweep<'_, F>, out: &mut [Vec<f32>; 3]) -> (usize, CurlSums) {
    let w = sw.w;
    let [ox, oy, _] = out;
    ox.par_chunks_mut(w * LANES)
        .zip(oy.par_chunks_mut(w * LANES))
        .enumerate()
        .map_init(RowScratch::default, |s, (band, (pb, qb))| {
            sw.band(s, band * LANES, pb, qb)
        })
        .reduce(
            || (0, CurlSums::default()),
            |a, b| (a.0 + b.0, a.1.merge(b.1)),
        )
}

/// Step 2 of the module docs; returns the curl sums after filtering.
fn column_sweep<F: LineFilter>(sw: &Sweep<'_, F>, out: &mut [Vec<f32>; 3]) -> CurlSums {
    let tasks = sw.w.div_ceil(LANES * TASK_GROUPS);
    let ptr = out.each_mut().map(|v| SharedMut(v.as_mut_ptr()));
    let per_group: Vec<(CurlSums, Vec<Seam>)> = (0..tasks)
        .into_par_iter()
        // SAFETY: `ptr` are the three w×h output planes, borrowed mutably for this call;
        // each task index is visited once, so each task owns its columns.
        .map_init(ColumnScratch::default, |s, t| unsafe { sw.task(s, t, ptr) })
        .flatten_iter()
        .collect();
    // The plaquettes at each group's last column, with the next group's first column
    // (averaged edge values formed as `GradientField::edge_values` does).
    let seams = per_group
        .par_windows(2)
        .map(|pair| {
            let (a, b) = (&pair[0].1, &pair[1].1);
            let (mut c2, mut g2, mut n, mut max) = (0.0f64, 0.0f64, 0usize, 0.0f32);
            for r in 1..a.len() {
                let (su, sc, tu, tc) = (&a[r - 1], &a[r], &b[r - 1], &b[r]);
                if sc.keep {
                    let pu = 0.5 * (su.p_last + tu.p_first);
                    let pc = 0.5 * (sc.p_last + tc.p_first);
                    let qc = 0.5 * (sc.q_last + su.q_last);
                    let qn = 0.5 * (tc.q_first + tu.q_first);
                    let c = (pu - pc) - (qn - qc);
                    c2 += f64::from(c * c);
                    g2 += f64::from(pc * pc + qc * qc);
                    n += 1;
                    max = max.max(c.abs());
                }
            }
            CurlSums { c2, g2, n, max }
        })
        .reduce(CurlSums::default, CurlSums::merge);
    per_group
        .into_iter()
        .fold(seams, |acc, (s, _)| acc.merge(s))
}

/// Curl sums (averaged model, module docs of `gradient`) of one filtered column group (`cols`
/// columns from `c0`) except the plaquettes of its last column, which need the next group
/// (see [`Seam`]). Columns `x = w−1` and row 0 are not counted.
#[inline(always)]
fn group_curl(
    bp: &[Lane],
    bq: &[Lane],
    mask: Option<&[f32]>,
    w: usize,
    c0: usize,
    cols: usize,
) -> CurlSums {
    // 0/1 weights: lanes whose plaquette is taken here (x ≤ w−2 and not the group's last
    // lane). Multiplying is exact (values are finite: gradients are clamped and the filters
    // are linear).
    let counted: Lane =
        std::array::from_fn(|l| f32::from(u8::from(l + 1 < cols && c0 + l + 1 < w)));
    let mut total = CurlSums::default();
    let (mut c2, mut g2, mut mx, mut n) = (
        lane_splat(0.0),
        lane_splat(0.0),
        lane_splat(0.0),
        lane_splat(0.0),
    );
    for r in 1..bp.len() {
        let (pu, pc, qu, qc) = (&bp[r - 1], &bp[r], &bq[r - 1], &bq[r]);
        let keep: Lane = match mask {
            None => counted,
            Some(m) => std::array::from_fn(|l| {
                if counted[l] > 0.0 && plaquette_covered(m, w, r, c0 + l) {
                    1.0
                } else {
                    0.0
                }
            }),
        };
        let next = |a: &Lane, l: usize| if l + 1 < LANES { a[l + 1] } else { 0.0 };
        for l in 0..LANES {
            let eu = 0.5 * (pu[l] + next(pu, l));
            let ec = 0.5 * (pc[l] + next(pc, l));
            let qcl = 0.5 * (qc[l] + qu[l]);
            let qn = 0.5 * (next(qc, l) + next(qu, l));
            let c = ((eu - ec) - (qn - qcl)) * keep[l];
            c2[l] += c * c;
            g2[l] += (ec * ec + qcl * qcl) * keep[l];
            mx[l] = mx[l].max(c.abs());
            n[l] += keep[l];
        }
        if r % F32_RUN == 0 || r + 1 == bp.len() {
            total = total.merge(CurlSums {
                c2: c2.iter().map(|&v| f64::from(v)).sum(),
                g2: g2.iter().map(|&v| f64::from(v)).sum(),
                n: n.iter().map(|&v| v as usize).sum(),
                max: mx.iter().copied().fold(0.0, f32::max),
            });
            (c2, g2, n) = (lane_splat(0.0), lane_splat(0.0), lane_splat(0.0));
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::convolve::{self, BoxFilter, Deriche, Fir};
    use crate::raster::gradient::{CurlStats, GradientField};
    use crate::raster::sample::Surface;
    use crate::raster::RgbnImage;

    /// The unfused reference: convert, stats, separable filter, stats, back to normals.
    fn reference<F: LineFilter>(
        img: &RgbnImage,
        f: &F,
        border: BorderMode,
    ) -> ([Vec<f32>; 3], usize, CurlStats, CurlStats) {
        let mut g = GradientField::from_normals(img);
        let before = g.curl_stats(img.mask());
        convolve::separable(&mut g.p, g.width, g.height, f, border);
        convolve::separable(&mut g.q, g.width, g.height, f, border);
        let after = g.curl_stats(img.mask());
        (g.to_normals(), g.clamped, before, after)
    }

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * a.abs().max(b.abs())
    }

    fn check<F: LineFilter>(img: &RgbnImage, f: &F, border: BorderMode) {
        let (w, h) = (img.width(), img.height());
        let [nx, ny, nz] = img.normal();
        let got = smooth_normals([nx, ny, nz], img.mask(), w, h, f, border);
        let (want, clamped, before, after) = reference(img, f, border);
        // Same filter, same arithmetic: bit-identical normals.
        for (k, (g, wa)) in got.normal.iter().zip(&want).enumerate() {
            assert!(
                g.iter().zip(wa).all(|(a, b)| a.to_bits() == b.to_bits()),
                "{w}×{h} {border:?}: plane {k} differs"
            );
        }
        assert_eq!(got.clamped, clamped);
        // Statistics: the same terms summed in another order; stated tolerance 1e-5 relative
        // on the RMS values, the maximum exactly.
        for (s, r) in [(got.curl_before, before), (got.curl_after, after)] {
            let s = s.stats();
            assert!(
                close(s.rms_curl, r.rms_curl, 1e-5),
                "{w}×{h}: {s:?} vs {r:?}"
            );
            assert!(
                close(s.rms_gradient, r.rms_gradient, 1e-5),
                "{w}×{h}: {s:?} vs {r:?}"
            );
            assert_eq!(s.max_abs_curl, r.max_abs_curl, "{w}×{h}");
        }
    }

    /// A non-integrable test image (curl ≠ 0 everywhere) with a few grazing normals.
    fn rough(w: usize, h: usize, masked: bool) -> RgbnImage {
        let (mut img, _) = Surface::Sphere {
            radius_px: 0.4 * w.min(h) as f64,
        }
        .render(w, h);
        let [nx, ny, nz] = img.normal_mut();
        for i in 0..w * h {
            let t = ((i * 7919) % 1013) as f32 / 1013.0 - 0.5;
            nx[i] += 0.3 * t;
            ny[i] -= 0.2 * t * t;
            if i % 97 == 0 {
                nz[i] = 1e-4;
            }
        }
        if masked {
            let m = (0..w * h).map(|i| (i % w) as f32 / w as f32).collect();
            img.set_mask(Some(m)).unwrap();
        }
        img
    }

    #[test]
    fn fused_equals_the_unfused_reference() {
        // Sizes around the lane count (partial bands and groups, single column/row groups).
        for (w, h) in [
            (37, 21),
            (16, 16),
            (17, 33),
            (64, 5),
            (1, 9),
            (9, 1),
            (2, 2),
        ] {
            for border in BorderMode::ALL {
                let img = rough(w, h, false);
                check(&img, &Deriche::new(4.0), border);
                check(&img, &BoxFilter { radius: 2 }, border);
            }
            check(&rough(w, h, true), &Fir::gaussian(1.5), BorderMode::Mirror);
        }
    }
}
