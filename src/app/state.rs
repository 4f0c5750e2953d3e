//! The editor's document model, free of egui: the graph being edited (the truth), its file,
//! edit commands and the undo history. Everything here is unit-tested without a window.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use crate::graph::file;
use crate::graph::{At, Graph, GraphError, NodeDef, NodeId, NodePorts, Source};
use crate::nodes::PortType;
use crate::params::ParamValue;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The demo graph, built in so the editor opens on something even without `graphs/`.
pub const DEMO_GRAPH: &str = include_str!("../../graphs/demo.ron");

/// How many undo steps are kept.
pub const UNDO_LIMIT: usize = 200;

/// Snapshot undo/redo. Graphs are small (parameters and edges, no pixels), so each step is a
/// whole graph: undo restores the previous graph exactly.
///
/// Continuous edits (dragging a slider or a node, typing in a field) are merged into one step:
/// [`History::record`] holds the graph from before the interaction and pushes it only when the
/// interaction ends.
#[derive(Clone, Debug, Default)]
pub struct History {
    undo: Vec<Graph>,
    redo: Vec<Graph>,
    pending: Option<Graph>,
    version: u64,
}

impl History {
    /// Records one frame's change from `before` to `after`. While `interacting` the change is
    /// held; when the interaction ends it becomes one undo step (if the graph ended up changed).
    pub fn record(&mut self, before: &Graph, after: &Graph, interacting: bool) {
        if before != after && self.pending.is_none() {
            self.pending = Some(before.clone());
        }
        if !interacting {
            if let Some(p) = self.pending.take() {
                if p != *after {
                    self.push(p);
                }
            }
        }
    }

    /// Pushes `before` as one undo step (a discrete command: add, delete, connect, …).
    pub fn commit(&mut self, before: Graph) {
        if let Some(p) = self.pending.take() {
            if p != before {
                self.push(p);
            }
        }
        self.push(before);
    }

    /// Changes whenever a step is pushed, undone or redone.
    #[must_use]
    pub fn version(&self) -> u64 {
        self.version
    }

    fn push(&mut self, g: Graph) {
        self.version += 1;
        if self.undo.last() != Some(&g) {
            self.undo.push(g);
            if self.undo.len() > UNDO_LIMIT {
                self.undo.remove(0);
            }
        }
        self.redo.clear();
    }

    /// Undoes the last step into `current`; false when there is nothing to undo.
    pub fn undo(&mut self, current: &mut Graph) -> bool {
        if let Some(p) = self.pending.take() {
            if p != *current {
                self.push(p);
            }
        }
        match self.undo.pop() {
            Some(g) => {
                self.version += 1;
                self.redo.push(std::mem::replace(current, g));
                true
            }
            None => false,
        }
    }

    /// Re-applies the last undone step; false when there is nothing to redo.
    pub fn redo(&mut self, current: &mut Graph) -> bool {
        match self.redo.pop() {
            Some(g) => {
                self.version += 1;
                self.undo.push(std::mem::replace(current, g));
                true
            }
            None => false,
        }
    }

    /// Steps that can be undone.
    #[must_use]
    pub fn undo_len(&self) -> usize {
        self.undo.len() + usize::from(self.pending.is_some())
    }

    /// Steps that can be redone.
    #[must_use]
    pub fn redo_len(&self) -> usize {
        self.redo.len()
    }

    /// Forgets everything (a new document).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

/// A graph being edited, its file and its history.
#[derive(Clone, Debug)]
pub struct Document {
    /// The graph: the truth the node view mirrors. It may be unfinished (inputs unconnected).
    pub graph: Graph,
    /// The file it was read from or saved to (`None` for a new graph or the built-in demo).
    pub path: Option<PathBuf>,
    /// The graph as last loaded or saved (for the unsaved-changes check).
    saved: Graph,
    /// Undo/redo.
    pub history: History,
    /// The title of a document without a file (e.g. the image `rgbn edit IMAGE` opened on a
    /// new graph); `None`: "untitled".
    pub name: Option<String>,
}

impl Default for Document {
    fn default() -> Self {
        Self::new()
    }
}

impl Document {
    /// An empty, unsaved graph.
    #[must_use]
    pub fn new() -> Self {
        Self::from_graph(Graph::default(), None)
    }

