//! Row-streamed files: PNG read and written, TIFF and EXR read, a band of rows at a time, so an image larger than
//! memory passes through with a peak set by the band, not the image (issue 12, item 5; the
//! strip driver is [`crate::raster::strips`]).
//!
//! - [`PngRows`] decodes the next rows of a PNG into `f32` planes as a normal map, linear colour
//!   or coverage, with the arithmetic of the whole-image loaders ([`super::load_normal_map`],
//!   [`super::load_color`], [`super::load_mask`]), so a streamed image equals a loaded one.
//!   Interlaced (Adam7) files store the image in seven passes and cannot be read top to bottom:
//!   [`PngRows::open`] returns `None` for them and callers read them whole.
//! - [`TiffRows`] does the same for a TIFF stored in strips of 8- or 16-bit interleaved
//!   samples, one strip decoded at a time (a tiled or planar TIFF is read whole), and
//!   [`ExrRows`] for channels of an EXR stored in scan-line blocks top to bottom (a tiled one
//!   is read whole); [`Rows`] is any of them, by the file's extension.
//! - [`PngTarget`] / [`PngRowWriter`] encode rows of normals or colour with the encoding and
//!   compression of [`super::save_normal_map`] / [`super::save_color`] into an [`AtomicFile`]:
//!   the target appears, complete, only when [`PngTarget::commit`] succeeds.

use super::temp;
use super::{open_check, png_decode_error, png_format, NormalConvention};
use crate::error::RgbnError;
use crate::raster::srgb::{linear_to_srgb, linear_to_srgb8, srgb16_lut, srgb8_lut};
use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file written under a temporary name beside its target and renamed over it by
/// [`commit`](Self::commit); dropped uncommitted (an error, a panic), it removes the temporary
/// and leaves the target as it was. See [`temp`].
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    file: File,
    _writing: temp::WriteGuard,
}

impl AtomicFile {
    /// Starts writing `path` (its folder must exist).
    pub fn create(path: &Path) -> Result<Self, RgbnError> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !dir.is_dir() {
            return Err(RgbnError::MissingDir { path: path.into() });
        }
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
        let writing = temp::WriteGuard::begin();
        // Temporaries of this target left by a killed process are removed first.
        temp::clean_stale(dir, Some(name));
        let tmp = temp::temp_path(dir, name);
        let file = File::create(&tmp).map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: path.into(),
        })?;
        Ok(Self {
            path: path.into(),
            tmp,
            file,
            _writing: writing,
        })
    }

    /// A handle to write the bytes through (flush what buffers it before
    /// [`commit`](Self::commit)).
    pub fn handle(&self) -> Result<File, RgbnError> {
        self.file.try_clone().map_err(|e| self.error(e))
    }

    /// The error of writing the target, `detail` saying what failed.
    #[must_use]
    pub fn error(&self, detail: impl ToString) -> RgbnError {
        RgbnError::Write {
            detail: detail.to_string(),
            path: self.path.clone(),
        }
    }

    /// Flushes, syncs and renames the temporary over the target.
    pub fn commit(mut self) -> Result<(), RgbnError> {
        self.file.sync_data().map_err(|e| self.error(e))?;
        std::fs::rename(&self.tmp, &self.path).map_err(|e| self.error(e))?;
        // Renamed: nothing left to remove.
        self.tmp = PathBuf::new();
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// How decoded samples become `f32`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowMap {
    /// A normal map: `v/(2^bits−1)·2 − 1`, `y` negated in the DirectX convention.
    Normal(NormalConvention),
    /// sRGB colour to linear light.
    Srgb,
    /// `v/(2^bits−1)` (masks).
    Unit,
}

/// Sample `v` of channel `k` of an 8- or 16-bit file as `map` says, with the arithmetic of the
/// whole-image loaders.
fn sample_map(map: RowMap, sixteen: bool) -> impl Fn(u16, usize) -> f32 {
    let max = if sixteen { 65535.0 } else { 255.0 };
    let (lut8, lut16) = (srgb8_lut(), srgb16_lut());
    move |v: u16, k: usize| -> f32 {
        match map {
            RowMap::Normal(conv) => {
                let n = f32::from(v) * (2.0 / max) - 1.0;
                if k == 1 && conv == NormalConvention::DirectX {
                    -n
                } else {
                    n
                }
            }
            RowMap::Srgb if sixteen => lut16[usize::from(v)],
            RowMap::Srgb => lut8[usize::from(v)],
            RowMap::Unit => f32::from(v) / max,
        }
    }
}

