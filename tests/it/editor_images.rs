//! The editor opening images directly (egui_kittest, no GPU): File ▸ Open image… through the
//! file dialog and files dropped on the window add a `load` node wired into the viewed chain,
//! the preview shows the file; new nodes never overlap existing ones; a load node names its
//! file's green convention.

use super::editor::{harness, settle, small_demo};
use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use rgbn::app::placement::Rect;
use rgbn::app::start::ImageStart;
use rgbn::app::state::Document;
use rgbn::app::{Dialog, EditorApp, Then};
use rgbn::graph::{NodeId, Source};
use rgbn::nodes::Value;
use rgbn::params::ParamValue;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Size of the test image: not square, so a swapped width and height would show.
const W: u32 = 37;
const H: u32 = 23;

/// Writes a W×H normal map (a gentle ramp) as a PNG.
fn write_normal_map(path: &Path) {
    let img = image::RgbImage::from_fn(W, H, |x, _| image::Rgb([100 + (x * 2) as u8, 128, 230]));
    img.save(path).unwrap();
}

/// A file dropped on the window (as eframe hands it to egui).
#[derive(Debug)]
struct Dropped(PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

fn drop_file(h: &mut Harness<'static, EditorApp>, path: &Path) {
    h.input_mut()
        .dropped_files
        .push(Arc::new(Dropped(path.to_path_buf())));
    h.step();
}

/// The size of the RGBN image on `(node, port)`.
fn image_size(app: &EditorApp, key: &(NodeId, String)) -> Option<(usize, usize)> {
    match &app.runtime.outcome.values.get(key)?.value {
        Value::Rgbn(img) => Some((img.width(), img.height())),
        _ => None,
    }
}

/// Steps until a widget whose label contains `text` shows (the file dialog lists folders on
/// a thread).
fn wait_for_label(h: &mut Harness<'static, EditorApp>, text: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while h.query_by_label_contains(text).is_none() {
        assert!(Instant::now() < deadline, "{text:?} never showed");
        std::thread::sleep(Duration::from_millis(10));
        h.step();
    }
}

/// Every new node was drawn and keeps clear of every other node as drawn.
fn assert_new_nodes_do_not_overlap(app: &EditorApp, new: &[NodeId]) {
    let rects: BTreeMap<NodeId, Rect> = app.drawn_node_rects();
    assert_eq!(
        rects.len(),
        app.session.doc.graph.nodes.len(),
        "every node was drawn"
    );
    for (a, ra) in &rects {
        for (b, rb) in &rects {
            if a < b && (new.contains(a) || new.contains(b)) {
                assert!(
                    !ra.overlaps(rb, 0.0),
                    "node #{a} {ra:?} overlaps #{b} {rb:?}"
                );
            }
        }
    }
}

