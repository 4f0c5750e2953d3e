//! The editor (feature `gui`): egui + egui-snarl over the same graphs the CLI runs. This is the
//! only module that uses egui.
//!
//! - [`state`]: the document (graph, file, undo history) and edit commands — no egui;
//! - [`worker`]: evaluation on a worker thread, generations, thumbnails — no egui;
//! - [`graph_view`]: the node graph (egui-snarl as a view of the graph);
//! - [`params_ui`]: the inspector; [`preview`]: the relit preview;
//! - [`tools`]: on-image pen, stamp and brush tools — no egui; [`tools_ui`]: their toolbar and
//!   overlays.
//!
//! Layout: menu bar; node graph | preview | inspector (resizable); status bar with evaluation
//! progress, cache memory and the viewed node's curl.

pub mod graph_view;
pub mod params_ui;
pub mod preview;
pub mod recent;
pub mod state;
pub mod tools;
pub mod tools_ui;
pub mod worker;

use crate::graph::{Graph, NodeDef, NodeId, NodePorts};
use crate::ops::Value;
use egui::{Color32, Key, KeyboardShortcut, Modifiers, RichText, TextureHandle, TextureOptions};
use graph_view::{Action, GraphView, ViewData};
use preview::{Preview, PreviewSettings};
use recent::{RecentFiles, Recovery};
use state::Document;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};
use worker::{EvalOutcome, EvalRequest, Generations, Worker, WorkerMsg};

/// Opens the editor window on `graph` (default: `graphs/demo.ron`, else the built-in demo).
pub fn run(graph: Option<PathBuf>) -> Result<(), String> {
    let doc = match &graph {
        Some(p) => Document::open(p).map_err(|e| e.to_string())?,
        None => {
            let p = Path::new("graphs/demo.ron");
            if p.is_file() {
                Document::open(p).unwrap_or_else(|_| Document::demo())
            } else {
                Document::demo()
            }
        }
    };
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1560.0, 940.0])
            .with_min_inner_size([800.0, 500.0])
            .with_title(format!("rgbn — {}", doc.title())),
        ..Default::default()
    };
    eframe::run_native(
        "rgbn",
        options,
        Box::new(move |_cc| {
            let mut app = EditorApp::new(doc);
            app.recent = RecentFiles::user();
            if let Some(p) = app.doc.path.clone() {
                let _ = app.recent.push(&p);
            }
            app.offer_recovery();
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| e.to_string())
}

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

/// What a file picked in the file dialog is for.
#[derive(Clone, Debug, PartialEq)]
pub enum FilePurpose {
    /// Open this graph.
    Open,
    /// Save the graph here.
    SaveAs,
    /// Write this node's output port here.
    Export(NodeId, String),
    /// Set this path parameter of this node.
    Param(NodeId, String),
}

/// A status-bar message.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Status {
    /// The text.
    pub text: String,
    /// Shown in red.
    pub error: bool,
}

struct InFlight {
    cancel: Arc<AtomicBool>,
    started: Instant,
}

/// The editor application.
pub struct EditorApp {
    /// The document.
    pub doc: Document,
    view: GraphView,
    worker: Worker,
    wake_ctx: Arc<OnceLock<egui::Context>>,
    gens: Generations,
    in_flight: Option<InFlight>,
    /// The evaluation-relevant graph of the last request (positions zeroed).
    last_sent: Option<Graph>,
    /// Progress of the running evaluation (done, total).
    pub progress: Option<(usize, usize)>,
    /// The latest accepted evaluation.
    pub outcome: EvalOutcome,
    thumbs: BTreeMap<NodeId, (Arc<crate::ops::Picture>, TextureHandle)>,
    ports: BTreeMap<NodeId, NodePorts>,
    ports_for: Option<Graph>,
    /// The node whose parameters the inspector shows.
    pub selected: Option<NodeId>,
    /// The node shown in the preview, and which of its outputs.
    pub viewed: Option<(NodeId, String)>,
    /// Preview display settings.
    pub settings: PreviewSettings,
    /// The preview.
    pub preview: Preview,
    /// Status-bar message.
    pub status: Status,
    /// An open dialog.
    pub dialog: Option<Dialog>,
    show_ops: bool,
    allow_close: bool,
    pending_then: Option<Then>,
    doc_epoch: u64,
    started: Instant,
    /// Time from start to the first preview texture.
    pub first_preview: Option<Duration>,
    frame_ms: f64,
    /// Frame times (ms) while the current evaluation runs: count, sum, max.
    eval_frames: (u32, f64, f64),
    timing: bool,
    last_autosave: Instant,
    last_widget_selection: Vec<NodeId>,
    /// Evaluation requests sent (tests).
    pub requests: u64,
    /// Recently used graph files (File ▸ Open recent).
    pub recent: RecentFiles,
    /// The open file dialog and what its pick is for.
    files: Option<(egui_file_dialog::FileDialog, FilePurpose)>,
    /// The folder the file dialog opens in: the last one used, else the graph's folder.
    pub dialog_dir: Option<PathBuf>,
    /// Copied nodes and the document epoch they were copied in.
    clipboard: Option<(u64, Vec<NodeDef>)>,
    /// On-image tools (pen, stamp, brush, vertices).
    pub tools: tools_ui::Tools,
}

