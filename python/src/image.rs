//! `rgbn.Image`, `rgbn.read`, `rgbn.write`: RGBN images as NumPy arrays.
//!
//! An `Image` is stored one of two ways:
//!
//! - **Arrays** (built by `Image(normals, color, mask)` from the caller's arrays): the arrays
//!   themselves, not copied when they are C-contiguous `float32` and need no repair
//!   (`img.normals is normals`). rgbn's kernels work on *planar* storage (one plane per
//!   channel, [`RgbnImage`]), so each call into Rust that reads such an image makes one planar
//!   copy of it (12 bytes per pixel per H×W×3 array read, 4 per mask; counted by
//!   `planar_copies()`), without the GIL.
//! - **Planar** (every `Image` rgbn returns: `read`, `filter`, `capture`, graph outputs): the
//!   [`RgbnImage`] itself, shared without a copy with the next call. Its arrays are made on
//!   first access (interleaved once, then cached) and are read-only, so they cannot drift from
//!   the planes.

use crate::error::{input, rgbn_err, RepairWarning};
use numpy::ndarray::Array;
use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use rgbn::error::RgbnError;
use rgbn::nodes::{Picture, Value};
use rgbn::raster::io::{
    self, ExrCompression, ExrPrecision, InputSpec, LoadOptions, NormalConvention, SaveOptions,
};
use rgbn::raster::{check_size, Plane, RgbnImage, Validation, MIN_NORMAL_LENGTH};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

/// Planar copies made of array-backed images on their way into Rust (see module docs).
static PLANAR_COPIES: AtomicU64 = AtomicU64::new(0);

/// How many planar copies of caller-owned arrays calls into Rust have made so far (each
/// H×W×3 or H×W array read once counts 1). `Image(...)` itself makes none.
#[pyfunction]
pub fn planar_copies() -> u64 {
    PLANAR_COPIES.load(Ordering::Relaxed)
}

/// The caller's arrays of an array-backed image.
struct Arrays {
    normals: Py<PyArray3<f32>>,
    color: Option<Py<PyArray3<f32>>>,
    mask: Option<Py<PyArray2<f32>>>,
}

enum Storage {
    Arrays(Arrays),
    Planar(RgbnImage),
}

/// An RGBN image: unit normals (H×W×3, OpenGL frame: +x right, +y up, +z towards the viewer),
/// linear colour (H×W×3) and an optional coverage mask (H×W), all float32.
///
/// ``Image(normals, color=None, mask=None, *, strict=False)`` validates as the command line
/// validates a file: NaN/inf or zero-length normals become (0, 0, 1), other normals are
/// renormalised, non-finite colour or mask values become 0 (with a ``RepairWarning`` naming the
/// counts), or with ``strict=True`` any of these is an ``InputError``. C-contiguous float32
/// arrays that need no repair are kept as given, not copied (``img.normals is normals``);
/// other layouts are copied once. Without ``color`` the colour is 0.75 grey, as for a normal map
/// read alone.
#[pyclass(module = "rgbn", frozen, name = "Image")]
pub struct Image {
    width: usize,
    height: usize,
    storage: Storage,
    repaired: Validation,
    normals_out: OnceLock<Py<PyArray3<f32>>>,
    color_out: OnceLock<Py<PyArray3<f32>>>,
    mask_out: OnceLock<Option<Py<PyArray2<f32>>>>,
    /// Array-backed without colour: the 0.75 grey planes, made once and shared by every
    /// planar copy.
    grey: OnceLock<RgbnImage>,
}

