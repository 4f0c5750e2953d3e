//! RTI files with hemispherical harmonics (`.rti`, "HSH": RTIBuilder's fitter, read by
//! RTIViewer, relight and OpenLIME): reading one as an RGBN image, and a writer used by tests
//! and tools.
//!
//! # File layout
//!
//! Text header lines ending in `\n` (RTIBuilder writes `\r\n`), then raw bytes:
//!
//! ```text
//! #HSH1.2                 any number of comment lines starting with '#'
//! 3                       RTI type: 3 = hemispherical harmonics
//! 320 470 3               width, height, bands
//! 9 2 1                   terms, colour layout, bytes per coefficient
//! <terms f32 scales> <terms f32 biases>        little-endian
//! <coefficient bytes>
//! ```
//!
//! - **Terms**: `order²` — 4 (order 2), 9 (order 3) or 16 (order 4).
//! - **Coefficient** `t` of a byte `c`: `c / 255 · scale_t + bias_t`; one scale and bias per
//!   term, shared by all pixels and bands. The value of a band under a light `l` is
//!   `Σ_t coef_t · H_t(l)`, in 0..1 units of the 8-bit photos (RTIViewer clamps it to [0, 1]
//!   and multiplies by 255).
//! - **Colour layouts** (the second field of the terms line):
//!   - `2`, **RGB** (what RTIBuilder writes): per pixel, `bands = 3` groups of `terms` bytes —
//!     all red terms, then green, then blue.
//!   - `1`, **LRGB**: per pixel, `terms` bytes of one luminance function, then the pixel's
//!     `R, G, B` bytes (the layout of a PTM_1.1 LRGB pixel; relight's universal writer numbers
//!     LRGB 1 and RGB 2). The value of a channel is `L(l) · C / 255` as in an LRGB PTM.
//! - **Rows are stored bottom-up** (the first row in the file is the bottom of the image), as
//!   in a PTM; `x` right, `y` up, like rgbn's normal frame: no axis is flipped.
//! - **Basis**: hemispherical harmonics (Gautron, Křivánek, Pattanaik & Bouatouch 2004), the
//!   associated Legendre functions of `2 cos θ − 1` over the upper hemisphere, with the light
//!   `l = (sin θ cos φ, sin θ sin φ, cos θ)` in the image frame; the term order and signs are
//!   RTIViewer's ([`hsh_basis`] writes them out).
//!
//! Sources read for the layout (no code copied): RTIViewer's HSH loader as distributed in
//! public mirrors (header lines, scale/bias arrays of `terms` floats, per-pixel band-major
//! bytes, `c/255 · scale + bias`), relight's `legacy_rti.cpp` (the bottom-up row order of
//! `.rti` data, colour-layout numbers 1 = LRGB, 2 = RGB), and joncooper/rti's `rti.coffee`
//! (the basis functions up to order 4). Real RTIBuilder files (`#HSH1.2`, `9 2 1`, 320 × 470)
//! were checked to have exactly the size this layout implies.
//!
//! # What rgbn makes of an HSH
//!
//! - **Normal**: the normal of the Lambertian lobe fitted to the pixel's reflectance function.
//!   The luminance (the mean of the three bands, or the LRGB luminance), sRGB-decoded to linear
//!   light, is evaluated at virtual lights — a grid of step 0.05 in `(l_x, l_y)` above 10° of
//!   elevation (about 1200 directions) — and `b = ρ n` is its least-squares fit `y ≈ b · l`,
//!   first over the lights brighter than 5 % of the brightest, then twice over the lights with
//!   `n · l ≥ 0.5` for the current estimate (the lit side: the model's `max(0, ·)` is inactive
//!   there, and a low-order fit rounds off the terminator). Photometric stereo on the fitted
//!   function, in short. The direction of the function's *maximum*, which RTIViewer-style
//!   readers of PTMs use, is biased for HSH: a low-order fit of a clamped cosine peaks before
//!   the pole (12.9° mean error on the test sphere, order 3); the lobe fit reads it at 1.4°
//!   mean over the whole visible hemisphere and 0.9° where the tilt is at most 60°. What is
//!   left is a radial bias near the horizon, which `TiltCorrection` removes by simulation
//!   (a Lambertian pixel under a model dome, fitted and read the same way): on the test sphere
//!   (a dome of rings at 15°–75°, not the model dome) 0.90° mean at order 3 and 0.66° at
//!   order 4 over the whole visible hemisphere, 1.85° at order 2.
//!   A black pixel (brightest value under three 8-bit levels, sRGB-encoded: the noise of the
//!   coefficients' quantisation) or a fit facing away gets mask 0 and normal
//!   `(0, 0, 1)`, as a PTM pixel without a maximum.
//! - **Colour**: RGB: each band's function at `l = n` (for a diffuse surface the albedo,
//!   free of shading), clamped to [0, 1]; LRGB: the stored bytes. Both sRGB-encoded, converted
//!   to rgbn's linear light.
//!
//! Not read (a one-line error naming what): other RTI types (PTM-basis, RBF, spherical
//! harmonics, DMD), bands other than 3 with RGB, more than one byte per coefficient, and the
//! multi-view `.mview` / web formats.
//!
//! # References
//!
//! - P. Gautron, J. Křivánek, S. Pattanaik, K. Bouatouch, "A Novel Hemispherical Basis for
//!   Accurate and Efficient Rendering", Eurographics Symposium on Rendering 2004.
//! - M. Mudge, T. Malzbender, C. Schroer, M. Lum, "New Reflection Transformation Imaging
//!   Methods for Rock Art and Multiple-Viewpoint Display", VAST 2006 (HSH in RTI).

