//! The runtime: evaluation on the worker thread (requests, generations, progress, the accepted
//! outcome, thumbnails, port lists) and frame timing. [`EditorApp::poll`] runs once per frame,
//! from `eframe::App::logic`.

use super::preview::RegionShown;
use super::worker::{EvalOutcome, EvalRequest, Generations, ViewRequest, Worker, WorkerMsg};
use super::{EditorApp, FilePurpose, Status};
use crate::graph::{Graph, NodeId, NodePorts};
use egui::{TextureHandle, TextureOptions};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

/// The running evaluation.
pub(super) struct InFlight {
    pub(super) cancel: Arc<AtomicBool>,
    pub(super) started: Instant,
}

/// Evaluation state and results, and frame timing.
pub struct Runtime {
    pub(super) worker: Worker,
    /// The egui context, for the worker to wake the UI (set by the first [`EditorApp::poll`]).
    pub(super) wake_ctx: Arc<OnceLock<egui::Context>>,
    pub(super) gens: Generations,
    pub(super) in_flight: Option<InFlight>,
    /// The shown outcome's integrability readouts are still to come.
    pub(super) readouts_pending: bool,
    /// The evaluation-relevant graph of the last request (positions zeroed).
    pub(super) last_sent: Option<Graph>,
    /// The view of the last request.
    pub(super) last_view: Option<ViewRequest>,
    /// The outputs last asked to be kept ([`EvalRequest::keep`]).
    pub(super) last_keep: Vec<(NodeId, String)>,
    /// Progress of the running evaluation (done, total).
    pub progress: Option<(usize, usize)>,
    /// The latest accepted evaluation.
    pub outcome: EvalOutcome,
    pub(super) thumbs: BTreeMap<NodeId, (Arc<crate::nodes::Picture>, TextureHandle)>,
    pub(super) ports: BTreeMap<NodeId, NodePorts>,
    pub(super) ports_for: Option<Graph>,
    /// Evaluation requests sent (tests).
    pub requests: u64,
    pub(super) started: Instant,
    /// Time from start to the first preview texture.
    pub first_preview: Option<Duration>,
    pub(super) frame_ms: f64,
    /// Frame times (ms) while the current evaluation runs: count, sum, max.
    pub(super) eval_frames: (u32, f64, f64),
    /// Quit confirmed: the next close request is not intercepted.
    pub(super) allow_close: bool,
    /// The window title last sent.
    pub(super) title: Option<String>,
}

impl Runtime {
    /// Starts the worker thread.
    pub(super) fn new() -> Self {
        let wake_ctx: Arc<OnceLock<egui::Context>> = Arc::new(OnceLock::new());
        let w = wake_ctx.clone();
        let worker = Worker::spawn(Arc::new(move || {
            if let Some(ctx) = w.get() {
                ctx.request_repaint();
            }
        }));
        Self {
            worker,
            wake_ctx,
            gens: Generations::default(),
            in_flight: None,
            readouts_pending: false,
            last_sent: None,
            last_view: None,
            last_keep: Vec::new(),
            progress: None,
            outcome: EvalOutcome::default(),
            thumbs: BTreeMap::new(),
            ports: BTreeMap::new(),
            ports_for: None,
            requests: 0,
            started: Instant::now(),
            first_preview: None,
            frame_ms: 0.0,
            eval_frames: (0, 0.0, 0.0),
            allow_close: false,
            title: None,
        }
    }
}

impl EditorApp {
    /// True while an evaluation is running or a newer graph waits to be sent. The graph
    /// compared is the one [`send_if_changed`](Self::send_if_changed) sends: inside a group,
    /// the subgraph in its context (`eval_context`), not the document alone.
    #[must_use]
    pub fn evaluating(&self) -> bool {
        self.runtime.in_flight.is_some()
            || self.runtime.last_sent.as_ref() != Some(&eval_graph(&self.eval_context().0))
    }

