//! The graph's node-editor habits driven through the UI (egui_kittest): the add menu from the
//! keyboard (Tab, Shift+A, typing, arrows, Enter, Escape) and from a right-click, new nodes
//! where the menu was opened, the dropped-wire menu, Frame selected / Frame all, a new node
//! that waits for its input, the sliders' soft ranges and text that is neither clipped nor
//! blurred at the default size.

use crate::editor::{harness, settle, small_demo};
use egui::accesskit::Role;
use egui::{Color32, Event, Key, Modifiers, PointerButton, Pos2, Rect};
use egui_kittest::kittest::{NodeT, Queryable};
use egui_kittest::Harness;
use rgbn::app::graph_view::{node_title, type_color};
use rgbn::app::params_ui::doc_summary;
use rgbn::app::state::Document;
use rgbn::app::EditorApp;
use rgbn::graph::{NodeId, Source};
use rgbn::nodes::{registry, PortType};
use rgbn::params::{ParamKind, ParamValue};

type H = Harness<'static, EditorApp>;

/// Graph coordinates of screen point `p` in the graph view as last drawn.
fn graph_at(h: &H, p: Pos2) -> [f32; 2] {
    let g = h.state().graph_view().to_global().inverse() * p;
    [g.x, g.y]
}

/// A screen point of the graph panel, in its lower part, with room for a new node around it
/// (no node within 320 × 220 graph units of it).
fn free_point(h: &H) -> Pos2 {
    let app = h.state();
    let panel = app.graph_view().panel().expect("the graph was drawn");
    let rects = app.graph_view().node_rects(&app.session.doc.graph);
    for fy in [0.85, 0.8, 0.75, 0.7, 0.65, 0.6] {
        for fx in [0.1, 0.2, 0.3, 0.4, 0.5] {
            let p = Pos2::new(
                panel.left() + fx * panel.width(),
                panel.top() + fy * panel.height(),
            );
            let g = graph_at(h, p);
            let clear = rects.iter().all(|(_, r)| {
                r.max()[0] < g[0] - 40.0
                    || r.min[0] > g[0] + 320.0
                    || r.max()[1] < g[1] - 40.0
                    || r.min[1] > g[1] + 220.0
            });
            if clear {
                return p;
            }
        }
    }
    panic!("no free point in the graph panel");
}

fn type_text(h: &mut H, text: &str) {
    h.event(Event::Text(text.into()));
    h.step();
}

fn press(h: &mut H, key: Key) {
    h.key_press(key);
    h.step();
}

/// The node added last.
fn newest(h: &H) -> NodeId {
    *h.state()
        .session
        .doc
        .graph
        .nodes
        .keys()
        .next_back()
        .unwrap()
}

fn click_at(h: &mut H, p: Pos2, button: PointerButton) {
    h.hover_at(p);
    h.step();
    for pressed in [true, false] {
        h.event(Event::PointerButton {
            pos: p,
            button,
            pressed,
            modifiers: Modifiers::NONE,
        });
        h.step();
    }
}

#[test]
fn tab_at_a_point_type_bilat_enter_adds_a_bilateral_node_at_that_point() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let n0 = h.state().session.doc.graph.nodes.len();
    let p = free_point(&h);
    let at = graph_at(&h, p);
    // One motion: Tab, type, Enter.
    h.hover_at(p);
    h.step();
    press(&mut h, Key::Tab);
    assert!(h.state().graph_view().menu.is_open(), "Tab opened the menu");
    type_text(&mut h, "bilat");
    assert_eq!(h.state().graph_view().menu.listed()[0], "bilateral");
    press(&mut h, Key::Enter);
    let g = &h.state().session.doc.graph;
    assert_eq!(g.nodes.len(), n0 + 1);
    let n = &g.nodes[&newest(&h)];
    assert_eq!(n.op, "bilateral");
    // At the point, in graph coordinates (the spot was free, so nothing moved it).
    assert!(
        (n.pos[0] - at[0]).abs() < 1.0 && (n.pos[1] - at[1]).abs() < 1.0,
        "node at {:?}, Tab at {at:?}",
        n.pos
    );
    assert!(!h.state().graph_view().menu.is_open());
    // Typing went to the menu, not to shortcuts: no "b" tool, nothing deleted.
    assert_eq!(g.nodes.len(), n0 + 1);
}

