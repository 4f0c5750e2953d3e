//! Many pen strokes on the 2048² demo, as the editor draws them, without a window (issue 38
//! item 5): each stroke goes through the pen tool's gestures ([`rgbn::app::tools`]) with live
//! updates, each update followed by the worker's viewport evaluation
//! ([`rgbn::app::worker::evaluate_view`]: the viewed pen at 1:1 in a 1600×1000 panel centred on
//! the stroke), and each finished stroke by the whole-graph refresh
//! ([`rgbn::app::worker::evaluate`]), all on one evaluator with the editor's cache budget.
//!
//! `one`: every stroke a new path of the selected pen node (the default); `chained`: every
//! stroke a new pen node ("new node" on). Prints, for strokes 1 and N, the viewport time per
//! live update (median and p90) and the whole-graph refresh time.
//!
//! `cargo run --release --example pen_strokes -- one 80` (run under `/usr/bin/time -f "%e %U %S
//! %M"` for the peak RSS).

use rgbn::app::state::Document;
use rgbn::app::tools::{pen_paths, Gesture, Press, ToolKind, ToolState};
use rgbn::app::worker::{evaluate, evaluate_view, EvalRequest, Sizes};
use rgbn::eval::Evaluator;
use rgbn::graph::NodeId;
use rgbn::params::ParamValue;
use std::path::Path;
use std::time::Instant;

/// The allocator the `rgbn` binary runs with.
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

const SIZE: f64 = 2048.0;
/// Live updates per stroke (10 px segments).
const SEGMENTS: usize = 20;

fn request(d: &Document, generation: u64, view: &(NodeId, String), at: [f64; 2]) -> EvalRequest {
    rgbn::app::soak::stroke_request(d, Path::new("."), generation, view, SIZE, at, Vec::new())
}

fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mode = args.get(1).map_or("one", String::as_str);
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(80);
    assert!(mode == "one" || mode == "chained", "mode: one or chained");
    let mut d = Document::demo();
    d.set_param(1, "size", ParamValue::Int(SIZE as i64));
    let budget = rgbn::eval::memory::physical_memory()
        .map_or(0, |m| usize::try_from(m / 4).unwrap_or(usize::MAX))
        .max(rgbn::eval::DEFAULT_BUDGET);
    let ev = Evaluator::new(budget);
    let tools = ToolState {
        kind: ToolKind::Pen,
        pen_new_node: mode == "chained",
        ..ToolState::default()
    };
    let mut sizes = Sizes::new();
    let (mut selected, mut viewed): (Option<NodeId>, (NodeId, String)) =
        (None, (3, "image".into()));
    let mut generation = 0;
    // The graph evaluated once before drawing, as the editor does on opening.
    evaluate(&ev, &request(&d, 0, &viewed, [1024.0, 1024.0]), None);
    let mut report = Vec::new();
    let base = d.base_dir();
    for k in 0..n {
        // Strokes on a 10 × 8 grid over the medallion, each a 200 px curve.
        let start = [
            224.0 + 180.0 * (k % 10) as f64,
            300.0 + 200.0 * ((k / 10) % 8) as f64,
        ];
        let mut gest = Gesture::stroke(&d, &tools, selected, Some(&viewed), Press::plain(start))
            .expect("a stroke starts");
        let mut live = Vec::new();
        let mut at = start;
        for s in 0..SEGMENTS {
            let a = 0.15 * s as f64 + 0.3 * (k % 7) as f64;
            at = [at[0] + 10.0 * a.cos(), at[1] + 10.0 * a.sin()];
            gest.update(&mut d.graph, at, Press::plain(at), false, true, &base)
                .expect("update");
            let node = gest.node().expect("written live");
            if selected != Some(node) {
                // The editor selects and views a node the tool made.
                selected = Some(node);
                viewed = (node, "image".into());
            }
            generation += 1;
            let t = Instant::now();
            evaluate_view(&ev, &request(&d, generation, &viewed, at), &mut sizes, true)
                .expect("viewport");
            live.push(t.elapsed().as_secs_f64() * 1e3);
        }
        assert!(gest.finish(&mut d, Press::plain(at)).expect("finish"));
        generation += 1;
        let t = Instant::now();
        let out = evaluate(&ev, &request(&d, generation, &viewed, at), None);
        let whole = t.elapsed().as_secs_f64() * 1e3;
        assert!(
            out.error.is_none() && out.node_errors.is_empty(),
            "{:?}",
            out.error
        );
        if k == 0 || k + 1 == n {
            report.push((k + 1, quantile(&live, 0.5), quantile(&live, 0.9), whole));
        }
    }
    let pens: Vec<NodeId> = d
        .graph
        .nodes
        .values()
        .filter(|n| n.op == "pen")
        .map(|n| n.id)
        .collect();
    let paths: usize = pens
        .iter()
        .map(|id| pen_paths(&d.graph, *id).map_or(0, |p| p.len()))
        .sum();
    println!(
        "mode {mode}: {} strokes → {} pen node(s), {paths} path(s); {} undo steps",
        n,
        pens.len(),
        d.history.undo_len()
    );
    for (k, med, p90, whole) in report {
        println!(
            "stroke {k}: viewport per live update median {med:.1} ms, p90 {p90:.1} ms; whole-graph refresh {whole:.0} ms"
        );
    }
}
