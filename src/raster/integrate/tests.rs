//! Tests of `raster/integrate/mod.rs`.

use super::test_util::*;
use super::*;
use crate::raster::buf;
use crate::raster::gradient::gradient_of_normal;
use crate::raster::sample::Surface;

use crate::raster::sample::noise_field;

fn disc_mask(w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, r) = (
                (i % w) as f64 - w as f64 / 2.0,
                (i / w) as f64 - h as f64 / 2.0,
            );
            f32::from(u8::from(x * x + 1.5 * r * r < (w as f64 * 0.4).powi(2)))
        })
        .collect()
}

#[test]
fn non_integrable_fraction_is_zero_for_a_height_and_near_root_two_over_pi_for_noise() {
    let (w, h) = (96, 80);
    let s = Surface::gaussians_for(96);
    let z = Plane::from_fn(w, h, |x, r| {
        s.height(x as f64 - 48.0, 40.0 - r as f64) as f32
    });
    // The samples of a height in the default (averaged) model: exactly integrable.
    let g = gradients_of_height(&z, None, None, Differences::Averaged);
    let m = disc_mask(w, h);
    for mask in [None, Some(&m[..])] {
        let f = non_integrable_fraction(&g, mask).unwrap();
        assert!(f < 1e-4, "height, mask {}: F = {f}", mask.is_some());
        // White noise samples: their edge averages are low-pass noise (spectrum
        // cos²(ω/2) per axis), of which the gradient part has the fraction 1 − 2/π of
        // the energy (the mean over the frequencies of
        // (s_x c_x + s_y c_y)/(s_x + s_y), s = sin²(ω/2), c = cos²(ω/2)): F ≈ √(2/π) ≈ 0.80
        // (the forward model's √½ for white edge values).
        let n = noise_field(w, h, 7);
        let f = non_integrable_fraction(&n, mask).unwrap();
        assert!(
            (0.74..0.83).contains(&f),
            "noise, mask {}: F = {f}",
            mask.is_some()
        );
        // Scale-free, unlike the relative curl when gradient energy is added.
        let scaled = GradientField {
            p: n.p.iter().map(|v| v * 8.0).collect(),
            q: n.q.iter().map(|v| v * 8.0).collect(),
            ..n.clone()
        };
        let fs = non_integrable_fraction(&scaled, mask).unwrap();
        assert!((fs - f).abs() < 1e-4, "{fs} vs {f}");
    }
    // The sum of a surface and noise of equal energy: between the two.
    let n = noise_field(w, h, 9);
    let rms = |v: &[f32]| (v.iter().map(|a| f64::from(a * a)).sum::<f64>() / v.len() as f64).sqrt();
    let k = (rms(&g.p) + rms(&g.q)) / (rms(&n.p) + rms(&n.q));
    let mixed = GradientField {
        p: g.p
            .iter()
            .zip(&n.p)
            .map(|(a, b)| a + k as f32 * b)
            .collect(),
        q: g.q
            .iter()
            .zip(&n.q)
            .map(|(a, b)| a + k as f32 * b)
            .collect(),
        ..g.clone()
    };
    let f = non_integrable_fraction(&mixed, None).unwrap();
    assert!((0.3..0.62).contains(&f), "mixed F = {f}");
    assert_eq!(
        non_integrable_fraction(&GradientField::zeros(8, 8), None).unwrap(),
        0.0
    );
}

#[test]
fn the_wrong_green_convention_reads_as_non_integrable() {
    let (w, h) = (96, 96);
    let s = Surface::gaussians_for(96);
    let z = Plane::from_fn(w, h, |x, r| {
        s.height(x as f64 - 48.0, 48.0 - r as f64) as f32
    });
    let g = gradients_of_height(&z, None, None, Differences::Averaged);
    let mut img = RgbnImage::flat(w, h, [0.5; 3]);
    g.write_normals(&mut img);
    let [gl, dx] = green_convention_fractions(&img).unwrap();
    assert!(gl < 1e-3 && dx > 0.1, "as stored {gl}, flipped {dx}");
    // The same image stored the other way round reads the other way round.
    let [x, y, zz] = img.normal();
    let flipped = img
        .with_normals([x.to_vec(), y.iter().map(|v| -v).collect(), zz.to_vec()])
        .unwrap();
    let [a, b] = green_convention_fractions(&flipped).unwrap();
    assert!((a - dx).abs() < 1e-6 && (b - gl).abs() < 1e-6, "{a} {b}");
}

