//! Many strokes, one pen node (issue 38 item 5): a pen's list of paths against chained
//! single-path pens and the single-stroke pen, its damage per path, and old files with one
//! `points` path.

use crate::region::max_diff;
use rgbn::eval::region::RegionOptions;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use rgbn::ops::pen::{apply_pen, PenParams};
use rgbn::params::{paths_text, ParamValue, PathValue};
use rgbn::raster::window::Rect;
use std::collections::BTreeMap;
use std::path::Path;

const W: usize = 320;
const H: usize = 240;

fn load(text: &str, dir: &Path) -> LoadedGraph {
    LoadedGraph::from_text(text, "pen.ron", dir.to_path_buf()).unwrap()
}

fn eval(lg: &LoadedGraph, dir: &Path, outputs: &[&str]) -> BTreeMap<String, Value> {
    let plan = Plan::new(lg, &BTreeMap::new(), dir).unwrap();
    Evaluator::default()
        .eval(&plan, outputs, &EvalOptions::default())
        .unwrap()
        .outputs
}

/// A surface and pen nodes `pens` (id 2, 3, …, each reading the one before), as a version-2
/// file; outputs `image` (the last pen) and `height_N` (each pen's height).
fn graph(pens: &[&str]) -> String {
    let mut nodes = format!(
        "(id: 1, op: \"surface\", params: {{ \"width\": Int({W}), \"height\": Int({H}), \"shape\": Choice(\"gaussians\") }}),\n"
    );
    let mut outputs = String::new();
    for (k, params) in pens.iter().enumerate() {
        let id = k + 2;
        nodes += &format!(
            "(id: {id}, op: \"pen\", params: {{ {params} }}, inputs: {{ \"image\": Node({}, \"image\") }}),\n",
            id - 1
        );
        outputs += &format!("\"height_{id}\": (node: {id}, port: \"height\"), ");
    }
    let last = pens.len() + 1;
    format!(
        "(version: 2, next_id: {}, outputs: {{ \"image\": (node: {last}, port: \"image\"), {outputs} }}, nodes: [\n{nodes}])",
        last + 1
    )
}

fn paths_param(paths: &[PathValue]) -> String {
    format!(
        "\"paths\": {}",
        ron::to_string(&ParamValue::Paths(paths.to_vec())).unwrap()
    )
}

fn open(points: &[[f64; 2]]) -> PathValue {
    PathValue::new(points.to_vec(), false)
}

fn scalar(v: &Value) -> &[f32] {
    match v {
        Value::Scalar(s) => s.data(),
        other => panic!("not a scalar: {other:?}"),
    }
}

/// The pen is linear in the gradients: one node with two paths (one with its own width and
/// height) gives the image and height of two chained single-path nodes.
#[test]
fn a_pen_with_two_paths_equals_two_chained_single_path_pens() {
    let d = tempfile::tempdir().unwrap();
    let a = open(&[[40.0, 40.0], [150.0, 90.0], [260.0, 60.0]]);
    let mut b = PathValue::new(
        vec![
            [100.0, 120.0],
            [200.0, 110.0],
            [180.0, 200.0],
            [90.0, 190.0],
        ],
        true,
    );
    b.params.insert("width_px".into(), ParamValue::Float(14.0));
    b.params
        .insert("profile".into(), ParamValue::Choice("step".into()));
    let shared = "\"width_px\": Float(10.0), \"height_px\": Float(3.0), \"taper_px\": Float(8.0)";
    let one = load(
        &graph(&[&format!(
            "{}, {shared}",
            paths_param(&[a.clone(), b.clone()])
        )]),
        d.path(),
    );
    // The second path as a node of its own: its own parameters become the node's.
    let b_alone = "\"width_px\": Float(14.0), \"profile\": Choice(\"step\"), \"height_px\": Float(3.0), \"taper_px\": Float(8.0)";
    let chained = load(
        &graph(&[
            &format!("{}, {shared}", paths_param(&[a])),
            &format!(
                "{}, {b_alone}",
                paths_param(&[PathValue::new(b.points.clone(), true)])
            ),
        ]),
        d.path(),
    );
    let x = eval(&one, d.path(), &["image", "height_2"]);
    let y = eval(&chained, d.path(), &["image", "height_2", "height_3"]);
    let diff = max_diff(&x["image"], &y["image"]);
    assert!(diff <= 1e-5, "normals differ by {diff}");
    // And the relief is really there: the pens changed the surface.
    let surface = eval(&load(&graph(&[]), d.path()), d.path(), &["image"]);
    assert!(max_diff(&surface["image"], &x["image"]) > 0.05);
    // The height of the node is the sum of its strokes' heights.
    let (h, h1, h2) = (
        scalar(&x["height_2"]),
        scalar(&y["height_2"]),
        scalar(&y["height_3"]),
    );
    let worst = (0..W * H)
        .map(|i| (h[i] - (h1[i] + h2[i])).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-5, "heights differ by {worst}");
    assert!(h.iter().any(|v| *v > 2.9), "the step raises its inside");
}

