//! The editor driven through its UI with egui_kittest (AccessKit queries, no GPU): open the
//! demo, add a node from the menu, connect, edit a parameter (re-evaluation, new preview),
//! undo, save and load; a pen stroke drawn on the preview.

use egui::accesskit::Role;
use egui::{Key, Modifiers, Pos2};
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use rgbn::app::graph_view::Action;
use rgbn::app::state::Document;
use rgbn::app::tools::ToolKind;
use rgbn::app::EditorApp;
use rgbn::graph::Source;
use rgbn::params::ParamValue;
use std::time::{Duration, Instant};

/// The demo graph at a small size (fast evaluations).
pub(crate) fn small_demo() -> Document {
    let mut d = Document::demo();
    d.graph
        .nodes
        .get_mut(&1)
        .unwrap()
        .params
        .insert("size".into(), ParamValue::Int(96));
    d
}

/// One editor frame as eframe runs it: `App::logic` (the worker is polled) then `App::ui`.
pub(crate) fn frame(ui: &mut egui::Ui, app: &mut EditorApp) {
    app.poll(ui.ctx());
    app.frame_ui(ui);
}

pub(crate) fn harness(doc: Document) -> Harness<'static, EditorApp> {
    Harness::builder()
        .with_size([1500.0, 900.0])
        .build_ui_state(frame, EditorApp::new(doc))
}

/// Steps frames until the worker has evaluated the current graph and the preview is rendered.
pub(crate) fn settle(h: &mut Harness<'static, EditorApp>) {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        h.step();
        if !h.state().busy() {
            break;
        }
        assert!(Instant::now() < deadline, "evaluation did not finish");
        std::thread::sleep(Duration::from_millis(10));
    }
    h.step();
    h.step();
}

#[test]
fn editor_opens_the_demo_and_previews_it() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let app = h.state();
    assert!(
        app.runtime.outcome.node_errors.is_empty(),
        "{:?}",
        app.runtime.outcome.node_errors
    );
    assert_eq!(app.session.viewed, Some((3, "image".to_string())));
    assert!(app.preview.renders >= 1, "the preview rendered");
    assert!(app.runtime.first_preview.is_some());
    assert!(app.runtime.outcome.thumbs.contains_key(&1));
    // The layout: menus, panels, node titles from the graph.
    for menu in ["File", "Edit", "Add", "View", "Help"] {
        h.get_by_role_and_label(Role::Button, menu);
    }
    h.get_by_label("Inspector");
    h.get_by_label("Preview");
    h.get_by_label("sharpen · Sharpen");
    // The viewed node's integrability (F and curl) is in the status bar; F on the nodes.
    h.get_by_label_contains(" · curl ");
    let with_f = h.query_all_by_label_contains("F ").count();
    assert!(with_f >= 2, "status bar and nodes: {with_f}");
}

