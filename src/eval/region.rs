//! Region evaluation: one graph output computed over a rectangle only, tile by tile
//! (GEGL's `get_required_for_output`, libvips' regions). This module is the only place that
//! knows about regions; operators state their [`Footprint`] and nothing else.
//!
//! 1. **Modes.** Walking up from the requested output, an instance is *tiled* when it has a
//!    connected input with a [`Footprint::Local`] footprint, is reached only through such
//!    inputs, and is not read through a `Number` port; everything else (sources, solvers,
//!    whatever a global operator reads) is evaluated *whole* with the ordinary evaluator and
//!    cached as before. At a coarse level, a global operator that has a coarse form (an
//!    integration, a projection) is evaluated *at the level* instead: whole, on its inputs at
//!    that level (tiled ones assembled from all their tiles), its outputs mapped back to
//!    full-resolution units (`Operator::level_outputs`), cached under (key, level).
//! 2. **Tiles.** A tiled instance's output plane is cut into `tile × tile` squares on a grid
//!    anchored at (0, 0). The requested rectangle asks its instance for the tiles covering it;
//!    each tile that is not in the memory cache asks every local input for the tiles covering
//!    it grown by the instance's halo (the largest of its inputs'), recursively.
//! 3. **Computing a tile.** Its inputs are cropped to the tile grown by the halo (clamped to
//!    the image, so a crop edge is either a real image edge, where the border mode applies as
//!    on the whole image, or at least a halo away), global inputs are passed whole, and the
//!    operator runs on the crop with its positional parameters shifted
//!    ([`crate::nodes::Operator::shifted`]); the tile is cut out of the result. Tiles of one
//!    instance run in parallel.
//! 4. **Caching.** Tiles live in the evaluator's byte-budgeted memory cache under
//!    (content key, level, tile size, tile position); an edit changes the content key of what
//!    depends on it, so unchanged instances keep their tiles.
//!
//! A tiled result equals the whole-image one: bit for bit where an operator's arithmetic does
//! not depend on where the image ends, and within the documented truncation of a recursive
//! Gaussian (an impulse response tail below 0.05 % of its peak) otherwise. `Number` outputs are
//! not computed for tiles (they summarise a whole image).

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{CacheEntry, CacheKey, Conn, EvalOptions, Evaluator, NodeStats, Plan};
use crate::graph::GraphError;
use crate::nodes::{Footprint, Picture, PortType, RunContext, Value};
use crate::ops::params::nearest;
use crate::ops::params::ParamValue;
use crate::raster::sample::Window;
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;

/// A pixel rectangle: columns `x..x + w`, rows `y..y + h` (row 0 at the top).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Rect {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
}

impl Rect {
    /// The rectangle at `(x, y)` of `w × h` pixels.
    #[must_use]
    pub fn new(x: usize, y: usize, w: usize, h: usize) -> Self {
        Self { x, y, w, h }
    }
    /// A whole `w × h` image.
    #[must_use]
    pub fn full((w, h): (usize, usize)) -> Self {
        Self::new(0, 0, w, h)
    }
    /// One past the last column.
    #[must_use]
    pub fn right(&self) -> usize {
        self.x + self.w
    }
    /// One past the last row.
    #[must_use]
    pub fn bottom(&self) -> usize {
        self.y + self.h
    }
    /// No pixel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.w == 0 || self.h == 0
    }
    /// The pixels both cover (possibly empty).
    #[must_use]
    pub fn intersect(&self, o: &Rect) -> Rect {
        let (x, y) = (self.x.max(o.x), self.y.max(o.y));
        let (r, b) = (self.right().min(o.right()), self.bottom().min(o.bottom()));
        Rect::new(x, y, r.saturating_sub(x), b.saturating_sub(y))
    }
    /// Grown by `halo` on every side, then clamped to a `size` image.
    #[must_use]
    pub fn grow(&self, halo: usize, size: (usize, usize)) -> Rect {
        let (x, y) = (self.x.saturating_sub(halo), self.y.saturating_sub(halo));
        let r = (self.right() + halo).min(size.0);
        let b = (self.bottom() + halo).min(size.1);
        Rect::new(x, y, r.saturating_sub(x), b.saturating_sub(y))
    }
    /// Parses `X,Y,W,H` (pixels).
    pub fn parse(s: &str) -> Result<Rect, String> {
        let v: Vec<&str> = s.split(',').map(str::trim).collect();
        let bad = || format!("region {s:?} must be X,Y,W,H in whole pixels, e.g. 0,0,512,512");
        if v.len() != 4 {
            return Err(bad());
        }
        let mut n = [0usize; 4];
        for (o, t) in n.iter_mut().zip(&v) {
            *o = t.parse().map_err(|_| bad())?;
        }
        let r = Rect::new(n[0], n[1], n[2], n[3]);
        if r.is_empty() {
            return Err(format!("region {s:?} is empty: W and H must be at least 1"));
        }
        Ok(r)
    }
}

impl std::fmt::Display for Rect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x, self.y, self.w, self.h)
    }
}

/// Tile side in pixels when none is given: whole-image and batch work, where larger tiles
/// spend less on halos (see BENCHMARKS.md, "Tile size").
pub const DEFAULT_TILE: usize = 512;

/// Tile side for interactive edits: a small edit recomputes less (see BENCHMARKS.md, "Tile
/// size").
pub const INTERACTIVE_TILE: usize = 64;

/// The coarsest level of detail (a 2^20 reduction).
pub const MAX_LEVEL: u32 = 20;

/// Options of a region evaluation.
#[derive(Clone, Copy, Debug)]
pub struct RegionOptions {
    /// Tile side in pixels (≥ 16).
    pub tile: usize,
    /// Level of detail: 0 is full resolution, level `L` the output reduced by `2^L`
    /// ([`crate::raster::pyramid`]); the rectangle is in the level's pixels.
    pub level: u32,
}

impl Default for RegionOptions {
    fn default() -> Self {
        Self {
            tile: DEFAULT_TILE,
            level: 0,
        }
    }
}

impl RegionOptions {
    /// Tiles of `tile` pixels at full resolution.
    #[must_use]
    pub fn tiles(tile: usize) -> Self {
        Self { tile, level: 0 }
    }
}

