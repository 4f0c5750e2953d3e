//! RGBN bilateral filter and base/detail split (Toler-Franklin et al. 2007; Pereira & Velho
//! §VII, Fig. 11).
//!
//! # Filter
//!
//! Each output normal is that of the weighted mean of the foreshorten-corrected gradients
//! `(p, q) = (−n_x/n_z, −n_y/n_z)` of its neighbours in the disc of radius `r = ⌈2σ_s⌉` (a
//! windowed brute force: a bilateral filter is not separable):
//!
//! `(p̄, q̄)(P) = Σ_Q w_s(P,Q) · w_c(P,Q) · w_n(P,Q) · (p, q)(Q) / Σ_Q w`, `n̂ = normal of (p̄, q̄)`
//!
//! - spatial `w_s = exp(−|P−Q|² / 2σ_s²)`, `|P − Q| ≤ r`,
//! - colour `w_c = exp(−|c(P) − c(Q)|² / 2σ_c²)` (linear RGB; skipped when `σ_c` is 0),
//! - normal similarity `w_n = exp(−δ² / 2σ_n²)` with `δ` the angle between the normals
//!   ([`NormalMetric::Angle`], radians) or `1 − n·n′` ([`NormalMetric::OneMinusDot`]).
//!
//! Averaging gradients, not unit normals, is the foreshortening correction (§III; equal to
//! Toler-Franklin et al.'s weighting of each normal by `1/n_z`): with the range weights at 1
//! the filter is a Gaussian of the gradients, so a smoothed surface stays a surface. The
//! kernel, its speed and that reason in full are in [`crate::raster::bilateral`].
//!
//! Pixels with mask coverage < ½ neither contribute nor change. Colour can be smoothed with the
//! same weights (`filter_color`). It is a nonlinear filter: the curl of the result is reported,
//! not guaranteed small.
//!
//! # Wide σ_s
//!
//! The exact disc has about `π(2σ_s)²` taps: 797 at σ_s = 8 (4.2 s on a 4K image), so its
//! cost grows with σ_s². From σ_s = 8 px on, [`BilateralMethod::Auto`] samples the disc every
//! `s = ⌈σ_s/4⌉` px instead (the spatially subsampled bilateral of Banterle et al. 2012, on a
//! regular grid, still symmetric): a disc of radius 8 samples, about 200 taps, whatever σ_s.
//! At 4K, 2 threads: σ_s = 8 1.0–1.3 s, 16 1.8 s, 32 1.2–1.6 s (exact at 8: 4.2–5.1 s).
//! Its error against the exact filter (test
//! `the_sampled_disc_stays_close_to_the_exact_filter_at_wide_sigma`: a dome with a 5 px
//! texture and a colour edge, σ_c = 0.2, σ_n = 0.3): mean 0.18° / max 1.8° at σ_s = 8,
//! 0.49° / 4.3° at 12, 0.33° / 2.9° at 16, where the filter itself moves normals by 6.8° on
//! average — the error is aliasing of detail finer than `2s`. `method: exact` keeps every
//! pixel. A bilateral grid or a permutohedral lattice was not used: the range here is 6-D
//! (colour and normal), where a grid is out of reach and the lattice's kernel is not a
//! Gaussian in the angle.
//!
//! # Split
//!
//! [`split`] returns `(base, detail)` with base = the filtered image and detail = the rotation
//! that takes the base normal to the original one, expressed as a normal in the base's tangent
//! frame: `d = Fᵀ(n̂) n` with `F` the frame of [`super::rotate`] (minimal rotation by default).
//! Rotation-combining them (`F(n̂) d`, [`super::rotate::CombineMode::Blend`] with weight 1 in the
//! same frame) gives the input back exactly (to float rounding). Detail colour is the original
//! colour (the base carries the smoothed one when `filter_color` is on).
//!
//! # References
//! - C. Toler-Franklin, A. Finkelstein, S. Rusinkiewicz, "Illustration of complex real-world
//!   objects using images with normals", NPAR 2007.
//! - C. Tomasi, R. Manduchi, "Bilateral filtering for gray and color images", ICCV 1998.
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §VII.