#[test]
fn forward_differences_recover_analytic_surfaces_at_the_staggered_position() {
    let size = 128;
    let c = size as f64 / 2.0;
    // Sum of Gaussians (zero slope at the borders): DCT and masked solvers.
    let s = Surface::gaussians_for(size);
    let (img, z_centre) = s.render(size, size);
    let z_stag = Plane::from_fn(size, size, |x, r| {
        s.height(x as f64 - 0.5 - c, c - r as f64 - 0.5) as f32
    });
    let amp = z_stag.data().iter().fold(0.0f32, |a, &v| a.max(v.abs()));
    for method in [
        IntegrationMethod::PoissonDct,
        IntegrationMethod::FrankotChellappa,
    ] {
        let params = IntegrateParams {
            method,
            differences: Differences::Forward,
            ..Default::default()
        };
        let (zi, _) = integrate_normals(&img, &params).unwrap();
        let rmse = rmse_up_to_constant(&zi, &z_stag, None);
        let rmse_centre = rmse_up_to_constant(&zi, &z_centre, None);
        eprintln!(
            "gaussians {size}² {method:?}: RMSE {rmse:.5} px (vs centre samples \
             {rmse_centre:.4} px), amplitude {amp:.1} px"
        );
        assert!(rmse < 0.06, "{method:?}: {rmse}");
        // Normals of the integrated height are integrable.
        let g = GradientField::from_height(&zi);
        assert!(g.curl_stats_forward(None).relative < 1e-5);
    }

    // A spherical cap (radius R, cut at ρ = a) on a flat plane: a kink at the rim.
    let (rr, a) = (0.5 * size as f64, 0.35 * size as f64);
    let cap = |u: f64, v: f64| {
        let rho2 = u * u + v * v;
        if rho2 < a * a {
            (rr * rr - rho2).sqrt() - (rr * rr - a * a).sqrt()
        } else {
            0.0
        }
    };
    let sphere = Surface::Sphere { radius_px: rr };
    let n = size * size;
    let mut normal = [
        buf::zeroed_f32(n),
        buf::zeroed_f32(n),
        buf::filled_f32(n, 1.0),
    ];
    for i in 0..n {
        let (u, v) = ((i % size) as f64 - c, c - (i / size) as f64);
        if u * u + v * v < a * a {
            let [p, q] = sphere.gradient(u, v).unwrap();
            let nn = crate::raster::gradient::normal_of_gradient(p as f32, q as f32);
            for (plane, v) in normal.iter_mut().zip(nn) {
                plane[i] = v;
            }
        }
    }
    let col = [vec![0.5; n], vec![0.5; n], vec![0.5; n]];
    let img = RgbnImage::new(size, size, col, normal, None).unwrap();
    let z_stag = Plane::from_fn(size, size, |x, r| {
        cap(x as f64 - 0.5 - c, c - r as f64 - 0.5) as f32
    });
    let forward = IntegrateParams {
        differences: Differences::Forward,
        ..Default::default()
    };
    let (zi, _) = integrate_normals(&img, &forward).unwrap();
    let rmse = rmse_up_to_constant(&zi, &z_stag, None);
    let cap_h = cap(0.0, 0.0);
    eprintln!("sphere cap {size}² (height {cap_h:.1} px): DCT forward RMSE {rmse:.4} px");
    assert!(rmse < 0.1, "{rmse}");
    // The default (averaged) model at the pixel centres.
    let z_centre = Plane::from_fn(size, size, |x, r| cap(x as f64 - c, c - r as f64) as f32);
    let (zi, _) = integrate_normals(&img, &IntegrateParams::default()).unwrap();
    let rmse = rmse_up_to_constant(&zi, &z_centre, None);
    eprintln!("sphere cap {size}²: DCT averaged RMSE {rmse:.4} px at pixel centres");
    assert!(rmse < 0.1, "{rmse}");
    let (out, _, rep) = project_integrable(&img, &ProjectParams::default()).unwrap();
    eprintln!(
        "sphere cap projection: relative curl {:.2e} → {:.2e}",
        rep.before.relative, rep.after.relative
    );
    assert!(rep.after.relative < 1e-4 && out.validate().is_clean());
}

