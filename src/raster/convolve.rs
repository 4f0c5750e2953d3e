//! Separable and recursive convolution of `f32` planes, with border modes, over rayon.
//!
//! Every 1-D filter runs on *lane-interleaved lines*: `L` image lines (rows for the horizontal
//! pass, columns for the vertical one) are gathered into a buffer of `[f32; L]` so the inner
//! loop processes `L` independent lines at once and vectorises, whichever axis is filtered.
//!
//! # Gaussian
//!
//! - `σ < `[`IIR_MIN_SIGMA`]: exact sampled Gaussian (FIR, radius `⌈4σ⌉`, normalised to sum 1).
//! - larger σ: Deriche's 4th-order recursive approximation (Deriche 1993), implemented as two
//!   parallel second-order sections (causal + anticausal), normalised to unit DC gain. Cost is
//!   independent of σ (16 multiply-adds per sample and pass). Borders are handled by running the
//!   recursion over `⌈7σ⌉` virtual samples of the border mode, started in steady state.
//!
//! Accuracy against exact convolution with the sampled, normalised Gaussian (impulse response,
//! line of 4·(7σ) samples, measured by `tests::deriche_accuracy_table`): the maximum absolute
//! error relative to the kernel's peak is below 1.2 % at σ = 3 and below 0.8 % for σ ≥ 8; on a
//! smooth signal (the use case — gradients of a surface) the relative RMS error of the output
//! is below 1e-3. See the doc of [`gaussian`] for the measured table.

use crate::raster::buf;
use crate::raster::par::SharedMut;
use rayon::prelude::*;

/// How samples outside the image are invented.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum BorderMode {
    /// Half-sample symmetric reflection: `… x1 x0 | x0 x1 …` (no artificial edge).
    #[default]
    Mirror,
    /// Repeat the edge sample.
    Clamp,
    /// Periodic (tiles seamlessly).
    Wrap,
    /// Zero outside (for gradients: the surface is flat outside the image).
    Zero,
}

impl BorderMode {
    /// All modes, for help texts and UIs.
    pub const ALL: [BorderMode; 4] = [Self::Mirror, Self::Clamp, Self::Wrap, Self::Zero];

    /// Lower-case name used by the CLI.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Mirror => "mirror",
            Self::Clamp => "clamp",
            Self::Wrap => "wrap",
            Self::Zero => "zero",
        }
    }

    /// Index into a line of length `n` for a (possibly outside) position `i`; `None` = zero.
    #[inline]
    #[must_use]
    pub fn map(self, i: isize, n: usize) -> Option<usize> {
        let n_i = n as isize;
        if (0..n_i).contains(&i) {
            return Some(i as usize);
        }
        match self {
            Self::Zero => None,
            Self::Clamp => Some(i.clamp(0, n_i - 1) as usize),
            Self::Wrap => Some(i.rem_euclid(n_i) as usize),
            Self::Mirror => {
                let m = i.rem_euclid(2 * n_i);
                Some(if m < n_i { m } else { 2 * n_i - 1 - m } as usize)
            }
        }
    }
}

impl std::str::FromStr for BorderMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown border mode {s:?} (mirror, clamp, wrap, zero)"))
    }
}

/// Smallest σ filtered recursively; below it the exact FIR is used (and is cheap).
pub const IIR_MIN_SIGMA: f32 = 3.0;

/// Lanes processed together. 16 f32 = one 64-byte cache line per row for the vertical pass.
pub(crate) const LANES: usize = 16;
/// `LANES` samples, one from each of `LANES` independent lines.
pub type Lane = [f32; LANES];

/// A 1-D filter applied along lane-interleaved lines.
pub trait LineFilter: Sync {
    /// Filters `line` (length = line length, each element = `LANES` independent lines) in place.
    /// `scratch` is reusable working memory.
    fn run(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode);
}

#[inline(always)]
pub(crate) fn lane_splat(v: f32) -> Lane {
    [v; LANES]
}

/// Fetches sample `i` (possibly outside) of `line` under `border`.
#[inline(always)]
fn fetch(line: &[Lane], i: isize, border: BorderMode) -> Lane {
    match border.map(i, line.len()) {
        Some(j) => line[j],
        None => lane_splat(0.0),
    }
}

/// Builds `ext` = `line` extended by `r` samples on both sides under `border`.
fn extend_into(line: &[Lane], r: usize, border: BorderMode, ext: &mut Vec<Lane>) {
    ext.clear();
    ext.reserve(line.len() + 2 * r);
    for i in -(r as isize)..0 {
        ext.push(fetch(line, i, border));
    }
    ext.extend_from_slice(line);
    for i in 0..r as isize {
        ext.push(fetch(line, line.len() as isize + i, border));
    }
}

/// A symmetric or general FIR kernel `k[-r..=r]` (stored as `taps[0..2r+1]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Fir {
    pub taps: Vec<f32>,
}

