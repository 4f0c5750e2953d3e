//! What a tool edits: the target node, inserting a node after the viewed output, and reading
//! and writing tool parameters.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::DEFAULT_STAMP_SIDE;
use crate::graph::{Graph, GraphError, NodeId, Source};
use crate::nodes::PortType;
use crate::params::{ParamValue, PathValue};
use std::path::Path;

/// The parameter holding a node's point list, by operator (a pen's: its list of paths).
#[must_use]
pub fn points_param(op: &str) -> Option<&'static str> {
    match op {
        "pen" => Some("paths"),
        "brush" => Some("points"),
        "stamp" => Some("positions"),
        _ => None,
    }
}

/// Fewest points a node's list must keep (a pen path needs two; a closed one three: see
/// `min_path_points`).
#[must_use]
pub fn min_points(op: &str) -> usize {
    if op == "pen" {
        2
    } else {
        1
    }
}

/// Fewest points a pen path keeps: two open, three closed.
#[must_use]
pub fn min_path_points(path: &PathValue) -> usize {
    if path.closed {
        3
    } else {
        2
    }
}

/// A node's parameter: its value in the graph, else the operator's default.
#[must_use]
pub fn param(g: &Graph, id: NodeId, name: &str) -> Option<ParamValue> {
    let n = g.nodes.get(&id)?;
    if let Some(v) = n.params.get(name) {
        return Some(v.clone());
    }
    let op = crate::nodes::find(&n.op)?;
    op.params()
        .iter()
        .find(|p| p.name == name)
        .map(|p| p.default.clone())
}

/// A float parameter (see [`param`]).
#[must_use]
pub fn param_f64(g: &Graph, id: NodeId, name: &str) -> Option<f64> {
    match param(g, id, name)? {
        ParamValue::Float(v) => Some(v),
        ParamValue::Int(v) => Some(v as f64),
        _ => None,
    }
}

/// The point list of a pen, brush or stamp node (see [`points_param`]); a pen's is every
/// vertex of its paths, path after path (a vertex's index in it: [`locate_vertex`]).
#[must_use]
pub fn node_points(g: &Graph, id: NodeId) -> Option<Vec<[f64; 2]>> {
    let name = points_param(&g.nodes.get(&id)?.op)?;
    match param(g, id, name)? {
        ParamValue::Points(p) => Some(p),
        ParamValue::Paths(p) => Some(p.into_iter().flat_map(|p| p.points).collect()),
        _ => None,
    }
}

/// A pen node's paths (its own list, else the operator's default).
#[must_use]
pub fn pen_paths(g: &Graph, id: NodeId) -> Option<Vec<PathValue>> {
    match param(g, id, "paths")? {
        ParamValue::Paths(p) => Some(p),
        _ => None,
    }
}

/// Path and index within it of vertex `index` of the paths' points taken path after path
/// (as [`node_points`] lists a pen's).
#[must_use]
pub fn locate_vertex(paths: &[PathValue], mut index: usize) -> Option<(usize, usize)> {
    for (k, p) in paths.iter().enumerate() {
        if index < p.points.len() {
            return Some((k, index));
        }
        index -= p.points.len();
    }
    None
}

/// True when the node's point list was set (not the operator's placeholder default).
#[must_use]
pub fn has_own_points(g: &Graph, id: NodeId) -> bool {
    g.nodes
        .get(&id)
        .and_then(|n| Some(n.params.contains_key(points_param(&n.op)?)))
        .unwrap_or(false)
}

pub(super) fn set(g: &mut Graph, id: NodeId, name: &str, v: ParamValue) {
    if let Some(n) = g.nodes.get_mut(&id) {
        n.params.insert(name.to_string(), v);
    }
}

/// Where a tool's gesture goes.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// Edit this node (the selected node is of the tool's operator).
    Edit(NodeId),
    /// Insert a new node after this RGBN output.
    After(NodeId, String),
}

