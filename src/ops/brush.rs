//! Local filter brush (Pereira & Velho §III, Fig. 1): apply any linear gradient filter (a list
//! of [`Kernel`]s from [`super::filter`]) only inside a painted region, blended smoothly into
//! the untouched outside.
//!
//! The region weight `m ∈ [0, 1]` is the union (max) of
//! - brush **strokes**: polylines in pixel coordinates `(x, row)` with a radius and a feather;
//!   with `d` the distance to the stroke, `m = 1 − S(r, r + f, d)` (quintic smoothstep `S`:
//!   full strength within the radius, fading to 0 over the feather), and
//! - an optional **mask plane** (e.g. painted elsewhere), values in `[0, 1]`.
//!
//! Result: `g′ = m·K(g) + (1 − m)·g` where `K` is the filter chain applied to the whole field
//! (optionally mask-aware inside the image's own mask, see [`FilterOptions`]).
//!
//! **Integrability.** The blend multiplies a gradient field by a varying weight: `curl(m·(Kg −
//! g)) = ∇m × (Kg − g)`, non-zero across the feather wherever the filter changed the slopes.
//! The brush therefore breaks integrability in its transition band in general; it reports the
//! measured curl (before and after) instead of hiding it. (Integrate-and-reproject, e.g. a
//! Poisson solve, is the remedy when an exactly integrable result is needed.)
//!
//! # References
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §III, Fig. 1.

use super::combine::check_weight;
use super::filter::{filter_gradients, FilterOptions, Kernel, SIGMA_RANGE, SIGMA_SOFT};
use super::geom::{check_points, smoothstep, Polyline};
use crate::error::RgbnError;
use crate::raster::convolve::BorderMode;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// Largest brush radius or feather (pixels).
pub const MAX_BRUSH_PX: f32 = 10_000.0;

/// One brush stroke: a polyline swept by a disc.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BrushStroke {
    /// Points in pixel coordinates `(x, row)`; a single point is a dab.
    pub points: Vec<[f32; 2]>,
    /// Full-strength radius (pixels), ≥ 0.
    pub radius_px: f32,
    /// Width of the smooth fade beyond the radius (pixels), ≥ 0.
    pub feather_px: f32,
}

impl Default for BrushStroke {
    fn default() -> Self {
        Self {
            points: vec![[32.0, 32.0]],
            radius_px: 8.0,
            feather_px: 4.0,
        }
    }
}

impl BrushStroke {
    /// Checks points, radius and feather.
    pub fn validate(&self) -> Result<(), RgbnError> {
        check_points("points", &self.points, 1)?;
        for (name, v) in [
            ("radius_px", self.radius_px),
            ("feather_px", self.feather_px),
        ] {
            if !(v.is_finite() && (0.0..=MAX_BRUSH_PX).contains(&v)) {
                return Err(RgbnError::param(
                    name,
                    format!("{v} must be in [0, {MAX_BRUSH_PX}] pixels"),
                ));
            }
        }
        if self.radius_px + self.feather_px <= 0.0 {
            return Err(RgbnError::param(
                "radius_px",
                "radius_px + feather_px must be > 0 (the stroke would cover nothing)",
            ));
        }
        Ok(())
    }
}

/// Parameters of [`brush_filter`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BrushParams {
    /// The filter chain, applied in order.
    pub kernels: Vec<Kernel>,
    /// Strokes painting the region (may be empty when a mask plane is given).
    pub strokes: Vec<BrushStroke>,
    pub filter: FilterOptions,
}

impl Default for BrushParams {
    fn default() -> Self {
        Self {
            kernels: vec![Kernel::Gaussian { sigma_px: 3.0 }],
            strokes: vec![BrushStroke::default()],
            filter: FilterOptions::default(),
        }
    }
}

impl BrushParams {
    /// Checks every kernel and stroke (at least one kernel).
    pub fn validate(&self) -> Result<(), RgbnError> {
        if self.kernels.is_empty() {
            return Err(RgbnError::param("kernels", "needs at least one kernel"));
        }
        for k in &self.kernels {
            k.validate()?;
        }
        for s in &self.strokes {
            s.validate()?;
        }
        Ok(())
    }
}

