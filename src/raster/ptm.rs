//! Polynomial Texture Maps (`.ptm`, Malzbender, Gelb & Wolters, "Polynomial Texture Maps",
//! SIGGRAPH 2001): reading an uncompressed LRGB or RGB PTM as an RGBN image, writing an RGBN
//! image as an LRGB PTM that RTIViewer opens ([`save_ptm`], [`ptm_from_rgbn`]), and a general
//! writer used by tests and tools.
//!
//! # File layout (PTM_1.2, also PTM_1.1)
//!
//! A text header of lines ending in `\n`, then raw bytes:
//!
//! ```text
//! PTM_1.2                       version
//! PTM_FORMAT_LRGB               or PTM_FORMAT_RGB
//! 512                           width
//! 384                           height
//! s0 s1 s2 s3 s4 s5             six scale floats
//! b0 b1 b2 b3 b4 b5             six bias integers
//! <coefficient bytes>
//! ```
//!
//! Width and height are read as the next two whitespace-separated numbers (one line each in the
//! files HP's fitter and RTIBuilder write; one line for both is accepted too). The binary data
//! starts right after the newline that ends the bias line.
//!
//! - Coefficient order per pixel: `a0..a5` of `L(u,v) = a0·u² + a1·v² + a2·uv + a3·u + a4·v +
//!   a5`, where `(u, v)` is the light direction projected on the image plane.
//! - Each byte `c` of coefficient `i` decodes as `a_i = (c − bias_i) · scale_i`; the six scale
//!   and bias values are shared by all pixels (and, in an RGB PTM, by the three channels).
//! - Rows are stored **bottom-up**: the first row in the file is the bottom row of the image.
//!   PTM texture coordinates have their origin at the lower left, so `u` points right and `v`
//!   **up** — the same frame as rgbn's normals (`+x` right, `+y` up, `+z` towards the viewer),
//!   and no axis is flipped.
//! - `PTM_FORMAT_LRGB`, version 1.2: all pixels' six luminance bytes (bottom row first), then all
//!   pixels' `R,G,B` bytes in the same order. Version 1.1 interleaves them per pixel (six
//!   coefficients then `R,G,B`).
//! - `PTM_FORMAT_RGB`: three blocks — red, green, blue — each holding six bytes per pixel,
//!   bottom row first.
//!
//! Sources checked (read, not copied): RTIViewer (Visual Computing Lab ISTI-CNR and Cultural
//! Heritage Imaging), `ptm.cpp` (`LRGBPtm::loadData`, `RGBPtm::loadData`: header lines, the
//! bottom-up `for (y = h − 1; y >= 0; y−−)` loops, `(c − bias[i]) · scale[i]`, the 1.1 vs 1.2
//! LRGB layouts, the R/G/B block order) and `ptm.h` (`Ptm::calculateNormal`: the maximum formula
//! below, and the concavity test `4·a0·a1 − a2² > 0 ∧ a0 < 0`); Marcello Perathoner's `ptmlib.h`
//! (coefficient order `u², v², uv, u, v, 1`, the format names including the compressed
//! `PTM_FORMAT_JPEG_*`, and luminance as `r + g + b`). Both cite HP Labs' "PTM File Format
//! 1.2" (PtmFormat12.pdf), which was not itself consulted.
//!
//! # What rgbn makes of a PTM
//!
//! - **Normal**: the maximum of the luminance biquadratic, as the paper and RTIViewer compute
//!   it: `u0 = (a2·a4 − 2·a1·a3) / (4·a0·a1 − a2²)`,
//!   `v0 = (a2·a3 − 2·a0·a4) / (4·a0·a1 − a2²)`, `n = (u0, v0, √(1 − u0² − v0²))`.
//! - **Mask**: a pixel whose polynomial has no interior maximum — not concave
//!   (`4·a0·a1 − a2² ≤ 0` or `a0 ≥ 0`, which includes a flat, e.g. black, pixel) or a maximum on
//!   or outside the unit circle — gets mask 0 and the normal `(0, 0, 1)` (RTIViewer instead
//!   searches the maximum on the circle; rgbn marks such pixels as unknown rather than guess).
//!   Every other pixel gets mask 1. The image always carries this mask; [`Ptm::no_maximum`]
//!   counts the masked pixels and [`load_ptm`] reports them (a `tracing` warning).
//! - **Colour**, in rgbn's linear light; the 8-bit values of a PTM come from camera photos and
//!   are treated as sRGB-encoded, like every 8-bit colour file rgbn reads:
//!   - LRGB: the stored `R,G,B` bytes (the unscaled colour that the viewer multiplies by
//!     `L(u,v)/255`).
//!   - RGB: each channel's polynomial evaluated at the luminance maximum `(u0, v0)`, divided by
//!     255 and clamped to [0, 1]. For a diffuse surface each channel is its albedo times the
//!     shading, so its value at the brightest light direction is the albedo, free of shading;
//!     the constant term `a5` (the value under a light from the viewer) would instead bake in
//!     `n_z` and darken every tilted pixel. Masked pixels (no maximum) use `(u, v) = (0, 0)`,
//!     i.e. `a5`.
//! - **RGB PTM luminance**: the maximum and the mask come from the mean of the three channel
//!   polynomials (`(R + G + B)/3`, coefficient-wise: the polynomial of the luminance
//!   `r + g + b` of ptmlib, up to a factor that does not move the maximum). RTIViewer instead
//!   computes one normal per channel and averages the three; that puts a dark channel's flat
//!   polynomial (e.g. blue on a red object) at its `(0, 0, 1)` fallback and drags the average
//!   towards the viewer, while the summed polynomial keeps the shared maximum of a diffuse
//!   surface (tested with a blue-free sphere below).
//!
//! Not read (a one-line error naming the format): the compressed `PTM_FORMAT_JPEG_RGB`,
//! `PTM_FORMAT_JPEG_LRGB`, `PTM_FORMAT_JPEGLS_*` and the other PTM formats (`PTM_FORMAT_LUM`,
//! palettes), and RTI files (`#HSH1.2` …; `.rti`, read by [`super::hsh`]).
//!
//! Safety on bad input: header fields are parsed strictly (negative, non-numeric, non-finite →
//! error), the size is checked against `RGBN_MAX_PIXELS` and the file length against the data
//! the header announces before anything is allocated.