/// A version-1 file with a pen's single `points` loads into one path and draws exactly the
/// single-stroke pen ([`apply_pen`]) on the same input.
#[test]
fn an_old_file_with_points_loads_into_one_path_and_draws_the_single_stroke() {
    let d = tempfile::tempdir().unwrap();
    let old = format!(
        r#"(version: 1, next_id: 3, outputs: {{ "image": (node: 2, port: "image"), "input": (node: 1, port: "image") }}, nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int({W}), "height": Int({H}), "shape": Choice("gaussians") }}),
        (id: 2, op: "pen", pos: (0.0, 0.0), params: {{ "points": Points([(30.0, 200.0), (120.0, 40.0), (290.0, 150.0)]), "closed": Bool(true), "profile": Choice("step"), "width_px": Float(12.0) }}, inputs: {{ "image": Node(1, "image") }}),
    ])"#
    );
    let lg = load(&old, d.path());
    let pen = &lg.graph.nodes[&2].params;
    assert_eq!(
        pen.get("paths"),
        Some(&ParamValue::Paths(vec![PathValue::new(
            vec![[30.0, 200.0], [120.0, 40.0], [290.0, 150.0]],
            true
        )]))
    );
    assert!(!pen.contains_key("points") && !pen.contains_key("closed"));
    let out = eval(&lg, d.path(), &["image", "input"]);
    let Value::Rgbn(input) = &out["input"] else {
        panic!()
    };
    let stroke = PenParams {
        points: vec![[30.0, 200.0], [120.0, 40.0], [290.0, 150.0]],
        closed: true,
        width_px: 12.0,
        ..PenParams::default()
    }
    .with_profile(&rgbn::ops::pen::Profile::Step { height_px: 2.0 });
    let (want, _) = apply_pen(input, &stroke).unwrap();
    assert_eq!(max_diff(&Value::Rgbn(want), &out["image"]), 0.0);
}

