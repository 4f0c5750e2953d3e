//! Group into a subgraph, and ungroup: the graph transforms behind the editor's commands.
//!
//! [`group`] moves a set of nodes into a graph of their own (written by the caller as a library
//! file, e.g. `lib/group.ron` beside the graph) and puts a `graph` node using that file in their
//! place. Every wire entering the set becomes an input of the subgraph, every wire leaving it
//! (and every graph output or exposed parameter naming a node in it) an output, and the chosen
//! inner parameters are exposed. The inner nodes keep their ids, names, parameters and
//! positions; relative input paths are rewritten for the library's folder. The group node sits
//! at the mean of the nodes' positions.
//!
//! [`ungroup`] inlines a `graph` node back: its file's nodes come in with fresh ids (ids are
//! never reused), the node's parameter overrides applied to the exposed parameters, wires
//! reconnected through its inputs and outputs, positions shifted by how far the node moved
//! from their mean. Grouping then ungrouping gives the same graph up to node ids (and
//! `next_id`), and evaluates the same outputs bit for bit: the plan inlines a graph node, so
//! the flattened instances are the same.

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{
    At, ExposedDef, FrameDef, Graph, GraphError, InputDef, NodeDef, NodeId, PortRef, Source,
};
use crate::nodes::{self, GRAPH_NODE_OP};
use crate::params::{ParamKind, ParamValue};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

/// An inner parameter to expose on the group node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Exposure {
    /// The inner node.
    pub node: NodeId,
    /// Its parameter.
    pub param: String,
    /// The name on the group node (unique).
    pub name: String,
}

/// The result of [`group`].
#[derive(Clone, Debug, PartialEq)]
pub struct Grouped {
    /// The graph with the group node in place of the nodes.
    pub graph: Graph,
    /// The subgraph, to be written at the group node's `path`.
    pub sub: Graph,
    /// The group node's id.
    pub node: NodeId,
}

/// The result of [`ungroup`].
#[derive(Clone, Debug, PartialEq)]
pub struct Ungrouped {
    /// The graph with the subgraph's nodes in place of the group node.
    pub graph: Graph,
    /// The new ids of the inlined nodes, in the order of their ids in the subgraph.
    pub nodes: Vec<NodeId>,
}

fn editor_at(id: Option<NodeId>, g: &Graph) -> At {
    let at = At::file("<editor>");
    match id {
        Some(id) => at.node(id, g.nodes.get(&id).and_then(|n| n.name.as_deref())),
        None => at,
    }
}

/// A name from `base` not in `taken`: `base`, `base_2`, `base_3`, …
fn unique(base: &str, taken: &BTreeSet<String>) -> String {
    if !taken.contains(base) {
        return base.to_string();
    }
    (2..)
        .map(|k| format!("{base}_{k}"))
        .find(|n| !taken.contains(n))
        .unwrap_or_else(|| base.to_string())
}

/// The mean of the positions of `nodes` (in id order).
fn centroid<'a>(nodes: impl Iterator<Item = &'a NodeDef>) -> [f32; 2] {
    let (mut x, mut y, mut n) = (0.0f32, 0.0f32, 0.0f32);
    for d in nodes {
        x += d.pos[0];
        y += d.pos[1];
        n += 1.0;
    }
    if n == 0.0 {
        [0.0, 0.0]
    } else {
        [x / n, y / n]
    }
}

