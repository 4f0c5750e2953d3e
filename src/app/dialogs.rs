//! Modal dialogs: recover autosaved work, unsaved changes (then new / open / quit), about.

use super::files::FilePurpose;
use super::recent::Recovery;
use super::state::Document;
use super::EditorApp;
use std::path::Path;

/// A dialog in progress.
#[derive(Clone, Debug, PartialEq)]
pub enum Dialog {
    /// Autosaved work newer than the file was found: recover it or discard it.
    Recover(Box<Recovery>),
    /// The document has unsaved changes; then do this.
    Unsaved(Then),
    /// About rgbn.
    About,
}

/// What to do once unsaved changes are dealt with.
#[derive(Clone, Debug, PartialEq)]
pub enum Then {
    /// Start a new graph.
    New,
    /// Open this file (or ask for one when empty).
    Open(String),
    /// Close the window.
    Quit,
}

impl EditorApp {
    pub(super) fn guarded(&mut self, then: Then) {
        // Groups entered in place are left first (their graphs saved).
        if !self.leave_all_groups() {
            return;
        }
        if self.session.doc.is_dirty() {
            self.dialog = Some(Dialog::Unsaved(then));
        } else {
            self.proceed(then);
        }
    }

    pub(super) fn proceed(&mut self, then: Then) {
        match then {
            Then::New => {
                self.new_doc(Document::new());
                self.say("new graph");
            }
            Then::Open(p) if p.is_empty() => self.browse(FilePurpose::Open),
            Then::Open(p) => self.open_path(Path::new(&p)),
            Then::Quit => {
                self.runtime.allow_close = true;
                if let Some(ctx) = self.runtime.wake_ctx.get() {
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
            }
        }
    }

    pub(super) fn dialogs_ui(&mut self, ctx: &egui::Context) {
        let Some(d) = self.dialog.clone() else {
            return;
        };
        let mut next = Some(d.clone());
        let mut then = None;
        let modal = egui::Modal::new(egui::Id::new("dialog")).show(ctx, |ui| {
            ui.set_min_width(380.0);
            match d {
                Dialog::Recover(r) => {
                    ui.heading("Recover unsaved work?");
                    let age = r
                        .modified
                        .elapsed()
                        .map_or_else(|_| "just now".to_string(), |d| format!("{} min ago", d.as_secs() / 60));
                    ui.label(format!(
                        "{} holds changes to {} that were never saved (autosaved {age}).",
                        r.path.display(),
                        self.session.doc.title()
                    ));
                    ui.horizontal(|ui| {
                        if ui.button("Recover").clicked() {
                            next = None;
                            self.recover(&r);
                        }
                        if ui.button("Discard").on_hover_text("Delete the recovery file").clicked() {
                            next = None;
                            let _ = std::fs::remove_file(&r.path);
                            self.say("discarded the autosaved work");
                        }
                        if ui.button("Later").on_hover_text("Keep the recovery file").clicked() {
                            next = None;
                        }
                    });
                }
                Dialog::Unsaved(t) => {
                    ui.heading("Unsaved changes");
                    ui.label(format!("{} has unsaved changes.", self.session.doc.title()));
                    ui.horizontal(|ui| {
                        if ui.button("Save").clicked() {
                            next = None;
                            then = Some(("save-then", String::new()));
                        }
                        if ui.button("Discard").clicked() {
                            next = None;
                            then = Some(("discard-then", String::new()));
                        }
                        if ui.button("Cancel").clicked() {
                            next = None;
                        }
                    });
                    if next.is_none() {
                        self.pending_then = Some(t);
                    }
                }
                Dialog::About => {
                    ui.heading("rgbn");
                    ui.label(format!("version {}", env!("CARGO_PKG_VERSION")));
                    ui.label("An editor for RGBN images (colour + normals) after Pereira & Velho, “RGBN image editing”: edits through foreshorten-corrected gradients keep the normals integrable; curl is shown everywhere.");
                    if ui.button("Close").clicked() {
                        next = None;
                    }
                }
            }
        });
        if modal.should_close() && then.is_none() {
            next = None;
        }
        self.dialog = next;
        match then {
            Some(("save-then", _)) => {
                let t = self.pending_then.take();
                if self.save() {
                    if let Some(t) = t {
                        self.proceed(t);
                    }
                }
            }
            Some(("discard-then", _)) => {
                if let Some(t) = self.pending_then.take() {
                    self.proceed(t);
                }
            }
            _ => {}
        }
    }
}
