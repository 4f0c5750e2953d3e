//! The example graphs under `graphs/`: round trip, evaluation, golden outputs, registry
//! coverage, and "the graph adds no maths" cross-checks.
//!
//! Golden files (`tests/golden/STEM.txt`) hold per-channel statistics and a 4×4 grid of samples
//! of every output; regenerate them (and the canonical text of the graph files) with
//! `UPDATE_GOLDEN=1 cargo test`.

use crate::common::*;
use rgbn::eval::Evaluator;
use rgbn::graph::LoadedGraph;
use rgbn::nodes::{registry, Value};
use rgbn::ops::filter::{filter_normals, FilterOptions, Kernel};
use rgbn::raster::sample::Surface;
use std::collections::BTreeSet;

fn update() -> bool {
    std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v == "1")
}

#[test]
fn every_graph_loads_saves_and_reloads_identically() {
    for path in all_graphs() {
        let text = std::fs::read_to_string(&path).unwrap();
        let lg = LoadedGraph::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let saved = lg.to_text();
        let base = path.parent().unwrap().to_path_buf();
        let again = LoadedGraph::from_text(&saved, "saved.ron", base).unwrap();
        assert_eq!(again.graph, lg.graph, "{}", path.display());
        assert_eq!(again.to_text(), saved, "{}", path.display());
        if update() {
            // Atomically: other tests read these files concurrently.
            let tmp = path.with_extension("ron.tmp");
            std::fs::write(&tmp, &saved).unwrap();
            std::fs::rename(&tmp, &path).unwrap();
        } else {
            assert_eq!(
                text,
                saved,
                "{} is not in canonical form (UPDATE_GOLDEN=1 rewrites it)",
                path.display()
            );
        }
    }
}

fn compare(golden: &str, got: &str, file: &str) {
    let g: Vec<&str> = golden.lines().collect();
    let o: Vec<&str> = got.lines().collect();
    assert_eq!(g.len(), o.len(), "{file}: channel list differs:\n{got}");
    for (gl, ol) in g.iter().zip(&o) {
        let gw: Vec<&str> = gl.split_whitespace().collect();
        let ow: Vec<&str> = ol.split_whitespace().collect();
        assert_eq!(gw[0], ow[0], "{file}: channel differs");
        assert_eq!(gw.len(), ow.len(), "{file}: {}", gw[0]);
        for (a, b) in gw[1..].iter().zip(&ow[1..]) {
            let (a, b): (f64, f64) = (a.parse().unwrap(), b.parse().unwrap());
            let tol = tolerance(gw[0], a);
            assert!(
                (a - b).abs() <= tol,
                "{file}: {} golden {a} got {b} (tolerance {tol})",
                gw[0]
            );
        }
    }
}

#[test]
fn every_graph_evaluates_and_matches_its_golden_output() {
    let out_dir = tempfile::tempdir().unwrap();
    let ev = Evaluator::default();
    for path in top_graphs() {
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let lg = LoadedGraph::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(!lg.graph.outputs.is_empty(), "{stem} has no outputs");
        let r = eval_all(&ev, &lg, out_dir.path());
        assert_eq!(r.outputs.len(), lg.graph.outputs.len(), "{stem}");
        let mut got = String::new();
        for (name, v) in &r.outputs {
            assert_eq!(Some(v.port_type()), lg.output_type(name), "{stem}.{name}");
            got.push_str(&summarise(name, v));
        }
        let golden = root().join("tests/golden").join(format!("{stem}.txt"));
        if update() {
            std::fs::write(&golden, &got).unwrap();
            continue;
        }
        let text = std::fs::read_to_string(&golden).unwrap_or_else(|_| {
            panic!("missing {} (UPDATE_GOLDEN=1 creates it)", golden.display())
        });
        compare(&text, &got, &stem);
    }
}

