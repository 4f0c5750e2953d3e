//! Integrability readout: the discrete curl `c = ∂p/∂y − ∂q/∂x` of an image's gradient field
//! in the integrator's default edge model (`Differences::Averaged`, see
//! [`crate::raster::gradient`]) as a scalar field, and its relative RMS.

use super::{Footprint, Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::params::NoParams;
use crate::raster::gradient::GradientField;
use std::sync::Arc;

/// The curl map and relative RMS curl of an image.
pub struct CurlOp;

impl Operator for CurlOp {
    type Params = NoParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "curl",
            "Curl readout",
            "analysis",
            "Integrability readout: the curl map of the gradient field and RMS(curl)/RMS(|g|) inside the mask (zero for the normals of a height).",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image."))
        .output(PortSpec::new("curl", PortType::Scalar, "Curl per pixel: circulation of the averaged edge slopes (the integrator's model) around the 2×2 pixels (x..x+1, r−1..r)."))
        .output(PortSpec::new(
            "relative_rms",
            PortType::Number,
            "RMS(curl) / RMS(|g|) inside the mask.",
        ))
    }
    fn footprint(_: &NoParams, _input: usize) -> Footprint {
        // Averaged edge slopes around a 2×2 block.
        Footprint::Local { halo: 2 }
    }
    fn run(_: &NoParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let g = GradientField::from_normals(img);
        let stats = g.curl_stats(img.mask());
        Ok(vec![
            Value::Scalar(Arc::new(g.curl())),
            Value::Number(stats.relative),
        ])
    }
}
