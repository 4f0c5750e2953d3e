//! Turning an RGBN image into something to look at: relighting (Lambert + Blinn-Phong with
//! directional lights, ambient and exposure), normals as colour, albedo, the curl map, and the
//! inspection views ([`View`]; their parameters: [`InspectParams`]).
//! Every view produces sRGB 8-bit RGBA, row-major, row 0 at the top.

pub mod curvature;
pub mod inspect;
pub mod npr;
pub mod occlusion;
pub mod rti;
mod settings;

pub use curvature::{curvature_scale, mean_curvature};
pub use inspect::InspectParams;
pub use settings::LightSettings;

use crate::error::RgbnError;
use crate::params::Choice;
use crate::raster::buf;
use crate::raster::fastmath::{exp2_fast, log2_fast, ROUND};
use crate::raster::gradient::GradientField;
use crate::raster::simd::Simd;
use crate::raster::srgb::{srgb8_lut_encode, SRGB8_LUT_SIZE};
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// A directional light: `direction` points from the surface towards the light (OpenGL frame,
/// need not be normalised), `color` is its linear RGB intensity.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Light {
    pub direction: [f32; 3],
    pub color: [f32; 3],
}

impl Light {
    /// A white light of intensity 1 from `direction`.
    #[must_use]
    pub fn white(direction: [f32; 3]) -> Self {
        Self {
            direction,
            color: [1.0; 3],
        }
    }
}

/// Relighting parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Shading {
    pub lights: Vec<Light>,
    /// Ambient term added to the diffuse light (times albedo).
    pub ambient: f32,
    /// Blinn-Phong specular strength (0 = pure Lambert). Specular is white, not albedo-tinted.
    pub specular: f32,
    /// Blinn-Phong exponent.
    pub shininess: f32,
    /// Exposure in stops: the result is multiplied by `2^exposure_ev` before sRGB encoding.
    pub exposure_ev: f32,
}

impl Default for Shading {
    fn default() -> Self {
        Self {
            lights: vec![Light::white([-0.5, 0.6, 0.8])],
            ambient: 0.08,
            specular: 0.25,
            shininess: 40.0,
            exposure_ev: 0.0,
        }
    }
}

impl Shading {
    /// Checks the parameters (finite, non-negative, lights with a direction).
    pub fn validate(&self) -> Result<(), RgbnError> {
        for (i, l) in self.lights.iter().enumerate() {
            let len2: f32 = l.direction.iter().map(|v| v * v).sum();
            if !(len2.is_finite() && len2 > 1e-12) {
                return Err(RgbnError::param(
                    format!("light[{i}].direction"),
                    format!(
                        "{:?} has no direction (give x,y,z not all zero)",
                        l.direction
                    ),
                ));
            }
            if l.color.iter().any(|c| !c.is_finite() || *c < 0.0) {
                return Err(RgbnError::param(
                    format!("light[{i}].color"),
                    "must be finite and ≥ 0",
                ));
            }
        }
        for (name, v) in [
            ("ambient", self.ambient),
            ("specular", self.specular),
            ("shininess", self.shininess),
        ] {
            if !v.is_finite() || v < 0.0 {
                return Err(RgbnError::param(
                    name,
                    format!("{v} must be finite and ≥ 0"),
                ));
            }
        }
        if !self.exposure_ev.is_finite() || self.exposure_ev.abs() > 32.0 {
            return Err(RgbnError::param("exposure", "must be within ±32 stops"));
        }
        Ok(())
    }
}

