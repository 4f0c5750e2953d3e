//! The editor's memory soak (issue 36 item 6): separate pen strokes on the demo, each a new
//! pen node chained after the one before (the worst case: "new node" on; the default draws
//! every stroke as a path of one pen node), sent to the editor's own worker thread
//! ([`Worker`]) as the editor sends them — live updates with the viewport, then the stroke's
//! end — holding each outcome as the editor does until the next arrives, and measuring the
//! process's resident memory against what the worker accounts for ([`MemoryUse`]).
//!
//! `tests/editor_memory.rs` runs it small; `examples/editor_soak.rs` runs the case
//! (80 strokes on the 2048² demo) and prints the figures.

use super::memory::{peak_resident, resident, MemoryUse};
use super::preview::{PreviewSettings, ViewSpec};
use super::refresh::kept_outputs;
use super::state::Document;
use super::tools::{Gesture, Press, ToolKind, ToolState};
use super::worker::{EvalOutcome, EvalRequest, ViewRequest, Worker, WorkerMsg};
use crate::graph::NodeId;
use crate::params::ParamValue;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What the editor asks while a stroke is drawn on a `size`² image: the viewed output in a
/// 1600 × 1000 panel at 1:1, centred on the pen at `at`, keeping `keep` whole.
#[must_use]
pub fn stroke_request(
    d: &Document,
    base: &std::path::Path,
    generation: u64,
    viewed: &(NodeId, String),
    size: f64,
    at: [f64; 2],
    keep: Vec<(NodeId, String)>,
) -> EvalRequest {
    EvalRequest {
        generation,
        graph: d.graph.clone(),
        base_dir: base.to_path_buf(),
        cancel: Arc::new(AtomicBool::new(false)),
        view: Some(ViewRequest {
            node: viewed.0,
            port: viewed.1.clone(),
            spec: ViewSpec {
                panel: [1600.0, 1000.0],
                zoom: Some(1.0),
                pan: [(0.5 * size - at[0]) as f32, (0.5 * size - at[1]) as f32],
            },
        }),
        settings: Some(PreviewSettings::default()),
        keep: Some(keep),
    }
}

/// One stroke's figures, taken once its outcome and readouts arrived.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    /// What the worker accounted for (the status bar's figure).
    pub accounted: MemoryUse,
    /// The process's resident memory then.
    pub resident: u64,
    /// The whole-graph refresh: its wall time in the worker.
    pub refresh: Duration,
    /// Nodes it computed.
    pub computed: usize,
}

/// What a soak measured.
#[derive(Clone, Debug)]
pub struct Report {
    /// Resident memory before the first evaluation (the process without images).
    pub baseline: u64,
    /// Peak resident memory over the whole soak (`VmHWM`).
    pub peak: u64,
    /// One per stroke, in order.
    pub samples: Vec<Sample>,
    /// Pen nodes in the graph at the end.
    pub pens: usize,
}

/// Waits for the outcome of `generation` and then its readouts (at most `limit` in all).
fn wait_done(w: &Worker, generation: u64, limit: Duration) -> Option<EvalOutcome> {
    let t0 = Instant::now();
    let mut done = None;
    while t0.elapsed() < limit {
        match w.wait(Duration::from_millis(100)) {
            Some(WorkerMsg::Done(o)) if o.generation == generation => done = Some(*o),
            Some(WorkerMsg::Readouts(r)) if r.generation == generation => return done,
            _ => {}
        }
    }
    done
}

/// Draws `strokes` pen strokes of `segments` live updates each on the demo at `size`² with the
/// editor's worker (whose budget is [`super::memory::budget`]: set it first), and measures.
///
/// # Panics
/// When a stroke cannot be drawn or an outcome does not come within a minute (a broken
/// editor, which is what the soak is for).
#[must_use]
pub fn run(size: usize, strokes: usize, segments: usize) -> Report {
    let s = size as f64;
    let mut d = Document::demo();
    d.set_param(1, "size", ParamValue::Int(size as i64));
    let tools = ToolState {
        kind: ToolKind::Pen,
        pen_new_node: true,
        ..ToolState::default()
    };
    let w = Worker::spawn(Arc::new(|| {}));
    let baseline = resident().unwrap_or(0);
    let (mut selected, mut viewed): (Option<NodeId>, (NodeId, String)) =
        (None, (3, "image".into()));
    let mut generation = 0u64;
    let base = d.base_dir();
    let request =
        |d: &Document, generation: u64, viewed: &(NodeId, String), selected, at: [f64; 2]| {
            let keep = kept_outputs(&d.graph, Some(viewed), selected, None);
            stroke_request(d, &base, generation, viewed, s, at, keep)
        };
    // The graph evaluated once before drawing, as the editor does on opening.
    generation += 1;
    w.send(request(&d, generation, &viewed, selected, [0.5 * s; 2]));
    let mut outcome = wait_done(&w, generation, Duration::from_secs(60)).expect("first outcome");
    let mut samples = Vec::new();
    let scale = s / 2048.0;
    for k in 0..strokes {
        // Strokes on a 10 × 8 grid over the medallion, each a short curve.
        let start = [
            scale * (224.0 + 180.0 * (k % 10) as f64),
            scale * (300.0 + 200.0 * ((k / 10) % 8) as f64),
        ];
        let mut gest = Gesture::stroke(&d, &tools, selected, Some(&viewed), Press::plain(start))
            .expect("a stroke starts");
        let mut at = start;
        for j in 0..segments {
            let a = 0.15 * j as f64 + 0.3 * (k % 7) as f64;
            at = [
                at[0] + 10.0 * scale * a.cos(),
                at[1] + 10.0 * scale * a.sin(),
            ];
            gest.update(&mut d.graph, at, Press::plain(at), false, true, &base)
                .expect("update");
            if let Some(node) = gest.node() {
                if selected != Some(node) {
                    // The editor selects and views a node the tool made.
                    selected = Some(node);
                    viewed = (node, "image".into());
                }
            }
            generation += 1;
            w.send(request(&d, generation, &viewed, selected, at));
        }
        assert!(
            gest.finish(&mut d, Press::plain(at)).expect("finish"),
            "stroke {k} drawn"
        );
        generation += 1;
        w.send(request(&d, generation, &viewed, selected, at));
        let out = wait_done(&w, generation, Duration::from_secs(120)).expect("outcome");
        assert!(
            out.error.is_none() && out.node_errors.is_empty(),
            "stroke {k}: {:?} {:?}",
            out.error,
            out.node_errors
        );
        // The editor holds the newest outcome until the next one replaces it.
        outcome = out;
        samples.push(Sample {
            accounted: outcome.memory,
            resident: resident().unwrap_or(0),
            refresh: outcome.elapsed,
            computed: outcome.computed,
        });
    }
    let pens = d.graph.nodes.values().filter(|n| n.op == "pen").count();
    drop(outcome);
    Report {
        baseline,
        peak: peak_resident().unwrap_or(0),
        samples,
        pens,
    }
}
