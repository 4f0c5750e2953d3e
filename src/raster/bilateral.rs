//! The kernel of the RGBN bilateral filter ([`crate::ops::bilateral`] is the operator).
//!
//! # What it computes
//!
//! For every pixel `P` whose mask coverage is ≥ ½, over the pixels `Q` of the disc
//! `|Q − P| ≤ r` that lie in the image and have coverage ≥ ½:
//!
//! ```text
//! w(P, Q) = exp(−|Q − P|² / 2σ_s²) · exp(−|c(P) − c(Q)|² / 2σ_c²) · exp(−δ(n(P), n(Q))² / 2σ_n²)
//! (p̄, q̄)(P) = Σ_Q w · (p, q)(Q) / Σ_Q w,        n̂(P) = (−p̄, −q̄, 1) / |(−p̄, −q̄, 1)|
//! ```
//!
//! with `(p, q) = (−n_x/n_z, −n_y/n_z)` ([`gradient_of_normal`], `n_z` clamped as everywhere) and
//! `δ` the angle between the unit normals ([`RangeMetric::Angle`]) or `1 − n·n′`
//! ([`RangeMetric::OneMinusDot`]). A colour σ or a normal σ may be absent (that factor is 1).
//! Pixels with coverage < ½ keep their input. With `filter_color` the colour is the same
//! weighted mean of the colours.
//!
//! **Foreshortening.** The mean is taken over the foreshorten-corrected gradients, not over the
//! raw unit normals. Two reasons. (1) Where the range weights are all 1 the filter is then a
//! Gaussian of the gradient field, which is the gradient of the Gaussian-filtered height: a
//! smoothed surface stays a surface, as for every linear filter of rgbn. Averaging unit normals
//! instead flattens steep slopes (the mean of two normals tilted by ±60° about different axes is
//! shorter and tilts less than either) and is not the gradient of anything. (2) It is the
//! correction of Toler-Franklin et al. (2007), who weight each normal by `1/n_z` before
//! averaging: `Σ w n / n_z = Σ w (−p, −q, 1)`, whose direction is exactly `(−p̄, −q̄, 1)`.
//!
//! # How it runs fast
//!
//! A bilateral filter is not separable, so this is a windowed brute force, made cheap:
//! - the disc window (`r = 4`: 49 taps, as OpenCV's `bilateralFilter` with `d = 9`);
//! - all three factors in one exponential, `2^−(a + b + c)` with the constants folded in, by the
//!   branch-free [`exp2_fast`] (3e-7 relative);
//! - the angle from the chord: `t = ½|n − n′|² = 1 − n·n′` (accurate for small angles, where
//!   `1 − dot` in `f32` is not) and `acos(1 − t)` by Abramowitz & Stegun 4.4.46 (`2e-8`);
//! - tiles of [`TILE_H`] × [`TILE_W`] pixels copied with their halo into a zero-padded local
//!   buffer (border and masked pixels have validity 0), so the tap loop has no branches and the
//!   working set stays in L2;
//! - [`LANES`] output pixels of a row per step, each tap one contiguous load per plane: the
//!   compiler vectorises the lane loop (AVX-512 or AVX2 twins chosen at run time).
//!
//! Its agreement with a brute-force `f64` evaluation of the formula above (true `exp`, `acos`,
//! square window test) is tested in `ops::bilateral` to 1e-5.

use super::fastmath::{exp2_neg, madd};
use super::gradient::{gradient_of_normal, normal_of_gradient};
use crate::raster::buf;
use rayon::prelude::*;

/// Output pixels of one row computed together (the vector width of the lane loop).
pub const LANES: usize = 16;
/// Rows of a tile (one rayon task computes a band of this many rows).
pub const TILE_H: usize = 16;
/// Columns of a tile.
pub const TILE_W: usize = 256;

/// How the normal-similarity distance `δ` is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeMetric {
    /// `δ = angle(n, n′)` in radians.
    Angle,
    /// `δ = 1 − n·n′`.
    OneMinusDot,
}