#[test]
fn add_from_menu_connect_edit_undo_save_load() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let n0 = h.state().session.doc.graph.nodes.len();

    // Add a node from the menu: it goes after the selected node (3, "detail"), connected.
    h.get_by_label("Add").click();
    h.run_steps(2);
    // The menu's search takes the keyboard: narrow the list so the entry is in view.
    h.event(egui::Event::Text("normaliz".into()));
    h.run_steps(2);
    h.get_by_label("Normalize").click();
    h.run_steps(2);
    let g = h.state().session.doc.graph.clone();
    assert_eq!(g.nodes.len(), n0 + 1);
    let new = *g.nodes.keys().next_back().unwrap();
    assert_eq!(g.nodes[&new].op, "normalize");
    assert_eq!(
        g.nodes[&new].inputs.get("image"),
        Some(&Source::Node(3, "image".into()))
    );
    settle(&mut h);
    assert!(h
        .state()
        .runtime
        .outcome
        .values
        .contains_key(&(new, "image".into())));

    // Connect (as the graph view asks): the core accepts a good edge ...
    h.state_mut().apply(Action::Connect {
        from: 2,
        from_port: "image".into(),
        to: new,
        port: "image".into(),
    });
    assert_eq!(
        h.state().session.doc.graph.nodes[&new].inputs["image"],
        Source::Node(2, "image".into())
    );
    // ... and refuses a bad one, saying why, with the graph unchanged.
    let before = h.state().session.doc.graph.clone();
    h.state_mut().apply(Action::Connect {
        from: 4,
        from_port: "picture".into(),
        to: new,
        port: "image".into(),
    });
    assert_eq!(h.state().session.doc.graph, before);
    assert!(h.state().status.error);
    h.step();
    h.get_by_label_contains("connection refused");
    settle(&mut h);

    // Edit a parameter through the inspector: select "sharpen", nudge its amount slider.
    h.state_mut().view_node(2);
    h.run_steps(2);
    let renders = h.state().preview.renders;
    let requests = h.state().runtime.requests;
    let key_before = h.state().runtime.outcome.values[&(2, "image".into())].key;
    let graph_before_edit = h.state().session.doc.graph.clone();
    h.get_by_role_and_label(Role::Slider, "amount").focus();
    h.step();
    h.key_press(Key::ArrowRight);
    h.step();
    h.key_press(Key::ArrowRight);
    h.step();
    // Leave the slider (ends the interaction: one undo step).
    h.key_press(Key::Escape);
    h.step();
    let amount = h.state().session.doc.graph.nodes[&2].params["amount"].clone();
    assert_ne!(
        amount,
        ParamValue::Float(1.0),
        "the slider changed the parameter"
    );
    settle(&mut h);
    assert!(
        h.state().runtime.requests > requests,
        "a re-evaluation was requested"
    );
    let key_after = h.state().runtime.outcome.values[&(2, "image".into())].key;
    assert_ne!(key_before, key_after, "the node's output changed");
    assert!(h.state().preview.renders > renders, "the preview changed");

    // Undo restores the graph from before the edit.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.step();
    assert_eq!(h.state().session.doc.graph, graph_before_edit);
    h.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    h.step();
    assert_eq!(
        h.state().session.doc.graph.nodes[&2].params["amount"],
        amount
    );

    // Save as … through the file dialog (opened in a temporary folder), then load: the same
    // graph.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("edited.ron");
    h.state_mut().prefs.dialog_dir = Some(dir.path().to_path_buf());
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Save As…").click();
    h.run_steps(3);
    assert!(h.state().file_dialog_open());
    // The file-name field has the focus with the name's stem selected: typing replaces it.
    h.key_press_modifiers(Modifiers::COMMAND, Key::A);
    h.step();
    let field = h
        .get_all_by_role(Role::TextInput)
        .find(|n| n.value().as_deref() == Some("graph.ron"))
        .expect("the file-name field shows the default name");
    field.focus();
    h.step();
    h.key_press_modifiers(Modifiers::COMMAND, Key::A);
    h.step();
    h.get_all_by_role(Role::TextInput)
        .find(|n| n.value().as_deref() == Some("graph.ron"))
        .unwrap()
        .type_text("edited.ron");
    h.run_steps(2);
    h.get_by_label("📥  Save").click();
    h.run_steps(3);
    assert!(path.is_file(), "saved: {:?}", h.state().status);
    assert!(!h.state().file_dialog_open());
    assert!(!h.state().session.doc.is_dirty());
    let back = Document::open(&path).unwrap();
    assert_eq!(back.graph, h.state().session.doc.graph);
}

