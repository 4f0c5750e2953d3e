//! Frequency bands of a gradient field (Pereira & Velho §III–IV): low-, high- and band-pass,
//! and band **removal**, so that the base keeps everything except a band that a detail can
//! then replace (see [`super::combine`]).
//!
//! Every band is a linear, shift-invariant kernel `B` applied to `p` and `q` (through
//! [`filter::Kernel`](super::filter::Kernel)), and removal is its complement `I − B`:
//!
//! | [`Band`] | `B ∗ g` | removal `g − B ∗ g` |
//! |---|---|---|
//! | `LowPass σ` | `G_σ ∗ g` | high-pass |
//! | `HighPass σ` | `g − G_σ ∗ g` | low-pass |
//! | `BandPass σ_f, σ_c` (DoG) | `(G_σf − G_σc) ∗ g` | `g − G_σf ∗ g + G_σc ∗ g` |
//! | `LoG σ` | `−σ²∇²(G_σ ∗ g)` (scale-normalised, peak gain `2/e ≈ 0.74` at `|ω| = √2/σ`) | `g − B ∗ g` |
//!
//! So `remove(g) + band(g) = g` exactly (up to float rounding), by construction. As with any
//! linear filter on gradients, an integrable field stays integrable away from the border (the
//! kernel commutes with differentiation; see [`super::filter`] for the border caveat).
//!
//! # References
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §III–IV.
//! - D. Marr, E. Hildreth, "Theory of edge detection", Proc. R. Soc. B 207 (1980) (LoG, DoG).

use super::filter::{
    check_sigma, filter_gradients, FilterOptions, Kernel, SIGMA_RANGE, SIGMA_SOFT,
};
use crate::error::RgbnError;
use crate::raster::convolve::BorderMode;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// A frequency band of a gradient field (module docs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Band {
    /// Frequencies below ≈ `1/(2πσ)` cycles per pixel: `G_σ ∗ g`.
    LowPass { sigma_px: f32 },
    /// Everything above the low-pass: `g − G_σ ∗ g`.
    HighPass { sigma_px: f32 },
    /// Difference of Gaussians `G_σf − G_σc` (`σ_f < σ_c`).
    BandPass {
        sigma_fine_px: f32,
        sigma_coarse_px: f32,
    },
    /// Scale-normalised Laplacian of Gaussian `−σ²∇²G_σ`.
    LoG { sigma_px: f32 },
}

impl Default for Band {
    fn default() -> Self {
        Band::BandPass {
            sigma_fine_px: 1.0,
            sigma_coarse_px: 4.0,
        }
    }
}

impl Band {
    /// Checks the σ's (positive, finite, ≤ [`super::filter::MAX_SIGMA_PX`]; `σ_f < σ_c` for a band-pass).
    pub fn validate(&self) -> Result<(), RgbnError> {
        match self {
            Band::LowPass { sigma_px } | Band::HighPass { sigma_px } | Band::LoG { sigma_px } => {
                check_sigma("sigma_px", *sigma_px)
            }
            Band::BandPass {
                sigma_fine_px,
                sigma_coarse_px,
            } => {
                check_sigma("sigma_fine_px", *sigma_fine_px)?;
                check_sigma("sigma_coarse_px", *sigma_coarse_px)?;
                if sigma_fine_px >= sigma_coarse_px {
                    return Err(RgbnError::param(
                        "sigma_coarse_px",
                        format!(
                            "{sigma_coarse_px} must be greater than sigma_fine_px = {sigma_fine_px}"
                        ),
                    ));
                }
                Ok(())
            }
        }
    }

    /// The kind, σ (the finer σ of a band-pass) and coarser σ (4 px when unused) of the band:
    /// the parameter form of [`BandKind::band`].
    #[must_use]
    pub fn parts(&self) -> (BandKind, f64, f64) {
        match *self {
            Band::LowPass { sigma_px } => (BandKind::LowPass, f64::from(sigma_px), 4.0),
            Band::HighPass { sigma_px } => (BandKind::HighPass, f64::from(sigma_px), 4.0),
            Band::BandPass {
                sigma_fine_px,
                sigma_coarse_px,
            } => (
                BandKind::BandPass,
                f64::from(sigma_fine_px),
                f64::from(sigma_coarse_px),
            ),
            Band::LoG { sigma_px } => (BandKind::LoG, f64::from(sigma_px), 4.0),
        }
    }