#[test]
fn shift_a_opens_the_menu_arrows_move_the_highlight_escape_closes() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let n0 = h.state().session.doc.graph.nodes.len();
    let p = free_point(&h);
    h.hover_at(p);
    h.step();
    // As a window system sends it: the key, and the text it types.
    h.key_press_modifiers(Modifiers::SHIFT, Key::A);
    h.event(Event::Text("A".into()));
    h.step();
    let menu = &h.state().graph_view().menu;
    assert!(menu.is_open(), "Shift+A opened the menu");
    assert_eq!(
        menu.search().unwrap().text,
        "",
        "the A opened the menu, it was not typed"
    );
    type_text(&mut h, "blur");
    assert_eq!(
        h.state().graph_view().menu.listed(),
        ["filter.gaussian", "filter.box"]
    );
    // Down, Down (stays on the last), Up, Down: the second row.
    for (key, row) in [
        (Key::ArrowDown, 1),
        (Key::ArrowDown, 1),
        (Key::ArrowUp, 0),
        (Key::ArrowDown, 1),
    ] {
        press(&mut h, key);
        assert_eq!(h.state().graph_view().menu.search().unwrap().highlight, row);
    }
    // The search field kept the keyboard through the arrows.
    assert!(h.ctx.egui_wants_keyboard_input());
    press(&mut h, Key::Enter);
    let g = &h.state().session.doc.graph;
    assert_eq!(g.nodes.len(), n0 + 1);
    assert_eq!(g.nodes[&newest(&h)].op, "filter.box");

    // Escape closes without adding.
    h.hover_at(p);
    h.step();
    press(&mut h, Key::Tab);
    assert!(h.state().graph_view().menu.is_open());
    type_text(&mut h, "gauss");
    press(&mut h, Key::Escape);
    assert!(!h.state().graph_view().menu.is_open());
    assert_eq!(h.state().session.doc.graph.nodes.len(), n0 + 1);
    // Tab with the pointer outside the graph does not open it.
    let panel = h.state().graph_view().panel().unwrap();
    h.hover_at(Pos2::new(panel.right() + 300.0, panel.center().y));
    h.step();
    press(&mut h, Key::Tab);
    assert!(!h.state().graph_view().menu.is_open());
}

#[test]
fn a_right_click_low_in_the_panel_adds_the_node_where_it_was_clicked() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let panel = h.state().graph_view().panel().unwrap();
    // Low in the panel: the menu (taller than what is left below) opens upwards.
    let p = Pos2::new(panel.left() + 0.3 * panel.width(), panel.bottom() - 40.0);
    let at = graph_at(&h, p);
    let rects = h
        .state()
        .graph_view()
        .node_rects(&h.state().session.doc.graph);
    assert!(
        rects.iter().all(|(_, r)| r.max()[1] < at[1] - 40.0),
        "the point is below every node"
    );
    click_at(&mut h, p, PointerButton::Secondary);
    assert!(
        h.state().graph_view().menu.is_open(),
        "right-click opened the menu"
    );
    let popup: Rect = h
        .ctx
        .memory(|m| m.area_rect(egui::Id::new("rgbn-add-menu")))
        .expect("the menu is drawn");
    assert!(
        popup.top() < p.y - 100.0,
        "the popup moved up to fit: {popup:?}"
    );
    // The field has the keyboard at once.
    type_text(&mut h, "bilateral");
    press(&mut h, Key::Enter);
    let n = &h.state().session.doc.graph.nodes[&newest(&h)];
    assert_eq!(n.op, "bilateral");
    assert!(
        (n.pos[0] - at[0]).abs() < 1.0 && (n.pos[1] - at[1]).abs() < 1.0,
        "node at {:?}, clicked at {at:?} (popup at {popup:?})",
        n.pos
    );
    // On screen, the node's corner is where the click was, not at the popup's top.
    let corner = h.state().graph_view().to_global() * Pos2::new(n.pos[0], n.pos[1]);
    assert!((corner.y - p.y).abs() < 2.0, "{corner:?} vs {p:?}");
}

