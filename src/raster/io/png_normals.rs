//! A PNG normal map decoded in a pipeline: the calling thread inflates and unfilters rows (the
//! part of PNG decoding that cannot be split: one deflate stream, each row's filter reading
//! the row above) while a second thread turns finished batches of rows into the image's
//! planes (`v/(2^bits−1)·2−1`, the default albedo, the validation counts).
//!
//! The one-shot path it replaces decoded the whole file into a byte buffer, converted that to
//! `u16` in a second buffer, split it into float planes in a third pass and validated the
//! planes in a fourth: three image-sized buffers touched for the first time (page faults) and
//! the conversion waiting for the last row. Here the planes are written while the file is
//! still being decoded, from batch buffers that stay in cache, and the counts of
//! [`RgbnImage::validate`] come with them. The numbers are the same, bit for bit: the same
//! formula per sample, the same counts (`tests`).
//!
//! With one thread ([`crate::raster::par::pipelined`] false) each batch is converted right
//! after it is decoded, on the calling thread: the same numbers, one thread of work.
//!
//! Only the common case takes this path: a non-interlaced 8- or 16-bit RGB or RGBA PNG. Others
//! (palette, greyscale, interlaced) go through the one-shot decoder.

use super::{png_decode_error, png_reader, DEFAULT_ALBEDO};
use crate::error::RgbnError;
use crate::raster::{buf, check_size, RgbnImage, Validation};
use std::path::Path;
use std::sync::mpsc;

/// Rows per batch handed to the converting thread: 4K rows of 16-bit RGB are 23 KB each, so a
/// batch is about 0.7 MB (a few fit in L2 beside the decoder's window).
const BATCH_ROWS: usize = 32;

/// Batches in flight (being filled, queued, being converted).
const BATCHES: usize = 4;

/// What a PNG sample is decoded from.
#[derive(Clone, Copy)]
enum Depth {
    Eight,
    Sixteen,
}

/// Decodes `path` as a normal map in a pipeline (module docs), with `ny` negated when
/// `flip_y` (DirectX maps). `Ok(None)` when the file is not a non-interlaced 8/16-bit RGB(A)
/// PNG (the caller decodes it the one-shot way). The validation counts are those of
/// [`RgbnImage::validate`] of the result.
///
/// # Errors
/// The file cannot be opened or decoded, or it is larger than rgbn reads.
pub(super) fn decode_png_normals(
    path: &Path,
    flip_y: bool,
) -> Result<Option<(RgbnImage, Validation)>, RgbnError> {
    let err = |e: png::DecodingError| png_decode_error(path, e);
    let mut reader = png_reader(path, png::Transformations::IDENTITY)?;
    let (w, h, channels, depth) = {
        let i = reader.info();
        let channels = match i.color_type {
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            _ => return Ok(None),
        };
        let depth = match i.bit_depth {
            png::BitDepth::Eight => Depth::Eight,
            png::BitDepth::Sixteen => Depth::Sixteen,
            _ => return Ok(None),
        };
        if i.interlaced {
            return Ok(None);
        }
        (i.width as usize, i.height as usize, channels, depth)
    };
    check_size(w, h, &path.display().to_string())?;
    let line = reader
        .output_line_size(w as u32)
        .ok_or_else(|| RgbnError::Decode {
            detail: "image too large for this machine".into(),
            path: path.into(),
        })?;
    let n = w * h;
    let mut normal = buf::zeroed_planes(n);
    let mut color = buf::zeroed_planes(n);
    let layout = RowLayout {
        w,
        channels,
        depth,
        line,
        flip_y,
    };
    // Decodes the next batch of rows (from row `y`) into `batch`.
    let mut decode = |y: usize, batch: &mut Vec<u8>| -> Result<(), RgbnError> {
        let rows = BATCH_ROWS.min(h - y);
        batch.resize(rows * line, 0);
        for (k, row) in batch.chunks_exact_mut(line).enumerate() {
            match reader.read_row(row) {
                Ok(Some(_)) => {}
                Ok(None) => {
                    return Err(RgbnError::Decode {
                        detail: format!("the image data ends at row {} of {h}", y + k + 1),
                        path: path.into(),
                    })
                }
                Err(e) => return Err(err(e)),
            }
        }
        Ok(())
    };
    let decoded = if crate::raster::par::pipelined() {
        let (full_tx, full_rx) = mpsc::sync_channel::<(usize, Vec<u8>)>(BATCHES);
        let (empty_tx, empty_rx) = mpsc::sync_channel::<Vec<u8>>(BATCHES);
        for _ in 0..BATCHES {
            empty_tx
                .send(vec![0u8; BATCH_ROWS * line])
                .expect("the receiver is alive");
        }
        std::thread::scope(|s| {
            let (normal, color) = (&mut normal, &mut color);
            let converter = s.spawn(move || {
                let mut v = Validation::default();
                for (y0, batch) in full_rx {
                    v = v.merge(layout.convert_batch(y0, &batch, normal, color));
                    // The decoder may be gone (an error): the buffer is then simply dropped.
                    let _ = empty_tx.send(batch);
                }
                v
            });
            let mut y = 0;
            let result: Result<(), RgbnError> = loop {
                if y == h {
                    break Ok(());
                }
                let mut batch = empty_rx.recv().expect("the converter returns every batch");
                if let Err(e) = decode(y, &mut batch) {
                    break Err(e);
                }
                let rows = batch.len() / line;
                full_tx.send((y, batch)).expect("the converter is alive");
                y += rows;
            };
            drop(full_tx);
            let counts = converter
                .join()
                .expect("the converting thread does not panic");
            result.map(|()| counts)
        })
    } else {
        // One thread: each batch is converted right after it is decoded.
        let mut batch = vec![0u8; BATCH_ROWS * line];
        let mut v = Validation::default();
        let mut y = 0;
        while y < h {
            decode(y, &mut batch)?;
            v = v.merge(layout.convert_batch(y, &batch, &mut normal, &mut color));
            y += batch.len() / line;
        }
        Ok(v)
    };
    let counts = decoded?;
    let img = RgbnImage::new(w, h, color, normal, None)?;
    Ok(Some((img, counts)))
}

