//! Tests of `ops/filter.rs`.

use super::*;
use crate::raster::sample::Surface;
use crate::raster::Plane;

#[test]
fn parse_and_display_roundtrip() {
    for s in [
        "gauss:8",
        "box:3",
        "sharpen:2,1.5",
        "edge:1,4,0.5",
        "highpass:6",
        "dog:1,3",
        "log:2",
        "scale:-0.5",
        "sep:1,2,1/0.25,0.5,0.25",
        "kernel:3x3:0,-1,0,-1,5,-1,0,-1,0",
    ] {
        let k = Kernel::parse(s).unwrap();
        assert_eq!(k.to_string(), s);
        assert_eq!(Kernel::parse(&k.to_string()).unwrap(), k);
    }
}

#[test]
fn bad_kernels_say_what_is_wrong() {
    for (s, needle) in [
        ("gauss:-1", "must be in (0"),
        ("gauss:nan", "must be in (0"),
        ("gauss", "expected gauss:SIGMA"),
        ("blur:3", "unknown kernel \"blur\""),
        ("box:1.5", "whole number"),
        ("sep:1,2/1", "odd number of taps"),
        ("kernel:3x3:1,2", "needs 9 weights"),
        ("sharpen:2,x", "\"x\" in"),
    ] {
        let e = Kernel::parse(s).unwrap_err().to_string();
        assert!(e.contains(needle), "{s}: {e}");
    }
}

/// Angular error (radians) between two unit normals.
/// (atan2 of |a×b| and a·b: accurate for tiny angles, unlike acos in f32.)
fn angle(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let c = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt().atan2(d)
}

#[test]
fn gaussian_filtered_normals_equal_normals_of_the_blurred_height() {
    // Independent oracle: a Gaussian bump of width s blurred by G_σ is a Gaussian bump of
    // width √(s²+σ²) and amplitude a·s²/(s²+σ²) — differentiate that analytically.
    let size = 256;
    let (a, s, sigma) = (30.0f64, 14.0f64, 8.0f64);
    let bump = |amp: f64, width: f64| Surface::Gaussians {
        bumps: vec![[0.0, 0.0, amp, width]],
    };
    let (img, _) = bump(a, s).render(size, size);
    let s2 = (s * s + sigma * sigma).sqrt();
    let (want, _) = bump(a * s * s / (s2 * s2), s2).render(size, size);
    for sig_f32 in [sigma as f32] {
        let (out, _) = filter_normals(
            &img,
            &[Kernel::Gaussian { sigma_px: sig_f32 }],
            &FilterOptions::default(),
        )
        .unwrap();
        let mut max_err = 0.0f32;
        for r in 0..size {
            for x in 0..size {
                max_err = max_err.max(angle(out.normal_at(x, r), want.normal_at(x, r)));
            }
        }
        // The sampled, recursive Gaussian vs the continuous one: stated tolerance 0.1°.
        assert!(
            max_err.to_degrees() < 0.1,
            "max angular error {}°",
            max_err.to_degrees()
        );
    }
}

