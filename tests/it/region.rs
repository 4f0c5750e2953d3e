//! Region evaluation (`rgbn::eval::region`): an output computed over a rectangle, tile by tile,
//! equals the same rectangle of the whole-image result.

use crate::common::*;
use rgbn::eval::region::RegionOptions;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::value::crop;
use rgbn::nodes::{PortType, Value};
use rgbn::params::ParamValue;
use rgbn::raster::window::Rect;
use std::collections::BTreeMap;

/// Largest absolute difference over every channel (pictures in units of 1/255).
pub fn max_diff(a: &Value, b: &Value) -> f64 {
    fn planes(a: &[f32], b: &[f32]) -> f64 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| f64::from((x - y).abs()))
            .fold(0.0, f64::max)
    }
    match (a, b) {
        (Value::Rgbn(x), Value::Rgbn(y)) => {
            assert_eq!((x.width(), x.height()), (y.width(), y.height()));
            assert_eq!(x.mask().is_some(), y.mask().is_some());
            let mut d = 0.0f64;
            for (p, q) in x.color().iter().zip(y.color()) {
                d = d.max(planes(p, q));
            }
            for (p, q) in x.normal().iter().zip(y.normal()) {
                d = d.max(planes(p, q));
            }
            if let (Some(p), Some(q)) = (x.mask(), y.mask()) {
                d = d.max(planes(p, q));
            }
            d
        }
        (Value::Mask(x), Value::Mask(y)) | (Value::Scalar(x), Value::Scalar(y)) => {
            assert_eq!((x.width(), x.height()), (y.width(), y.height()));
            planes(x.data(), y.data())
        }
        (Value::Picture(x), Value::Picture(y)) => {
            assert_eq!((x.width, x.height), (y.width, y.height));
            x.rgba
                .iter()
                .zip(&y.rgba)
                .map(|(p, q)| f64::from(p.abs_diff(*q)) / 255.0)
                .fold(0.0, f64::max)
        }
        _ => panic!("different kinds: {a:?} / {b:?}"),
    }
}

/// Small deterministic generator (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn every_graph_output_over_a_region_equals_the_whole_results_crop() {
    let out_dir = tempfile::tempdir().unwrap();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut tiled = 0;
    for path in top_graphs() {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let lg = LoadedGraph::load(&path).unwrap();
        let plan = Plan::new(&lg, &example_bindings(&lg), out_dir.path()).unwrap();
        let whole = Evaluator::default()
            .eval(&plan, &[], &EvalOptions::default())
            .unwrap_or_else(|e| panic!("{stem}: {e}"));
        // A recursive Gaussian (σ ≥ 3) is cut at 4σ: per pass its tail's mass (< 3.5e-4, see
        // `raster::convolve::gaussian_support`) times twice the largest gradient bounds the
        // change (2e-3 over two passes for gradients up to 1.4; unit normals change less).
        // Elsewhere only the order of float operations may differ. Pictures: one 8-bit level.
        let recursive = plan.instances.iter().any(|i| {
            i.params.values().iter().any(|(k, v)| {
                ["sigma_px", "sigma_fine_px", "sigma_coarse_px"].contains(&k.as_str())
                    && matches!(v, ParamValue::Float(s) if *s >= 3.0)
            })
        });
        for (name, ty) in &plan.output_types {
            if *ty == PortType::Number {
                continue;
            }
            let full = &whole.outputs[name];
            let (w, h) = match full {
                Value::Rgbn(i) => (i.width(), i.height()),
                Value::Mask(p) | Value::Scalar(p) => (p.width(), p.height()),
                Value::Picture(p) => (p.width, p.height),
                Value::Number(_) => unreachable!(),
            };
            for tile in [16, 40, 256] {
                let x = rng.below(w);
                let y = rng.below(h);
                let rect = Rect::new(x, y, 1 + rng.below(w - x), 1 + rng.below(h - y));
                let ev = Evaluator::default();
                let r = ev
                    .eval_region(
                        &plan,
                        name,
                        rect,
                        &RegionOptions::tiles(tile),
                        &EvalOptions::default(),
                    )
                    .unwrap_or_else(|e| panic!("{stem}.{name}: {e}"));
                assert_eq!(r.rect, rect);
                tiled += r.tiles.len();
                let d = max_diff(&crop(full, rect), &r.value);
                eprintln!(
                    "{stem}.{name} tile {tile} rect {rect}: {} tiled nodes, {} tiles, max diff {d:.2e}",
                    r.tiles.len(),
                    r.tiles_computed()
                );
                let tol = match (ty, recursive) {
                    (PortType::Picture, _) => 1.0 / 255.0,
                    (_, true) => 2e-3,
                    (_, false) => 2e-6,
                };
                assert!(
                    d <= tol,
                    "{stem}.{name} tile {tile} rect {rect}: {d} > {tol}"
                );
            }
        }
    }
    assert!(tiled > 40, "only {tiled} tiled node evaluations");
}