crate::choice_enum! {
    /// The one linear kernel a [`SimpleBrushParams`] paints (as the `filter.*` nodes).
    pub enum BrushKernel {
        /// Gaussian blur of σ `sigma_px`.
        Gaussian = "gaussian",
        /// Box blur of half-width `box_radius_px`.
        Box = "box",
        /// Unsharp masking: σ `sigma_px`, `amount`.
        Sharpen = "sharpen",
        /// Edge enhancement (DoG boost): σ `sigma_px` and `sigma_coarse_px`, `amount`.
        Edge = "edge",
        /// High-pass `I − G_σ` of σ `sigma_px`.
        HighPass = "highpass",
        /// Difference of Gaussians of σ `sigma_px` and `sigma_coarse_px`.
        DoG = "dog",
        /// Scale-normalised Laplacian of Gaussian of σ `sigma_px`.
        LoG = "log",
        /// Depth scale by the factor `amount`.
        Scale = "scale",
    }
}

crate::params! {
    /// One kernel painted along one stroke and/or a mask (the brush node's parameters), adapted
    /// to [`BrushParams`] by [`SimpleBrushParams::to_params`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct SimpleBrushParams {
        /// The linear filter painted with the brush (as the filter.* nodes): gaussian, box, sharpen, edge, highpass, dog, log, scale.
        pub kernel: BrushKernel = BrushKernel::Gaussian => choice,
        /// σ of the kernel (the finer σ of edge and dog).
        pub sigma_px: f64 = 3.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// Coarser σ of edge and dog (must exceed sigma_px).
        pub sigma_coarse_px: f64 = 6.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// Amount of sharpen and edge; the depth factor of scale.
        pub amount: f64 = 1.0 => float.range(-100.0, 100.0).soft(-2.0, 4.0),
        /// Half-width of the box kernel.
        pub box_radius_px: i64 = 2 => int.unit("px").range(1.0, 4096.0).soft(1.0, 32.0).log(),
        /// The stroke: a polyline in pixels (x, row); one point is a dab; empty when only the mask input paints the region.
        pub points: Vec<[f64; 2]> = vec![[32.0, 32.0]] => points.unit("px"),
        /// Full-strength radius around the stroke.
        pub radius_px: f64 = 8.0 => float.unit("px").range(0.0, 10_000.0).soft(0.0, 64.0),
        /// Width of the smooth (quintic) fade beyond the radius.
        pub feather_px: f64 = 4.0 => float.unit("px").range(0.0, 10_000.0).soft(0.0, 32.0),
        /// How the image is extended beyond its border.
        pub border: BorderMode = BorderMode::Mirror => choice,
        /// Filter inside the image's own mask only (normalised convolution).
        pub mask_aware: bool = false => bool,
    }
}

impl SimpleBrushParams {
    /// The kernel chosen, with its parameters.
    #[must_use]
    pub fn kernel(&self) -> Kernel {
        let (s, c, a) = (
            self.sigma_px as f32,
            self.sigma_coarse_px as f32,
            self.amount as f32,
        );
        match self.kernel {
            BrushKernel::Gaussian => Kernel::Gaussian { sigma_px: s },
            BrushKernel::Box => Kernel::Box {
                radius_px: self.box_radius_px.clamp(0, i64::from(u32::MAX)) as u32,
            },
            BrushKernel::Sharpen => Kernel::Sharpen {
                sigma_px: s,
                amount: a,
            },
            BrushKernel::Edge => Kernel::EdgeEnhance {
                sigma_fine_px: s,
                sigma_coarse_px: c,
                amount: a,
            },
            BrushKernel::HighPass => Kernel::HighPass { sigma_px: s },
            BrushKernel::DoG => Kernel::DoG {
                sigma_fine_px: s,
                sigma_coarse_px: c,
            },
            BrushKernel::LoG => Kernel::LoG { sigma_px: s },
            BrushKernel::Scale => Kernel::DepthScale { scale: a },
        }
    }