/// Tiles computed and reused at one tiled instance.
#[derive(Clone, Debug)]
pub struct TileStats {
    /// The instance's node.
    pub at: crate::graph::At,
    /// Operator id.
    pub op: &'static str,
    /// Tiles computed.
    pub computed: usize,
    /// Tiles taken from the cache.
    pub cached: usize,
    /// Tiles taken from the previous result because an edit cannot have changed them (they
    /// lie outside its damage).
    pub reused: usize,
    /// Pixels of the tiles computed.
    pub pixels: usize,
}

/// The result of [`Evaluator::eval_region`].
#[derive(Clone, Debug)]
pub struct RegionResult {
    /// The output over the rectangle (its size is the rectangle's).
    pub value: Value,
    /// The rectangle, clamped to the output's size.
    pub rect: Rect,
    /// The output's whole size (at the level).
    pub size: (usize, usize),
    /// The output's whole size at full resolution.
    pub full_size: (usize, usize),
    /// The instances evaluated whole (sources, global operators).
    pub whole: Vec<NodeStats>,
    /// Per tiled instance, in evaluation order.
    pub tiles: Vec<TileStats>,
    /// Content key of the whole output at full resolution ([`super::port_key`]): the key
    /// [`Evaluator::eval`] gives the same output, so a region can be matched with it.
    pub key: CacheKey,
}

impl RegionResult {
    /// Tiles computed over all instances.
    #[must_use]
    pub fn tiles_computed(&self) -> usize {
        self.tiles.iter().map(|t| t.computed).sum()
    }
    /// Pixels of the tiles computed over all instances.
    #[must_use]
    pub fn pixels_computed(&self) -> usize {
        self.tiles.iter().map(|t| t.pixels).sum()
    }
}

/// A tiled instance as last evaluated: what a later evaluation compares with to find what an
/// edit changed (damage).
#[derive(Clone, Debug)]
struct Seen {
    key: CacheKey,
    params: BTreeMap<String, ParamValue>,
    /// Content keys of the inputs in port order.
    inputs: Vec<Option<CacheKey>>,
    /// The edits that led to `key`, oldest first: each an earlier key and what changed from
    /// it to the next one.
    trail: Trail,
}

/// Earlier keys of an instance, oldest first, each with the pixels that may differ from it to
/// the next key (`None`: anywhere).
type Trail = Vec<(CacheKey, Option<Vec<Rect>>)>;

/// Edits remembered per instance.
const TRAIL: usize = 16;

/// The pixels that may differ between key `from` of an instance and its current key, from its
/// trail (`None`: anywhere, or `from` not in the trail).
fn damage_since(trail: &Trail, from: CacheKey) -> Option<Vec<Rect>> {
    let mut acc = Vec::new();
    for (k, d) in trail.iter().rev() {
        acc.extend(d.as_ref()?.iter().copied());
        if *k == from {
            return Some(acc);
        }
    }
    None
}

/// An instance as the history knows it: (instance index, operator, file, node id). A plan
/// rebuilt after an edit keeps its indices while the graph's shape stays the same.
type Ident = (usize, &'static str, String, Option<u64>);

/// The evaluator's memory of tiled instances, by [`Ident`] and level of detail (each level's
/// damage is in its own pixels, from the instance's parameters at that level).
#[derive(Default, Debug)]
pub(super) struct History {
    seen: HashMap<(Ident, u32), Seen>,
    /// The last result, to patch where an edit changed it rather than assemble it again.
    last: Option<LastResult>,
}

/// A region result as returned, with what it was made from.
#[derive(Debug)]
struct LastResult {
    ident: Ident,
    port: usize,
    rect: Rect,
    tile: usize,
    level: u32,
    key: CacheKey,
    value: Value,
}

/// The damage boxes of an operator as pixel rectangles of a `size` image.
fn boxes_to_rects(boxes: &[[f64; 4]], size: (usize, usize)) -> Vec<Rect> {
    boxes
        .iter()
        .filter_map(|b| {
            let clamp = |v: f64, n: usize| {
                if v.is_nan() {
                    0
                } else {
                    v.clamp(0.0, n as f64) as usize
                }
            };
            let (x0, y0) = (clamp(b[0].floor(), size.0), clamp(b[1].floor(), size.1));
            let (x1, y1) = (
                clamp(b[2].ceil() + 1.0, size.0),
                clamp(b[3].ceil() + 1.0, size.1),
            );
            let r = Rect::new(x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0));
            (!r.is_empty()).then_some(r)
        })
        .collect()
}

/// How an instance is evaluated for a region, in increasing order of what it needs: a value
/// wanted in two modes takes the later one.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Mode {
    Unneeded,
    /// Tile by tile, at the level.
    Tiled,
    /// Whole, at a coarse level: a global operator with a coarse form run on its inputs at the
    /// level ([`at_level`]).
    Level,
    /// Whole at full resolution with the ordinary evaluator (reduced at a coarse level).
    Whole,
}

/// Parameters per instance at a level of detail.
type LevelParams = [Option<BTreeMap<String, ParamValue>>];

/// The parameters of every instance at level `level` (reduction `s`): their own at level 0 and
/// for regional sources (which sample the level themselves), [`crate::nodes::Operator::scaled`]
/// otherwise (`None`: no coarse form).
fn level_params(plan: &Plan, level: u32, s: usize) -> Vec<Option<BTreeMap<String, ParamValue>>> {
    plan.instances
        .iter()
        .map(|inst| {
            if level == 0 || inst.op.regional(&inst.params) {
                Some(inst.params.clone())
            } else {
                inst.op.scaled(&inst.params, s as f64)
            }
        })
        .collect()
}

/// Input `k`'s footprint of instance `i` with its parameters at the level.
fn footprint(plan: &Plan, lp: &LevelParams, i: usize, k: usize) -> Footprint {
    let inst = &plan.instances[i];
    match &lp[i] {
        Some(p) => inst.op.footprint(p, k),
        None => Footprint::Global,
    }
}

/// The largest halo of an instance's local inputs, `None` when it has no connected local
/// input and is not [regional](crate::nodes::Operator::regional), or has no form at the level
/// (then it is evaluated whole).
fn local_halo(plan: &Plan, lp: &LevelParams, i: usize) -> Option<usize> {
    let inst = &plan.instances[i];
    if inst.op.spec().side_effect || lp[i].is_none() {
        return None;
    }
    if regional(plan, i) {
        return Some(0);
    }
    inst.inputs
        .iter()
        .enumerate()
        .filter(|(_, c)| matches!(c, Conn::Slot(..)))
        .filter_map(|(k, _)| match footprint(plan, lp, i, k) {
            Footprint::Local { halo } => Some(halo),
            Footprint::Global | Footprint::Pattern => None,
        })
        .max()
}

