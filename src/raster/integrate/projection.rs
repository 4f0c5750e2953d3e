//! The integrability projection: normals replaced by those of their integrated height.

use super::{curl_interior, gradients_of_height, integrate_gradients, IntegrateParams};
use super::{IntegrationMethod, IntegrationReport};
use crate::error::RgbnError;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::{Plane, RgbnImage};

/// Parameters of [`project_integrable`].
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProjectParams {
    /// The integration used for the projection. `MaskedPoisson` projects inside the mask and
    /// keeps the normals outside it.
    pub integrate: IntegrateParams,
}

impl ProjectParams {
    /// Checks the integration parameters.
    pub fn validate(&self) -> Result<(), RgbnError> {
        self.integrate.validate()
    }
}

/// Integrability before and after [`project_integrable`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProjectionReport {
    /// Model curl of the input's gradients (over the mask's [`curl_interior`] if masked).
    pub before: CurlStats,
    /// Model curl of the output's gradients (from its normals, so including unit-vector
    /// rounding).
    pub after: CurlStats,
    pub integration: IntegrationReport,
}

/// Replaces the normals by those of their integrated height: the nearest integrable field in
/// the least-squares sense (module docs). Colour and mask are shared with the input. Returns
/// the projected image, the height and the curl report.
///
/// # Errors
/// As [`integrate_gradients`].
pub fn project_integrable(
    img: &RgbnImage,
    params: &ProjectParams,
) -> Result<(RgbnImage, Plane, ProjectionReport), RgbnError> {
    params.validate()?;
    let g = GradientField::from_normals(img);
    let interior = img
        .mask()
        .map(|m| curl_interior(m, img.width(), img.height()));
    let model = params.integrate.differences;
    let before = g.curl_stats_of(model, interior.as_deref());
    let (z, integration) = integrate_gradients(&g, img.mask(), &params.integrate)?;
    let masked = params.integrate.method == IntegrationMethod::MaskedPoisson;
    let dom = if masked { img.mask() } else { None };
    let g2 = gradients_of_height(&z, dom, Some(&g), model);
    let mut out = img.clone();
    g2.write_normals(&mut out);
    let after = GradientField::from_normals(&out).curl_stats_of(model, interior.as_deref());
    Ok((
        out,
        z,
        ProjectionReport {
            before,
            after,
            integration,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::raster::sample::Surface;

    #[test]
    fn projection_keeps_integrable_fields_and_removes_rotation() {
        let size = 96;
        let s = Surface::gaussians_for(size);
        let (_, z) = s.render(size, size);
        for (method, differences) in [
            (IntegrationMethod::PoissonDct, Differences::Averaged),
            (IntegrationMethod::MaskedPoisson, Differences::Averaged),
            (IntegrationMethod::PoissonDct, Differences::Forward),
            (IntegrationMethod::MaskedPoisson, Differences::Forward),
        ] {
            // The samples of a height in the model: an integrable field of that model.
            let mut img = RgbnImage::flat(size, size, [0.5; 3]);
            gradients_of_height(&z, None, None, differences).write_normals(&mut img);
            let params = ProjectParams {
                integrate: IntegrateParams {
                    method,
                    differences,
                    ..Default::default()
                },
            };
            let (out, _, rep) = project_integrable(&img, &params).unwrap();
            let max_dn = (0..3)
                .flat_map(|k| {
                    img.normal()[k]
                        .iter()
                        .zip(&out.normal()[k])
                        .map(|(a, b)| (a - b).abs())
                })
                .fold(0.0f32, f32::max);
            eprintln!(
                "{method:?} {differences:?} projection of an integrable field: max |Δn| \
                 {max_dn:.2e}, curl {:.2e} → {:.2e}",
                rep.before.relative, rep.after.relative
            );
            assert!(max_dn <= 1e-4, "{max_dn}");
            assert!(rep.before.relative < 1e-4, "{rep:?}");
            // Projecting twice changes nothing more.
            let (out2, _, _) = project_integrable(&out, &params).unwrap();
            let d2 = (0..3)
                .flat_map(|k| {
                    out.normal()[k]
                        .iter()
                        .zip(&out2.normal()[k])
                        .map(|(a, b)| (a - b).abs())
                })
                .fold(0.0f32, f32::max);
            assert!(d2 <= 1e-4, "{d2}");
        }
        let mut img = RgbnImage::flat(size, size, [0.5; 3]);
        gradients_of_height(&z, None, None, Differences::Averaged).write_normals(&mut img);

        // Add a divergence-free vortex g_rot = (∂ψ/∂v, −∂ψ/∂u) of a Gaussian stream function
        // ψ (tangential at the border, so it carries no height under Neumann boundaries).
        let (amp, s2) = (3.0f32, 2.0 * 8.0f32 * 8.0);
        let mut g = gradients_of_height(&z, None, None, Differences::Averaged);
        for r in 0..size {
            for x in 0..size {
                let (u, v) = (x as f32 - 40.0, 50.0 - r as f32);
                let psi = amp * (-(u * u + v * v) / s2).exp();
                let (dpu, dpv) = (-2.0 * u / s2 * psi, -2.0 * v / s2 * psi);
                g.p[r * size + x] += dpv;
                g.q[r * size + x] -= dpu;
            }
        }
        let mut bad = img.clone();
        g.write_normals(&mut bad);
        let (out, zi, rep) = project_integrable(&bad, &ProjectParams::default()).unwrap();
        eprintln!(
            "vortex added: relative curl {:.3e} → {:.3e} (rms curl {:.3e} → {:.3e})",
            rep.before.relative, rep.after.relative, rep.before.rms_curl, rep.after.rms_curl
        );
        assert!(rep.before.relative > 0.03);
        assert!(rep.after.relative < 1e-4);
        // The vortex has no height: the projection recovers the original height (to the
        // O(h²) divergence of the sampled vortex).
        let e = rmse_up_to_constant(&zi, &z, None);
        eprintln!("height RMSE after removing the rotation: {e:.4} px");
        assert!(e < 0.05, "{e}");
        assert!(out.validate().is_clean());
    }
}
