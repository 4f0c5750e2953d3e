//! Screen ↔ image coordinates of the preview, and point-list helpers shared by the tools.

/// Screen ↔ image mapping of the preview: the image's top-left corner on screen and the zoom
/// (screen points per image pixel). Pixel `(x, row)` is centred at integer coordinates (as the
/// operators sample), so its square spans `[x − ½, x + ½]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewTransform {
    /// Screen position of the image's top-left corner.
    pub origin: [f32; 2],
    /// Screen points per image pixel.
    pub zoom: f32,
}

impl ViewTransform {
    /// The mapping of the preview: panel `centre`, `pan` offset, image `size` in pixels, `zoom`.
    #[must_use]
    pub fn new(centre: [f32; 2], pan: [f32; 2], size: [f32; 2], zoom: f32) -> Self {
        Self {
            origin: [
                centre[0] + pan[0] - size[0] * zoom / 2.0,
                centre[1] + pan[1] - size[1] * zoom / 2.0,
            ],
            zoom,
        }
    }

    /// Image coordinates `(x, row)` of a screen position.
    #[must_use]
    pub fn image_from_screen(&self, s: [f32; 2]) -> [f64; 2] {
        [
            f64::from((s[0] - self.origin[0]) / self.zoom) - 0.5,
            f64::from((s[1] - self.origin[1]) / self.zoom) - 0.5,
        ]
    }

    /// Screen position of image coordinates `(x, row)`.
    #[must_use]
    pub fn screen_from_image(&self, p: [f64; 2]) -> [f32; 2] {
        [
            self.origin[0] + (p[0] as f32 + 0.5) * self.zoom,
            self.origin[1] + (p[1] as f32 + 0.5) * self.zoom,
        ]
    }

    /// A screen length in image pixels.
    #[must_use]
    pub fn px_from_pt(&self, len_pt: f32) -> f64 {
        f64::from(len_pt / self.zoom)
    }
}

pub(super) fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Appends `p` unless it is closer than `min_px` to the last point; true if appended.
pub fn push_simplified(points: &mut Vec<[f64; 2]>, p: [f64; 2], min_px: f64) -> bool {
    if !(p[0].is_finite() && p[1].is_finite()) {
        return false;
    }
    match points.last() {
        Some(&last) if dist(last, p) < min_px => false,
        _ => {
            points.push(p);
            true
        }
    }
}

/// Index of the point nearest to `p` within `tol_px`, if any.
#[must_use]
pub fn hit_vertex(points: &[[f64; 2]], p: [f64; 2], tol_px: f64) -> Option<usize> {
    points
        .iter()
        .enumerate()
        .map(|(i, q)| (i, dist(*q, p)))
        .filter(|(_, d)| *d <= tol_px)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}
#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;

    #[test]
    fn screen_and_image_coordinates_map_both_ways_under_zoom_and_pan() {
        // A 100×50 image at zoom 2 in a panel centred at (300, 200), panned by (10, −20): the
        // image's left edge is at 300 + 10 − 100 = 210, its top at 200 − 20 − 50 = 130.
        let t = ViewTransform::new([300.0, 200.0], [10.0, -20.0], [100.0, 50.0], 2.0);
        assert_eq!(t.origin, [210.0, 130.0]);
        // Pixel (0, 0) is centred one half pixel (1 point) inside the corner.
        assert_eq!(t.screen_from_image([0.0, 0.0]), [211.0, 131.0]);
        assert_eq!(t.image_from_screen([211.0, 131.0]), [0.0, 0.0]);
        // The corner itself is at −½.
        assert_eq!(t.image_from_screen([210.0, 130.0]), [-0.5, -0.5]);
        // The last pixel's centre.
        assert_eq!(t.screen_from_image([99.0, 49.0]), [409.0, 229.0]);
        for s in [[233.5f32, 171.25], [-40.0, 900.0]] {
            let back = t.screen_from_image(t.image_from_screen(s));
            assert!((back[0] - s[0]).abs() < 1e-3 && (back[1] - s[1]).abs() < 1e-3);
        }
        assert_eq!(t.px_from_pt(7.0), 3.5);
    }

    #[test]
    fn stroke_simplification_drops_points_closer_than_the_spacing() {
        let mut pts = Vec::new();
        assert!(push_simplified(&mut pts, [0.0, 0.0], MIN_SPACING_PX));
        assert!(!push_simplified(&mut pts, [1.0, 1.0], MIN_SPACING_PX)); // √2 < 1.5
        assert!(push_simplified(&mut pts, [1.5, 0.0], MIN_SPACING_PX));
        assert!(!push_simplified(&mut pts, [f64::NAN, 0.0], MIN_SPACING_PX));
        // Spacing is measured from the last kept point, so slow drags still progress.
        for i in 1..=10 {
            push_simplified(&mut pts, [1.5 + 0.5 * f64::from(i), 0.0], MIN_SPACING_PX);
        }
        assert_eq!(
            pts,
            vec![[0.0, 0.0], [1.5, 0.0], [3.0, 0.0], [4.5, 0.0], [6.0, 0.0]]
        );
    }
}