    /// Takes worker messages, accepts current results, sends a new request when the graph
    /// changed and none is running. Never blocks.
    pub fn poll(&mut self, ctx: &egui::Context) {
        let _ = self.runtime.wake_ctx.set(ctx.clone());
        while let Some(msg) = self.runtime.worker.poll() {
            match msg {
                WorkerMsg::Progress {
                    generation,
                    done,
                    total,
                } => {
                    if generation == self.runtime.gens.latest() {
                        self.runtime.progress = Some((done, total));
                    }
                }
                WorkerMsg::Region(r) => {
                    let viewed = self.session.viewed.as_ref();
                    if r.generation == self.runtime.gens.latest()
                        && viewed == Some(&(r.node, r.port.clone()))
                    {
                        if self.prefs.timing {
                            let after_edit =
                                self.tools.newest_sent_edit().map_or_else(String::new, |t| {
                                    format!(
                                        "; ready {:.1} ms after the newest edit",
                                        r.ready.saturating_duration_since(t).as_secs_f64() * 1e3
                                    )
                                });
                            tracing::info!(
                                target: super::TIMING,
                                "viewport {}×{} at level {} of {}×{} evaluated and relit in {:.1} ms ({} tiles computed){after_edit}",
                                r.rect.w,
                                r.rect.h,
                                r.level,
                                r.full_size.0,
                                r.full_size.1,
                                r.elapsed.as_secs_f64() * 1e3,
                                r.tiles_computed
                            );
                        }
                        let r = *r;
                        self.preview.set_region(
                            ctx,
                            RegionShown {
                                key: r.key,
                                rect: r.rect,
                                level: r.level,
                                coarse: r.coarse,
                                full_size: r.full_size,
                                value: r.value,
                            },
                            r.picture,
                        );
                    }
                }
                WorkerMsg::Readouts(r) => {
                    let o = &mut self.runtime.outcome;
                    if r.generation == o.generation {
                        o.curl.extend(r.curl);
                        o.fraction.extend(r.fraction);
                        self.runtime.readouts_pending = false;
                    }
                }
                WorkerMsg::Done(out) => {
                    if self.runtime.gens.accept(out.generation) {
                        self.runtime.in_flight = None;
                        self.runtime.readouts_pending = out.readouts_follow;
                        self.runtime.progress = None;
                        if self.prefs.timing {
                            let (n, sum, max) = self.runtime.eval_frames;
                            tracing::info!(
                                target: super::TIMING,
                                "evaluation {} took {:.0} ms ({} computed); {n} UI frames meanwhile, mean {:.2} ms, max {:.2} ms",
                                out.generation,
                                out.elapsed.as_secs_f64() * 1e3,
                                out.computed,
                                if n > 0 { sum / f64::from(n) } else { 0.0 },
                                max
                            );
                        }
                        self.runtime.eval_frames = (0, 0.0, 0.0);
                        if out.cancelled {
                            self.say("evaluation cancelled");
                        } else {
                            self.accept_outcome(ctx, *out);
                        }
                    }
                }
            }
        }
        self.send_if_changed();
    }

    /// Sends a request when the graph (or, while the viewed output has no whole value, the
    /// view) changed since the last one. Runs when the frame starts ([`EditorApp::poll`]) and
    /// again when it ends, so that an edit made in a frame is evaluated at once.
    pub fn send_if_changed(&mut self) {
        let (graph, base_dir) = self.eval_context();
        let want = eval_graph(&graph);
        let view = self.view_request();
        // The first request waits for the preview's first frame, which says what is on screen:
        // then the viewport comes first instead of a whole evaluation that cannot be cut short.
        if self.runtime.last_sent.is_none() && self.session.viewed.is_some() && view.is_none() {
            return;
        }
        let graph_changed = self.runtime.last_sent.as_ref() != Some(&want);
        // Panning or zooming asks for a new viewport only while the viewed output has no
        // whole value to show (it is being evaluated, or too large to evaluate whole).
        let view_changed = view.is_some()
            && self.runtime.last_view != view
            && (self.runtime.in_flight.is_some() || self.viewed_value().is_none());
        // An output to keep whose value the last outcome does not carry (a split's input, a
        // stamp's source, an output being exported) is asked for once.
        let keep = self.kept_outputs();
        let out = &self.runtime.outcome;
        let keep_changed = self.runtime.last_keep != keep
            && keep
                .iter()
                .any(|k| out.keys.contains_key(k) && !out.values.contains_key(k));
        if graph_changed || view_changed || keep_changed {
            // A newer request supersedes the running one: while edits keep coming, the worker
            // evaluates only the viewport of each.
            self.cancel();
            let cancel = Arc::new(AtomicBool::new(false));
            self.runtime.worker.send(EvalRequest {
                generation: self.runtime.gens.new_request(),
                graph,
                base_dir,
                cancel: cancel.clone(),
                view: view.clone(),
                settings: Some(self.prefs.settings.clone()),
                keep: Some(keep.clone()),
            });
            self.runtime.requests += 1;
            self.tools.request_sent();
            self.runtime.in_flight = Some(InFlight {
                cancel,
                started: Instant::now(),
            });
            self.runtime.last_sent = Some(want);
            self.runtime.last_view = view;
            self.runtime.last_keep = keep;
        }
    }