/// Whether instance `i` can be evaluated whole at coarse level `level` on its inputs at that
/// level: a global operator (no local input) with a coarse form ([`crate::nodes::Operator::scaled`]),
/// e.g. an integration. Its result approximates the full-resolution one reduced, at the
/// cost of the level's pixels rather than the image's.
/// `known`: the instances' full-resolution sizes as far as known before running; the level
/// must leave the output at least [`LEVEL_MIN_SIDE`] pixels a side.
fn at_level(
    plan: &Plan,
    lp: &LevelParams,
    level: u32,
    i: usize,
    known: &[Option<(usize, usize)>],
) -> bool {
    let inst = &plan.instances[i];
    let big = known[i].is_some_and(|(w, h)| (w.min(h) >> level) >= LEVEL_MIN_SIDE);
    level > 0
        && big
        && lp[i].is_some()
        && !inst.op.spec().side_effect
        && !regional(plan, i)
        && local_halo(plan, lp, i).is_none()
        && inst.inputs.iter().any(|c| matches!(c, Conn::Slot(..)))
}

/// Whether graph output `output` depends on a global operator that has a coarse form (an
/// integration, a projection): at a coarse level it costs that level's pixels instead of the
/// whole image's, so an editor can show such an output at a coarse level while edits keep
/// coming.
#[must_use]
pub fn depends_on_coarse_global(plan: &Plan, output: &str) -> bool {
    let Some(Conn::Slot(root, _)) = plan.outputs.get(output) else {
        return false;
    };
    let lp = level_params(plan, 1, 2);
    let known = super::memory::sizes(plan, &HashMap::new());
    let mut up = vec![false; plan.instances.len()];
    up[*root] = true;
    for i in (0..=*root).rev() {
        if !up[i] {
            continue;
        }
        if at_level(plan, &lp, 1, i, &known) {
            return true;
        }
        for c in &plan.instances[i].inputs {
            if let Conn::Slot(j, _) = c {
                up[*j] = true;
            }
        }
    }
    false
}

/// The smallest side, in pixels of the level, on which a global operator runs at a coarse
/// level; coarser (a size probe, a tiny image), it is computed whole and reduced.
pub const LEVEL_MIN_SIDE: usize = 16;

/// The cache key of an instance's whole value computed at a level ([`Mode::Level`]); tile
/// side 1 is never a tile's.
fn level_key(key: CacheKey, level: u32) -> CacheKey {
    tile_key(key, 1, level, 0, 0)
}

/// Whether instance `i` computes any window on its own (its inputs, if any, passed whole).
fn regional(plan: &Plan, i: usize) -> bool {
    let inst = &plan.instances[i];
    inst.op.regional(&inst.params)
}

fn tile_key(key: CacheKey, tile: usize, level: u32, tx: usize, ty: usize) -> CacheKey {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(b"rgbn-tile-1\0");
    h.update(&key.to_le_bytes());
    for v in [tile as u64, u64::from(level), tx as u64, ty as u64] {
        h.update(&v.to_le_bytes());
    }
    h.digest128()
}

/// The tiles (column, row of the grid) covering `r`.
fn covering(r: &Rect, tile: usize) -> impl Iterator<Item = (usize, usize)> {
    let (x0, x1) = (r.x / tile, r.right().div_ceil(tile));
    let (y0, y1) = (r.y / tile, r.bottom().div_ceil(tile));
    let empty = r.is_empty();
    (y0..y1)
        .flat_map(move |ty| (x0..x1).map(move |tx| (tx, ty)))
        .filter(move |_| !empty)
}

fn tile_rect((tx, ty): (usize, usize), tile: usize, size: (usize, usize)) -> Rect {
    Rect::new(tx * tile, ty * tile, tile, tile).intersect(&Rect::full(size))
}

/// A tile's column and row in the grid.
type Tile = (usize, usize);

type TileMap = HashMap<Tile, Arc<CacheEntry>>;

