//! OME-Zarr stores: a path ending in `.zarr` is a folder holding an image as an OME-Zarr
//! multiscale image (NGFF, <https://ngff.openmicroscopy.org/>), read and written with the
//! `zarrs` crate.
//!
//! **Written**: NGFF 0.5 on Zarr v3. One array per level (`0`, `1`, …) of shape `(c, y, x)`;
//! the channels are named in `omero.channels[].label` and in the `rgbn` attribute:
//!
//! | content | channels | data type |
//! |---|---|---|
//! | RGBN image | `R, G, B` (linear colour), `nx, ny, nz` (unit normal, `+y` up), `mask` when there is one | float32 (default), float16 or uint16 |
//! | picture (a render) | `R, G, B, A` (sRGB bytes, as the PNG) | uint8 |
//! | mask | `mask` | as an image |
//! | scalar field (a height, a curl map) | `value` | float32 or float16 |
//!
//! uint16 stores `round((n + 1) / 2 · 65535)` for a normal component and `round(v · 65535)` for
//! linear colour and coverage (both clamped to their range), and reads them back as
//! `v / 65535 · 2 − 1` and `v / 65535`.
//!
//! A chunk holds every channel of a `chunk × chunk` square (`--chunk`, [`DEFAULT_CHUNK`]);
//! with `--shard S` the arrays are sharded, `S × S` pixels a shard. **Levels** are the engine's
//! levels of detail ([`crate::raster::pyramid`]): level `k` is level 0 reduced by `2^k` (block
//! means, coverage-weighted, normals renormalised), its coordinate transformation a scale of
//! `2^k` and a translation of `(2^k − 1)/2` (pixel centres). Level `k`'s chunks are
//! `chunk / 2^k` pixels a side, so every level's chunk `(i, j)` covers the same pixels of the
//! image as level 0's: a chunk-aligned region is written whole at every level by the process
//! that computes it, with no other process's pixels (see `docs/distributed.md`). Levels stop
//! where a chunk would be under 32 pixels or the level under 32 pixels a side.
//!
//! **Read**: NGFF 0.5 on Zarr v3 and NGFF 0.4 on Zarr v2 (float32, float16, uint16, uint8;
//! zstd, blosc, gzip), axes `c`, `y`, `x` in any order with any other axis of size 1; the
//! channels by their labels (`R`, `G`, `B`, `nx`, `ny`, `nz`, `mask`, `A`, `value`, any case).
//! A region or level reads the chunks that cover it and no others ([`ZarrImage::read`]);
//! [`chunks_read`] counts them. A chunk missing from a store rgbn wrote (a region not yet
//! written) is an error; in other stores it is the fill value, as Zarr has it.

mod read;
mod store;
mod write;
mod write_levels;

pub use read::{ZarrImage, ZarrRows};
pub use store::chunks_read;
pub use write::{save_planes_zarr, save_zarr, ZarrRowWriter, ZarrWriter};

use crate::error::RgbnError;
use std::path::Path;

/// Chunk side in pixels when none is chosen: the region engine's tile for whole-image work
/// ([`crate::eval::region`]'s 512), so a tile reads exactly one chunk; its size and speed
/// against 256 and 1024: BENCHMARKS.md, thirteenth session.
pub const DEFAULT_CHUNK: usize = 512;

/// No level's chunk is below this side, and no level's image.
pub const MIN_LEVEL_SIDE: usize = 32;

/// Whether `path` names an OME-Zarr store (its extension is `.zarr`, any case).
#[must_use]
pub fn is_zarr(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("zarr"))
}

/// Data type of a written store.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum ZarrDtype {
    /// 32-bit floats: exact.
    #[default]
    F32,
    /// 16-bit half floats: half the bytes, ~3 decimal digits.
    F16,
    /// 16-bit integers over each channel's range (module docs).
    U16,
}

impl ZarrDtype {
    /// Every data type, in menu order.
    pub const ALL: [Self; 3] = [Self::F32, Self::F16, Self::U16];
    /// The name on the command line, in graph files and in the Zarr metadata.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::F32 => "float32",
            Self::F16 => "float16",
            Self::U16 => "uint16",
        }
    }
}

