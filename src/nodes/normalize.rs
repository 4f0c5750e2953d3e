//! The normalisation of [`crate::ops::normalize`] as a node.

use super::{Kind, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::normalize::{normalize, NormalizeParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`Normalize`].
    pub struct NormalizeIn {
        /// Image.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`Normalize`].
    pub struct NormalizeOut {
        /// Image with unit normals.
        pub image: RgbnImage,
        /// Input values that were not finite or normals of zero length (repaired when repair is on).
        pub invalid: f64,
        /// Normals lifted to n_z = min_z.
        pub lifted: f64,
    }
}

/// The [`normalize`] node.
pub struct Normalize;

impl Operator for Normalize {
    type Params = NormalizeParams;
    type In = NormalizeIn;
    type Out = NormalizeOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "normalize",
            "Normalize",
            "filter",
            "Rescales every normal to unit length (idempotent); optionally repairs bad normals and lifts back-facing ones. Colour and mask are unchanged except for repairs.",
        )
        .version(2)
    }
    fn kind(_: &NormalizeParams) -> Kind {
        Kind::POINT
    }
    fn run(p: &NormalizeParams, i: NormalizeIn, _: &RunContext) -> Result<NormalizeOut, RgbnError> {
        let (image, rep) = normalize(&i.image, p)?;
        let b = rep.before;
        let invalid = b.non_finite_normal + b.zero_length_normal + b.non_finite_color;
        Ok(NormalizeOut {
            image,
            invalid: invalid as f64,
            lifted: rep.lifted as f64,
        })
    }
}