/// Centres of the pins of colour `fill` drawn this frame (squares for outputs, circles for
/// inputs).
fn pins(h: &H, fill: Color32) -> Vec<Pos2> {
    let mut out = Vec::new();
    for cs in &h.output().shapes {
        match &cs.shape {
            egui::Shape::Path(p) if p.closed && p.points.len() == 4 && p.fill == fill => {
                let c = p
                    .points
                    .iter()
                    .fold(egui::Vec2::ZERO, |a, q| a + q.to_vec2())
                    / 4.0;
                out.push(c.to_pos2());
            }
            egui::Shape::Circle(c) if c.fill == fill => out.push(c.center),
            _ => {}
        }
    }
    out
}

/// Drags from `from` to `to` with the primary button and releases there.
fn drag(h: &mut H, from: Pos2, to: Pos2) {
    h.hover_at(from);
    h.step();
    h.drag_at(from);
    h.step();
    for k in 1..=6 {
        let t = k as f32 / 6.0;
        h.hover_at(from + (to - from) * t);
        h.step();
    }
    h.drop_at(to);
    h.step();
    h.step();
}

#[test]
fn a_wire_dropped_in_empty_space_offers_what_takes_it_and_connects_the_new_node() {
    let mut h = harness(small_demo());
    settle(&mut h);
    // Node 3 ("detail") has one RGBN output; its pin is the RGBN square right of its rectangle's
    // middle.
    let xf = h.state().graph_view().to_global();
    let r3 = h
        .state()
        .graph_view()
        .drawn_rects(&h.state().session.doc.graph)[&3];
    let (min, max) = (
        xf * Pos2::new(r3.min[0], r3.min[1]),
        xf * Pos2::new(r3.max()[0], r3.max()[1]),
    );
    let node3 = Rect::from_min_max(min, max);
    let pin = pins(&h, type_color(PortType::Rgbn))
        .into_iter()
        .filter(|p| node3.contains(*p) && p.x > node3.center().x)
        .min_by(|a, b| a.y.total_cmp(&b.y))
        .expect("node 3's output pin");
    let drop = free_point(&h);
    let at = graph_at(&h, drop);
    drag(&mut h, pin, drop);
    let menu = &h.state().graph_view().menu;
    assert!(menu.is_open(), "dropping the wire opened the menu");
    assert_eq!(
        menu.wire(),
        Some(&rgbn::app::add_menu::Wire::Out {
            node: 3,
            port: "image".into()
        })
    );
    // Only operators with an RGBN input are offered: no sources, no mask loaders; and a
    // reroute, which takes any wire.
    let listed = menu.listed();
    assert!(listed.contains(&"normalize") && listed.contains(&"relight"));
    assert!(!listed.contains(&"demo") && !listed.contains(&"load_mask"));
    assert!(listed.contains(&rgbn::nodes::REROUTE_OP));
    for id in listed.iter().filter(|id| **id != rgbn::nodes::REROUTE_OP) {
        let op = rgbn::nodes::find(id).unwrap();
        assert!(
            op.spec().inputs.iter().any(|p| p.ty == PortType::Rgbn),
            "{id} offered"
        );
    }
    type_text(&mut h, "normal");
    press(&mut h, Key::Enter);
    let new = newest(&h);
    let n = &h.state().session.doc.graph.nodes[&new];
    assert_eq!(n.op, "normalize");
    assert_eq!(
        n.inputs.get("image"),
        Some(&Source::Node(3, "image".into()))
    );
    // Its left edge at the wire's end, its first input about level with it.
    assert!(
        (n.pos[0] - at[0]).abs() < 20.0 && (n.pos[1] - at[1]).abs() < 40.0,
        "node at {:?}, wire dropped at {at:?}",
        n.pos
    );
    // One undo step removes the node and its wire together.
    let version_before = h.state().session.doc.history.undo_len();
    assert!(version_before > 0);
    h.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    h.step();
    assert!(!h.state().session.doc.graph.nodes.contains_key(&new));
    settle(&mut h);
    assert!(h
        .state()
        .runtime
        .outcome
        .values
        .keys()
        .any(|(id, _)| *id == 3));
}

