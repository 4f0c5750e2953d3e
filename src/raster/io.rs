//! Reading and writing RGBN images.
//!
//! - **EXR** (exr crate, submodule `openexr`): colour `R,G,B` (linear), normal `N.X,N.Y,N.Z`,
//!   mask `A`; f16 or f32. By option, an EXR whose `R,G,B` *is* a normal pass (Blender style)
//!   is read as normals.
//! - **Colour** PNG/JPEG/TIFF, 8 or 16 bit, sRGB → linear; EXR colour is already linear.
//! - **Normal maps** PNG/TIFF (8/16 bit) or EXR: `n = v/(2^bits−1)·2−1`, then renormalised;
//!   OpenGL (`+y` up, the internal frame) or DirectX (`y` flipped) convention.
//! - **Masks**: any greyscale (or first channel) image, values in [0, 1].
//! - **PTM**: an uncompressed LRGB or RGB Polynomial Texture Map gives colour, the normal at the
//!   luminance maximum and a mask of the pixels without one (see [`super::ptm`]); an RGBN image
//!   is written as an LRGB PTM.
//! - **RTI** (`.rti`, read only): an HSH file gives colour, the normal at the luminance maximum
//!   and a mask (see [`super::hsh`]).
//!
//! Bad normals on load are **repaired, with counts** (see [`RgbnImage::repair`]): non-finite and
//! zero-length normals become `(0, 0, 1)`, others are renormalised; back-facing normals are kept
//! and counted. [`LoadOptions::strict`] turns any repair into an error instead.
//!
//! Writes are atomic (a temporary file in the same folder, then rename) and refuse to write over
//! any input (see [`check_output`]).

pub mod ahead;
mod exr_write;
mod format;
mod openexr;
mod png_normals;
mod raster_write;
pub mod stream;
pub mod targets;
pub mod zarr;

use raster_write::png_format;
pub use raster_write::{write_png8_text, write_raster16, write_raster8};

pub use exr_write::ExrFormat;
pub use format::Format;
pub mod temp;

pub use openexr::{
    load_exr, save_exr, save_exr_with, save_plane_exr, ExrCompression, ExrPrecision,
};

use super::srgb::{linear_to_srgb, linear_to_srgb8, srgb16_lut, srgb8_lut};
use super::{check_size, RgbnImage, Validation};
use crate::error::RgbnError;
use crate::raster::buf;
use openexr::read_exr_channels;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Normal-map convention of a file. Internally rgbn always uses OpenGL (`+y` up).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum NormalConvention {
    /// `+y` up (OpenGL, Blender, DiLiGenT).
    #[default]
    OpenGl,
    /// `+y` down (DirectX, Unreal): the green channel is flipped on load and save.
    DirectX,
}

/// Options for loading.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Convention of normal-map files (EXR `N.*` channels are always OpenGL).
    pub convention: NormalConvention,
    /// Read an EXR's `R,G,B` as the normal (a Blender-style normal pass) instead of colour.
    pub exr_rgb_is_normal: bool,
    /// Refuse (instead of repairing) non-finite or zero-length normals and non-finite colours.
    pub strict: bool,
}

impl LoadOptions {
    /// The options of the loader's flags: `dx` (normal maps in the DirectX convention,
    /// green = −y), `exr_rgb_is_normal`, `strict`.
    #[must_use]
    pub fn of_flags(dx: bool, exr_rgb_is_normal: bool, strict: bool) -> Self {
        Self {
            convention: if dx {
                NormalConvention::DirectX
            } else {
                NormalConvention::OpenGl
            },
            exr_rgb_is_normal,
            strict,
        }
    }
}

/// Where the parts of one RGBN image come from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InputSpec {
    /// An RGBN EXR (colour + `N.*`), or a normal map alone (any supported format).
    pub rgbn: Option<PathBuf>,
    /// Colour image (overrides an EXR's colour).
    pub color: Option<PathBuf>,
    /// Normal map (when `rgbn` is not given).
    pub normal: Option<PathBuf>,
    /// Coverage mask.
    pub mask: Option<PathBuf>,
}

impl InputSpec {
    /// Every path named, for the "never overwrite an input" check.
    #[must_use]
    pub fn paths(&self) -> Vec<&Path> {
        [&self.rgbn, &self.color, &self.normal, &self.mask]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect()
    }
}