impl crate::params::Choice for ZarrDtype {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        Self::name(self)
    }
    fn doc(self) -> &'static str {
        match self {
            Self::F32 => "32-bit floats: exact (the default).",
            Self::F16 => "16-bit half floats: half the size, ~3 decimal digits.",
            Self::U16 => "16-bit integers over each channel's range: normals in [-1, 1], colour and mask in [0, 1].",
        }
    }
}

/// Compression of a written store's chunks (lossless).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum ZarrCompression {
    /// zstd (level 1), the Zarr v3 core codec.
    #[default]
    Zstd,
    /// Blosc: byte shuffle, then zstd (level 1) inside.
    Blosc,
    /// None.
    None,
}

impl ZarrCompression {
    /// Every compression, in menu order.
    pub const ALL: [Self; 3] = [Self::Zstd, Self::Blosc, Self::None];
    /// The name on the command line and in graph files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Zstd => "zstd",
            Self::Blosc => "blosc",
            Self::None => "none",
        }
    }
}

impl crate::params::Choice for ZarrCompression {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        Self::name(self)
    }
    fn doc(self) -> &'static str {
        match self {
            Self::Zstd => "zstd, level 1 (the default).",
            Self::Blosc => "Blosc: byte shuffle, then zstd level 1.",
            Self::None => "No compression (largest stores).",
        }
    }
}

/// How a store is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ZarrOptions {
    /// Data type (pictures are always uint8).
    pub dtype: ZarrDtype,
    /// Compression.
    pub compression: ZarrCompression,
    /// Chunk side at level 0, in pixels.
    pub chunk: usize,
    /// Shard side at level 0, in pixels (a multiple of `chunk`); 0: no sharding.
    pub shard: usize,
    /// Most levels to write (level 0 included); `None`: as many as [`MIN_LEVEL_SIDE`] allows.
    pub levels: Option<usize>,
}

impl Default for ZarrOptions {
    fn default() -> Self {
        Self {
            dtype: ZarrDtype::F32,
            compression: ZarrCompression::Zstd,
            chunk: DEFAULT_CHUNK,
            shard: 0,
            levels: None,
        }
    }
}

/// What a store holds (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Content {
    /// An RGBN image, with or without a mask.
    Rgbn {
        /// A `mask` channel.
        mask: bool,
    },
    /// An sRGB RGBA picture.
    Picture,
    /// A coverage mask.
    Mask,
    /// A scalar field.
    Scalar,
}

impl Content {
    /// The channel labels, in order.
    #[must_use]
    pub fn channels(self) -> Vec<&'static str> {
        match self {
            Content::Rgbn { mask } => {
                let mut c = vec!["R", "G", "B", "nx", "ny", "nz"];
                if mask {
                    c.push("mask");
                }
                c
            }
            Content::Picture => vec!["R", "G", "B", "A"],
            Content::Mask => vec!["mask"],
            Content::Scalar => vec!["value"],
        }
    }

    /// The name in the `rgbn` attribute.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Content::Rgbn { .. } => "rgbn",
            Content::Picture => "picture",
            Content::Mask => "mask",
            Content::Scalar => "scalar",
        }
    }
}

/// What a channel is, by its label.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Colour (`R`, `G`, `B`: index 0–2).
    Color(usize),
    /// A normal component (`nx`, `ny`, `nz`).
    Normal(usize),
    /// Coverage.
    Mask,
    /// A picture's alpha.
    Alpha,
    /// A scalar field's value.
    Value,
    /// Anything else.
    Other,
}