/// A file read top to bottom, a band of rows at a time: a PNG ([`PngRows`]), a TIFF stored
/// in strips ([`TiffRows`]) or channels of a scan-line EXR ([`ExrRows`]).
pub enum Rows {
    /// A PNG.
    Png(Box<PngRows>),
    /// A TIFF.
    Tiff(Box<TiffRows>),
    /// Channels of an EXR.
    Exr(Box<ExrRows>),
}

impl Rows {
    /// Opens `path` (PNG or TIFF) for reading top to bottom, or says why it must be read whole
    /// (another format, an interlaced PNG, a tiled or planar TIFF, samples other than 8 or 16
    /// bits). An EXR's channels are opened by name with [`ExrRows::open`].
    pub fn open(path: &Path) -> Result<Result<Self, String>, RgbnError> {
        Ok(match super::Format::of(path)? {
            super::Format::Png => match PngRows::open(path)? {
                Some(r) => Ok(Rows::Png(Box::new(r))),
                None => Err("an interlaced PNG (its rows are not stored in order)".into()),
            },
            super::Format::Tiff => TiffRows::open(path)?.map(|r| Rows::Tiff(Box::new(r))),
            fmt => Err(format!(
                "{} (only PNG and TIFF are read row by row here; EXR channels by ExrRows)",
                format!("{fmt:?}").to_uppercase()
            )),
        })
    }

    /// Width and height in pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        match self {
            Rows::Png(r) => r.size(),
            Rows::Tiff(r) => (r.width, r.height),
            Rows::Exr(r) => (r.width, r.height),
        }
    }

    /// Samples per pixel (1 grey, 2 grey + alpha, 3 RGB, 4 RGBA; an EXR's: the channels
    /// chosen).
    #[must_use]
    pub fn channels(&self) -> usize {
        match self {
            Rows::Png(r) => r.channels(),
            Rows::Tiff(r) => r.channels,
            Rows::Exr(r) => r.want.len(),
        }
    }

    /// The file.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            Rows::Png(r) => r.path(),
            Rows::Tiff(r) => &r.path,
            Rows::Exr(r) => &r.path,
        }
    }

    /// Decodes the next `planes[0].len() / width` rows into `planes` ([`PngRows::read`]; an
    /// EXR's float samples are taken as they are, as [`super::load_exr`] does, whatever `map`).
    pub fn read(&mut self, planes: &mut [&mut [f32]], map: RowMap) -> Result<(), RgbnError> {
        match self {
            Rows::Png(r) => r.read(planes, map),
            Rows::Tiff(r) => r.read(planes, map),
            Rows::Exr(r) => r.read(planes),
        }
    }
}

type ExrBlocks = exr::block::reader::SequentialBlockDecompressor<
    exr::block::reader::AllChunksReader<BufReader<File>>,
>;

/// Channels of an EXR of one layer stored in scan-line blocks top to bottom (line order
/// increasing), read one block at a time: each sample as `f32`, as [`super::load_exr`] reads
/// it. A file opened once per group of channels (normals, colour, mask) decodes its blocks
/// once per group.
pub struct ExrRows {
    path: PathBuf,
    width: usize,
    height: usize,
    blocks: ExrBlocks,
    channels: exr::meta::attribute::ChannelList,
    /// The file's channel index of each plane read.
    want: Vec<usize>,
    /// Rows decoded and not yet read, one vector per plane, from row `buf_y0`.
    buf: Vec<Vec<f32>>,
    buf_y0: usize,
    buf_rows: usize,
    row: usize,
}

impl ExrRows {
    /// The channel names of `path`'s first layer (for choosing what to read).
    pub fn channel_names(path: &Path) -> Result<Vec<String>, RgbnError> {
        open_check(path)?;
        let meta =
            exr::meta::MetaData::read_from_file(path, false).map_err(|e| RgbnError::Decode {
                detail: e.to_string(),
                path: path.into(),
            })?;
        Ok(meta.headers.first().map_or_else(Vec::new, |h| {
            h.channels.list.iter().map(|c| c.name.to_string()).collect()
        }))
    }

