//! Frames, reroutes and groups driven through the editor's UI (egui_kittest): Ctrl+J frames
//! the selected nodes and dragging the frame's title moves them (one undo step); Ctrl+G groups
//! three nodes of graphs/demo.ron into a subgraph through the dialog and Ctrl+Shift+G ungroups
//! them, with every output bit-identical to the original and the files round-tripping; a
//! double-click opens a group in place and the breadcrumb leads back.

use crate::editor::{harness, settle, small_demo};
use crate::structure::{outputs, read};
use egui::{Event, Key, Modifiers, PointerButton, Pos2, Rect, Vec2};
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use rgbn::app::graph_view::node_title;
use rgbn::app::state::Document;
use rgbn::app::EditorApp;
use rgbn::graph::{LoadedGraph, NodeId};
use std::path::Path;

type H = Harness<'static, EditorApp>;

/// Node `id`'s rectangle on the screen, as last drawn.
fn screen_rect(h: &H, id: NodeId) -> Rect {
    let xf = h.state().graph_view().to_global();
    let r = h
        .state()
        .graph_view()
        .drawn_rects(&h.state().session.doc.graph)[&id];
    Rect::from_min_max(
        xf * Pos2::new(r.min[0], r.min[1]),
        xf * Pos2::new(r.max()[0], r.max()[1]),
    )
}

fn button(h: &mut H, p: Pos2, button: PointerButton, pressed: bool, m: Modifiers) {
    h.event_modifiers(
        Event::PointerButton {
            pos: p,
            button,
            pressed,
            modifiers: m,
        },
        m,
    );
    h.step();
}

/// Shift+clicks each node's header: they become the graph's selection.
fn select(h: &mut H, ids: &[NodeId]) {
    for id in ids {
        let r = screen_rect(h, *id);
        let at = Pos2::new(r.center().x, r.top() + 8.0);
        h.hover_at(at);
        h.step();
        button(h, at, PointerButton::Primary, true, Modifiers::SHIFT);
        button(h, at, PointerButton::Primary, false, Modifiers::SHIFT);
    }
    h.event(Event::ModifiersChanged(Modifiers::NONE));
    h.step();
    let mut sel = h.state().graph_view().selected(&h.ctx);
    sel.sort_unstable();
    assert_eq!(sel, ids, "selected by Shift+click");
}

fn key(h: &mut H, m: Modifiers, k: Key) {
    h.key_press_modifiers(m, k);
    h.step();
    h.step();
}

/// Hovers an empty spot of the graph panel's top (for keys that act on the graph).
fn hover_graph(h: &mut H) {
    let panel = h.state().graph_view().panel().unwrap();
    h.hover_at(Pos2::new(panel.center().x, panel.top() + 30.0));
    h.step();
}

fn double_click(h: &mut H, p: Pos2) {
    h.hover_at(p);
    h.step();
    // (The harness gives each event a frame of its own: see `demo_in_tempdir` for their length.)
    for pressed in [true, false, true, false] {
        h.event(Event::PointerButton {
            pos: p,
            button: PointerButton::Primary,
            pressed,
            modifiers: Modifiers::NONE,
        });
    }
    h.step();
    h.step();
}