use super::ptm::{image_from_pixels, srgb8_to_linear};
use super::{check_size, RgbnImage};
use crate::error::RgbnError;
use crate::raster::io::write_atomic;
use crate::raster::srgb::{linear_to_srgb, srgb_to_linear};
use rayon::prelude::*;
use std::io::{BufRead, Read, Write};
use std::path::Path;

/// Most terms of a supported basis (order 4).
pub const MAX_TERMS: usize = 16;

/// The colour layout of an HSH file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HshLayout {
    /// One function per colour channel (RTIBuilder's layout, number 2).
    Rgb,
    /// One luminance function plus 8-bit `R, G, B` per pixel (number 1).
    Lrgb,
}

impl HshLayout {
    fn number(self) -> u32 {
        match self {
            Self::Lrgb => 1,
            Self::Rgb => 2,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Self::Lrgb => "LRGB",
            Self::Rgb => "RGB",
        }
    }
    /// Bytes per pixel for `terms` terms.
    fn bytes_per_pixel(self, terms: usize) -> usize {
        match self {
            Self::Lrgb => terms + 3,
            Self::Rgb => 3 * terms,
        }
    }
}

/// An HSH `.rti` read as an RGBN image.
#[derive(Clone, Debug)]
pub struct Hsh {
    /// Colour (linear), normal at the luminance maximum, mask (0 where there is none).
    pub image: RgbnImage,
    /// The file's colour layout.
    pub layout: HshLayout,
    /// Terms per function (4, 9 or 16).
    pub terms: usize,
    /// Black pixels and fits facing away (mask 0, normal `(0, 0, 1)`).
    pub no_maximum: usize,
}

/// The hemispherical-harmonics basis at the light direction `l` (unit, `l_z ≥ 0`; a direction
/// below the horizon is evaluated at the horizon), in RTIViewer's term order: entries
/// `0..terms` are set.
#[must_use]
pub fn hsh_basis(l: [f64; 3], terms: usize) -> [f64; MAX_TERMS] {
    use std::f64::consts::PI;
    let z = l[2].clamp(0.0, 1.0);
    let phi = l[1].atan2(l[0]);
    let (s1, c1) = phi.sin_cos();
    let (s2, c2) = (2.0 * phi).sin_cos();
    let (s3, c3) = (3.0 * phi).sin_cos();
    // sqrt(z − z²) = sqrt(cos θ − cos² θ), and 2z − 1 = the shifted cos θ.
    let q = (z - z * z).max(0.0);
    let s = q.sqrt();
    let t = 2.0 * z - 1.0;
    let mut h = [0.0; MAX_TERMS];
    h[0] = 1.0 / (2.0 * PI).sqrt();
    if terms > 1 {
        h[1] = (6.0 / PI).sqrt() * c1 * s;
        h[2] = (3.0 / (2.0 * PI)).sqrt() * t;
        h[3] = (6.0 / PI).sqrt() * s1 * s;
    }
    if terms > 4 {
        let k = (30.0 / PI).sqrt();
        h[4] = k * c2 * (z * z - z);
        h[5] = k * c1 * t * s;
        h[6] = (5.0 / (2.0 * PI)).sqrt() * (1.0 - 6.0 * z + 6.0 * z * z);
        h[7] = k * s1 * t * s;
        h[8] = k * s2 * (z * z - z);
    }
    if terms > 9 {
        let (k35, k210, k21) = (
            2.0 * (35.0 / PI).sqrt(),
            (210.0 / PI).sqrt(),
            2.0 * (21.0 / PI).sqrt(),
        );
        let p3 = 1.0 - 5.0 * z + 5.0 * z * z;
        h[9] = k35 * c3 * q * s;
        h[10] = k210 * c2 * t * (z * z - z);
        h[11] = k21 * c1 * s * p3;
        h[12] = (7.0 / (2.0 * PI)).sqrt() * (-1.0 + 12.0 * z - 30.0 * z * z + 20.0 * z * z * z);
        h[13] = k21 * s1 * s * p3;
        h[14] = k210 * s2 * t * (z * z - z);
        h[15] = k35 * s3 * q * s;
    }
    h
}