#[test]
fn a_wire_dropped_from_an_input_offers_sources_of_its_type() {
    let mut h = harness(small_demo());
    settle(&mut h);
    // Node 5, the curl readout, has one RGBN input: the RGBN circle left of its middle.
    let xf = h.state().graph_view().to_global();
    let g = &h.state().session.doc.graph;
    let (id, _) = g
        .nodes
        .iter()
        .find(|(_, n)| n.op == "curl")
        .expect("a curl node");
    let id = *id;
    let r = h.state().graph_view().drawn_rects(g)[&id];
    let node = Rect::from_min_max(
        xf * Pos2::new(r.min[0], r.min[1]),
        xf * Pos2::new(r.max()[0], r.max()[1]),
    );
    let pin = pins(&h, type_color(PortType::Rgbn))
        .into_iter()
        .find(|p| node.contains(*p) && p.x < node.center().x)
        .expect("the curl node's input pin");
    let drop = free_point(&h);
    drag(&mut h, pin, drop);
    let listed = h.state().graph_view().menu.listed();
    assert!(listed.contains(&"demo") && listed.contains(&"normalize"));
    assert!(!listed.contains(&"relight"), "a picture is not an image");
    type_text(&mut h, "surface");
    press(&mut h, Key::Enter);
    let new = newest(&h);
    assert_eq!(h.state().session.doc.graph.nodes[&new].op, "surface");
    assert_eq!(
        h.state().session.doc.graph.nodes[&id].inputs.get("image"),
        Some(&Source::Node(new, "image".into()))
    );
}

/// The screen rectangle of node `id` as last drawn.
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

#[test]
fn f_frames_the_selected_node_and_home_frames_all() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let panel = h.state().graph_view().panel().unwrap();
    // Select node 1 (Shift+click), then F: it fills the view's middle at 1:1.
    let r1 = screen_rect(&h, 1);
    let at = Pos2::new(r1.center().x, r1.top() + 8.0);
    h.hover_at(at);
    h.step();
    for pressed in [true, false] {
        h.event_modifiers(
            Event::PointerButton {
                pos: at,
                button: PointerButton::Primary,
                pressed,
                modifiers: Modifiers::SHIFT,
            },
            Modifiers::SHIFT,
        );
        h.step();
    }
    let hov = Pos2::new(panel.center().x, panel.top() + 20.0);
    h.hover_at(hov);
    h.step();
    press(&mut h, Key::F);
    h.run_steps(3);
    let r1 = screen_rect(&h, 1);
    assert!(
        (r1.center() - panel.center()).length() < 2.0,
        "{r1:?} centred in {panel:?}"
    );
    assert_eq!(h.state().graph_view().to_global().scaling, 1.0);
    // Home: every node inside the panel.
    press(&mut h, Key::Home);
    h.run_steps(3);
    for id in h
        .state()
        .session
        .doc
        .graph
        .nodes
        .keys()
        .copied()
        .collect::<Vec<_>>()
    {
        let r = screen_rect(&h, id);
        assert!(
            panel.contains_rect(r),
            "node {id} at {r:?} outside {panel:?}"
        );
    }
    // With nothing selected in the graph, F frames the node the inspector shows.
    h.state_mut().session.selected = Some(4);
    assert!(h.state().graph_view().to_global().scaling < 1.0);
    // (Ctrl+click on empty space clears the graph's selection.)
    for pressed in [true, false] {
        h.event_modifiers(
            Event::PointerButton {
                pos: hov,
                button: PointerButton::Primary,
                pressed,
                modifiers: Modifiers::COMMAND,
            },
            Modifiers::COMMAND,
        );
        h.step();
    }
    assert!(h.state().graph_view().selected(&h.ctx).is_empty());
    press(&mut h, Key::F);
    h.run_steps(3);
    let r4 = screen_rect(&h, 4);
    assert!((r4.center() - panel.center()).length() < 2.0, "{r4:?}");
}

#[test]
fn a_new_unconnected_node_waits_for_its_input_and_is_not_a_failure() {
    let mut h = harness(small_demo());
    settle(&mut h);
    let p = free_point(&h);
    h.hover_at(p);
    h.step();
    press(&mut h, Key::Tab);
    type_text(&mut h, "normalize");
    press(&mut h, Key::Enter);
    let id = newest(&h);
    settle(&mut h);
    let app = h.state();
    assert!(!app.status.error, "{:?}", app.status);
    assert_eq!(app.status.text, format!("#{id} waits for input image"));
    assert_eq!(
        app.runtime.outcome.waiting.get(&id).map(String::as_str),
        Some("image")
    );
    assert!(app.runtime.outcome.node_errors.is_empty());
    h.get_by_label("waits for input image");
}

