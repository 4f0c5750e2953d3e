//! EXR files (exr crate): colour `R,G,B` (linear), normal `N.X,N.Y,N.Z`, mask `A`; f16 or f32
//! (module docs of [`super`]).

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

/// Compression of EXR output.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum ExrCompression {
    /// No compression: fastest to write and read, largest files (24–28 bytes/pixel in f32).
    /// The default: at 4K, f32 normals barely compress losslessly (ZIP: ~2.7×) while ZIP
    /// costs ~7× the write time (measured with `examples/perf_probe.rs exr`).
    #[default]
    None,
    /// Run-length: shrinks constant planes (default albedo, full mask) to almost nothing,
    /// leaves varying float data as is; ~1.5× the write time of `None`.
    Rle,
    /// zlib over 16 scan lines (OpenCV's default): ~2× smaller on smooth data, several times
    /// slower to write.
    Zip16,
    /// Wavelet + Huffman: good ratio on noisy data, slower than RLE.
    Piz,
}

impl ExrCompression {
    fn to_exr(self) -> exr::compression::Compression {
        use exr::compression::Compression as C;
        match self {
            Self::None => C::Uncompressed,
            Self::Rle => C::RLE,
            Self::Zip16 => C::ZIP16,
            Self::Piz => C::PIZ,
        }
    }
}

/// Writes an RGBN EXR (`R,G,B`, `N.X,N.Y,N.Z`, and `A` if masked) with the default
/// [`ExrCompression`] (uncompressed).
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
    use exr::prelude::*;
    let mut list = Vec::with_capacity(7);
    let mut push = |name: &str, data: &[f32]| {
        let samples = match precision {
            ExrPrecision::Full => FlatSamples::F32(data.to_vec()),
            ExrPrecision::Half => {
                FlatSamples::F16(data.par_iter().map(|&v| f16::from_f32(v)).collect())
            }
        };
        list.push(AnyChannel::new(name, samples));
    };
    for (name, plane) in ["R", "G", "B"].iter().zip(img.color()) {
        push(name, plane);
    }
    for (name, plane) in ["N.X", "N.Y", "N.Z"].iter().zip(img.normal()) {
        push(name, plane);
    }
    if let Some(m) = img.mask() {
        push("A", m);
    }
    write_exr_channels(img.width(), img.height(), list, path, compression)
}

pub(super) fn write_exr_channels(
    w: usize,
    h: usize,
    list: Vec<exr::prelude::AnyChannel<exr::prelude::FlatSamples>>,
    path: &Path,
    compression: ExrCompression,
) -> Result<(), RgbnError> {
    use exr::prelude::*;
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("rgbn"),
        Encoding {
            compression: compression.to_exr(),
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let image = Image::from_layer(layer);
    write_atomic(path, |out| {
        image.write().to_buffered(out).map_err(|e| e.to_string())
    })
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
    use exr::prelude::*;
    let list = vec![AnyChannel::new(
        channel,
        FlatSamples::F32(plane.data().to_vec()),
    )];
    write_exr_channels(
        plane.width(),
        plane.height(),
        list,
        path,
        ExrCompression::default(),
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
}