impl Fir {
    /// The sampled Gaussian of standard deviation `sigma` (radius ⌈4σ⌉), normalised to sum 1.
    #[must_use]
    pub fn gaussian(sigma: f32) -> Self {
        let r = (4.0 * sigma).ceil().max(1.0) as i32;
        let s2 = 2.0 * f64::from(sigma).powi(2);
        let w: Vec<f64> = (-r..=r).map(|i| (-f64::from(i * i) / s2).exp()).collect();
        let sum: f64 = w.iter().sum();
        Self {
            taps: w.iter().map(|v| (v / sum) as f32).collect(),
        }
    }

    fn radius(&self) -> usize {
        self.taps.len() / 2
    }
}

impl LineFilter for Fir {
    fn run(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode) {
        let r = self.radius();
        extend_into(line, r, border, scratch);
        for (n, out) in line.iter_mut().enumerate() {
            let mut acc = lane_splat(0.0);
            for (k, &t) in self.taps.iter().enumerate() {
                let s = &scratch[n + k];
                for l in 0..LANES {
                    acc[l] += t * s[l];
                }
            }
            *out = acc;
        }
    }
}

/// Box filter of radius `r` (width `2r+1`), normalised, via a running sum in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxFilter {
    pub radius: usize,
}

impl LineFilter for BoxFilter {
    fn run(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode) {
        let r = self.radius;
        extend_into(line, r + 1, border, scratch);
        let inv = 1.0 / (2 * r + 1) as f64;
        let mut sum = [0.0f64; LANES];
        // window for output n covers ext[n+1 ..= n+2r+1]
        for s in &scratch[1..=2 * r + 1] {
            for l in 0..LANES {
                sum[l] += f64::from(s[l]);
            }
        }
        let n_len = line.len();
        for n in 0..n_len {
            for l in 0..LANES {
                line[n][l] = (sum[l] * inv) as f32;
            }
            if n + 1 < n_len {
                let (add, sub) = (scratch[n + 2 * r + 2], scratch[n + 1]);
                for l in 0..LANES {
                    sum[l] += f64::from(add[l]) - f64::from(sub[l]);
                }
            }
        }
    }
}

/// One second-order section of the parallel-form recursive Gaussian.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Section {
    n0: f32,
    n1: f32,
    m1: f32,
    m2: f32,
    d1: f32,
    d2: f32,
}

/// Deriche's 4th-order recursive Gaussian as two parallel second-order sections.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deriche {
    sec: [Section; 2],
    pad: usize,
}

impl Deriche {
    /// Coefficients for standard deviation `sigma` (pixels, > 0).
    #[must_use]
    pub fn new(sigma: f32) -> Self {
        // Deriche (1993): h(x) ≈ Σ_k (a_k cos(w_k x/σ) + b_k sin(w_k x/σ)) e^{-β_k x/σ}, x ≥ 0.
        const A: [f64; 2] = [1.680, -0.6803];
        const B: [f64; 2] = [3.735, -0.2598];
        const W: [f64; 2] = [0.6318, 1.997];
        const BETA: [f64; 2] = [1.783, 1.723];
        let s = f64::from(sigma);
        let mut secs = [(0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0); 2];
        let mut total = 0.0;
        for k in 0..2 {
            let r = (-BETA[k] / s).exp();
            let th = W[k] / s;
            let (a, b) = (A[k], B[k]);
            let n0 = a;
            let n1 = r * (b * th.sin() - a * th.cos());
            let m1 = r * (b * th.sin() + a * th.cos());
            let m2 = -a * r * r;
            let d1 = -2.0 * r * th.cos();
            let d2 = r * r;
            total += (n0 + n1 + m1 + m2) / (1.0 + d1 + d2);
            secs[k] = (n0, n1, m1, m2, d1, d2);
        }
        let sec = secs.map(|(n0, n1, m1, m2, d1, d2)| Section {
            n0: (n0 / total) as f32,
            n1: (n1 / total) as f32,
            m1: (m1 / total) as f32,
            m2: (m2 / total) as f32,
            d1: d1 as f32,
            d2: d2 as f32,
        });
        Self {
            sec,
            pad: (7.0 * sigma).ceil() as usize,
        }
    }
}

/// One step of a second-order section: `a·x + b·x' − d1·y1 − d2·y2`, as fused multiply-adds
/// (exactly rounded on every target, so all vector twins give the same bits). The state terms
/// come last, so the recursion's critical path is one multiply-add per step.
#[inline(always)]
fn section(a: f32, b: f32, x: f32, xp: f32, s: &Section, y1: f32, y2: f32) -> f32 {
    let input = a.mul_add(x, b * xp);
    (-s.d1).mul_add(y1, (-s.d2).mul_add(y2, input))
}

