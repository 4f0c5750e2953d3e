//! The `ambient_occlusion` inspection view: horizon-based ambient occlusion (Bavoil, Sainz &
//! Dimitrov 2008, "Image-space horizon-based ambient occlusion", HBAO) on the height integrated
//! from the normals.

use super::rti::write_linear_rgb;
use super::InspectParams;
use super::{check_output_len, Shading};
use crate::error::RgbnError;
use crate::raster::integrate::{integrate_normals, IntegrateParams, IntegrationMethod};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// Most samples marched per direction; a larger radius spaces them further apart.
const MAX_STEPS: usize = 32;

/// The ambient-occlusion factor per pixel, in [0, 1] (1 = unoccluded), of
/// [`ambient_occlusion_into`].
///
/// 1. The normals are integrated to a height `z` in pixels with
///    [`crate::raster::integrate::integrate_normals`]: Poisson/DCT without a mask, the masked
///    Poisson solver (only edges inside the mask) with one; then multiplied by `ao_depth`.
/// 2. Per pixel, `ao_directions` directions `θₖ = 2πk/N` (image frame, `y` up) are marched
///    out to `ao_radius` px in `min(⌈radius⌉, 32)` even steps, sampling `z` bilinearly; a
///    direction stops at the image border or where a sample touches a pixel outside the mask
///    (coverage < 0.5).
/// 3. As HBAO: the horizon angle `hₖ` is the largest elevation `atan(Δz / s)` seen, starting
///    from the surface's tangent angle `tₖ` along that direction (`tan tₖ` = the central
///    difference of `z` over ±1 px, one-sided at a border), so a direction contributes
///    `sin hₖ − sin tₖ ≥ 0`, 0 for any plane, tilted or not.
/// 4. `occlusion = 1 − clamp(mean_k (sin hₖ − sin tₖ), 0, 1)`.
///
/// Simplifications of Bavoil et al.: no distance attenuation `W(r)` and no per-pixel jitter
/// of the directions (the result is deterministic).
///
/// # Errors
/// Parameters out of range, or a mask with no pixel inside.
pub fn ambient_occlusion(img: &RgbnImage, p: &InspectParams) -> Result<Plane, RgbnError> {
    p.validate()?;
    let (w, h) = (img.width(), img.height());
    let mask = img.mask();
    let ip = IntegrateParams {
        method: if mask.is_some() {
            IntegrationMethod::MaskedPoisson
        } else {
            IntegrationMethod::PoissonDct
        },
        max_iterations: 1000,
        tolerance: 1e-4,
        ..IntegrateParams::default()
    };
    let (mut z, _) = integrate_normals(img, &ip)?;
    let depth = p.ao_depth as f32;
    z.data_mut().par_iter_mut().for_each(|v| *v *= depth);
    let zd = z.data();
    let field = HeightField { z: zd, w, h, mask };
    let dirs: Vec<[f32; 2]> = (0..p.ao_directions)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / p.ao_directions as f64;
            // (column, row) step: y up is row down.
            [a.cos() as f32, -a.sin() as f32]
        })
        .collect();
    let radius = p.ao_radius as f32;
    let steps = (radius.ceil() as usize).clamp(1, MAX_STEPS);
    let mut ao = vec![1.0f32; w * h];
    ao.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(r, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                *o = field.occlusion(x, r, &dirs, radius, steps);
            }
        });
    Plane::from_vec(w, h, ao)
}

/// The integrated height with its domain.
struct HeightField<'a> {
    z: &'a [f32],
    w: usize,
    h: usize,
    mask: Option<&'a [f32]>,
}

