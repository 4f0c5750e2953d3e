//! The tile pyramid of a published folder, written level by level as rows arrive: Deep Zoom
//! (DZI) geometry, 2×2 reductions and PNG tiles, with memory bounded by one band of tile rows
//! per level (not by the image).
//!
//! # Deep Zoom
//!
//! Level `max = ⌈log₂ max(w, h)⌉` is the image; level `k` is `⌈w / 2^(max−k)⌉ × ⌈h / 2^(max−k)⌉`
//! (level 0 is one pixel). Each level is cut into [`TILE`]² tiles, column `c`, row `r`, each
//! grown by [`OVERLAP`] pixels into its neighbours (not past the level's edge), stored as
//! `LAYER_files/k/c_r.png`. This is what OpenSeadragon's `DziTileSource` and OpenLIME's
//! `deepzoom1px` layout read (OpenLIME needs a power-of-two tile side: 512 is).
//!
//! # Reduction
//!
//! Level `k − 1` is level `k` in 2×2 blocks (the last column or row alone when the side is odd):
//! colour and normals are the means weighted by coverage (unweighted where the block has none),
//! normals renormalised, coverage the block's mean.
//!
//! # Rows in, tiles out
//!
//! [`Pyramid::push`] takes the next rows of the image. Each level keeps its rows quantised to
//! 8 bits in a band that holds the tile row being filled (plus the overlap), writes a tile row as
//! soon as its last row is in, and hands pairs of rows, reduced, to the next level; an odd row
//! waits for its pair. So a level holds at most one tile row and one batch of rows, and the
//! whole pyramid about twice the finest level's band.

use super::fallback::Fallback;
use crate::error::RgbnError;
use crate::raster::io::DEFAULT_ALBEDO;
use crate::raster::srgb::linear_to_srgb;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// A tile column and its two encoded PNGs (albedo, normals).
type EncodedTile = (usize, Vec<u8>, Vec<u8>);

/// Tile side in pixels (without the overlap).
pub const TILE: usize = 512;
/// Pixels each tile shares with its neighbours on each inner side.
pub const OVERLAP: usize = 1;
/// Floats per pixel in a reduced row: linear colour (3), unit normal (3), coverage.
const PX: usize = 7;

/// One level of the pyramid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Level {
    /// The Deep Zoom level number (0: one pixel).
    pub level: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Tile columns.
    pub cols: usize,
    /// Tile rows.
    pub rows: usize,
}

/// The Deep Zoom levels of a `width × height` image, level 0 (one pixel) first.
#[must_use]
pub fn levels(width: usize, height: usize) -> Vec<Level> {
    let (w, h) = (width.max(1), height.max(1));
    let max = w.max(h).next_power_of_two().trailing_zeros() as usize;
    (0..=max)
        .map(|k| {
            let s = 1usize << (max - k);
            let (lw, lh) = (w.div_ceil(s), h.div_ceil(s));
            Level {
                level: k,
                width: lw,
                height: lh,
                cols: lw.div_ceil(TILE),
                rows: lh.div_ceil(TILE),
            }
        })
        .collect()
}

/// The pixels of tile `(col, row)` of a level `size` wide or high along one axis: first pixel
/// and count, the overlap included.
#[must_use]
pub fn tile_span(size: usize, i: usize) -> (usize, usize) {
    let a = (i * TILE).saturating_sub(OVERLAP);
    let b = ((i + 1) * TILE + OVERLAP).min(size);
    (a, b - a)
}

/// Where tile `(col, row)` of `layer` at Deep Zoom `level` is, relative to the folder.
#[must_use]
pub fn tile_path(layer: &str, level: usize, col: usize, row: usize) -> PathBuf {
    PathBuf::from(format!("{layer}_files/{level}/{col}_{row}.png"))
}

/// The `.dzi` descriptor of a layer.
#[must_use]
pub fn dzi(width: usize, height: usize) -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Image xmlns=\"http://schemas.microsoft.com/deepzoom/2008\" Format=\"png\" Overlap=\"{OVERLAP}\" TileSize=\"{TILE}\">\n  <Size Width=\"{width}\" Height=\"{height}\"/>\n</Image>\n"
    )
}