/// Moves `ids` (nodes of `g`) into a subgraph whose file will be at `lib_path` (relative to
/// `base_dir`, the folder of `g`'s file, or absolute) and puts a `graph` node named `name`
/// in their place, exposing `expose`. See the module documentation.
pub fn group(
    g: &Graph,
    ids: &[NodeId],
    lib_path: &str,
    name: Option<&str>,
    expose: &[Exposure],
    base_dir: &Path,
) -> Result<Grouped, GraphError> {
    let set: BTreeSet<NodeId> = ids.iter().copied().collect();
    if set.is_empty() {
        return Err(GraphError::Param {
            param: "nodes".into(),
            detail: "nothing to group: select one or more nodes".into(),
            at: editor_at(None, g),
        });
    }
    if let Some(&missing) = set.iter().find(|id| !g.nodes.contains_key(id)) {
        return Err(GraphError::MissingNode {
            what: "group".into(),
            missing,
            at: editor_at(None, g),
        });
    }
    let lib_dir = base_dir.join(Path::new(lib_path).parent().unwrap_or(Path::new("")));
    let mut parent = g.clone();
    let gid = parent.next_id;
    parent.next_id += 1;
    let mut sub = Graph {
        next_id: set.iter().next_back().map_or(1, |m| m + 1),
        ..Graph::default()
    };

    // The inner nodes: paths rebased for the library's folder.
    for id in &set {
        let mut n = g.nodes[id].clone();
        rebase_node_paths(&mut n, base_dir, &lib_dir);
        sub.nodes.insert(*id, n);
    }

    // Wires entering the set: one subgraph input per distinct source.
    let mut in_names: BTreeMap<Source, String> = BTreeMap::new();
    let mut group_inputs: BTreeMap<String, Source> = BTreeMap::new();
    for id in &set {
        let ports = g.node_ports(*id, base_dir).ok();
        let inputs = g.nodes[id].inputs.clone();
        for (port, src) in inputs {
            if matches!(&src, Source::Node(s, _) if set.contains(s)) {
                continue;
            }
            let name = match in_names.get(&src) {
                Some(n) => n.clone(),
                None => {
                    let ty = match &src {
                        Source::Node(s, p) => g
                            .node_ports(*s, base_dir)?
                            .outputs
                            .into_iter()
                            .find(|o| &o.name == p)
                            .map(|o| o.ty),
                        Source::Input(n) => g.inputs.get(n).map(|d| d.ty),
                    };
                    let Some(ty) = ty else {
                        return Err(GraphError::UnknownPort {
                            dir: "output",
                            port: match &src {
                                Source::Node(_, p) | Source::Input(p) => p.clone(),
                            },
                            op: format!("the source of node {id} input {port:?}"),
                            suggestion: None,
                            at: editor_at(Some(*id), g),
                        });
                    };
                    let doc = ports
                        .as_ref()
                        .and_then(|p| p.inputs.iter().find(|i| i.name == port))
                        .map(|i| i.doc.clone())
                        .unwrap_or_default();
                    let taken = sub.inputs.keys().cloned().collect();
                    let name = unique(&port, &taken);
                    sub.inputs.insert(name.clone(), InputDef { ty, doc });
                    group_inputs.insert(name.clone(), src.clone());
                    in_names.insert(src.clone(), name.clone());
                    name
                }
            };
            if let Some(n) = sub.nodes.get_mut(id) {
                n.inputs.insert(port, Source::Input(name));
            }
        }
    }

    // Wires leaving the set, graph outputs and exposed parameters naming nodes in it.
    let mut out_names: BTreeMap<(NodeId, String), String> = BTreeMap::new();
    let mut out_name = |sub: &mut Graph, node: NodeId, port: &str| -> String {
        if let Some(n) = out_names.get(&(node, port.to_string())) {
            return n.clone();
        }
        let taken = sub.outputs.keys().cloned().collect();
        let name = unique(port, &taken);
        sub.outputs.insert(
            name.clone(),
            PortRef {
                node,
                port: port.to_string(),
            },
        );
        out_names.insert((node, port.to_string()), name.clone());
        name
    };
    for id in &set {
        parent.nodes.remove(id);
    }
    for n in parent.nodes.values_mut() {
        for s in n.inputs.values_mut() {
            if let Source::Node(src, port) = s {
                if set.contains(src) {
                    let name = out_name(&mut sub, *src, port);
                    *s = Source::Node(gid, name);
                }
            }
        }
    }
    for r in parent.outputs.values_mut() {
        if set.contains(&r.node) {
            let name = out_name(&mut sub, r.node, &r.port);
            *r = PortRef {
                node: gid,
                port: name,
            };
        }
    }
    let mut taken: BTreeSet<String> = BTreeSet::new();
    for e in expose {
        if !set.contains(&e.node) || !taken.insert(e.name.clone()) || e.name == "path" {
            return Err(GraphError::Param {
                param: e.name.clone(),
                detail: format!(
                    "cannot expose {:?} of node {} as {:?}: the node must be in the group and the name unique (and not \"path\")",
                    e.param, e.node, e.name
                ),
                at: editor_at(Some(e.node), g),
            });
        }
        sub.exposed.insert(
            e.name.clone(),
            ExposedDef {
                node: e.node,
                param: e.param.clone(),
                doc: String::new(),
            },
        );
    }
    for (name, ex) in parent.exposed.iter_mut() {
        if set.contains(&ex.node) {
            let inner = unique(name, &taken);
            taken.insert(inner.clone());
            sub.exposed.insert(inner.clone(), ex.clone());
            *ex = ExposedDef {
                node: gid,
                param: inner,
                doc: ex.doc.clone(),
            };
        }
    }

    // Frames: one wholly inside moves into the subgraph; the others lose the grouped nodes,
    // and the group node joins the frame that held every one of them.
    let mut frames = Vec::new();
    for f in &parent.frames {
        let (inside, outside): (Vec<NodeId>, Vec<NodeId>) =
            f.nodes.iter().partition(|n| set.contains(n));
        if outside.is_empty() {
            sub.frames.push(f.clone());
            continue;
        }
        let mut nodes = outside;
        if inside.len() == set.len() {
            nodes.push(gid);
        }
        frames.push(FrameDef { nodes, ..f.clone() });
    }
    parent.frames = frames;

    parent.nodes.insert(
        gid,
        NodeDef {
            id: gid,
            op: GRAPH_NODE_OP.to_string(),
            name: name.filter(|n| !n.trim().is_empty()).map(str::to_string),
            pos: centroid(set.iter().map(|id| &g.nodes[id])),
            params: BTreeMap::from([("path".to_string(), ParamValue::Path(lib_path.to_string()))]),
            inputs: group_inputs,
        },
    );
    Ok(Grouped {
        graph: parent,
        sub,
        node: gid,
    })
}

