//! Fused "normals → gradient → separable smoother → normals" with the curl statistics of the
//! field before and after, in two sweeps over the image instead of seven.
//!
//! The unfused reference is `GradientField::from_normals` → `curl_stats` → `filter_rows` →
//! `filter_columns` → `curl_stats` → `to_normals` (what `ops::filter` runs for masks and
//! compound kernels). Here:
//!
//! 1. **Row sweep** (bands of `LANES` rows), in chunks of `GRADIENT_CHUNK` columns that
//!    stay in L1: each row's `(p, q)` is computed from the normals (same
//!    [`gradient_of_normal`] and `n_z` clamp), its curl sums (averaged model) are taken with
//!    the previous row's `p`, `q` (one extra row per band and one extra column per chunk are
//!    recomputed), and the chunk is transposed into a per-thread band of lanes (lane `k` =
//!    row `k` of the band). `p` and `q` are filtered along x there (in L2), one after the
//!    other (two recursions interleaved step by step measured slower: BENCHMARKS.md), then
//!    *parked* in two planes laid out for the column sweep: each task's columns contiguous,
//!    band after band (`park_offset`), written with non-temporal stores where the AVX-512
//!    twin runs. The parked pair is kept between calls (see `take_parked`).
//! 2. **Column sweep** (groups of `LANES` columns, `TASK_GROUPS` neighbouring groups a
//!    task): a task reads its columns in one sequential run per plane,
//!    transposing each 16 × 16 block into rows; `p`, `q` are filtered along y, the curl sums
//!    of the filtered field are taken from the lane buffers, and [`normal_of_gradient`] is
//!    written straight into the three output planes (allocated without a zero fill: the tasks
//!    write every value). The plaquettes at a group's last column need the next group's first
//!    column: each group hands over its first and last columns' filtered `p`, `q`, and those
//!    `height` plaquettes per group are summed afterwards.
//!
//! Filtered values are bit-identical to the unfused path (same line filter, same arithmetic);
//! the curl statistics are the same sums taken in a different order (`f32` partial sums over
//! a row, or over ≤ 64 rows of one column, then `f64`), so they agree to rounding
//! (`tests::fused_equals_the_unfused_reference`).

use super::convolve::{
    lane_splat, prefetch_span, rows_into_lanes, store_lane, transpose_lanes, BorderMode, Lane,
    LineFilter, LANES, PREFETCH_ROWS,
};
use super::gradient::{
    gradient_of_normal, normal_of_gradient, plaquette_covered, CurlSums, NZ_EPSILON,
};
use super::par::SharedMut;
use super::simd::Simd;
use crate::raster::buf;
use crate::raster::par::OrderedReduce;
use parking_lot::Mutex;
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

/// Columns of one column-sweep task.
const TASK_COLUMNS: usize = TASK_GROUPS * LANES;

/// Lanes of one parked plane of a `w × h` image.
fn parked_len(w: usize, h: usize) -> usize {
    h.div_ceil(LANES) * w
}

/// Where band `band`'s lanes of columns `c0 .. c0 + span` (one column-sweep task's columns,
/// `c0` a multiple of [`TASK_COLUMNS`]) are parked, out of `nb` bands: each task's columns are
/// contiguous, band after band, so the column sweep reads one sequential run per plane.
fn park_offset(c0: usize, band: usize, nb: usize, span: usize) -> usize {
    c0 * nb + band * span
}

/// Bands the column sweep's loads prefetch ahead.
const PREFETCH_BANDS: usize = 2;

/// Columns of the row sweep's gradient chunks: 17 rows × 257 columns × 2 planes = 35 KB, in L1.
const GRADIENT_CHUNK: usize = 256;

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
    smooth_normals_twin(normal, mask, w, h, f, border, Simd::active())
}