/// The filter's settings (module docs). `sigma_*` of `None` drop that factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spec {
    /// Spatial σ in pixels.
    pub sigma_spatial: f32,
    /// Window radius in pixels (the disc `dx² + dy² ≤ r²`).
    pub radius: usize,
    /// Colour σ (linear RGB distance).
    pub sigma_color: Option<f32>,
    /// Normal σ (radians for the angle, unitless for `1 − n·n′`).
    pub sigma_normal: Option<f32>,
    /// How `δ` is measured.
    pub metric: RangeMetric,
    /// Also average the colour.
    pub filter_color: bool,
}

/// Planar input of [`filter`]: normals, colours, optional mask, all `width × height`.
#[derive(Clone, Copy)]
pub struct Input<'a> {
    pub width: usize,
    pub height: usize,
    pub normal: [&'a [f32]; 3],
    pub color: [&'a [f32]; 3],
    pub mask: Option<&'a [f32]>,
}

/// Result of [`filter`]: the filtered unit normals, and colours when `filter_color` is on.
pub struct Output {
    pub normal: [Vec<f32>; 3],
    pub color: Option<[Vec<f32>; 3]>,
}

/// Local planes of a tile, in this order.
const NX: usize = 0;
const NY: usize = 1;
const NZ: usize = 2;
const C0: usize = 3;
const P: usize = 6;
const Q: usize = 7;
const VALID: usize = 8;
const PLANES: usize = 9;
/// The colour of invalid pixels in the local planes (see `Kernel::fill`).
const FAR_COLOR: f32 = 1e18;

/// Distance between the local planes (floats): a constant, so that one pointer and immediate
/// offsets address all nine planes of a tap (no spilled plane pointers). Large enough for the
/// largest window (`r = 128`) with a narrower tile; not a power of two (17 cache lines more),
/// so the planes of one tap do not fall into the same cache sets.
const STRIDE: usize = (1 << 17) + 17 * 16;

/// `δ` kinds as const-generic values.
const NRM_NONE: u8 = 0;
const NRM_ANGLE: u8 = 1;
const NRM_DOT: u8 = 2;
/// The angle where the weight of any pixel more than 90° away is below 1e-8 (module docs).
const NRM_ANGLE_NARROW: u8 = 3;

/// `acos(1 − t)² = t · G(t)` for `t ∈ [0, 1]` (angles up to 90°), `G` a degree-6 polynomial
/// (Chebyshev fit in `f64`, coefficients rounded to `f32`): relative error ≤ 8e-7, so a weight
/// `exp(−k δ²)` is off by at most `8e-7 · max(x e^−x) < 3e-7`. No square root.
#[inline(always)]
fn acos_one_minus_sq_narrow<const F: bool>(t: f32) -> f32 {
    let mut g = madd::<F>(0.009_070_478, t, -0.010_330_418);
    for c in [
        0.021_646_81,
        0.023_973_45,
        0.089_773_22,
        0.333_264_56,
        2.000_001_2,
    ] {
        g = madd::<F>(g, t, c);
    }
    t * g
}

/// `acos(1 − t)` for `t ∈ [0, 2]`: Abramowitz & Stegun 4.4.46, `acos x = √(1 − x) · Σ aᵢ xⁱ`
/// for `x ∈ [0, 1]` (error ≤ 2e-8), and `π − acos(−x)` below 0. `√(1 − x)` is `√t` (or
/// `√(2 − t)`), exact from the chord. Branch-free.
#[inline(always)]
fn acos_one_minus<const F: bool>(t: f32) -> f32 {
    let u = (1.0 - t).abs();
    let s = 1.0 - u;
    let mut poly = madd::<F>(-0.001_262_491, u, 0.006_670_09);
    for c in [
        -0.017_088_126,
        0.030_891_88,
        -0.050_174_305,
        0.088_978_99,
        -0.214_598_8,
        std::f32::consts::FRAC_PI_2,
    ] {
        poly = madd::<F>(poly, u, c);
    }
    let a = s.max(0.0).sqrt() * poly;
    if t <= 1.0 {
        a
    } else {
        std::f32::consts::PI - a
    }
}

/// The `LANES` values of `p` from `j`.
#[inline(always)]
fn lanes(p: &[f32], j: usize) -> &[f32; LANES] {
    p[j..j + LANES].try_into().expect("LANES values")
}

/// The bilateral-filtered normals (and colours) of `input` (module docs).
///
/// # Panics
/// If a plane's length is not `width × height`.
#[must_use]
pub fn filter(input: &Input<'_>, spec: &Spec) -> Output {
    filter_with(input, spec, Twin::Widest)
}

/// Which compiled twin of the kernel runs (tests compare them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Twin {
    /// AVX-512 + FMA, else AVX2 + FMA, else portable.
    Widest,
    /// AVX2 + FMA when present, else portable.
    #[cfg_attr(not(test), allow(dead_code))]
    Avx2,
    /// Baseline instructions, no FMA.
    #[cfg_attr(not(test), allow(dead_code))]
    Portable,
}

