//! The stamp tool: placement geometry, handles, click-to-place.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::coords::dist;
use super::gesture::{Gesture, GestureKind, Press};
use super::graph_edit::{has_own_points, insert_after, node_points, param_f64, set};
use super::graph_edit::{target, Target};
use super::DEFAULT_STAMP_SIDE;
use super::MIN_STAMP_SCALE;
use crate::app::state::Document;
use crate::graph::{Graph, GraphError, NodeId};
use crate::params::ParamValue;

/// Which part of a stamp placement is dragged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StampHandle {
    /// The placement itself (its centre follows the pointer, keeping the grab offset).
    Move {
        /// Index in `positions`.
        index: usize,
        /// Pointer minus centre at the grab.
        offset: [f64; 2],
    },
    /// The rotate handle (sets `angle_rad`).
    Rotate,
    /// The scale handle at the stamp's corner (sets `scale_x`, `scale_y`).
    Scale,
}

/// The geometry of one stamp placement, from the stamp node's parameters (see
/// [`crate::ops::stamp`]: `P = A s + t` in a y-up frame, `A = R(angle) · shear · diag(scale)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StampFrame {
    /// Centre `t` in image pixels `(x, row)`.
    pub centre: [f64; 2],
    /// Rotation, counter-clockwise on screen.
    pub angle_rad: f64,
    /// Scale along u and v.
    pub scale: [f64; 2],
    /// Shear.
    pub shear: f64,
    /// Stamp size in its pixels (width, height).
    pub size: [f64; 2],
}

impl StampFrame {
    /// The frame of placement `index` of stamp node `id`; `stamp_size` is the stamp input's
    /// size when known.
    #[must_use]
    pub fn of(g: &Graph, id: NodeId, index: usize, stamp_size: Option<[usize; 2]>) -> Option<Self> {
        let centre = *node_points(g, id)?.get(index)?;
        let f = |n| param_f64(g, id, n);
        let s = stamp_size.unwrap_or([DEFAULT_STAMP_SIDE; 2]);
        Some(Self {
            centre,
            angle_rad: f("angle_rad")?,
            scale: [f("scale_x")?, f("scale_y")?],
            shear: f("shear")?,
            size: [s[0] as f64, s[1] as f64],
        })
    }

    /// `Sh · S · s` (before the rotation), y-up.
    pub(super) fn sheared(&self, s: [f64; 2]) -> [f64; 2] {
        let (u, v) = (self.scale[0] * s[0], self.scale[1] * s[1]);
        [u + self.shear * v, v]
    }

    pub(super) fn rotate(a: f64, p: [f64; 2]) -> [f64; 2] {
        let (sn, c) = a.sin_cos();
        [c * p[0] - sn * p[1], sn * p[0] + c * p[1]]
    }

    /// Image pixel `(x, row)` of stamp coordinates `s = (u, v)` (y-up, centred).
    #[must_use]
    pub fn image_from_stamp(&self, s: [f64; 2]) -> [f64; 2] {
        let d = Self::rotate(self.angle_rad, self.sheared(s));
        [self.centre[0] + d[0], self.centre[1] - d[1]]
    }

    /// Offset of an image point from the centre in the y-up frame.
    pub(super) fn up(&self, p: [f64; 2]) -> [f64; 2] {
        [p[0] - self.centre[0], -(p[1] - self.centre[1])]
    }

    /// The outline: the stamp's four corners in image pixels (counter-clockwise in stamp space).
    #[must_use]
    pub fn corners(&self) -> [[f64; 2]; 4] {
        let (hw, hh) = (self.size[0] / 2.0, self.size[1] / 2.0);
        [[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]].map(|s| self.image_from_stamp(s))
    }

    /// The scale handle: the corner `(+w/2, +h/2)`.
    #[must_use]
    pub fn scale_handle(&self) -> [f64; 2] {
        self.image_from_stamp([self.size[0] / 2.0, self.size[1] / 2.0])
    }

    /// The rotate handle: `gap_px` beyond the middle of the `+u` edge.
    #[must_use]
    pub fn rotate_handle(&self, gap_px: f64) -> [f64; 2] {
        let edge = self.up(self.image_from_stamp([self.size[0] / 2.0, 0.0]));
        let len = edge[0].hypot(edge[1]).max(1e-9);
        let d = [
            edge[0] * (1.0 + gap_px / len),
            edge[1] * (1.0 + gap_px / len),
        ];
        [self.centre[0] + d[0], self.centre[1] - d[1]]
    }

