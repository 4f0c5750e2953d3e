//! Recent files and crash recovery — no egui.
//!
//! - [`RecentFiles`]: the last graphs opened or saved, newest first, kept in
//!   `$RGBN_CONFIG_DIR/recent.txt` (default `$XDG_CONFIG_HOME/rgbn`, else `~/.config/rgbn`),
//!   one absolute path per line, written atomically.
//! - Recovery: the editor autosaves unsaved work to [`recovery_path`] (beside the graph file, or
//!   in the temporary folder for an untitled graph). When a document is opened and its recovery
//!   file holds a different graph that is newer than the file, [`recovery_offer`] says so and the
//!   editor offers to restore it.

use crate::graph::{file, At, Graph};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// How many recent files are kept.
pub const MAX_RECENT: usize = 10;

/// The folder for the editor's own settings.
#[must_use]
pub fn config_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("RGBN_CONFIG_DIR") {
        return Some(PathBuf::from(d));
    }
    if let Some(d) = std::env::var_os("XDG_CONFIG_HOME").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(d).join("rgbn"));
    }
    std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config").join("rgbn"))
}

/// The recently used graph files, newest first.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecentFiles {
    /// Absolute paths, newest first, no duplicates, at most [`MAX_RECENT`].
    pub paths: Vec<PathBuf>,
    /// Where the list is stored (`None`: not persisted).
    pub store: Option<PathBuf>,
}

impl RecentFiles {
    /// Reads the list from `store` (a missing or unreadable file gives an empty list).
    #[must_use]
    pub fn load(store: Option<PathBuf>) -> Self {
        let paths = store
            .as_deref()
            .and_then(|p| std::fs::read_to_string(p).ok())
            .map(|t| {
                t.lines()
                    .map(str::trim)
                    .filter(|l| !l.is_empty())
                    .map(PathBuf::from)
                    .take(MAX_RECENT)
                    .collect()
            })
            .unwrap_or_default();
        Self { paths, store }
    }

    /// The list in the user's config folder.
    #[must_use]
    pub fn user() -> Self {
        Self::load(config_dir().map(|d| d.join("recent.txt")))
    }

    /// Puts `path` first (made absolute), drops older duplicates, keeps [`MAX_RECENT`], and
    /// writes the list. Returns the write error, if any (the list in memory is updated anyway).
    pub fn push(&mut self, path: &Path) -> Result<(), String> {
        let abs = absolute(path);
        self.paths.retain(|p| p != &abs);
        self.paths.insert(0, abs);
        self.paths.truncate(MAX_RECENT);
        self.write()
    }

    /// Forgets `path` (e.g. it no longer exists) and writes the list.
    pub fn remove(&mut self, path: &Path) -> Result<(), String> {
        let abs = absolute(path);
        self.paths.retain(|p| p != &abs);
        self.write()
    }

    fn write(&self) -> Result<(), String> {
        let Some(store) = &self.store else {
            return Ok(());
        };
        if let Some(dir) = store.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        }
        let mut text = String::new();
        for p in &self.paths {
            text.push_str(&p.to_string_lossy());
            text.push('\n');
        }
        crate::raster::io::write_atomic(store, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })
        .map_err(|e| e.to_string())
    }
}

/// `path` made absolute (canonical when it exists).
#[must_use]
pub fn absolute(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| {
        std::env::current_dir()
            .map(|d| d.join(path))
            .unwrap_or_else(|_| path.to_path_buf())
    })
}

/// Where unsaved work on the graph at `doc_path` is autosaved: `.NAME.autosave.ron` beside
/// it, or `rgbn-untitled.autosave.ron` in the temporary folder for an untitled graph.
#[must_use]
pub fn recovery_path(doc_path: Option<&Path>) -> PathBuf {
    match doc_path {
        Some(p) => {
            let name = p
                .file_stem()
                .map_or_else(|| "graph".to_string(), |s| s.to_string_lossy().into_owned());
            let dir = match p.parent() {
                Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
                _ => PathBuf::from("."),
            };
            dir.join(format!(".{name}.autosave.ron"))
        }
        None => std::env::temp_dir().join("rgbn-untitled.autosave.ron"),
    }
}