/// A loaded image and what was repaired.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub image: RgbnImage,
    /// Validation *before* repair: the counts of what was fixed (and back-facing normals).
    pub repaired: Validation,
}

/// Albedo given to images that come without colour (a normal map alone).
pub const DEFAULT_ALBEDO: f32 = 0.75;

/// Loads an image as described by `spec`.
pub fn load(spec: &InputSpec, opts: &LoadOptions) -> Result<Loaded, RgbnError> {
    let (mut image, normal_path, counted) = match (&spec.rgbn, &spec.normal) {
        (Some(p), None) | (None, Some(p)) => {
            let (img, counted) = match Format::of(p)? {
                Format::Zarr if spec.color.is_none() && spec.mask.is_none() => {
                    return zarr::load(p, opts)
                }
                Format::Zarr => (zarr::load(p, opts)?.image, None),
                Format::Exr => (load_exr(p, opts)?, None),
                Format::Ptm => (super::ptm::load_ptm(p)?, None),
                Format::Rti => (super::hsh::load_hsh(p)?, None),
                _ => load_normal_map_counted(p, opts)?,
            };
            (img, p.clone(), counted)
        }
        (Some(_), Some(n)) => {
            return Err(RgbnError::param(
                "input",
                format!(
                    "give either an RGBN file or --normal, not both (--normal {})",
                    n.display()
                ),
            ))
        }
        (None, None) => {
            return Err(RgbnError::param(
                "input",
                "no normals given: name an RGBN EXR or a normal map (or use the built-in demo)",
            ))
        }
    };
    let (w, h) = (image.width(), image.height());
    if let Some(c) = &spec.color {
        let (cw, ch, color) = load_color(c)?;
        if (cw, ch) != (w, h) {
            return Err(RgbnError::SizeMismatch {
                what: "colour image",
                want_w: w,
                want_h: h,
                got_w: cw,
                got_h: ch,
                path: c.clone(),
            });
        }
        image.set_color(color)?;
    }
    if let Some(m) = &spec.mask {
        let (mw, mh, mask) = load_mask(m)?;
        if (mw, mh) != (w, h) {
            return Err(RgbnError::SizeMismatch {
                what: "mask",
                want_w: w,
                want_h: h,
                got_w: mw,
                got_h: mh,
                path: m.clone(),
            });
        }
        image.set_mask(Some(mask))?;
    }
    // A pipelined PNG decode counted the problems as it went (colour and mask added above
    // were not counted).
    let before = match counted {
        Some(v) if spec.color.is_none() && spec.mask.is_none() => v,
        _ => image.validate(),
    };
    if opts.strict {
        if let Some(e) = before.strict_error(&normal_path) {
            return Err(e);
        }
    }
    image.repair_validated(&before);
    Ok(Loaded {
        image,
        repaired: before,
    })
}

fn open_check(path: &Path) -> Result<(), RgbnError> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => Ok(()),
        Ok(_) => Err(RgbnError::Read {
            path: path.into(),
            source: std::io::Error::other("not a regular file"),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Err(RgbnError::NotFound { path: path.into() })
        }
        Err(e) => Err(RgbnError::Read {
            path: path.into(),
            source: e,
        }),
    }
}

/// Decoded integer or float samples of a raster file, interleaved.
enum Samples {
    U8(Vec<u8>),
    U16(Vec<u16>),
    F32(Vec<f32>),
}

struct Raster {
    width: usize,
    height: usize,
    channels: usize,
    samples: Samples,
}

/// A decoder's failure: an I/O error other than a truncated file is a read error; everything
/// else (truncation included) is a decode error with the decoder's message.
fn read_or_decode_error(path: &Path, io: Option<std::io::Error>, detail: String) -> RgbnError {
    match io {
        Some(io) if io.kind() != std::io::ErrorKind::UnexpectedEof => RgbnError::Read {
            path: path.into(),
            source: io,
        },
        _ => RgbnError::Decode {
            detail,
            path: path.into(),
        },
    }
}

