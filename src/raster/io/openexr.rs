//! EXR files (exr crate): colour `R,G,B` (linear), normal `N.X,N.Y,N.Z`, mask `A`; f16 or f32
//! (module docs of [`super`]).

use super::exr_write::{write_planes, ExrFormat};
use super::{open_check, write_atomic, Format, LoadOptions, DEFAULT_ALBEDO};
use crate::error::RgbnError;
use crate::raster::{buf, check_size, Plane, RgbnImage};
use rayon::prelude::*;
use std::path::Path;

pub(super) struct ExrChannels {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) channels: Vec<(String, Vec<f32>)>,
}

impl ExrChannels {
    pub(super) fn take(&mut self, name: &str) -> Option<Vec<f32>> {
        let i = self.channels.iter().position(|(n, _)| n == name)?;
        Some(self.channels.swap_remove(i).1)
    }
    pub(super) fn names(&self) -> String {
        self.channels
            .iter()
            .map(|(n, _)| n.as_str())
            .collect::<Vec<_>>()
            .join(",")
    }
    pub(super) fn take_rgb(&self, path: &Path) -> Result<[Vec<f32>; 3], RgbnError> {
        let mut me = ExrChannels {
            width: self.width,
            height: self.height,
            channels: self.channels.clone(),
        };
        me.take_three(["R", "G", "B"], path)
    }
    pub(super) fn take_three(
        &mut self,
        names: [&str; 3],
        path: &Path,
    ) -> Result<[Vec<f32>; 3], RgbnError> {
        let have = self.names();
        let mut out = Vec::with_capacity(3);
        for n in names {
            out.push(self.take(n).ok_or_else(|| RgbnError::Decode {
                detail: format!("missing channel {n} (channels present: {have})"),
                path: path.into(),
            })?);
        }
        Ok(out.try_into().expect("three channels"))
    }
}

/// Reads every channel of an EXR's first layer (largest resolution) as f32.
pub(super) fn read_exr_channels(path: &Path) -> Result<ExrChannels, RgbnError> {
    open_check(path)?;
    let exr_err = |e: exr::error::Error| match e {
        exr::error::Error::Io(io) if io.kind() != std::io::ErrorKind::UnexpectedEof => {
            RgbnError::Read {
                path: path.into(),
                source: io,
            }
        }
        other => RgbnError::Decode {
            detail: other.to_string(),
            path: path.into(),
        },
    };
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(exr_err)?;
    let header = meta.headers.first().ok_or_else(|| RgbnError::Decode {
        detail: "no layers".into(),
        path: path.into(),
    })?;
    let size = header.layer_size;
    check_size(size.0, size.1, &path.display().to_string())?;
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(exr_err)?;
    let layer = image.layer_data;
    let (width, height) = (layer.size.0, layer.size.1);
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|c| {
            let v: Vec<f32> = match c.sample_data {
                FlatSamples::F32(v) => v,
                FlatSamples::F16(v) => v.into_par_iter().map(f16::to_f32).collect(),
                FlatSamples::U32(v) => v.into_par_iter().map(|u| u as f32).collect(),
            };
            (c.name.to_string(), v)
        })
        .collect();
    Ok(ExrChannels {
        width,
        height,
        channels,
    })
}

/// Loads an RGBN EXR: colour `R,G,B` (default albedo if absent), normals `N.X,N.Y,N.Z` (or, with
/// [`LoadOptions::exr_rgb_is_normal`], `R,G,B` as normals in [−1, 1]), mask `A` if present.
pub fn load_exr(path: &Path, opts: &LoadOptions) -> Result<RgbnImage, RgbnError> {
    let mut e = read_exr_channels(path)?;
    let (w, h) = (e.width, e.height);
    let n = w * h;
    let (color, normal) = if opts.exr_rgb_is_normal {
        let normal = e.take_three(["R", "G", "B"], path)?;
        (
            [
                buf::filled_f32(n, DEFAULT_ALBEDO),
                buf::filled_f32(n, DEFAULT_ALBEDO),
                buf::filled_f32(n, DEFAULT_ALBEDO),
            ],
            normal,
        )
    } else {
        let have = e.names();
        let normal = e.take_three(["N.X", "N.Y", "N.Z"], path).map_err(|_| RgbnError::Decode {
            detail: format!(
                "no normal channels N.X,N.Y,N.Z (channels present: {have}); if R,G,B is a normal pass, use --exr-rgb-is-normal"
            ),
            path: path.into(),
        })?;
        let color = e.take_three(["R", "G", "B"], path).unwrap_or_else(|_| {
            [
                buf::filled_f32(n, DEFAULT_ALBEDO),
                buf::filled_f32(n, DEFAULT_ALBEDO),
                buf::filled_f32(n, DEFAULT_ALBEDO),
            ]
        });
        (color, normal)
    };
    let mask = e.take("A");
    RgbnImage::new(w, h, color, normal, mask)
}