impl Role {
    /// The role of a channel labelled `label` (any case).
    #[must_use]
    pub fn of(label: &str) -> Self {
        match label.to_ascii_lowercase().as_str() {
            "r" | "red" => Role::Color(0),
            "g" | "green" => Role::Color(1),
            "b" | "blue" => Role::Color(2),
            "nx" | "n.x" => Role::Normal(0),
            "ny" | "n.y" => Role::Normal(1),
            "nz" | "n.z" => Role::Normal(2),
            "mask" | "coverage" => Role::Mask,
            "a" | "alpha" => Role::Alpha,
            "value" | "y" | "height" => Role::Value,
            _ => Role::Other,
        }
    }
}

/// The shape of a store: its size, channels, data type, chunks and levels.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Level-0 width.
    pub width: usize,
    /// Level-0 height.
    pub height: usize,
    /// What it holds.
    pub content: Content,
    /// The data type's name in the Zarr metadata.
    pub dtype: &'static str,
    /// The options it is written with.
    pub opts: ZarrOptions,
    /// Levels (level 0 included).
    pub levels: usize,
}

impl Layout {
    /// The layout of a `width × height` store of `content` written with `opts`: checks the
    /// chunk and shard sides and the data type, and counts the levels.
    pub fn new(
        width: usize,
        height: usize,
        content: Content,
        opts: &ZarrOptions,
        path: &Path,
    ) -> Result<Self, RgbnError> {
        let bad = |detail: String| RgbnError::Write {
            detail,
            path: path.into(),
        };
        if opts.chunk < 16 || opts.chunk > 8192 {
            return Err(bad(format!(
                "chunk side {} is outside 16..=8192 pixels",
                opts.chunk
            )));
        }
        if opts.shard != 0 && (opts.shard < opts.chunk || !opts.shard.is_multiple_of(opts.chunk)) {
            return Err(bad(format!(
                "shard side {} is not a multiple of the chunk side {}",
                opts.shard, opts.chunk
            )));
        }
        let dtype = match (content, opts.dtype) {
            (Content::Picture, _) => "uint8",
            (Content::Scalar, ZarrDtype::U16) => {
                return Err(bad(
                    "a scalar field (a height, a curl map) has no range for uint16: write it as float32 or float16".into(),
                ))
            }
            (_, d) => d.name(),
        };
        let most = opts.levels.unwrap_or(usize::MAX).max(1);
        let mut levels = 1;
        while levels < most {
            let s = 1usize << levels;
            let (lw, lh) = crate::raster::pyramid::reduced_size((width, height), s);
            if !opts.chunk.is_multiple_of(s)
                || opts.chunk / s < MIN_LEVEL_SIDE
                || lw.max(lh) < MIN_LEVEL_SIDE
            {
                break;
            }
            levels += 1;
        }
        Ok(Self {
            width,
            height,
            content,
            dtype,
            opts: *opts,
            levels,
        })
    }

    /// The side of a cell of the arrays' chunk grid at level 0 (a shard when sharded): the unit
    /// a region is written in.
    #[must_use]
    pub fn cell(&self) -> usize {
        if self.opts.shard > 0 {
            self.opts.shard
        } else {
            self.opts.chunk
        }
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.content.channels().len()
    }

    /// The size of level `k`.
    #[must_use]
    pub fn level_size(&self, k: usize) -> (usize, usize) {
        crate::raster::pyramid::reduced_size((self.width, self.height), 1 << k)
    }
}

/// An error about the store at `path`: `detail` says what is wrong.
fn store_error(path: &Path, detail: impl Into<String>) -> RgbnError {
    RgbnError::Decode {
        detail: detail.into(),
        path: path.into(),
    }
}

/// A picture's interleaved RGBA bytes as four planes of values 0–255 (the picture channel
/// set's samples).
#[must_use]
pub fn rgba_planes(rgba: &[u8]) -> Vec<Vec<f32>> {
    (0..4)
        .map(|c| {
            rgba.iter()
                .skip(c)
                .step_by(4)
                .map(|&v| f32::from(v))
                .collect()
        })
        .collect()
}

/// A store named where a colour image, a photo or a normal-map file is expected, or as the
/// target of a colour or normal-map file.
pub fn not_a_raster(path: &Path) -> RgbnError {
    RgbnError::UnsupportedFormat {
        format: "zarr (an OME-Zarr store holds a whole RGBN image, picture, mask or field: read it as the image or mask, write it with save or -o)".into(),
        path: path.into(),
    }
}

