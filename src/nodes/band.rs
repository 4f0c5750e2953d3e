//! The band filters of [`crate::ops::band`] as a node: keep or remove a low-, high-, band-pass or
//! LoG band of the gradients ([`band_filter_image`]).

use super::kit::kernel_kind;
use super::{Coarse, Kind, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::band::{band_filter_image, BandParams};
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`BandNode`].
    pub struct BandIn {
        /// Image to filter.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`BandNode`].
    pub struct BandOut {
        /// Filtered normals; colour and mask unchanged.
        pub image: RgbnImage,
        /// RMS(curl) / RMS(|g|) of the filtered gradients inside the mask: the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Keep or remove a frequency band of the relief.
pub struct BandNode;

impl Operator for BandNode {
    type Params = BandParams;
    type In = BandIn;
    type Out = BandOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "band",
            "Band filter",
            "filter",
            "Keeps or removes a frequency band of the gradients (Pereira & Velho §III–IV): keep + remove = the input exactly. Removing a band prepares a base whose band a detail can replace (combine.linear).",
        )
    }
    fn check(p: &BandParams) -> Result<(), RgbnError> {
        p.validate()
    }
    fn kind(p: &BandParams) -> Kind {
        // Checked parameters always give a band.
        let halo = p.band().map_or(0, |b| b.kernel().support_px());
        kernel_kind(p.border, halo, Coarse::None)
    }
    fn run(p: &BandParams, i: BandIn, _: &RunContext) -> Result<BandOut, RgbnError> {
        let (image, curl) = band_filter_image(&i.image, p)?;
        Ok(BandOut {
            image,
            relative_rms_curl: curl.relative,
        })
    }
}
