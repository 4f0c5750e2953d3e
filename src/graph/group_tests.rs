//! Tests of grouping, ungrouping and path rebasing.

use super::*;
use crate::graph::{FrameDef, LoadedGraph};

fn demo() -> Graph {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron"))
            .unwrap();
    Graph::from_file(
        crate::graph::file::parse(&text, "demo.ron").unwrap(),
        &At::file("demo.ron"),
    )
    .unwrap()
}

#[test]
fn rebase_moves_relative_paths_between_folders_and_back() {
    let (base, lib) = (Path::new("graphs"), Path::new("graphs/lib"));
    assert_eq!(rebase("data/x.png", base, lib), "../data/x.png");
    assert_eq!(rebase("../data/x.png", lib, base), "data/x.png");
    assert_eq!(rebase("../x.png", base, lib), "../../x.png");
    assert_eq!(rebase("../../x.png", lib, base), "../x.png");
    assert_eq!(
        rebase("./a/../b.png", Path::new("."), Path::new("lib")),
        "../b.png"
    );
    assert_eq!(rebase("/abs/x.png", base, lib), "/abs/x.png");
    assert_eq!(rebase("", base, lib), "");
    // Into a folder whose name is unknown (above the working folder): absolute.
    let up = rebase("x.png", Path::new("."), Path::new("../elsewhere"));
    assert!(Path::new(&up).is_absolute(), "{up}");
    assert_eq!(Path::new(&up), std::path::absolute("x.png").unwrap());
}

#[test]
fn grouping_three_demo_nodes_makes_a_subgraph_with_their_wires_as_ports() {
    let g = demo();
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs");
    let ex = [Exposure {
        node: 3,
        param: "amount".into(),
        name: "detail_amount".into(),
    }];
    let r = group(&g, &[2, 3, 4], "lib/grp.ron", Some("grp"), &ex, &base).unwrap();
    let (p, s, gid) = (&r.graph, &r.sub, r.node);
    assert_eq!(gid, g.next_id);
    assert_eq!(p.next_id, g.next_id + 1);
    // The parent: nodes 2, 3, 4 replaced by the group node, fed by node 1.
    let keys: Vec<NodeId> = p.nodes.keys().copied().collect();
    assert_eq!(keys, vec![1, 5, 6, gid]);
    let gn = &p.nodes[&gid];
    assert_eq!(gn.op, "graph");
    assert_eq!(gn.name.as_deref(), Some("grp"));
    assert_eq!(gn.params["path"], ParamValue::Path("lib/grp.ron".into()));
    assert_eq!(gn.inputs["image"], Source::Node(1, "image".into()));
    // The mean of the three positions (240, 0), (480, 0), (720, -80).
    assert_eq!(gn.pos, [480.0, -80.0 / 3.0]);
    // Wires leaving the group: 5 and 6 read detail's image; the outputs image and relit.
    assert_eq!(
        p.nodes[&5].inputs["image"],
        Source::Node(gid, "image".into())
    );
    assert_eq!(
        p.nodes[&6].inputs["image"],
        Source::Node(gid, "image".into())
    );
    assert_eq!(
        p.outputs["image"],
        PortRef {
            node: gid,
            port: "image".into()
        }
    );
    assert_eq!(
        p.outputs["relit"],
        PortRef {
            node: gid,
            port: "picture".into()
        }
    );
    assert_eq!(p.outputs["normals"], g.outputs["normals"]);
    // The subgraph: the three nodes unchanged but for the entering wire.
    assert_eq!(s.nodes.keys().copied().collect::<Vec<_>>(), vec![2, 3, 4]);
    assert_eq!(s.nodes[&2].inputs["image"], Source::Input("image".into()));
    for id in [3, 4] {
        assert_eq!(s.nodes[&id], g.nodes[&id]);
    }
    assert_eq!(s.nodes[&2].params, g.nodes[&2].params);
    assert_eq!(s.inputs["image"].ty, crate::nodes::PortType::Rgbn);
    assert_eq!(
        s.outputs["image"],
        PortRef {
            node: 3,
            port: "image".into()
        }
    );
    assert_eq!(
        s.outputs["picture"],
        PortRef {
            node: 4,
            port: "picture".into()
        }
    );
    assert_eq!(s.exposed["detail_amount"].param, "amount");
    assert_eq!(s.next_id, 5);
    // Both validate once the subgraph is where the node says.
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("lib")).unwrap();
    s.save(&dir.path().join("lib/grp.ron")).unwrap();
    let lg = LoadedGraph::from_graph(p.clone(), None, dir.path().to_path_buf()).unwrap();
    assert_eq!(lg.param_names(gid), vec!["path", "detail_amount"]);

    // Ungrouping gives the graph back, with fresh ids for the three nodes.
    let u = ungroup(p, gid, dir.path()).unwrap();
    assert_eq!(u.nodes, vec![gid + 1, gid + 2, gid + 3]);
    let map: BTreeMap<NodeId, NodeId> = [2, 3, 4].into_iter().zip(u.nodes.clone()).collect();
    let relabel = |s: &Source| match s {
        Source::Node(n, p) => Source::Node(*map.get(n).unwrap_or(n), p.clone()),
        other => other.clone(),
    };
    assert_eq!(u.graph.nodes.len(), g.nodes.len());
    for (id, n) in &g.nodes {
        let m = &u.graph.nodes[map.get(id).unwrap_or(id)];
        assert_eq!(
            (&m.op, &m.name, &m.params, m.pos),
            (&n.op, &n.name, &n.params, n.pos)
        );
        let want: BTreeMap<String, Source> = n
            .inputs
            .iter()
            .map(|(k, s)| (k.clone(), relabel(s)))
            .collect();
        assert_eq!(m.inputs, want, "node {id}");
    }
    for (name, r) in &g.outputs {
        assert_eq!(
            u.graph.outputs[name].node,
            *map.get(&r.node).unwrap_or(&r.node)
        );
        assert_eq!(u.graph.outputs[name].port, r.port);
    }
    assert!(u.graph.exposed.is_empty() && u.graph.frames.is_empty());
}

