//! Frames, reroutes and groups in the editor's UI: their node-menu entries, keys, dialogs
//! (group into a subgraph, choosing the parameters to expose; rename / recolour a frame), and
//! groups opened in place with a breadcrumb bar to leave them. The commands are in
//! [`super::structure`]; frames in the graph view in [`super::frames`].
//!
//! Keys (also in Help ▸ Keyboard shortcuts): `Ctrl+J` frames the selected nodes (Blender's
//! "join in new frame"), `Ctrl+G` groups them into a subgraph, `Ctrl+Shift+G` ungroups the
//! selected group nodes. Shift + right-click on a wire puts a reroute there; a double-click on
//! a group node opens it.

use super::graph_view::Action;
use super::params_ui;
use super::session::default_view;
use super::state::Document;
use super::structure::{context_graph, Entered};
use super::EditorApp;
use crate::graph::group::{self, Exposure};
use crate::graph::{Graph, NodeId};
use crate::nodes::GRAPH_NODE_OP;
use egui::{Key, KeyboardShortcut, Modifiers, RichText};
use std::collections::BTreeSet;
use std::path::PathBuf;

/// The "Group into subgraph" dialog.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupDialog {
    /// The nodes to group.
    pub ids: Vec<NodeId>,
    /// The group's name (its node's name, and its file's).
    pub name: String,
    /// Every parameter of the nodes: node, parameter, exposed name, exposed or not.
    pub params: Vec<(NodeId, String, String, bool)>,
}

/// The frame rename / recolour dialog.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameDialog {
    /// The frame's index.
    pub index: usize,
    /// Its title being edited.
    pub title: String,
    /// Its colour being edited.
    pub color: [u8; 3],
}

/// The dialogs of this module in progress.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StructureUi {
    /// The group dialog, when open.
    pub group: Option<GroupDialog>,
    /// The frame dialog, when open.
    pub frame: Option<FrameDialog>,
}

/// The node menu's entries for frames and groups: on the selection when the node is in it,
/// else on the node alone.
pub fn node_menu_ui(
    ui: &mut egui::Ui,
    graph: &Graph,
    id: NodeId,
    selected: &[NodeId],
    actions: &mut Vec<Action>,
) {
    let nodes = if selected.contains(&id) {
        selected.to_vec()
    } else {
        vec![id]
    };
    ui.separator();
    let many = if nodes.len() > 1 {
        format!(" ({} nodes)", nodes.len())
    } else {
        String::new()
    };
    let ctx = ui.ctx().clone();
    let key = |m, k| ctx.format_shortcut(&KeyboardShortcut::new(m, k));
    if ui
        .add(egui::Button::new(format!("Frame{many}")).shortcut_text(key(Modifiers::COMMAND, Key::J)))
        .on_hover_text("Put a titled, coloured frame around the nodes; drag its title bar to move them together")
        .clicked()
    {
        actions.push(Action::FrameNodes(nodes.clone()));
        ui.close();
    }
    if ui
        .add(egui::Button::new(format!("Group into subgraph…{many}")).shortcut_text(key(Modifiers::COMMAND, Key::G)))
        .on_hover_text("Move the nodes into a graph file of their own (lib/NAME.ron beside this graph), used here as one node")
        .clicked()
    {
        actions.push(Action::Group(nodes));
        ui.close();
    }
    if graph.nodes.get(&id).is_some_and(|n| n.op == GRAPH_NODE_OP) {
        if ui
            .button("Open group")
            .on_hover_text("Edit the group's graph in place (also: double-click the node); the bar above the graph leads back")
            .clicked()
        {
            actions.push(Action::EnterGroup(id));
            ui.close();
        }
        if ui
            .add(
                egui::Button::new("Ungroup")
                    .shortcut_text(key(Modifiers::COMMAND | Modifiers::SHIFT, Key::G)),
            )
            .on_hover_text("Put the group's nodes back in its place")
            .clicked()
        {
            actions.push(Action::Ungroup(id));
            ui.close();
        }
    }
}

