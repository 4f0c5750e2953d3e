//! Full-pixel goldens: a few example graphs evaluated at small sizes, every pixel compared with
//! a stored truth image within a tolerance (beside the statistic goldens of `graphs.rs`, which
//! cover every graph at its own size).
//!
//! The truth images live in `tests/golden/pixels/`: `STEM.OUTPUT.exr` for RGBN images (half
//! floats, ZIP-compressed: colour, normal and mask channels) and `STEM.OUTPUT.png` for pictures
//! (8-bit RGBA). Regenerate them after an intended change of results with
//!
//! ```sh
//! UPDATE_GOLDEN=1 cargo test --test tests golden
//! ```
//!
//! and review the images before committing them.

use crate::common::*;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use rgbn::raster::io::{self, ExrCompression, ExrPrecision};
use rgbn::RgbnImage;
use std::path::{Path, PathBuf};

/// `(node, parameter, value)`, as `--set NODE.PARAM=VALUE`.
type Set = (&'static str, &'static str, &'static str);

/// Graph, `--set` overrides that make it small, and the outputs compared pixel by pixel.
const CASES: &[(&str, &[Set], &[&str])] = &[
    (
        "demo",
        &[("source", "size", "48")],
        &["image", "relit", "normals"],
    ),
    (
        "filter_gaussian",
        &[("1", "width", "40"), ("1", "height", "32")],
        &["image"],
    ),
    (
        "combine_rotation",
        &[
            ("1", "size", "48"),
            ("3", "width", "48"),
            ("3", "height", "48"),
        ],
        &["image"],
    ),
    ("band_remove", &[("1", "size", "48")], &["image"]),
];

/// Float channels: absolute + relative tolerance (covers the half-float storage, ~5e-4
/// relative, and reordered float sums); 8-bit pictures: one level.
const FLOAT_ABS: f32 = 2e-3;
const FLOAT_REL: f32 = 2e-3;
const PICTURE_LEVELS: u8 = 1;

fn update() -> bool {
    std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v == "1")
}

fn pixels_dir() -> PathBuf {
    root().join("tests/golden/pixels")
}

/// Every plane of an RGBN image with its channel name (colour, normal, mask if any).
fn planes(img: &RgbnImage) -> Vec<(&'static str, &[f32])> {
    let mut v: Vec<(&'static str, &[f32])> = ["R", "G", "B"]
        .into_iter()
        .zip(img.color().iter().map(Vec::as_slice))
        .chain(
            ["N.X", "N.Y", "N.Z"]
                .into_iter()
                .zip(img.normal().iter().map(Vec::as_slice)),
        )
        .collect();
    if let Some(m) = img.mask() {
        v.push(("A", m));
    }
    v
}

/// `Err` naming the first differing pixel (and how many differ) if `got` is not `want`
/// within the tolerance.
fn compare_rgbn(want: &RgbnImage, got: &RgbnImage) -> Result<(), String> {
    let (w, h) = (got.width(), got.height());
    if (want.width(), want.height()) != (w, h) {
        return Err(format!(
            "size {}×{} but the golden is {}×{}",
            w,
            h,
            want.width(),
            want.height()
        ));
    }
    let (pw, pg) = (planes(want), planes(got));
    if pw.len() != pg.len() {
        return Err(format!(
            "{} channels but the golden has {}",
            pg.len(),
            pw.len()
        ));
    }
    for ((name, a), (_, b)) in pw.iter().zip(&pg) {
        let bad: Vec<usize> = (0..w * h)
            // NaN in either differs.
            .filter(|&i| {
                let d = (a[i] - b[i]).abs();
                d.is_nan() || d > FLOAT_ABS + FLOAT_REL * a[i].abs()
            })
            .collect();
        if let Some(&i) = bad.first() {
            return Err(format!(
                "channel {name}: {} of {} pixels differ; first at ({}, {}): golden {} got {}",
                bad.len(),
                w * h,
                i % w,
                i / w,
                a[i],
                b[i]
            ));
        }
    }
    Ok(())
}

fn compare_rgba(want: &[u8], got: &[u8], w: usize) -> Result<(), String> {
    if want.len() != got.len() {
        return Err(format!(
            "{} bytes but the golden has {}",
            got.len(),
            want.len()
        ));
    }
    let bad: Vec<usize> = (0..got.len())
        .filter(|&i| want[i].abs_diff(got[i]) > PICTURE_LEVELS)
        .collect();
    match bad.first() {
        None => Ok(()),
        Some(&i) => Err(format!(
            "{} of {} samples differ; first at ({}, {}) channel {}: golden {} got {}",
            bad.len(),
            got.len(),
            (i / 4) % w,
            (i / 4) / w,
            i % 4,
            want[i],
            got[i]
        )),
    }
}

/// Stores (with `UPDATE_GOLDEN=1`) or compares one output; `Err` says what differs.
fn check_output(file: &Path, v: &Value) -> Result<(), String> {
    match v {
        Value::Rgbn(img) => {
            if update() {
                io::save_exr_with(img, file, ExrPrecision::Half, ExrCompression::Zip)
                    .map_err(|e| e.to_string())?;
            }
            let want = io::load_exr(file, &Default::default()).map_err(|e| e.to_string())?;
            compare_rgbn(&want, img)
        }
        Value::Picture(p) => {
            if update() {
                rgbn::nodes::save::write_value(v, file, &Default::default())
                    .map_err(|e| e.to_string())?;
            }
            let want = image::open(file).map_err(|e| e.to_string())?.to_rgba8();
            if (want.width() as usize, want.height() as usize) != (p.width, p.height) {
                return Err(format!(
                    "size {}×{} but the golden is {}×{}",
                    p.width,
                    p.height,
                    want.width(),
                    want.height()
                ));
            }
            compare_rgba(want.as_raw(), &p.rgba, p.width)
        }
        other => Err(format!(
            "{} outputs have no pixel golden",
            other.port_type().name()
        )),
    }
}

fn extension(v: &Value) -> &'static str {
    match v {
        Value::Rgbn(_) => "exr",
        _ => "png",
    }
}