#[test]
fn cli_eval_region_writes_the_rectangle_of_the_whole_output() {
    let d = tempfile::tempdir().unwrap();
    let graph = graph_path("filter_gaussian.ron");
    let part = d.path().join("part.exr");
    let o = rgbn(&[
        "eval",
        graph.to_str().unwrap(),
        "--region",
        "10,20,30,40",
        "--tile",
        "16",
        "--stats",
        "-o",
        &format!("image={}", part.display()),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("at 10,20,30,40"), "{}", stdout(&o));
    let got = rgbn::raster::io::load_exr(&part, &Default::default()).unwrap();
    let lg = LoadedGraph::load(&graph).unwrap();
    let whole = eval_all(&Evaluator::default(), &lg, d.path());
    let want = crop(&whole.outputs["image"], Rect::new(10, 20, 30, 40));
    // EXR at full precision: the file holds the rectangle's values (σ < 3: exact FIR).
    let d = max_diff(&want, &Value::Rgbn(got));
    assert!(d <= 2e-6, "{d}");
    // A number output has no region; a rectangle outside the image is refused.
    for (region, msg) in [("0,0,8,8", "no region"), ("500,0,8,8", "outside")] {
        let o = rgbn(&[
            "eval",
            graph.to_str().unwrap(),
            "--region",
            region,
            "-o",
            &format!(
                "{}={}",
                if msg == "no region" { "curl" } else { "image" },
                d_path(&part)
            ),
        ]);
        assert_eq!(o.status.code(), Some(2), "{region}");
        assert!(stderr(&o).contains(msg), "{region}: {}", stderr(&o));
    }
}

fn d_path(p: &std::path::Path) -> String {
    p.with_file_name("other.exr").display().to_string()
}

fn points_text(p: &[[f64; 2]]) -> String {
    p.iter()
        .map(|q| format!("{}:{}", q[0], q[1]))
        .collect::<Vec<_>>()
        .join(",")
}

/// The tiles of side `tile` that a box `[x0, y0, x1, y1]` touches in a `size` image.
fn tiles_touching(b: [f64; 4], tile: usize, size: (usize, usize)) -> usize {
    let c = |v: f64, n: usize| (v.max(0.0) as usize).min(n - 1) / tile;
    let (x0, x1) = (c(b[0].floor(), size.0), c(b[2].ceil(), size.0));
    let (y0, y1) = (c(b[1].floor(), size.1), c(b[3].ceil(), size.1));
    (x1 - x0 + 1) * (y1 - y0 + 1)
}

#[test]
fn after_random_pen_stamp_and_brush_edits_the_incremental_result_equals_a_full_recompute() {
    let d = tempfile::tempdir().unwrap();
    let (w, h) = (320usize, 240usize);
    let text = format!(
        r#"(
    version: 1,
    next_id: 7,
    outputs: {{ "image": (node: 5, port: "image"), "relit": (node: 6, port: "picture"), "pen": (node: 3, port: "image") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int({w}), "height": Int({h}), "shape": Choice("gaussians") }}),
        (id: 2, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(20), "height": Int(16), "shape": Choice("gaussians") }}),
        (id: 3, op: "pen", name: Some("pen"), pos: (0.0, 0.0), params: {{ "points": Points([(40.0, 40.0), (60.0, 50.0)]), "width_px": Float(10.0), "taper_px": Float(8.0) }}, inputs: {{ "image": Node(1, "image") }}),
        (id: 4, op: "stamp", name: Some("stamp"), pos: (0.0, 0.0), params: {{ "positions": Points([(200.0, 60.0), (100.0, 180.0)]), "angle_rad": Float(0.3) }}, inputs: {{ "image": Node(3, "image"), "stamp": Node(2, "image") }}),
        (id: 5, op: "brush", name: Some("brush"), pos: (0.0, 0.0), params: {{ "points": Points([(250.0, 200.0)]), "radius_px": Float(6.0), "feather_px": Float(3.0), "sigma_px": Float(2.0) }}, inputs: {{ "image": Node(4, "image") }}),
        (id: 6, op: "relight", pos: (0.0, 0.0), inputs: {{ "image": Node(5, "image") }}),
    ],
)"#
    );
    let mut lg = LoadedGraph::from_text(&text, "edits.ron", d.path().to_path_buf()).unwrap();
    let ev = Evaluator::default();
    let tile = 32;
    let ropts = RegionOptions::tiles(tile);
    let opts = EvalOptions::default();
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut pen = vec![[40.0, 40.0], [60.0, 50.0]];
    let mut stamps = vec![[200.0, 60.0], [100.0, 180.0]];
    let mut brush = vec![[250.0, 200.0]];
    let full = Rect::full((w, h));
    let mut appended = 0;
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    for name in ["image", "relit"] {
        ev.eval_region(&plan, name, full, &ropts, &opts).unwrap();
    }
    for step in 0..30 {
        let what = rng.below(5);
        match what {
            0 | 1 => {
                // Append a short pen segment, inside the image.
                let last = *pen.last().unwrap();
                let a = rng.below(628) as f64 / 100.0;
                let p = [
                    (last[0] + 10.0 * a.cos()).clamp(5.0, w as f64 - 5.0),
                    (last[1] + 10.0 * a.sin()).clamp(5.0, h as f64 - 5.0),
                ];
                pen.push(p);
                lg.set_param("pen", "paths", &points_text(&pen)).unwrap();
            }
            2 => {
                let k = rng.below(stamps.len());
                stamps[k] = [
                    20.0 + rng.below(w - 40) as f64,
                    20.0 + rng.below(h - 40) as f64,
                ];
                lg.set_param("stamp", "positions", &points_text(&stamps))
                    .unwrap();
            }
            3 => {
                brush.push([rng.below(w) as f64, rng.below(h) as f64]);
                lg.set_param("brush", "points", &points_text(&brush))
                    .unwrap();
            }
            _ => {
                let width = 6 + rng.below(10);
                lg.set_param("pen", "width_px", &width.to_string()).unwrap();
            }
        }
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        // Alternate the whole image and a viewport (tiles outside it are not kept fresh), and
        // the outputs; the same request often twice in a row (the last result is patched).
        let rect = if step % 5 >= 3 {
            Rect::new(60, 30, 200, 150)
        } else {
            full
        };
        let name = if (step / 2) % 2 == 0 {
            "image"
        } else {
            "relit"
        };
        let r = ev
            .eval_region(&plan, name, rect, &ropts, &opts)
            .unwrap_or_else(|e| panic!("step {step}: {e}"));
        let want = Evaluator::default().eval(&plan, &[name], &opts).unwrap();
        let diff = max_diff(&crop(&want.outputs[name], rect), &r.value);
        let tol = if name == "relit" { 1.0 / 255.0 } else { 2e-6 };
        assert!(diff <= tol, "step {step} ({what}): {diff}");
    }
    // Then appends with the pen's own output asked for whole each time: each recomputes only
    // the tiles its change touches.
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    ev.eval_region(&plan, "pen", full, &ropts, &opts).unwrap();
    for step in 0..8 {
        let last = *pen.last().unwrap();
        let a = rng.below(628) as f64 / 100.0;
        pen.push([
            (last[0] + 10.0 * a.cos()).clamp(5.0, w as f64 - 5.0),
            (last[1] + 10.0 * a.sin()).clamp(5.0, h as f64 - 5.0),
        ]);
        lg.set_param("pen", "paths", &points_text(&pen)).unwrap();
        // Independent expectation: the end taper (8 px) reaches back at most one 10 px
        // segment, the relief half the width (at most 8 px) plus differencing.
        let back = &pen[pen.len() - 3..];
        let (mut b0, mut b1) = ([f64::MAX; 2], [f64::MIN; 2]);
        for q in back {
            b0 = [b0[0].min(q[0]), b0[1].min(q[1])];
            b1 = [b1[0].max(q[0]), b1[1].max(q[1])];
        }
        let bound = tiles_touching(
            [b0[0] - 12.0, b0[1] - 12.0, b1[0] + 12.0, b1[1] + 12.0],
            tile,
            (w, h),
        );
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let r = ev.eval_region(&plan, "pen", full, &ropts, &opts).unwrap();
        let want = Evaluator::default().eval(&plan, &["pen"], &opts).unwrap();
        assert!(
            max_diff(&want.outputs["pen"], &r.value) <= 2e-6,
            "append {step}"
        );
        let at_pen = r.tiles.iter().find(|t| t.op == "pen").unwrap();
        // Only the tiles the change touches are even asked for: the last result is patched.
        assert!(
            at_pen.computed >= 1 && at_pen.computed + at_pen.reused <= bound,
            "append {step}: pen recomputed {} tiles (reused {}), its change touches {bound}",
            at_pen.computed,
            at_pen.reused
        );
        appended += 1;
    }
    assert_eq!(appended, 8);
}

