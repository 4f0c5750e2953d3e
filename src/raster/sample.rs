//! Built-in inputs: the procedural demo medallion (so rgbn runs with no files) and analytic
//! test surfaces with exact heights *and* exact normals.
//!
//! Coordinates: pixel `(x, row)` maps to `u = x − cx`, `v = cy − row` (y up), heights in pixels.

use super::gradient::{corner_samples, normal_of_gradient, GradientField};
use super::window::Window;
use super::{Plane, RgbnImage};
use crate::raster::buf;
use rayon::prelude::*;

/// An analytic height field `z(u, v)` with its exact gradient.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Surface {
    /// Upper hemisphere of radius `radius_px` centred in the image; flat (z = 0) outside, where
    /// the mask is 0. Slopes grow without bound at the rim.
    Sphere { radius_px: f64 },
    /// `z = −curvature · (u² + v²)`: a dome whose slope grows linearly.
    Paraboloid { curvature: f64 },
    /// `z = amplitude · sin(2π u / period) · sin(2π v / period)`.
    Sinusoid { amplitude_px: f64, period_px: f64 },
    /// `Σ aᵢ · exp(−((u−uᵢ)² + (v−vᵢ)²) / 2sᵢ²)`, each bump `(u, v, amplitude, sigma)`.
    Gaussians { bumps: Vec<[f64; 4]> },
}

impl Surface {
    /// A default sum of Gaussians well inside a `size × size` image (zero slope at the borders).
    #[must_use]
    pub fn gaussians_for(size: usize) -> Self {
        let s = size as f64;
        Surface::Gaussians {
            bumps: vec![
                [-0.15 * s, 0.1 * s, 0.12 * s, 0.09 * s],
                [0.18 * s, -0.12 * s, -0.08 * s, 0.06 * s],
                [0.05 * s, 0.2 * s, 0.05 * s, 0.04 * s],
            ],
        }
    }

    /// Height at `(u, v)`.
    #[must_use]
    pub fn height(&self, u: f64, v: f64) -> f64 {
        match self {
            Surface::Sphere { radius_px: r } => (r * r - u * u - v * v).max(0.0).sqrt(),
            Surface::Paraboloid { curvature: c } => -c * (u * u + v * v),
            Surface::Sinusoid {
                amplitude_px: a,
                period_px: l,
            } => {
                let k = std::f64::consts::TAU / l;
                a * (k * u).sin() * (k * v).sin()
            }
            Surface::Gaussians { bumps } => bumps
                .iter()
                .map(|[bu, bv, a, s]| {
                    a * (-((u - bu).powi(2) + (v - bv).powi(2)) / (2.0 * s * s)).exp()
                })
                .sum(),
        }
    }

    /// Exact gradient `(∂z/∂u, ∂z/∂v)`; `None` where the surface has no finite slope (outside or
    /// on the sphere's rim).
    #[must_use]
    pub fn gradient(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        Some(match self {
            Surface::Sphere { radius_px: r } => {
                let z2 = r * r - u * u - v * v;
                if z2 <= 0.0 {
                    return None;
                }
                let z = z2.sqrt();
                [-u / z, -v / z]
            }
            Surface::Paraboloid { curvature: c } => [-2.0 * c * u, -2.0 * c * v],
            Surface::Sinusoid {
                amplitude_px: a,
                period_px: l,
            } => {
                let k = std::f64::consts::TAU / l;
                [
                    a * k * (k * u).cos() * (k * v).sin(),
                    a * k * (k * u).sin() * (k * v).cos(),
                ]
            }
            Surface::Gaussians { bumps } => {
                bumps.iter().fold([0.0, 0.0], |[gu, gv], [bu, bv, a, s]| {
                    let e = a * (-((u - bu).powi(2) + (v - bv).powi(2)) / (2.0 * s * s)).exp();
                    [gu - e * (u - bu) / (s * s), gv - e * (v - bv) / (s * s)]
                })
            }
        })
    }

    /// Samples the surface on a `width × height` grid: the RGBN (albedo 0.8 grey, exact normals,
    /// a mask where the slope is undefined) and the height plane.
    #[must_use]
    pub fn render(&self, width: usize, height: usize) -> (RgbnImage, Plane) {
        self.render_window((width, height), Window::full(width, height))
    }