/// Decodes a PNG/JPEG/TIFF with the image crate, checking the size before decoding.
fn decode_raster(path: &Path) -> Result<Raster, RgbnError> {
    open_check(path)?;
    let fmt = match Format::of(path)? {
        Format::Png => image::ImageFormat::Png,
        Format::Jpeg => image::ImageFormat::Jpeg,
        Format::Tiff => image::ImageFormat::Tiff,
        Format::Exr => unreachable!("EXR is decoded by the exr crate"),
        Format::Ptm | Format::Rti => return Err(ptm_not_a_raster(path)),
        Format::Zarr => return Err(zarr::not_a_raster(path)),
    };
    let decode_err = |e: image::ImageError| {
        let detail = e.to_string();
        match e {
            image::ImageError::IoError(io) => read_or_decode_error(path, Some(io), detail),
            _ => read_or_decode_error(path, None, detail),
        }
    };
    let open = || {
        image::ImageReader::open(path)
            .map(|mut r| {
                r.set_format(fmt);
                r
            })
            .map_err(|e| RgbnError::Read {
                path: path.into(),
                source: e,
            })
    };
    if fmt == image::ImageFormat::Png {
        return decode_png(path);
    }
    let (w, h) = open()?.into_dimensions().map_err(decode_err)?;
    let (w, h) = (w as usize, h as usize);
    check_size(w, h, &path.display().to_string())?;
    let mut reader = open()?;
    reader.no_limits(); // our own limit was checked above
    let img = reader.decode().map_err(decode_err)?;
    use image::DynamicImage as D;
    let channels = usize::from(img.color().channel_count());
    let samples = match img {
        D::ImageLuma8(b) => Samples::U8(b.into_raw()),
        D::ImageLumaA8(b) => Samples::U8(b.into_raw()),
        D::ImageRgb8(b) => Samples::U8(b.into_raw()),
        D::ImageRgba8(b) => Samples::U8(b.into_raw()),
        D::ImageLuma16(b) => Samples::U16(b.into_raw()),
        D::ImageLumaA16(b) => Samples::U16(b.into_raw()),
        D::ImageRgb16(b) => Samples::U16(b.into_raw()),
        D::ImageRgba16(b) => Samples::U16(b.into_raw()),
        D::ImageRgb32F(b) => Samples::F32(b.into_raw()),
        D::ImageRgba32F(b) => Samples::F32(b.into_raw()),
        other => Samples::F32(other.into_rgb32f().into_raw()),
    };
    let channels = if matches!(samples, Samples::F32(_)) && channels != 4 {
        3
    } else {
        channels
    };
    Ok(Raster {
        width: w,
        height: h,
        channels,
        samples,
    })
}

/// A `png` crate error reading `path` (see [`read_or_decode_error`]).
fn png_decode_error(path: &Path, e: png::DecodingError) -> RgbnError {
    let detail = e.to_string();
    match e {
        png::DecodingError::IoError(io) => read_or_decode_error(path, Some(io), detail),
        _ => read_or_decode_error(path, None, detail),
    }
}

/// A `png` reader of `path` past its header, with `transformations` and without the crate's
/// memory limit (the callers check rgbn's own size limit before any image buffer exists).
fn png_reader(
    path: &Path,
    transformations: png::Transformations,
) -> Result<png::Reader<std::io::BufReader<ahead::ReadAhead>>, RgbnError> {
    let file = std::fs::File::open(path).map_err(|e| RgbnError::Read {
        path: path.into(),
        source: e,
    })?;
    let limits = png::Limits { bytes: usize::MAX };
    let mut dec =
        png::Decoder::new_with_limits(std::io::BufReader::new(ahead::ReadAhead::new(file)), limits);
    dec.set_transformations(transformations);
    dec.read_info().map_err(|e| png_decode_error(path, e))
}

/// Decodes a PNG with the `png` crate: the size is checked before the pixel buffer is
/// allocated, palette and sub-byte images are expanded to 8 bits, and 16-bit big-endian
/// samples are converted to `u16` in parallel.
fn decode_png(path: &Path) -> Result<Raster, RgbnError> {
    let err = |e: png::DecodingError| png_decode_error(path, e);
    let mut reader = png_reader(path, png::Transformations::EXPAND)?;
    let (w, h) = {
        let i = reader.info();
        (i.width as usize, i.height as usize)
    };
    check_size(w, h, &path.display().to_string())?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| RgbnError::Decode {
            detail: "image too large for this machine".into(),
            path: path.into(),
        })?;
    let mut buf = buf::zeroed_u8(size);
    let frame = reader.next_frame(&mut buf).map_err(err)?;
    buf.truncate(frame.buffer_size());
    let channels = frame.color_type.samples();
    let samples = match frame.bit_depth {
        png::BitDepth::Sixteen => {
            let mut v = vec![0u16; buf.len() / 2];
            v.par_chunks_mut(1 << 16)
                .zip(buf.par_chunks(2 << 16))
                .for_each(|(d, s)| {
                    for (d, s) in d.iter_mut().zip(s.chunks_exact(2)) {
                        *d = u16::from_be_bytes([s[0], s[1]]);
                    }
                });
            Samples::U16(v)
        }
        _ => Samples::U8(buf),
    };
    Ok(Raster {
        width: w,
        height: h,
        channels,
        samples,
    })
}

