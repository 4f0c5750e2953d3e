//! The transform of [`crate::ops::transform`] as a node: crop, mirror, flip, quarter turns and
//! resize of a whole image.

use super::{Kind, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::transform::{transform, TransformParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`TransformNode`].
    pub struct TransformIn {
        /// Image to transform.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`TransformNode`].
    pub struct TransformOut {
        /// The transformed image, its normals turned with it.
        pub image: RgbnImage,
    }
}

/// Crop, mirror, flip, rotate and resize.
pub struct TransformNode;

impl Operator for TransformNode {
    type Params = TransformParams;
    type In = TransformIn;
    type Out = TransformOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "transform",
            "Transform",
            "filter",
            "Crops, mirrors, flips, turns by quarter turns and resizes a whole image; the normals turn with it (a mirror negates n_x, a rotation rotates (n_x, n_y)) and a resize works on the gradients, so a surface stays a surface.",
        )
    }
    fn kind(_: &TransformParams) -> Kind {
        // Output pixels come from elsewhere in the input (and a resize changes the grid).
        Kind::GLOBAL
    }
    fn out_size(p: &TransformParams, inputs: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        p.out_size((*inputs.first()?)?).ok()
    }
    fn run(p: &TransformParams, i: TransformIn, _: &RunContext) -> Result<TransformOut, RgbnError> {
        Ok(TransformOut {
            image: transform(&i.image, p)?,
        })
    }
}
