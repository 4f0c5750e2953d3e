//! Headline kernels at 4K (3840×2160), the sizes and operations that `BENCHMARKS.md` compares
//! with the peers in `../shared/peers` (OpenCV / NumPy on the same machine).
//!
//! Run: `cargo bench --bench kernels` (set `RAYON_NUM_THREADS=2` to match the peer runs).

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::ops::bilateral::BilateralParams;
use rgbn::ops::filter::{
    filter_gradients, filter_normals, filter_normals_general, FilterOptions, Kernel,
};
use rgbn::raster::gradient::GradientField;
use rgbn::raster::io::{self, ExrPrecision, NormalConvention};
use rgbn::raster::sample::Surface;
use rgbn::raster::RgbnImage;
use rgbn::render::{self, Shading};
use std::hint::black_box;
use std::time::Duration;

const W: usize = 3840;
const H: usize = 2160;

/// A 4K RGBN with relief at many scales (sum of Gaussians + a fine sinusoid), coloured.
fn input_4k() -> RgbnImage {
    let coarse = Surface::gaussians_for(H);
    let fine = Surface::Sinusoid {
        amplitude_px: 1.5,
        period_px: 23.0,
    };
    let (mut img, _) = coarse.render(W, H);
    let (f, _) = fine.render(W, H);
    let mut g = GradientField::from_normals(&img);
    let gf = GradientField::from_normals(&f);
    for (a, b) in g.p.iter_mut().zip(&gf.p) {
        *a += b;
    }
    for (a, b) in g.q.iter_mut().zip(&gf.q) {
        *a += b;
    }
    g.write_normals(&mut img);
    let n = W * H;
    let color = [
        (0..n).map(|i| (i % W) as f32 / W as f32).collect(),
        (0..n).map(|i| (i / W) as f32 / H as f32).collect(),
        vec![0.5; n],
    ];
    img.set_color(color).unwrap();
    img.set_mask(None).unwrap();
    img
}

/// `image` → bilateral (σ_s 2, σ_c 0.1, σ_n 0.2, colour filtered: `bilateral_rgbn_9x9`'s
/// parameters) → graph output `base`, with `img` bound to the input; the bindings must outlive
/// the evaluations.
fn bilateral_graph(img: &RgbnImage) -> (rgbn::eval::Plan, Vec<rgbn::nodes::bound::Binding>) {
    let text = r#"(
    version: 2,
    next_id: 2,
    inputs: { "image": (ty: Rgbn) },
    outputs: { "base": (node: 1, port: "base") },
    nodes: [
        (id: 1, op: "bilateral", params: {
            "filter_color": Bool(true), "sigma_color": Float(0.1),
            "sigma_normal": Float(0.2), "sigma_spatial_px": Float(2.0),
        }, inputs: { "image": Input("image") }),
    ],
)"#;
    let lg = rgbn::graph::LoadedGraph::from_text(text, "bil9.ron", std::path::PathBuf::from("."))
        .expect("graph");
    let mut plan = rgbn::eval::Plan::new(
        &lg,
        &std::collections::BTreeMap::new(),
        std::path::Path::new("."),
    )
    .expect("plan");
    let values = [("image".to_string(), rgbn::nodes::Value::Rgbn(img.clone()))].into();
    let bound = plan.bind_values(&lg, values).expect("bound");
    (plan, bound)
}

fn kernels(c: &mut Criterion) {
    let img = input_4k();
    let opts = FilterOptions::default();
    let mut group = c.benchmark_group("4k");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));

    for sigma in [8.0f32, 32.0] {
        group.bench_function(format!("normals_gauss{sigma}_normals"), |b| {
            b.iter(|| {
                filter_normals(
                    black_box(&img),
                    &[Kernel::Gaussian { sigma_px: sigma }],
                    &opts,
                )
                .unwrap()
            })
        });
    }
    // The unfused path (masks, compound kernels): the "before" of the fused sweeps.
    group.bench_function("normals_gauss8_normals_unfused", |b| {
        b.iter(|| {
            filter_normals_general(
                black_box(&img),
                &[Kernel::Gaussian { sigma_px: 8.0 }],
                &opts,
            )
            .unwrap()
        })
    });
    // Issue 13: the RGBN bilateral, 6 channels (colour and normals filtered, both in the range
    // weight), 9 × 9 window (σ_s = 2: the disc of radius 4, as OpenCV's d = 9). Peer:
    // `peer_bench.py --op bilateral9` (OpenCV's 3-channel bilateralFilter, d = 9).
    let bilateral = BilateralParams {
        sigma_spatial_px: 2.0,
        sigma_color: 0.1,
        sigma_normal: 0.2,
        filter_color: true,
        ..BilateralParams::default()
    };
    group.bench_function("bilateral_rgbn_9x9", |b| {
        b.iter(|| rgbn::ops::bilateral::bilateral(black_box(&img), &bilateral).unwrap())
    });
    // The same filter as a node: a one-node graph whose base is its output, the image bound as
    // a graph input, a fresh evaluator each iteration (so the node runs every time: keys, the
    // memory estimate, the node, the cache insertion). Peer: the same OpenCV filter.
    let (plan, _bound) = bilateral_graph(&img);
    group.bench_function("bilateral_rgbn_9x9_node", |b| {
        b.iter(|| {
            let ev = rgbn::eval::Evaluator::new(8 << 30);
            ev.eval(&plan, &["base"], &rgbn::eval::EvalOptions::default())
                .unwrap()
        })
    });
    let g0 = GradientField::from_normals(&img);
    group.bench_function("gauss8_on_gradient_field", |b| {
        b.iter_batched_ref(
            || g0.clone(),
            |g| filter_gradients(g, &[Kernel::Gaussian { sigma_px: 8.0 }], &opts, None).unwrap(),
            criterion::BatchSize::LargeInput,
        )
    });
    group.bench_function("curl", |b| b.iter(|| black_box(&g0).curl()));
    let shading = Shading::default();
    group.bench_function("relight", |b| {
        b.iter(|| render::relight(black_box(&img), &shading).unwrap())
    });
    // The preview's case: the same output buffer relit again and again (no page faults).
    let mut rgba = vec![0u8; img.len() * 4];
    group.bench_function("relight_into_reused_buffer", |b| {
        b.iter(|| render::relight_into(black_box(&img), &shading, &mut rgba).unwrap())
    });

    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("bench.exr");
    group.bench_function("exr_f32_write", |b| {
        b.iter(|| io::save_exr(&img, &exr, ExrPrecision::Full).unwrap())
    });
    group.bench_function("exr_f32_read", |b| {
        b.iter(|| io::load_exr(&exr, &Default::default()).unwrap())
    });
    let png = dir.path().join("bench.png");
    group.bench_function("png16_normal_write", |b| {
        b.iter(|| io::save_normal_map(&img, &png, 16, NormalConvention::OpenGl).unwrap())
    });
    group.bench_function("png16_normal_read", |b| {
        b.iter(|| io::load_normal_map(&png, &Default::default()).unwrap())
    });
    group.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