impl Evaluator {
    /// Evaluates graph output `output` over `rect` only (clamped to the output's size), tile by
    /// tile (module docs). The instances it cannot tile are evaluated whole and cached as by
    /// [`Evaluator::eval`].
    pub fn eval_region(
        &self,
        plan: &Plan,
        output: &str,
        rect: Rect,
        ropts: &RegionOptions,
        opts: &EvalOptions,
    ) -> Result<RegionResult, GraphError> {
        let tile = ropts.tile.max(16);
        let level = ropts.level.min(MAX_LEVEL);
        let s = 1usize << level;
        let lp = level_params(plan, level, s);
        let (root, root_port) = match plan.outputs.get(output) {
            Some(Conn::Slot(i, p)) => (*i, *p),
            Some(Conn::Unbound { name, at }) => {
                return Err(GraphError::UnboundInput {
                    name: name.clone(),
                    at: at.clone(),
                })
            }
            Some(Conn::None) | None => {
                return Err(GraphError::Unknown {
                    what: "graph output",
                    name: output.to_string(),
                    suggestion: nearest(output, plan.outputs.keys().map(String::as_str)),
                    at: plan.at.clone(),
                })
            }
        };
        if plan.output_types.get(output) == Some(&PortType::Number) {
            return Err(GraphError::Param {
                param: "region".into(),
                detail: format!(
                    "graph output {output:?} is a number, which has no region; ask for an image, mask, field or picture output"
                ),
                at: plan.at.clone(),
            });
        }
        // 1. Modes, from the output up (instances are in topological order).
        let n = plan.instances.len();
        let known = super::memory::sizes(plan, &HashMap::new());
        let mut mode = vec![Mode::Unneeded; n];
        mode[root] = if local_halo(plan, &lp, root).is_some() {
            Mode::Tiled
        } else if at_level(plan, &lp, level, root, &known) {
            Mode::Level
        } else {
            Mode::Whole
        };
        for i in (0..=root).rev() {
            if mode[i] == Mode::Unneeded {
                continue;
            }
            let inst = &plan.instances[i];
            for (k, c) in inst.inputs.iter().enumerate() {
                let Conn::Slot(j, port) = c else { continue };
                let fp = footprint(plan, &lp, i, k);
                // What instance i needs of input j: tiles (a local input of a tiled instance,
                // or any input of one evaluated at the level, which takes all of its tiles), the
                // value at the level, or the whole full-resolution value.
                let by_level = matches!(mode[i], Mode::Tiled | Mode::Level)
                    && !plan.is_number(*j, *port)
                    && !regional(plan, i)
                    && fp != Footprint::Pattern;
                let tiles = local_halo(plan, &lp, *j).is_some()
                    && match mode[i] {
                        Mode::Tiled => matches!(fp, Footprint::Local { .. }),
                        _ => mode[i] == Mode::Level,
                    };
                let need = if by_level && tiles {
                    Mode::Tiled
                } else if by_level && at_level(plan, &lp, level, *j, &known) {
                    Mode::Level
                } else {
                    Mode::Whole
                };
                mode[*j] = mode[*j].max(need);
            }
        }
        // 2. Whole instances that tiled ones, ones at the level (or the request) read directly.
        let whole_roots: Vec<usize> = (0..n)
            .filter(|&j| mode[j] == Mode::Whole)
            .filter(|&j| {
                j == root
                    || plan.instances.iter().enumerate().any(|(i, inst)| {
                        matches!(mode[i], Mode::Tiled | Mode::Level)
                            && inst
                                .inputs
                                .iter()
                                .any(|c| matches!(c, Conn::Slot(s, _) if *s == j))
                    })
            })
            .collect();
        let whole = self.eval_instances(plan, &whole_roots, opts)?;
        let mut keys = whole.keys;
        // The whole results at the level: reduced (and cached so) at a coarse one.
        let mut wv: HashMap<usize, Arc<CacheEntry>> = whole
            .results
            .iter()
            .map(|(j, e)| {
                if s == 1 {
                    return (*j, e.clone());
                }
                let k = tile_key(keys[j], 0, level, 0, 0);
                let r = self.mem_get(k).unwrap_or_else(|| {
                    let r = Arc::new(CacheEntry {
                        values: e.values.iter().map(|v| reduce(v, s)).collect(),
                        curl: None,
                        fraction: None,
                    });
                    self.mem_insert(k, r.clone());
                    r
                });
                (*j, r)
            })
            .collect();
        // 3. Sizes of tiled instances: their first connected local input's.
        let mut size: Vec<Option<(usize, usize)>> = vec![None; n];
        for (j, e) in &whole.results {
            size[*j] = e.values.iter().find_map(super::memory::value_size);
        }
        for i in 0..=root {
            let inst = &plan.instances[i];
            if mode[i] == Mode::Level {
                let sizes: Vec<Option<(usize, usize)>> = inst
                    .inputs
                    .iter()
                    .map(|c| match c {
                        Conn::Slot(j, port) => match whole.results.get(j) {
                            Some(e) => e.values.get(*port).and_then(super::memory::value_size),
                            None => size[*j],
                        },
                        _ => None,
                    })
                    .collect();
                size[i] = inst.op.out_size(&inst.params, &sizes);
                self.key(plan, i, &mut keys)?;
                continue;
            }
            if mode[i] != Mode::Tiled {
                continue;
            }
            // Every local input must have the same size: they are cropped alike.
            let mut first: Option<(&str, (usize, usize))> = None;
            for (k, c) in inst.inputs.iter().enumerate() {
                let Conn::Slot(j, port) = c else { continue };
                if !matches!(footprint(plan, &lp, i, k), Footprint::Local { .. }) {
                    continue;
                }
                let s = match whole.results.get(j) {
                    Some(e) => e.values.get(*port).and_then(super::memory::value_size),
                    None => size[*j],
                };
                let (Some(s), name) = (s, inst.op.spec().inputs[k].name.as_str()) else {
                    continue;
                };
                match first {
                    None => first = Some((name, s)),
                    Some((f, fs)) if fs != s => {
                        return Err(GraphError::Node {
                            op: inst.op.spec().id.to_string(),
                            source: crate::error::RgbnError::InvalidImage(format!(
                                "input {name:?} is {}×{} but input {f:?} is {}×{}: give both the same size",
                                s.0, s.1, fs.0, fs.1
                            )),
                            at: inst.at.clone(),
                        });
                    }
                    Some(_) => {}
                }
            }
            size[i] = first.map(|(_, s)| s);
            if regional(plan, i) {
                let sizes: Vec<Option<(usize, usize)>> = inst
                    .inputs
                    .iter()
                    .map(|c| match c {
                        Conn::Slot(j, port) => whole
                            .results
                            .get(j)
                            .and_then(|e| e.values.get(*port))
                            .and_then(super::memory::value_size),
                        _ => None,
                    })
                    .collect();
                size[i] = inst.op.out_size(&inst.params, &sizes);
            }
            self.key(plan, i, &mut keys)?;
        }
        // At full resolution, an instance whose whole value is in the memory cache (an editor
        // evaluated it whole) is cropped rather than computed again tile by tile; the
        // instances above it are then not needed for it.
        if level == 0 {
            for i in 0..=root {
                if mode[i] != Mode::Tiled {
                    continue;
                }
                if let Some(e) = self.mem_get(keys[&i]) {
                    mode[i] = Mode::Whole;
                    wv.insert(i, e);
                }
            }
        }
        let lsize: Vec<Option<(usize, usize)>> = size
            .iter()
            .map(|z| z.map(|z| crate::raster::pyramid::reduced_size(z, s)))
            .collect();
        // Damage: what each tiled instance's edit (its parameters, its inputs' damage grown by
        // its halo) can have changed since it was last evaluated at this level, in the level's
        // pixels.
        let mut trails: Vec<Trail> = vec![Vec::new(); n];
        {
            let mut hist = super::lock(&self.seen);
            for i in 0..=root {
                if mode[i] != Mode::Tiled {
                    continue;
                }
                let inst = &plan.instances[i];
                let spec = inst.op.spec();
                let ident = ((i, spec.id, inst.at.file.clone(), inst.at.node), level);
                let input_keys: Vec<Option<CacheKey>> = inst
                    .inputs
                    .iter()
                    .map(|c| match c {
                        Conn::Slot(j, port) => keys.get(j).map(|k| k ^ (*port as u128)),
                        _ => None,
                    })
                    .collect();
                let key = keys[&i];
                let params = lp[i].as_ref().unwrap_or(&inst.params);
                let trail = match hist.seen.get(&ident) {
                    Some(old) if old.key == key => old.trail.clone(),
                    Some(old) if old.inputs.len() == input_keys.len() => {
                        let d = damage_of(plan, &lp, i, old, &input_keys, &trails, &lsize);
                        let mut t = old.trail.clone();
                        t.push((old.key, d));
                        let cut = t.len().saturating_sub(TRAIL);
                        t.drain(..cut);
                        t
                    }
                    _ => Vec::new(),
                };
                trails[i] = trail.clone();
                hist.seen.insert(
                    ident,
                    Seen {
                        key,
                        params: params.clone(),
                        inputs: input_keys,
                        trail,
                    },
                );
            }
        }
        let Some(out_size) = lsize[root] else {
            return Err(GraphError::Param {
                param: "region".into(),
                detail: format!("graph output {output:?} has no pixel size"),
                at: plan.at.clone(),
            });
        };
        let rect = rect.intersect(&Rect::full(out_size));
        if rect.is_empty() {
            return Err(GraphError::Param {
                param: "region".into(),
                detail: format!(
                    "the region lies outside graph output {output:?} ({}×{})",
                    out_size.0, out_size.1
                ),
                at: plan.at.clone(),
            });
        }
        if mode[root] == Mode::Whole {
            let v = wv[&root].values[root_port].clone();
            return Ok(RegionResult {
                value: crop(&v, rect),
                rect,
                size: out_size,
                full_size: size[root].unwrap_or(out_size),
                whole: whole.stats,
                tiles: Vec::new(),
                key: super::port_key(keys[&root], root_port),
            });
        }
        // The previous result of the same request, if it can be patched where the edits
        // since can have changed it: then only the tiles there are wanted.
        let root_inst = &plan.instances[root];
        let ident = (
            root,
            root_inst.op.spec().id,
            root_inst.at.file.clone(),
            root_inst.at.node,
        );
        let last = super::lock(&self.seen).last.take().and_then(|l| {
            let same = (&l.ident, l.port, l.rect, l.tile, l.level)
                == (&ident, root_port, rect, tile, level);
            let damage = if l.key == keys[&root] {
                Some(Vec::new())
            } else {
                damage_since(&trails[root], l.key)
            };
            match damage {
                Some(d) if same && patchable(&l.value) => Some((l.value, d)),
                _ => None,
            }
        });
        let touched = |t: &Tile, d: &[Rect]| {
            let tr = tile_rect(*t, tile, out_size);
            d.iter().any(|x| !x.intersect(&tr).is_empty())
        };
        // 4. Tiles wanted per tiled instance, and those to compute (not cached).
        let mut want: Vec<BTreeSet<(usize, usize)>> = vec![BTreeSet::new(); n];
        match &last {
            Some((_, d)) => want[root].extend(covering(&rect, tile).filter(|t| touched(t, d))),
            None => want[root].extend(covering(&rect, tile)),
        }
        let mut have: Vec<TileMap> = vec![HashMap::new(); n];
        let mut todo: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
        let mut reused = vec![0usize; n];
        // Instances at the level whose value is needed, and those of them to compute.
        let mut level_want = vec![false; n];
        level_want[root] = mode[root] == Mode::Level;
        let mut level_todo = vec![false; n];
        for i in (0..=root).rev() {
            let inst = &plan.instances[i];
            if mode[i] == Mode::Level && level_want[i] {
                if let Some(e) = self.mem_get(level_key(keys[&i], level)) {
                    wv.insert(i, e);
                    continue;
                }
                level_todo[i] = true;
                for c in &inst.inputs {
                    let Conn::Slot(j, _) = c else { continue };
                    match mode[*j] {
                        Mode::Tiled => {
                            let all = Rect::full(lsize[*j].unwrap_or_default());
                            want[*j].extend(covering(&all, tile));
                        }
                        Mode::Level => level_want[*j] = true,
                        _ => {}
                    }
                }
                continue;
            }
            if mode[i] != Mode::Tiled || want[i].is_empty() {
                continue;
            }
            let (key, sz) = (keys[&i], lsize[i].unwrap_or_default());
            let halo = local_halo(plan, &lp, i).unwrap_or(0);
            let wanted = std::mem::take(&mut want[i]);
            for t in wanted {
                if let Some(e) = self.mem_get(tile_key(key, tile, level, t.0, t.1)) {
                    have[i].insert(t, e);
                    continue;
                }
                // The same tile of an earlier key, if no edit since can have changed it.
                let tr = tile_rect(t, tile, sz);
                let earlier = trails[i]
                    .iter()
                    .rev()
                    .map_while(|(k, d)| {
                        let clear = d.as_ref()?.iter().all(|d| d.intersect(&tr).is_empty());
                        clear.then_some(*k)
                    })
                    .enumerate()
                    .find_map(|(depth, k)| {
                        self.mem_get(tile_key(k, tile, level, t.0, t.1))
                            .map(|e| (depth, e))
                    });
                if let Some((depth, e)) = earlier {
                    // Found far back: stored under the new key too (its bytes count once),
                    // so it stays reachable however many edits follow.
                    if depth >= TRAIL / 2 {
                        self.mem_insert(tile_key(key, tile, level, t.0, t.1), e.clone());
                    }
                    have[i].insert(t, e);
                    reused[i] += 1;
                    continue;
                }
                todo[i].push(t);
                let need = tile_rect(t, tile, sz).grow(halo, sz);
                for (k, c) in inst.inputs.iter().enumerate() {
                    let Conn::Slot(j, _) = c else { continue };
                    if mode[*j] == Mode::Tiled
                        && matches!(footprint(plan, &lp, i, k), Footprint::Local { .. })
                    {
                        want[*j].extend(covering(&need, tile));
                    }
                    if mode[*j] == Mode::Level {
                        level_want[*j] = true;
                    }
                }
            }
        }
        // 5. Compute, instance by instance in order, the tiles of each in parallel.
        let ctx = RunContext {
            protected: plan.protected.clone(),
        };
        let mut tiles = Vec::new();
        for i in 0..=root {
            if level_todo[i] {
                let e =
                    self.run_at_level(plan, &lp, i, (&mode, &have, &wv), &lsize, tile, s, &ctx)?;
                self.mem_insert(level_key(keys[&i], level), e.clone());
                let sz = lsize[i].unwrap_or_default();
                let inst = &plan.instances[i];
                tiles.push(TileStats {
                    at: inst.at.clone(),
                    op: inst.op.spec().id,
                    computed: 1,
                    cached: 0,
                    reused: 0,
                    pixels: sz.0 * sz.1,
                });
                wv.insert(i, e);
                continue;
            }
            if mode[i] != Mode::Tiled || (todo[i].is_empty() && have[i].is_empty()) {
                continue;
            }
            let inst = &plan.instances[i];
            let spec = inst.op.spec();
            let (key, sz) = (keys[&i], lsize[i].unwrap_or_default());
            let halo = local_halo(plan, &lp, i).unwrap_or(0);
            // Tiled instances have parameters at the level (see `local_halo`).
            let params = lp[i].as_ref().unwrap_or(&inst.params);
            let computed: Vec<Result<(Tile, Arc<CacheEntry>), GraphError>> = todo[i]
                .par_iter()
                .map(|&t| {
                    if opts.cancelled() {
                        return Err(GraphError::Cancelled);
                    }
                    let tr = tile_rect(t, tile, sz);
                    let node_err = |source| GraphError::Node {
                        op: spec.id.to_string(),
                        source,
                        at: inst.at.clone(),
                    };
                    let values = if regional(plan, i) {
                        // The operator computes the window itself; its inputs come whole.
                        let inputs: Vec<Option<Value>> = inst
                            .inputs
                            .iter()
                            .map(|c| match c {
                                Conn::Slot(j, port) => wv[j].values.get(*port).cloned(),
                                _ => None,
                            })
                            .collect();
                        let win = Window {
                            x: tr.x,
                            y: tr.y,
                            w: tr.w,
                            h: tr.h,
                            scale: s,
                        };
                        inst.op
                            .run_region(params, &inputs, win, &ctx)
                            .map_err(node_err)?
                    } else {
                        // The operator runs on its inputs cropped to the tile and its halo.
                        let crop_rect = tr.grow(halo, sz);
                        let inputs: Vec<Option<Value>> = inst
                            .inputs
                            .iter()
                            .enumerate()
                            .map(|(k, c)| {
                                let Conn::Slot(j, port) = c else { return None };
                                let fp = footprint(plan, &lp, i, k);
                                if fp == Footprint::Pattern {
                                    // At its own resolution: the whole value, never reduced.
                                    if let Some(e) = whole.results.get(j) {
                                        return e.values.get(*port).cloned();
                                    }
                                }
                                let local = matches!(fp, Footprint::Local { .. });
                                match (mode[*j], local) {
                                    (Mode::Tiled, _) => Some(assemble(
                                        &have[*j],
                                        *port,
                                        tile,
                                        lsize[*j].unwrap_or_default(),
                                        crop_rect,
                                    )),
                                    (_, true) => {
                                        wv[j].values.get(*port).map(|v| crop(v, crop_rect))
                                    }
                                    (_, false) => wv[j].values.get(*port).cloned(),
                                }
                            })
                            .collect();
                        let mut values = inst
                            .op
                            .run_at(params, &inputs, &ctx, (crop_rect.x, crop_rect.y))
                            .map_err(node_err)?;
                        if s > 1 {
                            values = inst.op.level_outputs(params, s as f64, values);
                        }
                        let inner = Rect::new(tr.x - crop_rect.x, tr.y - crop_rect.y, tr.w, tr.h);
                        values
                            .iter()
                            .map(|v| match v {
                                Value::Number(_) => Value::Number(f64::NAN),
                                v => crop(v, inner),
                            })
                            .collect()
                    };
                    let e = Arc::new(CacheEntry {
                        values,
                        curl: None,
                        fraction: None,
                    });
                    self.mem_insert(tile_key(key, tile, level, t.0, t.1), e.clone());
                    Ok((t, e))
                })
                .collect();
            let mut st = TileStats {
                at: inst.at.clone(),
                op: spec.id,
                computed: 0,
                cached: have[i].len() - reused[i],
                reused: reused[i],
                pixels: 0,
            };
            for r in computed {
                let (t, e) = r?;
                let tr = tile_rect(t, tile, sz);
                st.computed += 1;
                st.pixels += tr.w * tr.h;
                have[i].insert(t, e);
            }
            tiles.push(st);
        }
        // Cut from the value at the level, patched in place (when the caller no longer holds
        // it), or assembled anew.
        let value = match last {
            _ if mode[root] == Mode::Level => crop(&wv[&root].values[root_port], rect),
            Some((mut value, d)) => {
                let parts: Vec<(Rect, &Value)> = covering(&rect, tile)
                    .filter(|t| touched(t, &d))
                    .filter_map(|t| {
                        let v = have[root].get(&t)?.values.get(root_port)?;
                        Some((tile_rect(t, tile, out_size), v))
                    })
                    .collect();
                patch(&mut value, rect, &parts);
                value
            }
            None => assemble(&have[root], root_port, tile, out_size, rect),
        };
        if mode[root] == Mode::Tiled {
            super::lock(&self.seen).last = Some(LastResult {
                ident,
                port: root_port,
                rect,
                tile,
                level,
                key: keys[&root],
                value: value.clone(),
            });
        }
        Ok(RegionResult {
            value,
            rect,
            size: out_size,
            full_size: size[root].unwrap_or(out_size),
            whole: whole.stats,
            tiles,
            key: super::port_key(keys[&root], root_port),
        })
    }