/// The RGBN image of the store at `path` (level 0), its normals repaired as
/// [`super::load`] repairs a file's, refused under `strict` when any needed it.
pub fn load(path: &Path, opts: &super::LoadOptions) -> Result<super::Loaded, RgbnError> {
    let z = ZarrImage::open(path)?;
    let (image, repaired) = z.read_rgbn(0, crate::raster::window::Rect::full(z.size()))?;
    if opts.strict {
        if let Some(e) = repaired.strict_error(path) {
            return Err(e);
        }
    }
    Ok(super::Loaded { image, repaired })
}

/// The linear colour of an RGBN store (or a picture's sRGB bytes, made linear) at `path`.
pub fn load_color(path: &Path) -> Result<(usize, usize, [Vec<f32>; 3]), RgbnError> {
    let z = ZarrImage::open(path)?;
    let (w, h) = z.size();
    let mut planes = z.read(0, crate::raster::window::Rect::full((w, h)))?;
    let find = |k: usize| {
        z.labels()
            .iter()
            .position(|l| Role::of(l) == Role::Color(k))
    };
    let (Some(r), Some(g), Some(b)) = (find(0), find(1), find(2)) else {
        return Err(store_error(
            path,
            format!(
                "no colour channels R, G, B (it has {})",
                z.labels().join(", ")
            ),
        ));
    };
    let mut take = |i: usize| std::mem::take(&mut planes[i]);
    let mut rgb = [take(r), take(g), take(b)];
    if z.content() == Content::Picture {
        let lut = crate::raster::srgb::srgb8_lut();
        for p in &mut rgb {
            p.iter_mut().for_each(|v| *v = lut[(*v as usize).min(255)]);
        }
    }
    Ok((w, h, rgb))
}

/// The `mask` channel of the store at `path` (a mask store, or an RGBN one with a mask).
pub fn load_mask(path: &Path) -> Result<(usize, usize, Vec<f32>), RgbnError> {
    let z = ZarrImage::open(path)?;
    let (w, h) = z.size();
    match z.read_channel(Role::Mask)? {
        Some(m) => Ok((w, h, m)),
        None => Err(store_error(
            path,
            format!("no mask channel (it has {})", z.labels().join(", ")),
        )),
    }
}

/// The content key of the store at `path` without reading its chunks: the XXH3-128 of its
/// metadata files' bytes and of every file's relative path, size and modification time
/// (a chunk rewritten, even with the same bytes, changes it; an unchanged store keeps it).
pub fn stamp(path: &Path) -> std::io::Result<u128> {
    let mut files = Vec::new();
    let mut todo = vec![path.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d)? {
            let e = e?;
            let m = e.metadata()?;
            if m.is_dir() {
                todo.push(e.path());
            } else {
                let rel = e
                    .path()
                    .strip_prefix(path)
                    .unwrap_or(&e.path())
                    .to_path_buf();
                let t = m
                    .modified()
                    .ok()
                    .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                    .map_or(0, |d| d.as_nanos());
                files.push((rel, m.len(), t));
            }
        }
    }
    files.sort();
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(b"rgbn-zarr-stamp-1\0");
    for (rel, len, t) in &files {
        let name = rel.to_string_lossy();
        h.update(name.as_bytes());
        h.update(&len.to_le_bytes());
        h.update(&t.to_le_bytes());
        if name.ends_with("zarr.json") || name.ends_with(".zarray") || name.ends_with(".zattrs") {
            h.update(&std::fs::read(path.join(rel))?);
        }
    }
    Ok(h.digest128())
}

/// The pixel size of the image in the store at `path` (its metadata only), or `None` if it is
/// not one rgbn reads.
#[must_use]
pub fn dimensions(path: &Path) -> Option<(usize, usize)> {
    ZarrImage::open(path).ok().map(|z| z.size())
}

#[cfg(test)]
mod tests;
