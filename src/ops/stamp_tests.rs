//! Tests of `ops/stamp.rs`.

use super::*;
use crate::raster::sample::Surface;

fn two_bumps() -> Surface {
    Surface::Gaussians {
        bumps: vec![[6.0, 3.0, 4.0, 5.0], [-7.0, -5.0, -2.0, 3.5]],
    }
}

fn stamp_plane(s: &Surface, n: usize) -> Plane {
    let c = (n - 1) as f64 / 2.0;
    Plane::from_fn(n, n, |i, j| s.height(i as f64 - c, c - j as f64) as f32)
}

#[test]
fn transform_gradient_is_the_inverse_transpose() {
    let p = StampParams {
        angle_rad: 0.7,
        scale_x: 1.5,
        scale_y: 0.6,
        shear: 0.3,
        ..StampParams::default()
    };
    let a = p.affine();
    // Linear height h(s) = g·s; H(P) = g·A⁻¹P, whose gradient we check by differencing.
    let g = [0.4, -1.3];
    let ainv = inverse(a);
    let hh = |x: f64, y: f64| {
        let s = [
            ainv[0][0] * x + ainv[0][1] * y,
            ainv[1][0] * x + ainv[1][1] * y,
        ];
        g[0] * s[0] + g[1] * s[1]
    };
    let want = [hh(1.0, 0.0) - hh(0.0, 0.0), hh(0.0, 1.0) - hh(0.0, 0.0)];
    let got = transform_gradient(a, g).unwrap();
    assert!((got[0] - want[0]).abs() < 1e-12 && (got[1] - want[1]).abs() < 1e-12);
    assert!(transform_gradient([[1.0, 2.0], [2.0, 4.0]], g).is_none());
}

#[test]
fn rotation_by_90_degrees_equals_differentiating_the_rotated_height() {
    let n = 33;
    let prepared = prepare_stamp_height(&stamp_plane(&two_bumps(), n), 4.0);
    let p = StampParams {
        positions: vec![[40.0, 40.0]],
        angle_rad: f64::from(std::f32::consts::FRAC_PI_2),
        ..StampParams::default()
    };
    let got = stamp_gradients(80, 80, &prepared, &p).unwrap();
    // Rotated height by index permutation: P − t = (dx, dy) = R90 (u, v) = (−v, u), so
    // u = dy = 40 − row, v = −dx = 40 − x; i = u + 16, j = 16 − v.
    let rotated = Plane::from_fn(80, 80, |x, r| {
        let (i, j) = (56 - r as isize, x as isize - 24);
        if (0..33).contains(&i) && (0..33).contains(&j) {
            prepared.at(i as usize, j as usize)
        } else {
            0.0
        }
    });
    let want = GradientField::of_height(&rotated).0;
    let err = got
        .p
        .iter()
        .zip(&want.p)
        .chain(got.q.iter().zip(&want.q))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(err < 1e-5, "{err}");
    // Counter-clockwise on screen: the positive bump at stamp (u, v) = (6, 3) lands at
    // P − t = (−3, 6), i.e. x = 37, row = 34.
    assert!(rotated.at(37, 34) > 3.5, "{}", rotated.at(37, 34));
    assert!(got.relative_rms_curl(None) < 1e-6);
}