/// A float32 array of `shape` (`None`: any size on that axis) taken from `obj`, C-contiguous
/// (copied only if it is not); messages name the argument.
fn array_arg<'py>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    shape: &[Option<usize>],
) -> PyResult<Bound<'py, PyUntypedArray>> {
    let py = obj.py();
    let shape_text = |dims: &[Option<usize>]| {
        let parts: Vec<String> = dims
            .iter()
            .enumerate()
            .map(|(i, d)| {
                d.map_or_else(|| ["H", "W", "C"][i.min(2)].to_string(), |d| d.to_string())
            })
            .collect();
        format!("({})", parts.join(", "))
    };
    let Ok(arr) = obj.cast::<PyUntypedArray>() else {
        return Err(input(format!(
            "{what} must be a NumPy array of shape {}, got {}",
            shape_text(shape),
            obj.get_type().name()?
        )));
    };
    let got = arr.shape().to_vec();
    let fits = got.len() == shape.len()
        && got
            .iter()
            .zip(shape)
            .all(|(g, s)| s.is_none_or(|s| s == *g));
    if !fits {
        let got: Vec<String> = got.iter().map(ToString::to_string).collect();
        return Err(input(format!(
            "{what} must have shape {}, got ({})",
            shape_text(shape),
            got.join(", ")
        )));
    }
    let dtype = arr.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<f32>(py)) {
        return Err(input(format!(
            "{what} must be float32, got {} (convert with .astype(numpy.float32))",
            dtype.str()?
        )));
    }
    if arr.is_c_contiguous() {
        Ok(arr.clone())
    } else {
        let numpy = py.import("numpy")?;
        Ok(numpy
            .call_method1("ascontiguousarray", (arr,))?
            .cast_into::<PyUntypedArray>()?)
    }
}

/// Counts what [`RgbnImage::validate`] counts, over interleaved normals and colours (the same
/// rule, without making planes).
fn validate_interleaved(n: &[f32], c: Option<&[f32]>, m: Option<&[f32]>) -> Validation {
    const CHUNK: usize = 1 << 15;
    let px = n.len() / 3;
    (0..px.div_ceil(CHUNK))
        .into_par_iter()
        .map(|k| {
            let r = k * CHUNK..((k + 1) * CHUNK).min(px);
            // Branch-free per-pixel flags summed in u32 lanes (the loop vectorises).
            let mut counts = [0u32; 5];
            for px in n[3 * r.start..3 * r.end].chunks_exact(3) {
                let [x, y, z] = [px[0], px[1], px[2]];
                let finite = x.is_finite() & y.is_finite() & z.is_finite();
                let len = (x * x + y * y + z * z).sqrt();
                let zero = finite & (len < MIN_NORMAL_LENGTH);
                let ok = finite & !zero;
                counts[0] += u32::from(!finite);
                counts[1] += u32::from(zero);
                counts[2] += u32::from(ok & ((len - 1.0).abs() > 1e-3));
                counts[3] += u32::from(ok & (z <= 0.0));
            }
            if let Some(c) = c {
                for px in c[3 * r.start..3 * r.end].chunks_exact(3) {
                    counts[4] +=
                        u32::from(!(px[0].is_finite() & px[1].is_finite() & px[2].is_finite()));
                }
            }
            let mut v = Validation {
                pixels: r.len(),
                non_finite_normal: counts[0] as usize,
                zero_length_normal: counts[1] as usize,
                non_unit: counts[2] as usize,
                back_facing: counts[3] as usize,
                non_finite_color: counts[4] as usize,
            };
            if let Some(m) = m {
                // A pixel counts once whether its colour, its mask or both are non-finite.
                let c = c.map(|c| &c[3 * r.start..3 * r.end]);
                v.non_finite_color += m[r.clone()]
                    .iter()
                    .enumerate()
                    .filter(|(i, v)| {
                        !v.is_finite()
                            && c.is_none_or(|c| c[3 * i..3 * i + 3].iter().all(|x| x.is_finite()))
                    })
                    .count();
            }
            v
        })
        .reduce(Validation::default, Validation::merge)
}