    /// The [`brush_filter`] parameters (one kernel, at most one stroke), checked; errors name
    /// these parameters.
    pub fn to_params(&self) -> Result<BrushParams, RgbnError> {
        let strokes = if self.points.is_empty() {
            Vec::new()
        } else {
            vec![BrushStroke {
                points: self.points.iter().map(|p| p.map(|v| v as f32)).collect(),
                radius_px: self.radius_px as f32,
                feather_px: self.feather_px as f32,
            }]
        };
        let p = BrushParams {
            kernels: vec![self.kernel()],
            strokes,
            filter: FilterOptions {
                border: self.border,
                mask_aware: self.mask_aware,
            },
        };
        p.validate().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "sigma_fine_px" => {
                RgbnError::param("sigma_px", detail)
            }
            RgbnError::InvalidParam { name, detail } if name == "scale" => {
                RgbnError::param("amount", detail)
            }
            other => other,
        })?;
        Ok(p)
    }
}

/// The region weight of some strokes on a `width × height` grid (module docs).
pub fn stroke_mask(
    width: usize,
    height: usize,
    strokes: &[BrushStroke],
) -> Result<Plane, RgbnError> {
    for s in strokes {
        s.validate()?;
    }
    let lines: Vec<(Polyline, f64, f64)> = strokes
        .iter()
        .map(|s| {
            (
                Polyline::new(&s.points, false),
                f64::from(s.radius_px),
                f64::from(s.feather_px),
            )
        })
        .collect();
    Ok(Plane::from_fn(width, height, |x, r| {
        let p = [x as f64, r as f64];
        let mut m = 0.0f64;
        for (pl, rad, fe) in &lines {
            let b = pl.bounds();
            let reach = rad + fe;
            if p[0] < b[0] - reach
                || p[0] > b[2] + reach
                || p[1] < b[1] - reach
                || p[1] > b[3] + reach
            {
                continue;
            }
            if let Some(pr) = pl.project(p) {
                let w = if *fe > 0.0 {
                    1.0 - smoothstep(*rad, rad + fe, pr.dist_px)
                } else {
                    f64::from(u8::from(pr.dist_px <= *rad))
                };
                m = m.max(w);
            }
        }
        m as f32
    }))
}

/// What the brush measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrushReport {
    pub curl_before: CurlStats,
    /// Curl after the brush (the feather band generally adds curl; module docs).
    pub curl_after: CurlStats,
    /// The region weight actually used.
    pub region: Option<Plane>,
}

/// Applies the brush to a gradient field (module docs). `mask` is an extra region plane
/// (values in [0, 1]) united with the strokes; `image_mask` is the image's coverage for
/// mask-aware filtering.
pub fn brush_filter(
    g: &GradientField,
    mask: Option<&Plane>,
    image_mask: Option<&[f32]>,
    params: &BrushParams,
) -> Result<(GradientField, BrushReport), RgbnError> {
    params.validate()?;
    let (w, h) = (g.width, g.height);
    if let Some(m) = mask {
        check_weight(m, (w, h))?;
    }
    if params.strokes.is_empty() && mask.is_none() {
        return Err(RgbnError::param(
            "strokes",
            "the region is empty: give at least one stroke or a mask plane",
        ));
    }
    let mut region = stroke_mask(w, h, &params.strokes)?;
    if let Some(m) = mask {
        region
            .data_mut()
            .par_iter_mut()
            .zip(m.data().par_iter())
            .for_each(|(a, b)| *a = a.max(*b));
    }
    let mut filtered = g.clone();
    filter_gradients(&mut filtered, &params.kernels, &params.filter, image_mask)?;
    let rm = region.data();
    for (f, o) in [(&mut filtered.p, &g.p), (&mut filtered.q, &g.q)] {
        f.par_iter_mut()
            .zip(o.par_iter().zip(rm.par_iter()))
            .for_each(|(f, (o, m))| *f = m * *f + (1.0 - m) * o);
    }
    let report = BrushReport {
        curl_before: g.curl_stats(image_mask),
        curl_after: filtered.curl_stats(image_mask),
        region: Some(region),
    };
    Ok((filtered, report))
}