    /// [`Surface::render`] of the `full` image, only over `win` (the same pixels, computed
    /// independently of the rest of the image).
    #[must_use]
    pub fn render_window(&self, full: (usize, usize), win: Window) -> (RgbnImage, Plane) {
        let (cx, cy) = (full.0 as f64 / 2.0, full.1 as f64 / 2.0);
        let (width, height) = (win.w, win.h);
        let n = width * height;
        let mut normal = [
            buf::zeroed_f32(n),
            buf::zeroed_f32(n),
            buf::filled_f32(n, 1.0),
        ];
        let mut mask = buf::filled_f32(n, 1.0);
        // Pixel (x, row) of the window's grid is sampled at the middle full-image pixel of
        // those it covers (itself at full resolution).
        let s = win.scale as f64;
        let mid = (s - 1.0) / 2.0;
        let at = |x: usize, r: usize| {
            (
                (win.x + x) as f64 * s + mid - cx,
                cy - ((win.y + r) as f64 * s + mid),
            )
        };
        let z = Plane::from_fn(width, height, |x, r| {
            let (u, v) = at(x, r);
            (self.height(u, v) / s) as f32
        });
        let [nx, ny, nz] = &mut normal;
        // Cancelled: the remaining rows keep (0, 0, 1) and the caller discards them.
        let cancel = crate::cancel::Cancel::current();
        for (i, ((a, b), (c, m))) in nx
            .iter_mut()
            .zip(ny.iter_mut())
            .zip(nz.iter_mut().zip(mask.iter_mut()))
            .enumerate()
        {
            if i % width == 0 && cancel.is_cancelled() {
                break;
            }
            let (u, v) = at(i % width, i / width);
            match self.gradient(u, v) {
                Some([p, q]) => [*a, *b, *c] = normal_of_gradient(p as f32, q as f32),
                None => *m = 0.0,
            }
        }
        if cancel.is_cancelled() {
            // Discarded by the caller: no colour planes filled.
            let c = || buf::zeroed_f32(n);
            let img = RgbnImage::new(width, height, [c(), c(), c()], normal, None)
                .expect("sizes match by construction");
            return (img, z);
        }
        let img = RgbnImage::new(
            width,
            height,
            [vec![0.8; n], vec![0.8; n], vec![0.8; n]],
            normal,
            self.undefined_somewhere(full).then_some(mask),
        )
        .expect("sizes match by construction");
        (img, z)
    }

    /// Whether the slope is undefined at some pixel centre or corner of a `full` image (then
    /// its renders carry a mask, whichever part of the image is rendered): the sphere when a
    /// corner of the image, the farthest point from its centre, lies on or outside it.
    #[must_use]
    pub fn undefined_somewhere(&self, full: (usize, usize)) -> bool {
        match self {
            Surface::Sphere { radius_px: r } => {
                // The arithmetic of `gradient` at corner (0, 0).
                let (u, v) = (-(full.0 as f64 / 2.0), full.1 as f64 / 2.0);
                r * r - u * u - v * v <= 0.0
            }
            _ => false,
        }
    }
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * t * (t * (6.0 * t - 15.0) + 10.0)
}

/// Signed distance to a five-pointed star of outer radius `r` (inner ratio `rf`), negative inside.
fn star_sd(mut px: f64, mut py: f64, r: f64, rf: f64) -> f64 {
    let k1 = (0.809_016_994_375, -0.587_785_252_292);
    let k2 = (-k1.0, k1.1);
    px = px.abs();
    let d1 = 2.0 * (k1.0 * px + k1.1 * py).max(0.0);
    px -= d1 * k1.0;
    py -= d1 * k1.1;
    let d2 = 2.0 * (k2.0 * px + k2.1 * py).max(0.0);
    px -= d2 * k2.0;
    py -= d2 * k2.1;
    px = px.abs();
    py -= r;
    let ba = (rf * -k1.1 - 0.0, rf * k1.0 - 1.0);
    let h = ((px * ba.0 + py * ba.1) / (ba.0 * ba.0 + ba.1 * ba.1)).clamp(0.0, r);
    let (dx, dy) = (px - ba.0 * h, py - ba.1 * h);
    (dx * dx + dy * dy).sqrt() * (py * ba.0 - px * ba.1).signum()
}

