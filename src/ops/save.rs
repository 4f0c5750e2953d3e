//! Parameters of the image writer ([`crate::nodes::save`]); the writing itself is
//! [`crate::raster::io::save`].

use crate::raster::io::{ExrPrecision, NormalConvention, SaveOptions};

// Kept at its old path (`crate::ops::save::write_value`) for the command line and the editor.
pub use crate::nodes::save::write_value;

crate::choice_enum! {
    /// Bits per channel of PNG/TIFF normal maps.
    pub enum Bits {
        /// 8 bits.
        Eight = "8",
        /// 16 bits.
        Sixteen = "16",
    }
}

crate::params! {
    /// Parameters of the image writer.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SaveParams {
        /// Output: .exr (colour + normals + mask) or .png/.tif (normal map).
        pub path: String = String::new() => path.output(),
        /// Bits per channel of PNG/TIFF normal maps.
        pub bits: Bits = Bits::Sixteen => choice,
        /// Write normal maps in the DirectX convention (green = −y).
        pub dx: bool = false => bool,
        /// Write EXR as 16-bit half floats.
        pub half: bool = false => bool,
    }
}

impl SaveParams {
    /// The I/O options these parameters describe.
    #[must_use]
    pub fn options(&self) -> SaveOptions {
        SaveOptions {
            bits: match self.bits {
                Bits::Eight => 8,
                Bits::Sixteen => 16,
            },
            convention: if self.dx {
                NormalConvention::DirectX
            } else {
                NormalConvention::OpenGl
            },
            precision: if self.half {
                ExrPrecision::Half
            } else {
                ExrPrecision::Full
            },
        }
    }
}