#[test]
fn inputs_of_different_sizes_are_an_error_naming_the_node_not_a_panic() {
    let d = tempfile::tempdir().unwrap();
    let mask = root().join("graphs/data/mask.png");
    let text = format!(
        r#"(
    version: 1,
    next_id: 4,
    outputs: {{ "image": (node: 3, port: "image") }},
    nodes: [
        (id: 1, op: "demo", pos: (0.0, 0.0), params: {{ "size": Int(100) }}),
        (id: 2, op: "load_mask", pos: (0.0, 0.0), params: {{ "path": Path("{}") }}),
        (id: 3, op: "apply_mask", name: Some("masked"), pos: (0.0, 0.0), inputs: {{ "image": Node(1, "image"), "mask": Node(2, "mask") }}),
    ],
)"#,
        mask.display()
    );
    let lg = LoadedGraph::from_text(&text, "sizes.ron", d.path().to_path_buf()).unwrap();
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    let e = Evaluator::default()
        .eval_region(
            &plan,
            "image",
            Rect::new(0, 0, 40, 40),
            &RegionOptions::tiles(16),
            &EvalOptions::default(),
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("masked") && e.contains("same size"), "{e}");
}

/// Procedural sources compute any window on their own (so the region evaluator tiles them
/// and a 16K source costs what the viewport costs): every window equals the whole image's
/// crop bit for bit, masks included (a sphere that leaves corners uncovered carries its mask in
/// every window, even one wholly on the sphere); a coarse level sampled directly agrees with the
/// full image reduced by block means.
#[test]
fn procedural_sources_compute_any_window_exactly_and_coarse_levels_match_block_means() {
    use rgbn::nodes::value::reduce;
    use rgbn::nodes::{find, RunContext};
    use rgbn::raster::window::Window;
    let ctx = RunContext::default();
    let (w, h) = (203usize, 150usize);
    let surface = |shape: &str, analytic: bool| {
        let mut v = BTreeMap::new();
        v.insert("width".to_string(), ParamValue::Int(w as i64));
        v.insert("height".to_string(), ParamValue::Int(h as i64));
        v.insert("shape".to_string(), ParamValue::Choice(shape.to_string()));
        v.insert("radius_px".to_string(), ParamValue::Float(90.0));
        v.insert("period_px".to_string(), ParamValue::Float(64.0));
        v.insert("analytic_normals".to_string(), ParamValue::Bool(analytic));
        ("surface", v)
    };
    let mut demo = BTreeMap::new();
    demo.insert("size".to_string(), ParamValue::Int(w as i64));
    let mut cases = vec![("demo", demo)];
    for shape in ["sphere", "paraboloid", "sinusoid", "gaussians"] {
        cases.push(surface(shape, false));
        cases.push(surface(shape, true));
    }
    let mut rng = Rng(0x51ed_2701_9c3b_44a1);
    for (id, values) in &cases {
        let op = find(id).unwrap();
        let params = op.parse(values).unwrap();
        let whole = op.run(&params, vec![], &ctx).unwrap();
        let Value::Rgbn(img) = &whole[0] else {
            panic!("{id}: not an image")
        };
        let size = (img.width(), img.height());
        let sphere = params.values().get("shape") == Some(&ParamValue::Choice("sphere".into()));
        assert_eq!(img.mask().is_some(), sphere, "{id} {params:?}");
        let mut windows = vec![Rect::new(size.0 / 2 - 5, size.1 / 2 - 5, 10, 10)];
        for _ in 0..6 {
            let (x, y) = (rng.below(size.0), rng.below(size.1));
            windows.push(Rect::new(
                x,
                y,
                1 + rng.below(size.0 - x),
                1 + rng.below(size.1 - y),
            ));
        }
        for r in windows {
            let win = Window {
                x: r.x,
                y: r.y,
                w: r.w,
                h: r.h,
                scale: 1,
            };
            let part = op.run_region(&params, vec![], win, &ctx).unwrap();
            assert_eq!(part.len(), whole.len());
            for (a, b) in whole.iter().zip(&part) {
                let d = max_diff(&crop(a, r), b);
                assert!(d == 0.0, "{id} {params:?} window {r}: differs by {d}");
            }
        }
        // Level 2 (scale 4): the coarse grid sampled directly against the block means. Both
        // are the surface at that scale; they differ by the curvature over a block (second
        // order), which for these smooth surfaces (features ≥ 10 px) stays below 0.05 in the
        // unit normal. Heights are in the coarse grid's pixels: a quarter of the fine ones.
        let s = 4;
        let (cw, ch) = (size.0.div_ceil(s), size.1.div_ceil(s));
        let win = Window {
            x: 0,
            y: 0,
            w: cw,
            h: ch,
            scale: s,
        };
        let coarse = op.run_region(&params, vec![], win, &ctx).unwrap();
        let (Value::Rgbn(a), Value::Rgbn(b)) = (&coarse[0], &reduce(&whole[0], s)) else {
            panic!()
        };
        if let (Some(ma), Some(mb)) = (a.mask(), b.mask()) {
            // The sphere's mask on the coarse grid (pixels whose corners all lie on it)
            // against the block means' coverage ≥ ½: they differ only along the rim, a ring
            // of about 2πr/4 coarse pixels.
            let inside = |m: &[f32]| m.iter().filter(|&&v| v >= 0.5).count();
            let differ = ma
                .iter()
                .zip(mb)
                .filter(|(x, y)| (**x >= 0.5) != (**y >= 0.5));
            let (ia, ib, differ) = (inside(ma), inside(mb), differ.count());
            let rim = 2.0 * std::f64::consts::PI * (ib as f64 / std::f64::consts::PI).sqrt();
            assert!(
                ib > 0 && (differ as f64) <= rim,
                "{id} {params:?}: coarse mask has {ia} inside, block means {ib}, {differ} differ"
            );
        }
        if sphere || *id == "demo" {
            continue; // the rim's slopes and the demo's fine textures are not smooth at 4 px
        }
        // Full blocks only: the last column and row of blocks are clipped by the image edge
        // in the block means but not on the directly sampled grid.
        let (fw, fh) = (size.0 / s, size.1 / s);
        let full_blocks = |p: &[f32], q: &[f32], f: &dyn Fn(f32, f32) -> f32| {
            (0..fh)
                .flat_map(|y| (0..fw).map(move |x| y * cw + x))
                .map(|i| f(p[i], q[i]))
                .fold(0.0f32, f32::max)
        };
        let d = a
            .normal()
            .iter()
            .zip(b.normal())
            .map(|(p, q)| full_blocks(p, q, &|x, y| (x - y).abs()))
            .fold(0.0f32, f32::max);
        assert!(d < 0.05, "{id} {params:?}: coarse normals differ by {d}");
        let (Value::Scalar(za), Value::Scalar(zb)) = (&coarse[1], &reduce(&whole[1], s)) else {
            panic!()
        };
        let peak = zb.data().iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let dz = full_blocks(za.data(), zb.data(), &|x, y| (x - y / s as f32).abs());
        assert!(
            dz <= 0.05 * peak / s as f32 + 1e-3,
            "{id} {params:?}: coarse heights differ by {dz} (peak {peak})"
        );
    }
}