use super::rotate::{normalize3, Frame, FrameSettings};
use crate::error::RgbnError;
use crate::raster::bilateral as kernel;
use crate::raster::buf;
use crate::raster::gradient::CurlStats;
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// Largest spatial σ accepted (pixels): the window is `(4σ+1)²` taps per pixel.
pub const MAX_BILATERAL_SIGMA_PX: f32 = 64.0;

crate::choice_enum! {
    /// How normal similarity is measured.
    pub enum NormalMetric {
        /// `δ = angle(n, n′)` in radians.
        Angle = "angle",
        /// `δ = 1 − n·n′` (cheaper, ≈ angle²/2).
        OneMinusDot = "one_minus_dot",
    }
}

crate::choice_enum! {
    /// Every pixel of the disc, or the disc sampled on a coarser grid (wide σ_s).
    pub enum BilateralMethod {
        /// Exact below σ_s = 8 px, sampled from 8 px on (where the exact disc has ≥ 797 taps).
        Auto = "auto",
        /// Every pixel of the disc of radius ⌈2σ_s⌉: cost grows with σ_s².
        Exact = "exact",
        /// The disc sampled every ⌈σ_s/4⌉ px (Banterle et al. 2012): about 200 taps whatever σ_s; error against the exact filter in the module docs.
        Sampled = "sampled",
    }
}

/// Spatial σ from which [`BilateralMethod::Auto`] samples the disc.
pub const SAMPLED_FROM_SIGMA_PX: f64 = 8.0;

impl BilateralMethod {
    /// Tap spacing (px) of the disc at spatial σ `sigma_spatial_px`: 1 for every pixel,
    /// `⌈σ_s / 4⌉` when sampled (the disc then has radius 8 in taps: ~200 of them).
    #[must_use]
    pub fn stride(self, sigma_spatial_px: f64) -> usize {
        let sampled = match self {
            Self::Auto => sigma_spatial_px >= SAMPLED_FROM_SIGMA_PX,
            Self::Exact => false,
            Self::Sampled => true,
        };
        if sampled {
            (sigma_spatial_px / 4.0).ceil().max(1.0) as usize
        } else {
            1
        }
    }
}

crate::params! {
    /// Parameters of [`bilateral`] and [`split`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct BilateralParams {
        /// Spatial σ; the window has radius ⌈2σ⌉.
        pub sigma_spatial_px: f64 = 3.0
            => float.unit("px").range(0.05, f64::from(MAX_BILATERAL_SIGMA_PX)).soft(0.5, 16.0).log(),
        /// Colour σ (linear RGB distance); 0 ignores colour.
        pub sigma_color: f64 = 0.0 => float.range(0.0, 1e6).soft(0.0, 0.5),
        /// Normal-similarity σ (radians for angle, unitless for one_minus_dot); 0 ignores normals.
        pub sigma_normal: f64 = f64::from(0.3f32) => float.range(0.0, 1e6).soft(0.0, 1.0),
        /// Normal similarity: the angle between the normals, or 1 − n·n′ (≈ angle²/2).
        pub normal_metric: NormalMetric = NormalMetric::Angle => choice,
        /// Every pixel of the disc, the disc sampled every ⌈σ_s/4⌉ px, or auto (sampled from σ_s = 8 px).
        pub method: BilateralMethod = BilateralMethod::Auto => choice,
        /// Also smooth the base's colour with the same weights.
        pub filter_color: bool = false => bool,
        /// The detail's tangent frame.
        pub tangent: FrameSettings = FrameSettings::default() => flatten,
    }
}

impl BilateralParams {
    /// The colour σ, `None` when colour is ignored (σ = 0).
    #[must_use]
    pub fn color_sigma(&self) -> Option<f32> {
        (self.sigma_color != 0.0).then_some(self.sigma_color as f32)
    }
    /// The normal σ, `None` when normals are ignored (σ = 0).
    #[must_use]
    pub fn normal_sigma(&self) -> Option<f32> {
        (self.sigma_normal != 0.0).then_some(self.sigma_normal as f32)
    }
    /// The frame of the detail in [`split`].
    #[must_use]
    pub fn detail_frame(&self) -> Frame {
        self.tangent.get()
    }
    /// These parameters with the detail frame `frame`.
    #[must_use]
    pub fn with_frame(mut self, frame: &Frame) -> Self {
        self.tangent.set(frame);
        self
    }