/// `Σ_t c_t H_t(l)` for the first `c.len()` terms.
#[must_use]
pub fn eval_hsh(c: &[f64], l: [f64; 3]) -> f64 {
    let h = hsh_basis(l, c.len());
    c.iter().zip(&h).map(|(a, b)| a * b).sum()
}

/// Grid step, in `(l_x, l_y)`, of the virtual lights (0.1 gives results that jump with the
/// set of lights a threshold keeps: 1.8° instead of 1.4° on the test sphere).
const GRID_STEP: f64 = 0.05;
/// Lowest elevation of a virtual light (measured: 10° reads the test sphere at 1.4° mean,
/// 20° at 2.2°).
const MIN_ELEVATION_DEG: f64 = 10.0;
/// The lobe fit's later passes keep the virtual lights with `n · l` at least this: the lit
/// side near the peak, away from the terminator a low-order fit rounds off (0.3: 3.2°,
/// 0.5: 1.4°, 0.7: 1.7°, 0.85: 3.6° mean on the test sphere).
const MIN_SHADING: f64 = 0.5;

/// sRGB-encoded `v` (clamped to [0, 1]) to linear light, by a 4097-entry table with linear
/// interpolation (within 1e-5 of the formula).
fn srgb_decode(v: f64) -> f64 {
    static LUT: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    let lut = LUT.get_or_init(|| {
        (0..=4096)
            .map(|i| f64::from(srgb_to_linear(i as f32 / 4096.0)))
            .collect()
    });
    let x = v.clamp(0.0, 1.0) * 4096.0;
    let i = (x as usize).min(4095);
    let f = x - i as f64;
    lut[i] * (1.0 - f) + lut[i + 1] * f
}

/// The virtual lights and their basis values.
struct Grid {
    dirs: Vec<[f64; 3]>,
    basis: Vec<[f64; MAX_TERMS]>,
}

impl Grid {
    fn new(terms: usize) -> Self {
        let gs = GRID_STEP;
        let k = (1.0 / gs).round() as i32;
        let zmin = MIN_ELEVATION_DEG.to_radians().sin();
        let mut dirs = Vec::new();
        for i in -k..=k {
            for j in -k..=k {
                let (u, v) = (f64::from(i) * gs, f64::from(j) * gs);
                let z2 = 1.0 - u * u - v * v;
                if z2 >= zmin * zmin {
                    dirs.push([u, v, z2.sqrt()]);
                }
            }
        }
        let basis = dirs.iter().map(|&l| hsh_basis(l, terms)).collect();
        Self { dirs, basis }
    }
}

/// Least squares `y ≈ b · l (+ c)` over the virtual lights `keep` selects: `b`, with an
/// offset `c` when `offset` (4 unknowns), by Gaussian elimination with partial pivoting.
#[allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]
fn lambert_fit(
    grid: &Grid,
    y: &[f64],
    offset: bool,
    keep: impl Fn(usize) -> bool,
) -> Option<[f64; 3]> {
    let m = if offset { 4 } else { 3 };
    let mut a = [[0.0f64; 5]; 4];
    let mut count = 0;
    for (k, l) in grid.dirs.iter().enumerate() {
        if !keep(k) {
            continue;
        }
        count += 1;
        let f = [l[0], l[1], l[2], 1.0];
        for i in 0..m {
            for j in 0..m {
                a[i][j] += f[i] * f[j];
            }
            a[i][4] += f[i] * y[k];
        }
    }
    if count < m + 2 {
        return None;
    }
    let scale = (0..m).map(|i| a[i][i]).fold(0.0, f64::max);
    for c in 0..m {
        let p = (c..m).max_by(|&x, &z| a[x][c].abs().total_cmp(&a[z][c].abs()))?;
        a.swap(c, p);
        if !(a[c][c].abs() > 1e-9 * scale) {
            return None;
        }
        for r in 0..m {
            if r != c {
                let f = a[r][c] / a[c][c];
                for k in c..5 {
                    a[r][k] -= f * a[c][k];
                }
            }
        }
    }
    let b = [a[0][4] / a[0][0], a[1][4] / a[1][1], a[2][4] / a[2][2]];
    b.iter().all(|v| v.is_finite()).then_some(b)
}

