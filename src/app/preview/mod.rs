//! The preview: any node's output, relit (light from a hemisphere widget, ambient, specular,
//! exposure), as albedo, normals or curl; zoom and pan with nearest-neighbour pixels; a
//! readout of colour, normal and curl under the cursor.
//!
//! What is shown is keyed by a [`PreviewRequest`] — plain data: the value's content key and the
//! display settings. The texture is re-rendered only when the request changes, so dragging the
//! light relights the evaluated image without re-running the graph.
//!
//! Rendering runs on its own thread ([`Renderer`]): the UI sends the newest request and keeps
//! showing the previous texture until the new picture arrives (requests that pile up while one
//! renders are skipped), so a 4K relight never stalls a frame. The height view integrates the
//! normals (DCT Poisson) on that thread, once per evaluated value.

use super::tools::ViewTransform;
use super::tools_ui::{ToolCx, Tools};
use crate::nodes::Value;
use crate::raster::gradient::GradientField;
use crate::raster::Plane;
use crate::render::{InspectParams, Light, Shading, View};
use egui::{
    Color32, PointerButton, Pos2, Rect, Sense, Stroke, TextureHandle, TextureOptions, Ui, Vec2,
};
use std::sync::Arc;

mod renderer;
mod widgets;
pub use renderer::*;
pub use widgets::*;

/// Where the preview panel shows an image: the panel's size, the zoom (`None`: fit) and the
/// pan, all in screen points. The preview draws with it and the worker evaluates the part it
/// makes visible ([`super::worker::ViewRequest`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSpec {
    /// Panel size.
    pub panel: [f32; 2],
    /// Screen points per image pixel; `None` fits the image to the panel.
    pub zoom: Option<f32>,
    /// Offset of the image centre from the panel centre.
    pub pan: [f32; 2],
}

/// The zoom that fits an image of `size` pixels into a panel of `panel` points.
#[must_use]
pub fn fit_zoom(panel: [f32; 2], size: [f32; 2]) -> f32 {
    (panel[0] / size[0].max(1.0))
        .min(panel[1] / size[1].max(1.0))
        .max(1e-3)
}

impl ViewSpec {
    /// The zoom for an image of `size` pixels.
    #[must_use]
    pub fn zoom_for(&self, size: (usize, usize)) -> f32 {
        self.zoom
            .unwrap_or_else(|| fit_zoom(self.panel, [size.0 as f32, size.1 as f32]))
    }

    /// The pyramid level shown for an image of `size` ([`Preview::stride_for_zoom`]) and the
    /// rectangle of that level's pixels on screen, grown to whole `tile`s (so that small pans
    /// ask for the same tiles) and clamped to the level; `None` when none of it is visible.
    #[must_use]
    pub fn visible(
        &self,
        size: (usize, usize),
        tile: usize,
    ) -> Option<(crate::raster::window::Rect, u32)> {
        self.visible_from(size, tile, 0)
    }

    /// [`ViewSpec::visible`] at level `min_level` or any coarser one shown.
    #[must_use]
    pub fn visible_from(
        &self,
        size: (usize, usize),
        tile: usize,
        min_level: u32,
    ) -> Option<(crate::raster::window::Rect, u32)> {
        let zoom = self.zoom_for(size);
        let level = Preview::stride_for_zoom(zoom)
            .ilog2()
            .max(min_level.min(crate::eval::region::MAX_LEVEL));
        let stride = 1usize << level;
        let (lw, lh) = crate::raster::pyramid::reduced_size(size, stride);
        // The image's top-left corner relative to the panel's.
        let min = [
            0.5 * self.panel[0] + self.pan[0] - 0.5 * size.0 as f32 * zoom,
            0.5 * self.panel[1] + self.pan[1] - 0.5 * size.1 as f32 * zoom,
        ];
        let tile = tile.max(1) as f64;
        let span = |m: f32, panel: f32, n: usize| -> Option<(usize, usize)> {
            let px = f64::from(zoom) * stride as f64; // screen points per level pixel
            let a = (f64::from(-m) / px).floor().max(0.0);
            let b = (f64::from(panel - m) / px).ceil().min(n as f64);
            if b <= a {
                return None;
            }
            let a = ((a / tile).floor() * tile) as usize;
            let b = (((b / tile).ceil() * tile) as usize).min(n);
            Some((a, b))
        };
        let (x0, x1) = span(min[0], self.panel[0], lw)?;
        let (y0, y1) = span(min[1], self.panel[1], lh)?;
        Some((
            crate::raster::window::Rect::new(x0, y0, x1 - x0, y1 - y0),
            level,
        ))
    }
}

