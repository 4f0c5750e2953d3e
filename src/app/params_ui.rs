//! The inspector: the selected node's parameters as widgets, built from the operator's
//! parameter declaration (the [`ParamInfo`] list its `ParamVisitor` produces: kind, doc, unit,
//! range, default). Edits write straight into the graph; the app turns a whole drag or a whole
//! text edit into one undo step.

use crate::graph::{Graph, NodeId};
use crate::nodes::{self, GRAPH_NODE_OP};
use crate::params::{ParamInfo, ParamKind, ParamValue};
use egui::{RichText, Ui};
use std::path::Path;

/// Draws the widget for one parameter; returns true if `value` changed.
pub fn param_ui(
    ui: &mut Ui,
    name: &str,
    info: &ParamInfo,
    value: &mut ParamValue,
    base_dir: &Path,
    browse: &mut bool,
) -> bool {
    let meta = &info.meta;
    let suffix = if meta.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", meta.unit)
    };
    let mut changed = false;
    let label = ui.label(name).on_hover_text(meta.doc).id;
    match (&info.kind, value) {
        (ParamKind::Bool, ParamValue::Bool(b)) => {
            changed |= ui
                .checkbox(b, "")
                .labelled_by(label)
                .on_hover_text(meta.doc)
                .changed();
        }
        (ParamKind::Int, ParamValue::Int(i)) => {
            let r = match meta.slider() {
                Some(sl) => {
                    let mut s = egui::Slider::new(i, sl.lo as i64..=sl.hi as i64)
                        .logarithmic(sl.log)
                        .clamping(egui::SliderClamping::Never)
                        .suffix(&suffix);
                    if sl.log && sl.lo == 0.0 {
                        s = s.smallest_positive(sl.smallest_positive(true));
                    }
                    ui.add(s)
                }
                None => ui.add(egui::DragValue::new(i).suffix(&suffix)),
            };
            // Beyond the slider, typed values are kept up to the hard range.
            if let Some((lo, hi)) = meta.range {
                *i = (*i).clamp(lo as i64, hi as i64);
            }
            changed |= r.labelled_by(label).on_hover_text(meta.doc).changed();
        }
        (ParamKind::Float, ParamValue::Float(x)) => {
            let r = match meta.slider() {
                Some(sl) => {
                    let mut s = egui::Slider::new(x, sl.lo..=sl.hi)
                        .logarithmic(sl.log)
                        .clamping(egui::SliderClamping::Never)
                        .suffix(&suffix)
                        .custom_formatter(|v, decimals| number_text(v, *decimals.start()));
                    if sl.log && sl.lo == 0.0 {
                        s = s.smallest_positive(sl.smallest_positive(false));
                    }
                    ui.add(s)
                }
                None => ui.add(egui::DragValue::new(x).speed(0.01).suffix(&suffix)),
            };
            if let Some((lo, hi)) = meta.range {
                *x = x.clamp(lo, hi);
            }
            changed |= r.labelled_by(label).on_hover_text(meta.doc).changed();
        }
        (ParamKind::Choice(options), ParamValue::Choice(s)) => {
            egui::ComboBox::from_id_salt(name)
                .selected_text(s.as_str())
                .show_ui(ui, |ui| {
                    for o in options {
                        changed |= ui.selectable_value(s, (*o).to_string(), *o).changed();
                    }
                });
        }
        (ParamKind::Text, ParamValue::Text(s)) => {
            changed |= ui.text_edit_singleline(s).labelled_by(label).changed();
        }
        (ParamKind::Path, ParamValue::Path(s) | ParamValue::Text(s)) => {
            ui.horizontal(|ui| {
                changed |= ui
                    .add(egui::TextEdit::singleline(s).desired_width(170.0))
                    .labelled_by(label)
                    .on_hover_text(meta.doc)
                    .changed();
                ui.menu_button("…", |ui| {
                    if let Some(p) = file_menu_ui(ui, base_dir) {
                        *s = p;
                        changed = true;
                        ui.close();
                    }
                })
                .response
                .on_hover_text("Pick a file next to the graph");
                if ui
                    .small_button("Browse…")
                    .on_hover_text("Choose any file in the file dialog")
                    .clicked()
                {
                    *browse = true;
                }
            });
        }
        (ParamKind::Vec3, ParamValue::Vec3(v)) => {
            ui.horizontal(|ui| {
                for c in v.iter_mut() {
                    let mut d = egui::DragValue::new(c).speed(0.01).max_decimals(3);
                    if let Some((lo, hi)) = meta.range {
                        d = d.range(lo..=hi);
                    }
                    changed |= ui.add(d).changed();
                }
            });
        }
        (ParamKind::Profile, ParamValue::Floats(v) | ParamValue::Profile(v)) => {
            ui.vertical(|ui| {
                changed |= profile_ui(ui, v, meta.range);
                ui.collapsing("values", |ui| changed |= list_ui(ui, v, meta.range));
            });
        }
        (ParamKind::Floats, ParamValue::Floats(v) | ParamValue::Profile(v)) => {
            changed |= list_ui(ui, v, meta.range);
        }
        (ParamKind::Points, ParamValue::Points(pts)) => {
            ui.vertical(|ui| changed |= points_ui(ui, pts));
        }
        (ParamKind::Paths, ParamValue::Paths(paths)) => {
            ui.vertical(|ui| {
                let mut remove = None;
                for (k, path) in paths.iter_mut().enumerate() {
                    let own = crate::params::paths_text(&[crate::params::PathValue {
                        points: Vec::new(),
                        ..path.clone()
                    }]);
                    let title = format!("path {} ({} points{})", k + 1, path.points.len(), {
                        if own.is_empty() {
                            String::new()
                        } else {
                            format!(", {own}")
                        }
                    });
                    ui.horizontal(|ui| {
                        ui.collapsing(title, |ui| changed |= points_ui(ui, &mut path.points));
                        changed |= ui.checkbox(&mut path.closed, "closed").changed();
                        if ui
                            .small_button("✖")
                            .on_hover_text("Remove this path")
                            .clicked()
                        {
                            remove = Some(k);
                        }
                    });
                }
                if let Some(k) = remove {
                    paths.remove(k);
                    changed = true;
                }
            })
            .response
            .on_hover_text(meta.doc);
        }
        (_, v) => {
            ui.label(format!("{v} ({})", v.kind_name()));
        }
    }
    ui.end_row();
    changed
}

