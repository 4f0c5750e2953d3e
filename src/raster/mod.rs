//! The RGBN image model and the pixel maths shared by many operators.
//!
//! Storage is planar `f32` (one `Vec` per channel, row-major, row 0 at the top) so that kernels
//! can run over rows with rayon and let the compiler vectorise the inner loops.
//!
//! Conventions (see `docs/ARCHITECTURE.md`): colour is linear light; normals are unit vectors
//! in the OpenGL frame (`+x` right, `+y` up, `+z` towards the viewer).

pub mod bilateral;
pub mod buf;
pub mod convolve;
pub(crate) mod fastmath;
pub mod gradient;
pub mod hsh;
pub mod integrate;
pub mod io;
pub mod mesh;
pub(crate) mod par;
pub mod ptm;
pub mod pyramid;
pub mod sample;
pub mod simd;
pub mod smooth;
pub mod srgb;
pub mod strips;
pub mod window;

use crate::error::RgbnError;
use std::sync::Arc;

/// Pixels refused before allocating. 2^27 ≈ 134 Mpx (e.g. 16384 × 8192) needs ~3.8 GB as an
/// RGBN image (28 bytes per pixel) plus working buffers. Override with `RGBN_MAX_PIXELS`.
pub const DEFAULT_MAX_PIXELS: u64 = 1 << 27;

/// Normals shorter than this (before normalisation) are "zero-length": no direction can be
/// recovered. Covers the 8-bit mid-grey `(128,128,128)` whose decoded length is 0.0068.
pub const MIN_NORMAL_LENGTH: f32 = 0.02;

/// The current pixel limit: `RGBN_MAX_PIXELS` if set to a number, else [`DEFAULT_MAX_PIXELS`].
#[must_use]
pub fn max_pixels() -> u64 {
    std::env::var("RGBN_MAX_PIXELS")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(DEFAULT_MAX_PIXELS)
}

/// Refuses sizes over [`max_pixels`] (or zero) before anything is allocated.
pub fn check_size(width: usize, height: usize, source: &str) -> Result<(), RgbnError> {
    let limit = max_pixels();
    let pixels = width as u64 * height as u64;
    if width == 0 || height == 0 {
        return Err(RgbnError::Decode {
            detail: format!("image has no pixels ({width}×{height})"),
            path: source.into(),
        });
    }
    if pixels > limit {
        return Err(RgbnError::TooLarge {
            width,
            height,
            limit,
            path: source.into(),
        });
    }
    Ok(())
}

/// A single `f32` channel: a height, a curl map, a mask or one gradient component.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl Plane {
    /// A plane filled with `value`.
    #[must_use]
    pub fn filled(width: usize, height: usize, value: f32) -> Self {
        Self {
            width,
            height,
            data: buf::filled_f32(width * height, value),
        }
    }

    /// Wraps `data` (row-major, `width * height` values).
    pub fn from_vec(width: usize, height: usize, data: Vec<f32>) -> Result<Self, RgbnError> {
        if data.len() != width * height {
            return Err(RgbnError::InvalidImage(format!(
                "plane of {width}×{height} needs {} values, got {}",
                width * height,
                data.len()
            )));
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Samples `f(x, y_row)` at every pixel. Once the calling thread's evaluation is
    /// cancelled, the remaining rows stay 0 (the caller discards them: [`crate::cancel`]).
    #[must_use]
    pub fn from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> f32 + Sync) -> Self {
        use rayon::prelude::*;
        let mut data = buf::zeroed_f32(width * height);
        let cancel = crate::cancel::Cancel::current();
        data.par_chunks_mut(width.max(1))
            .enumerate()
            .for_each(|(row, out)| {
                if cancel.is_cancelled() {
                    return;
                }
                for (x, v) in out.iter_mut().enumerate() {
                    *v = f(x, row);
                }
            });
        Self {
            width,
            height,
            data,
        }
    }

    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }
    #[must_use]
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }
    /// The value at column `x`, row `row`.
    #[must_use]
    pub fn at(&self, x: usize, row: usize) -> f32 {
        self.data[row * self.width + x]
    }
}

