//! Inspection views after RTIViewer (Cultural Heritage Imaging / ISTI-CNR) and Fattal et al.
//! 2007: [`specular_enhancement_into`], [`normal_unsharp_into`] and [`multi_light_into`].
//!
//! Every view writes sRGB RGBA8 (row 0 at the top) with alpha = mask coverage (not
//! premultiplied; pixels of coverage 0 are transparent black, as [`super::relight`]). Lights
//! and exposure come from the [`Shading`] unless a view says otherwise; each view's own
//! parameters are its group in [`InspectParams`] (`spec_*`, `unsharp_*`, `multi_*`), checked
//! against their declared ranges before anything is computed (a one-line error naming the
//! field).

use super::{check_output_len, normalize3, relight_into, InspectParams, Shading};
use crate::error::RgbnError;
use crate::raster::convolve::{gaussian, BorderMode};
use crate::raster::srgb::linear_to_srgb8;
use crate::raster::{buf, RgbnImage};
use rayon::prelude::*;

/// Writes one RGBA8 pixel per index from linear RGB `f(i)` (clamped to [0, 1], sRGB-encoded),
/// alpha = coverage; coverage ≤ 0 is transparent black (and `f` is not called). In parallel.
pub(crate) fn write_linear_rgb(
    out: &mut [u8],
    mask: Option<&[f32]>,
    f: impl Fn(usize) -> [f32; 3] + Sync,
) {
    const RUN: usize = 4096;
    out.par_chunks_mut(4 * RUN).enumerate().for_each(|(c, o)| {
        for (k, px) in o.chunks_exact_mut(4).enumerate() {
            let i = c * RUN + k;
            let alpha = match mask {
                None => 255,
                Some(m) if m[i] <= 0.0 => {
                    px.copy_from_slice(&[0; 4]);
                    continue;
                }
                Some(m) => (m[i].min(1.0) * 255.0 + 0.5) as u8,
            };
            let v = f(i);
            px.copy_from_slice(&[
                linear_to_srgb8(v[0]),
                linear_to_srgb8(v[1]),
                linear_to_srgb8(v[2]),
                alpha,
            ]);
        }
    });
}

/// Gaussian blur of `planes` (σ in px, mirrored borders). With a mask, a normalised
/// convolution over the covered pixels (coverage ≥ 0.5): `G∗(v·w) / G∗w`, so values outside the
/// object never leak in; pixels whose neighbourhood holds no covered pixel keep their value.
pub(crate) fn blur_planes(
    planes: &mut [Vec<f32>],
    w: usize,
    h: usize,
    sigma: f32,
    mask: Option<&[f32]>,
) {
    let Some(m) = mask else {
        planes
            .par_iter_mut()
            .for_each(|p| gaussian(p, w, h, sigma, BorderMode::Mirror));
        return;
    };
    let weight: Vec<f32> = (0..w * h)
        .into_par_iter()
        .map(|i| f32::from(u8::from(m[i] >= 0.5)))
        .collect();
    let mut wsum = weight.clone();
    gaussian(&mut wsum, w, h, sigma, BorderMode::Mirror);
    planes.par_iter_mut().for_each(|p| {
        let mut wp: Vec<f32> = p.iter().zip(&weight).map(|(v, k)| v * k).collect();
        gaussian(&mut wp, w, h, sigma, BorderMode::Mirror);
        for ((v, s), ws) in p.iter_mut().zip(&wp).zip(&wsum) {
            if *ws > 1e-6 {
                *v = s / ws;
            }
        }
    });
}

/// A light of the shading with its unit direction and unit half vector (viewer at `+z`).
struct UnitLight {
    dir: [f32; 3],
    half: [f32; 3],
    color: [f32; 3],
}

fn unit_lights(shading: &Shading) -> Vec<UnitLight> {
    shading
        .lights
        .iter()
        .map(|l| {
            let d = normalize3(l.direction);
            UnitLight {
                dir: d,
                half: normalize3([d[0], d[1], d[2] + 1.0]),
                color: l.color,
            }
        })
        .collect()
}

