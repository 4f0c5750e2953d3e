//! Opening images directly: File ▸ Open image… and files dropped on the window add a `load`
//! node wired into the viewed chain; and where new nodes go (never on top of existing ones,
//! see [`placement`]).

use super::dialogs::Then;
use super::placement::{self, Rect};
use super::recent;
use super::EditorApp;
use crate::graph::NodeId;
use crate::raster::io::Format;
use egui::{Align2, Color32, FontId, Id, LayerId, Order};
use std::path::Path;

/// The size to expect of a node showing an error (see `graph_view`'s node body).
const ERROR_NODE_SIZE: [f32; 2] = [360.0, 150.0];

/// What the editor opens, for messages.
const OPENS: &str = "an image (PNG, JPEG, TIFF, EXR, PTM) or a graph (.ron)";

impl EditorApp {
    /// The rectangle of every node in graph coordinates (as last drawn; an estimate for nodes
    /// not drawn yet).
    #[must_use]
    pub fn node_rects(&self) -> Vec<(NodeId, Rect)> {
        self.view.node_rects(&self.session.doc.graph)
    }

    /// The rectangles of the nodes drawn in the graph view (graph coordinates).
    #[must_use]
    pub fn drawn_node_rects(&self) -> std::collections::BTreeMap<NodeId, Rect> {
        self.view.drawn_rects(&self.session.doc.graph)
    }

    /// Where a new node of operator `op` goes: `preferred` if it overlaps no node there, else
    /// the nearest free spot ([`placement::free_position`]). `connected`: its inputs will be
    /// wired (else a node with a required input shows an error, which makes it wider).
    #[must_use]
    pub fn place_node(&self, op: &str, preferred: [f32; 2], connected: bool) -> [f32; 2] {
        let rects: Vec<Rect> = self.node_rects().into_iter().map(|(_, r)| r).collect();
        let mut size = self.view.size_hint(&self.session.doc.graph, op);
        let needs_input =
            crate::nodes::find(op).is_some_and(|o| o.spec().inputs.iter().any(|p| !p.optional));
        if !connected && needs_input {
            size = [
                size[0].max(ERROR_NODE_SIZE[0]),
                size[1].max(ERROR_NODE_SIZE[1]),
            ];
        }
        placement::free_position(&rects, size, preferred)
    }

    /// Keeps node `id` (just placed by the editor) clear of others until it is drawn with its
    /// evaluated content ([`keep_placed_clear`](Self::keep_placed_clear)).
    pub(super) fn watch_placed(&mut self, id: NodeId) {
        if let Some(n) = self.session.doc.graph.nodes.get(&id) {
            self.placed.insert(id, (n.pos, 3));
        }
    }

    /// A node's size is known only once drawn, and it changes when its thumbnail or error
    /// arrives: a node the editor placed that now overlaps another is moved to the nearest
    /// free spot. It is watched until it has been drawn evaluated for a few frames, or until
    /// it is moved by hand (or deleted).
    pub(super) fn keep_placed_clear(&mut self) {
        if self.placed.is_empty() {
            return;
        }
        let graph = &self.session.doc.graph;
        self.placed
            .retain(|id, (p, _)| graph.nodes.get(id).is_some_and(|n| n.pos == *p));
        let evaluating = self.runtime.in_flight.is_some();
        let ids: Vec<NodeId> = self.placed.keys().copied().collect();
        for id in ids {
            let drawn = self.view.drawn_rects(&self.session.doc.graph);
            let Some(r) = drawn.get(&id).copied() else {
                continue;
            };
            let others: Vec<Rect> = self
                .node_rects()
                .into_iter()
                .filter(|(o, _)| *o != id)
                .map(|(_, r)| r)
                .collect();
            if others.iter().any(|o| r.overlaps(o, 0.0)) {
                let Some(n) = self.session.doc.graph.nodes.get_mut(&id) else {
                    continue;
                };
                let off = [r.min[0] - n.pos[0], r.min[1] - n.pos[1]];
                let m = placement::free_position(&others, r.size, r.min);
                n.pos = [m[0] - off[0], m[1] - off[1]];
                let pos = n.pos;
                if let Some(w) = self.placed.get_mut(&id) {
                    w.0 = pos;
                }
            }
            let out = &self.runtime.outcome;
            let evaluated = !evaluating
                && (out.node_errors.contains_key(&id)
                    || out.waiting.contains_key(&id)
                    || out.keys.keys().any(|k| k.0 == id));
            if evaluated {
                if let Some(w) = self.placed.get_mut(&id) {
                    w.1 = w.1.saturating_sub(1);
                    if w.1 == 0 {
                        self.placed.remove(&id);
                    }
                }
            }
        }
    }