/// The normal of the Lambertian lobe fitted to a pixel's linear luminance `y` at the virtual
/// lights (module docs), or `None` for a black pixel or a fit facing away.
fn lobe_normal(y: &[f64], grid: &Grid) -> Option<[f64; 3]> {
    let ymax = y.iter().copied().fold(0.0, f64::max);
    if !(ymax > f64::from(srgb_to_linear(3.0 / 255.0)) && ymax.is_finite()) {
        return None;
    }
    let unit = |b: [f64; 3]| {
        let len = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
        (len > 0.0 && len.is_finite()).then(|| b.map(|c| c / len))
    };
    let mut n = unit(lambert_fit(grid, y, false, |k| y[k] >= 0.05 * ymax)?)?;
    for _ in 0..2 {
        let lit = |k: usize| {
            let l = grid.dirs[k];
            n[0] * l[0] + n[1] * l[1] + n[2] * l[2] >= MIN_SHADING
        };
        match lambert_fit(grid, y, false, lit).and_then(unit) {
            Some(m) => n = m,
            None => break,
        }
    }
    (n[2] > 0.0).then_some(n)
}

/// Lights of the model dome of [`TiltCorrection`]: a Fibonacci spiral, even in solid angle,
/// over the elevations 15°..90° (`MODEL_DOME_LIGHTS` of them). Not any real dome's layout:
/// RTI domes spread their lights roughly evenly above a lowest ring of about 10°–20°.
const MODEL_DOME_LIGHTS: usize = 64;
const MODEL_DOME_MIN_ELEVATION_DEG: f64 = 15.0;
/// The model pixel's albedo (its luminance function is fitted sRGB-encoded, as RTI fitters do).
const MODEL_ALBEDO: f64 = 0.5;
/// Tilt step of the correction table.
const TILT_STEP_DEG: f64 = 0.5;

fn model_dome() -> Vec<[f64; 3]> {
    let zmin = MODEL_DOME_MIN_ELEVATION_DEG.to_radians().sin();
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..MODEL_DOME_LIGHTS)
        .map(|k| {
            // Even in solid angle: z uniform in [zmin, 1].
            let z = 1.0 - (1.0 - zmin) * (k as f64 + 0.5) / MODEL_DOME_LIGHTS as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * k as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// Solves the square system `a x = b` by Gaussian elimination with partial pivoting.
#[allow(clippy::needless_range_loop)]
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))?;
        a.swap(c, p);
        b.swap(c, p);
        if a[c][c].abs() < 1e-12 {
            return None;
        }
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// The bias of [`lobe_normal`] as a function of the tilt, and its inverse.
///
/// A low-order HSH cannot hold a clamped cosine; the lobe fit on it reads a tilt `θ̂(θ)` that
/// departs from the true `θ` as the lobe nears the horizon (the fit is cut off there, and the
/// fitted function rings). The bias is, to first order, radial and a function of `θ` alone:
/// it is simulated once per term count — a Lambertian pixel of tilt `θ` rendered under a model
/// dome ([`model_dome`]), sRGB-encoded, fitted by least squares, read by [`lobe_normal`] — and
/// a read tilt is mapped back through the inverse of `θ ↦ θ̂` (linear interpolation; the
/// azimuth is kept).
struct TiltCorrection {
    /// `θ̂` in degrees at `θ = i · TILT_STEP_DEG`, increasing (cut where it stops increasing).
    read: Vec<f64>,
}

