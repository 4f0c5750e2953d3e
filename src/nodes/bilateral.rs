//! The RGBN bilateral filter of [`crate::ops::bilateral`] as a node, with the base/detail split
//! ([`split`](crate::ops::bilateral::split)) as its two outputs.

use super::{Coarse, Kind, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::bilateral::{detail, filtered, BilateralParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`BilateralNode`].
    pub struct BilateralIn {
        /// Image to split.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`BilateralNode`].
    pub struct BilateralOut {
        /// The filtered image (colour smoothed only with filter_color).
        pub base: RgbnImage,
        /// Detail normals in the base's frame; the input's colour.
        pub detail: RgbnImage,
        /// RMS(curl) / RMS(|g|) of the base's gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Bilateral filter and base/detail split.
pub struct BilateralNode;

impl Operator for BilateralNode {
    type Params = BilateralParams;
    type In = BilateralIn;
    type Out = BilateralOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "bilateral",
            "Bilateral split",
            "filter",
            "RGBN bilateral filter (Toler-Franklin et al. 2007; Pereira & Velho §VII): base = the edge-preserving smoothing of the normals, detail = the rotation taking the base to the input, as a normal in the base's tangent frame. combine.rotation (blend, same frame) of base and detail gives the input back.",
        )
        // The detail and the readout are computed only when read: the base alone is the
        // filter (its kernel's cost).
        .lazy_outputs()
    }
    fn check(p: &BilateralParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(p: &BilateralParams) -> Kind {
        // The range weights are not a linear filter: no coarse form.
        Kind::Area {
            halo: p.radius_px(),
            coarse: Coarse::None,
        }
    }
    fn run(
        p: &BilateralParams,
        i: BilateralIn,
        ctx: &RunContext,
    ) -> Result<BilateralOut, RgbnError> {
        let base = filtered(&i.image, p)?;
        // Outputs not read get placeholders (the evaluator records them as skipped): an
        // empty image, NaN.
        let detail = if ctx.wants(1) {
            detail(&i.image, &base, p)?
        } else {
            RgbnImage::flat(0, 0, [0.0; 3])
        };
        let relative_rms_curl = if ctx.wants(2) {
            crate::raster::gradient::curl_stats_of_normals(&base).relative
        } else {
            f64::NAN
        };
        Ok(BilateralOut {
            base,
            detail,
            relative_rms_curl,
        })
    }
}