/// The layout of the decoded rows and what to do with them.
#[derive(Clone, Copy)]
struct RowLayout {
    w: usize,
    channels: usize,
    depth: Depth,
    line: usize,
    flip_y: bool,
}

impl RowLayout {
    /// Turns the decoded rows `batch` (from image row `y0`) into the image's pixels: normals,
    /// the default albedo, and their validation counts.
    fn convert_batch(
        &self,
        y0: usize,
        batch: &[u8],
        normal: &mut [Vec<f32>; 3],
        color: &mut [Vec<f32>; 3],
    ) -> Validation {
        let w = self.w;
        let rows = batch.len() / self.line;
        let px = y0 * w..(y0 + rows) * w;
        let [nx, ny, nz] = normal.each_mut();
        let [cr, cg, cb] = color.each_mut();
        let (nx, ny, nz) = (
            &mut nx[px.clone()],
            &mut ny[px.clone()],
            &mut nz[px.clone()],
        );
        self.convert(batch, [&mut *nx, &mut *ny, &mut *nz]);
        let (cr, cg, cb) = (&mut cr[px.clone()], &mut cg[px.clone()], &mut cb[px]);
        for c in [&mut *cr, &mut *cg, &mut *cb] {
            c.fill(DEFAULT_ALBEDO);
        }
        Validation::of_pixels([cr, cg, cb], [nx, ny, nz], None)
    }