#[inline]
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// RTIViewer's **specular enhancement** (Malzbender, Gelb & Wolters 2001 "Polynomial texture
/// maps"; RTIViewer, Cultural Heritage Imaging): the albedo is replaced by a grey material with
/// a strong, tight Blinn-Phong highlight, which brings out fine relief that the colour hides.
///
/// Per channel `j`: `v = 2^ev · Σᵢ cᵢⱼ (kd·max(0, n·lᵢ) + ks·max(0, n·hᵢ)^α)`, the specular term
/// only where `n·lᵢ > 0`, `lᵢ` the shading's light directions normalised and
/// `hᵢ = normalize(lᵢ + (0,0,1))`, as [`super::relight`]; then clamped to [0, 1] and
/// sRGB-encoded. White lights give grey, `R = G = B = v`. The shading's ambient, specular and
/// shininess are not used; `kd`, `ks`, `α` are [`InspectParams`].
///
/// # Errors
/// An output of the wrong size, invalid shading or parameters.
pub fn specular_enhancement_into(
    img: &RgbnImage,
    shading: &Shading,
    p: &InspectParams,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    check_output_len(img, out, "specular_enhancement")?;
    shading.validate()?;
    p.validate()?;
    let lights = unit_lights(shading);
    let gain = 2f32.powf(shading.exposure_ev);
    let (kd, ks, alpha) = (p.spec_kd as f32, p.spec_ks as f32, p.spec_alpha as f32);
    let [nx, ny, nz] = img.normal();
    write_linear_rgb(out, img.mask(), |i| {
        let n = [nx[i], ny[i], nz[i]];
        let mut v = [0.0f32; 3];
        for l in &lights {
            let ndl = dot(n, l.dir);
            if ndl > 0.0 {
                let ndh = dot(n, l.half).clamp(0.0, 1.0);
                let t = kd * ndl + ks * ndh.powf(alpha);
                for (vj, cj) in v.iter_mut().zip(l.color) {
                    *vj += cj * t;
                }
            }
        }
        v.map(|c| gain * c)
    });
    Ok(())
}

/// The normals of [`normal_unsharp_into`]: `n' = normalize(n + gain·(n − G_σ∗n))`, the blur
/// restricted to the mask (normalised convolution) when there is one. Where `n'` has no length
/// (cannot happen for unit normals and gain ≥ 0, kept as a guard) the normal is kept.
///
/// # Errors
/// Parameters out of range.
pub fn unsharp_normals(img: &RgbnImage, p: &InspectParams) -> Result<[Vec<f32>; 3], RgbnError> {
    p.validate()?;
    let (w, h) = (img.width(), img.height());
    let n = img.normal();
    let mut blurred = n.to_vec();
    blur_planes(&mut blurred, w, h, p.unsharp_sigma as f32, img.mask());
    let gain = p.unsharp_gain as f32;
    let mut out = buf::zeroed_planes(w * h);
    let [ox, oy, oz] = &mut out;
    ox.par_iter_mut()
        .zip(oy.par_iter_mut())
        .zip(oz.par_iter_mut())
        .enumerate()
        .for_each(|(i, ((a, b), c))| {
            let v = [0, 1, 2].map(|j| n[j][i] + gain * (n[j][i] - blurred[j][i]));
            let len = dot(v, v).sqrt();
            [*a, *b, *c] = if len > 1e-12 && len.is_finite() {
                v.map(|x| x / len)
            } else {
                [n[0][i], n[1][i], n[2][i]]
            };
        });
    Ok(out)
}

/// RTIViewer's **normal unsharp masking** (Malzbender et al. 2001, "unsharp masking" of the
/// surface normals): the normals' high frequencies are amplified,
/// `n' = normalize(n + gain·(n − G_σ∗n))` ([`unsharp_normals`]), then the image is relit with
/// the shading exactly as [`super::relight`] (albedo kept). A plane, or gain 0, gives relit.
///
/// # Errors
/// An output of the wrong size, invalid shading or parameters.
pub fn normal_unsharp_into(
    img: &RgbnImage,
    shading: &Shading,
    p: &InspectParams,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    check_output_len(img, out, "normal_unsharp")?;
    shading.validate()?;
    let sharpened = img.with_normals(unsharp_normals(img, p)?)?;
    relight_into(&sharpened, shading, out)
}

/// The virtual lights of [`multi_light_into`]: unit directions at `elevation` degrees above
/// the image plane, azimuths `2πk/count` (the first from `+x`).
#[must_use]
pub fn multi_light_directions(count: usize, elevation_deg: f64) -> Vec<[f32; 3]> {
    let e = elevation_deg.to_radians();
    (0..count)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / count as f64;
            [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()].map(|v| v as f32)
        })
        .collect()
}