#[test]
fn recover_autosave_export_any_node_split_and_height_views() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("g.ron");
    let mut doc = small_demo();
    doc.save_as(&file).unwrap();
    // Work autosaved after the file was written, never saved: amount of node 2 changed.
    let mut edited = doc.graph.clone();
    edited
        .nodes
        .get_mut(&2)
        .unwrap()
        .params
        .insert("amount".into(), ParamValue::Float(3.0));
    std::thread::sleep(Duration::from_millis(20));
    edited
        .save(&rgbn::app::recent::recovery_path(Some(&file)))
        .unwrap();

    let mut app = EditorApp::new(Document::open(&file).unwrap());
    app.offer_recovery();
    let mut h = Harness::builder()
        .with_size([1500.0, 900.0])
        .build_ui_state(frame, app);
    h.run_steps(2);
    h.get_by_label("Recover unsaved work?");
    h.get_by_label("Recover").click();
    h.run_steps(2);
    assert_eq!(
        h.state().session.doc.graph,
        edited,
        "the autosaved graph is back"
    );
    assert!(
        h.state().session.doc.is_dirty(),
        "recovered work is unsaved"
    );
    h.state_mut().session.doc.undo();
    assert_eq!(
        h.state().session.doc.graph,
        doc.graph,
        "undo goes back to the file"
    );
    h.state_mut().session.doc.redo();
    settle(&mut h);

    // Export node 1 (not the viewed one) from its menu: the file dialog opens in the graph's
    // folder with a name from the node and port.
    assert_ne!(h.state().session.viewed.as_ref().map(|v| v.0), Some(1));
    h.state_mut().apply(Action::Export(1));
    h.run_steps(3);
    assert!(h.state().file_dialog_open());
    h.get_by_label("📥  Save").click();
    h.run_steps(3);
    // The whole-graph refresh keeps only what is shown: the export asks for node 1's value
    // and writes it when it arrives.
    settle(&mut h);
    let out = dir.path().join("node1-image.exr");
    assert!(out.is_file(), "exported: {:?}", h.state().status);
    let back = rgbn::raster::io::load_exr(&out, &Default::default()).unwrap();
    let rgbn::nodes::Value::Rgbn(orig) =
        &h.state().runtime.outcome.values[&(1, "image".into())].value
    else {
        panic!("node 1 gives an RGBN image")
    };
    assert_eq!((back.width(), back.height()), (orig.width(), orig.height()));
    for (a, b) in back.normal().iter().zip(orig.normal()) {
        assert_eq!(a, b, "EXR f32 round trip is exact");
    }

    // Split view on node 2 (its input is node 1's image).
    h.state_mut().view_node(2);
    h.run_steps(2);
    assert!(!h.state().preview.showing_before());
    h.get_by_label("before/after").click();
    h.run_steps(1);
    settle(&mut h);
    assert!(h.state().preview.showing_before());

    // Height view: the shown picture is the integrated height.
    let renders = h.state().preview.renders;
    h.get_by_role_and_label(Role::Button, "height").click();
    h.run_steps(1);
    settle(&mut h);
    assert!(h.state().preview.renders > renders);
    assert_eq!(
        h.state().preview.shown_settings().map(|s| s.view),
        Some(rgbn::app::preview::Mode::Height)
    );
}

