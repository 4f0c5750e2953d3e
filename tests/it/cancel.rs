//! Cancellation reaches the running operator (`rgbn::cancel`): long kernels check the token
//! while they run, a cancelled evaluation returns `Cancelled`, and nothing computed after the
//! cancellation is cached, in memory or on disk.

use crate::common::*;
use rgbn::cancel::Cancel;
use rgbn::eval::{EvalOptions, EvalResult, Evaluator, Plan, Status};
use rgbn::graph::{GraphError, LoadedGraph};
use std::collections::BTreeMap;
use std::path::Path;

/// A masked sphere (`surface`, node 1) into `op` (node 2) with `params`, output `out` of node 2.
fn graph(op: &str, params: &str, out: &str) -> LoadedGraph {
    let text = format!(
        r#"(
    version: 2,
    next_id: 3,
    outputs: {{ "out": (node: 2, port: "{out}") }},
    nodes: [
        (id: 1, op: "surface", params: {{ "shape": Choice("sphere"), "width": Int(160), "height": Int(144), "radius_px": Float(60.0) }}),
        (id: 2, op: "{op}", params: {{ {params} }}, inputs: {{ "image": Node(1, "image") }}),
    ],
)"#
    );
    LoadedGraph::from_text(&text, "cancel.ron", root().join("graphs")).unwrap()
}

#[allow(clippy::result_large_err)] // the library's own error type, as its API returns it
fn eval(ev: &Evaluator, lg: &LoadedGraph, cancel: Cancel) -> Result<EvalResult, GraphError> {
    let plan = Plan::new(lg, &BTreeMap::new(), Path::new(".")).unwrap();
    ev.eval(
        &plan,
        &["out"],
        &EvalOptions {
            cancel,
            ..EvalOptions::default()
        },
    )
}

fn status_of(r: &EvalResult, node: u64) -> Status {
    r.stats
        .iter()
        .find(|s| s.at.node == Some(node))
        .map(|s| s.status)
        .unwrap()
}

