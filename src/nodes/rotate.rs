//! The rotation combine of [`crate::ops::rotate`] as a node (`combine.rotation`).

use super::{Coarse, Kind, Mask, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::rotate::{rotation_combine, RotateParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`RotationCombineNode`].
    pub struct RotationIn {
        /// Base image (colour and mask are kept).
        pub base: RgbnImage,
        /// Detail normals, in the base's tangent frame (+z = no detail).
        pub detail: RgbnImage,
        /// The normals being edited, fine detail included (§VII's a): replace, blend and rotate act on them; the base when unconnected.
        pub existing: Option<RgbnImage>,
        /// Per-pixel weight in [0, 1] (1 everywhere when unconnected).
        pub weight: Option<Mask>,
    }
}

crate::outputs! {
    /// Outputs of [`RotationCombineNode`].
    pub struct RotationOut {
        /// Combined image.
        pub image: RgbnImage,
        /// Pixels moved back to n_z = min_z.
        pub saturated: f64,
        /// RMS(curl) / RMS(|g|) of the combined gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Rotation combine of normals.
pub struct RotationCombineNode;

impl Operator for RotationCombineNode {
    type Params = RotateParams;
    type In = RotationIn;
    type Out = RotationOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "combine.rotation",
            "Rotation combine",
            "combine",
            "Expresses a detail normal in the tangent frame of a base normal (Pereira & Velho §VII), so the detail keeps its look on a tilted base; industry blends (RNM, UDN, whiteout, partial derivative) as modes. Nonlinear: the curl of the result is reported; integrable: true returns the nearest integrable result, changed only inside the edit's support.",
        )
        // 2: the `integrable` option.
        .version(2)
    }
    fn check(p: &RotateParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(p: &RotateParams) -> Kind {
        if p.integrable {
            // The projection solves a Poisson equation over the edit's support: the inputs are
            // needed whole, and (nonlinear) there is no coarse form.
            return Kind::GLOBAL;
        }
        // Per pixel, but nonlinear in the normals: the rotation of reduced normals is not the
        // reduced rotation, so no coarse form.
        Kind::Point {
            coarse: Coarse::None,
        }
    }
    fn run(p: &RotateParams, i: RotationIn, _: &RunContext) -> Result<RotationOut, RgbnError> {
        let (image, rep) = rotation_combine(
            &i.base,
            &i.detail,
            i.existing.as_ref(),
            i.weight.as_deref(),
            p,
        )?;
        Ok(RotationOut {
            image,
            saturated: rep.saturated as f64,
            relative_rms_curl: rep.curl_after.relative,
        })
    }
}
