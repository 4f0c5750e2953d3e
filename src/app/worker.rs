//! Evaluation off the UI thread. A worker thread owns the [`Evaluator`] (and so its cache);
//! the UI sends [`EvalRequest`]s numbered by a generation and polls [`WorkerMsg`]s. Results of
//! an older generation than the latest request are stale and dropped ([`Generations`]).
//!
//! The editor's graph is often unfinished. The worker evaluates every node it can: a node
//! whose validation or evaluation fails gets the error message, and it and its descendants are
//! left out, while the rest of the graph still evaluates. Nodes with side effects (`save`) and
//! their descendants are never evaluated automatically.
//!
//! Viewport first: a request carries what the preview shows ([`ViewRequest`]). The worker
//! evaluates that rectangle of the viewed output, tile by tile at the level of detail shown
//! ([`evaluate_view`]), renders it and sends it ([`WorkerMsg::Region`]); the whole graph is
//! evaluated only once no newer request has come for [`SETTLE`], so a stroke or a slider drag
//! costs the tiles it touches. A newer request also cancels the running one. An output larger
//! than [`WHOLE_PIXELS`] is never evaluated whole here.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::memory::{self, MemoryUse};
use super::preview::{PreviewSettings, ViewSpec};
use super::refresh::{self, Memo};
use super::state::error_node;
use crate::eval::region::{RegionOptions, INTERACTIVE_TILE};
use crate::eval::{CacheKey, EvalOptions, Evaluator, Plan, Progress};
use crate::graph::{Graph, GraphError, LoadedGraph, NodeId, PortRef, Source};
use crate::nodes::{self, Picture, Value};
use crate::raster::window::Rect;
use crate::raster::RgbnImage;
use crate::render::{self, Shading, View};
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Side of the node thumbnails, in pixels.
pub const THUMB_SIZE: usize = 96;

/// How long the graph must stay unchanged after a viewport was sent before the whole graph is
/// evaluated: while edits keep coming (a stroke, a slider drag) only the viewport is.
pub const SETTLE: Duration = Duration::from_millis(120);

/// The largest output (pixels) the editor evaluates whole; a larger viewed output is shown by
/// its viewport only (`rgbn eval` computes it whole).
pub const WHOLE_PIXELS: usize = 64 << 20;

/// While edits keep coming, a viewed output that depends on a global operator with a coarse
/// form (an integration, a projection) is evaluated at the first level where it has at most
/// this many pixels, if that is coarser than the level shown: the global operator then runs
/// on that level's pixels ([`crate::eval::region`]). The level shown follows once edits pause,
/// then the whole graph.
pub const INTERACTIVE_GLOBAL_PIXELS: usize = 1 << 20;

/// Label of the top-level graph in errors (see [`error_node`]).
pub const TOP_LABEL: &str = "<memory>";

/// Asks the worker to evaluate every node of `graph` it can.
#[derive(Clone)]
pub struct EvalRequest {
    /// Increases with every request.
    pub generation: u64,
    /// The graph (a copy: the UI keeps editing its own).
    pub graph: Graph,
    /// Folder that relative paths are relative to.
    pub base_dir: PathBuf,
    /// Set to stop this evaluation early.
    pub cancel: Arc<AtomicBool>,
    /// The part of one output the preview shows: evaluated first, tile by tile at the level of
    /// detail shown ([`Evaluator::eval_region`]), and sent as [`WorkerMsg::Region`] before the
    /// whole graph is evaluated.
    pub view: Option<ViewRequest>,
    /// The preview's display settings: the worker renders the viewport with them, so that it
    /// goes on screen in the frame it arrives.
    pub settings: Option<PreviewSettings>,
    /// Outputs whose whole values the outcome carries besides the viewed one (the input of a
    /// before/after split, a stamp's source, an output being exported); the others are
    /// evaluated for their thumbnails and keys only ([`super::refresh`]). `None`: every value
    /// is carried (callers without a preview).
    pub keep: Option<Vec<(NodeId, String)>>,
}

/// The output the preview shows, and how.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewRequest {
    /// The node shown.
    pub node: NodeId,
    /// Its output port.
    pub port: String,
    /// Panel size, zoom and pan: which rectangle of the output is on screen, at which level.
    pub spec: ViewSpec,
}

