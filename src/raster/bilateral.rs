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
//! - **each pair once**: the weight is symmetric, `w(P, Q) = w(Q, P)`, so the disc kernel
//!   ([`Kernel::tile_sym`]) evaluates it for the half disc only and adds it to both ends —
//!   about 0.55× the exponentials at [`SYM_TILE_H`]-row tiles, halo pairs included;
//! - all three factors in one exponential, `2^−(a + b + c)` with the constants folded in, by a
//!   branch-free `exp2` (3e-7 relative) with fused multiply-adds;
//! - the angle without a square root: `δ² = acos(1 − t)² = t·G(t)` with `t = 1 − n·n′` and `G`
//!   a degree-6 polynomial (8e-7 relative) where σ_n makes every pixel beyond 90° weigh
//!   < 1e-8 (σ_n ≤ 0.259 rad); beyond that, `acos` by Abramowitz & Stegun 4.4.46 (2e-8);
//! - tiles copied with their halo into padded local planes a fixed, not-power-of-two stride
//!   apart (one pointer and immediate offsets per tap, no cache-set aliasing). Border, masked
//!   and non-finite pixels get validity 0 — and, when colour is in the range, a colour
//!   (`FAR_COLOR`) so far from any other that their weight is the `exp2` floor 2^−126, which
//!   saves the validity load and multiply. The tap loop has no branches and the working set
//!   stays in L2;
//! - [`LANES`] output pixels of a row per step, each tap one contiguous load per plane: the
//!   compiler vectorises the lane loop (AVX-512 or AVX2 twins with FMA chosen at run time; a
//!   portable twin without FMA, compared with them in the tests).
//!
//! Discs wider than `SYM_MAX_RADIUS` take one weight per tap ([`Kernel::tile`]). With a
//! `stride` s > 1 the disc is sampled on the grid `s·(i, j)`: the wide-σ approximation of
//! [`crate::ops::bilateral`] (a constant number of taps whatever σ_s).
//!
//! Its agreement with a brute-force `f64` evaluation of the formula above (true `exp` and
//! `acos`) is tested in `ops::bilateral` to 1e-5.

use super::fastmath::{exp2_neg, madd};
use super::gradient::{normal_of_gradient, NZ_EPSILON};
use crate::raster::buf;
use rayon::prelude::*;

/// Output pixels of one row computed together (the vector width of the lane loop).
pub const LANES: usize = 16;
/// Rows of a tile (one rayon task computes a band of this many rows).
pub const TILE_H: usize = 16;
/// Columns of a tile.
pub const TILE_W: usize = 256;
/// Rows of a tile of the symmetric (disc) kernel: taller, so the halo rows whose pairs are
/// computed for nothing are fewer.
pub const SYM_TILE_H: usize = 64;
/// Largest radius run by the symmetric kernel (its planes must fit in [`STRIDE`]); wider discs
/// take one weight per tap.
const SYM_MAX_RADIUS: usize = 32;

