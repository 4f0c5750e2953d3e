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
//! with `(p, q) = (−n_x/n_z, −n_y/n_z)` ([`gradient_of_normal`](crate::raster::gradient::gradient_of_normal), `n_z` clamped as everywhere) and
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
//!   (`Kernel::tile_sym`) evaluates it for the half disc only and adds it to both ends —
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
//! - a vector of output pixels of a row per step, each tap one contiguous load per plane, the
//!   kernel written once over a vector type (`vector::Vf`) and compiled as three twins
//!   ([`crate::raster::simd`]): AVX-512 (16 lanes, the array form the compiler vectorises),
//!   AVX2 (8 lanes in intrinsics: the array form spilled its 16 registers), both with FMA, and
//!   a portable one (8 lanes, no FMA). [`Simd::active`] picks one (`RGBN_SIMD` forces it); the
//!   tests compare every twin the CPU runs with the portable one, to [`TWIN_TOLERANCE`].
//!
//! Discs wider than `SYM_MAX_RADIUS` take one weight per tap (`Kernel::tile`). With a
//! `stride` s > 1 the disc is sampled on the grid `s·(i, j)`: the wide-σ approximation of
//! [`crate::ops::bilateral`] (a constant number of taps whatever σ_s).
//!
//! Its agreement with a brute-force `f64` evaluation of the formula above (true `exp` and
//! `acos`) is tested in `ops::bilateral` to 1e-5.

mod tile;
mod vector;

use super::gradient::NZ_EPSILON;
use super::simd::Simd;
use crate::raster::buf;
use rayon::prelude::*;
use tile::NARROW_G;
#[cfg(target_arch = "x86_64")]
use vector::Avx2;
use vector::{Lanes, Vf};

/// Output pixels of one row computed together (the vector width of the lane loop).
pub const LANES: usize = 16;
/// How far the output of a twin with fused multiply-adds may be from the portable twin's
/// (absolute, on unit normals and colours in [0, 1]): they differ by rounding only.
pub const TWIN_TOLERANCE: f32 = 2e-6;
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
/// The widest vector ([`Lanes`] of the AVX-512 twin).
const MAX_L: usize = 16;
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

/// The bilateral-filtered normals (and colours) of `input` (module docs).
///
/// # Panics
/// If a plane's length is not `width × height`.
#[must_use]
pub fn filter(input: &Input<'_>, spec: &Spec) -> Output {
    filter_with(input, spec, Simd::active())
}

