//! Patterns along the pen's path (issue 13, item 5): the example graphs are surfaces, the
//! texture pattern follows its image at every level of detail, and a texture that does not fit
//! (not one channel, too large, not asked for) is a one-line error naming the node and port.

use rgbn::eval::region::RegionOptions;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::value::reduce;
use rgbn::nodes::Value;
use rgbn::raster::gradient::GradientField;
use rgbn::raster::window::Rect;
use std::collections::BTreeMap;

fn run(args: &[&str]) -> (Option<i32>, String) {
    let d = tempfile::tempdir().unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(d.path())
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn graph(name: &str) -> String {
    crate::common::graph_path(name).display().to_string()
}

#[test]
fn a_texture_that_does_not_fit_is_named_with_its_node_and_port() {
    let d = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(graph("pen_texture.ron")).unwrap();
    // An RGBN image (three normal and three colour channels) where a height image belongs,
    // and a texture connected to a pen whose pattern is not texture.
    let [rgbn, unused] = [
        (
            "rgbn_texture.ron",
            r#""texture": Node(2, "height")"#,
            r#""texture": Node(2, "image")"#,
        ),
        (
            "unused_texture.ron",
            r#""pattern": Choice("texture")"#,
            r#""pattern": Choice("rope")"#,
        ),
    ]
    .map(|(name, from, to)| crate::common::write(d.path(), name, &src.replace(from, to)));
    let big = ["eval", &graph("pen_texture.ron"), "--set", "2.width=2000"];
    for (args, says) in [
        (vec!["eval", rgbn.to_str().unwrap()], "expects scalar"),
        (
            vec!["eval", unused.to_str().unwrap()],
            "set pattern: texture",
        ),
        (big.to_vec(), "1024×1024"),
    ] {
        let (code, err) = run(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains("\"texture\"") || err.contains("texture:"),
            "names the port: {err}"
        );
        assert!(
            err.contains("node 3 \"a string of beads\""),
            "names the node: {err}"
        );
        assert!(err.contains(says), "{err}");
    }
}

#[test]
fn rope_and_texture_at_coarse_levels_reproduce_the_reduced_relief() {
    // At a coarse level the pen runs on the coarse grid with its lengths scaled (and the
    // texture reduced with the image): it stays a surface and approximates the block means of
    // the full-resolution result.
    // Levels at which a period of the pattern still spans 4 coarse pixels or more (rope: 60 px,
    // beads: 12 px): measured errors 0.09 and 0.29 of the edit for the rope at levels 1 and 2,
    // 0.14 for the beads at level 1 (at level 2 a bead is 3 px and aliases: 0.5).
    let d = tempfile::tempdir().unwrap();
    for (name, levels) in [
        ("pen_rope.ron", &[1u32, 2][..]),
        ("pen_texture.ron", &[1][..]),
    ] {
        let text = std::fs::read_to_string(crate::common::graph_path(name))
            .unwrap()
            .replacen(
                "outputs: {",
                r#"outputs: { "source": (node: 1, port: "image"),"#,
                1,
            );
        let lg = LoadedGraph::from_text(&text, name, d.path().to_path_buf()).unwrap();
        let plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let opts = EvalOptions::default();
        let whole = Evaluator::default().eval(&plan, &[], &opts).unwrap();
        let Value::Number(curl) = whole.outputs["relative_rms_curl"] else {
            panic!("a number")
        };
        assert!(curl < 1e-5, "{name}: relative curl {curl:e}");
        let full = match &whole.outputs["image"] {
            Value::Rgbn(i) => (i.width(), i.height()),
            _ => panic!("an image"),
        };
        for &level in levels {
            let s = 1usize << level;
            let r = Evaluator::default()
                .eval_region(
                    &plan,
                    "image",
                    Rect::full(full),
                    &RegionOptions { tile: 32, level },
                    &opts,
                )
                .unwrap();
            assert!(r.tiles.iter().any(|t| t.op == "pen"), "{name}: pen tiled");
            let want = reduce(&whole.outputs["image"], s);
            let unedited = reduce(&whole.outputs["source"], s);
            let (err, edit) = (
                crate::common::rms_normals(&r.value, &want),
                crate::common::rms_normals(&unedited, &want),
            );
            eprintln!("{name} level {level}: RMS normal error {err:.4}, the edit {edit:.4}");
            assert!(err < 0.35 * edit, "{name} level {level}: {err} vs {edit}");
            let Value::Rgbn(img) = &r.value else {
                panic!("an image")
            };
            let c = GradientField::from_normals(img).relative_rms_curl(None);
            assert!(c < 1e-3, "{name} level {level}: relative curl {c:e}");
        }
    }
}