use super::{check_size, RgbnImage};
use crate::error::RgbnError;
use crate::raster::io::write_atomic;
use crate::raster::srgb::srgb_to_linear;
use rayon::prelude::*;
use std::io::{BufRead, Read, Write};
use std::path::Path;

/// The uncompressed PTM formats rgbn reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PtmFormat {
    /// One luminance polynomial per pixel plus 8-bit `R,G,B`.
    Lrgb,
    /// One polynomial per colour channel.
    Rgb,
}

impl PtmFormat {
    /// The format line of the file.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Lrgb => "PTM_FORMAT_LRGB",
            Self::Rgb => "PTM_FORMAT_RGB",
        }
    }
    /// Bytes per pixel of the (uncompressed) data.
    fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Lrgb => 9,
            Self::Rgb => 18,
        }
    }
}

/// A PTM read as an RGBN image.
#[derive(Clone, Debug)]
pub struct Ptm {
    /// Colour (linear), normal from the luminance maximum, mask (0 where there is none).
    pub image: RgbnImage,
    /// The file's format.
    pub format: PtmFormat,
    /// Pixels whose luminance polynomial has no maximum inside the unit disk (mask 0, normal
    /// `(0, 0, 1)`).
    pub no_maximum: usize,
}

/// Six biquadratic coefficients `a0..a5` of `a0·u² + a1·v² + a2·uv + a3·u + a4·v + a5`.
pub type Coefficients = [f64; 6];

/// Value of the biquadratic at `(u, v)`.
#[must_use]
pub fn eval_biquadratic(a: &Coefficients, u: f64, v: f64) -> f64 {
    a[0] * u * u + a[1] * v * v + a[2] * u * v + a[3] * u + a[4] * v + a[5]
}

/// The maximum `(u0, v0)` of the biquadratic if it is strictly concave and its maximum lies
/// strictly inside the unit disk (Malzbender et al. 2001; RTIViewer's
/// `calculateNormal`); `None` otherwise.
#[must_use]
pub fn biquadratic_maximum(a: &Coefficients) -> Option<(f64, f64)> {
    let det = 4.0 * a[0] * a[1] - a[2] * a[2];
    if !(det > 0.0 && a[0] < 0.0) {
        return None;
    }
    let u0 = (a[2] * a[4] - 2.0 * a[1] * a[3]) / det;
    let v0 = (a[2] * a[3] - 2.0 * a[0] * a[4]) / det;
    (u0 * u0 + v0 * v0 < 1.0).then_some((u0, v0))
}

