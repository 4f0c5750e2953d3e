//! RGBN bilateral filter and base/detail split (Toler-Franklin et al. 2007; Pereira & Velho
//! §VII, Fig. 11).
//!
//! # Filter
//!
//! Each output normal is the normalised weighted mean of its neighbours within radius
//! `r = ⌈2σ_s⌉` (a windowed brute force: a bilateral filter is not separable):
//!
//! `n̂(P) = normalize( Σ_Q w_s(P,Q) · w_c(P,Q) · w_n(P,Q) · n(Q) )`
//!
//! - spatial `w_s = exp(−|P−Q|² / 2σ_s²)` (precomputed per offset),
//! - colour `w_c = exp(−|c(P) − c(Q)|² / 2σ_c²)` (linear RGB; skipped when `σ_c` is 0),
//! - normal similarity `w_n = exp(−δ² / 2σ_n²)` with `δ` the angle between the normals
//!   ([`NormalMetric::Angle`], radians) or `1 − n·n′` ([`NormalMetric::OneMinusDot`]).
//!
//! Pixels with mask coverage < ½ neither contribute nor change. Colour can be smoothed with the
//! same weights (`filter_color`). It is a nonlinear filter: the curl of the result is reported,
//! not guaranteed small.
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

use super::rotate::{normalize3, Frame, FrameKind};
use crate::error::RgbnError;
use crate::raster::buf;
use crate::raster::gradient::{CurlStats, GradientField};
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

crate::params! {
    /// Parameters of [`bilateral`] and [`split`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct BilateralParams {
        /// Spatial σ; the window has radius ⌈2σ⌉.
        pub sigma_spatial_px: f64 = 3.0
            => float.unit("px").range(0.05, f64::from(MAX_BILATERAL_SIGMA_PX)),
        /// Colour σ (linear RGB distance); 0 ignores colour.
        pub sigma_color: f64 = 0.0 => float.range(0.0, 1e6),
        /// Normal-similarity σ (radians for angle, unitless for one_minus_dot); 0 ignores normals.
        pub sigma_normal: f64 = f64::from(0.3f32) => float.range(0.0, 1e6),
        /// Normal similarity: the angle between the normals, or 1 − n·n′ (≈ angle²/2).
        pub normal_metric: NormalMetric = NormalMetric::Angle => choice,
        /// Also smooth the base's colour with the same weights.
        pub filter_color: bool = false => bool,
        /// Tangent frame of the base normal: minimal (shortest-arc rotation from +z; Blend = RNM) or oriented (tangent = orientation projected on the tangent plane).
        pub frame: FrameKind = FrameKind::Minimal => choice,
        /// Orientation vector of the oriented frame (x right, y up, z to the viewer).
        pub orientation: [f64; 3] = [1.0, 0.0, 0.0] => vec3.range(-1e6, 1e6),
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
        self.frame.frame(self.orientation)
    }
    /// These parameters with the detail frame `frame`.
    #[must_use]
    pub fn with_frame(mut self, frame: &Frame) -> Self {
        (self.frame, self.orientation) = FrameKind::of(frame, self.orientation);
        self
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        let s = self.sigma_spatial_px as f32;
        if !(s.is_finite() && s > 0.0 && s <= MAX_BILATERAL_SIGMA_PX) {
            return Err(RgbnError::param(
                "sigma_spatial_px",
                format!("{s} must be in (0, {MAX_BILATERAL_SIGMA_PX}] pixels"),
            ));
        }
        for (name, v) in [
            ("sigma_color", self.color_sigma()),
            ("sigma_normal", self.normal_sigma()),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0 && v <= 1e6) {
                    return Err(RgbnError::param(
                        name,
                        format!("{v} must be in (0, 1e6] (or 0 to ignore)"),
                    ));
                }
            }
        }
        self.detail_frame().validate()
    }
}

/// What the bilateral filter measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BilateralReport {
    /// Curl of the base's gradients (nonlinear filter: reported, not guaranteed small).
    pub curl_after: CurlStats,
}