/// Height and linear colour of the medallion at `(u, v)` for a design of radius `rr`.
fn medallion(u: f64, v: f64, rr: f64) -> (f64, [f32; 3]) {
    let r = (u * u + v * v).sqrt();
    let th = v.atan2(u);
    let s = rr / 440.0; // design units → pixels
    let plate = 1.0 - smoothstep(rr - 10.0 * s, rr, r);
    let mut z = 10.0 * s * plate;
    // rim ridge
    z += 9.0 * s * (-(r - (rr - 28.0 * s)).powi(2) / (2.0 * (7.0 * s).powi(2))).exp();
    // central dome
    let rd = 230.0 * s;
    if r < rd {
        z += 38.0 * s * (1.0 - (r / rd).powi(2)).powi(2);
    }
    // raised star on the dome
    let star = 1.0 - smoothstep(-2.0 * s, 2.0 * s, star_sd(u, v, 150.0 * s, 0.45));
    z += 6.0 * s * star;
    // sixteen rays between the dome and the beads
    let env = smoothstep(245.0 * s, 262.0 * s, r) * (1.0 - smoothstep(320.0 * s, 338.0 * s, r));
    let ray = (16.0 * th).cos();
    z += 3.5 * s * env * ray;
    // ring of 24 beads
    let bead_r = 368.0 * s;
    let sector = std::f64::consts::TAU / 24.0;
    let a = (th / sector).round() * sector;
    let (bu, bv) = (bead_r * a.cos(), bead_r * a.sin());
    let bd2 = (u - bu).powi(2) + (v - bv).powi(2);
    let bead = (-bd2 / (2.0 * (9.0 * s).powi(2))).exp();
    z += 8.0 * s * bead;
    // hammered fine texture on the plate, woven texture outside
    let fine =
        (0.9 * u + 0.4 * v).sin() * (0.35 * u - 0.8 * v).sin() + 0.5 * (0.25 * (u + 2.0 * v)).sin();
    let weave = (std::f64::consts::TAU * u / 6.0).sin() * (std::f64::consts::TAU * v / 6.0).cos();
    z += plate * 0.35 * fine + (1.0 - plate) * 0.6 * weave;

    // colour (linear)
    let gold = [0.80f32, 0.52, 0.18];
    let cloth = if ((u / 24.0).floor() + (v / 24.0).floor()) as i64 % 2 == 0 {
        [0.05f32, 0.07, 0.16]
    } else {
        [0.07, 0.09, 0.20]
    };
    let teal = [0.05f32, 0.35, 0.33];
    let cream = [0.75f32, 0.65, 0.45];
    let enamel_red = [0.55f32, 0.05, 0.04];
    let silver = [0.80f32, 0.80, 0.82];
    let blue = [0.06f32, 0.12, 0.55];
    let mix = |a: [f32; 3], b: [f32; 3], t: f64| {
        let t = t as f32;
        [
            a[0] + (b[0] - a[0]) * t,
            a[1] + (b[1] - a[1]) * t,
            a[2] + (b[2] - a[2]) * t,
        ]
    };
    let sector_col = if ray > 0.0 { teal } else { cream };
    let mut c = mix(gold, sector_col, env * 0.85);
    c = mix(
        c,
        enamel_red,
        if r < rd {
            1.0 - smoothstep(rd - 6.0 * s, rd, r)
        } else {
            0.0
        },
    );
    c = mix(c, silver, star);
    c = mix(c, blue, smoothstep(0.35, 0.6, bead));
    c = mix(cloth, c, plate);
    (z, c)
}