/// Levels of detail: a region at level L is the same whatever the tiling and the rectangle
/// (pan and zoom show the pixels of the whole level); operators with a coarse form run on the
/// coarse grid and approximate the full result reduced by block means; those without one
/// (a box blur) are computed at full resolution and reduced, exactly.
#[test]
fn a_level_of_detail_is_tiling_independent_and_approximates_the_reduced_full_result() {
    use rgbn::nodes::value::reduce;
    let d = tempfile::tempdir().unwrap();
    let graph = |filter: &str| {
        format!(
            r#"(
    version: 1,
    next_id: 4,
    outputs: {{ "image": (node: 2, port: "image"), "relit": (node: 3, port: "picture") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(300), "height": Int(220), "shape": Choice("gaussians") }}),
        (id: 2, op: {filter}, inputs: {{ "image": Node(1, "image") }}),
        (id: 3, op: "relight", pos: (0.0, 0.0), inputs: {{ "image": Node(2, "image") }}),
    ],
)"#
        )
    };
    let opts = EvalOptions::default();
    for (filter, exact) in [
        (
            r#""filter.gaussian", pos: (0.0, 0.0), params: { "sigma_px": Float(6.0) }"#,
            false,
        ),
        (
            r#""filter.box", pos: (0.0, 0.0), params: { "radius_px": Int(3) }"#,
            true,
        ),
    ] {
        let lg = LoadedGraph::from_text(&graph(filter), "lod.ron", d.path().to_path_buf()).unwrap();
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let whole = Evaluator::default().eval(&plan, &[], &opts).unwrap();
        for level in [1u32, 2] {
            let s = 1usize << level;
            let (lw, lh) = (300usize.div_ceil(s), 220usize.div_ceil(s));
            for name in ["image", "relit"] {
                let ev = Evaluator::default();
                let at = |tile: usize, rect: Rect| {
                    ev.eval_region(&plan, name, rect, &RegionOptions { tile, level }, &opts)
                        .unwrap()
                };
                let full = at(64, Rect::full((300, 220)));
                assert_eq!(full.size, (lw, lh), "{filter} level {level}");
                assert_eq!(full.rect, Rect::full((lw, lh)));
                // The Gaussian runs tile by tile on the coarse grid; the box is computed whole.
                let tiled: Vec<&str> = full.tiles.iter().map(|t| t.op).collect();
                assert_eq!(tiled.contains(&"filter.gaussian"), !exact, "{tiled:?}");
                assert_eq!(tiled.contains(&"surface"), !exact, "{tiled:?}");
                // Another tiling, a panned and zoomed-in rectangle.
                let r = Rect::new(lw / 5, lh / 3, lw / 2, lh / 3);
                let part = at(16, r);
                let d = max_diff(&crop(&full.value, r), &part.value);
                // σ 6 at level 1 is σ 3: the recursive Gaussian, cut at 4σ (see the first test).
                // Pictures: one 8-bit level.
                let tiling_tol = match (!exact && level == 1, name) {
                    (_, "relit") => 1.0 / 255.0,
                    (true, _) => 2e-3,
                    _ => 2e-6,
                };
                assert!(
                    d <= tiling_tol,
                    "{filter} {name} level {level}: tiling changes {d}"
                );
                // Against the full-resolution result reduced by block means.
                let want = reduce(&whole.outputs[name], s);
                let d = max_diff(&want, &full.value);
                eprintln!("{filter} {name} level {level}: {d:.2e} from the reduced full result");
                let tol = match (exact, name) {
                    (true, "image") => 1e-5,
                    // Normals: the blur is applied on the coarse grid (σ/s) rather than
                    // before the block mean.
                    (false, "image") => 0.02,
                    // Relighting the mean normal rather than averaging the relit pixels (a
                    // shading is not linear in the normal), plus one 8-bit level.
                    _ => 0.02 + 1.0 / 255.0,
                };
                assert!(d <= tol, "{filter} {name} level {level}: {d} > {tol}");
            }
        }
    }
}