impl TiltCorrection {
    fn new(terms: usize, grid: &Grid) -> Self {
        let lights = model_dome();
        let basis: Vec<[f64; MAX_TERMS]> = lights.iter().map(|&l| hsh_basis(l, terms)).collect();
        let bt_b: Vec<Vec<f64>> = (0..terms)
            .map(|i| {
                (0..terms)
                    .map(|j| basis.iter().map(|h| h[i] * h[j]).sum())
                    .collect()
            })
            .collect();
        let mut read: Vec<f64> = Vec::new();
        let steps = (90.0 / TILT_STEP_DEG).round() as usize;
        for i in 0..steps {
            let t = (i as f64 * TILT_STEP_DEG).to_radians();
            let n = [t.sin(), 0.0, t.cos()];
            let obs: Vec<f64> = lights
                .iter()
                .map(|l| {
                    let s = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0);
                    f64::from(linear_to_srgb((MODEL_ALBEDO * s) as f32))
                })
                .collect();
            let rhs = (0..terms)
                .map(|k| basis.iter().zip(&obs).map(|(h, o)| h[k] * o).sum())
                .collect();
            let Some(c) = solve_dense(bt_b.clone(), rhs) else {
                break;
            };
            let y: Vec<f64> = grid
                .basis
                .iter()
                .map(|h| srgb_decode(c.iter().zip(h).map(|(a, b)| a * b).sum()))
                .collect();
            let Some(m) = lobe_normal(&y, grid) else {
                break;
            };
            let got = m[2].clamp(-1.0, 1.0).acos().to_degrees();
            if read.last().is_some_and(|&prev| got <= prev) {
                break;
            }
            read.push(got);
        }
        Self { read }
    }

    /// The normal whose read tilt is `n`'s (module docs); `n` unchanged outside the table.
    fn correct(&self, n: [f64; 3]) -> [f64; 3] {
        let got = n[2].clamp(-1.0, 1.0).acos().to_degrees();
        let r = &self.read;
        let Some(k) = r.windows(2).position(|w| got >= w[0] && got <= w[1]) else {
            return n;
        };
        let f = (got - r[k]) / (r[k + 1] - r[k]);
        let t = ((k as f64 + f) * TILT_STEP_DEG).to_radians();
        let len = n[0].hypot(n[1]);
        if len <= 0.0 {
            return n;
        }
        [t.sin() * n[0] / len, t.sin() * n[1] / len, t.cos()]
    }
}

#[derive(Clone, Debug)]
struct Header {
    width: usize,
    height: usize,
    terms: usize,
    layout: HshLayout,
    /// Bytes of header text before the scale floats.
    len: u64,
}

/// Longest header line accepted.
const MAX_LINE: u64 = 4096;

fn decode_err(path: &Path, detail: impl Into<String>) -> RgbnError {
    RgbnError::Decode {
        detail: detail.into(),
        path: path.into(),
    }
}

fn read_err(path: &Path, e: std::io::Error) -> RgbnError {
    RgbnError::Read {
        path: path.into(),
        source: e,
    }
}

/// A header line for an error message: at most 40 characters, control characters escaped.
fn shown(line: &str) -> String {
    let short: String = line.chars().take(40).collect();
    let more = if line.chars().count() > 40 { "…" } else { "" };
    format!("{short:?}{more}")
}

fn read_line(
    r: &mut impl BufRead,
    len: &mut u64,
    path: &Path,
    what: &str,
) -> Result<String, RgbnError> {
    let mut buf = Vec::new();
    let n = r
        .by_ref()
        .take(MAX_LINE)
        .read_until(b'\n', &mut buf)
        .map_err(|e| read_err(path, e))?;
    *len += n as u64;
    if buf.last() != Some(&b'\n') {
        return Err(decode_err(
            path,
            if n as u64 >= MAX_LINE {
                format!("RTI header: {what} line longer than {MAX_LINE} bytes (not an RTI file?)")
            } else {
                format!("RTI header truncated before the {what} line ended")
            },
        ));
    }
    buf.pop();
    if buf.last() == Some(&b'\r') {
        buf.pop();
    }
    Ok(String::from_utf8_lossy(&buf).trim().to_string())
}

/// `count` whole numbers from one header line.
fn numbers(line: &str, count: usize, what: &str, path: &Path) -> Result<Vec<usize>, RgbnError> {
    let toks: Vec<&str> = line.split_whitespace().collect();
    if toks.len() != count {
        return Err(decode_err(
            path,
            format!(
                "RTI header: the {what} line {} should hold {count} numbers",
                shown(line)
            ),
        ));
    }
    toks.iter()
        .map(|t| {
            t.parse::<u32>().map(|v| v as usize).map_err(|_| {
                decode_err(
                    path,
                    format!(
                        "RTI header: {} in the {what} line is not a whole number",
                        shown(t)
                    ),
                )
            })
        })
        .collect()
}

