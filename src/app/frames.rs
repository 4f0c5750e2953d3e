//! Frames in the graph view: drawn behind the nodes (from the viewer's background hook), with a
//! title bar that drags the frame's nodes, and opens its menu (rename, recolour, delete) on a
//! right-click or a double-click.
//!
//! A frame's box is the bounding box of its nodes' drawn rectangles, grown by [`MARGIN`], with
//! a [`TITLE_HEIGHT`] bar above: it follows its nodes. Everything here is in graph coordinates
//! (the snarl layer's transform maps them to the screen).

use super::graph_view::Action;
use super::placement::{self, Rect as PlaceRect};
use crate::graph::{Graph, NodeId};
use egui::emath::TSTransform;
use egui::{Color32, FontId, Id, LayerId, Pos2, Rect, Sense, Stroke, Ui, UiBuilder};
use std::collections::BTreeMap;

/// Space between a frame's nodes and its edges.
pub const MARGIN: f32 = 14.0;
/// Height of a frame's title bar.
pub const TITLE_HEIGHT: f32 = 24.0;

/// A frame's body and title bar in graph coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRects {
    /// Around the nodes.
    pub body: Rect,
    /// The bar above, with the title: drag it to move the frame.
    pub title: Rect,
}

/// The rectangles of every frame of `graph` with nodes, by index: `node_rect` gives a node's
/// rectangle (as drawn, or a default size at its position).
#[must_use]
pub fn frame_rects(
    graph: &Graph,
    node_rect: impl Fn(NodeId) -> Option<PlaceRect>,
) -> Vec<(usize, FrameRects)> {
    graph
        .frames
        .iter()
        .enumerate()
        .filter_map(|(i, f)| {
            let mut bb = Rect::NOTHING;
            for id in &f.nodes {
                if let Some(r) = node_rect(*id) {
                    let max = r.max();
                    bb = bb.union(Rect::from_min_max(
                        Pos2::new(r.min[0], r.min[1]),
                        Pos2::new(max[0], max[1]),
                    ));
                }
            }
            if !bb.is_finite() {
                return None;
            }
            let body = bb.expand(MARGIN);
            let title = Rect::from_min_max(
                Pos2::new(body.min.x, body.min.y - TITLE_HEIGHT),
                Pos2::new(body.max.x, body.min.y),
            );
            Some((i, FrameRects { body, title }))
        })
        .collect()
}

/// A node's rectangle: as last drawn (`measured`: offset from its position and size), else
/// [`placement::DEFAULT_NODE_SIZE`] at its position.
#[must_use]
pub fn node_rect(
    graph: &Graph,
    measured: &BTreeMap<NodeId, ([f32; 2], [f32; 2])>,
    id: NodeId,
) -> Option<PlaceRect> {
    let n = graph.nodes.get(&id)?;
    Some(match measured.get(&id) {
        Some((off, size)) => PlaceRect::new([n.pos[0] + off[0], n.pos[1] + off[1]], *size),
        None => PlaceRect::new(n.pos, placement::DEFAULT_NODE_SIZE),
    })
}

/// The colour of frame colour `c` for its body (translucent) and bar.
fn colors(c: [u8; 3]) -> (Color32, Color32) {
    (
        Color32::from_rgba_unmultiplied(c[0], c[1], c[2], 70),
        Color32::from_rgba_unmultiplied(c[0], c[1], c[2], 220),
    )
}

/// Paints the frames behind the nodes (the painter is the snarl's, in graph coordinates).
pub fn paint(painter: &egui::Painter, graph: &Graph, rects: &[(usize, FrameRects)]) {
    for (i, r) in rects {
        let f = &graph.frames[*i];
        let (body, bar) = colors(f.color);
        painter.rect_filled(r.body.union(r.title), 6.0, body);
        painter.rect_filled(
            r.title,
            egui::CornerRadius {
                nw: 6,
                ne: 6,
                sw: 0,
                se: 0,
            },
            bar,
        );
        painter.rect_stroke(
            r.body.union(r.title),
            6.0,
            Stroke::new(1.0, bar),
            egui::StrokeKind::Inside,
        );
        let title = if f.title.is_empty() {
            "frame"
        } else {
            &f.title
        };
        let text = painter.layout_no_wrap(
            title.to_string(),
            FontId::proportional(14.0),
            Color32::WHITE,
        );
        let pos = Pos2::new(
            r.title.min.x + 8.0,
            r.title.center().y - text.size().y / 2.0,
        );
        painter
            .with_clip_rect(r.title.intersect(painter.clip_rect()))
            .galley(pos, text, Color32::WHITE);
    }
}

/// The accessible label of frame `title`'s bar (what tests and screen readers find).
#[must_use]
pub fn bar_label(title: &str) -> String {
    format!("frame {title}")
}

/// The title bars' interaction, in the snarl's layer above its nodes: a drag moves the frame's
/// nodes (returned as a delta per frame, applied to the widget's node positions); a
/// right-click opens the frame's menu, a double-click its rename dialog. `to_global` is the
/// view's transform, `view` the panel's screen rectangle, `snarl_id` the graph widget's id.
pub fn bars_ui(
    ui: &mut Ui,
    snarl_id: Id,
    graph: &Graph,
    rects: &[(usize, FrameRects)],
    to_global: TSTransform,
    view: Rect,
    actions: &mut Vec<Action>,
) -> Vec<(usize, egui::Vec2)> {
    let layer = LayerId::new(ui.layer_id().order, snarl_id);
    let mut fui = ui.new_child(UiBuilder::new().layer_id(layer).max_rect(Rect::EVERYTHING));
    fui.set_clip_rect(to_global.inverse() * view);
    let mut moves = Vec::new();
    for (i, r) in rects {
        let f = &graph.frames[*i];
        let label = bar_label(&f.title);
        let resp = fui
            .interact(r.title, Id::new(("rgbn-frame-bar", *i)), Sense::click_and_drag())
            .on_hover_cursor(egui::CursorIcon::Grab)
            .on_hover_text("Drag to move the frame and its nodes; double-click or right-click to rename, recolour or delete it");
        resp.widget_info(|| egui::WidgetInfo::labeled(egui::WidgetType::Button, true, &label));
        if resp.dragged_by(egui::PointerButton::Primary) {
            let d = resp.drag_delta();
            if d != egui::Vec2::ZERO {
                moves.push((*i, d));
            }
        }
        if resp.double_clicked() {
            actions.push(Action::EditFrame(*i));
        }
        resp.context_menu(|ui| {
            ui.label(egui::RichText::new(&label).strong());
            if ui.button("Rename / recolour…").clicked() {
                actions.push(Action::EditFrame(*i));
                ui.close();
            }
            if ui
                .button("Delete frame")
                .on_hover_text("Remove the frame; its nodes stay")
                .clicked()
            {
                actions.push(Action::DeleteFrame(*i));
                ui.close();
            }
        });
    }
    moves
}
