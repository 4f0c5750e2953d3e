//! Tests of the graph file: round trips, migrations, refusals.

use super::*;

const V1: &str = r#"(
    version: 1,
    next_id: 3,
    outputs: { "out": (node: 2, port: "image") },
    nodes: [
        (id: 1, op: "demo", pos: (0.0, 0.0), params: { "size": Int(32) }),
        (id: 2, op: "normalize", name: Some("n"), pos: (10.0, 5.0), inputs: { "image": Node(1, "image") }),
    ],
)"#;

#[test]
fn text_round_trip_is_stable() {
    let f = parse(V1, "t.ron").unwrap();
    let t = to_text(&f);
    let g = parse(&t, "t.ron").unwrap();
    assert_eq!(f, g);
    assert_eq!(t, to_text(&g));
    assert!(t.contains("\"size\": Int(32)"), "{t}");
}

#[test]
fn v0_migrates_to_v1() {
    let v0 = r#"(version: 0, outputs: { "out": (node: 2, port: "image") }, nodes: [
            (id: 1, op: "demo", x: 0.0, y: 0.0, params: { "size": Int(32) }),
            (id: 2, op: "normalize", name: Some("n"), x: 10.0, y: 5.0, inputs: { "image": Node(1, "image") }),
        ])"#;
    assert_eq!(parse(v0, "old.ron").unwrap(), parse(V1, "new.ron").unwrap());
}

#[test]
fn v1_pen_points_become_one_path() {
    use crate::params::PathValue;
    let v1 = r#"(version: 1, next_id: 4, nodes: [
            (id: 1, op: "pen", params: { "points": Points([(1.0, 2.0), (3.0, 4.0), (5.0, 1.0)]), "closed": Bool(true), "width_px": Float(6.0) }),
            (id: 2, op: "pen", params: { "width_px": Float(6.0) }),
            (id: 3, op: "brush", params: { "points": Points([(1.0, 2.0)]) }),
        ])"#;
    let f = parse(v1, "old.ron").unwrap();
    assert_eq!(f.version, CURRENT_VERSION);
    let p = &f.nodes[0].params;
    assert_eq!(
        p["paths"],
        ParamValue::Paths(vec![PathValue::new(
            vec![[1.0, 2.0], [3.0, 4.0], [5.0, 1.0]],
            true
        )])
    );
    assert!(!p.contains_key("points") && !p.contains_key("closed"));
    assert_eq!(p["width_px"], ParamValue::Float(6.0));
    // A pen at its default path keeps it by default; other operators' points stay.
    assert!(!f.nodes[1].params.contains_key("paths"));
    assert!(f.nodes[2].params.contains_key("points"));
    // The migrated file is written in the current schema and reads back the same.
    let t = to_text(&f);
    assert!(t.contains("version: 3") && t.contains("paths"), "{t}");
    assert_eq!(parse(&t, "new.ron").unwrap(), f);
}

#[test]
fn newer_version_refused_and_syntax_errors_located() {
    let e = parse("(version: 7, next_id: 1, nodes: [])", "f.ron").unwrap_err();
    assert!(matches!(e, GraphError::UnsupportedVersion { found: 7, .. }));
    assert!(e.to_string().contains("f.ron"));
    let e = parse("(\n  version: 1,\n  next_id: 1\n  nodes: [],\n)", "f.ron").unwrap_err();
    match e {
        GraphError::Syntax { line, .. } => assert_eq!(line, 4),
        other => panic!("{other}"),
    }
}

/// A version-3 file with every part of the schema: inputs, outputs, exposed parameters,
/// nodes with names, parameters and edges, reroutes (one fanning out) and frames.
const V3: &str = r#"(
    version: 3,
    next_id: 9,
    inputs: {
        "image": (
            ty: Rgbn,
            doc: "Image to edit.",
        ),
    },
    outputs: {
        "relit": (
            node: 5,
            port: "picture",
        ),
        "sharp": (
            node: 7,
            port: "out",
        ),
    },
    exposed: {
        "amount": (
            node: 2,
            param: "amount",
            doc: "Sharpening.",
        ),
    },
    nodes: [
        (
            id: 2,
            op: "filter.sharpen",
            name: Some("sharpen"),
            pos: (240.0, 0.0),
            params: {
                "amount": Float(1.5),
            },
            inputs: {
                "image": Input("image"),
            },
        ),
        (
            id: 5,
            op: "relight",
            pos: (480.0, 0.0),
            inputs: {
                "image": Node(8, "out"),
            },
        ),
        (
            id: 7,
            op: "reroute",
            pos: (360.0, 40.5),
            inputs: {
                "in": Node(2, "image"),
            },
        ),
        (
            id: 8,
            op: "reroute",
            pos: (420.0, 60.0),
            inputs: {
                "in": Node(7, "out"),
            },
        ),
    ],
    frames: [
        (
            title: "Sharpen",
            color: (72, 96, 128),
            nodes: [
                2,
                7,
            ],
        ),
        (
            title: "",
            color: (120, 60, 40),
            nodes: [
                5,
            ],
        ),
    ],
)
"#;

#[test]
fn a_v3_file_with_frames_and_reroutes_round_trips_exactly() {
    let f = parse(V3, "v3.ron").unwrap();
    assert_eq!(f.version, 3);
    assert_eq!(f.frames.len(), 2);
    assert_eq!(f.frames[0].nodes, vec![2, 7]);
    assert_eq!(f.frames[1].color, [120, 60, 40]);
    assert_eq!(f.nodes[2].op, "reroute");
    // The text written is the text read, byte for byte.
    assert_eq!(to_text(&f), V3);
    // A frame's colour defaults; a frame needs its nodes.
    let t = "(version: 3, next_id: 2, nodes: [(id: 1, op: \"demo\")], frames: [(title: \"a\", nodes: [1])])";
    assert_eq!(
        parse(t, "d.ron").unwrap().frames[0].color,
        FrameDef::DEFAULT_COLOR
    );
    let e = parse(
        "(version: 3, next_id: 2, nodes: [], frames: [(title: \"a\")])",
        "d.ron",
    )
    .unwrap_err();
    assert!(e.to_string().contains("nodes"), "{e}");
}

#[test]
fn v2_migrates_to_v3_unchanged_and_refuses_frames() {
    let v2 = V1.replace("version: 1", "version: 2");
    let f = parse(&v2, "v2.ron").unwrap();
    assert_eq!(f.version, 3);
    assert!(f.frames.is_empty());
    // The same nodes, edges and outputs as written.
    let old: v2::GraphFile = ron::from_str(&v2).unwrap();
    assert_eq!(f, migrate_v2(old.clone()));
    assert_eq!(
        (f.nodes, f.outputs, f.next_id),
        (old.nodes, old.outputs, old.next_id)
    );
    // Frames are a version-3 field: a version-2 file with them is refused where they are.
    let bad = "(version: 2, next_id: 2, nodes: [],\n frames: [])";
    match parse(bad, "v2.ron").unwrap_err() {
        GraphError::Syntax { line, detail, .. } => {
            assert_eq!(line, 2);
            assert!(detail.contains("frames"), "{detail}");
        }
        other => panic!("{other}"),
    }
    // Written back, a migrated file is version 3.
    let t = to_text(&parse(&v2, "v2.ron").unwrap());
    assert!(t.contains("version: 3"), "{t}");
}
