//! Frames, reroutes and groups (graph file version 3): every example graph migrates and loads;
//! a version-3 file round-trips; `rgbn check` refuses bad frames and reroutes naming them; a
//! graph evaluates the same with reroutes as without, with the same content keys; grouping
//! three nodes of the demo into a subgraph and ungrouping keeps every output bit for bit.

use crate::common::*;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::group::{self, Exposure};
use rgbn::graph::{file, At, Graph, LoadedGraph, NodeId, PortRef, Source};
use rgbn::nodes::Value;
use rgbn::params::ParamValue;
use std::collections::BTreeMap;
use std::path::Path;

/// Every bit of a value (floats by their bits, so -0 ≠ 0 and NaN = NaN of the same bits).
pub(crate) fn bits(v: &Value) -> Vec<u32> {
    let f = |p: &[f32]| p.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
    match v {
        Value::Rgbn(i) => {
            let mut out = vec![i.width() as u32, i.height() as u32];
            for p in i.color().iter().chain(i.normal().iter()) {
                out.extend(f(p));
            }
            if let Some(m) = i.mask() {
                out.extend(f(m));
            }
            out
        }
        Value::Mask(p) | Value::Scalar(p) => f(p.data()),
        Value::Picture(p) => p.rgba.iter().map(|b| u32::from(*b)).collect(),
        Value::Number(x) => {
            let b = x.to_bits();
            vec![(b >> 32) as u32, b as u32]
        }
    }
}

/// Every output of `lg` (inputs bound as the examples are) with a fresh evaluator: the
/// outputs' bits and content keys by name, and the number of instances in the plan.
pub(crate) fn outputs(
    lg: &LoadedGraph,
) -> (BTreeMap<String, Vec<u32>>, BTreeMap<String, String>, usize) {
    let plan = Plan::new(lg, &example_bindings(lg), Path::new(".")).expect("plan");
    let ev = Evaluator::default();
    let keys = ev
        .output_keys(&plan)
        .unwrap()
        .into_iter()
        .map(|(k, (key, port))| (k, format!("{key:032x}:{port}")))
        .collect();
    let r = ev.eval(&plan, &[], &EvalOptions::default()).unwrap();
    let values = r
        .outputs
        .iter()
        .map(|(k, v)| (k.clone(), bits(v)))
        .collect();
    (values, keys, plan.instances.len())
}

pub(crate) fn read(p: &Path) -> Graph {
    let text = std::fs::read_to_string(p).unwrap();
    let name = p.display().to_string();
    Graph::from_file(file::parse(&text, &name).unwrap(), &At::file(&name)).unwrap()
}

#[test]
fn every_example_graph_migrates_to_version_3_and_loads() {
    let all = all_graphs();
    assert!(all.len() > 40, "{}", all.len());
    for p in all {
        let text = std::fs::read_to_string(&p).unwrap();
        let name = p.display().to_string();
        let f = file::parse(&text, &name).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(f.version, file::CURRENT_VERSION, "{name}");
        // Written in the current schema, it reads back the same, and writes the same text.
        let t = file::to_text(&f);
        let back = file::parse(&t, &name).unwrap();
        assert_eq!(back, f, "{name}");
        assert_eq!(file::to_text(&back), t, "{name}");
        LoadedGraph::load(&p).unwrap_or_else(|e| panic!("{e}"));
        // The same file as version 2 (which had neither frames nor reroutes) migrates to it.
        if f.frames.is_empty() && f.nodes.iter().all(|n| n.op != "reroute") {
            let v2 = text.replacen("version: 3,", "version: 2,", 1);
            assert_ne!(v2, text, "{name}");
            assert_eq!(file::parse(&v2, &name).unwrap(), f, "{name} as version 2");
        }
    }
}

