//! The graph file: a versioned RON schema of its own (not serialized runtime structs).
//!
//! ```ron
//! (
//!     version: 3,
//!     next_id: 4,                        // ids are never reused
//!     inputs: { "image": (ty: Rgbn, doc: "Image to edit.") },
//!     outputs: { "relit": (node: 3, port: "picture") },
//!     exposed: { "sigma": (node: 2, param: "sigma_px", doc: "Blur radius.") },
//!     nodes: [
//!         (id: 2, op: "filter.gaussian", name: Some("blur"), pos: (200.0, 0.0),
//!          params: { "sigma_px": Float(2.0) }, inputs: { "image": Input("image") }),
//!         (id: 3, op: "relight", pos: (400.0, 0.0), inputs: { "image": Node(2, "image") }),
//!         (id: 4, op: "reroute", pos: (300.0, 80.0), inputs: { "in": Node(2, "image") }),
//!     ],
//!     frames: [ (title: "Detail", color: (70, 100, 140), nodes: [2, 4]) ],
//! )
//! ```
//!
//! Edges live with the node they lead into (`inputs: { PORT: Node(ID, PORT) | Input(NAME) }`),
//! so an input port has at most one edge by construction. Maps are sorted (`BTreeMap`), nodes
//! are written in id order, the output is pretty RON: files diff well.
//!
//! **Versions.** [`CURRENT_VERSION`] is written. A newer version is refused with
//! [`GraphError::UnsupportedVersion`]; older versions are read with their own schema and
//! migrated one version at a time by functions ([`migrate_v0`], [`migrate_v1`],
//! [`migrate_v2`]).
//!
//! - 0 → 1: node positions `x`, `y` became `pos`; `next_id` and `exposed` were added.
//! - 1 → 2: a pen node holds a list of paths (`paths`) instead of one path (`points` and
//!   `closed`).
//! - 2 → 3: `frames` (titled, coloured boxes around nodes) and reroute nodes (`op: "reroute"`,
//!   one input `in`, one output `out`, typed by what feeds them) were added; a version-2 file
//!   has neither, so it migrates unchanged ([`migrate_v2`]).
//!
//! **Frames** are drawn behind their nodes and move them; they do nothing to evaluation. A
//! node is in at most one frame. **Reroutes** are wires with a point to drag: the plan resolves
//! them to direct connections, so a graph evaluates (and keys) the same with or without them.

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::error::GraphError;
use crate::nodes::PortType;
use crate::params::ParamValue;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The version this rgbn writes.
pub const CURRENT_VERSION: u32 = 3;

/// A graph file, current version.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphFile {
    /// Schema version.
    pub version: u32,
    /// The next node id to hand out (above every id ever used).
    pub next_id: u64,
    /// Named graph inputs (ports of the graph when used as a node).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub inputs: BTreeMap<String, InputDef>,
    /// Named graph outputs.
    #[serde(default)]
    pub outputs: BTreeMap<String, PortRef>,
    /// Parameters exposed to a graph using this one as a node.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub exposed: BTreeMap<String, ExposedDef>,
    /// The nodes, in id order.
    pub nodes: Vec<NodeDef>,
    /// Frames: titled, coloured boxes drawn behind their nodes (editor only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<FrameDef>,
}

/// A frame: a titled, coloured box drawn behind a set of nodes, which moves them with it. It
/// has no effect on evaluation. Its box is the bounding box of its nodes (with a margin and a
/// title bar), so it follows them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameDef {
    /// The title shown in its bar.
    #[serde(default)]
    pub title: String,
    /// Its colour, sRGB `(r, g, b)`.
    #[serde(default = "FrameDef::default_color")]
    pub color: [u8; 3],
    /// The nodes inside it (each node is in at most one frame).
    pub nodes: Vec<u64>,
}

impl FrameDef {
    /// The colour of a new frame: a muted blue-grey.
    pub const DEFAULT_COLOR: [u8; 3] = [72, 96, 128];

