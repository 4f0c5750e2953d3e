//! Tests of the frame, reroute and group commands and of evaluation inside a group.

use super::*;
use crate::eval::{Evaluator, Plan};
use crate::graph::{LoadedGraph, PortRef};
use std::collections::BTreeMap;

/// The demo saved as `demo.ron` in a fresh folder, opened.
fn saved_demo() -> (tempfile::TempDir, Document) {
    let dir = tempfile::tempdir().unwrap();
    let mut d = Document::demo();
    d.save_as(&dir.path().join("demo.ron")).unwrap();
    (dir, d)
}

#[test]
fn frame_commands_are_undo_steps() {
    let mut d = Document::demo();
    let g0 = d.graph.clone();
    assert_eq!(d.add_frame(&[2, 3, 99], "detail"), Some(0));
    assert_eq!(d.graph.frames[0].nodes, vec![2, 3]);
    assert_eq!(d.graph.frame_of(3), Some(0));
    // A node joins at most one frame: a second frame takes node 3 over.
    assert_eq!(d.add_frame(&[3, 4], "light"), Some(1));
    assert_eq!(d.graph.frames[0].nodes, vec![2]);
    d.edit_frame(1, "relit", [200, 10, 10]);
    assert_eq!(
        (d.graph.frames[1].title.as_str(), d.graph.frames[1].color),
        ("relit", [200, 10, 10])
    );
    // Deleting the frame's last node removes the frame.
    d.delete(&[2]);
    assert_eq!(d.graph.frames.len(), 1);
    d.delete_frame(0);
    assert!(d.graph.frames.is_empty());
    assert!(
        d.graph.nodes.contains_key(&3),
        "a deleted frame keeps its nodes"
    );
    assert_eq!(d.history.undo_len(), 5);
    for _ in 0..5 {
        assert!(d.undo());
    }
    assert_eq!(d.graph, g0);
    assert_eq!(d.add_frame(&[42], "none"), None);
}

#[test]
fn a_reroute_on_a_wire_keeps_the_evaluation() {
    let mut d = Document::demo();
    let g0 = d.graph.clone();
    let r = d
        .insert_reroute(3, "image", 5, "image", [600.0, 40.0])
        .unwrap();
    assert_eq!(d.graph.nodes[&r].op, "reroute");
    assert_eq!(
        d.graph.nodes[&r].inputs["in"],
        Source::Node(3, "image".into())
    );
    assert_eq!(
        d.graph.nodes[&5].inputs["image"],
        Source::Node(r, "out".into())
    );
    // No such wire: refused, nothing changed.
    let before = d.graph.clone();
    assert!(d
        .insert_reroute(2, "image", 5, "image", [0.0, 0.0])
        .is_err());
    assert_eq!(d.graph, before);
    // The plan reads node 3 directly: the same instances and keys as without the reroute.
    let keys = |g: &Graph| {
        let lg = LoadedGraph::from_graph(g.clone(), None, ".".into()).unwrap();
        let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).unwrap();
        (
            plan.instances.len(),
            Evaluator::default().output_keys(&plan).unwrap(),
        )
    };
    assert_eq!(keys(&d.graph), keys(&g0));
    assert!(d.undo());
    assert_eq!(d.graph, g0);
}

#[test]
fn group_writes_a_new_library_file_and_undo_restores_the_graph() {
    let (dir, mut d) = saved_demo();
    let g0 = d.graph.clone();
    // An unsaved graph cannot be grouped (its subgraph has nowhere to go).
    let mut unsaved = Document::demo();
    let e = unsaved.group(&[2, 3], "g", &[]).unwrap_err();
    assert!(e.to_string().contains("save the graph first"), "{e}");
    // A file of that name exists: the next free name is used.
    std::fs::create_dir(dir.path().join("lib")).unwrap();
    std::fs::write(dir.path().join("lib/my_group.ron"), "keep me").unwrap();
    assert_eq!(d.lib_path_for("My group"), "lib/my_group_2.ron");
    assert_eq!(d.lib_path_for(" ?! "), "lib/group.ron");
    let (id, file) = d.group(&[2, 3, 4], "My group", &[]).unwrap();
    assert_eq!(file, dir.path().join("lib/my_group_2.ron"));
    assert_eq!(
        std::fs::read_to_string(dir.path().join("lib/my_group.ron")).unwrap(),
        "keep me"
    );
    assert_eq!(d.graph.nodes[&id].op, "graph");
    assert_eq!(d.graph.nodes[&id].name.as_deref(), Some("My group"));
    LoadedGraph::from_graph(d.graph.clone(), None, dir.path().into()).unwrap();
    assert!(d.undo());
    assert_eq!(d.graph, g0);
    assert!(d.redo());
    // Ungroup: one step; back to the demo's shape.
    let new = d.ungroup(id).unwrap();
    assert_eq!(new.len(), 3);
    assert_eq!(d.graph.nodes.len(), g0.nodes.len());
    assert!(d.undo());
    assert!(d.graph.nodes.contains_key(&id));
}

#[test]
fn inside_a_group_the_inner_graph_is_fed_from_outside() {
    let (dir, mut d) = saved_demo();
    let (id, file) = d.group(&[2, 3, 4], "grp", &[]).unwrap();
    // The group node overrides detail's amount (exposed by editing the subgraph).
    let mut inner = Document::open(&file).unwrap();
    inner.graph.exposed.insert(
        "amount".into(),
        crate::graph::ExposedDef {
            node: 3,
            param: "amount".into(),
            doc: String::new(),
        },
    );
    d.set_param(id, "amount", crate::params::ParamValue::Float(0.8));
    let stack = [Entered {
        doc: d.clone(),
        node: id,
        selected: None,
        viewed: None,
    }];
    let ctx = context_graph(&stack, &inner.graph, &inner.base_dir());
    // The inner nodes keep their ids; node 1 (the demo source) comes in above them.
    assert!(ctx.nodes.contains_key(&2) && ctx.nodes.contains_key(&4));
    assert_eq!(
        ctx.nodes[&2].inputs["image"],
        Source::Node(1 + 5, "image".into())
    );
    assert_eq!(ctx.nodes[&6].op, "demo");
    assert_eq!(ctx.nodes.len(), 4, "only what feeds the group comes in");
    // Its relit output is the demo's: the same content key.
    let key = |g: &Graph, base: &Path, node: NodeId| {
        let mut g = g.clone();
        g.outputs = BTreeMap::from([(
            "o".to_string(),
            PortRef {
                node,
                port: "picture".into(),
            },
        )]);
        let lg = LoadedGraph::from_graph(g, None, base.to_path_buf()).unwrap();
        let plan = Plan::new(&lg, &BTreeMap::new(), base).unwrap();
        Evaluator::default().output_keys(&plan).unwrap()["o"]
    };
    let demo = Document::demo().graph;
    assert_eq!(key(&ctx, &inner.base_dir(), 4), key(&demo, dir.path(), 4));
    // No group entered: the graph itself.
    assert_eq!(context_graph(&[], &demo, dir.path()), demo);
}
