//! Writing values to files: the `save` node and [`write_value`], which the CLI uses for graph
//! outputs (`-o NAME=PATH`). Writes are atomic (temporary file + rename) and never overwrite a
//! file the graph reads.
//!
//! Parameters of the image writer (the nodes below); the writing itself is
//! [`crate::raster::io::save`].

use super::{Kind, OpSpec, Operator, RunContext, Value};
use crate::error::RgbnError;
use crate::raster::io::zarr::{Content, ZarrCompression, ZarrDtype, ZarrOptions};
use crate::raster::io::{self, Format, SaveOptions};
use crate::raster::io::{ExrCompression, ExrPrecision, NormalConvention};
use crate::raster::window::Rect;
use crate::raster::Plane;
use crate::RgbnImage;
use std::path::{Path, PathBuf};

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
        /// Output: .exr or .zarr (an OME-Zarr store: colour + normals + mask, with its levels) or .png/.tif (normal map).
        pub path: String = String::new() => path.output(),
        /// Bits per channel of PNG/TIFF normal maps.
        pub bits: Bits = Bits::Sixteen => choice,
        /// Write normal maps in the DirectX convention (green = −y).
        pub dx: bool = false => bool,
        /// Write EXR as 16-bit half floats (f16) instead of 32-bit floats.
        pub half: bool = false => bool,
        /// Compression of an EXR (lossless): zip (default: zlib over 16 lines, about OpenEXR's size for little more time than none), zips, rle, piz or none.
        pub exr_compression: ExrCompression = ExrCompression::default() => choice,
        /// Data type of an OME-Zarr store: float32, float16, or uint16 over each channel's range.
        pub zarr_dtype: ZarrDtype = ZarrDtype::F32 => choice,
        /// Chunk side of an OME-Zarr store in pixels (level k's chunks are chunk / 2^k).
        pub zarr_chunk: i64 = crate::raster::io::zarr::DEFAULT_CHUNK as i64 => int.unit("px").range(16.0, 8192.0),
        /// Compression of an OME-Zarr store's chunks: zstd (default), blosc or none.
        pub zarr_compression: ZarrCompression = ZarrCompression::Zstd => choice,
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
            compression: self.exr_compression,
            zarr: ZarrOptions {
                dtype: self.zarr_dtype,
                chunk: self.zarr_chunk as usize,
                compression: self.zarr_compression,
                ..ZarrOptions::default()
            },
        }
    }
}

/// Writes `value` to `path` by its type and the path's extension:
/// RGBN → `.exr` (everything), `.png`/`.tif` (normal map) or `.ptm` (LRGB PTM); picture → `.png`/`.tif`;
/// mask → `.png`/`.tif` (16-bit grey) or `.exr`; scalar field → `.exr` (`Y` channel, f32);
/// number → a text file with the value.
pub fn write_value(value: &Value, path: &Path, opts: &SaveOptions) -> Result<(), RgbnError> {
    if matches!(Format::of(path), Ok(Format::Zarr)) {
        return write_value_zarr(value, path, &opts.zarr, None);
    }
    match value {
        Value::Rgbn(img) => io::save(img, path, opts),
        Value::Picture(p) => match Format::of(path)? {
            f @ (Format::Png | Format::Tiff) => {
                io::write_raster8(&p.rgba, p.width, p.height, 4, f, path)
            }
            _ => Err(unsupported(path, "pictures are written as .png or .tif")),
        },
        Value::Mask(m) => match Format::of(path)? {
            Format::Exr => write_exr_plane(m, path),
            f @ (Format::Png | Format::Tiff) => {
                let data: Vec<u16> = m
                    .data()
                    .iter()
                    .map(|v| (v.clamp(0.0, 1.0) * 65535.0).round() as u16)
                    .collect();
                io::write_raster16(&data, m.width(), m.height(), 1, f, path)
            }
            Format::Jpeg | Format::Ptm | Format::Rti | Format::Zarr => {
                Err(unsupported(path, "masks are written as .png, .tif or .exr"))
            }
        },
        Value::Scalar(s) => match Format::of(path) {
            Ok(Format::Exr) => write_exr_plane(s, path),
            _ => Err(unsupported(path, "scalar fields are written as .exr")),
        },
        Value::Number(x) => io::write_atomic(path, |w| {
            use std::io::Write;
            writeln!(w, "{x}").map_err(|e| e.to_string())
        }),
    }
}

