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
