//! Reading OME-Zarr stores: the metadata (NGFF 0.5 on Zarr v3, 0.4 on v2), windows of a level
//! decoded chunk by chunk on the pool ([`ZarrImage::read`]), and the rows of level 0 top to
//! bottom for the strip driver ([`ZarrRows`]).

use super::store::Store;
use super::{store_error, Content, Role};
use crate::error::RgbnError;
use crate::raster::io::DEFAULT_ALBEDO;
use crate::raster::par::SharedMut;
use crate::raster::window::Rect;
use crate::raster::{RgbnImage, Validation};
use parking_lot::Mutex;
use rayon::prelude::*;
use serde_json::Value as Json;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::data_type::{Float16DataType, Float32DataType, UInt16DataType, UInt8DataType};
use zarrs::array::Array;

/// A level's array and its chunking.
struct Level {
    array: Array<Store>,
    /// Its path in the store (for messages).
    name: String,
    /// Width and height.
    size: (usize, usize),
    /// Chunk sides along c, y and x.
    chunk: [usize; 3],
}

/// The sample type of a store.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dtype {
    F32,
    F16,
    U16,
    U8,
}

/// Decoded samples of one chunk.
enum ChunkData {
    F32(Vec<f32>),
    F16(Vec<half::f16>),
    U16(Vec<u16>),
    U8(Vec<u8>),
}

/// An OME-Zarr image opened for reading: its metadata and one array per level.
pub struct ZarrImage {
    path: PathBuf,
    store: Arc<Store>,
    levels: Vec<Level>,
    labels: Vec<String>,
    roles: Vec<Role>,
    content: Content,
    dtype: Dtype,
    /// Positions of the c, y and x axes, and the number of axes.
    axes: (Option<usize>, usize, usize, usize),
    /// Written by rgbn (a missing chunk is then an error, not the fill value).
    ours: bool,
}

impl std::fmt::Debug for ZarrImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZarrImage")
            .field("path", &self.path)
            .field("labels", &self.labels)
            .field("levels", &self.levels.len())
            .finish()
    }
}