    /// Opens `path` to read channels `names` top to bottom; `Err(why)` for an EXR that cannot
    /// be (tiled, several layers, another line order, subsampled channels, deep data).
    pub fn open(path: &Path, names: &[&str]) -> Result<Result<Self, String>, RgbnError> {
        open_check(path)?;
        let err = |e: exr::error::Error| RgbnError::Decode {
            detail: e.to_string(),
            path: path.into(),
        };
        let file = File::open(path).map_err(|e| RgbnError::Read {
            path: path.into(),
            source: e,
        })?;
        let reader =
            exr::block::read(BufReader::with_capacity(1 << 20, file), false).map_err(err)?;
        let headers = reader.headers();
        if headers.len() != 1 {
            return Ok(Err(format!(
                "an EXR of {} layers (read whole)",
                headers.len()
            )));
        }
        let h = &headers[0];
        if h.deep {
            return Ok(Err("a deep EXR (read whole)".into()));
        }
        if !matches!(h.blocks, exr::meta::BlockDescription::ScanLines) {
            return Ok(Err("a tiled EXR (read whole)".into()));
        }
        if h.line_order != exr::meta::attribute::LineOrder::Increasing {
            return Ok(Err(format!(
                "an EXR in line order {:?} (only increasing is read top to bottom)",
                h.line_order
            )));
        }
        if h.channels
            .list
            .iter()
            .any(|c| c.sampling != exr::math::Vec2(1, 1))
        {
            return Ok(Err("an EXR with subsampled channels (read whole)".into()));
        }
        let mut want = Vec::new();
        for n in names {
            match h
                .channels
                .list
                .iter()
                .position(|c| c.name.to_string() == *n)
            {
                Some(i) => want.push(i),
                None => {
                    let have: Vec<String> =
                        h.channels.list.iter().map(|c| c.name.to_string()).collect();
                    return Err(RgbnError::Decode {
                        detail: format!(
                            "missing channel {n} (channels present: {})",
                            have.join(",")
                        ),
                        path: path.into(),
                    });
                }
            }
        }
        let (width, height) = (h.layer_size.0, h.layer_size.1);
        if width == 0 || height == 0 {
            return Err(RgbnError::Decode {
                detail: format!("image has no pixels ({width}×{height})"),
                path: path.into(),
            });
        }
        let channels = h.channels.clone();
        use exr::block::reader::ChunksReader;
        let blocks = reader
            .all_chunks(false)
            .map_err(err)?
            .sequential_decompressor(false);
        Ok(Ok(Self {
            path: path.into(),
            width,
            height,
            blocks,
            channels,
            want,
            buf: Vec::new(),
            buf_y0: 0,
            buf_rows: 0,
            row: 0,
        }))
    }

    /// Decodes the block after the buffered rows.
    fn next_block(&mut self) -> Result<(), RgbnError> {
        let at = |detail: String, row: usize, height: usize| RgbnError::Decode {
            detail: format!("{detail} (at row {row} of {height})"),
            path: self.path.clone(),
        };
        let next = self.buf_y0 + self.buf_rows;
        let block = match self.blocks.decompress_next_block() {
            Some(Ok(b)) => b,
            Some(Err(e)) => return Err(at(e.to_string(), next, self.height)),
            None => {
                return Err(at("the image data ends".into(), next, self.height));
            }
        };
        let (y0, rows) = (block.index.pixel_position.y(), block.index.pixel_size.y());
        if y0 != next {
            return Err(at(
                format!("a block of rows {y0}.. came where rows {next}.. were due"),
                next,
                self.height,
            ));
        }
        let w = self.width;
        self.buf = vec![vec![0.0; rows * w]; self.want.len()];
        use exr::meta::attribute::SampleType as T;
        for line in block.lines(&self.channels) {
            let Some(k) = self.want.iter().position(|&c| c == line.location.channel) else {
                continue;
            };
            let y = line.location.position.y() - y0;
            let out = &mut self.buf[k][y * w..(y + 1) * w];
            let bad = |e: exr::error::Error| at(e.to_string(), y0 + y, self.height);
            match self.channels.list[line.location.channel].sample_type {
                T::F32 => line.read_samples_into_slice(out).map_err(bad)?,
                T::F16 => {
                    let mut h = vec![half::f16::ZERO; w];
                    line.read_samples_into_slice(&mut h).map_err(bad)?;
                    out.iter_mut().zip(&h).for_each(|(o, v)| *o = v.to_f32());
                }
                T::U32 => {
                    let mut u = vec![0u32; w];
                    line.read_samples_into_slice(&mut u).map_err(bad)?;
                    out.iter_mut().zip(&u).for_each(|(o, v)| *o = *v as f32);
                }
            }
        }
        (self.buf_y0, self.buf_rows) = (y0, rows);
        Ok(())
    }