    fn default_color() -> [u8; 3] {
        Self::DEFAULT_COLOR
    }
}

/// A graph input.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputDef {
    /// Type of the values it takes.
    pub ty: PortType,
    /// Documentation.
    #[serde(default)]
    pub doc: String,
}

/// An output port of a node.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PortRef {
    /// Node id.
    pub node: u64,
    /// Output port name.
    pub port: String,
}

/// A node parameter exposed as a parameter of the graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExposedDef {
    /// Node id.
    pub node: u64,
    /// The node's parameter name.
    pub param: String,
    /// Documentation (defaults to the parameter's own).
    #[serde(default)]
    pub doc: String,
}

/// Where an input port's value comes from.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Source {
    /// Output `port` of node `id`.
    Node(u64, String),
    /// The graph input of that name.
    Input(String),
}

/// A node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeDef {
    /// Stable id, never reused.
    pub id: u64,
    /// Operator id (or `graph` for a graph file used as a node).
    pub op: String,
    /// Optional name (for people and `--set NAME.PARAM=…`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Editor position `[x, y]`.
    #[serde(default)]
    pub pos: [f32; 2],
    /// Parameters that differ from (or restate) the defaults.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub params: BTreeMap<String, ParamValue>,
    /// Incoming edges by input port name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub inputs: BTreeMap<String, Source>,
}

/// Version 0 (a synthetic earlier schema kept to exercise migration): node positions were two
/// fields `x`, `y`, and there was no `next_id` nor `exposed`.
pub mod v0 {
    use super::*;

    /// A version-0 file.
    #[derive(Clone, Debug, PartialEq, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct GraphFile {
        /// Always 0.
        pub version: u32,
        /// Graph inputs.
        #[serde(default)]
        pub inputs: BTreeMap<String, InputDef>,
        /// Graph outputs.
        #[serde(default)]
        pub outputs: BTreeMap<String, PortRef>,
        /// Nodes.
        pub nodes: Vec<NodeDef>,
    }

    /// A version-0 node.
    #[derive(Clone, Debug, PartialEq, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct NodeDef {
        /// Id.
        pub id: u64,
        /// Operator.
        pub op: String,
        /// Name.
        #[serde(default)]
        pub name: Option<String>,
        /// Editor x.
        #[serde(default)]
        pub x: f32,
        /// Editor y.
        #[serde(default)]
        pub y: f32,
        /// Parameters.
        #[serde(default)]
        pub params: BTreeMap<String, ParamValue>,
        /// Incoming edges.
        #[serde(default)]
        pub inputs: BTreeMap<String, Source>,
    }
}

/// Versions 1 and 2 (the same schema; 2 differs in the meaning of pen parameters): the
/// current schema without `frames`.
pub mod v2 {
    use super::*;

    /// A version-1 or version-2 file.
    #[derive(Clone, Debug, PartialEq, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct GraphFile {
        /// 1 or 2.
        pub version: u32,
        /// The next node id to hand out.
        pub next_id: u64,
        /// Graph inputs.
        #[serde(default)]
        pub inputs: BTreeMap<String, InputDef>,
        /// Graph outputs.
        #[serde(default)]
        pub outputs: BTreeMap<String, PortRef>,
        /// Exposed parameters.
        #[serde(default)]
        pub exposed: BTreeMap<String, ExposedDef>,
        /// Nodes.
        pub nodes: Vec<NodeDef>,
    }
}

/// Migrates a version-0 file to version 1: `pos = [x, y]`, `next_id = max id + 1`, no exposed
/// parameters.
#[must_use]
pub fn migrate_v0(old: v0::GraphFile) -> v2::GraphFile {
    let next_id = old.nodes.iter().map(|n| n.id + 1).max().unwrap_or(1);
    v2::GraphFile {
        version: 1,
        next_id,
        inputs: old.inputs,
        outputs: old.outputs,
        exposed: BTreeMap::new(),
        nodes: old
            .nodes
            .into_iter()
            .map(|n| NodeDef {
                id: n.id,
                op: n.op,
                name: n.name,
                pos: [n.x, n.y],
                params: n.params,
                inputs: n.inputs,
            })
            .collect(),
    }
}