/// Reads a JSON file of the store, `None` when it is absent.
fn read_json(path: &Path, name: &str) -> Result<Option<Json>, RgbnError> {
    let file = path.join(name);
    match std::fs::read(&file) {
        Ok(b) => serde_json::from_slice(&b)
            .map(Some)
            .map_err(|e| store_error(path, format!("{name} is not valid JSON ({e})"))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(RgbnError::Read {
            path: file,
            source: e,
        }),
    }
}

impl ZarrImage {
    /// Opens the store at `path` and checks that it holds an image rgbn reads (module docs):
    /// OME multiscales metadata, axes `c`, `y`, `x`, labelled channels whose count is the
    /// arrays', a data type rgbn reads. Each problem is one error naming the store and what is
    /// wrong.
    pub fn open(path: &Path) -> Result<Self, RgbnError> {
        match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => {
                return Err(store_error(
                    path,
                    "a .zarr path is an OME-Zarr store, a folder; this is a file",
                ))
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(RgbnError::NotFound { path: path.into() })
            }
            Err(e) => {
                return Err(RgbnError::Read {
                    path: path.into(),
                    source: e,
                })
            }
        }
        let err = |d: String| store_error(path, d);
        let (attrs, v3) = if let Some(root) = read_json(path, "zarr.json")? {
            if root["node_type"] == "array" {
                return Err(err(
                    "a Zarr array, not an OME-Zarr image (an image is a group with multiscales metadata)".into(),
                ));
            }
            (root["attributes"].clone(), true)
        } else if let Some(a) = read_json(path, ".zattrs")? {
            (a, false)
        } else if path.join(".zgroup").exists() || path.join(".zarray").exists() {
            (Json::Null, false)
        } else {
            return Err(err(
                "not a Zarr store (no zarr.json, .zgroup or .zattrs in the folder)".into(),
            ));
        };
        // NGFF 0.5 nests its metadata under "ome"; 0.4 has it at the top.
        let ome = if attrs["ome"].is_object() {
            &attrs["ome"]
        } else {
            &attrs
        };
        let Some(ms) = ome["multiscales"].get(0) else {
            return Err(err(format!(
                "a Zarr {} without OME multiscales metadata: not an OME-Zarr image",
                if v3 { "v3 group" } else { "v2 group" }
            )));
        };
        let store = Arc::new(Store::open(path).map_err(|e| err(e.to_string()))?);
        let datasets = ms["datasets"].as_array().cloned().unwrap_or_default();
        if datasets.is_empty() {
            return Err(err("its multiscales metadata lists no datasets".into()));
        }
        // Axes by name (0.4, 0.5: objects; 0.3: strings; none: by the number of dimensions).
        let names: Vec<String> = match ms["axes"].as_array() {
            Some(a) => a
                .iter()
                .map(|x| {
                    x["name"]
                        .as_str()
                        .or_else(|| x.as_str())
                        .unwrap_or_default()
                        .to_ascii_lowercase()
                })
                .collect(),
            None => Vec::new(),
        };
        let mut levels = Vec::new();
        let mut axes = (None, 0, 0, 0);
        let mut dtype = Dtype::F32;
        for (k, d) in datasets.iter().enumerate() {
            let Some(p) = d["path"].as_str() else {
                return Err(err(format!("dataset {k} of its multiscales has no path")));
            };
            let array = match Array::open(store.clone(), &format!("/{}", p.trim_matches('/'))) {
                Ok(a) => a,
                Err(e) if k == 0 => return Err(err(format!("level 0 (array {p:?}): {e}"))),
                Err(e) => {
                    tracing::debug!("{}: level {k} not read ({e})", path.display());
                    break;
                }
            };
            let shape: Vec<usize> = array.shape().iter().map(|&s| s as usize).collect();
            if k == 0 {
                let names = if names.len() == shape.len() {
                    names.clone()
                } else {
                    match shape.len() {
                        2 => vec!["y".into(), "x".into()],
                        3 => vec!["c".into(), "y".into(), "x".into()],
                        5 => ["t", "c", "z", "y", "x"].map(String::from).to_vec(),
                        n => {
                            return Err(err(format!(
                                "level 0 has {n} dimensions and no axes metadata naming them"
                            )))
                        }
                    }
                };
                let find = |a: &str| names.iter().position(|n| n == a);
                let (Some(y), Some(x)) = (find("y"), find("x")) else {
                    return Err(err(format!(
                        "axes {names:?} have no y and x: rgbn reads 2-D images (axes c, y, x)"
                    )));
                };
                let c = find("c");
                for (i, n) in names.iter().enumerate() {
                    if Some(i) != c && i != y && i != x && shape[i] != 1 {
                        return Err(err(format!(
                            "axis {n:?} has {} entries: rgbn reads one 2-D image (axes c, y, x; any other axis of size 1)",
                            shape[i]
                        )));
                    }
                }
                axes = (c, y, x, shape.len());
                let dt = array.data_type();
                dtype = if dt.is::<Float32DataType>() {
                    Dtype::F32
                } else if dt.is::<Float16DataType>() {
                    Dtype::F16
                } else if dt.is::<UInt16DataType>() {
                    Dtype::U16
                } else if dt.is::<UInt8DataType>() {
                    Dtype::U8
                } else {
                    let meta = serde_json::to_value(array.metadata()).unwrap_or_default();
                    let name = if v3 {
                        meta["data_type"].clone()
                    } else {
                        meta["dtype"].clone()
                    };
                    return Err(err(format!(
                        "wrong data type {name} (rgbn reads float32, float16, uint16 and uint8)"
                    )));
                };
            }
            let (c, y, x, ndim) = axes;
            if shape.len() != ndim {
                break;
            }
            let size = (shape[x], shape[y]);
            if k > 0 {
                // A level rgbn can use is the block means of 2^k pixels of level 0.
                let want = crate::raster::pyramid::reduced_size(levels_size(&levels), 1usize << k);
                let same_c = c.is_none_or(|c| shape[c] == levels_shape_c(&levels, c));
                let same_dt = array.data_type() == levels[0].array.data_type();
                if size != want || !same_c || !same_dt {
                    tracing::debug!(
                        "{}: level {k} is {}×{}, not level 0 reduced by {} ({}×{}): levels from {k} on are not read",
                        path.display(), size.0, size.1, 1 << k, want.0, want.1
                    );
                    break;
                }
            }
            let zero = vec![0u64; ndim];
            let cs = array.chunk_shape(&zero).map_err(|e| {
                err(format!(
                    "level {k} (array {p:?}) has no regular chunk grid ({e})"
                ))
            })?;
            let cs: Vec<usize> = cs.iter().map(|v| v.get() as usize).collect();
            let chunk = [c.map_or(1, |c| cs[c]), cs[y], cs[x]];
            levels.push(Level {
                array,
                name: p.to_string(),
                size,
                chunk,
            });
        }
        let (c, _, _, _) = axes;
        let channels = c.map_or(1, |c| levels_shape_c(&levels, c));
        // Channel labels: omero's, else the rgbn attribute's, else one unnamed channel.
        let labels_of = |v: &Json, key: Option<&str>| -> Option<Vec<String>> {
            let a = v.as_array()?;
            Some(
                a.iter()
                    .map(|x| match key {
                        Some(k) => x[k].as_str().unwrap_or_default().to_string(),
                        None => x.as_str().unwrap_or_default().to_string(),
                    })
                    .collect(),
            )
        };
        let labels = labels_of(&ome["omero"]["channels"], Some("label"))
            .or_else(|| labels_of(&attrs["rgbn"]["channels"], None))
            .or_else(|| (channels == 1).then(|| vec!["value".to_string()]))
            .ok_or_else(|| {
                err(format!(
                    "its {channels} channels have no labels (omero.channels[].label): rgbn reads R, G, B, nx, ny, nz, mask"
                ))
            })?;
        if labels.len() != channels {
            return Err(err(format!(
                "wrong channel count: level 0 has {channels} channels but the metadata names {} ({})",
                labels.len(),
                labels.join(", ")
            )));
        }
        let roles: Vec<Role> = labels.iter().map(|l| Role::of(l)).collect();
        let has = |r: Role| roles.contains(&r);
        let content = if (0..3).all(|k| has(Role::Normal(k))) {
            Content::Rgbn {
                mask: has(Role::Mask),
            }
        } else if (0..3).all(|k| has(Role::Color(k))) && has(Role::Alpha) {
            Content::Picture
        } else if roles == [Role::Mask] {
            Content::Mask
        } else if roles.len() == 1 {
            Content::Scalar
        } else {
            return Err(err(format!(
                "channels {} are not an image rgbn reads: an RGBN image (nx, ny, nz; optionally R, G, B, mask), a picture (R, G, B, A), a mask or one scalar channel",
                labels.join(", ")
            )));
        };
        Ok(Self {
            path: path.to_path_buf(),
            store,
            levels,
            labels,
            roles,
            content,
            dtype,
            axes,
            ours: attrs["rgbn"].is_object(),
        })
    }

    /// The store's folder.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Level-0 width and height.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        self.levels[0].size
    }

    /// Levels that are block means of level 0 (at least level 0).
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Width and height of level `k` (one of [`levels`](Self::levels)).
    #[must_use]
    pub fn level_size(&self, k: usize) -> (usize, usize) {
        self.levels[k].size
    }

    /// The chunk's height and width at level `k`.
    #[must_use]
    pub fn chunk(&self, k: usize) -> (usize, usize) {
        (self.levels[k].chunk[1], self.levels[k].chunk[2])
    }

    /// What it holds.
    #[must_use]
    pub fn content(&self) -> Content {
        self.content
    }

    /// The channel labels.
    #[must_use]
    pub fn labels(&self) -> &[String] {
        &self.labels
    }

    /// The chunks of level `k` that cover `rect` (in the level's pixels): (c, y, x) indices.
    fn chunks_covering(&self, k: usize, rect: Rect) -> Vec<[usize; 3]> {
        let [cc, cy, cx] = self.levels[k].chunk;
        let mut v = Vec::new();
        if rect.is_empty() {
            return v;
        }
        for ci in 0..self.labels.len().div_ceil(cc) {
            for gy in rect.y / cy..=(rect.bottom() - 1) / cy {
                for gx in rect.x / cx..=(rect.right() - 1) / cx {
                    v.push([ci, gy, gx]);
                }
            }
        }
        v
    }

    /// Chunks (or shards) read from this store so far (by every reader of it).
    #[must_use]
    pub fn chunks_read(&self) -> u64 {
        self.store.reads()
    }

    /// How many chunks (or shards) reading `rect` of level `k` decodes: those that cover it.
    #[must_use]
    pub fn chunks_for(&self, k: usize, rect: Rect) -> usize {
        self.chunks_covering(k, rect).len()
    }

    /// Decodes one chunk; a missing one is the fill value (zeros) in a store of another tool's,
    /// an error in one rgbn wrote.
    fn decode(&self, k: usize, [ci, gy, gx]: [usize; 3]) -> Result<ChunkData, RgbnError> {
        let lv = &self.levels[k];
        let (c, y, x, ndim) = self.axes;
        let mut idx = vec![0u64; ndim];
        if let Some(c) = c {
            idx[c] = ci as u64;
        }
        idx[y] = gy as u64;
        idx[x] = gx as u64;
        let key = || lv.array.chunk_key(&idx).to_string();
        let bad = |e: zarrs::array::ArrayError| {
            store_error(
                &self.path,
                format!(
                    "chunk {} of level {k} (array {:?}) cannot be decoded, truncated or corrupt ({e})",
                    key(),
                    lv.name
                ),
            )
        };
        let n: usize = lv
            .array
            .chunk_shape(&idx)
            .map_err(bad)?
            .iter()
            .map(|v| v.get() as usize)
            .product();
        macro_rules! get {
            ($t:ty, $variant:ident, $zero:expr) => {
                match lv.array.retrieve_chunk_if_exists::<Vec<$t>>(&idx).map_err(bad)? {
                    Some(v) => ChunkData::$variant(v),
                    None if self.ours => {
                        return Err(store_error(
                            &self.path,
                            format!(
                                "chunk {} of level {k} (array {:?}) is missing: a region not yet written, or a damaged store",
                                key(),
                                lv.name
                            ),
                        ))
                    }
                    None => ChunkData::$variant(vec![$zero; n]),
                }
            };
        }
        Ok(match self.dtype {
            Dtype::F32 => get!(f32, F32, 0.0),
            Dtype::F16 => get!(half::f16, F16, half::f16::ZERO),
            Dtype::U16 => get!(u16, U16, 0),
            Dtype::U8 => get!(u8, U8, 0),
        })
    }

    /// Channel `ch`'s samples as `f32`: floats as they are; uint16 and uint8 over the
    /// channel's range (module docs), a picture's bytes as they are (0–255).
    fn map_fn(&self, ch: usize) -> impl Fn(&ChunkData, usize) -> f32 + Sync + '_ {
        let role = self.roles[ch];
        let picture = self.content == Content::Picture;
        let (scale, offset) = match role {
            Role::Normal(_) => (2.0, -1.0),
            _ => (1.0, 0.0),
        };
        let s16 = scale / 65535.0;
        let s8 = if picture { 1.0 } else { scale / 255.0 };
        let o8 = if picture { 0.0 } else { offset };
        move |d: &ChunkData, i: usize| match d {
            ChunkData::F32(v) => v[i],
            ChunkData::F16(v) => v[i].to_f32(),
            ChunkData::U16(v) => f32::from(v[i]) * s16 + offset,
            ChunkData::U8(v) => f32::from(v[i]) * s8 + o8,
        }
    }

    /// Every channel of `rect` of level `k` (in the level's pixels, within it), as `f32` planes
    /// of `rect.w × rect.h`: the chunks covering it are decoded in parallel, each once.
    pub fn read(&self, k: usize, rect: Rect) -> Result<Vec<Vec<f32>>, RgbnError> {
        let nc = self.labels.len();
        let mut out: Vec<Vec<f32>> = (0..nc)
            .map(|_| crate::raster::buf::zeroed_f32(rect.w * rect.h))
            .collect();
        self.read_into(k, rect, &mut out)?;
        Ok(out)
    }

    /// [`read`](Self::read) into `out` (`rect.w × rect.h` values per channel).
    fn read_into(&self, k: usize, rect: Rect, out: &mut [Vec<f32>]) -> Result<(), RgbnError> {
        let lv = &self.levels[k];
        let full = Rect::full(lv.size);
        if rect.intersect(&full) != rect {
            return Err(store_error(
                &self.path,
                format!(
                    "rectangle {}×{} at ({}, {}) lies outside level {k} ({}×{})",
                    rect.w, rect.h, rect.x, rect.y, lv.size.0, lv.size.1
                ),
            ));
        }
        let [cc, cy, cx] = lv.chunk;
        let (c_ax, y_ax, x_ax, ndim) = self.axes;
        let jobs = self.chunks_covering(k, rect);
        // Strides of a chunk's samples (C order over the array's axes).
        let cs: Vec<usize> = {
            let mut shape = vec![1usize; ndim];
            if let Some(c) = c_ax {
                shape[c] = cc;
            }
            shape[y_ax] = cy;
            shape[x_ax] = cx;
            shape
        };
        let mut strides = vec![1usize; ndim];
        for i in (0..ndim.saturating_sub(1)).rev() {
            strides[i] = strides[i + 1] * cs[i + 1];
        }
        let (sc, sy, sx) = (c_ax.map_or(0, |c| strides[c]), strides[y_ax], strides[x_ax]);
        let nc = self.labels.len();
        let maps: Vec<_> = (0..nc).map(|ch| self.map_fn(ch)).collect();
        // Decode in parallel; each chunk writes the part of the rectangle it covers straight
        // into the output planes.
        let ptrs: Vec<SharedMut<f32>> = out
            .iter_mut()
            .map(|o| {
                assert_eq!(o.len(), rect.w * rect.h);
                SharedMut(o.as_mut_ptr())
            })
            .collect();
        let floats = self.dtype == Dtype::F32;
        jobs.par_iter().try_for_each(|&[ci, gy, gx]| {
            let data = self.decode(k, [ci, gy, gx])?;
            let cell = Rect::new(gx * cx, gy * cy, cx, cy);
            let r = cell.intersect(&rect);
            let c0 = ci * cc;
            for ch in c0..(c0 + cc).min(nc) {
                let f = &maps[ch];
                for y in r.y..r.bottom() {
                    let base = (ch - c0) * sc + (y - cell.y) * sy + (r.x - cell.x) * sx;
                    let d = (y - rect.y) * rect.w + (r.x - rect.x);
                    // SAFETY: row y of channel ch, columns r.x..r.right() of the rectangle lie
                    // inside the plane (r is within rect); the chunks' rectangles are disjoint,
                    // so no other task writes these elements, and `out` outlives the tasks.
                    let dst = unsafe { std::slice::from_raw_parts_mut(ptrs[ch].get().add(d), r.w) };
                    match &data {
                        ChunkData::F32(v) if floats && sx == 1 => {
                            dst.copy_from_slice(&v[base..base + r.w]);
                        }
                        _ => {
                            for (i, o) in dst.iter_mut().enumerate() {
                                *o = f(&data, base + i * sx);
                            }
                        }
                    }
                }
            }
            Ok::<(), RgbnError>(())
        })?;
        Ok(())
    }

    /// `rect` of level `k` as an RGBN image (colour [`DEFAULT_ALBEDO`] without colour
    /// channels) with its normals repaired as the strip driver repairs them (each divided by
    /// its length; zero-length ones become `(0, 0, 1)`), and what was repaired. A level coarser
    /// than the store holds is read from its coarsest level and reduced further
    /// ([`crate::raster::pyramid::reduce_rgbn`]).
    pub fn read_rgbn(&self, k: usize, rect: Rect) -> Result<(RgbnImage, Validation), RgbnError> {
        let Content::Rgbn { .. } = self.content else {
            return Err(store_error(
                &self.path,
                format!(
                    "holds a {} (channels {}), not an RGBN image (channels nx, ny, nz)",
                    self.content.name(),
                    self.labels.join(", ")
                ),
            ));
        };
        let have = self.levels.len() - 1;
        if k > have {
            let f = 1usize << (k - have);
            let (lw, lh) = self.levels[have].size;
            let r = Rect::new(
                rect.x * f,
                rect.y * f,
                ((rect.x + rect.w) * f).min(lw) - rect.x * f,
                ((rect.y + rect.h) * f).min(lh) - rect.y * f,
            );
            let (img, v) = self.read_rgbn(have, r)?;
            return Ok((crate::raster::pyramid::reduce_rgbn(&img, f), v));
        }
        let mut planes = self.read(k, rect)?;
        let find = |r: Role| self.roles.iter().position(|&x| x == r);
        let mut take = |r: Role| find(r).map(|i| std::mem::take(&mut planes[i]));
        let n = rect.w * rect.h;
        let mut normal = [0, 1, 2].map(|i| take(Role::Normal(i)).expect("an RGBN store"));
        let color = match [0, 1, 2].map(|i| take(Role::Color(i))) {
            [Some(r), Some(g), Some(b)] => [r, g, b],
            _ => std::array::from_fn(|_| crate::raster::buf::filled_f32(n, DEFAULT_ALBEDO)),
        };
        let mask = take(Role::Mask);
        let [nx, ny, nz] = &mut normal;
        let repaired = crate::raster::strips::repair_normals([nx, ny, nz]);
        Ok((
            RgbnImage::new(rect.w, rect.h, color, normal, mask)?,
            repaired,
        ))
    }

    /// The channel labelled as `role` over level 0, or `None` when there is none.
    pub fn read_channel(&self, role: Role) -> Result<Option<Vec<f32>>, RgbnError> {
        let Some(i) = self.roles.iter().position(|&r| r == role) else {
            return Ok(None);
        };
        let mut planes = self.read(0, Rect::full(self.size()))?;
        Ok(Some(std::mem::take(&mut planes[i])))
    }

    /// The rows of level 0 top to bottom, for the strip driver: the normals, and the colour
    /// and the mask when the store has them, read by three readers that share the decoded
    /// chunk rows (each chunk is decoded once).
    pub fn rows(self: &Arc<Self>) -> (ZarrRows, Option<ZarrRows>, Option<ZarrRows>) {
        let find = |r: Role| self.roles.iter().position(|&x| x == r);
        let shared = Arc::new(Mutex::new(RowBlocks::default()));
        let mut readers = 0;
        let mut reader = |chans: Option<Vec<usize>>| {
            chans.map(|c| {
                readers += 1;
                ZarrRows {
                    image: self.clone(),
                    shared: shared.clone(),
                    id: readers - 1,
                    channels: c,
                    row: 0,
                    window: Rect::full(self.size()),
                }
            })
        };
        let normal = reader((0..3).map(|i| find(Role::Normal(i))).collect());
        let color = reader((0..3).map(|i| find(Role::Color(i))).collect());
        let mask = reader(find(Role::Mask).map(|i| vec![i]));
        shared.lock().positions = vec![0; readers];
        (normal.expect("an RGBN store has normals"), color, mask)
    }
}

