//! The editor's memory stays within its budget (issue 36 item 6): eighty separate pen strokes,
//! each a new pen node chained after the one before, drawn on the demo through the editor's
//! own worker thread ([`rgbn::app::soak`]) under a budget far below what the strokes produce;
//! the process's resident memory must stay within the budget plus a margin, and the status
//! bar's figure must follow it.
//!
//! Its own test binary: the resident memory is the whole process's. The case (2048²,
//! budget + 1 GiB) is measured in release by `examples/editor_soak.rs` (BENCHMARKS.md); here
//! the demo is 1024² (a quarter of the pixels, so a quarter of the margin: 256 MiB) to keep a
//! debug build's run short. Eighty chained 1024² pens produce about 1 GiB of new normal planes
//! alone, two and a half times the budget: what the cache cannot keep must be let go.

#![cfg(feature = "gui")]

/// The allocator the `rgbn` binary runs with (freed image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

const MIB: u64 = 1 << 20;

#[test]
fn eighty_chained_pen_strokes_stay_within_the_budget_and_the_status_bar_follows_rss() {
    let budget = 384 * MIB;
    rgbn::app::memory::set_budget(budget);
    let r = rgbn::app::soak::run(1024, 80, 2);
    assert_eq!(r.pens, 80, "every stroke made a pen node");
    assert_eq!(r.samples.len(), 80);
    let above = r.peak.saturating_sub(r.baseline);
    assert!(
        above <= budget + 256 * MIB,
        "peak resident memory {} MiB above the baseline ({} MiB), budget {} MiB",
        above / MIB,
        r.baseline / MIB,
        budget / MIB
    );
    for (k, s) in r.samples.iter().enumerate() {
        assert_eq!(s.accounted.budget, budget, "stroke {}", k + 1);
        assert!(
            s.accounted.total() <= budget + 128 * MIB,
            "stroke {}: {:?}",
            k + 1,
            s.accounted
        );
        // The status bar's figure follows the resident memory the images take (the process
        // above its baseline) once the budget is in use.
        if k >= 20 {
            let rss = s.resident.saturating_sub(r.baseline) as f64;
            let shown = s.accounted.total() as f64;
            assert!(
                (shown - rss).abs() <= 0.2 * rss,
                "stroke {}: status bar {:.0} MiB, resident above baseline {:.0} MiB",
                k + 1,
                shown / MIB as f64,
                rss / MIB as f64
            );
        }
    }
    // Each refresh computes the new pen and the demo's nodes after it, as the first stroke's
    // did: never the chain before it, whatever the cache had to drop.
    let first = r.samples[0].computed;
    for (k, s) in r.samples.iter().enumerate() {
        assert!(
            s.computed <= first,
            "stroke {}: {} nodes computed, stroke 1: {first}",
            k + 1,
            s.computed
        );
    }
}
