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
//!   is read whole), and [`super::zarr::ZarrRows`] for the channels of an OME-Zarr store, a
//!   row of chunks at a time; [`Rows`] is any of them, by the file's extension.

use super::ahead::ReadAhead;
use super::{open_check, png_decode_error, NormalConvention};
use crate::error::RgbnError;
use crate::raster::srgb::{srgb16_lut, srgb8_lut};
use std::fs::File;
use std::io::BufReader;
use std::mem::MaybeUninit;
use std::ops::Range;
use std::path::{Path, PathBuf};

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

/// How sample `v` of channel `k` of an 8- or 16-bit file becomes `f32` as `map` says, with the
/// arithmetic of the whole-image loaders.
#[derive(Clone, Copy)]
enum SampleFn {
    /// `v·scale − 1`, negated for a DirectX normal's `y`.
    Normal { scale: f32, negate: bool },
    /// `v / max`.
    Div(f32),
    /// A table (sRGB to linear).
    Lut(&'static [f32]),
}

impl SampleFn {
    fn of(map: RowMap, sixteen: bool, k: usize) -> Self {
        let max = if sixteen { 65535.0 } else { 255.0 };
        match map {
            RowMap::Normal(conv) => SampleFn::Normal {
                scale: 2.0 / max,
                negate: k == 1 && conv == NormalConvention::DirectX,
            },
            RowMap::Srgb if sixteen => SampleFn::Lut(srgb16_lut()),
            RowMap::Srgb => SampleFn::Lut(srgb8_lut()),
            RowMap::Unit => SampleFn::Div(max),
        }
    }

    /// `out[i] = self(sample(i))` for every `i`.
    #[inline]
    fn fill(self, out: &mut [MaybeUninit<f32>], sample: impl Fn(usize) -> u16) {
        // One loop per mapping, the mapping chosen once per plane, not per sample.
        match self {
            SampleFn::Normal {
                scale,
                negate: false,
            } => {
                for (i, o) in out.iter_mut().enumerate() {
                    o.write(f32::from(sample(i)) * scale - 1.0);
                }
            }
            SampleFn::Normal {
                scale,
                negate: true,
            } => {
                for (i, o) in out.iter_mut().enumerate() {
                    o.write(-(f32::from(sample(i)) * scale - 1.0));
                }
            }
            SampleFn::Div(max) => {
                for (i, o) in out.iter_mut().enumerate() {
                    o.write(f32::from(sample(i)) / max);
                }
            }
            SampleFn::Lut(t) => {
                for (i, o) in out.iter_mut().enumerate() {
                    o.write(t[usize::from(sample(i))]);
                }
            }
        }
    }
}

/// Rows of a file as decoded, before they become `f32` planes ([`Samples::map_rows`]): what the
/// strip driver's reading thread hands on ([`crate::raster::strips`]), so that the mapping,
/// which can be split, runs on the pool as the rows are appended to a strip's window, and the
/// reading thread, whose decoding cannot be split, only decodes. Integer samples stay in their
/// file's width (6 bytes a pixel for a 16-bit RGB PNG, not 12 as `f32` planes).
pub struct Samples {
    width: usize,
    rows: usize,
    /// Samples per pixel (interleaved data) or planes ([`SampleData::Planes`]).
    channels: usize,
    /// 16-bit samples (the scale of the mapping).
    sixteen: bool,
    data: SampleData,
}

enum SampleData {
    /// 8-bit samples, interleaved.
    U8(Vec<u8>),
    /// 16-bit samples, interleaved, as big-endian byte pairs (PNG).
    U16Be(Vec<u8>),
    /// 16-bit samples, interleaved (TIFF; its 8-bit samples widened).
    U16(Vec<u16>),
    /// One `f32` plane per channel (EXR), taken as they are.
    Planes(Vec<Vec<f32>>),
}

impl Samples {
    /// Rows held.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Writes rows `rows` (of the ones held) of channel `k` into `planes[k]` (`rows.len() ×
    /// width` values each, all written), mapped by `map` (an EXR's floats as they are); a
    /// greyscale file repeats its channel.
    ///
    /// # Panics
    /// If `rows` is not within the rows held or a plane has another length.
    pub fn map_rows(
        &self,
        rows: Range<usize>,
        planes: &mut [&mut [MaybeUninit<f32>]],
        map: RowMap,
    ) {
        assert!(rows.end <= self.rows);
        let (w, c) = (self.width, self.channels.max(1));
        let n = rows.len() * w;
        for (k, out) in planes.iter_mut().enumerate() {
            assert_eq!(out.len(), n, "a plane of {} values for {n}", out.len());
            let ch = k.min(c - 1);
            let f = SampleFn::of(map, self.sixteen, k);
            let base = rows.start * w * c + ch;
            match &self.data {
                SampleData::U8(d) => f.fill(out, |i| u16::from(d[base + i * c])),
                SampleData::U16Be(d) => f.fill(out, |i| {
                    let j = 2 * (base + i * c);
                    u16::from_be_bytes([d[j], d[j + 1]])
                }),
                SampleData::U16(d) => f.fill(out, |i| d[base + i * c]),
                SampleData::Planes(p) => {
                    let src = &p[ch][rows.start * w..rows.end * w];
                    for (o, v) in out.iter_mut().zip(src) {
                        o.write(*v);
                    }
                }
            }
        }
    }

