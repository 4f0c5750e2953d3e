//! The local filter brush of [`crate::ops::brush`] as a node: one linear kernel applied inside a
//! stroke (a polyline swept by a disc with a feather) and/or a mask input ([`brush_image`]).
//! Several strokes: chain brush nodes, or paint them into a mask.

use super::kit::kernel_kind;
use super::{Coarse, Kind, Mask, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::brush::{brush_image, BrushKernel, SimpleBrushParams};
use crate::ops::filter::Kernel;
use crate::ops::geom::{changed_path_bounds, paths_bounds};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`BrushNode`].
    pub struct BrushIn {
        /// Image to edit.
        pub image: RgbnImage,
        /// Extra region in [0, 1] united (max) with the stroke.
        pub mask: Option<Mask>,
    }
}

crate::outputs! {
    /// Outputs of [`BrushNode`].
    pub struct BrushOut {
        /// Edited normals; colour and mask unchanged.
        pub image: RgbnImage,
        /// The region weight m actually used.
        pub region: Mask,
        /// RMS(curl) / RMS(|g|) of the edited gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Filter brush.
pub struct BrushNode;

impl Operator for BrushNode {
    type Params = SimpleBrushParams;
    type In = BrushIn;
    type Out = BrushOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "brush",
            "Filter brush",
            "filter",
            "Applies a linear filter only inside a painted region (Pereira & Velho §III, Fig. 1): g′ = m·K(g) + (1 − m)·g, with m the union of a feathered stroke and the optional mask input. The feather band generally adds curl (reported).",
        )
    }
    fn check(p: &SimpleBrushParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn kind(p: &SimpleBrushParams) -> Kind {
        // A box radius is whole pixels and a LoG's response scales with σ⁻²: no coarse form.
        let coarse = if matches!(p.kernel, BrushKernel::Box | BrushKernel::LoG) {
            Coarse::None
        } else {
            Coarse::Scaled
        };
        match p.to_params() {
            Ok(b) => kernel_kind(
                b.filter.border,
                b.kernels.iter().map(Kernel::support_px).max().unwrap_or(0),
                coarse,
            ),
            // Checked parameters always convert.
            Err(_) => Kind::GLOBAL,
        }
    }
    fn damage(
        old: &SimpleBrushParams,
        new: &SimpleBrushParams,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        // g′ = m·K(g) + (1 − m)·g: only the stroke's weight m moves when only its points do.
        let same_but_points = SimpleBrushParams {
            points: new.points.clone(),
            ..old.clone()
        } == *new;
        let reach = |p: &SimpleBrushParams| p.radius_px + p.feather_px + 2.0;
        if same_but_points {
            return Some(changed_path_bounds(
                &old.points,
                &new.points,
                0.0,
                reach(new),
            ));
        }
        // Another kernel changes the result wherever m > 0: inside the strokes, unless a mask
        // input adds to m.
        if inputs.get(1).is_some_and(Option::is_some) {
            return None;
        }
        paths_bounds(&[&old.points, &new.points], reach(old).max(reach(new))).map(|b| vec![b])
    }
    fn run(p: &SimpleBrushParams, i: BrushIn, _: &RunContext) -> Result<BrushOut, RgbnError> {
        let (image, rep) = brush_image(&i.image, i.mask.as_deref(), &p.to_params()?)?;
        let region = rep
            .region
            .ok_or_else(|| RgbnError::InvalidImage("brush returned no region".into()))?;
        Ok(BrushOut {
            image,
            region: Mask::new(region),
            relative_rms_curl: rep.curl_after.relative,
        })
    }
}