    fn from_graph(graph: Graph, path: Option<PathBuf>) -> Self {
        Self {
            saved: graph.clone(),
            graph,
            path,
            history: History::default(),
            name: None,
        }
    }

    /// The built-in demo graph (not tied to a file).
    #[must_use]
    pub fn demo() -> Self {
        let f = file::parse(DEMO_GRAPH, "demo.ron").expect("the built-in demo graph parses");
        let g = Graph::from_file(f, &At::file("demo.ron")).expect("the built-in demo is valid");
        Self::from_graph(g, None)
    }

    /// Reads (and migrates) a graph file. It is not validated as a whole: an editor opens
    /// unfinished graphs too; problems show on their nodes.
    pub fn open(path: &Path) -> Result<Self, GraphError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| GraphError::Io {
            file: name.clone(),
            source,
        })?;
        let g = Graph::from_file(file::parse(&text, &name)?, &At::file(&name))?;
        Ok(Self::from_graph(g, Some(path.to_path_buf())))
    }

    /// Writes the graph to `path` atomically and makes it the document's file.
    pub fn save_as(&mut self, path: &Path) -> Result<(), GraphError> {
        self.graph.save(path)?;
        self.path = Some(path.to_path_buf());
        self.saved = self.graph.clone();
        Ok(())
    }

    /// True when the graph differs from the file.
    #[must_use]
    pub fn is_dirty(&self) -> bool {
        self.graph != self.saved
    }

    /// Folder that relative paths in the graph are relative to.
    #[must_use]
    pub fn base_dir(&self) -> PathBuf {
        match self.path.as_deref().and_then(Path::parent) {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        }
    }

    /// A short title: file name (or "untitled") and a star when unsaved.
    #[must_use]
    pub fn title(&self) -> String {
        let name = self
            .path
            .as_deref()
            .and_then(Path::file_name)
            .map(|n| n.to_string_lossy().into_owned())
            .or_else(|| self.name.clone())
            .unwrap_or_else(|| "untitled".to_string());
        format!("{name}{}", if self.is_dirty() { " *" } else { "" })
    }

    /// Ports of node `id` (see [`Graph::node_ports`]).
    pub fn ports(&self, id: NodeId) -> Result<NodePorts, GraphError> {
        self.graph.node_ports(id, &self.base_dir())
    }

    /// Applies `f` to the graph as one undo step (none if nothing changed).
    pub(super) fn edit<R>(&mut self, f: impl FnOnce(&mut Graph) -> R) -> R {
        let before = self.graph.clone();
        let r = f(&mut self.graph);
        if self.graph != before {
            self.history.commit(before);
        }
        r
    }

    /// Adds a node of operator `op` at `pos`.
    pub fn add_node(&mut self, op: &str, pos: [f32; 2]) -> NodeId {
        self.edit(|g| g.add_node(op, pos))
    }

    /// Deletes nodes with their edges (and graph outputs or exposed parameters naming them, and
    /// their places in frames).
    pub fn delete(&mut self, ids: &[NodeId]) {
        let ids: BTreeSet<NodeId> = ids.iter().copied().collect();
        self.edit(|g| {
            for id in &ids {
                g.nodes.remove(id);
            }
            for n in g.nodes.values_mut() {
                n.inputs
                    .retain(|_, s| !matches!(s, Source::Node(src, _) if ids.contains(src)));
            }
            g.outputs.retain(|_, r| !ids.contains(&r.node));
            g.exposed.retain(|_, e| !ids.contains(&e.node));
            g.forget_in_frames(&ids);
        });
    }

    /// Duplicates nodes (same operator, parameters and incoming edges; edges among the
    /// duplicated nodes follow the copies), offset by `offset`. Returns the new ids in order.
    pub fn duplicate(&mut self, ids: &[NodeId], offset: [f32; 2]) -> Vec<NodeId> {
        let nodes = self.copy(ids);
        self.paste(&nodes, offset, true)
    }

    /// The nodes `ids` as they are now (for the clipboard).
    #[must_use]
    pub fn copy(&self, ids: &[NodeId]) -> Vec<NodeDef> {
        ids.iter()
            .filter_map(|id| self.graph.nodes.get(id).cloned())
            .collect()
    }

    /// Inserts copies of `nodes` (new ids, offset by `offset`) as one undo step. Edges among
    /// the copied nodes follow the copies; an edge from a node outside the set is kept when
    /// `keep_external` (the nodes came from this same graph) and that node still exists, and
    /// dropped otherwise. Returns the new ids in order.
    pub fn paste(
        &mut self,
        nodes: &[NodeDef],
        offset: [f32; 2],
        keep_external: bool,
    ) -> Vec<NodeId> {
        self.edit(|g| {
            let mut map = BTreeMap::new();
            for n in nodes {
                let new = g.add_node(&n.op, [n.pos[0] + offset[0], n.pos[1] + offset[1]]);
                let d = g.nodes.get_mut(&new).expect("just added");
                d.params.clone_from(&n.params);
                d.inputs.clone_from(&n.inputs);
                map.insert(n.id, new);
            }
            for new in map.values() {
                let existing: BTreeSet<NodeId> = g.nodes.keys().copied().collect();
                if let Some(d) = g.nodes.get_mut(new) {
                    d.inputs.retain(|_, s| match s {
                        Source::Node(src, _) => {
                            if let Some(m) = map.get(src) {
                                *src = *m;
                                true
                            } else {
                                keep_external && existing.contains(src)
                            }
                        }
                        _ => true,
                    });
                }
            }
            map.into_values().collect()
        })
    }

    /// Connects output `from_port` of `from` to input `port` of `to`, if the core accepts the
    /// edge (ports, types, cycles); otherwise the graph is unchanged and the reason returned.
    pub fn connect(
        &mut self,
        from: NodeId,
        from_port: &str,
        to: NodeId,
        port: &str,
    ) -> Result<(), GraphError> {
        let base = self.base_dir();
        self.edit(|g| g.connect(from, from_port, to, port, &base))
    }

    /// Removes the edge into input `port` of `to`.
    pub fn disconnect(&mut self, to: NodeId, port: &str) {
        self.edit(|g| {
            if let Some(n) = g.nodes.get_mut(&to) {
                n.inputs.remove(port);
            }
        });
    }

    /// Sets one parameter as a single undo step.
    pub fn set_param(&mut self, id: NodeId, name: &str, value: ParamValue) {
        self.edit(|g| {
            if let Some(n) = g.nodes.get_mut(&id) {
                n.params.insert(name.to_string(), value);
            }
        });
    }

    /// True when node `id` is an image source: no input ports and an RGBN output (`demo`,
    /// `load`, `surface`, …).
    #[must_use]
    pub fn is_source(&self, id: NodeId) -> bool {
        self.ports(id)
            .is_ok_and(|p| p.inputs.is_empty() && p.outputs.iter().any(|o| o.ty == PortType::Rgbn))
    }

    /// The image source the chain ending at node `id` starts from: followed upstream through
    /// each node's first connected input (in port order) until a node with none; that node if
    /// it [is a source](Self::is_source), else `None` (also on a cycle or a missing node).
    #[must_use]
    pub fn chain_source(&self, id: NodeId) -> Option<NodeId> {
        let mut at = id;
        let mut seen = BTreeSet::new();
        loop {
            if !seen.insert(at) {
                return None;
            }
            let node = self.graph.nodes.get(&at)?;
            let ports = self.ports(at).ok()?;
            let up = ports
                .inputs
                .iter()
                .find_map(|p| match node.inputs.get(&p.name) {
                    Some(Source::Node(src, _)) => Some(*src),
                    _ => None,
                });
            match up {
                Some(src) => at = src,
                None => return self.is_source(at).then_some(at),
            }
        }
    }

    /// Adds a `load` node reading `path` (as written in the graph: relative to
    /// [`base_dir`](Self::base_dir) or absolute) at `pos`, as one undo step. When `replace`
    /// names a [source](Self::is_source), the new node takes over its connections: every
    /// input and graph output fed by one of its RGBN outputs now reads the new node's `image`
    /// instead; the old source stays in the graph. Returns the new node's id.
    pub fn add_load(&mut self, path: &str, pos: [f32; 2], replace: Option<NodeId>) -> NodeId {
        let rgbn_outputs: BTreeSet<String> = replace
            .filter(|r| self.is_source(*r))
            .and_then(|r| self.ports(r).ok())
            .map(|p| {
                p.outputs
                    .into_iter()
                    .filter(|o| o.ty == PortType::Rgbn)
                    .map(|o| o.name)
                    .collect()
            })
            .unwrap_or_default();
        self.edit(|g| {
            let id = g.add_node("load", pos);
            if let Some(n) = g.nodes.get_mut(&id) {
                n.params
                    .insert("path".into(), ParamValue::Path(path.to_string()));
            }
            let Some(old) = replace else { return id };
            let fed = |s: &Source| matches!(s, Source::Node(n, p) if *n == old && rgbn_outputs.contains(p));
            for n in g.nodes.values_mut() {
                for s in n.inputs.values_mut() {
                    if fed(s) {
                        *s = Source::Node(id, "image".into());
                    }
                }
            }
            for r in g.outputs.values_mut() {
                if r.node == old && rgbn_outputs.contains(&r.port) {
                    r.node = id;
                    r.port = "image".into();
                }
            }
            id
        })
    }

    /// Undoes one step.
    pub fn undo(&mut self) -> bool {
        self.history.undo(&mut self.graph)
    }

    /// Redoes one step.
    pub fn redo(&mut self) -> bool {
        self.history.redo(&mut self.graph)
    }
}