    /// Converts a batch of decoded rows into its normal planes' pixels.
    fn convert(&self, batch: &[u8], [nx, ny, nz]: [&mut [f32]; 3]) {
        let c = self.channels;
        let sign = if self.flip_y { -1.0f32 } else { 1.0 };
        let mut i = 0;
        for row in batch.chunks_exact(self.line) {
            let (nx, ny, nz) = (
                &mut nx[i..i + self.w],
                &mut ny[i..i + self.w],
                &mut nz[i..i + self.w],
            );
            match self.depth {
                Depth::Sixteen => {
                    let s = |px: &[u8], k: usize| {
                        f32::from(u16::from_be_bytes([px[2 * k], px[2 * k + 1]])) * (2.0 / 65535.0)
                            - 1.0
                    };
                    for (x, px) in row.chunks_exact(2 * c).enumerate() {
                        (nx[x], ny[x], nz[x]) = (s(px, 0), sign * s(px, 1), s(px, 2));
                    }
                }
                Depth::Eight => {
                    let s = |px: &[u8], k: usize| f32::from(px[k]) * (2.0 / 255.0) - 1.0;
                    for (x, px) in row.chunks_exact(c).enumerate() {
                        (nx[x], ny[x], nz[x]) = (s(px, 0), sign * s(px, 1), s(px, 2));
                    }
                }
            }
            i += self.w;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{decode_normal_map, load, InputSpec, LoadOptions, NormalConvention};
    use super::*;

    /// Writes a `w × h` PNG of `channels` channels at `bits` bits whose samples run through
    /// every value (a different stride per channel), with a patch of mid-grey (a zero-length
    /// normal once decoded) and a row of zeros (a back-facing, non-unit one).
    fn write_png(path: &Path, w: usize, h: usize, channels: usize, bits: u8) {
        let max = (1u32 << bits) - 1;
        let sample = |x: usize, y: usize, k: usize| -> u32 {
            if (3..6).contains(&x) && (3..6).contains(&y) {
                return max.div_ceil(2);
            }
            if y == h - 2 {
                return 0;
            }
            ((x * 7919 + y * 104_729 + k * 3571) as u32 * (k as u32 + 1)) % (max + 1)
        };
        let mut bytes = Vec::new();
        for y in 0..h {
            for x in 0..w {
                for k in 0..channels {
                    let v = sample(x, y, k);
                    if bits == 16 {
                        bytes.extend_from_slice(&(v as u16).to_be_bytes());
                    } else {
                        bytes.push(v as u8);
                    }
                }
            }
        }
        let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        let mut enc = png::Encoder::new(file, w as u32, h as u32);
        enc.set_color(if channels == 4 {
            png::ColorType::Rgba
        } else {
            png::ColorType::Rgb
        });
        enc.set_depth(if bits == 16 {
            png::BitDepth::Sixteen
        } else {
            png::BitDepth::Eight
        });
        enc.write_header()
            .unwrap()
            .write_image_data(&bytes)
            .unwrap();
    }

    fn bits(img: &RgbnImage) -> Vec<u32> {
        let [a, b, c] = img.normal();
        let [d, e, f] = img.color();
        [a, b, c, d, e, f]
            .iter()
            .flat_map(|p| p.iter().map(|v| v.to_bits()))
            .collect()
    }

    /// The pipeline gives the one-shot decoder's image bit for bit, and `validate`'s counts,
    /// for 8- and 16-bit RGB and RGBA, both green conventions, and a height that is not a
    /// multiple of the batch.
    #[test]
    fn the_pipeline_equals_the_one_shot_decoder() {
        let dir = tempfile::tempdir().unwrap();
        for (channels, bits_per) in [(3, 8), (4, 8), (3, 16), (4, 16)] {
            let (w, h) = (37, 2 * BATCH_ROWS + 7);
            let path = dir.path().join(format!("n{channels}_{bits_per}.png"));
            write_png(&path, w, h, channels, bits_per);
            for convention in [NormalConvention::OpenGl, NormalConvention::DirectX] {
                let opts = LoadOptions {
                    convention,
                    ..LoadOptions::default()
                };
                let (fast, counts) =
                    decode_png_normals(&path, convention == NormalConvention::DirectX)
                        .unwrap()
                        .expect("an RGB(A) PNG takes the pipeline");
                let slow = decode_normal_map(&path, &opts).unwrap();
                let what = format!("{channels} channels, {bits_per} bits, {convention:?}");
                assert!(bits(&fast) == bits(&slow), "{what}");
                assert_eq!(counts, slow.validate(), "{what}");
                assert!(
                    counts.zero_length_normal >= 9 && counts.back_facing >= w,
                    "{what}: {counts:?}"
                );
                // And the whole load (repair included) agrees with the counts it reports.
                let spec = InputSpec {
                    normal: Some(path.clone()),
                    ..InputSpec::default()
                };
                let loaded = load(&spec, &opts).unwrap();
                assert_eq!(loaded.repaired, counts, "{what}");
            }
        }
    }

    /// A file cut short is a decode error naming it, never a panic or a partial image.
    #[test]
    fn a_truncated_png_is_a_decode_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cut.png");
        write_png(&path, 64, 3 * BATCH_ROWS, 3, 16);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let e = decode_png_normals(&path, false).unwrap_err();
        assert!(matches!(e, RgbnError::Decode { .. }), "{e}");
        assert!(e.to_string().contains("cut.png"), "{e}");
    }

    /// Greyscale and palette PNGs are not taken (the one-shot decoder handles them).
    #[test]
    fn other_pngs_are_left_to_the_one_shot_decoder() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grey.png");
        let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let mut enc = png::Encoder::new(file, 4, 4);
        enc.set_color(png::ColorType::Grayscale);
        enc.write_header()
            .unwrap()
            .write_image_data(&[128; 16])
            .unwrap();
        assert!(decode_png_normals(&path, false).unwrap().is_none());
    }
}