/// Migrates a version-1 file to version 2: each pen node's `points` and `closed` become the
/// one path of its `paths` (the pen's old default path where `points` was not given). The
/// schema is otherwise the same.
#[must_use]
pub fn migrate_v1(mut f: v2::GraphFile) -> v2::GraphFile {
    use crate::params::PathValue;
    f.version = 2;
    for n in f.nodes.iter_mut().filter(|n| n.op == "pen") {
        let points = n.params.remove("points");
        let closed = n.params.remove("closed");
        if points.is_none() && closed.is_none() {
            continue;
        }
        let points = match points {
            Some(ParamValue::Points(p)) => p,
            // Not a list of points: kept for the parameter check to refuse by name.
            Some(other) => {
                n.params.insert("points".into(), other);
                continue;
            }
            None => crate::ops::pen::PenParams::default().points,
        };
        let closed = match closed {
            Some(ParamValue::Bool(b)) => b,
            None => false,
            Some(other) => {
                n.params.insert("points".into(), ParamValue::Points(points));
                n.params.insert("closed".into(), other);
                continue;
            }
        };
        n.params.insert(
            "paths".into(),
            ParamValue::Paths(vec![PathValue::new(points, closed)]),
        );
    }
    f
}

/// Migrates a version-2 file to version 3: the schema gained `frames` (none in the migrated
/// file) and the `reroute` node; nothing else changed.
#[must_use]
pub fn migrate_v2(f: v2::GraphFile) -> GraphFile {
    GraphFile {
        version: 3,
        next_id: f.next_id,
        inputs: f.inputs,
        outputs: f.outputs,
        exposed: f.exposed,
        nodes: f.nodes,
        frames: Vec::new(),
    }
}

fn syntax(file: &str, e: &ron::error::SpannedError) -> GraphError {
    GraphError::Syntax {
        file: file.to_string(),
        line: e.span.start.line,
        col: e.span.start.col,
        detail: e.code.to_string(),
    }
}

/// Parses graph-file text of any supported version into the current schema. `file` names the
/// source in messages.
pub fn parse(text: &str, file: &str) -> Result<GraphFile, GraphError> {
    #[derive(Deserialize)]
    struct Probe {
        version: u32,
    }
    let probe: Probe = ron::from_str(text).map_err(|e| syntax(file, &e))?;
    let v2 = || -> Result<v2::GraphFile, GraphError> {
        ron::from_str(text).map_err(|e| syntax(file, &e))
    };
    match probe.version {
        0 => Ok(migrate_v2(migrate_v1(migrate_v0(
            ron::from_str(text).map_err(|e| syntax(file, &e))?,
        )))),
        1 => Ok(migrate_v2(migrate_v1(v2()?))),
        2 => Ok(migrate_v2(v2()?)),
        CURRENT_VERSION => ron::from_str(text).map_err(|e| syntax(file, &e)),
        found => Err(GraphError::UnsupportedVersion {
            file: file.to_string(),
            found,
            supported: CURRENT_VERSION,
        }),
    }
}

/// Writes the current schema as pretty RON (sorted maps, nodes in id order, trailing newline).
#[must_use]
pub fn to_text(f: &GraphFile) -> String {
    let mut f = f.clone();
    f.nodes.sort_by_key(|n| n.id);
    let cfg = ron::ser::PrettyConfig::new()
        .indentor("    ".to_string())
        .struct_names(false);
    let mut s = ron::ser::to_string_pretty(&f, cfg).unwrap_or_else(|e| {
        // Serialising plain data to a string cannot fail; keep a visible trace if it ever does.
        format!("// serialisation failed: {e}\n")
    });
    s.push('\n');
    s
}

#[cfg(test)]
#[path = "file_tests.rs"]
mod tests;