    /// The interleaved bytes of `spare` (8- or 16-bit PNG samples), emptied, their memory kept
    /// for the next rows: a reader that reuses the band it handed on earlier writes into pages
    /// already mapped instead of fresh ones the kernel must zero on first touch (on the
    /// decoding thread, whose work cannot be split: BENCHMARKS.md, twelfth session).
    fn spare_bytes(spare: Option<Samples>) -> Vec<u8> {
        match spare.map(|s| s.data) {
            Some(SampleData::U8(mut v) | SampleData::U16Be(mut v)) => {
                v.clear();
                v
            }
            _ => Vec::new(),
        }
    }

    /// [`spare_bytes`](Self::spare_bytes) for 16-bit TIFF samples.
    fn spare_u16(spare: Option<Samples>) -> Vec<u16> {
        match spare.map(|s| s.data) {
            Some(SampleData::U16(mut v)) => {
                v.clear();
                v
            }
            _ => Vec::new(),
        }
    }

    /// [`spare_bytes`](Self::spare_bytes) for `n` EXR planes.
    fn spare_planes(spare: Option<Samples>, n: usize) -> Vec<Vec<f32>> {
        match spare.map(|s| s.data) {
            Some(SampleData::Planes(mut v)) if v.len() == n => {
                v.iter_mut().for_each(Vec::clear);
                v
            }
            _ => vec![Vec::new(); n],
        }
    }

    /// [`map_rows`](Self::map_rows) of every row held into initialised planes.
    pub fn map_into(&self, planes: &mut [&mut [f32]], map: RowMap) {
        let mut views: Vec<&mut [MaybeUninit<f32>]> = planes
            .iter_mut()
            // SAFETY: `map_rows` writes only initialised values.
            .map(|p| unsafe { as_uninit(p) })
            .collect();
        self.map_rows(0..self.rows, &mut views, map);
    }
}

/// `p` as a slice to be written through [`Samples::map_rows`].
///
/// # Safety
/// Only initialised values may be written through the result (as `map_rows` does), or `p` is
/// left uninitialised.
unsafe fn as_uninit(p: &mut [f32]) -> &mut [MaybeUninit<f32>] {
    // SAFETY: `MaybeUninit<f32>` has `f32`'s layout; the caller writes only initialised values.
    unsafe { &mut *(std::ptr::from_mut::<[f32]>(p) as *mut [MaybeUninit<f32>]) }
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
    /// Channels of an OME-Zarr store's level 0.
    Zarr(Box<super::zarr::ZarrRows>),
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

    /// Reads only `window` of the image from now on (before the first read): only an OME-Zarr
    /// store's rows can be cut to a window (its chunks cover it); a file is read whole rows.
    pub fn set_window(&mut self, window: crate::raster::window::Rect) -> Result<(), String> {
        match self {
            Rows::Zarr(r) => r.set_window(window),
            _ => Err(format!(
                "{} is read in whole rows (only OME-Zarr stores are read in windows)",
                self.path().display()
            )),
        }
    }

    /// Width and height in pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        match self {
            Rows::Png(r) => r.size(),
            Rows::Tiff(r) => (r.width, r.height),
            Rows::Exr(r) => (r.width, r.height),
            Rows::Zarr(r) => r.size(),
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
            Rows::Zarr(r) => r.channels(),
        }
    }

    /// The file.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            Rows::Png(r) => r.path(),
            Rows::Tiff(r) => &r.path,
            Rows::Exr(r) => &r.path,
            Rows::Zarr(r) => r.path(),
        }
    }

    /// Decodes the next `rows` rows as they are stored ([`Samples`]), into the memory of
    /// `spare`, samples this reader handed on earlier and no longer needed (of another kind,
    /// or `None`: fresh memory).
    pub fn read_samples_reusing(
        &mut self,
        rows: usize,
        spare: Option<Samples>,
    ) -> Result<Samples, RgbnError> {
        match self {
            Rows::Png(r) => r.read_samples_reusing(rows, spare),
            Rows::Tiff(r) => r.read_samples_reusing(rows, spare),
            Rows::Exr(r) => r.read_samples_reusing(rows, spare),
            Rows::Zarr(r) => {
                let mut planes = Samples::spare_planes(spare, r.channels());
                let before = r.size().0;
                r.read_rows(rows, &mut planes)?;
                Ok(Samples {
                    width: before,
                    rows: planes[0].len() / before.max(1),
                    channels: planes.len(),
                    sixteen: false,
                    data: SampleData::Planes(planes),
                })
            }
        }
    }
}

