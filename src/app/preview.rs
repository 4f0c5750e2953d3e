//! The preview: any node's output, relit (light from a hemisphere widget, ambient, specular,
//! exposure), as albedo, normals or curl; zoom and pan with nearest-neighbour pixels; a
//! readout of colour, normal and curl under the cursor.
//!
//! What is shown is keyed by a [`PreviewRequest`] — plain data: the value's content key and the
//! display settings. The texture is re-rendered only when the request changes, so dragging the
//! light relights the evaluated image without re-running the graph.

use super::tools::ViewTransform;
use super::tools_ui::{ToolCx, Tools};
use crate::ops::{Picture, Value};
use crate::raster::gradient::GradientField;
use crate::raster::Plane;
use crate::render::{self, Light, Shading, View};
use egui::{
    Color32, PointerButton, Pos2, Rect, Sense, Stroke, TextureHandle, TextureOptions, Ui, Vec2,
};
use std::sync::Arc;

/// Display settings of the preview (not part of the graph).
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewSettings {
    /// Relit, albedo, normals or curl.
    pub view: View,
    /// Direction towards the light (OpenGL frame, unit).
    pub light: [f32; 3],
    /// Ambient term.
    pub ambient: f32,
    /// Specular strength.
    pub specular: f32,
    /// Blinn-Phong exponent.
    pub shininess: f32,
    /// Exposure in stops.
    pub exposure_ev: f32,
}

impl Default for PreviewSettings {
    fn default() -> Self {
        let s = Shading::default();
        let d = s.lights[0].direction;
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        Self {
            view: View::Relit,
            light: [d[0] / len, d[1] / len, d[2] / len],
            ambient: s.ambient,
            specular: s.specular,
            shininess: s.shininess,
            exposure_ev: s.exposure_ev,
        }
    }
}

impl PreviewSettings {
    /// The shading these settings describe.
    #[must_use]
    pub fn shading(&self) -> Shading {
        Shading {
            lights: vec![Light::white(self.light)],
            ambient: self.ambient,
            specular: self.specular,
            shininess: self.shininess,
            exposure_ev: self.exposure_ev,
        }
    }
}

/// What the preview texture shows: when this is unchanged, nothing is re-rendered.
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewRequest {
    /// Content key of the value shown.
    pub key: u128,
    /// Display settings (ignored for values that are already pictures).
    pub settings: Option<PreviewSettings>,
}

/// The preview's runtime state.
pub struct Preview {
    texture: Option<TextureHandle>,
    last: Option<PreviewRequest>,
    curl: Option<(u128, Arc<Plane>)>,
    /// Zoom (screen points per image pixel); `None` fits the image to the panel.
    pub zoom: Option<f32>,
    /// Pan offset of the image centre from the panel centre.
    pub pan: Vec2,
    /// How many times the texture was rendered (tests, statistics).
    pub renders: u64,
    /// Time of the last render.
    pub render_ms: f64,
    /// The screen ↔ image mapping of the last drawn frame (tools, tests).
    pub transform: Option<ViewTransform>,
}

impl Default for Preview {
    fn default() -> Self {
        Self {
            texture: None,
            last: None,
            curl: None,
            zoom: None,
            pan: Vec2::ZERO,
            renders: 0,
            render_ms: 0.0,
            transform: None,
        }
    }
}

/// Renders a value for display (sRGB RGBA8), or `None` for numbers.
pub fn render_value(v: &Value, s: &PreviewSettings) -> Option<Picture> {
    match v {
        Value::Rgbn(img) => {
            let rgba = render::render(img, s.view, &s.shading()).ok()?;
            Some(Picture {
                width: img.width(),
                height: img.height(),
                rgba,
            })
        }
        Value::Picture(p) => Some((**p).clone()),
        Value::Mask(p) | Value::Scalar(p) => Some(super::worker::plane_picture(p)),
        Value::Number(_) => None,
    }
}

