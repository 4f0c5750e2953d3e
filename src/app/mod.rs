//! The editor (feature `gui`): egui + egui-snarl over the same graphs the CLI runs. This is the
//! only module that uses egui.
//!
//! - [`state`]: the document (graph, file, undo history) and edit commands — no egui;
//! - [`worker`]: evaluation on a worker thread, generations, thumbnails; of egui it uses only
//!   `egui::ColorImage`, the rendered picture it hands the UI thread (no widgets, no context);
//! - [`graph_view`]: the node graph (egui-snarl as a view of the graph); [`green_badge`]: the
//!   `load` nodes' OpenGL / DirectX verdicts, checked off the UI thread;
//! - [`params_ui`]: the inspector; [`preview`]: the relit preview;
//! - [`tools`]: on-image pen, stamp, brush and vertex tools — no egui; [`tools_ui`]: their
//!   toolbar and overlays.
//!
//! [`EditorApp`] groups its state as [`prefs`] (preferences), [`session`] (the open document,
//! selection, clipboard) and [`runtime`] (evaluation requests and results, timing; its
//! [`EditorApp::poll`] runs once per frame from `eframe::App::logic`). Its behaviour is split
//! by concern: [`files`] (file dialog, open / save / export, autosave and recovery),
//! [`images`] (open an image or drop a file: a `load` node wired into the viewed chain; where
//! new nodes go, with the pure geometry in [`placement`]), [`dialogs`] (modal dialogs),
//! `menu` (menu bar, shortcuts), [`structure_ui`] (frames, reroutes, groups entered in place;
//! their commands in [`structure`], frames in the view in [`frames`]); this file holds the frame layout, the panels and the graph
//! commands.
//!
//! Layout: menu bar; node graph | preview | inspector (resizable); status bar with evaluation
//! progress, cache memory and the viewed node's curl.

pub mod add_menu;
pub mod crisp;
pub mod dialogs;
pub mod files;
pub mod frames;
pub mod graph_view;
pub mod green_badge;
pub mod images;
pub mod memory;
mod menu;
pub mod params_ui;
pub mod placement;
pub mod prefs;
pub mod preview;
pub mod recent;
pub mod refresh;
pub mod runtime;
pub mod session;
pub mod shortcuts;
pub mod soak;
pub mod start;
pub mod state;
pub mod structure;
pub mod structure_ui;
pub mod tools;
pub mod tools_ui;
pub mod worker;

pub use dialogs::{Dialog, Then};
pub use files::FilePurpose;

use crate::graph::{NodeId, Source};

/// The tracing target of the editor's timings: `RUST_LOG=rgbn::editor::timing=info` logs them
/// (`RGBN_EDITOR_TIMING=1` is an alias the binary keeps).
pub const TIMING: &str = "rgbn::editor::timing";

/// Whether the editor's timings are logged.
#[must_use]
pub fn timing_enabled() -> bool {
    tracing::enabled!(target: TIMING, tracing::Level::INFO)
}
use crate::nodes::Value;
use egui::{Color32, RichText, TextureHandle};
use graph_view::{Action, GraphView, ViewData};
use menu::ops_doc_ui;
use prefs::Preferences;
use preview::Preview;
use recent::RecentFiles;
use runtime::Runtime;
use session::Session;
use state::Document;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Opens the editor window on `start` (see [`start::Start`]).
pub fn run(start: &start::Start) -> Result<(), String> {
    let app = start.app()?;
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1560.0, 940.0])
            .with_min_inner_size([800.0, 500.0])
            .with_title(format!("rgbn — {}", app.session.doc.title())),
        ..Default::default()
    };
    eframe::run_native(
        "rgbn",
        options,
        Box::new(move |_cc| {
            let mut app = app;
            app.prefs.recent = RecentFiles::user();
            if let Some(p) = app.session.doc.path.clone() {
                let _ = app.prefs.recent.push(&p);
            }
            app.offer_recovery();
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| e.to_string())
}

/// A status-bar message.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Status {
    /// The text.
    pub text: String,
    /// Shown in red.
    pub error: bool,
}

