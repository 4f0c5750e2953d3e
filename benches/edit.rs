//! Interactive edits on region evaluation (`rgbn::eval::region`): the cost of one local edit
//! and of showing its relit viewport, which should not grow with the image.
//!
//! - `edit/pen_segment_4k`: a 4K image whose pen result is cached; append one 10 px segment to
//!   a 500 px, 20 px wide path, then produce the relit 1920×1080 viewport around it at 1:1.
//!   Timed: setting the parameter, planning, and the region evaluation (what the editor does
//!   per pointer move). Every append is new (no result is ever cached already); after 20 the
//!   path is reset, untimed.
//! - `whole/pen_segment_4k`: the baseline, the same appends through the whole-image evaluator
//!   (the viewport cut from the whole relit picture), as the editor evaluates today.
//! - `edit/pen_segment_16k`: the same on a 16384² image (its procedural source is computed
//!   tile by tile like everything else, so only the viewport's tiles exist): the cost should
//!   not depend on the image's size.
//! - `edit/stamp_move_4k`: move one placement of a 64² stamp on 4K by a few pixels and produce
//!   the relit viewport.
//! - `view/relight_fit_16k`: a 16384² image fitted into a 1600×1000 window: the level whose
//!   side first fits within twice the window (level 4, 1024², one coarse pixel per 16×16) is
//!   relit whole after the light moves. Its source tiles are cached at that level (first, untimed
//!   evaluation); each iteration is a new light direction, so every relit tile is new.
//! - `tile/…`: whole-image work through tiles by tile side, against the whole-image evaluator
//!   (the measurement behind `DEFAULT_TILE` and `INTERACTIVE_TILE`).
//!
//! The edits use tiles of `INTERACTIVE_TILE` (64) pixels, the side the editor's viewports use
//! (`benches/editor.rs`, `viewport/…`, measures the editor's own path).
//!
//! Run: `cargo bench --no-default-features --bench edit` (set `RAYON_NUM_THREADS=2` to match
//! the other benches).

#[path = "support/mod.rs"]
mod support;

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::eval::region::{RegionOptions, DEFAULT_TILE, INTERACTIVE_TILE};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::value::crop;
use rgbn::raster::window::Rect;
use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};
use support::base_path;

const W: usize = 3840;
const H: usize = 2160;
/// The 16K image of `edit/pen_segment_16k`.
const BIG: usize = 16384;
const VIEW: (usize, usize) = (1920, 1080);

fn points_text(p: &[[f64; 2]]) -> String {
    p.iter()
        .map(|q| format!("{:.3}:{:.3}", q[0], q[1]))
        .collect::<Vec<_>>()
        .join(",")
}

fn graph(edit_node: &str) -> LoadedGraph {
    graph_of((W, H), edit_node)
}

fn graph_of((w, h): (usize, usize), edit_node: &str) -> LoadedGraph {
    let text = format!(
        r#"(
    version: 1,
    next_id: 5,
    outputs: {{ "relit": (node: 4, port: "picture") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int({w}), "height": Int({h}), "shape": Choice("gaussians") }}),
        (id: 2, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int(64), "height": Int(64), "shape": Choice("gaussians") }}),
        {edit_node},
        (id: 4, op: "relight", pos: (0.0, 0.0), inputs: {{ "image": Node(3, "image") }}),
    ],
)"#
    );
    LoadedGraph::from_text(&text, "edit.ron", Path::new(".").to_path_buf()).expect("graph")
}

/// The viewport of `VIEW` pixels centred on `c`, inside a `w × h` image.
fn viewport(c: [f64; 2], (w, h): (usize, usize)) -> Rect {
    let x = (c[0] as usize).saturating_sub(VIEW.0 / 2).min(w - VIEW.0);
    let y = (c[1] as usize).saturating_sub(VIEW.1 / 2).min(h - VIEW.1);
    Rect::new(x, y, VIEW.0, VIEW.1)
}

fn pen_segment(c: &mut Criterion) {
    pen_segment_on(c, "edit/pen_segment_4k", (W, H), [1600.0, 1000.0], false);
    pen_segment_on(
        c,
        "edit/pen_segment_16k",
        (BIG, BIG),
        [8000.0, 8000.0],
        false,
    );
    // The baseline: the whole-image evaluator, the viewport cut from its result.
    pen_segment_on(c, "whole/pen_segment_4k", (W, H), [1600.0, 1000.0], true);
}