#[test]
fn affine_stamp_gradient_is_a_inverse_transpose_of_the_stamp_gradient() {
    let surf = two_bumps();
    let n = 65;
    let prepared = prepare_stamp_height(&stamp_plane(&surf, n), 6.0);
    let size = 160;
    // Tolerances: bilinear sampling of the stamp height and the [1 2 1]/4 blur of
    // `GradientField::of_height` (≈ ¼ Δh per axis); magnified stamps show the facets.
    for (angle_rad, scale, shear, tol) in [
        (0.5f32, [1.5f32, 0.8f32], 0.2f32, 0.06),
        (0.0, [2.0, 2.0], 0.0, 0.08),
        (-1.2, [1.0, -1.0], 0.0, 0.06),
        (0.3, [0.7, 0.7], 0.0, 0.06),
    ] {
        let p = StampParams {
            positions: vec![[80.0, 80.0]],
            angle_rad: f64::from(angle_rad),
            scale_x: f64::from(scale[0]),
            scale_y: f64::from(scale[1]),
            shear: f64::from(shear),
            ..StampParams::default()
        };
        let got = stamp_gradients(size, size, &prepared, &p).unwrap();
        let a = p.affine();
        let ainv = inverse(a);
        let analytic = |x: f64, r: f64| {
            let (dx, dy) = (x - 80.0, 80.0 - r);
            let s = [
                ainv[0][0] * dx + ainv[0][1] * dy,
                ainv[1][0] * dx + ainv[1][1] * dy,
            ];
            let g = surf.gradient(s[0], s[1]).unwrap_or([0.0, 0.0]);
            transform_gradient(a, g).unwrap_or([0.0, 0.0])
        };
        let want = crate::ops::geom::sample_gradient_centres(size, size, analytic);
        let (mut e2, mut g2) = (0.0f64, 0.0f64);
        for i in 0..size * size {
            e2 += f64::from(got.p[i] - want.p[i]).powi(2) + f64::from(got.q[i] - want.q[i]).powi(2);
            g2 += f64::from(want.p[i]).powi(2) + f64::from(want.q[i]).powi(2);
        }
        let rel = (e2 / g2).sqrt();
        println!("stamp A⁻ᵀ check angle {angle_rad} scale {scale:?} shear {shear}: relative RMS error {rel:.3e}");
        assert!(rel < tol, "{rel}");
        assert!(got.relative_rms_curl(None) < 1e-6);
    }
    // Scaling by s divides gradients by s.
    let g1 = stamp_gradients(
        size,
        size,
        &prepared,
        &StampParams {
            positions: vec![[80.0, 80.0]],
            ..StampParams::default()
        },
    )
    .unwrap();
    let g2 = stamp_gradients(
        size,
        size,
        &prepared,
        &StampParams {
            positions: vec![[80.0, 80.0]],
            scale_x: 2.0,
            scale_y: 2.0,
            ..StampParams::default()
        },
    )
    .unwrap();
    let max = |g: &GradientField| g.p.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let ratio = max(&g2) / max(&g1);
    println!("stamp scale 2: max |p| ratio {ratio:.4}");
    assert!((ratio - 0.5).abs() < 0.02, "{ratio}");
}

#[test]
fn stamp_image_from_normals_is_integrable_and_composites_colour() {
    let (stamp, _) = two_bumps().render(40, 40);
    let mut stamp = stamp;
    stamp
        .set_color([vec![1.0; 1600], vec![0.0; 1600], vec![0.0; 1600]])
        .unwrap();
    // Integrable target.
    let (target, _) = Surface::gaussians_for(128).render(128, 128);
    let p = StampParams {
        positions: vec![[40.0, 40.0], [90.0, 80.0]],
        angle_rad: 0.4,
        scale_x: 1.3,
        scale_y: 1.3,
        ..StampParams::default()
    };
    let (out, rep) = stamp_image(&target, &stamp, None, &p).unwrap();
    println!("stamp_image: {rep:?}");
    assert!(rep.curl_stamp.relative < 1e-6, "{rep:?}");
    let before = GradientField::from_normals(&target).relative_rms_curl(None);
    assert!(
        rep.curl_after.relative <= before + 1e-3,
        "{rep:?} vs {before}"
    );
    assert!((out.color_at(40, 40)[0] - 1.0).abs() < 1e-5 && out.color_at(40, 40)[1] < 1e-5);
    assert_eq!(out.color_at(5, 120), target.color_at(5, 120));
    // The stamped relief appears: normals differ near the placements, not far away.
    assert_ne!(out.normal_at(44, 40), target.normal_at(44, 40));
    assert_eq!(out.normal_at(5, 120), target.normal_at(5, 120));
}