#[test]
fn box_and_sharpen_follow_the_sinusoid_transfer_function() {
    // A sinusoid z = A sin(ku) sin(kv) is an eigenfunction of every symmetric LSI kernel:
    // the box of width 2r+1 scales it by (sin((2r+1)k/2) / ((2r+1) sin(k/2)))² on the
    // grid, sharpen by (1 + k_s·(1 − ĝ²)) with ĝ the Gaussian's 1-D response.
    let size = 192; // whole number of periods (32 px) → wrap border is exact
    let (amp, period) = (2.0f64, 32.0f64);
    let surf = |a: f64| Surface::Sinusoid {
        amplitude_px: a,
        period_px: period,
    };
    let (img, _) = surf(amp).render(size, size);
    let k = std::f64::consts::TAU / period;
    let r = 3.0f64;
    let box_gain = ((2.0 * r + 1.0) * k / 2.0).sin() / ((2.0 * r + 1.0) * (k / 2.0).sin());
    let opts = FilterOptions {
        border: BorderMode::Wrap,
        mask_aware: false,
    };
    let (out, _) = filter_normals(&img, &[Kernel::Box { radius_px: 3 }], &opts).unwrap();
    let (want, _) = surf(amp * box_gain * box_gain).render(size, size);
    let err = (0..size * size)
        .map(|i| {
            angle(
                out.normal_at(i % size, i / size),
                want.normal_at(i % size, i / size),
            )
        })
        .fold(0.0f32, f32::max);
    assert!(err.to_degrees() < 0.01, "box: {}°", err.to_degrees());

    // Gaussian σ=2 (FIR path) sampled response on the grid: Σ g_i cos(k i).
    let fir = Fir::gaussian(2.0);
    let rr = fir.taps.len() as i32 / 2;
    let g_hat: f64 = fir
        .taps
        .iter()
        .enumerate()
        .map(|(i, t)| f64::from(*t) * (k * f64::from(i as i32 - rr)).cos())
        .sum();
    let ks = 1.5f64;
    let (out, _) = filter_normals(
        &img,
        &[Kernel::Sharpen {
            sigma_px: 2.0,
            amount: ks as f32,
        }],
        &opts,
    )
    .unwrap();
    let (want, _) = surf(amp * (1.0 + ks * (1.0 - g_hat * g_hat))).render(size, size);
    let err = (0..size * size)
        .map(|i| {
            angle(
                out.normal_at(i % size, i / size),
                want.normal_at(i % size, i / size),
            )
        })
        .fold(0.0f32, f32::max);
    assert!(err.to_degrees() < 0.01, "sharpen: {}°", err.to_degrees());
}

#[test]
fn every_linear_filter_keeps_integrable_input_integrable() {
    // Integrable input: the discrete (forward-difference) gradient of a height whose relief
    // lies well inside the image.
    // Relief (σ ≤ 12 px) within 60 px of the centre of a 512² image: even blurred by σ = 32
    // it is negligible at the border, where no extension of a gradient field is integrable.
    let size = 512;
    let surf = Surface::Gaussians {
        bumps: vec![
            [-40.0, 25.0, 20.0, 12.0],
            [35.0, -30.0, -12.0, 9.0],
            [5.0, 40.0, 6.0, 4.0],
        ],
    };
    let (_, z) = surf.render(size, size);
    let z = Plane::from_vec(size, size, z.into_vec()).unwrap();
    let base = GradientField::of_height(&z).0;
    assert!(base.relative_rms_curl(None) < 1e-6);
    let kernels = [
        "gauss:1.5",
        "gauss:8",
        "gauss:32",
        "box:4",
        "sharpen:3,2",
        "edge:1,4,1.5",
        "highpass:6",
        "dog:1,4",
        "log:3",
        "scale:2.5",
        "sep:1,4,6,4,1/1,2,1",
        "kernel:3x3:0,-1,0,-1,5,-1,0,-1,0",
    ];
    for ks in kernels {
        for border in BorderMode::ALL {
            let mut g = base.clone();
            filter_gradients(
                &mut g,
                &[Kernel::parse(ks).unwrap()],
                &FilterOptions {
                    border,
                    mask_aware: false,
                },
                None,
            )
            .unwrap();
            let rel = g.relative_rms_curl(None);
            assert!(rel <= 1e-4, "{ks} {border:?}: relative RMS curl {rel:e}");
        }
    }
}

#[test]
fn mask_aware_filter_does_not_bleed_across_the_mask() {
    // Left half steep (p = 1), right half flat; mask = left half. A mask-aware blur keeps
    // the left half at p = 1 exactly (no flat values averaged in) and leaves the right alone.
    let (w, h) = (64, 16);
    let mut g = GradientField::zeros(w, h);
    let mut mask = vec![0.0f32; w * h];
    for r in 0..h {
        for x in 0..w / 2 {
            g.p[r * w + x] = 1.0;
            mask[r * w + x] = 1.0;
        }
    }
    let mut a = g.clone();
    filter_gradients(
        &mut a,
        &[Kernel::Gaussian { sigma_px: 4.0 }],
        &FilterOptions {
            border: BorderMode::Mirror,
            mask_aware: true,
        },
        Some(&mask),
    )
    .unwrap();
    assert!(a.p.iter().zip(&g.p).all(|(x, y)| (x - y).abs() < 1e-4));
    let mut b = g.clone();
    filter_gradients(
        &mut b,
        &[Kernel::Gaussian { sigma_px: 4.0 }],
        &FilterOptions::default(),
        Some(&mask),
    )
    .unwrap();
    assert!(
        (b.p[w / 2 - 1] - 0.5).abs() < 0.1,
        "plain blur does bleed: {}",
        b.p[w / 2 - 1]
    );
}

