//! The add-node menu: a search field that has the keyboard as soon as the menu opens (typing
//! filters, Enter adds the highlighted operator, Up / Down move the highlight, Escape closes),
//! opened by a right-click on empty graph space, by Tab or Shift+A with the pointer over the
//! graph, or by dropping a wire in empty space — then it offers only the operators whose ports
//! the core accepts for that wire ([`Graph::connect`] decides), and the new node is connected.
//!
//! The node lands where the menu was opened: the point right-clicked or under the pointer in
//! graph coordinates, kept apart from the popup's own position (egui moves a popup to fit on
//! screen: a menu opened low in the panel opens upwards, and taking the node's position from
//! the popup put it at the top of the view), or at the end of the dropped wire.
//!
//! Nodes (Houdini, Nuke, Substance use Tab; Blender Shift+A) — the menu's ranking (exact id or
//! title, then prefixes, then words, then anywhere) is [`ranked`], tested without a window.

use super::EditorApp;
use crate::graph::{Graph, NodeId};
use crate::nodes::{self, OpSpec};
use egui::emath::TSTransform;
use egui::{Event, Key, Modifiers, Pos2, RichText, Ui};
use std::path::Path;

/// A wire dropped in empty space: the pin it was dragged from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Wire {
    /// From an output of `node`: the new node's input takes it.
    Out {
        /// The node.
        node: NodeId,
        /// Its output port.
        port: String,
    },
    /// From an input of `node`: the new node's output feeds it.
    In {
        /// The node.
        node: NodeId,
        /// Its input port.
        port: String,
    },
}

impl Wire {
    /// `#3.image` (for the menu's title and messages).
    #[must_use]
    pub fn label(&self) -> String {
        match self {
            Wire::Out { node, port } => format!("from #{node}.{port}"),
            Wire::In { node, port } => format!("into #{node}.{port}"),
        }
    }
}

/// An operator the menu offers, with the port of the new node a dropped wire goes to.
#[derive(Clone, Debug, PartialEq)]
pub struct Offer {
    /// The operator.
    pub spec: &'static OpSpec,
    /// The new node's port the wire connects (an input for [`Wire::Out`], an output for
    /// [`Wire::In`]); `None` without a wire.
    pub port: Option<String>,
}

/// The reroute's entry in the menu (a point on a wire, not an operator: see
/// [`crate::graph::reroute`]).
pub fn reroute_spec() -> &'static OpSpec {
    static SPEC: std::sync::LazyLock<OpSpec> = std::sync::LazyLock::new(|| {
        OpSpec {
        id: nodes::REROUTE_OP,
        title: "Reroute",
        category: "layout",
        doc: "A point on a wire, to route it around nodes; its output fans out to any number of inputs. Evaluation does not see it.",
        version: 1,
        inputs: Vec::new(),
        outputs: Vec::new(),
        side_effect: false,
        lazy_outputs: false,
    }
    });
    &SPEC
}

/// Every registered operator, in menu order, then the reroute.
#[must_use]
pub fn all_offers() -> Vec<Offer> {
    nodes::registry()
        .iter()
        .map(|o| o.spec())
        .chain([reroute_spec()])
        .map(|spec| Offer { spec, port: None })
        .collect()
}

/// The operators a new node of which the core connects to `wire`, with the port it takes:
/// for each operator, a node of it is added to a copy of `graph` and [`Graph::connect`] is
/// asked for each of its ports in turn (inputs for a wire from an output, outputs for a wire
/// into an input); the first it accepts is the port.
#[must_use]
pub fn offers_for_wire(graph: &Graph, wire: &Wire, base_dir: &Path) -> Vec<Offer> {
    let mut out = Vec::new();
    for op in nodes::registry() {
        let spec = op.spec();
        let mut g = graph.clone();
        let id = g.add_node(spec.id, [0.0, 0.0]);
        let Ok(ports) = g.node_ports(id, base_dir) else {
            continue;
        };
        let port = match wire {
            Wire::Out { node, port } => ports.inputs.iter().find(|i| {
                g.clone()
                    .connect(*node, port, id, &i.name, base_dir)
                    .is_ok()
            }),
            Wire::In { node, port } => ports.outputs.iter().find(|o| {
                g.clone()
                    .connect(id, &o.name, *node, port, base_dir)
                    .is_ok()
            }),
        };
        if let Some(p) = port {
            out.push(Offer {
                spec,
                port: Some(p.name.clone()),
            });
        }
    }
    // A reroute takes any wire.
    let port = match wire {
        Wire::Out { .. } => crate::graph::reroute::IN,
        Wire::In { .. } => crate::graph::reroute::OUT,
    };
    out.push(Offer {
        spec: reroute_spec(),
        port: Some(port.into()),
    });
    out
}