#[test]
fn a_pen_stroke_on_the_preview_adds_a_pen_path_evaluates_and_undoes() {
    let mut h = harness(small_demo());
    settle(&mut h);
    // Choose the pen from the toolbar above the preview.
    h.get_by_label("Pen").click();
    h.run_steps(2);
    assert_eq!(h.state().tools.state.kind, ToolKind::Pen);

    let before = h.state().session.doc.graph.clone();
    let (requests, renders, steps) = {
        let a = h.state();
        (
            a.runtime.requests,
            a.preview.renders,
            a.session.doc.history.undo_len(),
        )
    };
    let pan = h.state().preview.pan;
    let path = [[20.0, 20.0], [40.0, 30.0], [60.0, 50.0], [70.0, 70.0]];
    let screen = screen_points(&h, &path);
    // Press, drag through the points, release: simulated pointer events.
    press_and_move(&mut h, &screen);
    // While drawing: the stroke is already in the graph (live), not yet an undo step.
    assert_ne!(h.state().session.doc.graph, before);
    h.drop_at(*screen.last().unwrap());
    h.step();
    h.step();

    let app = h.state();
    assert_eq!(app.preview.pan, pan, "a pen drag does not pan");
    let g = &app.session.doc.graph;
    assert_eq!(g.nodes.len(), before.nodes.len() + 1);
    let pen = *g.nodes.keys().next_back().unwrap();
    assert_eq!(g.nodes[&pen].op, "pen");
    // Inserted after the viewed node (3, "detail"): it reads it, its readers read the pen.
    assert_eq!(
        g.nodes[&pen].inputs["image"],
        Source::Node(3, "image".into())
    );
    assert_eq!(
        g.nodes[&4].inputs["image"],
        Source::Node(pen, "image".into())
    );
    let ParamValue::Paths(paths) = &g.nodes[&pen].params["paths"] else {
        panic!("pen paths: {:?}", g.nodes[&pen].params)
    };
    assert_eq!(paths.len(), 1, "one stroke, one path");
    let got = &paths[0].points;
    assert_eq!(got.len(), path.len(), "{got:?}");
    for (a, b) in got.iter().zip(&path) {
        assert!(
            (a[0] - b[0]).abs() < 1e-3 && (a[1] - b[1]).abs() < 1e-3,
            "{got:?}"
        );
    }
    assert_eq!(
        app.session.doc.history.undo_len(),
        steps + 1,
        "one stroke, one step"
    );
    assert_eq!(app.session.selected, Some(pen));
    assert_eq!(app.session.viewed, Some((pen, "image".to_string())));

    // The edit was evaluated and the preview shows the pen's output.
    settle(&mut h);
    let app = h.state();
    assert!(
        app.runtime.requests > requests,
        "a re-evaluation was requested"
    );
    assert!(
        app.runtime.outcome.node_errors.is_empty(),
        "{:?}",
        app.runtime.outcome.node_errors
    );
    assert!(app
        .runtime
        .outcome
        .values
        .contains_key(&(pen, "image".into())));
    assert!(app.preview.renders > renders, "the preview changed");

    // Undo restores the graph exactly.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.step();
    assert_eq!(h.state().session.doc.graph, before);
}

/// Screen positions of image-pixel points under the preview's last drawn transform.
fn screen_points(h: &Harness<'_, EditorApp>, path: &[[f64; 2]]) -> Vec<Pos2> {
    let xf = h.state().preview.transform.expect("the preview was drawn");
    path.iter()
        .map(|p| {
            let s = xf.screen_from_image(*p);
            Pos2::new(s[0], s[1])
        })
        .collect()
}

/// Presses the primary button at `screen[0]` and moves through the rest (not released).
fn press_and_move(h: &mut Harness<'_, EditorApp>, screen: &[Pos2]) {
    h.hover_at(screen[0]);
    h.step();
    h.drag_at(screen[0]);
    h.step();
    for p in &screen[1..] {
        h.hover_at(*p);
        h.step();
    }
}

#[test]
fn shift_drag_on_the_image_moves_the_light_without_panning() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let (light0, pan0) = (h.state().prefs.settings.light, h.state().preview.pan);
    // From the image centre towards its right edge: the light tilts towards +x.
    let screen = screen_points(
        &h,
        &[[48.0, 48.0], [60.0, 48.0], [80.0, 48.0], [90.0, 48.0]],
    );
    h.event(egui::Event::ModifiersChanged(Modifiers::SHIFT));
    press_and_move(&mut h, &screen);
    h.drop_at(*screen.last().unwrap());
    h.step();
    h.event(egui::Event::ModifiersChanged(Modifiers::NONE));
    h.step();
    let app = h.state();
    assert_eq!(app.preview.pan, pan0, "a Shift-drag does not pan");
    let l = app.prefs.settings.light;
    assert_ne!(l, light0, "the light moved");
    assert!(l[0] > 0.5 && l[1].abs() < 0.05, "light towards +x: {l:?}");
    let len = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
    assert!((len - 1.0).abs() < 1e-5, "unit light direction: {len}");
}