    /// Instance `i` ([`Mode::Level`]) computed whole at the level (reduction `s`): its
    /// operator's coarse form on its inputs at the level, tiled ones assembled whole, the
    /// outputs mapped back by [`crate::nodes::Operator::level_outputs`].
    #[allow(clippy::too_many_arguments)]
    fn run_at_level(
        &self,
        plan: &Plan,
        lp: &LevelParams,
        i: usize,
        (mode, have, wv): (&[Mode], &[TileMap], &HashMap<usize, Arc<CacheEntry>>),
        lsize: &[Option<(usize, usize)>],
        tile: usize,
        s: usize,
        ctx: &RunContext,
    ) -> Result<Arc<CacheEntry>, GraphError> {
        let inst = &plan.instances[i];
        let params = lp[i].as_ref().unwrap_or(&inst.params);
        let inputs: Vec<Option<Value>> = inst
            .inputs
            .iter()
            .map(|c| {
                let Conn::Slot(j, port) = c else { return None };
                if mode[*j] == Mode::Tiled {
                    let full = lsize[*j]?;
                    return Some(assemble(&have[*j], *port, tile, full, Rect::full(full)));
                }
                wv.get(j)?.values.get(*port).cloned()
            })
            .collect();
        let values = inst
            .op
            .run(params, &inputs, ctx)
            .map(|v| inst.op.level_outputs(params, s as f64, v))
            .map_err(|source| GraphError::Node {
                op: inst.op.spec().id.to_string(),
                source,
                at: inst.at.clone(),
            })?;
        Ok(Arc::new(CacheEntry {
            values,
            curl: None,
            fraction: None,
        }))
    }

