//! Pen and brush strokes (they share the stroke code; the brush adds its radius and feather).

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::coords::dist;
use super::gesture::{Gesture, GestureKind, Press};
use super::graph_edit::{has_own_points, insert_after, min_points, node_points, param, set};
use super::graph_edit::{target, Target};
use super::{ToolKind, ToolState};
use crate::app::state::Document;
use crate::graph::{Graph, GraphError, NodeId};
use crate::params::ParamValue;
use std::path::Path;

/// How a stroke joins the node's existing points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StrokeMode {
    /// The stroke is the whole list.
    Replace,
    /// The stroke continues the list from its last point.
    Append,
    /// The stroke continues the list from its first point (the list is prepended, reversed).
    Prepend,
}

/// A pen or brush stroke in progress.
#[derive(Clone, Debug, PartialEq)]
pub struct Stroke {
    /// `"pen"` or `"brush"`.
    pub op: &'static str,
    /// The node drawn into (`None` until it is created on the first write).
    pub node: Option<NodeId>,
    /// Where a new node goes.
    pub create_after: Option<(NodeId, String)>,
    /// How the stroke joins the existing points.
    pub mode: StrokeMode,
    /// The node's points before the stroke.
    pub base: Vec<[f64; 2]>,
    /// The stroke's points in drawing order (simplified).
    pub points: Vec<[f64; 2]>,
    /// Brush radius and feather for a new brush node.
    pub brush: (f64, f64),
    /// Width and height for a new pen node.
    pub pen: (f64, f64),
}

impl Stroke {
    /// The node's whole point list with this stroke.
    #[must_use]
    pub fn path(&self) -> Vec<[f64; 2]> {
        match self.mode {
            StrokeMode::Replace => self.points.clone(),
            StrokeMode::Append => {
                let mut p = self.base.clone();
                p.extend(self.points.iter().skip(1));
                p
            }
            StrokeMode::Prepend => {
                let mut p: Vec<[f64; 2]> = self.points.iter().skip(1).rev().copied().collect();
                p.extend(&self.base);
                p
            }
        }
    }

    pub(super) fn write(&mut self, g: &mut Graph, base_dir: &Path) -> Result<(), GraphError> {
        let path = self.path();
        if path.len() < min_points(self.op) || path.len() == self.base.len() {
            return Ok(());
        }
        let id = match (self.node, &self.create_after) {
            (Some(id), _) => id,
            (None, Some((after, port))) => {
                let id = insert_after(g, self.op, *after, port, base_dir)?;
                if self.op == "brush" {
                    set(g, id, "radius_px", ParamValue::Float(self.brush.0));
                    set(g, id, "feather_px", ParamValue::Float(self.brush.1));
                } else {
                    set(g, id, "width_px", ParamValue::Float(self.pen.0));
                    set(g, id, "height_px", ParamValue::Float(self.pen.1));
                }
                self.node = Some(id);
                id
            }
            (None, None) => return Ok(()),
        };
        set(g, id, "points", ParamValue::Points(path));
        Ok(())
    }
}

