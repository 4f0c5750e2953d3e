//! The editor's preview work per light move, without a window: relight a 2K RGBN (2048² demo
//! medallion, 4.2 MP — twice a 2048×1080 frame) and turn it into the egui image that is
//! uploaded as the texture. This is what the preview thread does for every light position
//! while the light is dragged; the graph is not re-run. Also the height view (DCT Poisson of
//! the normals, once per evaluated value).
//!
//! Zoomed out (fit to the panel), the preview renders every `⌊1/zoom⌋`-th pixel; the
//! `_stride2/3` cases measure that path.
//!
//! The viewport path (what the editor's worker does per edit, and its preview per light move
//! on an image too large to evaluate whole):
//!
//! - `viewport/pen_segment_4k`: the demo graph at 4096² with a pen after `detail`, viewed at
//!   1:1 in a 1920×1080 panel centred on the path's end, the pen's input evaluated whole (as
//!   the editor does once edits pause). Each iteration appends a 10 px segment and runs
//!   `worker::evaluate_view`: planning the graph, the viewport's tiles, and its relit picture
//!   (the egui image uploaded as the overlay texture).
//! - `viewport/pen_under_project_4k`: the same stroke viewed through an integrability
//!   projection (a global operator) while edits come: evaluated at level 2, the projection on
//!   1024² pixels; `viewport/pen_under_project_4k_full` evaluates it at the level shown (the
//!   projection at 4096²), as every edit did before.
//! - `viewport/relight_fit_16k`: the demo graph at 16384² fitted into a 1600×1000 panel: the
//!   viewport is level 4 (1024²); each iteration relights it for a new light direction, as the
//!   preview's viewport renderer does while the light is dragged.
//!
//! `RAYON_NUM_THREADS=2 cargo bench --bench editor`

#[path = "support/mod.rs"]
mod support;

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::app::preview::{color_image, preview_level, Mode, PreviewSettings, ViewSpec};
use rgbn::app::state::Document;
use rgbn::app::worker::{evaluate, evaluate_view, EvalRequest, Sizes, ViewRequest};
use rgbn::eval::Evaluator;
use rgbn::nodes::Value;
use rgbn::params::{ParamValue, PathValue};
use std::hint::black_box;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};
use support::base_path;

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

fn demo_of(size: i64) -> Document {
    let mut d = Document::demo();
    d.set_param(1, "size", ParamValue::Int(size));
    d
}

fn request(d: &Document, generation: u64, view: ViewRequest) -> EvalRequest {
    EvalRequest {
        generation,
        graph: d.graph.clone(),
        base_dir: PathBuf::from("."),
        cancel: Arc::new(AtomicBool::new(false)),
        view: Some(view),
        settings: Some(PreviewSettings::default()),
        keep: Some(Vec::new()),
    }
}

