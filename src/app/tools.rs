//! On-image tools, free of egui: the mapping from pointer gestures on the preview to graph
//! parameters. The egui side ([`super::tools_ui`]) only turns pointer events into calls here
//! and draws overlays; everything that decides what a gesture does to the graph is here and
//! unit-tested without a window.
//!
//! - **Pen**: a drag draws a path in image pixels (`pen.points`). It extends the selected pen
//!   node's path when it starts at one of the path's ends (or with Shift), replaces a pen node's
//!   untouched default path, and otherwise creates a new pen node.
//! - **Brush**: the same for the filter brush's stroke (`brush.points`, `radius_px`).
//! - **Stamp**: a click adds a placement (`stamp.positions`); dragging a placement moves it,
//!   dragging the rotate handle sets `angle_rad`, the scale handle `scale_x`/`scale_y`.
//! - **Vertices**: drag any vertex of the selected pen/brush/stamp node.
//!
//! A new node is inserted after the viewed node: it takes the viewed output as its `image` input,
//! and the nodes and graph outputs that read that output read the new node instead (so the
//! result includes the stroke); the new node is selected and viewed. Each gesture is one undo
//! step ([`Gesture::finish`]); while it runs the graph is updated as it goes (when
//! [`ToolState::live`]), so the worker re-evaluates the edited node and its descendants only.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::state::Document;
use crate::graph::{Graph, GraphError, NodeId, Source};
use crate::ops::params::ParamValue;
use crate::ops::PortType;
use std::path::Path;

/// Stroke points closer than this (image pixels) to the previous one are dropped.
pub const MIN_SPACING_PX: f64 = 1.5;
/// Pick radius of vertices and handles, in screen points.
pub const PICK_RADIUS_PT: f32 = 7.0;
/// Distance of the rotate handle beyond the stamp's edge, in screen points.
pub const ROTATE_HANDLE_GAP_PT: f32 = 18.0;
/// Smallest stamp scale magnitude a handle drag sets (keeps the map invertible).
pub const MIN_STAMP_SCALE: f64 = 0.02;
/// Stamp side assumed when the stamp input has not been evaluated yet.
pub const DEFAULT_STAMP_SIDE: usize = 32;

/// The active tool.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToolKind {
    /// No tool: drag pans, as without tools.
    #[default]
    Pan,
    /// Draw pen paths.
    Pen,
    /// Place, move, rotate and scale stamps.
    Stamp,
    /// Paint the filter brush's region.
    Brush,
    /// Move vertices of the selected node's path, stroke or placements.
    Vertices,
}

impl ToolKind {
    /// All tools in toolbar order.
    pub const ALL: [ToolKind; 5] = [
        ToolKind::Pan,
        ToolKind::Pen,
        ToolKind::Stamp,
        ToolKind::Brush,
        ToolKind::Vertices,
    ];

    /// Toolbar label.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ToolKind::Pan => "Pan",
            ToolKind::Pen => "Pen",
            ToolKind::Stamp => "Stamp",
            ToolKind::Brush => "Brush",
            ToolKind::Vertices => "Edit vertices",
        }
    }

    /// The operator this tool draws with.
    #[must_use]
    pub fn op(self) -> Option<&'static str> {
        match self {
            ToolKind::Pen => Some("pen"),
            ToolKind::Stamp => Some("stamp"),
            ToolKind::Brush => Some("brush"),
            ToolKind::Pan | ToolKind::Vertices => None,
        }
    }
}

/// Tool settings kept between gestures (not part of the graph).
#[derive(Clone, Debug, PartialEq)]
pub struct ToolState {
    /// The active tool.
    pub kind: ToolKind,
    /// Stroke width of new pen paths.
    pub pen_width_px: f64,
    /// Relief height of new pen paths (negative engraves).
    pub pen_height_px: f64,
    /// Radius of new brush strokes.
    pub brush_radius_px: f64,
    /// Feather of new brush strokes.
    pub brush_feather_px: f64,
    /// Push the parameter change to the graph while the gesture runs (the worker re-evaluates
    /// as fast as it can); otherwise only when it ends.
    pub live: bool,
}