#[test]
fn extract_stamp_crops_and_high_passes() {
    let (img, _) = Surface::Paraboloid { curvature: 0.01 }.render(64, 64);
    let s = extract_stamp(&img, 10, 20, 16, 12, Some(2.0)).unwrap();
    assert_eq!((s.width(), s.height()), (16, 12));
    // A paraboloid's gradient is linear: the high-pass removes it (except near the border).
    let g = GradientField::from_normals(&s);
    assert!(g.p[6 * 16 + 8].abs() < 1e-3 && g.q[6 * 16 + 8].abs() < 1e-3);
    let raw = extract_stamp(&img, 10, 20, 16, 12, None).unwrap();
    assert_eq!(raw.normal_at(0, 0), img.normal_at(10, 20));
    assert!(extract_stamp(&img, 60, 0, 16, 12, None)
        .unwrap_err()
        .to_string()
        .contains("inside"));
}

#[test]
fn real_data_stamp_from_rosewood_is_integrable() {
    let Some(img) = crate::ops::geom::rosewood_crop(256) else {
        return;
    };
    let stamp = extract_stamp(&img, 40, 60, 48, 48, Some(6.0)).unwrap();
    let target = RgbnImage::flat(160, 160, [0.5; 3]);
    let p = StampParams {
        positions: vec![[50.0, 50.0], [110.0, 100.0]],
        angle_rad: 0.8,
        scale_x: 1.2,
        scale_y: 0.9,
        falloff_px: 6.0,
        ..StampParams::default()
    };
    let (out, rep) = stamp_image(&target, &stamp, None, &p).unwrap();
    let raw = GradientField::from_normals(&stamp).curl_stats(None);
    println!(
        "rosewood stamp: stamp's own curl {:.3e} (rms slope {:.3e}) → stamped {:.3e} (rms slope {:.3e})",
        raw.relative, raw.rms_gradient, rep.curl_after.relative, rep.curl_after.rms_gradient
    );
    assert!(rep.curl_after.relative < 1e-5, "{rep:?}");
    assert!(rep.curl_after.rms_gradient > 0.05 * raw.rms_gradient);
    assert!(out.validate().is_clean());
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
    #[test]
    fn any_valid_affine_gives_a_curl_free_stamp(
        angle in -4.0f32..4.0, sx in 0.3f32..3.0, sy in -3.0f32..-0.3, shear in -1.0f32..1.0,
        x in 0.0f32..96.0, r in 0.0f32..96.0
    ) {
        let prepared = prepare_stamp_height(&stamp_plane(&two_bumps(), 25), 3.0);
        let p = StampParams {
            positions: vec![[f64::from(x), f64::from(r)]],
            angle_rad: f64::from(angle),
            scale_x: f64::from(sx),
            scale_y: f64::from(sy),
            shear: f64::from(shear),
            ..StampParams::default()
        };
        let g = stamp_gradients(96, 96, &prepared, &p).unwrap();
        proptest::prop_assert!(g.relative_rms_curl(None) < 1e-5);
        proptest::prop_assert!(g.p.iter().chain(&g.q).all(|v| v.is_finite()));
    }
}

#[test]
fn bad_params_are_refused() {
    let ok = StampParams::default();
    for (p, needle) in [
        (
            StampParams {
                scale_x: 0.0,
                ..ok.clone()
            },
            "zero area",
        ),
        (
            StampParams {
                scale_x: f64::NAN,
                ..ok.clone()
            },
            "scale",
        ),
        (
            StampParams {
                positions: vec![],
                ..ok.clone()
            },
            "positions",
        ),
        (
            StampParams {
                falloff_px: -1.0,
                ..ok.clone()
            },
            "falloff_px",
        ),
        (
            StampParams {
                opacity: 2.0,
                ..ok.clone()
            },
            "[0, 1]",
        ),
    ] {
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    }
    let tiny = RgbnImage::flat(1, 1, [0.0; 3]);
    let e = stamp_image(&RgbnImage::flat(8, 8, [0.0; 3]), &tiny, None, &ok)
        .unwrap_err()
        .to_string();
    assert!(e.contains("stamp"), "{e}");
}
