//! The node graph view: a [`Snarl<NodeId>`] mirroring the document's [`Graph`].
//!
//! The graph is the truth, the widget a view. The viewer never edits the graph nor the snarl
//! itself: connects, disconnects and menu commands become [`Action`]s that the app applies to
//! the document (the core checks connections); then [`GraphView::sync`] mirrors the graph into
//! the snarl (incrementally, so the widget keeps its selection). Egui-snarl's own node ids are
//! reused slab indices: they are never persisted nor used as keys outside this module.

use super::add_menu::{self, AddMenu, Wire};
use super::crisp;
use super::placement::{self, Rect as PlaceRect};
use crate::graph::{Graph, NodeId, NodePorts};
use crate::nodes::{self, PortType, GRAPH_NODE_OP, REROUTE_OP};
use egui::emath::TSTransform;
use egui::{Color32, Id, Pos2, RichText, TextureHandle, Ui};
use egui_snarl::ui::{AnyPins, PinInfo, SnarlPin, SnarlStyle, SnarlViewer, SnarlWidget};
use egui_snarl::{InPin, InPinId, OutPin, OutPinId, Snarl};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The snarl widget's id (selection is read back through it).
pub const SNARL_ID: &str = "rgbn-graph";

/// An edit asked for in the graph view, applied by the app after the frame's UI.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Add a node of this operator at this position.
    AddNode {
        /// Operator id.
        op: String,
        /// Graph position.
        pos: [f32; 2],
    },
    /// Add a node of this operator at a dropped wire's end, connected to it.
    AddWired {
        /// Operator id.
        op: String,
        /// The wire's end (graph position).
        pos: [f32; 2],
        /// The wire.
        wire: Wire,
        /// The new node's port it connects.
        port: String,
    },
    /// Connect an output to an input.
    Connect {
        /// Source node.
        from: NodeId,
        /// Its output port.
        from_port: String,
        /// Target node.
        to: NodeId,
        /// Its input port.
        port: String,
    },
    /// Remove the edge into an input.
    Disconnect {
        /// Target node.
        to: NodeId,
        /// Its input port.
        port: String,
    },
    /// Delete nodes.
    Delete(Vec<NodeId>),
    /// Duplicate nodes.
    Duplicate(Vec<NodeId>),
    /// Show this node's output in the preview.
    View(NodeId),
    /// Show this output port of this node in the preview.
    ViewPort(NodeId, String),
    /// Write this node's (first) output to a file chosen in the file dialog.
    Export(NodeId),
    /// Choose this path parameter of this node in the file dialog.
    BrowseParam(NodeId, String),
    /// Put a new frame around these nodes.
    FrameNodes(Vec<NodeId>),
    /// Open the rename / recolour dialog of frame number `index`.
    EditFrame(usize),
    /// Remove frame number `index` (its nodes stay).
    DeleteFrame(usize),
    /// Put a reroute at `pos` on the wire from `from`'s `from_port` into `to`'s `port`.
    InsertReroute {
        /// Source node.
        from: NodeId,
        /// Its output port.
        from_port: String,
        /// Target node.
        to: NodeId,
        /// Its input port.
        port: String,
        /// Graph position.
        pos: [f32; 2],
    },
    /// Group these nodes into a subgraph (opens the dialog choosing what to expose).
    Group(Vec<NodeId>),
    /// Inline this graph node.
    Ungroup(NodeId),
    /// Open this graph node in place.
    EnterGroup(NodeId),
}

/// Colour of a port type (pins and wires).
#[must_use]
pub fn type_color(t: PortType) -> Color32 {
    match t {
        PortType::Rgbn => Color32::from_rgb(0x5b, 0x9b, 0xd5),
        PortType::Mask => Color32::from_rgb(0xc0, 0xc0, 0xc0),
        PortType::Scalar => Color32::from_rgb(0xe0, 0xa0, 0x40),
        PortType::Picture => Color32::from_rgb(0x70, 0xc0, 0x70),
        PortType::Number => Color32::from_rgb(0xc0, 0x70, 0xc0),
    }
}

