//! The stamp of [`crate::ops::stamp`] as a node: place an RGBN stamp at positions with an affine map
//! ([`stamp_image`]).

use super::{Coarse, Kind, Mask, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::stamp::{extract, placement_bounds, stamp_image, ExtractParams, StampParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`StampNode`].
    pub struct StampIn {
        /// Target image.
        pub image: RgbnImage,
        /// The stamp (at most 512 px a side); its mask limits its relief (feathered over the falloff) and its colour.
        pub stamp: RgbnImage => whole,
        /// Optional region (the target's size): the stamped relief and colour are multiplied by it, integrably.
        pub region: Option<Mask>,
    }
}

crate::outputs! {
    /// Outputs of [`StampNode`].
    pub struct StampOut {
        /// Stamped image.
        pub image: RgbnImage,
        /// RMS(curl) / RMS(|g|) of the result's gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Stamp.
pub struct StampNode;

impl Operator for StampNode {
    type Params = StampParams;
    type In = StampIn;
    type Out = StampOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "stamp",
            "Stamp",
            "combine",
            "Places a small RGBN (its relief, optionally its colour) at positions with an affine map (Pereira & Velho §IV, Fig. 4). The stamp is integrated once and its windowed height added, so the stamped relief is integrable for any map.",
        )
    }
    fn check(p: &StampParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(_: &StampParams) -> Kind {
        // The stamped height is differentiated over one pixel; the stamp itself is read whole
        // (its port says so). Positions and the falloff are declared in pixels.
        Kind::Area {
            halo: 1,
            coarse: Coarse::Scaled,
        }
    }
    fn damage(
        old: &StampParams,
        new: &StampParams,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        let (sw, sh) = (*inputs.get(1)?)?;
        let same_but_positions = StampParams {
            positions: new.positions.clone(),
            ..old.clone()
        } == *new;
        let (ob, nb) = (placement_bounds(old, sw, sh), placement_bounds(new, sw, sh));
        if !same_but_positions {
            return Some(ob.into_iter().chain(nb).collect());
        }
        // Placements that moved, appeared or went: their old and new footprints.
        let f = |p: &[f64; 2]| p.map(|v| v as f32);
        let mut out = Vec::new();
        for k in 0..ob.len().max(nb.len()) {
            let (o, n) = (old.positions.get(k), new.positions.get(k));
            if o.map(f) != n.map(f) {
                out.extend(ob.get(k).copied());
                out.extend(nb.get(k).copied());
            }
        }
        Some(out)
    }
    fn run(p: &StampParams, i: StampIn, _: &RunContext) -> Result<StampOut, RgbnError> {
        let region = i.region.as_ref().map(|m| m.data());
        let (image, rep) = stamp_image(&i.image, &i.stamp, region, p)?;
        Ok(StampOut {
            image,
            relative_rms_curl: rep.curl_after.relative,
        })
    }
}

crate::inputs! {
    /// Inputs of [`ExtractNode`].
    pub struct ExtractIn {
        /// Image to cut from.
        pub image: RgbnImage,
        /// Optional region (the image's size): its bounding box is cut, its coverage is the piece's mask.
        pub region: Option<Mask>,
    }
}

crate::outputs! {
    /// Outputs of [`ExtractNode`].
    pub struct ExtractOut {
        /// The piece (at most 512 px a side).
        pub stamp: RgbnImage,
    }
}

/// Extract: a piece of an image as a stamp.
pub struct ExtractNode;

impl Operator for ExtractNode {
    type Params = ExtractParams;
    type In = ExtractIn;
    type Out = ExtractOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "extract",
            "Extract stamp",
            "combine",
            "Cuts a piece out of an RGBN image to stamp elsewhere (Pereira & Velho Fig. 4): a rectangle, or the bounding box of a region mask whose coverage becomes the piece's mask; optionally high-passed so only its detail is stamped.",
        )
    }
    fn kind(_: &ExtractParams) -> Kind {
        // The piece's size and place come from the whole region.
        Kind::GLOBAL
    }
    fn out_size(p: &ExtractParams, inputs: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        match inputs.get(1) {
            Some(Some(_)) => Some((512, 512)),
            _ => Some((p.width as usize, p.height as usize)),
        }
    }
    fn run(p: &ExtractParams, i: ExtractIn, _: &RunContext) -> Result<ExtractOut, RgbnError> {
        let region = i.region.as_ref().map(|m| m.data());
        Ok(ExtractOut {
            stamp: extract(&i.image, region, p)?,
        })
    }
}