/// What the preview shows of an RGBN image: any [`View`] (relit, albedo, normals, curl and the
/// inspection views), or the integrated height.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// A rendered view (relit with the preview's light, colour only, normals as colour, curl
    /// map, curvature, exaggerated shading, …).
    View(View),
    /// The height the normals integrate to (DCT Poisson), grey from low to high.
    Height,
}

impl Default for Mode {
    fn default() -> Self {
        Mode::View(View::Relit)
    }
}

impl Mode {
    /// Relit with the preview's light.
    pub const RELIT: Mode = Mode::View(View::Relit);

    /// Every mode, in menu order: every view, then the height.
    pub const ALL: [Mode; View::ALL.len() + 1] = {
        let mut all = [Mode::Height; View::ALL.len() + 1];
        let mut i = 0;
        while i < View::ALL.len() {
            all[i] = Mode::View(View::ALL[i]);
            i += 1;
        }
        all
    };

    /// Its name in menus.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Mode::View(v) => v.name(),
            Mode::Height => "height",
        }
    }

    /// One line of documentation (hover text).
    #[must_use]
    pub fn doc(self) -> &'static str {
        match self {
            Mode::View(v) => v.doc(),
            Mode::Height => {
                "The height the normals integrate to (DCT Poisson), grey from low to high."
            }
        }
    }

    fn render_view(self) -> Option<View> {
        match self {
            Mode::View(v) => Some(v),
            Mode::Height => None,
        }
    }
}

/// Display settings of the preview (not part of the graph).
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewSettings {
    /// A view or the height.
    pub view: Mode,
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
    /// The inspection views' parameters.
    pub inspect: InspectParams,
}

