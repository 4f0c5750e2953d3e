//! `--exr-compression` and `--exr-type`: how every command that writes EXR files stores them.

use crate::raster::io::{ExrCompression, ExrFormat, ExrPrecision, SaveOptions};
use clap::builder::PossibleValue;
use clap::{Args, ValueEnum};

impl ValueEnum for ExrCompression {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }
    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()).help(crate::params::Choice::doc(*self)))
    }
}

impl ValueEnum for ExrPrecision {
    fn value_variants<'a>() -> &'a [Self] {
        &[Self::Full, Self::Half]
    }
    fn to_possible_value(&self) -> Option<PossibleValue> {
        let c = *self;
        Some(PossibleValue::new(crate::params::Choice::name(c)).help(crate::params::Choice::doc(c)))
    }
}

/// How EXR files are written.
#[derive(Args, Clone, Copy, Debug, Default)]
pub struct ExrArgs {
    /// Compression of the EXR files written (all lossless). The default, zip, writes about
    /// the size of OpenEXR's ZIP for little more time than none (BENCHMARKS.md, "EXR
    /// compression").
    #[arg(long, value_enum, value_name = "C", default_value_t = ExrCompression::default())]
    pub exr_compression: ExrCompression,
    /// Sample type of the EXR files written: f32 (exact) or f16 (half the bytes).
    #[arg(long, value_enum, value_name = "T", default_value_t = ExrPrecision::Full)]
    pub exr_type: ExrPrecision,
}

impl ExrArgs {
    /// The EXR format asked for.
    #[must_use]
    pub fn format(&self) -> ExrFormat {
        ExrFormat {
            precision: self.exr_type,
            compression: self.exr_compression,
        }
    }

    /// The default save options with this EXR format.
    #[must_use]
    pub fn save_options(&self) -> SaveOptions {
        SaveOptions {
            precision: self.exr_type,
            compression: self.exr_compression,
            ..SaveOptions::default()
        }
    }
}
