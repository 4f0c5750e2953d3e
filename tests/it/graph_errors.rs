//! Bad graphs and bad requests: each gives the documented error, naming the file and the node
//! (and port or parameter), never a panic.

use crate::common::*;
use rgbn::cli::{CliError, Exit};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::{GraphError, LoadedGraph};
use std::collections::BTreeMap;
use std::path::Path;

const HEAD: &str =
    "(version: 1, next_id: 10, outputs: { \"out\": (node: 2, port: \"image\") }, nodes: [";

fn graph(nodes: &str) -> String {
    format!("{HEAD}{nodes}])")
}

const SRC: &str = "(id: 1, op: \"surface\", params: { \"width\": Int(16), \"height\": Int(16) }),";

fn load_err(dir: &Path, name: &str, text: &str) -> (GraphError, String) {
    let p = write(dir, name, text);
    match LoadedGraph::load(&p) {
        Ok(_) => panic!("{name} loaded without error"),
        Err(e) => {
            let m = e.to_string();
            assert!(m.contains(name), "message does not name the file: {m}");
            assert!(!m.contains('\n'), "message is not one line: {m}");
            let again = LoadedGraph::load(&p).map(|_| ()).unwrap_err();
            assert_eq!(CliError::from(again).exit(), Exit::Usage, "{m}");
            (e, m)
        }
    }
}

fn has(m: &str, words: &[&str]) {
    for w in words {
        assert!(m.contains(w), "{w:?} not in: {m}");
    }
}

#[test]
fn file_level_errors() {
    let d = tempfile::tempdir().unwrap();
    let (e, m) = load_err(
        d.path(),
        "syntax.ron",
        "(\n    version: 1,\n    next_id: 2\n    nodes: [],\n)",
    );
    assert!(matches!(e, GraphError::Syntax { line: 4, .. }), "{m}");
    has(&m, &["line 4, column"]);

    let (e, m) = load_err(
        d.path(),
        "future.ron",
        "(version: 99, next_id: 1, nodes: [])",
    );
    assert!(matches!(
        e,
        GraphError::UnsupportedVersion { found: 99, .. }
    ));
    has(&m, &["version 99", "newer"]);

    let (_, m) = load_err(
        d.path(),
        "dup.ron",
        &graph(&format!("{SRC}(id: 1, op: \"normalize\"),")),
    );
    has(&m, &["duplicate node id 1", "node 1"]);

    let (_, m) = load_err(
        d.path(),
        "nextid.ron",
        "(version: 1, next_id: 2, nodes: [(id: 5, op: \"demo\")])",
    );
    has(&m, &["next_id 2", "largest node id 5"]);

    let (_, m) = load_err(
        d.path(),
        "field.ron",
        "(version: 1, next_id: 2, nodes: [(id: 1, op: \"demo\", parms: {})])",
    );
    has(&m, &["parms", "line 1"]);
}