fn read_header(r: &mut impl BufRead, path: &Path) -> Result<Header, RgbnError> {
    let mut len = 0u64;
    let mut first = true;
    let type_line = loop {
        let line = read_line(r, &mut len, path, "type")?;
        if first && line.starts_with("PTM_") {
            return Err(decode_err(
                path,
                "a PTM file named .rti: rename it to .ptm to read it as a PTM",
            ));
        }
        first = false;
        if !line.starts_with('#') {
            break line;
        }
    };
    match type_line.parse::<i64>() {
        Ok(3) => {}
        Ok(t) => {
            let what = match t {
                0 | 1 => "PTM-basis",
                2 => "spherical-harmonics",
                4 => "RBF",
                _ => "unknown",
            };
            return Err(decode_err(
                path,
                format!(
                    "RTI type {t} ({what}) is not read: rgbn reads hemispherical-harmonics (HSH, type 3) .rti files and .ptm files"
                ),
            ));
        }
        Err(_) => {
            return Err(decode_err(
                path,
                format!(
                    "not an RTI file: expected the type number (3 for HSH) after the comments, found {}",
                    shown(&type_line)
                ),
            ))
        }
    }
    let dims = numbers(
        &read_line(r, &mut len, path, "size")?,
        3,
        "width height bands",
        path,
    )?;
    let basis = numbers(
        &read_line(r, &mut len, path, "basis")?,
        3,
        "terms layout bytes",
        path,
    )?;
    let (width, height, bands) = (dims[0], dims[1], dims[2]);
    let (terms, layout, element) = (basis[0], basis[1], basis[2]);
    if ![4, 9, 16].contains(&terms) {
        return Err(decode_err(
            path,
            format!(
                "RTI header: {terms} HSH terms; rgbn reads orders 2, 3 and 4 (4, 9 or 16 terms)"
            ),
        ));
    }
    let layout = match layout {
        1 => HshLayout::Lrgb,
        2 => HshLayout::Rgb,
        l => {
            return Err(decode_err(
                path,
                format!("RTI header: colour layout {l} is not read (1 = LRGB, 2 = RGB)"),
            ))
        }
    };
    if bands != 3 {
        return Err(decode_err(
            path,
            format!("RTI header: {bands} bands; rgbn reads 3 (colour)"),
        ));
    }
    if element != 1 {
        return Err(decode_err(
            path,
            format!("RTI header: {element} bytes per coefficient; rgbn reads 1"),
        ));
    }
    Ok(Header {
        width,
        height,
        terms,
        layout,
        len,
    })
}

/// The pixel size in an HSH file's header (nothing else read), or `None` when it is not one.
#[must_use]
pub fn dimensions(path: &Path) -> Option<(usize, usize)> {
    let f = std::fs::File::open(path).ok()?;
    let h = read_header(&mut std::io::BufReader::new(f), path).ok()?;
    Some((h.width, h.height))
}

/// Reads an HSH `.rti` file (module docs: what becomes colour, normal and mask).
///
/// # Errors
/// [`RgbnError::NotFound`]/[`RgbnError::Read`] for file problems, [`RgbnError::TooLarge`] over
/// the pixel limit, [`RgbnError::Decode`] for a malformed, truncated or unsupported file (the
/// message names what), [`RgbnError::Cancelled`] when the current token is set.
pub fn read_hsh(path: &Path) -> Result<Hsh, RgbnError> {
    let file = std::fs::File::open(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            RgbnError::NotFound { path: path.into() }
        } else {
            read_err(path, e)
        }
    })?;
    let meta = file.metadata().map_err(|e| read_err(path, e))?;
    if !meta.is_file() {
        return Err(read_err(path, std::io::Error::other("not a regular file")));
    }
    let mut r = std::io::BufReader::new(file);
    let h = read_header(&mut r, path)?;
    check_size(h.width, h.height, &path.display().to_string())?;
    let n = h.width * h.height;
    let need = n
        .checked_mul(h.layout.bytes_per_pixel(h.terms))
        .ok_or_else(|| decode_err(path, "RTI file too large for this machine"))?;
    let have = meta.len().saturating_sub(h.len);
    let floats = 8 * h.terms as u64;
    if have < floats + need as u64 {
        return Err(decode_err(
            path,
            format!(
                "truncated HSH {} file: {}×{} with {} terms needs {} bytes of scales, biases and coefficients after the header, the file has {have}",
                h.layout.name(),
                h.width,
                h.height,
                h.terms,
                floats + need as u64
            ),
        ));
    }
    let mut fl = vec![0u8; floats as usize];
    let mut data = super::buf::zeroed_u8(need);
    r.read_exact(&mut fl)
        .and_then(|()| r.read_exact(&mut data))
        .map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                decode_err(path, "truncated HSH data")
            } else {
                read_err(path, e)
            }
        })?;
    let f32s: Vec<f64> = fl
        .chunks_exact(4)
        .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
        .collect();
    let (scale, bias) = f32s.split_at(h.terms);
    if let Some(i) = f32s.iter().position(|v| !v.is_finite()) {
        return Err(decode_err(
            path,
            format!(
                "RTI header: {} {} is not a finite number",
                if i < h.terms { "scale" } else { "bias" },
                i % h.terms
            ),
        ));
    }
    decode(&h, scale, bias, &data)
}