/// Rows of an image as float planes: linear colour (`None`: [`DEFAULT_ALBEDO`]), unit normals,
/// coverage (`None`: 1).
#[derive(Clone, Copy)]
pub struct PlaneRows<'a> {
    /// Width in pixels.
    pub width: usize,
    /// Linear colour planes.
    pub color: Option<[&'a [f32]; 3]>,
    /// Unit normal planes.
    pub normal: [&'a [f32]; 3],
    /// Coverage.
    pub coverage: Option<&'a [f32]>,
}

/// Pixels read by row and column.
trait Source: Sync {
    fn rows(&self) -> usize;
    /// Colour, normal, coverage of pixel `x` of row `y`.
    fn px(&self, y: usize, x: usize) -> [f32; PX];
}

impl Source for PlaneRows<'_> {
    fn rows(&self) -> usize {
        self.normal[0].len() / self.width.max(1)
    }
    #[inline]
    fn px(&self, y: usize, x: usize) -> [f32; PX] {
        let i = y * self.width + x;
        let c = self
            .color
            .map_or([DEFAULT_ALBEDO; 3], |c| [c[0][i], c[1][i], c[2][i]]);
        let n = [self.normal[0][i], self.normal[1][i], self.normal[2][i]];
        let a = self.coverage.map_or(1.0, |m| m[i]);
        [c[0], c[1], c[2], n[0], n[1], n[2], a]
    }
}

/// Reduced rows, [`PX`] floats per pixel.
struct Packed<'a> {
    width: usize,
    data: &'a [f32],
}

impl Source for Packed<'_> {
    fn rows(&self) -> usize {
        self.data.len() / (PX * self.width.max(1))
    }
    #[inline]
    fn px(&self, y: usize, x: usize) -> [f32; PX] {
        let i = (y * self.width + x) * PX;
        self.data[i..i + PX].try_into().expect("PX floats")
    }
}

/// A level's waiting odd row, then a batch.
struct Chain<'a, S> {
    first: Option<Packed<'a>>,
    rest: &'a S,
}

impl<S: Source> Source for Chain<'_, S> {
    fn rows(&self) -> usize {
        usize::from(self.first.is_some()) + self.rest.rows()
    }
    #[inline]
    fn px(&self, y: usize, x: usize) -> [f32; PX] {
        match &self.first {
            Some(f) if y == 0 => f.px(0, x),
            Some(_) => self.rest.px(y - 1, x),
            None => self.rest.px(y, x),
        }
    }
}

/// The reduction of rows `2o` and `2o + 1` (or `2o` alone) of `src`, `width` wide, into
/// `out` (one reduced row).
fn reduce_row<S: Source>(src: &S, width: usize, o: usize, alone: bool, out: &mut [f32]) {
    let ys: &[usize] = if alone { &[0] } else { &[0, 1] };
    for (x, o_px) in out.chunks_exact_mut(PX).enumerate() {
        let mut block = [[0.0f32; PX]; 4];
        let mut n = 0;
        for &dy in ys {
            for sx in 2 * x..(2 * x + 2).min(width) {
                block[n] = src.px(2 * o + dy, sx);
                n += 1;
            }
        }
        let block = &block[..n];
        let cov: f32 = block.iter().map(|p| p[6]).sum();
        let weighted = cov > 0.0;
        let wsum = if weighted { cov } else { n as f32 };
        let weight = |p: &[f32; PX]| if weighted { p[6] } else { 1.0 };
        for (j, o) in o_px[..3].iter_mut().enumerate() {
            *o = block.iter().map(|p| weight(p) * p[j]).sum::<f32>() / wsum;
        }
        let v: [f32; 3] = std::array::from_fn(|j| block.iter().map(|p| weight(p) * p[3 + j]).sum());
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let v = if len > 1e-12 && len.is_finite() {
            v.map(|c| c / len)
        } else {
            [0.0, 0.0, 1.0]
        };
        o_px[3..6].copy_from_slice(&v);
        o_px[6] = cov / n as f32;
    }
}

/// sRGB 8-bit of a linear value.
#[inline]
fn srgb8(v: f32) -> u8 {
    (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8
}

/// `(n + 1)/2` in 8 bits.
#[inline]
fn unit8(v: f32) -> u8 {
    ((v.clamp(-1.0, 1.0) + 1.0) * 127.5 + 0.5) as u8
}

/// One level being written.
struct LevelWriter {
    level: Level,
    /// Rows received.
    received: usize,
    /// The image row of the band's first row.
    band_y0: usize,
    /// Albedo bytes of the band (RGB, or RGBA with the coverage when masked).
    albedo: Vec<u8>,
    /// Normal bytes of the band (RGB).
    normals: Vec<u8>,
    /// The next tile row to write.
    next_tile_row: usize,
    /// A row waiting for its pair (reduced form).
    pending: Option<Vec<f32>>,
}

/// Tile files written, and their bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Written {
    /// Tile files.
    pub tiles: usize,
    /// Bytes of tile files.
    pub bytes: u64,
}

/// The pyramid being written into a folder (see the module docs).
pub struct Pyramid<'d> {
    dir: &'d Path,
    masked: bool,
    /// Index: Deep Zoom level.
    writers: Vec<LevelWriter>,
    fallback: Fallback,
    written: Written,
}