/// Pixel-centre samples of a surface of revolution `z = f(ρ)` about the image centre
/// (`u = x − c`, `v = c − row`): the image (normals written from the analytic gradients,
/// mask given) and the true heights at pixel centres.
fn revolution(
    size: usize,
    f: &(dyn Fn(f64) -> f64 + Sync),
    df: &(dyn Fn(f64) -> f64 + Sync),
    mask: Option<Vec<f32>>,
) -> (RgbnImage, Plane) {
    let c = size as f64 / 2.0;
    let uv = |i: usize| ((i % size) as f64 - c, c - (i / size) as f64);
    let mut g = GradientField::zeros(size, size);
    for i in 0..size * size {
        let (u, v) = uv(i);
        let rho = u.hypot(v);
        if rho > 0.0 {
            g.p[i] = (df(rho) * u / rho) as f32;
            g.q[i] = (df(rho) * v / rho) as f32;
        }
    }
    let col = [
        vec![0.5; size * size],
        vec![0.5; size * size],
        vec![0.5; size * size],
    ];
    let mut img = RgbnImage::new(size, size, col, g.to_normals(), mask).unwrap();
    g.write_normals(&mut img);
    let z = Plane::from_fn(size, size, |x, r| {
        let (u, v) = uv(r * size + x);
        f(u.hypot(v)) as f32
    });
    (img, z)
}

/// An irregular mask: a wobbly disc of radius ≤ `rm` with a round hole.
fn wobbly_mask(size: usize, rm: f64) -> Vec<f32> {
    let c = size as f64 / 2.0;
    (0..size * size)
        .map(|i| {
            let (u, v) = ((i % size) as f64 - c, c - (i / size) as f64);
            let th = v.atan2(u);
            let edge = rm * (0.86 + 0.14 * (3.0 * th + 0.4).sin());
            let hole = (u - 0.3 * rm).hypot(v + 0.2 * rm) < 0.12 * rm;
            f32::from(u8::from(u.hypot(v) < edge && !hole))
        })
        .collect()
}

#[test]
fn steep_surfaces_are_recovered_at_pixel_centres_inside_an_irregular_mask() {
    // Slopes up to 10 px/px, normals sampled at pixel centres, masked_poisson: the averaged
    // model registers the height at the centres; the forward model is half a pixel off.
    let size = 160;
    let (rs, k) = (70.0f64, 1.0 / 14.0);
    let a = rs * 10.0 / 101f64.sqrt(); // sphere slope 10 at ρ = a
    let sphere = |r: f64| (rs * rs - r.min(a).powi(2)).sqrt();
    let dsphere = |r: f64| -r.min(a) / (rs * rs - r.min(a).powi(2)).sqrt();
    let para = |r: f64| k * r * r;
    let dpara = |r: f64| 2.0 * k * r;
    let vase = |r: f64| -30.0 * ((r - 40.0) / 3.0).tanh();
    let dvase = |r: f64| -10.0 / ((r - 40.0) / 3.0).cosh().powi(2);
    type Radial<'a> = &'a (dyn Fn(f64) -> f64 + Sync);
    let cases: [(&str, Radial, Radial, f64); 3] = [
        ("sphere cap", &sphere, &dsphere, a),
        ("paraboloid", &para, &dpara, 70.0),
        ("vase (tanh profile)", &vase, &dvase, 70.0),
    ];
    for (name, f, df, rm) in cases {
        let mask = wobbly_mask(size, rm);
        let (img, z) = revolution(size, f, df, Some(mask.clone()));
        let max_slope = (0..size * size)
            .filter(|&i| mask[i] > 0.5)
            .map(|i| {
                let [p, q] = gradient_of_normal([
                    img.normal()[0][i],
                    img.normal()[1][i],
                    img.normal()[2][i],
                ]);
                p.hypot(q)
            })
            .fold(0.0f32, f32::max);
        let mut rmse = [0.0; 2];
        for (j, differences) in [Differences::Averaged, Differences::Forward]
            .into_iter()
            .enumerate()
        {
            let params = IntegrateParams {
                method: IntegrationMethod::MaskedPoisson,
                differences,
                ..Default::default()
            };
            let (zi, rep) = integrate_normals(&img, &params).unwrap();
            rmse[j] = rmse_up_to_constant(&zi, &z, Some(&mask));
            eprintln!(
                "{name} {size}² (max slope {max_slope:.2}): masked_poisson {differences:?} \
                 RMSE {:.4} px at pixel centres ({} CG iterations)",
                rmse[j], rep.iterations
            );
            assert!(rep.relative_residual <= 1e-6, "{rep:?}");
        }
        assert!(max_slope > 9.0, "{name}: {max_slope}");
        assert!(rmse[0] <= 0.15, "{name}: averaged RMSE {}", rmse[0]);
        assert!(
            rmse[1] > 4.0 * rmse[0],
            "{name}: forward {} vs averaged",
            rmse[1]
        );
    }
}