/// The subgraph file of `graph` node `id` and its folder.
fn sub_file(g: &Graph, id: NodeId, base_dir: &Path) -> Result<PathBuf, GraphError> {
    let at = editor_at(Some(id), g);
    let Some(n) = g.nodes.get(&id).filter(|n| n.op == GRAPH_NODE_OP) else {
        return Err(GraphError::Param {
            param: "path".into(),
            detail: format!("node {id} is not a graph node: only a graph node can be ungrouped"),
            at,
        });
    };
    match n.params.get("path") {
        Some(ParamValue::Path(p) | ParamValue::Text(p)) if !p.is_empty() => Ok(base_dir.join(p)),
        _ => Err(GraphError::Param {
            param: "path".into(),
            detail: "a graph node needs parameter \"path\" (the graph file it uses)".into(),
            at,
        }),
    }
}

/// Reads the subgraph that `graph` node `id` uses (unvalidated: unfinished subgraphs can be
/// opened and ungrouped too). Returns it with its file.
pub fn read_sub(g: &Graph, id: NodeId, base_dir: &Path) -> Result<(Graph, PathBuf), GraphError> {
    let file = sub_file(g, id, base_dir)?;
    let name = file.display().to_string();
    let text = std::fs::read_to_string(&file).map_err(|source| GraphError::Io {
        file: name.clone(),
        source,
    })?;
    let sub = Graph::from_file(super::file::parse(&text, &name)?, &At::file(&name))?;
    Ok((sub, file))
}

