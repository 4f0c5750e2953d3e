//! Integrability readout: the discrete curl `c = ∂p/∂y − ∂q/∂x` of an image's gradient field
//! in the integrator's default edge model (`Differences::Averaged`, see
//! [`crate::raster::gradient`]) as a scalar field, and its relative RMS.

use super::{Coarse, Kind, OpSpec, Operator, RunContext, Scalar};
use crate::error::RgbnError;
use crate::params::NoParams;
use crate::raster::gradient::GradientField;
use crate::RgbnImage;

crate::inputs! {
    /// Inputs of [`CurlOp`].
    pub struct CurlIn {
        /// Image.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`CurlOp`].
    pub struct CurlOut {
        /// Curl per pixel: circulation of the averaged edge slopes (the integrator's model) around the 2×2 pixels (x..x+1, r−1..r).
        pub curl: Scalar,
        /// RMS(curl) / RMS(|g|) inside the mask.
        pub relative_rms: f64,
    }
}

/// The curl map and relative RMS curl of an image.
pub struct CurlOp;

impl Operator for CurlOp {
    type Params = NoParams;
    type In = CurlIn;
    type Out = CurlOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "curl",
            "Curl readout",
            "analysis",
            "Integrability readout: the curl map of the gradient field and RMS(curl)/RMS(|g|) inside the mask (zero for the normals of a height).",
        )
    }
    fn kind(_: &NoParams) -> Kind {
        // Averaged edge slopes around a 2×2 block; a curl in per-pixel units has no coarse
        // form from the reduced field.
        Kind::Area {
            halo: 2,
            coarse: Coarse::None,
        }
    }
    fn run(_: &NoParams, i: CurlIn, _: &RunContext) -> Result<CurlOut, RgbnError> {
        let g = GradientField::from_normals(&i.image);
        let stats = g.curl_stats(i.image.mask());
        Ok(CurlOut {
            curl: Scalar::new(g.curl()),
            relative_rms: stats.relative,
        })
    }
}