/// Heights of `f(u, v)` at the `(win.w + 1) × (win.h + 1)` pixel corners of `win` in a `full`
/// image ([`corner_samples`]), with `u = x − cx`, `v = cy − row` for corner `(x, row)` of the
/// full image and `(cx, cy)` its centre; at a coarser scale, corner `(x, row)` of the window's
/// grid is corner `(x·scale, row·scale)` of the full image and heights are divided by the
/// scale (they are in the window's pixels, so slopes are unchanged).
fn corner_heights(
    full: (usize, usize),
    win: Window,
    f: impl Fn(f64, f64) -> f64 + Sync,
) -> Vec<f64> {
    let (cx, cy) = (full.0 as f64 / 2.0, full.1 as f64 / 2.0);
    if win.scale == 1 {
        return corner_samples(win.w, win.h, |x, row| {
            f((win.x + x) as f64 - cx, cy - (win.y + row) as f64)
        });
    }
    let s = win.scale as f64;
    corner_samples(win.w, win.h, |x, row| {
        f((win.x + x) as f64 * s - cx, cy - (win.y + row) as f64 * s) / s
    })
}

impl Surface {
    /// Samples the surface as a capture does: the height at the pixel corners, each pixel's
    /// normal from the differences of its four corners ([`GradientField::from_corner_heights`]), so the image is
    /// exactly integrable (curl 0 up to rounding) and the returned height (the corner mean,
    /// at pixel centres) is what integrating its normals gives back. Masked where the slope is
    /// undefined at any of the four corners (outside the sphere or on its rim).
    #[must_use]
    pub fn render_sampled(&self, width: usize, height: usize) -> (RgbnImage, Plane) {
        self.render_sampled_window((width, height), Window::full(width, height))
    }

    /// [`Surface::render_sampled`] of the `full` image, only over `win` (the same pixels,
    /// bit for bit: every corner is sampled on its own).
    #[must_use]
    pub fn render_sampled_window(&self, full: (usize, usize), win: Window) -> (RgbnImage, Plane) {
        let (width, height) = (win.w, win.h);
        let zc = corner_heights(full, win, |u, v| self.height(u, v));
        // Cancelled: zeros of the right size (untouched pages), which the caller discards
        // (crate::cancel); each pass below is skipped once the token is set.
        let cancel = crate::cancel::Cancel::current();
        let discarded = || {
            let z = || buf::zeroed_f32(width * height);
            let img = RgbnImage::new(width, height, [z(), z(), z()], [z(), z(), z()], None)
                .expect("sizes match by construction");
            (
                img,
                Plane::from_vec(width, height, z()).expect("sizes match"),
            )
        };
        if cancel.is_cancelled() {
            return discarded();
        }
        let (mut g, z) = GradientField::from_corner_heights(width, height, &zc);
        drop(zc);
        if cancel.is_cancelled() {
            return discarded();
        }
        let mask = self.undefined_somewhere(full).then(|| {
            let defined = corner_heights(full, win, |u, v| {
                f64::from(u8::from(self.gradient(u, v).is_some()))
            });
            let cw = width + 1;
            let mask: Vec<f32> = (0..width * height)
                .into_par_iter()
                .map(|i| {
                    let (x, row) = (i % width, i / width);
                    let (a, b) = (row * cw + x, (row + 1) * cw + x);
                    // 1 where defined, divided by the scale as heights are.
                    let all = [a, a + 1, b, b + 1].iter().all(|&c| defined[c] > 0.0);
                    f32::from(u8::from(all))
                })
                .collect();
            for (i, &m) in mask.iter().enumerate() {
                if m == 0.0 {
                    (g.p[i], g.q[i]) = (0.0, 0.0);
                }
            }
            mask
        });
        if cancel.is_cancelled() {
            return discarded();
        }
        let n = width * height;
        let img = RgbnImage::new(
            width,
            height,
            [vec![0.8; n], vec![0.8; n], vec![0.8; n]],
            g.to_normals(),
            mask,
        )
        .expect("sizes match by construction");
        (img, z)
    }
}

/// The procedural demo RGBN: a relief medallion (dome, star, rays, beads, rim, hammered and woven
/// textures, enamel colours) of `size × size` pixels; 1024 is the intended size. Its height is
/// sampled at the pixel corners and each normal is taken from the differences of its pixel's
/// four corners, as [`Surface::render_sampled`] does: the demo is exactly a surface (curl 0 up to
/// rounding), and [`demo_height`] is the height that integrating it gives back.
#[must_use]
pub fn demo_medallion(size: usize) -> RgbnImage {
    demo_window(size, Window::full(size, size))
}