    /// The band as a [`Kernel`] of [`super::filter`].
    #[must_use]
    pub fn kernel(&self) -> Kernel {
        match *self {
            Band::LowPass { sigma_px } => Kernel::Gaussian { sigma_px },
            Band::HighPass { sigma_px } => Kernel::HighPass { sigma_px },
            Band::BandPass {
                sigma_fine_px,
                sigma_coarse_px,
            } => Kernel::DoG {
                sigma_fine_px,
                sigma_coarse_px,
            },
            Band::LoG { sigma_px } => Kernel::LoG { sigma_px },
        }
    }
}

crate::choice_enum! {
    /// The kind of a [`Band`].
    pub enum BandKind {
        /// Low-pass `G_σ`.
        LowPass = "lowpass",
        /// High-pass `I − G_σ`.
        HighPass = "highpass",
        /// Band-pass `G_σ − G_coarse` (DoG).
        BandPass = "bandpass",
        /// Scale-normalised Laplacian of Gaussian `−σ²∇²G_σ`.
        LoG = "log",
    }
}

impl BandKind {
    /// The band of this kind with σ `sigma_px` (the finer σ of a band-pass) and, for a
    /// band-pass, the coarser σ `sigma_coarse_px`, checked; errors name `sigma_px` and
    /// `sigma_coarse_px`.
    pub fn band(self, sigma_px: f64, sigma_coarse_px: f64) -> Result<Band, RgbnError> {
        let (s, c) = (sigma_px as f32, sigma_coarse_px as f32);
        let band = match self {
            BandKind::LowPass => Band::LowPass { sigma_px: s },
            BandKind::HighPass => Band::HighPass { sigma_px: s },
            BandKind::BandPass => Band::BandPass {
                sigma_fine_px: s,
                sigma_coarse_px: c,
            },
            BandKind::LoG => Band::LoG { sigma_px: s },
        };
        band.validate().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "sigma_fine_px" => {
                RgbnError::param("sigma_px", detail)
            }
            other => other,
        })?;
        Ok(band)
    }
}

crate::choice_enum! {
    /// Keep the band or remove it.
    pub enum BandOp {
        /// `B ∗ g`: the band only.
        Keep = "keep",
        /// `g − B ∗ g`: the base without the band.
        Remove = "remove",
    }
}

crate::params! {
    /// Parameters of [`band_filter`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct BandParams {
        /// Which band: lowpass G_σ, highpass I − G_σ, bandpass G_σ − G_coarse (DoG), log −σ²∇²G_σ.
        pub band: BandKind = BandKind::BandPass => choice,
        /// σ of the band (low-pass, high-pass, LoG), or the finer σ of a band-pass.
        pub sigma_px: f64 = 1.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// The coarser σ of a band-pass (must exceed sigma_px); unused by the others.
        pub sigma_coarse_px: f64 = 4.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// keep: B * g (the band only); remove: g − B * g (everything but the band).
        pub op: BandOp = BandOp::Keep => choice,
        /// How the image is extended beyond its border.
        pub border: BorderMode = BorderMode::Mirror => choice,
    }
}

impl BandParams {
    /// The band, checked.
    pub fn band(&self) -> Result<Band, RgbnError> {
        self.band.band(self.sigma_px, self.sigma_coarse_px)
    }
    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        self.band().map(|_| ())
    }
}

/// `B ∗ g` (Keep) or `g − B ∗ g` (Remove) of a gradient field for [`BandParams`].
pub fn band_filter(g: &GradientField, params: &BandParams) -> Result<GradientField, RgbnError> {
    apply_band(g, &params.band()?, params.op, params.border)
}

