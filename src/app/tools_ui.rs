//! The egui side of the on-image tools ([`super::tools`]): the toolbar above the preview,
//! pointer handling on the image and the overlays (path with vertex handles, stamp outlines
//! with rotate and scale handles, brush cursor). What a gesture does to the graph is decided in
//! [`super::tools`]; this module only feeds it pointer positions in image pixels.
//!
//! With a tool active, the primary button draws; pan with the middle or secondary button or
//! Space + drag; Escape abandons the gesture in progress.

use super::state::Document;
use super::tools::{
    self, delete_vertex, node_points, param_f64, place_stamp, Gesture, GestureKind, Press,
    StampFrame, ToolKind, ToolState, ViewTransform, PICK_RADIUS_PT, ROTATE_HANDLE_GAP_PT,
};
use crate::graph::NodeId;
use egui::{Color32, Key, Painter, PointerButton, Pos2, Response, Shape, Stroke, Ui, Vec2};
use std::time::Instant;

/// Tool settings and the gesture in progress.
#[derive(Default)]
pub struct Tools {
    /// Settings (tool kind, brush radius, live updates).
    pub state: ToolState,
    /// The gesture in progress.
    pub gesture: Option<Gesture>,
    /// Times of the first and latest tool edits not yet sent to the worker.
    unsent: Option<(Instant, Instant)>,
    /// The same for the evaluation request in flight.
    sent: Option<(Instant, Instant)>,
    /// Latest tool edit → relit preview latencies (oldest and newest edit shown), ms.
    pub last_latency_ms: Option<(f64, f64)>,
    /// During a gesture: the previous frame's time and the intervals between frames (ms) —
    /// how long a pointer move waits for its overlay at most.
    frames: (Option<Instant>, Vec<f64>),
}

/// What the tools need from the editor for one frame.
pub struct ToolCx<'a> {
    /// The document edited.
    pub doc: &'a mut Document,
    /// The selected node (the tool edits it when it fits; new nodes get selected).
    pub selected: &'a mut Option<NodeId>,
    /// The viewed output (new nodes after it get viewed).
    pub viewed: &'a mut Option<(NodeId, String)>,
    /// Size of the selected stamp node's stamp input, when evaluated.
    pub stamp_size: Option<[usize; 2]>,
    /// A status message for the editor to show.
    pub message: Option<String>,
}

/// Colours of the overlays.
const PATH: Color32 = Color32::from_rgb(90, 200, 255);
const LIVE: Color32 = Color32::from_rgb(255, 170, 40);
const HANDLE: Color32 = Color32::from_rgb(255, 240, 120);

fn pos(p: [f32; 2]) -> Pos2 {
    Pos2::new(p[0], p[1])
}

impl Tools {
    /// True when a tool other than Pan is active (primary drag draws instead of panning).
    #[must_use]
    pub fn active(&self) -> bool {
        self.state.kind != ToolKind::Pan
    }

