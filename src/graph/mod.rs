//! Graphs of operator nodes: the data model ([`Graph`]), its file format ([`file`](mod@file)), and
//! validation ([`LoadedGraph`]): operators and parameters resolved, edges type-checked, cycles
//! refused, graph files used as nodes loaded (their inputs, outputs and exposed parameters
//! become the node's ports and parameters).
//!
//! The graph is the truth: an editor mirrors it and asks it before changing anything. Node ids
//! are stable `u64`s handed out from `next_id` and never reused.

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

pub mod error;
pub mod file;
pub mod frame;
pub mod group;
pub mod reroute;

pub use error::{At, GraphError};
pub use file::{ExposedDef, FrameDef, InputDef, NodeDef, PortRef, Source};

use crate::nodes::{self, DynOp, Parsed, PortSpec, PortType, GRAPH_NODE_OP, REROUTE_OP};
use crate::params::{nearest, ParamInfo, ParamKind, ParamValue};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A stable node id.
pub type NodeId = u64;

/// A graph: nodes by id, named inputs and outputs, exposed parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Graph {
    /// The next id to hand out.
    pub next_id: NodeId,
    /// Named graph inputs.
    pub inputs: BTreeMap<String, InputDef>,
    /// Named graph outputs.
    pub outputs: BTreeMap<String, PortRef>,
    /// Exposed parameters.
    pub exposed: BTreeMap<String, ExposedDef>,
    /// Nodes by id.
    pub nodes: BTreeMap<NodeId, NodeDef>,
    /// Frames around nodes (editor only; see [`frame`]).
    pub frames: Vec<FrameDef>,
}

impl Default for Graph {
    fn default() -> Self {
        Self {
            next_id: 1,
            inputs: BTreeMap::new(),
            outputs: BTreeMap::new(),
            exposed: BTreeMap::new(),
            nodes: BTreeMap::new(),
            frames: Vec::new(),
        }
    }
}

impl Graph {
    /// Builds the graph from the file schema, refusing duplicate ids and a `next_id` that would
    /// reuse one.
    pub fn from_file(f: file::GraphFile, at: &At) -> Result<Self, GraphError> {
        let mut nodes = BTreeMap::new();
        for n in f.nodes {
            let id = n.id;
            if nodes.insert(id, n).is_some() {
                return Err(GraphError::DuplicateNode {
                    id,
                    at: at.node(id, None),
                });
            }
        }
        if let Some(&max) = nodes.keys().next_back() {
            if f.next_id <= max {
                return Err(GraphError::NextId {
                    next_id: f.next_id,
                    max,
                    at: at.clone(),
                });
            }
        }
        Ok(Self {
            next_id: f.next_id.max(1),
            inputs: f.inputs,
            outputs: f.outputs,
            exposed: f.exposed,
            nodes,
            frames: f.frames,
        })
    }

    /// The file schema of this graph (current version).
    #[must_use]
    pub fn to_file(&self) -> file::GraphFile {
        file::GraphFile {
            version: file::CURRENT_VERSION,
            next_id: self.next_id,
            inputs: self.inputs.clone(),
            outputs: self.outputs.clone(),
            exposed: self.exposed.clone(),
            nodes: self.nodes.values().cloned().collect(),
            frames: self.frames.clone(),
        }
    }

    /// Pretty RON text of the graph.
    #[must_use]
    pub fn to_text(&self) -> String {
        file::to_text(&self.to_file())
    }

    /// Adds a node of operator `op` at `pos` with default parameters; returns its new id.
    pub fn add_node(&mut self, op: &str, pos: [f32; 2]) -> NodeId {
        let id = self.next_id;
        self.next_id += 1;
        self.nodes.insert(
            id,
            NodeDef {
                id,
                op: op.to_string(),
                name: None,
                pos,
                params: BTreeMap::new(),
                inputs: BTreeMap::new(),
            },
        );
        id
    }