#[test]
fn golden_pixels_of_small_example_graphs() {
    let out_dir = tempfile::tempdir().unwrap();
    let ev = Evaluator::default();
    if update() {
        std::fs::create_dir_all(pixels_dir()).unwrap();
    }
    let mut failures = Vec::new();
    for (stem, sets, outputs) in CASES {
        let mut lg = LoadedGraph::load(&graph_path(&format!("{stem}.ron")))
            .unwrap_or_else(|e| panic!("{e}"));
        for (node, param, value) in *sets {
            lg.set_param(node, param, value)
                .unwrap_or_else(|e| panic!("{stem}: {e}"));
        }
        let plan = Plan::new(&lg, &example_bindings(&lg), out_dir.path()).expect("plan");
        let r = ev
            .eval(&plan, outputs, &EvalOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
        for name in *outputs {
            let v = &r.outputs[*name];
            let file = pixels_dir().join(format!("{stem}.{name}.{}", extension(v)));
            if let Err(e) = check_output(&file, v) {
                failures.push(format!("{}: {e}", file.display()));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "pixel goldens differ (UPDATE_GOLDEN=1 cargo test --test tests golden regenerates them \
         after an intended change):\n{}",
        failures.join("\n")
    );
}

/// The comparison catches a one-pixel change (so the golden test can fail).
#[test]
fn golden_pixel_comparison_catches_one_changed_pixel() {
    let img = rgbn::raster::sample::demo_medallion(24);
    assert_eq!(compare_rgbn(&img, &img), Ok(()));
    let mut normal = img.normal().clone();
    normal[0][5 * 24 + 7] += 0.01;
    let changed = RgbnImage::new(
        24,
        24,
        img.color().clone(),
        normal,
        img.mask().map(<[f32]>::to_vec),
    )
    .unwrap();
    let e = compare_rgbn(&img, &changed).unwrap_err();
    assert!(
        e.contains("N.X") && e.contains("1 of 576") && e.contains("(7, 5)"),
        "{e}"
    );

    let a = vec![10u8; 16];
    let mut b = a.clone();
    assert_eq!(compare_rgba(&a, &b, 2), Ok(()));
    b[9] = 12;
    let e = compare_rgba(&a, &b, 2).unwrap_err();
    assert!(e.contains("1 of 16") && e.contains("(0, 1)"), "{e}");
}
