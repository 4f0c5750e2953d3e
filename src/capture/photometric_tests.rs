//! Tests of [`super`]: synthetic renders with exact normals.

use super::*;
use crate::capture::linalg::angle_deg;
use crate::raster::sample::Surface;

/// Renders Lambertian photos of an RGBN (albedo × intensity × max(0, n·l)).
/// Lambertian photos of `img` (`k = 1` of [`render_minnaert`]).
fn render(img: &RgbnImage, lights: &Lights) -> PhotoStack {
    render_minnaert(img, lights, 1.0)
}

fn ring_lights(m: usize, tilt_deg: f32) -> Vec<[f32; 3]> {
    let t = tilt_deg.to_radians();
    (0..m)
        .map(|j| {
            let a = std::f32::consts::TAU * j as f32 / m as f32;
            [t.sin() * a.cos(), t.sin() * a.sin(), t.cos()]
        })
        .collect()
}

fn coloured(mut img: RgbnImage) -> RgbnImage {
    let (w, h) = (img.width(), img.height());
    let col = [0.7f32, 0.4, 0.2].map(|base| {
        (0..w * h)
            .map(|i| base * (0.5 + 0.5 * ((i % w) as f32 / w as f32)) + 0.05 * ((i / w) % 3) as f32)
            .collect()
    });
    img.set_color(col).unwrap();
    img
}

fn max_angle_deg(a: &RgbnImage, b: &RgbnImage, sel: &[f32]) -> f64 {
    (0..a.len())
        .filter(|&i| sel[i] >= 0.5)
        .map(|i| {
            let x = a.normal_at(i % a.width(), i / a.width());
            let y = b.normal_at(i % b.width(), i / b.width());
            angle_deg(x, y)
        })
        .fold(0.0, f64::max)
}

#[test]
fn least_squares_is_exact_on_lambertian_renders_without_shadows() {
    // Mild dome + near-frontal lights: every pixel is lit by every light.
    let (img, _) = Surface::Paraboloid { curvature: 0.004 }.render(48, 40);
    let img = coloured(img);
    let lights = Lights {
        directions: ring_lights(6, 25.0),
        intensities: Some(vec![
            [1.0, 0.9, 0.8],
            [1.2, 1.1, 1.0],
            [0.7, 0.8, 0.9],
            [1.0, 1.0, 1.0],
            [0.9, 1.3, 1.1],
            [1.1, 1.0, 0.6],
        ]),
    };
    let stack = render(&img, &lights);
    for method in [PsMethod::LeastSquares, PsMethod::Trimmed] {
        let params = PhotometricParams {
            method,
            ..Default::default()
        };
        let (out, rep) = photometric_stereo(&stack, &lights, None, &params).unwrap();
        assert_eq!(rep.solved, 48 * 40, "{rep:?}");
        let all = vec![1.0; 48 * 40];
        let e = max_angle_deg(&out, &img, &all);
        assert!(e < 0.01, "{method:?}: {e}°");
        for c in 0..3 {
            for (a, b) in out.color()[c].iter().zip(&img.color()[c]) {
                assert!((a - b).abs() < 1e-4, "{method:?} albedo {a} vs {b}");
            }
        }
    }
}