/// The unit normal at the maximum of the biquadratic (see [`biquadratic_maximum`]).
#[must_use]
pub fn normal_from_coefficients(a: &Coefficients) -> Option<[f64; 3]> {
    biquadratic_maximum(a).map(|(u, v)| [u, v, (1.0 - u * u - v * v).max(0.0).sqrt()])
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Version {
    V11,
    V12,
}

#[derive(Clone, Debug)]
struct Header {
    version: Version,
    format: PtmFormat,
    width: usize,
    height: usize,
    scale: [f64; 6],
    bias: [f64; 6],
    /// Bytes of header text before the coefficient data.
    len: u64,
}

/// Longest header line accepted (real headers are well under 200 bytes).
const MAX_LINE: u64 = 4096;

fn decode_err(path: &Path, detail: impl Into<String>) -> RgbnError {
    RgbnError::Decode {
        detail: detail.into(),
        path: path.into(),
    }
}

/// A header line for an error message: at most 40 characters, control characters escaped.
fn shown(line: &str) -> String {
    let short: String = line.chars().take(40).collect();
    let more = if line.chars().count() > 40 { "…" } else { "" };
    format!("{:?}{more}", short)
}

/// Reads one `\n`-terminated header line (without the line end), counting the bytes consumed.
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
                format!("PTM header: {what} line longer than {MAX_LINE} bytes (not a PTM file?)")
            } else {
                format!("PTM header truncated before the {what} line ended")
            },
        ));
    }
    buf.pop();
    if buf.last() == Some(&b'\r') {
        buf.pop();
    }
    Ok(String::from_utf8_lossy(&buf).trim().to_string())
}

fn read_err(path: &Path, e: std::io::Error) -> RgbnError {
    RgbnError::Read {
        path: path.into(),
        source: e,
    }
}

/// Checks the version line; names HSH/RBF RTI files and other non-PTM files.
fn parse_version(line: &str, path: &Path) -> Result<Version, RgbnError> {
    match line {
        "PTM_1.2" => Ok(Version::V12),
        "PTM_1.1" => Ok(Version::V11),
        l if l.starts_with("#HSH") || l.starts_with("#RBF") || l.starts_with('#') => {
            Err(decode_err(
                path,
                format!(
                    "RTI file {} (HSH/RBF), not a PTM: rgbn reads only PTM_FORMAT_LRGB and PTM_FORMAT_RGB PTMs",
                    shown(l)
                ),
            ))
        }
        l if l.starts_with("PTM_") => Err(decode_err(
            path,
            format!(
                "unsupported PTM version {} (rgbn reads PTM_1.1 and PTM_1.2)",
                shown(l)
            ),
        )),
        l => Err(decode_err(
            path,
            format!("not a PTM file: first line {}, expected PTM_1.2", shown(l)),
        )),
    }
}

fn parse_format(line: &str, path: &Path) -> Result<PtmFormat, RgbnError> {
    match line {
        "PTM_FORMAT_LRGB" => Ok(PtmFormat::Lrgb),
        "PTM_FORMAT_RGB" => Ok(PtmFormat::Rgb),
        l if l.starts_with("PTM_FORMAT_JPEG") => Err(decode_err(
            path,
            format!(
                "compressed PTM {l} is not supported: rgbn reads the uncompressed PTM_FORMAT_LRGB and PTM_FORMAT_RGB (re-export the PTM uncompressed)"
            ),
        )),
        l if l.starts_with("PTM_FORMAT_") => Err(decode_err(
            path,
            format!(
                "PTM format {l} is not supported: rgbn reads PTM_FORMAT_LRGB and PTM_FORMAT_RGB"
            ),
        )),
        l => Err(decode_err(
            path,
            format!(
                "PTM header: unknown format line {} (expected PTM_FORMAT_LRGB or PTM_FORMAT_RGB)",
                shown(l)
            ),
        )),
    }
}

fn parse_dimension(tok: &str, what: &str, path: &Path) -> Result<usize, RgbnError> {
    let bad = |why: &str| decode_err(path, format!("PTM header: {what} {} {why}", shown(tok)));
    if tok.starts_with('-') {
        return Err(bad("is negative"));
    }
    let v: u64 = tok.parse().map_err(|_| bad("is not a whole number"))?;
    usize::try_from(v).map_err(|_| bad("is too large"))
}