crate::choice_enum! {
    /// The view a render produces. Adding a view: a variant here (its doc is its documentation
    /// in `rgbn render --help`, `rgbn ops` and the editor), a parameter group in
    /// [`InspectParams`] (with its prefix in [`InspectParams::prefix`]), an arm in
    /// [`render_with_into`] and the function it calls.
    #[derive(serde::Serialize, serde::Deserialize)]
    pub enum View {
        /// Relit with the shading (Lambert + Blinn-Phong).
        Relit = "relit",
        /// Albedo (colour) only.
        Albedo = "albedo",
        /// Normals encoded (n+1)/2 (no sRGB curve, as normal maps are stored).
        Normals = "normals",
        /// Curl of the gradient field, blue (negative) – white – red (positive).
        Curl = "curl",
        /// Mean curvature H = ½ div n in 1/px, red (convex) – white – blue (concave), saturating
        /// at ±1/curvature_scale (0 = automatic: the 99th percentile of |H|).
        Curvature = "curvature",
        /// Exaggerated shading (Rusinkiewicz, Burns & DeCarlo 2006): each scale of the normals
        /// lit relative to the next coarser one, clamped cosines summed with per-scale weights.
        Exaggerated = "exaggerated",
        /// Radiance scaling (Vergne et al. 2010): the relit picture brightened where the surface
        /// is convex and darkened where it is concave, with strength radiance_alpha.
        RadianceScaling = "radiance_scaling",
        /// Specular enhancement (RTIViewer; Malzbender et al. 2001): albedo removed, a grey
        /// material kd·(n·l) + ks·(n·h)^α with a strong, tight highlight that shows fine relief.
        SpecularEnhancement = "specular_enhancement",
        /// Normal unsharp masking (RTIViewer): the normals' detail amplified,
        /// n' = normalize(n + gain·(n − G_σ∗n)), then relit with the shading (albedo kept).
        NormalUnsharp = "normal_unsharp",
        /// Toon shading: Lambert quantised into toon_levels bands times albedo, with black
        /// outlines near silhouettes and at strong curvature.
        Toon = "toon",
        /// Line drawing: ridges and valleys (local extrema of |H| above a threshold) and
        /// contour-like lines (n_z small), black on white.
        Lines = "lines",
        /// Horizon-based ambient occlusion (Bavoil et al. 2008) on the height integrated from
        /// the normals: cavities dark, open surface white; independent of the lights.
        AmbientOcclusion = "ambient_occlusion",
        /// Multi-light detail enhancement (RTIViewer; Fattal et al. 2007): grey shading under
        /// multi_lights virtual lights, the mean base plus the per-pixel strongest detail ×
        /// multi_gain; independent of the shading's lights.
        MultiLight = "multi_light",
    }
}

impl View {
    /// Every view, in menu order.
    pub const ALL: &'static [View] = <View as Choice>::ALL;

    /// Its name (`rgbn render --view NAME`, graph files, menus).
    #[must_use]
    pub fn name(self) -> &'static str {
        <View as Choice>::name(self)
    }

    /// One-line documentation.
    #[must_use]
    pub fn doc(self) -> &'static str {
        <View as Choice>::doc(self)
    }

    /// True when the view uses the shading's lights (the editor then shows the light controls).
    #[must_use]
    pub fn lit(self) -> bool {
        !matches!(
            self,
            View::Albedo
                | View::Normals
                | View::Curl
                | View::Curvature
                | View::Lines
                | View::AmbientOcclusion
                | View::MultiLight
        )
    }
}

impl std::str::FromStr for View {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        View::from_name(s).ok_or_else(|| {
            let names = View::names().join(", ");
            match crate::params::nearest(s, View::names()) {
                Some(n) => format!("unknown view {s:?} (did you mean {n:?}? views: {names})"),
                None => format!("unknown view {s:?} (views: {names})"),
            }
        })
    }
}

/// Renders `view` of `img` as sRGB RGBA8, with the default view parameters.
pub fn render(img: &RgbnImage, view: View, shading: &Shading) -> Result<Vec<u8>, RgbnError> {
    render_with(img, view, shading, &InspectParams::default())
}

/// Renders `view` of `img` as sRGB RGBA8 with the view parameters `params` (checked: a value
/// out of range is an error naming the parameter).
pub fn render_with(
    img: &RgbnImage,
    view: View,
    shading: &Shading,
    params: &InspectParams,
) -> Result<Vec<u8>, RgbnError> {
    let mut out = buf::zeroed_u8(img.len() * 4);
    render_with_into(img, view, shading, params, &mut out)?;
    Ok(out)
}

/// [`render`] into `out` (`4 · width · height` bytes), e.g. straight into a texture's pixels.
/// The relit and albedo views of a masked image carry coverage in alpha (not premultiplied);
/// normals and curl are opaque; the inspection views document their alpha.
pub fn render_into(
    img: &RgbnImage,
    view: View,
    shading: &Shading,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    render_with_into(img, view, shading, &InspectParams::default(), out)
}