/// A PTM or RTI file named where a colour image, mask, normal map or picture is expected.
fn ptm_not_a_raster(path: &Path) -> RgbnError {
    RgbnError::UnsupportedFormat {
        format: "ptm/rti (an RTI file is read whole, as the RGBN input, and an RGBN image is written as .ptm; neither is read as a colour image, mask or photo, nor written from one)".into(),
        path: path.into(),
    }
}

/// Splits interleaved samples into `out.len()` planes, mapping each sample through `f`.
/// Missing channels (greyscale input) repeat channel 0.
fn deinterleave<T: Copy + Sync>(
    src: &[T],
    channels: usize,
    out: &mut [Vec<f32>],
    f: impl Fn(T) -> f32 + Sync,
) {
    let n = src.len() / channels;
    for o in out.iter_mut() {
        o.resize(n, 0.0);
    }
    let chunk = 4096;
    let k_out = out.len();
    // Split each plane into chunks and process chunk-aligned pieces in parallel.
    let mut planes: Vec<std::slice::ChunksMut<'_, f32>> =
        out.iter_mut().map(|o| o.chunks_mut(chunk)).collect();
    let mut pieces: Vec<Vec<&mut [f32]>> = Vec::new();
    while let Some(first) = planes[0].next() {
        let mut v = vec![first];
        for p in planes.iter_mut().skip(1) {
            v.push(p.next().expect("planes have equal length"));
        }
        pieces.push(v);
    }
    pieces
        .into_par_iter()
        .enumerate()
        .for_each(|(ci, mut piece)| {
            let base = ci * chunk;
            for i in 0..piece[0].len() {
                let s = &src[(base + i) * channels..(base + i + 1) * channels];
                for (k, plane) in piece.iter_mut().enumerate().take(k_out) {
                    plane[i] = f(s[k.min(channels - 1)]);
                }
            }
        });
}

/// Loads a colour image as linear planes: PNG/JPEG/TIFF are sRGB, EXR `R,G,B` are linear.
pub fn load_color(path: &Path) -> Result<(usize, usize, [Vec<f32>; 3]), RgbnError> {
    if Format::of(path)? == Format::Zarr {
        return zarr::load_color(path);
    }
    if Format::of(path)? == Format::Exr {
        let e = read_exr_channels(path)?;
        let color = e.take_rgb(path)?;
        return Ok((e.width, e.height, color));
    }
    let r = decode_raster(path)?;
    let mut planes = vec![Vec::new(), Vec::new(), Vec::new()];
    match &r.samples {
        Samples::U8(s) => {
            let lut = srgb8_lut();
            deinterleave(s, r.channels, &mut planes, |v| lut[usize::from(v)]);
        }
        Samples::U16(s) => {
            let lut = srgb16_lut();
            deinterleave(s, r.channels, &mut planes, |v| lut[usize::from(v)]);
        }
        Samples::F32(s) => deinterleave(s, r.channels, &mut planes, |v| v),
    }
    let [a, b, c]: [Vec<f32>; 3] = planes.try_into().expect("three planes");
    Ok((r.width, r.height, [a, b, c]))
}