/// The planes of an image: colour, normal, mask ([`RgbnImage::into_planes`]).
pub type ImagePlanes = ([Vec<f32>; 3], [Vec<f32>; 3], Option<Vec<f32>>);

/// [`ImagePlanes`] with the colour still shared ([`RgbnImage::into_shared_color`]).
pub type SharedColorPlanes = (Arc<[Vec<f32>; 3]>, [Vec<f32>; 3], Option<Vec<f32>>);

/// Colour + unit normal (+ optional coverage mask) per pixel.
///
/// The three parts are reference-counted and copy-on-write: cloning an image is cheap, and an
/// operator that changes only the normals shares the colour and mask with its input.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbnImage {
    width: usize,
    height: usize,
    /// Linear-light R, G, B planes.
    color: Arc<[Vec<f32>; 3]>,
    /// Normal x, y, z planes (OpenGL frame, unit length).
    normal: Arc<[Vec<f32>; 3]>,
    /// Coverage in [0, 1]; `None` means everything is covered.
    mask: Option<Arc<Vec<f32>>>,
}

/// What [`RgbnImage::validate`] found. Counts are pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Validation {
    pub pixels: usize,
    /// Colour or mask values that are NaN or infinite.
    pub non_finite_color: usize,
    /// Normals with a NaN or infinite component.
    pub non_finite_normal: usize,
    /// Normals shorter than [`MIN_NORMAL_LENGTH`].
    pub zero_length_normal: usize,
    /// Normals with `n_z ≤ 0` (facing away from the viewer).
    pub back_facing: usize,
    /// Normals whose length is off 1 by more than 1e-3 (not normalised).
    pub non_unit: usize,
}

impl Validation {
    /// The counts of both (of two parts of one image).
    #[must_use]
    pub fn merge(self, b: Self) -> Self {
        Validation {
            pixels: self.pixels + b.pixels,
            non_finite_color: self.non_finite_color + b.non_finite_color,
            non_finite_normal: self.non_finite_normal + b.non_finite_normal,
            zero_length_normal: self.zero_length_normal + b.zero_length_normal,
            back_facing: self.back_facing + b.back_facing,
            non_unit: self.non_unit + b.non_unit,
        }
    }

    /// The counts of pixels given as colour, normal and mask slices of one length (a part of
    /// an image; at most `u32::MAX` pixels).
    #[must_use]
    pub fn of_pixels(
        [cr, cg, cb]: [&[f32]; 3],
        [nx, ny, nz]: [&[f32]; 3],
        mask: Option<&[f32]>,
    ) -> Self {
        // Branch-free per-pixel flags summed in u32 lanes (the loop vectorises).
        let mut counts = [0u32; 5];
        for i in 0..nx.len() {
            let col_ok = cr[i].is_finite()
                & cg[i].is_finite()
                & cb[i].is_finite()
                & mask.is_none_or(|m| m[i].is_finite());
            let [x, y, z] = [nx[i], ny[i], nz[i]];
            let finite = x.is_finite() & y.is_finite() & z.is_finite();
            let len = (x * x + y * y + z * z).sqrt();
            let zero = finite & (len < MIN_NORMAL_LENGTH);
            let ok = finite & !zero;
            counts[0] += u32::from(!col_ok);
            counts[1] += u32::from(!finite);
            counts[2] += u32::from(zero);
            counts[3] += u32::from(ok & ((len - 1.0).abs() > 1e-3));
            counts[4] += u32::from(ok & (z <= 0.0));
        }
        let [col, nonfin, zero, non_unit, back] = counts.map(|c| c as usize);
        Validation {
            pixels: nx.len(),
            non_finite_color: col,
            non_finite_normal: nonfin,
            zero_length_normal: zero,
            back_facing: back,
            non_unit,
        }
    }

    /// True when nothing needs repair (back-facing normals are reported, not repaired).
    #[must_use]
    pub fn is_clean(&self) -> bool {
        self.non_finite_color == 0
            && self.non_finite_normal == 0
            && self.zero_length_normal == 0
            && self.non_unit == 0
    }