/// Interleaved H×W×3 samples as three planes (one pass, rows in parallel; the planes are not
/// zero-filled first, so blocks the allocator recycles are written once).
pub fn split3(src: &[f32]) -> [Vec<f32>; 3] {
    let n = src.len() / 3;
    let mut out = [
        rgbn::raster::buf::reserved_f32(n),
        rgbn::raster::buf::reserved_f32(n),
        rgbn::raster::buf::reserved_f32(n),
    ];
    const CHUNK: usize = 1 << 14;
    {
        let [a, b, c] = &mut out;
        a.spare_capacity_mut()[..n]
            .par_chunks_mut(CHUNK)
            .zip(b.spare_capacity_mut()[..n].par_chunks_mut(CHUNK))
            .zip(c.spare_capacity_mut()[..n].par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(k, ((a, b), c))| {
                let s = &src[3 * k * CHUNK..3 * (k * CHUNK + a.len())];
                for (i, px) in s.chunks_exact(3).enumerate() {
                    a[i].write(px[0]);
                    b[i].write(px[1]);
                    c[i].write(px[2]);
                }
            });
    }
    for v in &mut out {
        // SAFETY: every one of the first `n` values was written above.
        unsafe { v.set_len(n) };
    }
    out
}

/// Three planes as interleaved H×W×3 samples.
pub fn join3(p: &[Vec<f32>; 3]) -> Vec<f32> {
    let n = p[0].len();
    let mut out = rgbn::raster::buf::reserved_f32(3 * n);
    const CHUNK: usize = 1 << 14;
    out.spare_capacity_mut()[..3 * n]
        .par_chunks_mut(3 * CHUNK)
        .enumerate()
        .for_each(|(k, o)| {
            let base = k * CHUNK;
            for (i, px) in o.chunks_exact_mut(3).enumerate() {
                px[0].write(p[0][base + i]);
                px[1].write(p[1][base + i]);
                px[2].write(p[2][base + i]);
            }
        });
    // SAFETY: every one of the `3 n` values was written above.
    unsafe { out.set_len(3 * n) };
    out
}

/// A flat image of the default grey colour: the last one made, shared when the size is the
/// same (its planes are reference-counted and copy-on-write), so a new array-backed `Image`
/// of a size seen before costs no colour planes.
fn grey_base(w: usize, h: usize) -> RgbnImage {
    static LAST: std::sync::Mutex<Option<RgbnImage>> = std::sync::Mutex::new(None);
    let mut last = LAST
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    match &*last {
        Some(img) if (img.width(), img.height()) == (w, h) => img.clone(),
        _ => {
            let img = RgbnImage::flat(w, h, [io::DEFAULT_ALBEDO; 3]);
            *last = Some(img.clone());
            img
        }
    }
}