/// Loads a colour image whose integer samples are already **linear** (raw camera data such as
/// the DiLiGenT photos): 8/16-bit values are divided by `2^bits − 1`, no transfer curve. Float
/// files (EXR, float TIFF) are returned as stored. Greyscale files repeat their channel.
pub fn load_color_linear(path: &Path) -> Result<(usize, usize, [Vec<f32>; 3]), RgbnError> {
    if Format::of(path)? == Format::Exr {
        return load_color(path);
    }
    let r = decode_raster(path)?;
    let mut planes = vec![Vec::new(), Vec::new(), Vec::new()];
    match &r.samples {
        Samples::U8(s) => deinterleave(s, r.channels, &mut planes, |v| f32::from(v) / 255.0),
        Samples::U16(s) => deinterleave(s, r.channels, &mut planes, |v| f32::from(v) / 65535.0),
        Samples::F32(s) => deinterleave(s, r.channels, &mut planes, |v| v),
    }
    let [a, b, c]: [Vec<f32>; 3] = planes.try_into().expect("three planes");
    Ok((r.width, r.height, [a, b, c]))
}

/// Loads a greyscale (or first-channel) mask in [0, 1]; EXR: `A`, else `Y`, else `R`.
pub fn load_mask(path: &Path) -> Result<(usize, usize, Vec<f32>), RgbnError> {
    if Format::of(path)? == Format::Zarr {
        return zarr::load_mask(path);
    }
    if Format::of(path)? == Format::Exr {
        let mut e = read_exr_channels(path)?;
        for name in ["A", "Y", "R"] {
            if let Some(m) = e.take(name) {
                return Ok((e.width, e.height, m));
            }
        }
        return Err(RgbnError::Decode {
            detail: "no A, Y or R channel for a mask".into(),
            path: path.into(),
        });
    }
    let r = decode_raster(path)?;
    let mut planes = vec![Vec::new()];
    match &r.samples {
        Samples::U8(s) => deinterleave(s, r.channels, &mut planes, |v| f32::from(v) / 255.0),
        Samples::U16(s) => deinterleave(s, r.channels, &mut planes, |v| f32::from(v) / 65535.0),
        Samples::F32(s) => deinterleave(s, r.channels, &mut planes, |v| v),
    }
    Ok((r.width, r.height, planes.pop().expect("one plane")))
}

/// Loads a normal map (PNG/TIFF/JPEG 8/16-bit, or EXR `N.*`/`R,G,B`) as an RGBN image with the
/// default albedo. Normals are decoded `v/(2^bits−1)·2−1` and *not yet* renormalised (that is
/// [`load`]'s repair step, which also counts problems).
pub fn load_normal_map(path: &Path, opts: &LoadOptions) -> Result<RgbnImage, RgbnError> {
    Ok(load_normal_map_counted(path, opts)?.0)
}

/// [`load_normal_map`], with [`RgbnImage::validate`]'s counts when the decoder took them on
/// the way (a non-interlaced 8/16-bit RGB(A) PNG: [`png_normals`]).
fn load_normal_map_counted(
    path: &Path,
    opts: &LoadOptions,
) -> Result<(RgbnImage, Option<Validation>), RgbnError> {
    if Format::of(path)? == Format::Png {
        open_check(path)?;
        let flip_y = opts.convention == NormalConvention::DirectX;
        if let Some((img, counts)) = png_normals::decode_png_normals(path, flip_y)? {
            return Ok((img, Some(counts)));
        }
    }
    if Format::of(path)? == Format::Exr {
        let o = LoadOptions {
            exr_rgb_is_normal: true,
            ..opts.clone()
        };
        return load_exr(path, &o).map(|i| (i, None));
    }
    Ok((decode_normal_map(path, opts)?, None))
}

/// A PNG/TIFF/JPEG normal map decoded whole, then converted.
fn decode_normal_map(path: &Path, opts: &LoadOptions) -> Result<RgbnImage, RgbnError> {
    let r = decode_raster(path)?;
    if r.channels < 3 {
        return Err(RgbnError::Decode {
            detail: format!(
                "a normal map needs 3 channels, this image has {}",
                r.channels
            ),
            path: path.into(),
        });
    }
    let mut planes = vec![Vec::new(), Vec::new(), Vec::new()];
    match &r.samples {
        Samples::U8(s) => deinterleave(s, r.channels, &mut planes, |v| {
            f32::from(v) * (2.0 / 255.0) - 1.0
        }),
        Samples::U16(s) => deinterleave(s, r.channels, &mut planes, |v| {
            f32::from(v) * (2.0 / 65535.0) - 1.0
        }),
        Samples::F32(s) => deinterleave(s, r.channels, &mut planes, |v| v * 2.0 - 1.0),
    }
    let [nx, mut ny, nz]: [Vec<f32>; 3] = planes.try_into().expect("three planes");
    if opts.convention == NormalConvention::DirectX {
        ny.par_iter_mut().for_each(|v| *v = -*v);
    }
    let n = r.width * r.height;
    RgbnImage::new(
        r.width,
        r.height,
        [
            buf::filled_f32(n, DEFAULT_ALBEDO),
            buf::filled_f32(n, DEFAULT_ALBEDO),
            buf::filled_f32(n, DEFAULT_ALBEDO),
        ],
        [nx, ny, nz],
        None,
    )
}