/// Inlines `graph` node `id` of `g` (its file read relative to `base_dir`). See the module
/// documentation.
pub fn ungroup(g: &Graph, id: NodeId, base_dir: &Path) -> Result<Ungrouped, GraphError> {
    let (mut sub, file) = read_sub(g, id, base_dir)?;
    let lib_dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
    let gnode = g.nodes[&id].clone();
    // The node's overrides of exposed parameters.
    for (name, v) in gnode.params.iter().filter(|(k, _)| *k != "path") {
        if let Some(ex) = sub.exposed.get(name) {
            if let Some(n) = sub.nodes.get_mut(&ex.node) {
                n.params.insert(ex.param.clone(), v.clone());
            }
        }
    }
    let c = centroid(sub.nodes.values());
    let offset = [gnode.pos[0] - c[0], gnode.pos[1] - c[1]];
    let mut out = g.clone();
    out.nodes.remove(&id);
    let mut map: BTreeMap<NodeId, NodeId> = BTreeMap::new();
    for k in sub.nodes.keys() {
        map.insert(*k, out.next_id);
        out.next_id += 1;
    }
    for (k, n) in &sub.nodes {
        let mut n = n.clone();
        n.id = map[k];
        n.pos = [n.pos[0] + offset[0], n.pos[1] + offset[1]];
        rebase_node_paths(&mut n, &lib_dir, base_dir);
        n.inputs = n
            .inputs
            .into_iter()
            .filter_map(|(port, s)| {
                let s = match s {
                    Source::Node(src, p) => Source::Node(*map.get(&src)?, p),
                    Source::Input(name) => gnode.inputs.get(&name)?.clone(),
                };
                Some((port, s))
            })
            .collect();
        out.nodes.insert(n.id, n);
    }
    let through = |port: &str| -> Option<(NodeId, String)> {
        let r = sub.outputs.get(port)?;
        Some((*map.get(&r.node)?, r.port.clone()))
    };
    for n in out.nodes.values_mut() {
        n.inputs.retain(|_, s| match s {
            Source::Node(src, port) if *src == id => match through(port) {
                Some((nn, p)) => {
                    *s = Source::Node(nn, p);
                    true
                }
                None => false,
            },
            _ => true,
        });
    }
    out.outputs.retain(|_, r| {
        if r.node != id {
            return true;
        }
        match through(&r.port) {
            Some((nn, p)) => {
                *r = PortRef { node: nn, port: p };
                true
            }
            None => false,
        }
    });
    out.exposed.retain(|_, e| {
        if e.node != id {
            return true;
        }
        match sub
            .exposed
            .get(&e.param)
            .and_then(|x| Some((map.get(&x.node)?, x)))
        {
            Some((nn, x)) => {
                e.node = *nn;
                e.param.clone_from(&x.param);
                true
            }
            None => false,
        }
    });
    // Frames: the subgraph's come out; the inlined nodes take the group node's place in its
    // frame.
    let new: Vec<NodeId> = map.values().copied().collect();
    for f in &mut out.frames {
        if let Some(i) = f.nodes.iter().position(|n| *n == id) {
            f.nodes.remove(i);
            f.nodes.extend(&new);
        }
    }
    out.frames.retain(|f| !f.nodes.is_empty());
    for f in std::mem::take(&mut sub.frames) {
        let nodes: Vec<NodeId> = f.nodes.iter().filter_map(|n| map.get(n).copied()).collect();
        out.forget_in_frames(&nodes.iter().copied().collect());
        if !nodes.is_empty() {
            out.frames.push(FrameDef { nodes, ..f });
        }
    }
    Ok(Ungrouped {
        graph: out,
        nodes: new,
    })
}

/// Rewrites the relative input paths of `n` (files it reads; for a graph node, its `path`)
/// from relative to `from_dir` to relative to `to_dir`. Output paths are relative to the
/// output folder, not the graph, and stay.
pub fn rebase_node_paths(n: &mut NodeDef, from_dir: &Path, to_dir: &Path) {
    let names: Vec<String> = if n.op == GRAPH_NODE_OP {
        vec!["path".into()]
    } else {
        nodes::find(&n.op)
            .map(|op| {
                op.params()
                    .iter()
                    .filter(|i| i.kind == ParamKind::Path && !i.meta.output)
                    .map(|i| i.name.to_string())
                    .collect()
            })
            .unwrap_or_default()
    };
    for name in names {
        if let Some(ParamValue::Path(p) | ParamValue::Text(p)) = n.params.get_mut(&name) {
            *p = rebase(p, from_dir, to_dir);
        }
    }
}

/// `p` lexically normalised: `.` dropped, `a/..` folded (leading `..` kept).
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if matches!(out.components().next_back(), Some(Component::Normal(_))) {
                    out.pop();
                } else {
                    out.push("..");
                }
            }
            other => out.push(other),
        }
    }
    out
}

/// Path `p`, relative to folder `from_dir`, made relative to folder `to_dir` (both relative to
/// the same working folder, or absolute). Empty and absolute paths are kept; where no relative
/// path exists (`to_dir` climbs out of a folder whose name is unknown) the absolute path.
#[must_use]
pub fn rebase(p: &str, from_dir: &Path, to_dir: &Path) -> String {
    let path = Path::new(p);
    if p.is_empty() || path.is_absolute() {
        return p.to_string();
    }
    let (mut from, mut to) = (from_dir.to_path_buf(), to_dir.to_path_buf());
    if from.is_absolute() != to.is_absolute() {
        from = std::path::absolute(&from).unwrap_or(from);
        to = std::path::absolute(&to).unwrap_or(to);
    }
    let target = normalize(&from.join(path));
    let to = normalize(&to);
    let (t, d): (Vec<Component>, Vec<Component>) =
        (target.components().collect(), to.components().collect());
    let common = t.iter().zip(&d).take_while(|(a, b)| a == b).count();
    if d[common..]
        .iter()
        .any(|c| !matches!(c, Component::Normal(_)))
    {
        return std::path::absolute(&target)
            .unwrap_or(target)
            .display()
            .to_string();
    }
    let mut out = PathBuf::new();
    for _ in common..d.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c);
    }
    out.display().to_string()
}

#[cfg(test)]
#[path = "group_tests.rs"]
mod tests;