/// [`filter`] by the twin of `simd` (clamped to what this CPU runs: [`Simd::clamped`]).
///
/// # Panics
/// As [`filter`].
#[must_use]
pub fn filter_with(input: &Input<'_>, spec: &Spec, simd: Simd) -> Output {
    let (w, h) = (input.width, input.height);
    let n = w * h;
    for p in input.normal.iter().chain(&input.color) {
        assert_eq!(p.len(), n, "plane size");
    }
    if let Some(m) = input.mask {
        assert_eq!(m.len(), n, "mask size");
    }
    let kernel = Kernel {
        simd: simd.clamped(),
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
    let need = kernel.scratch_len();
    // Cancelled: the remaining bands are skipped and the caller discards the output.
    let cancel = crate::cancel::Cancel::current();
    bands.into_par_iter().for_each(|(b, (((x, y), z), c))| {
        if cancel.is_cancelled() {
            return;
        }
        SCRATCH.with_borrow_mut(|scratch| {
            if scratch.len() < need {
                *scratch = vec![0.0f32; need];
            }
            let mut out = BandOut { n: [x, y, z], c };
            kernel.band(input, b * kernel.tile_h, &mut out, &mut scratch[..need]);
        });
    });
    Output {
        normal: out_n,
        color: out_c,
    }
}

thread_local! {
    /// Each thread's local planes, kept from call to call: allocating them per call (7 MB,
    /// most of it never touched) cost a zero-fill, and a freed block of another size made the
    /// allocator ([`crate::recycle`]) drop the output planes it kept for the next call. Every
    /// value read is written first in the same tile ([`Kernel::fill`], the accumulators'
    /// clearing), so what an earlier call left does not matter.
    static SCRATCH: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
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
    ($self:ident, $method:ident, $v:ident, $f:ident, $($arg:expr),*) => {
        match ($self.col, $self.nrm, $self.fc) {
            (false, NRM_NONE, false) => $self.$method::<$v, false, NRM_NONE, false, $f>($($arg),*),
            (false, NRM_NONE, true) => $self.$method::<$v, false, NRM_NONE, true, $f>($($arg),*),
            (false, NRM_ANGLE, false) => $self.$method::<$v, false, NRM_ANGLE, false, $f>($($arg),*),
            (false, NRM_ANGLE, true) => $self.$method::<$v, false, NRM_ANGLE, true, $f>($($arg),*),
            (false, NRM_ANGLE_NARROW, false) => {
                $self.$method::<$v, false, NRM_ANGLE_NARROW, false, $f>($($arg),*)
            }
            (false, NRM_ANGLE_NARROW, true) => {
                $self.$method::<$v, false, NRM_ANGLE_NARROW, true, $f>($($arg),*)
            }
            (false, _, false) => $self.$method::<$v, false, NRM_DOT, false, $f>($($arg),*),
            (false, _, true) => $self.$method::<$v, false, NRM_DOT, true, $f>($($arg),*),
            (true, NRM_NONE, false) => $self.$method::<$v, true, NRM_NONE, false, $f>($($arg),*),
            (true, NRM_NONE, true) => $self.$method::<$v, true, NRM_NONE, true, $f>($($arg),*),
            (true, NRM_ANGLE, false) => $self.$method::<$v, true, NRM_ANGLE, false, $f>($($arg),*),
            (true, NRM_ANGLE, true) => $self.$method::<$v, true, NRM_ANGLE, true, $f>($($arg),*),
            (true, NRM_ANGLE_NARROW, false) => {
                $self.$method::<$v, true, NRM_ANGLE_NARROW, false, $f>($($arg),*)
            }
            (true, NRM_ANGLE_NARROW, true) => {
                $self.$method::<$v, true, NRM_ANGLE_NARROW, true, $f>($($arg),*)
            }
            (true, _, false) => $self.$method::<$v, true, NRM_DOT, false, $f>($($arg),*),
            (true, _, true) => $self.$method::<$v, true, NRM_DOT, true, $f>($($arg),*),
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
    /// `kn · gᵢ`: the narrow angle's polynomial with `kn` folded in.
    hn: [f32; 7],
    col: bool,
    nrm: u8,
    fc: bool,
    /// The twin that runs (supported by this CPU).
    simd: Simd,
    /// Symmetric pairs ([`Kernel::tile_sym`]) or one weight per tap (discs wider than
    /// `SYM_MAX_RADIUS`).
    sym: bool,
    /// Rows of a tile (and of a band).
    tile_h: usize,
    /// The half disc of [`Kernel::tile_sym`]: `(offset, spatial exponent)`, `dy` varying
    /// fastest so consecutive taps touch different rows of the accumulators.
    half_taps: Vec<(isize, f32)>,
    /// The tap after each of `half_taps` (the last one again after the last).
    half_next: Vec<(isize, f32)>,
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
        let half_taps: Vec<(isize, f32)> = half
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
            hn: NARROW_G.map(|g| g * k(spec.sigma_normal)),
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
            simd: Simd::Portable,
            sym,
            tile_h,
            half_next: half_taps
                .iter()
                .skip(1)
                .chain(half_taps.last())
                .copied()
                .collect(),
            half_taps,
        }
    }

    fn scratch_len(&self) -> usize {
        let planes = if self.sym { ACC + ACCS } else { PLANES };
        (planes - 1) * STRIDE + self.lw * self.lh
    }

    /// Rows `r0..r0 + TILE_H` (clipped), tile by tile, by the twin of `self.simd`.
    fn band(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, scratch: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: `self.simd` is clamped to what this CPU runs (`filter_with`): AVX-512F,
            // AVX2 and FMA are present.
            Simd::Avx512 => return unsafe { self.band_avx512(input, r0, out, scratch) },
            // SAFETY: as above, AVX2 and FMA are present.
            Simd::Avx2 => return unsafe { self.band_avx2(input, r0, out, scratch) },
            Simd::Portable => {}
        }
        self.band_portable(input, r0, out, scratch);
    }

    /// The AVX-512 twin: the array form of 16 lanes (one register), fused multiply-adds.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn band_avx512(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, s: &mut [f32]) {
        self.band_with::<Lanes<16>, true>(input, r0, out, s);
    }

    /// The AVX2 twin: 8 lanes in intrinsics ([`Avx2`]), fused multiply-adds.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn band_avx2(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, s: &mut [f32]) {
        self.band_with::<Avx2, true>(input, r0, out, s);
    }

    /// The portable twin: the array form of 8 lanes, no fused multiply-add.
    #[inline(always)]
    fn band_portable(&self, input: &Input<'_>, r0: usize, out: &mut BandOut<'_>, s: &mut [f32]) {
        self.band_with::<Lanes<8>, false>(input, r0, out, s);
    }

    /// The band, with fused multiply-adds when `F`.
    #[inline(always)]
    fn band_with<V: Vf, const F: bool>(
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
                dispatch!(self, tile_sym, V, F, input, at, s, out);
            } else {
                dispatch!(self, tile, V, F, input, at, s, out);
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
                    // Selects, not conditional stores (masked stores are slow on AMD).
                    let far = vv[c] == 0.0;
                    d0[c] = if far { FAR_COLOR } else { d0[c] };
                    d1[c] = if far { FAR_COLOR } else { d1[c] };
                    d2[c] = if far { FAR_COLOR } else { d2[c] };
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
}

#[cfg(test)]
mod tests;
