//! Writing OME-Zarr stores: the metadata, and blocks of whole chunk-grid cells encoded on the
//! pool with every level of their pyramid.
//!
//! **A whole image** is written into a new folder beside the target (`.NAME.rgbn-tmp-…`) and
//! swapped in at [`ZarrWriter::commit`] (on Linux `renameat2(RENAME_EXCHANGE)`, then the old
//! store is removed): a reader sees the old store or the new one, never a mix, and a process
//! killed before the commit leaves the old store untouched.
//!
//! **A region** ([`ZarrWriter::create_region`]) writes into the store in place, creating it
//! first when it does not exist. Creation is safe when several processes start at once with
//! no step before them: each writes the metadata into a folder of its own beside the target
//! and renames it into place; the rename of one succeeds, the others find the store there,
//! check that its metadata is byte for byte what they would have written, and go on (a store
//! of another shape, type, chunking or channels is an error). Chunks are written atomically
//! (`store.rs`), and the bytes of a chunk depend only on its pixels, so a retried region writes
//! the same bytes again.

use super::store::{write_atomic, Store};
use super::{Content, Layout, Role, ZarrCompression, ZarrDtype, ZarrOptions};
use crate::error::RgbnError;
use crate::raster::window::Rect;
use crate::raster::RgbnImage;
use rayon::prelude::*;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::codec::{BloscCodec, ZstdCodec};
use zarrs::array::{
    transmute_to_bytes, transmute_to_bytes_vec, Array, ArrayBuilder, ArrayMetadata, CodecOptions,
};

/// zstd's level (1: fastest; levels above cost more time than they save bytes on float planes:
/// BENCHMARKS.md, thirteenth session).
const ZSTD_LEVEL: i32 = 1;

fn write_error(path: &Path, detail: impl Into<String>) -> RgbnError {
    RgbnError::Write {
        detail: detail.into(),
        path: path.into(),
    }
}

/// The files of a store's metadata (relative path, bytes): the group's `zarr.json` with the
/// OME and rgbn attributes, and each level's array `zarr.json`. The same layout always gives
/// the same bytes (concurrent creators compare them).
fn metadata_files(layout: &Layout, path: &Path) -> Result<Vec<(String, Vec<u8>)>, RgbnError> {
    let labels = layout.content.channels();
    let nc = labels.len() as u64;
    let colors = |l: &str| match l {
        "R" => "FF0000",
        "G" => "00FF00",
        "B" => "0000FF",
        _ => "FFFFFF",
    };
    let (lo, hi) = match (layout.content, layout.dtype) {
        (Content::Picture, _) => (0.0, 255.0),
        _ => (0.0, 1.0),
    };
    let channels: Vec<_> = labels
        .iter()
        .map(|l| {
            let (min, max) = if matches!(Role::of(l), Role::Value | Role::Normal(_)) {
                (-1.0, 1.0)
            } else {
                (lo, hi)
            };
            json!({
                "label": l,
                "color": colors(l),
                "active": true,
                "window": {"start": min, "end": max, "min": min, "max": max},
            })
        })
        .collect();
    let datasets: Vec<_> = (0..layout.levels)
        .map(|k| {
            let s = (1u64 << k) as f64;
            let mut t = vec![json!({"type": "scale", "scale": [1.0, s, s]})];
            if k > 0 {
                let o = (s - 1.0) / 2.0;
                t.push(json!({"type": "translation", "translation": [0.0, o, o]}));
            }
            json!({"path": k.to_string(), "coordinateTransformations": t})
        })
        .collect();
    let group = json!({
        "zarr_format": 3,
        "node_type": "group",
        "attributes": {
            "ome": {
                "version": "0.5",
                "multiscales": [{
                    "name": "rgbn",
                    "axes": [
                        {"name": "c", "type": "channel"},
                        {"name": "y", "type": "space"},
                        {"name": "x", "type": "space"},
                    ],
                    "datasets": datasets,
                    "type": "mean",
                    "metadata": {
                        "description": "level k: level 0 reduced by 2^k, block means (coverage-weighted colour and normals, normals renormalised); its chunks cover the pixels of level 0's",
                    },
                }],
                "omero": {
                    "channels": channels,
                    "rdefs": {"model": "color"},
                },
            },
            "rgbn": {
                "version": 1,
                "content": layout.content.name(),
                "channels": labels,
                "uint16": "normal components: v / 65535 * 2 - 1; colour (linear) and mask: v / 65535",
            },
        },
    });
    let mut files = vec![(
        "zarr.json".to_string(),
        serde_json::to_vec_pretty(&group).map_err(|e| write_error(path, e.to_string()))?,
    )];
    for k in 0..layout.levels {
        let meta = array_metadata(layout, k, nc).map_err(|e| write_error(path, e))?;
        let bytes =
            serde_json::to_vec_pretty(&meta).map_err(|e| write_error(path, e.to_string()))?;
        files.push((format!("{k}/zarr.json"), bytes));
    }
    Ok(files)
}