impl Gesture {
    /// Starts a pen or brush stroke at `press` (nothing changes in the graph until the stroke
    /// has enough points; see [`Gesture::update`]).
    #[must_use]
    pub fn stroke(
        doc: &Document,
        tools: &ToolState,
        selected: Option<NodeId>,
        viewed: Option<&(NodeId, String)>,
        press: Press,
    ) -> Option<Self> {
        let op = match tools.kind {
            ToolKind::Pen => "pen",
            ToolKind::Brush => "brush",
            _ => return None,
        };
        let g = &doc.graph;
        let mut s = Stroke {
            op,
            node: None,
            create_after: None,
            mode: StrokeMode::Replace,
            base: Vec::new(),
            points: vec![press.at],
            brush: (tools.brush_radius_px, tools.brush_feather_px),
            pen: (tools.pen_width_px, tools.pen_height_px),
        };
        match target(g, op, selected, viewed, &doc.base_dir())? {
            Target::Edit(id) if !has_own_points(g, id) => s.node = Some(id),
            Target::Edit(id) => {
                let base = node_points(g, id)?;
                let (first, last) = (*base.first()?, *base.last()?);
                let closed = op == "pen" && param(g, id, "closed") == Some(ParamValue::Bool(true));
                s.mode = if press.extend || (!closed && dist(press.at, last) <= press.tol_px) {
                    StrokeMode::Append
                } else if !closed && dist(press.at, first) <= press.tol_px {
                    StrokeMode::Prepend
                } else {
                    // A separate path: a new node after this one.
                    s.create_after = Some((id, "image".into()));
                    StrokeMode::Replace
                };
                if s.mode == StrokeMode::Replace {
                    s.base.clear();
                } else {
                    s.node = Some(id);
                    s.points[0] = if s.mode == StrokeMode::Append {
                        last
                    } else {
                        first
                    };
                    s.base = base;
                }
            }
            Target::After(id, port) => s.create_after = Some((id, port)),
        }
        Some(Self {
            before: doc.graph.clone(),
            kind: GestureKind::Stroke(s),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::graph::Source;

    #[test]
    fn a_pen_stroke_inserts_a_pen_after_the_viewed_node_as_one_undo_step() {
        let mut d = demo();
        let g0 = d.graph.clone();
        let viewed = (3, "image".to_string());
        let pts = [
            [10.0, 10.0],
            [10.5, 10.2],
            [20.0, 10.0],
            [30.0, 15.0],
            [40.0, 30.0],
        ];
        let id = draw(&mut d, &pen_tools(), Some(3), &viewed, &pts).unwrap();
        let g = &d.graph;
        assert_eq!(g.nodes[&id].op, "pen");
        // The point closer than 1.5 px was dropped.
        assert_eq!(
            g.nodes[&id].params["points"],
            ParamValue::Points(vec![[10.0, 10.0], [20.0, 10.0], [30.0, 15.0], [40.0, 30.0]])
        );
        // With the tool's width and height.
        assert_eq!(g.nodes[&id].params["width_px"], ParamValue::Float(12.0));
        assert_eq!(g.nodes[&id].params["height_px"], ParamValue::Float(4.0));
        // Below the other nodes in the graph view.
        assert!(g
            .nodes
            .values()
            .all(|n| n.id == id || n.pos[1] < g.nodes[&id].pos[1]));
        // Wired into the data flow: reads the viewed node; its readers and the graph's
        // "image" output now read the pen.
        assert_eq!(
            g.nodes[&id].inputs["image"],
            Source::Node(3, "image".into())
        );
        for reader in [4, 5, 6] {
            assert_eq!(
                g.nodes[&reader].inputs["image"],
                Source::Node(id, "image".into())
            );
        }
        assert_eq!(g.outputs["image"].node, id);
        // The edited graph is valid as a whole.
        crate::graph::LoadedGraph::from_graph(g.clone(), None, base()).unwrap();
        assert_eq!(d.history.undo_len(), 1, "one stroke, one step");
        assert!(d.undo());
        assert_eq!(d.graph, g0, "undo restores the graph exactly");
    }

    #[test]
    fn strokes_extend_a_selected_pen_at_either_end_or_start_a_new_one() {
        let mut d = demo();
        let viewed = (3, "image".to_string());
        let tools = pen_tools();
        let pen = draw(
            &mut d,
            &tools,
            Some(3),
            &viewed,
            &[[10.0, 10.0], [20.0, 10.0]],
        )
        .unwrap();
        // From near the last point: appended (the press snaps to the end point).
        let same = draw(
            &mut d,
            &tools,
            Some(pen),
            &viewed,
            &[[21.0, 11.0], [30.0, 20.0]],
        );
        assert_eq!(same, Some(pen));
        assert_eq!(
            node_points(&d.graph, pen).unwrap(),
            vec![[10.0, 10.0], [20.0, 10.0], [30.0, 20.0]]
        );
        // From near the first point: prepended, reversed.
        draw(
            &mut d,
            &tools,
            Some(pen),
            &viewed,
            &[[9.0, 9.0], [0.0, 5.0], [0.0, 0.0]],
        );
        assert_eq!(
            node_points(&d.graph, pen).unwrap(),
            vec![
                [0.0, 0.0],
                [0.0, 5.0],
                [10.0, 10.0],
                [20.0, 10.0],
                [30.0, 20.0]
            ]
        );
        assert_eq!(d.history.undo_len(), 3);
        // Elsewhere: a new pen after this one.
        let n = d.graph.nodes.len();
        let other = draw(
            &mut d,
            &tools,
            Some(pen),
            &viewed,
            &[[50.0, 50.0], [60.0, 50.0]],
        );
        let other = other.unwrap();
        assert_ne!(other, pen);
        assert_eq!(d.graph.nodes.len(), n + 1);
        assert_eq!(
            d.graph.nodes[&other].inputs["image"],
            Source::Node(pen, "image".into())
        );
        assert_eq!(
            node_points(&d.graph, pen).unwrap().len(),
            5,
            "old path kept"
        );
        // Undo steps back stroke by stroke.
        d.undo();
        assert_eq!(node_points(&d.graph, pen).unwrap().len(), 5);
        assert!(!d.graph.nodes.contains_key(&other));
        d.undo();
        assert_eq!(node_points(&d.graph, pen).unwrap().len(), 3);
    }

    #[test]
    fn a_stroke_ending_at_its_start_closes_the_path_and_a_default_path_is_replaced() {
        let mut d = demo();
        let pen = d.add_node("pen", [0.0, 0.0]);
        d.connect(3, "image", pen, "image").unwrap();
        let steps = d.history.undo_len();
        let viewed = (pen, "image".to_string());
        let square = [
            [10.0, 10.0],
            [40.0, 10.0],
            [40.0, 40.0],
            [10.0, 40.0],
            [11.0, 12.0],
        ];
        draw(&mut d, &pen_tools(), Some(pen), &viewed, &square);
        let n = &d.graph.nodes[&pen];
        assert_eq!(
            n.params["points"],
            ParamValue::Points(square[..4].to_vec()),
            "the untouched default path is replaced; the closing point dropped"
        );
        assert_eq!(n.params["closed"], ParamValue::Bool(true));
        assert_eq!(d.history.undo_len(), steps + 1);
    }

    #[test]
    fn nothing_is_written_before_a_pen_path_has_two_points() {
        let mut d = demo();
        let g0 = d.graph.clone();
        let viewed = (3, "image".to_string());
        let mut gest =
            Gesture::stroke(&d, &pen_tools(), None, Some(&viewed), press([5.0, 5.0])).unwrap();
        gest.update(
            &mut d.graph,
            [5.5, 5.0],
            press([5.5, 5.0]),
            false,
            true,
            &base(),
        )
        .unwrap();
        assert_eq!(d.graph, g0);
        assert!(!gest.finish(&mut d, press([5.5, 5.0])).unwrap());
        assert_eq!(d.graph, g0);
        assert_eq!(d.history.undo_len(), 0);
    }

    #[test]
    fn a_stroke_not_written_live_reaches_the_graph_at_its_end() {
        let mut d = demo();
        let g0 = d.graph.clone();
        let viewed = (3, "image".to_string());
        let mut gest =
            Gesture::stroke(&d, &pen_tools(), None, Some(&viewed), press([5.0, 5.0])).unwrap();
        for x in [10.0, 20.0, 30.0] {
            let changed = gest
                .update(
                    &mut d.graph,
                    [x, 5.0],
                    press([x, 5.0]),
                    false,
                    false,
                    &base(),
                )
                .unwrap();
            assert!(changed);
        }
        assert_eq!(d.graph, g0, "not live: untouched while drawing");
        assert!(gest.finish(&mut d, press([30.0, 5.0])).unwrap());
        let pen = *d.graph.nodes.keys().next_back().unwrap();
        assert_eq!(node_points(&d.graph, pen).unwrap().len(), 4);
    }

    #[test]
    fn brush_strokes_set_points_and_radius() {
        let mut d = demo();
        let tools = ToolState {
            kind: ToolKind::Brush,
            brush_radius_px: 20.0,
            brush_feather_px: 3.0,
            ..ToolState::default()
        };
        let viewed = (2, "image".to_string());
        // A single dab is a valid brush stroke.
        let mut gest = Gesture::stroke(&d, &tools, None, Some(&viewed), press([8.0, 9.0])).unwrap();
        gest.update(
            &mut d.graph,
            [8.2, 9.0],
            press([8.2, 9.0]),
            false,
            true,
            &base(),
        )
        .unwrap();
        gest.finish(&mut d, press([8.2, 9.0])).unwrap();
        let b = *d.graph.nodes.keys().next_back().unwrap();
        let n = &d.graph.nodes[&b];
        assert_eq!(n.op, "brush");
        assert_eq!(n.params["points"], ParamValue::Points(vec![[8.0, 9.0]]));
        assert_eq!(n.params["radius_px"], ParamValue::Float(20.0));
        assert_eq!(n.params["feather_px"], ParamValue::Float(3.0));
        // Inserted between 2 and its reader 3.
        assert_eq!(
            d.graph.nodes[&3].inputs["image"],
            Source::Node(b, "image".into())
        );
        // Shift extends from the end wherever the press is; the radius of the node is kept.
        let mut p = press([50.0, 50.0]);
        p.extend = true;
        let t2 = ToolState {
            brush_radius_px: 5.0,
            ..tools
        };
        let mut gest = Gesture::stroke(&d, &t2, Some(b), Some(&viewed), p).unwrap();
        gest.update(&mut d.graph, [60.0, 50.0], p, false, true, &base())
            .unwrap();
        gest.finish(&mut d, p).unwrap();
        assert_eq!(
            node_points(&d.graph, b).unwrap(),
            vec![[8.0, 9.0], [60.0, 50.0]]
        );
        assert_eq!(param_f64(&d.graph, b, "radius_px"), Some(20.0));
        crate::graph::LoadedGraph::from_graph(d.graph.clone(), None, base()).unwrap();
    }
}