impl EditorApp {
    /// An editor on `doc`; the worker thread starts at once.
    #[must_use]
    pub fn new(doc: Document) -> Self {
        let wake_ctx: Arc<OnceLock<egui::Context>> = Arc::new(OnceLock::new());
        let w = wake_ctx.clone();
        let worker = Worker::spawn(Arc::new(move || {
            if let Some(ctx) = w.get() {
                ctx.request_repaint();
            }
        }));
        let viewed = default_view(&doc.graph);
        Self {
            selected: viewed.as_ref().map(|v| v.0),
            viewed,
            doc,
            view: GraphView::default(),
            worker,
            wake_ctx,
            gens: Generations::default(),
            in_flight: None,
            last_sent: None,
            progress: None,
            outcome: EvalOutcome::default(),
            thumbs: BTreeMap::new(),
            ports: BTreeMap::new(),
            ports_for: None,
            settings: PreviewSettings::default(),
            preview: Preview::default(),
            status: Status::default(),
            dialog: None,
            show_ops: false,
            allow_close: false,
            pending_then: None,
            doc_epoch: 0,
            started: Instant::now(),
            first_preview: None,
            frame_ms: 0.0,
            eval_frames: (0, 0.0, 0.0),
            timing: std::env::var_os("RGBN_EDITOR_TIMING").is_some(),
            requests: 0,
            last_autosave: Instant::now(),
            last_widget_selection: Vec::new(),
            recent: RecentFiles::default(),
            files: None,
            dialog_dir: None,
            clipboard: None,
            tools: tools_ui::Tools::default(),
        }
    }

    /// If the document's recovery file holds newer, different work, asks whether to restore it.
    pub fn offer_recovery(&mut self) {
        if let Some(r) = recent::recovery_offer(self.doc.path.as_deref(), &self.doc.graph) {
            self.dialog = Some(Dialog::Recover(Box::new(r)));
        }
    }

    /// Replaces the graph with the recovered one (one undo step back to the file's graph); the
    /// document stays unsaved until the user saves.
    pub fn recover(&mut self, r: &Recovery) {
        let before = self.doc.graph.clone();
        self.doc.graph = r.graph.clone();
        self.doc.history.commit(before);
        self.say(format!("recovered unsaved work from {}", r.path.display()));
    }

    /// True while the file dialog is open.
    #[must_use]
    pub fn file_dialog_open(&self) -> bool {
        self.files.is_some()
    }

    /// Opens the file dialog for `purpose`.
    pub fn browse(&mut self, purpose: FilePurpose) {
        use egui_file_dialog::FileDialog;
        let dir = match &self.dialog_dir {
            Some(d) if d.is_dir() => d.clone(),
            _ => recent::absolute(&self.doc.base_dir()),
        };
        let d = FileDialog::new().initial_directory(dir);
        let mut d = match &purpose {
            FilePurpose::Open => d
                .title("Open graph")
                .add_file_filter_extensions("Graphs (*.ron)", vec!["ron"])
                .default_file_filter("Graphs (*.ron)"),
            FilePurpose::SaveAs => {
                let name = self
                    .doc
                    .path
                    .as_deref()
                    .and_then(Path::file_name)
                    .map_or_else(|| "graph.ron".to_string(), |n| n.to_string_lossy().into());
                d.title("Save graph as").default_file_name(&name)
            }
            FilePurpose::Export(id, port) => {
                let ext = match self.outcome.values.get(&(*id, port.clone())) {
                    Some(v) if matches!(v.value, Value::Rgbn(_)) => "exr",
                    _ => "png",
                };
                d.title("Export output")
                    .default_file_name(&format!("node{id}-{port}.{ext}"))
            }
            FilePurpose::Param(_, name) => d.title(&format!("Choose {name}")),
        };
        match purpose {
            FilePurpose::Open | FilePurpose::Param(..) => d.pick_file(),
            FilePurpose::SaveAs | FilePurpose::Export(..) => d.save_file(),
        }
        self.files = Some((d, purpose));
    }