/// Level `k`'s array metadata.
fn array_metadata(layout: &Layout, k: usize, nc: u64) -> Result<ArrayMetadata, String> {
    let (w, h) = layout.level_size(k);
    let cell = (layout.cell() >> k) as u64;
    let chunk = (layout.opts.chunk >> k) as u64;
    let mut b = match layout.dtype {
        "float32" => ArrayBuilder::new(
            vec![nc, h as u64, w as u64],
            vec![nc, cell, cell],
            "float32",
            0.0f32,
        ),
        "float16" => ArrayBuilder::new(
            vec![nc, h as u64, w as u64],
            vec![nc, cell, cell],
            "float16",
            half::f16::ZERO,
        ),
        "uint16" => ArrayBuilder::new(
            vec![nc, h as u64, w as u64],
            vec![nc, cell, cell],
            "uint16",
            0u16,
        ),
        _ => ArrayBuilder::new(
            vec![nc, h as u64, w as u64],
            vec![nc, cell, cell],
            "uint8",
            0u8,
        ),
    };
    let typesize = match layout.dtype {
        "float32" => 4,
        "uint8" => 1,
        _ => 2,
    };
    let codecs: Vec<Arc<dyn zarrs::array::codec::api::BytesToBytesCodecTraits>> = match layout
        .opts
        .compression
    {
        ZarrCompression::Zstd => vec![Arc::new(ZstdCodec::new(ZSTD_LEVEL, false))],
        ZarrCompression::Blosc => {
            use zarrs::array::codec::{BloscCompressionLevel, BloscCompressor, BloscShuffleMode};
            vec![Arc::new(
                BloscCodec::new(
                    BloscCompressor::Zstd,
                    BloscCompressionLevel::try_from(ZSTD_LEVEL as u8)
                        .map_err(|l| format!("blosc level {l}"))?,
                    None,
                    BloscShuffleMode::Shuffle,
                    Some(typesize),
                )
                .map_err(|e| e.to_string())?,
            )]
        }
        ZarrCompression::None => Vec::new(),
    };
    b.bytes_to_bytes_codecs(codecs)
        .dimension_names(Some(["c", "y", "x"]));
    if layout.opts.shard > 0 {
        b.subchunk_shape(vec![nc, chunk, chunk]);
    }
    b.build_metadata()
        .map(ArrayMetadata::V3)
        .map_err(|e| e.to_string())
}