/// One causal step of both second-order sections for `LANES` lines: input `x` = x\[i\],
/// `xp` = x\[i-1\], `st` = \[a1, a2, b1, b2\] (y\[i-1\], y\[i-2\] of each section); returns y\[i\].
#[inline(always)]
fn causal_step(x: &Lane, xp: &Lane, st: &mut [Lane; 4], s0: &Section, s1: &Section) -> Lane {
    let mut out = [0.0; LANES];
    for l in 0..LANES {
        let ya = section(s0.n0, s0.n1, x[l], xp[l], s0, st[0][l], st[1][l]);
        let yb = section(s1.n0, s1.n1, x[l], xp[l], s1, st[2][l], st[3][l]);
        st[1][l] = st[0][l];
        st[0][l] = ya;
        st[3][l] = st[2][l];
        st[2][l] = yb;
        out[l] = ya + yb;
    }
    out
}

/// One anticausal step: `x1` = x\[i+1\], `x2` = x\[i+2\]; returns the anticausal y\[i\].
#[inline(always)]
fn anti_step(x1: &Lane, x2: &Lane, st: &mut [Lane; 4], s0: &Section, s1: &Section) -> Lane {
    let mut out = [0.0; LANES];
    for l in 0..LANES {
        let ya = section(s0.m1, s0.m2, x1[l], x2[l], s0, st[0][l], st[1][l]);
        let yb = section(s1.m1, s1.m2, x1[l], x2[l], s1, st[2][l], st[3][l]);
        st[1][l] = st[0][l];
        st[0][l] = ya;
        st[3][l] = st[2][l];
        st[2][l] = yb;
        out[l] = ya + yb;
    }
    out
}

/// Steady-state recursion state for a constant input `x` (gains `g0`, `g1` of the sections).
#[inline(always)]
fn steady_state(x: &Lane, g0: f32, g1: f32) -> [Lane; 4] {
    let mut st = [lane_splat(0.0); 4];
    for l in 0..LANES {
        st[0][l] = x[l] * g0;
        st[1][l] = st[0][l];
        st[2][l] = x[l] * g1;
        st[3][l] = st[2][l];
    }
    st
}

impl Section {
    /// DC gain of the causal (`fwd`) or anticausal part.
    fn gain(&self, fwd: bool) -> f32 {
        let num = if fwd {
            self.n0 + self.n1
        } else {
            self.m1 + self.m2
        };
        num / (1.0 + self.d1 + self.d2)
    }
}

impl Deriche {
    /// Virtual border samples run before/after the line for `border`.
    fn pad_for(&self, border: BorderMode) -> usize {
        match border {
            BorderMode::Mirror | BorderMode::Wrap => self.pad,
            // Clamp and zero are exactly represented by a steady-state start.
            BorderMode::Clamp | BorderMode::Zero => 0,
        }
    }
}

impl LineFilter for Deriche {
    fn run(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode) {
        #[cfg(target_arch = "x86_64")]
        {
            if crate::raster::simd::Simd::Avx512.runs() {
                // SAFETY: `run_avx512` only requires AVX-512F, which is present (`Simd::runs`).
                return unsafe { self.run_avx512(line, scratch, border) };
            }
            if crate::raster::simd::Simd::Avx2.runs() {
                // SAFETY: `run_avx2` only requires AVX2 and FMA, which are present (`Simd::runs`).
                return unsafe { self.run_avx2(line, scratch, border) };
            }
        }
        self.run_portable(line, scratch, border);
    }
}

impl Deriche {
    /// [`Self::run_portable`] compiled with 256-bit AVX2 vectors and hardware FMA: the
    /// recursion is compute-bound and the baseline x86-64 target only has 128-bit SSE2. The
    /// steps are explicit fused multiply-adds (`f32::mul_add`, exactly rounded everywhere; Rust
    /// never contracts `a*b+c` by itself), so results are bit-identical to the portable path
    /// (`tests::avx2_and_avx512_paths_are_bit_identical`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn run_avx2(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode) {
        self.run_portable(line, scratch, border);
    }

    /// [`Self::run_portable`] with 512-bit vectors: a [`Lane`] is one register, half the
    /// instructions of the AVX2 twin (AVX-512F includes FMA), bit-identical too.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn run_avx512(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode) {
        self.run_portable(line, scratch, border);
    }

    #[inline(always)]
    fn run_portable(&self, line: &mut [Lane], scratch: &mut Vec<Lane>, border: BorderMode) {
        let n = line.len();
        if n == 0 {
            return;
        }
        let pad = self.pad_for(border);
        let [s0, s1] = self.sec;

        // ---- causal pass into scratch (every element written below) ----
        if scratch.len() != n {
            scratch.clear();
            scratch.resize(n, lane_splat(0.0));
        }
        let x0 = fetch(line, -(pad as isize) - 1, border);
        let mut xp = x0; // x[i-1]
                         // Recursion state of the two second-order sections: [a1, a2, b1, b2] (y[i-1], y[i-2]).
        let mut st = steady_state(&x0, s0.gain(true), s1.gain(true));
        for i in -(pad as isize)..0 {
            let x = fetch(line, i, border);
            causal_step(&x, &xp, &mut st, &s0, &s1);
            xp = x;
        }
        for i in 0..n {
            let x = line[i];
            scratch[i] = causal_step(&x, &xp, &mut st, &s0, &s1);
            xp = x;
        }

        // ---- anticausal pass, adding into line (in place: x[i+1], x[i+2] kept in registers) ----
        let xe = fetch(line, (n + pad) as isize, border);
        let (mut x1, mut x2) = (xe, xe); // x[i+1], x[i+2]
        let mut st = steady_state(&xe, s0.gain(false), s1.gain(false));
        for i in (n as isize..(n + pad) as isize).rev() {
            anti_step(&x1, &x2, &mut st, &s0, &s1);
            x2 = x1;
            x1 = fetch(line, i, border);
        }
        for i in (0..n).rev() {
            let y = anti_step(&x1, &x2, &mut st, &s0, &s1);
            x2 = x1;
            x1 = line[i];
            let c = scratch[i];
            for l in 0..LANES {
                line[i][l] = c[l] + y[l];
            }
        }
    }
}