/// An H×W×3 float32 array owning `data` (no copy).
fn array3(
    py: Python<'_>,
    h: usize,
    w: usize,
    data: Vec<f32>,
) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let a = Array::from_shape_vec((h, w, 3), data).map_err(|e| input(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

/// An H×W array owning `data` (no copy).
pub fn array2<T: numpy::Element>(
    py: Python<'_>,
    h: usize,
    w: usize,
    data: Vec<T>,
) -> PyResult<Bound<'_, PyArray2<T>>> {
    let a = Array::from_shape_vec((h, w), data).map_err(|e| input(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

fn read_only<T: numpy::Element, D: numpy::ndarray::Dimension>(
    a: &Bound<'_, numpy::PyArray<T, D>>,
) -> PyResult<()> {
    a.getattr("flags")?.setattr("writeable", false)
}

/// Emits the command line's repair note as a `RepairWarning`.
pub fn warn_repairs(py: Python<'_>, v: &Validation, name: &str) -> PyResult<()> {
    if let Some(note) = v.repair_note(name) {
        let msg = std::ffi::CString::new(note).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<RepairWarning>(), &msg, 2)?;
    }
    Ok(())
}

pub fn validation_dict<'py>(py: Python<'py>, v: &Validation) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("pixels", v.pixels)?;
    d.set_item("non_finite_color", v.non_finite_color)?;
    d.set_item("non_finite_normal", v.non_finite_normal)?;
    d.set_item("zero_length_normal", v.zero_length_normal)?;
    d.set_item("non_unit", v.non_unit)?;
    d.set_item("back_facing", v.back_facing)?;
    Ok(d)
}

impl Image {
    /// An image rgbn made (planar storage).
    pub fn planar(img: RgbnImage, repaired: Validation) -> Self {
        Self {
            width: img.width(),
            height: img.height(),
            storage: Storage::Planar(img),
            repaired,
            normals_out: OnceLock::new(),
            color_out: OnceLock::new(),
            mask_out: OnceLock::new(),
            grey: OnceLock::new(),
        }
    }

    /// The image as rgbn's planar [`RgbnImage`]: shared for planar images, one copy (without
    /// the GIL) for array-backed ones.
    pub fn to_rgbn(&self, py: Python<'_>) -> PyResult<RgbnImage> {
        let a = match &self.storage {
            Storage::Planar(img) => return Ok(img.clone()),
            Storage::Arrays(a) => a,
        };
        let (w, h) = (self.width, self.height);
        let n = a
            .normals
            .bind(py)
            .try_readonly()
            .map_err(|e| input(e.to_string()))?;
        let c = match &a.color {
            Some(c) => Some(
                c.bind(py)
                    .try_readonly()
                    .map_err(|e| input(e.to_string()))?,
            ),
            None => None,
        };
        let m = match &a.mask {
            Some(m) => Some(
                m.bind(py)
                    .try_readonly()
                    .map_err(|e| input(e.to_string()))?,
            ),
            None => None,
        };
        let ns = n.as_slice().map_err(|e| input(e.to_string()))?;
        let cs = match &c {
            Some(c) => Some(c.as_slice().map_err(|e| input(e.to_string()))?),
            None => None,
        };
        let ms = match &m {
            Some(m) => Some(m.as_slice().map_err(|e| input(e.to_string()))?),
            None => None,
        };
        let copies = 1 + u64::from(cs.is_some()) + u64::from(ms.is_some());
        PLANAR_COPIES.fetch_add(copies, Ordering::Relaxed);
        let grey = &self.grey;
        py.detach(|| {
            let normal = split3(ns);
            let mask = ms.map(<[f32]>::to_vec);
            match cs {
                Some(c) => RgbnImage::new(w, h, split3(c), normal, mask),
                None => {
                    let base = grey.get_or_init(|| grey_base(w, h));
                    let mut img = base.with_normals(normal)?;
                    img.set_mask(mask)?;
                    Ok(img)
                }
            }
        })
        .map_err(rgbn_err)
    }

    /// The validation counts of the image as it was given (before any repair).
    pub fn repaired_counts(&self) -> Validation {
        self.repaired
    }

    /// The image with `mask` (an H×W float32 array, copied into a plane) as its mask.
    pub fn with_mask_value(&self, py: Python<'_>, mask: &Bound<'_, PyAny>) -> PyResult<RgbnImage> {
        let mut img = self.to_rgbn(py)?;
        let a = array_arg(mask, "mask", &[Some(self.height), Some(self.width)])?;
        let a = a.cast_into::<PyArray2<f32>>()?;
        PLANAR_COPIES.fetch_add(1, Ordering::Relaxed);
        let m = a.to_vec().map_err(|e| input(e.to_string()))?;
        img.set_mask(Some(m)).map_err(rgbn_err)?;
        Ok(img)
    }

    /// `Value::Rgbn` of [`Self::to_rgbn`].
    pub fn to_value(&self, py: Python<'_>) -> PyResult<Value> {
        Ok(Value::Rgbn(self.to_rgbn(py)?))
    }
}

#[pymethods]
impl Image {
    #[new]
    #[pyo3(signature = (normals, color=None, mask=None, *, strict=false))]
    pub fn new(
        py: Python<'_>,
        normals: &Bound<'_, PyAny>,
        color: Option<&Bound<'_, PyAny>>,
        mask: Option<&Bound<'_, PyAny>>,
        strict: bool,
    ) -> PyResult<Self> {
        let n = array_arg(normals, "normals", &[None, None, Some(3)])?;
        let (h, w) = (n.shape()[0], n.shape()[1]);
        if w == 0 || h == 0 {
            return Err(input(format!("image has no pixels ({w}×{h}): normals")));
        }
        // Too many pixels: the command line's message (RGBN_MAX_PIXELS), as bad input.
        check_size(w, h, "normals").map_err(|e| input(e.to_string()))?;
        let size_err = |what: &'static str, got: &[usize]| {
            rgbn_err(RgbnError::SizeMismatch {
                what,
                want_w: w,
                want_h: h,
                got_w: got[1],
                got_h: got[0],
                path: PathBuf::from(if what == "mask" { "mask" } else { "color" }),
            })
        };
        let c = match color {
            Some(c) if !c.is_none() => {
                let c = array_arg(c, "color", &[None, None, Some(3)])?;
                if c.shape()[..2] != [h, w] {
                    return Err(size_err("colour image", c.shape()));
                }
                Some(c.cast_into::<PyArray3<f32>>()?)
            }
            _ => None,
        };
        let m = match mask {
            Some(m) if !m.is_none() => {
                let m = array_arg(m, "mask", &[None, None])?;
                if m.shape() != [h, w] {
                    return Err(size_err("mask", m.shape()));
                }
                Some(m.cast_into::<PyArray2<f32>>()?)
            }
            _ => None,
        };
        let n = n.cast_into::<PyArray3<f32>>()?;
        let v = {
            let nr = n.try_readonly().map_err(|e| input(e.to_string()))?;
            let cr = c
                .as_ref()
                .map(|c| c.try_readonly())
                .transpose()
                .map_err(|e| input(e.to_string()))?;
            let mr = m
                .as_ref()
                .map(|m| m.try_readonly())
                .transpose()
                .map_err(|e| input(e.to_string()))?;
            let ns = nr.as_slice().map_err(|e| input(e.to_string()))?;
            let cs = cr
                .as_ref()
                .map(|c| c.as_slice())
                .transpose()
                .map_err(|e| input(e.to_string()))?;
            let ms = mr
                .as_ref()
                .map(|m| m.as_slice())
                .transpose()
                .map_err(|e| input(e.to_string()))?;
            py.detach(|| validate_interleaved(ns, cs, ms))
        };
        if strict {
            if let Some(e) = v.strict_error(Path::new("normals")) {
                return Err(rgbn_err(e));
            }
        }
        let arrays = Self {
            width: w,
            height: h,
            storage: Storage::Arrays(Arrays {
                normals: n.unbind(),
                color: c.map(Bound::unbind),
                mask: m.map(Bound::unbind),
            }),
            repaired: v,
            normals_out: OnceLock::new(),
            color_out: OnceLock::new(),
            mask_out: OnceLock::new(),
            grey: OnceLock::new(),
        };
        if v.is_clean() {
            return Ok(arrays);
        }
        // Repaired as a loaded file is: a planar copy, fixed in place.
        let mut img = arrays.to_rgbn(py)?;
        py.detach(|| img.repair_validated(&v));
        warn_repairs(py, &v, "normals")?;
        Ok(Self::planar(img, v))
    }

    /// Width in pixels.
    #[getter]
    fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    #[getter]
    fn height(&self) -> usize {
        self.height
    }
    /// ``(H, W)``.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (self.height, self.width)
    }
    /// Whether the image is stored as rgbn's planes (``True`` for images rgbn returned) or as
    /// the caller's arrays (copied to planes on each call into Rust).
    #[getter]
    fn is_planar(&self) -> bool {
        matches!(self.storage, Storage::Planar(_))
    }
    /// Unit normals, H×W×3 float32 (read-only for images rgbn returned).
    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        match &self.storage {
            Storage::Arrays(a) => Ok(a.normals.bind(py).clone()),
            Storage::Planar(img) => {
                if let Some(a) = self.normals_out.get() {
                    return Ok(a.bind(py).clone());
                }
                let data = py.detach(|| join3(img.normal()));
                let a = array3(py, self.height, self.width, data)?;
                read_only(&a)?;
                Ok(self.normals_out.get_or_init(|| a.unbind()).bind(py).clone())
            }
        }
    }
    /// Linear colour, H×W×3 float32 (0.75 grey when none was given).
    #[getter]
    fn color<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        if let Storage::Arrays(Arrays { color: Some(c), .. }) = &self.storage {
            return Ok(c.bind(py).clone());
        }
        if let Some(a) = self.color_out.get() {
            return Ok(a.bind(py).clone());
        }
        let data = match &self.storage {
            Storage::Planar(img) => py.detach(|| join3(img.color())),
            Storage::Arrays(_) => vec![io::DEFAULT_ALBEDO; 3 * self.width * self.height],
        };
        let a = array3(py, self.height, self.width, data)?;
        read_only(&a)?;
        Ok(self.color_out.get_or_init(|| a.unbind()).bind(py).clone())
    }
    /// Coverage mask, H×W float32, or ``None``.
    #[getter]
    fn mask<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f32>>>> {
        match &self.storage {
            Storage::Arrays(a) => Ok(a.mask.as_ref().map(|m| m.bind(py).clone())),
            Storage::Planar(img) => {
                if let Some(m) = self.mask_out.get() {
                    return Ok(m.as_ref().map(|m| m.bind(py).clone()));
                }
                let m = match img.mask() {
                    Some(m) => {
                        let a = array2(py, self.height, self.width, m.to_vec())?;
                        read_only(&a)?;
                        Some(a.unbind())
                    }
                    None => None,
                };
                Ok(self
                    .mask_out
                    .get_or_init(|| m)
                    .as_ref()
                    .map(|m| m.bind(py).clone()))
            }
        }
    }
    /// What was repaired on the way in (counts before repair; ``back_facing`` is reported,
    /// never repaired).
    #[getter]
    fn repaired<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        validation_dict(py, &self.repaired)
    }
    /// A copy with another mask (H×W float32, or ``None`` to drop it); colour and normals are
    /// shared.
    #[pyo3(signature = (mask))]
    fn with_mask(&self, py: Python<'_>, mask: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let img = match mask {
            Some(m) if !m.is_none() => self.with_mask_value(py, m)?,
            _ => {
                let mut img = self.to_rgbn(py)?;
                img.set_mask(None).map_err(rgbn_err)?;
                img
            }
        };
        Ok(Self::planar(img, self.repaired))
    }
    fn __repr__(&self) -> String {
        format!(
            "rgbn.Image({}×{}, mask={}, {})",
            self.width,
            self.height,
            match &self.storage {
                Storage::Arrays(a) => a.mask.is_some(),
                Storage::Planar(i) => i.mask().is_some(),
            },
            if self.is_planar() { "planar" } else { "arrays" }
        )
    }
}