/// A new folder beside `path` for the store's files before they are renamed into place.
fn temp_dir(path: &Path) -> Result<PathBuf, RgbnError> {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let t = dir.join(format!(
        ".{name}.rgbn-tmp-{}-{}",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&t);
    std::fs::create_dir(&t)
        .map_err(|e| write_error(path, format!("cannot create {}: {e}", t.display())))?;
    Ok(t)
}

/// Swaps folder `new` into place at `path` (see the module docs); the old store, if any, is
/// removed.
fn swap_in(new: &Path, path: &Path) -> Result<(), RgbnError> {
    let err =
        |e: std::io::Error| write_error(path, format!("cannot move the new store into place: {e}"));
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return std::fs::rename(new, path).map_err(err)
        }
        Err(e) => return Err(err(e)),
        Ok(m) if !m.is_dir() => {
            return Err(write_error(
                path,
                "a file is in the way of the store (a .zarr output is a folder): remove it or choose another path",
            ))
        }
        Ok(_) => {}
    }
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes()).ok();
        if let (Some(a), Some(b)) = (c(new), c(path)) {
            // SAFETY: two valid NUL-terminated paths; renameat2 reads them only.
            let r = unsafe {
                libc::renameat2(
                    libc::AT_FDCWD,
                    a.as_ptr(),
                    libc::AT_FDCWD,
                    b.as_ptr(),
                    libc::RENAME_EXCHANGE,
                )
            };
            if r == 0 {
                // `new` now holds the old store.
                return std::fs::remove_dir_all(new).map_err(err);
            }
        }
    }
    // Elsewhere: the old store aside, the new one in, the old one removed.
    let old = temp_dir(path)?;
    std::fs::remove_dir(&old).map_err(err)?;
    std::fs::rename(path, &old).map_err(err)?;
    std::fs::rename(new, path).map_err(err)?;
    std::fs::remove_dir_all(&old).map_err(err)
}

/// A store being written (module docs).
pub struct ZarrWriter {
    path: PathBuf,
    layout: Layout,
    arrays: Vec<Array<Store>>,
    /// The folder written into before it is swapped in (whole images).
    temp: Option<PathBuf>,
    /// The level-0 pixels this writer may write.
    area: Rect,
}

impl ZarrWriter {
    /// Starts a whole store at `path` (module docs).
    pub fn create(path: &Path, layout: Layout) -> Result<Self, RgbnError> {
        let dir = temp_dir(path)?;
        let files = metadata_files(&layout, path)?;
        for (rel, bytes) in &files {
            write_atomic(&dir.join(rel), bytes).map_err(|e| write_error(path, e.to_string()))?;
        }
        let area = Rect::full((layout.width, layout.height));
        let arrays = Self::arrays(&dir, &layout, path)?;
        Ok(Self {
            path: path.to_path_buf(),
            layout,
            arrays,
            temp: Some(dir),
            area,
        })
    }

    /// Opens the store at `path` for writing `region` (level-0 pixels) in place, creating it
    /// first if it does not exist (module docs). The region must be aligned to the chunk grid
    /// (to the shards when sharded), except at the image's right and bottom edges.
    pub fn create_region(path: &Path, layout: Layout, region: Rect) -> Result<Self, RgbnError> {
        let g = layout.cell();
        let (w, h) = (layout.width, layout.height);
        let edge_ok = |start: usize, len: usize, size: usize| {
            start.is_multiple_of(g) && (len.is_multiple_of(g) || start + len == size)
        };
        if region.is_empty()
            || region.right() > w
            || region.bottom() > h
            || !edge_ok(region.x, region.w, w)
            || !edge_ok(region.y, region.h, h)
        {
            return Err(RgbnError::InvalidParam {
                name: "region".into(),
                detail: format!(
                    "{},{},{},{} is not aligned to the {g}-pixel chunks of {} ({w}×{h}): its left and top must be multiples of {g}, its width and height too unless it reaches the right or bottom edge (a region covers whole chunks, which no other region writes)",
                    region.x, region.y, region.w, region.h,
                    path.display()
                ),
            });
        }
        let files = metadata_files(&layout, path)?;
        if !path.exists() {
            let dir = temp_dir(path)?;
            for (rel, bytes) in &files {
                write_atomic(&dir.join(rel), bytes)
                    .map_err(|e| write_error(path, e.to_string()))?;
            }
            if std::fs::rename(&dir, path).is_err() {
                // Another process created it first: ours goes; theirs is checked below.
                let _ = std::fs::remove_dir_all(&dir);
            }
        }
        for (rel, bytes) in &files {
            let have = std::fs::read(path.join(rel)).ok();
            if have.as_deref() != Some(bytes.as_slice()) {
                return Err(write_error(
                    path,
                    format!(
                        "the store exists with other metadata ({rel} {}): a region is written into a store of the output's size, data type, chunks and channels; remove it or choose another path",
                        if have.is_some() { "differs" } else { "is missing" }
                    ),
                ));
            }
        }
        let arrays = Self::arrays(path, &layout, path)?;
        Ok(Self {
            path: path.to_path_buf(),
            layout,
            arrays,
            temp: None,
            area: region,
        })
    }

