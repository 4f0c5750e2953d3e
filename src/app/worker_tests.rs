//! Tests of `app/worker.rs`.

use super::*;
use crate::app::state::Document;
use crate::params::ParamValue;
use std::path::Path;

fn request(g: &Graph, generation: u64) -> EvalRequest {
    EvalRequest {
        generation,
        graph: g.clone(),
        base_dir: PathBuf::from("."),
        cancel: Arc::new(AtomicBool::new(false)),
        view: None,
        settings: None,
        keep: None,
    }
}

fn small_demo() -> Document {
    let mut d = Document::demo();
    d.set_param(1, "size", ParamValue::Int(64));
    d
}

#[test]
fn generations_drop_stale_results() {
    let mut g = Generations::default();
    assert!(!g.in_flight());
    let a = g.new_request();
    let b = g.new_request();
    assert!(g.in_flight());
    assert!(!g.accept(a), "an older result is stale");
    assert!(g.in_flight());
    assert!(g.accept(b));
    assert!(!g.in_flight());
    assert_eq!(g.latest(), b);
}

#[test]
fn evaluates_every_node_and_reports_errors_on_their_nodes() {
    let mut d = small_demo();
    let lonely = d.add_node("normalize", [0.0, 0.0]); // required input missing
    let below = d.add_node("curl", [0.0, 0.0]);
    d.connect(lonely, "image", below, "image").unwrap();
    let broken = d.add_node("load", [0.0, 0.0]);
    d.set_param(broken, "path", ParamValue::Path("no-such-file.png".into()));
    let ev = Evaluator::default();
    let req = request(&d.graph, 7);
    let (out, plan) = evaluate_with_plan(&ev, &req, None);
    assert_eq!(out.generation, 7);
    assert!(out.error.is_none(), "{:?}", out.error);
    // A node whose required input is not connected waits for it: not a failure.
    assert_eq!(out.waiting.get(&lonely).map(String::as_str), Some("image"));
    assert!(
        !out.node_errors.contains_key(&lonely),
        "{:?}",
        out.node_errors
    );
    // A node that cannot run fails, with its error.
    let e = &out.node_errors[&broken];
    assert!(e.contains("no-such-file.png"), "{e}");
    assert!(!out.waiting.contains_key(&broken));
    assert!(!out.values.contains_key(&(below, "relative_rms".into())));
    for id in 1..=6 {
        assert!(
            out.values.keys().any(|(n, _)| *n == id),
            "node {id} has a value"
        );
    }
    assert!(out.thumbs.contains_key(&3));
    let t = &out.thumbs[&3];
    assert!(t.width <= THUMB_SIZE && t.height <= THUMB_SIZE);
    // The readouts come after the values, for the same generation.
    let r = readouts(&ev, &req, &plan.expect("a plan")).expect("readouts");
    assert_eq!(r.generation, 7);
    assert!(r.curl.contains_key(&3) && r.fraction.contains_key(&3));
    // Same graph again: all from the cache, same keys.
    let again = evaluate(&ev, &request(&d.graph, 8), None);
    assert_eq!(again.computed, 0);
    assert_eq!(
        again.values[&(3, "image".into())].key,
        out.values[&(3, "image".into())].key
    );
}

#[test]
fn cancelled_request_reports_cancelled() {
    let d = small_demo();
    let req = request(&d.graph, 1);
    req.cancel.store(true, Ordering::Relaxed);
    let out = evaluate(&Evaluator::default(), &req, None);
    assert!(out.cancelled);
}

#[test]
fn save_nodes_are_not_run_automatically() {
    let mut d = small_demo();
    let s = d.add_node("save", [0.0, 0.0]);
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("x.exr");
    d.set_param(s, "path", ParamValue::Path(target.display().to_string()));
    d.connect(3, "image", s, "image").unwrap();
    let out = evaluate(&Evaluator::default(), &request(&d.graph, 1), None);
    assert!(!target.exists());
    assert!(!out.values.keys().any(|(n, _)| *n == s));
}

#[test]
fn worker_thread_answers_the_newest_request() {
    let d = small_demo();
    let w = Worker::spawn(Arc::new(|| {}));
    let mut gens = Generations::default();
    let a = gens.new_request();
    w.send(request(&d.graph, a));
    let b = gens.new_request();
    w.send(request(&d.graph, b));
    let mut got_current = false;
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline && !got_current {
        if let Some(WorkerMsg::Done(o)) = w.wait(Duration::from_millis(100)) {
            got_current = gens.accept(o.generation);
            if got_current {
                assert!(!o.values.is_empty());
            }
        }
    }
    assert!(got_current);
}