/// The half disc `{(dx, dy) : dx² + dy² ≤ r², dy > 0 or (dy = 0 and dx > 0)}`.
fn taps_half(r: usize) -> impl Iterator<Item = (isize, isize)> {
    let r = r as isize;
    (0..=r)
        .flat_map(move |dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(move |&(dx, dy)| dx * dx + dy * dy <= r * r && (dy > 0 || dx > 0))
}

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
    /// Window radius in pixels: the disc `dx² + dy² ≤ r²`.
    pub radius: usize,
    /// Tap spacing in pixels: 1 is every pixel of the window; `s > 1` samples the disc on the
    /// grid `s·(i, j)` (the wide-σ approximation: (2r/s + 1)²-ish taps whatever σ).
    pub stride: usize,
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
/// The accumulator planes of the symmetric tile (Σwp, Σwq, Σw, Σwc₀, Σwc₁, Σwc₂) start here.
const ACC: usize = PLANES;
const ACCS: usize = 6;
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
    let band = kernel.tile_h * w;
    let nb = h.div_ceil(kernel.tile_h);
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
    // Cancelled: the remaining bands are skipped and the caller discards the output.
    let cancel = crate::cancel::Cancel::current();
    bands.into_par_iter().with_min_len(leaf).for_each_init(
        || vec![0.0f32; kernel.scratch_len()],
        |scratch, (b, (((x, y), z), c))| {
            if cancel.is_cancelled() {
                return;
            }
            let mut out = BandOut { n: [x, y, z], c };
            kernel.band(input, b * kernel.tile_h, &mut out, scratch);
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

/// Calls `$self.$method::<COL, NRM, FC, F>(args)` with the kernel's flags as constants.
macro_rules! dispatch {
    ($self:ident, $method:ident, $f:ident, $($arg:expr),*) => {
        match ($self.col, $self.nrm, $self.fc) {
            (false, NRM_NONE, false) => $self.$method::<false, NRM_NONE, false, $f>($($arg),*),
            (false, NRM_NONE, true) => $self.$method::<false, NRM_NONE, true, $f>($($arg),*),
            (false, NRM_ANGLE, false) => $self.$method::<false, NRM_ANGLE, false, $f>($($arg),*),
            (false, NRM_ANGLE, true) => $self.$method::<false, NRM_ANGLE, true, $f>($($arg),*),
            (false, NRM_ANGLE_NARROW, false) => {
                $self.$method::<false, NRM_ANGLE_NARROW, false, $f>($($arg),*)
            }
            (false, NRM_ANGLE_NARROW, true) => {
                $self.$method::<false, NRM_ANGLE_NARROW, true, $f>($($arg),*)
            }
            (false, _, false) => $self.$method::<false, NRM_DOT, false, $f>($($arg),*),
            (false, _, true) => $self.$method::<false, NRM_DOT, true, $f>($($arg),*),
            (true, NRM_NONE, false) => $self.$method::<true, NRM_NONE, false, $f>($($arg),*),
            (true, NRM_NONE, true) => $self.$method::<true, NRM_NONE, true, $f>($($arg),*),
            (true, NRM_ANGLE, false) => $self.$method::<true, NRM_ANGLE, false, $f>($($arg),*),
            (true, NRM_ANGLE, true) => $self.$method::<true, NRM_ANGLE, true, $f>($($arg),*),
            (true, NRM_ANGLE_NARROW, false) => {
                $self.$method::<true, NRM_ANGLE_NARROW, false, $f>($($arg),*)
            }
            (true, NRM_ANGLE_NARROW, true) => {
                $self.$method::<true, NRM_ANGLE_NARROW, true, $f>($($arg),*)
            }
            (true, _, false) => $self.$method::<true, NRM_DOT, false, $f>($($arg),*),
            (true, _, true) => $self.$method::<true, NRM_DOT, true, $f>($($arg),*),
        }
    };
}

/// The filter with its constants folded (exponents in base 2).
struct Kernel {
    /// Halo widths: columns left and right, rows above and below.
    rx: usize,
    ry: usize,
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
    /// Symmetric pairs ([`Kernel::tile_sym`]) or one weight per tap (discs wider than
    /// `SYM_MAX_RADIUS`).
    sym: bool,
    /// Rows of a tile (and of a band).
    tile_h: usize,
    /// The half disc of [`Kernel::tile_sym`]: `(offset, spatial exponent)`, `dy` varying
    /// fastest so consecutive taps touch different rows of the accumulators.
    half_taps: Vec<(isize, f32)>,
}

impl Kernel {
    fn new(spec: &Spec) -> Self {
        let r = spec.radius;
        let sym = r <= SYM_MAX_RADIUS;
        let (rx, ry) = if sym { (2 * r, r) } else { (r, r) };
        let tile_h = if sym { SYM_TILE_H } else { TILE_H };
        let slack = if sym { LANES } else { 0 };
        let lh = tile_h + 2 * ry;
        // The widest tile (≤ TILE_W, a multiple of LANES) whose halo'd planes fit in STRIDE.
        let tile_w = TILE_W
            .min((STRIDE / lh).saturating_sub(2 * rx + slack) / LANES * LANES)
            .max(LANES);
        let lw = tile_w + 2 * rx + slack;
        debug_assert!(
            lw * lh <= STRIDE,
            "radius {r} too large for the local planes"
        );
        let log2e = std::f32::consts::LOG2_E;
        let ks = log2e / (2.0 * spec.sigma_spatial * spec.sigma_spatial);
        let (ri, rxi, ryi) = (r as isize, rx as isize, ry as isize);
        let st = spec.stride.max(1) as isize;
        let mut taps = Vec::new();
        for dy in -ryi..=ryi {
            for dx in -rxi..=rxi {
                let d2 = dx * dx + dy * dy;
                if d2 <= ri * ri && dx % st == 0 && dy % st == 0 {
                    taps.push((dy * lw as isize + dx, d2 as f32 * ks));
                }
            }
        }
        let st = spec.stride.max(1) as isize;
        let mut half: Vec<(isize, isize, f32)> = taps_half(r / spec.stride.max(1))
            .map(|(dx, dy)| (dx * st, dy * st))
            .map(|(dx, dy)| (dx, dy, (dx * dx + dy * dy) as f32 * ks))
            .collect();
        half.sort_by_key(|&(dx, dy, _)| (dx, dy));
        let half_taps = half
            .into_iter()
            .map(|(dx, dy, st)| (dy * lw as isize + dx, st))
            .collect();
        let k = |s: Option<f32>| s.map_or(0.0, |s| log2e / (2.0 * s * s));
        Self {
            rx,
            ry,
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
            sym,
            tile_h,
            half_taps,
        }
    }

    fn scratch_len(&self) -> usize {
        let planes = if self.sym { ACC + ACCS } else { PLANES };
        (planes - 1) * STRIDE + self.lw * self.lh
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
            if self.sym {
                dispatch!(self, tile_sym, F, input, at, s, out);
            } else {
                dispatch!(self, tile, F, input, at, s, out);
            }
            x0 += self.tile_w;
        }
    }

    /// Copies the tile at `(x0, r0)` with its halo into the local planes: pixels outside the
    /// image, masked out (< ½) or not finite get validity 0, finite values (0 where not
    /// finite) and the colour `FAR_COLOR`.
    #[inline(always)]
    fn fill(&self, input: &Input<'_>, r0: usize, x0: usize, s: &mut [f32]) {
        let (w, h, lw) = (input.width, input.height, self.lw);
        let (rx, ry) = (self.rx, self.ry);
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
        // Local columns lc ↔ image columns x0 + lc − rx, clipped to the image.
        let lc0 = rx.saturating_sub(x0);
        let lc1 = (w + rx - x0).min(lw);
        for lr in 0..self.lh {
            let row = lr * lw;
            let Some(y) = (r0 + lr).checked_sub(ry).filter(|&y| y < h) else {
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
            let i0 = y * w + x0 + lc0 - rx;
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
            let n = lc1 - lc0;
            let (pp, qq, vv) = (&mut pp[..n], &mut qq[..n], &mut vv[..n]);
            // Separate simple loops, so each vectorises.
            for c in 0..n {
                let inv = 1.0 / nz[c].max(NZ_EPSILON);
                pp[c] = -nx[c] * inv;
                qq[c] = -ny[c] * inv;
            }
            for c in 0..n {
                // x · 0 is 0 for finite x and NaN otherwise: one test for the eight values.
                let z = 0.0 * nx[c]
                    + 0.0 * ny[c]
                    + 0.0 * nz[c]
                    + 0.0 * k0[c]
                    + 0.0 * k1[c]
                    + 0.0 * k2[c]
                    + 0.0 * pp[c]
                    + 0.0 * qq[c];
                vv[c] = if z == 0.0 { 1.0 } else { 0.0 };
            }
            let all_finite = vv.iter().all(|&v| v > 0.0);
            if let Some(m) = mask {
                for c in 0..n {
                    vv[c] = if m[c] >= 0.5 { vv[c] } else { 0.0 };
                }
            }
            let all_valid = vv.iter().all(|&v| v > 0.0);
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

    /// The weight of the pair `(a, b)` (normal then colour of each) whose spatial exponent is
    /// `st`; `valid` is b's validity (used without colour: with colour an invalid pixel's
    /// FAR_COLOR already makes its weight 2^−126).
    #[inline(always)]
    fn weight<const COL: bool, const NRM: u8, const F: bool>(
        &self,
        st: f32,
        a: [f32; 6],
        b: [f32; 6],
        valid: f32,
    ) -> f32 {
        let mut e = st;
        if COL {
            let (d0, d1, d2) = (b[3] - a[3], b[4] - a[4], b[5] - a[5]);
            let d = madd::<F>(d2, d2, madd::<F>(d1, d1, d0 * d0));
            e = madd::<F>(self.kc, d, e);
        }
        if NRM != NRM_NONE {
            let dot = madd::<F>(b[2], a[2], madd::<F>(b[1], a[1], b[0] * a[0]));
            let t = (1.0 - dot).max(0.0);
            let d2 = match NRM {
                NRM_ANGLE_NARROW => acos_one_minus_sq_narrow::<F>(t.min(1.0)),
                NRM_ANGLE => {
                    let d = acos_one_minus::<F>(t.min(2.0));
                    d * d
                }
                _ => t * t,
            };
            e = madd::<F>(self.kn, d2, e);
        }
        if COL {
            exp2_neg::<F>(e)
        } else {
            valid * exp2_neg::<F>(e)
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
        let (w, lw) = (input.width, self.lw);
        // The LANES values of plane k at local index j.
        let at = |k: usize, j: usize| -> &[f32; LANES] { lanes(&s[k * STRIDE..], j) };
        for ty in 0..rows {
            for tx in (0..tw).step_by(LANES) {
                let base = (ty + self.ry) * lw + tx + self.rx;
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
                        let wt = self.weight::<COL, NRM, F>(
                            st,
                            [cnx[l], cny[l], cnz[l], cc0[l], cc1[l], cc2[l]],
                            [vx[l], vy[l], vz[l], v0[l], v1[l], v2[l]],
                            vm[l],
                        );
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
                    let sums = [ap[l], aq[l], aw[l], ac[0][l], ac[1][l], ac[2][l]];
                    emit(
                        input,
                        out,
                        o + l,
                        (r0 + ty) * w + x0 + tx + l,
                        cv[l] > 0.0,
                        sums,
                    );
                }
            }
        }
    }

    /// [`Self::tile`] with each pair's weight computed once (it is symmetric: w(P, Q) =
    /// w(Q, P)) and added to both ends: P runs over the output pixels and the halo pixels above
    /// and beside them, Q = P + o over the half disc (`dy > 0`, or `dy = 0 < dx`); P's sums
    /// stay in registers, Q's go to accumulator planes. About 0.55× the exponentials of the
    /// full disc at 64-row tiles. Needs `rx = 2r`, `ry = r` and the accumulator planes.
    #[inline(always)]
    fn tile_sym<const COL: bool, const NRM: u8, const FC: bool, const F: bool>(
        &self,
        input: &Input<'_>,
        at: TileAt,
        s: &mut [f32],
        out: &mut BandOut<'_>,
    ) {
        let TileAt { r0, x0, tw, rows } = at;
        let (w, lw, r) = (input.width, self.lw, self.ry);
        let span = lw * self.lh;
        let (vals, accs) = s.split_at_mut(ACC * STRIDE);
        for k in 0..ACCS {
            accs[k * STRIDE..k * STRIDE + span].fill(0.0);
        }
        // P columns: the output's (from rx = 2r) and r on each side, in whole lane groups.
        let groups = (tw + 2 * r).div_ceil(LANES);
        for lr in 0..r + rows {
            for g in 0..groups {
                let base = lr * lw + r + g * LANES;
                let c = |k: usize| -> [f32; LANES] { *lanes(&vals[k * STRIDE..], base) };
                let (cnx, cny, cnz) = (c(NX), c(NY), c(NZ));
                let (cc0, cc1, cc2) = (c(C0), c(C0 + 1), c(C0 + 2));
                let cval = c(VALID);
                let (gp, gq) = (c(P), c(Q));
                // P's own sums start with itself (weight 1 when valid).
                let own =
                    |v: &[f32; LANES]| -> [f32; LANES] { std::array::from_fn(|l| cval[l] * v[l]) };
                let (mut mp, mut mq, mut mw) = (own(&gp), own(&gq), cval);
                let (mut m0, mut m1, mut m2) = (own(&cc0), own(&cc1), own(&cc2));
                for &(off, st) in &self.half_taps {
                    let j = base.wrapping_add_signed(off);
                    let blk = &vals[j..j + (PLANES - 1) * STRIDE + LANES];
                    let at = |k: usize| -> &[f32; LANES] { lanes(blk, k * STRIDE) };
                    let (vx, vy, vz) = (at(NX), at(NY), at(NZ));
                    let (v0, v1, v2) = (at(C0), at(C0 + 1), at(C0 + 2));
                    let (vp, vq, vm) = (at(P), at(Q), at(VALID));
                    let mut wt = [0.0f32; LANES];
                    for l in 0..LANES {
                        wt[l] = self.weight::<COL, NRM, F>(
                            st,
                            [cnx[l], cny[l], cnz[l], cc0[l], cc1[l], cc2[l]],
                            [vx[l], vy[l], vz[l], v0[l], v1[l], v2[l]],
                            vm[l],
                        );
                        if !COL {
                            wt[l] *= cval[l];
                        }
                        mp[l] = madd::<F>(wt[l], vp[l], mp[l]);
                        mq[l] = madd::<F>(wt[l], vq[l], mq[l]);
                        mw[l] += wt[l];
                        if FC {
                            m0[l] = madd::<F>(wt[l], v0[l], m0[l]);
                            m1[l] = madd::<F>(wt[l], v1[l], m1[l]);
                            m2[l] = madd::<F>(wt[l], v2[l], m2[l]);
                        }
                    }
                    // Q's sums, in the accumulator planes.
                    let ablk = &mut accs[j..j + (ACCS - 1) * STRIDE + LANES];
                    add_into::<F>(ablk, 0, &wt, &gp);
                    add_into::<F>(ablk, STRIDE, &wt, &gq);
                    add_into::<F>(ablk, 2 * STRIDE, &wt, &[1.0; LANES]);
                    if FC {
                        add_into::<F>(ablk, 3 * STRIDE, &wt, &cc0);
                        add_into::<F>(ablk, 4 * STRIDE, &wt, &cc1);
                        add_into::<F>(ablk, 5 * STRIDE, &wt, &cc2);
                    }
                }
                let ablk = &mut accs[base..base + (ACCS - 1) * STRIDE + LANES];
                let one = [1.0; LANES];
                add_into::<F>(ablk, 0, &one, &mp);
                add_into::<F>(ablk, STRIDE, &one, &mq);
                add_into::<F>(ablk, 2 * STRIDE, &one, &mw);
                if FC {
                    add_into::<F>(ablk, 3 * STRIDE, &one, &m0);
                    add_into::<F>(ablk, 4 * STRIDE, &one, &m1);
                    add_into::<F>(ablk, 5 * STRIDE, &one, &m2);
                }
            }
        }
        // Row by row, branch-free (it vectorises): the normal of the mean gradient and the
        // mean colour where the centre is valid, else the input.
        for ty in 0..rows {
            let j = (ty + r) * lw + self.rx;
            let acc = |k: usize| &accs[k * STRIDE + j..k * STRIDE + j + tw];
            let (sp, sq, sw) = (acc(0), acc(1), acc(2));
            let valid = &vals[VALID * STRIDE + j..VALID * STRIDE + j + tw];
            let (o, g) = (ty * w + x0, (r0 + ty) * w + x0);
            let [ox, oy, oz] = out.n.each_mut().map(|p| &mut p[o..o + tw]);
            let [ix, iy, iz] = input.normal.map(|p| &p[g..g + tw]);
            for x in 0..tw {
                let inv = 1.0 / sw[x];
                let (p, q) = (sp[x] * inv, sq[x] * inv);
                let l = 1.0 / madd::<F>(q, q, madd::<F>(p, p, 1.0)).sqrt();
                let ok = valid[x] > 0.0;
                ox[x] = if ok { -p * l } else { ix[x] };
                oy[x] = if ok { -q * l } else { iy[x] };
                oz[x] = if ok { l } else { iz[x] };
            }
            if let Some(c) = out.c.as_mut() {
                for (k, (oc, ic)) in c.iter_mut().zip(&input.color).enumerate() {
                    let (oc, ic, sc) = (&mut oc[o..o + tw], &ic[g..g + tw], acc(3 + k));
                    for x in 0..tw {
                        oc[x] = if valid[x] > 0.0 { sc[x] / sw[x] } else { ic[x] };
                    }
                }
            }
        }
    }
}

/// `d[off + l] += w[l] · v[l]` for the LANES lanes.
#[inline(always)]
fn add_into<const F: bool>(d: &mut [f32], off: usize, w: &[f32; LANES], v: &[f32; LANES]) {
    let d: &mut [f32; LANES] = (&mut d[off..off + LANES]).try_into().expect("LANES values");
    for l in 0..LANES {
        d[l] = madd::<F>(w[l], v[l], d[l]);
    }
}

/// Writes output pixel `i` of the band (image pixel `g`): the normal of the mean gradient and
/// the mean colour from `sums` = (Σwp, Σwq, Σw, Σwc₀, Σwc₁, Σwc₂) when `valid`, else the input.
#[inline(always)]
fn emit(input: &Input<'_>, out: &mut BandOut<'_>, i: usize, g: usize, valid: bool, sums: [f32; 6]) {
    if valid {
        let inv = 1.0 / sums[2];
        let nrm = normal_of_gradient(sums[0] * inv, sums[1] * inv);
        for (o, v) in out.n.iter_mut().zip(nrm) {
            o[i] = v;
        }
        if let Some(c) = out.c.as_mut() {
            for (o, a) in c.iter_mut().zip(&sums[3..]) {
                o[i] = a * inv;
            }
        }
    } else {
        // Masked out or not finite: the input, unchanged.
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
                    stride: 1,
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