/// Per-frame data the viewer shows.
pub struct ViewData<'a> {
    /// The graph.
    pub graph: &'a Graph,
    /// Resolved ports of every node (missing: the node failed to resolve).
    pub ports: &'a BTreeMap<NodeId, NodePorts>,
    /// Thumbnails.
    pub thumbs: &'a BTreeMap<NodeId, TextureHandle>,
    /// Errors by node.
    pub errors: &'a BTreeMap<NodeId, String>,
    /// Nodes waiting for an input (the port), shown as waiting, not failed.
    pub waiting: &'a BTreeMap<NodeId, String>,
    /// Non-integrable fraction F of each node's RGBN output.
    pub fraction: &'a BTreeMap<NodeId, f64>,
    /// Green-convention badges of the `load` nodes ([`super::green_badge`]).
    pub green: &'a BTreeMap<NodeId, super::green_badge::Badge>,
    /// The node shown in the preview.
    pub viewed: Option<NodeId>,
    /// Its output port shown in the preview.
    pub viewed_port: Option<&'a str>,
    /// The folder relative paths are resolved in (connections are checked against it).
    pub base_dir: &'a Path,
}

/// The mirror of the graph in egui-snarl.
pub struct GraphView {
    snarl: Snarl<NodeId>,
    by_id: BTreeMap<NodeId, egui_snarl::NodeId>,
    style: SnarlStyle,
    /// The search of the menu bar's Add menu.
    pub bar_search: add_menu::Search,
    /// The add-node menu of the graph (right-click, Tab, Shift+A, a dropped wire).
    pub menu: AddMenu,
    /// Frames left during which the view is fitted to the graph (panels settle in the first
    /// frames, so fitting lasts a few).
    pub frame_pending: u32,
    /// Fit the view to these nodes rather than to all of them ("Frame selected").
    frame_only: Option<BTreeSet<NodeId>>,
    /// The view's graph-to-screen transform, as last drawn.
    to_global: TSTransform,
    /// The graph panel's screen rectangle, as last drawn.
    panel: Option<egui::Rect>,
    /// Each drawn node's rectangle relative to its position (offset of the top-left corner,
    /// size), as the widget last drew it.
    measured: BTreeMap<NodeId, ([f32; 2], [f32; 2])>,
    /// Which document the widget shows ([`Self::new_document`]): its state (selection, view)
    /// is kept in egui under an id of its own per document.
    doc_scope: u64,
}

impl Default for GraphView {
    fn default() -> Self {
        let style = SnarlStyle {
            pin_size: Some(9.0),
            collapsible: Some(false),
            ..SnarlStyle::new()
        };
        Self {
            snarl: Snarl::new(),
            by_id: BTreeMap::new(),
            style,
            bar_search: add_menu::Search::default(),
            menu: AddMenu::default(),
            frame_pending: 3,
            frame_only: None,
            to_global: TSTransform::IDENTITY,
            panel: None,
            measured: BTreeMap::new(),
            doc_scope: 0,
        }
    }
}

impl GraphView {
    /// Starts over for another document (opened, or a group entered or left): no node of the
    /// old one stays in the widget, and its selection, kept by the widget's node indices, does
    /// not carry over to the nodes of the new one that reuse them. The view is fitted again.
    pub fn new_document(&mut self) {
        self.snarl = Snarl::new();
        self.by_id.clear();
        self.measured.clear();
        self.frame_only = None;
        self.frame_pending = 3;
        self.doc_scope += 1;
    }

    /// The widget's egui id for the current document.
    fn snarl_id(&self) -> Id {
        Id::new(SNARL_ID).with(self.doc_scope)
    }