impl HeightField<'_> {
    fn inside(&self, i: usize) -> bool {
        self.mask.is_none_or(|m| m[i] >= 0.5)
    }

    /// Bilinear height at column `fx`, row `fr`; `None` outside the image or where any of the
    /// four pixels is outside the mask.
    fn sample(&self, fx: f32, fr: f32) -> Option<f32> {
        let (w, h) = (self.w, self.h);
        if !(fx >= 0.0 && fr >= 0.0 && fx <= (w - 1) as f32 && fr <= (h - 1) as f32) {
            return None;
        }
        let x0 = (fx as usize).min(w.saturating_sub(2));
        let r0 = (fr as usize).min(h.saturating_sub(2));
        let (x1, r1) = ((x0 + 1).min(w - 1), (r0 + 1).min(h - 1));
        let (tx, tr) = (fx - x0 as f32, fr - r0 as f32);
        let idx = [r0 * w + x0, r0 * w + x1, r1 * w + x0, r1 * w + x1];
        if !idx.iter().all(|&i| self.inside(i)) {
            return None;
        }
        let z = idx.map(|i| self.z[i]);
        let top = z[0] + (z[1] - z[0]) * tx;
        let bottom = z[2] + (z[3] - z[2]) * tx;
        Some(top + (bottom - top) * tr)
    }

    /// The occlusion factor at pixel `(x, r)` (see [`ambient_occlusion`]).
    fn occlusion(&self, x: usize, r: usize, dirs: &[[f32; 2]], radius: f32, steps: usize) -> f32 {
        if !self.inside(r * self.w + x) {
            return 1.0;
        }
        let (fx, fr) = (x as f32, r as f32);
        let z0 = self.z[r * self.w + x];
        let sin_of = |dz: f32, s: f32| dz / (dz * dz + s * s).sqrt();
        let mut total = 0.0f32;
        for d in dirs {
            let ahead = self.sample(fx + d[0], fr + d[1]);
            let behind = self.sample(fx - d[0], fr - d[1]);
            let tan_t = match (ahead, behind) {
                (Some(a), Some(b)) => 0.5 * (a - b),
                (Some(a), None) => a - z0,
                (None, Some(b)) => z0 - b,
                (None, None) => 0.0,
            };
            let sin_t = sin_of(tan_t, 1.0);
            let mut sin_h = sin_t;
            for j in 1..=steps {
                let s = radius * j as f32 / steps as f32;
                let Some(zs) = self.sample(fx + s * d[0], fr + s * d[1]) else {
                    break;
                };
                sin_h = sin_h.max(sin_of(zs - z0, s));
            }
            total += sin_h - sin_t;
        }
        1.0 - (total / dirs.len() as f32).clamp(0.0, 1.0)
    }
}