    /// The toolbar: tool buttons, brush radius and the live-update switch.
    pub fn toolbar_ui(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            ui.label("Tool");
            for k in ToolKind::ALL {
                let r = ui.selectable_value(&mut self.state.kind, k, k.name());
                r.on_hover_text(match k {
                    ToolKind::Pan => "Drag to pan, scroll to zoom, double-click to fit",
                    ToolKind::Pen => "Drag to draw a pen path: a new path of the selected pen node (Ctrl, or \"new node\": a new pen node); start at an end of one of its paths (or hold Shift) to extend it; end where you began to close it",
                    ToolKind::Stamp => "Click to place the stamp; drag a placement to move it, the round handle to rotate, the square one to scale (Shift: keep aspect)",
                    ToolKind::Brush => "Drag to paint the filter brush's region (Shift extends the selected brush's stroke)",
                    ToolKind::Vertices => "Drag a vertex of the selected pen, brush or stamp node; right-click deletes it",
                });
            }
            if self.state.kind == ToolKind::Pen {
                ui.separator();
                ui.add(
                    egui::DragValue::new(&mut self.state.pen_width_px)
                        .range(0.5..=2000.0)
                        .speed(0.2)
                        .prefix("width ")
                        .suffix(" px"),
                )
                .on_hover_text("Stroke width of new pen paths");
                ui.add(
                    egui::DragValue::new(&mut self.state.pen_height_px)
                        .range(-500.0..=500.0)
                        .speed(0.1)
                        .prefix("height ")
                        .suffix(" px"),
                )
                .on_hover_text("Relief height of new pen paths (negative engraves)");
                ui.checkbox(&mut self.state.pen_new_node, "new node")
                    .on_hover_text("Each stroke makes a new pen node (else it is a new path of the selected pen node; Ctrl does this for one stroke)");
            }
            if self.state.kind == ToolKind::Brush {
                ui.separator();
                ui.add(
                    egui::DragValue::new(&mut self.state.brush_radius_px)
                        .range(0.5..=2000.0)
                        .speed(0.2)
                        .prefix("radius ")
                        .suffix(" px"),
                );
                ui.add(
                    egui::DragValue::new(&mut self.state.brush_feather_px)
                        .range(0.0..=2000.0)
                        .speed(0.2)
                        .prefix("feather ")
                        .suffix(" px"),
                );
            }
            if self.active() {
                ui.separator();
                ui.checkbox(&mut self.state.live, "live")
                    .on_hover_text("Re-evaluate while drawing (else when the stroke ends)");
            }
        });
    }

    /// Handles the pointer on the preview image and draws the overlays. `resp` is the image
    /// area's response, `xf` the screen ↔ image mapping.
    pub fn image_ui(
        &mut self,
        ui: &Ui,
        resp: &Response,
        painter: &Painter,
        xf: ViewTransform,
        cx: &mut ToolCx<'_>,
    ) {
        if !self.active() {
            return;
        }
        let (shift, ctrl, space, escape, press_origin) = ui.input(|i| {
            (
                i.modifiers.shift,
                i.modifiers.command,
                i.key_down(Key::Space),
                i.key_pressed(Key::Escape),
                i.pointer.press_origin(),
            )
        });
        let press_at = |p: Pos2| Press {
            at: xf.image_from_screen([p.x, p.y]),
            tol_px: xf.px_from_pt(PICK_RADIUS_PT),
            gap_px: xf.px_from_pt(ROTATE_HANDLE_GAP_PT),
            extend: shift,
            new_node: ctrl,
        };
        let base = cx.doc.base_dir();
        if self.gesture.is_some() {
            let now = Instant::now();
            if let Some(t) = self.frames.0 {
                self.frames.1.push((now - t).as_secs_f64() * 1e3);
            }
            self.frames.0 = Some(now);
        }

        // Start a gesture.
        if self.gesture.is_none() && resp.drag_started_by(PointerButton::Primary) && !space {
            if let Some(origin) = press_origin {
                let press = press_at(origin);
                let sel = *cx.selected;
                self.gesture = match self.state.kind {
                    ToolKind::Pen | ToolKind::Brush => {
                        Gesture::stroke(cx.doc, &self.state, sel, cx.viewed.as_ref(), press)
                    }
                    ToolKind::Stamp => Gesture::stamp(cx.doc, sel, cx.stamp_size, press),
                    ToolKind::Vertices => Gesture::vertex(cx.doc, sel, press),
                    ToolKind::Pan => None,
                };
                if self.gesture.is_none() && self.state.kind != ToolKind::Stamp {
                    cx.message = Some(match self.state.kind {
                        ToolKind::Vertices => "no vertex of the selected node here".into(),
                        _ => "nothing to draw on: view an image first".into(),
                    });
                }
            }
        }
        // Continue it.
        let mut wrote = false;
        if let (Some(g), Some(p)) = (&mut self.gesture, resp.interact_pointer_pos()) {
            if resp.dragged_by(PointerButton::Primary) {
                let press = press_at(p);
                let created = g.node().is_none();
                match g.update(
                    &mut cx.doc.graph,
                    press.at,
                    press,
                    shift,
                    self.state.live,
                    &base,
                ) {
                    Ok(changed) => wrote = changed && self.state.live,
                    Err(e) => cx.message = Some(e.to_string()),
                }
                if created {
                    if let Some(id) = g.node() {
                        adopt(cx, id);
                    }
                }
            }
        }
        if wrote {
            self.wrote();
        }
        if escape {
            if let Some(g) = self.gesture.take() {
                self.frames = (None, Vec::new());
                g.cancel(cx.doc);
                cx.message = Some("stroke cancelled".into());
            }
        }
        // End it: one undo step.
        let released = !ui.input(|i| i.pointer.button_down(PointerButton::Primary));
        if self.gesture.is_some() && (resp.drag_stopped() || released) {
            let g = self.gesture.take().expect("checked");
            let (_, iv) = std::mem::take(&mut self.frames);
            if !iv.is_empty() && super::timing_enabled() {
                let mut s = iv.clone();
                s.sort_by(f64::total_cmp);
                tracing::info!(
                                target: super::TIMING,
                                "gesture of {} frames; frame interval median {:.1} ms, p90 {:.1} ms, max {:.1} ms",
                    s.len() + 1,
                    s[s.len() / 2],
                    s[s.len() * 9 / 10],
                    s[s.len() - 1]
                );
            }
            let p = resp
                .interact_pointer_pos()
                .or(resp.hover_pos())
                .unwrap_or_default();
            let created = g.node().is_none();
            let pre = cx.doc.graph.clone();
            match g.finish(cx.doc, press_at(p)) {
                Ok(true) => {
                    if cx.doc.graph != pre {
                        self.wrote();
                    }
                    if created {
                        if let Some(id) = cx.doc.graph.nodes.keys().next_back().copied() {
                            adopt(cx, id);
                        }
                    }
                }
                Ok(false) => {}
                Err(e) => cx.message = Some(e.to_string()),
            }
        }
        // Clicks.
        if self.gesture.is_none() && resp.clicked_by(PointerButton::Primary) && !space {
            if let (ToolKind::Stamp, Some(p)) = (self.state.kind, resp.interact_pointer_pos()) {
                let press = press_at(p);
                let viewed = cx.viewed.clone();
                match place_stamp(cx.doc, *cx.selected, viewed.as_ref(), press.at) {
                    Ok(Some(id)) => {
                        self.wrote();
                        adopt(cx, id);
                    }
                    Ok(None) => {
                        cx.message = Some("nothing to stamp on: view an image first".into())
                    }
                    Err(e) => cx.message = Some(e.to_string()),
                }
            }
        }
        if resp.clicked_by(PointerButton::Secondary) && self.state.kind == ToolKind::Vertices {
            if let (Some(id), Some(p)) = (*cx.selected, resp.interact_pointer_pos()) {
                let press = press_at(p);
                let pts = node_points(&cx.doc.graph, id).unwrap_or_default();
                if let Some(i) = tools::hit_vertex(&pts, press.at, press.tol_px) {
                    if !delete_vertex(cx.doc, id, i) {
                        cx.message = Some("the path needs its remaining points".into());
                    }
                }
            }
        }
        if resp.hovered() && !space {
            ui.ctx().set_cursor_icon(egui::CursorIcon::Crosshair);
        }
        self.overlay(ui, resp, painter, xf, cx);
    }

    fn wrote(&mut self) {
        let now = Instant::now();
        let first = self.unsent.map_or(now, |u| u.0);
        self.unsent = Some((first, now));
    }

    /// Called when an evaluation request is sent: it carries the tool edits made so far.
    pub fn request_sent(&mut self) {
        if let Some(u) = self.unsent.take() {
            self.sent = Some(u);
        }
    }

    /// When the newest tool edit of the last request was made (timing).
    #[must_use]
    pub fn newest_sent_edit(&self) -> Option<Instant> {
        self.sent.map(|s| s.1)
    }

    /// Called after the preview texture was re-rendered from a new evaluation. Returns (and
    /// keeps) how long ago the oldest and newest tool edits it shows were made, in ms.
    pub fn preview_rendered(&mut self) -> Option<(f64, f64)> {
        let (first, last) = self.sent.take()?;
        let ms = |t: Instant| t.elapsed().as_secs_f64() * 1e3;
        self.last_latency_ms = Some((ms(first), ms(last)));
        self.last_latency_ms
    }

    fn overlay(
        &self,
        ui: &Ui,
        resp: &Response,
        painter: &Painter,
        xf: ViewTransform,
        cx: &ToolCx<'_>,
    ) {
        let g = &cx.doc.graph;
        let scr = |p: [f64; 2]| pos(xf.screen_from_image(p));
        let sel = cx.selected.filter(|s| g.nodes.contains_key(s));
        let sel_op = sel.map(|s| g.nodes[&s].op.as_str());
        let dark = Stroke::new(3.0, Color32::from_black_alpha(160));
        // The selected node's points.
        if let (Some(id), Some(op)) = (sel, sel_op) {
            let pts: Vec<Pos2> = node_points(g, id)
                .unwrap_or_default()
                .into_iter()
                .map(scr)
                .collect();
            match op {
                "pen" | "brush" => {
                    if op == "brush" {
                        let r = param_f64(g, id, "radius_px").unwrap_or(0.0) as f32 * xf.zoom;
                        brush_band(
                            painter,
                            &pts,
                            r,
                            Color32::from_rgba_unmultiplied(90, 200, 255, 40),
                        );
                    }
                    // A pen's paths each as its own line (closed ones joined), a brush's one.
                    let lines: Vec<Vec<Pos2>> = match tools::pen_paths(g, id) {
                        Some(paths) if op == "pen" => paths
                            .into_iter()
                            .map(|p| {
                                let mut l: Vec<Pos2> = p.points.into_iter().map(scr).collect();
                                if p.closed && l.len() > 2 {
                                    l.push(l[0]);
                                }
                                l
                            })
                            .collect(),
                        _ => vec![pts.clone()],
                    };
                    let mut handles: Vec<Pos2> = Vec::new();
                    for line in lines {
                        if self.state.kind != ToolKind::Vertices {
                            handles.extend(line.first().into_iter().chain(line.last()));
                        }
                        painter.line(
                            line.clone(),
                            Stroke::new(2.5, Color32::from_black_alpha(90)),
                        );
                        painter.line(line, Stroke::new(1.0, PATH.gamma_multiply(0.7)));
                    }
                    let hover = resp.hover_pos();
                    if self.state.kind == ToolKind::Vertices {
                        handles = pts.clone();
                    }
                    for p in &handles {
                        let hot = hover.is_some_and(|h| h.distance(*p) <= PICK_RADIUS_PT);
                        painter.circle(
                            *p,
                            if hot { 5.0 } else { 3.5 },
                            if hot { HANDLE } else { Color32::WHITE },
                            Stroke::new(1.0, Color32::BLACK),
                        );
                    }
                }
                "stamp" => {
                    let n = pts.len();
                    for i in 0..n {
                        if let Some(f) = StampFrame::of(g, id, i, cx.stamp_size) {
                            let c: Vec<Pos2> = f.corners().into_iter().map(scr).collect();
                            painter.add(Shape::closed_line(c.clone(), dark));
                            painter.add(Shape::closed_line(c, Stroke::new(1.5, PATH)));
                            painter.circle_filled(scr(f.centre), 2.5, PATH);
                        }
                    }
                    if let Some(f) = n
                        .checked_sub(1)
                        .and_then(|i| StampFrame::of(g, id, i, cx.stamp_size))
                    {
                        let gap = xf.px_from_pt(ROTATE_HANDLE_GAP_PT);
                        let edge = scr(f.image_from_stamp([f.size[0] / 2.0, 0.0]));
                        let rot = scr(f.rotate_handle(gap));
                        painter.line_segment([edge, rot], Stroke::new(1.5, HANDLE));
                        painter.circle(rot, 5.5, HANDLE, Stroke::new(1.0, Color32::BLACK));
                        let s = scr(f.scale_handle());
                        painter.rect(
                            egui::Rect::from_center_size(s, Vec2::splat(9.0)),
                            0.0,
                            HANDLE,
                            Stroke::new(1.0, Color32::BLACK),
                            egui::StrokeKind::Middle,
                        );
                    }
                }
                _ => {}
            }
        }
        // The stroke in progress (immediate feedback, also when not written live).
        if let Some(Gesture {
            kind: GestureKind::Stroke(s),
            ..
        }) = &self.gesture
        {
            let pts: Vec<Pos2> = s.path().into_iter().map(scr).collect();
            if s.op == "brush" {
                let r = match s.node {
                    Some(id)
                        if s.mode != tools::StrokeMode::Replace || s.create_after.is_none() =>
                    {
                        param_f64(g, id, "radius_px").unwrap_or(s.brush.0)
                    }
                    _ => s.brush.0,
                } as f32
                    * xf.zoom;
                brush_band(
                    painter,
                    &pts,
                    r,
                    Color32::from_rgba_unmultiplied(255, 170, 40, 50),
                );
            }
            painter.line(pts.clone(), dark);
            painter.line(pts, Stroke::new(2.0, LIVE));
        }
        // Brush cursor: radius and feather.
        if self.state.kind == ToolKind::Brush {
            if let Some(h) = resp.hover_pos() {
                let (r, f) = match (sel, sel_op) {
                    (Some(id), Some("brush"))
                        if !ui.input(|i| i.modifiers.shift) || self.gesture.is_some() =>
                    {
                        (
                            param_f64(g, id, "radius_px").unwrap_or(self.state.brush_radius_px),
                            param_f64(g, id, "feather_px").unwrap_or(self.state.brush_feather_px),
                        )
                    }
                    _ => (self.state.brush_radius_px, self.state.brush_feather_px),
                };
                let z = xf.zoom;
                painter.circle_stroke(h, (r as f32 * z).max(1.0), Stroke::new(1.5, Color32::WHITE));
                painter.circle_stroke(
                    h,
                    ((r + f) as f32 * z).max(2.0),
                    Stroke::new(1.0, Color32::from_white_alpha(90)),
                );
            }
        }
    }
}

/// The region a brush stroke covers: a wide translucent line plus discs at the ends.
fn brush_band(painter: &Painter, pts: &[Pos2], r: f32, color: Color32) {
    if r < 0.5 || pts.is_empty() {
        return;
    }
    if pts.len() > 1 {
        painter.line(pts.to_vec(), Stroke::new(2.0 * r, color));
    }
    painter.circle_filled(pts[0], r, color);
    if let Some(l) = pts.last() {
        painter.circle_filled(*l, r, color);
    }
}

/// Selects a node the tools made, and views it if the viewed output was the one it follows.
fn adopt(cx: &mut ToolCx<'_>, id: NodeId) {
    *cx.selected = Some(id);
    let reads_viewed = cx.viewed.as_ref().is_some_and(|(v, port)| {
        cx.doc
            .graph
            .nodes
            .get(&id)
            .and_then(|n| n.inputs.get("image"))
            == Some(&crate::graph::Source::Node(*v, port.clone()))
    });
    if reads_viewed {
        *cx.viewed = Some((id, "image".into()));
    }
}
