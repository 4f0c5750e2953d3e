//! Damage: what an edit can have changed. Each tiled instance's last evaluation is remembered
//! ([`History`]); comparing it with the next one (the operator's `damage` for its parameters,
//! its inputs' damage grown by its halo) gives the pixels that may differ, and every tile
//! outside them is reused.

use super::super::{CacheKey, Conn, Plan};
use super::grid::LevelParams;
use crate::nodes::{Footprint, Parsed, Value};
use crate::raster::window::Rect;
use std::collections::HashMap;

/// A tiled instance as last evaluated: what a later evaluation compares with to find what an
/// edit changed (damage).
#[derive(Clone, Debug)]
pub(super) struct Seen {
    pub(super) key: CacheKey,
    pub(super) params: Parsed,
    /// Content keys of the inputs in port order.
    pub(super) inputs: Vec<Option<CacheKey>>,
    /// The edits that led to `key`, oldest first: each an earlier key and what changed from
    /// it to the next one.
    pub(super) trail: Trail,
}

/// Earlier keys of an instance, oldest first, each with the pixels that may differ from it to
/// the next key (`None`: anywhere).
pub(super) type Trail = Vec<(CacheKey, Option<Vec<Rect>>)>;

/// Edits remembered per instance.
pub(super) const TRAIL: usize = 16;

/// The pixels that may differ between key `from` of an instance and its current key, from its
/// trail (`None`: anywhere, or `from` not in the trail).
pub(super) fn damage_since(trail: &Trail, from: CacheKey) -> Option<Vec<Rect>> {
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
pub(super) type Ident = (usize, &'static str, String, Option<u64>);

/// The evaluator's memory of tiled instances, by [`Ident`] and level of detail (each level's
/// damage is in its own pixels, from the instance's parameters at that level).
#[derive(Default, Debug)]
pub(crate) struct History {
    pub(super) seen: HashMap<(Ident, u32), Seen>,
    /// The last result, to patch where an edit changed it rather than assemble it again.
    pub(super) last: Option<LastResult>,
}

impl History {
    /// The last region result kept (to patch), if any.
    pub(crate) fn last_value(&self) -> Option<&Value> {
        self.last.as_ref().map(|l| &l.value)
    }
}

/// A region result as returned, with what it was made from.
#[derive(Debug)]
pub(super) struct LastResult {
    pub(super) ident: Ident,
    pub(super) port: usize,
    pub(super) rect: Rect,
    pub(super) tile: usize,
    pub(super) level: u32,
    pub(super) key: CacheKey,
    pub(super) value: Value,
}

/// The damage boxes of an operator as pixel rectangles of a `size` image.
pub(super) fn boxes_to_rects(boxes: &[[f64; 4]], size: (usize, usize)) -> Vec<Rect> {
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

/// The pixels instance `i` may have changed since `old`, given its inputs' keys now and the
/// changes found for the instances before it (`None`: anywhere).
pub(super) fn damage_of(
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