/// What the preview shows of an output, evaluated before the whole graph.
#[derive(Clone, Debug)]
pub struct RegionOutcome {
    /// The request's generation.
    pub generation: u64,
    /// The node shown.
    pub node: NodeId,
    /// Its output port.
    pub port: String,
    /// The rectangle evaluated, in pixels of the level.
    pub rect: Rect,
    /// The level of detail (pixels are `2^level` blocks of full-resolution ones).
    pub level: u32,
    /// Evaluated at a level coarser than the one shown, because a global operator is computed
    /// at a coarse level while edits keep coming ([`INTERACTIVE_GLOBAL_PIXELS`]).
    pub coarse: bool,
    /// The output's size at full resolution.
    pub full_size: (usize, usize),
    /// The output over `rect` at the level.
    pub value: Value,
    /// The content key of the whole output (as [`PortValue::key`]).
    pub key: CacheKey,
    /// The viewport rendered under [`EvalRequest::settings`] (not in the height view, which
    /// needs the whole image).
    pub picture: Option<(egui::ColorImage, PreviewSettings)>,
    /// Tiles computed (not taken from the cache or the previous result).
    pub tiles_computed: usize,
    /// Wall time of the region evaluation (and rendering).
    pub elapsed: Duration,
    /// When it was done.
    pub ready: Instant,
}

/// One node's output.
#[derive(Clone, Debug)]
pub struct PortValue {
    /// The value.
    pub value: Value,
    /// Its content key (the same value has the same key in every evaluation).
    pub key: CacheKey,
}

/// Everything the worker learnt in one evaluation.
#[derive(Clone, Debug, Default)]
pub struct EvalOutcome {
    /// The request's generation.
    pub generation: u64,
    /// Output values by (node, port): the viewed output's and [`EvalRequest::keep`]'s.
    pub values: BTreeMap<(NodeId, String), PortValue>,
    /// The content key of every output evaluated (with a value or not), by (node, port).
    pub keys: BTreeMap<(NodeId, String), CacheKey>,
    /// Thumbnails (sRGB RGBA, at most [`THUMB_SIZE`] a side) of each node's first output.
    pub thumbs: BTreeMap<NodeId, Arc<Picture>>,
    /// Errors by node.
    pub node_errors: BTreeMap<NodeId, String>,
    /// Nodes waiting for an input: a required input (this port) is not connected yet. Not a
    /// failure: a node just added is in this state until it is wired.
    pub waiting: BTreeMap<NodeId, String>,
    /// Errors not attributable to a node of this graph.
    pub error: Option<String>,
    /// Relative RMS curl of each node's RGBN output.
    pub curl: BTreeMap<NodeId, f64>,
    /// Non-integrable fraction F of each node's RGBN output.
    pub fraction: BTreeMap<NodeId, f64>,
    /// Nodes computed (cache misses) in this evaluation.
    pub computed: usize,
    /// Wall time.
    pub elapsed: Duration,
    /// Memory cache: entries and bytes.
    pub cache: (usize, usize),
    /// What the worker holds against the memory budget (the values kept included).
    pub memory: MemoryUse,
    /// The evaluation was cancelled.
    pub cancelled: bool,
    /// The viewed output is larger than [`WHOLE_PIXELS`]: only its viewport was evaluated
    /// ([`WorkerMsg::Region`]), no node whole.
    pub viewport_only: bool,
    /// A [`WorkerMsg::Readouts`] of this generation follows, unless a newer request came
    /// first (whose own outcome then supersedes this one).
    pub readouts_follow: bool,
}

/// Messages from the worker.
#[derive(Debug)]
pub enum WorkerMsg {
    /// A node finished.
    Progress {
        /// Generation of the request.
        generation: u64,
        /// Nodes done.
        done: usize,
        /// Nodes to run.
        total: usize,
    },
    /// The viewed part of the viewed output, ahead of the whole evaluation.
    Region(Box<RegionOutcome>),
    /// The evaluation finished (or failed, or was cancelled).
    Done(Box<EvalOutcome>),
    /// The integrability readouts of the evaluation of the same generation.
    Readouts(Box<Readouts>),
}

/// The integrability readouts of an evaluation, sent after its values.
#[derive(Clone, Debug, Default)]
pub struct Readouts {
    /// The request's generation.
    pub generation: u64,
    /// Relative RMS curl of each node's RGBN output.
    pub curl: BTreeMap<NodeId, f64>,
    /// Non-integrable fraction F of each node's RGBN output.
    pub fraction: BTreeMap<NodeId, f64>,
}

