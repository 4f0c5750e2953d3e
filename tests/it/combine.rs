//! `combine.rotation` through graphs, against values computed by hand from §VII of the paper
//! and from Barré-Brisebois & Hill's published test vectors: the inputs are constant-normal
//! EXR files bound to a graph's inputs, the output read back from the evaluated graph.

use super::common::write;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use rgbn::raster::io::{save_exr, ExrPrecision};
use rgbn::RgbnImage;
use std::collections::BTreeMap;
use std::path::Path;

const SIZE: usize = 3;

/// A `SIZE`² image whose every normal is `n` (unit or not: the graph normalises on load).
fn constant(dir: &Path, name: &str, n: [f64; 3]) -> std::path::PathBuf {
    let len = n.iter().map(|v| v * v).sum::<f64>().sqrt();
    let k = SIZE * SIZE;
    let img = RgbnImage::new(
        SIZE,
        SIZE,
        [vec![0.5; k], vec![0.5; k], vec![0.5; k]],
        n.map(|c| vec![(c / len) as f32; k]),
        None,
    )
    .unwrap();
    let p = dir.join(format!("{name}.exr"));
    save_exr(&img, &p, ExrPrecision::Full).unwrap();
    p
}

/// A tilt of `deg` degrees about the y axis (towards +x).
fn tilt(deg: f64) -> [f64; 3] {
    let r = deg.to_radians();
    [r.sin(), 0.0, r.cos()]
}

/// Evaluates `combine.rotation` with `mode` on the three inputs (`existing` connected when
/// given) and `strength`; returns the centre pixel's normal.
fn combine(
    mode: &str,
    base: [f64; 3],
    detail: [f64; 3],
    existing: Option<[f64; 3]>,
    strength: f64,
) -> [f64; 3] {
    let d = tempfile::tempdir().unwrap();
    let mut bind = BTreeMap::new();
    bind.insert("base".to_string(), constant(d.path(), "base", base));
    bind.insert("detail".to_string(), constant(d.path(), "detail", detail));
    let existing_port = if let Some(e) = existing {
        bind.insert("existing".to_string(), constant(d.path(), "existing", e));
        r#""existing": Input("existing"),"#
    } else {
        ""
    };
    let inputs: String = bind
        .keys()
        .map(|k| format!("\"{k}\": (ty: Rgbn),"))
        .collect();
    let text = format!(
        r#"(
    version: 1,
    next_id: 2,
    inputs: {{ {inputs} }},
    outputs: {{ "image": (node: 1, port: "image") }},
    nodes: [
        (
            id: 1,
            op: "combine.rotation",
            pos: (0.0, 0.0),
            params: {{ "mode": Choice("{mode}"), "strength": Float({strength:?}) }},
            inputs: {{
                "base": Input("base"),
                "detail": Input("detail"),
                {existing_port}
            }},
        ),
    ],
)"#
    );
    let p = write(d.path(), "g.ron", &text);
    let lg = LoadedGraph::load(&p).unwrap_or_else(|e| panic!("{e}"));
    let plan = Plan::new(&lg, &bind, d.path()).unwrap_or_else(|e| panic!("{e}"));
    let r = Evaluator::default()
        .eval(&plan, &[], &EvalOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    let Value::Rgbn(img) = &r.outputs["image"] else {
        panic!("image output")
    };
    let i = SIZE * SIZE / 2;
    let [x, y, z] = img.normal();
    [x[i], y[i], z[i]].map(f64::from)
}

/// The angle between two unit vectors, accurate near 0 (atan2 of |a × b| and a · b).
fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    let c: f64 = (0..3).map(|k| a[k] * b[k]).sum();
    let x = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let s = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
    s.atan2(c).to_degrees()
}

#[test]
fn rotate_saturates_the_detail_first_as_section_vii_says() {
    // Base 80°, detail 30°, existing 50°, all about y: the detail on the base would be at
    // 110° (under the horizon); saturated at n_z = 0.05 it is at acos(0.05) = 87.134°, so
    // the rotation is 7.134° and the existing normal ends at 57.134°.
    let r = combine("rotate", tilt(80.0), tilt(30.0), Some(tilt(50.0)), 1.0);
    let got = angle_deg(r, [0.0, 0.0, 1.0]);
    let want = 50.0 + (0.05f64).acos().to_degrees() - 80.0;
    assert!((want - 57.134).abs() < 1e-3, "hand value {want}");
    assert!((got - want).abs() < 0.01, "tilt {got}°, want {want}°");
    assert!(
        r[1].abs() < 1e-6 && r[0] > 0.0,
        "stays in the xz plane: {r:?}"
    );
}

#[test]
fn weight_zero_returns_the_existing_normal_in_the_section_vii_modes() {
    let existing = [-0.3, 0.2, 0.9];
    let len = existing.iter().map(|v| v * v).sum::<f64>().sqrt();
    let want = existing.map(|v| v / len);
    for mode in ["replace", "blend", "rotate"] {
        let r = combine(mode, tilt(20.0), tilt(35.0), Some(existing), 0.0);
        assert!(angle_deg(r, want) < 1e-3, "{mode}: {r:?} vs {want:?}");
    }
    // Full weight: replace gives the detail on the base (20° + 35° in the minimal frame),
    // whatever the existing normal.
    let r = combine("replace", tilt(20.0), tilt(35.0), Some(existing), 1.0);
    assert!(angle_deg(r, tilt(55.0)) < 1e-3, "replace: {r:?}");
    // Half-way blend: on the great arc from the existing normal to the detail on the base, in
    // the middle.
    let r = combine("blend", tilt(20.0), tilt(35.0), Some(existing), 0.5);
    let (da, db) = (angle_deg(r, want), angle_deg(r, tilt(55.0)));
    assert!((da - db).abs() < 1e-3, "midpoint: {da}° vs {db}°");
    assert!(
        (da + db - angle_deg(want, tilt(55.0))).abs() < 1e-3,
        "on the arc"
    );
}

/// Barré-Brisebois & Hill's example ("Blending in Detail", 2012): base (0.3, 0.4, 0.866),
/// detail (−0.2, 0.1, 0.97) normalised.
#[test]
fn industry_test_vectors() {
    let base = [0.3, 0.4, 0.866];
    let detail = [-0.2, 0.1, 0.97];
    for (mode, want) in [
        ("rnm", [0.0947, 0.4946, 0.8640]),
        ("partial_derivative", [0.1212, 0.4883, 0.8642]),
        // Blend and rotate with the existing normal unconnected are RNM in the minimal frame.
        ("blend", [0.0947, 0.4946, 0.8640]),
        ("rotate", [0.0947, 0.4946, 0.8640]),
    ] {
        let r = combine(mode, base, detail, None, 1.0);
        assert!(
            (0..3).all(|k| (r[k] - want[k]).abs() < 1e-4),
            "{mode}: {r:?} vs {want:?}"
        );
    }
}