/// How well `spec` matches the lowercase query `q`: 0 the id or title itself, 1 a prefix of
/// either, 2 a prefix of a word of the title or of the id after its family (`gaussian` of
/// `filter.gaussian`), 3 anywhere in either, 4 the category; `None`: no match.
fn score(spec: &OpSpec, q: &str) -> Option<u8> {
    let id = spec.id.to_lowercase();
    let title = spec.title.to_lowercase();
    if id == q || title == q {
        return Some(0);
    }
    if id.starts_with(q) || title.starts_with(q) {
        return Some(1);
    }
    let words = title
        .split(|c: char| !c.is_alphanumeric())
        .chain(id.split(['.', '_']));
    if words.filter(|w| !w.is_empty()).any(|w| w.starts_with(q)) {
        return Some(2);
    }
    if id.contains(q) || title.contains(q) {
        return Some(3);
    }
    spec.category.to_lowercase().contains(q).then_some(4)
}

/// The offers matching `query`, in the order the menu lists them (the first is the one Enter
/// adds): with no query, by category (alphabetical) then menu order; with one, by how well they
/// match (`score`), then category, then menu order.
#[must_use]
pub fn ranked(query: &str, offers: &[Offer]) -> Vec<usize> {
    let q = query.trim().to_lowercase();
    let mut hits: Vec<(u8, &str, usize)> = offers
        .iter()
        .enumerate()
        .filter_map(|(k, o)| {
            let s = if q.is_empty() {
                Some(0)
            } else {
                score(o.spec, &q)
            }?;
            Some((s, o.spec.category, k))
        })
        .collect();
    hits.sort();
    hits.into_iter().map(|(_, _, k)| k).collect()
}

/// The search and highlight of a list of operators.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Search {
    /// The text typed.
    pub text: String,
    /// The highlighted row (Enter adds it).
    pub highlight: usize,
}

/// Draws the search field and the list; returns the index in `offers` of the operator chosen
/// (clicked, or highlighted when Enter was pressed). With `grab`, the field takes the keyboard
/// and the list answers Up, Down and Enter.
pub fn list_ui(ui: &mut Ui, search: &mut Search, offers: &[Offer], grab: bool) -> Option<usize> {
    let rows = ranked(&search.text, offers);
    let (mut up, mut down, mut enter) = (false, false, false);
    if grab {
        ui.input_mut(|i| {
            up = i.consume_key(Modifiers::NONE, Key::ArrowUp);
            down = i.consume_key(Modifiers::NONE, Key::ArrowDown);
            enter = i.consume_key(Modifiers::NONE, Key::Enter);
            // Tab would move the keyboard to another widget.
            i.consume_key(Modifiers::NONE, Key::Tab);
        });
        if up || down {
            // The arrows would also move the keyboard focus to a neighbouring widget.
            ui.memory_mut(|m| m.move_focus(egui::FocusDirection::None));
        }
    }
    let moved = up || down;
    if down {
        search.highlight = (search.highlight + 1).min(rows.len().saturating_sub(1));
    }
    if up {
        search.highlight = search.highlight.saturating_sub(1);
    }
    ui.horizontal(|ui| {
        ui.label("🔍");
        let r = ui.add(
            egui::TextEdit::singleline(&mut search.text)
                .hint_text("search operators")
                .desired_width(200.0),
        );
        if grab && !r.has_focus() {
            r.request_focus();
        }
        if r.changed() {
            search.highlight = 0;
        }
    });
    let rows = ranked(&search.text, offers);
    search.highlight = search.highlight.min(rows.len().saturating_sub(1));
    if enter {
        return rows.get(search.highlight).copied();
    }
    if rows.is_empty() {
        ui.weak("no operator matches");
        return None;
    }
    let mut chosen = None;
    let grouped = search.text.trim().is_empty();
    egui::ScrollArea::vertical()
        .max_height(360.0)
        .auto_shrink([false, true])
        .show(ui, |ui| {
            let mut last_cat = "";
            for (row, &k) in rows.iter().enumerate() {
                let spec = offers[k].spec;
                if grouped && spec.category != last_cat {
                    ui.label(RichText::new(spec.category).small().weak());
                    last_cat = spec.category;
                }
                let hl = row == search.highlight;
                let r = ui.horizontal(|ui| {
                    let r = ui.selectable_label(hl, spec.title).on_hover_text(spec.doc);
                    if !grouped {
                        ui.label(RichText::new(spec.category).small().weak());
                    }
                    r
                });
                if hl && moved {
                    r.response.scroll_to_me(None);
                }
                if r.inner.clicked() {
                    chosen = Some(k);
                }
            }
        });
    chosen
}

