//! The values that flow along edges ([`Value`]), their port types, and the pixel operations the
//! engine applies to any value: [`crop`], [`reduce`], [`window_of`], assembling tiles
//! ([`gather_value`]) and patching a value in place ([`patch`]).

use crate::raster::window::{gather, Rect, Window};
use crate::raster::{Plane, RgbnImage};
use std::sync::Arc;

/// The type of a port; connections are checked against it.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
pub enum PortType {
    /// An RGBN image (colour, normals, optional mask).
    Rgbn,
    /// A coverage mask in [0, 1].
    Mask,
    /// A scalar field (height, curl).
    Scalar,
    /// A display picture: sRGB 8-bit RGBA (renders, views).
    Picture,
    /// A single number (statistics).
    Number,
}

impl PortType {
    /// Every port type.
    pub const ALL: [PortType; 5] = [
        PortType::Rgbn,
        PortType::Mask,
        PortType::Scalar,
        PortType::Picture,
        PortType::Number,
    ];
    /// Lower-case name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            PortType::Rgbn => "rgbn",
            PortType::Mask => "mask",
            PortType::Scalar => "scalar",
            PortType::Picture => "picture",
            PortType::Number => "number",
        }
    }
}

/// An sRGB 8-bit RGBA picture, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `4 · width · height` bytes.
    pub rgba: Vec<u8>,
}

/// A value flowing along an edge. Cloning is cheap (reference counted).
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// An RGBN image (its planes are shared, copy-on-write).
    Rgbn(RgbnImage),
    /// A mask.
    Mask(Arc<Plane>),
    /// A scalar field.
    Scalar(Arc<Plane>),
    /// A display picture.
    Picture(Arc<Picture>),
    /// A number.
    Number(f64),
}

impl Value {
    /// The port type this value fits.
    #[must_use]
    pub fn port_type(&self) -> PortType {
        match self {
            Value::Rgbn(_) => PortType::Rgbn,
            Value::Mask(_) => PortType::Mask,
            Value::Scalar(_) => PortType::Scalar,
            Value::Picture(_) => PortType::Picture,
            Value::Number(_) => PortType::Number,
        }
    }
    /// Pixel size (`None` for numbers).
    #[must_use]
    pub fn size(&self) -> Option<(usize, usize)> {
        match self {
            Value::Rgbn(i) => Some((i.width(), i.height())),
            Value::Mask(p) | Value::Scalar(p) => Some((p.width(), p.height())),
            Value::Picture(p) => Some((p.width, p.height)),
            Value::Number(_) => None,
        }
    }
    /// The separately shared blocks of pixel data this value holds, as (address, bytes): an
    /// RGBN image's colour planes, normal planes and mask are each shared copy-on-write, so
    /// two values that share a block name the same address (a pen's output shares its input's
    /// colour). Memory counted by parts counts such a block once; the bytes add up to
    /// [`Value::byte_size`].
    #[must_use]
    pub fn parts(&self) -> Vec<(usize, usize)> {
        let f = std::mem::size_of::<f32>();
        match self {
            Value::Rgbn(i) => {
                let planes = |p: &[Vec<f32>; 3]| (p.as_ptr() as usize, 3 * i.len() * f);
                let mut v = vec![planes(i.color()), planes(i.normal())];
                if let Some(m) = i.mask() {
                    v.push((m.as_ptr() as usize, std::mem::size_of_val(m)));
                }
                v
            }
            Value::Mask(p) | Value::Scalar(p) => {
                vec![(Arc::as_ptr(p) as usize, std::mem::size_of_val(p.data()))]
            }
            Value::Picture(p) => vec![(Arc::as_ptr(p) as usize, p.rgba.len())],
            Value::Number(_) => vec![(std::ptr::from_ref(self) as usize, 8)],
        }
    }
    /// Bytes of pixel data held.
    #[must_use]
    pub fn byte_size(&self) -> usize {
        match self {
            Value::Rgbn(i) => i.byte_size(),
            Value::Mask(p) | Value::Scalar(p) => p.data().len() * 4,
            Value::Picture(p) => p.rgba.len(),
            Value::Number(_) => 8,
        }
    }
}