/// Reads `cols ≤ LANES` floats from `src` into a lane (the rest zero). A whole lane is one
/// 64-byte load instead of a `memmove` call of variable length.
///
/// # Safety
/// `src..src+cols` must be readable.
#[inline(always)]
pub(crate) unsafe fn load_lane(src: *const f32, cols: usize) -> Lane {
    if cols == LANES {
        // SAFETY: the caller guarantees LANES readable floats.
        unsafe { src.cast::<Lane>().read_unaligned() }
    } else {
        let mut lane = lane_splat(0.0);
        // SAFETY: the caller guarantees `cols` readable floats; `lane` holds LANES ≥ cols.
        unsafe { std::ptr::copy_nonoverlapping(src, lane.as_mut_ptr(), cols) };
        lane
    }
}

/// Writes the first `cols ≤ LANES` floats of `lane` to `dst`.
///
/// # Safety
/// `dst..dst+cols` must be writable and not aliased by any live reference.
#[inline(always)]
pub(crate) unsafe fn store_lane(dst: *mut f32, lane: &Lane, cols: usize) {
    if cols == LANES {
        // SAFETY: the caller guarantees LANES writable floats.
        unsafe { dst.cast::<Lane>().write_unaligned(*lane) }
    } else {
        // SAFETY: the caller guarantees `cols` writable floats.
        unsafe { std::ptr::copy_nonoverlapping(lane.as_ptr(), dst, cols) };
    }
}

/// Gathers a band of `rows ≤ LANES` rows (`band`, row-major, `width` floats each) into lanes:
/// `lanes[x][k] = band[k·width + x]`, lanes `rows..` zero. A full band goes through 8×8
/// register transposes (AVX) instead of one scalar store per float.
pub(crate) fn rows_to_lanes(band: &[f32], width: usize, lanes: &mut Vec<Lane>) {
    if lanes.len() != width {
        lanes.clear();
        lanes.resize(width, lane_splat(0.0));
    }
    rows_into_lanes(band, width, lanes);
}

/// [`rows_to_lanes`] into a slice of `width` lanes (whatever it held before).
pub(crate) fn rows_into_lanes(band: &[f32], width: usize, lanes: &mut [Lane]) {
    let rows = band.len() / width.max(1);
    assert!(rows <= LANES && band.len() == rows * width && lanes.len() == width);
    if rows < LANES {
        lanes.fill(lane_splat(0.0));
    }
    #[cfg(target_arch = "x86_64")]
    if rows == LANES && crate::raster::simd::Simd::Avx512.runs() {
        // SAFETY: AVX-512F is present (`Simd::runs`); `band` holds LANES rows of `width`, `lanes`
        // `width`.
        return unsafe { transpose_avx512::rows_to_lanes(band, width, lanes) };
    }
    #[cfg(target_arch = "x86_64")]
    if rows == LANES && crate::raster::simd::Simd::Avx2.runs() {
        // SAFETY: AVX is present (`Simd::runs`: AVX2 implies it); `band` holds LANES rows of `width`, `lanes` `width`.
        return unsafe { transpose_avx::rows_to_lanes(band, width, lanes) };
    }
    for k in 0..rows {
        for (lane, &v) in lanes.iter_mut().zip(&band[k * width..(k + 1) * width]) {
            lane[k] = v;
        }
    }
}

/// The 16 × 16 transpose `dst[x][k] = src[k][x]` (`LANES` lanes each).
pub(crate) fn transpose_lanes(src: &[Lane], dst: &mut [Lane]) {
    assert!(src.len() == LANES && dst.len() == LANES);
    rows_into_lanes(src.as_flattened(), LANES, dst);
}

