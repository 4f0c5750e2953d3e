//! Tests of the graph model: editor connections, validation, ids.

use super::*;

const G: &str = r#"(version: 1, next_id: 4, outputs: { "o": (node: 3, port: "image") }, nodes: [
    (id: 1, op: "surface", params: { "width": Int(8), "height": Int(8) }),
    (id: 2, op: "normalize", inputs: { "image": Node(1, "image") }),
    (id: 3, op: "normalize", inputs: { "image": Node(2, "image") }),
])"#;

#[test]
fn connect_checks_types_and_cycles_before_changing_the_graph() {
    let mut lg = LoadedGraph::from_text(G, "g.ron", PathBuf::from(".")).unwrap();
    let before = lg.graph.clone();
    let e = lg
        .connect(2, "image", Source::Node(1, "height".into()))
        .unwrap_err();
    assert!(matches!(e, GraphError::TypeMismatch { .. }), "{e}");
    let e = lg
        .connect(2, "image", Source::Node(3, "image".into()))
        .unwrap_err();
    assert!(matches!(e, GraphError::Cycle { .. }), "{e}");
    let e = lg.disconnect(2, "image").unwrap_err();
    assert!(matches!(e, GraphError::MissingInput { .. }), "{e}");
    assert_eq!(lg.graph, before);
    lg.connect(3, "image", Source::Node(1, "image".into()))
        .unwrap();
    assert_eq!(lg.order.last(), Some(&3));
    assert_eq!(
        lg.graph.nodes[&3].inputs["image"],
        Source::Node(1, "image".into())
    );
}

#[test]
fn editor_connect_on_an_unfinished_graph() {
    let mut g = LoadedGraph::from_text(G, "g.ron", PathBuf::from("."))
        .unwrap()
        .graph;
    let n = g.add_node("normalize", [0.0, 0.0]); // required input left unconnected
    let before = g.clone();
    let e = g
        .connect(1, "height", n, "image", Path::new("."))
        .unwrap_err();
    assert!(matches!(e, GraphError::TypeMismatch { .. }), "{e}");
    let e = g
        .connect(3, "image", 2, "image", Path::new("."))
        .unwrap_err();
    assert!(matches!(e, GraphError::Cycle { .. }), "{e}");
    let e = g
        .connect(n, "image", n, "image", Path::new("."))
        .unwrap_err();
    assert!(matches!(e, GraphError::Cycle { .. }), "{e}");
    let e = g
        .connect(1, "imag", n, "image", Path::new("."))
        .unwrap_err();
    assert!(matches!(e, GraphError::UnknownPort { .. }), "{e}");
    assert_eq!(g, before);
    g.connect(3, "image", n, "image", Path::new(".")).unwrap();
    assert_eq!(g.nodes[&n].inputs["image"], Source::Node(3, "image".into()));
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("g.ron");
    g.save(&p).unwrap();
    assert_eq!(LoadedGraph::load(&p).unwrap().graph, g);
}

#[test]
fn added_nodes_get_fresh_ids() {
    let mut g = LoadedGraph::from_text(G, "g.ron", PathBuf::from("."))
        .unwrap()
        .graph;
    g.nodes.remove(&3);
    let id = g.add_node("demo", [0.0, 0.0]);
    assert_eq!(id, 4, "ids are never reused");
    assert_eq!(g.next_id, 5);
}

/// `G` with a reroute (node 4) between nodes 1 and 3 and `extra` nodes and frames.
fn with_reroute(extra_nodes: &str, frames: &str) -> String {
    format!(
        r#"(version: 3, next_id: 9, outputs: {{ "o": (node: 3, port: "image"), "r": (node: 4, port: "out") }}, nodes: [
        (id: 1, op: "surface", params: {{ "width": Int(8), "height": Int(8) }}),
        (id: 2, op: "normalize", inputs: {{ "image": Node(1, "image") }}),
        (id: 3, op: "normalize", inputs: {{ "image": Node(4, "out") }}),
        (id: 4, op: "reroute", pos: (50.0, 20.0), inputs: {{ "in": Node(2, "image") }}),
        {extra_nodes}
    ], frames: [{frames}])"#
    )
}

fn load(text: &str) -> Result<LoadedGraph, GraphError> {
    LoadedGraph::from_text(text, "r.ron", PathBuf::from("."))
}

#[test]
fn reroutes_take_the_type_of_what_feeds_them_and_fan_out() {
    let lg = load(&with_reroute(
        r#"(id: 5, op: "reroute", inputs: { "in": Node(4, "out") }),
           (id: 6, op: "relight", inputs: { "image": Node(5, "out") }),
           (id: 7, op: "reroute", inputs: { "in": Node(1, "height") })"#,
        "",
    ))
    .unwrap();
    for id in [4, 5] {
        assert_eq!(lg.ports[&id].outputs[0].ty, PortType::Rgbn, "node {id}");
        assert_eq!(lg.ports[&id].inputs[0].name, "in");
    }
    assert_eq!(lg.ports[&7].outputs[0].ty, PortType::Scalar);
    assert_eq!(lg.output_type("r"), Some(PortType::Rgbn));
    assert!(matches!(lg.kinds[&4], NodeKind::Reroute));
    // A reroute's output into a port of another type is refused like any wire.
    let e = load(&with_reroute(
        r#"(id: 5, op: "normalize", inputs: { "image": Node(7, "out") }),
           (id: 7, op: "reroute", inputs: { "in": Node(1, "height") })"#,
        "",
    ))
    .unwrap_err();
    assert!(matches!(e, GraphError::TypeMismatch { .. }), "{e}");
}

