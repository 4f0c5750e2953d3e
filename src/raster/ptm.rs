//! Polynomial Texture Maps (`.ptm`, Malzbender, Gelb & Wolters, "Polynomial Texture Maps",
//! SIGGRAPH 2001): reading an uncompressed LRGB or RGB PTM as an RGBN image, and a writer used
//! by tests and tools.
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
//! palettes), and HSH/RBF RTI files (`#HSH1.2` …; `.rti`).
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
    let plane = |k: usize| -> Vec<f32> { px.par_iter().map(|p| p[k]).collect() };
    let color = [plane(0), plane(1), plane(2)];
    let normal = [plane(3), plane(4), plane(5)];
    let mask = plane(6);
    let no_maximum = mask.par_iter().filter(|&&m| m == 0.0).count();
    let image = RgbnImage::new(w, ht, color, normal, Some(mask))
        .expect("planes have width × height values");
    Ptm {
        image,
        format: h.format,
        no_maximum,
    }
}

fn srgb8_to_linear() -> &'static [f32; 256] {
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
    for b in &blocks {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Solves the 6×6 normal equations of a least-squares biquadratic fit.
    #[allow(clippy::needless_range_loop)] // matrix indices read best as indices
    fn fit(lights: &[[f64; 3]], intensity: impl Fn(&[f64; 3]) -> f64) -> Coefficients {
        let mut a = [[0.0f64; 7]; 6];
        for l in lights {
            let f = [l[0] * l[0], l[1] * l[1], l[0] * l[1], l[0], l[1], 1.0];
            let y = intensity(l);
            for i in 0..6 {
                for j in 0..6 {
                    a[i][j] += f[i] * f[j];
                }
                a[i][6] += f[i] * y;
            }
        }
        for c in 0..6 {
            let p = (c..6)
                .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
                .unwrap();
            a.swap(c, p);
            for r in 0..6 {
                if r != c {
                    let f = a[r][c] / a[c][c];
                    for k in c..7 {
                        a[r][k] -= f * a[c][k];
                    }
                }
            }
        }
        std::array::from_fn(|i| a[i][6] / a[i][i])
    }

    /// Light directions on a grid of the unit disk of radius `rmax` (elevation ≥ acos(rmax)).
    fn lights(rmax: f64) -> Vec<[f64; 3]> {
        let k = 10;
        let mut out = Vec::new();
        for i in -k..=k {
            for j in -k..=k {
                let (u, v) = (
                    f64::from(i) / f64::from(k) * rmax,
                    f64::from(j) / f64::from(k) * rmax,
                );
                if u * u + v * v <= rmax * rmax + 1e-12 {
                    out.push([u, v, (1.0 - u * u - v * v).sqrt()]);
                }
            }
        }
        out
    }

    /// A sphere in rgbn's frame (row 0 at the top, `+y` up), off-centre in a non-square image so
    /// that a flipped row order or axis shows. `None` outside the sphere.
    struct Sphere {
        w: usize,
        h: usize,
    }
    impl Sphere {
        const W: usize = 56;
        const H: usize = 44;
        fn new() -> Self {
            Self {
                w: Self::W,
                h: Self::H,
            }
        }
        fn normal(&self, x: usize, row: usize) -> Option<[f64; 3]> {
            let (cx, cy, r) = (30.0, 20.0, 18.0);
            let px = (x as f64 + 0.5 - cx) / r;
            let py = -(row as f64 + 0.5 - cy) / r;
            let d = px * px + py * py;
            (d < 1.0).then(|| [px, py, (1.0 - d).sqrt()])
        }
    }

    fn angle_deg(a: [f32; 3], b: [f64; 3]) -> f64 {
        let dot = f64::from(a[0]) * b[0] + f64::from(a[1]) * b[1] + f64::from(a[2]) * b[2];
        let len =
            (f64::from(a[0]).powi(2) + f64::from(a[1]).powi(2) + f64::from(a[2]).powi(2)).sqrt();
        (dot / len).clamp(-1.0, 1.0).acos().to_degrees()
    }

    /// (mean, max, count) angular error over the unmasked pixels whose true normal satisfies
    /// `keep`.
    fn errors(img: &RgbnImage, s: &Sphere, keep: impl Fn(&[f64; 3]) -> bool) -> (f64, f64, usize) {
        let mask = img.mask().expect("PTMs carry a mask");
        let (mut sum, mut max, mut count) = (0.0, 0.0f64, 0);
        for row in 0..s.h {
            for x in 0..s.w {
                let n = s
                    .normal(x, row)
                    .filter(|n| keep(n) && mask[row * s.w + x] > 0.0);
                if let Some(n) = n {
                    let e = angle_deg(img.normal_at(x, row), n);
                    sum += e;
                    max = max.max(e);
                    count += 1;
                }
            }
        }
        (sum / count as f64, max, count)
    }

    /// An "ideal" PTM of the normal `n`: a concave biquadratic whose maximum is exactly at
    /// `(n_x, n_y)`, with a per-pixel anisotropy and `uv` term (so that every coefficient and
    /// its position matter), peak value `peak` (0..255 units).
    fn ideal(n: [f64; 3], peak: f64, x: usize) -> Coefficients {
        let t = x as f64 * 0.37;
        let (k1, k2, k12) = (
            0.5 + 0.2 * t.sin(),
            0.5 - 0.15 * t.cos(),
            0.2 * (1.3 * t).sin(),
        );
        let (du, dv) = (n[0], n[1]);
        // peak · (1 − [d]ᵀ Q [d]) with d = (u − du, v − dv), Q = [[k1, k12], [k12, k2]]
        let p = peak;
        [
            -p * k1,
            -p * k2,
            -p * 2.0 * k12,
            p * (2.0 * k1 * du + 2.0 * k12 * dv),
            p * (2.0 * k2 * dv + 2.0 * k12 * du),
            p * (1.0 - k1 * du * du - k2 * dv * dv - 2.0 * k12 * du * dv),
        ]
    }

    const ALBEDO: [f64; 3] = [0.8, 0.45, 0.0];

    fn lrgb_rgb(s: &Sphere) -> Vec<[u8; 3]> {
        (0..s.w * s.h)
            .map(|i| [(i % 251) as u8, 200, (i * 7 % 256) as u8])
            .collect()
    }

    #[test]
    fn ideal_sphere_lrgb_and_rgb_recover_normals_within_2_degrees() {
        let s = Sphere::new();
        let d = tempfile::tempdir().unwrap();
        let flat: Coefficients = [0.0, 0.0, 0.0, 0.0, 0.0, 10.0];
        let lum: Vec<Coefficients> = (0..s.w * s.h)
            .map(|i| {
                let (x, row) = (i % s.w, i / s.w);
                s.normal(x, row).map_or(flat, |n| ideal(n, 200.0, x))
            })
            .collect();
        let rgb = lrgb_rgb(&s);
        let p = d.path().join("ideal_lrgb.ptm");
        write_ptm(
            &p,
            s.w,
            s.h,
            &PtmData::Lrgb {
                lum: lum.clone(),
                rgb: rgb.clone(),
            },
        )
        .unwrap();
        let ptm = read_ptm(&p).unwrap();
        assert_eq!(ptm.format, PtmFormat::Lrgb);
        let img = &ptm.image;
        assert_eq!((img.width(), img.height()), (s.w, s.h));
        // Sphere interior: the pixels with tilt ≤ 60° (n_z ≥ 0.5, the inner 87 % of the radius); nearer the rim the 8-bit coefficient steps move the maximum more
        // (measured: max 2.5° at tilt ≤ 72.5°).
        let (mean, max, count) = errors(img, &s, |n| n[2] >= 0.5);
        eprintln!("ideal LRGB, tilt ≤ 60°: mean {mean:.3}°, max {max:.3}° over {count} px");
        assert!(count > 700, "{count}");
        assert!(mean < 2.0 && max < 2.0, "mean {mean}°, max {max}°");
        let (mean, max, count) = errors(img, &s, |n| n[2] >= 0.3);
        eprintln!("ideal LRGB, tilt ≤ 72.5°: mean {mean:.3}°, max {max:.3}° over {count} px");
        // Colour is the stored bytes, sRGB-decoded; flat (background) pixels are masked.
        let lin = srgb8_to_linear();
        for (i, c) in rgb.iter().enumerate() {
            let (x, row) = (i % s.w, i / s.w);
            let got = img.color_at(x, row);
            for k in 0..3 {
                assert_eq!(got[k], lin[usize::from(c[k])], "colour at {x},{row}");
            }
        }
        let mask = img.mask().unwrap();
        let outside = (0..s.w * s.h)
            .filter(|&i| s.normal(i % s.w, i / s.w).is_none())
            .count();
        // Flat background pixels are masked, with the fallback normal; the interior is not.
        assert!(
            ptm.no_maximum >= outside && ptm.no_maximum < outside + 60,
            "{}",
            ptm.no_maximum
        );
        assert_eq!(img.normal_at(0, 0), [0.0, 0.0, 1.0]);
        assert_eq!(mask[0], 0.0);
        for (i, &m) in mask.iter().enumerate() {
            if s.normal(i % s.w, i / s.w).is_some_and(|n| n[2] >= 0.3) {
                assert_eq!(m, 1.0, "pixel {i}");
            }
        }

        // RGB: three channels with albedo (0.8, 0.45, 0): blue is flat zero everywhere.
        let channels: [Vec<Coefficients>; 3] = std::array::from_fn(|c| {
            (0..s.w * s.h)
                .map(|i| {
                    let (x, row) = (i % s.w, i / s.w);
                    s.normal(x, row)
                        .map_or([0.0; 6], |n| ideal(n, 255.0 * ALBEDO[c], x))
                })
                .collect()
        });
        let p = d.path().join("ideal_rgb.ptm");
        write_ptm(&p, s.w, s.h, &PtmData::Rgb { channels }).unwrap();
        let ptm = read_ptm(&p).unwrap();
        assert_eq!(ptm.format, PtmFormat::Rgb);
        let (mean, max, count) = errors(&ptm.image, &s, |n| n[2] >= 0.5);
        eprintln!("ideal RGB, tilt ≤ 60°: mean {mean:.3}°, max {max:.3}° over {count} px");
        assert!(mean < 2.0 && max < 2.0, "mean {mean}°, max {max}°");
        let (mean, max, count) = errors(&ptm.image, &s, |n| n[2] >= 0.3);
        eprintln!("ideal RGB, tilt ≤ 72.5°: mean {mean:.3}°, max {max:.3}° over {count} px");
        assert!(
            ptm.no_maximum >= outside && ptm.no_maximum < outside + 60,
            "{}",
            ptm.no_maximum
        );
        // Colour at the maximum is the albedo (the peak), sRGB-decoded.
        let c = ptm.image.color_at(30, 20);
        for k in 0..3 {
            let want = srgb_to_linear(ALBEDO[k] as f32);
            assert!(
                (c[k] - want).abs() < 0.02,
                "channel {k}: {} vs {want}",
                c[k]
            );
        }
    }

    #[test]
    fn lambertian_sphere_fit_recovers_normals_where_the_biquadratic_model_holds() {
        // The PTM of a diffuse sphere as a fitter makes it: per pixel, the least-squares
        // biquadratic through max(0, n·l) under 317 lights of elevation ≥ 53° (|l_uv| ≤ 0.6),
        // quantised to 8 bits with scale and bias.
        let s = Sphere::new();
        let ls = lights(0.6);
        let fit_px = |i: usize, albedo: f64| -> Coefficients {
            let (x, row) = (i % s.w, i / s.w);
            match s.normal(x, row) {
                Some(n) => fit(&ls, |l| {
                    255.0 * albedo * (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0)
                }),
                None => [0.0; 6],
            }
        };
        let d = tempfile::tempdir().unwrap();
        let lum: Vec<Coefficients> = (0..s.w * s.h).map(|i| fit_px(i, 0.9)).collect();
        let p = d.path().join("lambert_lrgb.ptm");
        write_ptm(
            &p,
            s.w,
            s.h,
            &PtmData::Lrgb {
                lum,
                rgb: lrgb_rgb(&s),
            },
        )
        .unwrap();
        let lrgb = read_ptm(&p).unwrap();
        let channels: [Vec<Coefficients>; 3] =
            std::array::from_fn(|c| (0..s.w * s.h).map(|i| fit_px(i, ALBEDO[c])).collect());
        let p = d.path().join("lambert_rgb.ptm");
        write_ptm(&p, s.w, s.h, &PtmData::Rgb { channels }).unwrap();
        let rgb = read_ptm(&p).unwrap();
        for (name, ptm) in [("LRGB", &lrgb), ("RGB", &rgb)] {
            // The biquadratic's maximum of a fitted cosine lobe is only near the true normal
            // for moderate tilts (a biquadratic only approximates a cosine lobe); with these lights
            // the model error is ≤ 1.5° up to 30° of tilt and grows beyond (≈ 4° at 35°,
            // ≈ 9° at 40°); steeper pixels get no interior maximum and are masked.
            let (mean, max, count) = errors(&ptm.image, &s, |n| n[2] >= 30f64.to_radians().cos());
            eprintln!(
                "Lambertian {name}, tilt ≤ 30°: mean {mean:.3}°, max {max:.3}° over {count} px"
            );
            assert!(count > 250, "{count}");
            assert!(mean < 2.0 && max < 2.0, "{name}: mean {mean}°, max {max}°");
            let (mean, max, count) = errors(&ptm.image, &s, |_| true);
            eprintln!(
                "Lambertian {name}, every unmasked sphere pixel: mean {mean:.2}°, max {max:.2}° over {count} px; {} px masked in the image",
                ptm.no_maximum
            );
            // Masked pixels are exactly those without an interior maximum; none at the centre.
            let mask = ptm.image.mask().unwrap();
            assert_eq!(mask[20 * s.w + 30], 1.0);
            assert_eq!(mask.iter().filter(|&&m| m == 0.0).count(), ptm.no_maximum);
        }
    }

    #[test]
    fn hand_written_bytes_pin_the_layout_row_order_and_formula() {
        // A 1×2 LRGB PTM_1.2 written byte by byte: the FIRST stored pixel is the BOTTOM row.
        // Bottom pixel: L = −u² − v² + 0.5·u + 5 → maximum at (0.25, 0); top pixel: maximum at
        // (0, −0.5) (v down). scale 0.5 for all, bias 100: a = (c − 100)·0.5.
        let enc = |a: f64| (a / 0.5 + 100.0) as u8;
        let mut f =
            b"PTM_1.2\r\nPTM_FORMAT_LRGB\n1 2\n0.5 0.5 0.5 0.5 0.5 0.5\n100 100 100 100 100 100\n"
                .to_vec();
        f.extend([-1.0, -1.0, 0.0, 0.5, 0.0, 5.0].map(enc)); // bottom (row 1)
        f.extend([-1.0, -1.0, 0.0, 0.0, -1.0, 5.0].map(enc)); // top (row 0)
        f.extend([10, 20, 30, 40, 50, 60]); // RGB: bottom, then top
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("hand.ptm");
        std::fs::write(&p, &f).unwrap();
        let img = read_ptm(&p).unwrap().image;
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6);
        let z = |u: f32, v: f32| (1.0 - u * u - v * v).sqrt();
        assert!(
            close(img.normal_at(0, 1), [0.25, 0.0, z(0.25, 0.0)]),
            "{:?}",
            img.normal_at(0, 1)
        );
        assert!(
            close(img.normal_at(0, 0), [0.0, -0.5, z(0.0, 0.5)]),
            "{:?}",
            img.normal_at(0, 0)
        );
        let lin = srgb8_to_linear();
        assert_eq!(img.color_at(0, 1), [lin[10], lin[20], lin[30]]);
        assert_eq!(img.color_at(0, 0), [lin[40], lin[50], lin[60]]);

        // The same as PTM_1.1 (coefficients and colour interleaved per pixel).
        let mut f =
            b"PTM_1.1\nPTM_FORMAT_LRGB\n1\n2\n0.5 0.5 0.5 0.5 0.5 0.5\n100 100 100 100 100 100\n"
                .to_vec();
        f.extend([-1.0, -1.0, 0.0, 0.5, 0.0, 5.0].map(enc));
        f.extend([10, 20, 30]);
        f.extend([-1.0, -1.0, 0.0, 0.0, -1.0, 5.0].map(enc));
        f.extend([40, 50, 60]);
        std::fs::write(&p, &f).unwrap();
        let img = read_ptm(&p).unwrap().image;
        assert!(close(img.normal_at(0, 1), [0.25, 0.0, z(0.25, 0.0)]));
        assert_eq!(img.color_at(0, 0), [lin[40], lin[50], lin[60]]);
    }

    #[test]
    fn maximum_rules() {
        // Convex, saddle, flat: no maximum.
        assert_eq!(biquadratic_maximum(&[1.0, 1.0, 0.0, 0.0, 0.0, 0.0]), None);
        assert_eq!(biquadratic_maximum(&[-1.0, 1.0, 0.0, 0.0, 0.0, 0.0]), None);
        assert_eq!(biquadratic_maximum(&[0.0; 6]), None);
        // Concave but the maximum (1.5, 0) is outside the unit disk.
        assert_eq!(biquadratic_maximum(&[-1.0, -1.0, 0.0, 3.0, 0.0, 0.0]), None);
        // With a uv term: −u² − v² + uv + u → ∂u: −2u + v + 1 = 0, ∂v: −2v + u = 0 → (2/3, 1/3).
        let (u, v) = biquadratic_maximum(&[-1.0, -1.0, 1.0, 1.0, 0.0, 0.0]).unwrap();
        assert!((u - 2.0 / 3.0).abs() < 1e-12 && (v - 1.0 / 3.0).abs() < 1e-12);
        let n = normal_from_coefficients(&[-1.0, -1.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
        assert_eq!(n, [0.0, 0.0, 1.0]);
    }

    fn header(version: &str, format: &str, dims: &str) -> Vec<u8> {
        format!("{version}\n{format}\n{dims}\n1 1 1 1 1 1\n0 0 0 0 0 0\n").into_bytes()
    }

    fn err_of(bytes: &[u8]) -> String {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("bad.ptm");
        std::fs::write(&p, bytes).unwrap();
        let e = read_ptm(&p).unwrap_err();
        let s = e.to_string();
        assert!(!s.contains('\n'), "one line: {s}");
        assert!(s.ends_with("bad.ptm"), "names the file: {s}");
        s
    }

    #[test]
    fn bad_headers_are_one_line_errors_never_panics() {
        let mut trunc = header("PTM_1.2", "PTM_FORMAT_LRGB", "4\n4");
        trunc.extend([0u8; 4 * 4 * 9 - 1]);
        let e = err_of(&trunc);
        assert!(
            e.contains("truncated PTM_FORMAT_LRGB PTM") && e.contains("144") && e.contains("143"),
            "{e}"
        );
        let mut trunc = header("PTM_1.2", "PTM_FORMAT_RGB", "4\n4");
        trunc.extend([0u8; 100]);
        assert!(err_of(&trunc).contains("truncated PTM_FORMAT_RGB"));
        let e = err_of(b"PTM_1.2\nPTM_FORMAT_LRGB\n4\n4\n1 1 1");
        assert!(e.contains("truncated"), "{e}");
        let e = err_of(&header("PTM_1.2", "PTM_FORMAT_JPEG_LRGB", "4\n4"));
        assert!(e.contains("compressed PTM PTM_FORMAT_JPEG_LRGB"), "{e}");
        let e = err_of(&header("PTM_1.2", "PTM_FORMAT_JPEGLS_RGB", "4\n4"));
        assert!(e.contains("PTM_FORMAT_JPEGLS_RGB"), "{e}");
        let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LUM", "4\n4"));
        assert!(e.contains("PTM_FORMAT_LUM is not supported"), "{e}");
        let e = err_of(b"#HSH1.2\n3\n4 4 2\n1 2 3\n");
        assert!(e.contains("HSH"), "{e}");
        let e = err_of(b"P6\n4 4\n255\n");
        assert!(e.contains("not a PTM file"), "{e}");
        let e = err_of(&header("PTM_2.0", "PTM_FORMAT_LRGB", "4\n4"));
        assert!(e.contains("unsupported PTM version"), "{e}");
        let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LRGB", "-4\n4"));
        assert!(e.contains("width \"-4\" is negative"), "{e}");
        let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LRGB", "4\nfour"));
        assert!(e.contains("height \"four\" is not a whole number"), "{e}");
        let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LRGB", "0\n4"));
        assert!(e.contains("no pixels"), "{e}");
        let e = err_of(&header(
            "PTM_1.2",
            "PTM_FORMAT_LRGB",
            "99999999999999999999\n4",
        ));
        assert!(e.contains("width"), "{e}");
        // Huge sizes are refused by the pixel limit before anything is allocated.
        let e = err_of(&header(
            "PTM_1.2",
            "PTM_FORMAT_RGB",
            "4000000000\n4000000000",
        ));
        assert!(e.contains("too large"), "{e}");
        let e = err_of(b"PTM_1.2\nPTM_FORMAT_RGB\n4\n4\n1 1 nan 1 1 1\n0 0 0 0 0 0\n");
        assert!(e.contains("scale 2"), "{e}");
        let e = err_of(b"PTM_1.2\nPTM_FORMAT_RGB\n4\n4\n1 1 1 1 1 1\n0 0 0 0 0 1.5\n");
        assert!(e.contains("bias 5"), "{e}");
        let e = err_of(b"PTM_1.2\nPTM_FORMAT_RGB\n4\n4\n1 1 1 1 1 1 1\n0 0 0 0 0 0\n");
        assert!(e.contains("15 values"), "{e}");
        let e = err_of(&[b'P'; 10_000]);
        assert!(e.contains("longer than"), "{e}");
        let e = err_of(b"");
        assert!(e.contains("truncated"), "{e}");
        // Every truncation of a valid file is an error (never a panic); the whole file reads.
        let mut full = header("PTM_1.2", "PTM_FORMAT_LRGB", "2\n2");
        full.extend([7u8; 36]);
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("cut.ptm");
        for cut in 0..full.len() {
            std::fs::write(&p, &full[..cut]).unwrap();
            assert!(read_ptm(&p).is_err(), "cut at {cut}");
        }
        std::fs::write(&p, &full).unwrap();
        assert_eq!(
            read_ptm(&p).unwrap().no_maximum,
            4,
            "constant polynomials: no maximum"
        );
    }
}