/// [`smooth_normals`] running the twin of `simd` (clamped to what this CPU runs): the tests
/// compare every twin with the portable one.
fn smooth_normals_twin<F: LineFilter>(
    normal: [&[f32]; 3],
    mask: Option<&[f32]>,
    w: usize,
    h: usize,
    f: &F,
    border: BorderMode,
    simd: Simd,
) -> SmoothedNormals {
    let n = w * h;
    assert!(normal.iter().all(|p| p.len() == n) && mask.is_none_or(|m| m.len() == n));
    // Empty planes with room for the result: the column sweep writes every value.
    let mut out = [
        buf::reserved_f32(n),
        buf::reserved_f32(n),
        buf::reserved_f32(n),
    ];
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
        simd: simd.clamped(),
    };
    let mut park = [take_parked(parked_len(w, h)), take_parked(parked_len(w, h))];
    let (clamped, curl_before) = row_sweep(&sw, &mut park);
    // Cancelled between the sweeps: zeros, which the caller discards (crate::cancel).
    if crate::cancel::Cancel::current().is_cancelled() {
        park.into_iter().for_each(give_parked);
        return SmoothedNormals {
            normal: [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)],
            clamped,
            curl_before,
            curl_after: CurlSums::default(),
        };
    }
    let curl_after = column_sweep(
        &sw,
        &park,
        out.each_mut().map(|v| SharedMut(v.as_mut_ptr())),
    );
    for v in &mut out {
        // SAFETY: each plane has capacity n, and the column sweep's tasks together wrote all
        // w·h values of each (every column group, every row).
        unsafe { v.set_len(n) };
    }
    park.into_iter().for_each(give_parked);
    SmoothedNormals {
        normal: out,
        clamped,
        curl_before,
        curl_after,
    }
}

/// Parked planes kept for the next call (two: `p` and `q` of one image).
static PARKED: Mutex<Vec<Vec<Lane>>> = Mutex::new(Vec::new());

/// Parked planes larger than this are freed rather than kept.
const PARKED_KEEP_BYTES: usize = 256 << 20;

/// A parked plane of `len` lanes: one kept from an earlier call if it is large enough (its
/// contents are stale; the row sweep writes every lane), else a new one. A 4K pair is 66 MB;
/// reusing it saves the first-touch page faults of a fresh allocation on every filter.
fn take_parked(len: usize) -> Vec<Lane> {
    let kept = PARKED.lock().pop();
    match kept {
        Some(mut v) if v.capacity() >= len => {
            v.resize(len, lane_splat(0.0));
            v
        }
        _ => {
            let v = vec![lane_splat(0.0); len];
            buf::advise_huge_pages(&v);
            v
        }
    }
}

/// Keeps `v` for the next [`take_parked`] (at most two, none over [`PARKED_KEEP_BYTES`]).
fn give_parked(v: Vec<Lane>) {
    if v.capacity() * std::mem::size_of::<Lane>() <= PARKED_KEEP_BYTES {
        let mut k = PARKED.lock();
        if k.len() < 2 {
            k.push(v);
        }
    }
}

/// Per-thread buffers of the row sweep.
#[derive(Default)]
struct RowScratch {
    filter: Vec<Lane>,
    p_band: Vec<f32>,
    q_band: Vec<f32>,
    /// The band's `p`, `q` in lanes (`w` each), filtered here and then parked.
    lp: Vec<Lane>,
    lq: Vec<Lane>,
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
    /// The twin the sweeps run (one this CPU has).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    simd: Simd,
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
    /// One band of the row sweep (rows `r0..`, band `r0 / LANES`): filters the band's `p`,
    /// `q` along x and parks them at `park` ([`park_offset`]); returns (clamped, curl sums
    /// before). Dispatches to the widest vector twin.
    ///
    /// # Safety
    /// `park` must point to two parked planes of [`parked_len`] lanes; no other task may
    /// write this band's pieces of them.
    unsafe fn band(
        &self,
        s: &mut RowScratch,
        r0: usize,
        park: [SharedMut<Lane>; 2],
    ) -> (usize, CurlSums) {
        #[cfg(target_arch = "x86_64")]
        {
            if self.simd >= Simd::Avx512 {
                // SAFETY: AVX-512F is present (`Sweep::simd` is clamped to the CPU); the rest is the caller's contract.
                return unsafe { self.band_avx512(s, r0, park) };
            }
            if self.simd >= Simd::Avx2 {
                // SAFETY: AVX2 is present (`Sweep::simd` is clamped to the CPU); the rest is the caller's contract.
                return unsafe { self.band_avx2(s, r0, park) };
            }
        }
        // SAFETY: the caller's contract.
        unsafe { self.band_portable::<false>(s, r0, park) }
    }