/// The demo (at 96 px) with reroutes on its wires: 2 → 3 through two chained reroutes, and
/// node 3 fanning out through one reroute to nodes 4, 5, 6 and the output "image"; frames
/// around some nodes. Returns it with the reroutes' ids.
fn demo_with_reroutes() -> (Graph, Graph, [NodeId; 3]) {
    let mut plain = read(&graph_path("demo.ron"));
    plain
        .nodes
        .get_mut(&1)
        .unwrap()
        .params
        .insert("size".into(), ParamValue::Int(96));
    let mut g = plain.clone();
    let a = g.add_node("reroute", [300.0, 30.0]);
    let b = g.add_node("reroute", [400.0, 30.0]);
    let c = g.add_node("reroute", [600.0, 30.0]);
    let wire = |g: &mut Graph, to: NodeId, port: &str, from: NodeId, from_port: &str| {
        g.nodes
            .get_mut(&to)
            .unwrap()
            .inputs
            .insert(port.into(), Source::Node(from, from_port.into()));
    };
    wire(&mut g, a, "in", 2, "image");
    wire(&mut g, b, "in", a, "out");
    wire(&mut g, 3, "image", b, "out");
    wire(&mut g, c, "in", 3, "image");
    for n in [4, 5, 6] {
        wire(&mut g, n, "image", c, "out");
    }
    g.outputs.insert(
        "image".into(),
        PortRef {
            node: c,
            port: "out".into(),
        },
    );
    g.add_frame(&[2, a, b], "sharpen", [90, 60, 60]).unwrap();
    g.add_frame(&[4, 5, 6, c], "views", [60, 90, 60]).unwrap();
    (plain, g, [a, b, c])
}