    /// The error a strict load gives for these counts (`None` when clean), naming `path`:
    /// the first problem found, in the order NaN/inf normals, zero-length normals, non-finite
    /// colour or mask values, normals not of unit length.
    #[must_use]
    pub fn strict_error(&self, path: &std::path::Path) -> Option<RgbnError> {
        if self.is_clean() {
            return None;
        }
        let (count, kind) = if self.non_finite_normal > 0 {
            (self.non_finite_normal, "NaN or infinite")
        } else if self.zero_length_normal > 0 {
            (self.zero_length_normal, "zero-length")
        } else if self.non_finite_color > 0 {
            (
                self.non_finite_color,
                "non-finite colour or mask values, not normals",
            )
        } else {
            (self.non_unit, "not unit length")
        };
        Some(RgbnError::InvalidNormals {
            count,
            kind: kind.into(),
            path: path.into(),
        })
    }

    /// The note printed when a load repaired these (`None` when clean), naming `name`.
    #[must_use]
    pub fn repair_note(&self, name: &str) -> Option<String> {
        (!self.is_clean()).then(|| {
            format!(
                "repaired {} NaN/inf and {} zero-length normals (now (0,0,1)), renormalised {}, zeroed {} non-finite colour values: {name}",
                self.non_finite_normal, self.zero_length_normal, self.non_unit, self.non_finite_color
            )
        })
    }
}