#[test]
fn registry_every_operator_is_documented_and_in_an_example_graph() {
    let mut used = BTreeSet::new();
    for path in all_graphs() {
        let lg = LoadedGraph::load(&path).unwrap();
        used.extend(lg.graph.nodes.values().map(|n| n.op.clone()));
    }
    assert!(
        used.contains(rgbn::nodes::GRAPH_NODE_OP),
        "no example uses a graph node"
    );
    for op in registry() {
        let s = op.spec();
        assert!(
            used.contains(s.id),
            "operator {} appears in no graphs/*.ron",
            s.id
        );
        assert!(!s.doc.trim().is_empty(), "{} has no doc", s.id);
        assert!(!s.title.trim().is_empty(), "{} has no title", s.id);
        for p in s.inputs.iter().chain(&s.outputs) {
            assert!(
                !p.doc.trim().is_empty(),
                "{}.{} port has no doc",
                s.id,
                p.name
            );
        }
        for p in op.params() {
            assert!(
                !p.meta.doc.trim().is_empty(),
                "{}.{} has no doc",
                s.id,
                p.name
            );
            if let Some((lo, hi)) = p.meta.range {
                assert!(lo <= hi, "{}.{}", s.id, p.name);
                let vals: Vec<f64> = match &p.default {
                    rgbn::params::ParamValue::Int(i) => vec![*i as f64],
                    rgbn::params::ParamValue::Float(x) => vec![*x],
                    rgbn::params::ParamValue::Vec3(v) => v.to_vec(),
                    rgbn::params::ParamValue::Floats(v) => v.clone(),
                    other => panic!("{}.{}: range on a {other:?}", s.id, p.name),
                };
                for v in vals {
                    assert!(
                        (lo..=hi).contains(&v),
                        "{}.{} default {v} outside [{lo}, {hi}]",
                        s.id,
                        p.name
                    );
                }
            }
        }
    }
}

fn image(v: &Value) -> &rgbn::RgbnImage {
    match v {
        Value::Rgbn(i) => i,
        other => panic!("expected an image, got {:?}", other.port_type()),
    }
}

#[test]
fn linear_filter_graph_equals_the_library_call() {
    let lg = LoadedGraph::load(&graph_path("filter_gaussian.ron")).unwrap();
    let r = eval_all(&Evaluator::default(), &lg, std::env::temp_dir().as_path());
    let got = image(&r.outputs["image"]);
    let (src, _) = Surface::gaussians_for(96).render_sampled(96, 96);
    let (want, _) = filter_normals(
        &src,
        &[Kernel::Gaussian { sigma_px: 2.5 }],
        &FilterOptions::default(),
    )
    .unwrap();
    assert_eq!(got, &want);
    // The golden statistics of this graph describe that same image: the filter changed it.
    assert_ne!(got.normal(), src.normal());
}

#[test]
fn reusable_graph_node_equals_its_inlined_maths() {
    let lg = LoadedGraph::load(&graph_path("subgraph.ron")).unwrap();
    let r = eval_all(&Evaluator::default(), &lg, std::env::temp_dir().as_path());
    let (src, _) = Surface::gaussians_for(80).render_sampled(80, 80);
    // lib/detail.ron: gaussian σ 0.8 then sharpen σ 4 with the exposed amount set to 2.
    let (a, _) = filter_normals(
        &src,
        &[Kernel::Gaussian { sigma_px: 0.8 }],
        &FilterOptions::default(),
    )
    .unwrap();
    let (want, _) = filter_normals(
        &a,
        &[Kernel::Sharpen {
            sigma_px: 4.0,
            amount: 2.0,
        }],
        &FilterOptions::default(),
    )
    .unwrap();
    assert_eq!(image(&r.outputs["image"]), &want);
}

#[test]
fn save_node_writes_the_image_where_asked() {
    let dir = tempfile::tempdir().unwrap();
    let lg = LoadedGraph::load(&graph_path("save.ron")).unwrap();
    let r = eval_all(&Evaluator::default(), &lg, dir.path());
    let written = dir.path().join("sphere_saved.exr");
    let back = rgbn::raster::io::load_exr(&written, &Default::default()).unwrap();
    assert_eq!(&back, image(&r.outputs["saved"]));
    let (want, _) = Surface::Sphere { radius_px: 12.0 }.render_sampled(32, 32);
    assert_eq!(back, want);
}
