//! The preview's settings widgets: the light hemisphere, display settings and view parameters.

use super::*;
use crate::params;
use crate::render::{InspectParams, View};
use egui::{Color32, Sense, Stroke, Ui, Vec2};

/// A hemisphere seen from above: drag to move the light. Returns true if `light` changed.
pub fn light_ui(ui: &mut Ui, light: &mut [f32; 3]) -> bool {
    let size = 84.0;
    let (rect, resp) = ui.allocate_exact_size(Vec2::splat(size), Sense::click_and_drag());
    let c = rect.center();
    let r = size * 0.5 - 3.0;
    let painter = ui.painter_at(rect.expand(2.0));
    // A small Lambert-shaded sphere shows where the light comes from.
    let steps = 14;
    for i in (1..=steps).rev() {
        let t = i as f32 / steps as f32;
        let g = (40.0 + 120.0 * (1.0 - t)) as u8;
        painter.circle_filled(
            c + Vec2::new(light[0], -light[1]) * r * (1.0 - t) * 0.6,
            r * t,
            Color32::from_gray(g),
        );
    }
    painter.circle_stroke(c, r, Stroke::new(1.0, Color32::from_gray(110)));
    let mut changed = false;
    if let Some(p) = resp.interact_pointer_pos() {
        if resp.dragged() || resp.clicked() {
            let mut d = (p - c) / r;
            if d.length() > 0.995 {
                d = d.normalized() * 0.995;
            }
            let z = (1.0 - d.length_sq()).max(0.0).sqrt();
            let new = [d.x, -d.y, z];
            if new != *light {
                *light = new;
                changed = true;
            }
        }
    }
    let dot = c + Vec2::new(light[0], -light[1]) * r;
    painter.circle_filled(dot, 5.0, Color32::from_rgb(255, 220, 80));
    painter.circle_stroke(dot, 5.0, Stroke::new(1.0, Color32::BLACK));
    resp.on_hover_text(format!(
        "Light direction (drag): {:+.2} {:+.2} {:+.2}",
        light[0], light[1], light[2]
    ));
    changed
}

/// The display controls: view mode, before/after split, light, ambient, specular, exposure.
/// `can_split`: the viewed node has an RGBN input to compare with.
pub fn settings_ui(ui: &mut Ui, s: &mut PreviewSettings, split: &mut Option<f32>, can_split: bool) {
    ui.horizontal_wrapped(|ui| {
        for v in Mode::ALL {
            ui.selectable_value(&mut s.view, v, v.name())
                .on_hover_text(v.doc());
        }
        ui.separator();
        let mut on = split.is_some();
        let r = ui
            .add_enabled(can_split, egui::Checkbox::new(&mut on, "before/after"))
            .on_hover_text("Show the node's input (before) left of a split line and its output (after) right of it");
        if r.changed() {
            *split = on.then_some(0.5);
        }
        if let Some(x) = split.as_mut() {
            ui.add_enabled(can_split, egui::Slider::new(x, 0.0..=1.0).show_value(false))
                .on_hover_text("Split position");
        }
    });
    let view = s.view.render_view();
    ui.horizontal(|ui| {
        if view.is_some_and(View::lit) {
            light_ui(ui, &mut s.light);
            egui::Grid::new("shading").num_columns(2).show(ui, |ui| {
                ui.label("ambient");
                ui.add(egui::Slider::new(&mut s.ambient, 0.0..=1.0));
                ui.end_row();
                ui.label("specular");
                ui.add(egui::Slider::new(&mut s.specular, 0.0..=2.0));
                ui.end_row();
                ui.label("shininess");
                ui.add(egui::Slider::new(&mut s.shininess, 1.0..=200.0).logarithmic(true));
                ui.end_row();
                ui.label("exposure");
                ui.add(egui::Slider::new(&mut s.exposure_ev, -4.0..=4.0).suffix(" EV"));
                ui.end_row();
            });
        }
        if let Some(v) = view {
            view_params_ui(ui, v, &mut s.inspect);
        }
    });
}

/// The selected view's own parameters ([`InspectParams::describe`]) as the inspector's widgets.
pub(super) fn view_params_ui(ui: &mut Ui, view: View, p: &mut InspectParams) {
    let infos = InspectParams::describe(view);
    if infos.is_empty() {
        return;
    }
    let mut values = params::to_values(p);
    let mut changed = false;
    egui::Grid::new("view_params")
        .num_columns(2)
        .show(ui, |ui| {
            for info in &infos {
                let mut browse = false;
                let v = values
                    .entry(info.name.to_string())
                    .or_insert_with(|| info.default.clone());
                let here = std::path::Path::new(".");
                // RTIViewer users know these controls by RTIViewer's names: shown beside
                // rgbn's (the parameter's name in files stays).
                let shown = match InspectParams::rtiviewer_name(info.name) {
                    Some(r) => format!("{r} ({})", info.name),
                    None => info.name.to_string(),
                };
                changed |= crate::app::params_ui::param_ui(ui, &shown, info, v, here, &mut browse);
            }
        });
    if changed {
        // The widgets keep values in range; a value the core refuses leaves the settings as
        // they were.
        if let Ok(new) = params::from_values::<InspectParams>(&values) {
            *p = new;
        }
    }
}