    fn mem_get(&self, key: CacheKey) -> Option<Arc<CacheEntry>> {
        super::lock(&self.mem).get(key)
    }

    fn mem_insert(&self, key: CacheKey, e: Arc<CacheEntry>) {
        super::lock(&self.mem).insert(key, e);
    }
}

/// The pixels instance `i` may have changed since `old`, given its inputs' keys now and the
/// changes found for the instances before it (`None`: anywhere).
fn damage_of(
    plan: &Plan,
    lp: &LevelParams,
    i: usize,
    old: &Seen,
    input_keys: &[Option<CacheKey>],
    trails: &[Trail],
    size: &[Option<(usize, usize)>],
) -> Option<Vec<Rect>> {
    let inst = &plan.instances[i];
    let params = lp[i].as_ref()?;
    let sz = size[i]?;
    let mut out = Vec::new();
    for (k, c) in inst.inputs.iter().enumerate() {
        if input_keys[k] == old.inputs[k] {
            continue;
        }
        // A changed input: only a tiled one whose change is known from exactly the key
        // seen last time, through a local footprint.
        let Conn::Slot(j, port) = c else { return None };
        let Footprint::Local { halo } = inst.op.footprint(params, k) else {
            return None;
        };
        let from = old.inputs[k]? ^ (*port as u128);
        let rects = damage_since(&trails[*j], from)?;
        out.extend(rects.iter().map(|r| r.grow(halo, sz)));
    }
    if *params != old.params {
        let sizes: Vec<Option<(usize, usize)>> = inst
            .inputs
            .iter()
            .map(|c| match c {
                Conn::Slot(j, _) => size[*j],
                _ => None,
            })
            .collect();
        let boxes = inst.op.damage(&old.params, params, &sizes)?;
        out.extend(boxes_to_rects(&boxes, sz));
    }
    Some(out)
}