/// The inverse of [`rows_to_lanes`]: `band[k·width + x] = lanes[x][k]` for the band's rows.
pub(crate) fn lanes_to_rows(lanes: &[Lane], width: usize, band: &mut [f32]) {
    let rows = band.len() / width.max(1);
    assert!(rows <= LANES && band.len() == rows * width && lanes.len() == width);
    #[cfg(target_arch = "x86_64")]
    if rows == LANES && crate::raster::simd::Simd::Avx512.runs() {
        // SAFETY: AVX-512F is present (`Simd::runs`); the sizes were just checked.
        return unsafe { transpose_avx512::lanes_to_rows(lanes, width, band) };
    }
    #[cfg(target_arch = "x86_64")]
    if rows == LANES && crate::raster::simd::Simd::Avx2.runs() {
        // SAFETY: AVX is present (`Simd::runs`: AVX2 implies it); the sizes were just checked.
        return unsafe { transpose_avx::lanes_to_rows(lanes, width, band) };
    }
    for k in 0..rows {
        for (v, lane) in band[k * width..(k + 1) * width].iter_mut().zip(lanes) {
            *v = lane[k];
        }
    }
}

/// The scalar rest of a full band's [`rows_to_lanes`]: columns `from..width`.
#[cfg(target_arch = "x86_64")]
fn rows_to_lanes_from(band: &[f32], width: usize, lanes: &mut [Lane], from: usize) {
    for k in 0..LANES {
        for x in from..width {
            lanes[x][k] = band[k * width + x];
        }
    }
}

/// The scalar rest of a full band's [`lanes_to_rows`]: columns `from..width`.
#[cfg(target_arch = "x86_64")]
fn lanes_to_rows_from(lanes: &[Lane], width: usize, band: &mut [f32], from: usize) {
    for k in 0..LANES {
        for x in from..width {
            band[k * width + x] = lanes[x][k];
        }
    }
}

/// The AVX-512 16 × 16 transposes behind [`rows_to_lanes`] and [`lanes_to_rows`] (data
/// movement only: bit-identical to the scalar loops). Four shuffle stages of 16 instructions
/// per 256 floats, a third fewer than two AVX 8 × 8 transposes per 16 × 8.
#[cfg(target_arch = "x86_64")]
mod transpose_avx512 {
    use super::{Lane, LANES};
    use std::arch::x86_64::{
        __m512, _mm512_loadu_ps, _mm512_setzero_ps, _mm512_shuffle_f32x4, _mm512_shuffle_ps,
        _mm512_storeu_ps, _mm512_unpackhi_ps, _mm512_unpacklo_ps,
    };

    /// `out[j][k] = r[k][j]`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn transpose16(r: [__m512; 16]) -> [__m512; 16] {
        // Within each 128-bit quarter m: u[4g + c] = rows 4g..4g+4 at column 4m + c.
        let mut u = [_mm512_setzero_ps(); 16];
        for g in 0..4 {
            let (a, b, c, d) = (r[4 * g], r[4 * g + 1], r[4 * g + 2], r[4 * g + 3]);
            let (ab_lo, ab_hi) = (_mm512_unpacklo_ps(a, b), _mm512_unpackhi_ps(a, b));
            let (cd_lo, cd_hi) = (_mm512_unpacklo_ps(c, d), _mm512_unpackhi_ps(c, d));
            u[4 * g] = _mm512_shuffle_ps::<0x44>(ab_lo, cd_lo);
            u[4 * g + 1] = _mm512_shuffle_ps::<0xEE>(ab_lo, cd_lo);
            u[4 * g + 2] = _mm512_shuffle_ps::<0x44>(ab_hi, cd_hi);
            u[4 * g + 3] = _mm512_shuffle_ps::<0xEE>(ab_hi, cd_hi);
        }
        // Quarters regrouped: w[c] = rows 0–7 of columns c and 8+c, w[4+c] of 4+c and 12+c,
        // w[8+c], w[12+c] the same for rows 8–15.
        let mut w = [_mm512_setzero_ps(); 16];
        for c in 0..4 {
            w[c] = _mm512_shuffle_f32x4::<0x88>(u[c], u[4 + c]);
            w[4 + c] = _mm512_shuffle_f32x4::<0xDD>(u[c], u[4 + c]);
            w[8 + c] = _mm512_shuffle_f32x4::<0x88>(u[8 + c], u[12 + c]);
            w[12 + c] = _mm512_shuffle_f32x4::<0xDD>(u[8 + c], u[12 + c]);
        }
        let mut out = [_mm512_setzero_ps(); 16];
        for c in 0..4 {
            out[c] = _mm512_shuffle_f32x4::<0x88>(w[c], w[8 + c]);
            out[8 + c] = _mm512_shuffle_f32x4::<0xDD>(w[c], w[8 + c]);
            out[4 + c] = _mm512_shuffle_f32x4::<0x88>(w[4 + c], w[12 + c]);
            out[12 + c] = _mm512_shuffle_f32x4::<0xDD>(w[4 + c], w[12 + c]);
        }
        out
    }

    /// # Safety
    /// AVX-512F available; `band.len() == LANES · width`, `lanes.len() == width`.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn rows_to_lanes(band: &[f32], width: usize, lanes: &mut [Lane]) {
        debug_assert!(band.len() == LANES * width && lanes.len() == width);
        let full = width / LANES * LANES;
        for x0 in (0..full).step_by(LANES) {
            let mut r = [_mm512_setzero_ps(); 16];
            for (k, v) in r.iter_mut().enumerate() {
                // SAFETY: row k < LANES, columns x0..x0+16 ≤ width: inside `band`.
                *v = unsafe { _mm512_loadu_ps(band.as_ptr().add(k * width + x0)) };
            }
            for (j, v) in transpose16(r).into_iter().enumerate() {
                // SAFETY: lane x0+j < width exists and holds LANES floats.
                unsafe { _mm512_storeu_ps(lanes[x0 + j].as_mut_ptr(), v) };
            }
        }
        super::rows_to_lanes_from(band, width, lanes, full);
    }

    /// # Safety
    /// AVX-512F available; `band.len() == LANES · width`, `lanes.len() == width`.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn lanes_to_rows(lanes: &[Lane], width: usize, band: &mut [f32]) {
        debug_assert!(band.len() == LANES * width && lanes.len() == width);
        let full = width / LANES * LANES;
        for x0 in (0..full).step_by(LANES) {
            let mut r = [_mm512_setzero_ps(); 16];
            for (j, v) in r.iter_mut().enumerate() {
                // SAFETY: lane x0+j < width exists and holds LANES floats.
                *v = unsafe { _mm512_loadu_ps(lanes[x0 + j].as_ptr()) };
            }
            for (k, v) in transpose16(r).into_iter().enumerate() {
                // SAFETY: row k < LANES, columns x0..x0+16 ≤ width: inside `band`.
                unsafe { _mm512_storeu_ps(band.as_mut_ptr().add(k * width + x0), v) };
            }
        }
        super::lanes_to_rows_from(lanes, width, band, full);
    }
}