    /// Mirrors `graph` into the snarl: adds and removes nodes, moves them, fixes wires.
    pub fn sync(&mut self, graph: &Graph, ports: &BTreeMap<NodeId, NodePorts>) {
        let gone: Vec<NodeId> = self
            .by_id
            .keys()
            .filter(|id| !graph.nodes.contains_key(id))
            .copied()
            .collect();
        for id in gone {
            if let Some(sid) = self.by_id.remove(&id) {
                self.snarl.remove_node(sid);
            }
        }
        self.measured.retain(|id, _| graph.nodes.contains_key(id));
        for (id, n) in &graph.nodes {
            let pos = Pos2::new(n.pos[0], n.pos[1]);
            match self.by_id.get(id) {
                None => {
                    let sid = self.snarl.insert_node(pos, *id);
                    self.by_id.insert(*id, sid);
                }
                Some(sid) => {
                    if let Some(info) = self.snarl.get_node_info_mut(*sid) {
                        if info.pos != pos {
                            info.pos = pos;
                        }
                    }
                }
            }
        }
        let mut want = BTreeSet::new();
        for (id, n) in &graph.nodes {
            let (Some(sid), Some(p)) = (self.by_id.get(id), ports.get(id)) else {
                continue;
            };
            for (port, src) in &n.inputs {
                let crate::graph::Source::Node(from, from_port) = src else {
                    continue;
                };
                let (Some(fsid), Some(fp)) = (self.by_id.get(from), ports.get(from)) else {
                    continue;
                };
                let (Some(i), Some(o)) = (
                    p.inputs.iter().position(|x| &x.name == port),
                    fp.outputs.iter().position(|x| &x.name == from_port),
                ) else {
                    continue;
                };
                want.insert((
                    OutPinId {
                        node: *fsid,
                        output: o,
                    },
                    InPinId {
                        node: *sid,
                        input: i,
                    },
                ));
            }
        }
        let have: BTreeSet<(OutPinId, InPinId)> = self.snarl.wires().collect();
        for (o, i) in have.difference(&want) {
            self.snarl.disconnect(*o, *i);
        }
        for (o, i) in want.difference(&have) {
            self.snarl.connect(*o, *i);
        }
    }

    /// Copies node positions moved in the widget back into the graph.
    pub fn write_back_positions(&self, graph: &mut Graph) {
        for (id, sid) in &self.by_id {
            if let (Some(info), Some(n)) = (self.snarl.get_node_info(*sid), graph.nodes.get_mut(id))
            {
                let p = [info.pos.x, info.pos.y];
                if n.pos != p {
                    n.pos = p;
                }
            }
        }
    }

    /// Graph ids of the nodes selected in the widget.
    #[must_use]
    pub fn selected(&self, ctx: &egui::Context) -> Vec<NodeId> {
        egui_snarl::ui::get_selected_nodes(self.snarl_id(), ctx)
            .into_iter()
            .filter_map(|sid| self.snarl.get_node(sid).copied())
            .collect()
    }

    /// The rectangle of every node of `graph` in graph coordinates: as last drawn, or of
    /// [`placement::DEFAULT_NODE_SIZE`] at its position when it was not drawn yet.
    #[must_use]
    pub fn node_rects(&self, graph: &Graph) -> Vec<(NodeId, PlaceRect)> {
        let drawn = self.drawn_rects(graph);
        graph
            .nodes
            .values()
            .map(|n| {
                let r = drawn
                    .get(&n.id)
                    .copied()
                    .unwrap_or_else(|| PlaceRect::new(n.pos, placement::DEFAULT_NODE_SIZE));
                (n.id, r)
            })
            .collect()
    }

    /// The rectangles of the nodes of `graph` that were drawn, at their current positions.
    #[must_use]
    pub fn drawn_rects(&self, graph: &Graph) -> BTreeMap<NodeId, PlaceRect> {
        graph
            .nodes
            .values()
            .filter_map(|n| {
                let (off, size) = self.measured.get(&n.id)?;
                Some((
                    n.id,
                    PlaceRect::new([n.pos[0] + off[0], n.pos[1] + off[1]], *size),
                ))
            })
            .collect()
    }

    /// The size to expect of a new node of operator `op`: the largest drawn node of that
    /// operator, at least [`placement::DEFAULT_NODE_SIZE`].
    #[must_use]
    pub fn size_hint(&self, graph: &Graph, op: &str) -> [f32; 2] {
        self.measured
            .iter()
            .filter(|(id, _)| graph.nodes.get(id).is_some_and(|n| n.op == op))
            .fold(placement::DEFAULT_NODE_SIZE, |a, (_, (_, s))| {
                [a[0].max(s[0]), a[1].max(s[1])]
            })
    }

    /// Number of wires shown (tests).
    #[must_use]
    pub fn wire_count(&self) -> usize {
        self.snarl.wires().count()
    }

    /// The graph-to-screen transform of the view, as last drawn.
    #[must_use]
    pub fn to_global(&self) -> TSTransform {
        self.to_global
    }

    /// The graph panel's screen rectangle, as last drawn.
    #[must_use]
    pub fn panel(&self) -> Option<egui::Rect> {
        self.panel
    }