/// The pixel size in a PTM's header (nothing else read), or `None` when it is not one.
#[must_use]
pub fn dimensions(path: &Path) -> Option<(usize, usize)> {
    let f = std::fs::File::open(path).ok()?;
    let h = read_header(&mut std::io::BufReader::new(f), path).ok()?;
    Some((h.width, h.height))
}

fn read_header(r: &mut impl BufRead, path: &Path) -> Result<Header, RgbnError> {
    let mut len = 0u64;
    let version = parse_version(&read_line(r, &mut len, path, "version")?, path)?;
    let format = parse_format(&read_line(r, &mut len, path, "format")?, path)?;
    // Width, height, six scales and six biases: whitespace-separated, usually one line for each
    // of width and height, one for the scales, one for the biases.
    let mut tokens: Vec<String> = Vec::with_capacity(14);
    while tokens.len() < 14 {
        let what = match tokens.len() {
            0 => "width",
            1 => "height",
            2..=7 => "scale",
            _ => "bias",
        };
        let line = read_line(r, &mut len, path, what)?;
        tokens.extend(line.split_whitespace().map(str::to_string));
        if tokens.len() > 14 {
            return Err(decode_err(
                path,
                format!(
                    "PTM header: {} values where width, height, 6 scales and 6 biases (14) were expected",
                    tokens.len()
                ),
            ));
        }
    }
    let width = parse_dimension(&tokens[0], "width", path)?;
    let height = parse_dimension(&tokens[1], "height", path)?;
    let mut scale = [0.0; 6];
    for (i, (s, t)) in scale.iter_mut().zip(&tokens[2..8]).enumerate() {
        *s = t
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                decode_err(
                    path,
                    format!("PTM header: scale {i} {} is not a finite number", shown(t)),
                )
            })?;
    }
    let mut bias = [0.0; 6];
    for (i, (b, t)) in bias.iter_mut().zip(&tokens[8..14]).enumerate() {
        *b = f64::from(t.parse::<i32>().map_err(|_| {
            decode_err(
                path,
                format!("PTM header: bias {i} {} is not an integer", shown(t)),
            )
        })?);
    }
    Ok(Header {
        version,
        format,
        width,
        height,
        scale,
        bias,
        len,
    })
}

/// Reads an uncompressed LRGB or RGB PTM (see the module documentation for what becomes colour,
/// normal and mask).
///
/// # Errors
/// [`RgbnError::NotFound`]/[`RgbnError::Read`] for file problems, [`RgbnError::TooLarge`] over
/// the pixel limit, [`RgbnError::Decode`] for a malformed, truncated or unsupported file (the
/// message names the format).
pub fn read_ptm(path: &Path) -> Result<Ptm, RgbnError> {
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
    let (w, ht) = (h.width, h.height);
    let n = w * ht; // within the pixel limit, so no overflow
    let need = n
        .checked_mul(h.format.bytes_per_pixel())
        .ok_or_else(|| decode_err(path, "PTM too large for this machine"))?;
    let have = meta.len().saturating_sub(h.len);
    if have < need as u64 {
        return Err(decode_err(
            path,
            format!(
                "truncated {} PTM: {w}×{ht} needs {need} data bytes after the header, the file has {have}",
                h.format.name()
            ),
        ));
    }
    let mut data = super::buf::zeroed_u8(need);
    r.read_exact(&mut data).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            decode_err(path, format!("truncated {} PTM data", h.format.name()))
        } else {
            read_err(path, e)
        }
    })?;
    Ok(decode(&h, &data))
}

