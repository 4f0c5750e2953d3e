//! The plan: a validated graph flattened into instances in topological order (graph files used
//! as nodes inlined, graph inputs bound, relative paths resolved), and the content key of an
//! instance's output port.

use super::CacheKey;
use crate::graph::{At, GraphError, LoadedGraph, NodeId, NodeKind, PortRef, Source};
use crate::nodes::{self, DynOp, Parsed, PortType, ALL_PORTS};
use crate::params::{nearest, ParamKind, ParamValue};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// The content key of output `port` of an instance whose key is `key` (port 0 and the rest
/// apart, the same value everywhere it is named).
#[must_use]
pub fn port_key(key: CacheKey, port: usize) -> CacheKey {
    key ^ (port as u128).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// Where an instance's input comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Conn {
    /// Unconnected (optional input).
    None,
    /// Output `port` of instance `index`.
    Slot(usize, usize),
    /// A graph input that was not bound (an error only if it is needed).
    Unbound {
        /// The input's name.
        name: String,
        /// Where it is used.
        at: At,
    },
}

/// One operator application in a flattened graph.
#[derive(Clone)]
pub struct Instance {
    /// The operator.
    pub op: &'static dyn DynOp,
    /// Its parameters, parsed once (relative paths resolved).
    pub params: Parsed,
    /// Inputs in port order.
    pub inputs: Vec<Conn>,
    /// The node it comes from (file, id, name).
    pub at: At,
}

/// A flattened graph ready to evaluate.
#[derive(Clone)]
pub struct Plan {
    /// Instances in topological order.
    pub instances: Vec<Instance>,
    /// Graph outputs by name.
    pub outputs: BTreeMap<String, Conn>,
    /// Types of the graph outputs.
    pub output_types: BTreeMap<String, PortType>,
    /// Files the graph reads (never overwritten).
    pub protected: Vec<PathBuf>,
    /// The top-level graph's location.
    pub at: At,
}

impl Plan {
    /// The connection of graph output `name`, or the error naming the nearest output.
    pub(crate) fn output(&self, name: &str) -> Result<&Conn, GraphError> {
        self.outputs.get(name).ok_or_else(|| GraphError::Unknown {
            what: "graph output",
            name: name.to_string(),
            suggestion: nearest(name, self.outputs.keys().map(String::as_str)),
            at: self.at.clone(),
        })
    }

    /// The outputs read of each instance (bit `k`: port `k`) when `roots` are asked for
    /// (instance, port; `None`: every port): a root's port, and every port an instance read
    /// takes as input. Over-estimated where a cache cuts the graph short (an instance read
    /// only by a cached one still counts). An operator without
    /// [`crate::nodes::OpSpec::lazy_outputs`] wants all its ports once one is read; 0: not read.
    #[must_use]
    pub fn demand(&self, roots: &[(usize, Option<usize>)]) -> Vec<u64> {
        let port_bit = |p: usize| if p < 64 { 1u64 << p } else { ALL_PORTS };
        let mut d = vec![0u64; self.instances.len()];
        for &(i, p) in roots {
            d[i] |= p.map_or(ALL_PORTS, port_bit);
        }
        // Instances are in topological order: a reader comes after what it reads.
        for i in (0..self.instances.len()).rev() {
            if d[i] == 0 {
                continue;
            }
            if !self.instances[i].op.spec().lazy_outputs {
                d[i] = ALL_PORTS;
            }
            for c in &self.instances[i].inputs {
                if let Conn::Slot(j, p) = c {
                    d[*j] |= port_bit(*p);
                }
            }
        }
        d
    }

    /// Whether output `port` of instance `j` is a number (a summary of a whole image).
    #[must_use]
    pub fn is_number(&self, j: usize, port: usize) -> bool {
        self.instances[j]
            .op
            .spec()
            .outputs
            .get(port)
            .is_some_and(|p| p.ty == crate::nodes::PortType::Number)
    }

