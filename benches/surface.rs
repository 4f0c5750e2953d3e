//! Surface benchmarks: DCT Poisson / Frankot–Chellappa / masked Poisson integration and
//! photometric stereo at 4K (3840 × 2160). Goals (BENCHMARKS.md): DCT integration ≤ 50 ms on 2
//! threads, masked Poisson (multigrid-preconditioned CG, a mask covering half the image,
//! default tolerance 1e-6) ≤ 1 s, photometric stereo from 12 photos ≤ 1 s excluding decoding.
//!
//! Run: `CARGO_TARGET_DIR=… cargo bench --no-default-features --bench surface`.

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::capture::inputs::{Lights, PhotoStack};
use rgbn::capture::photometric::{photometric_stereo, PhotometricParams, PsMethod};
use rgbn::raster::gradient::GradientField;
use rgbn::raster::integrate::{
    integrate_gradients, project_integrable, IntegrateParams, IntegrationMethod, ProjectParams,
};
use rgbn::raster::sample::Surface;
use std::hint::black_box;

const W: usize = 3840;
const H: usize = 2160;

fn integration(c: &mut Criterion) {
    let (img, _) = Surface::gaussians_for(H).render(W, H);
    let g = GradientField::from_normals(&img);
    let mut group = c.benchmark_group("integrate_4k");
    group.sample_size(10);
    for method in [
        IntegrationMethod::PoissonDct,
        IntegrationMethod::FrankotChellappa,
    ] {
        let params = IntegrateParams {
            method,
            ..Default::default()
        };
        group.bench_function(format!("{method:?}"), |b| {
            b.iter(|| integrate_gradients(black_box(&g), None, &params).unwrap())
        });
    }
    // An irregular blob (wobbly ellipse) covering half of the image.
    let mask = half_mask();
    let covered = mask.iter().filter(|&&v| v >= 0.5).count() as f64 / (W * H) as f64;
    eprintln!(
        "integrate_4k/MaskedPoisson: mask covers {:.1} % of the image",
        100.0 * covered
    );
    let params = IntegrateParams {
        method: IntegrationMethod::MaskedPoisson,
        ..Default::default()
    };
    let (_, rep) = integrate_gradients(&g, Some(&mask), &params).unwrap();
    eprintln!(
        "integrate_4k/MaskedPoisson: {} CG iterations, relative residual {:.2e}",
        rep.iterations, rep.relative_residual
    );
    group.bench_function("MaskedPoisson", |b| {
        b.iter(|| integrate_gradients(black_box(&g), Some(&mask), &params).unwrap())
    });
    group.bench_function("project_integrable_dct", |b| {
        b.iter(|| project_integrable(black_box(&img), &ProjectParams::default()).unwrap())
    });
    group.finish();
}

/// A wobbly ellipse covering half of the 4K frame (0/1 coverage).
fn half_mask() -> Vec<f32> {
    let (cx, cy) = (W as f64 / 2.0, H as f64 / 2.0);
    // Area of the ellipse with semi-axes (k·cx, k·cy) is π k² cx cy = ½ · 4 cx cy.
    let k = (2.0 / std::f64::consts::PI).sqrt();
    (0..W * H)
        .map(|i| {
            let (u, v) = (((i % W) as f64 - cx) / cx, ((i / W) as f64 - cy) / cy);
            let th = v.atan2(u);
            let edge = k * (1.0 + 0.08 * (5.0 * th).sin());
            f32::from(u8::from(u.hypot(v) < edge))
        })
        .collect()
}

fn photometric(c: &mut Criterion) {
    let (img, _) = Surface::Sphere {
        radius_px: 0.45 * H as f64,
    }
    .render(W, H);
    // 12 lights on a 30° ring and a frontal one (a DiLiGenT-like spread of 13), Minnaert
    // shading with k = 1.1 so that the exponent search has something to find.
    let k = 1.1f32;
    let dirs: Vec<[f32; 3]> = (0..12)
        .map(|j| {
            let a = std::f32::consts::TAU * j as f32 / 12.0;
            let t = 0.5f32;
            [t.sin() * a.cos(), t.sin() * a.sin(), t.cos()]
        })
        .chain([[0.0, 0.0, 1.0]])
        .collect();
    let n = W * H;
    let photos = dirs
        .iter()
        .map(|l| {
            let plane: Vec<f32> = (0..n)
                .map(|i| {
                    let nn = [img.normal()[0][i], img.normal()[1][i], img.normal()[2][i]];
                    let s = (nn[0] * l[0] + nn[1] * l[1] + nn[2] * l[2]).max(0.0);
                    0.8 * s.powf(k) * nn[2].max(0.0).powf(k - 1.0)
                })
                .collect();
            [plane.clone(), plane.clone(), plane]
        })
        .collect();
    let stack = PhotoStack::new(W, H, photos).unwrap();
    let lights = Lights {
        directions: dirs,
        intensities: None,
    };
    let mut group = c.benchmark_group("photometric_4k_13_lights");
    group.sample_size(10);
    // Woodham: least squares with k = 1 (the time baseline); every estimator with the
    // exponent estimated (the default) and the trimmed one with k = 1.
    let runs = [
        ("woodham", PsMethod::LeastSquares, Some(1.0)),
        ("trimmed_k1", PsMethod::Trimmed, Some(1.0)),
        ("trimmed", PsMethod::Trimmed, None),
        ("l1", PsMethod::L1, None),
        ("sbl", PsMethod::Sbl, None),
    ];
    for (name, method, exponent) in runs {
        let params = PhotometricParams {
            method,
            exponent,
            ..Default::default()
        };
        group.bench_function(name, |b| {
            b.iter(|| photometric_stereo(black_box(&stack), &lights, None, &params).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, integration, photometric);
criterion_main!(benches);