/// [`demo_medallion`] of a `size × size` image, only over `win` (the same pixels, bit for bit).
#[must_use]
pub fn demo_window(size: usize, win: Window) -> RgbnImage {
    let (w, h) = (win.w, win.h);
    let n = w * h;
    let c = size as f64 / 2.0;
    let rr = 0.45 * size as f64;
    // Cancelled: every stage stops, and the image returned is zeros (untouched pages) that
    // the caller discards (crate::cancel).
    let cancel = crate::cancel::Cancel::current();
    let discarded = || {
        let z = || buf::zeroed_f32(n);
        RgbnImage::new(w, h, [z(), z(), z()], [z(), z(), z()], None)
            .expect("sizes match by construction")
    };
    let zc = corner_heights((size, size), win, |u, v| medallion(u, v, rr).0);
    if cancel.is_cancelled() {
        return discarded();
    }
    let (g, _) = GradientField::from_corner_heights(w, h, &zc);
    drop(zc);
    if cancel.is_cancelled() {
        return discarded();
    }
    let mut color = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    let s = win.scale as f64;
    let [cr, cg, cb] = &mut color;
    let row = w.max(1);
    cr.par_chunks_mut(row)
        .zip(cg.par_chunks_mut(row))
        .zip(cb.par_chunks_mut(row))
        .enumerate()
        .for_each(|(y, ((r, g), b))| {
            if cancel.is_cancelled() {
                return;
            }
            let v = c - ((win.y + y) as f64 + 0.5) * s;
            for x in 0..w {
                let col = medallion(((win.x + x) as f64 + 0.5) * s - c, v, rr).1;
                (r[x], g[x], b[x]) = (col[0], col[1], col[2]);
            }
        });
    if cancel.is_cancelled() {
        return discarded();
    }
    RgbnImage::new(w, h, color, g.to_normals(), None).expect("sizes match by construction")
}

/// The height of the demo medallion (pixels) at pixel centres — the mean of each pixel's four
/// corner samples, the height its normals integrate to — for tests and the height view.
#[must_use]
pub fn demo_height(size: usize) -> Plane {
    let rr = 0.45 * size as f64;
    let zc = corner_heights((size, size), Window::full(size, size), |u, v| {
        medallion(u, v, rr).0
    });
    GradientField::from_corner_heights(size, size, &zc).1
}

