//! Pen and brush strokes (they share the stroke code; the brush adds its radius and feather).
//!
//! A pen node holds a list of paths: a stroke extends one of them (from one of its ends),
//! replaces the node's untouched default path, or is added as a new path of the selected pen
//! node — with the tool's width and height as its own where they differ from the node's. A new
//! pen node is made only when nothing pen is selected, or when asked ([`ToolState::pen_new_node`],
//! or Ctrl held at the press: [`Press::new_node`]).

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::coords::dist;
use super::gesture::{Gesture, GestureKind, Press};
use super::graph_edit::{has_own_points, insert_after, min_points, node_points, set};
use super::graph_edit::{param_f64, pen_paths, target, Target};
use super::{ToolKind, ToolState};
use crate::app::state::Document;
use crate::graph::{Graph, GraphError, NodeId};
use crate::params::{ParamValue, PathValue};
use std::collections::BTreeMap;
use std::path::Path;

/// How a stroke joins the node's existing points (a pen's: the points of the path it draws).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StrokeMode {
    /// The stroke is the whole list (a pen's: a new path, or the default path replaced).
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
    /// The node's points before the stroke (a pen's: those of the path it extends).
    pub base: Vec<[f64; 2]>,
    /// A pen's paths before the stroke (kept; empty for a new node or a default path).
    pub paths: Vec<PathValue>,
    /// Which of them the stroke draws (`paths.len()`: a new path).
    pub path_index: usize,
    /// A new pen path's own parameters (the tool's width and height where the node's differ).
    pub own: BTreeMap<String, ParamValue>,
    /// The stroke closes its new path (a pen stroke ending where it began).
    pub closed: bool,
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
        if self.op == "pen" {
            set(g, id, "paths", ParamValue::Paths(self.pen_paths(path)));
        } else {
            set(g, id, "points", ParamValue::Points(path));
        }
        Ok(())
    }

    /// The pen node's whole list of paths with this stroke's path `points`.
    fn pen_paths(&self, points: Vec<[f64; 2]>) -> Vec<PathValue> {
        let mut paths = self.paths.clone();
        match paths.get_mut(self.path_index) {
            Some(p) => p.points = points,
            None => paths.push(PathValue {
                points,
                closed: self.closed,
                params: self.own.clone(),
            }),
        }
        paths
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
            paths: Vec::new(),
            path_index: 0,
            own: BTreeMap::new(),
            closed: false,
            points: vec![press.at],
            brush: (tools.brush_radius_px, tools.brush_feather_px),
            pen: (tools.pen_width_px, tools.pen_height_px),
        };
        let new_node = op == "pen" && (tools.pen_new_node || press.new_node);
        match target(g, op, selected, viewed, &doc.base_dir())? {
            Target::Edit(id) if new_node => s.create_after = Some((id, "image".into())),
            Target::Edit(id) if !has_own_points(g, id) => s.node = Some(id),
            Target::Edit(id) if op == "pen" => s.pen_into(g, id, tools, press)?,
            Target::Edit(id) => {
                let base = node_points(g, id)?;
                let (first, last) = (*base.first()?, *base.last()?);
                s.mode = if press.extend || dist(press.at, last) <= press.tol_px {
                    StrokeMode::Append
                } else if dist(press.at, first) <= press.tol_px {
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

impl Stroke {
    /// A pen stroke into pen node `id`, which has paths of its own: it extends the open path
    /// whose end (or start) it begins at — the newest such, or the newest path's end with
    /// Shift — and is otherwise a new path of the node.
    fn pen_into(&mut self, g: &Graph, id: NodeId, tools: &ToolState, press: Press) -> Option<()> {
        let paths = pen_paths(g, id)?;
        let near = |q: Option<&[f64; 2]>| q.is_some_and(|q| dist(press.at, *q) <= press.tol_px);
        let open = |k: &usize| !paths[*k].closed;
        let newest = paths.len().checked_sub(1).filter(open);
        let hit = |end: fn(&PathValue) -> Option<&[f64; 2]>| {
            (0..paths.len())
                .rev()
                .filter(open)
                .find(|&k| near(end(&paths[k])))
        };
        let (mode, k) = if let (true, Some(k)) = (press.extend, newest) {
            (StrokeMode::Append, k)
        } else if let Some(k) = hit(|p| p.points.last()) {
            (StrokeMode::Append, k)
        } else if let Some(k) = hit(|p| p.points.first()) {
            (StrokeMode::Prepend, k)
        } else {
            // A separate path of the same node.
            (StrokeMode::Replace, paths.len())
        };
        self.node = Some(id);
        self.mode = mode;
        self.path_index = k;
        if let Some(p) = paths.get(k) {
            self.base = p.points.clone();
            self.points[0] = match mode {
                StrokeMode::Append => *p.points.last()?,
                _ => *p.points.first()?,
            };
        } else {
            // The tool's width and height, as the path's own where the node's differ.
            for (name, v) in [
                ("width_px", tools.pen_width_px),
                ("height_px", tools.pen_height_px),
            ] {
                if param_f64(g, id, name) != Some(v) {
                    self.own.insert(name.into(), ParamValue::Float(v));
                }
            }
        }
        self.paths = paths;
        Some(())
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
            g.nodes[&id].params["paths"],
            ParamValue::Paths(vec![PathValue::new(
                vec![[10.0, 10.0], [20.0, 10.0], [30.0, 15.0], [40.0, 30.0]],
                false
            )])
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
        // Elsewhere: a new path of the same pen node, the old path kept.
        let n = d.graph.nodes.len();
        let same = draw(
            &mut d,
            &tools,
            Some(pen),
            &viewed,
            &[[50.0, 50.0], [60.0, 50.0]],
        );
        assert_eq!(same, Some(pen));
        assert_eq!(d.graph.nodes.len(), n, "no new node");
        let paths = pen_paths(&d.graph, pen).unwrap();
        assert_eq!(paths.len(), 2);
        assert_eq!(paths[0].points.len(), 5, "old path kept");
        assert_eq!(
            paths[1],
            PathValue::new(vec![[50.0, 50.0], [60.0, 50.0]], false)
        );
        // A stroke from the new path's end extends it, not the first one.
        draw(
            &mut d,
            &tools,
            Some(pen),
            &viewed,
            &[[61.0, 51.0], [70.0, 60.0]],
        );
        let paths = pen_paths(&d.graph, pen).unwrap();
        assert_eq!(paths.len(), 2);
        assert_eq!(
            paths[1].points,
            vec![[50.0, 50.0], [60.0, 50.0], [70.0, 60.0]]
        );
        // Undo steps back stroke by stroke: the extension, then the new path.
        d.undo();
        assert_eq!(pen_paths(&d.graph, pen).unwrap()[1].points.len(), 2);
        d.undo();
        assert_eq!(
            pen_paths(&d.graph, pen).unwrap().len(),
            1,
            "the last path removed"
        );
        assert_eq!(node_points(&d.graph, pen).unwrap().len(), 5);
        d.undo();
        assert_eq!(node_points(&d.graph, pen).unwrap().len(), 3);
    }

    #[test]
    fn a_new_path_takes_the_tools_width_and_height_where_the_nodes_differ() {
        let mut d = demo();
        let viewed = (3, "image".to_string());
        let mut tools = pen_tools();
        let pen = draw(
            &mut d,
            &tools,
            Some(3),
            &viewed,
            &[[10.0, 10.0], [20.0, 10.0]],
        )
        .unwrap();
        tools.pen_height_px = -2.0;
        draw(
            &mut d,
            &tools,
            Some(pen),
            &viewed,
            &[[50.0, 50.0], [60.0, 50.0]],
        );
        let paths = pen_paths(&d.graph, pen).unwrap();
        assert!(paths[0].params.is_empty());
        assert_eq!(
            paths[1].params.clone().into_iter().collect::<Vec<_>>(),
            vec![("height_px".to_string(), ParamValue::Float(-2.0))],
            "the width is the node's; the height its own"
        );
        assert_eq!(
            param_f64(&d.graph, pen, "height_px"),
            Some(4.0),
            "node unchanged"
        );
        crate::graph::LoadedGraph::from_graph(d.graph.clone(), None, base()).unwrap();
    }

    #[test]
    fn the_new_node_toggle_or_ctrl_makes_a_new_pen_node() {
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
        let toggled = ToolState {
            pen_new_node: true,
            ..tools.clone()
        };
        let n = d.graph.nodes.len();
        let a = draw(
            &mut d,
            &toggled,
            Some(pen),
            &viewed,
            &[[50.0, 50.0], [60.0, 50.0]],
        )
        .unwrap();
        assert_ne!(a, pen);
        assert_eq!(d.graph.nodes.len(), n + 1);
        assert_eq!(
            d.graph.nodes[&a].inputs["image"],
            Source::Node(pen, "image".into())
        );
        assert_eq!(
            pen_paths(&d.graph, pen).unwrap().len(),
            1,
            "the selected pen unchanged"
        );
        // Ctrl at the press: the same for one stroke, even from the selected path's end.
        let mut p = press([60.0, 50.0]);
        p.new_node = true;
        let mut gest = Gesture::stroke(&d, &tools, Some(a), Some(&viewed), p).unwrap();
        gest.update(&mut d.graph, [70.0, 50.0], p, false, true, &base())
            .unwrap();
        let b = gest.node().unwrap();
        gest.finish(&mut d, p).unwrap();
        assert_ne!(b, a);
        assert_eq!(d.graph.nodes.len(), n + 2);
        assert_eq!(
            pen_paths(&d.graph, b).unwrap()[0].points,
            vec![[60.0, 50.0], [70.0, 50.0]]
        );
        d.undo();
        assert_eq!(d.graph.nodes.len(), n + 1);
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
            n.params["paths"],
            ParamValue::Paths(vec![PathValue::new(square[..4].to_vec(), true)]),
            "the untouched default path is replaced; the closing point dropped"
        );
        assert_eq!(d.history.undo_len(), steps + 1);
        // A second closed path in the same node; a stroke from a closed path's vertex is a
        // new path, not an extension.
        let tri = [[60.0, 10.0], [90.0, 10.0], [75.0, 40.0], [61.0, 11.0]];
        draw(&mut d, &pen_tools(), Some(pen), &viewed, &tri);
        draw(
            &mut d,
            &pen_tools(),
            Some(pen),
            &viewed,
            &[[40.0, 40.0], [50.0, 60.0]],
        );
        let paths = pen_paths(&d.graph, pen).unwrap();
        assert_eq!(paths.len(), 3);
        assert_eq!((&paths[1].points[..], paths[1].closed), (&tri[..3], true));
        // The node's width and height are not the tool's: the new paths carry the tool's.
        assert_eq!(paths[1].params["width_px"], ParamValue::Float(12.0));
        assert_eq!(paths[2].points, vec![[40.0, 40.0], [50.0, 60.0]]);
        crate::graph::LoadedGraph::from_graph(d.graph.clone(), None, base()).unwrap();
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
