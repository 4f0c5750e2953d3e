//! File handling: the file dialog, new / open / save / export, autosave and recovery.

use super::dialogs::Dialog;
use super::recent::{self, Recovery};
use super::session::default_view;
use super::state::Document;
use super::worker::EvalOutcome;
use super::EditorApp;
use crate::graph::NodeId;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What a file picked in the file dialog is for.
#[derive(Clone, Debug, PartialEq)]
pub enum FilePurpose {
    /// Open this graph.
    Open,
    /// Open this image as a `load` node in the viewed chain.
    OpenImage,
    /// Save the graph here.
    SaveAs,
    /// Write this node's output port here.
    Export(NodeId, String),
    /// Set this path parameter of this node.
    Param(NodeId, String),
}

impl EditorApp {
    /// If the document's recovery file holds newer, different work, asks whether to restore it.
    pub fn offer_recovery(&mut self) {
        if let Some(r) =
            recent::recovery_offer(self.session.doc.path.as_deref(), &self.session.doc.graph)
        {
            self.dialog = Some(Dialog::Recover(Box::new(r)));
        }
    }

    /// Replaces the graph with the recovered one (one undo step back to the file's graph); the
    /// document stays unsaved until the user saves.
    pub fn recover(&mut self, r: &Recovery) {
        let before = self.session.doc.graph.clone();
        self.session.doc.graph = r.graph.clone();
        self.session.doc.history.commit(before);
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
        let dir = match &self.prefs.dialog_dir {
            Some(d) if d.is_dir() => d.clone(),
            _ => recent::absolute(&self.session.doc.base_dir()),
        };
        let d = FileDialog::new().initial_directory(dir);
        let mut d = match &purpose {
            FilePurpose::Open => d
                .title("Open graph")
                .add_file_filter_extensions("Graphs (*.ron)", vec!["ron"])
                .default_file_filter("Graphs (*.ron)"),
            FilePurpose::OpenImage => d
                .title("Open image")
                .add_file_filter(
                    "Images (PNG, JPEG, TIFF, EXR, PTM, OME-Zarr)",
                    egui_file_dialog::Filter::new(|p: &Path| {
                        crate::raster::io::Format::of(p).is_ok() || zarr_store_of(p).is_some()
                    }),
                )
                .default_file_filter("Images (PNG, JPEG, TIFF, EXR, PTM, OME-Zarr)"),
            FilePurpose::SaveAs => {
                let name = self
                    .session
                    .doc
                    .path
                    .as_deref()
                    .and_then(Path::file_name)
                    .map(|n| n.to_string_lossy().into_owned())
                    .or_else(|| {
                        let name = self.session.doc.name.as_deref()?;
                        let stem = Path::new(name).file_stem()?.to_string_lossy();
                        Some(format!("{stem}.ron"))
                    })
                    .unwrap_or_else(|| "graph.ron".to_string());
                d.title("Save graph as").default_file_name(&name)
            }
            FilePurpose::Export(id, port) => {
                // By the port's declared type: the value may not be kept (only what is shown is).
                let rgbn = self
                    .runtime
                    .ports
                    .get(id)
                    .and_then(|p| p.outputs.iter().find(|o| o.name == *port))
                    .is_some_and(|o| o.ty == crate::nodes::PortType::Rgbn);
                let ext = if rgbn { "exr" } else { "png" };
                d.title("Export output")
                    .default_file_name(&format!("node{id}-{port}.{ext}"))
            }
            FilePurpose::Param(_, name) => d.title(&format!("Choose {name}")),
        };
        match purpose {
            FilePurpose::Open | FilePurpose::OpenImage | FilePurpose::Param(..) => d.pick_file(),
            FilePurpose::SaveAs | FilePurpose::Export(..) => d.save_file(),
        }
        self.files = Some((d, purpose));
    }