/// Precision of EXR output channels.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum ExrPrecision {
    /// 16-bit half floats: half the size, ~3 significant digits (normals to ~5e-4).
    Half,
    /// 32-bit floats: exact round trip.
    #[default]
    Full,
}

/// Compression of EXR output (all lossless). Each is the OpenEXR compression of the same name,
/// written block by block on every core. The default, ZIP, is chosen by size and speed
/// measured on 4K RGBN images (BENCHMARKS.md, "EXR compression"): about the size of
/// OpenEXR's own ZIP for little more time than no compression, because the blocks' noise
/// (float mantissas) is stored and only the rest deflated.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum ExrCompression {
    /// No compression: the largest files (24–28 bytes a pixel in f32).
    None,
    /// Run-length over byte differences, one line a block: fast; shrinks constant half-float
    /// planes, but not 32-bit ones (their bytes alternate rather than repeat).
    Rle,
    /// zlib, one line a block.
    Zips,
    /// zlib over blocks of 16 lines (OpenEXR's and OpenCV's default).
    #[default]
    Zip,
    /// Wavelet + Huffman over 32 lines: good on noisy data, slower.
    Piz,
}

impl ExrCompression {
    /// Every compression, in menu order.
    pub const ALL: [Self; 5] = [Self::None, Self::Rle, Self::Zips, Self::Zip, Self::Piz];

    /// The name used on the command line and in graph files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Rle => "rle",
            Self::Zips => "zips",
            Self::Zip => "zip",
            Self::Piz => "piz",
        }
    }

    pub(super) fn to_exr(self) -> exr::compression::Compression {
        use exr::compression::Compression as C;
        match self {
            Self::None => C::Uncompressed,
            Self::Rle => C::RLE,
            Self::Zips => C::ZIP1,
            Self::Zip => C::ZIP16,
            Self::Piz => C::PIZ,
        }
    }
}

impl crate::params::Choice for ExrCompression {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        Self::name(self)
    }
    fn doc(self) -> &'static str {
        match self {
            Self::None => "No compression (largest files).",
            Self::Rle => "Run-length, one line a block: fast; shrinks constant half floats only.",
            Self::Zips => "zlib, one line a block.",
            Self::Zip => "zlib over 16 lines (the default; OpenEXR's too).",
            Self::Piz => "Wavelet + Huffman over 32 lines: good on noisy data, slower.",
        }
    }
}

impl crate::params::Choice for ExrPrecision {
    const ALL: &'static [Self] = &[Self::Full, Self::Half];
    fn name(self) -> &'static str {
        match self {
            Self::Full => "f32",
            Self::Half => "f16",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            Self::Full => "32-bit floats: exact round trip.",
            Self::Half => "16-bit half floats: half the size, ~3 decimal digits.",
        }
    }
}

/// Writes an RGBN EXR (`R,G,B`, `N.X,N.Y,N.Z`, and `A` if masked) with the default
/// compression.
pub fn save_exr(img: &RgbnImage, path: &Path, precision: ExrPrecision) -> Result<(), RgbnError> {
    save_exr_with(img, path, precision, ExrCompression::default())
}

/// [`save_exr`] with a chosen compression.
pub fn save_exr_with(
    img: &RgbnImage,
    path: &Path,
    precision: ExrPrecision,
    compression: ExrCompression,
) -> Result<(), RgbnError> {
    let [r, g, b] = img.color();
    let [nx, ny, nz] = img.normal();
    let mut channels: Vec<(&str, &[f32])> = vec![
        ("R", r),
        ("G", g),
        ("B", b),
        ("N.X", nx),
        ("N.Y", ny),
        ("N.Z", nz),
    ];
    if let Some(m) = img.mask() {
        channels.push(("A", m));
    }
    write_planes_atomic(
        path,
        (img.width(), img.height()),
        &channels,
        ExrFormat {
            precision,
            compression,
        },
    )
}