    /// Fits the view to `ids` (all nodes when empty) over the next frames.
    pub fn frame_nodes(&mut self, ids: &[NodeId]) {
        self.frame_only = (!ids.is_empty()).then(|| ids.iter().copied().collect());
        self.frame_pending = 2;
    }

    /// The graph's keys, at the start of a frame (before any widget takes Tab for focus):
    /// Tab or Shift+A with the pointer over the graph opens the add menu there; F frames the
    /// nodes selected in the graph (else the `inspected` node, else all), Home all of them.
    /// Not while `typing` in a field.
    pub fn keys(&mut self, ctx: &egui::Context, typing: bool, inspected: Option<NodeId>) {
        if typing || self.menu.is_open() {
            return;
        }
        let over_graph = ctx.pointer_hover_pos().filter(|p| {
            self.panel.is_some_and(|r| r.contains(*p))
                && ctx
                    .layer_id_at(*p)
                    .is_none_or(|l| l.order == egui::Order::Background)
        });
        if let Some(p) = over_graph {
            if let Some(typed) = add_menu::take_open_keys(ctx) {
                self.menu.open_at(p, self.to_global);
                self.menu.swallow(typed);
                return;
            }
        }
        let (f, home) = ctx.input_mut(|i| {
            (
                i.consume_key(egui::Modifiers::NONE, egui::Key::F),
                i.consume_key(egui::Modifiers::NONE, egui::Key::Home),
            )
        });
        if f {
            let mut sel = self.selected(ctx);
            if sel.is_empty() {
                sel.extend(inspected);
            }
            self.frame_nodes(&sel);
        } else if home {
            self.frame_nodes(&[]);
        }
    }

    /// Draws the graph and the add menu; returns the actions asked for.
    pub fn show_ui(&mut self, ui: &mut Ui, data: &ViewData<'_>) -> Vec<Action> {
        let panel = ui.available_rect_before_wrap();
        self.panel = Some(panel);
        let frame = (self.frame_pending > 0).then_some(panel);
        self.frame_pending = self.frame_pending.saturating_sub(1);
        let (pointer, shift) = ui.input(|i| (i.pointer.latest_pos(), i.modifiers.shift));
        let snarl_id = self.snarl_id();
        let mut viewer = Viewer {
            data,
            actions: Vec::new(),
            frame,
            frame_only: self.frame_only.as_ref(),
            measured: &mut self.measured,
            to_global: self.to_global,
            request: None,
            pointer,
            shift,
            snarl_id,
        };
        let resp = SnarlWidget::new().id(snarl_id).style(self.style).show(
            &mut self.snarl,
            &mut viewer,
            ui,
        );
        let (mut actions, request, to_global) = (viewer.actions, viewer.request, viewer.to_global);
        self.to_global = to_global;
        if self.frame_pending == 0 {
            self.frame_only = None;
        }
        // Frames: their title bars drag their nodes (moved in the widget, written back to the
        // graph with the nodes' own moves).
        let rects = super::frames::frame_rects(data.graph, |id| {
            super::frames::node_rect(data.graph, &self.measured, id)
        });
        for (i, delta) in super::frames::bars_ui(
            ui,
            snarl_id,
            data.graph,
            &rects,
            to_global,
            resp.rect,
            &mut actions,
        ) {
            for id in &data.graph.frames[i].nodes {
                if let Some(info) = self
                    .by_id
                    .get(id)
                    .and_then(|s| self.snarl.get_node_info_mut(*s))
                {
                    info.pos += delta;
                }
            }
        }
        // A double-click on a graph node opens it in place.
        if let Some(p) = pointer.filter(|p| resp.rect.contains(*p)) {
            // (egui counts a second quick click on the spot of a click made up to 0.6 s
            // earlier anywhere else as a triple click.)
            let b = egui::PointerButton::Primary;
            if ui
                .input(|i| i.pointer.button_double_clicked(b) || i.pointer.button_triple_clicked(b))
            {
                let at = to_global.inverse() * p;
                let hit = self.drawn_rects(data.graph).into_iter().find(|(id, r)| {
                    let max = r.max();
                    data.graph.nodes[id].op == GRAPH_NODE_OP
                        && (r.min[0]..=max[0]).contains(&at.x)
                        && (r.min[1]..=max[1]).contains(&at.y)
                });
                if let Some((id, _)) = hit {
                    actions.push(Action::EnterGroup(id));
                }
            }
        }
        let ctx = ui.ctx().clone();
        if let Some(req) = request {
            let screen = ctx
                .input(|i| i.pointer.interact_pos().or(i.pointer.latest_pos()))
                .unwrap_or(panel.center());
            match req {
                MenuRequest::Graph => self.menu.open_at(screen, to_global),
                MenuRequest::Wire(w) => {
                    self.menu
                        .open_for_wire(screen, to_global, w, data.graph, data.base_dir);
                }
            }
        }
        if let Some(pick) = self.menu.show(&ctx) {
            let op = pick.op.to_string();
            actions.push(match pick.wire {
                None => Action::AddNode { op, pos: pick.at },
                Some((wire, port)) => Action::AddWired {
                    op,
                    pos: pick.at,
                    wire,
                    port,
                },
            });
        }
        actions
    }
}