impl<'d> Pyramid<'d> {
    /// Starts the pyramid of a `width × height` image in `dir` (the layer folders are created
    /// as levels are written). `masked`: the albedo tiles carry the coverage in alpha.
    pub fn new(dir: &'d Path, width: usize, height: usize, masked: bool) -> Self {
        let writers = levels(width, height)
            .into_iter()
            .map(|level| LevelWriter {
                level,
                received: 0,
                band_y0: 0,
                albedo: Vec::new(),
                normals: Vec::new(),
                next_tile_row: 0,
                pending: None,
            })
            .collect();
        Self {
            dir,
            masked,
            writers,
            fallback: Fallback::new(),
            written: Written::default(),
        }
    }

    /// The levels, level 0 (one pixel) first.
    #[must_use]
    pub fn levels(&self) -> Vec<Level> {
        self.writers.iter().map(|w| w.level).collect()
    }

    /// Takes the image's next rows (in order, top to bottom).
    pub fn push(&mut self, rows: &PlaneRows<'_>) -> Result<(), RgbnError> {
        let top = self.writers.len() - 1;
        self.push_at(top, rows)
    }

    /// What was written and the levels with a fallback script; errors if rows are missing.
    pub fn finish(self) -> Result<(Written, Vec<usize>), RgbnError> {
        for w in &self.writers {
            if w.received != w.level.height || w.next_tile_row != w.level.rows {
                return Err(RgbnError::Write {
                    detail: format!(
                        "level {} got {} of {} rows",
                        w.level.level, w.received, w.level.height
                    ),
                    path: self.dir.into(),
                });
            }
        }
        self.fallback.write(self.dir)?;
        Ok((self.written, self.fallback.levels()))
    }