#[test]
fn reroutes_evaluate_as_wires_with_the_same_content_keys() {
    let (plain, with, reroutes) = demo_with_reroutes();
    let root = root().join("graphs");
    let lp = LoadedGraph::from_graph(plain, None, root.clone()).unwrap();
    let lr = LoadedGraph::from_graph(with.clone(), None, root.clone()).unwrap();
    let (vp, kp, np) = outputs(&lp);
    let (vr, kr, nr) = outputs(&lr);
    assert_eq!(nr, np, "reroutes are no instances");
    assert_eq!(kr, kp, "the same content keys");
    assert_eq!(vr.len(), 4);
    assert_eq!(vr, vp, "the same outputs, bit for bit");
    // The file form round-trips exactly, reroutes and frames included, and checks.
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("rerouted.ron");
    with.save(&p).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(
        text.contains("version: 3") && text.contains("frames:"),
        "{text}"
    );
    assert!(text.contains("op: \"reroute\""), "{text}");
    assert_eq!(read(&p), with);
    assert_eq!(read(&p).to_text(), text);
    let o = rgbn(&["check", &p.to_string_lossy()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).starts_with("ok: 9 nodes"), "{}", stdout(&o));
    // `rgbn eval` writes an output named by a reroute like any other.
    let out = d.path().join("image.exr");
    let o = rgbn(&[
        "eval",
        &p.to_string_lossy(),
        "--set",
        "source.size=32",
        "-o",
        &format!("image={}", out.display()),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.is_file());
    assert!(reroutes.iter().all(|r| with.is_reroute(*r)));
}

#[test]
fn check_refuses_bad_frames_and_reroutes_naming_file_and_node() {
    let d = tempfile::tempdir().unwrap();
    let head = r#"(version: 3, next_id: 9, outputs: { "o": (node: 2, port: "image") }, nodes: [
        (id: 1, op: "surface", params: { "width": Int(8), "height": Int(8) }),
        (id: 2, op: "normalize", inputs: { "image": Node(3, "out") }),"#;
    let cases = [
        (
            "frame.ron",
            r#"(id: 3, op: "reroute", inputs: { "in": Node(1, "image") })], frames: [(title: "Inputs", nodes: [1, 7])])"#,
            "frame 0 \"Inputs\" names node 7, which does not exist",
        ),
        (
            "dangling.ron",
            r#"(id: 3, op: "reroute", inputs: { "in": Node(8, "image") })])"#,
            "reroute input \"in\" refers to missing node 8: node 3 in ",
        ),
        (
            "unfed.ron",
            r#"(id: 3, op: "reroute")])"#,
            "reroute has nothing connected to its input \"in\"",
        ),
        (
            "loop.ron",
            r#"(id: 3, op: "reroute", inputs: { "in": Node(4, "out") }), (id: 4, op: "reroute", inputs: { "in": Node(3, "out") })])"#,
            "reroute is on a loop of reroutes 3 → 4 → 3",
        ),
    ];
    for (name, tail, want) in cases {
        let p = write(d.path(), name, &format!("{head}{tail}"));
        let o = rgbn(&["check", &p.to_string_lossy()]);
        assert_eq!(o.status.code(), Some(2), "{name}");
        let err = stderr(&o);
        assert!(err.contains(want), "{name}: {err}");
        assert!(err.trim_end().ends_with(name), "{name}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    }
    // A newer version is refused with what to do.
    let p = write(d.path(), "v4.ron", "(version: 4, next_id: 1, nodes: [])");
    let err = stderr(&rgbn(&["check", &p.to_string_lossy()]));
    assert!(
        err.contains("version 4 is newer") && err.contains("update rgbn"),
        "{err}"
    );
}

/// The closing-table number: group 3 nodes of `graphs/demo.ron` into a subgraph, ungroup;
/// the outputs before, grouped and after are bit-identical (and keep their content keys);
/// the grouped graph file and its library file round-trip exactly.
#[test]
fn group_three_demo_nodes_then_ungroup_outputs_bit_identical_and_files_round_trip() {
    let d = tempfile::tempdir().unwrap();
    let base = d.path();
    let demo = graph_path("demo.ron");
    std::fs::copy(&demo, base.join("demo.ron")).unwrap();
    let g0 = LoadedGraph::load(&base.join("demo.ron")).unwrap();
    let (v0, k0, n0) = outputs(&g0);
    assert_eq!(v0.len(), 4);

    // sharpen (2) → detail (3) → light (4): fed by node 1, read by 5, 6 and two outputs.
    let expose = [Exposure {
        node: 3,
        param: "amount".into(),
        name: "detail_amount".into(),
    }];
    let r = group::group(
        &g0.graph,
        &[2, 3, 4],
        "lib/group.ron",
        Some("group"),
        &expose,
        base,
    )
    .unwrap();
    std::fs::create_dir(base.join("lib")).unwrap();
    r.sub.save(&base.join("lib/group.ron")).unwrap();
    r.graph.save(&base.join("grouped.ron")).unwrap();
    // Both files round-trip exactly: read back equal, written back byte for byte.
    for (p, g) in [("grouped.ron", &r.graph), ("lib/group.ron", &r.sub)] {
        let text = std::fs::read_to_string(base.join(p)).unwrap();
        let back = read(&base.join(p));
        assert_eq!(&back, g, "{p}");
        assert_eq!(back.to_text(), text, "{p}");
    }
    let grouped = LoadedGraph::load(&base.join("grouped.ron")).unwrap();
    assert_eq!(grouped.graph.nodes.len(), 4);
    let (v1, k1, n1) = outputs(&grouped);
    assert_eq!(n1, n0, "the plan inlines the group");
    assert_eq!(k1, k0, "the same content keys");
    assert_eq!(v1, v0, "grouped: the same outputs, bit for bit");

    let u = group::ungroup(&r.graph, r.node, base).unwrap();
    let ungrouped = LoadedGraph::from_graph(u.graph.clone(), None, base.to_path_buf()).unwrap();
    let (v2, k2, _) = outputs(&ungrouped);
    assert_eq!(k2, k0);
    assert_eq!(v2, v0, "ungrouped: the same outputs, bit for bit");
    // The same graph up to the three nodes' ids.
    assert_eq!(u.graph.nodes.len(), g0.graph.nodes.len());
    for (old, new) in [2, 3, 4].iter().zip(&u.nodes) {
        let (a, b) = (&g0.graph.nodes[old], &u.graph.nodes[new]);
        assert_eq!(
            (&a.op, &a.name, &a.params, a.pos),
            (&b.op, &b.name, &b.params, b.pos)
        );
    }
    assert_eq!(
        u.graph.outputs.keys().collect::<Vec<_>>(),
        g0.graph.outputs.keys().collect::<Vec<_>>()
    );
}