#[test]
fn cli_eval_level_writes_the_reduced_output_and_a_region_of_it() {
    let d = tempfile::tempdir().unwrap();
    let graph = graph_path("filter_gaussian.ron");
    let lg = LoadedGraph::load(&graph).unwrap();
    let whole = eval_all(&Evaluator::default(), &lg, d.path());
    let Value::Rgbn(full) = &whole.outputs["image"] else {
        panic!("image output")
    };
    let (w, h) = (full.width(), full.height());
    let level_file = d.path().join("level.exr");
    let o = rgbn(&[
        "eval",
        graph.to_str().unwrap(),
        "--level",
        "2",
        "-o",
        &format!("image={}", level_file.display()),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("level 2"), "{}", stdout(&o));
    let got = rgbn::raster::io::load_exr(&level_file, &Default::default()).unwrap();
    assert_eq!((got.width(), got.height()), (w.div_ceil(4), h.div_ceil(4)));
    // The same level through a region: its rectangle of the level.
    let part = d.path().join("part.exr");
    let o = rgbn(&[
        "eval",
        graph.to_str().unwrap(),
        "--level",
        "2",
        "--region",
        "3,4,10,7",
        "-o",
        &format!("image={}", part.display()),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let part = rgbn::raster::io::load_exr(&part, &Default::default()).unwrap();
    let want = crop(&Value::Rgbn(got), Rect::new(3, 4, 10, 7));
    let diff = max_diff(&want, &Value::Rgbn(part));
    assert!(diff <= 2e-6, "{diff}");
    // Beyond the coarsest level: a usage error naming the option.
    let o = rgbn(&["eval", graph.to_str().unwrap(), "--level", "21"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--level"), "{}", stderr(&o));
}

/// The paper's local edits at a coarse level: pen, stamp and brush run on the coarse grid with
/// their lengths and positions scaled, and reproduce the full-resolution edit reduced: the RMS
/// normal error against it is well under the size of the edit itself (the unedited image's
/// error against it), and tilings of the level agree.
#[test]
fn pen_stamp_and_brush_at_a_coarse_level_reproduce_the_reduced_edit() {
    use rgbn::nodes::value::reduce;
    let d = tempfile::tempdir().unwrap();
    let text = r#"(
    version: 1,
    next_id: 6,
    outputs: { "source": (node: 1, port: "image"), "image": (node: 5, port: "image") },
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: { "width": Int(320), "height": Int(240), "shape": Choice("gaussians") }),
        (id: 2, op: "surface", pos: (0.0, 0.0), params: { "width": Int(40), "height": Int(32), "shape": Choice("paraboloid"), "curvature": Float(0.02) }),
        (id: 3, op: "pen", pos: (0.0, 0.0), params: { "points": Points([(40.0, 40.0), (150.0, 90.0), (260.0, 60.0)]), "width_px": Float(16.0), "taper_px": Float(12.0), "height_px": Float(5.0) }, inputs: { "image": Node(1, "image") }),
        (id: 4, op: "stamp", pos: (0.0, 0.0), params: { "positions": Points([(200.0, 160.0), (90.0, 170.0)]), "angle_rad": Float(0.3), "color": Bool(false) }, inputs: { "image": Node(3, "image"), "stamp": Node(2, "image") }),
        (id: 5, op: "brush", pos: (0.0, 0.0), params: { "points": Points([(150.0, 90.0), (230.0, 120.0)]), "radius_px": Float(20.0), "feather_px": Float(8.0), "sigma_px": Float(2.5) }, inputs: { "image": Node(4, "image") }),
    ],
)"#;
    let lg = LoadedGraph::from_text(text, "edits.ron", d.path().to_path_buf()).unwrap();
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    let opts = EvalOptions::default();
    let whole = Evaluator::default().eval(&plan, &[], &opts).unwrap();
    let rms = rms_normals;
    for level in [1u32, 2] {
        let s = 1usize << level;
        let ev = Evaluator::default();
        let r = ev
            .eval_region(
                &plan,
                "image",
                Rect::full((320, 240)),
                &RegionOptions { tile: 32, level },
                &opts,
            )
            .unwrap();
        let tiled: Vec<&str> = r.tiles.iter().map(|t| t.op).collect();
        for op in ["pen", "stamp", "brush", "surface"] {
            assert!(
                tiled.contains(&op),
                "level {level}: {op} not tiled: {tiled:?}"
            );
        }
        let want = reduce(&whole.outputs["image"], s);
        let unedited = reduce(&whole.outputs["source"], s);
        let (err, edit) = (rms(&r.value, &want), rms(&unedited, &want));
        eprintln!("level {level}: RMS normal error {err:.4}, the edit itself {edit:.4}");
        // Measured 0.14 (level 1) and 0.24 (level 2) of the edit, mostly the stamp's: a
        // sampled image, reduced and integrated again on a grid 2^L times coarser (the pen
        // alone, analytic, is within 0.08).
        assert!(
            err < 0.3 * edit,
            "level {level}: {err} against an edit of {edit}"
        );
        // Another tiling of the same level.
        let part = Rect::new(7, 5, 320 / s - 20, 240 / s - 12);
        let p = Evaluator::default()
            .eval_region(
                &plan,
                "image",
                part,
                &RegionOptions { tile: 16, level },
                &opts,
            )
            .unwrap();
        let diff = max_diff(&crop(&r.value, part), &p.value);
        assert!(diff <= 2e-6, "level {level}: tilings differ by {diff}");
    }
}

#[test]
fn a_region_reads_upstream_values_already_evaluated_whole_instead_of_tiling_them() {
    let d = tempfile::tempdir().unwrap();
    let text = r#"(
    version: 1,
    next_id: 4,
    outputs: { "sharp": (node: 2, port: "image"), "pen": (node: 3, port: "image") },
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: { "width": Int(300), "height": Int(200), "shape": Choice("gaussians") }),
        (id: 2, op: "filter.sharpen", pos: (0.0, 0.0), params: { "sigma_px": Float(2.0) }, inputs: { "image": Node(1, "image") }),
        (id: 3, op: "pen", name: Some("pen"), pos: (0.0, 0.0), params: { "points": Points([(40.0, 40.0), (160.0, 90.0)]), "width_px": Float(10.0) }, inputs: { "image": Node(2, "image") }),
    ],
)"#;
    let lg = LoadedGraph::from_text(text, "up.ron", d.path().to_path_buf()).unwrap();
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    let opts = EvalOptions::default();
    let rect = Rect::new(20, 30, 180, 100);
    let ropts = RegionOptions::tiles(32);
    // Cold: every instance is tiled.
    let cold = Evaluator::default()
        .eval_region(&plan, "pen", rect, &ropts, &opts)
        .unwrap();
    assert_eq!(cold.tiles.len(), 3, "{:?}", cold.tiles);
    // The editor's case: the pen's input was evaluated whole (and is cached); the region then
    // tiles only the pen, on crops of it.
    let ev = Evaluator::default();
    let whole = ev.eval(&plan, &["sharp"], &opts).unwrap();
    let r = ev.eval_region(&plan, "pen", rect, &ropts, &opts).unwrap();
    let ops: Vec<&str> = r.tiles.iter().map(|t| t.op).collect();
    assert_eq!(ops, ["pen"], "only the pen is tiled");
    // Same pixels as the cold tiling (the sharpen's Gaussian is a FIR at σ 2: exact up to the
    // order of float operations), and the whole input is that input.
    assert!(max_diff(&cold.value, &r.value) <= 2e-6);
    let sharp = ev.eval_region(&plan, "sharp", rect, &ropts, &opts).unwrap();
    assert!(sharp.tiles.is_empty(), "a cached whole output is cropped");
    assert_eq!(
        max_diff(&crop(&whole.outputs["sharp"], rect), &sharp.value),
        0.0
    );
}