/// Reads an RGBN image: an RGBN EXR (colour, ``N.X/N.Y/N.Z``, mask ``A``), an OME-Zarr store
/// (``.zarr``: channels R, G, B, nx, ny, nz, mask; ``level``: one of its levels of detail, read
/// directly), a normal map (PNG/TIFF/JPEG 8/16-bit or EXR) or a PTM, with optional separate
/// ``color`` and ``mask`` files, exactly as the command line reads its input (``dx``: the normal
/// map's green is −y; ``exr_rgb_is_normal``: an EXR's R,G,B is a normal pass; ``strict``: refuse
/// instead of repair).
#[pyfunction]
#[pyo3(signature = (path, color=None, mask=None, *, dx=false, exr_rgb_is_normal=false, strict=false, level=0))]
#[allow(clippy::too_many_arguments)]
pub fn read(
    py: Python<'_>,
    path: PathBuf,
    color: Option<PathBuf>,
    mask: Option<PathBuf>,
    dx: bool,
    exr_rgb_is_normal: bool,
    strict: bool,
    level: usize,
) -> PyResult<Image> {
    if level > 0 {
        if !io::zarr::is_zarr(&path) || color.is_some() || mask.is_some() {
            return Err(input(
                "level: only an OME-Zarr store (.zarr, no separate color or mask) has levels",
            ));
        }
        let (img, repaired) = py
            .detach(|| {
                let z = io::zarr::ZarrImage::open(&path)?;
                let size = rgbn::raster::pyramid::reduced_size(z.size(), 1 << level.min(20));
                z.read_rgbn(level.min(20), rgbn::raster::window::Rect::full(size))
            })
            .map_err(rgbn_err)?;
        warn_repairs(py, &repaired, &path.display().to_string())?;
        return Ok(Image::planar(img, repaired));
    }
    let spec = InputSpec {
        rgbn: Some(path.clone()),
        color,
        normal: None,
        mask,
    };
    let opts = LoadOptions::of_flags(dx, exr_rgb_is_normal, strict);
    let loaded = py.detach(|| io::load(&spec, &opts)).map_err(rgbn_err)?;
    warn_repairs(py, &loaded.repaired, &path.display().to_string())?;
    Ok(Image::planar(loaded.image, loaded.repaired))
}