    fn push_at<S: Source>(&mut self, k: usize, rows: &S) -> Result<(), RgbnError> {
        let n = rows.rows();
        if n == 0 {
            return Ok(());
        }
        let w = &mut self.writers[k];
        let (lw, lh) = (w.level.width, w.level.height);
        if w.received + n > lh {
            return Err(RgbnError::Write {
                detail: format!("level {k} got more than its {lh} rows"),
                path: self.dir.into(),
            });
        }
        // Quantise into the band.
        let ac = if self.masked { 4 } else { 3 };
        let (a0, n0) = (w.albedo.len(), w.normals.len());
        w.albedo.resize(a0 + n * lw * ac, 0);
        w.normals.resize(n0 + n * lw * 3, 0);
        w.albedo[a0..]
            .par_chunks_mut(lw * ac)
            .zip(w.normals[n0..].par_chunks_mut(lw * 3))
            .enumerate()
            .for_each(|(y, (a, nrm))| {
                for x in 0..lw {
                    let p = rows.px(y, x);
                    a[x * ac] = srgb8(p[0]);
                    a[x * ac + 1] = srgb8(p[1]);
                    a[x * ac + 2] = srgb8(p[2]);
                    if ac == 4 {
                        a[x * ac + 3] = (p[6].clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
                    }
                    nrm[x * 3] = unit8(p[3]);
                    nrm[x * 3 + 1] = unit8(p[4]);
                    nrm[x * 3 + 2] = unit8(p[5]);
                }
            });
        w.received += n;
        self.write_ready_tiles(k)?;
        if k == 0 {
            return Ok(());
        }
        // Pairs of rows, reduced, go to the next level; an odd row waits (or goes alone at the
        // level's end).
        let w = &mut self.writers[k];
        let pending = w.pending.take();
        let chain = Chain {
            first: pending.as_deref().map(|data| Packed { width: lw, data }),
            rest: rows,
        };
        let total = chain.rows();
        let last = w.received == lh;
        let pairs = total / 2;
        let out_rows = pairs + usize::from(last && total % 2 == 1);
        let ow = lw.div_ceil(2);
        let mut out = vec![0.0f32; out_rows * ow * PX];
        out.par_chunks_mut(ow * PX)
            .enumerate()
            .for_each(|(o, row)| reduce_row(&chain, lw, o, o == pairs, row));
        if !last && total % 2 == 1 {
            let mut keep = vec![0.0f32; lw * PX];
            for (x, p) in keep.chunks_exact_mut(PX).enumerate() {
                p.copy_from_slice(&chain.px(total - 1, x));
            }
            self.writers[k].pending = Some(keep);
        }
        drop(pending);
        self.push_at(
            k - 1,
            &Packed {
                width: ow,
                data: &out,
            },
        )
    }

    /// Writes every tile row of level `k` whose rows are all in, then drops the rows no later
    /// tile row needs.
    fn write_ready_tiles(&mut self, k: usize) -> Result<(), RgbnError> {
        let ac = if self.masked { 4 } else { 3 };
        loop {
            let w = &self.writers[k];
            let lv = w.level;
            if w.next_tile_row == lv.rows {
                return Ok(());
            }
            let (y0, th) = tile_span(lv.height, w.next_tile_row);
            if w.received < y0 + th {
                return Ok(());
            }
            let r = w.next_tile_row;
            let band_y0 = w.band_y0;
            let level_dir = |layer: &str| self.dir.join(format!("{layer}_files/{}", lv.level));
            if r == 0 {
                for layer in ["albedo", "normals"] {
                    let d = level_dir(layer);
                    std::fs::create_dir_all(&d).map_err(|e| RgbnError::Write {
                        detail: e.to_string(),
                        path: d.clone(),
                    })?;
                }
            }
            let keep_small = self.fallback.wants(lv);
            let tiles: Vec<Result<EncodedTile, RgbnError>> = (0..lv.cols)
                .into_par_iter()
                .map(|c| {
                    let (x0, tw) = tile_span(lv.width, c);
                    let crop = |band: &[u8], ch: usize| {
                        let mut t = Vec::with_capacity(tw * th * ch);
                        for y in y0..y0 + th {
                            let s = ((y - band_y0) * lv.width + x0) * ch;
                            t.extend_from_slice(&band[s..s + tw * ch]);
                        }
                        t
                    };
                    let a = encode_png(&crop(&w.albedo, ac), tw, th, ac)?;
                    let n = encode_png(&crop(&w.normals, 3), tw, th, 3)?;
                    for (layer, bytes) in [("albedo", &a), ("normals", &n)] {
                        let p = self.dir.join(tile_path(layer, lv.level, c, r));
                        std::fs::write(&p, bytes).map_err(|e| RgbnError::Write {
                            detail: e.to_string(),
                            path: p.clone(),
                        })?;
                    }
                    Ok((c, a, n))
                })
                .collect();
            for t in tiles {
                let (c, a, n) = t?;
                self.written.tiles += 2;
                self.written.bytes += (a.len() + n.len()) as u64;
                if keep_small {
                    self.fallback.add(lv, c, r, &a, &n);
                }
            }
            // The next tile row starts OVERLAP rows above its first own row.
            let w = &mut self.writers[k];
            w.next_tile_row += 1;
            let next_y0 = if w.next_tile_row < lv.rows {
                tile_span(lv.height, w.next_tile_row).0
            } else {
                lv.height
            };
            let drop_rows = next_y0
                .saturating_sub(w.band_y0)
                .min(w.received - w.band_y0);
            w.albedo.drain(..drop_rows * lv.width * ac);
            w.normals.drain(..drop_rows * lv.width * 3);
            w.band_y0 += drop_rows;
            if w.next_tile_row == lv.rows {
                w.albedo = Vec::new();
                w.normals = Vec::new();
            }
        }
    }
}

/// 8-bit PNG bytes (fast compression, adaptive filter: as the image writers).
fn encode_png(bytes: &[u8], w: usize, h: usize, channels: usize) -> Result<Vec<u8>, RgbnError> {
    let mut out = Vec::new();
    let err = |e: png::EncodingError| RgbnError::Write {
        detail: format!("PNG encoding: {e}"),
        path: PathBuf::new(),
    };
    {
        let mut enc = png::Encoder::new(&mut out, w as u32, h as u32);
        enc.set_color(match channels {
            1 => png::ColorType::Grayscale,
            4 => png::ColorType::Rgba,
            _ => png::ColorType::Rgb,
        });
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        enc.set_filter(png::Filter::Adaptive);
        let mut wr = enc.write_header().map_err(err)?;
        wr.write_image_data(bytes).map_err(err)?;
        wr.finish().map_err(err)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deep_zoom_levels_halve_rounding_up_down_to_one_pixel() {
        let l = levels(1000, 300);
        assert_eq!(l.len(), 11); // 2^10 = 1024 ≥ 1000
        assert_eq!((l[10].width, l[10].height), (1000, 300));
        assert_eq!((l[9].width, l[9].height), (500, 150));
        assert_eq!((l[8].width, l[8].height), (250, 75));
        assert_eq!((l[1].width, l[1].height), (2, 1));
        assert_eq!((l[0].width, l[0].height), (1, 1));
        assert_eq!((l[10].cols, l[10].rows), (2, 1));
        for w in l.windows(2) {
            assert_eq!(w[0].width, w[1].width.div_ceil(2));
            assert_eq!(w[0].height, w[1].height.div_ceil(2));
        }
        assert_eq!(levels(1, 1).len(), 1);
        assert_eq!(levels(16384, 16384).len(), 15);
    }

    #[test]
    fn tiles_overlap_their_neighbours_by_one_pixel_inside_the_level() {
        assert_eq!(tile_span(1000, 0), (0, 513));
        assert_eq!(tile_span(1000, 1), (511, 489));
        assert_eq!(tile_span(512, 0), (0, 512));
        assert_eq!(tile_span(1536, 1), (511, 514));
    }
}