#[test]
fn node_level_errors() {
    let d = tempfile::tempdir().unwrap();
    let cases: &[(&str, String, &[&str])] = &[
        (
            "unknown_op.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"filter.gausian\", inputs: {{ \"image\": Node(1, \"image\") }}),"
            )),
            &["unknown operator \"filter.gausian\"", "did you mean \"filter.gaussian\"", "node 2"],
        ),
        (
            "unknown_param.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"filter.gaussian\", params: {{ \"sigma\": Float(2.0) }}, inputs: {{ \"image\": Node(1, \"image\") }}),"
            )),
            &["unknown parameter \"sigma\"", "did you mean \"sigma_px\"", "node 2"],
        ),
        (
            "range.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"filter.gaussian\", params: {{ \"sigma_px\": Float(-3.0) }}, inputs: {{ \"image\": Node(1, \"image\") }}),"
            )),
            &["sigma_px", "-3", "out of range", "node 2"],
        ),
        (
            "kind.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"filter.gaussian\", params: {{ \"sigma_px\": Bool(true) }}, inputs: {{ \"image\": Node(1, \"image\") }}),"
            )),
            &["sigma_px", "float", "bool", "node 2"],
        ),
        (
            "choice.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"filter.gaussian\", params: {{ \"border\": Choice(\"mirrror\") }}, inputs: {{ \"image\": Node(1, \"image\") }}),"
            )),
            &["border", "did you mean \"mirror\"", "node 2"],
        ),
        (
            "missing_input.ron",
            graph(&format!("{SRC}(id: 2, op: \"filter.gaussian\"),")),
            &["required input \"image\" is not connected", "node 2"],
        ),
        (
            "type.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"filter.gaussian\", inputs: {{ \"image\": Node(1, \"height\") }}),"
            )),
            &["type mismatch", "\"image\"", "rgbn", "scalar", "node 1 output \"height\"", "node 2"],
        ),
        (
            "missing_node.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"normalize\", inputs: {{ \"image\": Node(7, \"image\") }}),"
            )),
            &["missing node 7", "node 2"],
        ),
        (
            "missing_out_port.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"normalize\", inputs: {{ \"image\": Node(1, \"imag\") }}),"
            )),
            &["no output port \"imag\"", "did you mean \"image\"", "node 2"],
        ),
        (
            "missing_in_port.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"normalize\", inputs: {{ \"image\": Node(1, \"image\"), \"img\": Node(1, \"image\") }}),"
            )),
            &["no input port \"img\"", "node 2"],
        ),
        (
            "cycle.ron",
            graph(
                "(id: 2, op: \"normalize\", inputs: { \"image\": Node(3, \"image\") }),\
                 (id: 3, op: \"normalize\", inputs: { \"image\": Node(2, \"image\") }),",
            ),
            &["cycle", "[2, 3]", "node 2"],
        ),
        (
            "output.ron",
            "(version: 1, next_id: 3, outputs: { \"out\": (node: 1, port: \"picture\") }, nodes: [(id: 1, op: \"demo\")])".to_string(),
            &["no output port \"picture\"", "node 1"],
        ),
        (
            // A closed path that crosses itself (a bow tie): §VI's inside is not defined.
            "crossing.ron",
            graph(&format!(
                "{SRC}(id: 2, op: \"pen\", name: Some(\"bow tie\"), params: {{ \"closed\": Bool(true), \"profile\": Choice(\"step\"), \"points\": Points([(2.0, 2.0), (12.0, 2.0), (2.0, 12.0), (12.0, 12.0)]) }}, inputs: {{ \"image\": Node(1, \"image\") }}),"
            )),
            &[
                "node 2",
                "bow tie",
                "points",
                "crosses itself",
                "segment 1 (points 1 → 2)",
                "segment 3 (points 3 → 0)",
                "(7.0, 7.0)",
            ],
        ),
    ];
    for (name, text, words) in cases {
        let (_, m) = load_err(d.path(), name, text);
        has(&m, words);
    }
}

#[test]
fn unknown_choice_names_are_refused_with_the_closest_name() {
    // Choices are enums behind `Choice`: a misspelt name is an error naming the parameter, the
    // node and the nearest name (it used to fall back to the default silently).
    let d = tempfile::tempdir().unwrap();
    let img = "inputs: { \"image\": Node(1, \"image\") }";
    let two = "inputs: { \"base\": Node(1, \"image\"), \"detail\": Node(1, \"image\") }";
    for (op, param, given, want, inputs) in [
        ("band", "op", "remve", "remove", img),
        ("band", "band", "hihgpass", "highpass", img),
        ("pen", "profile", "scrach", "scratch", img),
        ("pen", "mode", "analytc", "analytic", img),
        (
            "bilateral",
            "normal_metric",
            "one_minus_dt",
            "one_minus_dot",
            img,
        ),
        (
            "combine.rotation",
            "mode",
            "partial_derivativ",
            "partial_derivative",
            two,
        ),
        ("combine.linear", "replace_band", "bandpas", "bandpass", two),
    ] {
        let name = format!("choice_{}.ron", op.replace('.', "_"));
        let text = graph(&format!(
            "{SRC}(id: 2, op: \"{op}\", params: {{ \"{param}\": Choice(\"{given}\") }}, {inputs}),"
        ));
        let (_, m) = load_err(d.path(), &name, &text);
        has(
            &m,
            &[
                &format!("\"{param}\""),
                &format!("\"{given}\""),
                &format!("did you mean \"{want}\""),
                "node 2",
            ],
        );
    }
    // The same through --set.
    let p = write(
        d.path(),
        "band_set.ron",
        &graph(&format!(
            "{SRC}(id: 2, op: \"band\", inputs: {{ \"image\": Node(1, \"image\") }}),"
        )),
    );
    let mut lg = LoadedGraph::load(&p).unwrap();
    let m = lg.set_param("2", "op", "kepp").unwrap_err().to_string();
    has(&m, &["\"op\"", "did you mean \"keep\"", "node 2"]);
    lg.set_param("2", "op", "remove").unwrap();
}