impl Preview {
    /// The request for showing `value` (with content key `key`) under `settings`.
    #[must_use]
    pub fn request(value: &Value, key: u128, settings: &PreviewSettings) -> PreviewRequest {
        PreviewRequest {
            key,
            settings: matches!(value, Value::Rgbn(_)).then(|| settings.clone()),
        }
    }

    /// Forgets the texture (the viewed node changed or has no value).
    pub fn clear(&mut self) {
        self.texture = None;
        self.last = None;
    }

    /// Makes the texture show `value` as `req` asks, rendering only if `req` changed.
    pub fn update(&mut self, ctx: &egui::Context, value: &Value, req: PreviewRequest) {
        if self.last.as_ref() == Some(&req) {
            return;
        }
        let t0 = std::time::Instant::now();
        let settings = req.settings.clone().unwrap_or_default();
        match render_value(value, &settings) {
            Some(p) => {
                let img = egui::ColorImage::from_rgba_unmultiplied([p.width, p.height], &p.rgba);
                match &mut self.texture {
                    Some(t) if t.size() == [p.width, p.height] => {
                        t.set(img, TextureOptions::NEAREST);
                    }
                    _ => {
                        self.texture =
                            Some(ctx.load_texture("preview", img, TextureOptions::NEAREST));
                    }
                }
            }
            None => self.texture = None,
        }
        self.renders += 1;
        self.render_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.last = Some(req);
    }

    fn curl_plane(&mut self, key: u128, img: &crate::RgbnImage) -> Arc<Plane> {
        match &self.curl {
            Some((k, p)) if *k == key => p.clone(),
            _ => {
                let p = Arc::new(GradientField::from_normals(img).curl());
                self.curl = Some((key, p.clone()));
                p
            }
        }
    }