/// An autosaved graph the user may want back.
#[derive(Clone, Debug, PartialEq)]
pub struct Recovery {
    /// The recovery file.
    pub path: PathBuf,
    /// The graph in it.
    pub graph: Graph,
    /// When it was written.
    pub modified: SystemTime,
}

/// The recovery file of the document at `doc_path` (showing `current`), if it holds a graph
/// that differs from `current` and is not older than the document's file. An unreadable or
/// invalid recovery file is no offer (it is left alone for the user to inspect).
#[must_use]
pub fn recovery_offer(doc_path: Option<&Path>, current: &Graph) -> Option<Recovery> {
    let path = recovery_path(doc_path);
    let modified = std::fs::metadata(&path).ok()?.modified().ok()?;
    if let Some(doc) = doc_path {
        if let Ok(doc_time) = std::fs::metadata(doc).and_then(|m| m.modified()) {
            if doc_time > modified {
                return None;
            }
        }
    }
    let name = path.display().to_string();
    let text = std::fs::read_to_string(&path).ok()?;
    let graph = Graph::from_file(file::parse(&text, &name).ok()?, &At::file(&name)).ok()?;
    (graph != *current).then_some(Recovery {
        path,
        graph,
        modified,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recent_files_are_newest_first_unique_bounded_and_persist() {
        let dir = tempfile::tempdir().expect("temp dir");
        let store = dir.path().join("cfg").join("recent.txt");
        let mut r = RecentFiles::load(Some(store.clone()));
        assert!(r.paths.is_empty());
        for k in 0..12 {
            let p = dir.path().join(format!("g{k}.ron"));
            std::fs::write(&p, "x").expect("write");
            r.push(&p).expect("push");
        }
        // Opening g3 again moves it to the front without duplicating it.
        r.push(&dir.path().join("g3.ron")).expect("push");
        assert_eq!(r.paths.len(), MAX_RECENT);
        assert!(r.paths[0].ends_with("g3.ron"));
        assert!(r.paths[1].ends_with("g11.ron"));
        assert_eq!(r.paths.iter().filter(|p| p.ends_with("g3.ron")).count(), 1);
        // g0 and g1 fell off the end.
        assert!(!r.paths.iter().any(|p| p.ends_with("g0.ron")));
        let again = RecentFiles::load(Some(store));
        assert_eq!(again.paths, r.paths);
        r.remove(&dir.path().join("g3.ron")).expect("remove");
        assert!(r.paths[0].ends_with("g11.ron"));
    }

    #[test]
    fn recovery_is_offered_only_for_a_newer_different_graph() {
        let dir = tempfile::tempdir().expect("temp dir");
        let doc = dir.path().join("edit.ron");
        let mut g = Graph::default();
        g.add_node("demo", [0.0, 0.0]);
        g.save(&doc).expect("save doc");
        assert_eq!(recovery_offer(Some(&doc), &g), None, "no recovery file");
        let rec = recovery_path(Some(&doc));
        assert_eq!(rec, dir.path().join(".edit.autosave.ron"));
        // Same graph autosaved: nothing to recover.
        g.save(&rec).expect("save recovery");
        assert_eq!(recovery_offer(Some(&doc), &g), None);
        // A different (edited) graph autosaved after the file: offered, exactly that graph.
        let mut edited = g.clone();
        edited.add_node("normalize", [200.0, 0.0]);
        edited.save(&rec).expect("save recovery");
        let offer = recovery_offer(Some(&doc), &g).expect("offered");
        assert_eq!(offer.graph, edited);
        assert_eq!(offer.path, rec);
        // The file saved after the autosave: the autosave is stale, no offer.
        std::thread::sleep(std::time::Duration::from_millis(20));
        g.save(&doc).expect("save doc again");
        let t = std::fs::metadata(&rec)
            .and_then(|m| m.modified())
            .expect("mtime");
        let d = std::fs::metadata(&doc)
            .and_then(|m| m.modified())
            .expect("mtime");
        assert!(d > t, "file system keeps sub-second modification times");
        assert_eq!(recovery_offer(Some(&doc), &g), None);
        // A corrupt recovery file is no offer (and is left in place).
        std::fs::write(&rec, "(version: 1, nodes: [").expect("write");
        assert_eq!(recovery_offer(Some(&doc), &g), None);
        assert!(rec.exists());
    }
}