/// The target of tool `op`: the selected node if it runs `op`, else a new node after the viewed
/// output (or, if that is not an RGBN image, after the RGBN image the viewed node reads).
pub fn target(
    g: &Graph,
    op: &str,
    selected: Option<NodeId>,
    viewed: Option<&(NodeId, String)>,
    base_dir: &Path,
) -> Option<Target> {
    if let Some(s) = selected {
        if g.nodes.get(&s).is_some_and(|n| n.op == op) {
            return Some(Target::Edit(s));
        }
    }
    let (id, port) = viewed?;
    let rgbn_out = |id: NodeId, port: &str| {
        g.node_ports(id, base_dir)
            .ok()
            .and_then(|p| p.outputs.into_iter().find(|o| o.name == port))
            .is_some_and(|o| o.ty == PortType::Rgbn)
    };
    if rgbn_out(*id, port) {
        return Some(Target::After(*id, port.clone()));
    }
    // A picture, mask or number: draw on the image it was made from.
    let n = g.nodes.get(id)?;
    n.inputs.values().find_map(|s| match s {
        Source::Node(src, p) if rgbn_out(*src, p) => Some(Target::After(*src, p.clone())),
        _ => None,
    })
}

/// Inserts a node of `op` after output `port` of `after`: its `image` input reads that output,
/// and every node input and graph output that read it reads the new node's `image` instead.
/// A new stamp node also gets a small analytic `surface` node as its stamp.
pub fn insert_after(
    g: &mut Graph,
    op: &str,
    after: NodeId,
    port: &str,
    base_dir: &Path,
) -> Result<NodeId, GraphError> {
    let pos = g.nodes.get(&after).map_or([0.0, 0.0], |n| n.pos);
    let old = Source::Node(after, port.to_string());
    let readers: Vec<(NodeId, String)> = g
        .nodes
        .iter()
        .flat_map(|(id, n)| {
            n.inputs
                .iter()
                .filter(|(_, s)| **s == old)
                .map(move |(p, _)| (*id, p.clone()))
        })
        .collect();
    // Below everything, so it does not cover other nodes.
    let below = g.nodes.values().map(|n| n.pos[1]).fold(pos[1], f32::max) + 130.0;
    let id = g.add_node(op, [pos[0] + 120.0, below]);
    if let Err(e) = g.connect(after, port, id, "image", base_dir) {
        g.nodes.remove(&id);
        return Err(e);
    }
    let new = Source::Node(id, "image".into());
    for (n, p) in readers {
        if let Some(node) = g.nodes.get_mut(&n) {
            node.inputs.insert(p, new.clone());
        }
    }
    for r in g.outputs.values_mut() {
        if r.node == after && r.port == port {
            r.node = id;
            r.port = "image".into();
        }
    }
    if op == "stamp" {
        let s = g.add_node("surface", [pos[0] - 40.0, below + 130.0]);
        set(g, s, "shape", ParamValue::Choice("gaussians".into()));
        set(g, s, "width", ParamValue::Int(DEFAULT_STAMP_SIDE as i64));
        set(g, s, "height", ParamValue::Int(DEFAULT_STAMP_SIDE as i64));
        g.connect(s, "image", id, "stamp", base_dir)?;
    }
    Ok(id)
}
#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::*;

    #[test]
    fn viewing_a_picture_draws_on_the_image_it_was_made_from() {
        let d = demo();
        // Node 4 (relight) outputs a picture made from node 3's image.
        let t = target(&d.graph, "pen", None, Some(&(4, "picture".into())), &base());
        assert_eq!(t, Some(Target::After(3, "image".into())));
        // The selected node wins when it runs the tool's operator.
        let mut g = d.graph.clone();
        let pen = g.add_node("pen", [0.0, 0.0]);
        let t = target(&g, "pen", Some(pen), Some(&(4, "picture".into())), &base());
        assert_eq!(t, Some(Target::Edit(pen)));
        // Nothing viewed, nothing selected: no target.
        assert_eq!(target(&g, "pen", Some(2), None, &base()), None);
    }
}
