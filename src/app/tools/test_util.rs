//! Helpers shared by the tools' tests.

use super::coords::dist;
use super::*;
use crate::app::state::Document;
use crate::graph::NodeId;
use std::path::PathBuf;

pub(super) fn demo() -> Document {
    Document::demo()
}

pub(super) fn press(at: [f64; 2]) -> Press {
    Press::plain(at)
}

pub(super) fn base() -> PathBuf {
    PathBuf::from(".")
}

pub(super) fn close(a: [f64; 2], b: [f64; 2], tol: f64) -> bool {
    dist(a, b) <= tol
}

/// Draws a stroke through `pts` with `tools`, live, and finishes it.
pub(super) fn draw(
    d: &mut Document,
    tools: &ToolState,
    sel: Option<NodeId>,
    viewed: &(NodeId, String),
    pts: &[[f64; 2]],
) -> Option<NodeId> {
    let mut gest = Gesture::stroke(d, tools, sel, Some(viewed), press(pts[0]))?;
    for p in &pts[1..] {
        gest.update(&mut d.graph, *p, press(*p), false, true, &base())
            .unwrap();
    }
    let id = gest.node();
    gest.finish(d, press(*pts.last().unwrap())).unwrap();
    id.or_else(|| d.graph.nodes.keys().next_back().copied())
}

pub(super) fn pen_tools() -> ToolState {
    ToolState {
        kind: ToolKind::Pen,
        ..ToolState::default()
    }
}