/// [`render_with`] into `out` (`4 · width · height` bytes).
pub fn render_with_into(
    img: &RgbnImage,
    view: View,
    shading: &Shading,
    params: &InspectParams,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    check_output_len(img, out, "render")?;
    if view != View::Relit && view.lit() {
        shading.validate()?;
    }
    params.validate()?;
    match view {
        View::Relit => relight_into(img, shading, out)?,
        View::Albedo => albedo_into(img, out),
        View::Normals => normals_as_color_into(img, out),
        View::Curl => curl_map_into(&GradientField::from_normals(img), None, out),
        View::Curvature => {
            curvature::curvature_into(img, params, out);
        }
        View::Exaggerated => npr::exaggerated_into(img, shading, params, out),
        View::RadianceScaling => npr::radiance_scaling_into(img, shading, params, out)?,
        View::Toon => npr::toon_into(img, shading, params, out),
        View::Lines => npr::lines_into(img, params, out),
        View::SpecularEnhancement => {
            rti::specular_enhancement_into(img, shading, params, out)?;
        }
        View::NormalUnsharp => rti::normal_unsharp_into(img, shading, params, out)?,
        View::AmbientOcclusion => {
            occlusion::ambient_occlusion_into(img, shading, params, out)?;
        }
        View::MultiLight => rti::multi_light_into(img, shading, params, out)?,
    }
    Ok(())
}

/// Refuses an RGBA8 output slice that does not hold exactly `img`'s pixels.
fn check_output_len(img: &RgbnImage, out: &[u8], what: &str) -> Result<(), RgbnError> {
    if out.len() == img.len() * 4 {
        return Ok(());
    }
    Err(RgbnError::InvalidImage(format!(
        "{what} output holds {} bytes; a {}×{} image needs {}",
        out.len(),
        img.width(),
        img.height(),
        img.len() * 4
    )))
}

/// Lambert + Blinn-Phong relighting with the viewer at `+z` (orthographic), to sRGB RGBA8.
/// Masked-out pixels (coverage 0) are transparent black.
///
/// `out = 2^ev · (albedo · (ambient + Σ cᵢ max(0, n·lᵢ)) + ks · Σ cᵢ max(0, n·hᵢ)^shininess)`,
/// specular only where `n·lᵢ > 0`.
pub fn relight(img: &RgbnImage, shading: &Shading) -> Result<Vec<u8>, RgbnError> {
    let mut out = buf::zeroed_u8(img.len() * 4);
    relight_into(img, shading, &mut out)?;
    Ok(out)
}

/// [`relight`] into `out` (`4 · width · height` bytes, RGBA8): lets a caller that relights the
/// same image again and again reuse memory that is already mapped, or render straight into
/// its own pixel type (the editor preview's texture pixels).
pub fn relight_into(img: &RgbnImage, shading: &Shading, out: &mut [u8]) -> Result<(), RgbnError> {
    relight_scaled_into(img, shading, None, out)
}

/// [`relight_into`] with the linear result of pixel `i` multiplied by `scale[i]` before the
/// sRGB curve (radiance scaling); `None` is a scale of 1.
fn relight_scaled_into(
    img: &RgbnImage,
    shading: &Shading,
    scale: Option<&[f32]>,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    relight_twin_into(img, shading, scale, out, Simd::active())
}

/// [`relight_scaled_into`] running the twin of `simd` (clamped to what this CPU runs): the
/// tests compare every twin with the portable one.
fn relight_twin_into(
    img: &RgbnImage,
    shading: &Shading,
    scale: Option<&[f32]>,
    out: &mut [u8],
    simd: Simd,
) -> Result<(), RgbnError> {
    check_output_len(img, out, "relight")?;
    shading.validate()?;
    let lights: Vec<RelightLight> = shading
        .lights
        .iter()
        .map(|l| {
            let d = normalize3(l.direction);
            RelightLight {
                dir: d,
                half: normalize3([d[0], d[1], d[2] + 1.0]),
                color: l.color,
            }
        })
        .collect();
    let w = img.width();
    let [cr, cg, cb] = img.color();
    let [nx, ny, nz] = img.normal();
    let mask = img.mask();
    let k = RelightKernel {
        lights: &lights,
        ambient: shading.ambient,
        gain: 2f32.powf(shading.exposure_ev),
        ks: shading.specular,
        shininess: shading.shininess,
        srgb: srgb8_lut_encode(),
        simd: simd.clamped(),
    };
    out.par_chunks_mut(w.max(1) * 4)
        .enumerate()
        .for_each(|(row, orow)| {
            let r = row * w..(row + 1) * w;
            let rows = RelightRow {
                c: [&cr[r.clone()], &cg[r.clone()], &cb[r.clone()]],
                n: [&nx[r.clone()], &ny[r.clone()], &nz[r.clone()]],
                mask: mask.map(|m| &m[r.clone()]),
                scale: scale.map(|m| &m[r]),
            };
            k.row(&rows, orow);
        });
    Ok(())
}

/// One light of [`relight`]: unit direction, unit half vector (viewer at `+z`), colour.
struct RelightLight {
    dir: [f32; 3],
    half: [f32; 3],
    color: [f32; 3],
}

