//! EXR writing by blocks: the planes of an image, or its rows as they come, are cut into the
//! scan-line blocks of the chosen compression (1 line for none, RLE and ZIPS; 16 for ZIP; 32
//! for PIZ), each block laid out as the format wants it (per line, the channels in name order),
//! compressed on every core, and written in order. Whole planes are never copied: a block's
//! bytes are built from the planes and dropped once it is written.

use super::openexr::{ExrCompression, ExrPrecision};
use exr::block::writer::ChunksWriter;
use exr::block::{BlockIndex, UncompressedBlock};
use exr::math::Vec2;
use exr::meta::attribute::{ChannelDescription, LineOrder, SampleType};
use exr::meta::header::Header;
use rayon::prelude::*;
use std::io::{Seek, Write};

/// How an EXR is stored: sample type and compression.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ExrFormat {
    /// 16- or 32-bit floats.
    pub precision: ExrPrecision,
    /// Compression.
    pub compression: ExrCompression,
}

/// Blocks compressed at once: enough to keep every core busy, few enough to bound memory (a
/// 16-line block of a 4K RGBN image is 1.7 MB).
const BATCH: usize = 32;

/// The single-layer scan-line header of a `width × height` image with channels `names`
/// (sorted by name, as the format requires).
fn header(width: usize, height: usize, names: &[&str], f: ExrFormat) -> Header {
    let ty = match f.precision {
        ExrPrecision::Half => SampleType::F16,
        ExrPrecision::Full => SampleType::F32,
    };
    let channels = names
        .iter()
        .map(|n| ChannelDescription::named(*n, ty))
        .collect();
    Header::new("rgbn".into(), (width, height), channels).with_encoding(
        f.compression.to_exr(),
        exr::meta::BlockDescription::ScanLines,
        LineOrder::Increasing,
    )
}

/// The uncompressed bytes of rows `rows` of `planes` (each `width` values a row, row 0 of the
/// slice being row `first` of the image): per row, each channel's samples in native byte order.
fn block_bytes(
    planes: &[&[f32]],
    width: usize,
    rows: std::ops::Range<usize>,
    half: bool,
) -> Vec<u8> {
    let size = if half { 2 } else { 4 };
    let mut out = Vec::with_capacity(rows.len() * planes.len() * width * size);
    for r in rows {
        for p in planes {
            let row = &p[r * width..(r + 1) * width];
            if half {
                for v in row {
                    out.extend_from_slice(&half::f16::from_f32(*v).to_ne_bytes());
                }
            } else {
                for v in row {
                    out.extend_from_slice(&v.to_ne_bytes());
                }
            }
        }
    }
    out
}

/// Compresses and writes the blocks covering rows `0..rows` of `planes` (local rows; image row
/// `first_row + r`), `first_row` a multiple of the block height. Returns the rows written: all
/// of them when `last` (the image's final rows), else only whole blocks.
fn write_rows<W: ChunksWriter>(
    writer: &mut W,
    headers: &[Header],
    planes: &[&[f32]],
    (width, height): (usize, usize),
    first_row: usize,
    rows: usize,
    last: bool,
) -> exr::error::Result<usize> {
    let lines = headers[0].compression.scan_lines_per_block();
    let half = headers[0].channels.list[0].sample_type == SampleType::F16;
    let whole = if last { rows } else { rows / lines * lines };
    let blocks = whole.div_ceil(lines);
    let mut b = 0;
    while b < blocks {
        let batch: Vec<exr::error::Result<(usize, exr::block::chunk::Chunk)>> = (b..(b + BATCH)
            .min(blocks))
            .into_par_iter()
            .map(|k| {
                let (r0, r1) = (k * lines, ((k + 1) * lines).min(whole));
                let y = first_row + r0;
                let block = UncompressedBlock {
                    index: BlockIndex {
                        layer: 0,
                        pixel_position: Vec2(0, y),
                        pixel_size: Vec2(width, r1 - r0),
                        level: Vec2(0, 0),
                    },
                    data: block_bytes(planes, width, r0..r1, half),
                };
                Ok((y / lines, block.compress_to_chunk(headers)?))
            })
            .collect();
        for c in batch {
            let (index, chunk) = c?;
            writer.write_chunk(index, chunk)?;
        }
        b += BATCH;
    }
    debug_assert!(first_row + whole <= height);
    Ok(whole)
}

/// Writes a `width × height` image given as named planes (any order) to `out`.
///
/// # Errors
/// The exr crate's errors, as text.
pub(crate) fn write_planes<W: Write + Seek>(
    out: W,
    (width, height): (usize, usize),
    channels: &[(&str, &[f32])],
    f: ExrFormat,
) -> Result<(), String> {
    let mut sorted: Vec<(&str, &[f32])> = channels.to_vec();
    sorted.sort_by(|a, b| a.0.cmp(b.0));
    let names: Vec<&str> = sorted.iter().map(|c| c.0).collect();
    let planes: Vec<&[f32]> = sorted.iter().map(|c| c.1).collect();
    let headers: exr::meta::Headers = std::iter::once(header(width, height, &names, f)).collect();
    exr::block::write(out, headers, true, |meta, writer| {
        write_rows(
            writer,
            &meta.headers,
            &planes,
            (width, height),
            0,
            height,
            true,
        )
        .map(|_| ())
    })
    .map_err(|e| e.to_string())
}

/// Rows arriving band by band (the streaming writer): bands are appended to a carry buffer
/// and every whole block in it is compressed and written; the rest waits for the next band.
pub(crate) struct RowBlocks {
    width: usize,
    height: usize,
    names: Vec<&'static str>,
    carry: Vec<Vec<f32>>,
    carry_rows: usize,
    written: usize,
}

impl RowBlocks {
    /// A writer of the channels `names` (sorted), `width × height`.
    pub(crate) fn new(width: usize, height: usize, names: Vec<&'static str>) -> Self {
        let carry = vec![Vec::new(); names.len()];
        Self {
            width,
            height,
            names,
            carry,
            carry_rows: 0,
            written: 0,
        }
    }

    /// The header of the file.
    pub(crate) fn header(&self, f: ExrFormat) -> Header {
        header(self.width, self.height, &self.names, f)
    }

    /// Appends a band of `rows` rows (planes in `names` order) and writes the whole blocks.
    pub(crate) fn push<W: ChunksWriter>(
        &mut self,
        writer: &mut W,
        headers: &[Header],
        planes: &[Vec<f32>],
        rows: usize,
    ) -> exr::error::Result<()> {
        for (c, p) in self.carry.iter_mut().zip(planes) {
            c.extend_from_slice(&p[..rows * self.width]);
        }
        self.carry_rows += rows;
        let last = self.written + self.carry_rows >= self.height;
        let views: Vec<&[f32]> = self.carry.iter().map(Vec::as_slice).collect();
        let done = write_rows(
            writer,
            headers,
            &views,
            (self.width, self.height),
            self.written,
            self.carry_rows,
            last,
        )?;
        let w = self.width;
        for c in &mut self.carry {
            c.drain(..done * w);
        }
        self.carry_rows -= done;
        self.written += done;
        Ok(())
    }

    /// Rows written so far.
    pub(crate) fn written(&self) -> usize {
        self.written
    }
}
