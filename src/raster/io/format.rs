//! [`Format`]: the file formats rgbn reads and writes, by extension.

use crate::error::RgbnError;
use std::path::Path;

/// File formats rgbn reads and writes, decided by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Png,
    Jpeg,
    Tiff,
    /// Polynomial Texture Map: read (LRGB or RGB, see [`crate::raster::ptm`]); an RGBN image
    /// is written as an LRGB PTM ([`crate::raster::ptm::save_ptm`]).
    Ptm,
    /// RTI file with hemispherical harmonics (read only, see [`crate::raster::hsh`]).
    Rti,
    /// An OME-Zarr store, a folder ([`super::zarr`]).
    Zarr,
}

impl Format {
    /// The format of `path` by its extension (case-insensitive).
    pub fn of(path: &Path) -> Result<Self, RgbnError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        Ok(match ext.as_str() {
            "exr" => Self::Exr,
            "png" => Self::Png,
            "jpg" | "jpeg" => Self::Jpeg,
            "tif" | "tiff" => Self::Tiff,
            "ptm" => Self::Ptm,
            "rti" => Self::Rti,
            "zarr" => Self::Zarr,
            _ => {
                return Err(RgbnError::UnsupportedFormat {
                    format: if ext.is_empty() {
                        "(no extension)".into()
                    } else {
                        ext
                    },
                    path: path.into(),
                })
            }
        })
    }
}