    /// The outputs whose whole values the editor needs besides the viewed one.
    fn kept_outputs(&self) -> Vec<(NodeId, String)> {
        let export = match (&self.files, &self.pending_export) {
            (Some((_, FilePurpose::Export(id, port))), _) | (_, Some((_, id, port))) => {
                Some((*id, port.clone()))
            }
            _ => None,
        };
        super::refresh::kept_outputs(
            &self.session.doc.graph,
            self.session.viewed.as_ref(),
            self.session.selected,
            export.as_ref(),
        )
    }

    /// What the preview shows: the viewed output, and where (`None` before the preview's first
    /// frame or with nothing viewed).
    fn view_request(&self) -> Option<ViewRequest> {
        let (node, port) = self.session.viewed.clone()?;
        Some(ViewRequest {
            node,
            port,
            spec: self.preview.view_spec()?,
        })
    }

    pub(super) fn accept_outcome(&mut self, ctx: &egui::Context, out: EvalOutcome) {
        // Thumbnail textures: re-upload only the pictures that changed.
        let mut thumbs = BTreeMap::new();
        for (id, pic) in &out.thumbs {
            let tex = match self.runtime.thumbs.remove(id) {
                Some((old, tex)) if Arc::ptr_eq(&old, pic) || *old == **pic => tex,
                _ => ctx.load_texture(
                    format!("thumb-{id}"),
                    egui::ColorImage::from_rgba_unmultiplied([pic.width, pic.height], &pic.rgba),
                    TextureOptions::LINEAR,
                ),
            };
            thumbs.insert(*id, (pic.clone(), tex));
        }
        self.runtime.thumbs = thumbs;
        if let Some(e) = &out.error {
            self.fail(e.clone());
        } else if !out.node_errors.is_empty() {
            let (id, e) = out.node_errors.iter().next().expect("not empty");
            self.fail(format!(
                "{} node(s) failed; #{id}: {e}",
                out.node_errors.len()
            ));
        } else if let Some((id, port)) = out.waiting.iter().next() {
            // Not a failure: a node just added waits for its input until it is wired.
            let more = match out.waiting.len() {
                1 => String::new(),
                n => format!(" ({} more node(s) wait for inputs)", n - 1),
            };
            self.say(format!("#{id} waits for input {port}{more}"));
        } else if self.status.error {
            self.status = Status::default();
        }
        self.runtime.outcome = out;
        self.finish_pending_export();
    }

    pub(super) fn cancel(&mut self) {
        if let Some(f) = &self.runtime.in_flight {
            f.cancel.store(true, Ordering::Relaxed);
        }
    }

    pub(super) fn refresh_ports(&mut self) {
        if self.runtime.ports_for.as_ref() == Some(&self.session.doc.graph) {
            return;
        }
        let base = self.session.doc.base_dir();
        self.runtime.ports = self
            .session
            .doc
            .graph
            .nodes
            .keys()
            .filter_map(|id| Some((*id, self.session.doc.graph.node_ports(*id, &base).ok()?)))
            .collect();
        self.runtime.ports_for = Some(self.session.doc.graph.clone());
    }
}

/// The graph as far as evaluation cares: positions and frames do not matter.
pub(super) fn eval_graph(g: &Graph) -> Graph {
    let mut g = g.clone();
    g.frames.clear();
    for n in g.nodes.values_mut() {
        n.pos = [0.0, 0.0];
    }
    g
}