#[test]
fn trimming_removes_attached_shadows_and_highlights() {
    // A sphere lit from steep directions: many pixels see some lights from behind, and one
    // light per pixel gets a fake specular spike.
    let (img, _) = Surface::Sphere { radius_px: 30.0 }.render(64, 64);
    let img = coloured(img);
    let lights = Lights {
        directions: ring_lights(12, 50.0)
            .into_iter()
            .chain([[0.0, 0.0, 1.0]])
            .collect(),
        intensities: None,
    };
    let mut stack = render(&img, &lights);
    // Specular spike: add 0.6 to the light closest to the mirror direction of the view.
    for i in 0..64 * 64 {
        let nn = img.normal_at(i % 64, i / 64);
        let h = [
            2.0 * nn[2] * nn[0],
            2.0 * nn[2] * nn[1],
            2.0 * nn[2] * nn[2] - 1.0,
        ];
        let j = (0..13)
            .min_by(|&a, &b| {
                angle_deg(h, lights.directions[a]).total_cmp(&angle_deg(h, lights.directions[b]))
            })
            .unwrap();
        if angle_deg(h, lights.directions[j]) < 20.0 {
            for c in 0..3 {
                stack.photos[j][c][i] += 0.3;
            }
        }
    }
    // Only pixels seen by enough lights: n_z ≥ 0.5.
    let sel: Vec<f32> = (0..64 * 64)
        .map(|i| {
            f32::from(u8::from(
                img.normal()[2][i] >= 0.5 && img.mask().unwrap()[i] > 0.5,
            ))
        })
        .collect();
    let mean = |out: &RgbnImage| {
        let idx: Vec<usize> = (0..64 * 64).filter(|&i| sel[i] > 0.5).collect();
        idx.iter()
            .map(|&i| angle_deg(out.normal_at(i % 64, i / 64), img.normal_at(i % 64, i / 64)))
            .sum::<f64>()
            / idx.len() as f64
    };
    let mask = img.mask().map(<[f32]>::to_vec);
    let ls = PhotometricParams {
        method: PsMethod::LeastSquares,
        ..Default::default()
    };
    let (out_ls, _) = photometric_stereo(&stack, &lights, mask.as_deref(), &ls).unwrap();
    let (out_tr, rep) = photometric_stereo(
        &stack,
        &lights,
        mask.as_deref(),
        &PhotometricParams::default(),
    )
    .unwrap();
    let (e_ls, e_tr) = (mean(&out_ls), mean(&out_tr));
    eprintln!(
        "synthetic sphere, shadows + highlights: LS {e_ls:.2}°, trimmed {e_tr:.2}° ({rep:?})"
    );
    assert!(e_tr < 0.5 * e_ls && e_tr < 1.0, "{e_ls} {e_tr}");
    assert!(out_tr.validate().is_clean());
}

#[test]
fn bad_inputs_are_clear_errors() {
    let (img, _) = Surface::Paraboloid { curvature: 0.004 }.render(16, 12);
    let lights = Lights {
        directions: ring_lights(4, 30.0),
        intensities: None,
    };
    let stack = render(&img, &lights);
    let p = PhotometricParams::default();
    // Too few lights.
    let two = PhotoStack::new(16, 12, stack.photos[..2].to_vec()).unwrap();
    let l2 = Lights {
        directions: lights.directions[..2].to_vec(),
        intensities: None,
    };
    assert!(matches!(
        photometric_stereo(&two, &l2, None, &p),
        Err(RgbnError::TooFewLights { count: 2 })
    ));
    // Rows ≠ photos.
    let l3 = Lights {
        directions: lights.directions[..3].to_vec(),
        intensities: None,
    };
    assert!(matches!(
        photometric_stereo(&stack, &l3, None, &p),
        Err(RgbnError::LightCountMismatch {
            got: 3,
            photos: 4,
            ..
        })
    ));
    let li = Lights {
        intensities: Some(vec![[1.0; 3]; 3]),
        ..lights.clone()
    };
    assert!(matches!(
        photometric_stereo(&stack, &li, None, &p),
        Err(RgbnError::LightCountMismatch { .. })
    ));
    // Coplanar (all in the x–z plane) and zero lights.
    let flat = Lights {
        directions: vec![
            [0.5, 0.0, 0.8],
            [-0.5, 0.0, 0.8],
            [0.0, 0.0, 1.0],
            [0.3, 0.0, 0.9],
        ],
        intensities: None,
    };
    let e = photometric_stereo(&stack, &flat, None, &p).unwrap_err();
    assert!(matches!(e, RgbnError::DegenerateLights { .. }), "{e}");
    let mut zero = lights.clone();
    zero.directions[1] = [0.0; 3];
    assert!(matches!(
        photometric_stereo(&stack, &zero, None, &p),
        Err(RgbnError::DegenerateLights { .. })
    ));
    // Mask of the wrong size; planes of the wrong size.
    assert!(matches!(
        photometric_stereo(&stack, &lights, Some(&[1.0; 5]), &p),
        Err(RgbnError::SizeMismatch { .. })
    ));
    assert!(PhotoStack::new(16, 12, vec![[vec![0.0; 5], vec![], vec![]]]).is_err());
    // Bad parameters.
    let bad = PhotometricParams {
        dark_fraction: 0.6,
        bright_fraction: 0.5,
        ..Default::default()
    };
    assert!(bad.validate().is_err());
    // Dark and saturated pixels are counted, not NaN.
    let mut s2 = stack.clone();
    for ph in &mut s2.photos {
        for plane in ph.iter_mut() {
            plane[0] = 0.0; // all dark
            plane[1] = 1.0; // saturated in every photo → unsolvable
        }
    }
    s2.photos[0][1][2] = 1.0; // one saturated observation → still solved from 3
    let (out, rep) = photometric_stereo(&s2, &lights, None, &p).unwrap();
    assert_eq!(rep.dark, 1, "{rep:?}");
    assert_eq!(rep.unsolvable, 1, "{rep:?}");
    assert_eq!(rep.with_saturated, 2, "{rep:?}");
    assert_eq!(rep.solved, 16 * 12 - 2);
    assert_eq!(out.normal_at(0, 0), [0.0, 0.0, 1.0]);
    assert_eq!(out.mask().unwrap()[0], 0.0);
    assert_eq!(out.mask().unwrap()[2], 1.0);
    assert!(out.validate().is_clean());
}