/// What the menu was opened for.
#[derive(Clone, Debug)]
struct Open {
    /// The popup's top-left on screen (egui may move it to fit).
    screen: Pos2,
    /// Where the new node goes, in graph coordinates.
    at: [f32; 2],
    /// The dropped wire, if any.
    wire: Option<Wire>,
    offers: Vec<Offer>,
    search: Search,
    /// Frames since it opened (a click that opened it does not close it).
    age: u32,
    /// Text the key that opened the menu types, kept out of the search field.
    swallow: Option<&'static str>,
}

/// A choice made in the menu.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    /// The operator.
    pub op: &'static str,
    /// Where the menu was opened (graph coordinates): the node's position, or the dropped
    /// wire's end.
    pub at: [f32; 2],
    /// The dropped wire and the new node's port it connects.
    pub wire: Option<(Wire, String)>,
}

/// The graph view's add menu (closed or open).
#[derive(Clone, Debug, Default)]
pub struct AddMenu {
    open: Option<Open>,
}

impl AddMenu {
    /// True while the menu is shown.
    #[must_use]
    pub fn is_open(&self) -> bool {
        self.open.is_some()
    }

    /// The dropped wire the open menu is for.
    #[must_use]
    pub fn wire(&self) -> Option<&Wire> {
        self.open.as_ref()?.wire.as_ref()
    }

    /// The search typed and the highlighted row (while open).
    #[must_use]
    pub fn search(&self) -> Option<&Search> {
        self.open.as_ref().map(|o| &o.search)
    }

    /// The operators offered (while open), in the order listed for the current search.
    #[must_use]
    pub fn listed(&self) -> Vec<&'static str> {
        self.open.as_ref().map_or_else(Vec::new, |o| {
            ranked(&o.search.text, &o.offers)
                .into_iter()
                .map(|k| o.offers[k].spec.id)
                .collect()
        })
    }

    /// The graph position new nodes go to (while open).
    #[must_use]
    pub fn at(&self) -> Option<[f32; 2]> {
        self.open.as_ref().map(|o| o.at)
    }

    /// Opens the menu at screen point `screen` of a view whose graph-to-screen transform is
    /// `to_global`: every operator, the new node at that point.
    pub fn open_at(&mut self, screen: Pos2, to_global: TSTransform) {
        let at = to_global.inverse() * screen;
        self.open = Some(Open {
            screen,
            at: [at.x, at.y],
            wire: None,
            offers: all_offers(),
            search: Search::default(),
            age: 0,
            swallow: None,
        });
    }

    /// Opens the menu for a wire dropped at `screen`: the operators the core connects to it.
    pub fn open_for_wire(
        &mut self,
        screen: Pos2,
        to_global: TSTransform,
        wire: Wire,
        graph: &Graph,
        base_dir: &Path,
    ) {
        let at = to_global.inverse() * screen;
        self.open = Some(Open {
            screen,
            at: [at.x, at.y],
            offers: offers_for_wire(graph, &wire, base_dir),
            wire: Some(wire),
            search: Search::default(),
            age: 0,
            swallow: None,
        });
    }

    /// Keeps `typed` (the text of the key that opened the menu: Shift+A types "A") out of the
    /// search field when it arrives in the next frames.
    pub fn swallow(&mut self, typed: &'static str) {
        if let Some(o) = &mut self.open {
            o.swallow = (!typed.is_empty()).then_some(typed);
        }
    }

    /// Closes the menu.
    pub fn close(&mut self) {
        self.open = None;
    }

    /// Draws the open menu (a popup above everything); returns the operator picked.
    pub fn show(&mut self, ctx: &egui::Context) -> Option<Pick> {
        let open = self.open.as_mut()?;
        open.age += 1;
        if let Some(t) = open.swallow {
            let found = ctx.input_mut(|i| {
                let k = i
                    .events
                    .iter()
                    .position(|e| matches!(e, Event::Text(x) if x == t));
                k.map(|k| i.events.remove(k)).is_some()
            });
            if found || open.age > 3 {
                open.swallow = None;
            }
        }
        let escape = ctx.input_mut(|i| i.consume_key(Modifiers::NONE, Key::Escape));
        if escape {
            self.open = None;
            return None;
        }
        let mut chosen = None;
        let area = egui::Area::new(egui::Id::new("rgbn-add-menu"))
            .order(egui::Order::Foreground)
            .fixed_pos(open.screen)
            .constrain(true)
            .show(ctx, |ui| {
                egui::Frame::menu(ui.style()).show(ui, |ui| {
                    ui.set_width(280.0);
                    let title = match &open.wire {
                        Some(w) => format!("Add node {}", w.label()),
                        None => "Add node".to_string(),
                    };
                    ui.label(RichText::new(title).strong());
                    if open.offers.is_empty() {
                        ui.weak("no operator takes this wire");
                    }
                    chosen = list_ui(ui, &mut open.search, &open.offers, true);
                });
            });
        // A press outside the menu closes it (the press that opened it is over by now).
        let outside = ctx.input(|i| {
            i.pointer.any_pressed()
                && i.pointer
                    .interact_pos()
                    .is_some_and(|p| !area.response.rect.contains(p))
        });
        let pick = chosen.map(|k| {
            let offer = &open.offers[k];
            Pick {
                op: offer.spec.id,
                at: open.at,
                wire: open.wire.clone().zip(offer.port.clone()),
            }
        });
        if pick.is_some() || (outside && open.age > 1) {
            self.open = None;
        }
        pick
    }
}