    /// The ports of node `id`, resolved without validating the rest of the graph (an editor's
    /// graph is often unfinished: inputs not yet connected, paths not yet chosen). A graph node's
    /// ports come from its file, relative to `base_dir`.
    pub fn node_ports(&self, id: NodeId, base_dir: &Path) -> Result<NodePorts, GraphError> {
        let at = At::file("<editor>");
        let Some(node) = self.nodes.get(&id) else {
            return Err(GraphError::MissingNode {
                what: "port lookup".into(),
                missing: id,
                at,
            });
        };
        let at = at.node(id, node.name.as_deref());
        if node.op == GRAPH_NODE_OP {
            let rel = match node.params.get("path") {
                Some(ParamValue::Path(p) | ParamValue::Text(p)) if !p.is_empty() => p.clone(),
                _ => {
                    return Err(GraphError::Param {
                        param: "path".into(),
                        detail: "a graph node needs parameter \"path\" (the graph file it uses)"
                            .into(),
                        at,
                    })
                }
            };
            let sub = LoadedGraph::load(&base_dir.join(rel))?;
            return Ok(sub.ports_as_node());
        }
        if node.op == REROUTE_OP {
            let ty = self
                .reroute_source_type(id, base_dir)
                .or_else(|| self.reroute_sink_type(id, base_dir))
                .unwrap_or(PortType::Rgbn);
            return Ok(reroute::ports(ty));
        }
        let op = find_op(&node.op, at)?;
        Ok(NodePorts {
            inputs: op.spec().inputs.clone(),
            outputs: op.spec().outputs.clone(),
        })
    }

    /// Connects output `from_port` of node `from` to input `port` of node `to` (replacing any
    /// edge into that port) if the edge is valid on its own: both ports exist, the types match,
    /// and no cycle results. Unlike [`LoadedGraph::connect`], the rest of the graph may be
    /// unfinished. On error the graph is unchanged.
    pub fn connect(
        &mut self,
        from: NodeId,
        from_port: &str,
        to: NodeId,
        port: &str,
        base_dir: &Path,
    ) -> Result<(), GraphError> {
        let src = self.node_ports(from, base_dir)?;
        let dst = self.node_ports(to, base_dir)?;
        let at = At::file("<editor>").node(to, self.nodes[&to].name.as_deref());
        let Some(out) = src.outputs.iter().find(|p| p.name == from_port) else {
            return Err(GraphError::UnknownPort {
                dir: "output",
                port: from_port.into(),
                op: format!("node {from} ({})", self.nodes[&from].op),
                suggestion: nearest(from_port, src.outputs.iter().map(|p| p.name.as_str())),
                at,
            });
        };
        let Some(inp) = dst.inputs.iter().find(|p| p.name == port) else {
            return Err(GraphError::UnknownPort {
                dir: "input",
                port: port.into(),
                op: self.nodes[&to].op.clone(),
                suggestion: nearest(port, dst.inputs.iter().map(|p| p.name.as_str())),
                at,
            });
        };
        // A reroute takes the type of what feeds it; one fed by nothing yet takes any type its
        // users accept.
        let is_reroute = |id: NodeId| self.nodes[&id].op == REROUTE_OP;
        let found = if is_reroute(from) {
            self.reroute_source_type(from, base_dir)
        } else {
            Some(out.ty)
        };
        let expected = if is_reroute(to) {
            self.reroute_sink_type(to, base_dir)
        } else {
            Some(inp.ty)
        };
        if let (Some(found), Some(expected)) = (found, expected) {
            if found != expected {
                return Err(GraphError::TypeMismatch {
                    port: port.into(),
                    expected: expected.name(),
                    from: format!("node {from} output {from_port:?}"),
                    found: found.name(),
                    at,
                });
            }
        }
        // A cycle appears if `to` is `from` or one of its ancestors.
        let mut stack = vec![from];
        let mut seen = BTreeSet::new();
        while let Some(n) = stack.pop() {
            if n == to {
                let mut nodes: Vec<NodeId> = seen.into_iter().collect();
                nodes.push(to);
                nodes.sort_unstable();
                nodes.dedup();
                return Err(GraphError::Cycle { nodes, at });
            }
            if !seen.insert(n) {
                continue;
            }
            for s in self
                .nodes
                .get(&n)
                .into_iter()
                .flat_map(|d| d.inputs.values())
            {
                if let Source::Node(sid, _) = s {
                    stack.push(*sid);
                }
            }
        }
        if let Some(n) = self.nodes.get_mut(&to) {
            n.inputs
                .insert(port.to_string(), Source::Node(from, from_port.to_string()));
        }
        Ok(())
    }