fn viewport(c: &mut Criterion) {
    let n = 4096.0;
    let mut d = demo_of(4096);
    let pen = d.add_node("pen", [0.0, 0.0]);
    d.connect(3, "image", pen, "image").expect("connect");
    for (k, v) in [("width_px", 20.0), ("taper_px", 16.0), ("height_px", 2.0)] {
        d.set_param(pen, k, ParamValue::Float(v));
    }
    let base = base_path([1500.0, 1700.0]);
    let end = base[base.len() - 1];
    let view = ViewRequest {
        node: pen,
        port: "image".into(),
        spec: ViewSpec {
            panel: [1920.0, 1080.0],
            zoom: Some(1.0),
            pan: [(0.5 * n - end[0]) as f32, (0.5 * n - end[1]) as f32],
        },
    };
    let ev = Evaluator::new(8 << 30);
    let mut sizes = Sizes::new();
    d.set_param(
        pen,
        "paths",
        ParamValue::Paths(vec![PathValue::new(base.clone(), false)]),
    );
    // The editor's whole evaluation, once edits paused.
    let _ = evaluate(&ev, &request(&d, 0, view.clone()), None);
    let mut generation = 1;
    // A new direction for every append, across criterion's calls too: no result of an
    // earlier append is ever in the cache.
    let mut serial = 0u64;
    let mut direction = move || {
        serial += 1;
        1.0 + 0.7 * ((serial as f64) * 0.618_034).fract()
    };
    c.bench_function("viewport/pen_segment_4k", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            let mut path = base.clone();
            for i in 0..iters {
                if i % 20 == 19 {
                    path = base.clone();
                    d.set_param(
                        pen,
                        "paths",
                        ParamValue::Paths(vec![PathValue::new(path.clone(), false)]),
                    );
                    let _ = evaluate_view(
                        &ev,
                        &request(&d, generation, view.clone()),
                        &mut sizes,
                        true,
                    );
                    generation += 1;
                }
                let last = path[path.len() - 1];
                let a = direction();
                path.push([last[0] + 10.0 * a.cos(), last[1] + 10.0 * a.sin()]);
                let t0 = Instant::now();
                d.set_param(
                    pen,
                    "paths",
                    ParamValue::Paths(vec![PathValue::new(path.clone(), false)]),
                );
                let r = evaluate_view(
                    &ev,
                    &request(&d, generation, view.clone()),
                    &mut sizes,
                    true,
                )
                .expect("viewport");
                total += t0.elapsed();
                assert!(r.picture.is_some() && r.level == 0);
                black_box(r);
                generation += 1;
            }
            total
        })
    });

    // The same stroke viewed through an integrability projection (a global operator): while
    // edits come the viewport is evaluated at level 2 (1024², ≤ 1 Mpx), where the projection
    // runs on a sixteenth of the pixels; `_full` evaluates the level shown (0), the projection
    // at full resolution, as every edit did before.
    let proj = d.add_node("project", [0.0, 0.0]);
    d.connect(pen, "image", proj, "image").expect("connect");
    let pview = ViewRequest {
        node: proj,
        ..view.clone()
    };
    for (id, interacting) in [
        ("viewport/pen_under_project_4k", true),
        ("viewport/pen_under_project_4k_full", false),
    ] {
        let mut g = c.benchmark_group("viewport");
        g.sample_size(10);
        let name = id.trim_start_matches("viewport/");
        g.bench_function(name, |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                let mut path = base.clone();
                for _ in 0..iters {
                    let last = path[path.len() - 1];
                    let a = direction();
                    path.push([last[0] + 10.0 * a.cos(), last[1] + 10.0 * a.sin()]);
                    let t0 = Instant::now();
                    d.set_param(
                        pen,
                        "paths",
                        ParamValue::Paths(vec![PathValue::new(path.clone(), false)]),
                    );
                    let req = request(&d, generation, pview.clone());
                    let r = evaluate_view(&ev, &req, &mut sizes, interacting).expect("viewport");
                    total += t0.elapsed();
                    assert!(r.picture.is_some() && r.level == if interacting { 2 } else { 0 });
                    black_box(r);
                    generation += 1;
                }
                total
            })
        });
        g.finish();
    }

    let big = demo_of(16384);
    let fit = ViewRequest {
        node: 3,
        port: "image".into(),
        spec: ViewSpec {
            panel: [1600.0, 1000.0],
            zoom: None,
            pan: [0.0, 0.0],
        },
    };
    let r = evaluate_view(&ev, &request(&big, 0, fit), &mut sizes, true).expect("viewport");
    assert_eq!((r.level, r.rect.w, r.rect.h), (4, 1024, 1024));
    let mut s = PreviewSettings::default();
    let mut k = 0u32;
    c.bench_function("viewport/relight_fit_16k", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let a = f32::from((k % 64) as u16) / 64.0 * std::f32::consts::TAU;
            s.light = [0.5 * a.cos(), 0.5 * a.sin(), 0.75f32.sqrt()];
            black_box(color_image(&r.value, &s).expect("relit"))
        })
    });
}

criterion_group!(benches, bench, viewport);
criterion_main!(benches);