    /// Acts on a file picked for `purpose`.
    pub fn picked(&mut self, path: &Path, purpose: FilePurpose) {
        self.dialog_dir = path.parent().map(Path::to_path_buf);
        match purpose {
            FilePurpose::Open => self.open_path(path),
            FilePurpose::SaveAs => {
                self.save_to(path);
            }
            FilePurpose::Export(id, port) => self.export(path, id, &port),
            FilePurpose::Param(id, name) => {
                let base = recent::absolute(&self.doc.base_dir());
                let rel = path.strip_prefix(&base).unwrap_or(path);
                let v = crate::ops::params::ParamValue::Path(rel.to_string_lossy().into_owned());
                self.doc.set_param(id, &name, v);
                self.say(format!("#{id}.{name} = {}", rel.display()));
            }
        }
    }

    fn file_dialog_ui(&mut self, ctx: &egui::Context) {
        let Some((d, _)) = &mut self.files else {
            return;
        };
        d.update(ctx);
        match d.state() {
            egui_file_dialog::DialogState::Open => {}
            egui_file_dialog::DialogState::Picked(p) => {
                let p = p.clone();
                if let Some((_, purpose)) = self.files.take() {
                    self.picked(&p, purpose);
                }
            }
            _ => self.files = None,
        }
    }

    /// Copies nodes to the editor's clipboard (and their RON text to the system clipboard).
    pub fn copy(&mut self, ids: &[NodeId]) {
        let nodes = self.doc.copy(ids);
        if nodes.is_empty() {
            return;
        }
        if let (Some(ctx), Ok(text)) = (
            self.wake_ctx.get(),
            ron::ser::to_string_pretty(&nodes, ron::ser::PrettyConfig::default()),
        ) {
            ctx.copy_text(text);
        }
        self.say(format!("copied {} node(s)", nodes.len()));
        self.clipboard = Some((self.doc_epoch, nodes));
    }

    /// Pastes the clipboard's nodes (offset; edges from outside the copied set kept when they
    /// were copied from this document). Returns the new ids.
    pub fn paste(&mut self) -> Vec<NodeId> {
        let Some((epoch, nodes)) = self.clipboard.clone() else {
            return Vec::new();
        };
        let new = self
            .doc
            .paste(&nodes, [40.0, 60.0], epoch == self.doc_epoch);
        self.selected = new.last().copied();
        self.say(format!("pasted {} node(s)", new.len()));
        new
    }