/// i.i.d. uniform samples in [−1, 1] for `p` and `q` (a 64-bit LCG, deterministic).
#[must_use]
pub fn noise_field(w: usize, h: usize, seed: u64) -> GradientField {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    };
    let p = (0..w * h).map(|_| next()).collect();
    let q = (0..w * h).map(|_| next()).collect();
    GradientField {
        width: w,
        height: h,
        p,
        q,
        clamped: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn analytic_gradients_match_finite_differences_of_the_height() {
        let surfaces = [
            Surface::Sphere { radius_px: 40.0 },
            Surface::Paraboloid { curvature: 0.01 },
            Surface::Sinusoid {
                amplitude_px: 3.0,
                period_px: 17.0,
            },
            Surface::gaussians_for(128),
        ];
        for s in &surfaces {
            for &(u, v) in &[(3.0, -7.0), (-11.5, 2.25), (20.0, 15.0)] {
                let h = 1e-4;
                let fd = [
                    (s.height(u + h, v) - s.height(u - h, v)) / (2.0 * h),
                    (s.height(u, v + h) - s.height(u, v - h)) / (2.0 * h),
                ];
                let g = s.gradient(u, v).unwrap();
                assert!(
                    (g[0] - fd[0]).abs() < 1e-6 && (g[1] - fd[1]).abs() < 1e-6,
                    "{s:?}"
                );
            }
        }
    }

    #[test]
    fn sphere_normals_point_radially_out() {
        let (img, _) = Surface::Sphere { radius_px: 20.0 }.render(64, 64);
        // pixel right of and above centre: normal has +x and +y components
        let n = img.normal_at(32 + 10, 32 - 5);
        let want = [10.0 / 20.0, 5.0 / 20.0, (400.0f32 - 125.0).sqrt() / 20.0];
        for k in 0..3 {
            assert!((n[k] - want[k]).abs() < 1e-5, "{n:?} vs {want:?}");
        }
        assert_eq!(
            img.mask().unwrap()[0],
            0.0,
            "corner lies outside the sphere"
        );
    }

    /// The averaged-model relative RMS curl (the readout of `rgbn info`).
    fn averaged_curl(img: &RgbnImage) -> f64 {
        use crate::raster::gradient::{Differences, GradientField};
        GradientField::from_normals(img)
            .curl_stats_of(Differences::Averaged, img.mask())
            .relative
    }

    #[test]
    fn sampled_normals_are_exactly_a_surface_and_integrate_to_its_height() {
        use crate::raster::integrate::{integrate_normals, IntegrateParams, IntegrationMethod};
        let surfaces = [
            // detail near the pixel scale: analytic normals are far from a surface here
            Surface::Gaussians {
                bumps: vec![[3.3, -2.1, 4.0, 1.5], [-20.0, 10.0, -3.0, 2.5]],
            },
            Surface::Sinusoid {
                amplitude_px: 3.0,
                period_px: 5.0,
            },
            Surface::gaussians_for(96),
            Surface::Sphere { radius_px: 40.0 },
        ];
        for s in &surfaces {
            let (img, z) = s.render_sampled(96, 80);
            let curl = averaged_curl(&img);
            assert!(curl <= 1e-5, "{s:?}: relative curl {curl:e}");
            let params = IntegrateParams {
                method: if img.mask().is_some() {
                    IntegrationMethod::MaskedPoisson
                } else {
                    IntegrationMethod::PoissonDct
                },
                ..IntegrateParams::default()
            };
            let (zi, _) = integrate_normals(&img, &params).unwrap();
            // compare up to the constant, inside the mask
            let inside: Vec<usize> = (0..96 * 80)
                .filter(|&i| img.mask().is_none_or(|m| m[i] >= 0.5))
                .collect();
            let off = inside
                .iter()
                .map(|&i| f64::from(z.data()[i] - zi.data()[i]))
                .sum::<f64>()
                / inside.len() as f64;
            let worst = inside
                .iter()
                .map(|&i| (f64::from(z.data()[i] - zi.data()[i]) - off).abs())
                .fold(0.0, f64::max);
            assert!(worst < 2e-3, "{s:?}: height error {worst} px");
        }
        // the analytic normals of the narrow bumps are not a surface on this grid
        let (analytic, _) = surfaces[0].render(96, 80);
        assert!(
            averaged_curl(&analytic) > 0.01,
            "{}",
            averaged_curl(&analytic)
        );
    }

    #[test]
    fn the_demo_is_exactly_a_surface_and_integrates_to_demo_height() {
        use crate::raster::integrate::{integrate_normals, IntegrateParams};
        let img = demo_medallion(128);
        let curl = averaged_curl(&img);
        assert!(curl <= 1e-4, "relative curl {curl:e}");
        let (zi, _) = integrate_normals(&img, &IntegrateParams::default()).unwrap();
        let z = demo_height(128);
        let n = z.data().len() as f64;
        let off = z
            .data()
            .iter()
            .zip(zi.data())
            .map(|(a, b)| f64::from(a - b))
            .sum::<f64>()
            / n;
        let worst = z
            .data()
            .iter()
            .zip(zi.data())
            .map(|(a, b)| (f64::from(a - b) - off).abs())
            .fold(0.0, f64::max);
        assert!(worst < 2e-3, "height error {worst} px");
    }

    #[test]
    fn demo_is_valid_and_has_relief() {
        let img = demo_medallion(128);
        let v = img.validate();
        assert!(v.is_clean() && v.back_facing == 0, "{v:?}");
        let tilted = img.normal()[2].iter().filter(|&&z| z < 0.95).count();
        assert!(tilted > 128 * 128 / 20, "demo should have visible relief");
    }
}