/// Adding a path to a pen node: its damage covers every pixel the path changes and lies within
/// the path's reach (half its width and a few pixels), the region engine recomputes only the
/// tiles of that footprint, and the result equals a full recompute.
#[test]
fn adding_a_path_recomputes_only_its_footprint_and_equals_a_full_recompute() {
    let d = tempfile::tempdir().unwrap();
    let tile = 32;
    let (ropts, opts) = (RegionOptions::tiles(tile), EvalOptions::default());
    let ev = Evaluator::default();
    let width = 10.0;
    let shared = format!("\"width_px\": Float({width}), \"taper_px\": Float(6.0)");
    let mut paths = vec![open(&[[20.0, 20.0], [60.0, 30.0]])];
    let text = graph(&[&format!("{}, {shared}", paths_param(&paths))]).replacen(
        "(id: 2, op: \"pen\",",
        "(id: 2, op: \"pen\", name: Some(\"pen\"),",
        1,
    );
    let mut lg = load(&text, d.path());
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    let full = Rect::full((W, H));
    ev.eval_region(&plan, "image", full, &ropts, &opts).unwrap();
    let pen = rgbn::nodes::find("pen").unwrap();
    // Strokes here and there, open and closed, one with its own width.
    let strokes: Vec<PathValue> = vec![
        open(&[[250.0, 200.0], [290.0, 215.0], [300.0, 180.0]]),
        PathValue::new(vec![[150.0, 60.0], [200.0, 60.0], [175.0, 100.0]], true),
        {
            let mut p = open(&[[40.0, 150.0], [80.0, 170.0]]);
            p.params.insert("width_px".into(), ParamValue::Float(20.0));
            p
        },
        open(&[[300.0, 20.0], [310.0, 60.0]]),
    ];
    for (step, s) in strokes.into_iter().enumerate() {
        let before = eval(&lg, d.path(), &["height_2"]);
        let old = lg.graph.nodes[&2].params.clone();
        paths.push(s.clone());
        lg.set_param("pen", "paths", &paths_text(&paths)).unwrap();
        let new = lg.graph.nodes[&2].params.clone();
        let (old, new) = (pen.parse(&old).unwrap(), pen.parse(&new).unwrap());
        let damage = pen.damage(&old, &new, &[]).unwrap();
        assert_eq!(damage.len(), 1, "step {step}: one path added, one box");
        let [x0, y0, x1, y1] = damage[0];
        // Within the path's reach of its points.
        let w = match s.params.get("width_px") {
            Some(ParamValue::Float(v)) => *v,
            _ => width,
        };
        let reach = w / 2.0 + 4.0;
        let (px, py): (Vec<f64>, Vec<f64>) = s.points.iter().map(|p| (p[0], p[1])).unzip();
        let lo = |v: &[f64]| v.iter().copied().fold(f64::MAX, f64::min);
        let hi = |v: &[f64]| v.iter().copied().fold(f64::MIN, f64::max);
        assert!(
            x0 >= lo(&px) - reach && y0 >= lo(&py) - reach,
            "step {step}: {damage:?}"
        );
        assert!(
            x1 <= hi(&px) + reach && y1 <= hi(&py) + reach,
            "step {step}: {damage:?}"
        );
        // Every pixel whose height the path changed lies in it.
        let after = eval(&lg, d.path(), &["height_2"]);
        let (a, b) = (scalar(&before["height_2"]), scalar(&after["height_2"]));
        let mut changed = 0;
        for r in 0..H {
            for c in 0..W {
                if a[r * W + c] != b[r * W + c] {
                    changed += 1;
                    let (x, y) = (c as f64, r as f64);
                    assert!(
                        x >= x0 && x <= x1 && y >= y0 && y <= y1,
                        "step {step}: pixel ({c}, {r}) changed outside {damage:?}"
                    );
                }
            }
        }
        assert!(changed > 0, "step {step}: the path drew nothing");
        // The engine recomputes the tiles of that box (and its one-pixel halo) only, and its
        // patched result equals a full recompute.
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let r = ev.eval_region(&plan, "image", full, &ropts, &opts).unwrap();
        let want = Evaluator::default().eval(&plan, &["image"], &opts).unwrap();
        assert!(
            max_diff(&want.outputs["image"], &r.value) <= 2e-6,
            "step {step}"
        );
        let t = |v: f64, n: usize| ((v.max(0.0) as usize).min(n - 1)) / tile;
        let tiles = |m: f64| (t(x1 + m, W) - t(x0 - m, W) + 1) * (t(y1 + m, H) - t(y0 - m, H) + 1);
        let at_pen = r.tiles.iter().find(|t| t.op == "pen").unwrap();
        assert!(
            at_pen.computed >= 1
                && at_pen.computed + at_pen.reused <= tiles(2.0)
                && at_pen.computed <= (W / tile + 1) * (H / tile + 1) / 4,
            "step {step}: pen recomputed {} tiles (reused {}), the path's box touches {}",
            at_pen.computed,
            at_pen.reused,
            tiles(2.0)
        );
    }
}