impl EditorApp {
    /// `Ctrl+J`, `Ctrl+G`, `Ctrl+Shift+G` on the graph view's selection.
    pub(super) fn structure_shortcuts(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() || self.files.is_some() || self.dialog.is_some() {
            return;
        }
        let hit = |m, k| ctx.input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(m, k)));
        let sel = self.view.selected(ctx);
        if hit(Modifiers::COMMAND | Modifiers::SHIFT, Key::G) {
            let groups: Vec<NodeId> = sel
                .into_iter()
                .filter(|id| {
                    let g = &self.session.doc.graph;
                    g.nodes.get(id).is_some_and(|n| n.op == GRAPH_NODE_OP)
                })
                .collect();
            for id in groups {
                self.apply_structure(Action::Ungroup(id));
            }
        } else if hit(Modifiers::COMMAND, Key::G) && !sel.is_empty() {
            self.apply_structure(Action::Group(sel));
        } else if hit(Modifiers::COMMAND, Key::J) && !sel.is_empty() {
            self.apply_structure(Action::FrameNodes(sel));
        }
    }

    /// Applies a frame, reroute or group action.
    pub(super) fn apply_structure(&mut self, a: Action) {
        match a {
            Action::FrameNodes(ids) => match self.session.doc.add_frame(&ids, "Frame") {
                Some(i) => self.say(format!(
                    "framed {} node(s): double-click the frame's title to rename or recolour it",
                    self.session.doc.graph.frames[i].nodes.len()
                )),
                None => self.fail("nothing to frame: select nodes first"),
            },
            Action::EditFrame(i) => self.open_frame_dialog(i),
            Action::DeleteFrame(i) => {
                self.session.doc.delete_frame(i);
                self.say("frame deleted (its nodes stay)");
            }
            Action::InsertReroute {
                from,
                from_port,
                to,
                port,
                pos,
            } => match self
                .session
                .doc
                .insert_reroute(from, &from_port, to, &port, pos)
            {
                Ok(id) => self.say(format!(
                    "reroute #{id} on #{from}.{from_port} → #{to}.{port}"
                )),
                Err(e) => self.fail(format!("no reroute: {e}")),
            },
            Action::Group(ids) => self.open_group_dialog(ids),
            Action::Ungroup(id) => match self.session.doc.ungroup(id) {
                Ok(new) => {
                    if self.session.viewed.as_ref().is_some_and(|v| v.0 == id) {
                        self.session.viewed = None;
                    }
                    self.session.selected = new.last().copied();
                    self.say(format!("ungrouped #{id} into {} node(s)", new.len()));
                }
                Err(e) => self.fail(format!("cannot ungroup: {e}")),
            },
            Action::EnterGroup(id) => self.enter_group(id),
            other => self.apply(other),
        }
    }

    fn open_frame_dialog(&mut self, index: usize) {
        if let Some(f) = self.session.doc.graph.frames.get(index) {
            self.structure.frame = Some(FrameDialog {
                index,
                title: f.title.clone(),
                color: f.color,
            });
        }
    }

    fn open_group_dialog(&mut self, ids: Vec<NodeId>) {
        let g = &self.session.doc.graph;
        let ids: Vec<NodeId> = ids
            .into_iter()
            .filter(|id| g.nodes.contains_key(id))
            .collect();
        if ids.is_empty() {
            self.fail("nothing to group: select nodes first");
            return;
        }
        let base = self.session.doc.base_dir();
        let mut taken = BTreeSet::new();
        let mut params = Vec::new();
        for id in &ids {
            for (name, _, _) in params_ui::node_params(g, *id, &base) {
                if name == "path" && g.nodes[id].op == GRAPH_NODE_OP {
                    continue;
                }
                let who = g.nodes[id].name.clone().unwrap_or_else(|| format!("n{id}"));
                let mut exposed = name.clone();
                if taken.contains(&exposed) || exposed == "path" {
                    exposed = format!("{who}_{name}");
                }
                let mut k = 2;
                while taken.contains(&exposed) {
                    exposed = format!("{who}_{name}_{k}");
                    k += 1;
                }
                taken.insert(exposed.clone());
                params.push((*id, name, exposed, false));
            }
        }
        self.structure.group = Some(GroupDialog {
            ids,
            name: "group".into(),
            params,
        });
    }

    /// Groups as the dialog says; returns the group node.
    pub fn group_from_dialog(&mut self, d: &GroupDialog) -> Option<NodeId> {
        let expose: Vec<Exposure> = d
            .params
            .iter()
            .filter(|p| p.3)
            .map(|(node, param, name, _)| Exposure {
                node: *node,
                param: param.clone(),
                name: name.clone(),
            })
            .collect();
        match self.session.doc.group(&d.ids, &d.name, &expose) {
            Ok((id, file)) => {
                self.session.selected = Some(id);
                if self
                    .session
                    .viewed
                    .as_ref()
                    .is_some_and(|v| d.ids.contains(&v.0))
                {
                    self.session.viewed = None;
                }
                self.say(format!(
                    "grouped {} node(s) into #{id} ({})",
                    d.ids.len(),
                    file.display()
                ));
                Some(id)
            }
            Err(e) => {
                self.fail(format!("cannot group: {e}"));
                None
            }
        }
    }

    /// The dialogs of this module.
    pub(super) fn structure_dialogs_ui(&mut self, ctx: &egui::Context) {
        if let Some(mut d) = self.structure.group.take() {
            let mut keep = true;
            let mut go = false;
            egui::Modal::new(egui::Id::new("group-dialog")).show(ctx, |ui| {
                ui.set_min_width(420.0);
                ui.heading("Group into subgraph");
                ui.horizontal(|ui| {
                    ui.label("name");
                    ui.text_edit_singleline(&mut d.name);
                });
                ui.label(
                    RichText::new(format!(
                        "{} node(s) go into {} (beside the graph); wires crossing the selection become its inputs and outputs.",
                        d.ids.len(),
                        self.session.doc.lib_path_for(&d.name)
                    ))
                    .small(),
                );
                ui.separator();
                ui.label("Parameters to expose on the group node:");
                egui::ScrollArea::vertical().max_height(280.0).show(ui, |ui| {
                    for (node, param, exposed, on) in &mut d.params {
                        let title = super::graph_view::node_title(&self.session.doc.graph, *node);
                        ui.checkbox(on, format!("{title} · {param}"))
                            .on_hover_text(format!("exposed as {exposed:?}"));
                    }
                });
                ui.separator();
                ui.horizontal(|ui| {
                    if ui.button("Group").clicked() {
                        go = true;
                    }
                    if ui.button("Cancel").clicked() {
                        keep = false;
                    }
                });
            });
            if go {
                self.group_from_dialog(&d);
            } else if keep {
                self.structure.group = Some(d);
            }
        }
        if let Some(mut d) = self.structure.frame.take() {
            let (mut keep, mut ok, mut delete) = (true, false, false);
            egui::Modal::new(egui::Id::new("frame-dialog")).show(ctx, |ui| {
                ui.heading("Frame");
                ui.horizontal(|ui| {
                    ui.label("title");
                    let r = ui.text_edit_singleline(&mut d.title);
                    if r.lost_focus() && ui.input(|i| i.key_pressed(Key::Enter)) {
                        ok = true;
                    }
                });
                ui.horizontal(|ui| {
                    ui.label("colour");
                    ui.color_edit_button_srgb(&mut d.color);
                });
                ui.horizontal(|ui| {
                    if ui.button("OK").clicked() {
                        ok = true;
                    }
                    if ui.button("Delete frame").clicked() {
                        delete = true;
                    }
                    if ui.button("Cancel").clicked() {
                        keep = false;
                    }
                });
            });
            if ok {
                self.session.doc.edit_frame(d.index, &d.title, d.color);
            } else if delete {
                self.session.doc.delete_frame(d.index);
            } else if keep {
                self.structure.frame = Some(d);
            }
        }
    }

    /// The graph the worker evaluates and the folder its paths are relative to: the document,
    /// or inside groups the group's graph fed from outside ([`context_graph`]).
    pub(super) fn eval_context(&self) -> (Graph, PathBuf) {
        let base = self.session.doc.base_dir();
        (
            context_graph(&self.session.groups, &self.session.doc.graph, &base),
            base,
        )
    }

    /// True when the document, or one around the group being edited, has unsaved changes.
    #[must_use]
    pub fn any_unsaved(&self) -> bool {
        self.session.doc.is_dirty() || self.session.groups.iter().any(|e| e.doc.is_dirty())
    }

    /// Groups entered, outermost first (the breadcrumb's titles).
    #[must_use]
    pub fn group_path(&self) -> Vec<String> {
        self.session
            .groups
            .iter()
            .map(|e| e.doc.title())
            .chain([self.session.doc.title()])
            .collect()
    }

    /// Opens graph node `id` in place: its subgraph becomes the document edited, fed from
    /// outside; the breadcrumb bar leads back.
    pub fn enter_group(&mut self, id: NodeId) {
        let base = self.session.doc.base_dir();
        let file = match group::read_sub(&self.session.doc.graph, id, &base) {
            Ok((_, file)) => file,
            Err(e) => {
                self.fail(format!("cannot open the group: {e}"));
                return;
            }
        };
        let inner = match Document::open(&file) {
            Ok(d) => d,
            Err(e) => {
                self.fail(format!("cannot open the group: {e}"));
                return;
            }
        };
        let outer = Entered {
            doc: self.session.doc.clone(),
            node: id,
            selected: self.session.selected,
            viewed: self.session.viewed.clone(),
        };
        let mut groups = std::mem::take(&mut self.session.groups);
        groups.push(outer);
        self.new_doc(inner);
        self.session.groups = groups;
        self.say(format!(
            "inside {} (the bar above the graph leads back)",
            file.display()
        ));
    }

    /// Leaves the innermost group, saving its graph when changed. False (and still inside)
    /// when it cannot be saved.
    pub fn leave_group(&mut self) -> bool {
        let Some(outer) = self.session.groups.pop() else {
            return true;
        };
        if self.session.doc.is_dirty() {
            let path = self.session.doc.path.clone().unwrap_or_default();
            if let Err(e) = self.session.doc.save_as(&path) {
                self.session.groups.push(outer);
                self.fail(format!("the group's graph was not saved: {e}"));
                return false;
            }
            self.say(format!("saved {}", path.display()));
        }
        let groups = std::mem::take(&mut self.session.groups);
        let Entered {
            doc,
            node,
            selected,
            viewed,
        } = outer;
        self.new_doc(doc);
        self.session.groups = groups;
        self.session.selected = selected.or(Some(node));
        self.session.viewed = viewed.or_else(|| default_view(&self.session.doc.graph));
        // The group's ports may have changed with its file.
        self.runtime.ports_for = None;
        true
    }

    /// Leaves every group entered (saving their graphs); false when one could not be saved.
    pub fn leave_all_groups(&mut self) -> bool {
        while !self.session.groups.is_empty() {
            if !self.leave_group() {
                return false;
            }
        }
        true
    }

    /// The breadcrumb bar above the graph while inside a group: the graph files from the
    /// outermost; a click on one leaves the groups inside it.
    pub(super) fn breadcrumb_ui(&mut self, ui: &mut egui::Ui) {
        if self.session.groups.is_empty() {
            return;
        }
        let path = self.group_path();
        let mut leave_to = None;
        ui.horizontal(|ui| {
            ui.label(RichText::new("in group:").weak());
            for (i, t) in path.iter().enumerate() {
                if i > 0 {
                    ui.label("▸");
                }
                if i + 1 == path.len() {
                    ui.label(RichText::new(t).strong());
                } else if ui
                    .button(t)
                    .on_hover_text("Leave the group (its graph is saved if changed)")
                    .clicked()
                {
                    leave_to = Some(i);
                }
            }
        });
        ui.separator();
        if let Some(level) = leave_to {
            while self.session.groups.len() > level {
                if !self.leave_group() {
                    break;
                }
            }
        }
    }
}
