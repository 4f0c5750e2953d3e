//! Photometric stereo ([`crate::capture::photometric`]) as a source node.
//!
//! The photos are named by a **list file** (one photo file name per line, relative to the list
//! file's folder, in the order of the light rows: the layout of DiLiGenT's `filenames.txt`),
//! because a parameter holds one path — or by an RTI light-position file (`.lp`), which names
//! the photos and their light directions at once. The evaluator keys the node by the bytes of the list,
//! light, intensity and mask files; **editing a photo in place without touching the list file
//! is not seen by the cache** (rewrite the list or run without a cache).

use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::capture::inputs::load_inputs;
use crate::capture::photometric::{photometric_stereo, PhotometricParams};
use crate::error::RgbnError;
use crate::ops::capture::PhotometricSettings;
use crate::raster::gradient::GradientField;
use crate::raster::integrate::curl_interior;

/// Photometric stereo source.
pub struct PhotometricStereoNode;

impl Operator for PhotometricStereoNode {
    type Params = PhotometricSettings;
    fn spec() -> OpSpec {
        OpSpec::new(
            "photometric_stereo",
            "Photometric stereo",
            "input",
            "Builds an RGBN image from photos of one viewpoint under known directional lights (Woodham 1980; trimmed robust variant): albedo colour, unit normals and a mask of the solved pixels.",
        )
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Albedo + normals; mask 1 where a normal was estimated.",
        ))
        .output(PortSpec::new(
            "solved",
            PortType::Number,
            "Pixels with an estimated normal.",
        ))
        .output(super::kit::curl_port("estimated normals (mask interior)"))
    }
    fn check(p: &PhotometricSettings) -> Result<(), RgbnError> {
        p.check_files()
    }
    fn run(
        p: &PhotometricSettings,
        _: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let inputs = load_inputs(&p.inputs()?)?;
        let params = PhotometricParams {
            method: p.method,
            ..PhotometricParams::default()
        };
        let (img, rep) = photometric_stereo(
            &inputs.stack,
            &inputs.lights,
            inputs.mask.as_deref(),
            &params,
        )?;
        // Over the mask's interior: the curl stencil must not straddle the silhouette.
        let interior = img
            .mask()
            .map(|m| curl_interior(m, img.width(), img.height()));
        let curl = GradientField::from_normals(&img)
            .curl_stats(interior.as_deref())
            .relative;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(rep.solved as f64),
            Value::Number(curl),
        ])
    }
}