/// Level 0's size.
fn levels_size(levels: &[Level]) -> (usize, usize) {
    levels[0].size
}

/// Level 0's entries along axis `c`.
fn levels_shape_c(levels: &[Level], c: usize) -> usize {
    levels[0].array.shape()[c] as usize
}

/// Chunk rows of level 0 decoded and not yet read by every reader.
#[derive(Default)]
pub(crate) struct RowBlocks {
    /// (first row, rows, every channel's planes).
    blocks: VecDeque<(usize, usize, Vec<Vec<f32>>)>,
    /// The next chunk row's first row.
    next: usize,
    /// Each reader's next row.
    positions: Vec<usize>,
    /// The planes of a chunk row every reader has passed, for the next one: a chunk row of a
    /// 4096-wide window is 8 MB a channel, and fresh planes were new mappings, page-faulted
    /// and zero-filled by the kernel row after row.
    spare: Option<Vec<Vec<f32>>>,
}

/// Rows of some channels of a store's level 0, read top to bottom (the strip driver's
/// [`crate::raster::io::stream::Rows::Zarr`]).
pub struct ZarrRows {
    image: Arc<ZarrImage>,
    shared: Arc<Mutex<RowBlocks>>,
    id: usize,
    channels: Vec<usize>,
    /// The next row (of the level).
    row: usize,
    /// The part of level 0 read ([`ZarrRows::set_window`]; the whole level unless set).
    window: Rect,
}