#[test]
fn graph_file_cycle_and_bad_exposed_param() {
    let d = tempfile::tempdir().unwrap();
    let a = "(version: 1, next_id: 2, inputs: { \"image\": (ty: Rgbn) }, outputs: { \"image\": (node: 1, port: \"image\") }, nodes: [(id: 1, op: \"graph\", params: { \"path\": Path(\"b.ron\") }, inputs: { \"image\": Input(\"image\") })])";
    let b = a.replace("b.ron", "a.ron");
    write(d.path(), "b.ron", &b);
    let (e, m) = load_err(d.path(), "a.ron", a);
    assert!(matches!(e, GraphError::FileCycle { .. }), "{m}");
    has(&m, &["cycle", "b.ron"]);

    let lib = root().join("graphs/lib/detail.ron");
    let user = format!(
        "(version: 1, next_id: 3, outputs: {{ \"out\": (node: 2, port: \"image\") }}, nodes: [{SRC}(id: 2, op: \"graph\", params: {{ \"path\": Path({:?}), \"amont\": Float(1.0) }}, inputs: {{ \"image\": Node(1, \"image\") }})])",
        lib.display().to_string()
    );
    let (_, m) = load_err(d.path(), "exposed.ron", &user);
    has(
        &m,
        &[
            "unknown parameter \"amont\"",
            "did you mean \"amount\"",
            "node 2",
        ],
    );
    let user = user.replace("\"amont\": Float(1.0)", "\"amount\": Float(1000.0)");
    let (_, m) = load_err(d.path(), "exposed_range.ron", &user);
    has(&m, &["amount", "out of range", "node 2"]);
}

#[test]
fn set_and_bind_errors() {
    let d = tempfile::tempdir().unwrap();
    let mut lg = LoadedGraph::load(&graph_path("demo.ron")).unwrap();
    let m = lg
        .set_param("sharpn", "amount", "2")
        .unwrap_err()
        .to_string();
    has(
        &m,
        &[
            "unknown node \"sharpn\"",
            "did you mean \"sharpen\"",
            "demo.ron",
        ],
    );
    let m = lg.set_param("2", "amout", "2").unwrap_err().to_string();
    has(
        &m,
        &[
            "unknown parameter \"amout\"",
            "did you mean \"amount\"",
            "node 2",
        ],
    );
    let m = lg
        .set_param("sharpen", "amount", "lots")
        .unwrap_err()
        .to_string();
    has(&m, &["\"lots\"", "not a number", "node 2"]);
    let m = lg
        .set_param("sharpen", "sigma_px", "0")
        .unwrap_err()
        .to_string();
    has(&m, &["sigma_px", "out of range", "node 2"]);
    // A good --set takes effect (by name and by id).
    lg.set_param("source", "size", "32").unwrap();
    lg.set_param("3", "amount", "0.5").unwrap();
    assert_eq!(
        lg.graph.nodes[&1].params["size"],
        rgbn::params::ParamValue::Int(32)
    );

    // A graph input that is needed but not bound; a missing input file.
    let lg = LoadedGraph::load(&graph_path("input_image.ron")).unwrap();
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    let e = Evaluator::default()
        .eval(&plan, &[], &EvalOptions::default())
        .unwrap_err();
    has(
        &e.to_string(),
        &["graph input \"image\"", "not given", "node 1"],
    );
    let mut inputs = BTreeMap::new();
    inputs.insert("image".to_string(), d.path().join("nope.exr"));
    let plan = Plan::new(&lg, &inputs, d.path()).unwrap();
    let e = Evaluator::default()
        .eval(&plan, &[], &EvalOptions::default())
        .unwrap_err();
    has(&e.to_string(), &["nope.exr", "file not found"]);
    assert_eq!(CliError::from(e).exit(), Exit::Usage);
    inputs.clear();
    inputs.insert("imag".to_string(), d.path().join("nope.exr"));
    let e = Plan::new(&lg, &inputs, d.path()).err().unwrap();
    has(
        &e.to_string(),
        &["unknown graph input \"imag\"", "did you mean \"image\""],
    );

    // A missing file read by a node names the node.
    let p = write(
        d.path(),
        "load_missing.ron",
        "(version: 1, next_id: 2, outputs: { \"o\": (node: 1, port: \"image\") }, nodes: [(id: 1, op: \"load\", params: { \"path\": Path(\"absent.exr\") })])",
    );
    let lg = LoadedGraph::load(&p).unwrap();
    let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
    let e = Evaluator::default()
        .eval(&plan, &["o"], &EvalOptions::default())
        .unwrap_err();
    has(
        &e.to_string(),
        &["absent.exr", "file not found", "node 1", "load_missing.ron"],
    );
    let e = Evaluator::default()
        .eval(&plan, &["p"], &EvalOptions::default())
        .unwrap_err();
    has(&e.to_string(), &["unknown graph output \"p\""]);
}