/// Reads a colour image as linear H×W×3 float32: PNG/JPEG/TIFF are decoded from sRGB (or,
/// ``linear=True``, taken as linear values divided by 2^bits − 1: raw photos), EXR is linear.
#[pyfunction]
#[pyo3(signature = (path, *, linear=false))]
pub fn read_color<'py>(
    py: Python<'py>,
    path: PathBuf,
    linear: bool,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let (w, h, planes) = py
        .detach(|| {
            if linear {
                io::load_color_linear(&path)
            } else {
                io::load_color(&path)
            }
        })
        .map_err(rgbn_err)?;
    let data = py.detach(|| join3(&planes));
    array3(py, h, w, data)
}

/// Reads a mask (greyscale or first channel; EXR ``A``, ``Y`` or ``R``) as H×W float32 in [0, 1].
#[pyfunction]
pub fn read_mask<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let (w, h, m) = py.detach(|| io::load_mask(&path)).map_err(rgbn_err)?;
    array2(py, h, w, m)
}

/// A value to write: an `Image`, a 2-D float32 array (a scalar field, or with ``mask=True`` a
/// mask) or an H×W×4 uint8 picture.
fn value_of(py: Python<'_>, obj: &Bound<'_, PyAny>, as_mask: bool) -> PyResult<Value> {
    if let Ok(img) = obj.cast::<Image>() {
        return img.get().to_value(py);
    }
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        if a.ndim() == 3 && a.shape()[2] == 4 && a.dtype().is_equiv_to(&numpy::dtype::<u8>(py)) {
            let (h, w) = (a.shape()[0], a.shape()[1]);
            let a = obj.cast::<numpy::PyArray3<u8>>()?;
            return Ok(Value::Picture(Arc::new(Picture {
                width: w,
                height: h,
                rgba: a
                    .to_vec()
                    .or_else(|_| Ok::<_, PyErr>(a.to_owned_array().iter().copied().collect()))?,
            })));
        }
        let a = array_arg(obj, "array", &[None, None])?;
        let (h, w) = (a.shape()[0], a.shape()[1]);
        let data = a
            .cast_into::<PyArray2<f32>>()?
            .to_vec()
            .map_err(|e| input(e.to_string()))?;
        let plane = Arc::new(Plane::from_vec(w, h, data).map_err(rgbn_err)?);
        return Ok(if as_mask {
            Value::Mask(plane)
        } else {
            Value::Scalar(plane)
        });
    }
    Err(input(format!(
        "cannot write a {}: give an rgbn.Image, an H×W float32 array or an H×W×4 uint8 picture",
        obj.get_type().name()?
    )))
}

