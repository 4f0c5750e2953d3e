//! Reroute nodes: a point on a wire that can be dragged, as Blender's reroute and Nuke's Dot.
//!
//! A reroute is a node of its own (`op: "reroute"`, no parameters) with one input `in` and one
//! output `out`, both of the type of what feeds it, so it can fan out to several inputs and be
//! chained. It runs nothing: [`crate::eval::Plan`] connects its users straight to its source,
//! so the evaluator, the content keys and the region engine never see it, and a graph
//! evaluates the same with or without reroutes.
//!
//! Validation (`type_reroutes`, run by [`LoadedGraph`]) refuses a reroute with nothing
//! connected, one whose wire comes from a missing node or port, and a loop of reroutes. In the
//! editor's unfinished graphs ([`Graph::node_ports`]) a reroute fed by nothing yet takes the
//! type its users expect.

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{Graph, GraphError, LoadedGraph, NodeId, NodePorts, Source};
use crate::nodes::{PortSpec, PortType, REROUTE_OP};
use crate::params::nearest;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The reroute's input port.
pub const IN: &str = "in";
/// The reroute's output port.
pub const OUT: &str = "out";

/// The ports of a reroute carrying values of type `ty`.
#[must_use]
pub fn ports(ty: PortType) -> NodePorts {
    NodePorts {
        inputs: vec![PortSpec::new(IN, ty, "The wire rerouted.")],
        outputs: vec![PortSpec::new(OUT, ty, "The same value, unchanged.")],
    }
}

impl Graph {
    /// Whether node `id` is a reroute.
    #[must_use]
    pub fn is_reroute(&self, id: NodeId) -> bool {
        self.nodes.get(&id).is_some_and(|n| n.op == REROUTE_OP)
    }

    /// The type of what feeds reroute `id`, through any chain of reroutes; `None` when nothing
    /// typed feeds it (unconnected, a missing node or port, a loop of reroutes).
    #[must_use]
    pub fn reroute_source_type(&self, id: NodeId, base_dir: &Path) -> Option<PortType> {
        let mut at = id;
        let mut seen = BTreeSet::new();
        loop {
            if !seen.insert(at) {
                return None;
            }
            match self.nodes.get(&at)?.inputs.get(IN)? {
                Source::Input(name) => return self.inputs.get(name).map(|d| d.ty),
                Source::Node(src, port) => {
                    if self.is_reroute(*src) {
                        at = *src;
                        continue;
                    }
                    let p = self.node_ports(*src, base_dir).ok()?;
                    return p.outputs.iter().find(|o| &o.name == port).map(|o| o.ty);
                }
            }
        }
    }

    /// The type the users of reroute `id` take (through reroutes downstream): the first one
    /// found, `None` when it feeds nothing typed.
    #[must_use]
    pub fn reroute_sink_type(&self, id: NodeId, base_dir: &Path) -> Option<PortType> {
        let mut stack = vec![id];
        let mut seen = BTreeSet::new();
        while let Some(r) = stack.pop() {
            if !seen.insert(r) {
                continue;
            }
            for n in self.nodes.values() {
                for (port, s) in &n.inputs {
                    if !matches!(s, Source::Node(src, _) if *src == r) {
                        continue;
                    }
                    if n.op == REROUTE_OP {
                        stack.push(n.id);
                    } else if let Ok(p) = self.node_ports(n.id, base_dir) {
                        if let Some(i) = p.inputs.iter().find(|i| &i.name == port) {
                            return Some(i.ty);
                        }
                    }
                }
            }
        }
        None
    }
}

/// Types every reroute of `lg` from what feeds it and sets its ports. Refuses a reroute with
/// nothing connected or an input other than `in`, a wire from a missing node or port, and a
/// loop of reroutes, naming the reroute.
pub(super) fn type_reroutes(lg: &mut LoadedGraph) -> Result<(), GraphError> {
    let mut typed: BTreeMap<NodeId, PortType> = BTreeMap::new();
    let ids: Vec<NodeId> = lg
        .graph
        .nodes
        .values()
        .filter(|n| n.op == REROUTE_OP)
        .map(|n| n.id)
        .collect();
    for id in ids {
        let mut chain: Vec<NodeId> = Vec::new();
        let mut cur = id;
        let ty = loop {
            if let Some(t) = typed.get(&cur) {
                break *t;
            }
            if let Some(i) = chain.iter().position(|c| *c == cur) {
                let ring: Vec<String> = chain[i..]
                    .iter()
                    .chain([&cur])
                    .map(ToString::to_string)
                    .collect();
                return Err(GraphError::Reroute {
                    detail: format!(
                        "is on a loop of reroutes {} (each feeds the next): break the loop",
                        ring.join(" → ")
                    ),
                    at: lg.at_node(cur),
                });
            }
            chain.push(cur);
            let node = &lg.graph.nodes[&cur];
            let at = lg.at_node(cur);
            if let Some(p) = node.inputs.keys().find(|k| *k != IN) {
                return Err(GraphError::UnknownPort {
                    dir: "input",
                    port: p.clone(),
                    op: REROUTE_OP.into(),
                    suggestion: nearest(p, [IN]),
                    at,
                });
            }
            match node.inputs.get(IN) {
                None => {
                    return Err(GraphError::Reroute {
                        detail: format!(
                            "has nothing connected to its input {IN:?}: connect a wire into it or delete it"
                        ),
                        at,
                    })
                }
                Some(Source::Input(name)) => match lg.graph.inputs.get(name) {
                    Some(d) => break d.ty,
                    None => {
                        return Err(GraphError::Unknown {
                            what: "graph input",
                            name: name.clone(),
                            suggestion: nearest(name, lg.graph.inputs.keys().map(String::as_str)),
                            at,
                        })
                    }
                },
                Some(Source::Node(src, port)) => {
                    let Some(snode) = lg.graph.nodes.get(src) else {
                        return Err(GraphError::MissingNode {
                            what: format!("reroute input {IN:?}"),
                            missing: *src,
                            at,
                        });
                    };
                    let outs: Vec<&str> = if snode.op == REROUTE_OP {
                        vec![OUT]
                    } else {
                        lg.ports[src]
                            .outputs
                            .iter()
                            .map(|o| o.name.as_str())
                            .collect()
                    };
                    if !outs.contains(&port.as_str()) {
                        return Err(GraphError::UnknownPort {
                            dir: "output",
                            port: port.clone(),
                            op: format!("node {src} ({})", snode.op),
                            suggestion: nearest(port, outs.iter().copied()),
                            at,
                        });
                    }
                    if snode.op == REROUTE_OP {
                        cur = *src;
                        continue;
                    }
                    let ty = lg.ports[src].outputs.iter().find(|o| &o.name == port);
                    break ty.map_or(PortType::Rgbn, |o| o.ty);
                }
            }
        };
        for c in chain {
            typed.insert(c, ty);
        }
    }
    for (id, ty) in typed {
        lg.ports.insert(id, ports(ty));
    }
    Ok(())
}
