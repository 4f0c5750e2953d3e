//! Cache behaviour, counted: what hits, what misses, and why.

use crate::common::*;
use rgbn::eval::{EvalOptions, EvalResult, Evaluator, Plan, Status};
use rgbn::graph::{LoadedGraph, NodeDef};
use rgbn::params::ParamValue;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// surface(1) → gaussian(2) → sharpen(3) → relight(4); gaussian(2) → curl(5); a second branch
/// view(6) from the surface.
const CHAIN: &str = r#"(
    version: 1,
    next_id: 7,
    outputs: {
        "relit": (node: 4, port: "picture"),
        "curl": (node: 5, port: "relative_rms"),
        "albedo": (node: 6, port: "picture"),
    },
    nodes: [
        (id: 1, op: "surface", params: { "shape": Choice("gaussians"), "width": Int(64), "height": Int(64) }),
        (id: 2, op: "filter.gaussian", name: Some("blur"), params: { "sigma_px": Float(1.5) }, inputs: { "image": Node(1, "image") }),
        (id: 3, op: "filter.sharpen", inputs: { "image": Node(2, "image") }),
        (id: 4, op: "relight", inputs: { "image": Node(3, "image") }),
        (id: 5, op: "curl", inputs: { "image": Node(2, "image") }),
        (id: 6, op: "view", params: { "view": Choice("albedo") }, inputs: { "image": Node(1, "image") }),
    ],
)"#;

fn chain() -> LoadedGraph {
    LoadedGraph::from_text(CHAIN, "chain.ron", root().join("graphs")).unwrap()
}

fn run(ev: &Evaluator, lg: &LoadedGraph, outputs: &[&str]) -> EvalResult {
    let plan = Plan::new(lg, &BTreeMap::new(), Path::new(".")).unwrap();
    ev.eval(&plan, outputs, &EvalOptions::default()).unwrap()
}

fn edit(lg: &LoadedGraph, f: impl FnOnce(&mut BTreeMap<u64, NodeDef>)) -> LoadedGraph {
    let mut g = lg.graph.clone();
    f(&mut g.nodes);
    LoadedGraph::from_graph(g, lg.path.clone(), lg.base_dir.clone()).unwrap()
}

#[test]
fn unchanged_moved_renamed_graphs_do_not_recompute() {
    let ev = Evaluator::default();
    let lg = chain();
    let first = run(&ev, &lg, &[]);
    assert_eq!(first.missed_nodes(), vec![1, 2, 3, 4, 5, 6]);
    assert_eq!(first.hits(), 0);

    let again = run(&ev, &lg, &[]);
    assert_eq!(again.misses(), 0);
    assert_eq!(again.outputs, first.outputs);

    let moved = edit(&lg, |n| {
        for node in n.values_mut() {
            node.pos = [node.pos[0] + 100.0, -50.0];
        }
        n.get_mut(&3).unwrap().name = Some("crisp".into());
        n.get_mut(&2).unwrap().name = None;
    });
    let r = run(&ev, &moved, &[]);
    assert_eq!(r.misses(), 0);
    assert_eq!(r.outputs, first.outputs);
    // A restated default is the same canonical parameter set.
    let restated = edit(&lg, |n| {
        n.get_mut(&3)
            .unwrap()
            .params
            .insert("amount".into(), ParamValue::Float(1.0));
    });
    assert_eq!(run(&ev, &restated, &[]).misses(), 0);
}

#[test]
fn a_parameter_change_misses_exactly_that_node_and_its_descendants() {
    let ev = Evaluator::default();
    let lg = chain();
    run(&ev, &lg, &[]);
    let edited = edit(&lg, |n| {
        n.get_mut(&2)
            .unwrap()
            .params
            .insert("sigma_px".into(), ParamValue::Float(2.5));
    });
    let r = run(&ev, &edited, &[]);
    assert_eq!(r.missed_nodes(), vec![2, 3, 4, 5]);
    // Upstream of the edit, the surface was a hit; the other branch (view) too.
    let hit: Vec<u64> = r
        .stats
        .iter()
        .filter(|s| s.status == Status::Hit)
        .filter_map(|s| s.at.node)
        .collect();
    assert!(hit.contains(&6) || hit.contains(&1), "{hit:?}");
    // Downstream of a hit nothing is pulled: node 1 need not be visited when 6 hits.
    let mut ids: Vec<u64> = r.stats.iter().filter_map(|s| s.at.node).collect();
    ids.sort_unstable();
    assert_eq!(ids, vec![1, 2, 3, 4, 5, 6]);

    let edited2 = edit(&edited, |n| {
        n.get_mut(&3)
            .unwrap()
            .params
            .insert("amount".into(), ParamValue::Float(0.5));
    });
    assert_eq!(run(&ev, &edited2, &[]).missed_nodes(), vec![3, 4]);
}