/// Turns the coefficient bytes into colour, normal and mask (rows flipped to top-down).
/// Checks the current cancellation token at every pixel (a lobe fit is tens of µs).
fn decode(h: &Header, scale: &[f64], bias: &[f64], data: &[u8]) -> Result<Hsh, RgbnError> {
    let cancel = crate::cancel::Cancel::current();
    let (w, ht, terms) = (h.width, h.height, h.terms);
    let n = w * ht;
    let bpp = h.layout.bytes_per_pixel(terms);
    let grid = Grid::new(terms);
    let tilt = TiltCorrection::new(terms, &grid);
    let lin = srgb8_to_linear();
    let coef = |bytes: &[u8]| -> [f64; MAX_TERMS] {
        let mut c = [0.0; MAX_TERMS];
        for (t, (o, &b)) in c.iter_mut().zip(bytes).enumerate() {
            *o = f64::from(b) / 255.0 * scale[t] + bias[t];
        }
        c
    };
    let mut px = vec![[0f32; 7]; n];
    px.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        let file_row = ht - 1 - row;
        for (x, o) in out.iter_mut().enumerate() {
            if cancel.is_cancelled() {
                return;
            }
            let k = (file_row * w + x) * bpp;
            let bytes = &data[k..k + bpp];
            let (lum, bands) = match h.layout {
                HshLayout::Lrgb => (coef(&bytes[..terms]), None),
                HshLayout::Rgb => {
                    let b: [[f64; MAX_TERMS]; 3] =
                        std::array::from_fn(|c| coef(&bytes[c * terms..(c + 1) * terms]));
                    let lum = std::array::from_fn(|t| (b[0][t] + b[1][t] + b[2][t]) / 3.0);
                    (lum, Some(b))
                }
            };
            // Linear luminance at the virtual lights (the file's values are sRGB-encoded).
            let lin_at = |c: &[f64; MAX_TERMS], h: &[f64; MAX_TERMS]| {
                let v: f64 = c[..terms].iter().zip(h).map(|(a, b)| a * b).sum();
                srgb_decode(v)
            };
            let y: Vec<f64> = grid
                .basis
                .iter()
                .map(|h| match &bands {
                    Some(b) => (lin_at(&b[0], h) + lin_at(&b[1], h) + lin_at(&b[2], h)) / 3.0,
                    None => lin_at(&lum, h),
                })
                .collect();
            let max = lobe_normal(&y, &grid).map(|n| tilt.correct(n));
            let normal = max.unwrap_or([0.0, 0.0, 1.0]);
            let color: [f32; 3] = match bands {
                None => std::array::from_fn(|c| lin[usize::from(bytes[terms + c])]),
                Some(b) => {
                    b.map(|c| srgb_to_linear(eval_hsh(&c[..terms], normal).clamp(0.0, 1.0) as f32))
                }
            };
            *o = [
                color[0],
                color[1],
                color[2],
                normal[0] as f32,
                normal[1] as f32,
                normal[2] as f32,
                if max.is_some() { 1.0 } else { 0.0 },
            ];
        }
    });
    cancel.check()?;
    let (image, no_maximum) = image_from_pixels(w, ht, &px);
    Ok(Hsh {
        image,
        layout: h.layout,
        terms,
        no_maximum,
    })
}

