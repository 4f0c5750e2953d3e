//! The inspection views from the outside: `rgbn render --view NAME --param NAME=VALUE` (help,
//! errors, the curvature scale in the PNG) and the `view` node offering every view with its
//! parameters.

use crate::common::*;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::Value;
use rgbn::render::{self, InspectParams, Shading, View};
use std::collections::BTreeMap;
use std::path::Path;

fn in_dir(dir: &Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("rgbn runs")
}

/// The tEXt chunks of a PNG.
fn png_text(path: &Path) -> BTreeMap<String, String> {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let reader = dec.read_info().unwrap();
    reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .map(|t| (t.keyword.clone(), t.text.clone()))
        .collect()
}

#[test]
fn render_curvature_prints_its_scale_and_stores_it_in_the_png() {
    let d = tempfile::tempdir().unwrap();
    let o = in_dir(
        d.path(),
        &[
            "render",
            "--demo",
            "--demo-size",
            "64",
            "--view",
            "curvature",
            "-o",
            "c.png",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    let printed = out
        .lines()
        .find_map(|l| l.strip_prefix("curvature scale: "))
        .and_then(|l| l.split_whitespace().next())
        .unwrap_or_else(|| panic!("no scale printed: {out}"));
    let text = png_text(&d.path().join("c.png"));
    assert_eq!(
        text.get("rgbn:curvature_scale").map(String::as_str),
        Some(printed)
    );
    // The same number as the library's, and the same pixels as render.
    let img = rgbn::raster::sample::demo_medallion(64);
    let want = render::curvature_scale(&img, 0.0);
    assert_eq!(printed.parse::<f32>().unwrap(), want);
    let png = image::open(d.path().join("c.png")).unwrap().to_rgba8();
    let rgba = render::render(&img, View::Curvature, &Shading::default()).unwrap();
    assert_eq!(png.as_raw(), &rgba);

    // A given scale is used as it is.
    let o = in_dir(
        d.path(),
        &[
            "render",
            "--demo",
            "--demo-size",
            "32",
            "--view",
            "curvature",
            "--param",
            "curvature_scale=12.5",
            "-o",
            "c2.png",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = png_text(&d.path().join("c2.png"));
    assert_eq!(
        text.get("rgbn:curvature_scale").map(String::as_str),
        Some("12.5")
    );
}

#[test]
fn render_params_set_the_view_and_bad_ones_are_one_line_errors() {
    let d = tempfile::tempdir().unwrap();
    let o = in_dir(
        d.path(),
        &[
            "render",
            "--demo",
            "--demo-size",
            "48",
            "--view",
            "toon",
            "--param",
            "toon_levels=2",
            "--param",
            "toon_crease=0",
            "-o",
            "t.png",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let png = image::open(d.path().join("t.png")).unwrap().to_rgba8();
    let p = InspectParams {
        toon_levels: 2,
        toon_crease: 0.0,
        ..InspectParams::default()
    };
    let img = rgbn::raster::sample::demo_medallion(48);
    let want = render::render_with(&img, View::Toon, &Shading::default(), &p).unwrap();
    assert_eq!(png.as_raw(), &want);

    for (args, needles) in [
        (
            vec!["--view", "toon", "--param", "toon_lvels=3"],
            vec!["toon_lvels", "did you mean \"toon_levels\""],
        ),
        (
            vec!["--view", "toon", "--param", "toon_levels=0"],
            vec!["toon_levels", "out of range"],
        ),
        (
            vec!["--view", "lines", "--param", "lines_sigma=wide"],
            vec!["lines_sigma", "not a number"],
        ),
        (
            vec!["--view", "toon", "--param", "toon_levels"],
            vec!["toon_levels", "NAME=VALUE"],
        ),
        (
            vec!["--view", "curvature", "--param", "toon_levels=3"],
            vec!["toon_levels", "toon view"],
        ),
        (vec!["--view", "toonn"], vec!["did you mean \"toon\""]),
    ] {
        let mut all = vec!["render", "--demo", "--demo-size", "16", "-o", "x.png"];
        all.extend(args.iter());
        let o = in_dir(d.path(), &all);
        assert_ne!(o.status.code(), Some(0), "{args:?}");
        let err = stderr(&o);
        for n in needles {
            assert!(err.contains(n), "{args:?}: {err}");
        }
        if !args.contains(&"toonn") {
            assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        }
        assert!(!d.path().join("x.png").exists());
    }
}

#[test]
fn render_help_documents_every_view_and_parameter() {
    let o = rgbn(&["render", "--help"]);
    assert_eq!(o.status.code(), Some(0));
    let help = stdout(&o);
    for v in View::ALL {
        assert!(
            help.contains(&format!("{}: ", v.name())),
            "{}: {help}",
            v.name()
        );
    }
    for i in rgbn::params::describe::<InspectParams>() {
        assert!(help.contains(i.name), "{}", i.name);
    }
    assert!(
        help.contains("Rusinkiewicz") && help.contains("Vergne"),
        "{help}"
    );
}

const GRAPH: &str = r#"(
    version: 1,
    next_id: 5,
    outputs: {
        "toon": (node: 2, port: "picture"),
        "curvature": (node: 3, port: "picture"),
        "normals": (node: 4, port: "picture"),
    },
    nodes: [
        (id: 1, op: "surface", params: { "shape": Choice("sphere"), "width": Int(40), "height": Int(40), "radius_px": Float(15.0) }),
        (id: 2, op: "view", params: { "view": Choice("toon"), "toon_levels": Int(3), "light": Vec3((0.0, 0.0, 1.0)) }, inputs: { "image": Node(1, "image") }),
        (id: 3, op: "view", params: { "view": Choice("curvature"), "curvature_scale": Float(15.0) }, inputs: { "image": Node(1, "image") }),
        (id: 4, op: "view", inputs: { "image": Node(1, "image") }),
    ],
)"#;

fn eval_text(text: &str) -> Result<BTreeMap<String, Value>, String> {
    let lg = LoadedGraph::from_text(text, "views.ron", root().join("graphs"))
        .map_err(|e| e.to_string())?;
    let plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).map_err(|e| e.to_string())?;
    let r = Evaluator::default()
        .eval(&plan, &[], &EvalOptions::default())
        .map_err(|e| e.to_string())?;
    Ok(r.outputs)
}

#[test]
fn the_view_node_offers_the_inspection_views_with_their_parameters() {
    let out = eval_text(GRAPH).unwrap();
    let (img, _) = rgbn::raster::sample::Surface::Sphere { radius_px: 15.0 }.render_sampled(40, 40);
    let pic = |name: &str| match &out[name] {
        Value::Picture(p) => p.rgba.clone(),
        other => panic!("{name}: {:?}", other.port_type()),
    };
    let shading = Shading {
        lights: vec![rgbn::render::Light::white([0.0, 0.0, 1.0])],
        ..Shading::default()
    };
    let toon = InspectParams {
        toon_levels: 3,
        ..InspectParams::default()
    };
    assert_eq!(
        pic("toon"),
        render::render_with(&img, View::Toon, &shading, &toon).unwrap()
    );
    let curv = InspectParams {
        curvature_scale: 15.0,
        ..InspectParams::default()
    };
    let s = Shading::default();
    assert_eq!(
        pic("curvature"),
        render::render_with(&img, View::Curvature, &s, &curv).unwrap()
    );
    // A view node without parameters still shows the normals.
    assert_eq!(
        pic("normals"),
        render::render(&img, View::Normals, &s).unwrap()
    );

    let bad = GRAPH.replace("\"toon_levels\": Int(3)", "\"toon_lvls\": Int(3)");
    let e = eval_text(&bad).unwrap_err();
    assert!(e.contains("toon_lvls") && e.contains("toon_levels"), "{e}");
    let bad = GRAPH.replace("\"toon_levels\": Int(3)", "\"toon_levels\": Int(0)");
    let e = eval_text(&bad).unwrap_err();
    assert!(e.contains("toon_levels"), "{e}");
}