/// Per-image constants of [`relight`].
struct RelightKernel<'a> {
    lights: &'a [RelightLight],
    ambient: f32,
    gain: f32,
    ks: f32,
    shininess: f32,
    srgb: &'a [u8],
    /// The twin rows run (one this CPU has).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    simd: Simd,
}

/// One row of input planes.
struct RelightRow<'a> {
    c: [&'a [f32]; 3],
    n: [&'a [f32]; 3],
    mask: Option<&'a [f32]>,
    scale: Option<&'a [f32]>,
}

/// Pixels shaded together: the light loop runs over a chunk's lanes (vectorised), then the
/// sRGB table lookups and RGBA stores run per pixel.
const CHUNK: usize = 64;

/// `x^s` for `x ∈ [0, 1]`, `s ≥ 0` (`0^0 = 1`, as `powf`).
#[inline(always)]
fn pow_unit(x: f32, s: f32) -> f32 {
    exp2_fast(s * log2_fast(x.max(1e-30)))
}

impl RelightKernel<'_> {
    fn row(&self, rows: &RelightRow<'_>, out: &mut [u8]) {
        #[cfg(target_arch = "x86_64")]
        if self.simd >= Simd::Avx2 {
            // SAFETY: `row_avx2` only requires AVX2, which is present (`simd` is clamped to
            // the CPU).
            return unsafe { self.row_avx2(rows, out) };
        }
        self.row_portable(rows, out);
    }

    /// [`Self::row_portable`] compiled for AVX2 (no FMA: bit-identical results).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn row_avx2(&self, rows: &RelightRow<'_>, out: &mut [u8]) {
        self.row_portable(rows, out);
    }

    #[inline(always)]
    fn row_portable(&self, rows: &RelightRow<'_>, out: &mut [u8]) {
        let mut scratch = ChunkScratch {
            diff: [[0.0; CHUNK]; 3],
            spec: [[0.0; CHUNK]; 3],
            ndl_lit: [0.0; CHUNK],
            spec_lit: [0.0; CHUNK],
            idx: [[0; CHUNK]; 3],
        };
        for (c, px) in out.chunks_mut(4 * CHUNK).enumerate() {
            let r = c * CHUNK..c * CHUNK + px.len() / 4;
            let rows = RelightRow {
                c: rows.c.map(|p| &p[r.clone()]),
                n: rows.n.map(|p| &p[r.clone()]),
                mask: rows.mask.map(|m| &m[r.clone()]),
                scale: rows.scale.map(|m| &m[r.clone()]),
            };
            self.chunk(&rows, &mut scratch, px);
        }
    }

    /// Shades up to [`CHUNK`] pixels into `out` (4 bytes each).
    #[inline(always)]
    fn chunk(&self, rows: &RelightRow<'_>, sc: &mut ChunkScratch, out: &mut [u8]) {
        let m = (out.len() / 4).min(CHUNK);
        let (nx, ny, nz) = (&rows.n[0][..m], &rows.n[1][..m], &rows.n[2][..m]);
        if self.lights.is_empty() {
            for j in 0..3 {
                sc.diff[j][..m].fill(self.ambient);
                sc.spec[j][..m].fill(0.0);
            }
        }
        for (li, l) in self.lights.iter().enumerate() {
            let (d, hv) = (l.dir, l.half);
            let lanes = sc.ndl_lit[..m].iter_mut().zip(&mut sc.spec_lit[..m]);
            for ((nl, sl), ((&x, &y), &z)) in lanes.zip(nx.iter().zip(ny).zip(nz)) {
                let ndl = x * d[0] + y * d[1] + z * d[2];
                let ndh = (x * hv[0] + y * hv[1] + z * hv[2]).clamp(0.0, 1.0);
                let s = pow_unit(ndh, self.shininess);
                // Lambert clamp; the specular lobe only on the lit side.
                (*nl, *sl) = if ndl > 0.0 { (ndl, s) } else { (0.0, 0.0) };
            }
            for j in 0..3 {
                let lc = l.color[j];
                let acc = sc.diff[j][..m].iter_mut().zip(&mut sc.spec[j][..m]);
                let lit = sc.ndl_lit[..m].iter().zip(&sc.spec_lit[..m]);
                if li == 0 {
                    for ((dv, sv), (&nl, &sl)) in acc.zip(lit) {
                        *dv = self.ambient + lc * nl;
                        *sv = lc * sl;
                    }
                } else {
                    for ((dv, sv), (&nl, &sl)) in acc.zip(lit) {
                        *dv += lc * nl;
                        *sv += lc * sl;
                    }
                }
            }
        }
        for j in 0..3 {
            let terms = rows.c[j][..m]
                .iter()
                .zip(sc.diff[j][..m].iter().zip(&sc.spec[j][..m]));
            match rows.scale {
                None => {
                    for (o, (&cv, (&dv, &sv))) in sc.idx[j][..m].iter_mut().zip(terms) {
                        *o = srgb8_table_index(self.gain * (cv * dv + self.ks * sv));
                    }
                }
                Some(g) => {
                    let terms = terms.zip(&g[..m]);
                    for (o, ((&cv, (&dv, &sv)), &gv)) in sc.idx[j][..m].iter_mut().zip(terms) {
                        *o = srgb8_table_index(gv * (self.gain * (cv * dv + self.ks * sv)));
                    }
                }
            }
        }
        let alpha = |i: usize| match rows.mask {
            None => Some(255),
            Some(mk) if mk[i] <= 0.0 => None,
            Some(mk) => Some(u32::from((mk[i].min(1.0) * 255.0 + 0.5) as u8)),
        };
        pack_rgba(&sc.idx, alpha, self.srgb, &mut out[..4 * m]);
    }
}

