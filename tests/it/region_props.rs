//! Region evaluation on random images: every local operator, border mode, mask and tile size
//! gives over a random rectangle what the whole-image evaluation gives there.

use proptest::prelude::*;
use rgbn::eval::region::RegionOptions;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::value::crop;
use rgbn::raster::io::{save, SaveOptions};
use rgbn::raster::window::Rect;
use rgbn::raster::RgbnImage;
use std::collections::BTreeMap;
use std::path::Path;

/// A random RGBN image: gradients uniform in [−1, 1] (normals of a rough, non-integrable
/// field), colour uniform in [0, 1].
fn random_image(w: usize, h: usize, seed: u64) -> RgbnImage {
    let mut s = seed | 1;
    let mut u = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f32 / (1u64 << 53) as f32
    };
    let n = w * h;
    let color: [Vec<f32>; 3] = std::array::from_fn(|_| (0..n).map(|_| u()).collect());
    let mut normal: [Vec<f32>; 3] = std::array::from_fn(|_| Vec::with_capacity(n));
    for _ in 0..n {
        let (p, q) = (2.0 * u() - 1.0, 2.0 * u() - 1.0);
        let l = (p * p + q * q + 1.0).sqrt();
        for (plane, v) in normal.iter_mut().zip([-p / l, -q / l, 1.0 / l]) {
            plane.push(v);
        }
    }
    RgbnImage::new(w, h, color, normal, None).unwrap()
}

