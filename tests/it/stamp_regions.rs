//! Stamp masks and regions (issue 13, item 3; Pereira & Velho Figs. 4 and 12): a stamp's mask
//! restricts its relief (the background of a cut-out piece is not stamped), a region on the
//! target restricts placements — both integrably (F of the result at rounding level), checked
//! against the unrestricted stamp and against the non-integrable alternative.

use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use rgbn::ops::stamp::{stamp_image, StampParams};
use rgbn::raster::gradient::{normal_of_gradient, GradientField};
use rgbn::raster::integrate::{integrate_normals, non_integrable_fraction, IntegrateParams};
use rgbn::raster::sample::Surface;
use rgbn::RgbnImage;
use std::collections::BTreeMap;
use std::path::Path;

const N: usize = 41;

/// A 41² stamp: a Gaussian bump (amplitude 4 px, σ 4 px) inside a disc of radius 14.5 px —
/// its mask — and a steep tilted "background" (slope 0.5) outside it.
fn leaf(with_mask: bool) -> RgbnImage {
    let (bump, _) = Surface::Gaussians {
        bumps: vec![[0.0, 0.0, 4.0, 4.0]],
    }
    .render_sampled(N, N);
    let c = (N / 2) as f32;
    let inside = |i: usize| {
        let (x, r) = ((i % N) as f32, (i / N) as f32);
        ((x - c).powi(2) + (r - c).powi(2)).sqrt() <= 14.5
    };
    let mut img = bump.clone();
    let tilt = normal_of_gradient(0.5, -0.2);
    let [nx, ny, nz] = img.normal_mut();
    for i in 0..N * N {
        if !inside(i) {
            (nx[i], ny[i], nz[i]) = (tilt[0], tilt[1], tilt[2]);
        }
    }
    if with_mask {
        let m = (0..N * N).map(|i| f32::from(u8::from(inside(i)))).collect();
        img.set_mask(Some(m)).unwrap();
    }
    img
}

fn flat(w: usize, h: usize) -> RgbnImage {
    RgbnImage::flat(w, h, [0.5; 3])
}

fn params(positions: Vec<[f64; 2]>) -> StampParams {
    StampParams {
        positions,
        falloff_px: 3.0,
        ..StampParams::default()
    }
}

fn max_tilt_where(img: &RgbnImage, keep: impl Fn(usize, usize) -> bool) -> f32 {
    let w = img.width();
    (0..w * img.height())
        .filter(|&i| keep(i % w, i / w))
        .map(|i| 1.0 - img.normal()[2][i])
        .fold(0.0, f32::max)
}

#[test]
fn a_stamp_mask_restricts_the_relief_integrably() {
    let target = flat(96, 96);
    let p = params(vec![[48.0, 48.0]]);
    let (masked, _) = stamp_image(&target, &leaf(true), None, &p).unwrap();
    let (unmasked, _) = stamp_image(&target, &leaf(false), None, &p).unwrap();
    let dist = |x: usize, r: usize| ((x as f32 - 48.0).powi(2) + (r as f32 - 48.0).powi(2)).sqrt();
    // Outside the mask's disc (+1 px for the gradient stencil) the target is untouched ...
    let outside = max_tilt_where(&masked, |x, r| dist(x, r) > 16.0);
    assert!(outside < 1e-6, "{outside}");
    // ... while without the mask the tilted background is stamped there (the test can fail).
    let bg = max_tilt_where(&unmasked, |x, r| dist(x, r) > 16.0 && dist(x, r) < 19.0);
    assert!(bg > 0.05, "{bg}");
    // Inside: the bump. Its height (integrated from the result) at the centre over the flat
    // surroundings: the stamp's centre sample (the mean of its four corners, 4·e^(−0.5/32) =
    // 3.938 px), less the level on the feather ring (the bump at r ≈ 10.5–13.5 px, weighted
    // towards the edge: ≈ 0.05 px), less the [1 2 1]/4 blur of the placed height at the crest
    // (¼ of its Laplacian −2A/σ² = −0.5 px⁻¹: 0.125 px): ≈ 3.76 px.
    let (z, _) = integrate_normals(&masked, &IntegrateParams::default()).unwrap();
    let rise = z.at(48, 48) - z.at(5, 5);
    assert!((rise - 3.76).abs() < 0.1, "{rise}");
    // Exactly a surface: the relief is the gradient of a (feathered) height.
    let f = non_integrable_fraction(&GradientField::from_normals(&masked), None).unwrap();
    assert!(f < 1e-3, "F = {f}");
}