/// The bilateral-filtered image (module docs). Colour is smoothed only with `filter_color`.
pub fn bilateral(
    img: &RgbnImage,
    params: &BilateralParams,
) -> Result<(RgbnImage, BilateralReport), RgbnError> {
    params.validate()?;
    let (w, h) = (img.width(), img.height());
    let sigma_spatial_px = params.sigma_spatial_px as f32;
    let rad = (2.0 * sigma_spatial_px).ceil() as isize;
    let side = (2 * rad + 1) as usize;
    let inv2s = 1.0 / (2.0 * sigma_spatial_px * sigma_spatial_px);
    let spatial: Vec<f32> = (0..side * side)
        .map(|k| {
            let (dx, dy) = ((k % side) as isize - rad, (k / side) as isize - rad);
            (-((dx * dx + dy * dy) as f32) * inv2s).exp()
        })
        .collect();
    let inv2c = params.color_sigma().map(|s| 1.0 / (2.0 * s * s));
    let inv2n = params.normal_sigma().map(|s| 1.0 / (2.0 * s * s));
    let metric = params.normal_metric;
    let (nrm, col, mask) = (img.normal(), img.color(), img.mask());
    let n = w * h;
    let mut out_n = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    let mut out_c = if params.filter_color {
        Some([buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)])
    } else {
        None
    };
    // Row results (normals, colours), computed in parallel then scattered.
    type Row = (Vec<[f32; 3]>, Vec<[f32; 3]>);
    let rows: Vec<Row> = (0..h)
        .into_par_iter()
        .map(|r| {
            let mut rn = vec![[0.0f32; 3]; w];
            let mut rc = vec![[0.0f32; 3]; if params.filter_color { w } else { 0 }];
            for x in 0..w {
                let i = r * w + x;
                let np = [nrm[0][i], nrm[1][i], nrm[2][i]];
                let cp = [col[0][i], col[1][i], col[2][i]];
                if mask.is_some_and(|m| m[i] < 0.5) {
                    rn[x] = np;
                    if params.filter_color {
                        rc[x] = cp;
                    }
                    continue;
                }
                let (mut acc, mut accc, mut wsum) = ([0.0f32; 3], [0.0f32; 3], 0.0f32);
                for dy in -rad..=rad {
                    let rr = r as isize + dy;
                    if rr < 0 || rr >= h as isize {
                        continue;
                    }
                    for dx in -rad..=rad {
                        let xx = x as isize + dx;
                        if xx < 0 || xx >= w as isize {
                            continue;
                        }
                        let j = rr as usize * w + xx as usize;
                        if mask.is_some_and(|m| m[j] < 0.5) {
                            continue;
                        }
                        let mut wt = spatial[((dy + rad) as usize) * side + (dx + rad) as usize];
                        let nq = [nrm[0][j], nrm[1][j], nrm[2][j]];
                        if let Some(k) = inv2c {
                            let d2 = (0..3).map(|c| (col[c][j] - cp[c]).powi(2)).sum::<f32>();
                            wt *= (-d2 * k).exp();
                        }
                        if let Some(k) = inv2n {
                            let dot =
                                (np[0] * nq[0] + np[1] * nq[1] + np[2] * nq[2]).clamp(-1.0, 1.0);
                            let d = match metric {
                                NormalMetric::Angle => dot.acos(),
                                NormalMetric::OneMinusDot => 1.0 - dot,
                            };
                            wt *= (-d * d * k).exp();
                        }
                        if !wt.is_finite() {
                            continue;
                        }
                        for c in 0..3 {
                            acc[c] += wt * nq[c];
                        }
                        if params.filter_color {
                            for c in 0..3 {
                                accc[c] += wt * col[c][j];
                            }
                        }
                        wsum += wt;
                    }
                }
                let v = normalize3([f64::from(acc[0]), f64::from(acc[1]), f64::from(acc[2])]);
                let len2 = acc.iter().map(|a| a * a).sum::<f32>();
                rn[x] = if len2 > 1e-20 && len2.is_finite() {
                    [v[0] as f32, v[1] as f32, v[2] as f32]
                } else {
                    np
                };
                if params.filter_color {
                    rc[x] = if wsum > 0.0 {
                        accc.map(|a| a / wsum)
                    } else {
                        cp
                    };
                }
            }
            (rn, rc)
        })
        .collect();
    for (r, (rn, rc)) in rows.into_iter().enumerate() {
        for x in 0..w {
            for c in 0..3 {
                out_n[c][r * w + x] = rn[x][c];
            }
            if let Some(oc) = out_c.as_mut() {
                for c in 0..3 {
                    oc[c][r * w + x] = rc[x][c];
                }
            }
        }
    }
    let mut out = img.with_normals(out_n)?;
    if let Some(c) = out_c {
        out.set_color(c)?;
    }
    let curl_after = GradientField::from_normals(&out).curl_stats(out.mask());
    Ok((out, BilateralReport { curl_after }))
}

/// Splits an image into `(base, detail)` (module docs): base = [`bilateral`], detail normals =
/// `Fᵀ(n̂) n` in the base's frame (`params.frame`, `params.orientation`), detail colour = the input's.
pub fn split(
    img: &RgbnImage,
    params: &BilateralParams,
) -> Result<(RgbnImage, RgbnImage, BilateralReport), RgbnError> {
    let (base, report) = bilateral(img, params)?;
    let frame = params.detail_frame();
    let (bn, on) = (base.normal(), img.normal());
    let n = img.len();
    let mut d = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
    let [dx, dy, dz] = &mut d;
    dx.par_iter_mut()
        .zip(dy.par_iter_mut())
        .zip(dz.par_iter_mut())
        .enumerate()
        .for_each(|(i, ((x, y), z))| {
            let b = normalize3([
                f64::from(bn[0][i]),
                f64::from(bn[1][i]),
                f64::from(bn[2][i]),
            ]);
            let o = normalize3([
                f64::from(on[0][i]),
                f64::from(on[1][i]),
                f64::from(on[2][i]),
            ]);
            let t = frame.to_tangent(b, o);
            (*x, *y, *z) = (t[0] as f32, t[1] as f32, t[2] as f32);
        });
    let detail = img.with_normals(d)?;
    Ok((base, detail, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::rotate::{rotation_combine, CombineMode, RotateParams};
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
                "(0, 1e6]",
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