    /// [`Self::band_portable`] compiled for AVX2 (no FMA: bit-identical results), as
    /// `convolve::Deriche::run_avx2`: the gradient and curl loops run 8 lanes wide.
    ///
    /// # Safety
    /// As [`Self::band`], and AVX2 must be available.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn band_avx2(
        &self,
        s: &mut RowScratch,
        r0: usize,
        park: [SharedMut<Lane>; 2],
    ) -> (usize, CurlSums) {
        // SAFETY: the caller's contract.
        unsafe { self.band_portable::<false>(s, r0, park) }
    }

    /// [`Self::band_portable`] compiled for AVX-512F (one [`Lane`] per register, no FMA),
    /// parking with non-temporal stores.
    ///
    /// # Safety
    /// As [`Self::band`], and AVX-512F must be available.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn band_avx512(
        &self,
        s: &mut RowScratch,
        r0: usize,
        park: [SharedMut<Lane>; 2],
    ) -> (usize, CurlSums) {
        // SAFETY: the caller's contract.
        unsafe { self.band_portable::<true>(s, r0, park) }
    }

    /// # Safety
    /// As [`Self::band`].
    #[inline(always)]
    unsafe fn band_portable<const STREAM: bool>(
        &self,
        s: &mut RowScratch,
        r0: usize,
        park: [SharedMut<Lane>; 2],
    ) -> (usize, CurlSums) {
        let (w, [nx, ny, nz]) = (self.w, self.normal);
        s.lp.resize(w, lane_splat(0.0));
        s.lq.resize(w, lane_splat(0.0));
        // The band's lanes, filtered here before they are parked.
        let (lp, lq) = (&mut s.lp, &mut s.lq);
        let rows = LANES.min(self.h - r0);
        // The row above the band too (its plaquettes with the band's first row are this
        // band's), recomputed here rather than shared with the band above.
        let above = usize::from(r0 > 0);
        let first = r0 - above;
        let nrows = rows + above;
        let stride = GRADIENT_CHUNK + 1;
        s.p_band.resize(nrows * stride, 0.0);
        s.q_band.resize(nrows * stride, 0.0);
        let (mut clamped, mut sums) = (0usize, CurlSums::default());
        // Chunks of columns, each with the next chunk's first column (for the plaquettes at
        // its last column): the chunk's gradient rows stay in L1 while their curl sums are
        // taken and they are transposed into lanes.
        for c0 in (0..w).step_by(GRADIENT_CHUNK) {
            let own = GRADIENT_CHUNK.min(w - c0);
            let ext = (own + 1).min(w - c0);
            let (pb, qb) = (&mut s.p_band[..nrows * ext], &mut s.q_band[..nrows * ext]);
            for k in 0..nrows {
                let o = (first + k) * w + c0;
                let (pr, qr) = (
                    &mut pb[k * ext..(k + 1) * ext],
                    &mut qb[k * ext..(k + 1) * ext],
                );
                let c = gradient_row(
                    &nx[o..o + own],
                    &ny[o..o + own],
                    &nz[o..o + own],
                    &mut pr[..own],
                    &mut qr[..own],
                );
                if ext > own {
                    [pr[own], qr[own]] =
                        gradient_of_normal([nx[o + own], ny[o + own], nz[o + own]]);
                }
                if k >= above {
                    clamped += c;
                }
                if k >= 1 {
                    let (pu, pc) = pb.split_at(k * ext);
                    let (qu, qc) = qb.split_at(k * ext);
                    let m = self.mask.map(|m| (&m[o - w..o - w + ext], &m[o..o + ext]));
                    sums = sums.merge(CurlSums::of_row(
                        &pu[(k - 1) * ext..],
                        &qu[(k - 1) * ext..],
                        &pc[..ext],
                        &qc[..ext],
                        m,
                    ));
                }
            }
            // The band's rows of the chunk into lanes (the extra column too: the next chunk
            // writes the same values there).
            rows_into_lanes(&pb[above * ext..], ext, &mut lp[c0..c0 + ext]);
            rows_into_lanes(&qb[above * ext..], ext, &mut lq[c0..c0 + ext]);
        }
        // p and q filtered along x one after the other (two recursions interleaved step by
        // step measured slower), then parked piece by piece.
        self.f.run(lp, &mut s.filter, self.border);
        self.f.run(lq, &mut s.filter, self.border);
        let (band, nb) = (r0 / LANES, self.h.div_ceil(LANES));
        for (dst, src) in park.iter().zip([&s.lp, &s.lq]) {
            let stream = STREAM && (dst.get() as usize).is_multiple_of(std::mem::size_of::<Lane>());
            for c0 in (0..w).step_by(TASK_COLUMNS) {
                let span = TASK_COLUMNS.min(w - c0);
                let at = dst.get().wrapping_add(park_offset(c0, band, nb, span));
                // SAFETY: `span` lanes of this band's piece, inside the parked plane
                // (`park_offset`) and written by this task alone (the caller's contract).
                unsafe {
                    if stream {
                        for (k, lane) in src[c0..c0 + span].iter().enumerate() {
                            stream_lane(at.add(k).cast(), lane);
                        }
                    } else {
                        std::ptr::copy_nonoverlapping(src[c0..].as_ptr(), at, span);
                    }
                }
            }
        }
        if STREAM {
            stream_fence();
        }
        (clamped, sums)
    }

    /// One task of the column sweep: column groups `t·TASK_GROUPS ..` (at most
    /// [`TASK_GROUPS`], each [`LANES`] columns). Reads the row-filtered `p`, `q` from the
    /// parked planes `park`, writes the normals at `out`; returns each group's curl sums and
    /// [`Seam`]. Dispatches to the widest vector twin.
    ///
    /// # Safety
    /// `out` must point to three allocations of `w × h` floats; no other task may touch the
    /// task's columns of them.
    unsafe fn task(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        park: [&[Lane]; 2],
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        #[cfg(target_arch = "x86_64")]
        {
            if self.simd >= Simd::Avx512 {
                // SAFETY: AVX-512F is present (`Sweep::simd` is clamped to the CPU); the rest is the caller's contract.
                return unsafe { self.task_avx512(s, t, park, out) };
            }
            if self.simd >= Simd::Avx2 {
                // SAFETY: AVX2 is present (`Sweep::simd` is clamped to the CPU); the rest is the caller's contract.
                return unsafe { self.task_avx2(s, t, park, out) };
            }
        }
        // SAFETY: the caller's contract.
        unsafe { self.task_portable::<false>(s, t, park, out) }
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
        park: [&[Lane]; 2],
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        // SAFETY: the caller's contract.
        unsafe { self.task_portable::<false>(s, t, park, out) }
    }

    /// [`Self::task_portable`] compiled for AVX-512F: a [`Lane`] is one register (no FMA:
    /// bit-identical results), and the normals go out with non-temporal stores.
    ///
    /// # Safety
    /// As [`Self::task`], and AVX-512F must be available.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn task_avx512(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        park: [&[Lane]; 2],
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        // SAFETY: the caller's contract.
        unsafe { self.task_portable::<true>(s, t, park, out) }
    }

    /// # Safety
    /// As [`Self::task`].
    #[inline(always)]
    unsafe fn task_portable<const STREAM: bool>(
        &self,
        s: &mut ColumnScratch,
        t: usize,
        park: [&[Lane]; 2],
        out: [SharedMut<f32>; 3],
    ) -> Vec<(CurlSums, Vec<Seam>)> {
        let (w, h) = (self.w, self.h);
        let g0 = t * TASK_GROUPS;
        let k = TASK_GROUPS.min(w.div_ceil(LANES) - g0);
        let c0 = g0 * LANES;
        let span = (k * LANES).min(w - c0);
        // The task's columns band by band from the parked planes (`span` lanes = 4 KiB
        // contiguous per band and plane), each group's 16 × 16 blocks transposed into rows.
        let nb = h.div_ceil(LANES);
        for (buf, src) in [(&mut s.p, park[0]), (&mut s.q, park[1])] {
            buf.resize_with(k, Vec::new);
            for b in buf.iter_mut() {
                // Every row is loaded below: only a new length needs filling.
                if b.len() != nb * LANES {
                    b.clear();
                    b.resize(nb * LANES, lane_splat(0.0));
                }
            }
            for band in 0..nb {
                let base = park_offset(c0, band, nb, span);
                prefetch_span(
                    src.as_ptr()
                        .wrapping_add(park_offset(c0, band + PREFETCH_BANDS, nb, span))
                        .cast(),
                    span * LANES,
                );
                for (j, b) in buf.iter_mut().enumerate() {
                    let cols = LANES.min(span - j * LANES);
                    let chunk = &src[base + j * LANES..base + j * LANES + cols];
                    let dst = &mut b[band * LANES..(band + 1) * LANES];
                    if cols == LANES {
                        transpose_lanes(chunk, dst);
                    } else {
                        for (k, row) in dst.iter_mut().enumerate() {
                            *row =
                                std::array::from_fn(|c| if c < cols { chunk[c][k] } else { 0.0 });
                        }
                    }
                }
            }
        }
        let mut result = Vec::with_capacity(k);
        for j in 0..k {
            let (bp, bq) = (&mut s.p[j][..h], &mut s.q[j][..h]);
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
        // Whole lanes go out with non-temporal stores when every one is cache-line aligned
        // (planes from `recycle::Recycler` are; `w` a multiple of 16): the normals are not read
        // again here, and a streaming store does not first read the line it overwrites.
        let stream = STREAM
            && w.is_multiple_of(LANES)
            && out
                .iter()
                .all(|p| (p.get() as usize).is_multiple_of(std::mem::size_of::<Lane>()));
        for r in 0..h {
            // The stores go down the strip a row apart: ask for the lines a few rows ahead.
            if !stream {
                for dst in &out {
                    prefetch_span(dst.get().wrapping_add((r + PREFETCH_ROWS) * w + c0), span);
                }
            }
            for j in 0..k {
                let (p, q) = (&s.p[j][r], &s.q[j][r]);
                let mut nrm = [lane_splat(0.0); 3];
                for l in 0..LANES {
                    [nrm[0][l], nrm[1][l], nrm[2][l]] = normal_of_gradient(p[l], q[l]);
                }
                let cols = LANES.min(span - j * LANES);
                for (dst, lane) in out.iter().zip(&nrm) {
                    let at = dst.get().wrapping_add(r * w + c0 + j * LANES);
                    // SAFETY: columns of row r inside the plane that belong to this task alone
                    // (aligned to a whole lane when streaming).
                    unsafe {
                        if stream && cols == LANES {
                            stream_lane(at, lane);
                        } else {
                            store_lane(at, lane, cols);
                        }
                    }
                }
            }
        }
        if stream {
            stream_fence();
        }
        result
    }
}