/// A document with one node of every registered operator, in rows of five.
fn every_operator() -> Document {
    let mut d = Document::new();
    for (k, op) in registry().iter().enumerate() {
        let pos = [(k % 5) as f32 * 260.0, (k / 5) as f32 * 220.0];
        d.graph.add_node(op.spec().id, pos);
    }
    d
}

#[test]
fn every_operators_sliders_span_its_soft_range_and_show_the_default() {
    let mut h = harness(every_operator());
    h.run_steps(3);
    let ids: Vec<(NodeId, String)> = h
        .state()
        .session
        .doc
        .graph
        .nodes
        .values()
        .map(|n| (n.id, n.op.clone()))
        .collect();
    let mut sliders = 0;
    for (id, op) in ids {
        h.state_mut().session.selected = Some(id);
        h.run_steps(2);
        for p in rgbn::nodes::find(&op).unwrap().params() {
            let (default, integer) = match (&p.kind, &p.default) {
                (ParamKind::Float, ParamValue::Float(x)) => (*x, false),
                (ParamKind::Int, ParamValue::Int(i)) => (*i as f64, true),
                _ => continue,
            };
            let Some(s) = p.meta.slider() else { continue };
            let node = h.get_by_role_and_label(Role::Slider, p.name);
            let (lo, hi) = if integer {
                (s.lo.trunc(), s.hi.trunc())
            } else {
                (s.lo, s.hi)
            };
            assert_eq!(
                (
                    node.accesskit_node().min_numeric_value(),
                    node.accesskit_node().max_numeric_value()
                ),
                (Some(lo), Some(hi)),
                "{op}.{}",
                p.name
            );
            let v = node.accesskit_node().numeric_value().unwrap();
            assert!(
                (v - default).abs() <= 1e-9 * default.abs().max(1.0),
                "{op}.{}: slider at {v}, default {default}",
                p.name
            );
            sliders += 1;
        }
    }
    assert!(sliders > 100, "{sliders} sliders");
}

#[test]
fn a_value_beyond_the_slider_is_kept_up_to_the_hard_bound() {
    let mut d = Document::new();
    let id = d.graph.add_node("bilateral", [0.0, 0.0]);
    let mut h = harness(d);
    h.state_mut().session.selected = Some(id);
    h.run_steps(3);
    // sigma_normal: slider [0, 1], hard range [0, 10⁶]. Type 5 into its number field.
    let slider = h.get_by_role_and_label(Role::Slider, "sigma_normal").rect();
    let field = h
        .get_all_by_role(Role::SpinButton)
        .find(|n| {
            (n.rect().center().y - slider.center().y).abs() < 4.0
                && n.rect().left() > slider.right() - 1.0
        })
        .expect("the slider's number field");
    field.click();
    h.run_steps(2);
    h.key_press_modifiers(Modifiers::COMMAND, Key::A);
    h.step();
    type_text(&mut h, "5");
    press(&mut h, Key::Enter);
    h.run_steps(2);
    assert_eq!(
        h.state().session.doc.graph.nodes[&id]
            .params
            .get("sigma_normal"),
        Some(&ParamValue::Float(5.0)),
        "5 (beyond the slider) kept"
    );
    let s = h.get_by_role_and_label(Role::Slider, "sigma_normal");
    assert_eq!(s.accesskit_node().numeric_value(), Some(5.0));
    assert_eq!(s.accesskit_node().max_numeric_value(), Some(1.0));
}

