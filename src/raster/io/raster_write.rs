//! Writing interleaved 8- and 16-bit samples as PNG, TIFF or JPEG (atomically, through
//! [`super::write_atomic`]).

use super::{ptm_not_a_raster, write_atomic, Format};
use crate::error::RgbnError;
use crate::raster::buf;
use rayon::prelude::*;
use std::path::Path;

fn color_type(channels: usize, sixteen: bool) -> image::ExtendedColorType {
    use image::ExtendedColorType as C;
    match (channels, sixteen) {
        (1, false) => C::L8,
        (1, true) => C::L16,
        (4, false) => C::Rgba8,
        (4, true) => C::Rgba16,
        (_, false) => C::Rgb8,
        (_, true) => C::Rgb16,
    }
}

/// PNG row filter for 16-bit files (normal maps, the large time-critical case): `Up` pairs with
/// the `png` crate's fast (fdeflate) compressor; adaptive filtering (trying all five filters
/// per row) cost more time than it saved. 8-bit files (colour, masks, small) keep adaptive
/// filtering, i.e. the bytes the image crate wrote before.
const PNG16_FILTER: png::Filter = png::Filter::Up;

/// Sets every PNG rgbn writes to the same format: `color`, 8 or 16 bits, fast compression,
/// [`PNG16_FILTER`] for 16 bits and adaptive filtering for 8.
pub(super) fn png_format<W: std::io::Write>(
    enc: &mut png::Encoder<'_, W>,
    color: png::ColorType,
    sixteen: bool,
) {
    enc.set_color(color);
    enc.set_depth(if sixteen {
        png::BitDepth::Sixteen
    } else {
        png::BitDepth::Eight
    });
    enc.set_compression(png::Compression::Fast);
    enc.set_filter(if sixteen {
        PNG16_FILTER
    } else {
        png::Filter::Adaptive
    });
}

/// Writes a PNG with the `png` crate (fast compression). `bytes` are the samples, 16-bit ones
/// big-endian as PNG stores them.
fn encode_png(
    bytes: &[u8],
    w: usize,
    h: usize,
    channels: usize,
    sixteen: bool,
    path: &Path,
) -> Result<(), RgbnError> {
    encode_png_text(bytes, w, h, channels, sixteen, &[], path)
}

/// Writes 8-bit RGBA samples as a PNG carrying `text` as tEXt chunks (keyword, value), e.g.
/// `rgbn:curvature_scale` written by `rgbn render --view curvature`.
pub fn write_png8_text(
    rgba: &[u8],
    w: usize,
    h: usize,
    text: &[(&str, &str)],
    path: &Path,
) -> Result<(), RgbnError> {
    encode_png_text(rgba, w, h, 4, false, text, path)
}

fn encode_png_text(
    bytes: &[u8],
    w: usize,
    h: usize,
    channels: usize,
    sixteen: bool,
    text: &[(&str, &str)],
    path: &Path,
) -> Result<(), RgbnError> {
    write_atomic(path, |out| {
        let mut enc = png::Encoder::new(out, w as u32, h as u32);
        for (k, v) in text {
            enc.add_text_chunk((*k).to_string(), (*v).to_string())
                .map_err(|e| e.to_string())?;
        }
        png_format(
            &mut enc,
            match channels {
                1 => png::ColorType::Grayscale,
                2 => png::ColorType::GrayscaleAlpha,
                4 => png::ColorType::Rgba,
                _ => png::ColorType::Rgb,
            },
            sixteen,
        );
        let mut wr = enc.write_header().map_err(|e| e.to_string())?;
        wr.write_image_data(bytes).map_err(|e| e.to_string())?;
        wr.finish().map_err(|e| e.to_string())
    })
}

fn encode_raster(
    bytes: &[u8],
    w: usize,
    h: usize,
    ct: image::ExtendedColorType,
    fmt: Format,
    path: &Path,
) -> Result<(), RgbnError> {
    use image::ImageEncoder;
    write_atomic(path, |out| {
        let r = match fmt {
            Format::Tiff => image::codecs::tiff::TiffEncoder::new(out)
                .write_image(bytes, w as u32, h as u32, ct),
            Format::Jpeg => image::codecs::jpeg::JpegEncoder::new_with_quality(out, 95)
                .write_image(bytes, w as u32, h as u32, ct),
            Format::Png | Format::Exr | Format::Ptm | Format::Rti | Format::Zarr => {
                unreachable!(
                    "PNG: encode_png; EXR: the exr crate; PTM, RTI, Zarr: refused by the callers"
                )
            }
        };
        r.map_err(|e| e.to_string())
    })
}

/// A PTM or an OME-Zarr store is not written from interleaved samples: the error naming the
/// writer to use instead.
fn refuse_non_raster(fmt: Format, path: &Path) -> Result<(), RgbnError> {
    match fmt {
        Format::Ptm | Format::Rti => Err(ptm_not_a_raster(path)),
        Format::Zarr => Err(super::zarr::not_a_raster(path)),
        _ => Ok(()),
    }
}

/// Writes interleaved 8-bit samples (1, 3 or 4 channels) as PNG/TIFF/JPEG.
pub fn write_raster8(
    data: &[u8],
    w: usize,
    h: usize,
    channels: usize,
    fmt: Format,
    path: &Path,
) -> Result<(), RgbnError> {
    refuse_non_raster(fmt, path)?;
    if fmt == Format::Png {
        return encode_png(data, w, h, channels, false, path);
    }
    encode_raster(data, w, h, color_type(channels, false), fmt, path)
}

/// Writes interleaved 16-bit samples as PNG/TIFF.
pub fn write_raster16(
    data: &[u16],
    w: usize,
    h: usize,
    channels: usize,
    fmt: Format,
    path: &Path,
) -> Result<(), RgbnError> {
    refuse_non_raster(fmt, path)?;
    if fmt == Format::Jpeg {
        return Err(RgbnError::UnsupportedFormat {
            format: "jpeg (8-bit only; use .png or .tif for 16 bit)".into(),
            path: path.into(),
        });
    }
    // PNG stores big-endian samples; the image crate's TIFF encoder takes native order.
    let png = fmt == Format::Png;
    let mut bytes = buf::zeroed_u8(data.len() * 2);
    bytes
        .par_chunks_mut(2 << 16)
        .zip(data.par_chunks(1 << 16))
        .for_each(|(d, s)| {
            for (d, v) in d.chunks_exact_mut(2).zip(s) {
                d.copy_from_slice(&if png {
                    v.to_be_bytes()
                } else {
                    v.to_ne_bytes()
                });
            }
        });
    if png {
        return encode_png(&bytes, w, h, channels, true, path);
    }
    encode_raster(&bytes, w, h, color_type(channels, true), fmt, path)
}
