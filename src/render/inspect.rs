//! Parameters of the inspection views ([`View`]): one field group per view, each field named
//! after the view's short name ([`InspectParams::prefix`]), declared once with
//! [`crate::params!`] so that `rgbn render --param`, the `view` node, `rgbn ops` and the editor
//! all document and check them the same way. Also the small helpers the views share.

use super::View;
use crate::error::RgbnError;
use crate::params::{self, ParamInfo};
use crate::raster::srgb::linear_to_srgb8;
use crate::raster::RgbnImage;

crate::params! {
    /// Parameters of the inspection views, one group per view.
    #[derive(Clone, Debug, PartialEq)]
    pub struct InspectParams {
        /// curvature: the colour is clamp(H·scale, −1, 1) with H in 1/px (full colour where the
        /// radius of curvature is scale px); 0 = automatic: 1 / (99th percentile of |H|).
        pub curvature_scale: f64 = 0.0 => float.unit("px").range(0.0, 1e9).soft(0.0, 1000.0).log(),
        /// exaggerated: number of detail scales (each smoothing doubles σ).
        pub exag_scales: i64 = 4 => int.range(1.0, 10.0),
        /// exaggerated: Gaussian σ of the first (finest) smoothing of the normals.
        pub exag_sigma: f64 = 1.0 => float.unit("px").range(0.25, 512.0).soft(0.25, 16.0).log(),
        /// exaggerated: clamp coefficient a: each scale contributes clamp(a·n·l, −1, 1), so a
        /// large a turns small tilts into full light or shadow (the paper's a).
        pub exag_clamp: f64 = 10.0 => float.range(0.01, 1000.0).soft(0.5, 100.0).log(),
        /// exaggerated: weight of scale i ∝ σᵢ^(−detail): positive favours fine detail, 0
        /// weighs all scales alike, negative favours coarse shape.
        pub exag_detail: f64 = 0.0 => float.range(-4.0, 4.0),
        /// radiance_scaling: strength α: radiance × 2^(α·tanh(H·scale)) (0 = plain relit).
        pub radiance_alpha: f64 = 1.0 => float.range(0.0, 16.0).soft(0.0, 4.0),
        /// radiance_scaling: curvature scale as curvature_scale (0 = automatic).
        pub radiance_scale: f64 = 0.0 => float.unit("px").range(0.0, 1e9).soft(0.0, 1000.0).log(),
        /// radiance_scaling: Gaussian σ the normals are smoothed with before the curvature is
        /// taken (0 = none), so that fine texture does not dominate.
        pub radiance_sigma: f64 = 1.0 => float.unit("px").range(0.0, 256.0).soft(0.0, 8.0),
        /// toon: number of shading bands.
        pub toon_levels: i64 = 4 => int.range(1.0, 64.0).soft(1.0, 16.0),
        /// toon: outline where the normal's n_z is below this (near the silhouette; 0 = none).
        pub toon_silhouette: f64 = 0.25 => float.range(0.0, 1.0),
        /// toon: outline where |H| exceeds this (1/px; 0 = no curvature outlines).
        pub toon_crease: f64 = 0.1 => float.unit("1/px").range(0.0, 100.0).soft(0.0, 0.5),
        /// toon: Gaussian σ the normals are smoothed with before the curvature is taken.
        pub toon_sigma: f64 = 2.0 => float.unit("px").range(0.0, 256.0).soft(0.0, 16.0),
        /// lines: ridge/valley lines where |H| exceeds this and is a local maximum across.
        pub lines_threshold: f64 = 0.05 => float.unit("1/px").range(0.0, 100.0).soft(0.0, 0.25),
        /// lines: contour-like lines where n_z is below this (0 = none).
        pub lines_contour: f64 = 0.2 => float.range(0.0, 1.0),
        /// lines: Gaussian σ the normals are smoothed with before the curvature is taken
        /// (0 = none): the scale of the features drawn.
        pub lines_sigma: f64 = 2.0 => float.unit("px").range(0.0, 256.0).soft(0.0, 16.0),
        // spec_*, unsharp_*, ao_*, multi_*: the same fields (docs, defaults, ranges) as the
        // views' own structs in render::rti and render::occlusion, which the views take; a
        // test there checks that the two declarations agree.
        /// specular_enhancement: diffuse weight kd of the grey material that replaces the
        /// albedo.
        pub spec_kd: f64 = 0.4 => float.range(0.0, 10.0).soft(0.0, 2.0),
        /// specular_enhancement: specular strength ks (white Blinn-Phong highlight).
        pub spec_ks: f64 = 0.7 => float.range(0.0, 10.0).soft(0.0, 2.0),
        /// specular_enhancement: highlight exponent α; larger is a tighter, glossier highlight.
        pub spec_alpha: f64 = 75.0 => float.range(0.0, 10000.0).soft(1.0, 1000.0).log(),
        /// normal_unsharp: how much of the normals' fine detail (normal minus its blur) is
        /// added back; 0 = relit.
        pub unsharp_gain: f64 = 2.0 => float.range(0.0, 100.0).soft(0.0, 8.0),
        /// normal_unsharp: σ of the Gaussian blur separating detail from shape.
        pub unsharp_sigma: f64 = 3.0 => float.unit("px").range(0.1, 1000.0).soft(0.5, 32.0).log(),
        /// ambient_occlusion: how far each direction is searched for a horizon; relief wider
        /// than this is not seen as occluding.
        pub ao_radius: f64 = 16.0 => float.unit("px").range(1.0, 512.0).soft(2.0, 128.0).log(),
        /// ambient_occlusion: number of directions marched around each pixel (evenly spaced
        /// in azimuth).
        pub ao_directions: i64 = 8 => int.range(1.0, 64.0).soft(1.0, 32.0),
        /// ambient_occlusion: multiplies the integrated height before the horizon search
        /// (relief exaggeration: shallow relief needs more than 1).
        pub ao_depth: f64 = 1.0 => float.range(0.01, 1000.0).soft(0.1, 10.0).log(),
        /// ambient_occlusion: multiply the grey occlusion by the albedo.
        pub ao_albedo: bool = false => bool,
        /// multi_light: number of virtual lights, spread evenly in azimuth around the
        /// hemisphere.
        pub multi_lights: i64 = 8 => int.range(1.0, 64.0).soft(1.0, 32.0),
        /// multi_light: elevation of the virtual lights above the image plane (90 = from the
        /// viewer).
        pub multi_elevation: f64 = 30.0 => float.unit("°").range(1.0, 90.0),
        /// multi_light: σ of the Gaussian separating each light's shading into base and
        /// detail.
        pub multi_sigma: f64 = 4.0 => float.unit("px").range(0.3, 1000.0).soft(0.5, 32.0).log(),
        /// multi_light: gain on the combined detail layer (0 = the mean base only).
        pub multi_gain: f64 = 1.0 => float.range(0.0, 100.0).soft(0.0, 4.0),
    }
}

