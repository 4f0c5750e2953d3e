//! Linear combine of gradient fields (Pereira & Velho §IV): add a detail's relief to a base.
//!
//! With base gradients `∇b`, detail gradients `∇h`, a weight (region) `m ∈ [0, 1]` per pixel
//! and a global amount `α`:
//!
//! - plain: `w = ∇b + α·m·∇h`;
//! - **replace band** `B` (a [`Band`] of [`super::band`]): `w = ∇b − m·B(∇b) + α·m·B(∇h)` —
//!   the base loses its own band where the detail goes, and gets the detail's band instead.
//!
//! Converted back to normals, the plain sum with `α = m = 1` is exactly the "partial
//! derivative" blend of Barré-Brisebois & Hill (2012): `normalize(n₁ₓᵧ n₂_z + n₂ₓᵧ n₁_z,
//! n₁_z n₂_z)` is `normalize(−(p₁+p₂), −(q₁+q₂), 1)` scaled by `n₁_z n₂_z`.
//!
//! **Integrability.** Sums of gradients of heights are gradients of the summed height, and the
//! band kernels are linear, so with a *constant* weight the result is as integrable as the
//! inputs (curl ≈ 0 away from the borders). A spatially varying weight multiplies a gradient
//! field by `m`, and `curl(m ∇h) = ∇m × ∇h ≠ 0` where the weight varies across the detail's
//! slopes; the report gives the measured curl. (The integrable alternative, `∇(m·h)`, needs
//! the detail's height: [`linear_combine_height`] takes the detail as a height and adds
//! `α ∇(m·h)`, integrable for any weight; [`super::stamp`] integrates its stamp for the same
//! reason.)
//!
//! # References
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §IV.
//! - C. Barré-Brisebois, S. Hill, "Blending in Detail", 2012.

use super::band::{apply_band, Band, BandKind, BandOp};
use super::filter::{SIGMA_RANGE, SIGMA_SOFT};
use crate::error::RgbnError;
use crate::params::Choice;
use crate::raster::convolve::BorderMode;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// Largest |α| accepted.
pub const MAX_ALPHA: f32 = 1000.0;

crate::choice_enum! {
    /// The band of the base a linear combine replaces by the detail's.
    pub enum ReplaceBand {
        /// None: plain addition.
        None = "none",
        /// Low-pass `G_σ`.
        LowPass = "lowpass",
        /// High-pass `I − G_σ`.
        HighPass = "highpass",
        /// Band-pass `G_σ − G_coarse` (DoG).
        BandPass = "bandpass",
        /// Laplacian of Gaussian `−σ²∇²G_σ`.
        LoG = "log",
    }
}

impl ReplaceBand {
    /// The band kind (`None` for plain addition).
    #[must_use]
    pub fn kind(self) -> Option<BandKind> {
        match self {
            ReplaceBand::None => None,
            ReplaceBand::LowPass => Some(BandKind::LowPass),
            ReplaceBand::HighPass => Some(BandKind::HighPass),
            ReplaceBand::BandPass => Some(BandKind::BandPass),
            ReplaceBand::LoG => Some(BandKind::LoG),
        }
    }
}

crate::params! {
    /// Parameters of [`linear_combine`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct LinearCombineParams {
        /// Amount of detail α (1 = as is, negative inverts the detail's relief).
        pub alpha: f64 = 1.0 => float.range(-1000.0, 1000.0).soft(-2.0, 4.0),
        /// none: w = ∇b + α·m·∇h; otherwise the base loses this band where the detail goes and
        /// gets the detail's band: w = ∇b − m·B(∇b) + α·m·B(∇h).
        pub replace_band: ReplaceBand = ReplaceBand::None => choice,
        /// σ of the band (low-pass, high-pass, LoG), or the finer σ of a band-pass.
        pub sigma_px: f64 = 1.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// The coarser σ of a band-pass (must exceed sigma_px); unused by the others.
        pub sigma_coarse_px: f64 = 4.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// How the image is extended beyond its border.
        pub border: BorderMode = BorderMode::Mirror => choice,
    }
}

impl LinearCombineParams {
    /// The band replaced (`None` = plain addition), checked.
    pub fn band(&self) -> Result<Option<Band>, RgbnError> {
        self.replace_band
            .kind()
            .map(|k| k.band(self.sigma_px, self.sigma_coarse_px))
            .transpose()
    }

