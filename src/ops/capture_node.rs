//! Photometric stereo ([`crate::capture::photometric`]) as a source node.
//!
//! The photos are named by a **list file** (one photo file name per line, relative to the list
//! file's folder, in the order of the light rows: the layout of DiLiGenT's `filenames.txt`),
//! because a parameter holds one path. The evaluator keys the node by the bytes of the list,
//! light, intensity and mask files; **editing a photo in place without touching the list file
//! is not seen by the cache** (rewrite the list or run without a cache).

use super::params::{Meta, ParamVisitor, Params};
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::capture::inputs::{load_inputs, read_name_list, PsInputSpec, Transfer};
use crate::capture::photometric::{photometric_stereo, PhotometricParams, PsMethod};
use crate::error::RgbnError;
use crate::raster::gradient::GradientField;
use crate::raster::integrate::curl_interior;
use std::path::{Path, PathBuf};

/// Parameters of [`PhotometricStereoNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct PhotometricNodeParams {
    /// List file of photos.
    pub photos: String,
    /// Light directions file.
    pub lights: String,
    /// Optional light intensities file.
    pub intensities: String,
    /// Optional mask image.
    pub mask: String,
    /// `ls` or `trimmed`.
    pub method: &'static str,
    /// Photos are sRGB-encoded.
    pub srgb: bool,
}

impl Default for PhotometricNodeParams {
    fn default() -> Self {
        Self {
            photos: String::new(),
            lights: String::new(),
            intensities: String::new(),
            mask: String::new(),
            method: "trimmed",
            srgb: false,
        }
    }
}

impl Params for PhotometricNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.path(
            "photos",
            &mut self.photos,
            &Meta::new("Text file listing the photos (one file name per line, relative to the list's folder), in light-row order."),
        );
        v.path(
            "lights",
            &mut self.lights,
            &Meta::new("Light directions, one 'x y z' row per photo (x right, y up, z to the camera); an optional first line with the row count."),
        );
        v.path(
            "intensities",
            &mut self.intensities,
            &Meta::new("Optional per-light 'r g b' intensities, same layout (all 1 when empty).")
                .optional(),
        );
        v.path(
            "mask",
            &mut self.mask,
            &Meta::new("Optional object mask (white = object), the photos' size.").optional(),
        );
        v.choice(
            "method",
            &mut self.method,
            &["ls", "trimmed"],
            &Meta::new("ls: Woodham's least squares on all unsaturated observations; trimmed: drop the darkest/brightest and the shadowed observations, re-solve (robust to shadows and highlights)."),
        );
        v.bool(
            "srgb",
            &mut self.srgb,
            &Meta::new("The photos are sRGB-encoded (decoded to linear); off for linear/raw data."),
        );
    }
}

/// The photo paths of a list file (relative names resolved against the list's folder).
///
/// # Errors
/// File errors naming the list.
pub fn photo_list(list: &Path) -> Result<Vec<PathBuf>, RgbnError> {
    let dir = list.parent().unwrap_or(Path::new("."));
    Ok(read_name_list(list)?
        .into_iter()
        .map(|n| dir.join(n))
        .collect())
}

impl PhotometricNodeParams {
    fn spec(&self) -> Result<PsInputSpec, RgbnError> {
        let opt = |s: &String| (!s.is_empty()).then(|| PathBuf::from(s));
        Ok(PsInputSpec {
            photos: photo_list(Path::new(&self.photos))?,
            lights: PathBuf::from(&self.lights),
            intensities: opt(&self.intensities),
            names: None,
            mask: opt(&self.mask),
            transfer: if self.srgb {
                Transfer::Srgb
            } else {
                Transfer::Linear
            },
        })
    }
}

/// Photometric stereo source.
pub struct PhotometricStereoNode;

impl Operator for PhotometricStereoNode {
    type Params = PhotometricNodeParams;
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
        .output(super::node_kit::curl_port("estimated normals (mask interior)"))
    }
    fn check(p: &PhotometricNodeParams) -> Result<(), RgbnError> {
        for (name, v) in [("photos", &p.photos), ("lights", &p.lights)] {
            if v.is_empty() {
                return Err(RgbnError::param(name, "a file path is required"));
            }
        }
        Ok(())
    }
    fn run(
        p: &PhotometricNodeParams,
        _: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let inputs = load_inputs(&p.spec()?)?;
        let params = PhotometricParams {
            method: if p.method == "ls" {
                PsMethod::LeastSquares
            } else {
                PsMethod::Trimmed
            },
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