    /// Flattens `lg`, binding graph inputs to files (`--input NAME=PATH`: RGBN inputs are
    /// loaded with `load`, masks with `load_mask`). Relative output paths of `save` nodes are
    /// resolved against `out_dir`, relative input paths against each graph file's folder.
    pub fn new(
        lg: &LoadedGraph,
        inputs: &BTreeMap<String, PathBuf>,
        out_dir: &Path,
    ) -> Result<Self, GraphError> {
        let mut plan = Plan {
            instances: Vec::new(),
            outputs: BTreeMap::new(),
            output_types: BTreeMap::new(),
            protected: Vec::new(),
            at: lg.at(),
        };
        let mut bindings = BTreeMap::new();
        for (name, path) in inputs {
            let Some(def) = lg.graph.inputs.get(name) else {
                return Err(GraphError::Unknown {
                    what: "graph input",
                    name: name.clone(),
                    suggestion: nearest(name, lg.graph.inputs.keys().map(String::as_str)),
                    at: lg.at(),
                });
            };
            let (op_id, param) = match def.ty {
                PortType::Rgbn => ("load", "path"),
                PortType::Mask => ("load_mask", "path"),
                other => {
                    return Err(GraphError::Param {
                        param: name.clone(),
                        detail: format!(
                            "graph input {name:?} has type {} and cannot be read from a file",
                            other.name()
                        ),
                        at: lg.at(),
                    })
                }
            };
            let op = nodes::find(op_id).expect("registered");
            let mut params = BTreeMap::new();
            params.insert(param.to_string(), ParamValue::Path(display(path)));
            let params = op.parse(&params).map_err(|e| GraphError::Param {
                param: name.clone(),
                detail: e.to_string(),
                at: lg.at(),
            })?;
            plan.protected.push(path.clone());
            plan.instances.push(Instance {
                op,
                params,
                inputs: Vec::new(),
                at: At::file(format!("--input {name}={}", display(path))),
            });
            bindings.insert(name.clone(), Conn::Slot(plan.instances.len() - 1, 0));
        }
        let outs = plan.flatten(lg, &bindings, out_dir);
        for (name, r) in &lg.graph.outputs {
            if let (Some(c), Some(ty)) = (outs.get(&(r.node, r.port.clone())), lg.output_type(name))
            {
                plan.outputs.insert(name.clone(), c.clone());
                plan.output_types.insert(name.clone(), ty);
            }
        }
        Ok(plan)
    }

    /// Inlines `lg`; returns every node output as a connection, keyed by (node, port).
    fn flatten(
        &mut self,
        lg: &LoadedGraph,
        bindings: &BTreeMap<String, Conn>,
        out_dir: &Path,
    ) -> HashMap<(NodeId, String), Conn> {
        let mut outs: HashMap<(NodeId, String), Conn> = HashMap::new();
        for id in &lg.order {
            let node = &lg.graph.nodes[id];
            let ports = &lg.ports[id];
            let at = lg.at_node(*id);
            let conn_of = |src: Option<&Source>| -> Conn {
                match src {
                    None => Conn::None,
                    Some(Source::Node(n, p)) => {
                        outs.get(&(*n, p.clone())).cloned().unwrap_or(Conn::None)
                    }
                    Some(Source::Input(name)) => {
                        bindings
                            .get(name)
                            .cloned()
                            .unwrap_or_else(|| Conn::Unbound {
                                name: name.clone(),
                                at: at.clone(),
                            })
                    }
                }
            };
            let inputs: Vec<Conn> = ports
                .inputs
                .iter()
                .map(|p| conn_of(node.inputs.get(&p.name)))
                .collect();
            match &lg.kinds[id] {
                NodeKind::Op { op, params } => {
                    let has_path = op.params().iter().any(|info| {
                        info.kind == ParamKind::Path
                            && matches!(params.values().get(info.name), Some(ParamValue::Path(p)) if !p.is_empty())
                    });
                    let params = if has_path {
                        op.map_paths(params, &mut |_, meta, p| {
                            if p.is_empty() {
                                return;
                            }
                            let base = if meta.output { out_dir } else { &lg.base_dir };
                            let resolved = base.join(&*p);
                            if !meta.output {
                                self.protected.push(resolved.clone());
                            }
                            *p = display(&resolved);
                        })
                    } else {
                        params.clone()
                    };
                    self.instances.push(Instance {
                        op: *op,
                        params,
                        inputs,
                        at,
                    });
                    let idx = self.instances.len() - 1;
                    for (k, p) in ports.outputs.iter().enumerate() {
                        outs.insert((*id, p.name.clone()), Conn::Slot(idx, k));
                    }
                }
                NodeKind::Graph(sub) => {
                    let sub_bindings: BTreeMap<String, Conn> = ports
                        .inputs
                        .iter()
                        .zip(inputs)
                        .map(|(p, c)| (p.name.clone(), c))
                        .collect();
                    let sub_outs = self.flatten(sub, &sub_bindings, out_dir);
                    for (name, PortRef { node, port }) in &sub.graph.outputs {
                        if let Some(c) = sub_outs.get(&(*node, port.clone())) {
                            outs.insert((*id, name.clone()), c.clone());
                        }
                    }
                }
                // A reroute is a wire: its users read its source directly, so no instance,
                // key or region ever sees it.
                NodeKind::Reroute => {
                    let c = inputs.into_iter().next().unwrap_or(Conn::None);
                    outs.insert((*id, crate::graph::reroute::OUT.to_string()), c);
                }
            }
        }
        outs
    }
}

pub(crate) fn display(p: &Path) -> String {
    p.display().to_string()
}