#[test]
fn evaluation_is_lazy() {
    let ev = Evaluator::default();
    let lg = chain();
    let r = run(&ev, &lg, &["albedo"]);
    let mut ids: Vec<u64> = r.stats.iter().filter_map(|s| s.at.node).collect();
    ids.sort_unstable();
    assert_eq!(ids, vec![1, 6]);
    assert_eq!(r.outputs.len(), 1);
    // Then only what is new for `curl` runs; a cached output needs nothing upstream.
    let r = run(&ev, &lg, &["curl"]);
    assert_eq!(r.missed_nodes(), vec![2, 5]);
    let r = run(&ev, &lg, &["curl"]);
    assert_eq!(
        r.stats.len(),
        1,
        "a hit on the output node pulls nothing upstream"
    );
}

/// Writes the two-node graph `text` as `name` in `dir` and evaluates it twice with one
/// evaluator: both nodes miss, then nothing does. Returns the evaluator, the plan and the first
/// result.
fn misses_then_hits(dir: &Path, name: &str, text: &str) -> (Evaluator, Plan, EvalResult) {
    let lg = LoadedGraph::load(&write(dir, name, text)).unwrap();
    let ev = Evaluator::default();
    let plan = Plan::new(&lg, &BTreeMap::new(), dir).unwrap();
    let opts = EvalOptions::default();
    let a = ev.eval(&plan, &[], &opts).unwrap();
    assert_eq!(a.missed_nodes(), vec![1, 2]);
    assert_eq!(ev.eval(&plan, &[], &opts).unwrap().misses(), 0);
    (ev, plan, a)
}

#[test]
fn changing_an_input_files_bytes_invalidates_its_dependants() {
    let d = tempfile::tempdir().unwrap();
    std::fs::copy(
        root().join("graphs/data/image.exr"),
        d.path().join("in.exr"),
    )
    .unwrap();
    let text = std::fs::read_to_string(graph_path("load.ron"))
        .unwrap()
        .replace("data/image.exr", "in.exr");
    let (ev, plan, a) = misses_then_hits(d.path(), "load.ron", &text);
    let opts = EvalOptions::default();
    // Same path, new bytes: a sphere instead of the demo.
    let (sphere, _) = rgbn::raster::sample::Surface::Sphere { radius_px: 20.0 }.render(48, 48);
    rgbn::raster::io::save_exr(
        &sphere,
        &d.path().join("in.exr"),
        rgbn::raster::io::ExrPrecision::Full,
    )
    .unwrap();
    let b = ev.eval(&plan, &[], &opts).unwrap();
    assert_eq!(b.missed_nodes(), vec![1, 2]);
    assert_ne!(a.outputs, b.outputs);
    // The same bytes under another name hit: keys are by content, not path.
    std::fs::copy(d.path().join("in.exr"), d.path().join("copy.exr")).unwrap();
    let p2 = write(d.path(), "load2.ron", &text.replace("in.exr", "copy.exr"));
    let lg2 = LoadedGraph::load(&p2).unwrap();
    let plan2 = Plan::new(&lg2, &BTreeMap::new(), d.path()).unwrap();
    assert_eq!(ev.eval(&plan2, &[], &opts).unwrap().misses(), 0);
}

/// A parameter file that is not an image — `integrate`'s K file — is keyed by its bytes too:
/// a new focal length re-integrates, the same K again hits.
#[test]
fn a_k_file_is_keyed_by_its_bytes() {
    let d = tempfile::tempdir().unwrap();
    let k = d.path().join("k.txt");
    std::fs::write(&k, "100 0 23.5\n0 100 23.5\n0 0 1\n").unwrap();
    let text = format!(
        r#"(
    version: 1,
    next_id: 3,
    outputs: {{ "height": (node: 2, port: "height") }},
    nodes: [
        (id: 1, op: "surface", params: {{ "shape": Choice("sphere"), "width": Int(48), "height": Int(48) }}),
        (id: 2, op: "integrate", params: {{ "method": Choice("masked_poisson"), "camera": Choice("k_file"), "k_file": Path({:?}) }}, inputs: {{ "image": Node(1, "image") }}),
    ],
)"#,
        k.display().to_string()
    );
    let (ev, plan, a) = misses_then_hits(d.path(), "k.ron", &text);
    let opts = EvalOptions::default();
    // A longer focal length (different bytes and size): integrate runs again and its height
    // changes (the perspective correction differs); the surface is reused.
    std::fs::write(&k, "1000 0 23.5\n0 1000 23.5\n0 0 1\n").unwrap();
    let b = ev.eval(&plan, &[], &opts).unwrap();
    assert_eq!(b.missed_nodes(), vec![2]);
    assert_ne!(a.outputs, b.outputs);
}