/// Tracks request generations: only the newest request's results are accepted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Generations {
    sent: u64,
    done: u64,
}

impl Generations {
    /// The number for a new request.
    pub fn new_request(&mut self) -> u64 {
        self.sent += 1;
        self.sent
    }
    /// True if a result of `generation` is current (and marks it done); false if stale.
    pub fn accept(&mut self, generation: u64) -> bool {
        if generation == self.sent {
            self.done = generation;
            true
        } else {
            false
        }
    }
    /// A request is out and its result not yet accepted.
    #[must_use]
    pub fn in_flight(&self) -> bool {
        self.done != self.sent
    }
    /// The newest generation sent.
    #[must_use]
    pub fn latest(&self) -> u64 {
        self.sent
    }
}

/// The worker thread's handle.
pub struct Worker {
    tx: Option<Sender<EvalRequest>>,
    rx: Receiver<WorkerMsg>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Worker {
    /// Starts the thread. `wake` is called after each message (the editor asks for a repaint).
    pub fn spawn(wake: Arc<dyn Fn() + Send + Sync>) -> Self {
        let (tx, req_rx) = channel::<EvalRequest>();
        let (msg_tx, rx) = channel();
        let thread = std::thread::Builder::new()
            .name("rgbn-eval".into())
            .spawn(move || {
                let budget = memory::budget().unwrap_or(crate::eval::DEFAULT_BUDGET as u64);
                crate::recycle::set_keep_limit(memory::pool_share(budget));
                let ev = Evaluator::new(memory::cache_share(budget));
                let mut memo = Memo::default();
                let mut sizes = Sizes::new();
                let mut next: Option<EvalRequest> = None;
                loop {
                    let mut req = match next.take() {
                        Some(r) => r,
                        None => match req_rx.recv() {
                            Ok(r) => r,
                            Err(_) => break,
                        },
                    };
                    // Only the newest request matters.
                    while let Ok(newer) = req_rx.try_recv() {
                        req = newer;
                    }
                    if req.cancel.load(Ordering::Relaxed) {
                        continue;
                    }
                    let mut whole_too = true;
                    if let Some(r) = evaluate_view(&ev, &req, &mut sizes, true) {
                        whole_too = r.full_size.0 * r.full_size.1 <= WHOLE_PIXELS;
                        let coarse = r.coarse;
                        if msg_tx.send(WorkerMsg::Region(Box::new(r))).is_err() {
                            break;
                        }
                        wake();
                        // While edits keep coming, only viewports are evaluated.
                        match req_rx.recv_timeout(SETTLE) {
                            Ok(newer) => {
                                next = Some(newer);
                                continue;
                            }
                            Err(RecvTimeoutError::Timeout) => {}
                            Err(RecvTimeoutError::Disconnected) => break,
                        }
                        // Edits paused: the level shown, then the whole graph.
                        if coarse {
                            if let Some(r) = evaluate_view(&ev, &req, &mut sizes, false) {
                                if msg_tx.send(WorkerMsg::Region(Box::new(r))).is_err() {
                                    break;
                                }
                                wake();
                            }
                            if let Ok(newer) = req_rx.try_recv() {
                                next = Some(newer);
                                continue;
                            }
                        }
                    }
                    let out = if whole_too {
                        let (ptx, pwake, g) = (msg_tx.clone(), wake.clone(), req.generation);
                        let progress = Arc::new(move |p: &Progress| {
                            let _ = ptx.send(WorkerMsg::Progress {
                                generation: g,
                                done: p.done,
                                total: p.total,
                            });
                            pwake();
                        });
                        let (out, plan) = evaluate_memo(&ev, &mut memo, &req, Some(progress));
                        for ((id, port), v) in &out.values {
                            if let Some(z) = v.value.size() {
                                sizes.insert((*id, port.clone()), z);
                            }
                        }
                        (out, plan)
                    } else {
                        let mut out = EvalOutcome {
                            generation: req.generation,
                            viewport_only: true,
                            cache: ev.mem_usage(),
                            ..EvalOutcome::default()
                        };
                        out.memory = memory_use(&ev, &memo, &out);
                        (out, None)
                    };
                    let (mut out, plan) = out;
                    out.readouts_follow = plan.is_some();
                    if msg_tx.send(WorkerMsg::Done(Box::new(out))).is_err() {
                        break;
                    }
                    wake();
                    memory::trim();
                    // The readouts, unless an edit came meanwhile.
                    if let Ok(newer) = req_rx.try_recv() {
                        next = Some(newer);
                        continue;
                    }
                    if let Some(p) = plan {
                        // Always answered (empty when there is nothing to read out): the editor
                        // counts itself busy until the readouts of what it shows arrive.
                        let r = refresh::readouts(&ev, &mut memo, &req, &p).unwrap_or_else(|| {
                            Readouts {
                                generation: req.generation,
                                ..Readouts::default()
                            }
                        });
                        if msg_tx.send(WorkerMsg::Readouts(Box::new(r))).is_err() {
                            break;
                        }
                        wake();
                    }
                }
            })
            .expect("spawn the evaluation thread");
        Self {
            tx: Some(tx),
            rx,
            thread: Some(thread),
        }
    }

    /// Queues a request.
    pub fn send(&self, req: EvalRequest) {
        if let Some(tx) = &self.tx {
            let _ = tx.send(req);
        }
    }

    /// The next message, if any (never blocks).
    pub fn poll(&self) -> Option<WorkerMsg> {
        self.rx.try_recv().ok()
    }

    /// Waits up to `timeout` for the next message (tests).
    pub fn wait(&self, timeout: Duration) -> Option<WorkerMsg> {
        self.rx.recv_timeout(timeout).ok()
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.tx = None; // ends the thread's loop after its current evaluation
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Full-resolution sizes of outputs seen, by (node, port).
pub type Sizes = BTreeMap<(NodeId, String), (usize, usize)>;

/// The graph without its side-effect nodes, with one output: "ID:PORT" of the view.
fn view_plan(req: &EvalRequest, v: &ViewRequest) -> Result<(Plan, String), GraphError> {
    let mut g = req.graph.clone();
    for id in side_effect_closure(&g) {
        g.nodes.remove(&id);
    }
    let name = format!("{}:{}", v.node, v.port);
    g.outputs.clear();
    g.exposed.clear();
    g.outputs.insert(
        name.clone(),
        PortRef {
            node: v.node,
            port: v.port.clone(),
        },
    );
    let lg = LoadedGraph::from_graph(g, None, req.base_dir.clone())?;
    Ok((Plan::new(&lg, &BTreeMap::new(), &req.base_dir)?, name))
}

/// Evaluates the request's view, if it has one and it evaluates: the rectangle of the viewed
/// output on screen, at the level of detail shown — or, when `interacting` and the output
/// depends on a global operator with a coarse form, at least at the level where the output
/// has [`INTERACTIVE_GLOBAL_PIXELS`] (then [`RegionOutcome::coarse`]). An output of unknown
/// size is first evaluated at the coarsest level (a pixel or so) to learn it. Errors are left
/// to the whole evaluation, which attributes them to nodes.
pub fn evaluate_view(
    ev: &Evaluator,
    req: &EvalRequest,
    sizes: &mut Sizes,
    interacting: bool,
) -> Option<RegionOutcome> {
    let t0 = Instant::now();
    let v = req.view.as_ref()?;
    let (plan, name) = view_plan(req, v).ok()?;
    let opts = EvalOptions {
        cancel: crate::cancel::Cancel::from_flag(req.cancel.clone()),
        progress: None,
        curl_stats: false,
    };
    let id = (v.node, v.port.clone());
    let probe = RegionOptions {
        tile: INTERACTIVE_TILE,
        level: crate::eval::region::MAX_LEVEL,
    };
    // A size remembered from an earlier evaluation may be stale (a parameter changed it): then
    // the result says the size, and the view is evaluated again.
    // Unknown (a node just added): most operators keep their input's size, so an input's
    // size seen before is the first guess; the result corrects it. Only without one is the
    // output evaluated at the coarsest level to learn it (operators without a coarse form are
    // then computed whole, which can take long).
    let guess = || {
        req.graph.nodes.get(&v.node).and_then(|n| {
            n.inputs.values().find_map(|s| match s {
                Source::Node(src, port) => sizes.get(&(*src, port.clone())).copied(),
                _ => None,
            })
        })
    };
    let mut full = match sizes.get(&id).copied().or_else(guess) {
        Some(z) => z,
        None => {
            ev.eval_region(&plan, &name, Rect::new(0, 0, 1, 1), &probe, &opts)
                .ok()?
                .full_size
        }
    };
    let global = interacting && crate::eval::region::depends_on_coarse_global(&plan, &name);
    let mut attempt = 0;
    let (r, level) = loop {
        let min_level = if global { interactive_level(full) } else { 0 };
        let (rect, level) = v.spec.visible_from(full, INTERACTIVE_TILE, min_level)?;
        let ropts = RegionOptions {
            tile: INTERACTIVE_TILE,
            level,
        };
        let r = ev.eval_region(&plan, &name, rect, &ropts, &opts);
        attempt += 1;
        match r {
            Ok(r) if r.full_size == full => break (r, level),
            Ok(r) if attempt < 2 => full = r.full_size,
            Err(_) if attempt < 2 => {
                full = ev
                    .eval_region(&plan, &name, Rect::new(0, 0, 1, 1), &probe, &opts)
                    .ok()?
                    .full_size;
            }
            _ => return None,
        }
    };
    sizes.insert(id, r.full_size);
    let picture = req
        .settings
        .as_ref()
        .filter(|s| !(matches!(r.value, Value::Rgbn(_)) && s.view == super::preview::Mode::Height))
        .and_then(|s| Some((super::preview::color_image(&r.value, s)?, s.clone())));
    Some(RegionOutcome {
        picture,
        generation: req.generation,
        node: v.node,
        port: v.port.clone(),
        rect: r.rect,
        level,
        coarse: v
            .spec
            .visible(r.full_size, INTERACTIVE_TILE)
            .is_some_and(|(_, shown)| shown < level),
        full_size: r.full_size,
        tiles_computed: r.tiles_computed(),
        key: r.key,
        value: r.value,
        elapsed: t0.elapsed(),
        ready: Instant::now(),
    })
}

/// The first level at which an output of `size` has at most [`INTERACTIVE_GLOBAL_PIXELS`].
fn interactive_level(size: (usize, usize)) -> u32 {
    let mut level = 0;
    while level < crate::eval::region::MAX_LEVEL
        && (size.0 >> level).max(1) * (size.1 >> level).max(1) > INTERACTIVE_GLOBAL_PIXELS
    {
        level += 1;
    }
    level
}

/// Nodes that run a side effect or depend on one.
fn side_effect_closure(g: &Graph) -> BTreeSet<NodeId> {
    let mut out = BTreeSet::new();
    let mut changed = true;
    while changed {
        changed = false;
        for (id, n) in &g.nodes {
            if out.contains(id) {
                continue;
            }
            let effect = nodes::find(&n.op).is_some_and(|o| o.spec().side_effect);
            let below = n
                .inputs
                .values()
                .any(|s| matches!(s, Source::Node(src, _) if out.contains(src)));
            if effect || below {
                out.insert(*id);
                changed = true;
            }
        }
    }
    out
}

/// `id` and every node downstream of it.
fn descendants(g: &Graph, id: NodeId) -> BTreeSet<NodeId> {
    let mut out = BTreeSet::from([id]);
    let mut changed = true;
    while changed {
        changed = false;
        for (nid, n) in &g.nodes {
            if !out.contains(nid)
                && n.inputs
                    .values()
                    .any(|s| matches!(s, Source::Node(src, _) if out.contains(src)))
            {
                out.insert(*nid);
                changed = true;
            }
        }
    }
    out
}

/// Evaluates every node of the request's graph it can (see the module docs).
pub fn evaluate(
    ev: &Evaluator,
    req: &EvalRequest,
    progress: Option<crate::eval::ProgressFn>,
) -> EvalOutcome {
    evaluate_with_plan(ev, req, progress).0
}

/// The integrability readouts (relative RMS curl, non-integrable fraction F) of every node
/// of `plan`, taken after an evaluation was shown ([`WorkerMsg::Readouts`]): the values come
/// from the cache, the readouts run on all cores, and an edit meanwhile cancels them.
pub fn readouts(ev: &Evaluator, req: &EvalRequest, plan: &Plan) -> Option<Readouts> {
    refresh::readouts(ev, &mut Memo::default(), req, plan)
}

/// [`evaluate`], and the plan it evaluated (without the nodes that failed).
pub fn evaluate_with_plan(
    ev: &Evaluator,
    req: &EvalRequest,
    progress: Option<crate::eval::ProgressFn>,
) -> (EvalOutcome, Option<Plan>) {
    evaluate_memo(ev, &mut Memo::default(), req, progress)
}

/// [`evaluate_with_plan`] remembering thumbnails and readouts in `memo` between evaluations
/// (as the worker does): a node whose content key `memo` knows is not evaluated for them.
pub fn evaluate_memo(
    ev: &Evaluator,
    memo: &mut Memo,
    req: &EvalRequest,
    progress: Option<crate::eval::ProgressFn>,
) -> (EvalOutcome, Option<Plan>) {
    let t0 = Instant::now();
    let mut out = EvalOutcome {
        generation: req.generation,
        ..EvalOutcome::default()
    };
    let mut g = req.graph.clone();
    for id in side_effect_closure(&g) {
        g.nodes.remove(&id);
    }
    // One graph output per node output: "ID:PORT".
    let mut ports: BTreeMap<NodeId, Vec<String>> = BTreeMap::new();
    let mut plan = None;
    for _attempt in 0..=req.graph.nodes.len() {
        if req.cancel.load(Ordering::Relaxed) {
            out.cancelled = true;
            return (out, None);
        }
        g.outputs.clear();
        g.exposed.clear();
        ports.clear();
        let ids: Vec<NodeId> = g.nodes.keys().copied().collect();
        let mut failed = None;
        for id in ids {
            match g.node_ports(id, &req.base_dir) {
                Ok(p) => {
                    let names: Vec<String> = p.outputs.iter().map(|o| o.name.clone()).collect();
                    for name in &names {
                        g.outputs.insert(
                            format!("{id}:{name}"),
                            PortRef {
                                node: id,
                                port: name.clone(),
                            },
                        );
                    }
                    ports.insert(id, names);
                }
                Err(e) => {
                    failed = Some((id, Left::Failed(e.to_string())));
                    break;
                }
            }
        }
        let err = match failed {
            Some(f) => Some(f),
            None => match LoadedGraph::from_graph(g.clone(), None, req.base_dir.clone())
                .and_then(|lg| Plan::new(&lg, &BTreeMap::new(), &req.base_dir))
            {
                Ok(p) => {
                    // The readouts come after, apart ([`readouts`]): they never delay values.
                    let opts = EvalOptions {
                        cancel: crate::cancel::Cancel::from_flag(req.cancel.clone()),
                        progress: progress.clone(),
                        curl_stats: false,
                    };
                    match refresh::whole(ev, memo, req, &p, &ports, &opts, &mut out) {
                        Ok(()) => {
                            plan = Some(p);
                            None
                        }
                        Err(GraphError::Cancelled) => {
                            out.cancelled = true;
                            return (out, None);
                        }
                        Err(e) => left_out(&e).or_else(|| {
                            out.error = Some(e.to_string());
                            None
                        }),
                    }
                }
                Err(e) => left_out(&e).or_else(|| {
                    out.error = Some(e.to_string());
                    None
                }),
            },
        };
        match err {
            Some((id, left)) => {
                match left {
                    Left::Failed(msg) => out.node_errors.insert(id, short_error(&msg)),
                    Left::Waiting(port) => out.waiting.insert(id, port),
                };
                for d in descendants(&g, id) {
                    g.nodes.remove(&d);
                }
            }
            None => break,
        }
    }
    out.elapsed = t0.elapsed();
    out.cache = ev.mem_usage();
    out.memory = memory_use(ev, memo, &out);
    (out, plan)
}

/// What `ev`, `memo` and the values of `out` hold against the memory budget (the budget being
/// the cache's and the recycle pool's shares).
#[must_use]
pub fn memory_use(ev: &Evaluator, memo: &Memo, out: &EvalOutcome) -> MemoryUse {
    let (n, bytes) = ev.mem_usage();
    MemoryUse {
        budget: (ev.mem_budget() + crate::recycle::keep_limit()) as u64,
        cache: bytes,
        cache_values: n,
        shown: ev.held_outside(out.values.values().map(|v| &v.value)),
        thumbs: memo.bytes(),
        pool: crate::recycle::kept_bytes(),
    }
}

/// Why a node was left out of an evaluation.
enum Left {
    /// It failed (the message).
    Failed(String),
    /// A required input (this port) is not connected: it waits for it.
    Waiting(String),
}

/// The node an error is about and why it is left out, if the error is about one node.
fn left_out(e: &GraphError) -> Option<(NodeId, Left)> {
    let id = error_node(e, TOP_LABEL)?;
    Some((
        id,
        match e {
            GraphError::MissingInput { port, .. } => Left::Waiting(port.clone()),
            _ => Left::Failed(e.to_string()),
        },
    ))
}

/// An error message without its trailing location (`: node 7 "name" in <memory>`), which the
/// editor shows on the node itself.
#[must_use]
pub fn short_error(msg: &str) -> String {
    match msg.rfind(": node ") {
        Some(i) if msg[i..].ends_with(TOP_LABEL) => msg[..i].to_string(),
        _ => msg.to_string(),
    }
}

/// A small picture of a value (nearest-neighbour downsampling; RGBN images relit with the
/// default light), or `None` for numbers.
#[must_use]
pub fn thumbnail(v: &Value) -> Option<Picture> {
    match v {
        Value::Rgbn(img) => {
            let small = downsample(img, THUMB_SIZE);
            let rgba = render::render(&small, View::Relit, &Shading::default()).ok()?;
            Some(Picture {
                width: small.width(),
                height: small.height(),
                rgba,
            })
        }
        Value::Picture(p) => Some(shrink_picture(p, THUMB_SIZE)),
        Value::Mask(p) | Value::Scalar(p) => {
            let pic = plane_picture(p);
            Some(shrink_picture(&pic, THUMB_SIZE))
        }
        Value::Number(_) => None,
    }
}

fn fit(w: usize, h: usize, max: usize) -> (usize, usize) {
    let s = (max as f64 / w.max(h).max(1) as f64).min(1.0);
    (
        ((w as f64 * s).round() as usize).max(1),
        ((h as f64 * s).round() as usize).max(1),
    )
}

fn downsample(img: &RgbnImage, max: usize) -> RgbnImage {
    let (w, h) = (img.width(), img.height());
    let (tw, th) = fit(w, h, max);
    if (tw, th) == (w, h) {
        return img.clone();
    }
    let idx: Vec<usize> = (0..th)
        .flat_map(|r| (0..tw).map(move |x| (r * h / th) * w + x * w / tw))
        .collect();
    gather(img, tw, th, &idx)
}

/// A `tw`×`th` image of the pixels of `img` at the flat indices `idx` (row-major), every plane
/// alike; `img` itself if that fails.
#[must_use]
pub fn gather(img: &RgbnImage, tw: usize, th: usize, idx: &[usize]) -> RgbnImage {
    let pick = |p: &[f32]| -> Vec<f32> { idx.iter().map(|&i| p[i]).collect() };
    let [cr, cg, cb] = img.color();
    let [nx, ny, nz] = img.normal();
    RgbnImage::new(
        tw,
        th,
        [pick(cr), pick(cg), pick(cb)],
        [pick(nx), pick(ny), pick(nz)],
        img.mask().map(pick),
    )
    .unwrap_or_else(|_| img.clone())
}

fn shrink_picture(p: &Picture, max: usize) -> Picture {
    let (tw, th) = fit(p.width, p.height, max);
    let mut rgba = Vec::with_capacity(tw * th * 4);
    for r in 0..th {
        for x in 0..tw {
            let i = ((r * p.height / th) * p.width + x * p.width / tw) * 4;
            rgba.extend_from_slice(&p.rgba[i..i + 4]);
        }
    }
    Picture {
        width: tw,
        height: th,
        rgba,
    }
}

/// A scalar field or mask as grey, scaled from its minimum to its maximum (a mask in [0, 1]
/// stays as is).
#[must_use]
pub fn plane_picture(p: &crate::raster::Plane) -> Picture {
    let d = p.data();
    let (mut lo, mut hi) = d
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    if lo >= 0.0 && hi <= 1.0 {
        (lo, hi) = (0.0, 1.0);
    }
    let span = if hi > lo { hi - lo } else { 1.0 };
    let rgba = d
        .iter()
        .flat_map(|v| {
            let g = (((v - lo) / span).clamp(0.0, 1.0) * 255.0).round() as u8;
            [g, g, g, 255]
        })
        .collect();
    Picture {
        width: p.width(),
        height: p.height(),
        rgba,
    }
}

#[cfg(test)]
#[path = "worker_tests.rs"]
mod tests;