    /// True while an evaluation is running or a newer graph waits to be sent.
    #[must_use]
    pub fn evaluating(&self) -> bool {
        self.in_flight.is_some() || self.last_sent.as_ref() != Some(&eval_graph(&self.doc.graph))
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

    /// Takes worker messages, accepts current results, sends a new request when the graph
    /// changed and none is running. Never blocks.
    pub fn poll(&mut self, ctx: &egui::Context) {
        let _ = self.wake_ctx.set(ctx.clone());
        while let Some(msg) = self.worker.poll() {
            match msg {
                WorkerMsg::Progress {
                    generation,
                    done,
                    total,
                } => {
                    if generation == self.gens.latest() {
                        self.progress = Some((done, total));
                    }
                }
                WorkerMsg::Done(out) => {
                    if self.gens.accept(out.generation) {
                        self.in_flight = None;
                        self.progress = None;
                        if self.timing {
                            let (n, sum, max) = self.eval_frames;
                            eprintln!(
                                "rgbn editor: evaluation {} took {:.0} ms ({} computed); {n} UI frames meanwhile, mean {:.2} ms, max {:.2} ms",
                                out.generation,
                                out.elapsed.as_secs_f64() * 1e3,
                                out.computed,
                                if n > 0 { sum / f64::from(n) } else { 0.0 },
                                max
                            );
                        }
                        self.eval_frames = (0, 0.0, 0.0);
                        if out.cancelled {
                            self.say("evaluation cancelled");
                        } else {
                            self.accept_outcome(ctx, *out);
                        }
                    }
                }
            }
        }
        let want = eval_graph(&self.doc.graph);
        if self.in_flight.is_none() && self.last_sent.as_ref() != Some(&want) {
            let cancel = Arc::new(AtomicBool::new(false));
            self.worker.send(EvalRequest {
                generation: self.gens.new_request(),
                graph: self.doc.graph.clone(),
                base_dir: self.doc.base_dir(),
                cancel: cancel.clone(),
            });
            self.requests += 1;
            self.tools.request_sent();
            self.in_flight = Some(InFlight {
                cancel,
                started: Instant::now(),
            });
            self.last_sent = Some(want);
        }
    }

    fn accept_outcome(&mut self, ctx: &egui::Context, out: EvalOutcome) {
        // Thumbnail textures: re-upload only the pictures that changed.
        let mut thumbs = BTreeMap::new();
        for (id, pic) in &out.thumbs {
            let tex = match self.thumbs.remove(id) {
                Some((old, tex)) if Arc::ptr_eq(&old, pic) || *old == **pic => tex,
                _ => ctx.load_texture(
                    format!("thumb-{id}"),
                    egui::ColorImage::from_rgba_unmultiplied([pic.width, pic.height], &pic.rgba),
                    TextureOptions::LINEAR,
                ),
            };
            thumbs.insert(*id, (pic.clone(), tex));
        }
        self.thumbs = thumbs;
        if let Some(e) = &out.error {
            self.fail(e.clone());
        } else if !out.node_errors.is_empty() {
            let (id, e) = out.node_errors.iter().next().expect("not empty");
            self.fail(format!(
                "{} node(s) failed; #{id}: {e}",
                out.node_errors.len()
            ));
        } else if self.status.error {
            self.status = Status::default();
        }
        self.outcome = out;
    }

    fn cancel(&mut self) {
        if let Some(f) = &self.in_flight {
            f.cancel.store(true, Ordering::Relaxed);
        }
    }

    fn refresh_ports(&mut self) {
        if self.ports_for.as_ref() == Some(&self.doc.graph) {
            return;
        }
        let base = self.doc.base_dir();
        self.ports = self
            .doc
            .graph
            .nodes
            .keys()
            .filter_map(|id| Some((*id, self.doc.graph.node_ports(*id, &base).ok()?)))
            .collect();
        self.ports_for = Some(self.doc.graph.clone());
    }

    /// The value the preview shows and its key.
    fn viewed_value(&self) -> Option<(&Value, u128)> {
        let (id, port) = self.viewed.as_ref()?;
        let v = self.outcome.values.get(&(*id, port.clone()))?;
        Some((&v.value, v.key))
    }

    /// The "before" of the viewed node for the split view: the value on its first input wired
    /// to an RGBN output, when the viewed value is RGBN too.
    fn before_value(&self) -> Option<(&Value, u128)> {
        let (id, port) = self.viewed.as_ref()?;
        let viewed = self.outcome.values.get(&(*id, port.clone()))?;
        if !matches!(viewed.value, Value::Rgbn(_)) {
            return None;
        }
        let node = self.doc.graph.nodes.get(id)?;
        let ports = self.ports.get(id)?;
        ports.inputs.iter().find_map(|i| {
            let crate::graph::Source::Node(src, sp) = node.inputs.get(&i.name)? else {
                return None;
            };
            let v = self.outcome.values.get(&(*src, sp.clone()))?;
            matches!(v.value, Value::Rgbn(_)).then_some((&v.value, v.key))
        })
    }

    /// True while an evaluation or a preview render is under way.
    #[must_use]
    pub fn busy(&self) -> bool {
        self.evaluating() || self.preview.pending()
    }

    /// Applies a graph-view action to the document.
    pub fn apply(&mut self, a: Action) {
        match a {
            Action::AddNode { op, pos } => {
                let id = self.doc.add_node(&op, pos);
                self.selected = Some(id);
                self.say(format!("added {op} (#{id})"));
            }
            Action::Connect {
                from,
                from_port,
                to,
                port,
            } => match self.doc.connect(from, &from_port, to, &port) {
                Ok(()) => self.say(format!("connected #{from}.{from_port} → #{to}.{port}")),
                Err(e) => self.fail(format!("connection refused: {e}")),
            },
            Action::Disconnect { to, port } => {
                self.doc.disconnect(to, &port);
                self.say(format!("disconnected #{to}.{port}"));
            }
            Action::Delete(ids) => {
                self.doc.delete(&ids);
                if self.selected.is_some_and(|s| ids.contains(&s)) {
                    self.selected = None;
                }
                if self.viewed.as_ref().is_some_and(|v| ids.contains(&v.0)) {
                    self.viewed = None;
                    self.preview.clear();
                }
                self.say(format!("deleted {} node(s)", ids.len()));
            }
            Action::Duplicate(ids) => {
                let new = self.doc.duplicate(&ids, [40.0, 60.0]);
                self.selected = new.last().copied();
                self.say(format!("duplicated {} node(s)", new.len()));
            }
            Action::View(id) => self.view_node(id),
            Action::ViewPort(id, port) => {
                self.selected = Some(id);
                self.viewed = Some((id, port));
            }
            Action::Export(id) => {
                let port = self
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
        }
    }

    /// Shows node `id`'s first output in the preview.
    pub fn view_node(&mut self, id: NodeId) {
        self.selected = Some(id);
        let base = self.doc.base_dir();
        let port = self
            .doc
            .graph
            .node_ports(id, &base)
            .ok()
            .and_then(|p| p.outputs.first().map(|o| o.name.clone()));
        if let Some(port) = port {
            if self.viewed.as_ref() != Some(&(id, port.clone())) {
                self.viewed = Some((id, port));
            }
        }
    }

    /// Adds a node of `op` after the selected node (connected to it when the types fit), as one
    /// undo step.
    pub fn add_node_after_selection(&mut self, op: &str) -> NodeId {
        let base = self.doc.base_dir();
        let (pos, after) = match self.selected.and_then(|s| self.doc.graph.nodes.get(&s)) {
            Some(n) => ([n.pos[0] + 260.0, n.pos[1] + 40.0], Some(n.id)),
            None => {
                let x = self
                    .doc
                    .graph
                    .nodes
                    .values()
                    .map(|n| n.pos[0])
                    .fold(-260.0f32, f32::max);
                ([x + 260.0, 0.0], None)
            }
        };
        let before = self.doc.graph.clone();
        let id = self.doc.graph.add_node(op, pos);
        if let Some(a) = after {
            let out = self.doc.graph.node_ports(a, &base).ok();
            let inp = self.doc.graph.node_ports(id, &base).ok();
            if let (Some(out), Some(inp)) = (out, inp) {
                if let Some(i) = inp.inputs.first() {
                    if let Some(o) = out.outputs.iter().find(|o| o.ty == i.ty) {
                        let _ = self.doc.graph.connect(a, &o.name, id, &i.name, &base);
                    }
                }
            }
        }
        self.doc.history.commit(before);
        self.selected = Some(id);
        self.view_node(id);
        self.say(format!("added {op} (#{id})"));
        id
    }

    fn new_doc(&mut self, doc: Document) {
        self.cancel();
        self.doc_epoch += 1;
        self.doc = doc;
        self.viewed = default_view(&self.doc.graph);
        self.selected = self.viewed.as_ref().map(|v| v.0);
        self.preview.clear();
        self.outcome = EvalOutcome::default();
        self.thumbs.clear();
        self.last_sent = None;
        self.in_flight = None; // its result will be stale
        self.view.frame_pending = 3;
    }

    /// Opens a graph file (no unsaved-changes check).
    pub fn open_path(&mut self, path: &Path) {
        match Document::open(path) {
            Ok(d) => {
                self.new_doc(d);
                self.say(format!("opened {}", path.display()));
                if let Err(e) = self.recent.push(path) {
                    tracing::warn!("recent files not saved: {e}");
                }
                self.offer_recovery();
            }
            Err(e) => {
                if !path.exists() {
                    let _ = self.recent.remove(path);
                }
                self.fail(e.to_string());
            }
        }
    }

    /// Saves to `path`.
    pub fn save_to(&mut self, path: &Path) -> bool {
        let old_recovery = self.recovery_path();
        match self.doc.save_as(path) {
            Ok(()) => {
                let _ = std::fs::remove_file(old_recovery);
                let _ = std::fs::remove_file(self.recovery_path());
                self.say(format!("saved {}", path.display()));
                if let Err(e) = self.recent.push(path) {
                    tracing::warn!("recent files not saved: {e}");
                }
                true
            }
            Err(e) => {
                self.fail(e.to_string());
                false
            }
        }
    }

    fn save(&mut self) -> bool {
        match self.doc.path.clone() {
            Some(p) => self.save_to(&p),
            None => {
                self.browse(FilePurpose::SaveAs);
                false
            }
        }
    }

    fn guarded(&mut self, then: Then) {
        if self.doc.is_dirty() {
            self.dialog = Some(Dialog::Unsaved(then));
        } else {
            self.proceed(then);
        }
    }

    fn proceed(&mut self, then: Then) {
        match then {
            Then::New => {
                self.new_doc(Document::new());
                self.say("new graph");
            }
            Then::Open(p) if p.is_empty() => self.browse(FilePurpose::Open),
            Then::Open(p) => self.open_path(Path::new(&p)),
            Then::Quit => {
                self.allow_close = true;
                if let Some(ctx) = self.wake_ctx.get() {
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
            }
        }
    }

    /// Writes output `port` of node `id` to `path` (format from the extension; atomic; never
    /// over one of the graph's input files).
    pub fn export(&mut self, path: &Path, id: NodeId, port: &str) {
        let Some(v) = self.outcome.values.get(&(id, port.to_string())) else {
            self.fail(format!(
                "nothing to export: node #{id} has no value on {port:?} yet (still evaluating, or it failed)"
            ));
            return;
        };
        let v = v.value.clone();
        // Never over one of the graph's own files (inputs, sub-graphs) or the graph itself.
        let base = self.doc.base_dir();
        let mut files: Vec<PathBuf> = self
            .doc
            .graph
            .nodes
            .values()
            .flat_map(|n| n.params.values())
            .filter_map(|p| match p {
                crate::ops::params::ParamValue::Path(p) if !p.is_empty() => Some(base.join(p)),
                _ => None,
            })
            .collect();
        files.extend(self.doc.path.clone());
        let inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
        if let Err(e) = crate::raster::io::check_output(path, &inputs) {
            self.fail(e.to_string());
            return;
        }
        match crate::ops::save::write_value(&v, path, &crate::raster::io::SaveOptions::default()) {
            Ok(()) => self.say(format!("exported {}", path.display())),
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// Where unsaved work is kept: beside the file (`.NAME.autosave.ron`), or in the temporary
    /// folder for an untitled graph.
    #[must_use]
    pub fn recovery_path(&self) -> PathBuf {
        recent::recovery_path(self.doc.path.as_deref())
    }

    /// Every 30 s with unsaved changes, writes the graph to the recovery file.
    fn autosave(&mut self) {
        if self.last_autosave.elapsed() < Duration::from_secs(30) {
            return;
        }
        self.last_autosave = Instant::now();
        if self.doc.is_dirty() {
            if let Err(e) = self.doc.graph.save(&self.recovery_path()) {
                self.fail(format!("autosave failed: {e}"));
            }
        }
    }

    fn undo(&mut self) {
        if self.doc.undo() {
            self.say("undo");
        }
    }

    fn redo(&mut self) {
        if self.doc.redo() {
            self.say("redo");
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let typing = ctx.egui_wants_keyboard_input();
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
        if hit(sc(Modifiers::COMMAND, Key::O)) {
            self.guarded(Then::Open(String::new()));
        }
        if hit(sc(Modifiers::COMMAND, Key::N)) {
            self.guarded(Then::New);
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

    /// The whole editor UI for one frame (used by eframe and by the UI tests).
    pub fn frame_ui(&mut self, ui: &mut egui::Ui) {
        let t0 = Instant::now();
        let ctx = ui.ctx().clone();
        self.poll(&ctx);
        if ctx.input(|i| i.viewport().close_requested()) && !self.allow_close && self.doc.is_dirty()
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.dialog = Some(Dialog::Unsaved(Then::Quit));
        }
        let before = self.doc.graph.clone();
        let (version, epoch) = (self.doc.history.version(), self.doc_epoch);
        let mut actions = Vec::new();
        self.shortcuts(&ctx);

        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui, &mut actions));
        egui::Panel::bottom("status").show(ui, |ui| self.status_ui(ui));
        egui::Panel::right("inspector")
            .resizable(true)
            .default_size(300.0)
            .size_range(220.0..=600.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.inspector_ui(ui));
            });
        self.refresh_ports();
        self.view.sync(&self.doc.graph, &self.ports);
        egui::Panel::left("graph")
            .resizable(true)
            .default_size(640.0)
            .size_range(300.0..=1400.0)
            .show(ui, |ui| {
                let tex: BTreeMap<NodeId, TextureHandle> = self
                    .thumbs
                    .iter()
                    .map(|(k, (_, t))| (*k, t.clone()))
                    .collect();
                let data = ViewData {
                    graph: &self.doc.graph,
                    ports: &self.ports,
                    thumbs: &tex,
                    errors: &self.outcome.node_errors,
                    viewed: self.viewed.as_ref().map(|v| v.0),
                    viewed_port: self.viewed.as_ref().map(|v| v.1.as_str()),
                };
                actions.extend(self.view.show_ui(ui, &data));
            });
        self.view.write_back_positions(&mut self.doc.graph);
        egui::CentralPanel::default().show(ui, |ui| self.preview_ui(ui));
        self.dialogs_ui(&ctx);
        self.file_dialog_ui(&ctx);
        if self.show_ops {
            let mut open = true;
            egui::Window::new("Operators")
                .open(&mut open)
                .default_size([520.0, 600.0])
                .show(&ctx, ops_doc_ui);
            self.show_ops = open;
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
        if self.doc.history.version() == version && self.doc_epoch == epoch {
            let interacting =
                ctx.input(|i| i.pointer.any_down()) || ctx.egui_wants_keyboard_input();
            self.doc
                .history
                .record(&before, &self.doc.graph, interacting);
        }
        for a in actions {
            self.apply(a);
        }
        self.autosave();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        self.frame_ms = 0.9 * self.frame_ms + 0.1 * ms;
        if self.in_flight.is_some() {
            let (n, sum, max) = self.eval_frames;
            self.eval_frames = (n + 1, sum + ms, max.max(ms));
        }
        let title = format!("rgbn — {}", self.doc.title());
        ctx.send_viewport_cmd(egui::ViewportCommand::Title(title));
    }

    fn menu_ui(&mut self, ui: &mut egui::Ui, actions: &mut Vec<Action>) {
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
                ui.menu_button("Open recent", |ui| {
                    if self.recent.paths.is_empty() {
                        ui.weak("no recent files");
                    }
                    for p in self.recent.paths.clone() {
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
                let viewed = self.viewed.clone();
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
                let (u, r) = (self.doc.history.undo_len(), self.doc.history.redo_len());
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
                        self.selected.into_iter().collect()
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
                    .add_enabled(self.clipboard.is_some(), egui::Button::new("Paste"))
                    .clicked()
                {
                    self.paste();
                    ui.close();
                }
            });
            ui.menu_button("Add", |ui| {
                if let Some(op) = graph_view::add_node_menu_ui(ui, &mut self.view.search) {
                    self.add_node_after_selection(op);
                }
            });
            ui.menu_button("View", |ui| {
                for v in preview::Mode::ALL {
                    if ui
                        .selectable_label(self.settings.view == v, v.name())
                        .clicked()
                    {
                        self.settings.view = v;
                        ui.close();
                    }
                }
                ui.separator();
                if ui.button("Frame graph").clicked() {
                    self.view.frame_pending = 2;
                    ui.close();
                }
                if ui.button("Frame image (preview)").clicked() {
                    self.preview.zoom = None;
                    self.preview.pan = egui::Vec2::ZERO;
                    ui.close();
                }
                if ui.button("Actual pixels (1:1)").clicked() {
                    self.preview.zoom = Some(1.0);
                    ui.close();
                }
            });
            ui.menu_button("Help", |ui| {
                if ui.button("Operators…").clicked() {
                    self.show_ops = true;
                    ui.close();
                }
                if ui.button("About rgbn").clicked() {
                    self.dialog = Some(Dialog::About);
                    ui.close();
                }
            });
            ui.separator();
            ui.label(RichText::new(self.doc.title()).weak());
        });
    }

    fn status_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            if let Some(f) = &self.in_flight {
                let (done, total) = self.progress.unwrap_or((0, 0));
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
            } else {
                ui.label(format!(
                    "evaluated in {:.0} ms ({} computed)",
                    self.outcome.elapsed.as_secs_f64() * 1e3,
                    self.outcome.computed
                ));
            }
            ui.separator();
            let (n, bytes) = self.outcome.cache;
            ui.label(format!("cache {n} values, {:.1} MiB", bytes as f64 / (1 << 20) as f64));
            ui.separator();
            match self.viewed.as_ref().and_then(|v| self.outcome.curl.get(&v.0)) {
                Some(c) => ui.label(format!("curl (rel. RMS) {c:.2e}")),
                None => ui.label("curl —"),
            }
            .on_hover_text("RMS(curl) / RMS(|gradient|) of the viewed node's normals: 0 for an integrable field");
            ui.separator();
            ui.label(RichText::new(format!("ui {:.1} ms", self.frame_ms)).weak());
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
            .selected
            .filter(|s| self.doc.graph.nodes.contains_key(s))
        else {
            ui.weak("Select a node to edit its parameters.");
            ui.weak("Right-click the graph (or use the Add menu) to add nodes.");
            return;
        };
        let base = self.doc.base_dir();
        if let Some(name) = params_ui::inspector_ui(ui, &mut self.doc.graph, id, &base) {
            self.browse(FilePurpose::Param(id, name));
        }
        if let Some(e) = self.outcome.node_errors.get(&id) {
            ui.separator();
            ui.colored_label(Color32::from_rgb(255, 110, 110), e);
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
            if let Some((id, port)) = self.viewed.clone() {
                ui.label(format!(
                    "{} · {port}",
                    graph_view::node_title(&self.doc.graph, id)
                ));
                let outs: Vec<String> = self
                    .ports
                    .get(&id)
                    .map(|p| p.outputs.iter().map(|o| o.name.clone()).collect())
                    .unwrap_or_default();
                if outs.len() > 1 {
                    for o in outs {
                        if ui.selectable_label(o == port, &o).clicked() {
                            self.viewed = Some((id, o));
                        }
                    }
                }
            }
        });
        let before = self.before_value().map(|(v, k)| (v.clone(), k));
        preview::settings_ui(
            ui,
            &mut self.settings,
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
                let mut req = Preview::request(v, *k, &self.settings);
                let before = before.filter(|_| self.preview.split.is_some());
                req.before = before.as_ref().map(|b| b.1);
                self.preview
                    .update(&ctx, v, before.as_ref().map(|b| &b.0), req);
                if self.preview.renders != renders {
                    if let Some((first, last)) = self.tools.preview_rendered() {
                        if self.timing {
                            eprintln!(
                                "rgbn editor: tool edit → relit preview after {last:.0} ms (newest edit shown), {first:.0} ms (oldest; texture render {:.0} ms)",
                                self.preview.render_ms
                            );
                        }
                    }
                }
                if self.first_preview.is_none() && self.preview.renders > 0 {
                    let t = self.started.elapsed();
                    self.first_preview = Some(t);
                    if self.timing {
                        eprintln!(
                            "rgbn editor: first preview after {:.0} ms",
                            t.as_secs_f64() * 1e3
                        );
                    }
                }
            }
            // A node a tool just made: keep the last picture until it is evaluated.
            None if self.in_flight.is_some() => {}
            None => self.preview.clear(),
        }
        let stamp_size = self.selected.and_then(|s| {
            let n = self.doc.graph.nodes.get(&s).filter(|n| n.op == "stamp")?;
            let crate::graph::Source::Node(src, port) = n.inputs.get("stamp")? else {
                return None;
            };
            match &self.outcome.values.get(&(*src, port.clone()))?.value {
                Value::Rgbn(img) => Some([img.width(), img.height()]),
                _ => None,
            }
        });
        let mut cx = tools_ui::ToolCx {
            doc: &mut self.doc,
            selected: &mut self.selected,
            viewed: &mut self.viewed,
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
            self.settings.light = l;
        }
        if let Some(m) = cx.message.take() {
            self.say(m);
        }
        let text = match (&current, &self.viewed) {
            (_, None) => "Click a node to view its output.".to_string(),
            (None, Some((id, _))) => match self.outcome.node_errors.get(id) {
                Some(e) => format!("error: {e}"),
                None if self.in_flight.is_some() => "evaluating…".into(),
                None => "no value (a save node, or an output that cannot be shown)".into(),
            },
            (Some(_), _) => readout
                .unwrap_or_else(|| "scroll to zoom, drag to pan, double-click to fit".to_string()),
        };
        ui.label(RichText::new(text).monospace().small());
    }

    fn dialogs_ui(&mut self, ctx: &egui::Context) {
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
                        self.doc.title()
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
                    ui.label(format!("{} has unsaved changes.", self.doc.title()));
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

/// The graph as far as evaluation cares: positions do not matter.
fn eval_graph(g: &Graph) -> Graph {
    let mut g = g.clone();
    for n in g.nodes.values_mut() {
        n.pos = [0.0, 0.0];
    }
    g
}

/// What to view first: the node behind the graph's `image` output, else its first output.
fn default_view(g: &Graph) -> Option<(NodeId, String)> {
    let r = g
        .outputs
        .get("image")
        .or_else(|| g.outputs.values().next())?;
    Some((r.node, r.port.clone()))
}

/// Every operator's documentation: doc, ports, parameters.
fn ops_doc_ui(ui: &mut egui::Ui) {
    egui::ScrollArea::vertical().show(ui, |ui| {
        for op in crate::ops::registry() {
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
                        let range = p
                            .meta
                            .range
                            .map(|(a, b)| format!(" [{a}, {b}]"))
                            .unwrap_or_default();
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

impl eframe::App for EditorApp {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        self.poll(ctx);
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.frame_ui(ui);
    }
}
