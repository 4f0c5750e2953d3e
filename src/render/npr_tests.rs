//! The inspection views on hand-computable surfaces built here from their analytic normals
//! (x right, y up, rows down; the sphere and cylinder bulge towards the viewer).

use super::super::{render, render_with, Light, Shading, View};
use crate::raster::srgb::linear_to_srgb;
use crate::render::{curvature_scale, mean_curvature, InspectParams};
use crate::RgbnImage;

/// `w × h` of albedo 0.5 with normals `f(x, y)` (pixel centre relative to the image centre,
/// y up).
fn surface(w: usize, h: usize, f: impl Fn(f32, f32) -> [f32; 3]) -> RgbnImage {
    let mut img = RgbnImage::flat(w, h, [0.5; 3]);
    let n = img.normal_mut();
    for r in 0..h {
        for c in 0..w {
            let x = c as f32 - (w as f32 - 1.0) / 2.0;
            let y = (h as f32 - 1.0) / 2.0 - r as f32;
            let v = f(x, y);
            for j in 0..3 {
                n[j][r * w + c] = v[j];
            }
        }
    }
    img
}

/// A sphere of radius `r` px (`sign` −1: a spherical dent), flat outside.
fn sphere(size: usize, r: f32, sign: f32) -> RgbnImage {
    surface(size, size, |x, y| {
        let q = (x * x + y * y) / (r * r);
        if q < 1.0 {
            [sign * x / r, sign * y / r, (1.0 - q).sqrt()]
        } else {
            [0.0, 0.0, 1.0]
        }
    })
}

/// A vertical cylinder of radius `r` px.
fn cylinder(w: usize, h: usize, r: f32) -> RgbnImage {
    surface(w, h, |x, _| {
        let q = (x / r).clamp(-1.0, 1.0);
        if q.abs() < 1.0 {
            [q, 0.0, (1.0 - q * q).sqrt()]
        } else {
            [0.0, 0.0, 1.0]
        }
    })
}

fn plane(n: [f32; 3]) -> RgbnImage {
    surface(40, 30, |_, _| n)
}

fn px(rgba: &[u8], w: usize, c: usize, r: usize) -> [u8; 4] {
    let i = (r * w + c) * 4;
    [rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3]]
}

fn with(f: impl FnOnce(&mut InspectParams)) -> InspectParams {
    let mut p = InspectParams::default();
    f(&mut p);
    p
}

#[test]
fn a_sphere_has_mean_curvature_one_over_its_radius() {
    for (r, sign) in [(20.0f32, 1.0f32), (45.0, 1.0), (30.0, -1.0)] {
        let img = sphere(128, r, sign);
        let hv = mean_curvature(&img);
        let mut checked = 0;
        for (i, h) in hv.iter().enumerate() {
            let x = (i % 128) as f32 - 63.5;
            let y = 63.5 - (i / 128) as f32;
            if (x * x + y * y).sqrt() < r - 3.0 {
                let want = sign / r;
                assert!(
                    (h - want).abs() < 0.03 * want.abs(),
                    "r {r}: H {h} vs {want}"
                );
                checked += 1;
            }
        }
        assert!(checked > 900, "{checked}");
    }
}

#[test]
fn a_cylinder_has_half_the_curvature_and_a_plane_none() {
    let r = 25.0;
    let img = cylinder(96, 40, r);
    let hv = mean_curvature(&img);
    for row in 1..39 {
        for c in 30..66 {
            let h = hv[row * 96 + c];
            assert!((h - 0.5 / r).abs() < 0.03 * 0.5 / r, "({c}, {row}): {h}");
        }
    }
    for n in [[0.0, 0.0, 1.0], [0.6, -0.48, 0.64]] {
        assert!(mean_curvature(&plane(n)).iter().all(|h| *h == 0.0));
    }
}