    /// Reads the next `planes[0].len() / width` rows of the chosen channels into `planes`.
    pub fn read(&mut self, planes: &mut [&mut [f32]]) -> Result<(), RgbnError> {
        let w = self.width;
        let rows = planes.first().map_or(0, |p| p.len() / w);
        for r in 0..rows {
            if self.row >= self.height {
                return Err(RgbnError::Decode {
                    detail: format!("the image has only {} rows", self.height),
                    path: self.path.clone(),
                });
            }
            while self.row >= self.buf_y0 + self.buf_rows {
                self.next_block()?;
            }
            let y = self.row - self.buf_y0;
            for (k, plane) in planes.iter_mut().enumerate() {
                let src = &self.buf[k.min(self.want.len() - 1)][y * w..(y + 1) * w];
                plane[r * w..(r + 1) * w].copy_from_slice(src);
            }
            self.row += 1;
        }
        Ok(())
    }
}

/// Strips taller than this many pixels are not streamed (a TIFF written as one strip would be
/// decoded whole anyway).
const MAX_TIFF_STRIP_PIXELS: usize = 1 << 24;

/// A TIFF stored in strips, read top to bottom one strip at a time: 8- or 16-bit unsigned
/// samples, grey, grey + alpha, RGB or RGBA, interleaved.
pub struct TiffRows {
    path: PathBuf,
    dec: tiff::decoder::Decoder<BufReader<File>>,
    width: usize,
    height: usize,
    channels: usize,
    sixteen: bool,
    /// Rows per strip (the last may have fewer).
    strip_rows: usize,
    /// The decoded strip holding the next rows, its first row, and rows read so far.
    strip: Vec<u16>,
    strip_y0: usize,
    row: usize,
}

impl TiffRows {
    /// Opens `path` and reads its header; `Err(why)` for a TIFF that cannot be read in strips
    /// of rows.
    pub fn open(path: &Path) -> Result<Result<Self, String>, RgbnError> {
        open_check(path)?;
        let file = File::open(path).map_err(|e| RgbnError::Read {
            path: path.into(),
            source: e,
        })?;
        let err = |e: tiff::TiffError| RgbnError::Decode {
            detail: e.to_string(),
            path: path.into(),
        };
        let mut dec =
            tiff::decoder::Decoder::new(BufReader::with_capacity(1 << 20, file)).map_err(err)?;
        let (w, h) = dec.dimensions().map_err(err)?;
        let (width, height) = (w as usize, h as usize);
        if width == 0 || height == 0 {
            return Err(RgbnError::Decode {
                detail: format!("image has no pixels ({width}×{height})"),
                path: path.into(),
            });
        }
        use tiff::ColorType as C;
        let (channels, bits) = match dec.colortype().map_err(err)? {
            C::Gray(b) => (1, b),
            C::GrayA(b) => (2, b),
            C::RGB(b) => (3, b),
            C::RGBA(b) => (4, b),
            other => return Ok(Err(format!("a TIFF of {other:?} samples (read whole)"))),
        };
        if bits != 8 && bits != 16 {
            return Ok(Err(format!("a TIFF of {bits}-bit samples (read whole)")));
        }
        if dec.get_chunk_type() != tiff::decoder::ChunkType::Strip {
            return Ok(Err("a tiled TIFF (read whole)".into()));
        }
        let planar = dec
            .find_tag_unsigned::<u16>(tiff::tags::Tag::PlanarConfiguration)
            .map_err(err)?;
        if planar.is_some_and(|p| p != 1) {
            return Ok(Err("a TIFF with separate colour planes (read whole)".into()));
        }
        let strip_rows = dec.chunk_dimensions().1 as usize;
        if strip_rows.saturating_mul(width) > MAX_TIFF_STRIP_PIXELS {
            return Ok(Err(format!(
                "a TIFF in strips of {strip_rows} rows (each decoded whole)"
            )));
        }
        Ok(Ok(Self {
            path: path.into(),
            dec,
            width,
            height,
            channels,
            sixteen: bits == 16,
            strip_rows: strip_rows.max(1),
            strip: Vec::new(),
            strip_y0: 0,
            row: 0,
        }))
    }