    /// These parameters replacing `band` (`None` = plain addition).
    #[must_use]
    pub fn with_band(mut self, band: Option<&Band>) -> Self {
        self.replace_band = ReplaceBand::None;
        if let Some(b) = band {
            let (kind, s, c) = b.parts();
            self.replace_band = ReplaceBand::from_name(kind.name()).unwrap_or_default();
            (self.sigma_px, self.sigma_coarse_px) = (s, c);
        }
        self
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        let alpha = self.alpha as f32;
        if !(alpha.is_finite() && alpha.abs() <= MAX_ALPHA) {
            return Err(RgbnError::param(
                "alpha",
                format!("{alpha} must be finite, in [-{MAX_ALPHA}, {MAX_ALPHA}]"),
            ));
        }
        self.band().map(|_| ())
    }
}

pub(crate) fn check_same_size(
    what: &'static str,
    want: (usize, usize),
    got: (usize, usize),
) -> Result<(), RgbnError> {
    if want != got {
        return Err(RgbnError::SizeMismatch {
            what,
            want_w: want.0,
            want_h: want.1,
            got_w: got.0,
            got_h: got.1,
            path: "".into(),
        });
    }
    Ok(())
}

/// Checks a weight plane: same size, values finite in `[0, 1]`.
pub(crate) fn check_weight(weight: &Plane, want: (usize, usize)) -> Result<(), RgbnError> {
    check_same_size("weight", want, (weight.width(), weight.height()))?;
    if let Some(v) = weight
        .data()
        .iter()
        .find(|v| !(v.is_finite() && (0.0..=1.0).contains(*v)))
    {
        return Err(RgbnError::param(
            "weight",
            format!("value {v} must be finite, in [0, 1]"),
        ));
    }
    Ok(())
}

/// `∇b + α·m·∇h`, or with a band `∇b − m·B(∇b) + α·m·B(∇h)` (module docs). `weight` = `m`
/// (default 1 everywhere).
pub fn linear_combine(
    base: &GradientField,
    detail: &GradientField,
    weight: Option<&Plane>,
    params: &LinearCombineParams,
) -> Result<GradientField, RgbnError> {
    params.validate()?;
    let size = (base.width, base.height);
    check_same_size("detail", size, (detail.width, detail.height))?;
    if let Some(m) = weight {
        check_weight(m, size)?;
    }
    let (base_band, det) = match &params.band()? {
        Some(band) => {
            let keep = |g| apply_band(g, band, BandOp::Keep, params.border);
            (Some(keep(base)?), keep(detail)?)
        }
        None => (None, detail.clone()),
    };
    let alpha = params.alpha as f32;
    let mut out = base.clone();
    for (k, o) in [&mut out.p, &mut out.q].into_iter().enumerate() {
        let d = if k == 0 { &det.p } else { &det.q };
        let bb = base_band.as_ref().map(|b| if k == 0 { &b.p } else { &b.q });
        o.par_iter_mut().enumerate().for_each(|(i, v)| {
            let m = weight.map_or(1.0, |m| m.data()[i]);
            let remove = bb.map_or(0.0, |b| b[i]);
            *v += m * (alpha * d[i] - remove);
        });
    }
    out.clamped = base.clamped + detail.clamped;
    Ok(out)
}

/// The integrable variant for a detail given as a **height** `h`: `w = ∇b + α ∇(m·h)` (the
/// gradient of `m·h` by [`GradientField::of_height`]), with the band (if
/// any) applied to the height: `B(h)` for the detail and `m·B(∇b)` removed from the base.
/// With a varying weight, only the base-band removal (`m·B(∇b)`) can add curl; without
/// `replace_band` the result is exactly as integrable as the base, for any weight.
pub fn linear_combine_height(
    base: &GradientField,
    detail_height: &Plane,
    weight: Option<&Plane>,
    params: &LinearCombineParams,
) -> Result<GradientField, RgbnError> {
    params.validate()?;
    let size = (base.width, base.height);
    check_same_size(
        "detail_height",
        size,
        (detail_height.width(), detail_height.height()),
    )?;
    if let Some(m) = weight {
        check_weight(m, size)?;
    }
    if let Some(v) = detail_height.data().iter().find(|v| !v.is_finite()) {
        return Err(RgbnError::param(
            "detail_height",
            format!("value {v} must be finite"),
        ));
    }
    let mut h = detail_height.clone();
    let mut out = base.clone();
    if let Some(band) = &params.band()? {
        let filter_plane = |data: &mut Plane| -> Result<(), RgbnError> {
            // A plane filtered as the p-component of a field (q unused).
            let mut g = GradientField::zeros(data.width(), data.height());
            g.p.copy_from_slice(data.data());
            let f = apply_band(&g, band, BandOp::Keep, params.border)?;
            data.data_mut().copy_from_slice(&f.p);
            Ok(())
        };
        filter_plane(&mut h)?;
        let bb = apply_band(base, band, BandOp::Keep, params.border)?;
        for (o, b) in [(&mut out.p, &bb.p), (&mut out.q, &bb.q)] {
            o.par_iter_mut().enumerate().for_each(|(i, v)| {
                *v -= weight.map_or(1.0, |m| m.data()[i]) * b[i];
            });
        }
    }
    let alpha = params.alpha as f32;
    if let Some(m) = weight {
        h.data_mut()
            .par_iter_mut()
            .zip(m.data().par_iter())
            .for_each(|(v, m)| *v *= m);
    }
    let d = GradientField::of_height(&h).0;
    out.p
        .par_iter_mut()
        .zip(d.p.par_iter())
        .for_each(|(o, d)| *o += alpha * d);
    out.q
        .par_iter_mut()
        .zip(d.q.par_iter())
        .for_each(|(o, d)| *o += alpha * d);
    Ok(out)
}