#[test]
fn the_preview_offers_every_view_and_shows_the_selected_views_parameters() {
    use rgbn::app::preview::Mode;
    use rgbn::render::View;
    let mut h = harness(small_demo());
    settle(&mut h);
    for v in View::ALL {
        assert!(
            h.query_all_by_label(v.name()).next().is_some(),
            "no preview button for {}",
            v.name()
        );
    }
    // No view parameters while relit.
    assert!(h.query_all_by_label("toon_levels").next().is_none());
    h.get_by_role_and_label(Role::Button, "toon").click();
    h.run_steps(1);
    settle(&mut h);
    assert_eq!(
        h.state().preview.shown_settings().map(|s| s.view),
        Some(Mode::View(View::Toon))
    );
    assert!(h.query_all_by_label("toon_levels").next().is_some());
    assert!(h.query_all_by_label("curvature_scale").next().is_none());
    // Changing a view parameter re-renders with it.
    let renders = h.state().preview.renders;
    h.state_mut().prefs.settings.inspect.toon_levels = 2;
    h.run_steps(1);
    settle(&mut h);
    assert!(h.state().preview.renders > renders);
    assert_eq!(
        h.state()
            .preview
            .shown_settings()
            .map(|s| s.inspect.toon_levels),
        Some(2)
    );
}

#[test]
fn after_pan_and_zoom_an_edit_shows_the_viewport_first_then_the_whole_output() {
    use rgbn::eval::region::{RegionOptions, INTERACTIVE_TILE};
    use rgbn::eval::{EvalOptions, Evaluator, Plan};
    use rgbn::graph::{LoadedGraph, PortRef};
    use rgbn::nodes::Value;
    let mut d = small_demo();
    d.set_param(1, "size", ParamValue::Int(300));
    let mut h = harness(d);
    settle(&mut h);
    h.state_mut().view_node(3);
    settle(&mut h);
    for (step, (zoom, pan)) in [(2.0f32, [120.0f32, -80.0f32]), (0.5, [30.0, 10.0])]
        .into_iter()
        .enumerate()
    {
        {
            let p = &mut h.state_mut().preview;
            p.zoom = Some(zoom);
            p.pan = egui::Vec2::new(pan[0], pan[1]);
        }
        h.step();
        // An edit upstream of the viewed node.
        let amount = 1.25 + 0.25 * step as f64;
        h.state_mut()
            .session
            .doc
            .set_param(2, "amount", ParamValue::Float(amount));
        let overlays = h.state().preview.overlays;
        let deadline = Instant::now() + Duration::from_secs(60);
        while h.state().preview.overlays == overlays {
            assert!(Instant::now() < deadline, "no viewport picture");
            h.step();
            std::thread::sleep(Duration::from_millis(2));
        }
        let app = h.state();
        let spec = app.preview.view_spec().expect("the panel was drawn");
        let (rect, level) = spec
            .visible((300, 300), INTERACTIVE_TILE)
            .expect("part of the image is on screen");
        assert_eq!(level, u32::from(zoom < 1.0), "zoom {zoom}: level");
        let region = app.preview.region().cloned().expect("a viewport");
        assert_eq!((region.rect, region.level), (rect, level));
        assert_eq!(
            app.preview.overlay_request().and_then(|r| r.region),
            Some((rect, level)),
            "the picture on screen is that viewport"
        );
        if level == 0 {
            assert!(
                rect.w < 300 || rect.h < 300,
                "zoomed in: only part of the image"
            );
        }
        // The same pixels as `rgbn eval --region … --level …` on the graph as it now is.
        let mut g = app.session.doc.graph.clone();
        g.outputs.clear();
        g.exposed.clear();
        g.outputs.insert(
            "shown".into(),
            PortRef {
                node: 3,
                port: "image".into(),
            },
        );
        let dir = std::env::temp_dir();
        let lg = LoadedGraph::from_graph(g, None, dir.clone()).unwrap();
        let plan = Plan::new(&lg, &Default::default(), &dir).unwrap();
        let cli = Evaluator::default()
            .eval_region(
                &plan,
                "shown",
                rect,
                &RegionOptions { tile: 256, level },
                &EvalOptions::default(),
            )
            .unwrap();
        assert_eq!(cli.key, region.key);
        let (Value::Rgbn(a), Value::Rgbn(b)) = (&region.value, &cli.value) else {
            panic!("RGBN viewports");
        };
        assert_eq!((a.width(), a.height()), (rect.w, rect.h));
        let mut worst = 0f32;
        for y in 0..rect.h {
            for x in 0..rect.w {
                let (n, m) = (a.normal_at(x, y), b.normal_at(x, y));
                for k in 0..3 {
                    worst = worst.max((n[k] - m[k]).abs());
                }
            }
        }
        // Tiles of 64 and 256 cut the recursive Gaussians' tails differently
        // (tests/it/region.rs: 2e-3).
        assert!(worst <= 2e-3, "zoom {zoom}: {worst}");
        // Once edits pause the whole output is evaluated, and its picture replaces the
        // viewport.
        settle(&mut h);
        let app = h.state();
        assert_eq!(
            app.runtime.outcome.values[&(3, "image".into())].key,
            region.key
        );
        assert!(app.preview.overlay_request().is_none(), "zoom {zoom}");
        assert!(app.preview.region().is_none());
    }
}