#[test]
fn frames_and_exposed_parameters_follow_the_nodes_both_ways() {
    let mut g = demo();
    g.add_frame(&[2, 3], "inner", [1, 2, 3]).unwrap();
    g.add_frame(&[4, 5, 6], "outer", [4, 5, 6]).unwrap();
    g.exposed.insert(
        "sharp".into(),
        ExposedDef {
            node: 2,
            param: "amount".into(),
            doc: "How sharp.".into(),
        },
    );
    let base = Path::new(".");
    let r = group(&g, &[2, 3, 4], "lib/g.ron", None, &[], base).unwrap();
    // "inner" moved into the subgraph; "outer" lost node 4, and the group node did not join
    // it (it held only one of the three).
    assert_eq!(r.sub.frames, vec![g.frames[0].clone()]);
    assert_eq!(r.graph.frames.len(), 1);
    assert_eq!(r.graph.frames[0].nodes, vec![5, 6]);
    assert_eq!(r.graph.exposed["sharp"].node, r.node);
    assert_eq!(r.sub.exposed["sharp"].node, 2);
    // The group node joins a frame that held all the grouped nodes.
    let r2 = group(&g, &[5, 6], "lib/h.ron", None, &[], base).unwrap();
    assert_eq!(r2.graph.frames[1].nodes, vec![4, r2.node]);
    // An exposure must name a grouped node and a fresh name.
    let bad = Exposure {
        node: 1,
        param: "size".into(),
        name: "size".into(),
    };
    assert!(group(&g, &[2], "lib/x.ron", None, &[bad], base).is_err());
    assert!(group(&g, &[], "lib/x.ron", None, &[], base).is_err());
    assert!(group(&g, &[99], "lib/x.ron", None, &[], base).is_err());

    // Ungroup r: the inner frame comes back around the new ids of 2 and 3.
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("lib")).unwrap();
    r.sub.save(&dir.path().join("lib/g.ron")).unwrap();
    let u = ungroup(&r.graph, r.node, dir.path()).unwrap();
    let inner: Vec<&FrameDef> = u
        .graph
        .frames
        .iter()
        .filter(|f| f.title == "inner")
        .collect();
    assert_eq!(inner.len(), 1);
    assert_eq!(inner[0].nodes, u.nodes[..2].to_vec());
    assert_eq!(u.graph.exposed["sharp"].node, u.nodes[0]);
    assert_eq!(u.graph.exposed["sharp"].param, "amount");
}

#[test]
fn ungroup_applies_overrides_rebases_paths_and_refuses_other_nodes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs");
    let text = std::fs::read_to_string(root.join("subgraph.ron")).unwrap();
    let g = Graph::from_file(
        crate::graph::file::parse(&text, "subgraph.ron").unwrap(),
        &At::file("subgraph.ron"),
    )
    .unwrap();
    // Node 2 uses lib/detail.ron with amount = 2.0 exposed onto its node 2.
    let u = ungroup(&g, 2, &root).unwrap();
    assert_eq!(u.nodes.len(), 2);
    let sharpen = &u.graph.nodes[&u.nodes[1]];
    assert_eq!(sharpen.op, "filter.sharpen");
    assert_eq!(sharpen.params["amount"], ParamValue::Float(2.0));
    let denoise = &u.graph.nodes[&u.nodes[0]];
    assert_eq!(denoise.inputs["image"], Source::Node(1, "image".into()));
    assert_eq!(
        u.graph.nodes[&3].inputs["image"],
        Source::Node(u.nodes[1], "image".into())
    );
    assert_eq!(u.graph.outputs["image"].node, u.nodes[1]);
    LoadedGraph::from_graph(u.graph.clone(), None, root.clone()).unwrap();
    // A load node's relative path is rewritten for the library's folder and back.
    let mut n = NodeDef {
        id: 1,
        op: "load".into(),
        name: None,
        pos: [0.0, 0.0],
        params: BTreeMap::from([("path".into(), ParamValue::Path("data/a.exr".into()))]),
        inputs: BTreeMap::new(),
    };
    rebase_node_paths(&mut n, Path::new("graphs"), Path::new("graphs/lib"));
    assert_eq!(n.params["path"], ParamValue::Path("../data/a.exr".into()));
    // A save node's output path is relative to the output folder: it stays.
    let mut s = NodeDef {
        op: "save".into(),
        params: BTreeMap::from([("path".into(), ParamValue::Path("out.exr".into()))]),
        ..n.clone()
    };
    rebase_node_paths(&mut s, Path::new("graphs"), Path::new("graphs/lib"));
    assert_eq!(s.params["path"], ParamValue::Path("out.exr".into()));
    // Only graph nodes ungroup.
    let e = ungroup(&g, 1, &root).unwrap_err();
    assert!(e.to_string().contains("not a graph node"), "{e}");
}