/// What the widget asked the menu for this frame.
enum MenuRequest {
    /// A right-click on empty space.
    Graph,
    /// A wire dropped in empty space.
    Wire(Wire),
}

struct Viewer<'a, 'd> {
    data: &'a ViewData<'d>,
    actions: Vec<Action>,
    /// Fit the view to the graph in this screen rectangle.
    frame: Option<egui::Rect>,
    /// Fit it to these nodes only.
    frame_only: Option<&'a BTreeSet<NodeId>>,
    /// Drawn node rectangles (see [`GraphView::node_rects`]).
    measured: &'a mut BTreeMap<NodeId, ([f32; 2], [f32; 2])>,
    /// The view's transform this frame.
    to_global: TSTransform,
    /// The menu asked for.
    request: Option<MenuRequest>,
    /// The pointer on the screen.
    pointer: Option<Pos2>,
    /// Shift is held (Shift + right-click on a wire inserts a reroute).
    shift: bool,
    /// The widget's egui id.
    snarl_id: Id,
}

impl Viewer<'_, '_> {
    /// The view's zoom this frame.
    fn zoom(&self) -> f32 {
        self.to_global.scaling
    }

    /// The font and colour of text `style`, weak or not.
    fn text_style(&self, ui: &Ui, style: egui::TextStyle, weak: bool) -> (egui::FontId, Color32) {
        let color = if weak {
            ui.visuals().weak_text_color()
        } else {
            ui.visuals().text_color()
        };
        (style.resolve(ui.style()), color)
    }

    fn ports(&self, id: NodeId) -> Option<&NodePorts> {
        self.data.ports.get(&id)
    }

    /// Asks to remove the edge into input number `input` of node `node`.
    fn disconnect_input(&mut self, node: NodeId, input: usize) {
        if let Some(tp) = self.ports(node).and_then(|p| p.inputs.get(input)) {
            self.actions.push(Action::Disconnect {
                to: node,
                port: tp.name.clone(),
            });
        }
    }
}

/// A node's title: its name, or its operator's title.
#[must_use]
pub fn node_title(graph: &Graph, id: NodeId) -> String {
    let Some(n) = graph.nodes.get(&id) else {
        return format!("#{id}");
    };
    let op_title = match n.op.as_str() {
        REROUTE_OP => "Reroute",
        GRAPH_NODE_OP => "Group",
        op => nodes::find(op).map_or(op, |o| o.spec().title),
    };
    match &n.name {
        Some(name) => format!("{name} · {op_title}"),
        None => op_title.to_string(),
    }
}

impl Viewer<'_, '_> {
    fn is_reroute(&self, id: NodeId) -> bool {
        self.data.graph.is_reroute(id)
    }
}

impl SnarlViewer<NodeId> for Viewer<'_, '_> {
    fn title(&mut self, node: &NodeId) -> String {
        node_title(self.data.graph, *node)
    }

    fn node_frame(
        &mut self,
        default: egui::Frame,
        node: egui_snarl::NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        snarl: &Snarl<NodeId>,
    ) -> egui::Frame {
        // A reroute is a small dot-like node: its two pins and a grip between them.
        if self.is_reroute(snarl[node]) {
            default.inner_margin(egui::Margin::same(1))
        } else {
            default
        }
    }