impl Default for ToolState {
    fn default() -> Self {
        Self {
            kind: ToolKind::Pan,
            pen_width_px: 12.0,
            pen_height_px: 4.0,
            brush_radius_px: 12.0,
            brush_feather_px: 6.0,
            live: true,
        }
    }
}

/// Screen ↔ image mapping of the preview: the image's top-left corner on screen and the zoom
/// (screen points per image pixel). Pixel `(x, row)` is centred at integer coordinates (as the
/// operators sample), so its square spans `[x − ½, x + ½]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewTransform {
    /// Screen position of the image's top-left corner.
    pub origin: [f32; 2],
    /// Screen points per image pixel.
    pub zoom: f32,
}

impl ViewTransform {
    /// The mapping of the preview: panel `centre`, `pan` offset, image `size` in pixels, `zoom`.
    #[must_use]
    pub fn new(centre: [f32; 2], pan: [f32; 2], size: [f32; 2], zoom: f32) -> Self {
        Self {
            origin: [
                centre[0] + pan[0] - size[0] * zoom / 2.0,
                centre[1] + pan[1] - size[1] * zoom / 2.0,
            ],
            zoom,
        }
    }

    /// Image coordinates `(x, row)` of a screen position.
    #[must_use]
    pub fn image_from_screen(&self, s: [f32; 2]) -> [f64; 2] {
        [
            f64::from((s[0] - self.origin[0]) / self.zoom) - 0.5,
            f64::from((s[1] - self.origin[1]) / self.zoom) - 0.5,
        ]
    }

    /// Screen position of image coordinates `(x, row)`.
    #[must_use]
    pub fn screen_from_image(&self, p: [f64; 2]) -> [f32; 2] {
        [
            self.origin[0] + (p[0] as f32 + 0.5) * self.zoom,
            self.origin[1] + (p[1] as f32 + 0.5) * self.zoom,
        ]
    }