/// [`brush_filter`] on an image's normals (colour and mask kept).
pub fn brush_image(
    img: &RgbnImage,
    mask: Option<&Plane>,
    params: &BrushParams,
) -> Result<(RgbnImage, BrushReport), RgbnError> {
    let g = GradientField::from_normals(img);
    let (f, rep) = brush_filter(&g, mask, img.mask(), params)?;
    let mut out = img.clone();
    f.write_normals(&mut out);
    Ok((out, rep))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::Surface;

    #[test]
    fn brush_changes_only_the_painted_region_and_reports_curl() {
        let size = 96;
        let (img, _) = Surface::Sinusoid {
            amplitude_px: 2.0,
            period_px: 8.0,
        }
        .render(size, size);
        let p = BrushParams {
            kernels: vec![Kernel::Gaussian { sigma_px: 3.0 }],
            strokes: vec![BrushStroke {
                points: vec![[20.0, 48.0], [60.0, 48.0]],
                radius_px: 8.0,
                feather_px: 6.0,
            }],
            filter: FilterOptions::default(),
        };
        let (out, rep) = brush_image(&img, None, &p).unwrap();
        // Far from the stroke: untouched.
        assert_eq!(out.normal_at(80, 10), img.normal_at(80, 10));
        // On the stroke: smoothed (a 8-px sinusoid blurred by σ=3 almost vanishes).
        let g = GradientField::from_normals(&out);
        let g0 = GradientField::from_normals(&img);
        let i = 48 * size + 40;
        assert!(
            g.p[i].abs() < 0.2 * g0.p[i].abs().max(0.5),
            "{} {}",
            g.p[i],
            g0.p[i]
        );
        println!(
            "brush curl before {:?} after {:?}",
            rep.curl_before, rep.curl_after
        );
        assert!(rep.curl_after.rms_curl.is_finite() && rep.curl_after.rms_curl > 0.0);
        let region = rep.region.unwrap();
        assert_eq!(region.at(40, 48), 1.0);
        assert_eq!(region.at(40, 10), 0.0);
        let half = region.at(40, 48 - 11);
        assert!(half > 0.0 && half < 1.0, "feathered: {half}");
    }

    #[test]
    fn a_mask_plane_is_united_with_the_strokes() {
        let size = 32;
        let g = GradientField::from_height(&Plane::from_fn(size, size, |x, r| {
            ((x * 3 + r * 5) % 7) as f32
        }));
        let mask = Plane::from_fn(size, size, |x, _| f32::from(u8::from(x < 8)));
        let p = BrushParams {
            strokes: vec![],
            ..BrushParams::default()
        };
        let (f, rep) = brush_filter(&g, Some(&mask), None, &p).unwrap();
        assert_eq!(f.p[5 * size + 20], g.p[5 * size + 20]);
        assert_ne!(f.p[5 * size + 3], g.p[5 * size + 3]);
        assert!(rep.curl_after.relative.is_finite());
    }

    #[test]
    fn bad_params_are_refused() {
        let g = GradientField::zeros(8, 8);
        for (p, needle) in [
            (
                BrushParams {
                    kernels: vec![],
                    ..BrushParams::default()
                },
                "kernels",
            ),
            (
                BrushParams {
                    strokes: vec![BrushStroke {
                        radius_px: -1.0,
                        ..BrushStroke::default()
                    }],
                    ..BrushParams::default()
                },
                "radius_px",
            ),
            (
                BrushParams {
                    strokes: vec![BrushStroke {
                        points: vec![],
                        ..BrushStroke::default()
                    }],
                    ..BrushParams::default()
                },
                "at least 1 point",
            ),
            (
                BrushParams {
                    strokes: vec![],
                    ..BrushParams::default()
                },
                "region is empty",
            ),
            (
                BrushParams {
                    kernels: vec![Kernel::Gaussian { sigma_px: f32::NAN }],
                    ..BrushParams::default()
                },
                "sigma_px",
            ),
        ] {
            let e = brush_filter(&g, None, None, &p).unwrap_err().to_string();
            assert!(e.contains(needle), "{needle}: {e}");
        }
    }
}