    fn draw_background(
        &mut self,
        background: Option<&egui_snarl::ui::BackgroundPattern>,
        viewport: &egui::Rect,
        snarl_style: &SnarlStyle,
        style: &egui::Style,
        painter: &egui::Painter,
        _snarl: &Snarl<NodeId>,
    ) {
        if let Some(b) = background {
            b.draw(viewport, snarl_style, style, painter);
        }
        let graph = self.data.graph;
        let rects = super::frames::frame_rects(graph, |id| {
            super::frames::node_rect(graph, self.measured, id)
        });
        super::frames::paint(painter, graph, &rects);
    }

    fn header_frame(
        &mut self,
        default: egui::Frame,
        node: egui_snarl::NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        snarl: &Snarl<NodeId>,
    ) -> egui::Frame {
        let id = snarl[node];
        if self.data.errors.contains_key(&id) {
            default.fill(Color32::from_rgb(0x8a, 0x20, 0x20))
        } else if self.data.viewed == Some(id) {
            default.fill(Color32::from_rgb(0x2a, 0x4a, 0x6a))
        } else {
            default
        }
    }

    fn show_header(
        &mut self,
        node: egui_snarl::NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<NodeId>,
    ) {
        let id = snarl[node];
        if self.is_reroute(id) {
            ui.add_space(6.0);
            return;
        }
        let title = self.title(&id);
        let font = egui::TextStyle::Body.resolve(ui.style());
        let color = ui.visuals().strong_text_color();
        let r = crisp::label_ui(
            ui,
            &title,
            &font,
            color,
            self.zoom(),
            false,
            egui::Sense::hover(),
        );
        if let Some(n) = self.data.graph.nodes.get(&id) {
            if let Some(op) = nodes::find(&n.op) {
                r.on_hover_text(op.spec().doc);
            }
        }
    }

    fn inputs(&mut self, node: &NodeId) -> usize {
        self.ports(*node).map_or(0, |p| p.inputs.len())
    }

    fn outputs(&mut self, node: &NodeId) -> usize {
        self.ports(*node).map_or(0, |p| p.outputs.len())
    }

