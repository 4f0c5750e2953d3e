//! Renormalise / repair normals, and the curl readout every operator's output can be checked
//! with.
//!
//! - [`normalize`]: `n ← n/|n|`; with `repair`, non-finite or zero-length normals (shorter than
//!   [`MIN_NORMAL_LENGTH`](crate::raster::MIN_NORMAL_LENGTH)) become `(0,0,1)` and non-finite
//!   colour becomes 0 (see [`RgbnImage::repair`]); optionally back-facing normals (`n_z < min_z`)
//!   are lifted to `n_z = min_z` keeping their azimuth (the same saturation as
//!   [`super::rotate`]). Idempotent.
//! - [`curl_readout`]: discrete curl `c = ∂p/∂y − ∂q/∂x` of the foreshorten-corrected gradients
//!   (forward differences, Agrawal et al. 2005; conventions in
//!   [`crate::raster::gradient`]) as statistics and, optionally, a map.
//!
//! # References
//! - A. Agrawal, R. Chellappa, R. Raskar, "An algebraic approach to surface reconstruction from
//!   gradient fields", ICCV 2005.

use super::rotate::saturate;
use crate::error::RgbnError;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::{Plane, RgbnImage, Validation};
use rayon::prelude::*;

crate::params! {
    /// Parameters of [`normalize`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct NormalizeParams {
        /// Replace non-finite or zero-length normals by (0,0,1) and non-finite colour by 0.
        pub repair: bool = true => bool,
        /// Lift normals with n_z < min_z to n_z = min_z, keeping their azimuth.
        pub lift_back_facing: bool = false => bool,
        /// Threshold on n_z for lift_back_facing.
        pub min_z: f64 = f64::from(0.05f32) => float.range(0.0, 0.999).soft(0.0, 0.5),
    }
}

impl NormalizeParams {
    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        if !(self.min_z.is_finite() && (0.0..1.0).contains(&self.min_z)) {
            return Err(RgbnError::param(
                "min_z",
                format!("{} must be in [0, 1)", self.min_z),
            ));
        }
        Ok(())
    }
}

/// What [`normalize`] found and did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NormalizeReport {
    /// Validation of the input (before any change).
    pub before: Validation,
    /// Normals lifted to `min_z`.
    pub lifted: usize,
}

/// Renormalises (and optionally repairs / lifts) an image's normals. Pure: returns a new image
/// sharing unchanged planes.
pub fn normalize(
    img: &RgbnImage,
    params: &NormalizeParams,
) -> Result<(RgbnImage, NormalizeReport), RgbnError> {
    params.validate()?;
    let mut out = img.clone();
    let before = if params.repair {
        out.repair()
    } else {
        img.validate()
    };
    out.normalize();
    let mut lifted = 0;
    if params.lift_back_facing {
        // Rounded through f32 as the node always did (same results as before).
        let mz = f64::from(params.min_z as f32);
        let [nx, ny, nz] = out.normal_mut();
        lifted = (nx.par_iter_mut(), ny.par_iter_mut(), nz.par_iter_mut())
            .into_par_iter()
            .map(|(x, y, z)| {
                if f64::from(*z) >= mz {
                    return 0;
                }
                let r = [f64::from(*x), f64::from(*y), f64::from(*z)];
                let s = saturate([0.0, 0.0, -1.0], r, mz);
                (*x, *y, *z) = (s[0] as f32, s[1] as f32, s[2] as f32);
                1
            })
            .sum();
    }
    Ok((out, NormalizeReport { before, lifted }))
}

/// Integrability readout of a gradient field or image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CurlReadout {
    pub stats: CurlStats,
    /// Pixels whose `n_z` was clamped when converting normals to gradients.
    pub clamped: usize,
    /// The curl map (0 on the top row and right column), when asked for.
    pub map: Option<Plane>,
}

/// Curl statistics (and optionally the map) of a gradient field, over `mask` (coverage ≥ ½).
#[must_use]
pub fn curl_readout_gradients(
    g: &GradientField,
    mask: Option<&[f32]>,
    with_map: bool,
) -> CurlReadout {
    CurlReadout {
        stats: g.curl_stats(mask),
        clamped: g.clamped,
        map: with_map.then(|| g.curl()),
    }
}

/// Curl readout of an image's foreshorten-corrected gradients, over its mask.
#[must_use]
pub fn curl_readout(img: &RgbnImage, with_map: bool) -> CurlReadout {
    curl_readout_gradients(&GradientField::from_normals(img), img.mask(), with_map)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::Surface;

    #[test]
    fn normalize_repairs_and_is_idempotent() {
        let mut img = RgbnImage::flat(3, 1, [0.5; 3]);
        {
            let n = img.normal_mut();
            n[0][0] = f32::NAN;
            n[2][1] = 3.0;
            n[0][2] = 0.8;
            n[2][2] = -0.6;
        }
        let p = NormalizeParams {
            lift_back_facing: true,
            ..NormalizeParams::default()
        };
        let (a, rep) = normalize(&img, &p).unwrap();
        assert_eq!(rep.before.non_finite_normal, 1);
        assert_eq!(rep.lifted, 1);
        assert_eq!(a.normal_at(0, 0), [0.0, 0.0, 1.0]);
        assert_eq!(a.normal_at(1, 0), [0.0, 0.0, 1.0]);
        let n = a.normal_at(2, 0);
        assert!((n[2] - 0.05).abs() < 1e-6 && n[0] > 0.99, "{n:?}");
        let (b, rep2) = normalize(&a, &p).unwrap();
        assert!(rep2.before.is_clean() && rep2.lifted == 0);
        for i in 0..3 {
            let (x, y) = (a.normal_at(i, 0), b.normal_at(i, 0));
            assert!((0..3).all(|k| (x[k] - y[k]).abs() < 1e-6), "{x:?} {y:?}");
        }
        assert!(normalize(&img, &NormalizeParams { min_z: -0.1, ..p })
            .unwrap_err()
            .to_string()
            .contains("min_z"));
    }

    #[test]
    fn curl_readout_of_an_analytic_surface_is_small_and_map_is_optional() {
        let (img, _) = Surface::gaussians_for(64).render(64, 64);
        let r = curl_readout(&img, true);
        assert!(r.stats.relative < 0.05 && r.map.as_ref().is_some_and(|m| m.width() == 64));
        assert!(curl_readout(&img, false).map.is_none());
    }
}