/// The AVX 8×8 transposes behind [`rows_to_lanes`] and [`lanes_to_rows`] (data movement only,
/// so results are bit-identical to the scalar loops).
#[cfg(target_arch = "x86_64")]
mod transpose_avx {
    use super::{Lane, LANES};
    use std::arch::x86_64::{
        __m256, _mm256_loadu_ps, _mm256_permute2f128_ps, _mm256_setzero_ps, _mm256_shuffle_ps,
        _mm256_storeu_ps, _mm256_unpackhi_ps, _mm256_unpacklo_ps,
    };

    /// `out[j][k] = r[k][j]`.
    #[inline]
    #[target_feature(enable = "avx")]
    fn transpose8(r: [__m256; 8]) -> [__m256; 8] {
        let t0 = _mm256_unpacklo_ps(r[0], r[1]);
        let t1 = _mm256_unpackhi_ps(r[0], r[1]);
        let t2 = _mm256_unpacklo_ps(r[2], r[3]);
        let t3 = _mm256_unpackhi_ps(r[2], r[3]);
        let t4 = _mm256_unpacklo_ps(r[4], r[5]);
        let t5 = _mm256_unpackhi_ps(r[4], r[5]);
        let t6 = _mm256_unpacklo_ps(r[6], r[7]);
        let t7 = _mm256_unpackhi_ps(r[6], r[7]);
        let s0 = _mm256_shuffle_ps::<0x44>(t0, t2);
        let s1 = _mm256_shuffle_ps::<0xee>(t0, t2);
        let s2 = _mm256_shuffle_ps::<0x44>(t1, t3);
        let s3 = _mm256_shuffle_ps::<0xee>(t1, t3);
        let s4 = _mm256_shuffle_ps::<0x44>(t4, t6);
        let s5 = _mm256_shuffle_ps::<0xee>(t4, t6);
        let s6 = _mm256_shuffle_ps::<0x44>(t5, t7);
        let s7 = _mm256_shuffle_ps::<0xee>(t5, t7);
        [
            _mm256_permute2f128_ps::<0x20>(s0, s4),
            _mm256_permute2f128_ps::<0x20>(s1, s5),
            _mm256_permute2f128_ps::<0x20>(s2, s6),
            _mm256_permute2f128_ps::<0x20>(s3, s7),
            _mm256_permute2f128_ps::<0x31>(s0, s4),
            _mm256_permute2f128_ps::<0x31>(s1, s5),
            _mm256_permute2f128_ps::<0x31>(s2, s6),
            _mm256_permute2f128_ps::<0x31>(s3, s7),
        ]
    }

