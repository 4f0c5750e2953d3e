//! The preview's render thread ([`Renderer`]) and the conversions from values to pictures
//! and textures.

use super::*;
use crate::nodes::{Picture, Value};
use crate::raster::Plane;
use crate::render::{self, View};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;

/// A render job for the preview thread.
pub(super) struct Job {
    pub(super) req: PreviewRequest,
    /// Renders of an older epoch are dropped ([`Preview::clear_region`]).
    pub(super) epoch: u64,
    pub(super) value: Value,
    pub(super) before: Option<Value>,
    pub(super) ctx: egui::Context,
}

/// A finished render.
pub(super) struct Rendered {
    pub(super) req: PreviewRequest,
    pub(super) epoch: u64,
    /// Size of the value in pixels (the texture is smaller when `req.stride > 1`).
    pub(super) logical: [usize; 2],
    pub(super) main: Option<egui::ColorImage>,
    pub(super) before: Option<egui::ColorImage>,
    pub(super) ms: f64,
}

/// The preview's render thread: renders the newest job, skipping older ones still queued.
pub struct Renderer {
    pub(super) tx: Option<Sender<Job>>,
    pub(super) rx: Receiver<Rendered>,
    pub(super) handle: Option<std::thread::JoinHandle<()>>,
}

impl Default for Renderer {
    fn default() -> Self {
        let (tx, jobs) = channel::<Job>();
        let (done, rx) = channel();
        let handle = std::thread::Builder::new()
            .name("rgbn-preview".into())
            .spawn(move || {
                let mut heights = HeightCache::default();
                let mut small = SmallCache::default();
                while let Ok(mut job) = jobs.recv() {
                    while let Ok(newer) = jobs.try_recv() {
                        job = newer;
                    }
                    let t0 = std::time::Instant::now();
                    let settings = job.req.settings.clone().unwrap_or_default();
                    let logical = value_size(&job.value);
                    let stride = job.req.stride;
                    let value = small.get(0, &job.value, job.req.key, stride);
                    let main = render_color_image(&value, job.req.key, &settings, &mut heights);
                    let before = job.before.as_ref().and_then(|b| {
                        let key = job.req.before.unwrap_or(0);
                        let b = small.get(1, b, key, stride);
                        render_color_image(&b, key, &settings, &mut heights)
                    });
                    let out = Rendered {
                        logical,
                        epoch: job.epoch,
                        req: job.req,
                        main,
                        before,
                        ms: t0.elapsed().as_secs_f64() * 1e3,
                    };
                    if done.send(out).is_err() {
                        break;
                    }
                    job.ctx.request_repaint();
                }
            })
            .expect("spawn the preview thread");
        Self {
            tx: Some(tx),
            rx,
            handle: Some(handle),
        }
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// Width and height of a value in pixels (`[0, 0]` for numbers).
pub(super) fn value_size(v: &Value) -> [usize; 2] {
    match v {
        Value::Rgbn(img) => [img.width(), img.height()],
        Value::Mask(p) | Value::Scalar(p) => [p.width(), p.height()],
        Value::Picture(p) => [p.width, p.height],
        Value::Number(_) => [0, 0],
    }
}

/// The preview's image at `stride` = 2^level: level `level` of the block-mean pyramid
/// ([`crate::raster::pyramid`], as `rgbn eval --level` computes it), or the image itself.
/// Detail finer than a screen pixel averages out rather than aliasing.
#[must_use]
pub fn preview_level(img: &crate::RgbnImage, stride: usize) -> crate::RgbnImage {
    crate::raster::pyramid::reduce_rgbn(img, stride)
}

/// The reduced copies of the last two values rendered (main and before), by key and stride:
/// while the light moves only the small image is relit.
#[derive(Default)]
pub(super) struct SmallCache([Option<(u128, usize, Value)>; 2]);

impl SmallCache {
    fn get(&mut self, slot: usize, v: &Value, key: u128, stride: usize) -> Value {
        let Value::Rgbn(img) = v else {
            return v.clone();
        };
        if stride <= 1 {
            return v.clone();
        }
        if let Some((k, s, small)) = &self.0[slot] {
            if *k == key && *s == stride && key != 0 {
                return small.clone();
            }
        }
        let small = Value::Rgbn(preview_level(img, stride));
        self.0[slot] = Some((key, stride, small.clone()));
        small
    }
}

/// The last integrated height, by the value's content key.
#[derive(Default)]
pub(super) struct HeightCache(Option<(u128, Arc<Plane>)>);

impl HeightCache {
    fn get(&mut self, key: u128, img: &crate::RgbnImage) -> Option<Arc<Plane>> {
        if let Some((k, p)) = &self.0 {
            if *k == key && key != 0 {
                return Some(p.clone());
            }
        }
        let params = crate::raster::integrate::IntegrateParams::default();
        let (z, _) = crate::raster::integrate::integrate_normals(img, &params).ok()?;
        let z = Arc::new(z);
        self.0 = Some((key, z.clone()));
        Some(z)
    }
}

pub(super) fn render_color_image(
    v: &Value,
    key: u128,
    s: &PreviewSettings,
    heights: &mut HeightCache,
) -> Option<egui::ColorImage> {
    match (v, s.view) {
        (Value::Rgbn(img), Mode::Height) => {
            let z = heights.get(key, img)?;
            Some(display_image(&crate::app::worker::plane_picture(&z)))
        }
        _ => color_image(v, s),
    }
}

/// The picture as an egui image. Pictures whose pixels are all opaque or transparent black
/// (relit, albedo, normals, curl, height) are already premultiplied: their bytes are taken as
/// they are instead of being converted pixel by pixel.
#[must_use]
pub fn display_image(p: &Picture) -> egui::ColorImage {
    let premultiplied = p
        .rgba
        .chunks_exact(4)
        .all(|c| c[3] == 255 || c == [0, 0, 0, 0]);
    if premultiplied {
        egui::ColorImage::from_rgba_premultiplied([p.width, p.height], &p.rgba)
    } else {
        egui::ColorImage::from_rgba_unmultiplied([p.width, p.height], &p.rgba)
    }
}

/// What the preview shows of `v` under `s` (all but the height view), as an egui image. A
/// view whose pixels are all opaque (any view of an unmasked RGBN; normals and curl always) is
/// rendered straight into the texture's pixels: its sRGB bytes already are egui's
/// premultiplied `Color32`s, so the 16 MB of a 2K frame are neither scanned, converted nor
/// copied (the light-drag case).
#[must_use]
pub fn color_image(v: &Value, s: &PreviewSettings) -> Option<egui::ColorImage> {
    if let (Value::Rgbn(img), Some(view)) = (v, s.view.render_view()) {
        if img.mask().is_none() || matches!(view, View::Normals | View::Curl) {
            let mut pixels: Vec<egui::Color32> = bytemuck::zeroed_vec(img.len());
            crate::raster::buf::advise_huge_pages(&pixels);
            let rgba: &mut [u8] = bytemuck::cast_slice_mut(&mut pixels);
            render::render_with_into(img, view, &s.shading(), &s.inspect, rgba).ok()?;
            return Some(egui::ColorImage::new([img.width(), img.height()], pixels));
        }
    }
    Some(display_image(&render_value(v, s)?))
}

/// Renders a value for display (sRGB RGBA8), or `None` for numbers.
pub fn render_value(v: &Value, s: &PreviewSettings) -> Option<Picture> {
    match v {
        Value::Rgbn(img) => {
            let view = s.view.render_view().unwrap_or(View::Relit);
            let rgba = render::render_with(img, view, &s.shading(), &s.inspect).ok()?;
            Some(Picture {
                width: img.width(),
                height: img.height(),
                rgba,
            })
        }
        Value::Picture(p) => Some((**p).clone()),
        Value::Mask(p) | Value::Scalar(p) => Some(crate::app::worker::plane_picture(p)),
        Value::Number(_) => None,
    }
}