#[test]
fn a_set_cancellation_token_stops_every_estimator() {
    let (img, _) = Surface::Paraboloid { curvature: 0.004 }.render(32, 24);
    let lights = Lights {
        directions: ring_lights(6, 25.0),
        intensities: None,
    };
    let stack = render(&img, &lights);
    for method in [
        PsMethod::LeastSquares,
        PsMethod::Trimmed,
        PsMethod::L1,
        PsMethod::Sbl,
    ] {
        let params = PhotometricParams {
            method,
            ..Default::default()
        };
        let cancel = crate::cancel::Cancel::new();
        cancel.cancel();
        let guard = cancel.enter();
        let got = photometric_stereo(&stack, &lights, None, &params);
        drop(guard);
        assert!(
            matches!(got, Err(RgbnError::Cancelled)),
            "{method:?}: {:?}",
            got.map(|(_, r)| r)
        );
        // Without a token the same call runs.
        assert!(photometric_stereo(&stack, &lights, None, &params).is_ok());
    }
}

/// Renders Minnaert photos, `ρ e max(0, n·l)^k (n·v)^(k−1)` with the view `v = (0, 0, 1)`.
fn render_minnaert(img: &RgbnImage, lights: &Lights, k: f32) -> PhotoStack {
    let n = img.len();
    let photos = lights
        .directions
        .iter()
        .enumerate()
        .map(|(j, d)| {
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let l = d.map(|c| c / len);
            let e = lights.intensities.as_ref().map_or([1.0; 3], |i| i[j]);
            std::array::from_fn(|c| {
                (0..n)
                    .map(|i| {
                        let nn = [img.normal()[0][i], img.normal()[1][i], img.normal()[2][i]];
                        let s = (nn[0] * l[0] + nn[1] * l[1] + nn[2] * l[2]).max(0.0);
                        img.color()[c][i] * e[c] * s.powf(k) * nn[2].max(0.0).powf(k - 1.0)
                    })
                    .collect()
            })
        })
        .collect();
    PhotoStack::new(img.width(), img.height(), photos).unwrap()
}

fn mean_angle_deg(a: &RgbnImage, b: &RgbnImage, sel: &[f32]) -> f64 {
    let idx: Vec<usize> = (0..a.len()).filter(|&i| sel[i] >= 0.5).collect();
    idx.iter()
        .map(|&i| {
            let x = a.normal_at(i % a.width(), i / a.width());
            let y = b.normal_at(i % b.width(), i / b.width());
            angle_deg(x, y)
        })
        .sum::<f64>()
        / idx.len() as f64
}

/// A sphere under 12 lights at 50° and a frontal one (attached shadows on every side).
fn steep_sphere() -> (RgbnImage, Lights, Vec<f32>) {
    let (img, _) = Surface::Sphere { radius_px: 30.0 }.render(64, 64);
    let img = coloured(img);
    let lights = Lights {
        directions: ring_lights(12, 50.0)
            .into_iter()
            .chain([[0.0, 0.0, 1.0]])
            .collect(),
        intensities: None,
    };
    // Inside the sphere and not grazing (n_z ≥ 0.3).
    let sel = (0..img.len())
        .map(|i| f32::from(u8::from(img.normal()[2][i] >= 0.3)))
        .collect();
    (img, lights, sel)
}