#[test]
fn curvature_at_the_border_and_at_the_mask_edge_is_one_sided() {
    // nx = x/r everywhere (a cylinder with no rim in view): the one-sided differences at the
    // image border and next to a masked-out column still give 1/(2r).
    let r = 100.0;
    let mut img = surface(20, 6, |x, _| [x / r, 0.0, (1.0 - (x / r) * (x / r)).sqrt()]);
    let mut mask = vec![1.0f32; 120];
    for row in 0..6 {
        mask[row * 20 + 10] = 0.2;
    }
    img.set_mask(Some(mask)).unwrap();
    let hv = mean_curvature(&img);
    for (i, h) in hv.iter().enumerate() {
        if i % 20 != 10 {
            assert!((h - 0.5 / r).abs() < 1e-4, "pixel {i}: {h}");
        }
    }
    // A lone pixel has no neighbour: 0.
    let mut one = RgbnImage::flat(1, 1, [0.5; 3]);
    one.normal_mut()[0][0] = 0.6;
    one.normal_mut()[2][0] = 0.8;
    assert_eq!(mean_curvature(&one), vec![0.0]);
}

#[test]
fn the_curvature_colour_map_ends_are_red_white_and_blue() {
    let r = 30.0;
    let s = Shading::default();
    let centre = |img: &RgbnImage, scale: f64| {
        let p = with(|p| p.curvature_scale = scale);
        px(
            &render_with(img, View::Curvature, &s, &p).unwrap(),
            96,
            48,
            48,
        )
    };
    // H·scale = ±1 (and beyond: saturated), ½, 0.
    assert_eq!(centre(&sphere(96, r, 1.0), f64::from(r)), [255, 0, 0, 255]);
    assert_eq!(
        centre(&sphere(96, r, 1.0), 10.0 * f64::from(r)),
        [255, 0, 0, 255]
    );
    assert_eq!(centre(&sphere(96, r, -1.0), f64::from(r)), [0, 0, 255, 255]);
    assert_eq!(
        centre(&sphere(96, r, 1.0), f64::from(r) / 2.0),
        [255, 128, 128, 255]
    );
    assert_eq!(
        centre(&sphere(96, r, -1.0), f64::from(r) / 2.0),
        [128, 128, 255, 255]
    );
    let flat = render(&plane([0.0, 0.0, 1.0]), View::Curvature, &s).unwrap();
    assert!(flat.chunks(4).all(|p| p == [255, 255, 255, 255]));
}