    /// # Safety
    /// AVX available; `band.len() == LANES · width`, `lanes.len() == width`.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn rows_to_lanes(band: &[f32], width: usize, lanes: &mut [Lane]) {
        debug_assert!(band.len() == LANES * width && lanes.len() == width);
        let full = width / 8 * 8;
        for x0 in (0..full).step_by(8) {
            for half in 0..LANES / 8 {
                let mut r = [_mm256_setzero_ps(); 8];
                for (k, v) in r.iter_mut().enumerate() {
                    // SAFETY: row half·8+k < LANES, columns x0..x0+8 ≤ width: inside `band`.
                    *v = unsafe { _mm256_loadu_ps(band.as_ptr().add((half * 8 + k) * width + x0)) };
                }
                for (j, v) in transpose8(r).into_iter().enumerate() {
                    // SAFETY: lane x0+j < width exists; floats half·8.. half·8+8 ≤ LANES.
                    unsafe { _mm256_storeu_ps(lanes[x0 + j].as_mut_ptr().add(half * 8), v) };
                }
            }
        }
        super::rows_to_lanes_from(band, width, lanes, full);
    }

    /// # Safety
    /// AVX available; `band.len() == LANES · width`, `lanes.len() == width`.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn lanes_to_rows(lanes: &[Lane], width: usize, band: &mut [f32]) {
        debug_assert!(band.len() == LANES * width && lanes.len() == width);
        let full = width / 8 * 8;
        for x0 in (0..full).step_by(8) {
            for half in 0..LANES / 8 {
                let mut r = [_mm256_setzero_ps(); 8];
                for (j, v) in r.iter_mut().enumerate() {
                    // SAFETY: lane x0+j < width exists; floats half·8.. half·8+8 ≤ LANES.
                    *v = unsafe { _mm256_loadu_ps(lanes[x0 + j].as_ptr().add(half * 8)) };
                }
                for (k, v) in transpose8(r).into_iter().enumerate() {
                    // SAFETY: row half·8+k < LANES, columns x0..x0+8 ≤ width: inside `band`.
                    unsafe {
                        _mm256_storeu_ps(band.as_mut_ptr().add((half * 8 + k) * width + x0), v);
                    }
                }
            }
        }
        super::lanes_to_rows_from(lanes, width, band, full);
    }
}

/// Filters every row of `data` (`width × height`, row-major) along x, in place.
pub fn filter_rows<F: LineFilter>(
    data: &mut [f32],
    width: usize,
    height: usize,
    f: &F,
    border: BorderMode,
) {
    assert_eq!(data.len(), width * height);
    if width == 0 || height == 0 {
        return;
    }
    data.par_chunks_mut(width * LANES).for_each_init(
        || (Vec::<Lane>::new(), Vec::<Lane>::new()),
        |(buf, scratch), band| {
            rows_to_lanes(band, width, buf);
            f.run(buf, scratch, border);
            lanes_to_rows(buf, width, band);
        },
    );
}

/// Rows ahead that column passes prefetch. Their loads and stores go down a strip of columns
/// a row apart (15 KB at 4K), too far apart for the hardware prefetcher, and each one missed.
/// Measured on the fused σ8 filter (BENCHMARKS.md, eleventh session): 8, 16 and 32 rows all
/// cut its median by a quarter; 16 was the best.
pub(crate) const PREFETCH_ROWS: usize = 16;

/// Asks for the cache lines of the `span` floats at `p` (one row of a column strip) ahead of
/// their use. A hint only: it never faults and never writes, whatever the address.
#[inline(always)]
pub(crate) fn prefetch_span(p: *const f32, span: usize) {
    #[cfg(target_arch = "x86_64")]
    for off in (0..span)
        .step_by(LANES)
        .chain(std::iter::once(span.saturating_sub(1)))
    {
        // SAFETY: `_mm_prefetch` only hints the cache; it reads and writes no memory, so any
        // address is sound (`wrapping_add` keeps the pointer arithmetic defined too).
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                p.wrapping_add(off).cast::<i8>(),
            );
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, span);
}

/// Filters every column of `data` along y, in place.
pub fn filter_columns<F: LineFilter>(
    data: &mut [f32],
    width: usize,
    height: usize,
    f: &F,
    border: BorderMode,
) {
    assert_eq!(data.len(), width * height);
    if width == 0 || height == 0 {
        return;
    }
    let groups = width.div_ceil(LANES);
    let ptr = SharedMut(data.as_mut_ptr());
    (0..groups).into_par_iter().for_each_init(
        || (Vec::<Lane>::new(), Vec::<Lane>::new()),
        |(buf, scratch), g| {
            let c0 = g * LANES;
            let cols = LANES.min(width - c0);
            buf.clear();
            buf.resize(height, lane_splat(0.0));
            let ahead = PREFETCH_ROWS * width;
            for (r, lane) in buf.iter_mut().enumerate() {
                let at = r * width + c0;
                prefetch_span(ptr.get().wrapping_add(at + ahead), cols);
                // SAFETY: reads columns c0..c0+cols of row r, inside the buffer; no other task
                // writes these columns (groups are disjoint).
                *lane = unsafe { load_lane(ptr.get().add(at), cols) };
            }
            f.run(buf, scratch, border);
            for (r, lane) in buf.iter().enumerate() {
                let at = r * width + c0;
                prefetch_span(ptr.get().wrapping_add(at + ahead), cols);
                // SAFETY: as above; this task alone owns columns c0..c0+cols.
                unsafe { store_lane(ptr.get().add(at), lane, cols) };
            }
        },
    );
}