/// The first sentence of an operator's doc (the inspector's line under the title): up to the
/// first full stop followed by a space that is outside parentheses and does not end an
/// abbreviation (`et al.`, `e.g.`, `i.e.`, `cf.`, `Fig.`, `vs.`) — "RGBN bilateral filter
/// (Toler-Franklin et al. 2007; …): base = …" is one sentence. The whole doc when it has one
/// sentence.
#[must_use]
pub fn doc_summary(doc: &str) -> &str {
    const ABBREVIATIONS: [&str; 6] = ["et al", "e.g", "i.e", "cf", "Fig", "vs"];
    let mut depth = 0i32;
    for (k, c) in doc.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            '.' if depth <= 0 && doc[k + 1..].starts_with(' ') => {
                let before = &doc[..k];
                if !ABBREVIATIONS.iter().any(|a| before.ends_with(a)) {
                    return &doc[..=k];
                }
            }
            _ => {}
        }
    }
    doc
}

/// A slider's number: at most 4 decimals (at least `min_decimals`), and small magnitudes
/// (tolerances of 10⁻⁶) in scientific notation rather than as `0.0000`.
#[must_use]
pub fn number_text(v: f64, min_decimals: usize) -> String {
    if v != 0.0 && v.abs() < 1e-3 {
        return format!("{v:.2e}");
    }
    let s = format!("{v:.4}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').to_string()
    } else {
        s
    };
    let s = s.trim_end_matches('.').to_string();
    let decimals = s.split_once('.').map_or(0, |(_, d)| d.len());
    if decimals < min_decimals {
        format!("{v:.min_decimals$}")
    } else {
        s
    }
}

