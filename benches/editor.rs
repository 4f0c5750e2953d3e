//! The editor's preview work per light move, without a window: relight a 2K RGBN (2048² demo
//! medallion, 4.2 MP — twice a 2048×1080 frame) and turn it into the egui image that is
//! uploaded as the texture. This is what the preview thread does for every light position
//! while the light is dragged; the graph is not re-run. Also the height view (DCT Poisson of
//! the normals, once per evaluated value).
//!
//! Zoomed out (fit to the panel), the preview renders every `⌊1/zoom⌋`-th pixel; the
//! `_stride2/3` cases measure that path.
//!
//! `RAYON_NUM_THREADS=2 cargo bench --bench editor`

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::app::preview::{color_image, preview_level, Mode, PreviewSettings};
use rgbn::ops::Value;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let img = Value::Rgbn(rgbn::raster::sample::demo_medallion(2048));
    let mut g = c.benchmark_group("preview_2048");
    g.sample_size(20);
    let mut s = PreviewSettings::default();
    let mut k = 0u32;
    g.bench_function("relight_to_texture", |b| {
        b.iter(|| {
            // A new light direction every time, as while dragging.
            k = k.wrapping_add(1);
            let a = f32::from((k % 64) as u16) / 64.0 * std::f32::consts::TAU;
            s.light = [0.5 * a.cos(), 0.5 * a.sin(), 0.75f32.sqrt()];
            black_box(color_image(&img, &s).expect("relit"))
        })
    });
    // Zoomed out to fit the default preview panel (≈ 600 px for 2048 px: zoom ≈ 0.3), the
    // preview renders pyramid level 1 (stride 2; level 2 below zoom 0.25), reduced once per
    // value and relit per light move.
    let Value::Rgbn(full) = &img else {
        unreachable!()
    };
    for stride in [2usize, 4] {
        let small = Value::Rgbn(preview_level(full, stride));
        g.bench_function(format!("relight_to_texture_stride{stride}"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let a = f32::from((k % 64) as u16) / 64.0 * std::f32::consts::TAU;
                s.light = [0.5 * a.cos(), 0.5 * a.sin(), 0.75f32.sqrt()];
                black_box(color_image(&small, &s).expect("relit"))
            })
        });
    }
    s.view = Mode::View(rgbn::render::View::Albedo);
    g.bench_function("albedo_to_texture", |b| {
        b.iter(|| black_box(color_image(&img, &s).expect("albedo")))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