    /// Acts on a file picked for `purpose` (an OME-Zarr store's `zarr.json`, `.zgroup` or
    /// `.zattrs` stands for the store: the dialog picks files, a store is a folder).
    pub fn picked(&mut self, path: &Path, purpose: FilePurpose) {
        let store = zarr_store_of(path);
        let path = store.as_deref().unwrap_or(path);
        self.prefs.dialog_dir = path.parent().map(Path::to_path_buf);
        match purpose {
            FilePurpose::Open => self.open_path(path),
            FilePurpose::OpenImage => {
                self.open_image(path);
            }
            FilePurpose::SaveAs => {
                self.save_to(path);
            }
            FilePurpose::Export(id, port) => self.export(path, id, &port),
            FilePurpose::Param(id, name) => {
                let base = recent::absolute(&self.session.doc.base_dir());
                let rel = path.strip_prefix(&base).unwrap_or(path);
                let v = crate::params::ParamValue::Path(rel.to_string_lossy().into_owned());
                self.session.doc.set_param(id, &name, v);
                self.say(format!("#{id}.{name} = {}", rel.display()));
            }
        }
    }

    pub(super) fn file_dialog_ui(&mut self, ctx: &egui::Context) {
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

    pub(super) fn new_doc(&mut self, doc: Document) {
        self.cancel();
        self.session.doc_epoch += 1;
        self.session.doc = doc;
        self.session.groups.clear();
        self.session.autosaved = None;
        self.session.viewed = default_view(&self.session.doc.graph);
        self.session.selected = self.session.viewed.as_ref().map(|v| v.0);
        self.preview.clear();
        self.runtime.outcome = EvalOutcome::default();
        self.runtime.thumbs.clear();
        self.runtime.last_sent = None;
        self.runtime.in_flight = None; // its result will be stale
        self.placed.clear();
        self.view.new_document();
        self.last_widget_selection.clear();
    }

    /// Opens a graph file (no unsaved-changes check).
    pub fn open_path(&mut self, path: &Path) {
        match Document::open(path) {
            Ok(d) => {
                self.new_doc(d);
                self.say(format!("opened {}", path.display()));
                if let Err(e) = self.prefs.recent.push(path) {
                    tracing::warn!("recent files not saved: {e}");
                }
                self.offer_recovery();
            }
            Err(e) => {
                if !path.exists() {
                    let _ = self.prefs.recent.remove(path);
                }
                self.fail(e.to_string());
            }
        }
    }

    /// Saves to `path`.
    pub fn save_to(&mut self, path: &Path) -> bool {
        let old_recovery = self.recovery_path();
        match self.session.doc.save_as(path) {
            Ok(()) => {
                let _ = std::fs::remove_file(old_recovery);
                let _ = std::fs::remove_file(self.recovery_path());
                self.session.autosaved = None;
                self.say(format!("saved {}", path.display()));
                if let Err(e) = self.prefs.recent.push(path) {
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

    pub(super) fn save(&mut self) -> bool {
        match self.session.doc.path.clone() {
            Some(p) => self.save_to(&p),
            None => {
                self.browse(FilePurpose::SaveAs);
                false
            }
        }
    }

    /// Writes output `port` of node `id` to `path` (format from the extension; atomic; never
    /// over one of the graph's input files).
    pub fn export(&mut self, path: &Path, id: NodeId, port: &str) {
        let key = (id, port.to_string());
        let Some(v) = self.runtime.outcome.values.get(&key) else {
            // The whole-graph refresh keeps only what is shown: an output evaluated but not
            // kept, or not evaluated yet, is asked for and written when it arrives.
            let failed = self.runtime.outcome.node_errors.get(&id);
            let waiting = self.runtime.outcome.waiting.get(&id);
            if let Some(e) = failed {
                self.fail(format!("nothing to export: node #{id} failed: {e}"));
            } else if let Some(port) = waiting {
                self.fail(format!(
                    "nothing to export: node #{id} waits for input {port} (connect it)"
                ));
            } else if self.session.doc.graph.nodes.contains_key(&id) {
                self.pending_export = Some((path.to_path_buf(), id, port.to_string()));
                self.say(format!(
                    "exporting node #{id} {port:?} to {} once it is evaluated",
                    path.display()
                ));
            } else {
                self.fail(format!("nothing to export: there is no node #{id}"));
            }
            return;
        };
        let v = v.value.clone();
        // Never over one of the graph's own files (inputs, sub-graphs) or the graph itself.
        let base = self.session.doc.base_dir();
        let mut files: Vec<PathBuf> = self
            .session
            .doc
            .graph
            .nodes
            .values()
            .flat_map(|n| n.params.values())
            .filter_map(|p| match p {
                crate::params::ParamValue::Path(p) if !p.is_empty() => Some(base.join(p)),
                _ => None,
            })
            .collect();
        files.extend(self.session.doc.path.clone());
        let inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
        if let Err(e) = crate::raster::io::check_output(path, &inputs) {
            self.fail(e.to_string());
            return;
        }
        match crate::nodes::save::write_value(&v, path, &crate::raster::io::SaveOptions::default())
        {
            Ok(()) => self.say(format!("exported {}", path.display())),
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// Writes the export asked for before its value was evaluated, once the outcome carries
    /// the value (or says why it cannot).
    pub(super) fn finish_pending_export(&mut self) {
        let Some((path, id, port)) = self.pending_export.take() else {
            return;
        };
        let out = &self.runtime.outcome;
        let evaluated = out.values.contains_key(&(id, port.clone()))
            || out.node_errors.contains_key(&id)
            || out.waiting.contains_key(&id)
            || !self.session.doc.graph.nodes.contains_key(&id);
        if evaluated {
            self.export(&path, id, &port);
        } else {
            self.pending_export = Some((path, id, port));
        }
    }

    /// Where unsaved work is kept: beside the file (`.NAME.autosave.ron`), or in the temporary
    /// folder for an untitled graph.
    #[must_use]
    pub fn recovery_path(&self) -> PathBuf {
        recent::recovery_path(self.session.doc.path.as_deref())
    }

    /// Writes unsaved changes to the recovery file at most every [`AUTOSAVE_INTERVAL`], and
    /// within that interval of any edit whatever the input: while the graph differs from the
    /// file and from what was last autosaved, each frame asks egui to wake the editor at the
    /// next autosave time (`request_repaint_after`), so the write does not wait for a mouse
    /// move or a key.
    pub(super) fn autosave(&mut self, ctx: &egui::Context) {
        let s = &self.session;
        if !s.doc.is_dirty() || s.autosaved.as_ref() == Some(&s.doc.graph) {
            return;
        }
        let due = s.last_autosave + AUTOSAVE_INTERVAL;
        let now = Instant::now();
        if now < due {
            ctx.request_repaint_after(due - now);
            return;
        }
        self.session.last_autosave = now;
        self.session.autosaved = Some(self.session.doc.graph.clone());
        if let Err(e) = self.session.doc.graph.save(&self.recovery_path()) {
            self.fail(format!("autosave failed: {e}"));
        }
    }
}

/// How often unsaved work is written to the recovery file.
pub const AUTOSAVE_INTERVAL: Duration = Duration::from_secs(30);

/// The OME-Zarr store (a `.zarr` folder) whose metadata file `p` is, if it is one.
fn zarr_store_of(p: &Path) -> Option<PathBuf> {
    let name = p.file_name()?.to_str()?;
    let dir = p.parent()?;
    (matches!(name, "zarr.json" | ".zgroup" | ".zattrs") && crate::raster::io::zarr::is_zarr(dir))
        .then(|| dir.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::zarr_store_of;
    use std::path::Path;

    #[test]
    fn a_stores_metadata_file_stands_for_the_store() {
        let store = zarr_store_of(Path::new("/d/scan.zarr/zarr.json"));
        assert_eq!(store.as_deref(), Some(Path::new("/d/scan.zarr")));
        assert!(zarr_store_of(Path::new("/d/scan.ZARR/.zattrs")).is_some());
        assert!(zarr_store_of(Path::new("/d/scan.zarr/0/zarr.json")).is_none());
        assert!(zarr_store_of(Path::new("/d/plain/zarr.json")).is_none());
        assert!(zarr_store_of(Path::new("/d/scan.exr")).is_none());
    }
}