/// A list of points as rows of x and y, each removable, and a button that adds one.
fn points_ui(ui: &mut Ui, pts: &mut Vec<[f64; 2]>) -> bool {
    let mut changed = false;
    let mut remove = None;
    for (k, p) in pts.iter_mut().enumerate() {
        ui.horizontal(|ui| {
            ui.label(format!("{k}"));
            changed |= ui
                .add(egui::DragValue::new(&mut p[0]).prefix("x "))
                .changed();
            changed |= ui
                .add(egui::DragValue::new(&mut p[1]).prefix("y "))
                .changed();
            if ui.small_button("✖").clicked() {
                remove = Some(k);
            }
        });
    }
    if let Some(k) = remove {
        pts.remove(k);
        changed = true;
    }
    if ui.small_button("+ point").clicked() {
        let last = pts.last().copied().unwrap_or([0.0, 0.0]);
        pts.push([last[0] + 10.0, last[1]]);
        changed = true;
    }
    changed
}

fn list_ui(ui: &mut Ui, v: &mut Vec<f64>, range: Option<(f64, f64)>) -> bool {
    let mut changed = false;
    ui.vertical(|ui| {
        ui.horizontal_wrapped(|ui| {
            for x in v.iter_mut() {
                let mut d = egui::DragValue::new(x).speed(0.01).max_decimals(4);
                if let Some((lo, hi)) = range {
                    d = d.range(lo..=hi);
                }
                changed |= ui.add(d).changed();
            }
        });
        ui.horizontal(|ui| {
            if ui.small_button("+").clicked() {
                v.push(v.last().copied().unwrap_or(0.0));
                changed = true;
            }
            if ui.small_button("−").clicked() && !v.is_empty() {
                v.pop();
                changed = true;
            }
        });
    });
    changed
}

/// A profile (samples at equally spaced u from −1 to 1) as an editable curve: drag a sample
/// up or down; double-click the curve to add a sample there, right-click a sample to remove it.
fn profile_ui(ui: &mut Ui, v: &mut Vec<f64>, range: Option<(f64, f64)>) -> bool {
    use egui::{Color32, Pos2, Rect, Sense, Stroke, Vec2};
    let mut changed = false;
    let (rect, resp) = ui.allocate_exact_size(Vec2::new(200.0, 90.0), Sense::click_and_drag());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 3.0, ui.visuals().extreme_bg_color);
    if v.len() < 2 {
        if ui.small_button("start a curve").clicked() {
            *v = vec![0.0, 1.0, 0.0];
            changed = true;
        }
        return changed;
    }
    // Vertical scale: the samples' range padded, always including 0.
    let lo = v.iter().copied().fold(0.0f64, f64::min);
    let hi = v.iter().copied().fold(0.0f64, f64::max);
    let pad = ((hi - lo) * 0.15).max(0.5);
    let (lo, hi) = (lo - pad, hi + pad);
    let inner = rect.shrink(6.0);
    let n = v.len();
    let to_screen = |k: usize, y: f64| {
        Pos2::new(
            inner.left() + inner.width() * k as f32 / (n - 1) as f32,
            inner.bottom() - inner.height() * ((y - lo) / (hi - lo)) as f32,
        )
    };
    let from_screen_y =
        |py: f32| lo + (hi - lo) * f64::from((inner.bottom() - py) / inner.height());
    let zero = to_screen(0, 0.0).y;
    painter.line_segment(
        [
            Pos2::new(inner.left(), zero),
            Pos2::new(inner.right(), zero),
        ],
        Stroke::new(1.0, Color32::from_gray(80)),
    );
    let pts: Vec<Pos2> = v
        .iter()
        .enumerate()
        .map(|(k, y)| to_screen(k, *y))
        .collect();
    painter.add(egui::Shape::line(
        pts.clone(),
        Stroke::new(1.5, Color32::from_rgb(120, 190, 255)),
    ));
    let drag_id = resp.id.with("sample");
    let hovered = resp.hover_pos().and_then(|p| {
        pts.iter()
            .enumerate()
            .map(|(k, q)| (k, q.distance(p)))
            .filter(|(_, d)| *d < 8.0)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(k, _)| k)
    });
    if resp.drag_started() {
        ui.data_mut(|d| d.insert_temp(drag_id, hovered));
    }
    let dragging: Option<usize> = ui.data(|d| d.get_temp(drag_id)).flatten();
    if let (true, Some(k), Some(p)) = (resp.dragged(), dragging, resp.interact_pointer_pos()) {
        let mut y = from_screen_y(p.y);
        if let Some((a, b)) = range {
            y = y.clamp(a, b);
        }
        let y = (y * 100.0).round() / 100.0;
        if k < n && v[k] != y {
            v[k] = y;
            changed = true;
        }
    }
    if resp.drag_stopped() {
        ui.data_mut(|d| d.remove::<Option<usize>>(drag_id));
    }
    if resp.secondary_clicked() && n > 2 {
        if let Some(k) = hovered {
            v.remove(k);
            changed = true;
        }
    }
    if resp.double_clicked() && hovered.is_none() {
        if let Some(p) = resp.interact_pointer_pos() {
            // Resample to one more sample, keeping the curve's shape (linear interpolation).
            let m = n + 1;
            let t = ((p.x - inner.left()) / inner.width()).clamp(0.0, 1.0);
            let at = |x: f64| {
                let f = x * (n - 1) as f64;
                let i = (f.floor() as usize).min(n - 2);
                let w = f - i as f64;
                v[i] * (1.0 - w) + v[i + 1] * w
            };
            let mut out: Vec<f64> = (0..m).map(|k| at(k as f64 / (m - 1) as f64)).collect();
            let near = (f64::from(t) * (m - 1) as f64).round() as usize;
            out[near] = from_screen_y(p.y);
            *v = out;
            changed = true;
        }
    }
    for (k, q) in pts.iter().enumerate() {
        let hot = hovered == Some(k) || dragging == Some(k);
        painter.circle_filled(
            *q,
            if hot { 5.0 } else { 3.5 },
            if hot { Color32::YELLOW } else { Color32::WHITE },
        );
    }
    painter.text(
        Rect::from_min_size(inner.min, Vec2::ZERO).min,
        egui::Align2::LEFT_TOP,
        format!("{hi:.1}"),
        egui::FontId::monospace(9.0),
        Color32::GRAY,
    );
    painter.text(
        Pos2::new(inner.left(), inner.bottom()),
        egui::Align2::LEFT_BOTTOM,
        format!("{lo:.1}"),
        egui::FontId::monospace(9.0),
        Color32::GRAY,
    );
    resp.on_hover_text(
        "Drag a sample up/down; double-click to add a sample; right-click a sample to remove it",
    );
    changed
}

