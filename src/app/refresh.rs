//! The whole-graph refresh with bounded memory (issue 36 item 6).
//!
//! The editor shows a thumbnail and the integrability readouts of every node, but whole values
//! of a few outputs only: the one viewed, the input of its before/after split, a stamp's
//! source, an output being exported ([`EvalRequest::keep`]). [`Memo`] remembers each node's
//! thumbnail and readouts by content key (a few kilobytes each), so a node whose key is known
//! needs neither its value nor a computation; the refresh evaluates the outputs kept and the
//! nodes not seen yet, through [`Evaluator::eval_kept`], which drops each value once nothing
//! still to run reads it. Eighty chained pen nodes on 2048² then hold the cache, the kept values
//! and the node running — not eighty images — and the refresh after the 80th stroke computes
//! one node, instead of recomputing the chain the cache could not hold.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::worker::{thumbnail, EvalOutcome, EvalRequest, PortValue, Readouts};
use crate::eval::{port_key, CacheKey, EvalOptions, Evaluator, Plan, ValueFn};
use crate::graph::{Graph, GraphError, NodeId, Source};
use crate::nodes::Picture;
use parking_lot::Mutex;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::Arc;

/// A node's integrability readouts: relative RMS curl and non-integrable fraction F.
type Readout = (Option<f64>, Option<f64>);

/// What the worker remembers of the nodes between evaluations, by the content key of the
/// node's instance.
#[derive(Debug, Default)]
pub struct Memo {
    /// Thumbnail of the first output (`None`: not a picture, e.g. a number).
    thumbs: HashMap<CacheKey, Option<Arc<Picture>>>,
    /// Integrability readouts.
    readouts: HashMap<CacheKey, Readout>,
}

impl Memo {
    /// Bytes of the thumbnails held.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.thumbs.values().flatten().map(|p| p.rgba.len()).sum()
    }
    /// Forgets every key but `live` (the current graph's).
    fn retain(&mut self, live: &HashSet<CacheKey>) {
        self.thumbs.retain(|k, _| live.contains(k));
        self.readouts.retain(|k, _| live.contains(k));
    }
}

/// The graph outputs of `plan`'s nodes: for each node, its output names ("ID:PORT") with
/// their content keys (instance key, port), first port first.
type NodeOutputs = BTreeMap<NodeId, Vec<(String, (CacheKey, usize))>>;

fn node_outputs(
    ev: &Evaluator,
    plan: &Plan,
    ports: &BTreeMap<NodeId, Vec<String>>,
) -> Result<NodeOutputs, GraphError> {
    let keys = ev.output_keys(plan)?;
    let mut out = NodeOutputs::new();
    for (id, names) in ports {
        let v: Vec<(String, (CacheKey, usize))> = names
            .iter()
            .filter_map(|p| {
                let name = format!("{id}:{p}");
                let k = *keys.get(&name)?;
                Some((name, k))
            })
            .collect();
        if !v.is_empty() {
            out.insert(*id, v);
        }
    }
    Ok(out)
}

/// The outputs whose whole values the editor needs besides the viewed one
/// ([`EvalRequest::keep`]): the viewed node's inputs (the before/after split), the selected
/// stamp's source, and an output being exported.
#[must_use]
pub fn kept_outputs(
    g: &Graph,
    viewed: Option<&(NodeId, String)>,
    selected: Option<NodeId>,
    export: Option<&(NodeId, String)>,
) -> Vec<(NodeId, String)> {
    let inputs = |id: NodeId| {
        g.nodes.get(&id).into_iter().flat_map(|n| {
            n.inputs.values().filter_map(|s| match s {
                Source::Node(src, port) => Some((*src, port.clone())),
                _ => None,
            })
        })
    };
    let mut keep: Vec<(NodeId, String)> = Vec::new();
    if let Some((id, _)) = viewed {
        keep.extend(inputs(*id));
    }
    if let Some(s) = selected.filter(|s| g.nodes.get(s).is_some_and(|n| n.op == "stamp")) {
        keep.extend(inputs(s));
    }
    keep.extend(export.cloned());
    keep.sort();
    keep.dedup();
    keep
}

/// The names of the outputs whose values `req` keeps: the viewed one and [`EvalRequest::keep`]
/// (every output without a list: a caller without a preview reads them all).
fn kept_names(req: &EvalRequest, nodes: &NodeOutputs) -> Vec<String> {
    let all = nodes.values().flatten().map(|(n, _)| n.clone());
    let Some(keep) = &req.keep else {
        return all.collect();
    };
    let wanted: HashSet<String> = req
        .view
        .iter()
        .map(|v| (v.node, v.port.clone()))
        .chain(keep.iter().cloned())
        .map(|(id, p)| format!("{id}:{p}"))
        .collect();
    all.filter(|n| wanted.contains(n)).collect()
}

/// A thumbnail made during a refresh, by the key of the value it shows (`None`: no picture).
type MadeThumb = (CacheKey, Option<Arc<Picture>>);

