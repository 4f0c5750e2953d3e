//! The editing-operator nodes add no maths: their example graphs equal direct calls of the
//! pure functions (cross-checks of the golden outputs), and their errors name node and
//! parameter.

use crate::common::*;
use rgbn::eval::Evaluator;
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use rgbn::ops::brush::{brush_image, BrushParams, BrushStroke};
use rgbn::ops::filter::Kernel;
use rgbn::ops::pen::{apply_pen, PenParams, Profile};
use rgbn::raster::integrate::{integrate_normals, project_integrable, IntegrateParams};
use rgbn::raster::sample::demo_medallion;
use rgbn::RgbnImage;

fn image(v: &Value) -> &RgbnImage {
    match v {
        Value::Rgbn(i) => i,
        other => panic!("expected an image, got {:?}", other.port_type()),
    }
}

fn number(v: &Value) -> f64 {
    match v {
        Value::Number(x) => *x,
        other => panic!("expected a number, got {:?}", other.port_type()),
    }
}

fn eval(name: &str, out: &std::path::Path) -> rgbn::eval::EvalResult {
    let lg = LoadedGraph::load(&graph_path(name)).unwrap_or_else(|e| panic!("{e}"));
    eval_all(&Evaluator::default(), &lg, out)
}

#[test]
fn pen_graph_equals_two_apply_pen_calls() {
    let r = eval("pen.ron", std::env::temp_dir().as_path());
    let demo = demo_medallion(128);
    let (a, _) = apply_pen(
        &demo,
        &PenParams {
            points: vec![[12.0, 110.0], [40.0, 90.0], [80.0, 100.0], [116.0, 80.0]],
            width_px: 10.0,
            taper_px: 12.0,
            ..PenParams::default()
        }
        .with_profile(&Profile::Bump { height_px: 3.0 }),
    )
    .unwrap();
    let (b, rep) = apply_pen(
        &a,
        &PenParams {
            points: vec![[16.0, 16.0], [56.0, 12.0], [60.0, 48.0], [20.0, 52.0]],
            closed: true,
            width_px: 8.0,
            ..PenParams::default()
        }
        .with_profile(&Profile::Step { height_px: 2.0 }),
    )
    .unwrap();
    assert_eq!(image(&r.outputs["image"]), &b);
    assert_eq!(
        number(&r.outputs["relative_rms_curl"]),
        rep.curl_after.relative
    );
    // The pen's own field is integrable (the curl above is the demo's own).
    assert!(rep.curl_pen.relative < 1e-5, "{:?}", rep.curl_pen);
}

#[test]
fn project_graph_equals_brush_then_projection() {
    let r = eval("project.ron", std::env::temp_dir().as_path());
    let (edited, _) = brush_image(
        &demo_medallion(96),
        None,
        &BrushParams {
            kernels: vec![Kernel::Sharpen {
                sigma_px: 2.0,
                amount: 3.0,
            }],
            strokes: vec![BrushStroke {
                points: vec![[16.0, 48.0], [80.0, 48.0]],
                radius_px: 6.0,
                feather_px: 10.0,
            }],
            ..BrushParams::default()
        },
    )
    .unwrap();
    let (want, _, rep) = project_integrable(&edited, &Default::default()).unwrap();
    assert_eq!(image(&r.outputs["image"]), &want);
    let (before, after) = (
        number(&r.outputs["curl_before"]),
        number(&r.outputs["curl_after"]),
    );
    assert_eq!(before, rep.before.relative);
    eprintln!("project.ron: relative RMS curl {before:.4} before, {after:.2e} after");
    // The demo itself is a surface (curl ≈ 1e-7): all of `before` is the brush's doing, and
    // the projection removes it to rounding.
    assert!(before > 0.01 && after < 1e-5, "{before} {after}");
}

#[test]
fn bilateral_graph_equals_split() {
    let r = eval("bilateral_split.ron", std::env::temp_dir().as_path());
    let (base, detail, _) = bilateral_split_example();
    assert_eq!(image(&r.outputs["base"]), &base);
    assert_eq!(image(&r.outputs["detail"]), &detail);
}

#[test]
fn integrate_graph_writes_the_height_and_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let r = eval("integrate.ron", dir.path());
    let (z, rep) = integrate_normals(&demo_medallion(96), &IntegrateParams::default()).unwrap();
    match &r.outputs["height"] {
        Value::Scalar(h) => assert_eq!(**h, z),
        other => panic!("{:?}", other.port_type()),
    }
    assert_eq!(number(&r.outputs["rms_residual"]), rep.rms_residual);
    assert_eq!(number(&r.outputs["vertices"]), 96.0 * 96.0);
    let ply = std::fs::read(dir.path().join("demo_mesh.ply")).unwrap();
    assert!(ply.starts_with(b"ply\nformat binary_little_endian"));
    assert!(dir.path().join("demo_height.exr").is_file());
}

#[test]
fn bad_node_params_name_node_and_parameter() {
    let dir = tempfile::tempdir().unwrap();
    // An open path with a level-changing profile is refused at validation.
    let o = rgbn(&[
        "eval",
        graph_path("pen.ron").to_str().unwrap(),
        "--set",
        "2.profile=step",
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("profile") && e.contains("node 2"), "{e}");
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    // A band-pass whose coarse σ is below the fine one.
    let o = rgbn(&[
        "eval",
        graph_path("band_remove.ron").to_str().unwrap(),
        "--set",
        "2.sigma_coarse_px=0.5",
    ]);
    let e = stderr(&o);
    assert_ne!(o.status.code(), Some(0), "{e}");
    assert!(e.contains("sigma_coarse_px") && e.contains("node 2"), "{e}");
    drop(dir);
}