/// Table index (into [`srgb8_lut_encode`]) of a linear value:
/// [`crate::raster::srgb::srgb8_index`] but rounding ties to even (through [`ROUND`], which
/// vectorises); [`pack_rgba`]'s mask keeps even a NaN's index inside the table.
#[inline(always)]
fn srgb8_table_index(v: f32) -> u32 {
    (v.clamp(0.0, 1.0) * (SRGB8_LUT_SIZE - 1) as f32 + ROUND).to_bits()
}

/// Writes `out.len() / 4 ≤ CHUNK` RGBA pixels: the sRGB bytes of the table indices `idx` and
/// `alpha(i)`, or transparent black where `alpha` is `None`. One 4-byte store per pixel.
#[inline(always)]
fn pack_rgba(
    idx: &[[u32; CHUNK]; 3],
    alpha: impl Fn(usize) -> Option<u32>,
    srgb: &[u8],
    out: &mut [u8],
) {
    let srgb = &srgb[..SRGB8_LUT_SIZE];
    let lookup = |j: usize, i: usize| u32::from(srgb[idx[j][i] as usize & (SRGB8_LUT_SIZE - 1)]);
    for (i, px) in out.chunks_exact_mut(4).take(CHUNK).enumerate() {
        let word = match alpha(i) {
            None => 0,
            Some(a) => lookup(0, i) | lookup(1, i) << 8 | lookup(2, i) << 16 | a << 24,
        };
        px.copy_from_slice(&word.to_le_bytes());
    }
}

/// Per-row working arrays of [`RelightKernel::chunk`] (allocated once per row, not per chunk).
struct ChunkScratch {
    diff: [[f32; CHUNK]; 3],
    spec: [[f32; CHUNK]; 3],
    ndl_lit: [f32; CHUNK],
    spec_lit: [f32; CHUNK],
    idx: [[u32; CHUNK]; 3],
}