/// `B ∗ g` (Keep) or `g − B ∗ g` (Remove) of a gradient field (module docs).
pub fn apply_band(
    g: &GradientField,
    band: &Band,
    op: BandOp,
    border: BorderMode,
) -> Result<GradientField, RgbnError> {
    band.validate()?;
    let mut b = g.clone();
    let opts = FilterOptions {
        border,
        mask_aware: false,
    };
    filter_gradients(&mut b, &[band.kernel()], &opts, None)?;
    if op == BandOp::Remove {
        for (out, orig) in [(&mut b.p, &g.p), (&mut b.q, &g.q)] {
            out.par_iter_mut()
                .zip(orig.par_iter())
                .for_each(|(o, g)| *o = g - *o);
        }
    }
    Ok(b)
}

/// The band and the rest in one go: `(B ∗ g, g − B ∗ g)`, which sum to `g`.
pub fn split_band(
    g: &GradientField,
    band: &Band,
    border: BorderMode,
) -> Result<(GradientField, GradientField), RgbnError> {
    let keep = apply_band(g, band, BandOp::Keep, border)?;
    let mut rest = g.clone();
    for (r, k) in [(&mut rest.p, &keep.p), (&mut rest.q, &keep.q)] {
        r.par_iter_mut()
            .zip(k.par_iter())
            .for_each(|(r, k)| *r -= k);
    }
    Ok((keep, rest))
}