/// Turns the coefficient bytes into colour, normal and mask (rows flipped to top-down).
fn decode(h: &Header, data: &[u8]) -> Ptm {
    let (w, ht) = (h.width, h.height);
    let n = w * ht;
    let lin = srgb8_to_linear();
    let coef = |bytes: &[u8]| -> Coefficients {
        std::array::from_fn(|i| (f64::from(bytes[i]) - h.bias[i]) * h.scale[i])
    };
    // Per pixel: colour (3), normal (3), mask.
    let mut px = vec![[0f32; 7]; n];
    px.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        let file_row = ht - 1 - row;
        for (x, o) in out.iter_mut().enumerate() {
            let k = file_row * w + x;
            // The luminance polynomial, and the colour or the channel polynomials it comes from.
            let (lum, color): (Coefficients, Result<[f32; 3], [Coefficients; 3]>) = match h.format {
                PtmFormat::Lrgb => {
                    let (c, rgb) = if h.version == Version::V11 {
                        (&data[k * 9..k * 9 + 6], &data[k * 9 + 6..k * 9 + 9])
                    } else {
                        (
                            &data[k * 6..k * 6 + 6],
                            &data[n * 6 + k * 3..n * 6 + k * 3 + 3],
                        )
                    };
                    (
                        coef(c),
                        Ok(std::array::from_fn(|i| lin[usize::from(rgb[i])])),
                    )
                }
                PtmFormat::Rgb => {
                    let ch: [Coefficients; 3] = std::array::from_fn(|c| {
                        let off = c * n * 6 + k * 6;
                        coef(&data[off..off + 6])
                    });
                    let lum = std::array::from_fn(|i| (ch[0][i] + ch[1][i] + ch[2][i]) / 3.0);
                    (lum, Err(ch))
                }
            };
            let max = biquadratic_maximum(&lum);
            let normal = max.map_or([0.0, 0.0, 1.0], |(u, v)| {
                [u, v, (1.0 - u * u - v * v).max(0.0).sqrt()]
            });
            let color = color.unwrap_or_else(|ch| {
                let (u, v) = max.unwrap_or((0.0, 0.0));
                ch.map(|c| {
                    srgb_to_linear((eval_biquadratic(&c, u, v) / 255.0).clamp(0.0, 1.0) as f32)
                })
            });
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
    let (image, no_maximum) = image_from_pixels(w, ht, &px);
    Ptm {
        image,
        format: h.format,
        no_maximum,
    }
}

/// Colour, normal and mask planes from per-pixel `[r, g, b, nx, ny, nz, mask]` (the PTM and
/// HSH decoders' output), and how many pixels are masked out (no maximum).
pub(super) fn image_from_pixels(w: usize, h: usize, px: &[[f32; 7]]) -> (RgbnImage, usize) {
    let plane = |k: usize| -> Vec<f32> { px.par_iter().map(|p| p[k]).collect() };
    let color = [plane(0), plane(1), plane(2)];
    let normal = [plane(3), plane(4), plane(5)];
    let mask = plane(6);
    let no_maximum = mask.par_iter().filter(|&&m| m == 0.0).count();
    let image =
        RgbnImage::new(w, h, color, normal, Some(mask)).expect("planes have width × height values");
    (image, no_maximum)
}

/// sRGB 8-bit code → linear value.
pub(super) fn srgb8_to_linear() -> &'static [f32; 256] {
    static LUT: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// [`read_ptm`] for [`crate::raster::io::load`]: the image, with a warning naming how many pixels
/// have no luminance maximum (masked out).
pub fn load_ptm(path: &Path) -> Result<RgbnImage, RgbnError> {
    let p = read_ptm(path)?;
    if p.no_maximum > 0 {
        tracing::warn!(
            "{} of {} pixels of the {} have no luminance maximum inside the unit disk: masked out, normal (0,0,1): {}",
            p.no_maximum,
            p.image.width() * p.image.height(),
            p.format.name(),
            path.display()
        );
    }
    Ok(p.image)
}

// ------------------------------------------------------------------------------------------
// Writing (tests and tools)
// ------------------------------------------------------------------------------------------

/// Polynomials to write as a PTM, row-major with row 0 at the **top** (rgbn's order; the writer
/// stores the rows bottom-up). Coefficients are in the file's units: `L(u, v)` in 0..255.
#[derive(Clone, Debug, PartialEq)]
pub enum PtmData {
    /// Luminance polynomial and 8-bit (sRGB-encoded) colour per pixel.
    Lrgb {
        lum: Vec<Coefficients>,
        rgb: Vec<[u8; 3]>,
    },
    /// One polynomial per channel: red, green, blue.
    Rgb { channels: [Vec<Coefficients>; 3] },
}

/// Writes an uncompressed PTM_1.2 (LRGB or RGB) atomically. The six scales and biases are chosen
/// per coefficient from its range over all pixels (and channels), so each coefficient is
/// quantised to 8 bits with a step of `range/254`.
///
/// # Errors
/// [`RgbnError::InvalidImage`] if the data do not have `width × height` entries or hold
/// non-finite coefficients; write errors.
pub fn write_ptm(
    path: &Path,
    width: usize,
    height: usize,
    data: &PtmData,
) -> Result<(), RgbnError> {
    let n = width * height;
    let (format, blocks): (PtmFormat, Vec<&[Coefficients]>) = match data {
        PtmData::Lrgb { lum, rgb } => {
            if rgb.len() != n {
                return Err(RgbnError::InvalidImage(format!(
                    "PTM colour has {} pixels, {width}×{height} needs {n}",
                    rgb.len()
                )));
            }
            (PtmFormat::Lrgb, vec![lum.as_slice()])
        }
        PtmData::Rgb { channels } => (PtmFormat::Rgb, channels.iter().map(Vec::as_slice).collect()),
    };
    for b in &blocks {
        if b.len() != n {
            return Err(RgbnError::InvalidImage(format!(
                "PTM coefficients for {} pixels, {width}×{height} needs {n}",
                b.len()
            )));
        }
        if b.iter().flatten().any(|v| !v.is_finite()) {
            return Err(RgbnError::InvalidImage("non-finite PTM coefficient".into()));
        }
    }
    let mut scale = [0f32; 6];
    let mut bias = [0i32; 6];
    for i in 0..6 {
        let (lo, hi) = blocks
            .iter()
            .flat_map(|b| b.iter().map(move |c| c[i]))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
        let range = hi - lo;
        scale[i] = if range > 1e-12 {
            (range / 254.0) as f32
        } else {
            (lo.abs().max(1e-6) / 100.0) as f32
        };
        bias[i] = (-lo / f64::from(scale[i])).round() as i32;
    }
    write_ptm_scaled(path, width, height, data, format, &blocks, scale, bias)
}

/// The bytes of a PTM with the given scales and biases (coefficients quantised to them).
#[allow(clippy::too_many_arguments)]
fn write_ptm_scaled(
    path: &Path,
    width: usize,
    height: usize,
    data: &PtmData,
    format: PtmFormat,
    blocks: &[&[Coefficients]],
    scale: [f32; 6],
    bias: [i32; 6],
) -> Result<(), RgbnError> {
    let n = width * height;
    let quant = |c: &Coefficients, i: usize| -> u8 {
        (c[i] / f64::from(scale[i]) + f64::from(bias[i]))
            .round()
            .clamp(0.0, 255.0) as u8
    };
    let join = |v: Vec<String>| v.join(" ");
    let header = format!(
        "PTM_1.2\n{}\n{width}\n{height}\n{}\n{}\n",
        format.name(),
        join(scale.iter().map(|s| s.to_string()).collect()),
        join(bias.iter().map(|b| b.to_string()).collect()),
    );
    let mut bytes = Vec::with_capacity(header.len() + n * format.bytes_per_pixel());
    bytes.extend_from_slice(header.as_bytes());
    for b in blocks {
        for row in (0..height).rev() {
            for c in &b[row * width..(row + 1) * width] {
                bytes.extend((0..6).map(|i| quant(c, i)));
            }
        }
    }
    if let PtmData::Lrgb { rgb, .. } = data {
        for row in (0..height).rev() {
            for c in &rgb[row * width..(row + 1) * width] {
                bytes.extend_from_slice(c);
            }
        }
    }
    write_atomic(path, |out| out.write_all(&bytes).map_err(|e| e.to_string()))
}

// ------------------------------------------------------------------------------------------
// An RGBN image as a PTM (for RTIViewer and the other RTI tools)
// ------------------------------------------------------------------------------------------

/// Half the luminance curvature of a Lambertian `255 · n · l` at its maximum for a normal
/// facing the viewer (its Hessian there is `−255 · I`), in file units.
const LAMBERT_HALF_CURVATURE: f64 = 127.5;

/// The fixed quantisation of [`ptm_from_rgbn`]: scales and biases of `a0..a5`, so that
/// `a0, a1 ∈ [−1.5k, −0.5k]` (k = 127.5) in 254 steps, `a2 ∈ {0, k}`, `a3, a4 ∈ [−3k, 3k]`,
/// `a5 ∈ [0, 256]`.
fn rgbn_ptm_grid() -> ([f32; 6], [i32; 6]) {
    let k = LAMBERT_HALF_CURVATURE as f32;
    (
        [
            k / 254.0,
            k / 254.0,
            k,
            6.0 * k / 254.0,
            6.0 * k / 254.0,
            255.0 / 254.0,
        ],
        [381, 381, 0, 127, 127, 0],
    )
}

/// An RGBN image as LRGB PTM data on the grid of `rgbn_ptm_grid`: per pixel a paraboloid
/// `L(u, v) = a5 + a0 (u² − 2 u u0) + a1 (v² − 2 v v0)` — the second-order shape of a
/// Lambertian `255 · n · l` about its maximum, peaking at 255 — whose maximum `(u0, v0)` is the
/// normal's `(n_x, n_y)`, so a PTM reader (rgbn's, RTIViewer's `calculateNormal`) finds the
/// normal again: `u0 = −a3 / (2 a0)`. The curvature `a0` of each axis is chosen among its 255
/// representable values, near `−127.5`, with `a3` rounded to its grid so that the ratio comes
/// closest to `n_x` (likewise `a1`, `a4` for `n_y`): the 8-bit file then holds the normal to
/// about 1e-4 instead of one quantisation step (≈ 0.4° near the rim). The colour is written
/// as sRGB bytes.
///
/// Pixels outside the mask or facing away (`n_z ≤ 0`) get `a0 = a1 = −0.5k`, `a2 = k`: no
/// maximum (read back as masked out), and their colour.
#[must_use]
pub fn ptm_from_rgbn(img: &RgbnImage) -> PtmData {
    let (scale, bias) = rgbn_ptm_grid();
    let val = |i: usize, c: i32| f64::from(c - bias[i]) * f64::from(scale[i]);
    // The best (curvature, linear) pair for a target maximum coordinate t (|t| < 1).
    let axis = |t: f64| -> (f64, f64) {
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for c0 in 0..=254 {
            let a0 = val(0, c0);
            let c3 = (-2.0 * a0 * t / f64::from(scale[3]) + f64::from(bias[3]))
                .round()
                .clamp(0.0, 254.0) as i32;
            let a3 = val(3, c3);
            let err = (-a3 / (2.0 * a0) - t).abs() + 1e-9 * (a0 + LAMBERT_HALF_CURVATURE).abs();
            if err < best.0 {
                best = (err, a0, a3);
            }
        }
        (best.1, best.2)
    };
    let [nx, ny, nz] = img.normal();
    let mask = img.mask();
    let k = LAMBERT_HALF_CURVATURE;
    let lum = (0..img.len())
        .into_par_iter()
        .map(|i| {
            let inside = mask.is_none_or(|m| m[i] >= 0.5) && nz[i] > 0.0;
            if !inside {
                return [-0.5 * k, -0.5 * k, k, 0.0, 0.0, 0.0];
            }
            let (x, y) = (f64::from(nx[i]), f64::from(ny[i]));
            let ((a0, a3), (a1, a4)) = (axis(x), axis(y));
            let (u0, v0) = (-a3 / (2.0 * a0), -a4 / (2.0 * a1));
            // L(u0, v0) = a5 − a0 u0² − a1 v0² = 255.
            let a5 = (255.0 + a0 * u0 * u0 + a1 * v0 * v0).clamp(0.0, 256.0);
            [a0, a1, 0.0, a3, a4, a5]
        })
        .collect();
    let [r, g, b] = img.color();
    let rgb = (0..img.len())
        .into_par_iter()
        .map(|i| [r[i], g[i], b[i]].map(crate::raster::srgb::linear_to_srgb8))
        .collect();
    PtmData::Lrgb { lum, rgb }
}

/// Writes an RGBN image as an uncompressed LRGB PTM_1.2 ([`ptm_from_rgbn`]), atomically.
///
/// # Errors
/// Write errors.
pub fn save_ptm(img: &RgbnImage, path: &Path) -> Result<(), RgbnError> {
    let data = ptm_from_rgbn(img);
    let PtmData::Lrgb { lum, .. } = &data else {
        unreachable!("ptm_from_rgbn writes LRGB")
    };
    let (scale, bias) = rgbn_ptm_grid();
    write_ptm_scaled(
        path,
        img.width(),
        img.height(),
        &data,
        PtmFormat::Lrgb,
        &[lum.as_slice()],
        scale,
        bias,
    )
}

#[cfg(test)]
#[path = "ptm_tests.rs"]
mod tests;