// ------------------------------------------------------------------------------------------
// Writing
// ------------------------------------------------------------------------------------------

/// Refuses `out` if its folder is missing or it is (the same file as) one of `inputs`.
pub fn check_output(out: &Path, inputs: &[&Path]) -> Result<(), RgbnError> {
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(RgbnError::MissingDir { path: out.into() });
    }
    let out_abs = std::fs::canonicalize(dir)
        .map(|d| d.join(out.file_name().unwrap_or_default()))
        .unwrap_or_else(|_| out.to_path_buf());
    for input in inputs {
        let same_path = std::fs::canonicalize(input).is_ok_and(|i| i == out_abs);
        if same_path || same_file(out, input) {
            return Err(RgbnError::OutputIsInput { path: out.into() });
        }
    }
    Ok(())
}

#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}
#[cfg(not(unix))]
fn same_file(_: &Path, _: &Path) -> bool {
    false
}

/// The pixel size of an image file from its header alone (nothing decoded), or `None` when
/// the file cannot be read or is not an image rgbn reads.
#[must_use]
pub fn dimensions(path: &Path) -> Option<(usize, usize)> {
    match Format::of(path).ok()? {
        Format::Exr => {
            let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
            let size = meta.headers.first()?.layer_size;
            Some((size.width(), size.height()))
        }
        Format::Ptm => super::ptm::dimensions(path),
        Format::Rti => super::hsh::dimensions(path),
        Format::Zarr => zarr::dimensions(path),
        _ => image::image_dimensions(path)
            .ok()
            .map(|(w, h)| (w as usize, h as usize)),
    }
}

/// Writes through `write` into a temporary file next to `path` (see [`temp`]), then renames it
/// over `path`. On error the temporary file is removed and `path` is untouched; a process
/// killed meanwhile leaves the old `path` (or none) and a temporary that the next write of
/// `path` removes.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<targets::TargetFile>) -> Result<(), String>,
) -> Result<(), RgbnError> {
    let file = targets::AtomicFile::create(path)?;
    let mut buf = std::io::BufWriter::with_capacity(1 << 20, file.handle()?);
    write(&mut buf).map_err(|e| file.error(e))?;
    buf.into_inner().map_err(|e| file.error(e.error()))?;
    file.commit()
}

/// Writes only the colour: EXR (linear `R,G,B`) or PNG/TIFF (sRGB, 8 or 16 bit).
pub fn save_color(img: &RgbnImage, path: &Path, bits: u8) -> Result<(), RgbnError> {
    match Format::of(path)? {
        Format::Zarr => Err(zarr::not_a_raster(path)),
        Format::Exr => {
            let [r, g, b] = img.color();
            openexr::write_planes_atomic(
                path,
                (img.width(), img.height()),
                &[("R", r), ("G", g), ("B", b)],
                ExrFormat::default(),
            )
        }
        fmt => {
            let [r, g, b] = img.color();
            if bits == 16 {
                let enc = |v: f32| (linear_to_srgb(v.clamp(0.0, 1.0)) * 65535.0 + 0.5) as u16;
                let data = interleave3(r, g, b, enc);
                write_raster16(&data, img.width(), img.height(), 3, fmt, path)
            } else {
                let data = interleave3(r, g, b, linear_to_srgb8);
                write_raster8(&data, img.width(), img.height(), 3, fmt, path)
            }
        }
    }
}