/// [`read_hsh`] for [`crate::raster::io::load`]: the image, with a warning naming how many
/// pixels have no normal (masked out).
///
/// # Errors
/// As [`read_hsh`].
pub fn load_hsh(path: &Path) -> Result<RgbnImage, RgbnError> {
    let p = read_hsh(path)?;
    if p.no_maximum > 0 {
        tracing::warn!(
            "{} of {} pixels of the HSH {} file have a flat function or a maximum on the horizon: masked out, normal (0,0,1): {}",
            p.no_maximum,
            p.image.width() * p.image.height(),
            p.layout.name(),
            path.display()
        );
    }
    Ok(p.image)
}

// ------------------------------------------------------------------------------------------
// Writing (tests and tools)
// ------------------------------------------------------------------------------------------

/// HSH functions to write, row-major with row 0 at the **top** (the writer stores the rows
/// bottom-up), each a list of `terms` coefficients in 0..1 units.
#[derive(Clone, Debug, PartialEq)]
pub enum HshData {
    /// One luminance function and 8-bit (sRGB-encoded) colour per pixel.
    Lrgb {
        lum: Vec<Vec<f64>>,
        rgb: Vec<[u8; 3]>,
    },
    /// One function per channel: red, green, blue.
    Rgb { channels: [Vec<Vec<f64>>; 3] },
}

/// Writes an HSH `.rti` atomically (the layout of the module docs). The scale and bias of each
/// term cover its range over all pixels and channels, so each coefficient is quantised to 8
/// bits with a step of `range/255`.
///
/// # Errors
/// [`RgbnError::InvalidImage`] for a wrong number of pixels or terms (4, 9 or 16, the same for
/// every pixel) or a non-finite coefficient; write errors.
pub fn write_hsh(
    path: &Path,
    width: usize,
    height: usize,
    data: &HshData,
) -> Result<(), RgbnError> {
    let n = width * height;
    let (layout, blocks): (HshLayout, Vec<&[Vec<f64>]>) = match data {
        HshData::Lrgb { lum, rgb } => {
            if rgb.len() != n {
                return Err(RgbnError::InvalidImage(format!(
                    "HSH colour has {} pixels, {width}×{height} needs {n}",
                    rgb.len()
                )));
            }
            (HshLayout::Lrgb, vec![lum.as_slice()])
        }
        HshData::Rgb { channels } => (HshLayout::Rgb, channels.iter().map(Vec::as_slice).collect()),
    };
    let terms = blocks.first().and_then(|b| b.first()).map_or(9, Vec::len);
    if ![4, 9, 16].contains(&terms) {
        return Err(RgbnError::InvalidImage(format!(
            "{terms} HSH terms: 4, 9 or 16 are written"
        )));
    }
    for b in &blocks {
        if b.len() != n || b.iter().any(|c| c.len() != terms) {
            return Err(RgbnError::InvalidImage(format!(
                "HSH coefficients must be {terms} per pixel for {width}×{height} pixels"
            )));
        }
        if b.iter().flatten().any(|v| !v.is_finite()) {
            return Err(RgbnError::InvalidImage("non-finite HSH coefficient".into()));
        }
    }
    let mut scale = vec![0f32; terms];
    let mut bias = vec![0f32; terms];
    for t in 0..terms {
        let (lo, hi) = blocks
            .iter()
            .flat_map(|b| b.iter().map(move |c| c[t]))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
        bias[t] = lo as f32;
        scale[t] = ((hi - lo) as f32).max(1e-12);
    }
    let quant = |v: f64, t: usize| -> u8 {
        ((v - f64::from(bias[t])) / f64::from(scale[t]) * 255.0)
            .round()
            .clamp(0.0, 255.0) as u8
    };
    let header = format!(
        "#HSH1.2\n3\n{width} {height} 3\n{terms} {} 1\n",
        layout.number()
    );
    let mut bytes =
        Vec::with_capacity(header.len() + 8 * terms + n * layout.bytes_per_pixel(terms));
    bytes.extend_from_slice(header.as_bytes());
    for v in scale.iter().chain(&bias) {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for row in (0..height).rev() {
        for i in row * width..(row + 1) * width {
            for b in &blocks {
                bytes.extend((0..terms).map(|t| quant(b[i][t], t)));
            }
            if let HshData::Lrgb { rgb, .. } = data {
                bytes.extend_from_slice(&rgb[i]);
            }
        }
    }
    write_atomic(path, |out| out.write_all(&bytes).map_err(|e| e.to_string()))
}

#[cfg(test)]
#[path = "hsh_tests.rs"]
mod tests;