impl ZarrRows {
    /// Width and height of what is read (the window).
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.window.w, self.window.h)
    }

    /// Reads only `window` of level 0 from now on: its rows top to bottom, each cut to the
    /// window's columns (only the chunks that cover it are decoded). Set before the first read,
    /// on every reader of the store that shares chunk rows ([`ZarrImage::rows`]), to the same
    /// window.
    pub fn set_window(&mut self, window: Rect) -> Result<(), String> {
        let full = Rect::full(self.image.size());
        if window.is_empty() || window.intersect(&full) != window {
            return Err(format!(
                "window {},{},{},{} is not inside the store's {}×{}",
                window.x, window.y, window.w, window.h, full.w, full.h
            ));
        }
        let mut s = self.shared.lock();
        if self.row != self.window.y || !s.blocks.is_empty() {
            return Err("rows were read already".into());
        }
        self.window = window;
        self.row = window.y;
        s.next = window.y;
        s.positions[self.id] = window.y;
        Ok(())
    }

    /// Channels read.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels.len()
    }

    /// The store.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.image.path
    }

    /// The next `rows` rows of its channels into `planes` (one per channel, emptied first):
    /// chunk rows are decoded as the readers need them and dropped once every reader is past.
    pub fn read_rows(&mut self, rows: usize, planes: &mut Vec<Vec<f32>>) -> Result<(), RgbnError> {
        let win = self.window;
        let (w, bottom) = (win.w, win.bottom());
        let (y0, y1) = (self.row, (self.row + rows).min(bottom));
        planes.resize_with(self.channels.len(), Vec::new);
        for p in planes.iter_mut() {
            p.clear();
            p.reserve((y1 - y0) * w);
        }
        let mut s = self.shared.lock();
        let cy = self.image.levels[0].chunk[1];
        while s.next < y1 {
            // To the end of the chunk row (a window's first may start inside one).
            let r = Rect::new(win.x, s.next, w, (cy - s.next % cy).min(bottom - s.next));
            let planes = match s.spare.take() {
                Some(mut planes) => {
                    // Every sample is overwritten (each chunk covering `r` writes its part).
                    for p in &mut planes {
                        p.resize(r.w * r.h, 0.0);
                    }
                    self.image.read_into(0, r, &mut planes)?;
                    planes
                }
                None => self.image.read(0, r)?,
            };
            s.blocks.push_back((r.y, r.h, planes));
            s.next += r.h;
        }
        for (b0, bh, bp) in &s.blocks {
            let (a, b) = (y0.max(*b0), y1.min(b0 + bh));
            if a >= b {
                continue;
            }
            for (p, &ch) in planes.iter_mut().zip(&self.channels) {
                p.extend_from_slice(&bp[ch][(a - b0) * w..(b - b0) * w]);
            }
        }
        self.row = y1;
        s.positions[self.id] = y1;
        let done = s.positions.iter().copied().min().unwrap_or(0);
        while s.blocks.front().is_some_and(|(b0, bh, _)| b0 + bh <= done) {
            if let Some((_, _, planes)) = s.blocks.pop_front() {
                s.spare = Some(planes);
            }
        }
        Ok(())
    }
}