    /// Writes the graph as pretty RON, atomically (a temporary file renamed into place).
    pub fn save(&self, path: &Path) -> Result<(), GraphError> {
        let text = self.to_text();
        crate::raster::io::write_atomic(path, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })
        .map_err(|e| GraphError::Io {
            file: display(path),
            source: std::io::Error::other(e.to_string()),
        })
    }

    /// The node named by `r`: a node id, or a node name.
    #[must_use]
    pub fn find_node(&self, r: &str) -> Option<NodeId> {
        if let Ok(id) = r.parse::<NodeId>() {
            if self.nodes.contains_key(&id) {
                return Some(id);
            }
        }
        self.nodes
            .values()
            .find(|n| n.name.as_deref() == Some(r))
            .map(|n| n.id)
    }
}

/// The resolved ports of a node.
#[derive(Clone, Debug, PartialEq)]
pub struct NodePorts {
    /// Input ports.
    pub inputs: Vec<PortSpec>,
    /// Output ports.
    pub outputs: Vec<PortSpec>,
}

/// The registered operator `id`, or an error naming the nearest id.
fn find_op(id: &str, at: At) -> Result<&'static dyn DynOp, GraphError> {
    nodes::find(id).ok_or_else(|| {
        let ids = nodes::registry()
            .iter()
            .map(|o| o.spec().id)
            .chain([GRAPH_NODE_OP, REROUTE_OP]);
        GraphError::UnknownOp {
            op: id.to_string(),
            suggestion: nearest(id, ids),
            at,
        }
    })
}

/// What a node runs.
#[derive(Clone)]
pub enum NodeKind {
    /// A registered operator with its parameters, parsed and checked once.
    Op {
        /// The operator.
        op: &'static dyn DynOp,
        /// The parameters.
        params: Parsed,
    },
    /// A graph file used as a node, loaded with this node's parameter overrides applied.
    Graph(Arc<LoadedGraph>),
    /// A reroute: its output is its input (resolved to a direct connection by the plan).
    Reroute,
}

/// A validated graph: every node resolved, every edge type-checked, no cycles.
#[derive(Clone)]
pub struct LoadedGraph {
    /// The graph.
    pub graph: Graph,
    /// The file it came from (`None` when built in memory).
    pub path: Option<PathBuf>,
    /// Folder that relative paths in the graph are relative to.
    pub base_dir: PathBuf,
    /// Resolved nodes.
    pub kinds: BTreeMap<NodeId, NodeKind>,
    /// Resolved ports.
    pub ports: BTreeMap<NodeId, NodePorts>,
    /// Node ids in a topological order (sources first).
    pub order: Vec<NodeId>,
}

impl std::fmt::Debug for LoadedGraph {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadedGraph")
            .field("path", &self.path)
            .field("nodes", &self.graph.nodes.len())
            .finish()
    }
}

fn display(p: &Path) -> String {
    p.display().to_string()
}