/// Files in `base_dir` and its `data/` folder (a light file picker without system dialogs).
fn file_menu_ui(ui: &mut Ui, base_dir: &Path) -> Option<String> {
    let mut out = None;
    let mut any = false;
    for sub in ["", "data"] {
        let dir = base_dir.join(sub);
        let Ok(rd) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut names: Vec<String> = rd
            .filter_map(Result::ok)
            .filter(|e| e.path().is_file())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.'))
            .collect();
        names.sort();
        for n in names {
            any = true;
            let rel = if sub.is_empty() {
                n.clone()
            } else {
                format!("{sub}/{n}")
            };
            if ui.button(&rel).clicked() {
                out = Some(rel);
            }
        }
    }
    if !any {
        ui.weak(format!("no files in {}", base_dir.display()));
    }
    out
}

/// A graph file loaded once per (path, modification time, size): the inspector draws every
/// frame and must not re-read and re-validate the file each time.
fn load_cached(path: &Path) -> Option<std::sync::Arc<crate::graph::LoadedGraph>> {
    use parking_lot::Mutex;
    use std::collections::HashMap;
    use std::sync::{Arc, OnceLock};
    type Entry = (
        Option<std::time::SystemTime>,
        u64,
        Arc<crate::graph::LoadedGraph>,
    );
    static CACHE: OnceLock<Mutex<HashMap<std::path::PathBuf, Entry>>> = OnceLock::new();
    let meta = std::fs::metadata(path).ok()?;
    let stamp = (meta.modified().ok(), meta.len());
    let cache = CACHE.get_or_init(Mutex::default);
    if let Some((t, len, g)) = cache.lock().get(path) {
        if (*t, *len) == stamp {
            return Some(g.clone());
        }
    }
    let g = Arc::new(crate::graph::LoadedGraph::load(path).ok()?);
    cache
        .lock()
        .insert(path.to_path_buf(), (stamp.0, stamp.1, g.clone()));
    Some(g)
}