fn filter_with(input: &Input<'_>, spec: &Spec, twin: Twin) -> Output {
    let (w, h) = (input.width, input.height);
    let n = w * h;
    for p in input.normal.iter().chain(&input.color) {
        assert_eq!(p.len(), n, "plane size");
    }
    if let Some(m) = input.mask {
        assert_eq!(m.len(), n, "mask size");
    }
    let kernel = Kernel {
        twin,
        ..Kernel::new(spec)
    };
    let mut out_n = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    let mut out_c = spec
        .filter_color
        .then(|| [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)]);
    if n == 0 {
        return Output {
            normal: out_n,
            color: out_c,
        };
    }
    let band = TILE_H * w;
    let nb = h.div_ceil(TILE_H);
    let mut colors: Vec<Option<[&mut [f32]; 3]>> = match out_c.as_mut() {
        Some([a, b, c]) => a
            .chunks_mut(band)
            .zip(b.chunks_mut(band))
            .zip(c.chunks_mut(band))
            .map(|((a, b), c)| Some([a, b, c]))
            .collect(),
        None => (0..nb).map(|_| None).collect(),
    };
    let [ox, oy, oz] = &mut out_n;
    let bands: Vec<_> = ox
        .chunks_mut(band)
        .zip(oy.chunks_mut(band))
        .zip(oz.chunks_mut(band))
        .zip(colors.drain(..))
        .enumerate()
        .collect();
    // A few leaf jobs per thread, so the scratch (zeroed pages) is allocated only that often.
    let leaf = nb.div_ceil(4 * rayon::current_num_threads()).max(1);
    bands.into_par_iter().with_min_len(leaf).for_each_init(
        || vec![0.0f32; kernel.scratch_len()],
        |scratch, (b, (((x, y), z), c))| {
            let mut out = BandOut { n: [x, y, z], c };
            kernel.band(input, b * TILE_H, &mut out, scratch);
        },
    );
    Output {
        normal: out_n,
        color: out_c,
    }
}

/// Where a tile is: its first image row and column, its width and its number of rows.
#[derive(Clone, Copy)]
struct TileAt {
    r0: usize,
    x0: usize,
    tw: usize,
    rows: usize,
}