/// Step 1 of the module docs; returns (clamped, curl sums before).
fn row_sweep<F: LineFilter>(sw: &Sweep<'_, F>, park: &mut [Vec<Lane>; 2]) -> (usize, CurlSums) {
    let n = parked_len(sw.w, sw.h);
    assert!(park.iter().all(|p| p.len() == n));
    let ptr = park.each_mut().map(|p| SharedMut(p.as_mut_ptr()));
    (0..sw.h.div_ceil(LANES))
        .into_par_iter()
        // SAFETY: `ptr` point to the two parked planes of `parked_len` lanes, which nothing
        // else touches during this call; each band is visited once and writes only its own
        // pieces (`park_offset`).
        .map_init(RowScratch::default, |s, band| unsafe {
            sw.band(s, band * LANES, ptr)
        })
        .ordered_reduce(
            || (0, CurlSums::default()),
            |a, b| (a.0 + b.0, a.1.merge(b.1)),
        )
}

/// Step 2 of the module docs; returns the curl sums after filtering.
fn column_sweep<F: LineFilter>(
    sw: &Sweep<'_, F>,
    park: &[Vec<Lane>; 2],
    ptr: [SharedMut<f32>; 3],
) -> CurlSums {
    let park = [&park[0][..], &park[1][..]];
    let tasks = sw.w.div_ceil(LANES * TASK_GROUPS);
    let per_group: Vec<(CurlSums, Vec<Seam>)> = (0..tasks)
        .into_par_iter()
        // SAFETY: `ptr` point to the three w×h output allocations, which nothing else touches
        // during this call; each task index is visited once, so each task owns its columns.
        .map_init(ColumnScratch::default, |s, t| unsafe {
            sw.task(s, t, park, ptr)
        })
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
        .ordered_reduce(CurlSums::default, CurlSums::merge);
    per_group
        .into_iter()
        .fold(seams, |acc, (s, _)| acc.merge(s))
}