/// RTIViewer's **multi-light detail enhancement**, after Fattal, Agrawala & Rusinkiewicz 2007,
/// "Multiscale shape and detail enhancement from multi-light image collections".
///
/// The image is shaded (grey Lambert `max(0, n·lₖ)`, albedo removed) under `multi_lights`
/// virtual lights around the hemisphere at `multi_elevation`. Each shading `Sₖ` is split into a
/// base `Bₖ = G_σ∗Sₖ` (restricted to the mask when there is one) and a detail `Dₖ = Sₖ − Bₖ`.
/// The result is `v = mean_k Bₖ + gain · D*`, clamped, sRGB-encoded, grey.
///
/// **Simplification of Fattal et al.**: they decompose each photograph at several scales with
/// the bilateral filter and combine, per pixel and scale, the detail coefficients with weights
/// favouring the image of largest local contrast (passed through a sigmoid), plus a
/// user-weighted base. Here: one scale, a Gaussian (not bilateral) decomposition, the
/// per-pixel **maximum-contrast rule taken hard** — `D*` is the `Dₖ` of largest `|Dₖ|` at that
/// pixel (sign kept) — no sigmoid, and the base is the mean of the lights' bases.
///
/// The view does not depend on the shading (its lights are virtual, from the parameters; no
/// exposure): `_shading` keeps the signature of the other views.
///
/// # Errors
/// An output of the wrong size, or parameters out of range.
pub fn multi_light_into(
    img: &RgbnImage,
    _shading: &Shading,
    p: &InspectParams,
    out: &mut [u8],
) -> Result<(), RgbnError> {
    check_output_len(img, out, "multi_light")?;
    p.validate()?;
    let (w, h) = (img.width(), img.height());
    let n = w * h;
    let [nx, ny, nz] = img.normal();
    let mask = img.mask();
    let lights = multi_light_directions(p.multi_lights as usize, p.multi_elevation);
    let mut base_sum = buf::zeroed_f32(n);
    let mut best = buf::zeroed_f32(n);
    let mut shade = buf::zeroed_f32(n);
    for (k, l) in lights.iter().enumerate() {
        shade
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, s)| *s = dot([nx[i], ny[i], nz[i]], *l).max(0.0));
        let mut base = [shade.clone()];
        blur_planes(&mut base, w, h, p.multi_sigma as f32, mask);
        let [base] = base;
        base_sum
            .par_iter_mut()
            .zip(best.par_iter_mut())
            .zip(shade.par_iter().zip(&base))
            .for_each(|((bs, d), (s, b))| {
                *bs += b;
                let detail = s - b;
                if k == 0 || detail.abs() > d.abs() {
                    *d = detail;
                }
            });
    }
    let inv = 1.0 / lights.len() as f32;
    let dg = p.multi_gain as f32;
    write_linear_rgb(out, mask, |i| {
        let v = base_sum[i] * inv + dg * best[i];
        [v; 3]
    });
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::raster::sample::Surface;
    use crate::raster::srgb::linear_to_srgb;
    use crate::render::{relight, Light};

    fn srgb_level(v: f64) -> i32 {
        (linear_to_srgb(v.clamp(0.0, 1.0) as f32) * 255.0).round() as i32
    }

    fn render_spec(img: &RgbnImage, s: &Shading, p: &InspectParams) -> Vec<u8> {
        let mut out = vec![0; img.len() * 4];
        specular_enhancement_into(img, s, p, &mut out).unwrap();
        out
    }

    fn tilted_plane(w: usize, h: usize, n: [f32; 3], color: [f32; 3]) -> RgbnImage {
        let n = normalize3(n);
        let mut img = RgbnImage::flat(w, h, color);
        for (j, plane) in img.normal_mut().iter_mut().enumerate() {
            plane.fill(n[j]);
        }
        img
    }

    fn xorshift(mut state: u64) -> impl FnMut() -> f32 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    #[test]
    fn specular_enhancement_of_a_plane_is_the_formula_by_hand() {
        // Plane facing the viewer, white light 30° off the normal in the x–z plane:
        // n·l = cos 30°, h halfway → n·h = cos 15°.
        let img = RgbnImage::flat(5, 3, [0.9, 0.2, 0.05]);
        let th = 30f64.to_radians();
        let s = Shading {
            lights: vec![Light::white([th.sin() as f32, 0.0, th.cos() as f32])],
            ..Shading::default()
        };
        let p = InspectParams {
            spec_kd: 0.3,
            spec_ks: 0.5,
            spec_alpha: 20.0,
            ..InspectParams::default()
        };
        let want = 0.3 * th.cos() + 0.5 * (th / 2.0).cos().powf(20.0);
        let px = render_spec(&img, &s, &p);
        for c in px.chunks_exact(4) {
            for &v in &c[..3] {
                assert!(
                    (i32::from(v) - srgb_level(want)).abs() <= 1,
                    "{c:?} vs {want}"
                );
            }
            assert_eq!(c[3], 255);
        }
        // Light straight on: kd + ks, one stop down.
        let s = Shading {
            lights: vec![Light::white([0.0, 0.0, 2.0])],
            exposure_ev: -1.0,
            ..Shading::default()
        };
        let px = render_spec(&img, &s, &p);
        assert!(
            (i32::from(px[0]) - srgb_level(0.4)).abs() <= 1,
            "{:?}",
            &px[..4]
        );
    }

    #[test]
    fn specular_enhancement_ignores_the_albedo() {
        let (a, _) = Surface::Sphere { radius_px: 12.0 }.render(32, 32);
        let mut b = a.clone();
        let n = b.len();
        let mut rnd = xorshift(7);
        b.set_color([0; 3].map(|_| (0..n).map(|_| rnd()).collect()))
            .unwrap();
        let s = Shading::default();
        let p = InspectParams::default();
        assert_eq!(render_spec(&a, &s, &p), render_spec(&b, &s, &p));
        // …whereas relit does depend on it (the two images really differ).
        assert_ne!(relight(&a, &s).unwrap(), relight(&b, &s).unwrap());
    }

    #[test]
    fn specular_enhancement_matches_the_formula_in_f64_within_one_level() {
        let (w, h) = (61, 9);
        let n = w * h;
        let mut rnd = xorshift(0x9e37_79b9_7f4a_7c15);
        let mut normal = buf::zeroed_planes(n);
        let mut mask = vec![0.0; n];
        for i in 0..n {
            let v = normalize3([rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd() + 0.05]);
            for j in 0..3 {
                normal[j][i] = v[j];
            }
            mask[i] = [0.0, 0.4, 1.0][i % 3];
        }
        let img = RgbnImage::new(
            w,
            h,
            [vec![0.3; n], vec![0.6; n], vec![0.9; n]],
            normal.clone(),
            Some(mask.clone()),
        )
        .unwrap();
        for (k, nl) in [1usize, 2, 3].into_iter().enumerate() {
            let lights: Vec<Light> = (0..nl)
                .map(|_| Light {
                    direction: [rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd()],
                    color: [rnd(), rnd(), rnd()],
                })
                .collect();
            let s = Shading {
                lights,
                exposure_ev: [0.0, 0.5, -1.0][k],
                ..Shading::default()
            };
            let p = InspectParams {
                spec_kd: [0.4, 0.8, 0.2][k],
                spec_ks: [0.7, 0.3, 1.5][k],
                spec_alpha: [75.0, 8.0, 300.0][k],
                ..InspectParams::default()
            };
            let px = render_spec(&img, &s, &p);
            let gain = 2f64.powf(f64::from(s.exposure_ev));
            for i in 0..n {
                let got = &px[4 * i..4 * i + 4];
                if mask[i] <= 0.0 {
                    assert_eq!(got, [0; 4]);
                    continue;
                }
                let nv = [0, 1, 2].map(|j| f64::from(normal[j][i]));
                let mut v = [0.0f64; 3];
                for l in &s.lights {
                    let d = l.direction.map(f64::from);
                    let dl = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                    let d = d.map(|x| x / dl);
                    let hv = [d[0], d[1], d[2] + 1.0];
                    let hl = (hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2]).sqrt();
                    let ndl = nv[0] * d[0] + nv[1] * d[1] + nv[2] * d[2];
                    let ndh = ((nv[0] * hv[0] + nv[1] * hv[1] + nv[2] * hv[2]) / hl).max(0.0);
                    if ndl > 0.0 {
                        let t = p.spec_kd * ndl + p.spec_ks * ndh.powf(p.spec_alpha);
                        for (vj, cj) in v.iter_mut().zip(l.color) {
                            *vj += f64::from(cj) * t;
                        }
                    }
                }
                for j in 0..3 {
                    let want = srgb_level(gain * v[j]);
                    assert!(
                        (i32::from(got[j]) - want).abs() <= 1,
                        "pixel {i} channel {j}: {} vs {want}",
                        got[j]
                    );
                }
                assert_eq!(got[3], (mask[i].min(1.0) * 255.0 + 0.5) as u8);
            }
        }
    }

    #[test]
    fn bad_parameters_are_refused_naming_the_parameter() {
        let img = RgbnImage::flat(2, 2, [0.5; 3]);
        let s = Shading::default();
        let mut out = vec![0; 16];
        let e = specular_enhancement_into(
            &img,
            &s,
            &InspectParams {
                spec_kd: -1.0,
                ..InspectParams::default()
            },
            &mut out,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("spec_kd") && !e.contains('\n'), "{e}");
        let e = normal_unsharp_into(
            &img,
            &s,
            &InspectParams {
                unsharp_sigma: f64::NAN,
                ..InspectParams::default()
            },
            &mut out,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("unsharp_sigma"), "{e}");
        let e = multi_light_into(
            &img,
            &s,
            &InspectParams {
                multi_lights: 0,
                ..InspectParams::default()
            },
            &mut out,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("multi_lights"), "{e}");
        let e = multi_light_into(&img, &s, &InspectParams::default(), &mut out[4..])
            .unwrap_err()
            .to_string();
        assert!(e.contains("multi_light") && e.contains("2×2"), "{e}");
    }

    fn render_unsharp(img: &RgbnImage, s: &Shading, p: &InspectParams) -> Vec<u8> {
        let mut out = vec![0; img.len() * 4];
        normal_unsharp_into(img, s, p, &mut out).unwrap();
        out
    }

    fn max_level_diff(a: &[u8], b: &[u8]) -> i32 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(x, y)| (i32::from(*x) - i32::from(*y)).abs())
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn normal_unsharp_leaves_a_plane_as_relit() {
        let s = Shading {
            lights: vec![
                Light::white([0.4, -0.3, 0.6]),
                Light::white([-1.0, 0.2, 0.3]),
            ],
            ..Shading::default()
        };
        let p = InspectParams {
            unsharp_gain: 5.0,
            unsharp_sigma: 4.0,
            ..InspectParams::default()
        };
        for n in [[0.0, 0.0, 1.0], [0.3, -0.5, 0.8]] {
            let mut img = tilted_plane(40, 30, n, [0.7, 0.5, 0.2]);
            assert_eq!(
                max_level_diff(&render_unsharp(&img, &s, &p), &relight(&img, &s).unwrap()),
                0
            );
            // Masked: the blur stays inside the mask, so the plane's normals are untouched.
            let mask: Vec<f32> = (0..img.len())
                .map(|i| f32::from(u8::from(i % 40 > 10)))
                .collect();
            img.set_mask(Some(mask)).unwrap();
            assert_eq!(
                max_level_diff(&render_unsharp(&img, &s, &p), &relight(&img, &s).unwrap()),
                0
            );
        }
    }

    #[test]
    fn normal_unsharp_with_gain_zero_is_relit() {
        let (img, _) = Surface::gaussians_for(48).render(48, 48);
        let s = Shading::default();
        let p = InspectParams {
            unsharp_gain: 0.0,
            unsharp_sigma: 2.0,
            ..InspectParams::default()
        };
        assert!(max_level_diff(&render_unsharp(&img, &s, &p), &relight(&img, &s).unwrap()) <= 1);
    }

    fn std_dev(px: &[u8]) -> f64 {
        let v: Vec<f64> = px.chunks_exact(4).map(|c| f64::from(c[0])).collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
    }

    fn bumpy(size: usize) -> RgbnImage {
        Surface::Sinusoid {
            amplitude_px: 0.6,
            period_px: 6.0,
        }
        .render(size, size)
        .0
    }

    #[test]
    fn normal_unsharp_amplifies_fine_relief() {
        // Fine ripples (period 6 px) are mostly above the blur's band: their normals' tilt
        // grows by ≈ (1 + gain), so the shading varies more than relit's.
        let img = bumpy(48);
        let s = Shading {
            lights: vec![Light::white([1.0, 0.5, 1.0])],
            ambient: 0.0,
            specular: 0.0,
            ..Shading::default()
        };
        let p = InspectParams {
            unsharp_gain: 1.0,
            unsharp_sigma: 4.0,
            ..InspectParams::default()
        };
        let relit = std_dev(&relight(&img, &s).unwrap());
        let sharp = std_dev(&render_unsharp(&img, &s, &p));
        assert!(sharp > 1.3 * relit, "{sharp} vs {relit}");
        // The tilt of the sharpened normals at the steepest slope: ≈ (1 + gain) × the original's
        // (a little more: the blurred normal's n_z is below 1, which lowers 2·n_z − G∗n_z).
        let n = unsharp_normals(&img, &p).unwrap();
        let (i, _) = img.normal()[0]
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap();
        let t0 = img.normal()[0][i] / img.normal()[2][i];
        let t1 = n[0][i] / n[2][i];
        assert!(t1 > 1.6 * t0 && t1 < 2.2 * t0, "{t1} vs {t0}");
    }

    fn render_multi(img: &RgbnImage, p: &InspectParams) -> Vec<u8> {
        let mut out = vec![0; img.len() * 4];
        multi_light_into(img, &Shading::default(), p, &mut out).unwrap();
        out
    }

    #[test]
    fn multi_light_of_a_plane_is_flat() {
        for n in [[0.0, 0.0, 1.0], [0.2, 0.3, 0.9]] {
            let img = tilted_plane(37, 23, n, [0.9, 0.1, 0.1]);
            let px = render_multi(&img, &InspectParams::default());
            assert!(px.chunks_exact(4).all(|c| c == &px[..4]), "{n:?}");
            // Facing the viewer: every light gives sin(elevation), no detail.
            if n[2] == 1.0 {
                let want = srgb_level(30f64.to_radians().sin());
                assert!((i32::from(px[0]) - want).abs() <= 1, "{} vs {want}", px[0]);
            }
        }
    }

    #[test]
    fn multi_light_detail_gain_increases_contrast() {
        let img = bumpy(48);
        let std_at = |g: f64| {
            std_dev(&render_multi(
                &img,
                &InspectParams {
                    multi_gain: g,
                    multi_sigma: 3.0,
                    ..InspectParams::default()
                },
            ))
        };
        let (s0, s1, s2) = (std_at(0.0), std_at(1.0), std_at(3.0));
        assert!(s1 > s0 + 1.0 && s2 > s1 + 1.0, "{s0} {s1} {s2}");
    }

    #[test]
    fn multi_light_directions_are_unit_at_the_elevation() {
        let d = multi_light_directions(4, 30.0);
        assert_eq!(d.len(), 4);
        for v in &d {
            assert!((dot(*v, *v) - 1.0).abs() < 1e-6);
            assert!((v[2] - 0.5).abs() < 1e-6);
        }
        assert!((d[1][1] - 30f32.to_radians().cos()).abs() < 1e-6);
    }

    #[test]
    fn the_views_render_through_render_with() {
        use crate::render::{render, render_with, InspectParams, View};
        let (img, _) = Surface::gaussians_for(40).render(40, 32);
        let s = Shading::default();
        let ip = InspectParams {
            spec_alpha: 30.0,
            unsharp_gain: 4.0,
            multi_lights: 5,
            ..InspectParams::default()
        };
        let direct = |f: &dyn Fn(&mut [u8]) -> Result<(), RgbnError>| {
            let mut out = vec![0; img.len() * 4];
            f(&mut out).unwrap();
            out
        };
        let cases: [(View, Vec<u8>); 3] = [
            (
                View::SpecularEnhancement,
                direct(&|o| specular_enhancement_into(&img, &s, &ip, o)),
            ),
            (
                View::NormalUnsharp,
                direct(&|o| normal_unsharp_into(&img, &s, &ip, o)),
            ),
            (
                View::MultiLight,
                direct(&|o| multi_light_into(&img, &s, &ip, o)),
            ),
        ];
        for (view, want) in cases {
            assert_eq!(view.name().parse::<View>(), Ok(view));
            assert_eq!(
                render_with(&img, view, &s, &ip).unwrap(),
                want,
                "{}",
                view.name()
            );
            assert!(render(&img, view, &s).is_ok());
        }
        let bad = InspectParams {
            multi_sigma: -2.0,
            ..InspectParams::default()
        };
        let e = render_with(&img, View::MultiLight, &s, &bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("multi_sigma"), "{e}");
    }
}