#[test]
fn gentle_surfaces_come_back_within_a_hundredth_of_a_pixel() {
    let size = 128;
    let c = size as f64 / 2.0;
    // Two Gaussian bumps, slopes ≤ 1: DCT (full rectangle) and masked (irregular mask).
    let bump = |u: f64, v: f64, a: f64, s: f64| a * (-(u * u + v * v) / (2.0 * s * s)).exp();
    let f =
        |u: f64, v: f64| bump(u - 10.0, v + 5.0, 25.0, 20.0) - bump(u + 25.0, v - 20.0, 6.0, 12.0);
    let grad = |u: f64, v: f64| {
        let (a, b) = (
            bump(u - 10.0, v + 5.0, 25.0, 20.0),
            bump(u + 25.0, v - 20.0, 6.0, 12.0),
        );
        [
            -a * (u - 10.0) / 400.0 + b * (u + 25.0) / 144.0,
            -a * (v + 5.0) / 400.0 + b * (v - 20.0) / 144.0,
        ]
    };
    // A periodic surface for Frankot–Chellappa: two periods along x, one along y.
    let tau = std::f64::consts::TAU;
    let (kx, ky) = (2.0 * tau / size as f64, tau / size as f64);
    let per = |u: f64, v: f64| 8.0 * (kx * u).sin() * (ky * v).cos();
    let dper = |u: f64, v: f64| {
        [
            8.0 * kx * (kx * u).cos() * (ky * v).cos(),
            -8.0 * ky * (kx * u).sin() * (ky * v).sin(),
        ]
    };
    type Surf<'a> = (
        &'a (dyn Fn(f64, f64) -> f64 + Sync),
        &'a dyn Fn(f64, f64) -> [f64; 2],
    );
    let mask = wobbly_mask(size, 60.0);
    let cases: [(IntegrationMethod, Surf, bool); 3] = [
        (IntegrationMethod::PoissonDct, (&f, &grad), false),
        (IntegrationMethod::MaskedPoisson, (&f, &grad), true),
        (IntegrationMethod::FrankotChellappa, (&per, &dper), false),
    ];
    for (method, (f, df), masked) in cases {
        let uv = |x: usize, r: usize| (x as f64 - c, c - r as f64);
        let mut g = GradientField::zeros(size, size);
        let mut max_slope = 0.0f64;
        for r in 0..size {
            for x in 0..size {
                let (u, v) = uv(x, r);
                let [p, q] = df(u, v);
                max_slope = max_slope.max(p.hypot(q));
                g.p[r * size + x] = p as f32;
                g.q[r * size + x] = q as f32;
            }
        }
        let z = Plane::from_fn(size, size, |x, r| {
            let (u, v) = uv(x, r);
            f(u, v) as f32
        });
        let m = masked.then_some(&mask[..]);
        let params = IntegrateParams {
            method,
            ..Default::default()
        };
        let (zi, _) = integrate_gradients(&g, m, &params).unwrap();
        let rmse = rmse_up_to_constant(&zi, &z, m);
        let max = max_err_up_to_constant(&zi, &z, m);
        eprintln!(
            "gentle {method:?} (max slope {max_slope:.2}): RMSE {rmse:.5} px, max {max:.5} px"
        );
        assert!(max_slope <= 1.0 && max_slope > 0.3);
        assert!(max <= 0.01, "{method:?}: max error {max}");
    }
}