/// One band's output rows (`TILE_H` rows or fewer at the bottom).
struct BandOut<'a> {
    n: [&'a mut [f32]; 3],
    c: Option<[&'a mut [f32]; 3]>,
}

/// The filter with its constants folded (exponents in base 2).
struct Kernel {
    radius: usize,
    /// Tile width (TILE_W, or less for very wide windows).
    tile_w: usize,
    /// Local buffer width: [`TILE_W`] + 2r, rounded so the last lane group fits.
    lw: usize,
    /// Local buffer height: [`TILE_H`] + 2r.
    lh: usize,
    /// `(offset in the local buffer, spatial exponent)` per tap of the disc.
    taps: Vec<(isize, f32)>,
    kc: f32,
    kn: f32,
    col: bool,
    nrm: u8,
    fc: bool,
    twin: Twin,
}

impl Kernel {
    fn new(spec: &Spec) -> Self {
        let r = spec.radius;
        let lh = TILE_H + 2 * r;
        // The widest tile (≤ TILE_W, a multiple of LANES) whose halo'd planes fit in STRIDE.
        let tile_w = TILE_W.min((STRIDE / lh - 2 * r) / LANES * LANES).max(LANES);
        let lw = tile_w + 2 * r;
        debug_assert!(
            lw * lh <= STRIDE,
            "radius {r} too large for the local planes"
        );
        let log2e = std::f32::consts::LOG2_E;
        let ks = log2e / (2.0 * spec.sigma_spatial * spec.sigma_spatial);
        let ri = r as isize;
        let mut taps = Vec::new();
        for dy in -ri..=ri {
            for dx in -ri..=ri {
                let d2 = dx * dx + dy * dy;
                if d2 <= ri * ri {
                    taps.push((dy * lw as isize + dx, d2 as f32 * ks));
                }
            }
        }
        let k = |s: Option<f32>| s.map_or(0.0, |s| log2e / (2.0 * s * s));
        Self {
            radius: r,
            tile_w,
            lw,
            lh,
            taps,
            kc: k(spec.sigma_color),
            kn: k(spec.sigma_normal),
            col: spec.sigma_color.is_some(),
            nrm: match (spec.sigma_normal, spec.metric) {
                (None, _) => NRM_NONE,
                // exp(−k (π/2)²) ≤ 1e-8: pixels beyond 90° weigh nothing; no square root.
                (Some(s), RangeMetric::Angle)
                    if std::f32::consts::FRAC_PI_2.powi(2) / (2.0 * s * s) >= 18.43 =>
                {
                    NRM_ANGLE_NARROW
                }
                (Some(_), RangeMetric::Angle) => NRM_ANGLE,
                (Some(_), RangeMetric::OneMinusDot) => NRM_DOT,
            },
            fc: spec.filter_color,
            twin: Twin::Widest,
        }
    }

    fn scratch_len(&self) -> usize {
        (PLANES - 1) * STRIDE + self.lw * self.lh
    }

    /// Rows `r0..r0 + TILE_H` (clipped), tile by tile. Dispatches to the widest vector twin.
    fn band(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, scratch: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        {
            let fma = self.twin != Twin::Portable && std::arch::is_x86_feature_detected!("fma");
            if fma && self.twin == Twin::Widest && std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: `band_avx512` only requires AVX-512F and FMA, just checked.
                return unsafe { self.band_avx512(input, r0, out, scratch) };
            }
            if fma && std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: `band_avx2` only requires AVX2 and FMA, just checked.
                return unsafe { self.band_avx2(input, r0, out, scratch) };
            }
        }
        self.band_portable(input, r0, out, scratch);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,fma")]
    fn band_avx512(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, s: &mut [f32]) {
        self.band_with::<true>(input, r0, out, s);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn band_avx2(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, s: &mut [f32]) {
        self.band_with::<true>(input, r0, out, s);
    }

    #[inline(always)]
    fn band_portable(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, s: &mut [f32]) {
        self.band_with::<false>(input, r0, out, s);
    }

    /// The band, with fused multiply-adds when `F`.
    #[inline(always)]
    fn band_with<const F: bool>(
        &self,
        input: &Input<'_>,
        r0: usize,
        out: &mut BandOut<'_>,
        s: &mut [f32],
    ) {
        let rows = out.n[0].len() / input.width.max(1);
        let mut x0 = 0;
        while x0 < input.width {
            let tw = self.tile_w.min(input.width - x0);
            self.fill(input, r0, x0, s);
            let at = TileAt { r0, x0, tw, rows };
            match (self.col, self.nrm, self.fc) {
                (false, NRM_NONE, false) => {
                    self.tile::<false, NRM_NONE, false, F>(input, at, s, out)
                }
                (false, NRM_NONE, true) => self.tile::<false, NRM_NONE, true, F>(input, at, s, out),
                (false, NRM_ANGLE, false) => {
                    self.tile::<false, NRM_ANGLE, false, F>(input, at, s, out)
                }
                (false, NRM_ANGLE, true) => {
                    self.tile::<false, NRM_ANGLE, true, F>(input, at, s, out)
                }
                (false, NRM_ANGLE_NARROW, false) => {
                    self.tile::<false, NRM_ANGLE_NARROW, false, F>(input, at, s, out)
                }
                (false, NRM_ANGLE_NARROW, true) => {
                    self.tile::<false, NRM_ANGLE_NARROW, true, F>(input, at, s, out)
                }
                (false, _, false) => self.tile::<false, NRM_DOT, false, F>(input, at, s, out),
                (false, _, true) => self.tile::<false, NRM_DOT, true, F>(input, at, s, out),
                (true, NRM_NONE, false) => self.tile::<true, NRM_NONE, false, F>(input, at, s, out),
                (true, NRM_NONE, true) => self.tile::<true, NRM_NONE, true, F>(input, at, s, out),
                (true, NRM_ANGLE, false) => {
                    self.tile::<true, NRM_ANGLE, false, F>(input, at, s, out)
                }
                (true, NRM_ANGLE, true) => self.tile::<true, NRM_ANGLE, true, F>(input, at, s, out),
                (true, NRM_ANGLE_NARROW, false) => {
                    self.tile::<true, NRM_ANGLE_NARROW, false, F>(input, at, s, out)
                }
                (true, NRM_ANGLE_NARROW, true) => {
                    self.tile::<true, NRM_ANGLE_NARROW, true, F>(input, at, s, out)
                }
                (true, _, false) => self.tile::<true, NRM_DOT, false, F>(input, at, s, out),
                (true, _, true) => self.tile::<true, NRM_DOT, true, F>(input, at, s, out),
            }
            x0 += self.tile_w;
        }
    }

    /// Copies the tile at `(x0, r0)` with its halo into the local planes: pixels outside the
    /// image, masked out (< ½) or not finite get validity 0 and zero values.
    #[inline(always)]
    fn fill(&self, input: &Input<'_>, r0: usize, x0: usize, s: &mut [f32]) {
        let (w, h, r, lw) = (input.width, input.height, self.radius, self.lw);
        let mut it = s.chunks_mut(STRIDE);
        let mut pl: [&mut [f32]; PLANES] = std::array::from_fn(|_| it.next().expect("9 planes"));
        // Outside the image: validity 0, values 0, colour FAR_COLOR.
        let pad = |k: usize| {
            if (C0..C0 + 3).contains(&k) {
                FAR_COLOR
            } else {
                0.0
            }
        };
        // Local columns lc ↔ image columns x0 + lc − r, clipped to the image.
        let lc0 = r.saturating_sub(x0);
        let lc1 = (w + r - x0).min(lw);
        for lr in 0..self.lh {
            let row = lr * lw;
            let Some(y) = (r0 + lr).checked_sub(r).filter(|&y| y < h) else {
                for (k, p) in pl.iter_mut().enumerate() {
                    p[row..row + lw].fill(pad(k));
                }
                continue;
            };
            for (k, p) in pl.iter_mut().enumerate() {
                p[row..row + lc0].fill(pad(k));
                p[row + lc1..row + lw].fill(pad(k));
            }
            let [dx, dy, dz, d0, d1, d2, pp, qq, vv] =
                pl.each_mut().map(|p| &mut p[row + lc0..row + lc1]);
            let i0 = y * w + x0 + lc0 - r;
            let i1 = i0 + (lc1 - lc0);
            let (nx, ny, nz) = (
                &input.normal[0][i0..i1],
                &input.normal[1][i0..i1],
                &input.normal[2][i0..i1],
            );
            let (k0, k1, k2) = (
                &input.color[0][i0..i1],
                &input.color[1][i0..i1],
                &input.color[2][i0..i1],
            );
            dx.copy_from_slice(nx);
            dy.copy_from_slice(ny);
            dz.copy_from_slice(nz);
            d0.copy_from_slice(k0);
            d1.copy_from_slice(k1);
            d2.copy_from_slice(k2);
            let mask = input.mask.map(|m| &m[i0..i1]);
            let (mut all_finite, mut all_valid) = (true, true);
            for c in 0..lc1 - lc0 {
                let [p, q] = gradient_of_normal([nx[c], ny[c], nz[c]]);
                // x · 0 is 0 for finite x and NaN otherwise: one test for the eight values.
                let z = 0.0 * nx[c]
                    + 0.0 * ny[c]
                    + 0.0 * nz[c]
                    + 0.0 * k0[c]
                    + 0.0 * k1[c]
                    + 0.0 * k2[c]
                    + 0.0 * p
                    + 0.0 * q;
                let finite = z == 0.0;
                let inside = mask.is_none_or(|m| m[c] >= 0.5);
                pp[c] = p;
                qq[c] = q;
                vv[c] = if finite && inside { 1.0 } else { 0.0 };
                all_finite &= finite;
                all_valid &= finite && inside;
            }
            if !all_valid {
                // Invalid pixels get a colour no pixel is near: with a colour term their weight
                // underflows to 2^−126 ≈ 1e-38 of the centre's (exp2_neg's floor) without the
                // validity plane's load and multiply. FAR_COLOR² · 3 stays finite in f32.
                for c in 0..lc1 - lc0 {
                    if vv[c] == 0.0 {
                        d0[c] = FAR_COLOR;
                        d1[c] = FAR_COLOR;
                        d2[c] = FAR_COLOR;
                    }
                }
            }
            if !all_finite {
                // Not-finite pixels weigh 0, but 0 · NaN is NaN: zero their values too.
                for c in 0..lc1 - lc0 {
                    let planes = [&mut *dx, &mut *dy, &mut *dz, &mut *pp, &mut *qq];
                    if !planes.iter().all(|p| p[c].is_finite()) {
                        for p in planes {
                            p[c] = 0.0;
                        }
                    }
                }
            }
        }
    }

    /// The filter over one filled tile (`tw` columns at `x0`, `rows` rows).
    #[inline(always)]
    fn tile<const COL: bool, const NRM: u8, const FC: bool, const F: bool>(
        &self,
        input: &Input<'_>,
        at: TileAt,
        s: &[f32],
        out: &mut BandOut<'_>,
    ) {
        let TileAt { r0, x0, tw, rows } = at;
        let (w, r, lw) = (input.width, self.radius, self.lw);
        let (kc, kn) = (self.kc, self.kn);
        // The LANES values of plane k at local index j.
        let at = |k: usize, j: usize| -> &[f32; LANES] { lanes(&s[k * STRIDE..], j) };
        for ty in 0..rows {
            for tx in (0..tw).step_by(LANES) {
                let base = (ty + r) * lw + tx + r;
                let lane = |k| *at(k, base);
                let (cnx, cny, cnz) = (lane(NX), lane(NY), lane(NZ));
                let (cc0, cc1, cc2) = (lane(C0), lane(C0 + 1), lane(C0 + 2));
                let mut ap = [0.0f32; LANES];
                let mut aq = [0.0f32; LANES];
                let mut aw = [0.0f32; LANES];
                let mut ac = [[0.0f32; LANES]; 3];
                for &(off, st) in &self.taps {
                    // All nine planes of this tap in one slice: one bounds check, then
                    // constant offsets.
                    let j = base.wrapping_add_signed(off);
                    let blk = &s[j..j + (PLANES - 1) * STRIDE + LANES];
                    let at = |k: usize| -> &[f32; LANES] { lanes(blk, k * STRIDE) };
                    let (vx, vy, vz) = (at(NX), at(NY), at(NZ));
                    let (v0, v1, v2) = (at(C0), at(C0 + 1), at(C0 + 2));
                    let (vp, vq, vm) = (at(P), at(Q), at(VALID));
                    for l in 0..LANES {
                        let mut e = st;
                        if COL {
                            let (d0, d1, d2) = (v0[l] - cc0[l], v1[l] - cc1[l], v2[l] - cc2[l]);
                            let d = madd::<F>(d2, d2, madd::<F>(d1, d1, d0 * d0));
                            e = madd::<F>(kc, d, e);
                        }
                        if NRM != NRM_NONE {
                            let dot =
                                madd::<F>(vz[l], cnz[l], madd::<F>(vy[l], cny[l], vx[l] * cnx[l]));
                            let t = (1.0 - dot).max(0.0);
                            let d2 = match NRM {
                                NRM_ANGLE_NARROW => acos_one_minus_sq_narrow::<F>(t.min(1.0)),
                                NRM_ANGLE => {
                                    let d = acos_one_minus::<F>(t.min(2.0));
                                    d * d
                                }
                                _ => t * t,
                            };
                            e = madd::<F>(kn, d2, e);
                        }
                        // With colour, invalid pixels already weigh 2^−126 (their colour is
                        // FAR_COLOR); without, the validity plane zeroes them.
                        let wt = if COL {
                            exp2_neg::<F>(e)
                        } else {
                            vm[l] * exp2_neg::<F>(e)
                        };
                        ap[l] = madd::<F>(wt, vp[l], ap[l]);
                        aq[l] = madd::<F>(wt, vq[l], aq[l]);
                        aw[l] += wt;
                        if FC {
                            ac[0][l] = madd::<F>(wt, v0[l], ac[0][l]);
                            ac[1][l] = madd::<F>(wt, v1[l], ac[1][l]);
                            ac[2][l] = madd::<F>(wt, v2[l], ac[2][l]);
                        }
                    }
                }
                let cv = lane(VALID);
                let o = ty * w + x0 + tx;
                for l in 0..LANES.min(tw - tx) {
                    let i = o + l;
                    if cv[l] > 0.0 {
                        let inv = 1.0 / aw[l];
                        let nrm = normal_of_gradient(ap[l] * inv, aq[l] * inv);
                        for (o, v) in out.n.iter_mut().zip(nrm) {
                            o[i] = v;
                        }
                        if let Some(c) = out.c.as_mut() {
                            for (o, a) in c.iter_mut().zip(&ac) {
                                o[i] = a[l] * inv;
                            }
                        }
                    } else {
                        // Masked out or not finite: the input, unchanged.
                        let g = (r0 + ty) * w + i - ty * w;
                        for (o, v) in out.n.iter_mut().zip(&input.normal) {
                            o[i] = v[g];
                        }
                        if let Some(c) = out.c.as_mut() {
                            for (o, v) in c.iter_mut().zip(&input.color) {
                                o[i] = v[g];
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_compiled_twin_gives_the_same_result() {
        // The AVX-512 / AVX2 twins use FMA, the portable one does not: equal to rounding. (The
        // widest one is checked against an f64 brute force in `ops::bilateral`.)
        let (w, h) = (70, 40);
        let n = w * h;
        let f = |i: usize, a: f32, b: f32| ((i % w) as f32 * a + (i / w) as f32 * b).sin();
        let (mut nx, mut ny, mut nz) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let (p, q) = (0.8 * f(i, 0.31, 0.17), 0.8 * f(i, 0.13, 0.41));
            let l = (p * p + q * q + 1.0f32).sqrt();
            (nx[i], ny[i], nz[i]) = (-p / l, -q / l, 1.0 / l);
        }
        let c: Vec<Vec<f32>> = (0..3)
            .map(|k| {
                (0..n)
                    .map(|i| 0.5 + 0.5 * f(i, 0.05 * (k + 1) as f32, 0.07))
                    .collect()
            })
            .collect();
        let mask: Vec<f32> = (0..n).map(|i| if i % 7 == 3 { 0.2 } else { 1.0 }).collect();
        let input = Input {
            width: w,
            height: h,
            normal: [&nx, &ny, &nz],
            color: [&c[0], &c[1], &c[2]],
            mask: Some(&mask),
        };
        for (sn, metric) in [
            (Some(0.2), RangeMetric::Angle),
            (Some(0.6), RangeMetric::Angle),
            (Some(0.3), RangeMetric::OneMinusDot),
            (None, RangeMetric::Angle),
        ] {
            for sc in [Some(0.2), None] {
                let spec = Spec {
                    sigma_spatial: 2.0,
                    radius: 4,
                    sigma_color: sc,
                    sigma_normal: sn,
                    metric,
                    filter_color: true,
                };
                let outs = [Twin::Widest, Twin::Avx2, Twin::Portable]
                    .map(|t| filter_with(&input, &spec, t));
                for o in &outs[1..] {
                    let planes = o.normal.iter().chain(o.color.as_ref().unwrap());
                    let base = outs[0].normal.iter().chain(outs[0].color.as_ref().unwrap());
                    for (a, b) in planes.zip(base) {
                        let d = a
                            .iter()
                            .zip(b)
                            .map(|(x, y)| (x - y).abs())
                            .fold(0.0, f32::max);
                        assert!(d <= 2e-6, "{sn:?} {metric:?} {sc:?}: {d}");
                    }
                }
            }
        }
    }
}