#[test]
fn open_image_replaces_the_viewed_chains_source_and_the_preview_shows_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("relief.png");
    write_normal_map(&png);
    let mut h = harness(small_demo());
    settle(&mut h);
    let before = h.state().session.doc.graph.clone();
    let renders = h.state().preview.renders;
    let viewed = h.state().session.viewed.clone().unwrap();
    assert_eq!(viewed, (3, "image".to_string()));
    assert_eq!(image_size(h.state(), &viewed), Some((96, 96)));

    // File ▸ Open image…: the file dialog, in the folder of the image; pick it, Open.
    h.state_mut().prefs.dialog_dir = Some(dir.path().to_path_buf());
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Open image…").click();
    h.run_steps(3);
    assert!(h.state().file_dialog_open());
    wait_for_label(&mut h, "relief.png");
    h.get_by_label_contains("relief.png").click();
    h.run_steps(2);
    h.get_by_label("🗀  Open").click();
    h.run_steps(3);
    assert!(!h.state().file_dialog_open());

    // One new node: a load of the file, feeding what the demo source fed.
    let g = h.state().session.doc.graph.clone();
    assert_eq!(g.nodes.len(), before.nodes.len() + 1);
    let id = *g.nodes.keys().next_back().unwrap();
    assert_eq!(g.nodes[&id].op, "load");
    let ParamValue::Path(p) = &g.nodes[&id].params["path"] else {
        panic!("a path parameter")
    };
    assert_eq!(
        std::fs::canonicalize(p).unwrap(),
        std::fs::canonicalize(&png).unwrap()
    );
    assert_eq!(
        g.nodes[&2].inputs["image"],
        Source::Node(id, "image".into())
    );
    // The old source stays, unconnected; nothing else changed.
    assert_eq!(g.nodes[&1], before.nodes[&1]);
    assert!(!g
        .nodes
        .values()
        .flat_map(|n| n.inputs.values())
        .any(|s| matches!(s, Source::Node(1, _))));
    for n in [3, 4, 5, 6] {
        assert_eq!(g.nodes[&n], before.nodes[&n]);
    }
    assert!(
        h.state().status.text.contains("relief.png"),
        "{:?}",
        h.state().status
    );

    // The viewed chain now evaluates on the file: the preview shows an image of its size.
    settle(&mut h);
    let app = h.state();
    assert!(
        app.runtime.outcome.node_errors.is_empty(),
        "{:?}",
        app.runtime.outcome.node_errors
    );
    assert_eq!(app.session.viewed.as_ref(), Some(&viewed));
    // The load node was evaluated (only the viewed chain's values are kept whole); the viewed
    // output has the file's size.
    assert!(app.runtime.outcome.keys.contains_key(&(id, "image".into())));
    assert_eq!(image_size(app, &viewed), Some((W as usize, H as usize)));
    assert!(
        app.preview.renders > renders,
        "the preview was rendered again"
    );
    assert_new_nodes_do_not_overlap(app, &[id]);

    // One undo step takes it all back.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.step();
    assert_eq!(h.state().session.doc.graph, before);
}

#[test]
fn dropping_an_image_graph_or_other_file_on_the_window() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("dropped.png");
    write_normal_map(&png);

    // On an empty graph: a load node, and the preview shows it.
    let mut h = harness(Document::new());
    h.run_steps(2);
    drop_file(&mut h, &png);
    let g = h.state().session.doc.graph.clone();
    assert_eq!(g.nodes.len(), 1);
    let id = *g.nodes.keys().next().unwrap();
    assert_eq!(g.nodes[&id].op, "load");
    assert_eq!(h.state().session.viewed, Some((id, "image".to_string())));
    settle(&mut h);
    let app = h.state();
    assert!(
        app.runtime.outcome.node_errors.is_empty(),
        "{:?}",
        app.runtime.outcome.node_errors
    );
    assert_eq!(
        image_size(app, &(id, "image".into())),
        Some((W as usize, H as usize))
    );
    assert!(app.preview.renders >= 1, "the preview shows the image");

    // Something rgbn cannot open: a clear message in the status bar, the graph unchanged.
    let txt = dir.path().join("notes.txt");
    std::fs::write(&txt, "not an image").unwrap();
    let g = h.state().session.doc.graph.clone();
    drop_file(&mut h, &txt);
    h.step();
    assert_eq!(h.state().session.doc.graph, g);
    assert!(h.state().status.error);
    h.get_by_label_contains("rgbn does not read .txt files");
    // An HSH RTI file is an RGBN input like an image: dropped, it becomes a load node.
    let rti = dir.path().join("scan.rti");
    std::fs::write(&rti, "x").unwrap();
    drop_file(&mut h, &rti);
    h.step();
    let after = &h.state().session.doc.graph;
    assert_eq!(after.nodes.len(), g.nodes.len() + 1);
    assert!(after
        .nodes
        .values()
        .any(|n| n.op == "load" && format!("{:?}", n.params.get("path")).contains("scan.rti")));

    // A graph: opened, after asking about the unsaved changes.
    let ron = dir.path().join("g.ron");
    small_demo().save_as(&ron).unwrap();
    drop_file(&mut h, &ron);
    assert_eq!(
        h.state().dialog,
        Some(Dialog::Unsaved(Then::Open(ron.display().to_string())))
    );
    h.step();
    h.get_by_label("Discard").click();
    h.run_steps(2);
    assert_eq!(h.state().session.doc.path.as_deref(), Some(ron.as_path()));
    settle(&mut h);

    // On the demo: the dropped image takes the place of its source, as Open image does.
    let before = h.state().session.doc.graph.clone();
    drop_file(&mut h, &png);
    let g = h.state().session.doc.graph.clone();
    let id = *g.nodes.keys().next_back().unwrap();
    assert_eq!(g.nodes.len(), before.nodes.len() + 1);
    assert_eq!(
        g.nodes[&2].inputs["image"],
        Source::Node(id, "image".into())
    );
    // Inside the graph's folder the path is written relative to it.
    assert_eq!(
        g.nodes[&id].params["path"],
        ParamValue::Path("dropped.png".into())
    );
    settle(&mut h);
    let app = h.state();
    assert_eq!(app.session.viewed, Some((3, "image".to_string())));
    assert_eq!(
        image_size(app, &(3, "image".into())),
        Some((W as usize, H as usize))
    );
    assert_new_nodes_do_not_overlap(app, &[id]);
}

