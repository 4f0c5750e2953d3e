//! The node graph view: a [`Snarl<NodeId>`] mirroring the document's [`Graph`].
//!
//! The graph is the truth, the widget a view. The viewer never edits the graph nor the snarl
//! itself: connects, disconnects and menu commands become [`Action`]s that the app applies to
//! the document (the core checks connections); then [`GraphView::sync`] mirrors the graph into
//! the snarl (incrementally, so the widget keeps its selection). Egui-snarl's own node ids are
//! reused slab indices: they are never persisted nor used as keys outside this module.

use super::placement::{self, Rect as PlaceRect};
use crate::graph::{Graph, NodeId, NodePorts};
use crate::nodes::{self, PortType, GRAPH_NODE_OP, REROUTE_OP};
use egui::{Color32, Id, Pos2, RichText, TextureHandle, Ui};
use egui_snarl::ui::{PinInfo, SnarlPin, SnarlStyle, SnarlViewer, SnarlWidget};
use egui_snarl::{InPin, InPinId, OutPin, OutPinId, Snarl};
use std::collections::{BTreeMap, BTreeSet};

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
    /// Non-integrable fraction F of each node's RGBN output.
    pub fraction: &'a BTreeMap<NodeId, f64>,
    /// Green-convention badges of the `load` nodes ([`super::green_badge`]).
    pub green: &'a BTreeMap<NodeId, super::green_badge::Badge>,
    /// The node shown in the preview.
    pub viewed: Option<NodeId>,
    /// Its output port shown in the preview.
    pub viewed_port: Option<&'a str>,
}

/// The mirror of the graph in egui-snarl.
pub struct GraphView {
    snarl: Snarl<NodeId>,
    by_id: BTreeMap<NodeId, egui_snarl::NodeId>,
    style: SnarlStyle,
    /// The text typed in the add-node menu's search field.
    pub search: String,
    /// Frames left during which the view is fitted to the whole graph (panels settle in the
    /// first frames, so fitting lasts a few).
    pub frame_pending: u32,
    /// Each drawn node's rectangle relative to its position (offset of the top-left corner,
    /// size), as the widget last drew it.
    measured: BTreeMap<NodeId, ([f32; 2], [f32; 2])>,
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
            search: String::new(),
            frame_pending: 3,
            measured: BTreeMap::new(),
        }
    }
}

impl GraphView {
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
        egui_snarl::ui::get_selected_nodes(Id::new(SNARL_ID), ctx)
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