/// What [`linear_combine_images`] measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CombineReport {
    /// Pixels of either input whose `n_z` was clamped converting to gradients.
    pub clamped: usize,
    /// Curl of the combined gradients (over the base's mask).
    pub curl_after: CurlStats,
}

/// [`linear_combine`] on the normals of two images; colour and mask come from `base`.
pub fn linear_combine_images(
    base: &RgbnImage,
    detail: &RgbnImage,
    weight: Option<&Plane>,
    params: &LinearCombineParams,
) -> Result<(RgbnImage, CombineReport), RgbnError> {
    params.validate()?;
    check_same_size(
        "detail",
        (base.width(), base.height()),
        (detail.width(), detail.height()),
    )?;
    let g = linear_combine(
        &GradientField::from_normals(base),
        &GradientField::from_normals(detail),
        weight,
        params,
    )?;
    let mut out = base.clone();
    g.write_normals(&mut out);
    Ok((
        out,
        CombineReport {
            clamped: g.clamped,
            curl_after: g.curl_stats(base.mask()),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::rotate::{combine_one, CombineMode, RotateParams};
    use crate::raster::sample::Surface;

    fn height_field(s: &Surface, size: usize) -> GradientField {
        let (_, z) = s.render(size, size);
        GradientField::of_height(&z).0
    }

    #[test]
    fn linear_combine_equals_partial_derivative_blend() {
        let n1 = [0.3f32, 0.4, 0.866];
        let l = (0.04f32 + 0.01 + 0.97 * 0.97).sqrt();
        let n2 = [-0.2 / l, 0.1 / l, 0.97 / l];
        let mut a = RgbnImage::flat(1, 1, [0.5; 3]);
        let mut b = a.clone();
        for k in 0..3 {
            a.normal_mut()[k][0] = n1[k];
            b.normal_mut()[k][0] = n2[k];
        }
        let (out, _) =
            linear_combine_images(&a, &b, None, &LinearCombineParams::default()).unwrap();
        let n = out.normal_at(0, 0);
        let want = [0.1212f32, 0.4883, 0.8642];
        assert!((0..3).all(|k| (n[k] - want[k]).abs() <= 1e-4), "{n:?}");
        let (pd, _) = combine_one(
            n1,
            n2,
            n1,
            1.0,
            &RotateParams {
                mode: CombineMode::PartialDerivative,
                ..RotateParams::default()
            },
        );
        assert!((0..3).all(|k| (n[k] - pd[k]).abs() <= 1e-5), "{n:?} {pd:?}");
    }

    #[test]
    fn combine_of_integrable_fields_is_integrable() {
        let size = 160;
        let base = height_field(&Surface::gaussians_for(size), size);
        // Periodic detail (16 whole periods) with wrap-around forward differences, so that the
        // band kernels' wrap border extension is integrable too.
        let (_, z) = Surface::Sinusoid {
            amplitude_px: 1.5,
            period_px: 10.0,
        }
        .render(size, size);
        let mut detail = GradientField::zeros(size, size);
        for r in 0..size {
            for x in 0..size {
                let i = r * size + x;
                // z at the pixel corners (periodic), 2 × 2 differences: exactly integrable
                // in the averaged model (`GradientField::from_corner_heights`).
                let (x1, r1) = ((x + 1) % size, (r + 1) % size);
                let (tl, tr, bl, br) = (z.at(x, r), z.at(x1, r), z.at(x, r1), z.at(x1, r1));
                detail.p[i] = 0.5 * ((tr - tl) + (br - bl));
                detail.q[i] = 0.5 * ((tl - bl) + (tr - br));
            }
        }
        // The detail reaches the border: a periodic border (16 whole periods) keeps the band
        // kernels' border extension integrable.
        for replace_band in [
            None,
            Some(Band::HighPass { sigma_px: 2.0 }),
            Some(Band::BandPass {
                sigma_fine_px: 1.0,
                sigma_coarse_px: 3.0,
            }),
        ] {
            let p = LinearCombineParams {
                alpha: 0.7,
                border: BorderMode::Wrap,
                ..LinearCombineParams::default()
            }
            .with_band(replace_band.as_ref());
            let w = linear_combine(&base, &detail, None, &p).unwrap();
            let rel = w.relative_rms_curl(None);
            println!(
                "linear combine {:?}: relative RMS curl {rel:.3e}",
                p.replace_band
            );
            assert!(rel <= 1e-3, "{p:?}: {rel:e}");
        }
        // A soft weight breaks integrability where it varies: reported, and > 0.
        let m = Plane::from_fn(size, size, |x, _| (x as f32 / size as f32).clamp(0.0, 1.0));
        let w = linear_combine(&base, &detail, Some(&m), &LinearCombineParams::default()).unwrap();
        let rel = w.relative_rms_curl(None);
        println!("linear combine with a ramp weight: relative RMS curl {rel:.3e}");
        assert!(rel.is_finite() && rel > 0.0);
    }

    #[test]
    fn height_variant_is_integrable_for_any_weight() {
        let size = 128;
        let base = height_field(&Surface::gaussians_for(size), size);
        let (_, h) = Surface::Sinusoid {
            amplitude_px: 1.5,
            period_px: 9.0,
        }
        .render(size, size);
        let m = Plane::from_fn(size, size, |x, _| (x as f32 / size as f32).clamp(0.0, 1.0));
        let p = LinearCombineParams {
            alpha: 0.8,
            ..LinearCombineParams::default()
        };
        let w = linear_combine_height(&base, &h, Some(&m), &p).unwrap();
        let rel = w.relative_rms_curl(None);
        let grad = linear_combine(&base, &GradientField::of_height(&h).0, Some(&m), &p).unwrap();
        let rel_g = grad.relative_rms_curl(None);
        println!("ramp weight: height variant curl {rel:.3e}, gradient variant {rel_g:.3e}");
        assert!(rel < 1e-6 && rel_g > 100.0 * rel, "{rel:e} {rel_g:e}");
        // Weight 1: both variants agree exactly.
        let a = linear_combine_height(&base, &h, None, &p).unwrap();
        let b = linear_combine(&base, &GradientField::of_height(&h).0, None, &p).unwrap();
        assert!(a.p.iter().zip(&b.p).all(|(x, y)| (x - y).abs() < 1e-5));
        let mut bad = h.clone();
        bad.data_mut()[3] = f32::NAN;
        assert!(linear_combine_height(&base, &bad, None, &p)
            .unwrap_err()
            .to_string()
            .contains("detail_height"));
    }

    #[test]
    fn replacing_a_band_swaps_it() {
        // Base and detail are the same field: replacing a band by the same band is a no-op,
        // and alpha = 0 removes it.
        let size = 96;
        let g = height_field(&Surface::gaussians_for(size), size);
        let band = Band::HighPass { sigma_px: 2.0 };
        let p = LinearCombineParams::default().with_band(Some(&band));
        let same = linear_combine(&g, &g, None, &p).unwrap();
        assert!(same.p.iter().zip(&g.p).all(|(a, b)| (a - b).abs() < 1e-5));
        let removed =
            linear_combine(&g, &g, None, &LinearCombineParams { alpha: 0.0, ..p }).unwrap();
        let want = apply_band(&g, &band, BandOp::Remove, BorderMode::Mirror).unwrap();
        assert!(removed
            .q
            .iter()
            .zip(&want.q)
            .all(|(a, b)| (a - b).abs() < 1e-5));
    }

    #[test]
    fn bad_params_are_refused() {
        let g = GradientField::zeros(4, 4);
        let e = linear_combine(
            &g,
            &g,
            None,
            &LinearCombineParams {
                alpha: f64::NAN,
                ..LinearCombineParams::default()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("alpha") && e.contains("[-1000, 1000]"), "{e}");
        let m = Plane::filled(4, 4, 2.0);
        let e = linear_combine(&g, &g, Some(&m), &LinearCombineParams::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("weight") && e.contains("[0, 1]"), "{e}");
        let small = GradientField::zeros(3, 4);
        assert!(linear_combine(&g, &small, None, &LinearCombineParams::default()).is_err());
    }
}