#[test]
fn the_shading_exponent_of_a_minnaert_render_is_recovered_and_removes_the_polar_bias() {
    let (img, lights, sel) = steep_sphere();
    for k in [0.8f32, 1.25] {
        let stack = render_minnaert(&img, &lights, k);
        let (est, rep) =
            photometric_stereo(&stack, &lights, Some(&sel), &PhotometricParams::default()).unwrap();
        assert!((rep.exponent - k).abs() < 0.01 * k, "k {k}: {rep:?}");
        let e_est = mean_angle_deg(&est, &img, &sel);
        let lambert = PhotometricParams {
            exponent: Some(1.0),
            ..Default::default()
        };
        let (lam, rep1) = photometric_stereo(&stack, &lights, Some(&sel), &lambert).unwrap();
        assert_eq!(rep1.exponent, 1.0);
        let e_lam = mean_angle_deg(&lam, &img, &sel);
        // Lambert's model on k ≠ 1 data tilts every normal; the estimated k fits the
        // generating model, so only the ~0.5 % error of the estimate is left.
        assert!(e_est < 0.25, "k {k}: {e_est}° with k = {}", rep.exponent);
        assert!(
            e_lam > 4.0 * e_est.max(0.1),
            "k {k}: Lambert {e_lam}°, estimated {e_est}°"
        );
        // The albedo fit with the model's shading: ρ (n·v)^(k−1), the view factor included.
        for c in 0..3 {
            for i in (0..img.len()).filter(|&i| sel[i] >= 0.5) {
                let want = img.color()[c][i] * img.normal()[2][i].powf(k - 1.0);
                let got = est.color()[c][i];
                assert!((got - want).abs() < 0.03 * want, "k {k}: ρ {got} vs {want}");
            }
        }
    }
}

#[test]
fn an_exponent_beyond_the_search_band_keeps_lambert_and_given_by_hand_is_exact() {
    // k = 1.6: the fit would go past the band's edge, which the estimate reads as photos the
    // model does not describe, and keeps k = 1; the exact k given by hand recovers the normals.
    let (img, lights, sel) = steep_sphere();
    let k = 1.6f32;
    let stack = render_minnaert(&img, &lights, k);
    let run = |exponent| {
        let params = PhotometricParams {
            exponent,
            ..Default::default()
        };
        let (out, rep) = photometric_stereo(&stack, &lights, Some(&sel), &params).unwrap();
        (mean_angle_deg(&out, &img, &sel), rep.exponent)
    };
    let (e_auto, k_auto) = run(None);
    assert_eq!(k_auto, 1.0);
    let (e_lam, _) = run(Some(1.0));
    assert_eq!(e_auto, e_lam);
    let (e_exact, k_exact) = run(Some(k));
    assert_eq!(k_exact, k);
    assert!(
        e_exact < 0.05 && e_lam > 2.0,
        "{e_exact}° with k = {k}, {e_lam}° with 1"
    );
}

#[test]
fn lambertian_photos_keep_the_exponent_one_and_too_few_observations_cannot_move_it() {
    let (img, lights, sel) = steep_sphere();
    let stack = render(&img, &lights);
    let (_, rep) =
        photometric_stereo(&stack, &lights, Some(&sel), &PhotometricParams::default()).unwrap();
    assert!((rep.exponent - 1.0).abs() < 0.005, "{rep:?}");
    // Three lights: every pixel is fitted exactly by any exponent, so nothing is learnt.
    let three = Lights {
        directions: ring_lights(3, 30.0),
        intensities: None,
    };
    let stack = render_minnaert(&img, &three, 1.3);
    let (_, rep) =
        photometric_stereo(&stack, &three, Some(&sel), &PhotometricParams::default()).unwrap();
    assert_eq!(rep.exponent, 1.0, "{rep:?}");
}

#[test]
fn an_exponent_outside_its_range_is_refused_by_name() {
    let (img, lights, _) = steep_sphere();
    let stack = render(&img, &lights);
    for k in [0.2f32, 2.5, f32::NAN] {
        let params = PhotometricParams {
            exponent: Some(k),
            ..Default::default()
        };
        let e = photometric_stereo(&stack, &lights, None, &params).unwrap_err();
        assert!(e.to_string().contains("exponent"), "{e}");
    }
}

#[test]
fn pow_fast_follows_powf() {
    for p in [0.5f32, 0.75, 0.9, 1.0 / 1.3, 1.1, 4.0 / 3.0, 2.0] {
        for i in 0..=4000 {
            // x from 1e-6 to 1e3, log-spaced.
            let x = 10f32.powf(-6.0 + 9.0 * i as f32 / 4000.0);
            {
                let want = f64::from(x).powf(f64::from(p));
                let got = f64::from(pow_fast(x, p));
                assert!(
                    (got - want).abs() <= 2e-6 * want,
                    "{x}^{p}: {got} vs {want}"
                );
            }
        }
    }
    assert_eq!(pow_fast(0.0, 0.9), 0.0);
    assert_eq!(pow_fast(-0.01, 0.9), 0.0);
    assert_eq!(pow_fast(f32::NAN, 0.9), 0.0);
}