    /// A screen length in image pixels.
    #[must_use]
    pub fn px_from_pt(&self, len_pt: f32) -> f64 {
        f64::from(len_pt / self.zoom)
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Appends `p` unless it is closer than `min_px` to the last point; true if appended.
pub fn push_simplified(points: &mut Vec<[f64; 2]>, p: [f64; 2], min_px: f64) -> bool {
    if !(p[0].is_finite() && p[1].is_finite()) {
        return false;
    }
    match points.last() {
        Some(&last) if dist(last, p) < min_px => false,
        _ => {
            points.push(p);
            true
        }
    }
}

/// Index of the point nearest to `p` within `tol_px`, if any.
#[must_use]
pub fn hit_vertex(points: &[[f64; 2]], p: [f64; 2], tol_px: f64) -> Option<usize> {
    points
        .iter()
        .enumerate()
        .map(|(i, q)| (i, dist(*q, p)))
        .filter(|(_, d)| *d <= tol_px)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// The parameter holding a node's point list, by operator.
#[must_use]
pub fn points_param(op: &str) -> Option<&'static str> {
    match op {
        "pen" | "brush" => Some("points"),
        "stamp" => Some("positions"),
        _ => None,
    }
}

/// Fewest points a node's list must keep (a pen path needs two).
#[must_use]
pub fn min_points(op: &str) -> usize {
    if op == "pen" {
        2
    } else {
        1
    }
}

/// A node's parameter: its value in the graph, else the operator's default.
#[must_use]
pub fn param(g: &Graph, id: NodeId, name: &str) -> Option<ParamValue> {
    let n = g.nodes.get(&id)?;
    if let Some(v) = n.params.get(name) {
        return Some(v.clone());
    }
    let op = crate::ops::find(&n.op)?;
    op.params()
        .iter()
        .find(|p| p.name == name)
        .map(|p| p.default.clone())
}

/// A float parameter (see [`param`]).
#[must_use]
pub fn param_f64(g: &Graph, id: NodeId, name: &str) -> Option<f64> {
    match param(g, id, name)? {
        ParamValue::Float(v) => Some(v),
        ParamValue::Int(v) => Some(v as f64),
        _ => None,
    }
}

/// The point list of a pen, brush or stamp node (see [`points_param`]).
#[must_use]
pub fn node_points(g: &Graph, id: NodeId) -> Option<Vec<[f64; 2]>> {
    let name = points_param(&g.nodes.get(&id)?.op)?;
    match param(g, id, name)? {
        ParamValue::Points(p) => Some(p),
        _ => None,
    }
}

/// True when the node's point list was set (not the operator's placeholder default).
#[must_use]
pub fn has_own_points(g: &Graph, id: NodeId) -> bool {
    g.nodes
        .get(&id)
        .and_then(|n| Some(n.params.contains_key(points_param(&n.op)?)))
        .unwrap_or(false)
}

fn set(g: &mut Graph, id: NodeId, name: &str, v: ParamValue) {
    if let Some(n) = g.nodes.get_mut(&id) {
        n.params.insert(name.to_string(), v);
    }
}

/// Where a tool's gesture goes.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// Edit this node (the selected node is of the tool's operator).
    Edit(NodeId),
    /// Insert a new node after this RGBN output.
    After(NodeId, String),
}

/// The target of tool `op`: the selected node if it runs `op`, else a new node after the viewed
/// output (or, if that is not an RGBN image, after the RGBN image the viewed node reads).
pub fn target(
    g: &Graph,
    op: &str,
    selected: Option<NodeId>,
    viewed: Option<&(NodeId, String)>,
    base_dir: &Path,
) -> Option<Target> {
    if let Some(s) = selected {
        if g.nodes.get(&s).is_some_and(|n| n.op == op) {
            return Some(Target::Edit(s));
        }
    }
    let (id, port) = viewed?;
    let rgbn_out = |id: NodeId, port: &str| {
        g.node_ports(id, base_dir)
            .ok()
            .and_then(|p| p.outputs.into_iter().find(|o| o.name == port))
            .is_some_and(|o| o.ty == PortType::Rgbn)
    };
    if rgbn_out(*id, port) {
        return Some(Target::After(*id, port.clone()));
    }
    // A picture, mask or number: draw on the image it was made from.
    let n = g.nodes.get(id)?;
    n.inputs.values().find_map(|s| match s {
        Source::Node(src, p) if rgbn_out(*src, p) => Some(Target::After(*src, p.clone())),
        _ => None,
    })
}

/// Inserts a node of `op` after output `port` of `after`: its `image` input reads that output,
/// and every node input and graph output that read it reads the new node's `image` instead.
/// A new stamp node also gets a small analytic `surface` node as its stamp.
pub fn insert_after(
    g: &mut Graph,
    op: &str,
    after: NodeId,
    port: &str,
    base_dir: &Path,
) -> Result<NodeId, GraphError> {
    let pos = g.nodes.get(&after).map_or([0.0, 0.0], |n| n.pos);
    let old = Source::Node(after, port.to_string());
    let readers: Vec<(NodeId, String)> = g
        .nodes
        .iter()
        .flat_map(|(id, n)| {
            n.inputs
                .iter()
                .filter(|(_, s)| **s == old)
                .map(move |(p, _)| (*id, p.clone()))
        })
        .collect();
    // Below everything, so it does not cover other nodes.
    let below = g.nodes.values().map(|n| n.pos[1]).fold(pos[1], f32::max) + 130.0;
    let id = g.add_node(op, [pos[0] + 120.0, below]);
    if let Err(e) = g.connect(after, port, id, "image", base_dir) {
        g.nodes.remove(&id);
        return Err(e);
    }
    let new = Source::Node(id, "image".into());
    for (n, p) in readers {
        if let Some(node) = g.nodes.get_mut(&n) {
            node.inputs.insert(p, new.clone());
        }
    }
    for r in g.outputs.values_mut() {
        if r.node == after && r.port == port {
            r.node = id;
            r.port = "image".into();
        }
    }
    if op == "stamp" {
        let s = g.add_node("surface", [pos[0] - 40.0, below + 130.0]);
        set(g, s, "shape", ParamValue::Choice("gaussians".into()));
        set(g, s, "width", ParamValue::Int(DEFAULT_STAMP_SIDE as i64));
        set(g, s, "height", ParamValue::Int(DEFAULT_STAMP_SIDE as i64));
        g.connect(s, "image", id, "stamp", base_dir)?;
    }
    Ok(id)
}

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