/// `edit/pen_segment_…` on a `size` image, the path starting at `start`; `whole`: by the
/// whole-image evaluator instead of regions.
fn pen_segment_on(c: &mut Criterion, id: &str, size: (usize, usize), start: [f64; 2], whole: bool) {
    let mut lg = graph_of(
        size,
        r#"(id: 3, op: "pen", name: Some("pen"), pos: (0.0, 0.0), params: { "width_px": Float(20.0), "taper_px": Float(16.0), "height_px": Float(2.0) }, inputs: { "image": Node(1, "image") })"#,
    );
    let ev = Evaluator::default();
    let ropts = RegionOptions::tiles(INTERACTIVE_TILE);
    let opts = EvalOptions::default();
    let base = base_path(start);
    let view = viewport(base[base.len() - 1], size);
    let inputs = BTreeMap::new();
    let eval = |lg: &LoadedGraph| {
        let plan = Plan::new(lg, &inputs, Path::new(".")).expect("plan");
        if whole {
            let r = ev.eval(&plan, &["relit"], &opts).expect("eval");
            black_box(crop(&r.outputs["relit"], view));
        } else {
            let r = ev
                .eval_region(&plan, "relit", view, &ropts, &opts)
                .expect("eval");
            black_box(r.value);
        }
    };
    let mut serial = 0u64;
    c.bench_function(id, |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            let mut path = base.clone();
            lg.set_param("pen", "paths", &points_text(&path))
                .expect("points");
            eval(&lg);
            for i in 0..iters {
                if i % 20 == 19 {
                    path = base.clone();
                    lg.set_param("pen", "paths", &points_text(&path))
                        .expect("points");
                    eval(&lg);
                }
                // A new direction every time: no result of an earlier append is reused.
                serial += 1;
                let a = 1.0 + 0.7 * ((serial as f64) * 0.618_034).fract();
                let last = path[path.len() - 1];
                path.push([last[0] + 10.0 * a.cos(), last[1] + 10.0 * a.sin()]);
                let t0 = Instant::now();
                lg.set_param("pen", "paths", &points_text(&path))
                    .expect("points");
                eval(&lg);
                total += t0.elapsed();
            }
            total
        });
    });
}

