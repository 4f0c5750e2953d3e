//! Graph evaluation of `graphs/demo.ron` at 1024²: cold (empty cache), warm (everything cached)
//! and after editing one downstream parameter (only the edited node and its descendants run).
//!
//! `cargo bench --bench graph`

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::Path;

fn demo_1024() -> LoadedGraph {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
    let mut lg = LoadedGraph::load(&path).expect("graphs/demo.ron loads");
    lg.set_param("source", "size", "1024")
        .expect("size is settable");
    lg
}

fn plan(lg: &LoadedGraph) -> Plan {
    Plan::new(lg, &BTreeMap::new(), Path::new(".")).expect("plan")
}

fn bench(c: &mut Criterion) {
    let lg = demo_1024();
    let p = plan(&lg);
    let opts = EvalOptions::default();
    let mut g = c.benchmark_group("graph_demo_1024");
    g.sample_size(10);
    g.bench_function("cold", |b| {
        b.iter(|| {
            let ev = Evaluator::default();
            black_box(ev.eval(&p, &["relit"], &opts).expect("eval"))
        })
    });
    let ev = Evaluator::default();
    ev.eval(&p, &["relit"], &opts).expect("eval");
    g.bench_function("warm", |b| {
        b.iter(|| black_box(ev.eval(&p, &["relit"], &opts).expect("eval")))
    });
    // Alternate between two values of the last filter's amount: each run misses exactly the
    // edited node and the relight (the cache keeps both variants, so alternate with a fresh
    // value each time).
    let mut k = 0u32;
    g.bench_function("one_param_edited", |b| {
        b.iter(|| {
            k += 1;
            let mut lg2 = lg.clone();
            lg2.set_param(
                "detail",
                "amount",
                &format!("{}", 0.5 + f64::from(k) * 1e-6),
            )
            .expect("set");
            black_box(ev.eval(&plan(&lg2), &["relit"], &opts).expect("eval"))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
