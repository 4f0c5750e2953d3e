//! Bilateral normal integration at 4K (3840 × 2160, orthographic): the Gaussian-bumps surface
//! torn open along a half-line (a depth discontinuity seen only as a line of normal
//! discontinuity, growing to ≈ 540 px at the top edge), over a wobbly ellipse covering half
//! of the frame. Goal (BENCHMARKS.md): ≤ 10 s with the defaults (k = 2, ≤ 150 reweighting
//! iterations, energy tolerance 1e-4, solve tolerance 1e-6).
//!
//! Run: `CARGO_TARGET_DIR=… cargo bench --no-default-features --bench bini`.

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::raster::gradient::GradientField;
use rgbn::raster::integrate::{integrate_normals, IntegrateParams, IntegrationMethod};
use rgbn::raster::sample::Surface;
use rgbn::raster::RgbnImage;
use std::hint::black_box;
use std::time::Instant;

/// The bench size; `RGBN_BINI_DIV=d` divides both sides by `d` (to study scaling).
fn size() -> (usize, usize) {
    let d = std::env::var("RGBN_BINI_DIV")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&d| d >= 1)
        .unwrap_or(1);
    (3840 / d, 2160 / d)
}

/// The scene of the module docs.
/// The scene of the module docs and its true height (the bumps, the torn quadrant rising
/// as `0.5 v`).
fn scene() -> (RgbnImage, Vec<f32>) {
    let (w, h) = size();
    let (img, z) = Surface::gaussians_for(h).render(w, h);
    let mut zt = z.data().to_vec();
    let mut g = GradientField::from_normals(&img);
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    for r in 0..h {
        for x in 0..w {
            if x as f64 > cx && (r as f64) < cy {
                g.q[r * w + x] += 0.5;
                zt[r * w + x] += (0.5 * (cy - r as f64)) as f32;
            }
        }
    }
    // A wobbly ellipse covering half of the frame (as benches/surface.rs).
    let k = (2.0 / std::f64::consts::PI).sqrt();
    let mask: Vec<f32> = (0..w * h)
        .map(|i| {
            let (u, v) = (((i % w) as f64 - cx) / cx, ((i / w) as f64 - cy) / cy);
            let th = v.atan2(u);
            let edge = k * (1.0 + 0.08 * (5.0 * th).sin());
            f32::from(u8::from(u.hypot(v) < edge))
        })
        .collect();
    let img = RgbnImage::new(w, h, img.color().clone(), g.to_normals(), Some(mask)).expect("scene");
    (img, zt)
}

/// RMSE and mean absolute error of `z` against `zt` over the mask, up to a constant.
fn errors(z: &[f32], zt: &[f32], mask: &[f32]) -> (f64, f64) {
    let d: Vec<f64> = (0..z.len())
        .filter(|&i| mask[i] >= 0.5)
        .map(|i| f64::from(z[i]) - f64::from(zt[i]))
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let rmse = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    let mae = d.iter().map(|v| (v - mean).abs()).sum::<f64>() / n;
    (rmse, mae)
}

fn bilateral(c: &mut Criterion) {
    let (img, zt) = scene();
    let params = IntegrateParams {
        method: IntegrationMethod::Bilateral,
        ..Default::default()
    };
    let t = Instant::now();
    let (z, rep) = integrate_normals(&img, &params).expect("bilateral");
    let secs = t.elapsed().as_secs_f64();
    let (rmse, mae) = errors(z.data(), &zt, img.mask().expect("mask"));
    eprintln!(
        "integrate_4k/Bilateral: {secs:.2} s, RMSE {rmse:.3} px, mean abs error {mae:.3} px \
         against the true height, {} IRLS iterations, {} solver iterations, {} pixels",
        rep.irls_iterations, rep.iterations, rep.domain_pixels
    );
    if std::env::var_os("RGBN_BINI_ONCE").is_some() {
        return;
    }
    let mut group = c.benchmark_group("integrate_4k");
    group.sample_size(10);
    group.bench_function("Bilateral", |b| {
        b.iter(|| integrate_normals(black_box(&img), &params).expect("bilateral"))
    });
    group.finish();
}

criterion_group!(benches, bilateral);
criterion_main!(benches);