/// Fills `dst`, the rectangle `r` with `c` values per pixel, from `parts` (each covering a
/// rectangle, its values row by row), in parallel over rows. `rows[k]` lists the parts that
/// can cover row `r.y + k` (by index into `parts`).
fn gather<T: Copy + Send + Sync>(
    dst: &mut [T],
    r: Rect,
    c: usize,
    parts: &[(Rect, &[T])],
    rows: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync),
) {
    dst.par_chunks_mut(r.w * c)
        .enumerate()
        .for_each(|(row, out)| {
            let y = r.y + row;
            for (at, src) in &parts[rows(y)] {
                if y < at.y || y >= at.bottom() {
                    continue;
                }
                let (x0, x1) = (r.x.max(at.x), r.right().min(at.right()));
                if x0 >= x1 {
                    continue;
                }
                let s = ((y - at.y) * at.w + (x0 - at.x)) * c;
                let d = (x0 - r.x) * c;
                let n = (x1 - x0) * c;
                out[d..d + n].copy_from_slice(&src[s..s + n]);
            }
        });
}

/// A value's pixel size (`None` for numbers).
fn dims(v: &Value) -> Option<(usize, usize)> {
    super::memory::value_size(v)
}

/// `r` assembled from `parts` (same kind, each covering its rectangle, sorted by rows so
/// that `rows(y)` gives the ones that can cover row `y`). Numbers: the first part's.
fn gather_value(
    parts: &[(Rect, &Value)],
    r: Rect,
    rows: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync),
) -> Value {
    let n = r.w * r.h;
    let Some((_, first)) = parts.first() else {
        return Value::Number(f64::NAN);
    };
    let plane = |get: &dyn Fn(&Value) -> Option<&[f32]>| -> Vec<f32> {
        let ps: Vec<(Rect, &[f32])> = parts
            .iter()
            .map(|(at, v)| (*at, get(v).unwrap_or(&[])))
            .collect();
        let mut out = vec![0.0f32; n];
        gather(&mut out, r, 1, &ps, rows);
        out
    };
    match first {
        Value::Rgbn(img) => {
            let c: [Vec<f32>; 3] = std::array::from_fn(|k| {
                plane(&|v| match v {
                    Value::Rgbn(i) => Some(&i.color()[k]),
                    _ => None,
                })
            });
            let nm: [Vec<f32>; 3] = std::array::from_fn(|k| {
                plane(&|v| match v {
                    Value::Rgbn(i) => Some(&i.normal()[k]),
                    _ => None,
                })
            });
            let mask = img.mask().map(|_| {
                plane(&|v| match v {
                    Value::Rgbn(i) => i.mask(),
                    _ => None,
                })
            });
            Value::Rgbn(RgbnImage::new(r.w, r.h, c, nm, mask).expect("planes of the right size"))
        }
        Value::Mask(_) | Value::Scalar(_) => {
            let data = plane(&|v| match v {
                Value::Mask(p) | Value::Scalar(p) => Some(p.data()),
                _ => None,
            });
            let p = Arc::new(Plane::from_vec(r.w, r.h, data).expect("right size"));
            if matches!(first, Value::Mask(_)) {
                Value::Mask(p)
            } else {
                Value::Scalar(p)
            }
        }
        Value::Picture(_) => {
            let ps: Vec<(Rect, &[u8])> = parts
                .iter()
                .map(|(at, v)| match v {
                    Value::Picture(p) => (*at, p.rgba.as_slice()),
                    _ => (*at, &[][..]),
                })
                .collect();
            let mut rgba = vec![0u8; 4 * n];
            gather(&mut rgba, r, 4, &ps, rows);
            Value::Picture(Arc::new(Picture {
                width: r.w,
                height: r.h,
                rgba,
            }))
        }
        Value::Number(v) => Value::Number(*v),
    }
}

