//! Parameters of the photometric-stereo node ([`crate::nodes::capture`]); the solver lives in
//! [`crate::capture::photometric`].

use super::params::Choice;
use crate::capture::photometric::{read_name_list, PsInputSpec, PsMethod, Transfer};
use crate::error::RgbnError;
use std::path::{Path, PathBuf};

impl Choice for PsMethod {
    const ALL: &'static [Self] = &[PsMethod::LeastSquares, PsMethod::Trimmed];
    fn name(self) -> &'static str {
        match self {
            PsMethod::LeastSquares => "ls",
            PsMethod::Trimmed => "trimmed",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            PsMethod::LeastSquares => "Woodham's least squares on all unsaturated observations.",
            PsMethod::Trimmed => {
                "Drop the darkest/brightest and the shadowed observations, re-solve."
            }
        }
    }
}

crate::params! {
    /// Parameters of the photometric-stereo node: its input files and the method.
    #[derive(Clone, Debug, PartialEq)]
    pub struct PhotometricSettings {
        /// Text file listing the photos (one file name per line, relative to the list's folder), in light-row order.
        pub photos: String = String::new() => path,
        /// Light directions, one 'x y z' row per photo (x right, y up, z to the camera); an optional first line with the row count.
        pub lights: String = String::new() => path,
        /// Optional per-light 'r g b' intensities, same layout (all 1 when empty).
        pub intensities: String = String::new() => path.optional(),
        /// Optional object mask (white = object), the photos' size.
        pub mask: String = String::new() => path.optional(),
        /// ls: Woodham's least squares on all unsaturated observations; trimmed: drop the darkest/brightest and the shadowed observations, re-solve (robust to shadows and highlights).
        pub method: PsMethod = PsMethod::Trimmed => choice,
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
    pub fn inputs(&self) -> Result<PsInputSpec, RgbnError> {
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
