//! Region evaluation (`rgbn::eval::region`): an output computed over a rectangle, tile by tile,
//! equals the same rectangle of the whole-image result.

use crate::common::*;
use rgbn::eval::region::{crop, Rect, RegionOptions};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::ops::params::ParamValue;
use rgbn::ops::{PortType, Value};

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
            i.params.iter().any(|(k, v)| {
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
                        &RegionOptions { tile },
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