type ExrBlocks = exr::block::reader::SequentialBlockDecompressor<
    exr::block::reader::AllChunksReader<BufReader<ReadAhead>>,
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
        let reader = exr::block::read(
            BufReader::with_capacity(1 << 20, ReadAhead::new(file)),
            false,
        )
        .map_err(err)?;
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

    /// Reads the next `rows` rows of the chosen channels ([`Samples`]: one `f32` plane each),
    /// into the memory of `spare` where it holds planes ([`Rows::read_samples_reusing`]).
    pub fn read_samples_reusing(
        &mut self,
        rows: usize,
        spare: Option<Samples>,
    ) -> Result<Samples, RgbnError> {
        let w = self.width;
        let mut planes = Samples::spare_planes(spare, self.want.len());
        for p in &mut planes {
            p.reserve_exact(rows * w);
        }
        for _ in 0..rows {
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
            for (plane, src) in planes.iter_mut().zip(&self.buf) {
                plane.extend_from_slice(&src[y * w..(y + 1) * w]);
            }
            self.row += 1;
        }
        Ok(Samples {
            width: w,
            rows,
            channels: self.want.len(),
            sixteen: false,
            data: SampleData::Planes(planes),
        })
    }
}

/// Strips taller than this many pixels are not streamed (a TIFF written as one strip would be
/// decoded whole anyway).
const MAX_TIFF_STRIP_PIXELS: usize = 1 << 24;

/// A TIFF stored in strips, read top to bottom one strip at a time: 8- or 16-bit unsigned
/// samples, grey, grey + alpha, RGB or RGBA, interleaved.
pub struct TiffRows {
    path: PathBuf,
    dec: tiff::decoder::Decoder<BufReader<ReadAhead>>,
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
            tiff::decoder::Decoder::new(BufReader::with_capacity(1 << 20, ReadAhead::new(file)))
                .map_err(err)?;
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

    /// Decodes the next `rows` rows, as they are stored ([`Samples`]), into the memory of
    /// `spare` where it holds 16-bit samples ([`Rows::read_samples_reusing`]).
    pub fn read_samples_reusing(
        &mut self,
        rows: usize,
        spare: Option<Samples>,
    ) -> Result<Samples, RgbnError> {
        let (w, c) = (self.width, self.channels);
        let mut data = Samples::spare_u16(spare);
        data.reserve_exact(rows * w * c);
        for _ in 0..rows {
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
            data.extend_from_slice(&self.strip[off..off + w * c]);
            self.row += 1;
        }
        Ok(Samples {
            width: w,
            rows,
            channels: c,
            sixteen: self.sixteen,
            data: SampleData::U16(data),
        })
    }
}

/// A PNG read top to bottom, a band of rows at a time.
pub struct PngRows {
    path: PathBuf,
    reader: png::Reader<BufReader<ReadAhead>>,
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
        let mut dec = png::Decoder::new_with_limits(
            BufReader::with_capacity(1 << 20, ReadAhead::new(file)),
            limits,
        );
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

    /// Decodes the next `rows` rows, as they are stored ([`Samples`]: 16-bit samples as the
    /// file's big-endian byte pairs). A file that ends early is a decode error naming the row.
    pub fn read_samples(&mut self, rows: usize) -> Result<Samples, RgbnError> {
        self.read_samples_reusing(rows, None)
    }

    /// [`read_samples`](Self::read_samples) into the memory of `spare` where it holds bytes
    /// ([`Rows::read_samples_reusing`]).
    pub fn read_samples_reusing(
        &mut self,
        rows: usize,
        spare: Option<Samples>,
    ) -> Result<Samples, RgbnError> {
        let c = self.channels;
        let row_bytes = self.width * c * if self.sixteen { 2 } else { 1 };
        let mut data = Samples::spare_bytes(spare);
        data.reserve_exact(rows * row_bytes);
        for _ in 0..rows {
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
            let bytes = row.data();
            if bytes.len() < row_bytes {
                return Err(RgbnError::Decode {
                    detail: format!(
                        "row {} holds {} bytes, {row_bytes} expected",
                        self.row,
                        bytes.len()
                    ),
                    path: self.path.clone(),
                });
            }
            data.extend_from_slice(&bytes[..row_bytes]);
            self.row += 1;
        }
        Ok(Samples {
            width: self.width,
            rows,
            channels: c,
            sixteen: self.sixteen,
            data: if self.sixteen {
                SampleData::U16Be(data)
            } else {
                SampleData::U8(data)
            },
        })
    }

