//! The menu bar, keyboard shortcuts and the Help ▸ Operators window.

use super::add_menu;
use super::dialogs::{Dialog, Then};
use super::files::FilePurpose;
use super::graph_view::Action;
use super::preview;
use super::EditorApp;
use crate::graph::NodeId;
use egui::{Key, KeyboardShortcut, Modifiers, RichText};

impl EditorApp {
    pub(super) fn shortcuts(&mut self, ctx: &egui::Context) {
        let typing = ctx.egui_wants_keyboard_input();
        if self.dialog.is_none() && self.files.is_none() {
            self.view.keys(ctx, typing, self.session.selected);
        }
        let sc = |m, k| KeyboardShortcut::new(m, k);
        let hit = |s: KeyboardShortcut| ctx.input_mut(|i| i.consume_shortcut(&s));
        if hit(sc(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z))
            || hit(sc(Modifiers::COMMAND, Key::Y))
        {
            self.redo();
        }
        if hit(sc(Modifiers::COMMAND, Key::Z)) {
            self.undo();
        }
        if hit(sc(Modifiers::COMMAND, Key::S)) {
            self.save();
        }
        if hit(sc(Modifiers::COMMAND | Modifiers::SHIFT, Key::O)) {
            self.browse(FilePurpose::OpenImage);
        }
        if hit(sc(Modifiers::COMMAND, Key::O)) {
            self.guarded(Then::Open(String::new()));
        }
        if hit(sc(Modifiers::COMMAND, Key::N)) {
            self.guarded(Then::New);
        }
        if hit(sc(Modifiers::COMMAND, Key::Num1)) {
            self.preview.set_zoom(1.0 / ctx.pixels_per_point());
        }
        if hit(sc(Modifiers::COMMAND, Key::Num0)) {
            self.preview.fit();
        }
        if !typing && self.files.is_none() {
            let (copy, paste) = ctx.input(|i| {
                (
                    i.events.iter().any(|e| matches!(e, egui::Event::Copy)),
                    i.events.iter().any(|e| matches!(e, egui::Event::Paste(_))),
                )
            });
            if copy {
                let sel = self.view.selected(ctx);
                self.copy(&sel);
            }
            if paste {
                self.paste();
            }
            let sel = self.view.selected(ctx);
            if !sel.is_empty() {
                if hit(sc(Modifiers::COMMAND, Key::D)) {
                    self.apply(Action::Duplicate(sel.clone()));
                }
                if hit(sc(Modifiers::NONE, Key::Delete)) || hit(sc(Modifiers::NONE, Key::Backspace))
                {
                    self.apply(Action::Delete(sel));
                }
            }
        }
    }