/// Checks every text shape of area `region` showing `text` exactly: its glyphs reach the screen
/// at the size they were rasterised at (within 5 %), it is not elided, the clip does not cut
/// it and it lies in `inside`. Returns how many shapes show it.
fn check_text(h: &H, text: &str, region: Rect, inside: Rect, what: &str) -> usize {
    let mut found = 0;
    for cs in &h.output().shapes {
        let egui::Shape::Text(t) = &cs.shape else {
            continue;
        };
        let r = t.galley.rect.translate(t.pos.to_vec2());
        if t.galley.text() != text || !region.contains(r.center()) {
            continue;
        }
        found += 1;
        assert!(!t.galley.elided, "{what}: {text:?} elided");
        assert!(
            cs.clip_rect.expand(0.5).contains_rect(r),
            "{what}: {text:?} at {r:?} clipped by {:?}",
            cs.clip_rect
        );
        assert!(
            inside.expand(0.5).contains_rect(r),
            "{what}: {text:?} at {r:?} outside {inside:?}"
        );
        // The layer's zoom scales a galley's meshes but not its glyphs' atlas rectangles: the
        // widest glyph quad on screen over the widest glyph in the atlas (both in points) is the
        // factor between glyphs drawn and glyphs rasterised (1: sharp; the zoom: shrunk).
        let mut quad = 0.0f32;
        let mut atlas = 0.0f32;
        for row in &t.galley.rows {
            for q in row.row.visuals.mesh.vertices.chunks(4) {
                let (lo, hi) = q.iter().fold((f32::MAX, f32::MIN), |(a, b), v| {
                    (a.min(v.pos.x), b.max(v.pos.x))
                });
                quad = quad.max(hi - lo);
            }
            for g in &row.row.glyphs {
                atlas = atlas.max(g.uv_rect.size.x);
            }
        }
        let ratio = quad / atlas;
        assert!(
            (ratio - 1.0).abs() < 0.05,
            "{what}: {text:?} drawn at {ratio:.2} × its rasterised size"
        );
    }
    found
}

#[test]
fn node_and_inspector_text_is_whole_and_sharp_for_every_operator() {
    // The demo as the editor opens it (zoomed out to fit its panel): every title and pin.
    let mut h = harness(small_demo());
    settle(&mut h);
    let zoom = h.state().graph_view().to_global().scaling;
    assert!(zoom < 0.95, "the demo opens zoomed out ({zoom})");
    let g = h.state().session.doc.graph.clone();
    for id in g.nodes.keys() {
        let title = node_title(&g, *id);
        let r = screen_rect(&h, *id);
        let panel = h.state().graph_view().panel().unwrap();
        assert_eq!(
            check_text(&h, &title, panel, r, "demo header"),
            1,
            "{title}"
        );
    }
    drop(h);

    // Every operator, a row of five at a time framed as the demo is.
    let mut h = harness(every_operator());
    h.run_steps(3);
    let g = h.state().session.doc.graph.clone();
    let ids: Vec<NodeId> = g.nodes.keys().copied().collect();
    let inspector = |h: &H| {
        let panel = h.state().graph_view().panel().unwrap();
        let screen = h.ctx.content_rect();
        Rect::from_min_max(Pos2::new(panel.right(), screen.top()), screen.max)
    };
    let mut headers = 0;
    for row in ids.chunks(5) {
        h.state_mut().frame_graph_nodes(row);
        h.run_steps(4);
        for id in row {
            let title = node_title(&g, *id);
            let r = screen_rect(&h, *id);
            let panel = h.state().graph_view().panel().unwrap();
            headers += check_text(&h, &title, panel, r, "header");
        }
    }
    assert_eq!(headers, ids.len(), "one header per node");
    // The inspector's doc line: the doc's first sentence, whole (wrapped, not cut).
    for id in &ids {
        h.state_mut().session.selected = Some(*id);
        h.run_steps(2);
        let op = rgbn::nodes::find(&g.nodes[id].op).unwrap();
        let summary = doc_summary(op.spec().doc);
        assert!(
            summary.ends_with('.') || summary == op.spec().doc,
            "{summary}"
        );
        assert_eq!(
            summary.matches('(').count(),
            summary.matches(')').count(),
            "{summary}"
        );
        let area = inspector(&h);
        assert_eq!(
            check_text(&h, summary, area, area, "inspector"),
            1,
            "{summary}"
        );
    }
    assert_eq!(
        doc_summary(rgbn::nodes::find("bilateral").unwrap().spec().doc),
        "RGBN bilateral filter (Toler-Franklin et al. 2007; Pereira & Velho §VII): base = the edge-preserving smoothing of the normals, detail = the rotation taking the base to the input, as a normal in the base's tangent frame."
    );
}

#[test]
fn every_shortcut_of_the_help_window_is_in_the_user_guide() {
    let doc = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/editor.md"),
    )
    .unwrap();
    for (keys, what) in rgbn::app::shortcuts::SHORTCUTS {
        assert!(
            doc.contains(&format!("| {keys} | {what} |")),
            "docs/editor.md lacks the row {keys} | {what}"
        );
    }
}
