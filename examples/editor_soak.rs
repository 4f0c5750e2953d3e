//! The editor's memory soak (issue 36 item 6): separate pen strokes on the demo, each a new
//! chained pen node, through the editor's worker thread ([`rgbn::app::soak`]); prints the
//! process's resident memory against the memory budget and the status bar's figure, and the
//! whole-graph refresh after each stroke.
//!
//! `cargo run --release --example editor_soak -- SIZE STROKES SEGMENTS BUDGET`, e.g.
//! `… -- 2048 80 20 4G` (the case: 80 strokes on the 2048² demo, 20 live updates each).

use rgbn::app::memory::{parse_budget, set_budget};
use rgbn::app::soak;

/// The allocator the `rgbn` binary runs with.
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

fn gib(b: u64) -> f64 {
    b as f64 / f64::from(1u32 << 30)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(2048);
    let strokes: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(80);
    let segments: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(20);
    if let Some(b) = args.get(4) {
        match parse_budget(b) {
            Ok(b) => set_budget(b),
            Err(e) => {
                eprintln!("editor_soak: {e}");
                std::process::exit(2);
            }
        }
    }
    let budget = rgbn::app::memory::budget().unwrap_or_else(|e| {
        eprintln!("editor_soak: {e}");
        std::process::exit(2);
    });
    let r = soak::run(size, strokes, segments);
    println!(
        "{strokes} strokes on {size}² ({segments} live updates each) → {} pen nodes; budget {:.2} GiB",
        r.pens,
        gib(budget)
    );
    println!("stroke  status bar GiB  RSS GiB  RSS−baseline  ratio  refresh ms  computed");
    let mut worst: f64 = 1.0;
    for (k, s) in r.samples.iter().enumerate() {
        let above = s.resident.saturating_sub(r.baseline);
        let ratio = s.accounted.total() as f64 / above.max(1) as f64;
        if k >= r.samples.len() / 8 {
            worst = if (ratio - 1.0).abs() > (worst - 1.0).abs() {
                ratio
            } else {
                worst
            };
        }
        if k == 0 || (k + 1) % 10 == 0 || k + 1 == r.samples.len() {
            println!(
                "{:6}  {:14.2}  {:7.2}  {:12.2}  {ratio:5.2}  {:10.0}  {:8}",
                k + 1,
                gib(s.accounted.total()),
                gib(s.resident),
                gib(above),
                s.refresh.as_secs_f64() * 1e3,
                s.computed
            );
        }
    }
    let last = r.samples.last().map(|s| s.accounted).unwrap_or_default();
    println!(
        "baseline RSS {:.2} GiB; peak RSS {:.2} GiB (budget + {:.2} GiB); last status bar: cache {:.2} GiB ({} values), shown {:.3} GiB, thumbnails {:.3} GiB, pool {:.3} GiB; worst status bar / (RSS − baseline) after the first eighth: {worst:.2}",
        gib(r.baseline),
        gib(r.peak),
        gib(r.peak) - gib(budget),
        gib(last.cache as u64),
        last.cache_values,
        gib(last.shown as u64),
        gib(last.thumbs as u64),
        gib(last.pool as u64),
    );
}