/// Whether [`patch`] updates values like `v` (not images with a mask, nor numbers).
fn patchable(v: &Value) -> bool {
    match v {
        Value::Rgbn(img) => img.mask().is_none(),
        Value::Number(_) => false,
        _ => true,
    }
}

/// Copies `parts` (each covering its rectangle) into `dst`, which covers `r`, in place where
/// `dst` is not shared. `false` for kinds it does not patch (see [`patchable`]).
fn patch(dst: &mut Value, r: Rect, parts: &[(Rect, &Value)]) -> bool {
    fn copy<T: Copy>(dst: &mut [T], r: Rect, c: usize, src: &[T], at: Rect) {
        let o = r.intersect(&at);
        for y in o.y..o.bottom() {
            let s = ((y - at.y) * at.w + (o.x - at.x)) * c;
            let d = ((y - r.y) * r.w + (o.x - r.x)) * c;
            dst[d..d + o.w * c].copy_from_slice(&src[s..s + o.w * c]);
        }
    }
    match dst {
        Value::Picture(p) => {
            let rgba = &mut Arc::make_mut(p).rgba;
            for (at, v) in parts {
                let Value::Picture(s) = v else { return false };
                copy(rgba, r, 4, &s.rgba, *at);
            }
        }
        Value::Mask(p) | Value::Scalar(p) => {
            let data = Arc::make_mut(p).data_mut();
            for (at, v) in parts {
                let (Value::Mask(s) | Value::Scalar(s)) = v else {
                    return false;
                };
                copy(data, r, 1, s.data(), *at);
            }
        }
        Value::Rgbn(img) if img.mask().is_none() => {
            for (at, v) in parts {
                let Value::Rgbn(s) = v else { return false };
                for (d, p) in img.color_mut().iter_mut().zip(s.color()) {
                    copy(d, r, 1, p, *at);
                }
                for (d, p) in img.normal_mut().iter_mut().zip(s.normal()) {
                    copy(d, r, 1, p, *at);
                }
            }
        }
        _ => return false,
    }
    true
}

/// `r` (in `v`'s own pixel coordinates) cut out of `v`; numbers are returned as they are.
#[must_use]
pub fn crop(v: &Value, r: Rect) -> Value {
    let Some(sz) = dims(v) else {
        return v.clone();
    };
    if r == Rect::full(sz) {
        return v.clone();
    }
    // Row by row into fresh vectors (no zero fill first).
    let rows = |src: &[f32]| -> Vec<f32> {
        let mut out = Vec::with_capacity(r.w * r.h);
        for y in r.y..r.bottom() {
            out.extend_from_slice(&src[y * sz.0 + r.x..y * sz.0 + r.right()]);
        }
        out
    };
    match v {
        Value::Rgbn(img) => {
            let c = img.color().each_ref().map(|p| rows(p));
            let n = img.normal().each_ref().map(|p| rows(p));
            let m = img.mask().map(rows);
            Value::Rgbn(RgbnImage::new(r.w, r.h, c, n, m).expect("planes of the right size"))
        }
        Value::Mask(p) => Value::Mask(Arc::new(
            Plane::from_vec(r.w, r.h, rows(p.data())).expect("right size"),
        )),
        Value::Scalar(p) => Value::Scalar(Arc::new(
            Plane::from_vec(r.w, r.h, rows(p.data())).expect("right size"),
        )),
        _ => gather_value(&[(Rect::full(sz), v)], r, &|_| 0..1),
    }
}

/// `v` reduced by `s` ([`crate::raster::pyramid`]); numbers as they are.
#[must_use]
pub fn reduce(v: &Value, s: usize) -> Value {
    use crate::raster::pyramid;
    if s <= 1 {
        return v.clone();
    }
    match v {
        Value::Rgbn(img) => Value::Rgbn(pyramid::reduce_rgbn(img, s)),
        Value::Mask(p) => Value::Mask(Arc::new(pyramid::reduce_plane(p, s))),
        Value::Scalar(p) => Value::Scalar(Arc::new(pyramid::reduce_plane(p, s))),
        Value::Picture(p) => {
            let (width, height) = pyramid::reduced_size((p.width, p.height), s);
            Value::Picture(Arc::new(Picture {
                width,
                height,
                rgba: pyramid::reduce_rgba8(&p.rgba, p.width, p.height, s),
            }))
        }
        Value::Number(_) => v.clone(),
    }
}

/// Window `win` of a full-resolution value: the fine pixels it covers, reduced by its scale.
#[must_use]
pub fn window_of(v: &Value, win: Window) -> Value {
    let s = win.scale.max(1);
    let Some(sz) = dims(v) else {
        return v.clone();
    };
    let fine = Rect::new(win.x * s, win.y * s, win.w * s, win.h * s).intersect(&Rect::full(sz));
    reduce(&crop(v, fine), s)
}

/// Port `port` of the tiles `have` of a `size` image, over `r`.
fn assemble(have: &TileMap, port: usize, tile: usize, size: (usize, usize), r: Rect) -> Value {
    // Parts in tile-row order; the parts of tile row `ty` are `by_row[ty - ty0]..[+1]`.
    let ty0 = r.y / tile;
    let mut parts: Vec<(Rect, &Value)> = Vec::new();
    let mut by_row = vec![0usize];
    let tiles: Vec<Tile> = covering(&r, tile).collect();
    let mut ty = ty0;
    for t in tiles {
        while t.1 > ty {
            by_row.push(parts.len());
            ty += 1;
        }
        if let Some(v) = have.get(&t).and_then(|e| e.values.get(port)) {
            parts.push((tile_rect(t, tile, size), v));
        }
    }
    by_row.push(parts.len());
    if let [(at, v)] = parts.as_slice() {
        if *at == r {
            return (*v).clone();
        }
    }
    gather_value(&parts, r, &|y| {
        let k = (y / tile - ty0).min(by_row.len() - 2);
        by_row[k]..by_row[k + 1]
    })
}
