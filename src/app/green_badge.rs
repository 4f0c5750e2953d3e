//! The green-convention badge of `load` nodes: "green: OpenGL", "green: DirectX — tick dx",
//! "green: uncertain (too little relief)" under the node's thumbnail, with
//! [`GreenConvention::describe`]'s full line as hover text — what `rgbn info` prints on its
//! `green:` line ([`green_convention`], `docs/green-convention.md`).
//!
//! The verdict needs the file's decoded normals, so it is computed off the UI thread: once per
//! [`BadgeKey`] (the resolved file and mask paths, the `dx` and `exr_rgb_is_normal` settings
//! and the files' modification times), one check at a time on a thread of its own, which asks
//! for a repaint when done. The file is read with the crate's loader ([`io::load`], no colour)
//! exactly as the node reads it. [`GreenBadges::update`] runs once per frame: it looks at the
//! files of the graph's `load` nodes (at most every [`RESTAT`]), collects a finished check and
//! starts the next one; it never waits.

use crate::graph::{Graph, NodeId};
use crate::nodes::load::LoadParams;
use crate::raster::integrate::{green_convention, GreenConvention, GreenVerdict, Uncertainty};
use crate::raster::io::{self, InputSpec, LoadOptions};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::{Duration, Instant, SystemTime};

/// How often the UI looks at a load node's files again for a changed modification time.
pub const RESTAT: Duration = Duration::from_millis(1000);

/// Finished badges kept beyond those of the current nodes (toggling `dx` back is instant).
const KEEP: usize = 32;

/// What one check depends on.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct BadgeKey {
    /// The normals' file, resolved against the graph's folder.
    pub path: PathBuf,
    /// Its modification time.
    pub modified: SystemTime,
    /// The coverage mask (pixels outside it do not vote) and its modification time.
    pub mask: Option<(PathBuf, Option<SystemTime>)>,
    /// The node reads normal maps in the DirectX convention.
    pub dx: bool,
    /// The node reads an EXR's R,G,B as the normal.
    pub exr_rgb_is_normal: bool,
}

impl BadgeKey {
    /// The key of a `load` node's parameters (paths relative to `base_dir`), or `None` when it
    /// names no file or its file cannot be looked at (the node shows its own error then).
    #[must_use]
    pub fn of(p: &LoadParams, base_dir: &Path) -> Option<Self> {
        if p.path.is_empty() {
            return None;
        }
        let path = base_dir.join(&p.path);
        let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
        let mask = (!p.mask.is_empty()).then(|| {
            let m = base_dir.join(&p.mask);
            let t = std::fs::metadata(&m).and_then(|m| m.modified()).ok();
            (m, t)
        });
        Some(Self {
            path,
            modified,
            mask,
            dx: p.dx,
            exr_rgb_is_normal: p.exr_rgb_is_normal,
        })
    }
}

/// One line under a node and its hover text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Badge {
    /// Short: "green: OpenGL", "green: DirectX — tick dx", "green: uncertain (…)".
    pub text: String,
    /// The verdict with its evidence (as `rgbn info` prints it).
    pub hover: String,
    /// The file is read in the other convention than the relief says (the badge asks to
    /// change `dx`).
    pub mismatch: bool,
}

impl Badge {
    /// The badge of a verdict on normals read with `dx` as set.
    #[must_use]
    pub fn of(g: &GreenConvention, dx: bool) -> Self {
        // The file's own convention: the one it was read in when its normals are a surface's
        // as held, the other one when they become one with green flipped.
        let file_dx = match g.verdict {
            GreenVerdict::OpenGl => Some(dx),
            GreenVerdict::DirectX => Some(!dx),
            GreenVerdict::Uncertain(_) => None,
        };
        let mismatch = g.verdict == GreenVerdict::DirectX;
        let text = match (file_dx, g.verdict) {
            (Some(true), _) if !dx => "green: DirectX — tick dx".to_string(),
            (Some(false), _) if dx => "green: OpenGL — untick dx".to_string(),
            (Some(true), _) => "green: DirectX".to_string(),
            (Some(false), _) => "green: OpenGL".to_string(),
            (None, GreenVerdict::Uncertain(Uncertainty::TooLittleRelief)) => {
                "green: uncertain (too little relief)".to_string()
            }
            (None, _) => "green: uncertain (both readings alike)".to_string(),
        };
        let hint = match (mismatch, dx) {
            (true, false) => " — load it with dx ticked",
            (true, true) => " — load it with dx unticked",
            _ => "",
        };
        Self {
            text,
            hover: format!(
                "Green convention by integrability (as `rgbn info` says it): {}{hint}",
                g.describe_loaded(dx)
            ),
            mismatch,
        }
    }

    /// The badge of a file that could not be read.
    #[must_use]
    pub fn unreadable(error: &str) -> Self {
        Self {
            text: "green: —".to_string(),
            hover: format!("The green convention could not be checked: {error}"),
            mismatch: false,
        }
    }

    /// The badge while the check runs.
    #[must_use]
    pub fn pending() -> Self {
        Self {
            text: "green: …".to_string(),
            hover: "Checking the green convention (OpenGL or DirectX) of the file's normals"
                .to_string(),
            mismatch: false,
        }
    }
}