/// The editor application.
///
/// State is grouped by lifetime: [`Preferences`] (how the user likes to work, across
/// documents), [`Session`] (the open document and what is selected and viewed in it),
/// [`Runtime`] (evaluation on the worker thread, its results and timing); the rest are the UI
/// components and the open dialogs.
pub struct EditorApp {
    /// Preview settings, recent files, the file dialog's folder.
    pub prefs: Preferences,
    /// The document and its selection.
    pub session: Session,
    /// Evaluation state and results.
    pub runtime: Runtime,
    view: GraphView,
    /// The preview.
    pub preview: Preview,
    /// On-image tools (pen, stamp, brush, vertices).
    pub tools: tools_ui::Tools,
    /// The green-convention badges of the `load` nodes (checked off the UI thread).
    pub green: green_badge::GreenBadges,
    /// Status-bar message.
    pub status: Status,
    /// An open dialog.
    pub dialog: Option<Dialog>,
    /// What an "Unsaved changes" dialog will do once answered.
    pending_then: Option<Then>,
    /// The open file dialog and what its pick is for.
    files: Option<(egui_file_dialog::FileDialog, FilePurpose)>,
    /// An export asked for before its value was evaluated (path, node, port): written when
    /// the value arrives.
    pending_export: Option<(std::path::PathBuf, NodeId, String)>,
    /// The Help ▸ Operators window is open.
    show_ops: bool,
    /// The Help ▸ Keyboard shortcuts window is open.
    show_keys: bool,
    /// The frame and group dialogs.
    pub structure: structure_ui::StructureUi,
    /// Nodes the editor placed that it keeps clear of others until they are drawn evaluated
    /// (their size is known only then): position given, frames left once evaluated.
    placed: BTreeMap<NodeId, ([f32; 2], u8)>,
    last_widget_selection: Vec<NodeId>,
}

impl EditorApp {
    /// An editor on `doc`; the worker thread starts at once.
    #[must_use]
    pub fn new(doc: Document) -> Self {
        Self {
            prefs: Preferences::default(),
            session: Session::new(doc),
            runtime: Runtime::new(),
            view: GraphView::default(),
            preview: Preview::default(),
            tools: tools_ui::Tools::default(),
            green: green_badge::GreenBadges::default(),
            status: Status::default(),
            dialog: None,
            pending_then: None,
            files: None,
            pending_export: None,
            show_ops: false,
            show_keys: false,
            structure: structure_ui::StructureUi::default(),
            placed: BTreeMap::new(),
            last_widget_selection: Vec::new(),
        }
    }

    /// The graph view (its add menu, transform, drawn node rectangles).
    #[must_use]
    pub fn graph_view(&self) -> &GraphView {
        &self.view
    }

    /// Fits the graph view to `ids` (all nodes when empty), as F and Home do.
    pub fn frame_graph_nodes(&mut self, ids: &[NodeId]) {
        self.view.frame_nodes(ids);
    }

    /// Copies nodes to the editor's clipboard (and their RON text to the system clipboard).
    pub fn copy(&mut self, ids: &[NodeId]) {
        let nodes = self.session.doc.copy(ids);
        if nodes.is_empty() {
            return;
        }
        if let (Some(ctx), Ok(text)) = (
            self.runtime.wake_ctx.get(),
            ron::ser::to_string_pretty(&nodes, ron::ser::PrettyConfig::default()),
        ) {
            ctx.copy_text(text);
        }
        self.say(format!("copied {} node(s)", nodes.len()));
        self.session.clipboard = Some((self.session.doc_epoch, nodes));
    }

    /// Pastes the clipboard's nodes (offset; edges from outside the copied set kept when they
    /// were copied from this document). Returns the new ids.
    pub fn paste(&mut self) -> Vec<NodeId> {
        let Some((epoch, nodes)) = self.session.clipboard.clone() else {
            return Vec::new();
        };
        let new = self
            .session
            .doc
            .paste(&nodes, [40.0, 60.0], epoch == self.session.doc_epoch);
        self.session.selected = new.last().copied();
        self.say(format!("pasted {} node(s)", new.len()));
        new
    }

    fn say(&mut self, text: impl Into<String>) {
        self.status = Status {
            text: text.into(),
            error: false,
        };
    }

    fn fail(&mut self, text: impl Into<String>) {
        self.status = Status {
            text: text.into(),
            error: true,
        };
    }

    /// The value the preview shows and its key.
    fn viewed_value(&self) -> Option<(&Value, u128)> {
        let (id, port) = self.session.viewed.as_ref()?;
        let v = self.runtime.outcome.values.get(&(*id, port.clone()))?;
        Some((&v.value, v.key))
    }