    fn arrays(dir: &Path, layout: &Layout, path: &Path) -> Result<Vec<Array<Store>>, RgbnError> {
        let store = Arc::new(Store::open(dir).map_err(|e| write_error(path, e))?);
        let nc = layout.channels() as u64;
        (0..layout.levels)
            .map(|k| {
                let meta = array_metadata(layout, k, nc).map_err(|e| write_error(path, e))?;
                Array::new_with_metadata(store.clone(), &format!("/{k}"), meta)
                    .map_err(|e| write_error(path, e.to_string()))
            })
            .collect()
    }

    /// The store's layout.
    #[must_use]
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// Writes `rect` of level 0 — whole cells of the chunk grid within the writer's area,
    /// clipped only at the image's edges — from `planes` (one per channel, `rect.w × rect.h`
    /// values), with every level of each cell; cells are encoded in parallel.
    pub fn write_block(&self, rect: Rect, planes: &[&[f32]]) -> Result<(), RgbnError> {
        let g = self.layout.cell();
        let (w, h) = (self.layout.width, self.layout.height);
        debug_assert_eq!(planes.len(), self.layout.channels());
        if rect.intersect(&self.area) != rect
            || !rect.x.is_multiple_of(g)
            || !rect.y.is_multiple_of(g)
        {
            return Err(write_error(
                &self.path,
                format!(
                    "block {}×{} at ({}, {}) is not whole cells of the writer's area",
                    rect.w, rect.h, rect.x, rect.y
                ),
            ));
        }
        let cells: Vec<(usize, usize)> = (rect.y / g..rect.bottom().div_ceil(g))
            .flat_map(|gy| (rect.x / g..rect.right().div_ceil(g)).map(move |gx| (gy, gx)))
            .collect();
        cells.par_iter().try_for_each(|&(gy, gx)| {
            let cell = Rect::new(gx * g, gy * g, g, g).intersect(&Rect::full((w, h)));
            if cell.intersect(&rect) != cell {
                return Err(write_error(
                    &self.path,
                    format!("block at ({}, {}) cuts a chunk", rect.x, rect.y),
                ));
            }
            // The cell's pixels, one plane per channel.
            let data: Vec<Vec<f32>> = planes
                .iter()
                .map(|p| {
                    let mut v = Vec::with_capacity(cell.w * cell.h);
                    for y in cell.y..cell.bottom() {
                        let s = (y - rect.y) * rect.w + (cell.x - rect.x);
                        v.extend_from_slice(&p[s..s + cell.w]);
                    }
                    v
                })
                .collect();
            self.write_cell(gy, gx, cell.w, cell.h, data)
        })
    }

