//! The region engine's plan: how each instance is evaluated for a request ([`Mode`]), its
//! parameters and footprints at a level of detail, the tile grid and its cache keys, and the
//! assembly of tiles into a value.

use super::super::{CacheEntry, CacheKey, Conn, Plan};
use crate::nodes::value::gather_value;
use crate::nodes::{Footprint, Parsed, Value};
use crate::raster::window::Rect;
use std::collections::HashMap;
use std::sync::Arc;

/// How an instance is evaluated for a region, in increasing order of what it needs: a value
/// wanted in two modes takes the later one.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
pub(super) enum Mode {
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
pub(super) type LevelParams = [Option<Parsed>];

/// The parameters of every instance at level `level` (reduction `s`): their own at level 0 and
/// for regional sources (which sample the level themselves), [`crate::nodes::Operator::scaled`]
/// otherwise (`None`: no coarse form).
pub(super) fn level_params(plan: &Plan, level: u32, s: usize) -> Vec<Option<Parsed>> {
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
pub(super) fn footprint(plan: &Plan, lp: &LevelParams, i: usize, k: usize) -> Footprint {
    let inst = &plan.instances[i];
    match &lp[i] {
        Some(p) => inst.op.footprint(p, k),
        None => Footprint::Global,
    }
}

/// The largest halo of an instance's local inputs, `None` when it has no connected local
/// input and is not regional (`Entry::regional` in `crate::nodes`), or has no form at the level
/// (then it is evaluated whole).
pub(super) fn local_halo(plan: &Plan, lp: &LevelParams, i: usize) -> Option<usize> {
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
pub(super) fn at_level(
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
    let known = super::super::memory::sizes(plan, &HashMap::new());
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
pub(super) fn level_key(key: CacheKey, level: u32) -> CacheKey {
    tile_key(key, 1, level, 0, 0)
}

/// Whether instance `i` computes any window on its own (its inputs, if any, passed whole).
pub(super) fn regional(plan: &Plan, i: usize) -> bool {
    let inst = &plan.instances[i];
    inst.op.regional(&inst.params)
}

pub(super) fn tile_key(key: CacheKey, tile: usize, level: u32, tx: usize, ty: usize) -> CacheKey {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(b"rgbn-tile-1\0");
    h.update(&key.to_le_bytes());
    for v in [tile as u64, u64::from(level), tx as u64, ty as u64] {
        h.update(&v.to_le_bytes());
    }
    h.digest128()
}

/// The tiles (column, row of the grid) covering `r`.
pub(super) fn covering(r: &Rect, tile: usize) -> impl Iterator<Item = (usize, usize)> {
    let (x0, x1) = (r.x / tile, r.right().div_ceil(tile));
    let (y0, y1) = (r.y / tile, r.bottom().div_ceil(tile));
    let empty = r.is_empty();
    (y0..y1)
        .flat_map(move |ty| (x0..x1).map(move |tx| (tx, ty)))
        .filter(move |_| !empty)
}

pub(super) fn tile_rect((tx, ty): (usize, usize), tile: usize, size: (usize, usize)) -> Rect {
    Rect::new(tx * tile, ty * tile, tile, tile).intersect(&Rect::full(size))
}

/// A tile's column and row in the grid.
pub(super) type Tile = (usize, usize);

pub(super) type TileMap = HashMap<Tile, Arc<CacheEntry>>;

/// Port `port` of the tiles `have` of a `size` image, over `r`.
pub(super) fn assemble(
    have: &TileMap,
    port: usize,
    tile: usize,
    size: (usize, usize),
    r: Rect,
) -> Value {
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