/// A value's pixel size (`None` for numbers).
fn dims(v: &Value) -> Option<(usize, usize)> {
    v.size()
}

/// `r` assembled from `parts` (same kind, each covering its rectangle, sorted by rows so
/// that `rows(y)` gives the ones that can cover row `y`). Numbers: the first part's.
pub fn gather_value(
    parts: &[(Rect, &Value)],
    r: Rect,
    rows: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync),
) -> Value {
    let n = r.w * r.h;
    let Some((_, first)) = parts.first() else {
        return Value::Number(f64::NAN);
    };
    let plane = |get: &dyn Fn(&Value) -> Option<&[f32]>| -> Vec<f32> {
        let ps: Vec<(Rect, &[f32])> = parts
            .iter()
            .map(|(at, v)| (*at, get(v).unwrap_or(&[])))
            .collect();
        let mut out = vec![0.0f32; n];
        gather(&mut out, r, 1, &ps, rows);
        out
    };
    match first {
        Value::Rgbn(img) => {
            let c: [Vec<f32>; 3] = std::array::from_fn(|k| {
                plane(&|v| match v {
                    Value::Rgbn(i) => Some(&i.color()[k]),
                    _ => None,
                })
            });
            let nm: [Vec<f32>; 3] = std::array::from_fn(|k| {
                plane(&|v| match v {
                    Value::Rgbn(i) => Some(&i.normal()[k]),
                    _ => None,
                })
            });
            let mask = img.mask().map(|_| {
                plane(&|v| match v {
                    Value::Rgbn(i) => i.mask(),
                    _ => None,
                })
            });
            Value::Rgbn(RgbnImage::new(r.w, r.h, c, nm, mask).expect("planes of the right size"))
        }
        Value::Mask(_) | Value::Scalar(_) => {
            let data = plane(&|v| match v {
                Value::Mask(p) | Value::Scalar(p) => Some(p.data()),
                _ => None,
            });
            let p = Arc::new(Plane::from_vec(r.w, r.h, data).expect("right size"));
            if matches!(first, Value::Mask(_)) {
                Value::Mask(p)
            } else {
                Value::Scalar(p)
            }
        }
        Value::Picture(_) => {
            let ps: Vec<(Rect, &[u8])> = parts
                .iter()
                .map(|(at, v)| match v {
                    Value::Picture(p) => (*at, p.rgba.as_slice()),
                    _ => (*at, &[][..]),
                })
                .collect();
            let mut rgba = vec![0u8; 4 * n];
            gather(&mut rgba, r, 4, &ps, rows);
            Value::Picture(Arc::new(Picture {
                width: r.w,
                height: r.h,
                rgba,
            }))
        }
        Value::Number(v) => Value::Number(*v),
    }
}

/// Whether [`patch`] updates values like `v` (not images with a mask, nor numbers).
pub fn patchable(v: &Value) -> bool {
    match v {
        Value::Rgbn(img) => img.mask().is_none(),
        Value::Number(_) => false,
        _ => true,
    }
}