#[test]
fn disk_cache_survives_a_new_evaluator_and_ignores_corrupt_entries() {
    let d = tempfile::tempdir().unwrap();
    let lg = chain();
    let first = run(
        &Evaluator::default().with_disk_cache(d.path()).unwrap(),
        &lg,
        &[],
    );
    let fresh = Evaluator::default().with_disk_cache(d.path()).unwrap();
    let r = run(&fresh, &lg, &[]);
    assert_eq!(r.misses(), 0);
    assert!(r.stats.iter().all(|s| s.status == Status::DiskHit));
    assert_eq!(r.outputs, first.outputs);
    // Edit downstream: upstream results come from disk.
    let edited = edit(&lg, |n| {
        n.get_mut(&3)
            .unwrap()
            .params
            .insert("amount".into(), ParamValue::Float(3.0));
    });
    let r = run(
        &Evaluator::default().with_disk_cache(d.path()).unwrap(),
        &edited,
        &["relit"],
    );
    assert_eq!(r.missed_nodes(), vec![3, 4]);
    assert_eq!(
        r.stats
            .iter()
            .filter(|s| s.status == Status::DiskHit)
            .count(),
        1
    );
    // Corrupt every entry: all recomputed, same results, no panic.
    for e in std::fs::read_dir(d.path()).unwrap().flatten() {
        let mut b = std::fs::read(e.path()).unwrap();
        let n = b.len();
        b.truncate(n / 2);
        std::fs::write(e.path(), b).unwrap();
    }
    let r = run(
        &Evaluator::default().with_disk_cache(d.path()).unwrap(),
        &lg,
        &[],
    );
    assert_eq!(r.misses(), 6);
    assert_eq!(r.outputs, first.outputs);
}

#[test]
fn memory_budget_evicts() {
    let lg = chain();
    let ev = Evaluator::new(0);
    run(&ev, &lg, &[]);
    assert_eq!(ev.mem_usage(), (0, 0));
    assert_eq!(run(&ev, &lg, &[]).misses(), 6);
}

#[test]
fn progress_is_reported_and_cancellation_stops() {
    let lg = chain();
    let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).unwrap();
    let count = Arc::new(AtomicUsize::new(0));
    let c2 = count.clone();
    let totals = Arc::new(AtomicUsize::new(0));
    let t2 = totals.clone();
    let opts = EvalOptions {
        progress: Some(Arc::new(move |p| {
            c2.fetch_add(1, Ordering::SeqCst);
            t2.store(p.total, Ordering::SeqCst);
            assert!(p.done <= p.total);
        })),
        ..EvalOptions::default()
    };
    let ev = Evaluator::default();
    ev.eval(&plan, &[], &opts).unwrap();
    assert_eq!(count.load(Ordering::SeqCst), 6);
    assert_eq!(totals.load(Ordering::SeqCst), 6);

    let cancel = Arc::new(AtomicBool::new(true));
    let opts = EvalOptions {
        cancel: rgbn::cancel::Cancel::from_flag(cancel),
        ..EvalOptions::default()
    };
    let e = Evaluator::default().eval(&plan, &[], &opts).unwrap_err();
    assert!(matches!(e, rgbn::graph::GraphError::Cancelled), "{e}");
    assert_eq!(rgbn::cli::CliError::from(e).exit(), rgbn::cli::Exit::Failed);
}