    /// The window's radius in pixels, ⌈2σ⌉ (the node's halo too).
    #[must_use]
    pub fn radius_px(&self) -> usize {
        (2.0 * self.sigma_spatial_px as f32).ceil() as usize
    }

    /// Checks every parameter: the ranges `params!` declares (σs finite and in range, 0 for
    /// the range σs meaning "ignore"), then the detail frame.
    pub fn validate(&self) -> Result<(), RgbnError> {
        crate::params::check_ranges(self)?;
        self.detail_frame().validate()
    }
}

/// What the bilateral filter measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BilateralReport {
    /// Curl of the base's gradients (nonlinear filter: reported, not guaranteed small).
    pub curl_after: CurlStats,
}

/// The bilateral-filtered image (module docs) with its curl. Colour is smoothed only with
/// `filter_color`.
pub fn bilateral(
    img: &RgbnImage,
    params: &BilateralParams,
) -> Result<(RgbnImage, BilateralReport), RgbnError> {
    let out = filtered(img, params)?;
    let curl_after = crate::raster::gradient::curl_stats_of_normals(&out);
    Ok((out, BilateralReport { curl_after }))
}

/// The bilateral-filtered image alone ([`bilateral`] without its curl).
pub fn filtered(img: &RgbnImage, params: &BilateralParams) -> Result<RgbnImage, RgbnError> {
    params.validate()?;
    let sigma_spatial = params.sigma_spatial_px as f32;
    let spec = kernel::Spec {
        sigma_spatial,
        radius: params.radius_px(),
        stride: 1,
        sigma_color: params.color_sigma(),
        sigma_normal: params.normal_sigma(),
        metric: match params.normal_metric {
            NormalMetric::Angle => kernel::RangeMetric::Angle,
            NormalMetric::OneMinusDot => kernel::RangeMetric::OneMinusDot,
        },
        filter_color: params.filter_color,
    };
    fn input<'a>(
        img: &'a RgbnImage,
        n: &'a [Vec<f32>; 3],
        c: &'a [Vec<f32>; 3],
    ) -> kernel::Input<'a> {
        kernel::Input {
            width: img.width(),
            height: img.height(),
            normal: [&n[0], &n[1], &n[2]],
            color: [&c[0], &c[1], &c[2]],
            mask: img.mask(),
        }
    }
    let kernel::Output {
        normal: out_n,
        color: out_c,
    } = kernel::filter(
        &input(img, img.normal(), img.color()),
        &kernel::Spec {
            stride: params.method.stride(params.sigma_spatial_px),
            ..spec
        },
    );
    let mut out = img.with_normals(out_n)?;
    if let Some(c) = out_c {
        out.set_color(c)?;
    }
    Ok(out)
}

/// Splits an image into `(base, detail)` (module docs): base = [`bilateral`], detail normals =
/// `Fᵀ(n̂) n` in the base's frame (`params.tangent`), detail colour = the input's.
pub fn split(
    img: &RgbnImage,
    params: &BilateralParams,
) -> Result<(RgbnImage, RgbnImage, BilateralReport), RgbnError> {
    let (base, report) = bilateral(img, params)?;
    let detail = detail(img, &base, params)?;
    Ok((base, detail, report))
}

/// The detail of [`split`] given its base: `img`'s normals in the tangent frame of `base`'s
/// (`params.tangent`), `img`'s colour.
pub fn detail(
    img: &RgbnImage,
    base: &RgbnImage,
    params: &BilateralParams,
) -> Result<RgbnImage, RgbnError> {
    if (base.width(), base.height()) != (img.width(), img.height()) {
        return Err(RgbnError::InvalidImage(format!(
            "the base is {}×{}, the image {}×{}",
            base.width(),
            base.height(),
            img.width(),
            img.height()
        )));
    }
    let frame = params.detail_frame();
    let (bn, on) = (base.normal(), img.normal());
    let n = img.len();
    let w = img.width().max(1);
    let mut d = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    let [dx, dy, dz] = &mut d;
    let minimal = matches!(frame, Frame::MinimalRotation);
    dx.par_chunks_mut(w)
        .zip(dy.par_chunks_mut(w))
        .zip(dz.par_chunks_mut(w))
        .enumerate()
        .for_each(|(row, ((x, y), z))| {
            let o0 = row * w;
            for k in 0..x.len() {
                let i = o0 + k;
                let b = [bn[0][i], bn[1][i], bn[2][i]];
                let o = [on[0][i], on[1][i], on[2][i]];
                let t = if minimal {
                    tangent_minimal(b, o)
                } else {
                    tangent_f64(&frame, b, o)
                };
                (x[k], y[k], z[k]) = (t[0], t[1], t[2]);
            }
        });
    img.with_normals(d)
}

