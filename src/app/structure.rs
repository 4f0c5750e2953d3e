//! Frames, reroutes and groups as edit commands of the [`Document`], each one undo step, and
//! groups entered in place ([`Entered`], [`context_graph`]) — no egui. The graph transforms
//! are the core's ([`crate::graph::group`], [`crate::graph::frame`]); the widgets are in
//! [`super::structure_ui`].

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::state::Document;
use crate::graph::group::{self, Exposure};
use crate::graph::reroute::{IN, OUT};
use crate::graph::{At, FrameDef, Graph, GraphError, NodeId, Source};
use crate::nodes::REROUTE_OP;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The folder, beside the graph, where "Group into subgraph" writes its subgraphs.
pub const LIB_DIR: &str = "lib";

impl Document {
    /// Puts a new frame titled `title` around the nodes `ids` (taken out of other frames), as
    /// one undo step. Returns its index.
    pub fn add_frame(&mut self, ids: &[NodeId], title: &str) -> Option<usize> {
        self.edit(|g| g.add_frame(ids, title, FrameDef::DEFAULT_COLOR))
    }

    /// Retitles and recolours frame `index`, as one undo step.
    pub fn edit_frame(&mut self, index: usize, title: &str, color: [u8; 3]) {
        self.edit(|g| {
            if let Some(f) = g.frames.get_mut(index) {
                f.title = title.to_string();
                f.color = color;
            }
        });
    }

    /// Removes frame `index` (its nodes stay), as one undo step.
    pub fn delete_frame(&mut self, index: usize) {
        self.edit(|g| {
            if index < g.frames.len() {
                g.frames.remove(index);
            }
        });
    }

    /// Puts a reroute at `pos` on the wire from output `from_port` of `from` into input `port`
    /// of `to`, as one undo step: the reroute reads the output and the input reads the
    /// reroute. Refused (the graph unchanged) when there is no such wire.
    pub fn insert_reroute(
        &mut self,
        from: NodeId,
        from_port: &str,
        to: NodeId,
        port: &str,
        pos: [f32; 2],
    ) -> Result<NodeId, GraphError> {
        let src = Source::Node(from, from_port.to_string());
        if self.graph.nodes.get(&to).and_then(|n| n.inputs.get(port)) != Some(&src) {
            return Err(GraphError::MissingNode {
                what: format!("a wire from output {from_port:?} of node {from} into {port:?}"),
                missing: from,
                at: At::file("<editor>").node(to, None),
            });
        }
        Ok(self.edit(|g| {
            let r = g.add_node(REROUTE_OP, pos);
            if let Some(n) = g.nodes.get_mut(&r) {
                n.inputs.insert(IN.into(), src);
            }
            if let Some(n) = g.nodes.get_mut(&to) {
                n.inputs
                    .insert(port.to_string(), Source::Node(r, OUT.into()));
            }
            r
        }))
    }

    /// The file a new group named `name` would be written to, relative to the graph's folder:
    /// `lib/NAME.ron` (the name reduced to letters, digits and `_`), numbered so that no
    /// existing file is overwritten.
    #[must_use]
    pub fn lib_path_for(&self, name: &str) -> String {
        let stem: String = name
            .trim()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                    c.to_ascii_lowercase()
                } else {
                    '_'
                }
            })
            .collect();
        let stem = if stem.trim_matches('_').is_empty() {
            "group".to_string()
        } else {
            stem
        };
        let base = self.base_dir();
        (1..)
            .map(|k| {
                if k == 1 {
                    format!("{LIB_DIR}/{stem}.ron")
                } else {
                    format!("{LIB_DIR}/{stem}_{k}.ron")
                }
            })
            .find(|p| !base.join(p).exists())
            .unwrap_or_else(|| format!("{LIB_DIR}/{stem}.ron"))
    }

    /// Groups `ids` into a subgraph named `name` exposing `expose`: writes the subgraph to
    /// [`lib_path_for`](Self::lib_path_for) (atomically, never over a file) and puts a `graph`
    /// node in their place, as one undo step (undo leaves the file). The graph must have a file
    /// (the subgraph goes beside it). Returns the group node and the file written.
    pub fn group(
        &mut self,
        ids: &[NodeId],
        name: &str,
        expose: &[Exposure],
    ) -> Result<(NodeId, PathBuf), GraphError> {
        if self.path.is_none() {
            return Err(GraphError::Param {
                param: "path".into(),
                detail: format!(
                    "save the graph first: a group's subgraph is written beside it, in {LIB_DIR}/"
                ),
                at: At::file("<editor>"),
            });
        }
        let base = self.base_dir();
        let rel = self.lib_path_for(name);
        let r = group::group(&self.graph, ids, &rel, Some(name), expose, &base)?;
        let file = base.join(&rel);
        if let Some(dir) = file.parent() {
            std::fs::create_dir_all(dir).map_err(|source| GraphError::Io {
                file: dir.display().to_string(),
                source,
            })?;
        }
        r.sub.save(&file)?;
        self.edit(|g| *g = r.graph);
        Ok((r.node, file))
    }

    /// Inlines graph node `id` (its subgraph's nodes with fresh ids), as one undo step.
    /// Returns the new nodes.
    pub fn ungroup(&mut self, id: NodeId) -> Result<Vec<NodeId>, GraphError> {
        let u = group::ungroup(&self.graph, id, &self.base_dir())?;
        self.edit(|g| *g = u.graph);
        Ok(u.nodes)
    }
}