    pub(super) fn menu_ui(&mut self, ui: &mut egui::Ui, actions: &mut Vec<Action>) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("New").clicked() {
                    self.guarded(Then::New);
                    ui.close();
                }
                if ui.button("Open…").clicked() {
                    self.guarded(Then::Open(String::new()));
                    ui.close();
                }
                if ui
                    .button("Open image…")
                    .on_hover_text(
                        "Add a load node for an image (PNG, JPEG, TIFF, EXR, PTM) in place of the viewed chain's source (Ctrl+Shift+O; or drop the file on the window)",
                    )
                    .clicked()
                {
                    self.browse(FilePurpose::OpenImage);
                    ui.close();
                }
                ui.menu_button("Open recent", |ui| {
                    if self.prefs.recent.paths.is_empty() {
                        ui.weak("no recent files");
                    }
                    for p in self.prefs.recent.paths.clone() {
                        let name = p.file_name().map_or_else(
                            || p.display().to_string(),
                            |n| n.to_string_lossy().into(),
                        );
                        if ui
                            .button(name)
                            .on_hover_text(p.display().to_string())
                            .clicked()
                        {
                            self.guarded(Then::Open(p.display().to_string()));
                            ui.close();
                        }
                    }
                });
                if ui.button("Save").clicked() {
                    self.save();
                    ui.close();
                }
                if ui.button("Save As…").clicked() {
                    self.browse(FilePurpose::SaveAs);
                    ui.close();
                }
                let viewed = self.session.viewed.clone();
                if ui
                    .add_enabled(viewed.is_some(), egui::Button::new("Export viewed output…"))
                    .on_hover_text(
                        "Write the previewed node's output to EXR/PNG (any node: right-click it)",
                    )
                    .clicked()
                {
                    if let Some((id, port)) = viewed {
                        self.browse(FilePurpose::Export(id, port));
                    }
                    ui.close();
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    self.guarded(Then::Quit);
                    ui.close();
                }
            });
            ui.menu_button("Edit", |ui| {
                let (u, r) = (
                    self.session.doc.history.undo_len(),
                    self.session.doc.history.redo_len(),
                );
                if ui.add_enabled(u > 0, egui::Button::new("Undo")).clicked() {
                    self.undo();
                    ui.close();
                }
                if ui.add_enabled(r > 0, egui::Button::new("Redo")).clicked() {
                    self.redo();
                    ui.close();
                }
                ui.separator();
                let sel: Vec<NodeId> = {
                    let s = self.view.selected(ui.ctx());
                    if s.is_empty() {
                        self.session.selected.into_iter().collect()
                    } else {
                        s
                    }
                };
                if ui
                    .add_enabled(!sel.is_empty(), egui::Button::new("Delete"))
                    .clicked()
                {
                    actions.push(Action::Delete(sel.clone()));
                    ui.close();
                }
                if ui
                    .add_enabled(!sel.is_empty(), egui::Button::new("Duplicate"))
                    .clicked()
                {
                    actions.push(Action::Duplicate(sel.clone()));
                    ui.close();
                }
                if ui
                    .add_enabled(!sel.is_empty(), egui::Button::new("Copy"))
                    .clicked()
                {
                    self.copy(&sel);
                    ui.close();
                }
                if ui
                    .add_enabled(self.session.clipboard.is_some(), egui::Button::new("Paste"))
                    .clicked()
                {
                    self.paste();
                    ui.close();
                }
            });
            ui.menu_button("Add", |ui| {
                let offers = add_menu::all_offers();
                if let Some(k) = add_menu::list_ui(ui, &mut self.view.bar_search, &offers, true) {
                    self.add_node_after_selection(offers[k].spec.id);
                    self.view.bar_search = add_menu::Search::default();
                    ui.close();
                }
            });
            ui.menu_button("View", |ui| {
                for v in preview::Mode::ALL {
                    if ui
                        .selectable_label(self.prefs.settings.view == v, v.name())
                        .clicked()
                    {
                        self.prefs.settings.view = v;
                        ui.close();
                    }
                }
                ui.separator();
                if ui
                    .add(egui::Button::new("Frame selected (graph)").shortcut_text("F"))
                    .clicked()
                {
                    let sel = self.view.selected(ui.ctx());
                    self.view.frame_nodes(&sel);
                    ui.close();
                }
                if ui
                    .add(egui::Button::new("Frame all (graph)").shortcut_text("Home"))
                    .clicked()
                {
                    self.view.frame_nodes(&[]);
                    ui.close();
                }
                let uictx = ui.ctx().clone();
                let ctrl = |k| uictx.format_shortcut(&KeyboardShortcut::new(Modifiers::COMMAND, k));
                if ui
                    .add(egui::Button::new("Frame image (preview)").shortcut_text(ctrl(Key::Num0)))
                    .clicked()
                {
                    self.preview.fit();
                    ui.close();
                }
                if ui
                    .add(egui::Button::new("Actual pixels (1:1)").shortcut_text(ctrl(Key::Num1)))
                    .clicked()
                {
                    self.preview.set_zoom(1.0 / ui.ctx().pixels_per_point());
                    ui.close();
                }
            });
            ui.menu_button("Help", |ui| {
                if ui.button("Operators…").clicked() {
                    self.show_ops = true;
                    ui.close();
                }
                if ui.button("Keyboard shortcuts…").clicked() {
                    self.show_keys = true;
                    ui.close();
                }
                if ui.button("About rgbn").clicked() {
                    self.dialog = Some(Dialog::About);
                    ui.close();
                }
            });
            ui.separator();
            ui.label(RichText::new(self.session.doc.title()).weak());
        });
    }
}

/// Every operator's documentation: doc, ports, parameters.
pub(super) fn ops_doc_ui(ui: &mut egui::Ui) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        for op in crate::nodes::registry() {
            let s = op.spec();
            egui::CollapsingHeader::new(format!("{} — {} ({})", s.title, s.id, s.category)).show(
                ui,
                |ui| {
                    ui.label(s.doc);
                    for p in &s.inputs {
                        ui.label(format!("in  {} : {} — {}", p.name, p.ty.name(), p.doc));
                    }
                    for p in &s.outputs {
                        ui.label(format!("out {} : {} — {}", p.name, p.ty.name(), p.doc));
                    }
                    for p in op.params() {
                        let range = p.meta.ranges_text();
                        ui.label(format!(
                            "param {} = {}{} {}{} — {}",
                            p.name, p.default, "", p.meta.unit, range, p.meta.doc
                        ));
                    }
                },
            );
        }
    });
}