/// Copies `parts` (each covering its rectangle) into `dst`, which covers `r`, in place where
/// `dst` is not shared. `false` for kinds it does not patch (see [`patchable`]).
pub fn patch(dst: &mut Value, r: Rect, parts: &[(Rect, &Value)]) -> bool {
    fn copy<T: Copy>(dst: &mut [T], r: Rect, c: usize, src: &[T], at: Rect) {
        let o = r.intersect(&at);
        for y in o.y..o.bottom() {
            let s = ((y - at.y) * at.w + (o.x - at.x)) * c;
            let d = ((y - r.y) * r.w + (o.x - r.x)) * c;
            dst[d..d + o.w * c].copy_from_slice(&src[s..s + o.w * c]);
        }
    }
    match dst {
        Value::Picture(p) => {
            let rgba = &mut Arc::make_mut(p).rgba;
            for (at, v) in parts {
                let Value::Picture(s) = v else { return false };
                copy(rgba, r, 4, &s.rgba, *at);
            }
        }
        Value::Mask(p) | Value::Scalar(p) => {
            let data = Arc::make_mut(p).data_mut();
            for (at, v) in parts {
                let (Value::Mask(s) | Value::Scalar(s)) = v else {
                    return false;
                };
                copy(data, r, 1, s.data(), *at);
            }
        }
        Value::Rgbn(img) if img.mask().is_none() => {
            for (at, v) in parts {
                let Value::Rgbn(s) = v else { return false };
                for (d, p) in img.color_mut().iter_mut().zip(s.color()) {
                    copy(d, r, 1, p, *at);
                }
                for (d, p) in img.normal_mut().iter_mut().zip(s.normal()) {
                    copy(d, r, 1, p, *at);
                }
            }
        }
        _ => return false,
    }
    true
}

/// `r` (in `v`'s own pixel coordinates) cut out of `v`; numbers are returned as they are.
#[must_use]
pub fn crop(v: &Value, r: Rect) -> Value {
    let Some(sz) = dims(v) else {
        return v.clone();
    };
    if r == Rect::full(sz) {
        return v.clone();
    }
    // Row by row into fresh vectors (no zero fill first).
    let rows = |src: &[f32]| -> Vec<f32> {
        let mut out = Vec::with_capacity(r.w * r.h);
        for y in r.y..r.bottom() {
            out.extend_from_slice(&src[y * sz.0 + r.x..y * sz.0 + r.right()]);
        }
        out
    };
    match v {
        Value::Rgbn(img) => {
            let c = img.color().each_ref().map(|p| rows(p));
            let n = img.normal().each_ref().map(|p| rows(p));
            let m = img.mask().map(rows);
            Value::Rgbn(RgbnImage::new(r.w, r.h, c, n, m).expect("planes of the right size"))
        }
        Value::Mask(p) => Value::Mask(Arc::new(
            Plane::from_vec(r.w, r.h, rows(p.data())).expect("right size"),
        )),
        Value::Scalar(p) => Value::Scalar(Arc::new(
            Plane::from_vec(r.w, r.h, rows(p.data())).expect("right size"),
        )),
        _ => gather_value(&[(Rect::full(sz), v)], r, &|_| 0..1),
    }
}

/// `v` reduced by `s` ([`crate::raster::pyramid`]); numbers as they are.
#[must_use]
pub fn reduce(v: &Value, s: usize) -> Value {
    use crate::raster::pyramid;
    if s <= 1 {
        return v.clone();
    }
    match v {
        Value::Rgbn(img) => Value::Rgbn(pyramid::reduce_rgbn(img, s)),
        Value::Mask(p) => Value::Mask(Arc::new(pyramid::reduce_plane(p, s))),
        Value::Scalar(p) => Value::Scalar(Arc::new(pyramid::reduce_plane(p, s))),
        Value::Picture(p) => {
            let (width, height) = pyramid::reduced_size((p.width, p.height), s);
            Value::Picture(Arc::new(Picture {
                width,
                height,
                rgba: pyramid::reduce_rgba8(&p.rgba, p.width, p.height, s),
            }))
        }
        Value::Number(_) => v.clone(),
    }
}

/// Window `win` of a full-resolution value: the fine pixels it covers, reduced by its scale.
#[must_use]
pub fn window_of(v: &Value, win: Window) -> Value {
    let s = win.scale.max(1);
    let Some(sz) = dims(v) else {
        return v.clone();
    };
    let fine = Rect::new(win.x * s, win.y * s, win.w * s, win.h * s).intersect(&Rect::full(sz));
    reduce(&crop(v, fine), s)
}