    /// Draws the graph; returns the actions asked for.
    pub fn show_ui(&mut self, ui: &mut Ui, data: &ViewData<'_>) -> Vec<Action> {
        let frame = (self.frame_pending > 0).then(|| ui.available_rect_before_wrap());
        self.frame_pending = self.frame_pending.saturating_sub(1);
        let (pointer, shift) = ui.input(|i| (i.pointer.latest_pos(), i.modifiers.shift));
        let mut viewer = Viewer {
            data,
            search: &mut self.search,
            actions: Vec::new(),
            frame,
            measured: &mut self.measured,
            transform: egui::emath::TSTransform::IDENTITY,
            pointer,
            shift,
        };
        let resp = SnarlWidget::new()
            .id(Id::new(SNARL_ID))
            .style(self.style)
            .show(&mut self.snarl, &mut viewer, ui);
        let (mut actions, to_global) = (viewer.actions, viewer.transform);
        // Frames: their title bars drag their nodes (moved in the widget, written back to the
        // graph with the nodes' own moves).
        let rects = super::frames::frame_rects(data.graph, |id| {
            super::frames::node_rect(data.graph, &self.measured, id)
        });
        for (i, delta) in super::frames::bars_ui(ui, data.graph, &rects, to_global, resp.rect, &mut actions) {
            for id in &data.graph.frames[i].nodes {
                if let Some(info) = self.by_id.get(id).and_then(|s| self.snarl.get_node_info_mut(*s)) {
                    info.pos += delta;
                }
            }
        }
        // A double-click on a graph node opens it in place.
        if let Some(p) = pointer.filter(|p| resp.rect.contains(*p)) {
            if ui.input(|i| i.pointer.button_double_clicked(egui::PointerButton::Primary)) {
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
        actions
    }
}

/// A menu of every operator by category, with a search field; returns the chosen op id.
pub fn add_node_menu_ui(ui: &mut Ui, search: &mut String) -> Option<&'static str> {
    let mut chosen = None;
    ui.horizontal(|ui| {
        ui.label("🔍");
        ui.add(
            egui::TextEdit::singleline(search)
                .hint_text("search operators")
                .desired_width(160.0),
        );
    });
    let q = search.to_lowercase();
    let mut cats: BTreeMap<&str, Vec<&'static dyn nodes::DynOp>> = BTreeMap::new();
    for op in nodes::registry() {
        let s = op.spec();
        let hit = q.is_empty()
            || s.id.to_lowercase().contains(&q)
            || s.title.to_lowercase().contains(&q)
            || s.category.contains(&q);
        if hit {
            cats.entry(s.category).or_default().push(op.as_ref());
        }
    }
    if cats.is_empty() {
        ui.weak("no operator matches");
    }
    for (cat, list) in cats {
        ui.separator();
        ui.label(RichText::new(cat).small().weak());
        for op in list {
            let s = op.spec();
            if ui.button(s.title).on_hover_text(s.doc).clicked() {
                chosen = Some(s.id);
                ui.close();
            }
        }
    }
    chosen
}

struct Viewer<'a, 'd> {
    data: &'a ViewData<'d>,
    search: &'a mut String,
    actions: Vec<Action>,
    /// Fit the view to the graph in this screen rectangle.
    frame: Option<egui::Rect>,
    /// Drawn node rectangles (see [`GraphView::node_rects`]).
    measured: &'a mut BTreeMap<NodeId, ([f32; 2], [f32; 2])>,
    /// The view's transform (graph → screen) this frame.
    transform: egui::emath::TSTransform,
    /// The pointer on the screen.
    pointer: Option<Pos2>,
    /// Shift is held (Shift + right-click on a wire inserts a reroute).
    shift: bool,
}

impl Viewer<'_, '_> {
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
        let r = ui.label(RichText::new(title).strong());
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
        ui.label(text)
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
        let text = if viewed {
            RichText::new(&p.name).underline()
        } else {
            RichText::new(&p.name)
        };
        if ui
            .add(egui::Label::new(text).sense(egui::Sense::click()))
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
            if let Some(f) = self.data.fraction.get(&id) {
                ui.label(RichText::new(format!("F {f:.2e}")).small().weak())
                    .on_hover_text("Non-integrable fraction of this node's normals: 0 for a surface, √(2/π) ≈ 0.80 for noise");
            }
            if let Some(b) = self.data.green.get(&id) {
                let text = RichText::new(&b.text).small();
                let text = if b.mismatch {
                    text.color(Color32::from_rgb(0xe0, 0xb0, 0x40))
                } else {
                    text.weak()
                };
                ui.label(text).on_hover_text(&b.hover);
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
            let at = self.transform.inverse() * p;
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

    fn current_transform(
        &mut self,
        to_global: &mut egui::emath::TSTransform,
        snarl: &mut Snarl<NodeId>,
    ) {
        self.transform = *to_global;
        let Some(view) = self.frame else { return };
        let mut bb = egui::Rect::NOTHING;
        for n in snarl.nodes_info() {
            // Node sizes are not known here: a typical node with a thumbnail.
            bb.extend_with(n.pos);
            bb.extend_with(n.pos + egui::vec2(250.0, 150.0));
        }
        if !bb.is_finite() || !view.is_finite() || view.width() < 10.0 {
            return;
        }
        let bb = bb.expand(30.0);
        let scaling = (view.size() / bb.size()).min_elem().clamp(0.2, 1.0);
        *to_global = egui::emath::TSTransform {
            scaling,
            translation: view.center().to_vec2() - bb.center().to_vec2() * scaling,
        };
        self.transform = *to_global;
    }

    fn has_graph_menu(&mut self, _pos: Pos2, _snarl: &mut Snarl<NodeId>) -> bool {
        true
    }

    fn show_graph_menu(&mut self, pos: Pos2, ui: &mut Ui, _snarl: &mut Snarl<NodeId>) {
        ui.label(RichText::new("Add node").strong());
        if let Some(op) = add_node_menu_ui(ui, self.search) {
            self.actions.push(Action::AddNode {
                op: op.to_string(),
                pos: [pos.x, pos.y],
            });
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
        let selected: Vec<NodeId> = egui_snarl::ui::get_selected_nodes(Id::new(SNARL_ID), ui.ctx())
            .into_iter()
            .filter_map(|s| snarl.get_node(s).copied())
            .collect();
        super::structure_ui::node_menu_ui(ui, self.data.graph, id, &selected, &mut self.actions);
    }
}