#[test]
fn edits_at_a_coarse_level_patch_only_their_damage_and_equal_a_cold_evaluation() {
    let d = tempfile::tempdir().unwrap();
    let (w, h) = (640usize, 480usize);
    let text = format!(
        r#"(
    version: 1,
    next_id: 6,
    outputs: {{ "image": (node: 5, port: "image") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int({w}), "height": Int({h}), "shape": Choice("gaussians") }}),
        (id: 2, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(40), "height": Int(32), "shape": Choice("gaussians") }}),
        (id: 3, op: "pen", name: Some("pen"), pos: (0.0, 0.0), params: {{ "points": Points([(80.0, 80.0), (120.0, 100.0)]), "width_px": Float(20.0), "taper_px": Float(16.0) }}, inputs: {{ "image": Node(1, "image") }}),
        (id: 4, op: "stamp", name: Some("stamp"), pos: (0.0, 0.0), params: {{ "positions": Points([(400.0, 120.0), (200.0, 360.0)]), "angle_rad": Float(0.3) }}, inputs: {{ "image": Node(3, "image"), "stamp": Node(2, "image") }}),
        (id: 5, op: "filter.gaussian", pos: (0.0, 0.0), params: {{ "sigma_px": Float(2.0) }}, inputs: {{ "image": Node(4, "image") }}),
    ],
)"#
    );
    let mut lg = LoadedGraph::from_text(&text, "coarse.ron", d.path().to_path_buf()).unwrap();
    let opts = EvalOptions::default();
    let ev = Evaluator::default();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut pen = vec![[80.0, 80.0], [120.0, 100.0]];
    let mut stamps = vec![[400.0, 120.0], [200.0, 360.0]];
    for level in [1u32, 2] {
        let s = 1usize << level;
        let ropts = RegionOptions { tile: 32, level };
        let lsize = (w.div_ceil(s), h.div_ceil(s));
        let rect = Rect::full(lsize);
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        ev.eval_region(&plan, "image", rect, &ropts, &opts).unwrap();
        for step in 0..10 {
            let moved_pen = step % 3 != 2;
            if moved_pen {
                let last = *pen.last().unwrap();
                let a = rng.below(628) as f64 / 100.0;
                pen.push([
                    (last[0] + 20.0 * a.cos()).clamp(10.0, w as f64 - 10.0),
                    (last[1] + 20.0 * a.sin()).clamp(10.0, h as f64 - 10.0),
                ]);
                lg.set_param("pen", "paths", &points_text(&pen)).unwrap();
            } else {
                let k = rng.below(2);
                stamps[k] = [
                    40.0 + rng.below(w - 80) as f64,
                    40.0 + rng.below(h - 80) as f64,
                ];
                lg.set_param("stamp", "positions", &points_text(&stamps))
                    .unwrap();
            }
            let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
            let r = ev.eval_region(&plan, "image", rect, &ropts, &opts).unwrap();
            let cold = Evaluator::default()
                .eval_region(&plan, "image", rect, &ropts, &opts)
                .unwrap();
            let diff = max_diff(&cold.value, &r.value);
            assert!(diff <= 2e-6, "level {level} step {step}: {diff}");
            // A pen append at this level touches the tiles around its last segments, not
            // the level's whole grid (an independent bound: the last two segments' box grown
            // by the width, taper and blur, in level pixels).
            if moved_pen {
                let back = &pen[pen.len() - 3..];
                let (mut b0, mut b1) = ([f64::MAX; 2], [f64::MIN; 2]);
                for q in back {
                    b0 = [b0[0].min(q[0]), b0[1].min(q[1])];
                    b1 = [b1[0].max(q[0]), b1[1].max(q[1])];
                }
                let g = 40.0;
                let sf = s as f64;
                let bound = tiles_touching(
                    [
                        (b0[0] - g) / sf,
                        (b0[1] - g) / sf,
                        (b1[0] + g) / sf,
                        (b1[1] + g) / sf,
                    ],
                    32,
                    lsize,
                );
                let at_pen = r.tiles.iter().find(|t| t.op == "pen").unwrap();
                let grid = lsize.0.div_ceil(32) * lsize.1.div_ceil(32);
                assert!(
                    at_pen.computed >= 1 && at_pen.computed <= bound && bound < grid,
                    "level {level} step {step}: pen recomputed {} tiles, bound {bound}, grid {grid}",
                    at_pen.computed
                );
            }
        }
    }
}

