//! A gesture in progress (stroke, vertex drag, stamp handle drag): live updates and one undo
//! step at the end.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::coords::{dist, push_simplified};
use super::stamp::{drag_handle, StampFrame, StampHandle};
use super::stroke::{Stroke, StrokeMode};
use super::vertices::drag_vertex;
use super::MIN_SPACING_PX;
use crate::app::state::Document;
use crate::graph::{Graph, GraphError, NodeId};
use std::path::Path;

/// A gesture in progress: everything it changes becomes one undo step when it ends.
#[derive(Clone, Debug, PartialEq)]
pub struct Gesture {
    /// The graph before the gesture.
    pub(super) before: Graph,
    /// What the gesture does.
    pub kind: GestureKind,
}

/// What a [`Gesture`] does.
#[derive(Clone, Debug, PartialEq)]
pub enum GestureKind {
    /// A pen or brush stroke.
    Stroke(Stroke),
    /// Dragging vertex `index` of node `node`'s point list.
    Vertex {
        /// The node.
        node: NodeId,
        /// Index in its point list.
        index: usize,
    },
    /// Dragging a stamp handle.
    Stamp {
        /// The stamp node.
        node: NodeId,
        /// The handle.
        handle: StampHandle,
        /// The frame at the grab (handles move relative to it).
        frame: StampFrame,
    },
}

/// What the pointer pressed at the start of a gesture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Press {
    /// Image position.
    pub at: [f64; 2],
    /// Pick tolerance in image pixels ([`PICK_RADIUS_PT`](super::PICK_RADIUS_PT) at the current zoom).
    pub tol_px: f64,
    /// Rotate handle gap in image pixels.
    pub gap_px: f64,
    /// Shift held: extend the path from its end whatever the press position.
    pub extend: bool,
    /// Ctrl held: a pen stroke makes a new pen node, even with a pen node selected.
    pub new_node: bool,
}

impl Press {
    /// A plain press at `at` (no modifier held) with the tolerances of a view at 1:1: a
    /// 4 px pick tolerance and a 6 px rotate-handle gap. Scripted strokes (the memory soak,
    /// the pen benchmark, the tools' tests) draw with it.
    #[must_use]
    pub fn plain(at: [f64; 2]) -> Self {
        Self {
            at,
            tol_px: 4.0,
            gap_px: 6.0,
            extend: false,
            new_node: false,
        }
    }
}

impl Gesture {
    /// The node the gesture edits (for a stroke: once created).
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match &self.kind {
            GestureKind::Stroke(s) => s.node,
            GestureKind::Vertex { node, .. } | GestureKind::Stamp { node, .. } => Some(*node),
        }
    }

    /// The pointer moved to image position `p`. With `write` the change goes into the graph
    /// now (live feedback); the stroke's own points are kept either way. Returns true if the
    /// gesture changed.
    pub fn update(
        &mut self,
        g: &mut Graph,
        p: [f64; 2],
        press: Press,
        uniform: bool,
        write: bool,
        base_dir: &Path,
    ) -> Result<bool, GraphError> {
        let changed = match &mut self.kind {
            GestureKind::Stroke(s) => push_simplified(&mut s.points, p, MIN_SPACING_PX),
            GestureKind::Vertex { node, index } => drag_vertex(g, *node, *index, p),
            GestureKind::Stamp {
                node,
                handle,
                frame,
            } => drag_handle(g, *node, *handle, frame, p, press.gap_px, uniform),
        };
        if write {
            if let GestureKind::Stroke(s) = &mut self.kind {
                s.write(g, base_dir)?;
            }
        }
        Ok(changed)
    }

    /// Ends the gesture: writes what is left and makes the whole gesture one undo step.
    /// A pen stroke that drew a new path ending where it began (within `press.tol_px`) closes
    /// the path. Returns true if the graph changed.
    pub fn finish(mut self, doc: &mut Document, press: Press) -> Result<bool, GraphError> {
        let base = doc.base_dir();
        if let GestureKind::Stroke(s) = &mut self.kind {
            let n = s.points.len();
            let closes = s.op == "pen"
                && s.mode == StrokeMode::Replace
                && n >= 4
                && dist(s.points[0], s.points[n - 1]) <= press.tol_px;
            if closes {
                s.points.pop();
                s.closed = true;
            }
            s.write(&mut doc.graph, &base)?;
        }
        let changed = doc.graph != self.before;
        if changed {
            doc.history.commit(self.before);
        }
        Ok(changed)
    }

    /// Abandons the gesture: the graph goes back to how it was before it.
    pub fn cancel(self, doc: &mut Document) {
        doc.graph = self.before;
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::*;

    #[test]
    fn cancel_restores_the_graph() {
        let mut d = demo();
        let g0 = d.graph.clone();
        let viewed = (3, "image".to_string());
        let mut gest =
            Gesture::stroke(&d, &pen_tools(), None, Some(&viewed), press([0.0, 0.0])).unwrap();
        gest.update(
            &mut d.graph,
            [10.0, 0.0],
            press([10.0, 0.0]),
            false,
            true,
            &base(),
        )
        .unwrap();
        assert_ne!(d.graph, g0);
        gest.cancel(&mut d);
        assert_eq!(d.graph, g0);
        assert_eq!(d.history.undo_len(), 0);
    }
}