/// Writes `value` as an OME-Zarr store ([`crate::raster::io::zarr`]): the whole store, or with
/// `region` = (the output's whole size, a rectangle of it), `value` is that rectangle and only
/// its chunks are written (the store is created at the whole size if it does not exist).
pub fn write_value_zarr(
    value: &Value,
    path: &Path,
    opts: &ZarrOptions,
    region: Option<((usize, usize), Rect)>,
) -> Result<(), RgbnError> {
    let bytes: Vec<Vec<f32>>;
    let (content, planes, size): (Content, Vec<&[f32]>, (usize, usize)) = match value {
        Value::Rgbn(img) => {
            let [r, g, b] = img.color();
            let [x, y, z] = img.normal();
            let mut p: Vec<&[f32]> = vec![r, g, b, x, y, z];
            p.extend(img.mask());
            let c = Content::Rgbn {
                mask: img.mask().is_some(),
            };
            (c, p, (img.width(), img.height()))
        }
        Value::Picture(pic) => {
            bytes = crate::raster::io::zarr::rgba_planes(&pic.rgba);
            let p = bytes.iter().map(Vec::as_slice).collect();
            (Content::Picture, p, (pic.width, pic.height))
        }
        Value::Mask(m) => (Content::Mask, vec![m.data()], (m.width(), m.height())),
        Value::Scalar(f) => (Content::Scalar, vec![f.data()], (f.width(), f.height())),
        Value::Number(_) => {
            return Err(unsupported(
                path,
                "numbers are written as text files, not OME-Zarr stores",
            ))
        }
    };
    match region {
        None => io::zarr::save_planes_zarr(path, size, content, &planes, opts, None),
        Some((full, rect)) => {
            io::zarr::save_planes_zarr(path, full, content, &planes, opts, Some(rect))
        }
    }
}

fn unsupported(path: &Path, why: &str) -> RgbnError {
    RgbnError::UnsupportedFormat {
        format: format!(
            "{} ({why})",
            path.extension()
                .map(|e| e.to_string_lossy().into_owned())
                .unwrap_or_default()
        ),
        path: path.into(),
    }
}

/// Writes one plane as a single-channel (`Y`) f32 EXR (ZIP): the engine's writer, which
/// compresses blocks on every core and stops between batches when the run is cancelled (the
/// exr crate's own writer took a second, on one core, for a 4K height).
fn write_exr_plane(p: &Plane, path: &Path) -> Result<(), RgbnError> {
    io::save_plane_exr(p, "Y", path)
}

crate::inputs! {
    /// Inputs of [`Save`].
    pub struct SaveIn {
        /// Image to write.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`Save`].
    pub struct SaveOut {
        /// The same image.
        pub image: RgbnImage,
    }
}

/// Writes its input to a file when evaluated and passes it through. Never cached.
pub struct Save;

impl Operator for Save {
    type Params = SaveParams;
    type In = SaveIn;
    type Out = SaveOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "save",
            "Save image",
            "output",
            "Writes the image to a file (atomically; never over a file the graph reads) and passes it through; runs whenever its output is requested.",
        )
        .side_effect()
    }
    fn check(p: &SaveParams) -> Result<(), RgbnError> {
        match Format::of(Path::new(&p.path))? {
            Format::Rti => Err(unsupported(
                Path::new(&p.path),
                "HSH .rti files are read, not written: write .ptm for RTIViewer",
            )),
            _ => Ok(()),
        }
    }
    fn kind(_: &SaveParams) -> Kind {
        // Writes the whole image.
        Kind::GLOBAL
    }
    fn run(p: &SaveParams, i: SaveIn, ctx: &RunContext) -> Result<SaveOut, RgbnError> {
        let path = PathBuf::from(&p.path);
        let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
        io::check_output(&path, &protected)?;
        io::save(&i.image, &path, &p.options())?;
        Ok(SaveOut { image: i.image })
    }
}