/// Reads the file of `key` as the node does (without its colour) and judges its green
/// convention. Blocking: decodes the whole normal map.
#[must_use]
pub fn check(key: &BadgeKey) -> Badge {
    let spec = InputSpec {
        rgbn: None,
        normal: Some(key.path.clone()),
        color: None,
        mask: key.mask.as_ref().map(|m| m.0.clone()),
    };
    // The node's input spec: an EXR is an RGBN file unless its RGB is a normal pass.
    let spec = match io::Format::of(&key.path) {
        Ok(io::Format::Exr) if !key.exr_rgb_is_normal => InputSpec {
            rgbn: spec.normal.clone(),
            normal: None,
            ..spec
        },
        Ok(_) => spec,
        Err(e) => return Badge::unreadable(&e.to_string()),
    };
    // Not strict: the verdict is about the relief, whatever a few bad normals.
    let opts = LoadOptions::of_flags(key.dx, key.exr_rgb_is_normal, false);
    match io::load(&spec, &opts) {
        Ok(l) => Badge::of(&green_convention(&l.image), key.dx),
        Err(e) => Badge::unreadable(&e.to_string()),
    }
}

/// A node's key, and when its files were last looked at.
struct Seen {
    params: LoadParams,
    base_dir: PathBuf,
    key: Option<BadgeKey>,
    at: Instant,
}

/// The badges of the graph's `load` nodes, computed off the UI thread.
#[derive(Default)]
pub struct GreenBadges {
    /// Finished checks.
    done: HashMap<BadgeKey, Badge>,
    /// The check under way.
    running: Option<(BadgeKey, Receiver<Badge>)>,
    /// Per load node: its parameters and key as last looked at.
    seen: BTreeMap<NodeId, Seen>,
    /// Checks started (tests).
    pub started: usize,
}

impl GreenBadges {
    /// Per frame: the badge of every `load` node of `graph` that names a readable file
    /// (pending while its check runs). Collects a finished check, starts the next missing
    /// one (`ctx` is asked to repaint when it ends); never blocks.
    pub fn update(
        &mut self,
        graph: &Graph,
        base_dir: &Path,
        ctx: &egui::Context,
    ) -> BTreeMap<NodeId, Badge> {
        self.collect();
        let now = Instant::now();
        self.seen
            .retain(|id, _| graph.nodes.get(id).is_some_and(|n| n.op == "load"));
        let mut keys: BTreeMap<NodeId, BadgeKey> = BTreeMap::new();
        for n in graph.nodes.values().filter(|n| n.op == "load") {
            let Ok(params) = crate::params::from_values::<LoadParams>(&n.params) else {
                continue;
            };
            let fresh = self.seen.get(&n.id).is_some_and(|s| {
                s.params == params && s.base_dir == base_dir && now - s.at < RESTAT
            });
            if !fresh {
                let key = BadgeKey::of(&params, base_dir);
                self.seen.insert(
                    n.id,
                    Seen {
                        params,
                        base_dir: base_dir.to_path_buf(),
                        key,
                        at: now,
                    },
                );
            }
            if let Some(k) = self.seen.get(&n.id).and_then(|s| s.key.clone()) {
                keys.insert(n.id, k);
            }
        }
        if self.running.is_none() {
            if let Some(k) = keys.values().find(|k| !self.done.contains_key(*k)) {
                self.start(k.clone(), ctx.clone());
            }
        }
        if self.done.len() > KEEP + keys.len() {
            let used: Vec<&BadgeKey> = keys.values().collect();
            self.done.retain(|k, _| used.contains(&k));
        }
        keys.into_iter()
            .map(|(id, k)| {
                let b = self.done.get(&k).cloned().unwrap_or_else(Badge::pending);
                (id, b)
            })
            .collect()
    }

    /// True while a check runs.
    #[must_use]
    pub fn pending(&self) -> bool {
        self.running.is_some()
    }

    /// Stores a finished check.
    fn collect(&mut self) {
        let Some((key, rx)) = &self.running else {
            return;
        };
        let badge = match rx.try_recv() {
            Ok(b) => b,
            Err(TryRecvError::Empty) => return,
            // The thread ended without an answer (it panicked).
            Err(TryRecvError::Disconnected) => Badge::unreadable("the check failed"),
        };
        self.done.insert(key.clone(), badge);
        self.running = None;
    }

    fn start(&mut self, key: BadgeKey, ctx: egui::Context) {
        let (tx, rx) = mpsc::channel();
        let k = key.clone();
        let spawned = std::thread::Builder::new()
            .name("rgbn-green-badge".into())
            .spawn(move || {
                let _ = tx.send(check(&k));
                ctx.request_repaint();
            });
        match spawned {
            Ok(_) => {
                self.running = Some((key, rx));
                self.started += 1;
            }
            Err(e) => {
                self.done
                    .insert(key, Badge::unreadable(&format!("no thread: {e}")));
            }
        }
    }
}

#[cfg(test)]
#[path = "green_badge_tests.rs"]
mod tests;
