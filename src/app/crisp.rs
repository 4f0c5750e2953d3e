//! Text that stays sharp in a zoomed graph view.
//!
//! egui-snarl zooms by a transform of its layer: text laid out at the style's size (14 px) is
//! rasterised into the font atlas at that size and its quads are then scaled with the view. At
//! the zoom a graph opens with (about 0.7 for the demo in its panel) the glyphs are shrunk from
//! texture and thin strokes fade: the `light · Relight` header read "ight Relight" (the `l`
//! gone, the `·` gone), `curl` read "cur". [`label_ui`] lays the text out at the size it has on
//! screen (`size × zoom`, so the atlas holds glyphs of the on-screen size), scales that galley
//! back by `1 / zoom` into the layer, and the layer's transform scales it by `zoom` again: the
//! glyphs reach the screen at the size they were rasterised at. The space taken in the node is
//! the text's size at the style's size (or the on-screen layout's, when it is wider), so nodes
//! keep their layout at every zoom.

use egui::emath::TSTransform;
use egui::epaint::TextShape;
use egui::{Color32, FontId, Pos2, Response, Sense, Stroke, Ui, Vec2, WidgetInfo, WidgetType};

/// The font size text of `size` is laid out at under a zoom of `zoom`: `size × zoom`, rounded
/// to half a pixel (so that zooming does not fill the font atlas with a size per frame), at
/// least 1.
#[must_use]
pub fn raster_size(size: f32, zoom: f32) -> f32 {
    ((size * zoom * 2.0).round() / 2.0).max(1.0)
}

/// A label in a layer zoomed by `zoom`, sharp on screen: `text` in `font` and `color`,
/// underlined when asked, sensing `sense`. Accessibility sees a label with the text.
pub fn label_ui(
    ui: &mut Ui,
    text: &str,
    font: &FontId,
    color: Color32,
    zoom: f32,
    underline: bool,
    sense: Sense,
) -> Response {
    let zoom = if zoom.is_finite() && zoom > 0.0 {
        zoom
    } else {
        1.0
    };
    let painter = ui.painter();
    let natural = painter.layout_no_wrap(text.to_owned(), font.clone(), color);
    let size_px = raster_size(font.size, zoom);
    // The galley is scaled by 1 / zoom into the layer, which scales it by zoom: on screen it
    // has the size it was laid out (and rasterised) at.
    let back = 1.0 / zoom;
    let on_screen = painter.layout_no_wrap(
        text.to_owned(),
        FontId::new(size_px, font.family.clone()),
        color,
    );
    let scaled = on_screen.size() * back;
    let size = Vec2::new(
        natural.size().x.max(scaled.x),
        natural.size().y.max(scaled.y),
    );
    let (rect, resp) = ui.allocate_exact_size(size, sense);
    if ui.is_rect_visible(rect) {
        let mut shape = TextShape::new(Pos2::ZERO, on_screen, color);
        shape.transform(TSTransform::from_scaling(back));
        shape.pos = Pos2::new(rect.min.x, rect.center().y - scaled.y / 2.0);
        if underline {
            let y = shape.pos.y + scaled.y;
            ui.painter().line_segment(
                [
                    Pos2::new(rect.min.x, y),
                    Pos2::new(rect.min.x + scaled.x, y),
                ],
                Stroke::new(1.0 / zoom, color),
            );
        }
        ui.painter().add(shape);
    }
    resp.widget_info(|| WidgetInfo::labeled(WidgetType::Label, ui.is_enabled(), text));
    resp
}