    /// Draws the image with zoom and pan; returns the readout line for the pixel under the
    /// cursor, if any.
    ///
    /// With an on-image tool active (`tools`), the primary button draws and panning moves to
    /// the middle or secondary button or Space + drag; without one, any drag pans.
    pub fn image_ui(
        &mut self,
        ui: &mut Ui,
        value: Option<(&Value, u128)>,
        tools: Option<(&mut Tools, &mut ToolCx<'_>)>,
    ) -> Option<String> {
        let (rect, resp) = ui.allocate_exact_size(ui.available_size(), Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::from_gray(24));
        let Some(tex) = &self.texture else {
            if let Some((Value::Number(x), _)) = value {
                painter.text(
                    rect.center(),
                    egui::Align2::CENTER_CENTER,
                    format!("{x:.6}"),
                    egui::FontId::proportional(28.0),
                    Color32::WHITE,
                );
            }
            return None;
        };
        let size = tex.size_vec2();
        let fit = (rect.width() / size.x)
            .min(rect.height() / size.y)
            .max(1e-3);
        let mut zoom = self.zoom.unwrap_or(fit);
        if resp.hovered() {
            let (scroll, pinch) = ui.input(|i| (i.smooth_scroll_delta.y, i.zoom_delta()));
            let factor = pinch * (scroll * 0.0025).exp();
            if (factor - 1.0).abs() > 1e-4 {
                // Zoom about the cursor.
                if let Some(p) = resp.hover_pos() {
                    let c = rect.center() + self.pan;
                    let new_zoom = (zoom * factor).clamp(0.02, 64.0);
                    self.pan += (p - c) * (1.0 - new_zoom / zoom);
                    zoom = new_zoom;
                    self.zoom = Some(zoom);
                }
            }
        }
        let tool_active = tools.as_ref().is_some_and(|(t, _)| t.active());
        let drawing = tools.as_ref().is_some_and(|(t, _)| t.gesture.is_some());
        let pan_drag = if tool_active {
            let space = ui.input(|i| i.key_down(egui::Key::Space));
            resp.dragged_by(PointerButton::Middle)
                || resp.dragged_by(PointerButton::Secondary)
                || (space && resp.dragged_by(PointerButton::Primary))
        } else {
            resp.dragged()
        };
        if pan_drag {
            self.pan += resp.drag_delta();
            self.zoom = Some(zoom);
        }
        if resp.double_clicked() && !tool_active {
            self.zoom = None;
            self.pan = Vec2::ZERO;
            zoom = fit;
        }
        let img_rect = Rect::from_center_size(rect.center() + self.pan, size * zoom);
        painter.image(
            tex.id(),
            img_rect,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
            Color32::WHITE,
        );
        painter.rect_stroke(
            img_rect,
            0.0,
            Stroke::new(1.0, Color32::from_gray(70)),
            egui::StrokeKind::Outside,
        );
        let xf = ViewTransform::new(
            [rect.center().x, rect.center().y],
            [self.pan.x, self.pan.y],
            [size.x, size.y],
            zoom,
        );
        self.transform = Some(xf);
        if let Some((t, cx)) = tools {
            t.image_ui(ui, &resp, &painter, xf, cx);
        }
        let pos = resp.hover_pos()?;
        let rel = (pos - img_rect.min) / zoom;
        let (x, row) = (rel.x.floor(), rel.y.floor());
        if x < 0.0 || row < 0.0 || x >= size.x || row >= size.y {
            return None;
        }
        let (x, row) = (x as usize, row as usize);
        if zoom >= 8.0 {
            let px = Rect::from_min_size(
                img_rect.min + Vec2::new(x as f32, row as f32) * zoom,
                Vec2::splat(zoom),
            );
            painter.rect_stroke(
                px,
                0.0,
                Stroke::new(1.0, Color32::YELLOW),
                egui::StrokeKind::Inside,
            );
        }
        let (v, key) = value?;
        Some(match v {
            Value::Rgbn(img) => {
                let c = img.color_at(x, row);
                let n = img.normal_at(x, row);
                // The curl plane costs a full-image pass on this thread: not for every
                // intermediate image of a stroke.
                let curl = match self.curl.as_ref().filter(|c| c.0 == key) {
                    _ if !drawing => format!("{:+.2e}", self.curl_plane(key, img).at(x, row)),
                    Some((_, p)) => format!("{:+.2e}", p.at(x, row)),
                    None => "—".into(),
                };
                format!(
                    "({x}, {row})  colour {:.3} {:.3} {:.3}  normal {:+.3} {:+.3} {:+.3}  curl {curl}",
                    c[0], c[1], c[2], n[0], n[1], n[2]
                )
            }
            Value::Picture(p) => {
                let i = (row * p.width + x) * 4;
                let c = &p.rgba[i..i + 4];
                format!("({x}, {row})  sRGB {} {} {} α {}", c[0], c[1], c[2], c[3])
            }
            Value::Mask(p) | Value::Scalar(p) => format!("({x}, {row})  {:.5}", p.at(x, row)),
            Value::Number(n) => format!("{n}"),
        })
    }
}

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

/// The display controls: view mode, light, ambient, specular, exposure.
pub fn settings_ui(ui: &mut Ui, s: &mut PreviewSettings) {
    ui.horizontal(|ui| {
        for v in View::ALL {
            ui.selectable_value(&mut s.view, v, v.name());
        }
    });
    if s.view == View::Relit {
        ui.horizontal(|ui| {
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
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preview_request_is_plain_data_keyed_apart_from_evaluation() {
        let img = Value::Rgbn(crate::raster::sample::demo_medallion(16));
        let mut s = PreviewSettings::default();
        let a = Preview::request(&img, 42, &s);
        assert_eq!(a, Preview::request(&img, 42, &s));
        s.light = [0.0, 0.0, 1.0];
        let b = Preview::request(&img, 42, &s);
        assert_ne!(a, b, "moving the light changes the request, not the key");
        assert_eq!(a.key, b.key);
        // Pictures ignore display settings.
        let pic = Value::Number(1.0);
        assert_eq!(
            Preview::request(&pic, 1, &s),
            Preview::request(&pic, 1, &PreviewSettings::default())
        );
        let p = render_value(&img, &s).unwrap();
        assert_eq!(p.rgba.len(), 16 * 16 * 4);
    }
}
