//! The graph file: a versioned RON schema of its own (not serialized runtime structs).
//!
//! ```ron
//! (
//!     version: 2,
//!     next_id: 4,                        // ids are never reused
//!     inputs: { "image": (ty: Rgbn, doc: "Image to edit.") },
//!     outputs: { "relit": (node: 3, port: "picture") },
//!     exposed: { "sigma": (node: 2, param: "sigma_px", doc: "Blur radius.") },
//!     nodes: [
//!         (id: 2, op: "filter.gaussian", name: Some("blur"), pos: (200.0, 0.0),
//!          params: { "sigma_px": Float(2.0) }, inputs: { "image": Input("image") }),
//!         (id: 3, op: "relight", pos: (400.0, 0.0), inputs: { "image": Node(2, "image") }),
//!     ],
//! )
//! ```
//!
//! Edges live with the node they lead into (`inputs: { PORT: Node(ID, PORT) | Input(NAME) }`),
//! so an input port has at most one edge by construction. Maps are sorted (`BTreeMap`), nodes
//! are written in id order, the output is pretty RON: files diff well.
//!
//! **Versions.** [`CURRENT_VERSION`] is written. A newer version is refused with
//! [`GraphError::UnsupportedVersion`]; older versions are read with their own schema and
//! migrated one version at a time by functions ([`migrate_v0`], [`migrate_v1`]).
//!
//! - 0 → 1: node positions `x`, `y` became `pos`; `next_id` and `exposed` were added.
//! - 1 → 2: a pen node holds a list of paths (`paths`) instead of one path (`points` and
//!   `closed`).

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::error::GraphError;
use crate::nodes::PortType;
use crate::params::ParamValue;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The version this rgbn writes.
pub const CURRENT_VERSION: u32 = 2;

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
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
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

/// Migrates a version-0 file to version 1: `pos = [x, y]`, `next_id = max id + 1`, no exposed
/// parameters.
#[must_use]
pub fn migrate_v0(old: v0::GraphFile) -> GraphFile {
    let next_id = old.nodes.iter().map(|n| n.id + 1).max().unwrap_or(1);
    GraphFile {
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
pub fn migrate_v1(mut f: GraphFile) -> GraphFile {
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
    let read =
        || -> Result<GraphFile, GraphError> { ron::from_str(text).map_err(|e| syntax(file, &e)) };
    match probe.version {
        0 => Ok(migrate_v1(migrate_v0(
            ron::from_str(text).map_err(|e| syntax(file, &e))?,
        ))),
        1 => Ok(migrate_v1(read()?)),
        CURRENT_VERSION => read(),
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
mod tests {
    use super::*;

    const V1: &str = r#"(
    version: 1,
    next_id: 3,
    outputs: { "out": (node: 2, port: "image") },
    nodes: [
        (id: 1, op: "demo", pos: (0.0, 0.0), params: { "size": Int(32) }),
        (id: 2, op: "normalize", name: Some("n"), pos: (10.0, 5.0), inputs: { "image": Node(1, "image") }),
    ],
)"#;

    #[test]
    fn text_round_trip_is_stable() {
        let f = parse(V1, "t.ron").unwrap();
        let t = to_text(&f);
        let g = parse(&t, "t.ron").unwrap();
        assert_eq!(f, g);
        assert_eq!(t, to_text(&g));
        assert!(t.contains("\"size\": Int(32)"), "{t}");
    }

    #[test]
    fn v0_migrates_to_v1() {
        let v0 = r#"(version: 0, outputs: { "out": (node: 2, port: "image") }, nodes: [
            (id: 1, op: "demo", x: 0.0, y: 0.0, params: { "size": Int(32) }),
            (id: 2, op: "normalize", name: Some("n"), x: 10.0, y: 5.0, inputs: { "image": Node(1, "image") }),
        ])"#;
        assert_eq!(parse(v0, "old.ron").unwrap(), parse(V1, "new.ron").unwrap());
    }

    #[test]
    fn v1_pen_points_become_one_path() {
        use crate::params::PathValue;
        let v1 = r#"(version: 1, next_id: 4, nodes: [
            (id: 1, op: "pen", params: { "points": Points([(1.0, 2.0), (3.0, 4.0), (5.0, 1.0)]), "closed": Bool(true), "width_px": Float(6.0) }),
            (id: 2, op: "pen", params: { "width_px": Float(6.0) }),
            (id: 3, op: "brush", params: { "points": Points([(1.0, 2.0)]) }),
        ])"#;
        let f = parse(v1, "old.ron").unwrap();
        assert_eq!(f.version, CURRENT_VERSION);
        let p = &f.nodes[0].params;
        assert_eq!(
            p["paths"],
            ParamValue::Paths(vec![PathValue::new(
                vec![[1.0, 2.0], [3.0, 4.0], [5.0, 1.0]],
                true
            )])
        );
        assert!(!p.contains_key("points") && !p.contains_key("closed"));
        assert_eq!(p["width_px"], ParamValue::Float(6.0));
        // A pen at its default path keeps it by default; other operators' points stay.
        assert!(!f.nodes[1].params.contains_key("paths"));
        assert!(f.nodes[2].params.contains_key("points"));
        // The migrated file is written in the current schema and reads back the same.
        let t = to_text(&f);
        assert!(t.contains("version: 2") && t.contains("paths"), "{t}");
        assert_eq!(parse(&t, "new.ron").unwrap(), f);
    }

    #[test]
    fn newer_version_refused_and_syntax_errors_located() {
        let e = parse("(version: 7, next_id: 1, nodes: [])", "f.ron").unwrap_err();
        assert!(matches!(e, GraphError::UnsupportedVersion { found: 7, .. }));
        assert!(e.to_string().contains("f.ron"));
        let e = parse("(\n  version: 1,\n  next_id: 1\n  nodes: [],\n)", "f.ron").unwrap_err();
        match e {
            GraphError::Syntax { line, .. } => assert_eq!(line, 4),
            other => panic!("{other}"),
        }
    }
}