    fn show_input(
        &mut self,
        pin: &InPin,
        ui: &mut Ui,
        snarl: &mut Snarl<NodeId>,
    ) -> impl SnarlPin + 'static {
        let id = snarl[pin.id.node];
        let Some(p) = self.ports(id).and_then(|p| p.inputs.get(pin.id.input)) else {
            return PinInfo::circle();
        };
        if self.is_reroute(id) {
            return PinInfo::circle().with_fill(type_color(p.ty));
        }
        let text = if p.optional {
            format!("{} (optional)", p.name)
        } else {
            p.name.clone()
        };
        let (font, color) = self.text_style(ui, egui::TextStyle::Body, false);
        crisp::label_ui(
            ui,
            &text,
            &font,
            color,
            self.zoom(),
            false,
            egui::Sense::hover(),
        )
        .on_hover_text(format!("{} — {}", p.ty.name(), p.doc));
        PinInfo::circle().with_fill(type_color(p.ty))
    }

    fn show_output(
        &mut self,
        pin: &OutPin,
        ui: &mut Ui,
        snarl: &mut Snarl<NodeId>,
    ) -> impl SnarlPin + 'static {
        let id = snarl[pin.id.node];
        let data = self.data;
        let Some(p) = data
            .ports
            .get(&id)
            .and_then(|p| p.outputs.get(pin.id.output))
        else {
            return PinInfo::circle();
        };
        if self.is_reroute(id) {
            return PinInfo::circle().with_fill(type_color(p.ty));
        }
        let viewed = self.data.viewed == Some(id) && self.data.viewed_port == Some(p.name.as_str());
        let (font, color) = self.text_style(ui, egui::TextStyle::Body, false);
        let zoom = self.zoom();
        if crisp::label_ui(
            ui,
            &p.name,
            &font,
            color,
            zoom,
            viewed,
            egui::Sense::click(),
        )
        .on_hover_text(format!("{} — {} (click to preview)", p.ty.name(), p.doc))
        .clicked()
        {
            self.actions.push(Action::ViewPort(id, p.name.clone()));
        }
        PinInfo::square().with_fill(type_color(p.ty))
    }

    fn has_body(&mut self, node: &NodeId) -> bool {
        if self.is_reroute(*node) {
            return self.data.errors.contains_key(node);
        }
        self.data.thumbs.contains_key(node)
            || self.data.errors.contains_key(node)
            || self.data.waiting.contains_key(node)
            || self.data.green.contains_key(node)
    }

    fn show_body(
        &mut self,
        node: egui_snarl::NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<NodeId>,
    ) {
        let id = snarl[node];
        ui.vertical(|ui| {
            if let Some(t) = self.data.thumbs.get(&id) {
                let size = t.size_vec2();
                let scale = (72.0 / size.x.max(size.y)).min(1.0);
                ui.add(egui::Image::new((t.id(), size * scale)));
            }
            let (small, weak) = self.text_style(ui, egui::TextStyle::Small, true);
            if let Some(f) = self.data.fraction.get(&id) {
                let zoom = self.zoom();
                crisp::label_ui(ui, &format!("F {f:.2e}"), &small, weak, zoom, false, egui::Sense::hover())
                    .on_hover_text("Non-integrable fraction of this node's normals: 0 for a surface, √(2/π) ≈ 0.80 for noise");
            }
            if let Some(b) = self.data.green.get(&id) {
                let color = if b.mismatch {
                    Color32::from_rgb(0xe0, 0xb0, 0x40)
                } else {
                    weak
                };
                crisp::label_ui(ui, &b.text, &small, color, self.zoom(), false, egui::Sense::hover())
                    .on_hover_text(&b.hover);
            }
            if let Some(port) = self.data.waiting.get(&id) {
                let text = format!("waits for input {port}");
                crisp::label_ui(ui, &text, &small, weak, self.zoom(), false, egui::Sense::hover())
                    .on_hover_text("Connect this input (drag a wire to it) to evaluate the node");
            }
            if let Some(e) = self.data.errors.get(&id) {
                ui.set_min_width(170.0);
                ui.set_max_width(220.0);
                ui.add(
                    egui::Label::new(RichText::new(e).color(Color32::from_rgb(255, 120, 120)))
                        .wrap_mode(egui::TextWrapMode::Wrap),
                );
            }
        });
    }

    fn connect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<NodeId>) {
        let (fid, tid) = (snarl[from.id.node], snarl[to.id.node]);
        let (Some(fp), Some(tp)) = (
            self.ports(fid).and_then(|p| p.outputs.get(from.id.output)),
            self.ports(tid).and_then(|p| p.inputs.get(to.id.input)),
        ) else {
            return;
        };
        self.actions.push(Action::Connect {
            from: fid,
            from_port: fp.name.clone(),
            to: tid,
            port: tp.name.clone(),
        });
    }

    /// Right-click on a wire disconnects it; Shift + right-click puts a reroute there.
    fn disconnect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<NodeId>) {
        let (fid, tid) = (snarl[from.id.node], snarl[to.id.node]);
        if let (true, Some(p)) = (self.shift, self.pointer) {
            let (Some(fp), Some(tp)) = (
                self.ports(fid).and_then(|p| p.outputs.get(from.id.output)),
                self.ports(tid).and_then(|p| p.inputs.get(to.id.input)),
            ) else {
                return;
            };
            // The reroute's centre under the pointer (its pin sits a little left of it).
            let at = self.to_global.inverse() * p;
            self.actions.push(Action::InsertReroute {
                from: fid,
                from_port: fp.name.clone(),
                to: tid,
                port: tp.name.clone(),
                pos: [at.x - 12.0, at.y - 12.0],
            });
            return;
        }
        self.disconnect_input(tid, to.id.input);
    }

    fn drop_inputs(&mut self, pin: &InPin, snarl: &mut Snarl<NodeId>) {
        if !pin.remotes.is_empty() {
            self.disconnect_input(snarl[pin.id.node], pin.id.input);
        }
    }

    fn drop_outputs(&mut self, pin: &OutPin, snarl: &mut Snarl<NodeId>) {
        for r in &pin.remotes {
            let tid = snarl[r.node];
            if let Some(tp) = self.ports(tid).and_then(|p| p.inputs.get(r.input)) {
                self.actions.push(Action::Disconnect {
                    to: tid,
                    port: tp.name.clone(),
                });
            }
        }
    }

    fn final_node_rect(
        &mut self,
        node: egui_snarl::NodeId,
        rect: egui::Rect,
        _ui: &mut Ui,
        snarl: &mut Snarl<NodeId>,
    ) {
        // The rectangle is in graph coordinates (the widget draws nodes at their positions
        // under its pan/zoom transform).
        let (Some(&id), Some(info)) = (snarl.get_node(node), snarl.get_node_info(node)) else {
            return;
        };
        if rect.is_finite() {
            let off = rect.min - info.pos;
            self.measured
                .insert(id, ([off.x, off.y], [rect.width(), rect.height()]));
        }
    }

    fn current_transform(&mut self, to_global: &mut TSTransform, snarl: &mut Snarl<NodeId>) {
        if let Some(view) = self.frame {
            let mut bb = egui::Rect::NOTHING;
            for (_, pos, id) in snarl.nodes_pos_ids() {
                if self.frame_only.is_some_and(|only| !only.contains(id)) {
                    continue;
                }
                // As last drawn; a node not drawn yet as a typical node with a thumbnail.
                let (off, size) = self
                    .measured
                    .get(id)
                    .copied()
                    .unwrap_or(([0.0, 0.0], [250.0, 150.0]));
                let min = pos + egui::vec2(off[0], off[1]);
                bb = bb.union(egui::Rect::from_min_size(min, egui::vec2(size[0], size[1])));
            }
            if bb.is_finite() && view.is_finite() && view.width() >= 10.0 {
                let bb = bb.expand(30.0);
                let scaling = (view.size() / bb.size()).min_elem().clamp(0.2, 1.0);
                *to_global = TSTransform {
                    scaling,
                    translation: view.center().to_vec2() - bb.center().to_vec2() * scaling,
                };
            }
        }
        self.to_global = *to_global;
    }

    fn has_graph_menu(&mut self, _pos: Pos2, _snarl: &mut Snarl<NodeId>) -> bool {
        true
    }

    /// The widget's own popup is closed at once: the menu is [`AddMenu`], which keeps the
    /// point clicked (the popup moves to fit on screen) and takes the keyboard.
    fn show_graph_menu(&mut self, _pos: Pos2, ui: &mut Ui, _snarl: &mut Snarl<NodeId>) {
        self.request = Some(MenuRequest::Graph);
        ui.close();
    }

    fn has_dropped_wire_menu(&mut self, src_pins: AnyPins, _snarl: &mut Snarl<NodeId>) -> bool {
        match src_pins {
            AnyPins::Out(p) => !p.is_empty(),
            AnyPins::In(p) => !p.is_empty(),
        }
    }

    fn show_dropped_wire_menu(
        &mut self,
        _pos: Pos2,
        ui: &mut Ui,
        src_pins: AnyPins,
        snarl: &mut Snarl<NodeId>,
    ) {
        ui.close();
        let wire = match src_pins {
            AnyPins::Out(pins) => pins.first().and_then(|pin| {
                let node = *snarl.get_node(pin.node)?;
                let port = self.ports(node)?.outputs.get(pin.output)?.name.clone();
                Some(Wire::Out { node, port })
            }),
            AnyPins::In(pins) => pins.first().and_then(|pin| {
                let node = *snarl.get_node(pin.node)?;
                let port = self.ports(node)?.inputs.get(pin.input)?.name.clone();
                Some(Wire::In { node, port })
            }),
        };
        if let Some(w) = wire {
            self.request = Some(MenuRequest::Wire(w));
        }
    }

    fn has_node_menu(&mut self, _node: &NodeId) -> bool {
        true
    }

    fn show_node_menu(
        &mut self,
        node: egui_snarl::NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<NodeId>,
    ) {
        let id = snarl[node];
        if ui.button("View output").clicked() {
            self.actions.push(Action::View(id));
            ui.close();
        }
        if ui.button("Export output…").clicked() {
            self.actions.push(Action::Export(id));
            ui.close();
        }
        if ui.button("Duplicate").clicked() {
            self.actions.push(Action::Duplicate(vec![id]));
            ui.close();
        }
        if ui.button("Delete").clicked() {
            self.actions.push(Action::Delete(vec![id]));
            ui.close();
        }
        let selected: Vec<NodeId> = egui_snarl::ui::get_selected_nodes(self.snarl_id, ui.ctx())
            .into_iter()
            .filter_map(|s| snarl.get_node(s).copied())
            .collect();
        super::structure_ui::node_menu_ui(ui, self.data.graph, id, &selected, &mut self.actions);
    }
}
