//! `--exr-compression` and `--exr-type`: how every command that writes EXR files stores them;
//! `--zarr-dtype`, `--chunk`, `--zarr-shard`, `--zarr-compression`, `--zarr-levels`: how it writes
//! OME-Zarr stores (`.zarr`).

use crate::raster::io::zarr::{ZarrCompression, ZarrDtype, ZarrOptions, DEFAULT_CHUNK};
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

impl ValueEnum for ZarrDtype {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }
    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()).help(crate::params::Choice::doc(*self)))
    }
}

impl ValueEnum for ZarrCompression {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }
    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()).help(crate::params::Choice::doc(*self)))
    }
}

/// How EXR files and OME-Zarr stores are written.
#[derive(Args, Clone, Copy, Debug)]
pub struct ExrArgs {
    /// Compression of the EXR files written (all lossless). The default, zip, writes about
    /// the size of OpenEXR's ZIP for little more time than none (BENCHMARKS.md, "EXR
    /// compression").
    #[arg(long, value_enum, value_name = "C", default_value_t = ExrCompression::default())]
    pub exr_compression: ExrCompression,
    /// Sample type of the EXR files written: f32 (exact) or f16 (half the bytes).
    #[arg(long, value_enum, value_name = "T", default_value_t = ExrPrecision::Full)]
    pub exr_type: ExrPrecision,
    /// Data type of the OME-Zarr stores written (.zarr): float32 (exact), float16, or uint16
    /// over each channel's range (normals [-1, 1], colour and mask [0, 1]). Pictures are uint8.
    #[arg(long, value_enum, value_name = "T", default_value_t = ZarrDtype::F32)]
    pub zarr_dtype: ZarrDtype,
    /// Chunk side in pixels of the OME-Zarr stores written (level k's chunks are CHUNK / 2^k;
    /// a --region written into a store must be aligned to it).
    #[arg(long, value_name = "PX", default_value_t = DEFAULT_CHUNK)]
    pub chunk: usize,
    /// Shard side in pixels of the OME-Zarr stores written (a multiple of --chunk; 0: no
    /// sharding): fewer, larger files; a --region must then be aligned to the shards.
    #[arg(long, value_name = "PX", default_value_t = 0)]
    pub zarr_shard: usize,
    /// Compression of the OME-Zarr stores' chunks (lossless): zstd, blosc or none
    /// (BENCHMARKS.md, thirteenth session).
    #[arg(long, value_enum, value_name = "C", default_value_t = ZarrCompression::Zstd)]
    pub zarr_compression: ZarrCompression,
    /// Most levels of detail in the OME-Zarr stores written (level 0 included; default: down
    /// to 32-pixel chunks or a 32-pixel level).
    #[arg(long, value_name = "N")]
    pub zarr_levels: Option<usize>,
}

impl Default for ExrArgs {
    fn default() -> Self {
        Self {
            exr_compression: ExrCompression::default(),
            exr_type: ExrPrecision::Full,
            zarr_dtype: ZarrDtype::F32,
            chunk: DEFAULT_CHUNK,
            zarr_shard: 0,
            zarr_compression: ZarrCompression::Zstd,
            zarr_levels: None,
        }
    }
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

    /// How OME-Zarr stores are written.
    #[must_use]
    pub fn zarr_options(&self) -> ZarrOptions {
        ZarrOptions {
            dtype: self.zarr_dtype,
            compression: self.zarr_compression,
            chunk: self.chunk,
            shard: self.zarr_shard,
            levels: self.zarr_levels,
        }
    }

    /// The default save options with this EXR format and these Zarr options.
    #[must_use]
    pub fn save_options(&self) -> SaveOptions {
        SaveOptions {
            precision: self.exr_type,
            compression: self.exr_compression,
            zarr: self.zarr_options(),
            ..SaveOptions::default()
        }
    }
}
