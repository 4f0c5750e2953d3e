//! Turning an RGBN image into something to look at: relighting (Lambert + Blinn-Phong with
//! directional lights, ambient and exposure), normals as colour, albedo, and the curl map.
//! Every view produces sRGB 8-bit RGBA, row-major, row 0 at the top.

use crate::error::RgbnError;
use crate::raster::gradient::GradientField;
use crate::raster::io::{srgb8_index, srgb8_lut_encode, SRGB8_LUT_SIZE};
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

/// Entries of the specular power table (linearly interpolated).
const POW_LUT: usize = 2048;

/// The view a render produces.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum View {
    /// Relit with [`Shading`].
    #[default]
    Relit,
    /// Albedo (colour) only.
    Albedo,
    /// Normals encoded `(n+1)/2` (no sRGB curve, as normal maps are stored).
    Normals,
    /// Curl of the gradient field, blue (negative) – white – red (positive).
    Curl,
}

impl View {
    pub const ALL: [View; 4] = [View::Relit, View::Albedo, View::Normals, View::Curl];
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            View::Relit => "relit",
            View::Albedo => "albedo",
            View::Normals => "normals",
            View::Curl => "curl",
        }
    }
}

impl std::str::FromStr for View {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        View::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| format!("unknown view {s:?} (relit, albedo, normals, curl)"))
    }
}

/// Renders `view` of `img` as sRGB RGBA8.
pub fn render(img: &RgbnImage, view: View, shading: &Shading) -> Result<Vec<u8>, RgbnError> {
    Ok(match view {
        View::Relit => relight(img, shading)?,
        View::Albedo => albedo(img),
        View::Normals => normals_as_color(img),
        View::Curl => curl_map(&GradientField::from_normals(img), None),
    })
}

/// Lambert + Blinn-Phong relighting with the viewer at `+z` (orthographic), to sRGB RGBA8.
/// Masked-out pixels (coverage 0) are transparent black.
///
/// `out = 2^ev · (albedo · (ambient + Σ cᵢ max(0, n·lᵢ)) + ks · Σ cᵢ max(0, n·hᵢ)^shininess)`,
/// specular only where `n·lᵢ > 0`.
pub fn relight(img: &RgbnImage, shading: &Shading) -> Result<Vec<u8>, RgbnError> {
    shading.validate()?;
    let lights: Vec<([f32; 3], [f32; 3], [f32; 3])> = shading
        .lights
        .iter()
        .map(|l| {
            let d = normalize3(l.direction);
            let h = normalize3([d[0], d[1], d[2] + 1.0]);
            (d, h, l.color)
        })
        .collect();
    let gain = 2f32.powf(shading.exposure_ev);
    let ks = shading.specular;
    let pow_lut: Vec<f32> = (0..=POW_LUT)
        .map(|i| (i as f32 / POW_LUT as f32).powf(shading.shininess))
        .collect();
    let srgb = srgb8_lut_encode();
    let (w, h) = (img.width(), img.height());
    let [cr, cg, cb] = img.color();
    let [nx, ny, nz] = img.normal();
    let mask = img.mask();
    let k = RelightKernel {
        lights: &lights,
        ambient: shading.ambient,
        gain,
        ks,
        pow_lut: &pow_lut,
        srgb,
    };
    let mut out = vec![0u8; w * h * 4];
    out.par_chunks_mut(w.max(1) * 4)
        .enumerate()
        .for_each(|(row, orow)| {
            let r = row * w..(row + 1) * w;
            let rows = RelightRow {
                c: [&cr[r.clone()], &cg[r.clone()], &cb[r.clone()]],
                n: [&nx[r.clone()], &ny[r.clone()], &nz[r.clone()]],
                mask: mask.map(|m| &m[r]),
            };
            k.row(&rows, orow);
        });
    Ok(out)
}

/// Per-image constants of [`relight`].
struct RelightKernel<'a> {
    lights: &'a [([f32; 3], [f32; 3], [f32; 3])],
    ambient: f32,
    gain: f32,
    ks: f32,
    pow_lut: &'a [f32],
    srgb: &'a [u8],
}