#[test]
fn curl_stats_are_measured_per_node() {
    let lg = chain();
    let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).unwrap();
    let opts = EvalOptions {
        curl_stats: true,
        ..EvalOptions::default()
    };
    let r = Evaluator::default().eval(&plan, &["curl"], &opts).unwrap();
    let by_node: BTreeMap<u64, Option<f64>> = r
        .stats
        .iter()
        .map(|s| (s.at.node.unwrap(), s.curl))
        .collect();
    // Exact normals of a height: curl at rounding level; the curl node's own output too.
    let c1 = by_node[&1].unwrap();
    let c2 = by_node[&2].unwrap();
    let rgbn::nodes::Value::Number(out) = r.outputs["curl"] else {
        panic!()
    };
    assert!((c2 - out).abs() < 1e-12, "{c2} vs {out}");
    assert!(c1 < 0.05 && c2 < 0.05, "{c1} {c2}");
    assert_eq!(by_node[&5], None);
    // The non-integrable fraction F beside it: the surface node is exactly a surface (heights
    // at pixel corners), linear filters keep it one; F of a node is that of its output.
    let f: BTreeMap<u64, Option<f64>> = r
        .stats
        .iter()
        .map(|s| (s.at.node.unwrap(), s.fraction))
        .collect();
    let (f1, f2) = (f[&1].unwrap(), f[&2].unwrap());
    assert!(f1 < 1e-4 && f2 < 1e-3, "{f1} {f2}");
    assert_eq!(f[&5], None);
    let (src, _) = rgbn::raster::sample::Surface::gaussians_for(64).render_sampled(64, 64);
    let want = rgbn::raster::integrate::non_integrable_fraction(
        &rgbn::raster::gradient::GradientField::from_normals(&src),
        None,
    )
    .unwrap();
    // The readout sums in parallel, in a fixed order: the same bits as the direct call.
    assert_eq!(f1.to_bits(), want.to_bits(), "{f1} vs {want}");
    // Noise reads √(2/π) ≈ 0.80 on the same scale (the number is scale-free).
    let mut noisy = src.clone();
    let mut seed = 1u32;
    let [nx, ny, nz] = noisy.normal_mut();
    for i in 0..64 * 64 {
        let mut rnd = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            f32::from((seed >> 16) as u16) / 65535.0 - 0.5
        };
        let (a, b) = (rnd(), rnd());
        let n = (a * a + b * b + 1.0).sqrt();
        (nx[i], ny[i], nz[i]) = (a / n, b / n, 1.0 / n);
    }
    let fn_ = rgbn::raster::integrate::non_integrable_fraction(
        &rgbn::raster::gradient::GradientField::from_normals(&noisy),
        None,
    )
    .unwrap();
    assert!((fn_ - 0.8).abs() < 0.05, "{fn_}");
}

/// A lazy operator's outputs that nothing reads are left out, and never handed on: asked for
/// later (memory or disk cache behind), the node runs again and they equal the direct split.
/// The bilateral computes its base alone when only the base is read.
#[test]
fn outputs_not_read_are_left_out_and_computed_when_asked_for() {
    use rgbn::nodes::Value;
    let lg = LoadedGraph::load(&graph_path("bilateral_split.ron")).unwrap();
    let (base, detail, rep) = bilateral_split_example();
    let image = |r: &EvalResult, name: &str| match &r.outputs[name] {
        Value::Rgbn(i) => i.clone(),
        other => panic!("{name}: {:?}", other.port_type()),
    };
    let d = tempfile::tempdir().unwrap();
    let ev = Evaluator::default().with_disk_cache(d.path()).unwrap();
    let r = run(&ev, &lg, &["base"]);
    assert_eq!(r.missed_nodes(), vec![1, 2]);
    assert_eq!(image(&r, "base"), base);
    // Asked for again, the base is a hit.
    assert_eq!(run(&ev, &lg, &["base"]).misses(), 0);
    // The detail was left out: the bilateral runs again (its input is a hit).
    let r = run(&ev, &lg, &["detail"]);
    assert_eq!(r.missed_nodes(), vec![2]);
    assert_eq!(image(&r, "detail"), detail);
    // So was the readout in both runs.
    let r = run(&ev, &lg, &["relative_rms_curl"]);
    assert_eq!(r.missed_nodes(), vec![2]);
    match r.outputs["relative_rms_curl"] {
        Value::Number(c) => assert_eq!(c, rep.curl_after.relative),
        ref other => panic!("{:?}", other.port_type()),
    }
    // The disk kept no partial entry: a fresh evaluator on it recomputes the bilateral for
    // its detail rather than reading a placeholder.
    let fresh = Evaluator::default().with_disk_cache(d.path()).unwrap();
    let r = run(&fresh, &lg, &["detail"]);
    assert_eq!(r.missed_nodes(), vec![2]);
    assert_eq!(image(&r, "detail"), detail);
    // Every output at once makes a complete entry: then nothing runs, whatever is asked.
    let r = run(&ev, &lg, &[]);
    assert_eq!(r.missed_nodes(), vec![2]);
    assert_eq!(
        (image(&r, "base"), image(&r, "detail")),
        (base.clone(), detail.clone())
    );
    for name in ["detail", "base", "relative_rms_curl"] {
        assert_eq!(run(&ev, &lg, &[name]).misses(), 0, "{name}");
    }
}
