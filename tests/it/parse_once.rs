//! Parameters are parsed once: building a graph parses each node's parameter map into its
//! typed parameters once, a change parses only the node it changes, and evaluating (whole or
//! by region, at any level) parses nothing.

use rgbn::eval::region::RegionOptions;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::params::parses;
use rgbn::raster::window::Rect;
use std::collections::BTreeMap;
use std::path::Path;

#[test]
fn a_hundred_edits_of_the_demo_parse_one_node_each() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let before = parses();
    let mut lg = LoadedGraph::load(&root.join("graphs/demo.ron")).expect("demo graph");
    let first = parses() - before;
    // Six nodes; a map parsed earlier in this process (another test) is not parsed again.
    assert!(
        first <= lg.graph.nodes.len(),
        "{first} parses for six nodes"
    );
    // A small demo keeps the test fast.
    lg.set_param("source", "size", "96").expect("set size");
    let ev = Evaluator::new(1 << 28);
    let opts = EvalOptions::default();
    for k in 0..100 {
        // Values no other test uses: each change is a map never parsed before.
        let (node, param, value) = if k % 2 == 0 {
            (
                "sharpen",
                "amount",
                format!("{}", 1.0 + 1e-3 * f64::from(k) + 1.17e-5),
            )
        } else {
            (
                "light",
                "exposure_ev",
                format!("{}", 0.25 + 1e-3 * f64::from(k) + 2.3e-6),
            )
        };
        let n0 = parses();
        lg.set_param(node, param, &value).expect("set");
        assert_eq!(
            parses() - n0,
            1,
            "change {k} ({node}.{param}) parsed more than its node"
        );
        let n1 = parses();
        let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).expect("plan");
        ev.eval(&plan, &[], &opts).expect("eval");
        let level = (k % 3) as u32;
        ev.eval_region(
            &plan,
            "relit",
            Rect::new(8, 8, 40, 24),
            &RegionOptions { tile: 32, level },
            &opts,
        )
        .expect("region");
        assert_eq!(parses(), n1, "planning or evaluating parsed parameters");
    }
}