#[test]
fn height_round_trips_through_exr() {
    let z = rough(13, 7);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("h.exr");
    crate::raster::io::save_plane_exr(&z, "Z", &path).unwrap();
    let img = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
    let ch = &img.layer_data.channel_data.list[0];
    assert_eq!(ch.name.to_string(), "Z");
    let back: Vec<f32> = ch.sample_data.values_as_f32().collect();
    assert_eq!(back, z.data());
    assert!(crate::raster::io::save_plane_exr(&z, "Z", &dir.path().join("h.png")).is_err());
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let g = GradientField::zeros(8, 8);
    let empty = buf::zeroed_f32(64);
    for method in [
        IntegrationMethod::PoissonDct,
        IntegrationMethod::FrankotChellappa,
        IntegrationMethod::MaskedPoisson,
    ] {
        let params = IntegrateParams {
            method,
            ..Default::default()
        };
        let e = integrate_gradients(&g, Some(&empty), &params).unwrap_err();
        assert!(matches!(e, RgbnError::EmptyMask { .. }), "{e}");
    }
    let e = integrate_gradients(&g, Some(&[1.0; 10]), &IntegrateParams::default());
    assert!(matches!(e, Err(RgbnError::InvalidImage(_))));
    let bad = IntegrateParams {
        tolerance: 0.0,
        ..Default::default()
    };
    assert!(integrate_gradients(&g, None, &bad).is_err());
    let bad = IntegrateParams {
        max_iterations: 0,
        ..Default::default()
    };
    assert!(bad.validate().is_err());
    for beta in [0.5, 10.5, f64::NAN] {
        let bad = IntegrateParams {
            over_relaxation: beta,
            ..Default::default()
        };
        let e = bad.validate().unwrap_err();
        assert!(
            matches!(e, RgbnError::InvalidParam { ref name, .. } if name == "over_relaxation"),
            "{e}"
        );
    }
    // A single pixel and an isolated masked pixel work.
    let one = GradientField::zeros(1, 1);
    let (z, _) = integrate_gradients(&one, None, &IntegrateParams::default()).unwrap();
    assert_eq!(z.data(), &[0.0]);
    let mut m = buf::zeroed_f32(64);
    m[9] = 1.0;
    let params = IntegrateParams {
        method: IntegrationMethod::MaskedPoisson,
        ..Default::default()
    };
    let (z, _) = integrate_gradients(&g, Some(&m), &params).unwrap();
    assert!(z.data().iter().all(|v| v.is_finite()));
    // A mask of several pixels with no two neighbours inside: no edge, a one-line error
    // naming the mask.
    m[27] = 1.0;
    let e = integrate_gradients(&g, Some(&m), &params).unwrap_err();
    assert!(
        matches!(e, RgbnError::InvalidParam { ref name, .. } if name == "mask"),
        "{e}"
    );
    assert!(!e.to_string().contains('\n'), "{e}");
    // A single-pixel component next to a real one: height 0, counted, never NaN.
    let g = noise_field(8, 8, 3);
    let mut m = buf::zeroed_f32(64);
    for i in [0, 1, 2, 8, 9, 10, 36] {
        m[i] = 1.0;
    }
    let (z, rep) = integrate_gradients(&g, Some(&m), &params).unwrap();
    assert!(z.data().iter().all(|v| v.is_finite()));
    assert_eq!(z.data()[36], 0.0);
    assert_eq!((rep.domain_pixels, rep.isolated_pixels), (7, 1), "{rep:?}");
    let mean = [0, 1, 2, 8, 9, 10]
        .iter()
        .map(|&i| z.data()[i])
        .sum::<f32>();
    assert!(mean.abs() < 1e-4, "{mean}");
}
