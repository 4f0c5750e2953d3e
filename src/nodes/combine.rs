//! The linear combine of [`crate::ops::combine`] as a node (`combine.linear`, with a detail
//! given as normals or as a height); the rotation combine is in [`super::rotate`].

use super::kit::kernel_kind;
use super::{Coarse, Kind, Mask, OpSpec, Operator, RunContext, Scalar};
use crate::error::RgbnError;
use crate::ops::combine::{linear_combine_height, linear_combine_images, LinearCombineParams};
use crate::raster::gradient::GradientField;
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`LinearCombineNode`].
    pub struct LinearCombineIn {
        /// Base image (colour and mask are kept).
        pub base: RgbnImage,
        /// Detail as normals (connect this or detail_height).
        pub detail: Option<RgbnImage>,
        /// Detail as a height in pixels (connect this or detail).
        pub detail_height: Option<Scalar>,
        /// Per-pixel weight m in [0, 1] (1 everywhere when unconnected).
        pub weight: Option<Mask>,
    }
}

crate::outputs! {
    /// Outputs of [`LinearCombineNode`].
    pub struct LinearCombineOut {
        /// Combined image.
        pub image: RgbnImage,
        /// RMS(curl) / RMS(|g|) of the combined gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Linear combine of gradients.
pub struct LinearCombineNode;

impl Operator for LinearCombineNode {
    type Params = LinearCombineParams;
    type In = LinearCombineIn;
    type Out = LinearCombineOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "combine.linear",
            "Linear combine",
            "combine",
            "Adds a detail's relief to a base through their gradients (Pereira & Velho §IV): ∇b + α·m·∇h, optionally replacing a band of the base. With weight 1 it is the partial-derivative blend. A detail given as a height adds α·∇(m·h) instead, which stays integrable for any weight.",
        )
    }
    fn check(p: &LinearCombineParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(p: &LinearCombineParams) -> Kind {
        // A height's gradient reads one pixel; a replaced band its kernel's reach.
        let band = p.band().ok().flatten();
        let halo = 1.max(band.map_or(0, |b| b.kernel().support_px()));
        kernel_kind(p.border, halo, Coarse::None)
    }
    fn run(
        p: &LinearCombineParams,
        i: LinearCombineIn,
        _: &RunContext,
    ) -> Result<LinearCombineOut, RgbnError> {
        let weight = i.weight.as_deref();
        match (&i.detail, &i.detail_height) {
            (Some(detail), None) => {
                let (image, rep) = linear_combine_images(&i.base, detail, weight, p)?;
                Ok(LinearCombineOut {
                    image,
                    relative_rms_curl: rep.curl_after.relative,
                })
            }
            (None, Some(h)) => {
                let g = linear_combine_height(&GradientField::from_normals(&i.base), h, weight, p)?;
                let curl = g.curl_stats(i.base.mask()).relative;
                let mut image = i.base;
                g.write_normals(&mut image);
                Ok(LinearCombineOut {
                    image,
                    relative_rms_curl: curl,
                })
            }
            _ => Err(RgbnError::param(
                "detail",
                "connect exactly one of the inputs detail (normals) and detail_height (height)",
            )),
        }
    }
}