#[test]
fn an_idle_editor_asks_for_no_more_frames() {
    let mut h = harness(small_demo());
    settle(&mut h);
    h.run_steps(10);
    h.step();
    assert!(
        !h.ctx.requested_repaint_last_pass(),
        "with nothing evaluating and no input, a frame asked for another one"
    );
}

/// Total area of the filled rectangles and meshes (pictures) of a frame, each clipped to its
/// clip rectangle: with software GL every painted pixel is shaded, so this is the frame's
/// fragment work (text and lines aside).
/// Not counted: the frame kittest wraps the UI in (a central panel's with an 8 px outer
/// margin; eframe gives `App::ui` an unfilled `Ui`).
fn painted_area(shapes: &[egui::epaint::ClippedShape]) -> f32 {
    fn area(shape: &egui::Shape, clip: egui::Rect) -> f32 {
        match shape {
            egui::Shape::Rect(r) if r.fill.a() > 0 => r.rect.intersect(clip).area().max(0.0),
            egui::Shape::Mesh(m) => m.calc_bounds().intersect(clip).area().max(0.0),
            egui::Shape::Vec(v) => v.iter().map(|s| area(s, clip)).sum(),
            _ => 0.0,
        }
    }
    let harness_frame = |s: &egui::Shape| {
        matches!(s, egui::Shape::Rect(r) if r.rect == egui::Rect::from_min_max(
            egui::pos2(8.0, 8.0),
            egui::pos2(1500.0 - 8.0, 900.0 - 8.0),
        ))
    };
    shapes
        .iter()
        .filter(|c| !harness_frame(&c.shape))
        .map(|c| area(&c.shape, c.clip_rect))
        .sum()
}

/// Each pixel of the window is painted about once: the panels are not filled (the frame is
/// cleared to their colour), and a picture that fills the preview is drawn without the
/// background under it. Before, panels, the preview's background and its picture were all
/// painted: about twice the window per frame, which with Mesa's software GL made every frame
/// 50 ms.
#[test]
fn a_frame_paints_each_pixel_about_once() {
    let mut d = small_demo();
    d.graph
        .nodes
        .get_mut(&1)
        .unwrap()
        .params
        .insert("size".into(), ParamValue::Int(1024));
    let mut h = harness(d);
    settle(&mut h);
    // Actual pixels: the 1024² picture fills the preview panel.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Num1);
    settle(&mut h);
    let window = 1500.0 * 900.0;
    let painted = painted_area(&h.output().shapes);
    eprintln!("painted {:.2} of the window", painted / window);
    // Measured 0.73 (1.92 with the panels filled and the background under the picture).
    assert!(
        painted <= 1.2 * window,
        "painted {:.2} windows",
        painted / window
    );
    // Fitted (letterboxed), the preview's background is painted, but still not the panels.
    h.key_press_modifiers(Modifiers::COMMAND, Key::Num0);
    settle(&mut h);
    let painted = painted_area(&h.output().shapes);
    eprintln!("fitted: painted {:.2} of the window", painted / window);
    // Measured 0.93.
    assert!(
        painted <= 1.2 * window,
        "fitted: painted {:.2} windows",
        painted / window
    );
}