/// The node a graph error points at, when it is a node of the top-level graph (`file`).
#[must_use]
pub fn error_node(e: &GraphError, file: &str) -> Option<NodeId> {
    let at = match e {
        GraphError::DuplicateNode { at, .. }
        | GraphError::UnknownOp { at, .. }
        | GraphError::Param { at, .. }
        | GraphError::BadValue { at, .. }
        | GraphError::UnknownPort { at, .. }
        | GraphError::MissingNode { at, .. }
        | GraphError::MissingInput { at, .. }
        | GraphError::TypeMismatch { at, .. }
        | GraphError::Cycle { at, .. }
        | GraphError::Unknown { at, .. }
        | GraphError::InputFile { at, .. }
        | GraphError::UnboundInput { at, .. }
        | GraphError::Node { at, .. }
        | GraphError::Reroute { at, .. } => at,
        _ => return None,
    };
    if at.file == file {
        at.node
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn demo() -> Document {
        Document::demo()
    }

    #[test]
    fn undo_restores_exactly_and_redo_reapplies() {
        let mut d = demo();
        let g0 = d.graph.clone();
        let id = d.add_node("normalize", [10.0, 20.0]);
        let g1 = d.graph.clone();
        d.connect(3, "image", id, "image").unwrap();
        let g2 = d.graph.clone();
        assert!(d.undo());
        assert_eq!(d.graph, g1);
        assert!(d.undo());
        assert_eq!(d.graph, g0);
        assert!(!d.undo());
        assert!(d.redo());
        assert_eq!(d.graph, g1);
        assert!(d.redo());
        assert_eq!(d.graph, g2);
        assert!(!d.redo());
        // A new edit after undo drops the redo branch.
        d.undo();
        d.delete(&[id]);
        assert_eq!(d.history.redo_len(), 0);
        assert!(!d.graph.nodes.contains_key(&id));
    }

    #[test]
    fn a_slider_drag_is_one_step() {
        let mut d = demo();
        let g0 = d.graph.clone();
        // Frames of a drag: the value changes every frame while the pointer is down.
        for (i, v) in [1.1, 1.4, 1.9, 2.5].iter().enumerate() {
            let before = d.graph.clone();
            d.graph
                .nodes
                .get_mut(&2)
                .unwrap()
                .params
                .insert("amount".into(), ParamValue::Float(*v));
            d.history.record(&before, &d.graph, true);
            assert_eq!(d.history.undo_len(), 1, "frame {i}");
        }
        // Release: no change this frame, the interaction ends.
        let before = d.graph.clone();
        d.history.record(&before, &d.graph, false);
        assert_eq!(d.history.undo_len(), 1);
        let dragged = d.graph.clone();
        assert!(d.undo());
        assert_eq!(d.graph, g0);
        assert!(d.redo());
        assert_eq!(d.graph, dragged);
        // A drag that ends where it started leaves no step.
        let mut d = demo();
        let start = d.graph.clone();
        let mut g = start.clone();
        g.nodes.get_mut(&2).unwrap().pos = [5.0, 5.0];
        d.history.record(&start, &g, true);
        d.history.record(&g, &start, false);
        assert_eq!(d.history.undo_len(), 0);
    }

    #[test]
    fn refused_connection_leaves_the_graph_unchanged() {
        let mut d = demo();
        let before = d.graph.clone();
        // The relit picture into an RGBN input: a type mismatch.
        let e = d.connect(4, "picture", 2, "image").unwrap_err();
        assert!(e.to_string().contains("picture"), "{e}");
        // Downstream into upstream: a cycle.
        let e = d.connect(3, "image", 2, "image").unwrap_err();
        assert!(matches!(e, GraphError::Cycle { .. }), "{e}");
        assert_eq!(d.graph, before);
        assert_eq!(d.history.undo_len(), 0);
        assert!(!d.is_dirty());
    }

    #[test]
    fn copy_paste_within_and_across_documents() {
        let mut d = demo();
        let clip = d.copy(&[2, 3]);
        let before = d.graph.clone();
        let new = d.paste(&clip, [10.0, 20.0], true);
        assert_eq!(new.len(), 2);
        let (a, b) = (new[0], new[1]);
        // 2 took its input from 1 (outside the copied set): kept within the same document.
        assert_eq!(
            d.graph.nodes[&a].inputs["image"],
            Source::Node(1, "image".into())
        );
        // 3 took its input from 2: follows the copy.
        assert_eq!(
            d.graph.nodes[&b].inputs["image"],
            Source::Node(a, "image".into())
        );
        assert_eq!(d.graph.nodes[&a].pos[0], before.nodes[&2].pos[0] + 10.0);
        assert_eq!(d.graph.nodes[&b].params, before.nodes[&3].params);
        // One undo step removes the whole paste.
        assert!(d.undo());
        assert_eq!(d.graph, before);
        // Into another document: edges from outside the copied set are dropped.
        let mut other = Document::new();
        let new = other.paste(&clip, [0.0, 0.0], false);
        assert_eq!(other.graph.nodes.len(), 2);
        assert!(!other.graph.nodes[&new[0]].inputs.contains_key("image"));
        assert_eq!(
            other.graph.nodes[&new[1]].inputs["image"],
            Source::Node(new[0], "image".into())
        );
    }

    #[test]
    fn delete_duplicate_and_params() {
        let mut d = demo();
        let copies = d.duplicate(&[2, 3], [30.0, 30.0]);
        assert_eq!(copies.len(), 2);
        let (a, b) = (copies[0], copies[1]);
        assert_eq!(
            d.graph.nodes[&a].inputs["image"],
            Source::Node(1, "image".into())
        );
        assert_eq!(
            d.graph.nodes[&b].inputs["image"],
            Source::Node(a, "image".into())
        );
        assert_eq!(d.graph.nodes[&b].params, d.graph.nodes[&3].params);
        d.set_param(a, "amount", ParamValue::Float(2.0));
        assert_eq!(d.graph.nodes[&a].params["amount"], ParamValue::Float(2.0));
        d.delete(&[3]);
        for n in d.graph.nodes.values() {
            assert!(!n
                .inputs
                .values()
                .any(|s| *s == Source::Node(3, "image".into())));
        }
        assert!(d.graph.outputs.values().all(|r| r.node != 3));
        assert!(d.is_dirty());
    }

    #[test]
    fn save_then_open_gives_the_same_graph() {
        let mut d = demo();
        let id = d.add_node("normalize", [1.5, -2.0]); // unfinished: input unconnected
        d.set_param(2, "amount", ParamValue::Float(0.25));
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("edited.ron");
        d.save_as(&p).unwrap();
        assert!(!d.is_dirty());
        let back = Document::open(&p).unwrap();
        assert_eq!(back.graph, d.graph);
        assert!(back.graph.nodes.contains_key(&id));
        assert_eq!(back.base_dir(), dir.path());
        assert_eq!(back.title(), "edited.ron");
    }

    #[test]
    fn a_load_node_replaces_the_viewed_chains_source_as_one_step() {
        let mut d = demo();
        // The demo's chains all start from node 1 (demo).
        for id in [1, 2, 3, 4, 5, 6] {
            assert_eq!(d.chain_source(id), Some(1), "node {id}");
        }
        assert!(d.is_source(1));
        assert!(!d.is_source(2));
        let g0 = d.graph.clone();
        let id = d.add_load("pic.png", [0.0, 200.0], d.chain_source(3));
        let g = &d.graph;
        assert_eq!(g.nodes[&id].op, "load");
        assert_eq!(g.nodes[&id].pos, [0.0, 200.0]);
        assert_eq!(
            g.nodes[&id].params["path"],
            ParamValue::Path("pic.png".into())
        );
        // The sharpen node reads the new node; the demo stays, fed into nothing.
        assert_eq!(
            g.nodes[&2].inputs["image"],
            Source::Node(id, "image".into())
        );
        assert!(g.nodes.contains_key(&1));
        assert!(!g
            .nodes
            .values()
            .flat_map(|n| n.inputs.values())
            .any(|s| matches!(s, Source::Node(1, _))));
        assert_eq!(d.chain_source(3), Some(id));
        // The rest of the graph is as it was.
        for n in [3, 4, 5, 6] {
            assert_eq!(g.nodes[&n], g0.nodes[&n]);
        }
        assert_eq!(g.outputs, g0.outputs);
        // One undo step.
        assert!(d.undo());
        assert_eq!(d.graph, g0);

        // A graph output naming the source follows it; no source: just added.
        let mut d = Document::new();
        let a = d.add_load("a.exr", [0.0, 0.0], None);
        assert!(d.graph.nodes[&a].inputs.is_empty());
        d.graph.outputs.insert(
            "image".into(),
            crate::graph::PortRef {
                node: a,
                port: "image".into(),
            },
        );
        let b = d.add_load("b.exr", [0.0, 0.0], d.chain_source(a));
        assert_eq!(d.graph.outputs["image"].node, b);
        assert_eq!(d.graph.nodes.len(), 2);
        // A non-source is never rewired.
        let mut d = demo();
        let g0 = d.graph.clone();
        let c = d.add_load("c.png", [0.0, 0.0], Some(2));
        d.graph.nodes.remove(&c);
        d.graph.next_id = g0.next_id;
        assert_eq!(d.graph, g0);
    }

    #[test]
    fn errors_point_at_top_level_nodes_only() {
        let mut g = Document::demo().graph;
        let id = g.add_node("normalize", [0.0, 0.0]);
        let e = crate::graph::LoadedGraph::from_graph(g, None, PathBuf::from(".")).unwrap_err();
        assert_eq!(error_node(&e, "<memory>"), Some(id));
        assert_eq!(error_node(&e, "other.ron"), None);
    }
}
