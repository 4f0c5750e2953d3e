//! On-image tools, free of egui: the mapping from pointer gestures on the preview to graph
//! parameters. The egui side ([`super::tools_ui`]) only turns pointer events into calls here
//! and draws overlays; everything that decides what a gesture does to the graph is here and
//! unit-tested without a window.
//!
//! - **Pen**: a drag draws a path in image pixels (one of `pen.paths`). It extends a path of
//!   the selected pen node when it starts at one of that path's ends (or the newest path with
//!   Shift), replaces a pen node's untouched default path, and otherwise adds a new path to the
//!   selected pen node; a new pen node is made when no pen node is selected, or with the
//!   toolbar's "new node" toggle ([`ToolState::pen_new_node`]) or Ctrl held.
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
//!
//! Files: `coords` (screen ↔ image mapping, point lists), `graph_edit` (the node a tool edits,
//! inserting a node after the viewed output, parameter access), `gesture` (a gesture in
//! progress and its undo step), `stroke` (pen and brush strokes), `stamp` (placements and
//! handles), `vertices` (dragging and deleting vertices).

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

mod coords;
mod gesture;
mod graph_edit;
mod stamp;
mod stroke;
#[cfg(test)]
mod test_util;
mod vertices;

pub use coords::{hit_vertex, push_simplified, ViewTransform};
pub use gesture::{Gesture, GestureKind, Press};
pub use graph_edit::{
    has_own_points, insert_after, locate_vertex, min_points, node_points, param, param_f64,
    pen_paths, points_param, target, Target,
};
pub use stamp::{place_stamp, StampFrame, StampHandle};
pub use stroke::{Stroke, StrokeMode};
pub use vertices::delete_vertex;

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
    /// A pen stroke makes a new pen node instead of a new path of the selected one.
    pub pen_new_node: bool,
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
            pen_new_node: false,
            brush_radius_px: 12.0,
            brush_feather_px: 6.0,
            live: true,
        }
    }
}