    /// Adds a `load` node for the image at `path` (one undo step). If the viewed chain starts
    /// from an image source (demo, load, …), the new node takes over that source's
    /// connections (the old source stays in the graph, unconnected) and the preview keeps
    /// showing the chain, now on this image; otherwise the preview shows the new node.
    /// Returns the new node, or `None` (with a message) when rgbn cannot read such a file.
    pub fn open_image(&mut self, path: &Path) -> Option<NodeId> {
        if let Err(e) = Format::of(path) {
            self.fail(format!("cannot open {}: {e}", path.display()));
            return None;
        }
        if !path.is_file() {
            self.fail(format!("cannot open {}: no such file", path.display()));
            return None;
        }
        // Relative to the graph's folder when it has one and the image is inside it.
        let abs = recent::absolute(path);
        let written = match &self.session.doc.path {
            Some(_) => {
                let base = recent::absolute(&self.session.doc.base_dir());
                abs.strip_prefix(&base).unwrap_or(&abs).to_path_buf()
            }
            None => abs.clone(),
        };
        let viewed = self.session.viewed.as_ref().map(|v| v.0);
        let source = viewed.and_then(|v| self.session.doc.chain_source(v));
        let g = &self.session.doc.graph;
        let preferred = match source.and_then(|s| g.nodes.get(&s)) {
            // Beside the source it replaces (the nearest free spot to it).
            Some(s) => s.pos,
            None => {
                let x = g
                    .nodes
                    .values()
                    .map(|n| n.pos[0])
                    .fold(f32::INFINITY, f32::min);
                let y = g
                    .nodes
                    .values()
                    .map(|n| n.pos[1])
                    .fold(f32::INFINITY, f32::min);
                if x.is_finite() && y.is_finite() {
                    [x, y]
                } else {
                    [0.0, 0.0]
                }
            }
        };
        let pos = self.place_node("load", preferred, true);
        let id = self
            .session
            .doc
            .add_load(&written.to_string_lossy(), pos, source);
        self.watch_placed(id);
        let name = path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        match source {
            Some(s) if viewed != Some(s) => {
                self.session.selected = Some(id);
                self.say(format!(
                    "opened {name} as load #{id}, in place of #{s} in the viewed chain (#{s} kept, unconnected)"
                ));
            }
            _ => {
                self.view_node(id);
                self.say(format!("opened {name} as load #{id}"));
            }
        }
        Some(id)
    }

    /// Acts on files dropped on the window: an image is opened with
    /// [`open_image`](Self::open_image), a `.ron` graph is opened (after the unsaved-changes
    /// check); anything else gets a message saying what can be dropped.
    pub fn open_dropped(&mut self, paths: &[&Path]) {
        for path in paths {
            let ext = path
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if ext.as_deref() == Some("ron") {
                self.guarded(Then::Open(path.display().to_string()));
            } else if Format::of(path).is_ok() {
                self.open_image(path);
            } else {
                let what = match ext {
                    Some(e) => format!(".{e} files"),
                    None => "files without an extension".into(),
                };
                self.fail(format!(
                    "cannot open {}: rgbn does not read {what}; drop {OPENS}",
                    path.display()
                ));
            }
        }
    }

    /// Takes this frame's dropped files, and while files are dragged over the window says
    /// what dropping them does.
    pub(super) fn dropped_files_ui(&mut self, ctx: &egui::Context) {
        let (dropped, hovering) = ctx.input(|i| {
            (
                i.raw
                    .dropped_files
                    .iter()
                    .map(|f| f.path().to_path_buf())
                    .collect::<Vec<_>>(),
                !i.raw.hovered_files.is_empty(),
            )
        });
        if !dropped.is_empty() {
            let paths: Vec<&Path> = dropped.iter().map(|p| p.as_path()).collect();
            self.open_dropped(&paths);
        }
        if hovering {
            let painter = ctx.layer_painter(LayerId::new(Order::Foreground, Id::new("drop-hint")));
            let rect = ctx.content_rect();
            painter.rect_filled(rect, 0.0, Color32::from_black_alpha(170));
            painter.text(
                rect.center(),
                Align2::CENTER_CENTER,
                format!("Drop {OPENS} to open it"),
                FontId::proportional(22.0),
                Color32::WHITE,
            );
        }
    }
}