    /// True when image point `p` lies inside the outline.
    #[must_use]
    pub fn contains(&self, p: [f64; 2]) -> bool {
        // Invert A: rotate back, then undo shear and scale.
        let q = Self::rotate(-self.angle_rad, self.up(p));
        let v = q[1] / self.scale[1];
        let u = (q[0] - self.shear * q[1]) / self.scale[0];
        u.abs() <= self.size[0] / 2.0 && v.abs() <= self.size[1] / 2.0
    }

    /// The rotation that puts the rotate handle (at `gap_px`) under the pointer `p`.
    #[must_use]
    pub fn angle_for(&self, p: [f64; 2], gap_px: f64) -> f64 {
        let h = self.up(self.rotate_handle(gap_px));
        let offset = h[1].atan2(h[0]) - self.angle_rad;
        let q = self.up(p);
        let a = q[1].atan2(q[0]) - offset;
        // Wrap to (−π, π].
        let t = std::f64::consts::TAU;
        a - t * ((a + std::f64::consts::PI) / t).ceil() + t
    }

    /// The scale `(scale_x, scale_y)` that puts the scale handle under the pointer `p`;
    /// `uniform` keeps the aspect ratio. Magnitudes are at least [`MIN_STAMP_SCALE`], signs
    /// (mirrors) follow the pointer.
    #[must_use]
    pub fn scale_for(&self, p: [f64; 2], uniform: bool) -> [f64; 2] {
        let q = Self::rotate(-self.angle_rad, self.up(p));
        let (hw, hh) = (self.size[0] / 2.0, self.size[1] / 2.0);
        let clamp = |s: f64| {
            if s.abs() < MIN_STAMP_SCALE {
                MIN_STAMP_SCALE.copysign(if s == 0.0 { 1.0 } else { s })
            } else {
                s
            }
        };
        if uniform {
            let c = self.sheared([hw, hh]);
            let f = (q[0] * c[0] + q[1] * c[1]) / (c[0] * c[0] + c[1] * c[1]).max(1e-12);
            let f = f.max(MIN_STAMP_SCALE / self.scale[0].abs().min(self.scale[1].abs()));
            return [clamp(self.scale[0] * f), clamp(self.scale[1] * f)];
        }
        let sy = clamp(q[1] / hh);
        let sx = clamp((q[0] - self.shear * sy * hh) / hw);
        [sx, sy]
    }
}

impl Gesture {
    /// Starts dragging a handle or placement of the selected stamp node, if `press` hits one
    /// (handles first, then the topmost placement).
    #[must_use]
    pub fn stamp(
        doc: &Document,
        selected: Option<NodeId>,
        stamp_size: Option<[usize; 2]>,
        press: Press,
    ) -> Option<Self> {
        let id = selected.filter(|s| doc.graph.nodes.get(s).is_some_and(|n| n.op == "stamp"))?;
        let n = node_points(&doc.graph, id)?.len();
        let frame = StampFrame::of(&doc.graph, id, n.checked_sub(1)?, stamp_size)?;
        let handle = if dist(frame.rotate_handle(press.gap_px), press.at) <= press.tol_px {
            StampHandle::Rotate
        } else if dist(frame.scale_handle(), press.at) <= press.tol_px {
            StampHandle::Scale
        } else {
            let index = (0..n).rev().find(|i| {
                StampFrame::of(&doc.graph, id, *i, stamp_size).is_some_and(|f| f.contains(press.at))
            })?;
            let c = node_points(&doc.graph, id)?[index];
            StampHandle::Move {
                index,
                offset: [press.at[0] - c[0], press.at[1] - c[1]],
            }
        };
        Some(Self {
            before: doc.graph.clone(),
            kind: GestureKind::Stamp {
                node: id,
                handle,
                frame,
            },
        })
    }
}