    /// Writes cell `(gy, gx)` of every level from its level-0 pixels (`cw × ch` per channel).
    fn write_cell(
        &self,
        gy: usize,
        gx: usize,
        cw: usize,
        ch: usize,
        level0: Vec<Vec<f32>>,
    ) -> Result<(), RgbnError> {
        let g = self.layout.cell();
        let opts = CodecOptions::default().with_store_empty_chunks(true);
        let store = |k: usize, lw: usize, lh: usize, planes: &[Vec<f32>]| {
            // The chunk's samples go through this thread's scratch buffer, kept from one chunk
            // to the next: a fresh one was a new mapping per chunk, page-faulted and
            // zero-filled by the kernel (6 MB for 512² × 6 float channels). Taken, not
            // borrowed: a task the codec's threads steal onto this one finds it empty.
            let mut scratch = SCRATCH.take();
            let bytes = encode(&self.layout, g >> k, lw, lh, planes, &mut scratch);
            let r = self.arrays[k]
                .store_chunk_opt(&[0, gy as u64, gx as u64], bytes, &opts)
                .map_err(|e| {
                    write_error(&self.path, format!("chunk ({gy}, {gx}) of level {k}: {e}"))
                });
            SCRATCH.set(scratch);
            r
        };
        store(0, cw, ch, &level0)?;
        if self.layout.levels > 1 {
            let mut pyr = super::write_levels::Pyramid::new(self.layout.content, cw, ch, &level0);
            drop(level0);
            for k in 1..self.layout.levels {
                let (lw, lh, planes) = pyr.next_level();
                store(k, lw, lh, &planes)?;
            }
        }
        Ok(())
    }

    /// Finishes the store: a whole one is swapped into place.
    pub fn commit(mut self) -> Result<(), RgbnError> {
        match self.temp.take() {
            Some(dir) => swap_in(&dir, &self.path),
            None => Ok(()),
        }
    }
}

impl Drop for ZarrWriter {
    fn drop(&mut self) {
        // Not committed: the new store is dropped, the old one (if any) is left as it was.
        if let Some(dir) = self.temp.take() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

thread_local! {
    /// A thread's buffer of one chunk's samples ([`encode`]), kept between chunks.
    static SCRATCH: std::cell::Cell<Vec<f32>> = const { std::cell::Cell::new(Vec::new()) };
}

/// A cell's samples (`lw × lh` valid per channel) padded to `side × side` with zeros and
/// converted to the store's type, channel after channel; float32 samples are `all`'s, borrowed.
fn encode<'a>(
    layout: &Layout,
    side: usize,
    lw: usize,
    lh: usize,
    planes: &[Vec<f32>],
    all: &'a mut Vec<f32>,
) -> zarrs::array::ArrayBytes<'a> {
    let labels = layout.content.channels();
    let n = side * side;
    let fill = |out: &mut [f32], p: &[f32]| {
        for y in 0..lh {
            out[y * side..y * side + lw].copy_from_slice(&p[y * lw..(y + 1) * lw]);
        }
    };
    all.clear();
    all.resize(n * planes.len(), 0.0);
    for (c, p) in planes.iter().enumerate() {
        fill(&mut all[c * n..(c + 1) * n], p);
    }
    let all: &'a [f32] = all;
    let roles: Vec<Role> = labels.iter().map(|l| Role::of(l)).collect();
    match (layout.dtype, layout.opts.dtype) {
        ("uint8", _) => all.iter().map(|&v| v as u8).collect::<Vec<u8>>().into(),
        (_, ZarrDtype::F32) => zarrs::array::ArrayBytes::from(transmute_to_bytes(all)),
        (_, ZarrDtype::F16) => {
            transmute_to_bytes_vec(all.iter().map(|&v| half::f16::from_f32(v)).collect()).into()
        }
        (_, ZarrDtype::U16) => transmute_to_bytes_vec::<u16>(
            all.iter()
                .enumerate()
                .map(|(i, &v)| match roles[i / n] {
                    Role::Normal(_) => {
                        ((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * 65535.0 + 0.5).min(65535.0) as u16
                    }
                    _ => (v.clamp(0.0, 1.0) * 65535.0 + 0.5).min(65535.0) as u16,
                })
                .collect(),
        )
        .into(),
    }
}

/// Writes `img` as a whole store at `path` (with a `mask` channel when it has a mask).
pub fn save_zarr(img: &RgbnImage, path: &Path, opts: &ZarrOptions) -> Result<(), RgbnError> {
    let [r, g, b] = img.color();
    let [nx, ny, nz] = img.normal();
    let mut planes: Vec<&[f32]> = vec![r, g, b, nx, ny, nz];
    if let Some(m) = img.mask() {
        planes.push(m);
    }
    let content = Content::Rgbn {
        mask: img.mask().is_some(),
    };
    save_planes_zarr(
        path,
        (img.width(), img.height()),
        content,
        &planes,
        opts,
        None,
    )
}

/// Writes `content` of a `size` image from its planes (one per channel of
/// [`Content::channels`], picture bytes as values 0–255): the whole store, or with `region`
/// the planes are that region's (level-0 pixels) and only its chunks are written
/// ([`ZarrWriter::create_region`]).
pub fn save_planes_zarr(
    path: &Path,
    size: (usize, usize),
    content: Content,
    planes: &[&[f32]],
    opts: &ZarrOptions,
    region: Option<Rect>,
) -> Result<(), RgbnError> {
    let layout = Layout::new(size.0, size.1, content, opts, path)?;
    match region {
        None => {
            let w = ZarrWriter::create(path, layout)?;
            w.write_block(Rect::full(size), planes)?;
            w.commit()
        }
        Some(r) => {
            let w = ZarrWriter::create_region(path, layout, r)?;
            w.write_block(r, planes)?;
            w.commit()
        }
    }
}

/// A store written row by row (the streamed `rgbn eval`; a region of one, an `rgbn.dask`
/// task): rows are kept until a row of chunk-grid cells is complete, which is then written
/// ([`ZarrWriter::write_block`]).
pub struct ZarrRowWriter {
    writer: ZarrWriter,
    /// Rows not yet written, one plane per channel, from row `y0`.
    band: Vec<Vec<f32>>,
    y0: usize,
    /// The level-0 pixels written: the whole image, or a region.
    area: Rect,
}

impl ZarrRowWriter {
    /// Starts a whole store at `path`.
    pub fn create(path: &Path, layout: Layout) -> Result<Self, RgbnError> {
        let area = Rect::full((layout.width, layout.height));
        Ok(Self::with(ZarrWriter::create(path, layout)?, area))
    }