    /// The "before" of the viewed node for the split view: the value on its first input wired
    /// to an RGBN output, when the viewed value is RGBN too.
    fn before_value(&self) -> Option<(&Value, u128)> {
        let (id, port) = self.session.viewed.as_ref()?;
        let viewed = self.runtime.outcome.values.get(&(*id, port.clone()))?;
        if !matches!(viewed.value, Value::Rgbn(_)) {
            return None;
        }
        let node = self.session.doc.graph.nodes.get(id)?;
        let ports = self.runtime.ports.get(id)?;
        ports.inputs.iter().find_map(|i| {
            let Source::Node(src, sp) = node.inputs.get(&i.name)? else {
                return None;
            };
            let v = self.runtime.outcome.values.get(&(*src, sp.clone()))?;
            matches!(v.value, Value::Rgbn(_)).then_some((&v.value, v.key))
        })
    }

    /// True while an evaluation, its integrability readouts or a preview render are under way.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.evaluating() || self.runtime.readouts_pending || self.preview.pending()
    }

    /// Applies a graph-view action to the document.
    pub fn apply(&mut self, a: Action) {
        match a {
            Action::AddNode { op, pos } => {
                let pos = self.place_node(&op, pos, false);
                let id = self.session.doc.add_node(&op, pos);
                self.watch_placed(id);
                self.session.selected = Some(id);
                self.say(format!("added {op} (#{id})"));
            }
            Action::AddWired {
                op,
                pos,
                wire,
                port,
            } => {
                self.add_wired(&op, pos, &wire, &port);
            }
            Action::Connect {
                from,
                from_port,
                to,
                port,
            } => match self.session.doc.connect(from, &from_port, to, &port) {
                Ok(()) => self.say(format!("connected #{from}.{from_port} → #{to}.{port}")),
                Err(e) => self.fail(format!("connection refused: {e}")),
            },
            Action::Disconnect { to, port } => {
                self.session.doc.disconnect(to, &port);
                self.say(format!("disconnected #{to}.{port}"));
            }
            Action::Delete(ids) => {
                self.session.doc.delete(&ids);
                if self.session.selected.is_some_and(|s| ids.contains(&s)) {
                    self.session.selected = None;
                }
                if self
                    .session
                    .viewed
                    .as_ref()
                    .is_some_and(|v| ids.contains(&v.0))
                {
                    self.session.viewed = None;
                    self.preview.clear();
                }
                self.say(format!("deleted {} node(s)", ids.len()));
            }
            Action::Duplicate(ids) => {
                let new = self.session.doc.duplicate(&ids, [40.0, 60.0]);
                self.session.selected = new.last().copied();
                self.say(format!("duplicated {} node(s)", new.len()));
            }
            Action::View(id) => self.view_node(id),
            Action::ViewPort(id, port) => {
                self.session.selected = Some(id);
                self.session.viewed = Some((id, port));
            }
            Action::Export(id) => {
                let port = self
                    .runtime
                    .ports
                    .get(&id)
                    .and_then(|p| p.outputs.first())
                    .map(|o| o.name.clone());
                match port {
                    Some(port) => self.browse(FilePurpose::Export(id, port)),
                    None => self.fail(format!("node #{id} has no output to export")),
                }
            }
            Action::BrowseParam(id, name) => self.browse(FilePurpose::Param(id, name)),
            other => self.apply_structure(other),
        }
    }

    /// Shows node `id`'s first output in the preview.
    pub fn view_node(&mut self, id: NodeId) {
        self.session.selected = Some(id);
        let base = self.session.doc.base_dir();
        let port = self
            .session
            .doc
            .graph
            .node_ports(id, &base)
            .ok()
            .and_then(|p| p.outputs.first().map(|o| o.name.clone()));
        if let Some(port) = port {
            if self.session.viewed.as_ref() != Some(&(id, port.clone())) {
                self.session.viewed = Some((id, port));
            }
        }
    }

    /// Adds a node of `op` after the selected node (connected to it when the types fit), as one
    /// undo step, where it overlaps no other node.
    pub fn add_node_after_selection(&mut self, op: &str) -> NodeId {
        let base = self.session.doc.base_dir();
        let (pos, after) = match self
            .session
            .selected
            .and_then(|s| self.session.doc.graph.nodes.get(&s))
        {
            Some(n) => ([n.pos[0] + 260.0, n.pos[1] + 40.0], Some(n.id)),
            None => {
                let x = self
                    .session
                    .doc
                    .graph
                    .nodes
                    .values()
                    .map(|n| n.pos[0])
                    .fold(-260.0f32, f32::max);
                ([x + 260.0, 0.0], None)
            }
        };
        let pos = self.place_node(op, pos, after.is_some());
        let before = self.session.doc.graph.clone();
        let id = self.session.doc.graph.add_node(op, pos);
        if let Some(a) = after {
            let out = self.session.doc.graph.node_ports(a, &base).ok();
            let inp = self.session.doc.graph.node_ports(id, &base).ok();
            if let (Some(out), Some(inp)) = (out, inp) {
                if let Some(i) = inp.inputs.first() {
                    if let Some(o) = out.outputs.iter().find(|o| o.ty == i.ty) {
                        let _ = self
                            .session
                            .doc
                            .graph
                            .connect(a, &o.name, id, &i.name, &base);
                    }
                }
            }
        }
        self.session.doc.history.commit(before);
        self.watch_placed(id);
        self.session.selected = Some(id);
        self.view_node(id);
        self.say(format!("added {op} (#{id})"));
        id
    }

    fn undo(&mut self) {
        if self.session.doc.undo() {
            self.say("undo");
        }
    }

    fn redo(&mut self) {
        if self.session.doc.redo() {
            self.say("redo");
        }
    }

    /// The whole editor UI for one frame (used by eframe and by the UI tests). Results of the
    /// worker are taken by [`poll`](Self::poll), which eframe runs before each frame from
    /// `App::logic`; a test harness calls it before this.
    pub fn frame_ui(&mut self, ui: &mut egui::Ui) {
        let t0 = Instant::now();
        let ctx = ui.ctx().clone();
        if ctx.input(|i| i.viewport().close_requested())
            && !self.runtime.allow_close
            && self.any_unsaved()
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.guarded(Then::Quit);
        }
        // Before `before`: moving a just-placed node off others is part of placing it, not
        // an edit of its own.
        self.keep_placed_clear();
        let before = self.session.doc.graph.clone();
        let (version, epoch) = (self.session.doc.history.version(), self.session.doc_epoch);
        let mut actions = Vec::new();
        self.shortcuts(&ctx);
        self.structure_shortcuts(&ctx);
        self.dropped_files_ui(&ctx);

        // Panels are not filled: the frame is cleared to their colour (`clear_color`), and
        // with software GL (llvmpipe) every filled pixel costs — the fills were a third of
        // each frame's fragments.
        let side = egui::Frame::side_top_panel(ui.style()).fill(Color32::TRANSPARENT);
        let central = egui::Frame::central_panel(ui.style()).fill(Color32::TRANSPARENT);
        egui::Panel::top("menu")
            .frame(side)
            .show(ui, |ui| self.menu_ui(ui, &mut actions));
        egui::Panel::bottom("status")
            .frame(side)
            .show(ui, |ui| self.status_ui(ui));
        egui::Panel::right("inspector")
            .frame(side)
            .resizable(true)
            .default_size(300.0)
            .size_range(220.0..=600.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.inspector_ui(ui));
            });
        self.refresh_ports();
        self.view.sync(&self.session.doc.graph, &self.runtime.ports);
        egui::Panel::left("graph")
            .frame(side)
            .resizable(true)
            .default_size(640.0)
            .size_range(300.0..=1400.0)
            .show(ui, |ui| {
                self.breadcrumb_ui(ui);
                let tex: BTreeMap<NodeId, TextureHandle> = self
                    .runtime
                    .thumbs
                    .iter()
                    .map(|(k, (_, t))| (*k, t.clone()))
                    .collect();
                let base_dir = self.session.doc.base_dir();
                let green = self
                    .green
                    .update(&self.session.doc.graph, &base_dir, ui.ctx());
                let data = ViewData {
                    graph: &self.session.doc.graph,
                    ports: &self.runtime.ports,
                    thumbs: &tex,
                    errors: &self.runtime.outcome.node_errors,
                    waiting: &self.runtime.outcome.waiting,
                    fraction: &self.runtime.outcome.fraction,
                    green: &green,
                    viewed: self.session.viewed.as_ref().map(|v| v.0),
                    viewed_port: self.session.viewed.as_ref().map(|v| v.1.as_str()),
                    base_dir: &base_dir,
                };
                actions.extend(self.view.show_ui(ui, &data));
            });
        self.view.write_back_positions(&mut self.session.doc.graph);
        egui::CentralPanel::default()
            .frame(central)
            .show(ui, |ui| self.preview_ui(ui));
        self.dialogs_ui(&ctx);
        self.structure_dialogs_ui(&ctx);
        self.file_dialog_ui(&ctx);
        if self.show_ops {
            let mut open = true;
            egui::Window::new("Operators")
                .open(&mut open)
                .default_size([520.0, 600.0])
                .show(&ctx, ops_doc_ui);
            self.show_ops = open;
        }
        if self.show_keys {
            let mut open = true;
            egui::Window::new("Keyboard shortcuts")
                .open(&mut open)
                .resizable(false)
                .show(&ctx, shortcuts::shortcuts_ui);
            self.show_keys = open;
        }

        // Selection drives the inspector and the preview.
        // (Only a change of the widget's selection counts: commands select nodes too.)
        let sel = self.view.selected(&ctx);
        if sel != self.last_widget_selection {
            if let [one] = sel.as_slice() {
                self.view_node(*one);
            }
            self.last_widget_selection = sel;
        }

        // Undo: continuous edits (drags, typing) become one step when the interaction ends.
        if self.session.doc.history.version() == version && self.session.doc_epoch == epoch {
            let interacting =
                ctx.input(|i| i.pointer.any_down()) || ctx.egui_wants_keyboard_input();
            self.session
                .doc
                .history
                .record(&before, &self.session.doc.graph, interacting);
        }
        for a in actions {
            self.apply(a);
        }
        // An edit made in this frame is evaluated now, not when the next frame starts.
        self.send_if_changed();
        self.autosave(&ctx);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        self.runtime.frame_ms = 0.9 * self.runtime.frame_ms + 0.1 * ms;
        if self.runtime.in_flight.is_some() {
            let (n, sum, max) = self.runtime.eval_frames;
            self.runtime.eval_frames = (n + 1, sum + ms, max.max(ms));
        }
        // Only when it changes: a viewport command asks for another frame, so sending it every
        // frame kept the editor repainting (and two cores busy) while idle.
        let title = format!("rgbn — {}", self.session.doc.title());
        if self.runtime.title.as_ref() != Some(&title) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.runtime.title = Some(title);
        }
    }

    fn status_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if let Some(f) = &self.runtime.in_flight {
                let (done, total) = self.runtime.progress.unwrap_or((0, 0));
                let frac = if total > 0 { done as f32 / total as f32 } else { 0.0 };
                ui.add(
                    egui::ProgressBar::new(frac)
                        .desired_width(140.0)
                        .text(format!("evaluating {done}/{total}")),
                );
                if f.started.elapsed() > Duration::from_millis(300) && ui.small_button("Cancel").clicked() {
                    self.cancel();
                }
                ui.ctx().request_repaint_after(Duration::from_millis(100));
            } else if self.runtime.outcome.viewport_only {
                ui.label("viewport evaluated");
            } else {
                ui.label(format!(
                    "evaluated in {:.0} ms ({} computed)",
                    self.runtime.outcome.elapsed.as_secs_f64() * 1e3,
                    self.runtime.outcome.computed
                ));
            }
            ui.separator();
            memory::status_ui(ui, &self.runtime.outcome.memory);
            ui.separator();
            let viewed = self.session.viewed.as_ref().map(|v| v.0);
            let outcome = &self.runtime.outcome;
            match viewed.and_then(|v| outcome.fraction.get(&v).map(|f| (f, outcome.curl.get(&v)))) {
                Some((f, c)) => ui.label(format!(
                    "F {f:.2e} · curl {}",
                    c.map_or_else(|| "—".into(), |c| format!("{c:.2e}"))
                )),
                None => ui.label("F —"),
            }
            .on_hover_text("Integrability of the viewed node's normals. F: the non-integrable fraction ‖e − ∇z*‖/‖e‖ of its edge slopes (z* the least-squares height): 0 for a surface, √(2/π) ≈ 0.80 for noise. curl: RMS(curl)/RMS(|gradient|).");
            ui.separator();
            if let Some((_, Some((_, level)))) =
                self.preview.overlay_request().map(|r| (r, r.region))
            {
                let coming = if self.runtime.outcome.viewport_only && self.runtime.in_flight.is_none() {
                    "whole output too large for the editor (rgbn eval computes it)"
                } else {
                    "whole output coming"
                };
                if self.preview.region().is_some_and(|r| r.coarse) {
                    ui.label(format!(
                        "viewport · level {level} (1:{}) while editing · level shown coming",
                        1u32 << level
                    ))
                    .on_hover_text(
                        "The viewed output depends on a global operator (an integration or projection): while edits keep coming it is computed at a coarse level, on that level's pixels. The level shown, then the whole output, follow once edits pause.",
                    );
                } else {
                    ui.label(format!("viewport · level {level} (1:{}) · {coming}", 1u32 << level))
                        .on_hover_text(
                            "The part of the viewed output on screen was evaluated first, tile by tile at the level shown; the whole output follows once edits pause.",
                        );
                }
                ui.separator();
            }
            let level = self.preview.shown_level();
            if level > 0 {
                ui.label(format!("level {level} (1:{})", 1u32 << level)).on_hover_text(
                    "Zoomed out: the preview shows a level of detail, each screen pixel the mean of a block of image pixels (as rgbn eval --level). Zoom to 100 % for every pixel.",
                );
                ui.separator();
            }
            ui.label(RichText::new(format!("ui {:.1} ms", self.runtime.frame_ms)).weak());
            ui.separator();
            let color = if self.status.error {
                Color32::from_rgb(255, 110, 110)
            } else {
                ui.visuals().text_color()
            };
            ui.add(
                egui::Label::new(RichText::new(&self.status.text).color(color))
                    .truncate(),
            )
            .on_hover_text(&self.status.text);
        });
    }

    fn inspector_ui(&mut self, ui: &mut egui::Ui) {
        ui.heading("Inspector");
        ui.separator();
        let Some(id) = self
            .session
            .selected
            .filter(|s| self.session.doc.graph.nodes.contains_key(s))
        else {
            ui.weak("Select a node to edit its parameters.");
            ui.weak("Right-click the graph, or press Tab over it, to add nodes (the Add menu adds after the selected node).");
            return;
        };
        let base = self.session.doc.base_dir();
        if let Some(name) = params_ui::inspector_ui(ui, &mut self.session.doc.graph, id, &base) {
            self.browse(FilePurpose::Param(id, name));
        }
        if let Some(e) = self.runtime.outcome.node_errors.get(&id) {
            ui.separator();
            ui.colored_label(Color32::from_rgb(255, 110, 110), e);
        } else if let Some(port) = self.runtime.outcome.waiting.get(&id) {
            ui.separator();
            ui.label(format!(
                "Waits for input {port}: connect it to evaluate this node."
            ));
        }
        ui.separator();
        ui.horizontal(|ui| {
            if ui.button("View output").clicked() {
                self.view_node(id);
            }
            if ui.button("Duplicate").clicked() {
                self.apply(Action::Duplicate(vec![id]));
            }
            if ui.button("Delete").clicked() {
                self.apply(Action::Delete(vec![id]));
            }
        });
    }

    fn preview_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.heading("Preview");
            if let Some((id, port)) = self.session.viewed.clone() {
                ui.label(format!(
                    "{} · {port}",
                    graph_view::node_title(&self.session.doc.graph, id)
                ));
                let outs: Vec<String> = self
                    .runtime
                    .ports
                    .get(&id)
                    .map(|p| p.outputs.iter().map(|o| o.name.clone()).collect())
                    .unwrap_or_default();
                if outs.len() > 1 {
                    for o in outs {
                        if ui.selectable_label(o == port, &o).clicked() {
                            self.session.viewed = Some((id, o));
                        }
                    }
                }
            }
        });
        let before = self.before_value().map(|(v, k)| (v.clone(), k));
        preview::settings_ui(
            ui,
            &mut self.prefs.settings,
            &mut self.preview.split,
            before.is_some(),
        );
        self.tools.toolbar_ui(ui);
        ui.separator();
        let ctx = ui.ctx().clone();
        let current = self.viewed_value().map(|(v, k)| (v.clone(), k));
        let renders = self.preview.renders;
        match &current {
            Some((v, k)) => {
                let mut req = Preview::request(v, *k, &self.prefs.settings);
                let before = before.filter(|_| self.preview.split.is_some());
                req.before = before.as_ref().map(|b| b.1);
                self.preview
                    .update(&ctx, v, before.as_ref().map(|b| &b.0), req);
                if self.preview.renders != renders {
                    if let Some((first, last)) = self.tools.preview_rendered() {
                        if self.prefs.timing {
                            tracing::info!(target: TIMING, "tool edit → relit preview after {last:.0} ms (newest edit shown), {first:.0} ms (oldest; texture render {:.0} ms)",
                                self.preview.render_ms
                            );
                        }
                    }
                }
            }
            // A node a tool just made: keep the last picture until it is evaluated; an output
            // too large to evaluate whole is shown by its viewport only.
            None if self.runtime.in_flight.is_some() || self.runtime.outcome.viewport_only => {}
            None => self.preview.clear(),
        }
        if self.preview.update_region(&ctx, &self.prefs.settings) && self.prefs.timing {
            if let Some((first, last)) = self.tools.preview_rendered() {
                tracing::info!(target: TIMING, "tool edit → relit viewport after {last:.0} ms (newest edit shown), {first:.0} ms (oldest)"
                );
            } else if let Some(ms) = self.preview.overlay_render_ms {
                tracing::info!(target: TIMING, "viewport re-rendered in {ms:.1} ms");
            }
        }
        if self.runtime.first_preview.is_none()
            && (self.preview.renders > 0 || self.preview.overlays > 0)
        {
            let t = self.runtime.started.elapsed();
            self.runtime.first_preview = Some(t);
            if self.prefs.timing {
                tracing::info!(target: TIMING, "first preview after {:.0} ms",
                    t.as_secs_f64() * 1e3
                );
            }
        }
        let stamp_size = self.session.selected.and_then(|s| {
            let n = self
                .session
                .doc
                .graph
                .nodes
                .get(&s)
                .filter(|n| n.op == "stamp")?;
            let Source::Node(src, port) = n.inputs.get("stamp")? else {
                return None;
            };
            match &self
                .runtime
                .outcome
                .values
                .get(&(*src, port.clone()))?
                .value
            {
                Value::Rgbn(img) => Some([img.width(), img.height()]),
                _ => None,
            }
        });
        let mut cx = tools_ui::ToolCx {
            doc: &mut self.session.doc,
            selected: &mut self.session.selected,
            viewed: &mut self.session.viewed,
            stamp_size,
            message: None,
        };
        let readout_h = 22.0;
        let mut rect_ui = ui.available_size();
        rect_ui.y -= readout_h;
        let mut readout = None;
        ui.allocate_ui(rect_ui, |ui| {
            readout = self.preview.image_ui(
                ui,
                current.as_ref().map(|(v, k)| (v, *k)),
                Some((&mut self.tools, &mut cx)),
            );
        });
        if let Some(l) = self.preview.light_request.take() {
            self.prefs.settings.light = l;
        }
        if let Some(m) = cx.message.take() {
            self.say(m);
        }
        let text = match (&current, &self.session.viewed) {
            (_, None) => "Click a node to view its output.".to_string(),
            (None, Some((id, _))) => match self.runtime.outcome.node_errors.get(id) {
                Some(e) => format!("error: {e}"),
                None if self.runtime.outcome.waiting.contains_key(id) => format!(
                    "node #{id} waits for input {}: connect it",
                    self.runtime.outcome.waiting[id]
                ),
                None if self.runtime.in_flight.is_some() => "evaluating…".into(),
                None if self.runtime.outcome.viewport_only => format!(
                    "viewport only: the output is larger than the editor evaluates whole ({} Mpx); pan and zoom evaluate what is shown, rgbn eval computes all of it",
                    worker::WHOLE_PIXELS >> 20
                ),
                None => "no value (a save node, or an output that cannot be shown)".into(),
            },
            (Some(_), _) => readout
                .unwrap_or_else(|| "scroll to zoom, drag to pan, double-click to fit".to_string()),
        };
        ui.label(RichText::new(text).monospace().small());
    }
}

/// eframe calls [`logic`](eframe::App::logic) once before every [`ui`](eframe::App::ui) (and
/// also while the window is hidden): the worker is polled there, once per frame.
impl eframe::App for EditorApp {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        self.poll(ctx);
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.frame_ui(ui);
    }

    /// The panels' colour: they are drawn unfilled on it (see `frame_ui`).
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }
}