/// Writes named planes as an EXR, atomically.
pub(super) fn write_planes_atomic(
    path: &Path,
    size: (usize, usize),
    channels: &[(&str, &[f32])],
    f: ExrFormat,
) -> Result<(), RgbnError> {
    write_atomic(path, |out| write_planes(out, size, channels, f))
}

/// Writes one plane (e.g. an integrated height, in pixels) as a single-channel 32-bit EXR
/// channel `channel` (use `"Z"` for heights), atomically.
///
/// # Errors
/// [`RgbnError::UnsupportedFormat`] unless `path` ends in `.exr`; write errors.
pub fn save_plane_exr(plane: &Plane, channel: &str, path: &Path) -> Result<(), RgbnError> {
    if Format::of(path)? != Format::Exr {
        return Err(RgbnError::UnsupportedFormat {
            format: "a single plane is written as .exr only".into(),
            path: path.into(),
        });
    }
    write_planes_atomic(
        path,
        (plane.width(), plane.height()),
        &[(channel, plane.data())],
        ExrFormat::default(),
    )
}

#[cfg(test)]
mod tests {
    use super::super::{load, InputSpec};
    use super::*;
    use crate::raster::sample::demo_medallion;

    #[test]
    fn exr_f32_roundtrip_is_exact() {
        let mut img = demo_medallion(64);
        img.set_mask(Some((0..64 * 64).map(|i| (i % 7) as f32 / 6.0).collect()))
            .unwrap();
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("a.exr");
        save_exr(&img, &p, ExrPrecision::Full).unwrap();
        let back = load(
            &InputSpec {
                rgbn: Some(p),
                ..Default::default()
            },
            &LoadOptions::default(),
        )
        .unwrap();
        assert_eq!(back.image, img);
    }

    #[test]
    fn exr_f16_roundtrip_is_within_half_precision() {
        let img = demo_medallion(32);
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("h.exr");
        save_exr(&img, &p, ExrPrecision::Half).unwrap();
        let back = load_exr(&p, &LoadOptions::default()).unwrap();
        for (a, b) in img.normal().iter().zip(back.normal()) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= 5e-4, "{x} {y}");
            }
        }
    }

    #[test]
    fn every_compression_round_trips_f32_exactly_and_f16_to_half_precision() {
        let mut img = demo_medallion(40);
        img.set_mask(Some((0..40 * 40).map(|i| (i % 5) as f32 / 4.0).collect()))
            .unwrap();
        let d = tempfile::tempdir().unwrap();
        for c in ExrCompression::ALL {
            let p = d.path().join(format!("{}.exr", c.name()));
            save_exr_with(&img, &p, ExrPrecision::Full, c).unwrap();
            let back = load_exr(&p, &LoadOptions::default()).unwrap();
            assert_eq!(back, img, "{}", c.name());
            save_exr_with(&img, &p, ExrPrecision::Half, c).unwrap();
            let back = load_exr(&p, &LoadOptions::default()).unwrap();
            for (a, b) in img.normal().iter().zip(back.normal()) {
                for (x, y) in a.iter().zip(b) {
                    assert!((x - y).abs() <= 5e-4, "{}: {x} {y}", c.name());
                }
            }
        }
    }

    #[test]
    fn rows_written_band_by_band_make_the_same_file_as_the_whole_image() {
        use super::super::targets::ExrTarget;
        // 37 rows in bands of 5: blocks of 16 (zip) and 32 (piz) lines span several bands.
        let img = demo_medallion(37);
        let d = tempfile::tempdir().unwrap();
        for c in ExrCompression::ALL {
            for precision in [ExrPrecision::Full, ExrPrecision::Half] {
                let whole = d.path().join("whole.exr");
                save_exr_with(&img, &whole, precision, c).unwrap();
                let banded = d.path().join("banded.exr");
                let format = ExrFormat {
                    precision,
                    compression: c,
                };
                let mut t = ExrTarget::create(&banded, 37, 37, format).unwrap();
                for y in (0..37).step_by(5) {
                    t.write(&img, y..(y + 5).min(37)).unwrap();
                }
                t.commit().unwrap();
                assert_eq!(
                    std::fs::read(&whole).unwrap(),
                    std::fs::read(&banded).unwrap(),
                    "{} {precision:?}",
                    c.name()
                );
            }
        }
    }
}