/// Writes atomically (a temporary file, then a rename; never over an existing file's data
/// half-way), by extension, with the command line's formats and options:
///
/// - an ``Image``: ``.exr`` holds colour, normals and mask (``half``: 16-bit floats;
///   ``exr_compression``: zip (default), zips, rle, piz or none);
///   ``.zarr`` an OME-Zarr store of the same with its levels of detail (``zarr_dtype``: float32
///   (default), float16 or uint16; ``chunk``: chunk side in pixels; ``zarr_compression``: zstd
///   (default), blosc or none); ``.png``/``.tif`` the normal map (``bits`` 8 or 16, ``dx``:
///   DirectX green); with
///   ``color=True`` the colour instead (PNG/TIFF sRGB, EXR linear) — ``rgbn filter --color-out``;
/// - an H×W float32 array: a scalar field (``.exr``, ``.zarr``), or with ``mask=True`` a mask
///   (``.png``/``.tif`` 16-bit, ``.exr`` or ``.zarr``);
/// - an H×W×4 uint8 array: a picture (``.png``/``.tif``/``.zarr``).
#[pyfunction]
#[pyo3(signature = (obj, path, *, bits=16, dx=false, half=false, exr_compression="zip", color=false, mask=false, zarr_dtype="float32", chunk=rgbn::raster::io::zarr::DEFAULT_CHUNK, zarr_compression="zstd"))]
#[allow(clippy::too_many_arguments)]
pub fn write(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    path: PathBuf,
    bits: u8,
    dx: bool,
    half: bool,
    exr_compression: &str,
    color: bool,
    mask: bool,
    zarr_dtype: &str,
    chunk: usize,
    zarr_compression: &str,
) -> PyResult<()> {
    use rgbn::raster::io::zarr::{ZarrCompression, ZarrDtype, ZarrOptions};
    let Some(dtype) = ZarrDtype::ALL.into_iter().find(|c| c.name() == zarr_dtype) else {
        return Err(input(format!(
            "\"{zarr_dtype}\": zarr_dtype must be one of float32, float16, uint16"
        )));
    };
    let Some(zcomp) = ZarrCompression::ALL
        .into_iter()
        .find(|c| c.name() == zarr_compression)
    else {
        return Err(input(format!(
            "\"{zarr_compression}\": zarr_compression must be one of zstd, blosc, none"
        )));
    };
    if bits != 8 && bits != 16 {
        return Err(input(format!("\"{bits}\": bits must be 8 or 16")));
    }
    let Some(compression) = ExrCompression::ALL
        .into_iter()
        .find(|c| c.name() == exr_compression)
    else {
        let names: Vec<&str> = ExrCompression::ALL.iter().map(|c| c.name()).collect();
        return Err(input(format!(
            "\"{exr_compression}\": exr_compression must be one of {}",
            names.join(", ")
        )));
    };
    let value = value_of(py, obj, mask)?;
    let opts = SaveOptions {
        bits,
        convention: if dx {
            NormalConvention::DirectX
        } else {
            NormalConvention::OpenGl
        },
        precision: if half {
            ExrPrecision::Half
        } else {
            ExrPrecision::Full
        },
        compression,
        zarr: ZarrOptions {
            dtype,
            compression: zcomp,
            chunk,
            ..ZarrOptions::default()
        },
    };
    py.detach(|| {
        io::check_output(&path, &[])?;
        match (&value, color) {
            (Value::Rgbn(img), true) => io::save_color(img, &path, bits),
            (v, _) => rgbn::nodes::save::write_value(v, &path, &opts),
        }
    })
    .map_err(rgbn_err)
}