    /// Decodes the strip holding row `self.row`.
    fn next_strip(&mut self) -> Result<(), RgbnError> {
        let index = self.row / self.strip_rows;
        let at = |detail: String| RgbnError::Decode {
            detail: format!(
                "{detail} (strip {index}, at row {} of {})",
                self.row, self.height
            ),
            path: self.path.clone(),
        };
        let data = self
            .dec
            .read_chunk(index as u32)
            .map_err(|e| at(e.to_string()))?;
        self.strip = match data {
            tiff::decoder::DecodingResult::U8(v) => v.into_iter().map(u16::from).collect(),
            tiff::decoder::DecodingResult::U16(v) => v,
            _ => return Err(at("unexpected sample type".into())),
        };
        let rows = (self.height - index * self.strip_rows).min(self.strip_rows);
        if self.strip.len() < rows * self.width * self.channels {
            return Err(at(format!(
                "the strip holds {} samples, {} expected",
                self.strip.len(),
                rows * self.width * self.channels
            )));
        }
        self.strip_y0 = index * self.strip_rows;
        Ok(())
    }

    /// Decodes the next `planes[0].len() / width` rows into `planes` ([`PngRows::read`]).
    pub fn read(&mut self, planes: &mut [&mut [f32]], map: RowMap) -> Result<(), RgbnError> {
        let (w, c) = (self.width, self.channels);
        let rows = planes.first().map_or(0, |p| p.len() / w);
        let f = sample_map(map, self.sixteen);
        for r in 0..rows {
            if self.row >= self.height {
                return Err(RgbnError::Decode {
                    detail: format!("the image has only {} rows", self.height),
                    path: self.path.clone(),
                });
            }
            if self.strip.is_empty() || self.row >= self.strip_y0 + self.strip_rows {
                self.next_strip()?;
            }
            let off = (self.row - self.strip_y0) * w * c;
            let data = &self.strip[off..off + w * c];
            for (k, plane) in planes.iter_mut().enumerate() {
                let ch = k.min(c - 1);
                let out = &mut plane[r * w..(r + 1) * w];
                for (x, o) in out.iter_mut().enumerate() {
                    *o = f(data[x * c + ch], k);
                }
            }
            self.row += 1;
        }
        Ok(())
    }
}

/// A PNG read top to bottom, a band of rows at a time.
pub struct PngRows {
    path: PathBuf,
    reader: png::Reader<BufReader<File>>,
    width: usize,
    height: usize,
    channels: usize,
    sixteen: bool,
    /// Rows read so far.
    row: usize,
}

impl PngRows {
    /// Opens `path` and reads its header; `None` for an interlaced file (not readable in row
    /// order). Palette and sub-byte images are expanded to 8 bits.
    pub fn open(path: &Path) -> Result<Option<Self>, RgbnError> {
        open_check(path)?;
        let file = File::open(path).map_err(|e| RgbnError::Read {
            path: path.into(),
            source: e,
        })?;
        // Rows are decoded one at a time: no image-sized buffer, so no size limit here.
        let limits = png::Limits { bytes: usize::MAX };
        let mut dec =
            png::Decoder::new_with_limits(BufReader::with_capacity(1 << 20, file), limits);
        dec.set_transformations(png::Transformations::EXPAND);
        let reader = dec.read_info().map_err(|e| png_decode_error(path, e))?;
        let info = reader.info();
        if info.interlaced {
            return Ok(None);
        }
        let (width, height) = (info.width as usize, info.height as usize);
        if width == 0 || height == 0 {
            return Err(RgbnError::Decode {
                detail: format!("image has no pixels ({width}×{height})"),
                path: path.into(),
            });
        }
        let (ct, depth) = reader.output_color_type();
        Ok(Some(Self {
            path: path.into(),
            reader,
            width,
            height,
            channels: ct.samples(),
            sixteen: depth == png::BitDepth::Sixteen,
            row: 0,
        }))
    }

