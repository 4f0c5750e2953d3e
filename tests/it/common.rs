//! Helpers shared by the integration test modules.

#![allow(dead_code)]

use rgbn::eval::{EvalOptions, EvalResult, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `graphs/NAME`.
pub fn graph_path(name: &str) -> PathBuf {
    root().join("graphs").join(name)
}

/// A shipped graph file: `*.ron`, not hidden (the editor's `.NAME.autosave.ron` recovery files
/// live beside the graphs they belong to and are not part of the repository).
fn shipped_graph(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "ron")
        && !p
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'))
}

/// Every `graphs/*.ron` (top level only, sorted).
pub fn top_graphs() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("graphs"))
        .expect("graphs/ exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| shipped_graph(p))
        .collect();
    v.sort();
    v
}

/// Every `.ron` under `graphs/`, recursively.
pub fn all_graphs() -> Vec<PathBuf> {
    fn walk(d: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(d).expect("readable").flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if shipped_graph(&p) {
                out.push(p);
            }
        }
    }
    let mut v = Vec::new();
    walk(&root().join("graphs"), &mut v);
    v.sort();
    v
}

/// Graph inputs of the example graphs are bound to `graphs/data/NAME.exr`.
pub fn example_bindings(lg: &LoadedGraph) -> BTreeMap<String, PathBuf> {
    lg.graph
        .inputs
        .keys()
        .map(|n| {
            (
                n.clone(),
                root().join("graphs/data").join(format!("{n}.exr")),
            )
        })
        .collect()
}

/// Evaluates every output of `lg` with a fresh plan.
pub fn eval_all(ev: &Evaluator, lg: &LoadedGraph, out_dir: &Path) -> EvalResult {
    let plan = Plan::new(lg, &example_bindings(lg), out_dir).expect("plan");
    ev.eval(&plan, &[], &EvalOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Writes `text` as `name` in `dir` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

/// Real third-party test data: `sub` under `$RGBN_DATA` (else `../shared/data`), or `None`
/// with a `SKIPPED` note — a failure instead with `RGBN_REQUIRE_DATA=1` (CI). The one helper
/// every real-data test uses, unit tests included.
pub use rgbn::test_data::real_data;

/// Runs the `rgbn` binary.
pub fn rgbn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .args(args)
        .output()
        .expect("the rgbn binary runs")
}

/// Stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Stdout as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// RMS difference of the normals of two RGBN values (all three planes, every pixel).
pub fn rms_normals(a: &rgbn::nodes::Value, b: &rgbn::nodes::Value) -> f64 {
    let (rgbn::nodes::Value::Rgbn(a), rgbn::nodes::Value::Rgbn(b)) = (a, b) else {
        panic!("images")
    };
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (p, q) in a.normal().iter().zip(b.normal()) {
        for (x, y) in p.iter().zip(q) {
            sum += f64::from(x - y).powi(2);
            n += 1;
        }
    }
    (sum / n as f64).sqrt()
}

/// `graphs/bilateral_split.ron` computed directly: the bilateral split of the 96² demo with the
/// graph's parameters (base, detail, report).
pub fn bilateral_split_example() -> (
    rgbn::RgbnImage,
    rgbn::RgbnImage,
    rgbn::ops::bilateral::BilateralReport,
) {
    use rgbn::ops::bilateral::{split, BilateralParams};
    split(
        &rgbn::raster::sample::demo_medallion(96),
        &BilateralParams {
            sigma_spatial_px: 2.5,
            sigma_normal: 0.25,
            sigma_color: 0.2,
            filter_color: true,
            ..BilateralParams::default()
        },
    )
    .unwrap()
}

/// One line per channel: name, mean, std, min, max, then 16 samples on a 4×4 grid.
pub fn channel(out: &mut String, label: &str, w: usize, h: usize, at: impl Fn(usize) -> f64) {
    let n = (w * h) as f64;
    let (mut s, mut s2, mut lo, mut hi) = (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..w * h {
        let v = at(i);
        assert!(v.is_finite(), "{label}: non-finite value");
        s += v;
        s2 += v * v;
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let mean = s / n;
    let std = (s2 / n - mean * mean).max(0.0).sqrt();
    let _ = write!(out, "{label} {mean:.6e} {std:.6e} {lo:.6e} {hi:.6e}");
    for gy in 0..4 {
        for gx in 0..4 {
            let (x, y) = ((2 * gx + 1) * w / 8, (2 * gy + 1) * h / 8);
            let _ = write!(out, " {:.6e}", at(y * w + x));
        }
    }
    out.push('\n');
}

/// Every channel of `v` as [`channel`] lines labelled `name.CHANNEL`.
pub fn summarise(name: &str, v: &Value) -> String {
    let mut s = String::new();
    match v {
        Value::Rgbn(img) => {
            let (w, h) = (img.width(), img.height());
            let planes = img.color().iter().chain(img.normal().iter());
            for (c, p) in ["R", "G", "B", "N.X", "N.Y", "N.Z"].iter().zip(planes) {
                channel(&mut s, &format!("{name}.{c}"), w, h, |i| f64::from(p[i]));
            }
            if let Some(m) = img.mask() {
                channel(&mut s, &format!("{name}.A"), w, h, |i| f64::from(m[i]));
            }
        }
        Value::Mask(p) | Value::Scalar(p) => {
            let d = p.data();
            channel(&mut s, name, p.width(), p.height(), |i| f64::from(d[i]));
        }
        Value::Picture(p) => {
            for (k, c) in ["r", "g", "b", "a"].iter().enumerate() {
                channel(&mut s, &format!("{name}.{c}"), p.width, p.height, |i| {
                    f64::from(p.rgba[4 * i + k])
                });
            }
        }
        Value::Number(x) => {
            let _ = writeln!(s, "{name} {x:.6e}");
        }
    }
    s
}

/// How far a [`channel`] statistic may move and still be the same result: ½ level for 8-bit
/// picture channels (labels ending `.r`, `.g`, `.b`, `.a`); 1e-5 absolute + 1e-4 relative for
/// floats (SIMD twins and thread counts change last bits, never this much).
pub fn tolerance(label: &str, golden: f64) -> f64 {
    let picture = [".r", ".g", ".b", ".a"].iter().any(|s| label.ends_with(s));
    if picture {
        0.5
    } else {
        1e-5 + 1e-4 * golden.abs()
    }
}