fn canonical_path(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

impl LoadedGraph {
    /// Reads, migrates and validates a graph file.
    pub fn load(path: &Path) -> Result<Self, GraphError> {
        Self::load_nested(path, &mut Vec::new())
    }

    fn load_nested(path: &Path, stack: &mut Vec<PathBuf>) -> Result<Self, GraphError> {
        let name = display(path);
        let text = std::fs::read_to_string(path).map_err(|source| GraphError::Io {
            file: name.clone(),
            source,
        })?;
        let graph = Graph::from_file(file::parse(&text, &name)?, &At::file(&name))?;
        let base = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        stack.push(canonical_path(path));
        let r = Self::build(graph, Some(path.to_path_buf()), base, stack);
        stack.pop();
        r
    }

    /// Validates an in-memory graph whose relative paths are relative to `base_dir`.
    pub fn from_graph(
        graph: Graph,
        path: Option<PathBuf>,
        base_dir: PathBuf,
    ) -> Result<Self, GraphError> {
        let mut stack: Vec<PathBuf> = path.iter().map(|p| canonical_path(p)).collect();
        Self::build(graph, path, base_dir, &mut stack)
    }

    /// Parses and validates graph text (`label` names it in messages).
    pub fn from_text(text: &str, label: &str, base_dir: PathBuf) -> Result<Self, GraphError> {
        let graph = Graph::from_file(file::parse(text, label)?, &At::file(label))?;
        Self::from_graph(graph, Some(PathBuf::from(label)), base_dir)
    }

    /// Where this graph is, for messages.
    #[must_use]
    pub fn at(&self) -> At {
        At::file(
            self.path
                .as_deref()
                .map_or_else(|| "<memory>".to_string(), display),
        )
    }

    /// The location of node `id`.
    #[must_use]
    pub fn at_node(&self, id: NodeId) -> At {
        let name = self.graph.nodes.get(&id).and_then(|n| n.name.as_deref());
        self.at().node(id, name)
    }

    /// Pretty RON text of the graph.
    #[must_use]
    pub fn to_text(&self) -> String {
        self.graph.to_text()
    }

    fn build(
        graph: Graph,
        path: Option<PathBuf>,
        base_dir: PathBuf,
        stack: &mut Vec<PathBuf>,
    ) -> Result<Self, GraphError> {
        let mut lg = LoadedGraph {
            graph,
            path,
            base_dir,
            kinds: BTreeMap::new(),
            ports: BTreeMap::new(),
            order: Vec::new(),
        };
        let ids: Vec<NodeId> = lg.graph.nodes.keys().copied().collect();
        for id in &ids {
            let (kind, ports) = lg.resolve_node(*id, stack)?;
            lg.kinds.insert(*id, kind);
            lg.ports.insert(*id, ports);
        }
        reroute::type_reroutes(&mut lg)?;
        lg.check_edges()?;
        lg.check_refs()?;
        frame::check_frames(&lg.graph, &lg.at())?;
        lg.order = lg.topo_order()?;
        Ok(lg)
    }

    fn resolve_node(
        &self,
        id: NodeId,
        stack: &mut Vec<PathBuf>,
    ) -> Result<(NodeKind, NodePorts), GraphError> {
        let node = &self.graph.nodes[&id];
        let at = self.at_node(id);
        if node.op == GRAPH_NODE_OP {
            return self.resolve_graph_node(node, at, stack);
        }
        if node.op == REROUTE_OP {
            if let Some(p) = node.params.keys().next() {
                return Err(GraphError::Param {
                    param: p.clone(),
                    detail: format!("a reroute has no parameters (found {p:?})"),
                    at,
                });
            }
            // Typed once every other node is resolved (`reroute::type_reroutes`).
            return Ok((NodeKind::Reroute, reroute::ports(PortType::Rgbn)));
        }
        let op = find_op(&node.op, at.clone())?;
        let params = op
            .parse(&node.params)
            .map_err(|e| param_error(&e, at.clone()))?;
        let spec = op.spec();
        Ok((
            NodeKind::Op { op, params },
            NodePorts {
                inputs: spec.inputs.clone(),
                outputs: spec.outputs.clone(),
            },
        ))
    }

    fn resolve_graph_node(
        &self,
        node: &NodeDef,
        at: At,
        stack: &mut Vec<PathBuf>,
    ) -> Result<(NodeKind, NodePorts), GraphError> {
        let rel = match node.params.get("path") {
            Some(ParamValue::Path(p) | ParamValue::Text(p)) if !p.is_empty() => p.clone(),
            Some(v) => {
                return Err(GraphError::Param {
                    param: "path".into(),
                    detail: format!(
                        "parameter \"path\" needs a path value, got a {}",
                        v.kind_name()
                    ),
                    at,
                })
            }
            None => {
                return Err(GraphError::Param {
                    param: "path".into(),
                    detail: "a graph node needs parameter \"path\" (the graph file it uses)".into(),
                    at,
                })
            }
        };
        let file = self.base_dir.join(&rel);
        let canon = canonical_path(&file);
        if stack.contains(&canon) {
            let mut chain: Vec<String> = stack.iter().map(|p| display(p)).collect();
            chain.push(display(&canon));
            return Err(GraphError::FileCycle {
                chain: chain.join(" → "),
            });
        }
        if !file.is_file() {
            return Err(GraphError::InputFile {
                path: display(&file),
                detail: "graph file not found".into(),
                at,
            });
        }
        let mut sub = Self::load_nested(&file, stack)?;
        // Apply this node's overrides of exposed parameters.
        let overrides: Vec<(&String, &ParamValue)> =
            node.params.iter().filter(|(k, _)| *k != "path").collect();
        if !overrides.is_empty() {
            for (name, value) in overrides {
                let Some(ex) = sub.graph.exposed.get(name).cloned() else {
                    let names = sub.graph.exposed.keys().map(String::as_str).chain(["path"]);
                    return Err(GraphError::Param {
                        param: name.clone(),
                        detail: format!(
                            "unknown parameter {name:?}{}",
                            nearest(name, names)
                                .map(|s| format!(" (did you mean {s:?}?)"))
                                .unwrap_or_default()
                        ),
                        at,
                    });
                };
                if let Some(n) = sub.graph.nodes.get_mut(&ex.node) {
                    n.params.insert(ex.param.clone(), value.clone());
                }
            }
            let (g, p, b) = (sub.graph.clone(), sub.path.clone(), sub.base_dir.clone());
            stack.push(canon);
            let r = Self::build(g, p, b, stack);
            stack.pop();
            sub = r.map_err(|e| match e {
                GraphError::Param { param, detail, .. } => GraphError::Param {
                    param,
                    detail,
                    at: at.clone(),
                },
                other => other,
            })?;
        }
        let ports = sub.ports_as_node();
        Ok((NodeKind::Graph(Arc::new(sub)), ports))
    }

    fn output_port(&self, r: &PortRef) -> Option<&PortSpec> {
        self.ports
            .get(&r.node)?
            .outputs
            .iter()
            .find(|p| p.name == r.port)
    }

    fn check_edges(&self) -> Result<(), GraphError> {
        for (id, node) in &self.graph.nodes {
            let at = self.at_node(*id);
            let ports = &self.ports[id];
            for (port, src) in &node.inputs {
                let Some(dst) = ports.inputs.iter().find(|p| &p.name == port) else {
                    return Err(GraphError::UnknownPort {
                        dir: "input",
                        port: port.clone(),
                        op: node.op.clone(),
                        suggestion: nearest(port, ports.inputs.iter().map(|p| p.name.as_str())),
                        at,
                    });
                };
                let (from, found) = match src {
                    Source::Node(sid, sport) => {
                        let Some(snode) = self.graph.nodes.get(sid) else {
                            return Err(GraphError::MissingNode {
                                what: format!("input {port:?}"),
                                missing: *sid,
                                at,
                            });
                        };
                        let outs = &self.ports[sid].outputs;
                        let Some(sp) = outs.iter().find(|p| &p.name == sport) else {
                            return Err(GraphError::UnknownPort {
                                dir: "output",
                                port: sport.clone(),
                                op: format!("node {sid} ({})", snode.op),
                                suggestion: nearest(sport, outs.iter().map(|p| p.name.as_str())),
                                at,
                            });
                        };
                        (format!("node {sid} output {sport:?}"), sp.ty)
                    }
                    Source::Input(name) => {
                        let Some(def) = self.graph.inputs.get(name) else {
                            return Err(GraphError::Unknown {
                                what: "graph input",
                                name: name.clone(),
                                suggestion: nearest(
                                    name,
                                    self.graph.inputs.keys().map(String::as_str),
                                ),
                                at,
                            });
                        };
                        (format!("graph input {name:?}"), def.ty)
                    }
                };
                if found != dst.ty {
                    return Err(GraphError::TypeMismatch {
                        port: port.clone(),
                        expected: dst.ty.name(),
                        from,
                        found: found.name(),
                        at,
                    });
                }
            }
            if let Some(p) = ports
                .inputs
                .iter()
                .find(|p| !p.optional && !node.inputs.contains_key(&p.name))
            {
                return Err(GraphError::MissingInput {
                    port: p.name.clone(),
                    at,
                });
            }
        }
        Ok(())
    }

    fn check_refs(&self) -> Result<(), GraphError> {
        for (name, r) in &self.graph.outputs {
            let what = format!("graph output {name:?}");
            let Some(node) = self.graph.nodes.get(&r.node) else {
                return Err(GraphError::MissingNode {
                    what,
                    missing: r.node,
                    at: self.at(),
                });
            };
            if self.output_port(r).is_none() {
                let outs = &self.ports[&r.node].outputs;
                return Err(GraphError::UnknownPort {
                    dir: "output",
                    port: r.port.clone(),
                    op: node.op.clone(),
                    suggestion: nearest(&r.port, outs.iter().map(|p| p.name.as_str())),
                    at: self.at_node(r.node),
                });
            }
        }
        for (name, ex) in &self.graph.exposed {
            if !self.graph.nodes.contains_key(&ex.node) {
                return Err(GraphError::MissingNode {
                    what: format!("exposed parameter {name:?}"),
                    missing: ex.node,
                    at: self.at(),
                });
            }
            if self.param_info(ex.node, &ex.param).is_none() {
                let names = self.param_names(ex.node);
                return Err(GraphError::Param {
                    param: ex.param.clone(),
                    detail: format!(
                        "exposed parameter {name:?} names unknown parameter {:?}{}",
                        ex.param,
                        nearest(&ex.param, names.iter().map(String::as_str))
                            .map(|s| format!(" (did you mean {s:?}?)"))
                            .unwrap_or_default()
                    ),
                    at: self.at_node(ex.node),
                });
            }
        }
        Ok(())
    }

    fn topo_order(&self) -> Result<Vec<NodeId>, GraphError> {
        // Kahn's algorithm on node → node edges.
        let mut indeg: BTreeMap<NodeId, usize> = self.graph.nodes.keys().map(|k| (*k, 0)).collect();
        let mut users: BTreeMap<NodeId, Vec<NodeId>> = BTreeMap::new();
        for (id, n) in &self.graph.nodes {
            for src in n.inputs.values() {
                if let Source::Node(s, _) = src {
                    *indeg.entry(*id).or_default() += 1;
                    users.entry(*s).or_default().push(*id);
                }
            }
        }
        let mut ready: BTreeSet<NodeId> = indeg
            .iter()
            .filter(|(_, d)| **d == 0)
            .map(|(k, _)| *k)
            .collect();
        let mut order = Vec::with_capacity(indeg.len());
        while let Some(id) = ready.pop_first() {
            order.push(id);
            for u in users.get(&id).into_iter().flatten() {
                let d = indeg.get_mut(u).expect("every user is a node");
                *d -= 1;
                if *d == 0 {
                    ready.insert(*u);
                }
            }
        }
        if order.len() < self.graph.nodes.len() {
            let done: BTreeSet<NodeId> = order.iter().copied().collect();
            let nodes: Vec<NodeId> = self
                .graph
                .nodes
                .keys()
                .filter(|k| !done.contains(k))
                .copied()
                .collect();
            return Err(GraphError::Cycle {
                at: self.at_node(nodes[0]),
                nodes,
            });
        }
        Ok(order)
    }

    /// Parameter names of node `id`.
    #[must_use]
    pub fn param_names(&self, id: NodeId) -> Vec<String> {
        match self.kinds.get(&id) {
            Some(NodeKind::Op { op, .. }) => op.params().iter().map(|p| p.name.into()).collect(),
            Some(NodeKind::Graph(sub)) => std::iter::once("path".to_string())
                .chain(sub.graph.exposed.keys().cloned())
                .collect(),
            Some(NodeKind::Reroute) | None => Vec::new(),
        }
    }

    /// Describes parameter `param` of node `id` (for a graph node: `path` or an exposed one).
    #[must_use]
    pub fn param_info(&self, id: NodeId, param: &str) -> Option<ParamInfo> {
        match self.kinds.get(&id)? {
            NodeKind::Op { op, .. } => op.params().iter().find(|p| p.name == param).cloned(),
            NodeKind::Graph(sub) => {
                if param == "path" {
                    return Some(ParamInfo {
                        name: "path",
                        kind: ParamKind::Path,
                        meta: crate::params::Meta::new("The graph file this node uses."),
                        default: ParamValue::Path(String::new()),
                    });
                }
                let ex = sub.graph.exposed.get(param)?;
                sub.param_info(ex.node, &ex.param)
            }
            NodeKind::Reroute => None,
        }
    }

    /// Sets parameter `param` of the node named by `node_ref` (id or name) from command-line
    /// text, then re-validates the graph.
    pub fn set_param(
        &mut self,
        node_ref: &str,
        param: &str,
        value: &str,
    ) -> Result<(), GraphError> {
        self.set_params(&[(node_ref, param, value)])
    }

    /// Sets several parameters (`(node, param, text)` as [`set_param`](Self::set_param)), then
    /// validates the graph once: parameters that depend on each other (`camera: k_file` and
    /// its `k_file`) can be set in any order. Each text is parsed by its parameter's kind
    /// first; nothing changes on an error.
    pub fn set_params(&mut self, sets: &[(&str, &str, &str)]) -> Result<(), GraphError> {
        let mut graph = self.graph.clone();
        for &(node_ref, param, value) in sets {
            let (id, v) = self.parse_set(node_ref, param, value)?;
            if let Some(n) = graph.nodes.get_mut(&id) {
                n.params.insert(param.to_string(), v);
            }
        }
        *self = Self::from_graph(graph, self.path.clone(), self.base_dir.clone())?;
        Ok(())
    }

    /// The node and parsed value of one `NODE.PARAM=VALUE`.
    fn parse_set(
        &self,
        node_ref: &str,
        param: &str,
        value: &str,
    ) -> Result<(NodeId, ParamValue), GraphError> {
        let Some(id) = self.graph.find_node(node_ref) else {
            let names: Vec<String> = self
                .graph
                .nodes
                .values()
                .flat_map(|n| [n.id.to_string()].into_iter().chain(n.name.clone()))
                .collect();
            return Err(GraphError::Unknown {
                what: "node",
                name: node_ref.to_string(),
                suggestion: nearest(node_ref, names.iter().map(String::as_str)),
                at: self.at(),
            });
        };
        let at = self.at_node(id);
        let Some(info) = self.param_info(id, param) else {
            let names = self.param_names(id);
            return Err(GraphError::Param {
                param: param.to_string(),
                detail: format!(
                    "unknown parameter {param:?}{}",
                    nearest(param, names.iter().map(String::as_str))
                        .map(|s| format!(" (did you mean {s:?}?)"))
                        .unwrap_or_default()
                ),
                at,
            });
        };
        let v = info
            .parse_str(value)
            .map_err(|detail| GraphError::BadValue {
                param: param.to_string(),
                value: value.to_string(),
                detail,
                at: at.clone(),
            })?;
        Ok((id, v))
    }

    /// Connects `source` to input `port` of node `to`, replacing any edge into that port. The
    /// graph is changed only if the result is valid (ports exist, types match, no cycle); an
    /// editor asks this first and mirrors the change in its view on success.
    pub fn connect(&mut self, to: NodeId, port: &str, source: Source) -> Result<(), GraphError> {
        let mut graph = self.graph.clone();
        let Some(n) = graph.nodes.get_mut(&to) else {
            return Err(GraphError::MissingNode {
                what: "connection".into(),
                missing: to,
                at: self.at(),
            });
        };
        n.inputs.insert(port.to_string(), source);
        *self = Self::from_graph(graph, self.path.clone(), self.base_dir.clone())?;
        Ok(())
    }

    /// Removes the edge into input `port` of node `to` (refused if that input is required).
    pub fn disconnect(&mut self, to: NodeId, port: &str) -> Result<(), GraphError> {
        let mut graph = self.graph.clone();
        if let Some(n) = graph.nodes.get_mut(&to) {
            n.inputs.remove(port);
        }
        *self = Self::from_graph(graph, self.path.clone(), self.base_dir.clone())?;
        Ok(())
    }

    /// The type of graph output `name`.
    #[must_use]
    pub fn output_type(&self, name: &str) -> Option<PortType> {
        Some(self.output_port(self.graph.outputs.get(name)?)?.ty)
    }

    /// The ports this graph has when used as a node in another graph: its named inputs and
    /// outputs.
    #[must_use]
    pub fn ports_as_node(&self) -> NodePorts {
        NodePorts {
            inputs: self
                .graph
                .inputs
                .iter()
                .map(|(n, d)| PortSpec::new(n, d.ty, &d.doc))
                .collect(),
            outputs: self
                .graph
                .outputs
                .keys()
                .filter_map(|n| Some(PortSpec::new(n, self.output_type(n)?, "")))
                .collect(),
        }
    }
}

fn param_error(e: &crate::params::ParamError, at: At) -> GraphError {
    use crate::params::ParamError as P;
    let param = match e {
        P::Unknown { name, .. } | P::Kind { name, .. } | P::Range { name, .. } => name.clone(),
    };
    GraphError::Param {
        param,
        detail: e.to_string(),
        at,
    }
}

#[cfg(test)]
#[path = "graph_tests.rs"]
mod tests;