fn stamp_move(c: &mut Criterion) {
    let positions = [[1800.0, 1000.0], [2300.0, 1300.0], [1500.0, 800.0]];
    let mut lg = graph(&format!(
        r#"(id: 3, op: "stamp", name: Some("stamp"), pos: (0.0, 0.0), params: {{ "positions": Points([{}]), "color": Bool(false) }}, inputs: {{ "image": Node(1, "image"), "stamp": Node(2, "image") }})"#,
        positions
            .iter()
            .map(|p| format!("({:.1}, {:.1})", p[0], p[1]))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    let ev = Evaluator::default();
    let ropts = RegionOptions::tiles(INTERACTIVE_TILE);
    let opts = EvalOptions::default();
    let view = viewport(positions[0], (W, H));
    let inputs = BTreeMap::new();
    let mut serial = 0u64;
    c.bench_function("edit/stamp_move_4k", |b| {
        b.iter(|| {
            // Placement 0 moves a few pixels, each time to a place it has not been.
            serial += 1;
            let t = (serial as f64) * 0.618_034;
            let mut p = positions;
            p[0] = [
                positions[0][0] + 40.0 * t.fract() - 20.0,
                positions[0][1] + 40.0 * (t * 1.7).fract() - 20.0,
            ];
            lg.set_param("stamp", "positions", &points_text(&p))
                .expect("positions");
            let plan = Plan::new(&lg, &inputs, Path::new(".")).expect("plan");
            let r = ev
                .eval_region(&plan, "relit", view, &ropts, &opts)
                .expect("eval");
            black_box(r.value)
        });
    });
}

/// The level at which a `size` image fits a `window`: the finest whose image is at most twice
/// the window on both axes (a 1–2 Mpx level for a 16K image in a 1600 × 1000 window).
fn fit_level(size: (usize, usize), window: (usize, usize)) -> u32 {
    let mut level = 0;
    while size.0 >> level > 2 * window.0 || size.1 >> level > 2 * window.1 {
        level += 1;
    }
    level
}

fn relight_fit(c: &mut Criterion) {
    let text = format!(
        r#"(
    version: 1,
    next_id: 3,
    outputs: {{ "relit": (node: 2, port: "picture") }},
    nodes: [
        (id: 1, op: "surface", pos: (0.0, 0.0), params: {{ "width": Int({BIG}), "height": Int({BIG}), "shape": Choice("gaussians") }}),
        (id: 2, op: "relight", name: Some("light"), pos: (0.0, 0.0), inputs: {{ "image": Node(1, "image") }}),
    ],
)"#
    );
    let mut lg =
        LoadedGraph::from_text(&text, "fit.ron", Path::new(".").to_path_buf()).expect("graph");
    let ev = Evaluator::default();
    let level = fit_level((BIG, BIG), (1600, 1000));
    assert_eq!(level, 4);
    let ropts = RegionOptions {
        tile: DEFAULT_TILE,
        level,
    };
    let opts = EvalOptions::default();
    let inputs = BTreeMap::new();
    // The whole level, in its own pixels.
    let full = Rect::full((BIG >> level, BIG >> level));
    let eval = |lg: &LoadedGraph| {
        let plan = Plan::new(lg, &inputs, Path::new(".")).expect("plan");
        let r = ev
            .eval_region(&plan, "relit", full, &ropts, &opts)
            .expect("eval");
        assert_eq!(r.size, (BIG >> level, BIG >> level));
        black_box(r.value);
    };
    eval(&lg);
    let mut serial = 0u64;
    c.bench_function("view/relight_fit_16k", |b| {
        b.iter(|| {
            serial += 1;
            let a = std::f64::consts::TAU * ((serial as f64) * 0.618_034).fract();
            lg.set_param(
                "light",
                "light",
                &format!("{:.6},{:.6},1", 0.6 * a.cos(), 0.6 * a.sin()),
            )
            .expect("light");
            eval(&lg);
        });
    });
}

/// Whole-image work through tiles, by tile side, against the whole-image evaluator: a 4K
/// Gaussian (σ 2: FIR, halo 8; σ 8: recursive, halo 32) and the relit picture, every tile
/// recomputed (σ changes by 1e-6 each time).
fn tile_size(c: &mut Criterion) {
    let mut g = c.benchmark_group("tile");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    for sigma in [2.0, 8.0] {
        let mut lg = graph(&format!(
            r#"(id: 3, op: "filter.gaussian", name: Some("blur"), pos: (0.0, 0.0), params: {{ "sigma_px": Float({sigma}) }}, inputs: {{ "image": Node(1, "image") }})"#
        ));
        let ev = Evaluator::default();
        let opts = EvalOptions::default();
        let inputs = BTreeMap::new();
        let mut serial = 0u32;
        let mut next = |lg: &mut LoadedGraph| {
            serial += 1;
            let s = sigma + 1e-6 * f64::from(serial);
            lg.set_param("blur", "sigma_px", &s.to_string())
                .expect("sigma");
            Plan::new(lg, &inputs, Path::new(".")).expect("plan")
        };
        for tile in [64, 128, 256, 512] {
            let ropts = RegionOptions::tiles(tile);
            g.bench_function(format!("gauss{sigma}_relight_4k/{tile}"), |b| {
                b.iter(|| {
                    let plan = next(&mut lg);
                    let r = ev
                        .eval_region(&plan, "relit", Rect::full((W, H)), &ropts, &opts)
                        .expect("eval");
                    black_box(r.value)
                });
            });
        }
        g.bench_function(format!("gauss{sigma}_relight_4k/whole"), |b| {
            b.iter(|| {
                let plan = next(&mut lg);
                let r = ev.eval(&plan, &["relit"], &opts).expect("eval");
                black_box(r.outputs)
            });
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(10));
    targets = pen_segment, stamp_move, relight_fit, tile_size
}
criterion_main!(benches);