    /// Writes `region` of the store at `path` in place, creating the store first if it does
    /// not exist ([`ZarrWriter::create_region`]: a chunk-aligned region).
    pub fn create_region(path: &Path, layout: Layout, region: Rect) -> Result<Self, RgbnError> {
        Ok(Self::with(
            ZarrWriter::create_region(path, layout, region)?,
            region,
        ))
    }

    fn with(writer: ZarrWriter, area: Rect) -> Self {
        Self {
            band: vec![Vec::new(); writer.layout.channels()],
            writer,
            y0: area.y,
            area,
        }
    }

    /// Appends the next rows (one plane per channel, rows as wide as the area).
    pub fn write(&mut self, planes: &[&[f32]]) -> Result<(), RgbnError> {
        let (w, bottom) = (self.area.w, self.area.bottom());
        let g = self.writer.layout.cell();
        for (b, p) in self.band.iter_mut().zip(planes) {
            b.extend_from_slice(p);
        }
        loop {
            let rows = self.band[0].len() / w;
            let full = g.min(bottom - self.y0);
            if rows < full || full == 0 {
                return Ok(());
            }
            let r = Rect::new(self.area.x, self.y0, w, full);
            let parts: Vec<&[f32]> = self.band.iter().map(|b| &b[..full * w]).collect();
            self.writer.write_block(r, &parts)?;
            for b in &mut self.band {
                b.drain(..full * w);
            }
            self.y0 += full;
        }
    }

    /// Finishes the store (every row of the area must have been written).
    pub fn commit(self) -> Result<(), RgbnError> {
        if self.y0 != self.area.bottom() {
            return Err(write_error(
                &self.writer.path,
                format!("{} of {} rows written", self.y0 - self.area.y, self.area.h),
            ));
        }
        self.writer.commit()
    }
}