#[test]
fn a_region_restricts_placements_integrably() {
    let target = flat(96, 96);
    let (bump, _) = Surface::Gaussians {
        bumps: vec![[0.0, 0.0, 3.0, 4.0]],
    }
    .render_sampled(33, 33);
    let p = params(vec![[24.0, 48.0], [48.0, 48.0], [72.0, 48.0]]);
    // The left half (columns < 48), a hard edge.
    let region: Vec<f32> = (0..96 * 96)
        .map(|i| f32::from(u8::from(i % 96 < 48)))
        .collect();
    let (out, _) = stamp_image(&target, &bump, Some(&region), &p).unwrap();
    let (all, _) = stamp_image(&target, &bump, None, &p).unwrap();
    // Right of the region (beyond the 1-px stencil of the height's gradient): untouched.
    let right = max_tilt_where(&out, |x, _| x >= 50);
    assert!(right < 1e-6, "{right}");
    assert!(max_tilt_where(&all, |x, _| x >= 66) > 0.05);
    // The left placement, wholly inside, is as without a region.
    for r in 30..66 {
        for x in 8..45 {
            let i = r * 96 + x;
            for k in 0..3 {
                let (a, b) = (out.normal()[k][i], all.normal()[k][i]);
                assert!((a - b).abs() < 1e-6, "({x}, {r}): {a} vs {b}");
            }
        }
    }
    // Integrable: the relief is ∇(m·H). Masking the gradients instead (m·∇H) is not.
    let g = GradientField::from_normals(&out);
    let f = non_integrable_fraction(&g, None).unwrap();
    assert!(f < 1e-3, "F = {f}");
    let mut naive = GradientField::from_normals(&all);
    for (i, &m) in region.iter().enumerate() {
        naive.p[i] *= m;
        naive.q[i] *= m;
    }
    let f_naive = non_integrable_fraction(&naive, None).unwrap();
    assert!(f_naive > 10.0 * f.max(1e-4), "{f_naive} vs {f}");
}

const GRAPH: &str = r#"(
    version: 1,
    next_id: 5,
    outputs: {
        "image": (node: 4, port: "image"),
    },
    nodes: [
        (id: 1, op: "surface", params: { "shape": Choice("sinusoid"), "width": Int(96), "height": Int(64), "amplitude_px": Float(0.0) }),
        (id: 2, op: "surface", params: { "shape": Choice("gaussians"), "width": Int(33), "height": Int(33) }),
        (id: 3, op: "brush", params: { "points": Points([(10.0, 32.0), (40.0, 32.0)]), "radius_px": Float(12.0), "feather_px": Float(4.0) }, inputs: { "image": Node(1, "image") }),
        (id: 4, op: "stamp", params: { "positions": Points([(25.0, 32.0), (70.0, 32.0)]) }, inputs: { "image": Node(1, "image"), "stamp": Node(2, "image"), "region": Node(3, "region") }),
    ],
)"#;

#[test]
fn the_stamp_node_takes_a_region_and_refuses_one_of_another_size() {
    let eval = |text: &str| {
        let lg = LoadedGraph::from_text(text, "regions.ron", Path::new(".").to_path_buf()).unwrap();
        let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).unwrap();
        Evaluator::default()
            .eval(&plan, &[], &EvalOptions::default())
            .map_err(|e| e.to_string())
    };
    let r = eval(GRAPH).unwrap();
    let Value::Rgbn(img) = &r.outputs["image"] else {
        panic!()
    };
    // The stroke's region covers the first placement (x 25), not the second (x 70).
    assert!(max_tilt_where(img, |x, _| (14..36).contains(&x)) > 0.01);
    assert!(max_tilt_where(img, |x, _| x >= 60) < 1e-6);
    // A region of another size: one line naming the node and the port.
    let bad = GRAPH
        .replace(r#""image": Node(1, "image"), "stamp""#, r#""image": Node(5, "image"), "stamp""#)
        .replace(
            "next_id: 5,",
            "next_id: 6,",
        )
        .replace(
            "    ],\n)",
            "        (id: 5, op: \"surface\", params: { \"shape\": Choice(\"sphere\"), \"width\": Int(80), \"height\": Int(64) }),\n    ],\n)",
        );
    let e = eval(&bad).unwrap_err();
    assert!(
        !e.contains('\n') && e.contains("region") && e.contains("node 4"),
        "{e}"
    );
}