#[test]
fn twenty_nodes_added_in_a_row_never_overlap() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let mut new = Vec::new();
    // Ten from the Add menu's command (after the selection), without a frame in between.
    for _ in 0..10 {
        new.push(h.state_mut().add_node_after_selection("normalize"));
    }
    h.run_steps(2);
    // Ten from the graph's right-click menu, all at the same occupied spot, a frame each.
    for _ in 0..10 {
        h.state_mut().apply(rgbn::app::graph_view::Action::AddNode {
            op: "curl".into(),
            pos: [240.0, 0.0],
        });
        new.push(h.state().session.selected.unwrap());
        h.step();
    }
    settle(&mut h);
    let app = h.state();
    assert_eq!(app.session.doc.graph.nodes.len(), 6 + 20);
    // None of the new ones overlaps another node, as drawn.
    assert_new_nodes_do_not_overlap(app, &new);
    // The chained ones are connected one after the other.
    let g = &app.session.doc.graph;
    for w in new[..10].windows(2) {
        assert_eq!(
            g.nodes[&w[1]].inputs["image"],
            Source::Node(w[0], "image".into())
        );
    }
}

/// Writes three Gaussian bumps (relief in both directions) as an 8-bit normal map in the
/// DirectX convention.
fn write_directx_bumps(path: &Path) {
    use rgbn::raster::io::{save_normal_map, NormalConvention};
    let (img, _) = rgbn::raster::sample::Surface::gaussians_for(96).render_sampled(96, 96);
    save_normal_map(&img, path, 8, NormalConvention::DirectX).unwrap();
}

#[test]
fn a_load_node_names_its_files_green_convention_and_asks_for_dx() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("bumps_dx.png");
    write_directx_bumps(&png);
    let app = EditorApp::on_image(&ImageStart {
        path: png.clone(),
        ..Default::default()
    })
    .unwrap();
    let id = *app.session.doc.graph.nodes.keys().next().unwrap();
    let mut h = Harness::builder()
        .with_size([1200.0, 800.0])
        .build_ui_state(super::editor::frame, app);
    settle(&mut h);
    // Read as OpenGL (dx unticked), the relief says DirectX: the node says so and asks for dx.
    wait_for_label(&mut h, "green: DirectX — tick dx");
    // (Its hover text, the evidence, is checked in src/app/green_badge_tests.rs: egui_kittest
    // did not show the tooltip after `hover()` and 60 steps.)
    assert_eq!(h.state().green.started, 1);

    // Ticked, the file is read in its own convention: the hint goes.
    h.state_mut()
        .session
        .doc
        .set_param(id, "dx", ParamValue::Bool(true));
    let deadline = Instant::now() + Duration::from_secs(30);
    while h.query_by_label("green: DirectX").is_none() {
        assert!(Instant::now() < deadline, "the badge did not change");
        std::thread::sleep(Duration::from_millis(10));
        h.step();
    }
    assert!(h.query_by_label_contains("tick dx").is_none());
    assert_eq!(h.state().green.started, 2);
}