#[test]
fn bad_reroutes_are_refused_naming_the_reroute() {
    let cases: [(&str, &str); 6] = [
        (
            r#"(id: 5, op: "reroute")"#,
            "reroute has nothing connected to its input \"in\": connect a wire into it or delete it: node 5 in r.ron",
        ),
        (
            r#"(id: 5, op: "reroute", inputs: { "in": Node(42, "image") })"#,
            "reroute input \"in\" refers to missing node 42: node 5 in r.ron",
        ),
        (
            r#"(id: 5, op: "reroute", inputs: { "in": Node(6, "out") }),
               (id: 6, op: "reroute", inputs: { "in": Node(5, "out") })"#,
            "reroute is on a loop of reroutes 5 → 6 → 5 (each feeds the next): break the loop: node 5 in r.ron",
        ),
        (
            r#"(id: 5, op: "reroute", inputs: { "inn": Node(1, "image") })"#,
            "no input port \"inn\" on reroute (did you mean \"in\"?): node 5 in r.ron",
        ),
        (
            r#"(id: 5, op: "reroute", inputs: { "in": Node(1, "imag") })"#,
            "no output port \"imag\" on node 1 (surface) (did you mean \"image\"?): node 5 in r.ron",
        ),
        (
            r#"(id: 5, op: "reroute", params: { "size": Int(3) }, inputs: { "in": Node(1, "image") })"#,
            "a reroute has no parameters (found \"size\"): node 5 in r.ron",
        ),
    ];
    for (nodes, msg) in cases {
        let e = load(&with_reroute(nodes, "")).unwrap_err();
        assert_eq!(e.to_string(), msg);
    }
    // A cycle through a reroute and operators is a cycle.
    let e = load(&with_reroute(r#""#, "").replace(
        r#"(id: 2, op: "normalize", inputs: { "image": Node(1, "image") })"#,
        r#"(id: 2, op: "normalize", inputs: { "image": Node(3, "image") })"#,
    ))
    .unwrap_err();
    match e {
        GraphError::Cycle { nodes, .. } => assert_eq!(nodes, vec![2, 3, 4]),
        other => panic!("{other}"),
    }
}

#[test]
fn frames_are_checked_against_the_nodes() {
    load(&with_reroute(
        "",
        r#"(title: "a", nodes: [1, 2]), (title: "b", nodes: [4])"#,
    ))
    .unwrap();
    let e = load(&with_reroute(
        "",
        r#"(title: "a", nodes: [1]), (title: "b", nodes: [9])"#,
    ))
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "frame 1 \"b\" names node 9, which does not exist: remove it from the frame's nodes: r.ron"
    );
    let e = load(&with_reroute(
        "",
        r#"(title: "a", nodes: [1, 2]), (title: "b", nodes: [2])"#,
    ))
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "frame 1 \"b\" holds node 2, which frame 0 \"a\" holds too: a node is in at most one frame: r.ron"
    );
    let e = load(&with_reroute("", r#"(title: "a", nodes: [3, 3])"#)).unwrap_err();
    assert!(e.to_string().contains("lists node 3 twice"), "{e}");
}

#[test]
fn editor_connects_through_reroutes_by_type() {
    let mut g = LoadedGraph::from_text(G, "g.ron", PathBuf::from("."))
        .unwrap()
        .graph;
    let base = Path::new(".");
    let r = g.add_node("reroute", [0.0, 0.0]);
    // Fed by nothing and feeding nothing: any type goes in.
    assert_eq!(g.reroute_source_type(r, base), None);
    g.connect(1, "height", r, "in", base).unwrap();
    assert_eq!(
        g.node_ports(r, base).unwrap().outputs[0].ty,
        PortType::Scalar
    );
    // Its output is a Scalar now: not into an image input.
    let e = g.connect(r, "out", 3, "image", base).unwrap_err();
    assert!(matches!(e, GraphError::TypeMismatch { .. }), "{e}");
    // Re-fed with an image, it feeds images; while it feeds an image input, a Scalar is
    // refused at its input.
    g.connect(1, "image", r, "in", base).unwrap();
    g.connect(r, "out", 3, "image", base).unwrap();
    let e = g.connect(1, "height", r, "in", base).unwrap_err();
    assert!(matches!(e, GraphError::TypeMismatch { .. }), "{e}");
    // A second reroute after it: typed through the chain; an unfed one takes its user's type.
    let r2 = g.add_node("reroute", [0.0, 0.0]);
    g.connect(r, "out", r2, "in", base).unwrap();
    assert_eq!(g.reroute_source_type(r2, base), Some(PortType::Rgbn));
    let r3 = g.add_node("reroute", [0.0, 0.0]);
    g.connect(r3, "out", 2, "image", base).unwrap();
    assert_eq!(g.reroute_sink_type(r3, base), Some(PortType::Rgbn));
    assert_eq!(g.node_ports(r3, base).unwrap().inputs[0].ty, PortType::Rgbn);
    // A loop of reroutes is a cycle.
    let e = g.connect(r2, "out", r, "in", base).unwrap_err();
    assert!(matches!(e, GraphError::Cycle { .. }), "{e}");
}