/// Global operators at a coarse level: an integration (and the integrability projection) runs
/// on the coarse grid, on its inputs at that level (the pen before it tiled at the level), at
/// the cost of the level's pixels; its height, scaled back to full-resolution pixels,
/// approximates the full-resolution height reduced by block means. A K file (full-resolution
/// pixels) has no coarse form: that integration is computed whole and reduced, exactly.
#[test]
fn global_operators_run_at_a_coarse_level_and_approximate_the_reduced_full_result() {
    use rgbn::nodes::value::reduce;
    let d = tempfile::tempdir().unwrap();
    std::fs::write(
        d.path().join("k.txt"),
        "1000 0 159.5\n0 1000 119.5\n0 0 1\n",
    )
    .unwrap();
    let graph = |shape: &str, method: &str, camera: &str| {
        format!(
            r#"(
    version: 1,
    next_id: 6,
    outputs: {{ "height": (node: 3, port: "height"), "projected": (node: 4, port: "image"), "relit": (node: 5, port: "picture") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(320), "height": Int(240), "shape": Choice("{shape}") }}),
        (id: 2, op: "pen", pos: (0.0, 0.0), params: {{ "points": Points([(40.0, 60.0), (160.0, 120.0), (280.0, 80.0)]), "width_px": Float(24.0), "taper_px": Float(12.0), "height_px": Float(6.0) }}, inputs: {{ "image": Node(1, "image") }}),
        (id: 3, op: "integrate", pos: (0.0, 0.0), params: {{ "method": Choice("{method}"), "camera": Choice("{camera}"), "k_file": Path("k.txt") }}, inputs: {{ "image": Node(2, "image") }}),
        (id: 4, op: "project", pos: (0.0, 0.0), params: {{ "method": Choice("{method}") }}, inputs: {{ "image": Node(2, "image") }}),
        (id: 5, op: "relight", pos: (0.0, 0.0), inputs: {{ "image": Node(4, "image") }}),
    ],
)"#
        )
    };
    // RMS over the blocks wholly inside the mask (`inside`: the reduced mask), after removing
    // the mean difference; and the spread of `b` there.
    let rms_height = |a: &Value, b: &Value, inside: Option<&[f32]>| -> (f64, f64) {
        let (Value::Scalar(a), Value::Scalar(b)) = (a, b) else {
            panic!("heights expected")
        };
        let pairs: Vec<(f64, f64)> = a
            .data()
            .iter()
            .zip(b.data())
            .enumerate()
            .filter(|(i, _)| inside.is_none_or(|m| m[*i] >= 1.0))
            .map(|(_, (x, y))| (f64::from(*x), f64::from(*y)))
            .collect();
        let n = pairs.len() as f64;
        let mean_d = pairs.iter().map(|(x, y)| x - y).sum::<f64>() / n;
        let mean_b = pairs.iter().map(|(_, y)| y).sum::<f64>() / n;
        let err = (pairs
            .iter()
            .map(|(x, y)| (x - y - mean_d).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let spread = (pairs.iter().map(|(_, y)| (y - mean_b).powi(2)).sum::<f64>() / n).sqrt();
        (err, spread)
    };
    let opts = EvalOptions::default();
    for (shape, method, camera) in [
        ("gaussians", "poisson_dct", "orthographic"),
        ("sphere", "masked_poisson", "orthographic"),
        ("gaussians", "poisson_dct", "pinhole"),
        ("gaussians", "poisson_dct", "k_file"),
    ] {
        let lg = LoadedGraph::from_text(
            &graph(shape, method, camera),
            "global.ron",
            d.path().to_path_buf(),
        )
        .unwrap();
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let whole = Evaluator::default().eval(&plan, &[], &opts).unwrap();
        let coarse = camera != "k_file";
        for level in [1u32, 2] {
            let s = 1usize << level;
            let (lw, lh) = (320 / s, 240 / s);
            let ev = Evaluator::default();
            let ropts = RegionOptions { tile: 32, level };
            let r = ev
                .eval_region(&plan, "height", Rect::full((lw, lh)), &ropts, &opts)
                .unwrap();
            let what = format!("{shape} {method} {camera} level {level}");
            let at_level: Vec<(&str, usize)> = r
                .tiles
                .iter()
                .filter(|t| t.op == "integrate")
                .map(|t| (t.op, t.pixels))
                .collect();
            let whole_ops: Vec<&str> = r.whole.iter().map(|n| n.op).collect();
            if coarse {
                // Computed once, on the level's pixels, not at full resolution; the pen
                // before it is tiled at the level.
                assert_eq!(at_level, [("integrate", lw * lh)], "{what}");
                assert!(!whole_ops.contains(&"integrate"), "{what}: {whole_ops:?}");
                assert!(r.tiles.iter().any(|t| t.op == "pen"), "{what}");
            } else {
                assert!(at_level.is_empty(), "{what}: {at_level:?}");
                assert!(whole_ops.contains(&"integrate"), "{what}: {whole_ops:?}");
            }
            let want = reduce(&whole.outputs["height"], s);
            let Value::Rgbn(reduced) = reduce(&whole.outputs["projected"], s) else {
                panic!("an image")
            };
            let (err, spread) = rms_height(&r.value, &want, reduced.mask());
            eprintln!("{what}: height RMS error {err:.4} px against a spread of {spread:.3} px");
            if coarse {
                // Measured ≤ 1.8 % of the spread (the sphere at level 2): the normals averaged
                // over 2^L × 2^L blocks and integrated on the coarse grid.
                assert!(err <= 0.03 * spread, "{what}: {err} against {spread}");
            } else {
                assert!(err <= 1e-5 * spread.max(1.0), "{what}: {err}");
            }
            // A part of the level is cut from the cached level value: nothing is computed.
            let part = Rect::new(5, 3, lw / 2, lh / 2);
            let p = ev
                .eval_region(&plan, "height", part, &ropts, &opts)
                .unwrap();
            assert!(max_diff(&crop(&r.value, part), &p.value) <= 0.0, "{what}");
            assert_eq!(p.tiles_computed(), 0, "{what}: {:?}", p.tiles);
            // The projection's normals at the level, against the reduced full projection.
            if coarse {
                let r = ev
                    .eval_region(&plan, "projected", Rect::full((lw, lh)), &ropts, &opts)
                    .unwrap();
                let (Value::Rgbn(got), Value::Rgbn(want)) =
                    (&r.value, reduce(&whole.outputs["projected"], s))
                else {
                    panic!("images")
                };
                // Over the blocks wholly inside the mask (the rim's grazing normals are not
                // resolved at any level).
                let inside: Vec<usize> = (0..lw * lh)
                    .filter(|&i| want.mask().is_none_or(|m| m[i] >= 1.0))
                    .collect();
                let sq: f64 = inside
                    .iter()
                    .map(|&i| {
                        (0..3)
                            .map(|k| f64::from(got.normal()[k][i] - want.normal()[k][i]).powi(2))
                            .sum::<f64>()
                    })
                    .sum();
                let err = (sq / inside.len() as f64).sqrt();
                eprintln!("{what}: projected normals RMS error {err:.4}");
                assert!(err <= 0.02, "{what}: projected {err}");
                assert!(r.tiles.iter().any(|t| t.op == "project" && t.computed == 1));
            }
        }
    }
}