    /// Width and height in pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Samples per pixel after expansion (1 grey, 2 grey + alpha, 3 RGB, 4 RGBA).
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The file.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Decodes the next `planes[0].len() / width` rows into `planes` (channel `k` into plane
    /// `k`; a greyscale file repeats its channel), mapped by `map`. A file that ends early is a
    /// decode error naming the row.
    pub fn read(&mut self, planes: &mut [&mut [f32]], map: RowMap) -> Result<(), RgbnError> {
        let w = self.width;
        let rows = planes.first().map_or(0, |p| p.len() / w);
        let c = self.channels;
        let f = sample_map(map, self.sixteen);
        for r in 0..rows {
            let row = match self.reader.next_row() {
                Ok(Some(row)) => row,
                Ok(None) => {
                    return Err(RgbnError::Decode {
                        detail: format!(
                            "the image data ends after row {} of {}",
                            self.row, self.height
                        ),
                        path: self.path.clone(),
                    })
                }
                Err(e) => {
                    let mut err = png_decode_error(&self.path, e);
                    if let RgbnError::Decode { detail, .. } = &mut err {
                        *detail = format!("{detail} (at row {} of {})", self.row, self.height);
                    }
                    return Err(err);
                }
            };
            let data = row.data();
            for (k, plane) in planes.iter_mut().enumerate() {
                let ch = k.min(c - 1);
                let out = &mut plane[r * w..(r + 1) * w];
                if self.sixteen {
                    for (x, o) in out.iter_mut().enumerate() {
                        let i = 2 * (x * c + ch);
                        *o = f(u16::from_be_bytes([data[i], data[i + 1]]), k);
                    }
                } else {
                    for (x, o) in out.iter_mut().enumerate() {
                        *o = f(u16::from(data[x * c + ch]), k);
                    }
                }
            }
            self.row += 1;
        }
        Ok(())
    }
}

/// Rows of an RGBN image on their way to an [`ExrTarget`]'s writer thread: the planes in the
/// file's (alphabetical) channel order.
struct ExrBand {
    rows: usize,
    mask: bool,
    planes: Vec<Vec<f32>>,
}

/// An RGBN image written to an EXR a band of rows at a time, as [`super::save_exr`] writes it
/// with its defaults: 32-bit floats `R,G,B`, `N.X,N.Y,N.Z` and `A` when there is a mask,
/// uncompressed, one scan line per block, line order increasing. The exr crate writes a file
/// within one call, so a thread owns the writer and the bands are sent to it (one band in
/// flight). The target appears, complete, only when [`ExrTarget::commit`] succeeds.
pub struct ExrTarget {
    tx: Option<std::sync::mpsc::SyncSender<ExrBand>>,
    thread: Option<std::thread::JoinHandle<Result<(), String>>>,
    file: Option<AtomicFile>,
    width: usize,
}

impl ExrTarget {
    /// Starts writing a `width × height` RGBN EXR at `path` (its folder must exist).
    pub fn create(path: &Path, width: usize, height: usize) -> Result<Self, RgbnError> {
        let file = AtomicFile::create(path)?;
        let handle = file.handle()?;
        let (tx, rx) = std::sync::mpsc::sync_channel::<ExrBand>(1);
        let thread = std::thread::Builder::new()
            .name("rgbn-exr-writer".into())
            .spawn(move || -> Result<(), String> {
                let Ok(first) = rx.recv() else {
                    return Err("no rows were written".into());
                };
                let names: &[&str] = if first.mask {
                    &["A", "B", "G", "N.X", "N.Y", "N.Z", "R"]
                } else {
                    &["B", "G", "N.X", "N.Y", "N.Z", "R"]
                };
                use exr::meta::attribute::{ChannelDescription, LineOrder, SampleType};
                use exr::meta::header::Header;
                let channels = names
                    .iter()
                    .map(|n| ChannelDescription::named(*n, SampleType::F32))
                    .collect();
                let header = Header::new("rgbn".into(), (width, height), channels).with_encoding(
                    exr::compression::Compression::Uncompressed,
                    exr::meta::BlockDescription::ScanLines,
                    LineOrder::Increasing,
                );
                let mut out = BufWriter::with_capacity(1 << 20, handle);
                let headers: exr::meta::Headers = std::iter::once(header).collect();
                exr::block::write(&mut out, headers, true, |meta, writer| {
                    use exr::block::writer::ChunksWriter;
                    let mut y = 0;
                    let mut band = Some(first);
                    let mut data = Vec::with_capacity(names.len() * width * 4);
                    while let Some(b) = band.take().or_else(|| rx.recv().ok()) {
                        for r in 0..b.rows {
                            data.clear();
                            for plane in &b.planes {
                                for v in &plane[r * width..(r + 1) * width] {
                                    data.extend_from_slice(&v.to_ne_bytes());
                                }
                            }
                            let block = exr::block::UncompressedBlock {
                                index: exr::block::BlockIndex {
                                    layer: 0,
                                    pixel_position: exr::math::Vec2(0, y),
                                    pixel_size: exr::math::Vec2(width, 1),
                                    level: exr::math::Vec2(0, 0),
                                },
                                data: data.clone(),
                            };
                            writer.write_chunk(y, block.compress_to_chunk(&meta.headers)?)?;
                            y += 1;
                        }
                    }
                    if y == height {
                        Ok(())
                    } else {
                        Err(exr::error::Error::Invalid(
                            format!("only {y} of {height} rows were written").into(),
                        ))
                    }
                })
                .map_err(|e| e.to_string())?;
                out.flush().map_err(|e| e.to_string())
            })
            .map_err(|e| RgbnError::Write {
                detail: format!("cannot start the EXR writer: {e}"),
                path: path.into(),
            })?;
        Ok(Self {
            tx: Some(tx),
            thread: Some(thread),
            file: Some(file),
            width,
        })
    }

