//! Bilateral normal integration at 4K (3840 × 2160, orthographic): the Gaussian-bumps surface
//! torn open along a half-line (a depth discontinuity seen only as a line of normal
//! discontinuity, growing to ≈ 540 px at the top edge), over a wobbly ellipse covering half
//! of the frame. Goal (BENCHMARKS.md): ≤ 10 s with the defaults (k = 2, ≤ 150 reweighting
//! iterations, energy tolerance 1e-4, solve tolerance 1e-6).
//!
//! Run: `CARGO_TARGET_DIR=… cargo bench --no-default-features --bench bini`.

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::raster::gradient::GradientField;
use rgbn::raster::integrate::{integrate_normals, IntegrateParams, IntegrationMethod};
use rgbn::raster::sample::Surface;
use rgbn::raster::RgbnImage;
use std::hint::black_box;
use std::time::Instant;

const W: usize = 3840;
const H: usize = 2160;

/// The scene of the module docs.
fn scene() -> RgbnImage {
    let (img, _) = Surface::gaussians_for(H).render(W, H);
    let mut g = GradientField::from_normals(&img);
    let (cx, cy) = (W as f64 / 2.0, H as f64 / 2.0);
    for r in 0..H {
        for x in 0..W {
            if x as f64 > cx && (r as f64) < cy {
                g.q[r * W + x] += 0.5;
            }
        }
    }
    // A wobbly ellipse covering half of the frame (as benches/surface.rs).
    let k = (2.0 / std::f64::consts::PI).sqrt();
    let mask: Vec<f32> = (0..W * H)
        .map(|i| {
            let (u, v) = (((i % W) as f64 - cx) / cx, ((i / W) as f64 - cy) / cy);
            let th = v.atan2(u);
            let edge = k * (1.0 + 0.08 * (5.0 * th).sin());
            f32::from(u8::from(u.hypot(v) < edge))
        })
        .collect();
    RgbnImage::new(W, H, img.color().clone(), g.to_normals(), Some(mask)).expect("scene")
}

fn bilateral(c: &mut Criterion) {
    let img = scene();
    let params = IntegrateParams {
        method: IntegrationMethod::Bilateral,
        ..Default::default()
    };
    let t = Instant::now();
    let (_, rep) = integrate_normals(&img, &params).expect("bilateral");
    eprintln!(
        "integrate_4k/Bilateral: {:.2} s, {} IRLS iterations, {} solver iterations, {} pixels",
        t.elapsed().as_secs_f64(),
        rep.irls_iterations,
        rep.iterations,
        rep.domain_pixels
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