impl Default for PreviewSettings {
    fn default() -> Self {
        let s = Shading::default();
        let d = s.lights[0].direction;
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        Self {
            view: Mode::RELIT,
            light: [d[0] / len, d[1] / len, d[2] / len],
            ambient: s.ambient,
            specular: s.specular,
            shininess: s.shininess,
            exposure_ev: s.exposure_ev,
            inspect: InspectParams::default(),
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
    /// Content key of the "before" value shown left of the split line, if any.
    pub before: Option<u128>,
    /// RGBN images are rendered from the pyramid level whose pixels are `stride × stride` blocks
    /// (1 = full resolution; [`preview_level`]). Zoomed out, the screen shows less than one pixel
    /// in `1/zoom` anyway, so the preview renders at about the displayed resolution:
    /// [`Preview::stride_for_zoom`].
    pub stride: usize,
    /// For a viewport evaluated ahead of the whole output: its rectangle (level pixels) and
    /// level. The value rendered is then that part, at that level.
    pub region: Option<(crate::raster::window::Rect, u32)>,
}

/// The preview's runtime state.
pub struct Preview {
    texture: Option<TextureHandle>,
    before_texture: Option<TextureHandle>,
    /// The newest request sent to the render thread.
    last: Option<PreviewRequest>,
    /// The request the texture on screen shows.
    shown: Option<PreviewRequest>,
    renderer: Renderer,
    /// Size in pixels of the value on screen (the texture may be smaller: `stride`).
    shown_size: Option<Vec2>,
    /// The zoom of the last frame drawn (screen points per image pixel).
    last_zoom: Option<f32>,
    /// A light direction asked for by Shift-dragging on the image (taken by the app).
    pub light_request: Option<[f32; 3]>,
    /// Where the before/after split line is (0 = all after … 1 = all before), when shown.
    pub split: Option<f32>,
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
    /// The panel's size in the last frame drawn.
    panel: Option<Vec2>,
    /// Renders the viewports evaluated ahead of whole outputs.
    region_renderer: Renderer,
    /// The newest viewport of the viewed output, as the worker evaluated it.
    region: Option<RegionShown>,
    /// The newest request sent to the region renderer.
    region_last: Option<PreviewRequest>,
    /// The viewport's picture, drawn over the texture until the whole output's picture (of the
    /// same content) is shown.
    overlay: Option<Overlay>,
    /// How many viewport pictures were shown (tests, statistics).
    pub overlays: u64,
    /// Increases when the viewport is forgotten: renders sent before are dropped.
    region_epoch: u64,
    /// A viewport picture went on screen since [`Preview::update_region`] last ran.
    overlay_fresh: bool,
    /// How long the render thread took for the viewport picture on screen (`None`: the worker
    /// rendered it with the evaluation).
    pub overlay_render_ms: Option<f64>,
}

/// A viewport of an output evaluated ahead of the whole output
/// ([`super::worker::RegionOutcome`]).
#[derive(Clone, Debug)]
pub struct RegionShown {
    /// Content key of the whole output.
    pub key: u128,
    /// The rectangle, in pixels of the level.
    pub rect: crate::raster::window::Rect,
    /// Level of detail.
    pub level: u32,
    /// A level coarser than the one shown, while edits keep coming (a global operator is
    /// evaluated at a coarse level: [`super::worker::INTERACTIVE_GLOBAL_PIXELS`]).
    pub coarse: bool,
    /// The output's size at full resolution.
    pub full_size: (usize, usize),
    /// The output over `rect` at the level.
    pub value: Value,
}

impl RegionShown {
    /// The viewport pixel covering full-resolution pixel `(x, y)`, if it is in the viewport.
    #[must_use]
    pub fn pixel_of(&self, x: usize, y: usize) -> Option<(usize, usize)> {
        let (lx, ly) = (x >> self.level, y >> self.level);
        let r = self.rect;
        (lx >= r.x && lx < r.right() && ly >= r.y && ly < r.bottom()).then(|| (lx - r.x, ly - r.y))
    }
}

/// A viewport's picture on screen.
struct Overlay {
    texture: TextureHandle,
    req: PreviewRequest,
    full_size: (usize, usize),
}

impl Default for Preview {
    fn default() -> Self {
        Self {
            texture: None,
            before_texture: None,
            last: None,
            shown: None,
            renderer: Renderer::default(),
            shown_size: None,
            last_zoom: None,
            light_request: None,
            split: None,
            curl: None,
            zoom: None,
            pan: Vec2::ZERO,
            renders: 0,
            render_ms: 0.0,
            transform: None,
            panel: None,
            region_renderer: Renderer::default(),
            region: None,
            region_last: None,
            overlay: None,
            overlays: 0,
            region_epoch: 0,
            overlay_fresh: false,
            overlay_render_ms: None,
        }
    }
}

impl Preview {
    /// The request for showing `value` (with content key `key`) under `settings`.
    #[must_use]
    pub fn request(value: &Value, key: u128, settings: &PreviewSettings) -> PreviewRequest {
        PreviewRequest {
            key,
            settings: matches!(value, Value::Rgbn(_)).then(|| settings.clone()),
            before: None,
            stride: 1,
            region: None,
        }
    }

    /// The render stride for a zoom: the largest power of two ≤ `1/zoom` (a pyramid level;
    /// at most 1024) when zoomed out, else 1.
    #[must_use]
    pub fn stride_for_zoom(zoom: f32) -> usize {
        if zoom >= 1.0 || !zoom.is_finite() || zoom <= 0.0 {
            1
        } else {
            let s = ((1.0 / zoom).floor() as usize).clamp(1, 1 << 10);
            1 << s.ilog2()
        }
    }

    /// Forgets the texture (the viewed node changed or has no value).
    pub fn clear(&mut self) {
        self.texture = None;
        self.before_texture = None;
        self.last = None;
        self.shown = None;
        self.clear_region();
    }

    /// Zooms to `zoom` screen points per image pixel, keeping the image pixel at the panel's
    /// centre where it is.
    pub fn set_zoom(&mut self, zoom: f32) {
        if let Some(old) = self.last_zoom.filter(|z| *z > 0.0) {
            self.pan *= zoom / old;
        }
        self.zoom = Some(zoom);
    }

    /// Fits the image to the panel.
    pub fn fit(&mut self) {
        self.zoom = None;
        self.pan = Vec2::ZERO;
    }

    /// Forgets the viewport and its picture.
    pub fn clear_region(&mut self) {
        self.region = None;
        self.region_last = None;
        self.overlay = None;
        self.region_epoch += 1;
    }

    /// Where the panel shows the image (`None` before the first frame).
    #[must_use]
    pub fn view_spec(&self) -> Option<ViewSpec> {
        let p = self.panel?;
        Some(ViewSpec {
            panel: [p.x, p.y],
            zoom: self.zoom,
            pan: [self.pan.x, self.pan.y],
        })
    }

    /// Takes a viewport evaluated ahead of the whole output: it is rendered
    /// ([`Preview::update_region`]) and drawn over the texture until the whole output's picture
    /// of the same content is on screen.
    ///
    /// `picture` is the viewport already rendered under `settings` (the worker renders it
    /// with the evaluation, which saves a frame): it goes on screen at once.
    pub fn set_region(
        &mut self,
        ctx: &egui::Context,
        r: RegionShown,
        picture: Option<(egui::ColorImage, PreviewSettings)>,
    ) {
        if let Some((img, settings)) = picture {
            let req = PreviewRequest {
                key: r.key,
                settings: Some(settings),
                before: None,
                stride: 1,
                region: Some((r.rect, r.level)),
            };
            self.show_overlay(ctx, img, req.clone(), r.full_size);
            self.overlay_render_ms = None;
            self.region_last = Some(req);
        }
        self.region = Some(r);
    }

    fn show_overlay(
        &mut self,
        ctx: &egui::Context,
        img: egui::ColorImage,
        req: PreviewRequest,
        full_size: (usize, usize),
    ) {
        match &mut self.overlay {
            Some(o) if o.texture.size() == img.size => {
                o.texture.set(img, TextureOptions::NEAREST);
                o.req = req;
                o.full_size = full_size;
            }
            _ => {
                self.overlay = Some(Overlay {
                    texture: ctx.load_texture("preview-viewport", img, TextureOptions::NEAREST),
                    req,
                    full_size,
                });
            }
        }
        self.overlays += 1;
        self.overlay_fresh = true;
    }

    /// The viewport taken last, if it is still to be shown.
    #[must_use]
    pub fn region(&self) -> Option<&RegionShown> {
        self.region.as_ref()
    }

    /// The viewport picture on screen: its request (rectangle and level in
    /// [`PreviewRequest::region`]).
    #[must_use]
    pub fn overlay_request(&self) -> Option<&PreviewRequest> {
        self.overlay.as_ref().map(|o| &o.req)
    }

    /// Renders the viewport when it or the settings changed, and takes finished renders.
    /// Returns true when a new viewport picture went on screen.
    pub fn update_region(&mut self, ctx: &egui::Context, settings: &PreviewSettings) -> bool {
        // The whole output's picture of the same content is on screen: the viewport is done.
        if let (Some(r), Some(shown)) = (&self.region, &self.shown) {
            if shown.key == r.key {
                self.clear_region();
            }
        }
        let mut newest = None;
        while let Ok(r) = self.region_renderer.rx.try_recv() {
            newest = Some(r);
        }
        // Any render of this epoch is newer than the picture on screen.
        if let (Some(r), Some(region)) = (newest, &self.region) {
            if r.epoch == self.region_epoch {
                if let Some(img) = r.main {
                    let full_size = region.full_size;
                    self.overlay_render_ms = Some(r.ms);
                    self.show_overlay(ctx, img, r.req, full_size);
                }
            }
        }
        let shown = std::mem::take(&mut self.overlay_fresh);
        let Some(region) = &self.region else {
            return shown;
        };
        let rgbn = matches!(region.value, Value::Rgbn(_));
        if rgbn && settings.view == Mode::Height {
            // Heights integrate the whole image: the viewport alone would be wrong.
            self.overlay = None;
            return shown;
        }
        let req = PreviewRequest {
            key: region.key,
            settings: rgbn.then(|| settings.clone()),
            before: None,
            stride: 1,
            region: Some((region.rect, region.level)),
        };
        if self.region_last.as_ref() != Some(&req) {
            if let Some(tx) = &self.region_renderer.tx {
                let job = Job {
                    req: req.clone(),
                    epoch: self.region_epoch,
                    value: region.value.clone(),
                    before: None,
                    ctx: ctx.clone(),
                };
                if tx.send(job).is_ok() {
                    self.region_last = Some(req);
                }
            }
        }
        shown
    }

    /// True when the split view's "before" picture is on screen.
    #[must_use]
    pub fn showing_before(&self) -> bool {
        self.split.is_some() && self.before_texture.is_some()
    }

    /// The display settings of the picture on screen (`None` for pictures and masks).
    #[must_use]
    pub fn shown_settings(&self) -> Option<&PreviewSettings> {
        self.shown.as_ref()?.settings.as_ref()
    }

    /// The pyramid level the shown RGBN picture was rendered from (0: full resolution).
    #[must_use]
    pub fn shown_level(&self) -> u32 {
        self.shown
            .as_ref()
            .filter(|r| r.settings.is_some())
            .map_or(0, |r| r.stride.max(1).ilog2())
    }

    /// True while a render for the newest request is under way.
    #[must_use]
    pub fn pending(&self) -> bool {
        self.last.is_some() && self.last != self.shown
    }

    /// Asks for `value` (and `before`, shown left of the split line) as `req` says; renders on
    /// the preview thread only if `req` changed. Takes finished renders: the texture shows the
    /// newest one.
    pub fn update(
        &mut self,
        ctx: &egui::Context,
        value: &Value,
        before: Option<&Value>,
        mut req: PreviewRequest,
    ) {
        self.take_rendered(ctx);
        if matches!(value, Value::Rgbn(_)) {
            req.stride = self.last_zoom.map_or(1, Self::stride_for_zoom);
        }
        if self.last.as_ref() == Some(&req) {
            return;
        }
        if let Some(tx) = &self.renderer.tx {
            let job = Job {
                req: req.clone(),
                epoch: 0,
                value: value.clone(),
                before: before.cloned(),
                ctx: ctx.clone(),
            };
            if tx.send(job).is_ok() {
                self.last = Some(req);
            }
        }
    }

    fn take_rendered(&mut self, ctx: &egui::Context) {
        let mut newest = None;
        while let Ok(r) = self.renderer.rx.try_recv() {
            newest = Some(r);
        }
        let Some(r) = newest else {
            return;
        };
        if self.last.as_ref().map(|l| l.key) != Some(r.req.key) && self.last.is_some() {
            // A render of a value no longer viewed: keep it only if nothing else is on screen.
            if self.texture.is_some() {
                return;
            }
        }
        self.shown_size = Some(Vec2::new(r.logical[0] as f32, r.logical[1] as f32));
        set_texture(ctx, &mut self.texture, "preview", r.main);
        set_texture(ctx, &mut self.before_texture, "preview-before", r.before);
        self.renders += 1;
        self.render_ms = r.ms;
        self.shown = Some(r.req);
    }

    /// Draws the "before" picture over the part of `img_rect` left of the split line, and the
    /// line itself.
    fn draw_split(&self, painter: &egui::Painter, img_rect: Rect) {
        let (Some(t), Some(s)) = (&self.before_texture, self.split) else {
            return;
        };
        let x = img_rect.left() + img_rect.width() * s.clamp(0.0, 1.0);
        let left = Rect::from_min_max(img_rect.min, Pos2::new(x, img_rect.bottom()));
        painter.image(
            t.id(),
            left,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(s.clamp(0.0, 1.0), 1.0)),
            Color32::WHITE,
        );
        painter.line_segment(
            [
                Pos2::new(x, img_rect.top()),
                Pos2::new(x, img_rect.bottom()),
            ],
            Stroke::new(1.5, Color32::from_rgb(255, 220, 80)),
        );
        for (text, align, dx) in [
            ("before", egui::Align2::RIGHT_TOP, -4.0),
            ("after", egui::Align2::LEFT_TOP, 4.0),
        ] {
            painter.text(
                Pos2::new(x + dx, img_rect.top().max(painter.clip_rect().top()) + 4.0),
                align,
                text,
                egui::FontId::proportional(12.0),
                Color32::from_rgb(255, 220, 80),
            );
        }
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
        let background = || painter.rect_filled(rect, 0.0, Color32::from_gray(24));
        self.panel = Some(rect.size());
        let overlay_size = self
            .overlay
            .as_ref()
            .map(|o| Vec2::new(o.full_size.0 as f32, o.full_size.1 as f32));
        let base_size = self
            .texture
            .as_ref()
            .map(|t| self.shown_size.unwrap_or_else(|| t.size_vec2()));
        let Some(size) = overlay_size.or(base_size) else {
            background();
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
        let fit = fit_zoom([rect.width(), rect.height()], [size.x, size.y]);
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
            // Shift-drag (or Alt-drag) moves the light instead of panning.
            let light_mod = ui.input(|i| i.modifiers.shift || i.modifiers.alt);
            if light_mod && resp.dragged_by(PointerButton::Primary) {
                if let Some(p) = resp.interact_pointer_pos() {
                    let c = rect.center() + self.pan;
                    let r = 0.5 * (size * zoom).min_elem().max(1.0);
                    let mut d = (p - c) / r;
                    if d.length() > 0.995 {
                        d = d.normalized() * 0.995;
                    }
                    let z = (1.0 - d.length_sq()).max(0.0).sqrt();
                    self.light_request = Some([d.x, -d.y, z]);
                }
                false
            } else {
                resp.dragged()
            }
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
        self.last_zoom = Some(zoom);
        let img_rect = Rect::from_center_size(rect.center() + self.pan, size * zoom);
        let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
        let overlay = self.overlay.as_ref().and_then(|o| {
            let (r, level) = o.req.region?;
            // Level pixel (x, y) covers full-resolution pixels [x·s, (x+1)·s) (the last
            // block of a row or column may be cut by the image's edge).
            let s = (1u64 << level) as f32;
            let x0 = r.x as f32 * s;
            let y0 = r.y as f32 * s;
            let x1 = (r.right() as f32 * s).min(size.x);
            let y1 = (r.bottom() as f32 * s).min(size.y);
            let at = Rect::from_min_max(
                img_rect.min + Vec2::new(x0, y0) * zoom,
                img_rect.min + Vec2::new(x1, y1) * zoom,
            );
            Some((o.texture.id(), at))
        });
        // The picture under a viewport that covers all of it on screen is not drawn: with
        // software GL each covered pixel would be shaded twice.
        let visible = img_rect.intersect(rect);
        // Likewise the background, when the picture fills the panel (zoomed in).
        if !img_rect.contains_rect(rect) {
            background();
        }
        let covered = overlay.is_some_and(|(_, at)| at.contains_rect(visible));
        if let Some(tex) = self.texture.as_ref().filter(|_| !covered) {
            painter.image(tex.id(), img_rect, uv, Color32::WHITE);
        }
        if let Some((id, at)) = overlay {
            painter.image(id, at, uv, Color32::WHITE);
        }
        self.draw_split(&painter, img_rect);
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
        let Some((v, key)) = value else {
            // Shown by its viewport only: read the viewport's pixel.
            let r = self.region.as_ref()?;
            let Value::Rgbn(img) = &r.value else {
                return None;
            };
            let (px, py) = r.pixel_of(x, row)?;
            let (c, n) = (img.color_at(px, py), img.normal_at(px, py));
            return Some(format!(
                "({x}, {row}) at level {} (1:{})  colour {:.3} {:.3} {:.3}  normal {:+.3} {:+.3} {:+.3}",
                r.level,
                1u64 << r.level,
                c[0],
                c[1],
                c[2],
                n[0],
                n[1],
                n[2]
            ));
        };
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

fn set_texture(
    ctx: &egui::Context,
    slot: &mut Option<TextureHandle>,
    name: &str,
    img: Option<egui::ColorImage>,
) {
    match (img, slot.as_mut()) {
        (Some(img), Some(t)) if t.size() == img.size => t.set(img, TextureOptions::NEAREST),
        (Some(img), _) => *slot = Some(ctx.load_texture(name, img, TextureOptions::NEAREST)),
        (None, _) => *slot = None,
    }
}

#[cfg(test)]
mod tests;