/// The long operators, each as (op, params, output).
const LONG: &[(&str, &str, &str)] = &[
    (
        "integrate",
        r#""method": Choice("masked_poisson")"#,
        "height",
    ),
    ("integrate", r#""method": Choice("poisson_dct")"#, "height"),
    (
        "integrate",
        r#""method": Choice("frankot_chellappa")"#,
        "height",
    ),
    ("integrate", r#""method": Choice("bilateral")"#, "height"),
    ("project", "", "image"),
    ("bilateral", r#""sigma_spatial_px": Float(3.0)"#, "base"),
    ("filter.gaussian", r#""sigma_px": Float(4.0)"#, "image"),
];

#[test]
fn a_cancelled_operator_is_stopped_inside_and_nothing_half_made_is_cached() {
    // Checks the evaluator itself makes on `surface → relight` (relight checks nothing): the
    // checks made before node 2's kernel starts are all but the last (node 2's own after-run
    // check), so a token set at check `base` is first seen inside node 2's kernel.
    let base = {
        let t = Cancel::after_checks(u64::MAX);
        eval(
            &Evaluator::default(),
            &graph("relight", "", "picture"),
            t.clone(),
        )
        .unwrap();
        t.checks()
    };
    assert!(
        base >= 2,
        "the evaluator checks before and after each node: {base}"
    );
    for &(op, params, out) in LONG {
        // A disk cache of its own, so node 1 runs here too and the checks count as above.
        let dir = tempfile::tempdir().unwrap();
        let lg = graph(op, params, out);
        let whole = eval(&Evaluator::default(), &lg, Cancel::never()).unwrap();
        // The operator's kernels check the token while they run.
        let counted = Cancel::after_checks(u64::MAX);
        eval(&Evaluator::default(), &lg, counted.clone()).unwrap();
        assert!(
            counted.checks() > base,
            "{op} {params}: {} checks, no more than the evaluator's own {base}",
            counted.checks()
        );

        let cached = Evaluator::default().with_disk_cache(dir.path()).unwrap();
        let r = eval(&cached, &lg, Cancel::after_checks(base));
        assert!(
            matches!(r, Err(GraphError::Cancelled)),
            "{op} {params}: {:?}",
            r.map(|_| "finished")
        );
        // Nothing of node 2 was kept: computed again, and equal to an uncancelled run.
        let again = eval(&cached, &lg, Cancel::never()).unwrap();
        assert_eq!(
            status_of(&again, 1),
            Status::Hit,
            "{op}: the source was kept"
        );
        assert_eq!(status_of(&again, 2), Status::Miss, "{op} {params}");
        assert_eq!(again.outputs, whole.outputs, "{op} {params}");
        // On disk too: a fresh process finds the complete entry only (bilateral, asked for
        // `base` alone, leaves `detail` out, and the disk keeps no partial entry).
        let fresh = Evaluator::default().with_disk_cache(dir.path()).unwrap();
        let from_disk = eval(&fresh, &lg, Cancel::never()).unwrap();
        let expect = if op == "bilateral" {
            Status::Miss
        } else {
            Status::DiskHit
        };
        assert_eq!(status_of(&from_disk, 2), expect, "{op} {params}");
        assert_eq!(from_disk.outputs, whole.outputs, "{op} {params}");
    }
}

#[test]
fn a_cancelled_conjugate_gradient_stops_at_its_next_iteration() {
    use rgbn::raster::integrate::{integrate_normals, IntegrateParams, IntegrationMethod};
    use rgbn::raster::sample::Surface;
    let (img, _) = Surface::Sphere { radius_px: 70.0 }.render(192, 176);
    assert!(img.mask().is_some());
    let p = IntegrateParams {
        method: IntegrationMethod::MaskedPoisson,
        ..IntegrateParams::default()
    };
    let (_, full) = integrate_normals(&img, &p).unwrap();
    assert!(full.iterations >= 6, "{} iterations", full.iterations);
    let t = Cancel::after_checks(3);
    let stopped = {
        let _current = t.enter();
        integrate_normals(&img, &p)
    };
    // Stopped: whatever it returned (the node layer discards it), it ran fewer iterations.
    if let Ok((_, r)) = stopped {
        assert!(
            r.iterations < full.iterations,
            "{} of {}",
            r.iterations,
            full.iterations
        );
    }
    assert!(t.is_cancelled());
    // Outside any token, the same call is unaffected.
    let (_, again) = integrate_normals(&img, &p).unwrap();
    assert_eq!(again.iterations, full.iterations);
}

/// The checks made evaluating one source node (`demo` or `surface`) of `rows` rows.
fn source_checks(source: &str, rows: usize) -> u64 {
    let params = if source == "demo" {
        format!(r#""size": Int({rows})"#)
    } else {
        format!(
            r#""shape": Choice("sphere"), "width": Int(64), "height": Int({rows}), "radius_px": Float(20.0)"#
        )
    };
    let text = format!(
        r#"(
    version: 2,
    next_id: 2,
    outputs: {{ "out": (node: 1, port: "image") }},
    nodes: [ (id: 1, op: "{source}", params: {{ {params} }}) ],
)"#
    );
    let lg = LoadedGraph::from_text(&text, "source.ron", root().join("graphs")).unwrap();
    let t = Cancel::after_checks(u64::MAX);
    eval(&Evaluator::default(), &lg, t.clone()).unwrap();
    t.checks()
}

#[test]
fn the_procedural_sources_check_the_token_on_every_row() {
    // A 4K demo takes seconds to compute: Ctrl-C while it runs must stop it, not wait for it.
    // Every row of each pass checks, so 300 more rows make at least 300 more checks (the
    // evaluator's own checks are the same for both sizes).
    for source in ["demo", "surface"] {
        let (small, large) = (source_checks(source, 64), source_checks(source, 364));
        assert!(
            large >= small + 300,
            "{source}: {small} checks for 64 rows, {large} for 364"
        );
    }
}