#[test]
fn ctrl_j_frames_the_selection_and_dragging_the_frame_moves_its_nodes_as_one_undo_step() {
    let mut h = harness(small_demo());
    settle(&mut h);
    select(&mut h, &[2, 3]);
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND, Key::J);
    let g = &h.state().session.doc.graph;
    assert_eq!(g.frames.len(), 1, "Ctrl+J made a frame");
    assert_eq!(g.frames[0].nodes, vec![2, 3]);
    let before: Vec<[f32; 2]> = (1..=6).map(|id| g.nodes[&id].pos).collect();
    let title = g.frames[0].title.clone();
    let undo_len = h.state().session.doc.history.undo_len();
    h.run_steps(2);

    // The frame's title bar (found by its accessible label) drags both nodes.
    // (The bar lives in the graph's layer: its accessible rectangle is in graph units.)
    let xf = h.state().graph_view().to_global();
    let bar = xf.mul_rect(h.get_by_label(&rgbn::app::frames::bar_label(&title)).rect());
    let r2 = screen_rect(&h, 2);
    assert!(
        bar.bottom() <= r2.top() && bar.left() <= r2.left(),
        "bar {bar:?} above node 2 {r2:?}"
    );
    let from = Pos2::new(bar.left() + 20.0, bar.center().y);
    let d = Vec2::new(90.0, 70.0);
    h.hover_at(from);
    h.step();
    button(&mut h, from, PointerButton::Primary, true, Modifiers::NONE);
    for k in 1..=6 {
        h.hover_at(from + d * (k as f32 / 6.0));
        h.step();
    }
    button(
        &mut h,
        from + d,
        PointerButton::Primary,
        false,
        Modifiers::NONE,
    );
    h.run_steps(2);
    let scale = h.state().graph_view().to_global().scaling;
    let g = &h.state().session.doc.graph;
    for id in 1..=6u64 {
        let (a, b) = (before[id as usize - 1], g.nodes[&id].pos);
        let moved = [b[0] - a[0], b[1] - a[1]];
        if id == 2 || id == 3 {
            assert!(
                (moved[0] - d.x / scale).abs() < 1.0 && (moved[1] - d.y / scale).abs() < 1.0,
                "node {id} moved by {moved:?}, dragged {d:?} at scale {scale}"
            );
        } else {
            assert_eq!(a, b, "node {id} is not in the frame");
        }
    }
    // The frame followed (it is drawn around its nodes) and is saved with the graph.
    let bar2 = xf.mul_rect(h.get_by_label(&rgbn::app::frames::bar_label(&title)).rect());
    assert!(
        (bar2.min - (bar.min + d)).length() < 1.5,
        "{bar2:?} vs {bar:?}"
    );
    let text = g.to_text();
    assert!(text.contains("frames:"), "{text}");

    // The move is one undo step.
    assert_eq!(h.state().session.doc.history.undo_len(), undo_len + 1);
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND, Key::Z);
    let g = &h.state().session.doc.graph;
    for id in 1..=6u64 {
        assert_eq!(
            g.nodes[&id].pos,
            before[id as usize - 1],
            "node {id} after undo"
        );
    }
    assert_eq!(g.frames.len(), 1);
}

/// graphs/demo.ron copied into a fresh folder, opened in the editor.
fn demo_in_tempdir() -> (tempfile::TempDir, H) {
    let dir = tempfile::tempdir().unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
    std::fs::copy(src, dir.path().join("demo.ron")).unwrap();
    let doc = Document::open(&dir.path().join("demo.ron")).unwrap();
    // Frames of 1/60 s (the default 1/4 s would put the two clicks of a double-click, each
    // event in a frame of its own, further apart than egui's 0.3 s).
    let mut h = Harness::builder()
        .with_size([1500.0, 900.0])
        .with_step_dt(1.0 / 60.0)
        .build_ui_state(crate::editor::frame, EditorApp::new(doc));
    settle(&mut h);
    (dir, h)
}