fn normalize3(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

/// Albedo as sRGB RGBA8.
#[must_use]
pub fn albedo(img: &RgbnImage) -> Vec<u8> {
    let mut out = buf::zeroed_u8(img.len() * 4);
    albedo_into(img, &mut out);
    out
}

/// [`albedo`] into `out` (`4 · len` bytes).
fn albedo_into(img: &RgbnImage, out: &mut [u8]) {
    // Runs of 64 chunks per task; per chunk the table indices are computed lanes-wide.
    const RUN: usize = 64 * CHUNK;
    let srgb = srgb8_lut_encode();
    let color = img.color();
    let mask = img.mask();
    out.par_chunks_mut(4 * RUN)
        .enumerate()
        .for_each(|(k, run)| {
            let mut idx = [[0u32; CHUNK]; 3];
            for (c, px) in run.chunks_mut(4 * CHUNK).enumerate() {
                let start = k * RUN + c * CHUNK;
                let m = (px.len() / 4).min(CHUNK);
                for (ij, plane) in idx.iter_mut().zip(color) {
                    for (o, &v) in ij[..m].iter_mut().zip(&plane[start..start + m]) {
                        *o = srgb8_table_index(v);
                    }
                }
                let alpha = |i: usize| {
                    Some(mask.map_or(255, |mk| {
                        u32::from((mk[start + i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
                    }))
                };
                pack_rgba(&idx, alpha, srgb, px);
            }
        });
}

/// Normals encoded `(n+1)/2 · 255` (OpenGL convention), opaque.
#[must_use]
pub fn normals_as_color(img: &RgbnImage) -> Vec<u8> {
    let mut out = buf::zeroed_u8(img.len() * 4);
    normals_as_color_into(img, &mut out);
    out
}

fn normals_as_color_into(img: &RgbnImage, out: &mut [u8]) {
    let [x, y, z] = img.normal();
    let enc = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 127.5 + 0.5) as u8;
    map_pixels(out, |i| [enc(x[i]), enc(y[i]), enc(z[i]), 255]);
}

/// The curl map, blue (−) – white (0) – red (+), saturating at ±`scale` (default: 4 × RMS
/// curl, so that a field with curl only at rounding level shows white).
#[must_use]
pub fn curl_map(g: &GradientField, scale: Option<f32>) -> Vec<u8> {
    let mut out = buf::zeroed_u8(g.width * g.height * 4);
    curl_map_into(g, scale, &mut out);
    out
}

fn curl_map_into(g: &GradientField, scale: Option<f32>, out: &mut [u8]) {
    let c = g.curl();
    let stats = g.curl_stats(None);
    let s = scale.unwrap_or((4.0 * stats.rms_curl) as f32).max(1e-6);
    let d = c.data();
    map_pixels(out, |i| {
        let t = (d[i] / s).clamp(-1.0, 1.0);
        let fade = ((1.0 - t.abs()) * 255.0 + 0.5) as u8;
        if t >= 0.0 {
            [255, fade, fade, 255]
        } else {
            [fade, fade, 255, 255]
        }
    });
}

/// Fills RGBA8 `out` with `f(pixel index)`, in parallel.
fn map_pixels(out: &mut [u8], f: impl Fn(usize) -> [u8; 4] + Sync) {
    out.par_chunks_mut(4 * 4096).enumerate().for_each(|(c, o)| {
        for (k, px) in o.chunks_exact_mut(4).enumerate() {
            px.copy_from_slice(&f(c * 4096 + k));
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::srgb::linear_to_srgb;

    #[test]
    fn every_relight_twin_equals_the_portable_one() {
        // The twins are the portable row compiled with wider instructions and no fused
        // multiply-adds: the same bytes, on a sphere with a mask, three lights with specular,
        // radiance scaling, and widths around the 64-pixel chunk.
        for w in [1, 63, 64, 65, 200] {
            let h = 37;
            let (mut img, _) = crate::raster::sample::Surface::Sphere {
                radius_px: 0.45 * w.min(h) as f64,
            }
            .render(w, h);
            let mask: Vec<f32> = (0..w * h)
                .map(|i| f32::from(u8::from(i % 5 != 0)))
                .collect();
            img.set_mask(Some(mask)).unwrap();
            let s = Shading {
                lights: vec![
                    Light::white([0.3, 0.5, 0.8]),
                    Light::white([-0.6, 0.1, 0.7]),
                    Light::white([0.0, -0.9, 0.3]),
                ],
                ambient: 0.05,
                specular: 0.4,
                shininess: 24.0,
                exposure_ev: 0.5,
            };
            let scale: Vec<f32> = (0..w * h).map(|i| 0.5 + (i % 7) as f32 / 7.0).collect();
            for sc in [None, Some(scale.as_slice())] {
                let mut want = vec![0u8; 4 * w * h];
                relight_twin_into(&img, &s, sc, &mut want, Simd::Portable).unwrap();
                // Not all one colour: the comparison sees shading.
                assert!(want.chunks(4).any(|p| p[0] != want[0]));
                for simd in Simd::supported_levels() {
                    let mut got = vec![0u8; 4 * w * h];
                    relight_twin_into(&img, &s, sc, &mut got, simd).unwrap();
                    assert_eq!(got, want, "{w}×{h}, {simd} twin, scaled {}", sc.is_some());
                }
            }
        }
    }

    #[test]
    fn lambert_matches_cosine_law() {
        // Flat surface facing the viewer, light at 60° from the normal: diffuse = cos 60° = 0.5.
        let img = RgbnImage::flat(3, 2, [1.0, 0.5, 0.25]);
        let th = 60f32.to_radians();
        let s = Shading {
            lights: vec![Light::white([th.sin(), 0.0, th.cos()])],
            ambient: 0.0,
            specular: 0.0,
            shininess: 1.0,
            exposure_ev: 1.0,
        };
        let px = relight(&img, &s).unwrap();
        let want = |lin: f32| (linear_to_srgb(lin) * 255.0).round() as i32;
        // exposure +1 stop doubles: 2 · 0.5 · albedo
        assert!((i32::from(px[0]) - want(1.0)).abs() <= 1);
        assert!((i32::from(px[1]) - want(0.5)).abs() <= 1);
        assert!((i32::from(px[2]) - want(0.25)).abs() <= 1);
        assert_eq!(px[3], 255);
    }

    #[test]
    fn specular_peaks_at_the_half_vector() {
        // Light straight on: h = n = (0,0,1) → spec = ks · 1; with albedo 0 only specular shows.
        let img = RgbnImage::flat(1, 1, [0.0; 3]);
        let s = Shading {
            lights: vec![Light::white([0.0, 0.0, 1.0])],
            ambient: 0.0,
            specular: 0.5,
            shininess: 64.0,
            exposure_ev: 0.0,
        };
        let px = relight(&img, &s).unwrap();
        let want = (linear_to_srgb(0.5) * 255.0).round() as i32;
        assert!((i32::from(px[0]) - want).abs() <= 1, "{px:?}");
        // tilted normal by 20°: (cos 10°)^64 with h halfway → compare to the formula
        let mut img = RgbnImage::flat(1, 1, [0.0; 3]);
        let t = 20f32.to_radians();
        img.normal_mut()[0][0] = t.sin();
        img.normal_mut()[2][0] = t.cos();
        let px = relight(&img, &s).unwrap();
        let lin = 0.5 * t.cos().powf(64.0);
        let want = (linear_to_srgb(lin) * 255.0).round() as i32;
        assert!((i32::from(px[0]) - want).abs() <= 1, "{px:?} vs {want}");
    }

    #[test]
    fn light_from_the_left_lights_left_facing_slopes() {
        // A sphere lit from the left (−x): its left half is brighter than its right half.
        let (img, _) = crate::raster::sample::Surface::Sphere { radius_px: 30.0 }.render(64, 64);
        let s = Shading {
            lights: vec![Light::white([-1.0, 0.0, 0.3])],
            ..Shading::default()
        };
        let px = relight(&img, &s).unwrap();
        let lum = |x: usize| u32::from(px[(32 * 64 + x) * 4]);
        assert!(lum(32 - 20) > lum(32 + 20) + 50);
    }

    #[test]
    fn fast_log2_and_exp2_agree_with_std() {
        // Every 97th float in [1e-30, 1] for log2; y in [-126, 0] for exp2; x^s for the
        // exponents a user types.
        let mut worst = [0.0f64; 3];
        let mut bits = 1e-30f32.to_bits();
        while bits <= 1f32.to_bits() {
            let x = f32::from_bits(bits);
            let want = f64::from(x).log2();
            // absolute near 1, relative for large |log2| (where f32 itself has ulp ~ 8e-6)
            let err = (f64::from(log2_fast(x)) - want).abs() / want.abs().max(1.0);
            worst[0] = worst[0].max(err);
            bits += 97;
        }
        for i in 0..=1_260_000 {
            let y = -(i as f32) * 1e-4;
            let want = 2f64.powf(f64::from(y));
            worst[1] = worst[1].max((f64::from(exp2_fast(y)) - want).abs() / want);
        }
        for s in [0.0f32, 0.5, 1.0, 8.0, 32.0, 40.0, 200.0] {
            for i in 0..=10_000 {
                let x = i as f32 / 10_000.0;
                let want = f64::from(x).powf(f64::from(s));
                worst[2] = worst[2].max((f64::from(pow_unit(x, s)) - want).abs());
            }
        }
        assert!(worst[0] < 3e-7, "log2 error {}", worst[0]);
        assert!(worst[1] < 5e-7, "exp2 rel error {}", worst[1]);
        // x^s on [0, 1]: 1.8e-7 measured; an 8-bit level is 4e-3.
        assert!(worst[2] < 2e-6, "pow abs error {}", worst[2]);
    }

    #[test]
    fn relight_matches_the_formula_in_f64_within_one_level() {
        // Random normals (front-facing), albedo, 1–3 coloured lights, a mask with zero, partial
        // and full coverage, odd width (chunks end mid-row): every channel within 1 level of
        // the formula evaluated in f64 with powf and the exact sRGB curve.
        let (w, h) = (203, 7);
        let mut img = RgbnImage::flat(w, h, [0.5; 3]);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let n = w * h;
        let mut normal = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut color = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut mask = vec![0.0; n];
        for i in 0..n {
            let v = [rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd() + 0.05];
            let v = normalize3(v);
            for j in 0..3 {
                normal[j][i] = v[j];
                color[j][i] = rnd();
            }
            mask[i] = [0.0, 0.3, 1.0][i % 3];
        }
        *img.normal_mut() = normal.clone();
        img.set_color(color.clone()).unwrap();
        img.set_mask(Some(mask.clone())).unwrap();
        for (k, nl) in [1usize, 2, 3].into_iter().enumerate() {
            let lights: Vec<Light> = (0..nl)
                .map(|_| Light {
                    direction: [rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd()],
                    color: [rnd(), rnd(), rnd()],
                })
                .collect();
            let s = Shading {
                lights,
                ambient: 0.05 * k as f32,
                specular: 0.4,
                shininess: [40.0, 7.5, 120.0][k],
                exposure_ev: [0.0, 0.5, -1.0][k],
            };
            let px = relight(&img, &s).unwrap();
            let gain = 2f64.powf(f64::from(s.exposure_ev));
            for i in 0..n {
                let got = &px[i * 4..i * 4 + 4];
                if mask[i] <= 0.0 {
                    assert_eq!(got, [0, 0, 0, 0]);
                    continue;
                }
                let nv = [0, 1, 2].map(|j| f64::from(normal[j][i]));
                let mut lin = [f64::from(s.ambient); 3];
                let mut spec = [0.0f64; 3];
                for l in &s.lights {
                    let d = l.direction.map(f64::from);
                    let dl = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    let d = d.map(|v| v / dl);
                    let hv = [d[0], d[1], d[2] + 1.0];
                    let hl = (hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2]).sqrt();
                    let ndl = nv[0] * d[0] + nv[1] * d[1] + nv[2] * d[2];
                    let ndh =
                        ((nv[0] * hv[0] + nv[1] * hv[1] + nv[2] * hv[2]) / hl).clamp(0.0, 1.0);
                    if ndl > 0.0 {
                        for j in 0..3 {
                            lin[j] += f64::from(l.color[j]) * ndl;
                            spec[j] += f64::from(l.color[j]) * ndh.powf(f64::from(s.shininess));
                        }
                    }
                }
                for j in 0..3 {
                    let v =
                        gain * (f64::from(color[j][i]) * lin[j] + f64::from(s.specular) * spec[j]);
                    let want = (linear_to_srgb(v.clamp(0.0, 1.0) as f32) * 255.0).round() as i32;
                    assert!(
                        (i32::from(got[j]) - want).abs() <= 1,
                        "pixel {i} channel {j}: {} vs {want} (lights {nl})",
                        got[j]
                    );
                }
                assert_eq!(got[3], (mask[i].min(1.0) * 255.0 + 0.5) as u8);
            }
        }
    }

    #[test]
    fn relight_into_overwrites_a_used_buffer_and_checks_its_size() {
        let (a, _) = crate::raster::sample::Surface::Sphere { radius_px: 20.0 }.render(48, 40);
        let s = Shading::default();
        let mut out = vec![7u8; 48 * 40 * 4];
        relight_into(&a, &s, &mut out).unwrap();
        assert_eq!(out, relight(&a, &s).unwrap());
        let err = relight_into(&a, &s, &mut out[4..]).unwrap_err().to_string();
        assert!(err.contains("48×40"), "{err}");
    }

    #[test]
    fn albedo_is_the_srgb_of_the_colour_with_the_mask_as_alpha() {
        // 70×67 = 4690 pixels: more than one task's run (4096) and a partial chunk.
        let (w, h) = (70, 67);
        let mut img = RgbnImage::flat(w, h, [0.0; 3]);
        let n = w * h;
        let ramp = |k: usize| (0..n).map(move |i| ((i * (k + 3)) % 1000) as f32 / 900.0 - 0.05);
        img.set_color([ramp(0).collect(), ramp(1).collect(), ramp(2).collect()])
            .unwrap();
        let mask: Vec<f32> = (0..n).map(|i| (i % 7) as f32 / 6.0).collect();
        img.set_mask(Some(mask.clone())).unwrap();
        let px = albedo(&img);
        for i in 0..n {
            for j in 0..3 {
                let v = img.color()[j][i].clamp(0.0, 1.0);
                let want = (linear_to_srgb(v) * 255.0).round() as i32;
                assert!((i32::from(px[4 * i + j]) - want).abs() <= 1, "pixel {i}");
            }
            assert_eq!(px[4 * i + 3], (mask[i] * 255.0 + 0.5) as u8, "alpha {i}");
        }
    }

    #[test]
    fn zero_light_direction_is_an_error_not_nan() {
        let img = RgbnImage::flat(1, 1, [1.0; 3]);
        let s = Shading {
            lights: vec![Light::white([0.0, 0.0, 0.0])],
            ..Shading::default()
        };
        assert!(relight(&img, &s).is_err());
    }
}