/// `o` in the tangent frame of base normal `b` (both normalised first), in `f64`.
fn tangent_f64(frame: &Frame, b: [f32; 3], o: [f32; 3]) -> [f32; 3] {
    let b = normalize3(b.map(f64::from));
    let o = normalize3(o.map(f64::from));
    frame.to_tangent(b, o).map(|v| v as f32)
}

/// [`tangent_f64`] for the minimal-rotation frame, in `f32` (the detail is stored in `f32`; the
/// two agree to 1e-5): the rotation taking `b` to `e_z` applied to `o`. Near the antipode
/// (`1 + b_z` under 0.05, base normals facing away, where `f32` loses the quotient) and for inputs that do not normalise,
/// the `f64` path.
#[inline]
fn tangent_minimal(b: [f32; 3], o: [f32; 3]) -> [f32; 3] {
    let unit = |a: [f32; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        (l.is_finite() && l > 1e-12).then(|| a.map(|v| v / l))
    };
    let (Some(b), Some(o)) = (unit(b), unit(o)) else {
        return tangent_f64(&Frame::MinimalRotation, b, o);
    };
    let c = b[2];
    if 1.0 + c < 0.05 {
        return tangent_f64(&Frame::MinimalRotation, b, o);
    }
    // v = (−b_y, b_x, 0); result = c·o + o × v + v·(v·o)/(1 + c).
    let v = [-b[1], b[0]];
    let s = (v[0] * o[0] + v[1] * o[1]) / (1.0 + c);
    [
        c * o[0] - o[2] * v[1] + v[0] * s,
        c * o[1] + o[2] * v[0] + v[1] * s,
        c * o[2] + o[0] * v[1] - o[1] * v[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `f32` minimal-rotation tangent equals the `f64` one over normals of every direction
    /// (the antipode, unnormalised and zero vectors included).
    #[test]
    fn the_f32_minimal_tangent_equals_the_f64_one() {
        let mut seed = 7u32;
        let mut r = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0
        };
        let mut cases: Vec<([f32; 3], [f32; 3])> = (0..20_000)
            .map(|_| ([r(), r(), r()], [r(), r(), r() * 2.0]))
            .collect();
        cases.extend([
            ([0.0, 0.0, -1.0], [0.3, -0.2, 0.9]),
            ([1e-4, 0.0, -1.0], [0.3, -0.2, 0.9]),
            ([0.0, 0.0, 0.0], [0.3, -0.2, 0.9]),
            ([0.0, 0.0, 3.0], [0.0, 0.0, 0.0]),
            ([f32::NAN, 0.0, 1.0], [0.1, 0.1, 1.0]),
        ]);
        for (b, o) in cases {
            let fast = tangent_minimal(b, o);
            let slow = tangent_f64(&Frame::MinimalRotation, b, o);
            let err = (0..3)
                .map(|k| (fast[k] - slow[k]).abs())
                .fold(0.0, f32::max);
            assert!(err <= 1e-5, "{b:?} {o:?}: {fast:?} vs {slow:?}");
        }
    }
    use crate::ops::rotate::{rotation_combine, CombineMode, RotateParams};
    use crate::raster::gradient::GradientField;
    use crate::raster::sample::Surface;
    use proptest::prelude::*;

    fn textured(size: usize) -> RgbnImage {
        // A dome with a fine sinusoidal texture: the base should keep the dome.
        let dome = Surface::Gaussians {
            bumps: vec![[0.0, 0.0, 12.0, size as f64 / 5.0]],
        };
        let (img, _) = dome.render(size, size);
        let tex = Surface::Sinusoid {
            amplitude_px: 0.6,
            period_px: 5.0,
        };
        let (t, _) = tex.render(size, size);
        let g = GradientField::from_normals(&img);
        let gt = GradientField::from_normals(&t);
        let mut sum = g.clone();
        for i in 0..sum.p.len() {
            sum.p[i] += gt.p[i];
            sum.q[i] += gt.q[i];
        }
        let mut out = img.clone();
        sum.write_normals(&mut out);
        out
    }

    /// The filter of the module docs evaluated directly in `f64` with the true `exp` and `acos`,
    /// one pixel at a time: (normals, colours).
    fn reference(img: &RgbnImage, p: &BilateralParams) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let (w, h) = (img.width() as i64, img.height() as i64);
        let ss = f64::from(p.sigma_spatial_px as f32);
        let r = (2.0 * ss).ceil() as i64;
        let at = |x: i64, y: i64| (y * w + x) as usize;
        let nrm = |i: usize| img.normal().each_ref().map(|c| f64::from(c[i]));
        let col = |i: usize| img.color().each_ref().map(|c| f64::from(c[i]));
        let inside = |i: usize| img.mask().is_none_or(|m| m[i] >= 0.5);
        let grad = |n: [f64; 3]| {
            let nz = n[2].max(1e-3);
            [-n[0] / nz, -n[1] / nz]
        };
        let (mut on, mut oc) = (Vec::new(), Vec::new());
        for y in 0..h {
            for x in 0..w {
                let i = at(x, y);
                let (np, cp) = (nrm(i), col(i));
                if !inside(i) {
                    on.push(np);
                    oc.push(cp);
                    continue;
                }
                let (mut sp, mut sq, mut sw, mut sc) = (0.0, 0.0, 0.0, [0.0; 3]);
                for dy in -r..=r {
                    for dx in -r..=r {
                        let (xx, yy) = (x + dx, y + dy);
                        if dx * dx + dy * dy > r * r || xx < 0 || yy < 0 || xx >= w || yy >= h {
                            continue;
                        }
                        let j = at(xx, yy);
                        if !inside(j) {
                            continue;
                        }
                        let (nq, cq) = (nrm(j), col(j));
                        let mut e = (dx * dx + dy * dy) as f64 / (2.0 * ss * ss);
                        if p.sigma_color != 0.0 {
                            let s = f64::from(p.sigma_color as f32);
                            let d2: f64 = (0..3).map(|k| (cq[k] - cp[k]).powi(2)).sum();
                            e += d2 / (2.0 * s * s);
                        }
                        if p.sigma_normal != 0.0 {
                            let s = f64::from(p.sigma_normal as f32);
                            let (a, b) = (normalize3(np), normalize3(nq));
                            let dot = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
                            let d = match p.normal_metric {
                                NormalMetric::Angle => dot.acos(),
                                NormalMetric::OneMinusDot => 1.0 - dot,
                            };
                            e += d * d / (2.0 * s * s);
                        }
                        let wt = (-e).exp();
                        let [gp, gq] = grad(nq);
                        sp += wt * gp;
                        sq += wt * gq;
                        sw += wt;
                        for k in 0..3 {
                            sc[k] += wt * cq[k];
                        }
                    }
                }
                on.push(normalize3([-sp / sw, -sq / sw, 1.0]));
                oc.push(if p.filter_color {
                    sc.map(|c| c / sw)
                } else {
                    cp
                });
            }
        }
        (on, oc)
    }

    /// A random image: normals with `n_z ≥ 0.2`, colours in [0, 1], and with `masked` a mask
    /// of which about a fifth is < ½.
    fn random_image(w: usize, h: usize, seed: u64, masked: bool) -> RgbnImage {
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let n = w * h;
        let mut planes = [vec![0.0f32; n], vec![0.0; n], vec![0.0; n]];
        let mut color = [vec![0.0f32; n], vec![0.0; n], vec![0.0; n]];
        for i in 0..n {
            // Smooth-ish structure plus noise, so neighbours are often alike (weights near 1)
            // and sometimes not (weights near 0).
            let v = normalize3([
                f64::from(next() * 2.0 - 1.0),
                f64::from(next() * 2.0 - 1.0),
                f64::from(0.2 + next()),
            ]);
            for k in 0..3 {
                planes[k][i] = v[k] as f32;
                color[k][i] = ((i % w) as f32 / w as f32 + 0.2 * next()).fract();
            }
        }
        let mut img = RgbnImage::flat(w, h, [0.5; 3])
            .with_normals(planes)
            .unwrap();
        img.set_color(color).unwrap();
        if masked {
            img.set_mask(Some(
                (0..n).map(|_| next() + 0.3).map(|v| v.min(1.0)).collect(),
            ))
            .unwrap();
        }
        img
    }

    #[test]
    fn the_fast_filter_agrees_with_an_f64_brute_force_to_1e_5() {
        // 300 × 37 crosses a tile column boundary (256) and two band boundaries (16 rows).
        let cases = [
            (23, 17, 2.0, 0.1, 0.2, NormalMetric::Angle, false),
            (300, 37, 2.0, 0.1, 0.2, NormalMetric::Angle, true),
            (41, 29, 1.3, 0.0, 0.5, NormalMetric::OneMinusDot, true),
            (41, 29, 3.0, 0.3, 0.0, NormalMetric::Angle, false),
            (19, 40, 2.5, 0.0, 0.0, NormalMetric::Angle, true),
            (5, 3, 4.0, 0.2, 1.5, NormalMetric::Angle, true),
            // 150 rows: three bands of the symmetric kernel (64 rows each).
            (37, 150, 2.0, 0.15, 0.25, NormalMetric::Angle, true),
            // r = 34 > 32: the disc with one weight per tap.
            (45, 40, 17.0, 0.3, 0.8, NormalMetric::Angle, true),
        ];
        for (k, &(w, h, ss, sc, sn, metric, masked)) in cases.iter().enumerate() {
            let img = random_image(w, h, k as u64 + 1, masked);
            let p = BilateralParams {
                sigma_spatial_px: ss,
                sigma_color: sc,
                sigma_normal: sn,
                normal_metric: metric,
                filter_color: true,
                method: BilateralMethod::Exact,
                ..BilateralParams::default()
            };
            let (out, _) = bilateral(&img, &p).unwrap();
            let (rn, rc) = reference(&img, &p);
            let mut worst = 0.0f64;
            for i in 0..w * h {
                for c in 0..3 {
                    worst = worst
                        .max((f64::from(out.normal()[c][i]) - rn[i][c]).abs())
                        .max((f64::from(out.color()[c][i]) - rc[i][c]).abs());
                }
            }
            println!(
                "case {k} ({w}×{h}, σ_s {ss}, σ_c {sc}, σ_n {sn}, {metric:?}): max |Δ| {worst:.2e}"
            );
            assert!(worst <= 1e-5, "case {k}: {worst}");
        }
    }

    /// Mean and max angle (degrees) between the normals of two images.
    fn angle_stats(a: &RgbnImage, b: &RgbnImage) -> (f64, f64) {
        let n = a.len();
        let (mut sum, mut max) = (0.0f64, 0.0f64);
        for i in 0..n {
            let (u, v) = (
                a.normal().each_ref().map(|c| f64::from(c[i])),
                b.normal().each_ref().map(|c| f64::from(c[i])),
            );
            let d = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            sum += d;
            max = max.max(d);
        }
        (sum / n as f64, max)
    }

    #[test]
    fn the_sampled_disc_stays_close_to_the_exact_filter_at_wide_sigma() {
        // A dome with a fine texture (period 5 px) and a colour edge, filtered at σ_s = 8, 12
        // and 16: the sampled disc (stride 2, 3, 4) against the exact one. Its error is the one
        // the module docs state, measured against the change the filter makes.
        let img = {
            let mut img = textured(160);
            let n = img.len();
            let color: [Vec<f32>; 3] = std::array::from_fn(|k| {
                (0..n)
                    .map(|i| {
                        if (i % 160) < 70 {
                            0.2 + 0.3 * k as f32
                        } else {
                            0.9 - 0.3 * k as f32
                        }
                    })
                    .collect()
            });
            img.set_color(color).unwrap();
            img
        };
        for sigma in [8.0, 12.0, 16.0] {
            let p = BilateralParams {
                sigma_spatial_px: sigma,
                sigma_color: 0.2,
                sigma_normal: 0.3,
                ..BilateralParams::default()
            };
            assert_eq!(
                p.method.stride(sigma),
                (sigma / 4.0) as usize,
                "auto samples from 8 px"
            );
            let (approx, _) = bilateral(&img, &p).unwrap();
            let (exact, _) = bilateral(
                &img,
                &BilateralParams {
                    method: BilateralMethod::Exact,
                    ..p.clone()
                },
            )
            .unwrap();
            let (mean, max) = angle_stats(&approx, &exact);
            let (change, _) = angle_stats(&exact, &img);
            println!("σ_s {sigma}: sampled vs exact mean {mean:.3}° max {max:.3}°; exact vs input mean {change:.3}°");
            assert!(mean < 0.1 * change, "{mean} vs {change}");
            assert!(max < 6.0, "{max}");
        }
    }

    #[test]
    fn without_range_weights_it_is_the_gaussian_of_the_gradients_and_keeps_a_surface() {
        // A surface (normals from the differences of a sampled height, curl ≈ 0) stays a
        // surface: a linear filter of the gradients commutes with the curl. Averaging unit
        // normals would not keep it (the reason for the correction).
        let (img, _) = Surface::Gaussians {
            bumps: vec![[10.0, 6.0, 9.0, 5.0], [-12.0, -8.0, -6.0, 4.0]],
        }
        .render_sampled(96, 80);
        let before = GradientField::from_normals(&img).curl_stats(None).relative;
        let p = BilateralParams {
            sigma_spatial_px: 2.0,
            sigma_color: 0.0,
            sigma_normal: 0.0,
            ..BilateralParams::default()
        };
        let (out, rep) = bilateral(&img, &p).unwrap();
        println!(
            "curl relative before {before:.2e}, after {:.2e}",
            rep.curl_after.relative
        );
        assert!(before < 1e-5, "{before}");
        assert!(rep.curl_after.relative < 1e-5, "{:?}", rep.curl_after);
        // Steep flanks keep their slope better than with averaged normals.
        let g0 = GradientField::from_normals(&img);
        let g1 = GradientField::from_normals(&out);
        let energy = |g: &GradientField| g.p.iter().chain(&g.q).map(|v| v * v).sum::<f32>();
        assert!(energy(&g1) > 0.5 * energy(&g0));
    }

    #[test]
    fn split_and_rotation_combine_reconstruct_the_input() {
        let img = textured(64);
        for frame in [
            Frame::MinimalRotation,
            Frame::Oriented {
                orientation: [1.0, 0.3, 0.0],
            },
        ] {
            let params = BilateralParams {
                sigma_spatial_px: 2.5,
                sigma_normal: 0.4,
                ..BilateralParams::default()
            }
            .with_frame(&frame);
            let (base, detail, rep) = split(&img, &params).unwrap();
            println!("bilateral base curl: {:?}", rep.curl_after);
            assert!(rep.curl_after.rms_curl.is_finite());
            let (back, _) = rotation_combine(
                &base,
                &detail,
                None,
                None,
                &RotateParams {
                    mode: CombineMode::Blend,
                    saturate: false,
                    ..RotateParams::default()
                }
                .with_frame(&frame),
            )
            .unwrap();
            let err = (0..img.len())
                .map(|i| {
                    let (a, b) = (
                        back.normal_at(i % 64, i / 64),
                        img.normal_at(i % 64, i / 64),
                    );
                    (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0f32, f32::max)
                })
                .fold(0.0f32, f32::max);
            println!("split + combine reconstruction max error {err:e}");
            assert!(err <= 1e-4, "{err}");
        }
    }

    #[test]
    fn base_is_smoother_than_the_input_and_keeps_the_dome() {
        let img = textured(64);
        let p = BilateralParams {
            sigma_normal: 1.5,
            ..BilateralParams::default()
        };
        let (base, _) = bilateral(&img, &p).unwrap();
        let rough = |im: &RgbnImage| {
            let g = GradientField::from_normals(im);
            let mut s = 0.0f64;
            for r in 0..64 {
                for x in 0..63 {
                    s += f64::from(g.p[r * 64 + x + 1] - g.p[r * 64 + x]).powi(2);
                }
            }
            s
        };
        assert!(
            rough(&base) < 0.2 * rough(&img),
            "{} {}",
            rough(&base),
            rough(&img)
        );
        // The dome tilts normals outwards on its flanks: kept.
        assert!(base.normal_at(20, 32)[0] < -0.1);
        // Unit normals everywhere.
        for i in 0..base.len() {
            let n = base.normal_at(i % 64, i / 64);
            assert!((n.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn color_term_preserves_colour_edges() {
        // Left half red, right half blue; normals tilt oppositely in the two halves. With a
        // tight colour σ, a pixel next to the edge is not pulled by the other side.
        let (w, h) = (32, 8);
        let mut img = RgbnImage::flat(w, h, [1.0, 0.0, 0.0]);
        let s = 0.5f32.sqrt();
        for r in 0..h {
            for x in 0..w {
                let i = r * w + x;
                let right = x >= w / 2;
                let c = img.color_mut();
                if right {
                    c[0][i] = 0.0;
                    c[2][i] = 1.0;
                }
                let n = img.normal_mut();
                n[0][i] = if right { s } else { -s };
                n[2][i] = s;
            }
        }
        let p = BilateralParams {
            sigma_spatial_px: 3.0,
            sigma_color: 0.1,
            sigma_normal: 0.0,
            filter_color: true,
            ..BilateralParams::default()
        };
        let (out, _) = bilateral(&img, &p).unwrap();
        assert!((out.normal_at(w / 2 - 1, 4)[0] + s).abs() < 1e-4);
        assert!((out.color_at(w / 2, 4)[2] - 1.0).abs() < 1e-4);
        let (blurred, _) = bilateral(
            &img,
            &BilateralParams {
                sigma_color: 0.0,
                ..p
            },
        )
        .unwrap();
        assert!(blurred.normal_at(w / 2 - 1, 4)[0] > -s + 0.1);
    }

    #[test]
    fn bad_params_are_refused() {
        let img = RgbnImage::flat(4, 4, [0.5; 3]);
        for (p, needle) in [
            (
                BilateralParams {
                    sigma_spatial_px: -1.0,
                    ..BilateralParams::default()
                },
                "sigma_spatial_px",
            ),
            (
                BilateralParams {
                    sigma_color: f64::NAN,
                    ..BilateralParams::default()
                },
                "sigma_color",
            ),
            (
                BilateralParams {
                    sigma_normal: -1.0,
                    ..BilateralParams::default()
                },
                "sigma_normal",
            ),
        ] {
            let e = bilateral(&img, &p).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
    }

    #[test]
    fn real_data_split_and_combine_reconstruct_rosewood() {
        let Some(img) = crate::ops::geom::rosewood_crop(192) else {
            return;
        };
        let p = BilateralParams {
            sigma_spatial_px: 3.0,
            sigma_color: 0.1,
            sigma_normal: 0.2,
            ..BilateralParams::default()
        };
        let (base, detail, rep) = split(&img, &p).unwrap();
        let (back, _) = rotation_combine(
            &base,
            &detail,
            None,
            None,
            &RotateParams {
                saturate: false,
                ..RotateParams::default()
            },
        )
        .unwrap();
        let w = img.width();
        let err = (0..img.len())
            .map(|i| {
                let (a, b) = (back.normal_at(i % w, i / w), img.normal_at(i % w, i / w));
                (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0f32, f32::max)
            })
            .fold(0.0f32, f32::max);
        let before = GradientField::from_normals(&img).curl_stats(None);
        println!(
            "rosewood 192²: reconstruction max error {err:e}; curl input {:.3e}, base {:.3e}",
            before.relative, rep.curl_after.relative
        );
        assert!(err <= 1e-4, "{err}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        #[test]
        fn split_combine_reconstructs_arbitrary_images(
            vals in proptest::collection::vec((-1.0f32..1.0, -1.0f32..1.0, 0.1f32..1.0), 36)
        ) {
            let (w, h) = (6, 6);
            let mut img = RgbnImage::flat(w, h, [0.5; 3]);
            {
                let n = img.normal_mut();
                for (i, (x, y, z)) in vals.iter().enumerate() {
                    let v = normalize3([f64::from(*x), f64::from(*y), f64::from(*z)]);
                    n[0][i] = v[0] as f32;
                    n[1][i] = v[1] as f32;
                    n[2][i] = v[2] as f32;
                }
            }
            let (base, detail, _) = split(&img, &BilateralParams::default()).unwrap();
            let (back, _) = rotation_combine(&base, &detail, None, None,
                &RotateParams { saturate: false, ..RotateParams::default() }).unwrap();
            for i in 0..w * h {
                let (a, b) = (back.normal_at(i % w, i / w), img.normal_at(i % w, i / w));
                prop_assert!((0..3).all(|k| (a[k] - b[k]).abs() <= 1e-4), "{:?} {:?}", a, b);
            }
        }
    }
}