/// A click with the stamp tool: adds a placement at `at` to the selected stamp node (replacing
/// its untouched default placement), or inserts a new stamp node after the viewed output. One
/// undo step; returns the stamp node.
pub fn place_stamp(
    doc: &mut Document,
    selected: Option<NodeId>,
    viewed: Option<&(NodeId, String)>,
    at: [f64; 2],
) -> Result<Option<NodeId>, GraphError> {
    let base = doc.base_dir();
    let before = doc.graph.clone();
    let g = &mut doc.graph;
    let id = match target(g, "stamp", selected, viewed, &base) {
        None => return Ok(None),
        Some(Target::Edit(id)) => id,
        Some(Target::After(after, port)) => insert_after(g, "stamp", after, &port, &base)?,
    };
    let mut pts = if has_own_points(g, id) {
        node_points(g, id).unwrap_or_default()
    } else {
        Vec::new()
    };
    pts.push(at);
    set(g, id, "positions", ParamValue::Points(pts));
    doc.history.commit(before);
    Ok(Some(id))
}
/// Drags `handle` of the stamp node `node` (grabbed on `frame`) to image position `p`:
/// moves the placement, or sets the angle or the scale. True if the node's parameters changed.
pub(super) fn drag_handle(
    g: &mut Graph,
    node: NodeId,
    handle: StampHandle,
    frame: &StampFrame,
    p: [f64; 2],
    gap_px: f64,
    uniform: bool,
) -> bool {
    let before = g.nodes.get(&node).map(|n| n.params.clone());
    match handle {
        StampHandle::Move { index, offset } => {
            let mut pts = node_points(g, node).unwrap_or_default();
            if let Some(q) = pts.get_mut(index) {
                *q = [p[0] - offset[0], p[1] - offset[1]];
            }
            set(g, node, "positions", ParamValue::Points(pts));
        }
        StampHandle::Rotate => {
            let a = frame.angle_for(p, gap_px);
            set(g, node, "angle_rad", ParamValue::Float(a));
        }
        StampHandle::Scale => {
            let [sx, sy] = frame.scale_for(p, uniform);
            set(g, node, "scale_x", ParamValue::Float(sx));
            set(g, node, "scale_y", ParamValue::Float(sy));
        }
    }
    g.nodes.get(&node).map(|n| n.params.clone()) != before
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::graph::Source;

    #[test]
    fn stamp_frame_matches_the_operators_affine_map() {
        // Against the operator's own A (stamp.rs), for a sheared, scaled, rotated frame.
        let f = StampFrame {
            centre: [50.0, 40.0],
            angle_rad: 0.7,
            scale: [1.5, -0.8],
            shear: 0.3,
            size: [20.0, 10.0],
        };
        let a = crate::ops::stamp::StampParams {
            scale_x: 1.5,
            scale_y: -0.8,
            angle_rad: 0.7,
            shear: 0.3,
            ..Default::default()
        }
        .affine();
        for s in [[3.0, -2.0], [12.0, 1.0], [-7.5, 1.0], [0.0, -6.0]] {
            let p = f.image_from_stamp(s);
            let up = [
                a[0][0] * s[0] + a[0][1] * s[1],
                a[1][0] * s[0] + a[1][1] * s[1],
            ];
            let want = [50.0 + up[0], 40.0 - up[1]];
            assert!(close(p, want, 1e-4), "{p:?} {want:?}");
            assert!(f.contains(p) == (s[0].abs() <= 10.0 && s[1].abs() <= 5.0));
        }
        // Unrotated, unit scale: the +u edge is to the right, +v up (towards row 0).
        let g = StampFrame {
            angle_rad: 0.0,
            scale: [1.0, 1.0],
            shear: 0.0,
            ..f
        };
        assert_eq!(g.scale_handle(), [60.0, 35.0]);
        assert_eq!(g.rotate_handle(6.0), [66.0, 40.0]);
        assert_eq!(g.corners()[0], [40.0, 45.0]);
    }

    #[test]
    fn rotate_and_scale_handles_follow_the_pointer() {
        let f = StampFrame {
            centre: [50.0, 40.0],
            angle_rad: 0.2,
            scale: [1.0, 2.0],
            shear: 0.25,
            size: [20.0, 10.0],
        };
        // Pointer straight above the centre: the rotate handle (on +u) points up → +90°.
        let a = f.angle_for([50.0, 10.0], 6.0);
        assert!((a - std::f64::consts::FRAC_PI_2).abs() < 1e-9, "{a}");
        // Below-left: wraps into (−π, π].
        let a = f.angle_for([40.0, 50.0], 6.0);
        assert!((a + 3.0 * std::f64::consts::FRAC_PI_4).abs() < 1e-9, "{a}");
        // Dragging the scale handle to a point puts the new handle exactly there.
        for target in [[70.0, 20.0], [45.0, 60.0]] {
            let [sx, sy] = f.scale_for(target, false);
            let g = StampFrame {
                scale: [sx, sy],
                ..f
            };
            assert!(
                close(g.scale_handle(), target, 1e-9),
                "{:?}",
                g.scale_handle()
            );
        }
        // Uniform: the aspect ratio is kept; the handle moving outwards by ×1.5 scales ×1.5.
        let h = f.scale_handle();
        let out = [50.0 + 1.5 * (h[0] - 50.0), 40.0 + 1.5 * (h[1] - 40.0)];
        let [sx, sy] = f.scale_for(out, true);
        assert!(
            (sx - 1.5).abs() < 1e-9 && (sy - 3.0).abs() < 1e-9,
            "{sx} {sy}"
        );
        // Through the centre: clamped away from a singular map.
        let [sx, sy] = f.scale_for([50.0, 40.0], false);
        assert!(sx.abs() >= MIN_STAMP_SCALE && sy.abs() >= MIN_STAMP_SCALE);
    }

    #[test]
    fn stamp_clicks_place_and_handles_rotate_scale_and_move() {
        let mut d = demo();
        let g0 = d.graph.clone();
        let viewed = (3, "image".to_string());
        let st = place_stamp(&mut d, None, Some(&viewed), [100.0, 100.0])
            .unwrap()
            .unwrap();
        assert_eq!(d.graph.nodes[&st].op, "stamp");
        assert_eq!(
            d.graph.nodes[&st].params["positions"],
            ParamValue::Points(vec![[100.0, 100.0]])
        );
        // The new stamp reads a small surface as its stamp; the graph is valid.
        let Source::Node(src, _) = &d.graph.nodes[&st].inputs["stamp"] else {
            panic!("stamp input")
        };
        assert_eq!(d.graph.nodes[src].op, "surface");
        crate::graph::LoadedGraph::from_graph(d.graph.clone(), None, base()).unwrap();
        place_stamp(&mut d, Some(st), Some(&viewed), [200.0, 150.0]).unwrap();
        assert_eq!(node_points(&d.graph, st).unwrap().len(), 2);
        assert_eq!(d.history.undo_len(), 2);

        // Rotate via the handle of the last placement (32 px stamp, unit scale).
        let size = Some([32, 32]);
        let f = StampFrame::of(&d.graph, st, 1, size).unwrap();
        let h = f.rotate_handle(6.0);
        assert_eq!(h, [222.0, 150.0]);
        let mut gest = Gesture::stamp(&d, Some(st), size, press(h)).unwrap();
        let up = [200.0, 120.0];
        gest.update(&mut d.graph, up, press(up), false, true, &base())
            .unwrap();
        gest.finish(&mut d, press(up)).unwrap();
        let a = param_f64(&d.graph, st, "angle_rad").unwrap();
        assert!((a - std::f64::consts::FRAC_PI_2).abs() < 1e-9);

        // Scale via the corner handle (now rotated by 90°).
        let f = StampFrame::of(&d.graph, st, 1, size).unwrap();
        let h = f.scale_handle();
        let mut gest = Gesture::stamp(&d, Some(st), size, press(h)).unwrap();
        assert!(matches!(
            gest.kind,
            GestureKind::Stamp {
                handle: StampHandle::Scale,
                ..
            }
        ));
        let to = [200.0 + 2.0 * (h[0] - 200.0), 150.0 + 2.0 * (h[1] - 150.0)];
        gest.update(&mut d.graph, to, press(to), true, true, &base())
            .unwrap();
        gest.finish(&mut d, press(to)).unwrap();
        assert!((param_f64(&d.graph, st, "scale_x").unwrap() - 2.0).abs() < 1e-9);
        assert!((param_f64(&d.graph, st, "scale_y").unwrap() - 2.0).abs() < 1e-9);

        // Move the first placement by grabbing it off-centre.
        let mut gest = Gesture::stamp(&d, Some(st), size, press([105.0, 95.0])).unwrap();
        gest.update(
            &mut d.graph,
            [125.0, 95.0],
            press([125.0, 95.0]),
            false,
            true,
            &base(),
        )
        .unwrap();
        gest.finish(&mut d, press([125.0, 95.0])).unwrap();
        assert_eq!(node_points(&d.graph, st).unwrap()[0], [120.0, 100.0]);
        assert_eq!(d.history.undo_len(), 5);
        // A press on empty image is not a stamp drag (the click places instead).
        assert!(Gesture::stamp(&d, Some(st), size, press([400.0, 400.0])).is_none());
        while d.undo() {}
        assert_eq!(d.graph, g0);
    }
}