/// The **ambient_occlusion** view: [`ambient_occlusion`]'s factor as grey (times the albedo
/// when `ao_albedo`), sRGB-encoded, alpha = mask coverage. It shows cavities — pits, grooves,
/// incisions — independently of the lights: the shading is not used (`_shading` keeps the
/// signature of the other views).
///
/// # Errors
/// An output of the wrong size, parameters out of range, an empty mask.
pub fn ambient_occlusion_into(
    img: &RgbnImage,
    _shading: &Shading,
    p: &InspectParams,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    check_output_len(img, out, "ambient_occlusion")?;
    let ao = ambient_occlusion(img, p)?;
    let a = ao.data();
    let c = img.color();
    let albedo = p.ao_albedo;
    write_linear_rgb(out, img.mask(), |i| {
        if albedo {
            [c[0][i] * a[i], c[1][i] * a[i], c[2][i] * a[i]]
        } else {
            [a[i]; 3]
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::gradient::normal_of_gradient;
    use crate::raster::sample::Surface;

    /// An image whose normals are those of slope `(p, q)(u, v)` (`u` right, `v` up from the
    /// centre).
    fn from_slope(w: usize, h: usize, slope: impl Fn(f64, f64) -> [f64; 2]) -> RgbnImage {
        let mut img = RgbnImage::flat(w, h, [0.5; 3]);
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        for i in 0..w * h {
            let (u, v) = ((i % w) as f64 - cx, cy - (i / w) as f64);
            let [p, q] = slope(u, v);
            let n = normal_of_gradient(p as f32, q as f32);
            for (j, plane) in img.normal_mut().iter_mut().enumerate() {
                plane[i] = n[j];
            }
        }
        img
    }

    fn render(img: &RgbnImage, p: &InspectParams) -> Vec<u8> {
        let mut out = vec![0; img.len() * 4];
        ambient_occlusion_into(img, &Shading::default(), p, &mut out).unwrap();
        out
    }

    #[test]
    fn a_plane_is_unoccluded_tilted_or_not_masked_or_not() {
        let p = InspectParams::default();
        for slope in [[0.0, 0.0], [0.4, -0.7], [-1.5, 0.2]] {
            let mut img = from_slope(41, 29, |_, _| slope);
            let px = render(&img, &p);
            assert!(px.iter().all(|&v| v == 255), "{slope:?}");
            let ao = ambient_occlusion(&img, &p).unwrap();
            assert!(ao.data().iter().all(|&a| a > 0.999), "{slope:?}");
            // A mask with a hole: still a plane inside.
            let mask: Vec<f32> = (0..img.len())
                .map(|i| {
                    let (x, r) = (i % 41, i / 41);
                    f32::from(u8::from(!(15..25).contains(&x) || !(10..18).contains(&r)))
                })
                .collect();
            img.set_mask(Some(mask.clone())).unwrap();
            let px = render(&img, &p);
            for (i, c) in px.chunks_exact(4).enumerate() {
                let want = if mask[i] > 0.0 { [255; 4] } else { [0; 4] };
                assert_eq!(c, want, "{slope:?} pixel {i}");
            }
        }
    }

    /// A paraboloid pit of radius `rad` and depth `depth` in a flat plane.
    fn pit_height(u: f64, v: f64, rad: f64, depth: f64) -> f64 {
        let r2 = (u * u + v * v) / (rad * rad);
        if r2 < 1.0 {
            -depth * (1.0 - r2)
        } else {
            0.0
        }
    }

    #[test]
    fn a_pit_is_darker_at_its_centre_than_at_its_rim_as_hbao_by_hand() {
        let (size, rad, depth) = (64usize, 14.0, 7.0);
        let img = pit(size, rad, depth);
        let p = InspectParams::default();
        let ao = ambient_occlusion(&img, &p).unwrap();
        let c = size / 2;
        let at = |x: usize, r: usize| ao.data()[r * size + x];
        let centre = at(c, c);
        let rim = at(c + 15, c);
        assert!(centre < rim - 0.3, "centre {centre}, rim {rim}");
        // The same horizon search on the analytic height (f64, exact samples, flat tangent
        // at the centre).
        let n = p.ao_directions as usize;
        let steps = 16;
        let mut total = 0.0;
        for k in 0..n {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            let mut best = 0.0f64;
            for j in 1..=steps {
                let s = p.ao_radius * j as f64 / steps as f64;
                let dz = pit_height(s * a.cos(), s * a.sin(), rad, depth) + depth;
                best = best.max(dz / (dz * dz + s * s).sqrt());
            }
            total += best;
        }
        let want = 1.0 - total / n as f64;
        assert!(
            (f64::from(centre) - want).abs() < 0.05,
            "{centre} vs {want}"
        );
        // Rendered: darker in the middle, white far away.
        let px = render(&img, &p);
        assert!(px[(c * size + c) * 4] + 40 < px[(c * size + c + 15) * 4]);
        assert_eq!(px[0], 255);
    }

    fn pit(size: usize, rad: f64, depth: f64) -> RgbnImage {
        from_slope(size, size, |u, v| {
            if u * u + v * v < rad * rad {
                [2.0 * depth * u / (rad * rad), 2.0 * depth * v / (rad * rad)]
            } else {
                [0.0, 0.0]
            }
        })
    }

    #[test]
    fn ao_depth_is_the_same_as_a_deeper_relief() {
        // The slopes of a pit twice as deep are twice as large, so its integrated height is
        // twice as large: ao_depth = 2 on the shallow pit must give the deep pit's occlusion.
        let shallow = ambient_occlusion(
            &pit(48, 10.0, 2.0),
            &InspectParams {
                ao_depth: 2.0,
                ..InspectParams::default()
            },
        )
        .unwrap();
        let deep = ambient_occlusion(&pit(48, 10.0, 4.0), &InspectParams::default()).unwrap();
        let plain = ambient_occlusion(&pit(48, 10.0, 2.0), &InspectParams::default()).unwrap();
        let c = 24 * 48 + 24;
        assert!(shallow.data()[c] < plain.data()[c] - 0.1);
        for (a, b) in shallow.data().iter().zip(deep.data()) {
            assert!((a - b).abs() < 1e-3, "{a} vs {b}");
        }
    }

    #[test]
    fn a_dome_is_unoccluded() {
        // Convex everywhere: every horizon lies below the tangent.
        let (img, _) = Surface::Paraboloid { curvature: 0.01 }.render(48, 40);
        let ao = ambient_occlusion(&img, &InspectParams::default()).unwrap();
        let min = ao.data().iter().copied().fold(1.0f32, f32::min);
        assert!(min > 0.99, "{min}");
    }

    #[test]
    fn occlusion_stays_in_the_unit_interval_on_rough_relief() {
        let mut state = 12345u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f64 / (1u64 << 24) as f64 * 2.0 - 1.0
        };
        let slopes: Vec<[f64; 2]> = (0..40 * 30).map(|_| [3.0 * rnd(), 3.0 * rnd()]).collect();
        let img = from_slope(40, 30, |u, v| {
            let (x, r) = ((u + 20.0) as usize, (15.0 - v) as usize);
            slopes[r * 40 + x]
        });
        for dirs in [1, 3, 8] {
            let p = InspectParams {
                ao_radius: 5.0,
                ao_directions: dirs,
                ..InspectParams::default()
            };
            let ao = ambient_occlusion(&img, &p).unwrap();
            let (lo, hi) = ao
                .data()
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            assert!((0.0..=1.0).contains(&lo) && hi <= 1.0, "{lo} {hi}");
            assert!(lo < 0.8, "rough relief occludes somewhere ({lo})");
        }
    }

    #[test]
    fn albedo_option_multiplies_and_bad_parameters_are_named() {
        let img = from_slope(8, 8, |_, _| [0.0, 0.0]);
        let mut img2 = img.clone();
        img2.set_color([vec![0.5; 64], vec![0.25; 64], vec![0.0; 64]])
            .unwrap();
        let p = InspectParams {
            ao_albedo: true,
            ..InspectParams::default()
        };
        let px = render(&img2, &p);
        let lvl = |v: f32| crate::raster::srgb::linear_to_srgb8(v);
        assert_eq!(&px[..4], &[lvl(0.5), lvl(0.25), 0, 255]);
        let mut out = vec![0; 64 * 4];
        let bad = InspectParams {
            ao_directions: 0,
            ..InspectParams::default()
        };
        let e = ambient_occlusion_into(&img, &Shading::default(), &bad, &mut out)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ao_directions") && !e.contains('\n'), "{e}");
        let bad = InspectParams {
            ao_radius: 0.5,
            ..InspectParams::default()
        };
        let e = ambient_occlusion(&img, &bad).unwrap_err().to_string();
        assert!(e.contains("ao_radius"), "{e}");
    }

    #[test]
    fn the_view_renders_through_render_with() {
        use crate::render::{render_with, View};
        let img = from_slope(20, 16, |u, v| [0.05 * u, -0.02 * v]);
        let ip = InspectParams {
            ao_radius: 6.0,
            ..InspectParams::default()
        };
        let s = Shading::default();
        let mut want = vec![0; img.len() * 4];
        ambient_occlusion_into(&img, &s, &ip, &mut want).unwrap();
        assert_eq!(
            render_with(&img, View::AmbientOcclusion, &s, &ip).unwrap(),
            want
        );
        assert!(!View::AmbientOcclusion.lit());
    }
}