    /// Decodes the next `planes[0].len() / width` rows into `planes` (channel `k` into plane
    /// `k`; a greyscale file repeats its channel), mapped by `map`. A file that ends early is a
    /// decode error naming the row.
    pub fn read(&mut self, planes: &mut [&mut [f32]], map: RowMap) -> Result<(), RgbnError> {
        let rows = planes.first().map_or(0, |p| p.len() / self.width);
        self.read_samples(rows)?.map_into(planes, map);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes a `w × h` PNG of `channels` samples of `bits` per sample, sample `i` being
    /// `f(i)`.
    fn png_of(
        path: &Path,
        (w, h): (u32, u32),
        color: png::ColorType,
        bits: u8,
        f: impl Fn(usize) -> u16,
    ) {
        let channels = color.samples();
        let mut enc = png::Encoder::new(File::create(path).unwrap(), w, h);
        enc.set_color(color);
        enc.set_depth(if bits == 16 {
            png::BitDepth::Sixteen
        } else {
            png::BitDepth::Eight
        });
        let n = w as usize * h as usize * channels;
        let data: Vec<u8> = if bits == 16 {
            (0..n).flat_map(|i| f(i).to_be_bytes()).collect()
        } else {
            (0..n).map(|i| f(i) as u8).collect()
        };
        enc.write_header().unwrap().write_image_data(&data).unwrap();
    }

    /// Rows mapped in blocks of any size, as the strip driver maps them, are the formula of
    /// the whole-image loaders: a 16-bit normal `v·2/65535 − 1` (its `y` negated for DirectX),
    /// an 8-bit grey mask what [`super::super::load_mask`] reads, repeated in every plane.
    #[test]
    fn samples_mapped_in_blocks_are_the_loaders_values() {
        let d = tempfile::tempdir().unwrap();
        let (w, h) = (13usize, 11usize);
        let sample = |i: usize| ((i * 7919 + 13) % 65536) as u16;
        let np = d.path().join("n.png");
        png_of(&np, (w as u32, h as u32), png::ColorType::Rgb, 16, sample);
        let mp = d.path().join("m.png");
        png_of(
            &mp,
            (w as u32, h as u32),
            png::ColorType::Grayscale,
            8,
            |i| (i * 37 % 256) as u16,
        );

        let mut rows = PngRows::open(&np).unwrap().unwrap();
        let first = rows.read_samples(4).unwrap();
        let rest = rows.read_samples(h - 4).unwrap();
        assert_eq!((first.rows(), rest.rows()), (4, h - 4));
        for conv in [NormalConvention::OpenGl, NormalConvention::DirectX] {
            let map = RowMap::Normal(conv);
            for (band, y0) in [(&first, 0), (&rest, 4)] {
                let n = band.rows() * w;
                let mut planes = [vec![f32::NAN; n], vec![f32::NAN; n], vec![f32::NAN; n]];
                // Blocks of 1, 2 and the rest of the rows, each into its part of the planes.
                let cuts = [0, 1.min(band.rows()), 3.min(band.rows()), band.rows()];
                for c in cuts.windows(2) {
                    let [a, b, cc] = &mut planes;
                    let mut views = [
                        &mut a[c[0] * w..c[1] * w],
                        &mut b[c[0] * w..c[1] * w],
                        &mut cc[c[0] * w..c[1] * w],
                    ]
                    // SAFETY: `map_rows` writes only initialised values.
                    .map(|p| unsafe { as_uninit(p) });
                    band.map_rows(c[0]..c[1], &mut views, map);
                }
                for (k, p) in planes.iter().enumerate() {
                    for (i, v) in p.iter().enumerate() {
                        let s = f64::from(sample((y0 * w + i) * 3 + k));
                        let mut want = s * 2.0 / 65535.0 - 1.0;
                        if k == 1 && conv == NormalConvention::DirectX {
                            want = -want;
                        }
                        assert!(
                            (f64::from(*v) - want).abs() < 2e-7,
                            "{conv:?} plane {k} pixel {i} of rows {y0}..: {v} vs {want}"
                        );
                    }
                }
            }
        }

        let (_, _, want) = super::super::load_mask(&mp).unwrap();
        let mut m = PngRows::open(&mp).unwrap().unwrap();
        let band = m.read_samples(h).unwrap();
        let mut planes = [vec![0.0; w * h], vec![0.0; w * h]];
        let [a, b] = &mut planes;
        band.map_into(&mut [a, b], RowMap::Unit);
        assert_eq!(
            planes[0], want,
            "the mask as the whole-image loader reads it"
        );
        assert_eq!(planes[1], want, "a grey file repeats its channel");
        assert!(m.read_samples(1).is_err(), "past the last row is an error");
    }
}
