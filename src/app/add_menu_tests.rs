use super::*;
use crate::graph::Graph;
use crate::nodes::PortType;

fn first(query: &str) -> &'static str {
    let offers = all_offers();
    offers[ranked(query, &offers)[0]].spec.id
}

#[test]
fn typing_a_prefix_puts_that_operator_first() {
    assert_eq!(first("bilat"), "bilateral");
    assert_eq!(first("Bilateral split"), "bilateral");
    assert_eq!(first("gauss"), "filter.gaussian");
    assert_eq!(first("integ"), "integrate");
    assert_eq!(first("normalize"), "normalize");
    // A word of the title: "Box blur".
    assert_eq!(first("box"), "filter.box");
    // An id after its family: filter.dog.
    assert_eq!(first("dog"), "filter.dog");
}

#[test]
fn no_query_lists_every_operator_by_category() {
    let offers = all_offers();
    let rows = ranked("", &offers);
    assert_eq!(rows.len(), offers.len());
    let cats: Vec<&str> = rows.iter().map(|&k| offers[k].spec.category).collect();
    let mut sorted = cats.clone();
    sorted.sort_unstable();
    assert_eq!(cats, sorted);
    // Within a category, the registry's (menu) order.
    for w in rows.windows(2) {
        if offers[w[0]].spec.category == offers[w[1]].spec.category {
            assert!(w[0] < w[1]);
        }
    }
}

#[test]
fn a_query_matching_nothing_lists_nothing() {
    assert!(ranked("zzzz-no-such", &all_offers()).is_empty());
}

#[test]
fn a_wire_offers_exactly_the_operators_the_core_connects() {
    let mut g = Graph::default();
    let src = g.add_node("demo", [0.0, 0.0]);
    let base = std::path::Path::new(".");
    let wire = Wire::Out {
        node: src,
        port: "image".into(),
    };
    let offers = offers_for_wire(&g, &wire, base);
    // Independently: an operator is offered iff one of its inputs has the RGBN type.
    for op in crate::nodes::registry() {
        let s = op.spec();
        let takes = s.inputs.iter().find(|p| p.ty == PortType::Rgbn);
        let offered = offers.iter().find(|o| o.spec.id == s.id);
        assert_eq!(
            offered.and_then(|o| o.port.clone()),
            takes.map(|p| p.name.clone()),
            "{}",
            s.id
        );
    }
    assert!(offers.iter().any(|o| o.spec.id == "bilateral"));
    assert!(!offers.iter().any(|o| o.spec.id == "demo"), "no inputs");

    // Into an input: the operators with an output of the input's type.
    let dst = g.add_node("relight", [300.0, 0.0]);
    let wire = Wire::In {
        node: dst,
        port: "image".into(),
    };
    let offers = offers_for_wire(&g, &wire, base);
    for op in crate::nodes::registry() {
        let s = op.spec();
        let gives = s.outputs.iter().find(|p| p.ty == PortType::Rgbn);
        let offered = offers.iter().find(|o| o.spec.id == s.id);
        assert_eq!(
            offered.and_then(|o| o.port.clone()),
            gives.map(|p| p.name.clone()),
            "{}",
            s.id
        );
    }
    // A reroute takes any wire.
    assert!(offers
        .iter()
        .any(|o| o.spec.id == "reroute" && o.port.as_deref() == Some("out")));
}