    /// Writes rows `rows` of `img` (whose width is the target's) as the next rows of the file.
    pub fn write(
        &mut self,
        img: &crate::raster::RgbnImage,
        rows: std::ops::Range<usize>,
    ) -> Result<(), RgbnError> {
        let w = self.width;
        let (a, b) = (rows.start * w, rows.end * w);
        let [r, g, bl] = img.color();
        let [nx, ny, nz] = img.normal();
        let mut planes: Vec<Vec<f32>> = Vec::with_capacity(7);
        if let Some(m) = img.mask() {
            planes.push(m[a..b].to_vec());
        }
        for p in [bl, g, nx, ny, nz, r] {
            planes.push(p[a..b].to_vec());
        }
        let band = ExrBand {
            rows: rows.len(),
            mask: img.mask().is_some(),
            planes,
        };
        let sent = self.tx.as_ref().is_some_and(|tx| tx.send(band).is_ok());
        if sent {
            Ok(())
        } else {
            // The writer stopped: its error.
            Err(self
                .finish()
                .err()
                .unwrap_or_else(|| self.error("the EXR writer stopped")))
        }
    }

    fn error(&self, detail: impl ToString) -> RgbnError {
        match &self.file {
            Some(f) => f.error(detail),
            None => RgbnError::Write {
                detail: detail.to_string(),
                path: PathBuf::new(),
            },
        }
    }

    /// Ends the rows and waits for the writer.
    fn finish(&mut self) -> Result<(), RgbnError> {
        self.tx.take();
        match self.thread.take().map(std::thread::JoinHandle::join) {
            Some(Ok(Ok(()))) | None => Ok(()),
            Some(Ok(Err(e))) => Err(self.error(e)),
            Some(Err(_)) => Err(self.error("the EXR writer panicked")),
        }
    }

    /// Completes the file (every row must have been written) and renames it over the target.
    pub fn commit(mut self) -> Result<(), RgbnError> {
        self.finish()?;
        self.file.take().expect("committed once").commit()
    }
}

impl Drop for ExrTarget {
    fn drop(&mut self) {
        // The writer stops (missing rows are its error) before the temporary file goes.
        let _ = self.finish();
    }
}

/// What a [`PngRowWriter`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowEncoding {
    /// Normals as a normal map: `round((n+1)/2·(2^bits−1))` (RGB).
    Normal(NormalConvention),
    /// Linear colour as sRGB (RGB).
    Srgb,
}

/// A PNG being written: its header is out, its rows go through [`rows`](Self::rows), and
/// [`commit`](Self::commit) ends it and renames it into place.
pub struct PngTarget {
    file: AtomicFile,
    writer: png::Writer<BufWriter<File>>,
    width: usize,
    height: usize,
    bits: u8,
}

impl PngTarget {
    /// Starts `path`: a `width × height` RGB PNG of `bits` (8 or 16) per sample, compressed
    /// as [`super::save_normal_map`] does.
    pub fn create(path: &Path, width: usize, height: usize, bits: u8) -> Result<Self, RgbnError> {
        Self::start(path, width, height, bits, png::ColorType::Rgb)
    }

    /// Starts `path`: a `width × height` 8-bit RGBA PNG (pictures), written with
    /// [`PngRowWriter::write_rgba8`].
    pub fn create_rgba8(path: &Path, width: usize, height: usize) -> Result<Self, RgbnError> {
        Self::start(path, width, height, 8, png::ColorType::Rgba)
    }

    fn start(
        path: &Path,
        width: usize,
        height: usize,
        bits: u8,
        color: png::ColorType,
    ) -> Result<Self, RgbnError> {
        let file = AtomicFile::create(path)?;
        let out = BufWriter::with_capacity(1 << 20, file.handle()?);
        let (w, h) = (
            u32::try_from(width).map_err(|e| file.error(e))?,
            u32::try_from(height).map_err(|e| file.error(e))?,
        );
        let mut enc = png::Encoder::new(out, w, h);
        png_format(&mut enc, color, bits == 16);
        let writer = enc.write_header().map_err(|e| file.error(e))?;
        Ok(Self {
            file,
            writer,
            width,
            height,
            bits,
        })
    }