#[test]
fn the_viewport_comes_first_and_equals_that_part_of_the_whole_output() {
    let mut d = small_demo();
    d.set_param(1, "size", ParamValue::Int(200));
    let w = Worker::spawn(Arc::new(|| {}));
    let mut req = request(&d.graph, 1);
    // 1:1, the image centre moved 60 points left and 40 up in a 100×80 panel: image
    // pixels 110..210 (clamped to 200) × 100..180 are on screen.
    let spec = ViewSpec {
        panel: [100.0, 80.0],
        zoom: Some(1.0),
        pan: [-60.0, -40.0],
    };
    req.view = Some(ViewRequest {
        node: 3,
        port: "image".into(),
        spec,
    });
    w.send(req);
    let mut region = None;
    let deadline = Instant::now() + Duration::from_secs(60);
    let done = loop {
        assert!(Instant::now() < deadline, "no result");
        match w.wait(Duration::from_millis(100)) {
            Some(WorkerMsg::Region(r)) => {
                assert!(region.is_none(), "one viewport per request");
                region = Some(r);
            }
            Some(WorkerMsg::Done(o)) => break o,
            _ => {}
        }
    };
    let r = region.expect("the viewport arrives before the whole evaluation");
    assert_eq!((r.node, r.level, r.full_size), (3, 0, (200, 200)));
    // Columns 110..200 and rows 100..180, grown to 64-pixel tiles: 64..200 × 64..192.
    assert_eq!(r.rect, Rect::new(64, 64, 136, 128));
    assert_eq!(
        Some((r.rect, 0)),
        spec.visible((200, 200), INTERACTIVE_TILE)
    );
    let whole = &done.values[&(3, "image".to_string())];
    assert_eq!(
        r.key, whole.key,
        "the viewport is of the value evaluated whole"
    );
    let (Value::Rgbn(part), Value::Rgbn(all)) = (&r.value, &whole.value) else {
        panic!("RGBN values");
    };
    assert_eq!((part.width(), part.height()), (136, 128));
    let mut worst = 0f32;
    for y in 0..128 {
        for x in 0..136 {
            let (a, b) = (part.normal_at(x, y), all.normal_at(64 + x, 64 + y));
            let (c, e) = (part.color_at(x, y), all.color_at(64 + x, 64 + y));
            for k in 0..3 {
                worst = worst.max((a[k] - b[k]).abs()).max((c[k] - e[k]).abs());
            }
        }
    }
    // The demo's edge filter is a recursive Gaussian (σ 6) cut at 4σ in tiles: its tail's
    // mass (< 3.5e-4 per pass, `raster::convolve::gaussian_support`) bounds the difference
    // (tests/it/region.rs, 2e-3); everything else is the same arithmetic.
    assert!(
        worst <= 2e-3,
        "viewport differs from the whole output by {worst}"
    );
}

#[test]
fn below_a_global_operator_edits_are_shown_at_a_coarse_level_then_at_the_level_shown() {
    // A 2048 × 1024 surface of three bumps (2 Mpx) projected, viewed at 1:1: while edits
    // come, the viewport is evaluated at level 1 (0.5 Mpx ≤ 1 Mpx), where the projection
    // runs on a quarter of the pixels; once they pause, level 0, then the whole graph.
    let mut g = Graph::default();
    let src = g.add_node("surface", [0.0, 0.0]);
    let proj = g.add_node("project", [200.0, 0.0]);
    let params = &mut g.nodes.get_mut(&src).unwrap().params;
    for (k, v) in [("width", 2048), ("height", 1024)] {
        params.insert(k.into(), ParamValue::Int(v));
    }
    params.insert("shape".into(), ParamValue::Choice("gaussians".into()));
    g.connect(src, "image", proj, "image", Path::new("."))
        .unwrap();
    assert_eq!(interactive_level((2048, 1024)), 1);
    assert_eq!(interactive_level((1024, 1024)), 0);
    let w = Worker::spawn(Arc::new(|| {}));
    let mut req = request(&g, 1);
    let spec = ViewSpec {
        panel: [300.0, 200.0],
        zoom: Some(1.0),
        pan: [0.0, 0.0],
    };
    req.view = Some(ViewRequest {
        node: proj,
        port: "image".into(),
        spec,
    });
    w.send(req);
    let mut regions = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(120);
    let done = loop {
        assert!(Instant::now() < deadline, "no result");
        match w.wait(Duration::from_millis(100)) {
            Some(WorkerMsg::Region(r)) => regions.push(r),
            Some(WorkerMsg::Done(o)) => break o,
            _ => {}
        }
    };
    let shown: Vec<(u32, bool)> = regions.iter().map(|r| (r.level, r.coarse)).collect();
    assert_eq!(shown, [(1, true), (0, false)]);
    // Each is the part of the value at its level: level 0 is the whole value's crop.
    let whole = &done.values[&(proj, "image".to_string())];
    let (Value::Rgbn(part), Value::Rgbn(all)) = (&regions[1].value, &whole.value) else {
        panic!("RGBN values");
    };
    let r = regions[1].rect;
    let mut worst = 0f32;
    for y in 0..r.h {
        for x in 0..r.w {
            let (a, b) = (part.normal_at(x, y), all.normal_at(r.x + x, r.y + y));
            for k in 0..3 {
                worst = worst.max((a[k] - b[k]).abs());
            }
        }
    }
    assert!(
        worst <= 1e-6,
        "level 0 viewport differs from the whole by {worst}"
    );
    // The coarse one approximates the same pixels reduced (normals within 0.02).
    let coarse = &regions[0];
    let reduced = crate::nodes::value::reduce(&whole.value, 2);
    let want = crate::nodes::value::crop(&reduced, coarse.rect);
    let (Value::Rgbn(a), Value::Rgbn(b)) = (&coarse.value, &want) else {
        panic!("RGBN values");
    };
    let worst = (0..3)
        .flat_map(|k| a.normal()[k].iter().zip(&b.normal()[k]))
        .map(|(p, q)| (p - q).abs())
        .fold(0f32, f32::max);
    assert!(
        worst <= 0.02,
        "coarse viewport differs from the reduced whole by {worst}"
    );
}
