//! What the editor starts on (`rgbn IMAGE`, `rgbn edit IMAGE`, a graph, anything else refused)
//! and autosave on a timer (egui_kittest, no GPU).

use super::common::{rgbn, stderr};
use super::editor::{frame, settle, small_demo};
use egui_kittest::Harness;
use rgbn::app::start::{ImageStart, Start};
use rgbn::app::state::Document;
use rgbn::app::EditorApp;
use rgbn::nodes::Value;
use rgbn::params::ParamValue;
use std::path::Path;
use std::time::{Duration, Instant};

const W: u32 = 41;
const H: u32 = 27;

fn write_normal_map(path: &Path) {
    let img = image::RgbImage::from_fn(W, H, |x, y| {
        image::Rgb([100 + (x * 2) as u8, 90 + (y * 3) as u8, 230])
    });
    img.save(path).unwrap();
}

fn abs(p: &Path) -> String {
    std::fs::canonicalize(p)
        .unwrap()
        .to_string_lossy()
        .into_owned()
}

#[test]
fn an_image_opens_on_a_new_unsaved_graph_as_open_image_builds_it() {
    let dir = tempfile::tempdir().unwrap();
    let (n, c, m) = (
        dir.path().join("photo_normals.png"),
        dir.path().join("photo_color.png"),
        dir.path().join("photo_mask.png"),
    );
    write_normal_map(&n);
    image::RgbImage::from_pixel(W, H, image::Rgb([200, 120, 40]))
        .save(&c)
        .unwrap();
    image::GrayImage::from_fn(W, H, |x, _| image::Luma([if x < 20 { 255 } else { 0 }]))
        .save(&m)
        .unwrap();

    let start = Start::of(
        Some(&n),
        ImageStart {
            color: Some(c.clone()),
            mask: Some(m.clone()),
            dx: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        matches!(&start, Start::Image(i) if i.path == n),
        "{start:?}"
    );
    let app = start.app().unwrap();

    // The graph File ▸ Open image… builds on a new document, plus the options.
    let mut by_menu = EditorApp::new(Document::new());
    let id = by_menu.open_image(&n).expect("opens");
    let mut want = by_menu.session.doc.graph.clone();
    let node = want.nodes.get_mut(&id).unwrap();
    node.params
        .insert("color".into(), ParamValue::Path(abs(&c)));
    node.params.insert("mask".into(), ParamValue::Path(abs(&m)));
    node.params.insert("dx".into(), ParamValue::Bool(true));
    let doc = &app.session.doc;
    assert_eq!(doc.graph, want);
    assert_eq!(doc.graph.nodes.len(), 1);
    assert_eq!(doc.graph.nodes[&id].op, "load");
    assert_eq!(
        doc.graph.nodes[&id].params["path"],
        ParamValue::Path(abs(&n))
    );
    // New and unsaved, titled by the image, viewed.
    assert_eq!(doc.path, None);
    assert!(doc.is_dirty());
    assert_eq!(doc.title(), "photo_normals.png *");
    assert_eq!(app.session.viewed, Some((id, "image".to_string())));
    assert_eq!(
        doc.history.undo_len(),
        0,
        "nothing to undo in a new document"
    );

    // The editor evaluates it: the image with its mask (left 20 columns covered).
    let mut h = Harness::builder()
        .with_size([1200.0, 800.0])
        .build_ui_state(frame, app);
    settle(&mut h);
    let out = &h.state().runtime.outcome;
    assert!(out.node_errors.is_empty(), "{:?}", out.node_errors);
    let Some(Value::Rgbn(img)) = out.values.get(&(id, "image".to_string())).map(|v| &v.value)
    else {
        panic!("no image evaluated");
    };
    assert_eq!((img.width(), img.height()), (W as usize, H as usize));
    let mask = img.mask().expect("the mask was read");
    assert_eq!(mask[19], 1.0);
    assert_eq!(mask[20], 0.0);
    // --dx: green is −y, so the stored y is the file's negated.
    let file_y = f32::from(90u8) / 255.0 * 2.0 - 1.0;
    let [_, ny, _] = img.normal();
    assert!(ny[0] > 0.0 && file_y < 0.0, "y flipped: {}", ny[0]);
}

#[test]
fn graphs_open_as_graphs_and_other_files_are_refused_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let g = dir.path().join("g.ron");
    small_demo().save_as(&g).unwrap();
    assert_eq!(
        Start::of(Some(&g), ImageStart::default()),
        Ok(Start::Graph(g.clone()))
    );
    assert_eq!(Start::of(None, ImageStart::default()), Ok(Start::Demo));
    let opened = Start::of(Some(&g), ImageStart::default())
        .unwrap()
        .app()
        .unwrap();
    assert_eq!(opened.session.doc.graph, small_demo().graph);

    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "not an image").unwrap();
    let n = dir.path().join("n.png");
    write_normal_map(&n);
    let (notes_s, n_s, g_s) = (
        notes.display().to_string(),
        n.display().to_string(),
        g.display().to_string(),
    );
    let missing = dir.path().join("missing.png").display().to_string();
    let cases: [(Vec<&str>, &str, &str); 5] = [
        (vec![&notes_s], ".ron", &notes_s),
        (vec!["edit", &notes_s], "PTM", &notes_s),
        (vec!["edit", &missing], "no such file", &missing),
        (vec!["edit", &g_s, "--color", &n_s], "not to a graph", &g_s),
        (vec![&n_s, "--mask", &notes_s], "--mask", &notes_s),
    ];
    for (args, needle, file) in cases {
        let o = rgbn(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(err.contains(file), "names {file}: {err}");
    }
}

/// The editor as eframe runs it with no input: a frame is drawn only when the previous one asked
/// for a repaint (`repaint_delay`), after that delay.
fn idle_until(h: &mut Harness<'static, EditorApp>, until: Instant) {
    loop {
        let delay = h.output().viewport_output[&egui::ViewportId::ROOT].repaint_delay;
        let now = Instant::now();
        if now >= until {
            return;
        }
        if delay >= until - now {
            std::thread::sleep(until - now);
            return;
        }
        std::thread::sleep(delay.max(Duration::from_millis(5)));
        h.step();
    }
}

#[test]
fn an_edit_is_autosaved_without_any_input_after_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("g.ron");
    small_demo().save_as(&file).unwrap();
    let recovery = rgbn::app::recent::recovery_path(Some(&file));
    let mut h = Harness::builder()
        .with_size([1200.0, 800.0])
        .build_ui_state(frame, EditorApp::new(Document::open(&file).unwrap()));
    settle(&mut h);
    // The edit, then one frame (the frame it is made in), then nothing.
    h.state_mut()
        .session
        .doc
        .set_param(2, "amount", ParamValue::Float(2.5));
    h.step();
    let edited = h.state().session.doc.graph.clone();
    assert!(!recovery.exists());
    idle_until(&mut h, Instant::now() + Duration::from_secs(31));
    assert!(
        recovery.is_file(),
        "no recovery file 31 s after the edit without input"
    );
    let text = std::fs::read_to_string(&recovery).unwrap();
    let g = rgbn::graph::Graph::from_file(
        rgbn::graph::file::parse(&text, "recovery").unwrap(),
        &rgbn::graph::At::file("recovery"),
    )
    .unwrap();
    assert_eq!(g, edited, "the recovery file holds the edit");
    assert_eq!(g.nodes[&2].params["amount"], ParamValue::Float(2.5));
}