/// Evaluates `plan` (every node of `req`'s graph that can be): the values kept, the thumbnails
/// of nodes not seen yet, and from `memo` those of the rest. `ports` are each node's output
/// names.
///
/// # Errors
/// The evaluation's (cancellation included).
pub fn whole(
    ev: &Evaluator,
    memo: &mut Memo,
    req: &EvalRequest,
    plan: &Plan,
    ports: &BTreeMap<NodeId, Vec<String>>,
    opts: &EvalOptions,
    out: &mut EvalOutcome,
) -> Result<(), GraphError> {
    let nodes = node_outputs(ev, plan, ports)?;
    let keep = kept_names(req, &nodes);
    // Nodes whose thumbnail is unknown: visited through their first output.
    let unseen: HashSet<CacheKey> = nodes
        .values()
        .map(|v| v[0].1 .0)
        .filter(|k| !memo.thumbs.contains_key(k))
        .collect();
    let visit: Vec<&str> = nodes
        .values()
        .filter(|v| unseen.contains(&v[0].1 .0))
        .map(|v| v[0].0.as_str())
        .collect();
    let made: Arc<Mutex<Vec<MadeThumb>>> = Arc::default();
    let on_value: ValueFn = {
        let (made, unseen) = (made.clone(), unseen.clone());
        Arc::new(
            move |_i: usize, key: CacheKey, e: &Arc<crate::eval::CacheEntry>| {
                if unseen.contains(&key) {
                    let t = e.values.first().and_then(thumbnail).map(Arc::new);
                    made.lock().push((key, t));
                }
            },
        )
    };
    let keep_refs: Vec<&str> = keep.iter().map(String::as_str).collect();
    let r = ev.eval_kept(plan, &keep_refs, &visit, opts, Some(&on_value))?;
    out.computed += r.misses();
    for (k, t) in made.lock().drain(..) {
        memo.thumbs.insert(k, t);
    }
    let live: HashSet<CacheKey> = nodes.values().map(|v| v[0].1 .0).collect();
    memo.retain(&live);
    for (id, names) in &nodes {
        let inst = names[0].1 .0;
        if let Some(Some(t)) = memo.thumbs.get(&inst) {
            out.thumbs.insert(*id, t.clone());
        }
        if let Some((c, f)) = memo.readouts.get(&inst) {
            if let Some(c) = c {
                out.curl.insert(*id, *c);
            }
            if let Some(f) = f {
                out.fraction.insert(*id, *f);
            }
        }
        for (name, (k, p)) in names {
            let port = name.split_once(':').map_or("", |x| x.1).to_string();
            out.keys.insert((*id, port.clone()), port_key(*k, *p));
            if let Some(v) = r.outputs.get(name) {
                out.values.insert(
                    (*id, port),
                    PortValue {
                        value: v.clone(),
                        key: port_key(*k, *p),
                    },
                );
            }
        }
    }
    Ok(())
}

/// The integrability readouts of every node of `plan`: those `memo` knows, and the rest
/// measured a few nodes at a time (each value kept only while measured). `None` when
/// cancelled (an edit came) or failed.
pub fn readouts(
    ev: &Evaluator,
    memo: &mut Memo,
    req: &EvalRequest,
    plan: &Plan,
) -> Option<Readouts> {
    let opts = EvalOptions {
        cancel: crate::cancel::Cancel::from_flag(req.cancel.clone()),
        progress: None,
        curl_stats: true,
    };
    let ports: BTreeMap<NodeId, Vec<String>> = plan
        .outputs
        .keys()
        .filter_map(|n| {
            let (id, p) = n.split_once(':')?;
            Some((id.parse().ok()?, p.to_string()))
        })
        .fold(BTreeMap::new(), |mut m, (id, p)| {
            m.entry(id).or_insert_with(Vec::new).push(p);
            m
        });
    let nodes = node_outputs(ev, plan, &ports).ok()?;
    let todo: Vec<(&str, CacheKey)> = nodes
        .values()
        .map(|v| (v[0].0.as_str(), v[0].1 .0))
        .filter(|(_, k)| !memo.readouts.contains_key(k))
        .collect();
    for chunk in todo.chunks(rayon::current_num_threads().max(1)) {
        let names: Vec<&str> = chunk.iter().map(|c| c.0).collect();
        let r = ev.eval_kept(plan, &names, &[], &opts, None).ok()?;
        for (_, k) in chunk {
            let st = r.stats.iter().find(|s| s.key == *k);
            memo.readouts
                .insert(*k, st.map_or((None, None), |s| (s.curl, s.fraction)));
        }
    }
    let mut out = Readouts {
        generation: req.generation,
        ..Readouts::default()
    };
    for (id, v) in &nodes {
        if let Some((c, f)) = memo.readouts.get(&v[0].1 .0) {
            if let Some(c) = c {
                out.curl.insert(*id, *c);
            }
            if let Some(f) = f {
                out.fraction.insert(*id, *f);
            }
        }
    }
    Some(out)
}