#[test]
fn depth_scale_scales_the_gradient() {
    let (img, _) = Surface::Paraboloid { curvature: 0.002 }.render(64, 64);
    let (out, _) = filter_normals(
        &img,
        &[Kernel::DepthScale { scale: 2.0 }],
        &FilterOptions::default(),
    )
    .unwrap();
    let a = GradientField::from_normals(&img);
    let b = GradientField::from_normals(&out);
    for i in 0..64 * 64 {
        assert!((b.p[i] - 2.0 * a.p[i]).abs() < 1e-4 && (b.q[i] - 2.0 * a.q[i]).abs() < 1e-4);
    }
}

#[test]
fn partial_derivative_blend_test_vector() {
    // Sum of gradients of n1 and n2 (the "partial derivative" blend, Barré-Brisebois & Hill).
    use crate::raster::gradient::{gradient_of_normal, normal_of_gradient};
    let n1 = [0.3f32, 0.4, 0.866];
    let l = (0.04f32 + 0.01 + 0.97 * 0.97).sqrt();
    let n2 = [-0.2 / l, 0.1 / l, 0.97 / l];
    let (g1, g2) = (gradient_of_normal(n1), gradient_of_normal(n2));
    let n = normal_of_gradient(g1[0] + g2[0], g1[1] + g2[1]);
    let want = [0.1212f32, 0.4883, 0.8642];
    for k in 0..3 {
        assert!((n[k] - want[k]).abs() <= 1e-4, "{n:?}");
    }
}

/// The fused sharpen, high-pass, edge-enhance and difference of Gaussians (FIR and recursive
/// sigmas, a rough field with a steep flank) equal the unfused path to rounding, with the same
/// report; and the node's report-free call gives the same normals.
#[test]
fn fused_combinations_equal_the_unfused_path() {
    let (w, h) = (97, 61);
    let (mut img, _) = Surface::gaussians_for(61).render(w, h);
    let (rip, _) = Surface::Sinusoid {
        amplitude_px: 2.0,
        period_px: 7.0,
    }
    .render(w, h);
    let mut g = GradientField::from_normals(&img);
    let r = GradientField::from_normals(&rip);
    g.p.iter_mut().zip(&r.p).for_each(|(a, b)| *a += b);
    g.q.iter_mut().zip(&r.q).for_each(|(a, b)| *a += 0.5 * b);
    g.write_normals(&mut img);
    for spec in [
        "sharpen:2,1.5",
        "sharpen:6,0.7",
        "highpass:1.5",
        "highpass:5",
        "edge:1,4,0.8",
        "dog:2,6",
    ] {
        let k = Kernel::parse(spec).unwrap();
        for border in BorderMode::ALL {
            let opts = FilterOptions {
                border,
                ..FilterOptions::default()
            };
            let (fused, rf) = filter_normals(&img, std::slice::from_ref(&k), &opts).unwrap();
            let (reference, rr) =
                filter_normals_general(&img, std::slice::from_ref(&k), &opts).unwrap();
            let mut worst = 0.0f32;
            for y in 0..h {
                for x in 0..w {
                    worst = worst.max(angle(fused.normal_at(x, y), reference.normal_at(x, y)));
                }
            }
            assert!(worst < 2e-5, "{spec} {border:?}: {worst} rad");
            assert_eq!(rf.clamped, rr.clamped, "{spec}");
            let rel = |a: f64, b: f64| (a - b).abs() <= 1e-4 * b.abs().max(1e-12);
            assert!(
                rel(rf.curl_before.rms_curl, rr.curl_before.rms_curl),
                "{spec}: {:?} {:?}",
                rf.curl_before,
                rr.curl_before
            );
            assert!(
                rel(rf.curl_after.rms_curl, rr.curl_after.rms_curl),
                "{spec}: {:?} {:?}",
                rf.curl_after,
                rr.curl_after
            );
            let node = filter_image(&img, std::slice::from_ref(&k), &opts).unwrap();
            assert_eq!(node.normal(), fused.normal(), "{spec}");
        }
    }
}