    /// The row writer (call once; its [`finish`](PngRowWriter::finish) before
    /// [`commit`](Self::commit)).
    pub fn rows(&mut self, encoding: RowEncoding) -> Result<PngRowWriter<'_>, RgbnError> {
        let stream = self
            .writer
            .stream_writer_with_size(1 << 16)
            .map_err(|e| self.file.error(e))?;
        Ok(PngRowWriter {
            stream,
            path: &self.file.path,
            width: self.width,
            height: self.height,
            sixteen: self.bits == 16,
            encoding,
            row: 0,
            bytes: Vec::new(),
        })
    }

    /// Ends the PNG and renames it over the target.
    pub fn commit(self) -> Result<(), RgbnError> {
        let Self { file, writer, .. } = self;
        writer.finish().map_err(|e| file.error(e))?;
        file.commit()
    }
}

/// The rows of a [`PngTarget`], a band at a time.
pub struct PngRowWriter<'a> {
    stream: png::StreamWriter<'a, BufWriter<File>>,
    path: &'a Path,
    width: usize,
    height: usize,
    sixteen: bool,
    encoding: RowEncoding,
    /// Rows written so far.
    row: usize,
    bytes: Vec<u8>,
}

impl PngRowWriter<'_> {
    fn error(&self, detail: impl ToString) -> RgbnError {
        RgbnError::Write {
            detail: detail.to_string(),
            path: self.path.into(),
        }
    }

    /// Encodes planes `[a, b, c]` (normal x, y, z or linear R, G, B) into `self.bytes` as PNG
    /// samples, with the arithmetic of the whole-image writers.
    fn encode(&mut self, planes: [&[f32]; 3]) {
        use rayon::prelude::*;
        const CHUNK: usize = 4096;
        let n = planes[0].len();
        let sixteen = self.sixteen;
        let per = if sixteen { 6 } else { 3 };
        self.bytes.clear();
        self.bytes.resize(n * per, 0);
        let scale = if sixteen { 65535.0 } else { 255.0 };
        let enc = self.encoding;
        let sample = move |v: f32, k: usize| -> u16 {
            match enc {
                RowEncoding::Normal(conv) => {
                    let v = if k == 1 && conv == NormalConvention::DirectX {
                        -v
                    } else {
                        v
                    };
                    ((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * scale + 0.5).min(scale) as u16
                }
                RowEncoding::Srgb if sixteen => {
                    (linear_to_srgb(v.clamp(0.0, 1.0)) * 65535.0 + 0.5) as u16
                }
                RowEncoding::Srgb => u16::from(linear_to_srgb8(v)),
            }
        };
        self.bytes
            .par_chunks_mut(CHUNK * per)
            .enumerate()
            .for_each(|(ci, out)| {
                let base = ci * CHUNK;
                for (i, px) in out.chunks_exact_mut(per).enumerate() {
                    for (k, plane) in planes.iter().enumerate() {
                        let s = sample(plane[base + i], k);
                        if sixteen {
                            px[2 * k..2 * k + 2].copy_from_slice(&s.to_be_bytes());
                        } else {
                            px[k] = s as u8;
                        }
                    }
                }
            });
    }

    /// Appends the next rows: planes `[a, b, c]` of the same whole number of rows.
    pub fn write(&mut self, planes: [&[f32]; 3]) -> Result<(), RgbnError> {
        let rows = planes[0].len() / self.width;
        if self.row + rows > self.height {
            return Err(self.error(format!(
                "{} rows written to a {}-row image",
                self.row + rows,
                self.height
            )));
        }
        self.encode(planes);
        self.row += rows;
        let r = self.stream.write_all(&self.bytes);
        r.map_err(|e| self.error(e))
    }

    /// Appends the next rows of an RGBA target: `4 · width` bytes per row.
    pub fn write_rgba8(&mut self, bytes: &[u8]) -> Result<(), RgbnError> {
        let rows = bytes.len() / (4 * self.width);
        if self.row + rows > self.height {
            return Err(self.error(format!(
                "{} rows written to a {}-row image",
                self.row + rows,
                self.height
            )));
        }
        self.row += rows;
        let r = self.stream.write_all(bytes);
        r.map_err(|e| self.error(e))
    }

    /// Checks that every row was written and ends the image data.
    pub fn finish(self) -> Result<(), RgbnError> {
        if self.row != self.height {
            return Err(self.error(format!(
                "only {} of {} rows were written",
                self.row, self.height
            )));
        }
        let path = self.path;
        self.stream.finish().map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: path.into(),
        })
    }
}