#[test]
fn the_automatic_curvature_scale_is_the_99th_percentile() {
    // Only the sphere's interior is covered: every covered pixel has H = 1/r.
    let r = 30.0;
    let mut img = sphere(96, r, 1.0);
    let mask: Vec<f32> = (0..96 * 96)
        .map(|i| {
            let (x, y) = ((i % 96) as f32 - 47.5, 47.5 - (i / 96) as f32);
            if (x * x + y * y).sqrt() < r - 1.0 {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    img.set_mask(Some(mask)).unwrap();
    let s = curvature_scale(&img, 0.0);
    assert!((s - r).abs() < 0.01 * r, "{s}");
    assert_eq!(curvature_scale(&img, 7.0), 7.0);
    assert_eq!(curvature_scale(&plane([0.0, 0.0, 1.0]), 0.0), 1.0);
    // Automatic: the interior is full red; masked-out pixels are transparent.
    let out = render(&img, View::Curvature, &Shading::default()).unwrap();
    assert_eq!(px(&out, 96, 48, 48), [255, 0, 0, 255]);
    assert_eq!(px(&out, 96, 0, 0)[3], 0);
}

#[test]
fn exaggerated_shading_of_a_plane_is_constant() {
    let s = Shading {
        lights: vec![Light::white([-0.5, 0.6, 0.8])],
        ..Shading::default()
    };
    for n in [[0.0, 0.0, 1.0], [0.3, 0.2, 0.932_737_9]] {
        let out = render(&plane(n), View::Exaggerated, &s).unwrap();
        let first = &out[..4];
        assert!(out.chunks(4).all(|p| p == first), "{n:?}");
        // E = ½ + ½·k_K·clamp(a n·l): the base term alone, hand-computed for the default
        // parameters (4 scales, σ₀ … σ₄ = 0.5, 1, 2, 4, 8, equal weights).
        let p = InspectParams::default();
        let w: Vec<f64> = (0..5)
            .map(|i| (p.exag_sigma * 2f64.powi(i - 1)).powf(-p.exag_detail))
            .collect();
        let kb = w[4] / w.iter().sum::<f64>();
        let l = [-0.5f64, 0.6, 0.8];
        let ll = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        let ndl = (f64::from(n[0]) * l[0] + f64::from(n[1]) * l[1] + f64::from(n[2]) * l[2]) / ll;
        let e = 0.5 + 0.5 * kb * (p.exag_clamp * ndl).clamp(-1.0, 1.0);
        let want = (f64::from(linear_to_srgb(e as f32)) * 255.0).round() as i32;
        assert!(
            (i32::from(first[0]) - want).abs() <= 1,
            "{first:?} vs {want}"
        );
    }
}

#[test]
fn exaggerated_shading_lights_the_side_facing_the_light() {
    let img = sphere(96, 35.0, 1.0);
    let s = Shading {
        lights: vec![Light::white([-1.0, 0.0, 0.3])],
        ..Shading::default()
    };
    let out = render(&img, View::Exaggerated, &s).unwrap();
    let lum = |c: usize| u32::from(px(&out, 96, c, 48)[0]);
    assert!(lum(48 - 20) > lum(48 + 20) + 20, "{} {}", lum(28), lum(68));
}

#[test]
fn radiance_scaling_with_strength_zero_is_relit_and_brightens_convex_places() {
    let s = Shading::default();
    for sign in [1.0, -1.0] {
        let img = sphere(80, 30.0, sign);
        let relit = render(&img, View::Relit, &s).unwrap();
        let zero = with(|p| p.radiance_alpha = 0.0);
        assert_eq!(
            render_with(&img, View::RadianceScaling, &s, &zero).unwrap(),
            relit
        );
        // H·scale = ±1 at the centre: × 2^±tanh 1 = × 1.70 or × 0.59 (linear).
        let p = with(|p| p.radiance_scale = 30.0);
        let scaled = render_with(&img, View::RadianceScaling, &s, &p).unwrap();
        // Centre of the sphere: convex → brighter, concave → darker.
        let (a, b) = (px(&scaled, 80, 40, 40)[1], px(&relit, 80, 40, 40)[1]);
        if sign > 0.0 {
            assert!(a > b + 10, "{a} vs {b}");
        } else {
            assert!(a + 10 < b, "{a} vs {b}");
        }
        // Flat surroundings are unchanged.
        assert_eq!(px(&scaled, 80, 2, 2), px(&relit, 80, 2, 2));
    }
}

#[test]
fn toon_shades_a_plane_in_one_flat_band() {
    // Light at 50° from the normal: d = cos 50° = 0.643, 4 levels → band ⌊2.57⌋ = 2 →
    // q = 2/3.
    let th = 50f32.to_radians();
    let s = Shading {
        lights: vec![Light::white([th.sin(), 0.0, th.cos()])],
        ambient: 0.1,
        ..Shading::default()
    };
    let out = render(&plane([0.0, 0.0, 1.0]), View::Toon, &s).unwrap();
    let want = (linear_to_srgb(0.5 * (0.1 + 2.0 / 3.0)) * 255.0).round() as i32;
    for p in out.chunks(4) {
        assert!((i32::from(p[0]) - want).abs() <= 1, "{p:?} vs {want}");
        assert_eq!(p, &out[..4]);
    }
}

#[test]
fn toon_outlines_the_silhouette_and_quantises_a_sphere() {
    let img = sphere(96, 40.0, 1.0);
    let s = Shading {
        lights: vec![Light::white([0.0, 0.0, 1.0])],
        ambient: 0.0,
        ..Shading::default()
    };
    let p = with(|p| p.toon_levels = 3);
    let out = render_with(&img, View::Toon, &s, &p).unwrap();
    // Near the rim n_z < 0.25: black; the centre n·l ≈ 1: the top band (q = 1).
    assert_eq!(px(&out, 96, 48 + 39, 48)[..3], [0, 0, 0]);
    let top = (linear_to_srgb(0.5) * 255.0).round() as u8;
    assert!(px(&out, 96, 48, 48)[0].abs_diff(top) <= 1);
    // Three bands plus the outline: at most 4 distinct colours on the sphere.
    let mut colours: Vec<[u8; 4]> = out.chunks(4).map(|p| [p[0], p[1], p[2], p[3]]).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() <= 4, "{colours:?}");
}

#[test]
fn a_plane_has_no_lines_and_a_ridge_has_one() {
    let s = Shading::default();
    for n in [[0.0, 0.0, 1.0], [0.5, 0.1, 0.860_232_5]] {
        let out = render(&plane(n), View::Lines, &s).unwrap();
        assert!(out.chunks(4).all(|p| p == [255, 255, 255, 255]), "{n:?}");
    }
    // A Gaussian ridge z = A·exp(−x²/2σ²) along y: H peaks on its crest (x = 0) at
    // A/(2σ²) = 0.125/px; far from it the surface is flat.
    let (a, sg) = (4.0f32, 4.0f32);
    let img = surface(61, 20, |x, _| {
        let dz = -a * x / (sg * sg) * (-x * x / (2.0 * sg * sg)).exp();
        let l = (dz * dz + 1.0).sqrt();
        [-dz / l, 0.0, 1.0 / l]
    });
    let p = with(|p| {
        p.lines_sigma = 0.0;
        p.lines_threshold = 0.05;
    });
    let out = render_with(&img, View::Lines, &s, &p).unwrap();
    for row in 0..20 {
        assert_eq!(px(&out, 61, 30, row), [0, 0, 0, 255], "crest, row {row}");
        for c in [0, 1, 2, 3, 57, 58, 59, 60] {
            assert_eq!(px(&out, 61, c, row), [255, 255, 255, 255], "({c}, {row})");
        }
    }
}

#[test]
fn a_sphere_has_contour_lines_at_its_rim_only() {
    let img = sphere(96, 40.0, 1.0);
    let out = render(&img, View::Lines, &Shading::default()).unwrap();
    assert_eq!(px(&out, 96, 48 + 39, 48)[..3], [0, 0, 0]);
    for c in 30..66 {
        assert_eq!(px(&out, 96, c, 48), [255, 255, 255, 255], "column {c}");
    }
}

#[test]
fn bad_view_parameters_are_errors_naming_the_parameter() {
    let img = plane([0.0, 0.0, 1.0]);
    let s = Shading::default();
    for (view, p, name) in [
        (View::Toon, with(|p| p.toon_levels = 0), "toon_levels"),
        (
            View::Exaggerated,
            with(|p| p.exag_sigma = f64::NAN),
            "exag_sigma",
        ),
        (
            View::Curvature,
            with(|p| p.curvature_scale = -1.0),
            "curvature_scale",
        ),
        (
            View::Lines,
            with(|p| p.lines_contour = 2.0),
            "lines_contour",
        ),
    ] {
        let e = render_with(&img, view, &s, &p).unwrap_err().to_string();
        assert!(e.contains(name) && !e.contains('\n'), "{e}");
    }
    let e = InspectParams::from_assignments(&["toon_lvls=3"])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("toon_lvls") && e.contains("did you mean \"toon_levels\""),
        "{e}"
    );
    let e = InspectParams::from_assignments(&["lines_sigma=wide"])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("lines_sigma") && e.contains("not a number"),
        "{e}"
    );
    let p = InspectParams::from_assignments(&["toon_levels=3", "curvature_scale=2.5"]).unwrap();
    assert_eq!((p.toon_levels, p.curvature_scale), (3, 2.5));
}

#[test]
fn every_view_has_a_name_that_parses_and_its_parameters_carry_its_prefix() {
    for v in View::ALL {
        assert_eq!(v.name().parse::<View>(), Ok(*v));
        for i in InspectParams::describe(*v) {
            assert_eq!(InspectParams::view_of(i.name), Some(*v));
            assert!(!i.meta.doc.is_empty());
        }
    }
    // Every parameter belongs to exactly one view.
    for i in crate::params::describe::<InspectParams>() {
        assert!(InspectParams::view_of(i.name).is_some(), "{}", i.name);
    }
    assert!("toonn"
        .parse::<View>()
        .unwrap_err()
        .contains("did you mean \"toon\""));
}