/// The operator under test as a RON node (id 4, reading node 3's image; node 5 is a second
/// image of the same size) and the output port compared.
fn op_node(k: usize, border: &str, w: usize, h: usize, a: f64, b: f64) -> (String, &'static str) {
    let (fw, fh) = (w as f64, h as f64);
    let pts = |n: usize| {
        (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                format!(
                    "({:.3}, {:.3})",
                    fw * (0.1 + 0.8 * ((t * 7.0 + a).sin() * 0.5 + 0.5)),
                    fh * (0.1 + 0.8 * ((t * 5.0 + b).cos() * 0.5 + 0.5))
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    // The same points in the order of their angle around their centroid: a closed path through
    // them does not cross itself (the pen refuses one that does).
    let simple_pts = |n: usize| {
        let p: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                [
                    fw * (0.1 + 0.8 * ((t * 7.0 + a).sin() * 0.5 + 0.5)),
                    fh * (0.1 + 0.8 * ((t * 5.0 + b).cos() * 0.5 + 0.5)),
                ]
            })
            .collect();
        let c = p.iter().fold([0.0, 0.0], |s, q| [s[0] + q[0], s[1] + q[1]]);
        let c = [c[0] / n as f64, c[1] / n as f64];
        let mut p = p;
        p.sort_by(|u, v| {
            (u[1] - c[1])
                .atan2(u[0] - c[0])
                .total_cmp(&(v[1] - c[1]).atan2(v[0] - c[0]))
        });
        p.iter()
            .map(|q| format!("({:.3}, {:.3})", q[0], q[1]))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let s1 = 0.6 + 3.4 * a; // FIR below 3, recursive above
    let (op, params, port) = match k {
        0 => (
            "filter.gaussian",
            format!(
                r#""sigma_px": Float({s1}), "border": Choice("{border}"), "mask_aware": Bool({})"#,
                b > 0.5
            ),
            "image",
        ),
        1 => (
            "filter.box",
            format!(
                r#""radius_px": Int({}), "border": Choice("{border}")"#,
                1 + (a * 4.0) as i64
            ),
            "image",
        ),
        2 => (
            "filter.sharpen",
            format!(
                r#""sigma_px": Float({s1}), "amount": Float(0.7), "border": Choice("{border}"), "mask_aware": Bool({})"#,
                b > 0.5
            ),
            "image",
        ),
        3 => (
            "filter.edge",
            format!(
                r#""sigma_fine_px": Float(0.8), "sigma_coarse_px": Float({}), "border": Choice("{border}")"#,
                s1 + 0.5
            ),
            "image",
        ),
        4 => (
            "filter.highpass",
            format!(r#""sigma_px": Float({s1}), "border": Choice("{border}")"#),
            "image",
        ),
        5 => (
            "filter.dog",
            format!(
                r#""sigma_fine_px": Float(0.7), "sigma_coarse_px": Float({}), "border": Choice("{border}")"#,
                s1 + 0.5
            ),
            "image",
        ),
        6 => (
            "filter.log",
            format!(r#""sigma_px": Float({s1}), "border": Choice("{border}")"#),
            "image",
        ),
        7 => (
            "filter.scale",
            format!(r#""scale": Float({})"#, 3.0 * a - 1.0),
            "image",
        ),
        8 => (
            "filter.separable",
            format!(
                r#""row": Floats([0.25, 0.5, 0.25]), "col": Floats([0.1, 0.2, 0.4, 0.2, 0.1]), "border": Choice("{border}")"#
            ),
            "image",
        ),
        9 => (
            "filter.dense",
            format!(
                r#""width": Int(3), "height": Int(5), "weights": Floats([0.0, -1.0, 0.0, 0.5, 1.0, 0.5, -1.0, 5.0, -1.0, 0.5, 1.0, 0.5, 0.0, -1.0, 0.0]), "border": Choice("{border}")"#
            ),
            "image",
        ),
        10 => (
            "band",
            format!(
                r#""band": Choice("bandpass"), "op": Choice("{}"), "sigma_px": Float(1.0), "sigma_coarse_px": Float({}), "border": Choice("{border}")"#,
                if b > 0.5 { "keep" } else { "remove" },
                s1 + 0.5
            ),
            "image",
        ),
        11 => (
            "bilateral",
            format!(
                r#""sigma_spatial_px": Float({}), "sigma_color": Float(0.3), "sigma_normal": Float(0.3), "filter_color": Bool({})"#,
                0.8 + 2.0 * a,
                b > 0.5
            ),
            if b > 0.25 { "base" } else { "detail" },
        ),
        12 => ("normalize", String::new(), "image"),
        13 => (
            "brush",
            format!(
                r#""points": Points([{}]), "radius_px": Float({}), "feather_px": Float(3.0), "sigma_px": Float({s1}), "border": Choice("{border}")"#,
                pts(3),
                3.0 + 8.0 * b
            ),
            if b > 0.3 { "image" } else { "region" },
        ),
        14 => (
            "pen",
            format!(
                r#""points": Points([{}]), "closed": Bool({}), "width_px": Float({}), "taper_px": Float(4.0), "mode": Choice("{}")"#,
                if b > 0.5 { simple_pts(4) } else { pts(4) },
                b > 0.5,
                3.0 + 6.0 * a,
                ["integrable", "analytic", "distance_transform"][(b * 2.99) as usize]
            ),
            if a > 0.3 { "image" } else { "height" },
        ),
        15 => (
            "stamp",
            format!(
                r#""positions": Points([{}]), "angle_rad": Float({a}), "scale_x": Float(0.6), "scale_y": Float(0.8), "falloff_px": Float(2.0), "color": Bool({})"#,
                pts(3),
                b > 0.5
            ),
            "image",
        ),
        16 => ("relight", String::new(), "picture"),
        17 => ("curl", String::new(), "curl"),
        18 => (
            "combine.linear",
            format!(
                r#""alpha": Float({}), "replace_band": Choice("{}"), "sigma_px": Float({s1}), "border": Choice("{border}")"#,
                2.0 * a - 0.5,
                if b > 0.5 { "highpass" } else { "none" }
            ),
            "image",
        ),
        _ => (
            "combine.rotation",
            format!(
                r#""mode": Choice("{}")"#,
                ["blend", "rotate", "replace"][(b * 2.99) as usize]
            ),
            "image",
        ),
    };
    let second = match op {
        "stamp" => r#""stamp": Node(6, "image")"#,
        "combine.linear" | "combine.rotation" => r#""detail": Node(5, "image")"#,
        _ => "",
    };
    let inputs = if second.is_empty() {
        r#""image": Node(3, "image")"#.to_string()
    } else if op == "stamp" {
        format!(r#""image": Node(3, "image"), {second}"#)
    } else {
        format!(r#""base": Node(3, "image"), {second}"#)
    };
    (
        format!(
            r#"(id: 4, op: "{op}", pos: (0.0, 0.0), params: {{ {params} }}, inputs: {{ {inputs} }})"#
        ),
        port,
    )
}

fn graph_text(dir: &Path, node: &str, port: &str, masked: bool) -> String {
    let p = |n: &str| dir.join(n).display().to_string();
    let mask = if masked {
        r#"inputs: { "image": Node(1, "image"), "mask": Node(2, "mask") }"#
    } else {
        r#"inputs: { "image": Node(1, "image") }"#
    };
    format!(
        r#"(
    version: 1,
    next_id: 7,
    outputs: {{ "out": (node: 4, port: "{port}") }},
    nodes: [
        (id: 1, op: "load", pos: (0.0, 0.0), params: {{ "path": Path("{}") }}),
        (id: 2, op: "load_mask", pos: (0.0, 0.0), params: {{ "path": Path("{}") }}),
        (id: 3, op: "apply_mask", pos: (0.0, 0.0), {mask}),
        {node},
        (id: 5, op: "load", pos: (0.0, 0.0), params: {{ "path": Path("{}") }}),
        (id: 6, op: "load", pos: (0.0, 0.0), params: {{ "path": Path("{}") }}),
    ],
)"#,
        p("a.exr"),
        p("mask.png"),
        p("b.exr"),
        p("stamp.exr")
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn a_region_of_any_local_operator_equals_the_whole_images_crop(
        (w, h) in (20usize..90, 20usize..90),
        seed in any::<u64>(),
        k in 0usize..20,
        border in 0usize..3,
        masked in any::<bool>(),
        (a, b) in (0.0f64..1.0, 0.0f64..1.0),
        tile in prop_oneof![Just(16usize), Just(24), Just(48), Just(256)],
        (rx, ry, rw, rh) in (0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let opts = SaveOptions::default();
        save(&random_image(w, h, seed), &dir.path().join("a.exr"), &opts).unwrap();
        save(&random_image(w, h, seed ^ 0x55), &dir.path().join("b.exr"), &opts).unwrap();
        save(&random_image(12, 9, seed ^ 0xaa), &dir.path().join("stamp.exr"), &opts).unwrap();
        // A mask with hard and soft parts: 0, 1 and a ramp.
        let m = image::GrayImage::from_fn(w as u32, h as u32, |x, y| {
            image::Luma([match (x * 7 / w as u32 + y * 3 / h as u32) % 3 {
                0 => 0,
                1 => 255,
                _ => (x * 255 / w as u32) as u8,
            }])
        });
        m.save(dir.path().join("mask.png")).unwrap();
        let border = ["mirror", "clamp", "zero"][border];
        let (node, port) = op_node(k, border, w, h, a, b);
        let text = graph_text(dir.path(), &node, port, masked);
        let lg = LoadedGraph::from_text(&text, "region.ron", dir.path().to_path_buf())
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        let plan = Plan::new(&lg, &BTreeMap::new(), dir.path()).unwrap();
        let whole = Evaluator::default()
            .eval(&plan, &["out"], &EvalOptions::default())
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        let x = (rx * w as f64) as usize;
        let y = (ry * h as f64) as usize;
        let rect = Rect::new(x, y, 1 + (rw * (w - x) as f64) as usize, 1 + (rh * (h - y) as f64) as usize)
            .intersect(&Rect::full((w, h)));
        let r = Evaluator::default()
            .eval_region(&plan, "out", rect, &RegionOptions::tiles(tile), &EvalOptions::default())
            .unwrap_or_else(|e| panic!("{e}\n{text}"));
        prop_assert!(!r.tiles.is_empty(), "{} was not tiled", node);
        let want = crop(&whole.outputs["out"], rect);
        let d = super::region::max_diff(&want, &r.value);
        // Gradients here reach 1 (|p|, |q| ≤ 1 before filtering): the recursive Gaussian's
        // cut (σ ≥ 3) changes a pass by at most 2 · 3.5e-4 · max|g|.
        let recursive = [0, 2, 3, 4, 5, 6, 10, 13, 18].contains(&k) && (0.6 + 3.4 * a >= 2.5);
        let tol = match (port, recursive) {
            ("picture", _) => 1.0 / 255.0,
            (_, true) => 3e-3,
            _ => 2e-6,
        };
        prop_assert!(d <= tol, "{node}.{port} tile {tile} rect {rect} on {w}×{h}: {d} > {tol}");
    }
}

#[test]
fn a_tapered_stroke_across_tile_edges_evaluates_by_tiles_as_whole() {
    // A long taper (beyond the stroke's half width) on a path that crosses many 16-pixel tile
    // edges, in every mode: the tiled evaluation equals the whole one, so the halo the node
    // declares (`reach_px`, one definition) covers everything the stroke changes.
    for mode in ["integrable", "analytic", "distance_transform"] {
        for port in ["image", "height"] {
            let text = format!(
                r#"(
    version: 2,
    next_id: 3,
    outputs: {{ "out": (node: 2, port: "{port}") }},
    nodes: [
        (id: 1, op: "surface", params: {{ "shape": Choice("sphere"), "width": Int(96), "height": Int(80), "radius_px": Float(30.0) }}),
        (id: 2, op: "pen", params: {{ "paths": Paths([(points: [(5.0, 7.0), (40.0, 33.0), (61.0, 18.0), (90.0, 70.0)])]), "width_px": Float(7.0), "taper_px": Float(40.0), "mode": Choice("{mode}") }}, inputs: {{ "image": Node(1, "image") }}),
    ],
)"#
            );
            let lg = LoadedGraph::from_text(&text, "taper.ron", std::env::temp_dir())
                .unwrap_or_else(|e| panic!("{e}"));
            let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).unwrap();
            let whole = Evaluator::default()
                .eval(&plan, &["out"], &EvalOptions::default())
                .unwrap();
            let rect = Rect::full((96, 80));
            let r = Evaluator::default()
                .eval_region(
                    &plan,
                    "out",
                    rect,
                    &RegionOptions::tiles(16),
                    &EvalOptions::default(),
                )
                .unwrap();
            assert!(r.tiles.len() > 1, "{mode}: not tiled");
            let d = super::region::max_diff(&whole.outputs["out"], &r.value);
            assert!(d <= 2e-6, "{mode} {port}: tiles differ from whole by {d}");
        }
    }
}
