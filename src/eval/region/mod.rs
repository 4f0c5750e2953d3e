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
//!    ([`crate::params::shifted`]); the tile is cut out of the result. Tiles of one
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

mod damage;
mod grid;
#[cfg(test)]
mod tests;

use super::{CacheEntry, CacheKey, Conn, EvalOptions, Evaluator, NodeStats, Plan};
use crate::graph::GraphError;
use crate::nodes::value::{crop, patch, patchable, reduce};
use crate::nodes::{Footprint, PortType, RunContext, Value};
use crate::params::nearest;
use crate::raster::window::{Rect, Window};
pub(crate) use damage::History;
use damage::{damage_of, damage_since, LastResult, Seen, Trail, TRAIL};
use grid::{
    assemble, at_level, covering, footprint, level_key, level_params, local_halo, regional,
    tile_key, tile_rect, LevelParams, Mode, Tile, TileMap,
};
pub use grid::{depends_on_coarse_global, LEVEL_MIN_SIDE};
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

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
        let whole = self.eval_instances(plan, &whole_roots, opts, None, None)?;
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
                        skipped: 0,
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
            size[*j] = e.values.iter().find_map(Value::size);
        }
        for i in 0..=root {
            let inst = &plan.instances[i];
            if mode[i] == Mode::Level {
                let sizes: Vec<Option<(usize, usize)>> = inst
                    .inputs
                    .iter()
                    .map(|c| match c {
                        Conn::Slot(j, port) => match whole.results.get(j) {
                            Some(e) => e.values.get(*port).and_then(Value::size),
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
                    Some(e) => e.values.get(*port).and_then(Value::size),
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
                            .and_then(Value::size),
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
                // Complete entries only (a lazy operator's may lack ports).
                if let Some(e) = self.mem_get(keys[&i]).filter(|e| e.skipped == 0) {
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
            let mut hist = self.seen.lock();
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
        let last = self.seen.lock().last.take().and_then(|l| {
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
        let ctx = RunContext::new(plan.protected.clone()).with_cancel(opts.token());
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
                            .run_region(params, inputs, win, &ctx)
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
                        let values = inst
                            .op
                            .run_at(params, inputs, &ctx, (crop_rect.x, crop_rect.y), s)
                            .map_err(node_err)?;
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
                        skipped: 0,
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
            self.seen.lock().last = Some(LastResult {
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
            .run_at(params, inputs, ctx, (0, 0), s)
            .map_err(|source| GraphError::Node {
                op: inst.op.spec().id.to_string(),
                source,
                at: inst.at.clone(),
            })?;
        Ok(Arc::new(CacheEntry {
            values,
            curl: None,
            fraction: None,
            skipped: 0,
        }))
    }

    fn mem_get(&self, key: CacheKey) -> Option<Arc<CacheEntry>> {
        self.mem.lock().get(key)
    }

    fn mem_insert(&self, key: CacheKey, e: Arc<CacheEntry>) {
        self.mem.lock().insert(key, e);
    }
}