/// A group entered in place: the document around it, the graph node entered, and what was
/// selected and viewed there (restored on leaving).
#[derive(Clone, Debug)]
pub struct Entered {
    /// The document holding the group node.
    pub doc: Document,
    /// The group node.
    pub node: NodeId,
    /// Its selection.
    pub selected: Option<NodeId>,
    /// Its viewed output.
    pub viewed: Option<(NodeId, String)>,
}

/// The graph the editor evaluates while inside the groups `stack` (outermost first), editing
/// `inner` (whose relative paths are relative to `inner_base`): `inner` with its graph inputs
/// fed by what feeds the group node outside, the group node's parameter overrides applied, and
/// the outside nodes that feed it, under ids above `inner`'s (so the editor's results for
/// `inner`'s nodes keep their ids). With no group entered, `inner` itself.
#[must_use]
pub fn context_graph(stack: &[Entered], inner: &Graph, inner_base: &Path) -> Graph {
    let Some((last, rest)) = stack.split_last() else {
        return inner.clone();
    };
    let outer_base = last.doc.base_dir();
    let outer = context_graph(rest, &last.doc.graph, &outer_base);
    embed(&outer, &outer_base, last.node, inner, inner_base)
}

fn sources(g: &Graph, id: NodeId) -> impl Iterator<Item = NodeId> + '_ {
    g.nodes
        .get(&id)
        .into_iter()
        .flat_map(|n| n.inputs.values())
        .filter_map(|s| match s {
            Source::Node(n, _) => Some(*n),
            Source::Input(_) => None,
        })
}

fn embed(
    outer: &Graph,
    outer_base: &Path,
    node: NodeId,
    inner: &Graph,
    inner_base: &Path,
) -> Graph {
    let mut g = inner.clone();
    let Some(gn) = outer.nodes.get(&node) else {
        return g;
    };
    for (name, v) in gn.params.iter().filter(|(k, _)| *k != "path") {
        if let Some(ex) = inner.exposed.get(name) {
            if let Some(n) = g.nodes.get_mut(&ex.node) {
                n.params.insert(ex.param.clone(), v.clone());
            }
        }
    }
    let mut ancestors = BTreeSet::new();
    let mut todo: Vec<NodeId> = sources(outer, node).collect();
    while let Some(a) = todo.pop() {
        if ancestors.insert(a) {
            todo.extend(sources(outer, a));
        }
    }
    let offset = g
        .nodes
        .keys()
        .next_back()
        .map_or(1, |m| m + 1)
        .max(g.next_id);
    let mut outer_inputs = BTreeSet::new();
    // The inner graph's inputs read what feeds the group node.
    for n in g.nodes.values_mut() {
        for s in n.inputs.values_mut() {
            let Source::Input(name) = s else { continue };
            match gn.inputs.get(name.as_str()) {
                Some(Source::Node(src, p)) => *s = Source::Node(src + offset, p.clone()),
                Some(Source::Input(outer_name)) => {
                    outer_inputs.insert(outer_name.clone());
                    *s = Source::Input(outer_name.clone());
                }
                None => {}
            }
        }
    }
    for a in &ancestors {
        let Some(n) = outer.nodes.get(a) else {
            continue;
        };
        let mut n = n.clone();
        n.id = a + offset;
        group::rebase_node_paths(&mut n, outer_base, inner_base);
        for s in n.inputs.values_mut() {
            match s {
                Source::Node(src, _) => *src += offset,
                Source::Input(name) => {
                    outer_inputs.insert(name.clone());
                }
            }
        }
        g.nodes.insert(n.id, n);
    }
    for name in outer_inputs {
        if let Some(d) = outer.inputs.get(&name) {
            g.inputs.entry(name).or_insert_with(|| d.clone());
        }
    }
    g.next_id = g.nodes.keys().next_back().map_or(1, |m| m + 1);
    g
}

#[cfg(test)]
#[path = "structure_tests.rs"]
mod tests;
