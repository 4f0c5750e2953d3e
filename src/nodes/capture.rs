//! Photometric stereo ([`crate::capture::photometric`]) as a source node.
//!
//! The photos are named by a **list file** (one photo file name per line, relative to the list
//! file's folder, in the order of the light rows: the layout of DiLiGenT's `filenames.txt`),
//! because a parameter holds one path — or by an RTI light-position file (`.lp`), which names
//! the photos and their light directions at once. The evaluator keys the node by the bytes of the list,
//! light, intensity and mask files; **editing a photo in place without touching the list file
//! is not seen by the cache** (rewrite the list or run without a cache).
//!
//! Parameters of the photometric-stereo node (the nodes below); the solver lives in
//! [`crate::capture::photometric`].

use super::{Kind, NoInputs, OpSpec, Operator, RunContext};
use crate::capture::inputs::load_inputs;
use crate::capture::inputs::{read_name_list, PsInputSpec, Transfer};
use crate::capture::lp::is_lp;
use crate::capture::photometric::PsMethod;
use crate::capture::photometric::{photometric_stereo, PhotometricParams};
use crate::error::RgbnError;
use crate::raster::gradient::GradientField;
use crate::raster::integrate::curl_interior;
use crate::RgbnImage;
use std::path::{Path, PathBuf};

crate::params! {
    /// Parameters of the photometric-stereo node: its input files and the method.
    #[derive(Clone, Debug, PartialEq)]
    pub struct PhotometricSettings {
        /// Text file listing the photos (one file name per line, relative to the list's folder), in light-row order; or an RTI light-position file (.lp: a count line, then 'NAME x y z' per photo), which names the photos and their lights at once (leave lights empty).
        pub photos: String = String::new() => path,
        /// Light directions, one 'x y z' row per photo (x right, y up, z to the camera); an optional first line with the row count. Empty when photos is an .lp file.
        pub lights: String = String::new() => path.optional(),
        /// Optional per-light 'r g b' intensities, same layout (all 1 when empty).
        pub intensities: String = String::new() => path.optional(),
        /// Optional object mask (white = object), the photos' size.
        pub mask: String = String::new() => path.optional(),
        /// The estimator: trimmed (drop the darkest/brightest and the shadowed observations, re-solve), ls (Woodham's least squares), l1 (L1 regression by reweighted least squares), sbl (sparse Bayesian learning, Ikehata et al. 2012); docs/capture.md says which to use when.
        pub method: PsMethod = PsMethod::Trimmed => choice,
        /// Estimate the shading exponent k of I ∝ ρ (n·l)^k from the photos (the k whose linearised photos fit the Lambertian model best; docs/capture.md); off uses exponent.
        pub estimate_exponent: bool = true => bool,
        /// The shading exponent k when estimate_exponent is off: 1 is Lambert (Woodham); above 1 the shading falls off faster than the cosine (Minnaert).
        pub exponent: f64 = 1.0 => float.range(0.5, 2.0).soft(0.7, 1.5),
        /// The photos are sRGB-encoded (decoded to linear); off for linear/raw data.
        pub srgb: bool = false => bool,
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

impl PhotometricSettings {
    /// The input files these parameters name.
    ///
    /// # Errors
    /// A missing `photos` or `lights`, `lights` given beside an `.lp` file, and list-file errors.
    pub fn inputs(&self) -> Result<PsInputSpec, RgbnError> {
        self.check_files()?;
        let opt = |s: &String| (!s.is_empty()).then(|| PathBuf::from(s));
        // An `.lp` file names the photos and their directions: `load_inputs` reads both from it.
        let (photos, lights) = if is_lp(Path::new(&self.photos)) {
            (Vec::new(), PathBuf::from(&self.photos))
        } else {
            (
                photo_list(Path::new(&self.photos))?,
                PathBuf::from(&self.lights),
            )
        };
        Ok(PsInputSpec {
            photos,
            lights,
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

    /// Checks that the files the node needs are named: `photos` always; `lights` unless
    /// `photos` is an `.lp` file, and then not (the `.lp` gives the directions).
    ///
    /// # Errors
    /// [`RgbnError::InvalidParam`] naming the parameter.
    pub fn check_files(&self) -> Result<(), RgbnError> {
        if self.photos.is_empty() {
            return Err(RgbnError::param("photos", "a file path is required"));
        }
        match (is_lp(Path::new(&self.photos)), self.lights.is_empty()) {
            (false, true) => Err(RgbnError::param(
                "lights",
                "a file path is required (or name an .lp light-position file as photos)",
            )),
            (true, false) => Err(RgbnError::param(
                "lights",
                "leave empty: the .lp file given as photos holds the light directions",
            )),
            _ => Ok(()),
        }
    }
}

crate::outputs! {
    /// Outputs of [`PhotometricStereoNode`].
    pub struct PhotometricOut {
        /// Albedo + normals; mask 1 where a normal was estimated.
        pub image: RgbnImage,
        /// Pixels with an estimated normal.
        pub solved: f64,
        /// RMS(curl) / RMS(|g|) of the estimated normals (mask interior): the integrability readout (0 for the gradients of a height).
        pub relative_rms_curl: f64,
    }
}

/// Photometric stereo source.
pub struct PhotometricStereoNode;

impl Operator for PhotometricStereoNode {
    type Params = PhotometricSettings;
    type In = NoInputs;
    type Out = PhotometricOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "photometric_stereo",
            "Photometric stereo",
            "input",
            "Builds an RGBN image from photos of one viewpoint under known directional lights (Woodham 1980; trimmed robust variant; shading exponent estimated from the photos): albedo colour, unit normals and a mask of the solved pixels.",
        )
        // 2: the shading exponent is estimated by default.
        .version(2)
    }
    fn check(p: &PhotometricSettings) -> Result<(), RgbnError> {
        p.check_files()
    }
    fn kind(_: &PhotometricSettings) -> Kind {
        // Reads files whole.
        Kind::GLOBAL
    }
    fn run(
        p: &PhotometricSettings,
        _: NoInputs,
        _: &RunContext,
    ) -> Result<PhotometricOut, RgbnError> {
        let inputs = load_inputs(&p.inputs()?)?;
        let params = PhotometricParams {
            method: p.method,
            exponent: (!p.estimate_exponent).then_some(p.exponent as f32),
            ..PhotometricParams::default()
        };
        let (image, rep) = photometric_stereo(
            &inputs.stack,
            &inputs.lights,
            inputs.mask.as_deref(),
            &params,
        )?;
        // Over the mask's interior: the curl stencil must not straddle the silhouette.
        let interior = image
            .mask()
            .map(|m| curl_interior(m, image.width(), image.height()));
        let curl = GradientField::from_normals(&image)
            .curl_stats(interior.as_deref())
            .relative;
        Ok(PhotometricOut {
            image,
            solved: rep.solved as f64,
            relative_rms_curl: curl,
        })
    }
}