/// Applies [`band_filter`] to an image's normals (colour and mask shared). Returns the image
/// and the curl of its new gradients (over the mask).
pub fn band_filter_image(
    img: &RgbnImage,
    params: &BandParams,
) -> Result<(RgbnImage, CurlStats), RgbnError> {
    let g = GradientField::from_normals(img);
    let b = band_filter(&g, params)?;
    let mut out = img.clone();
    b.write_normals(&mut out);
    Ok((out, b.curl_stats(img.mask())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::Surface;
    use crate::raster::Plane;

    fn bumpy(size: usize) -> GradientField {
        let (_, z) = Surface::Gaussians {
            bumps: vec![
                [-30.0, 20.0, 15.0, 10.0],
                [25.0, -20.0, -8.0, 3.0],
                [5.0, 30.0, 3.0, 1.5],
            ],
        }
        .render(size, size);
        GradientField::of_height(&Plane::from_vec(size, size, z.into_vec()).unwrap()).0
    }

    fn all_bands() -> Vec<Band> {
        vec![
            Band::LowPass { sigma_px: 4.0 },
            Band::HighPass { sigma_px: 3.0 },
            Band::BandPass {
                sigma_fine_px: 1.0,
                sigma_coarse_px: 5.0,
            },
            Band::LoG { sigma_px: 2.0 },
        ]
    }

    #[test]
    fn removal_plus_band_is_the_original() {
        let g = bumpy(128);
        for band in all_bands() {
            let keep = apply_band(&g, &band, BandOp::Keep, BorderMode::Mirror).unwrap();
            let rest = apply_band(&g, &band, BandOp::Remove, BorderMode::Mirror).unwrap();
            let err = (0..g.p.len())
                .map(|i| {
                    (keep.p[i] + rest.p[i] - g.p[i])
                        .abs()
                        .max((keep.q[i] + rest.q[i] - g.q[i]).abs())
                })
                .fold(0.0f32, f32::max);
            assert!(err < 1e-6, "{band:?}: {err}");
            let (k2, r2) = split_band(&g, &band, BorderMode::Mirror).unwrap();
            assert_eq!(k2, keep);
            assert!(r2.p.iter().zip(&rest.p).all(|(a, b)| (a - b).abs() < 1e-6));
        }
    }

    #[test]
    fn bands_select_the_right_frequencies() {
        // Sinusoids of period 6 px (fine) and 96 px (coarse) under wrap borders: the low-pass
        // keeps the coarse one, the high-pass the fine one, the DoG band between them neither
        // fully.
        let size = 192;
        let energy =
            |g: &GradientField| -> f64 { g.p.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>() };
        let field = |period: f64| {
            let (_, z) = Surface::Sinusoid {
                amplitude_px: 1.0,
                period_px: period,
            }
            .render(size, size);
            GradientField::of_height(&Plane::from_vec(size, size, z.into_vec()).unwrap()).0
        };
        let (fine, coarse) = (field(6.0), field(96.0));
        let run = |g: &GradientField, band: Band| {
            energy(&apply_band(g, &band, BandOp::Keep, BorderMode::Wrap).unwrap()) / energy(g)
        };
        // 2-D sinusoid: the energy gain is ĝ(k)⁴ (both axes), ĝ(k) = exp(−σ²k²/2).
        let low = Band::LowPass { sigma_px: 4.0 };
        let (lf, lc) = (run(&fine, low.clone()), run(&coarse, low));
        let high = Band::HighPass { sigma_px: 4.0 };
        let (hf, hc) = (run(&fine, high.clone()), run(&coarse, high));
        let log = run(&coarse, Band::LoG { sigma_px: 1.0 });
        println!(
            "band energy gains: low {lf:.2e}/{lc:.3} high {hf:.3}/{hc:.2e} LoG coarse {log:.2e}"
        );
        let k = std::f64::consts::TAU / 96.0;
        let want_lc = (-16.0 * k * k / 2.0f64).exp().powi(4);
        assert!(
            lf < 1e-3 && (lc - want_lc).abs() < 0.01,
            "{lf} {lc} vs {want_lc}"
        );
        assert!(hf > 0.99 && hc < 0.01, "{hf} {hc}");
        assert!(log < 1e-3, "{log}");
    }

    #[test]
    fn band_of_integrable_field_stays_integrable() {
        let g = bumpy(160);
        for band in all_bands() {
            for op in [BandOp::Keep, BandOp::Remove] {
                let out = apply_band(&g, &band, op, BorderMode::Mirror).unwrap();
                let rel = out.relative_rms_curl(None);
                assert!(rel < 1e-3, "{band:?} {op:?}: {rel:e}");
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(16))]
        #[test]
        fn keep_plus_remove_is_identity_on_any_field(
            vals in proptest::collection::vec(-5.0f32..5.0, 2 * 24 * 20),
            sigma in 0.5f32..8.0, which in 0usize..4
        ) {
            let (w, h) = (24, 20);
            let mut g = GradientField::zeros(w, h);
            g.p.copy_from_slice(&vals[..w * h]);
            g.q.copy_from_slice(&vals[w * h..]);
            let band = match which {
                0 => Band::LowPass { sigma_px: sigma },
                1 => Band::HighPass { sigma_px: sigma },
                2 => Band::BandPass { sigma_fine_px: sigma, sigma_coarse_px: 2.0 * sigma },
                _ => Band::LoG { sigma_px: sigma },
            };
            let (keep, rest) = split_band(&g, &band, BorderMode::Mirror).unwrap();
            for i in 0..w * h {
                proptest::prop_assert!((keep.p[i] + rest.p[i] - g.p[i]).abs() < 1e-4);
                proptest::prop_assert!((keep.q[i] + rest.q[i] - g.q[i]).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn bad_sigmas_are_refused() {
        for (b, needle) in [
            (Band::LowPass { sigma_px: -1.0 }, "sigma_px"),
            (Band::LoG { sigma_px: f32::NAN }, "(0, 4096]"),
            (
                Band::BandPass {
                    sigma_fine_px: 4.0,
                    sigma_coarse_px: 2.0,
                },
                "greater than sigma_fine_px",
            ),
        ] {
            let e = apply_band(
                &GradientField::zeros(4, 4),
                &b,
                BandOp::Keep,
                BorderMode::Mirror,
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains(needle), "{e}");
        }
        // Through the params: the finer σ is called sigma_px.
        let p = BandParams {
            sigma_px: 5.0,
            ..BandParams::default()
        };
        let e = band_filter(&GradientField::zeros(4, 4), &p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("sigma_coarse_px") && e.contains("sigma_fine_px = 5"),
            "{e}"
        );
    }
}
