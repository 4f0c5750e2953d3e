//! Dragging and deleting the vertices of a pen, brush or stamp node's point list.

use super::coords::hit_vertex;
use super::gesture::{Gesture, GestureKind, Press};
use super::graph_edit::{
    locate_vertex, min_path_points, min_points, node_points, pen_paths, points_param, set,
};
use crate::app::state::Document;
use crate::graph::{Graph, NodeId};
use crate::params::ParamValue;

impl Gesture {
    /// Starts dragging a vertex of the selected node (pen/brush/stamp), if `press` hits one.
    #[must_use]
    pub fn vertex(doc: &Document, selected: Option<NodeId>, press: Press) -> Option<Self> {
        let id = selected?;
        let pts = node_points(&doc.graph, id)?;
        let index = hit_vertex(&pts, press.at, press.tol_px)?;
        Some(Self {
            before: doc.graph.clone(),
            kind: GestureKind::Vertex { node: id, index },
        })
    }
}

/// Removes vertex `index` of the node's point list if enough points remain (one undo step);
/// true if removed.
pub fn delete_vertex(doc: &mut Document, node: NodeId, index: usize) -> bool {
    let Some(n) = doc.graph.nodes.get(&node) else {
        return false;
    };
    let (op, Some(name)) = (n.op.clone(), points_param(&n.op)) else {
        return false;
    };
    if op == "pen" {
        // The vertex of one of the paths; each path keeps what it needs.
        let mut paths = pen_paths(&doc.graph, node).unwrap_or_default();
        let Some((k, i)) = locate_vertex(&paths, index) else {
            return false;
        };
        if paths[k].points.len() <= min_path_points(&paths[k]) {
            return false;
        }
        paths[k].points.remove(i);
        doc.set_param(node, name, ParamValue::Paths(paths));
        return true;
    }
    let mut pts = node_points(&doc.graph, node).unwrap_or_default();
    if index >= pts.len() || pts.len() <= min_points(&op) {
        return false;
    }
    pts.remove(index);
    doc.set_param(node, name, ParamValue::Points(pts));
    true
}
/// Moves vertex `index` of `node`'s point list to `p`; true if it moved.
pub(super) fn drag_vertex(g: &mut Graph, node: NodeId, index: usize, p: [f64; 2]) -> bool {
    if g.nodes.get(&node).is_some_and(|n| n.op == "pen") {
        let mut paths = pen_paths(g, node).unwrap_or_default();
        let Some((k, i)) = locate_vertex(&paths, index) else {
            return false;
        };
        if paths[k].points[i] == p {
            return false;
        }
        paths[k].points[i] = p;
        set(g, node, "paths", ParamValue::Paths(paths));
        return true;
    }
    let mut pts = node_points(g, node).unwrap_or_default();
    match pts.get_mut(index) {
        Some(q) if *q != p => {
            *q = p;
            let name = points_param(&g.nodes[&node].op).unwrap_or("points");
            set(g, node, name, ParamValue::Points(pts));
            true
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::*;

    #[test]
    fn vertices_are_hit_dragged_and_deleted_one_step_each() {
        let pts = [[0.0, 0.0], [10.0, 0.0], [10.5, 0.5]];
        assert_eq!(hit_vertex(&pts, [9.0, 0.0], 2.0), Some(1));
        assert_eq!(hit_vertex(&pts, [10.4, 0.3], 2.0), Some(2), "the nearest");
        assert_eq!(hit_vertex(&pts, [5.0, 0.0], 2.0), None);

        let mut d = demo();
        let viewed = (3, "image".to_string());
        let pen = draw(
            &mut d,
            &pen_tools(),
            None,
            &viewed,
            &[[0.0, 0.0], [20.0, 0.0], [40.0, 0.0]],
        )
        .unwrap();
        let g1 = d.graph.clone();
        assert!(Gesture::vertex(&d, Some(pen), press([30.0, 0.0])).is_none());
        let mut gest = Gesture::vertex(&d, Some(pen), press([21.0, 1.0])).unwrap();
        for p in [[22.0, 5.0], [25.0, 12.0]] {
            assert!(gest
                .update(&mut d.graph, p, press(p), false, true, &base())
                .unwrap());
        }
        gest.finish(&mut d, press([25.0, 12.0])).unwrap();
        assert_eq!(
            node_points(&d.graph, pen).unwrap(),
            vec![[0.0, 0.0], [25.0, 12.0], [40.0, 0.0]]
        );
        let g2 = d.graph.clone();
        assert!(delete_vertex(&mut d, pen, 1));
        assert_eq!(node_points(&d.graph, pen).unwrap().len(), 2);
        assert!(
            !delete_vertex(&mut d, pen, 0),
            "a pen path keeps two points"
        );
        d.undo();
        assert_eq!(d.graph, g2);
        d.undo();
        assert_eq!(d.graph, g1);
    }
}