/// The parameters of node `id` (name, description, current value: the default where the file
/// has none). A graph node's parameters are its `path` and the sub-graph's exposed ones.
#[must_use]
pub fn node_params(
    graph: &Graph,
    id: NodeId,
    base_dir: &Path,
) -> Vec<(String, ParamInfo, ParamValue)> {
    let Some(n) = graph.nodes.get(&id) else {
        return Vec::new();
    };
    let infos: Vec<(String, ParamInfo)> = if n.op == GRAPH_NODE_OP {
        let mut v = vec![(
            "path".to_string(),
            ParamInfo {
                name: "path",
                kind: ParamKind::Path,
                meta: crate::params::Meta::new("The graph file this node uses."),
                default: ParamValue::Path(String::new()),
            },
        )];
        if let Some(ParamValue::Path(p) | ParamValue::Text(p)) = n.params.get("path") {
            if let Some(sub) = load_cached(&base_dir.join(p)) {
                for (name, ex) in &sub.graph.exposed {
                    if let Some(mut info) = sub.param_info(ex.node, &ex.param) {
                        if let Some(x) = sub
                            .graph
                            .nodes
                            .get(&ex.node)
                            .and_then(|n| n.params.get(&ex.param))
                        {
                            info.default = x.clone();
                        }
                        v.push((name.clone(), info));
                    }
                }
            }
        }
        v
    } else {
        nodes::find(&n.op)
            .map(|o| {
                o.params()
                    .iter()
                    .map(|i| (i.name.to_string(), i.clone()))
                    .collect()
            })
            .unwrap_or_default()
    };
    infos
        .into_iter()
        .map(|(name, info)| {
            let v = n
                .params
                .get(&name)
                .cloned()
                .unwrap_or_else(|| info.default.clone());
            (name, info, v)
        })
        .collect()
}

/// The inspector for node `id`: name, operator doc, parameters. Edits go into `graph`.
/// Returns the name of a path parameter whose "Browse…" button was clicked.
pub fn inspector_ui(ui: &mut Ui, graph: &mut Graph, id: NodeId, base_dir: &Path) -> Option<String> {
    let mut browse_for = None;
    let Some(n) = graph.nodes.get(&id) else {
        ui.weak("No node selected.");
        return None;
    };
    let op = nodes::find(&n.op);
    ui.heading(super::graph_view::node_title(graph, id));
    ui.label(RichText::new(format!("#{id} · {}", n.op)).small().weak());
    if let Some(op) = op {
        let doc = op.spec().doc;
        ui.add(egui::Label::new(doc_summary(doc)).wrap())
            .on_hover_text(doc);
    }
    ui.separator();
    let mut name = n.name.clone().unwrap_or_default();
    let params = node_params(graph, id, base_dir);
    let mut edits: Vec<(String, ParamValue)> = Vec::new();
    let mut name_changed = false;
    egui::Grid::new(("params", id))
        .num_columns(2)
        .spacing([8.0, 6.0])
        .striped(true)
        .show(ui, |ui| {
            ui.label("name")
                .on_hover_text("Optional node name (for --set NAME.PARAM=…)");
            name_changed = ui.text_edit_singleline(&mut name).changed();
            ui.end_row();
            for (pname, info, mut value) in params {
                let mut browse = false;
                if param_ui(ui, &pname, &info, &mut value, base_dir, &mut browse) {
                    edits.push((pname.clone(), value));
                }
                if browse {
                    browse_for = Some(pname);
                }
            }
        });
    if let Some(n) = graph.nodes.get_mut(&id) {
        if name_changed {
            n.name = if name.trim().is_empty() {
                None
            } else {
                Some(name)
            };
        }
        for (k, v) in edits {
            n.params.insert(k, v);
        }
    }
    if ui.small_button("Reset to defaults").clicked() {
        if let Some(n) = graph.nodes.get_mut(&id) {
            n.params.retain(|k, _| k == "path" && n.op == GRAPH_NODE_OP);
        }
    }
    browse_for
}