/// Tab or Shift+A this frame (consumed): the keys that open the menu at the pointer. Returns
/// the text the key types (`"A"` for Shift+A, which [`AddMenu::swallow`] keeps out of the
/// search field whether it comes in the same frame or the next), or `None` without them.
pub fn take_open_keys(ctx: &egui::Context) -> Option<&'static str> {
    let typed = ctx.input_mut(|i| {
        if i.consume_key(Modifiers::NONE, Key::Tab) {
            Some("")
        } else if i.consume_key(Modifiers::SHIFT, Key::A) {
            Some("A")
        } else {
            None
        }
    })?;
    // Tab also moves egui's keyboard focus to the next widget.
    ctx.memory_mut(|m| m.move_focus(egui::FocusDirection::None));
    Some(typed)
}

impl EditorApp {
    /// Adds a node of `op` at graph position `pos` connected to a dropped `wire` through the
    /// new node's `port`, as one undo step. The node's side that takes the wire is put at the
    /// wire's end (its left edge for a wire from an output, its right edge for one into an
    /// input), then moved to the nearest free spot.
    pub fn add_wired(&mut self, op: &str, pos: [f32; 2], wire: &Wire, port: &str) -> NodeId {
        let size = self.view.size_hint(&self.session.doc.graph, op);
        let corner = match wire {
            Wire::Out { .. } => [pos[0] + 12.0, pos[1] - 30.0],
            Wire::In { .. } => [pos[0] - size[0] - 12.0, pos[1] - 30.0],
        };
        let corner = self.place_node(op, corner, true);
        let base = self.session.doc.base_dir();
        let before = self.session.doc.graph.clone();
        let g = &mut self.session.doc.graph;
        let id = g.add_node(op, corner);
        let connected = match wire {
            Wire::Out { node, port: from } => g.connect(*node, from, id, port, &base),
            Wire::In { node, port: into } => g.connect(id, port, *node, into, &base),
        };
        self.session.doc.history.commit(before);
        self.watch_placed(id);
        self.session.selected = Some(id);
        match connected {
            Ok(()) => self.say(format!("added {op} (#{id}) {}", wire.label())),
            Err(e) => self.fail(format!("added {op} (#{id}); connection refused: {e}")),
        }
        id
    }
}

#[cfg(test)]
#[path = "add_menu_tests.rs"]
mod tests;