/// Applies the same 1-D filter along x then y.
pub fn separable<F: LineFilter>(
    data: &mut [f32],
    width: usize,
    height: usize,
    f: &F,
    border: BorderMode,
) {
    filter_rows(data, width, height, f, border);
    filter_columns(data, width, height, f, border);
}

/// The reach of [`gaussian`] in pixels: the FIR radius `⌈4σ⌉` below [`IIR_MIN_SIGMA`], and for
/// the recursive filter the distance `⌈TAIL_SIGMAS·σ⌉` beyond which its impulse response stays
/// below 0.05 % of its peak (`tests::deriche_tail_beyond_support`; the response rings, so the
/// bound falls slowly beyond: 1.4e-4 at 5σ, 1.8e-5 at 7σ). Region evaluation crops with this
/// halo; per pass, a pixel then differs from a whole-image run by at most the tail's mass
/// (< 3.5e-4) times the largest difference between the samples beyond the crop and those
/// its border mode invents.
#[must_use]
pub fn gaussian_support(sigma_px: f32) -> usize {
    if sigma_px <= 0.0 || !sigma_px.is_finite() {
        0
    } else if sigma_px < IIR_MIN_SIGMA {
        Fir::gaussian(sigma_px).radius()
    } else {
        (TAIL_SIGMAS * sigma_px).ceil() as usize
    }
}

/// See [`gaussian_support`].
pub const TAIL_SIGMAS: f32 = 4.0;

/// Gaussian blur of standard deviation `sigma_px` in place (`sigma_px ≤ 0` leaves the data).
///
/// Measured accuracy of the recursive path (`tests::deriche_accuracy_table`, max abs error of
/// the impulse response / kernel peak): σ=3: 0.037 %, σ=8: 0.045 %, σ=32 and σ=100: 0.047 %.
pub fn gaussian(data: &mut [f32], width: usize, height: usize, sigma_px: f32, border: BorderMode) {
    if sigma_px <= 0.0 || !sigma_px.is_finite() {
        return;
    }
    if sigma_px < IIR_MIN_SIGMA {
        separable(data, width, height, &Fir::gaussian(sigma_px), border);
    } else {
        separable(data, width, height, &Deriche::new(sigma_px), border);
    }
}

/// Box blur of radius `radius_px` (width `2r+1`) in place.
pub fn box_blur(
    data: &mut [f32],
    width: usize,
    height: usize,
    radius_px: usize,
    border: BorderMode,
) {
    if radius_px > 0 {
        separable(
            data,
            width,
            height,
            &BoxFilter { radius: radius_px },
            border,
        );
    }
}

/// Separable convolution with a row kernel then a column kernel (odd lengths, centred).
pub fn convolve_separable(
    data: &mut [f32],
    width: usize,
    height: usize,
    row: &Fir,
    col: &Fir,
    border: BorderMode,
) {
    filter_rows(data, width, height, row, border);
    filter_columns(data, width, height, col, border);
}

/// Direct 2-D convolution with a small dense kernel (`kw × kh`, odd, centred, row-major with
/// row 0 at the top). Returns a new buffer.
#[must_use]
pub fn convolve_2d(
    data: &[f32],
    width: usize,
    height: usize,
    kernel: &[f32],
    kw: usize,
    kh: usize,
    border: BorderMode,
) -> Vec<f32> {
    let (rx, ry) = ((kw / 2) as isize, (kh / 2) as isize);
    let mut out = buf::zeroed_f32(data.len());
    out.par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(r, orow)| {
            for (x, o) in orow.iter_mut().enumerate() {
                let mut acc = 0.0f32;
                for j in 0..kh as isize {
                    let Some(rr) = border.map(r as isize + j - ry, height) else {
                        continue;
                    };
                    let srow = &data[rr * width..(rr + 1) * width];
                    for i in 0..kw as isize {
                        if let Some(xx) = border.map(x as isize + i - rx, width) {
                            acc += kernel[(j * kw as isize + i) as usize] * srow[xx];
                        }
                    }
                }
                *o = acc;
            }
        });
    out
}

/// 5-point discrete Laplacian `∂²/∂x² + ∂²/∂y²` (pixel units). Returns a new buffer.
#[must_use]
pub fn laplacian(data: &[f32], width: usize, height: usize, border: BorderMode) -> Vec<f32> {
    convolve_2d(
        data,
        width,
        height,
        &[0.0, 1.0, 0.0, 1.0, -4.0, 1.0, 0.0, 1.0, 0.0],
        3,
        3,
        border,
    )
}

impl crate::params::Choice for BorderMode {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        Self::name(self)
    }
    fn doc(self) -> &'static str {
        use BorderMode as B;
        match self {
            B::Mirror => "Half-sample symmetric reflection (no artificial edge).",
            B::Clamp => "Repeat the edge sample.",
            B::Wrap => "Periodic (tiles seamlessly).",
            B::Zero => "Zero outside (the surface is flat outside the image).",
        }
    }
}

#[cfg(test)]
#[path = "convolve_tests.rs"]
mod tests;