impl RgbnImage {
    /// An image of constant colour and normal `(0, 0, 1)` (a flat surface facing the viewer).
    #[must_use]
    pub fn flat(width: usize, height: usize, color: [f32; 3]) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            color: Arc::new(color.map(|c| buf::filled_f32(n, c))),
            normal: Arc::new([
                buf::zeroed_f32(n),
                buf::zeroed_f32(n),
                buf::filled_f32(n, 1.0),
            ]),
            mask: None,
        }
    }

    /// Builds an image from planes; every plane must hold `width * height` values.
    pub fn new(
        width: usize,
        height: usize,
        color: [Vec<f32>; 3],
        normal: [Vec<f32>; 3],
        mask: Option<Vec<f32>>,
    ) -> Result<Self, RgbnError> {
        Self::with_shared_color(width, height, Arc::new(color), normal, mask)
    }

    /// [`RgbnImage::new`] over colour planes shared with their owner (not copied): the
    /// streamed strips' constant albedo.
    pub fn with_shared_color(
        width: usize,
        height: usize,
        color: Arc<[Vec<f32>; 3]>,
        normal: [Vec<f32>; 3],
        mask: Option<Vec<f32>>,
    ) -> Result<Self, RgbnError> {
        let n = width * height;
        let bad = color.iter().chain(normal.iter()).any(|c| c.len() != n)
            || mask.as_ref().is_some_and(|m| m.len() != n);
        if bad {
            return Err(RgbnError::InvalidImage(format!(
                "every plane of a {width}×{height} image needs {n} values"
            )));
        }
        Ok(Self {
            width,
            height,
            color,
            normal: Arc::new(normal),
            mask: mask.map(Arc::new),
        })
    }

    /// The planes back with the colour as shared ([`RgbnImage::with_shared_color`]): normal
    /// and mask taken without a copy when this image holds the only reference, copied
    /// otherwise.
    #[must_use]
    pub fn into_shared_color(self) -> SharedColorPlanes {
        (
            self.color,
            Arc::try_unwrap(self.normal).unwrap_or_else(|a| (*a).clone()),
            self.mask
                .map(|m| Arc::try_unwrap(m).unwrap_or_else(|m| (*m).clone())),
        )
    }

    /// The planes back: colour, normal, mask (each taken without a copy when this image holds
    /// the only reference to it, copied otherwise).
    #[must_use]
    pub fn into_planes(self) -> ImagePlanes {
        let own = |a: Arc<[Vec<f32>; 3]>| Arc::try_unwrap(a).unwrap_or_else(|a| (*a).clone());
        (
            own(self.color),
            own(self.normal),
            self.mask
                .map(|m| Arc::try_unwrap(m).unwrap_or_else(|m| (*m).clone())),
        )
    }

    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }
    #[must_use]
    pub fn len(&self) -> usize {
        self.width * self.height
    }
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    #[must_use]
    pub fn color(&self) -> &[Vec<f32>; 3] {
        &self.color
    }
    /// Mutable colour planes (copied first if shared).
    pub fn color_mut(&mut self) -> &mut [Vec<f32>; 3] {
        Arc::make_mut(&mut self.color)
    }
    #[must_use]
    pub fn normal(&self) -> &[Vec<f32>; 3] {
        &self.normal
    }
    /// Mutable normal planes (copied first if shared).
    pub fn normal_mut(&mut self) -> &mut [Vec<f32>; 3] {
        Arc::make_mut(&mut self.normal)
    }
    /// A copy sharing colour and mask, with new normal planes (each `width * height` long).
    pub fn with_normals(&self, normal: [Vec<f32>; 3]) -> Result<Self, RgbnError> {
        if normal.iter().any(|c| c.len() != self.len()) {
            return Err(RgbnError::InvalidImage("normal plane size mismatch".into()));
        }
        Ok(Self {
            normal: Arc::new(normal),
            ..self.clone()
        })
    }
    #[must_use]
    pub fn mask(&self) -> Option<&[f32]> {
        self.mask.as_ref().map(|m| m.as_slice())
    }
    /// Replaces the mask; its length must match.
    pub fn set_mask(&mut self, mask: Option<Vec<f32>>) -> Result<(), RgbnError> {
        if let Some(m) = &mask {
            if m.len() != self.len() {
                return Err(RgbnError::InvalidImage(format!(
                    "mask has {} values, image has {}",
                    m.len(),
                    self.len()
                )));
            }
        }
        self.mask = mask.map(Arc::new);
        Ok(())
    }
    /// Replaces the colour planes (same size).
    pub fn set_color(&mut self, color: [Vec<f32>; 3]) -> Result<(), RgbnError> {
        if color.iter().any(|c| c.len() != self.len()) {
            return Err(RgbnError::InvalidImage("colour plane size mismatch".into()));
        }
        self.color = Arc::new(color);
        Ok(())
    }

    /// The normal at column `x`, row `row`.
    #[must_use]
    pub fn normal_at(&self, x: usize, row: usize) -> [f32; 3] {
        let i = row * self.width + x;
        [self.normal[0][i], self.normal[1][i], self.normal[2][i]]
    }
    /// The colour at column `x`, row `row`.
    #[must_use]
    pub fn color_at(&self, x: usize, row: usize) -> [f32; 3] {
        let i = row * self.width + x;
        [self.color[0][i], self.color[1][i], self.color[2][i]]
    }

    /// Bytes held by the pixel planes.
    #[must_use]
    pub fn byte_size(&self) -> usize {
        (6 + usize::from(self.mask.is_some())) * self.len() * std::mem::size_of::<f32>()
    }

    /// Counts problem pixels without changing anything.
    #[must_use]
    pub fn validate(&self) -> Validation {
        use rayon::prelude::*;
        let n = self.len();
        let chunk = 1 << 16;
        let [cr, cg, cb] = &*self.color;
        let [nx, ny, nz] = &*self.normal;
        let mask = self.mask.as_deref();
        (0..n.div_ceil(chunk))
            .into_par_iter()
            .map(|c| {
                let r = c * chunk..((c + 1) * chunk).min(n);
                Validation::of_pixels(
                    [&cr[r.clone()], &cg[r.clone()], &cb[r.clone()]],
                    [&nx[r.clone()], &ny[r.clone()], &nz[r.clone()]],
                    mask.map(|m| &m[r.clone()]),
                )
            })
            .reduce(Validation::default, Validation::merge)
    }

    /// Repairs what [`validate`](Self::validate) counts: non-finite colour/mask values become 0,
    /// non-finite or zero-length normals become `(0, 0, 1)`, other normals are normalised.
    /// Back-facing normals are kept (gradient conversion clamps them, see [`gradient`]).
    /// Returns the validation of the image *before* repair.
    pub fn repair(&mut self) -> Validation {
        let before = self.validate();
        self.repair_validated(&before);
        before
    }

    /// [`repair`](Self::repair) given `before`, a [`validate`](Self::validate) of the image
    /// as it is now (saves validating twice).
    pub fn repair_validated(&mut self, before: &Validation) {
        if before.is_clean() {
            return;
        }
        use rayon::prelude::*;
        let [nx, ny, nz] = self.normal_mut();
        (nx.par_iter_mut(), ny.par_iter_mut(), nz.par_iter_mut())
            .into_par_iter()
            .for_each(|(x, y, z)| {
                let len = (*x * *x + *y * *y + *z * *z).sqrt();
                if !len.is_finite() || len < MIN_NORMAL_LENGTH {
                    (*x, *y, *z) = (0.0, 0.0, 1.0);
                } else {
                    (*x, *y, *z) = (*x / len, *y / len, *z / len);
                }
            });
        let fix = |plane: &mut Vec<f32>| {
            plane.par_iter_mut().for_each(|v| {
                if !v.is_finite() {
                    *v = 0.0;
                }
            })
        };
        if before.non_finite_color > 0 {
            self.color_mut().iter_mut().for_each(fix);
            if let Some(m) = self.mask.as_mut() {
                fix(Arc::make_mut(m));
            }
        }
    }

    /// Renormalises every normal in place (zero-length ones become `(0, 0, 1)`).
    pub fn normalize(&mut self) {
        use rayon::prelude::*;
        let [nx, ny, nz] = self.normal_mut();
        (nx.par_iter_mut(), ny.par_iter_mut(), nz.par_iter_mut())
            .into_par_iter()
            .for_each(|(x, y, z)| {
                let len2 = *x * *x + *y * *y + *z * *z;
                if len2.is_finite() && len2 > MIN_NORMAL_LENGTH * MIN_NORMAL_LENGTH {
                    let inv = len2.sqrt().recip();
                    (*x, *y, *z) = (*x * inv, *y * inv, *z * inv);
                } else {
                    (*x, *y, *z) = (0.0, 0.0, 1.0);
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_counts_each_problem_once() {
        let mut img = RgbnImage::flat(4, 1, [0.5; 3]);
        let n = img.normal_mut();
        // pixel 0 fine; 1 NaN; 2 zero-length; 3 back-facing and unnormalised
        n[0][1] = f32::NAN;
        n[2][2] = 0.0;
        n[0][3] = 0.6;
        n[2][3] = -0.9;
        img.color_mut()[1][0] = f32::INFINITY;
        let v = img.validate();
        assert_eq!(v.pixels, 4);
        assert_eq!(v.non_finite_normal, 1);
        assert_eq!(v.zero_length_normal, 1);
        assert_eq!(v.back_facing, 1);
        assert_eq!(v.non_unit, 1);
        assert_eq!(v.non_finite_color, 1);
        let before = img.repair();
        assert_eq!(before, v);
        let after = img.validate();
        assert!(after.is_clean(), "{after:?}");
        assert_eq!(after.back_facing, 1, "back-facing normals are kept");
        assert_eq!(img.normal_at(1, 0), [0.0, 0.0, 1.0]);
        let [x, _, z] = img.normal_at(3, 0);
        assert!((x - 0.6 / (0.36f32 + 0.81).sqrt()).abs() < 1e-6 && z < 0.0);
    }

    #[test]
    fn size_limit_is_checked_before_allocation() {
        let err = check_size(1 << 20, 1 << 20, "huge.exr").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("1048576×1048576"), "{msg}");
        assert!(msg.ends_with("huge.exr"), "{msg}");
        assert!(check_size(0, 5, "empty.png").is_err());
        assert!(check_size(64, 64, "ok.png").is_ok());
    }
}