    fn write(&mut self, g: &mut Graph, base_dir: &Path) -> Result<(), GraphError> {
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
    fn sheared(&self, s: [f64; 2]) -> [f64; 2] {
        let (u, v) = (self.scale[0] * s[0], self.scale[1] * s[1]);
        [u + self.shear * v, v]
    }

    fn rotate(a: f64, p: [f64; 2]) -> [f64; 2] {
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
    fn up(&self, p: [f64; 2]) -> [f64; 2] {
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

/// A gesture in progress: everything it changes becomes one undo step when it ends.
#[derive(Clone, Debug, PartialEq)]
pub struct Gesture {
    /// The graph before the gesture.
    before: Graph,
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
    /// Pick tolerance in image pixels ([`PICK_RADIUS_PT`] at the current zoom).
    pub tol_px: f64,
    /// Rotate handle gap in image pixels.
    pub gap_px: f64,
    /// Shift held: extend the path from its end whatever the press position.
    pub extend: bool,
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
            GestureKind::Vertex { node, index } => {
                let mut pts = node_points(g, *node).unwrap_or_default();
                match pts.get_mut(*index) {
                    Some(q) if *q != p => {
                        *q = p;
                        let name = points_param(&g.nodes[node].op).unwrap_or("points");
                        set(g, *node, name, ParamValue::Points(pts));
                        true
                    }
                    _ => false,
                }
            }
            GestureKind::Stamp {
                node,
                handle,
                frame,
            } => {
                let before = g.nodes.get(node).map(|n| n.params.clone());
                match *handle {
                    StampHandle::Move { index, offset } => {
                        let mut pts = node_points(g, *node).unwrap_or_default();
                        if let Some(q) = pts.get_mut(index) {
                            *q = [p[0] - offset[0], p[1] - offset[1]];
                        }
                        set(g, *node, "positions", ParamValue::Points(pts));
                    }
                    StampHandle::Rotate => {
                        let a = frame.angle_for(p, press.gap_px);
                        set(g, *node, "angle_rad", ParamValue::Float(a));
                    }
                    StampHandle::Scale => {
                        let [sx, sy] = frame.scale_for(p, uniform);
                        set(g, *node, "scale_x", ParamValue::Float(sx));
                        set(g, *node, "scale_y", ParamValue::Float(sy));
                    }
                }
                g.nodes.get(node).map(|n| n.params.clone()) != before
            }
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
            }
            s.write(&mut doc.graph, &base)?;
            if let (true, Some(id)) = (closes, s.node) {
                set(&mut doc.graph, id, "closed", ParamValue::Bool(true));
            }
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

/// Removes vertex `index` of the node's point list if enough points remain (one undo step);
/// true if removed.
pub fn delete_vertex(doc: &mut Document, node: NodeId, index: usize) -> bool {
    let Some(n) = doc.graph.nodes.get(&node) else {
        return false;
    };
    let (op, Some(name)) = (n.op.clone(), points_param(&n.op)) else {
        return false;
    };
    let mut pts = node_points(&doc.graph, node).unwrap_or_default();
    if index >= pts.len() || pts.len() <= min_points(&op) {
        return false;
    }
    pts.remove(index);
    doc.set_param(node, name, ParamValue::Points(pts));
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn demo() -> Document {
        Document::demo()
    }

    fn press(at: [f64; 2]) -> Press {
        Press {
            at,
            tol_px: 4.0,
            gap_px: 6.0,
            extend: false,
        }
    }

    fn base() -> PathBuf {
        PathBuf::from(".")
    }

    fn close(a: [f64; 2], b: [f64; 2], tol: f64) -> bool {
        dist(a, b) <= tol
    }

    /// Draws a stroke through `pts` with `tools`, live, and finishes it.
    fn draw(
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

    fn pen_tools() -> ToolState {
        ToolState {
            kind: ToolKind::Pen,
            ..ToolState::default()
        }
    }

    #[test]
    fn screen_and_image_coordinates_map_both_ways_under_zoom_and_pan() {
        // A 100×50 image at zoom 2 in a panel centred at (300, 200), panned by (10, −20): the
        // image's left edge is at 300 + 10 − 100 = 210, its top at 200 − 20 − 50 = 130.
        let t = ViewTransform::new([300.0, 200.0], [10.0, -20.0], [100.0, 50.0], 2.0);
        assert_eq!(t.origin, [210.0, 130.0]);
        // Pixel (0, 0) is centred one half pixel (1 point) inside the corner.
        assert_eq!(t.screen_from_image([0.0, 0.0]), [211.0, 131.0]);
        assert_eq!(t.image_from_screen([211.0, 131.0]), [0.0, 0.0]);
        // The corner itself is at −½.
        assert_eq!(t.image_from_screen([210.0, 130.0]), [-0.5, -0.5]);
        // The last pixel's centre.
        assert_eq!(t.screen_from_image([99.0, 49.0]), [409.0, 229.0]);
        for s in [[233.5f32, 171.25], [-40.0, 900.0]] {
            let back = t.screen_from_image(t.image_from_screen(s));
            assert!((back[0] - s[0]).abs() < 1e-3 && (back[1] - s[1]).abs() < 1e-3);
        }
        assert_eq!(t.px_from_pt(7.0), 3.5);
    }

    #[test]
    fn stroke_simplification_drops_points_closer_than_the_spacing() {
        let mut pts = Vec::new();
        assert!(push_simplified(&mut pts, [0.0, 0.0], MIN_SPACING_PX));
        assert!(!push_simplified(&mut pts, [1.0, 1.0], MIN_SPACING_PX)); // √2 < 1.5
        assert!(push_simplified(&mut pts, [1.5, 0.0], MIN_SPACING_PX));
        assert!(!push_simplified(&mut pts, [f64::NAN, 0.0], MIN_SPACING_PX));
        // Spacing is measured from the last kept point, so slow drags still progress.
        for i in 1..=10 {
            push_simplified(&mut pts, [1.5 + 0.5 * f64::from(i), 0.0], MIN_SPACING_PX);
        }
        assert_eq!(
            pts,
            vec![[0.0, 0.0], [1.5, 0.0], [3.0, 0.0], [4.5, 0.0], [6.0, 0.0]]
        );
    }

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
    fn viewing_a_picture_draws_on_the_image_it_was_made_from() {
        let d = demo();
        // Node 4 (relight) outputs a picture made from node 3's image.
        let t = target(&d.graph, "pen", None, Some(&(4, "picture".into())), &base());
        assert_eq!(t, Some(Target::After(3, "image".into())));
        // The selected node wins when it runs the tool's operator.
        let mut g = d.graph.clone();
        let pen = g.add_node("pen", [0.0, 0.0]);
        let t = target(&g, "pen", Some(pen), Some(&(4, "picture".into())), &base());
        assert_eq!(t, Some(Target::Edit(pen)));
        // Nothing viewed, nothing selected: no target.
        assert_eq!(target(&g, "pen", Some(2), None, &base()), None);
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
            scale: [1.5, -0.8],
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
