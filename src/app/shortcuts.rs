//! The editor's keys, listed once: Help ▸ Keyboard shortcuts shows this table, and a test
//! checks that docs/editor.md names every key in it.

/// (keys, what they do), in the order shown.
pub const SHORTCUTS: &[(&str, &str)] = &[
    (
        "Tab / Shift+A",
        "Add node: opens the add menu at the pointer (over the graph)",
    ),
    (
        "Right-click",
        "Add node where clicked (empty graph space); on a node: its menu",
    ),
    (
        "Drag a wire into empty space",
        "Add a node that takes it, connected",
    ),
    ("Type", "In the add menu: filter the operators"),
    ("↑ / ↓", "In the add menu: move the highlight"),
    ("Enter", "In the add menu: add the highlighted operator"),
    (
        "Escape",
        "Close the add menu; abandon a stroke on the image",
    ),
    ("F", "Frame the selected nodes (all when none is selected)"),
    ("Home", "Frame all nodes"),
    ("Shift+drag", "Select nodes in a rectangle (graph)"),
    ("Delete / Backspace", "Delete the selected nodes"),
    ("Ctrl+D", "Duplicate the selected nodes"),
    ("Ctrl+C / Ctrl+V", "Copy / paste nodes"),
    ("Ctrl+Z / Ctrl+Shift+Z", "Undo / redo (also Ctrl+Y)"),
    (
        "Ctrl+J",
        "Put the selected nodes in a frame (a titled, coloured box)",
    ),
    ("Drag a frame's title", "Move the frame with its nodes"),
    (
        "Double-click a frame's title",
        "Rename or recolour the frame (right-click: delete it)",
    ),
    (
        "Shift+right-click a wire",
        "Put a reroute point there (or add \"Reroute\" from the add menu)",
    ),
    (
        "Ctrl+G",
        "Group the selected nodes into a subgraph (choose the parameters to expose)",
    ),
    ("Ctrl+Shift+G", "Ungroup the selected group nodes"),
    (
        "Double-click a group node",
        "Open the group in place; the bar above the graph leads back",
    ),
    ("Ctrl+N", "New graph"),
    ("Ctrl+O", "Open a graph"),
    ("Ctrl+Shift+O", "Open an image"),
    ("Ctrl+S", "Save"),
    ("Ctrl+0", "Fit the image in the preview"),
    ("Ctrl+1", "Actual pixels (1:1) in the preview"),
    ("Space+drag", "Pan the preview while a tool is active"),
];

/// The Help ▸ Keyboard shortcuts window's contents.
pub fn shortcuts_ui(ui: &mut egui::Ui) {
    egui::Grid::new("shortcuts")
        .num_columns(2)
        .striped(true)
        .spacing([16.0, 4.0])
        .show(ui, |ui| {
            for (keys, what) in SHORTCUTS {
                ui.label(egui::RichText::new(*keys).monospace());
                ui.label(*what);
                ui.end_row();
            }
        });
}