impl InspectParams {
    /// The name prefix of `view`'s parameter group, or `None` when it has no parameters.
    #[must_use]
    pub fn prefix(view: View) -> Option<&'static str> {
        match view {
            View::Relit | View::Albedo | View::Normals | View::Curl => None,
            View::Curvature => Some("curvature_"),
            View::Exaggerated => Some("exag_"),
            View::RadianceScaling => Some("radiance_"),
            View::Toon => Some("toon_"),
            View::Lines => Some("lines_"),
            View::SpecularEnhancement => Some("spec_"),
            View::NormalUnsharp => Some("unsharp_"),
            View::AmbientOcclusion => Some("ao_"),
            View::MultiLight => Some("multi_"),
        }
    }

    /// The view whose group holds the parameter `name`.
    #[must_use]
    pub fn view_of(name: &str) -> Option<View> {
        View::ALL
            .iter()
            .copied()
            .find(|v| Self::prefix(*v).is_some_and(|p| name.starts_with(p)))
    }

    /// The parameters of `view` (name, kind, doc, range, default).
    #[must_use]
    pub fn describe(view: View) -> Vec<ParamInfo> {
        let Some(p) = Self::prefix(view) else {
            return Vec::new();
        };
        params::describe::<Self>()
            .into_iter()
            .filter(|i| i.name.starts_with(p))
            .collect()
    }

    /// Checks every value against its declared range: an error names the parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        Ok(params::check_ranges(self)?)
    }

    /// Sets parameters from `name=value` strings (the command line's `--param`): an unknown
    /// name is refused with the nearest known one, a value with the parameter's own error.
    pub fn from_assignments<S: AsRef<str>>(items: &[S]) -> Result<Self, RgbnError> {
        let infos = params::describe::<Self>();
        let mut values = std::collections::BTreeMap::new();
        for item in items {
            let item = item.as_ref();
            let Some((name, value)) = item.split_once('=') else {
                return Err(RgbnError::param(
                    item,
                    "expected NAME=VALUE (e.g. curvature_scale=20)",
                ));
            };
            let name = name.trim();
            let Some(info) = infos.iter().find(|i| i.name == name) else {
                let detail = match params::nearest(name, infos.iter().map(|i| i.name)) {
                    Some(s) => format!("no such view parameter (did you mean {s:?}?)"),
                    None => "no such view parameter (see rgbn render --help)".into(),
                };
                return Err(RgbnError::param(name, detail));
            };
            let v = info
                .parse_str(value.trim())
                .map_err(|e| RgbnError::param(name, e))?;
            values.insert(name.to_string(), v);
        }
        Ok(params::from_values::<Self>(&values)?)
    }

    /// Every view with its documentation and parameters, for `rgbn render --help`.
    #[must_use]
    pub fn help() -> String {
        let mut s = String::new();
        for v in View::ALL {
            s.push_str(&format!("{}: {}\n", v.name(), v.doc()));
            for i in Self::describe(*v) {
                let unit = if i.meta.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", i.meta.unit)
                };
                s.push_str(&format!(
                    "    {} (default {}{unit}): {}\n",
                    i.name, i.default, i.meta.doc
                ));
            }
        }
        s
    }
}

/// Coverage of pixel `i` (1 without a mask).
#[inline]
pub(super) fn coverage(img: &RgbnImage, i: usize) -> f32 {
    img.mask().map_or(1.0, |m| m[i].clamp(0.0, 1.0))
}

/// Alpha byte of a coverage.
#[inline]
pub(super) fn alpha8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// A linear RGB value as sRGB RGBA8 with alpha = coverage of pixel `i`.
#[inline]
pub(super) fn srgb_px(img: &RgbnImage, i: usize, rgb: [f32; 3]) -> [u8; 4] {
    let [r, g, b] = rgb.map(linear_to_srgb8);
    [r, g, b, alpha8(coverage(img, i))]
}