/// Writes the normals as a normal map: EXR (`R,G,B` = normal in [−1, 1]) or PNG/TIFF encoded
/// `v = round((n+1)/2 · (2^bits−1))`, in the given convention.
pub fn save_normal_map(
    img: &RgbnImage,
    path: &Path,
    bits: u8,
    convention: NormalConvention,
) -> Result<(), RgbnError> {
    let [nx, ny, nz] = img.normal();
    let flip = if convention == NormalConvention::DirectX {
        -1.0
    } else {
        1.0
    };
    match Format::of(path)? {
        Format::Exr => {
            let flipped: Vec<f32>;
            let ny: &[f32] = if flip < 0.0 {
                flipped = ny.iter().map(|v| -v).collect();
                &flipped
            } else {
                ny
            };
            openexr::write_planes_atomic(
                path,
                (img.width(), img.height()),
                &[("R", nx), ("G", ny), ("B", nz)],
                ExrFormat::default(),
            )
        }
        Format::Jpeg => Err(RgbnError::UnsupportedFormat {
            format: "jpeg (lossy; write normal maps as .png, .tif or .exr)".into(),
            path: path.into(),
        }),
        Format::Zarr => Err(zarr::not_a_raster(path)),
        fmt => {
            if bits == 16 {
                let data = interleave_normals(nx, ny, nz, flip, 65535.0, |v| v as u16);
                write_raster16(&data, img.width(), img.height(), 3, fmt, path)
            } else {
                let data = interleave_normals(nx, ny, nz, flip, 255.0, |v| v as u8);
                write_raster8(&data, img.width(), img.height(), 3, fmt, path)
            }
        }
    }
}

fn interleave_normals<T: Copy + Default + Send>(
    nx: &[f32],
    ny: &[f32],
    nz: &[f32],
    flip: f32,
    scale: f32,
    cast: impl Fn(f32) -> T + Sync,
) -> Vec<T> {
    let enc = |v: f32| cast(((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * scale + 0.5).min(scale));
    let mut out = vec![T::default(); nx.len() * 3];
    out.par_chunks_mut(3 * 4096).enumerate().for_each(|(c, o)| {
        let base = c * 4096;
        for (i, px) in o.chunks_exact_mut(3).enumerate() {
            let j = base + i;
            px[0] = enc(nx[j]);
            px[1] = enc(ny[j] * flip);
            px[2] = enc(nz[j]);
        }
    });
    out
}

fn interleave3<T: Copy + Default + Send>(
    a: &[f32],
    b: &[f32],
    c: &[f32],
    f: impl Fn(f32) -> T + Sync,
) -> Vec<T> {
    let mut out = vec![T::default(); a.len() * 3];
    out.par_chunks_mut(3 * 4096)
        .enumerate()
        .for_each(|(ci, o)| {
            let base = ci * 4096;
            for (i, px) in o.chunks_exact_mut(3).enumerate() {
                let j = base + i;
                px[0] = f(a[j]);
                px[1] = f(b[j]);
                px[2] = f(c[j]);
            }
        });
    out
}

/// Saves an RGBN image by extension: `.exr` and `.zarr` (an OME-Zarr store) get everything
/// (colour, normals, mask); PNG/TIFF get the normal map (`bits` 8 or 16).
pub fn save(img: &RgbnImage, path: &Path, opts: &SaveOptions) -> Result<(), RgbnError> {
    match Format::of(path)? {
        Format::Exr => save_exr_with(img, path, opts.precision, opts.compression),
        Format::Zarr => zarr::save_zarr(img, path, &opts.zarr),
        Format::Ptm => super::ptm::save_ptm(img, path),
        Format::Rti => Err(RgbnError::UnsupportedFormat {
            format: "rti (HSH files are read, not written: write .ptm for RTIViewer)".into(),
            path: path.into(),
        }),
        _ => save_normal_map(img, path, opts.bits, opts.convention),
    }
}

/// Options for [`save`].
#[derive(Clone, Debug, PartialEq)]
pub struct SaveOptions {
    pub bits: u8,
    pub convention: NormalConvention,
    pub precision: ExrPrecision,
    pub compression: ExrCompression,
    /// How an OME-Zarr store is written.
    pub zarr: zarr::ZarrOptions,
}

impl Default for SaveOptions {
    fn default() -> Self {
        Self {
            bits: 16,
            convention: NormalConvention::OpenGl,
            precision: ExrPrecision::Full,
            compression: ExrCompression::default(),
            zarr: zarr::ZarrOptions::default(),
        }
    }
}

#[cfg(test)]
#[path = "io_tests.rs"]
mod tests;
