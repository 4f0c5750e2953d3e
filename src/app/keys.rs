//! Help ▸ Keyboard shortcuts: every key and pointer gesture of the editor, one table (also in
//! docs/editor.md).

/// (where, keys, what), in the order shown.
pub const SHORTCUTS: &[(&str, &str, &str)] = &[
    ("Document", "Ctrl+N", "New graph"),
    ("Document", "Ctrl+O", "Open a graph"),
    ("Document", "Ctrl+Shift+O", "Open an image (a load node in place of the viewed chain's source)"),
    ("Document", "Ctrl+S", "Save"),
    ("Document", "Ctrl+Z / Ctrl+Shift+Z (Ctrl+Y)", "Undo / redo"),
    ("Graph", "Right-click empty space", "Add a node (searchable menu)"),
    ("Graph", "Right-click a node", "View, export, duplicate, delete, frame, group"),
    ("Graph", "Ctrl+C / Ctrl+V", "Copy / paste the selected nodes"),
    ("Graph", "Ctrl+D", "Duplicate the selected nodes"),
    ("Graph", "Delete / Backspace", "Delete the selected nodes"),
    ("Graph", "Shift+click, Shift+drag", "Add nodes to the selection"),
    ("Graph", "Right-click a wire", "Disconnect it"),
    ("Graph", "Shift+right-click a wire", "Put a reroute point there (drag it; its output fans out)"),
    ("Frames", "Ctrl+J", "Frame the selected nodes"),
    ("Frames", "Drag a frame's title", "Move the frame with its nodes"),
    ("Frames", "Double-click a frame's title", "Rename or recolour it (right-click: delete it)"),
    ("Groups", "Ctrl+G", "Group the selected nodes into a subgraph (choose the parameters to expose)"),
    ("Groups", "Ctrl+Shift+G", "Ungroup the selected group nodes"),
    ("Groups", "Double-click a group node", "Open it in place; the bar above the graph leads back"),
    ("Preview", "Ctrl+0 / double-click", "Fit the image"),
    ("Preview", "Ctrl+1", "Actual pixels"),
    ("Preview", "Shift/Alt-drag", "Move the light"),
    ("Preview", "Escape", "Abandon a stroke"),
];

/// The shortcuts as a table.
pub fn keys_ui(ui: &mut egui::Ui) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        egui::Grid::new("keys").num_columns(2).striped(true).show(ui, |ui| {
            let mut group = "";
            for (g, keys, what) in SHORTCUTS {
                if *g != group {
                    group = g;
                    ui.label(egui::RichText::new(*g).strong());
                    ui.end_row();
                }
                ui.label(egui::RichText::new(*keys).monospace());
                ui.label(*what);
                ui.end_row();
            }
        });
    });
}