/// One row of input planes.
struct RelightRow<'a> {
    c: [&'a [f32]; 3],
    n: [&'a [f32]; 3],
    mask: Option<&'a [f32]>,
}

impl RelightKernel<'_> {
    fn row(&self, rows: &RelightRow<'_>, out: &mut [u8]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: `row_avx2` only requires AVX2, whose presence was just checked.
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
        let [cr, cg, cb] = rows.c;
        let [nx, ny, nz] = rows.n;
        let w = out.len() / 4;
        let (cr, cg, cb, nx, ny, nz) = (&cr[..w], &cg[..w], &cb[..w], &nx[..w], &ny[..w], &nz[..w]);
        let pow_lut = &self.pow_lut[..=POW_LUT];
        let srgb = &self.srgb[..SRGB8_LUT_SIZE];
        // Table index of a linear value, as `srgb8_index` (i32 conversion vectorises; the
        // clamped value lies in [0, 16383.5], so the result is the same).
        let idx = |v: f32| -> usize {
            ((v.clamp(0.0, 1.0) * (SRGB8_LUT_SIZE - 1) as f32 + 0.5) as i32 as usize)
                .min(SRGB8_LUT_SIZE - 1)
        };
        for (x, px) in out.chunks_exact_mut(4).enumerate() {
            let cov = rows.mask.map_or(1.0, |m| m[x]);
            if cov <= 0.0 {
                px.copy_from_slice(&[0, 0, 0, 0]);
                continue;
            }
            let n = [nx[x], ny[x], nz[x]];
            let mut diff = [self.ambient; 3];
            let mut spec = [0.0f32; 3];
            for (d, hv, c) in self.lights {
                let ndl = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
                if ndl > 0.0 {
                    let ndh = (n[0] * hv[0] + n[1] * hv[1] + n[2] * hv[2]).clamp(0.0, 1.0);
                    let t = ndh * POW_LUT as f32;
                    let k = (t as i32 as usize).min(POW_LUT - 1);
                    let f = t - k as f32;
                    let s = pow_lut[k] + (pow_lut[k + 1] - pow_lut[k]) * f;
                    for j in 0..3 {
                        diff[j] += c[j] * ndl;
                        spec[j] += c[j] * s;
                    }
                }
            }
            let g = self.gain;
            px[0] = srgb[idx(g * (cr[x] * diff[0] + self.ks * spec[0]))];
            px[1] = srgb[idx(g * (cg[x] * diff[1] + self.ks * spec[1]))];
            px[2] = srgb[idx(g * (cb[x] * diff[2] + self.ks * spec[2]))];
            px[3] = (cov.min(1.0) * 255.0 + 0.5) as u8;
        }
    }
}

fn normalize3(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / l, v[1] / l, v[2] / l]
}

/// Albedo as sRGB RGBA8.
#[must_use]
pub fn albedo(img: &RgbnImage) -> Vec<u8> {
    let srgb = srgb8_lut_encode();
    let [r, g, b] = img.color();
    let mask = img.mask();
    map_pixels(img.width(), img.height(), |i| {
        let a = mask.map_or(255, |m| (m[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
        [
            srgb[srgb8_index(r[i])],
            srgb[srgb8_index(g[i])],
            srgb[srgb8_index(b[i])],
            a,
        ]
    })
}

/// Normals encoded `(n+1)/2 · 255` (OpenGL convention), opaque.
#[must_use]
pub fn normals_as_color(img: &RgbnImage) -> Vec<u8> {
    let [x, y, z] = img.normal();
    let enc = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 127.5 + 0.5) as u8;
    map_pixels(img.width(), img.height(), |i| {
        [enc(x[i]), enc(y[i]), enc(z[i]), 255]
    })
}

/// The curl map, blue (−) – white (0) – red (+), saturating at ±`scale` (default: 4 × RMS
/// curl, so that a field with curl only at rounding level shows white).
#[must_use]
pub fn curl_map(g: &GradientField, scale: Option<f32>) -> Vec<u8> {
    let c = g.curl();
    let stats = g.curl_stats(None);
    let s = scale.unwrap_or((4.0 * stats.rms_curl) as f32).max(1e-6);
    let d = c.data();
    map_pixels(g.width, g.height, |i| {
        let t = (d[i] / s).clamp(-1.0, 1.0);
        let fade = ((1.0 - t.abs()) * 255.0 + 0.5) as u8;
        if t >= 0.0 {
            [255, fade, fade, 255]
        } else {
            [fade, fade, 255, 255]
        }
    })
}

fn map_pixels(w: usize, h: usize, f: impl Fn(usize) -> [u8; 4] + Sync) -> Vec<u8> {
    let mut out = vec![0u8; w * h * 4];
    out.par_chunks_mut(4 * 4096).enumerate().for_each(|(c, o)| {
        for (k, px) in o.chunks_exact_mut(4).enumerate() {
            px.copy_from_slice(&f(c * 4096 + k));
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::io::linear_to_srgb;

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
    fn zero_light_direction_is_an_error_not_nan() {
        let img = RgbnImage::flat(1, 1, [1.0; 3]);
        let s = Shading {
            lights: vec![Light::white([0.0, 0.0, 0.0])],
            ..Shading::default()
        };
        assert!(relight(&img, &s).is_err());
    }
}