#[test]
fn group_three_demo_nodes_and_ungroup_in_the_editor_outputs_bit_identical_files_round_trip() {
    let (dir, mut h) = demo_in_tempdir();
    let base = dir.path();
    let original = LoadedGraph::load(&base.join("demo.ron")).unwrap();
    let (v0, k0, _) = outputs(&original);
    assert_eq!(v0.len(), 4);
    let g0 = h.state().session.doc.graph.clone();

    // sharpen (2) → detail (3) → light (4): Ctrl+G opens the dialog.
    select(&mut h, &[2, 3, 4]);
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND, Key::G);
    let dialog = h
        .state()
        .structure
        .group
        .clone()
        .expect("Ctrl+G opened the dialog");
    assert_eq!(dialog.ids, vec![2, 3, 4]);
    // Expose detail's amount: tick it, then Group.
    let label = format!("{} · amount", node_title(&g0, 3));
    h.get_by_label(&label).click();
    h.step();
    h.get_by_label("Group").click();
    h.run_steps(2);
    assert!(h.state().structure.group.is_none(), "the dialog closed");
    let grouped = h.state().session.doc.graph.clone();
    assert_eq!(grouped.nodes.len(), g0.nodes.len() - 2);
    let gid = *grouped.nodes.keys().next_back().unwrap();
    assert_eq!(grouped.nodes[&gid].op, "graph");
    let lib = base.join("lib/group.ron");
    let sub = read(&lib);
    assert_eq!(sub.nodes.len(), 3);
    assert_eq!(sub.exposed.len(), 1, "one parameter exposed");
    let exposed = sub.exposed.values().next().unwrap();
    assert_eq!((exposed.node, exposed.param.as_str()), (3, "amount"));

    // Saved, the grouped graph round-trips and evaluates bit for bit as the original.
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND, Key::S);
    assert!(!h.state().session.doc.is_dirty(), "Ctrl+S saved");
    for p in [base.join("demo.ron"), lib.clone()] {
        let text = std::fs::read_to_string(&p).unwrap();
        let back = read(&p);
        assert_eq!(back.to_text(), text, "{} round-trips", p.display());
    }
    assert_eq!(read(&base.join("demo.ron")), grouped);
    let (v1, k1, _) = outputs(&LoadedGraph::load(&base.join("demo.ron")).unwrap());
    assert_eq!(k1, k0, "grouped: the same content keys");
    assert_eq!(v1, v0, "grouped: the same outputs, bit for bit");
    // The editor evaluates it without errors.
    settle(&mut h);
    assert!(
        h.state().runtime.outcome.node_errors.is_empty(),
        "{:?}",
        h.state().runtime.outcome.node_errors
    );

    // Undo puts the three nodes back; redo groups again.
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND, Key::Z);
    assert_eq!(h.state().session.doc.graph, g0);
    key(&mut h, Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    assert_eq!(h.state().session.doc.graph, grouped);
    settle(&mut h);

    // Ctrl+Shift+G on the group node ungroups it.
    select(&mut h, &[gid]);
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND | Modifiers::SHIFT, Key::G);
    let u = h.state().session.doc.graph.clone();
    assert_eq!(u.nodes.len(), g0.nodes.len());
    assert!(!u.nodes.contains_key(&gid));
    key(&mut h, Modifiers::COMMAND, Key::S);
    let text = std::fs::read_to_string(base.join("demo.ron")).unwrap();
    assert_eq!(read(&base.join("demo.ron")).to_text(), text);
    assert_eq!(read(&base.join("demo.ron")), u);
    let (v2, k2, _) = outputs(&LoadedGraph::load(&base.join("demo.ron")).unwrap());
    assert_eq!(k2, k0, "ungrouped: the same content keys");
    assert_eq!(v2, v0, "ungrouped: the same outputs, bit for bit");
    // The same nodes, parameters and positions as the original, up to the three ids.
    let shape = |g: &rgbn::graph::Graph| {
        let mut v: Vec<String> = g
            .nodes
            .values()
            .map(|n| format!("{} {:?} {:?} {:?}", n.op, n.name, n.params, n.pos))
            .collect();
        v.sort();
        v
    };
    assert_eq!(shape(&u), shape(&g0));
}

#[test]
fn double_click_opens_a_group_in_place_and_the_breadcrumb_leads_back() {
    let (dir, mut h) = demo_in_tempdir();
    select(&mut h, &[2, 3, 4]);
    hover_graph(&mut h);
    key(&mut h, Modifiers::COMMAND, Key::G);
    h.get_by_label("Group").click();
    h.run_steps(2);
    let outer = h.state().session.doc.graph.clone();
    let gid = *outer.nodes.keys().next_back().unwrap();
    settle(&mut h);

    // Double-click the group node's header: its subgraph is the document edited.
    let r = screen_rect(&h, gid);
    double_click(&mut h, Pos2::new(r.center().x, r.top() + 8.0));
    assert_eq!(
        h.state().session.groups.len(),
        1,
        "inside the group; status: {}",
        h.state().status.text
    );
    assert_eq!(
        h.state().session.doc.path.as_deref(),
        Some(dir.path().join("lib/group.ron").as_path())
    );
    assert_eq!(h.state().session.doc.graph.nodes.len(), 3);
    assert_eq!(
        h.state().group_path(),
        vec!["demo.ron *".to_string(), "group.ron".to_string()]
    );
    // Inside, the group's nodes evaluate fed from outside: no node waits or fails.
    settle(&mut h);
    assert!(
        h.state().runtime.outcome.node_errors.is_empty(),
        "{:?}",
        h.state().runtime.outcome.node_errors
    );
    // The breadcrumb's outer entry leads back, to the graph as it was.
    h.get_by_label("demo.ron *").click();
    h.run_steps(2);
    assert!(h.state().session.groups.is_empty(), "left the group");
    assert_eq!(h.state().session.doc.graph, outer);
    assert_eq!(h.state().session.selected, Some(gid));
    // The widget's selection does not carry over to other nodes: its node indices are reused
    // by the other document's nodes.
    let widget = h.state().graph_view().selected(&h.ctx);
    assert!(widget.iter().all(|id| *id == gid), "{widget:?}");
}