/// Writes a whole lane to the 64-byte aligned `dst` with a non-temporal store (called from
/// the AVX-512F twin only; elsewhere a plain store).
///
/// # Safety
/// `dst` must be valid for `LANES` writes and 64-byte aligned; AVX-512F must be available.
#[inline(always)]
unsafe fn stream_lane(dst: *mut f32, lane: &Lane) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: the caller's contract.
    unsafe {
        use std::arch::x86_64::{_mm512_loadu_ps, _mm512_stream_ps};
        _mm512_stream_ps(dst, _mm512_loadu_ps(lane.as_ptr()));
    }
    #[cfg(not(target_arch = "x86_64"))]
    // SAFETY: the caller's contract.
    unsafe {
        store_lane(dst, lane, LANES)
    };
}

/// Orders the non-temporal stores before whatever follows (the task's results are read by
/// other threads once it returns).
#[inline(always)]
fn stream_fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `sfence` has no preconditions (SSE, part of x86-64).
    unsafe {
        std::arch::x86_64::_mm_sfence()
    };
}

/// `a` moved down one lane (`a[l + 1]` at `l`, 0 at the last lane).
#[inline(always)]
fn next_lane(a: &Lane) -> Lane {
    let mut o = [0.0; LANES];
    o[..LANES - 1].copy_from_slice(&a[1..]);
    o
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
        // Each lane's right neighbour (the group's last lane is not counted here).
        let (pun, pcn, qun, qcn) = (next_lane(pu), next_lane(pc), next_lane(qu), next_lane(qc));
        for l in 0..LANES {
            let eu = 0.5 * (pu[l] + pun[l]);
            let ec = 0.5 * (pc[l] + pcn[l]);
            let qcl = 0.5 * (qc[l] + qu[l]);
            let qn = 0.5 * (qcn[l] + qun[l]);
            let c = ((eu - ec) - (qn - qcl)) * keep[l];
            c2[l] += c * c;
            g2[l] += (ec * ec + qcl * qcl) * keep[l];
            let a = c.abs();
            mx[l] = if a > mx[l] { a } else { mx[l] };
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
        let (want, clamped, before, after) = reference(img, f, border);
        // Every twin this CPU runs (the portable one included): the same arithmetic without
        // fused multiply-adds, so bit-identical normals (and the same statistics).
        for simd in Simd::supported_levels() {
            let got = smooth_normals_twin([nx, ny, nz], img.mask(), w, h, f, border, simd);
            for (k, (g, wa)) in got.normal.iter().zip(&want).enumerate() {
                assert!(
                    g.iter().zip(wa).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{w}×{h} {border:?}, {simd} twin: plane {k} differs"
                );
            }
            assert_eq!(got.clamped, clamped, "{simd} twin");
        }
        let got = smooth_normals([nx, ny, nz], img.mask(), w, h, f, border);
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
        // Sizes around the lane count (partial bands and groups, single column/row groups)
        // and around the gradient chunk (a chunk of one column, chunks of 256 and 257).
        for (w, h) in [
            (300, 20),
            (257, 17),
            (513, 3),
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
