//! Rotation combine of normals (Pereira & Velho §VII): a *detail* normal is expressed in a
//! tangent frame attached to a *base* normal, so that detail keeps its look on a tilted base.
//!
//! # Frames
//!
//! A frame is a rotation `F = [t b n]` (columns) whose third axis is the base normal `n`.
//! - **Minimal rotation** ([`Frame::MinimalRotation`]): the shortest-arc rotation taking
//!   `e_z = (0,0,1)` to `n`. With `v = e_z × n = (−n_y, n_x, 0)` and `c = n_z`
//!   (Rodrigues): `F d = c·d + v × d + v (v·d)/(1 + c)`. For `n = −e_z` (no unique shortest
//!   arc) the rotation by π about `x` is used.
//! - **Oriented** ([`Frame::Oriented`]): `t = normalize(o − (o·n) n)` for an orientation vector
//!   `o` (e.g. the image's `x` axis or a brush direction), `b = n × t`; falls back to the
//!   minimal frame where `o ∥ n`.
//!
//! # Modes (per pixel; base `n`, detail `d` expressed in the base's frame, existing normal `a`,
//! weight `w ∈ [0,1]`)
//!
//! The three modes of §VII edit the *existing* normal `a` — the image before the edit, fine
//! detail included (the `existing` input; the base `n` when it is not connected). The detail,
//! taken to the image frame, is the new normal `b = F d`. §VII: "This strategy fails when b has
//! a negative z value. In this case we … replace b by a saturated vector k": with saturation
//! on, a `b` with `b_z < min_z` is first moved back along the great arc from `n` to `b`, to the
//! first point `k` where `z = min_z` (see Saturation).
//! - [`CombineMode::Replace`]: `a ← b` where `w ≥ ½`, else `a` (a hard region).
//! - [`CombineMode::Blend`]: `slerp(a, b, w)`: a smooth falloff back to the existing normal.
//! - [`CombineMode::Rotate`]: the weight first *attenuates* the detail along its great arc to
//!   the pole, `d_w = slerp(e_z, d, w)`, `b = F d_w` (saturated to `k`); then `a` is rotated by
//!   the shortest-arc rotation taking `n` to `b` (axis `n × b`, angle `∠(n, b)`): the existing
//!   normal turns by the direction and angle the detail specifies. A base at 80°, a detail of
//!   30° and an existing normal at 50°, all tilted about `y`: `b` would be at 110°, `k` is at
//!   `acos(min_z)` = 87.13°, and the result is at 50° + 7.13° = 57.13°.
//!
//! With `a = n` (existing not connected) Blend and Rotate both give `F d_w`, the detail on the
//! base.
//! - Industry blends of Barré-Brisebois & Hill (2012) on `(n, d_w)` in the image frame (they
//!   ignore `a`): [`CombineMode::Rnm`] (reoriented normal mapping: equals Blend in the minimal
//!   frame with `a = n`), [`CombineMode::Udn`] `normalize(n_xy + d_xy, n_z)`,
//!   [`CombineMode::Whiteout`] `normalize(n_xy + d_xy, n_z d_z)`, and
//!   [`CombineMode::PartialDerivative`] `normalize(n_xy d_z + d_xy n_z, n_z d_z)`, i.e. the sum
//!   of the gradients (= the linear combine of [`super::combine`]).
//!
//! # Saturation
//!
//! Rotating a tilted base by a tilted detail can push a normal over the horizon (RNM gives
//! `z < 0` for a base at 80° and a 30° detail in the same direction). With saturation on, a
//! vector with `z < min_z` is moved back along the great arc from where the rotation starts to
//! it, to the first point where `z = min_z` (the rotation "stops" at the threshold); if the
//! start itself is below `min_z`, along the meridian (keeping the azimuth). The §VII modes
//! saturate `b` (arc from `n`) and then, should the edited normal still fall below `min_z`
//! (a rotated `a` already near the horizon), the result (arc from `a`); the industry blends
//! saturate their result (arc from `n`).
//!
//! # Integrable
//!
//! None of these modes gives the normals of a surface in general (§VII controls the nonlinear
//! combine's integrability with a two-band split only: the smooth band is left alone and the
//! detail is small). With `integrable` on, the result is replaced by the nearest integrable
//! field that differs from the unedited image (the `existing` input for the §VII modes, the
//! base for the industry blends) only inside the edit's *support* — the pixels whose weight
//! lets the detail act, plus any pixel the combine changed: the change of the slopes is
//! projected onto the gradients of height changes that are 0 outside the support (a Poisson
//! equation on the support with the border held at the unedited image's height, see
//! [`crate::raster::integrate::project_in_support`]; with a border, the height change lives
//! at the pixel corners, so the held border is met exactly). Outside the support nothing
//! changes, and the result is exactly as integrable as the unedited image.
//!
//! # References
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §VII.
//! - C. Barré-Brisebois, S. Hill, "Blending in Detail", 2012
//!   (<https://blog.selfshadow.com/publications/blending-in-detail/>).
//! - C. Toler-Franklin et al., "Illustration of complex real-world objects using images with
//!   normals", NPAR 2007 (detail as a rotation of the base).

use crate::error::RgbnError;
use crate::raster::buf;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::integrate::{integrable_edit, IntegrateParams};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// 3-vector helpers (f64 internally for accuracy).
pub type V3 = [f64; 3];

#[inline]
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a / |a|`, or `(0, 0, 1)` for a zero or non-finite vector.
#[inline]
#[must_use]
pub fn normalize3(a: V3) -> V3 {
    let l = dot(a, a).sqrt();
    if l.is_finite() && l > 1e-12 {
        scale(a, 1.0 / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

fn to64(n: [f32; 3]) -> V3 {
    [f64::from(n[0]), f64::from(n[1]), f64::from(n[2])]
}
fn to32(n: V3) -> [f32; 3] {
    [n[0] as f32, n[1] as f32, n[2] as f32]
}

/// `1 + c` below this is treated as the antipodal case of the minimal rotation.
const ANTIPODAL_EPS: f64 = 1e-9;

/// The shortest-arc rotation taking `e_z` to unit `n`, applied to `d` (module docs).
#[inline]
#[must_use]
pub fn min_rotation_apply(n: V3, d: V3) -> V3 {
    let c = n[2];
    if 1.0 + c < ANTIPODAL_EPS {
        return [d[0], -d[1], -d[2]];
    }
    let v = [-n[1], n[0], 0.0];
    add(
        add(scale(d, c), cross(v, d)),
        scale(v, dot(v, d) / (1.0 + c)),
    )
}

/// The inverse of [`min_rotation_apply`]: the rotation taking unit `n` to `e_z`, applied to `x`.
#[inline]
#[must_use]
pub fn min_rotation_inverse(n: V3, x: V3) -> V3 {
    let c = n[2];
    if 1.0 + c < ANTIPODAL_EPS {
        return [x[0], -x[1], -x[2]];
    }
    let v = [-n[1], n[0], 0.0];
    add(
        add(scale(x, c), cross(x, v)),
        scale(v, dot(v, x) / (1.0 + c)),
    )
}

/// How the tangent frame of a base normal is built.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Frame {
    /// Shortest-arc rotation from `e_z` to the base normal (makes Blend equal RNM).
    #[default]
    MinimalRotation,
    /// Tangent = the orientation vector projected onto the base's tangent plane.
    Oriented {
        /// Orientation vector in the image frame (x right, y up, z to the viewer).
        orientation: [f32; 3],
    },
}

impl Frame {
    /// The frame `[t, b, n]` of unit base normal `n`, as columns.
    #[must_use]
    pub fn axes(&self, n: V3) -> [V3; 3] {
        match self {
            Frame::MinimalRotation => [
                min_rotation_apply(n, [1.0, 0.0, 0.0]),
                min_rotation_apply(n, [0.0, 1.0, 0.0]),
                n,
            ],
            Frame::Oriented { orientation } => {
                let o = to64(*orientation);
                let t = add(o, scale(n, -dot(o, n)));
                let l = dot(t, t).sqrt();
                if l.is_nan() || l <= 1e-6 {
                    return Frame::MinimalRotation.axes(n);
                }
                let t = scale(t, 1.0 / l);
                [t, cross(n, t), n]
            }
        }
    }

    /// Tangent-frame coordinates → image frame: `F d`.
    #[must_use]
    pub fn to_world(&self, n: V3, d: V3) -> V3 {
        if let Frame::MinimalRotation = self {
            return min_rotation_apply(n, d);
        }
        let [t, b, n] = self.axes(n);
        add(add(scale(t, d[0]), scale(b, d[1])), scale(n, d[2]))
    }

    /// Image frame → tangent-frame coordinates: `Fᵀ x`.
    #[must_use]
    pub fn to_tangent(&self, n: V3, x: V3) -> V3 {
        if let Frame::MinimalRotation = self {
            return min_rotation_inverse(n, x);
        }
        let [t, b, n] = self.axes(n);
        [dot(x, t), dot(x, b), dot(x, n)]
    }

    /// Checks the orientation vector (finite, non-zero).
    pub fn validate(&self) -> Result<(), RgbnError> {
        if let Frame::Oriented { orientation } = self {
            let o = to64(*orientation);
            if !(o.iter().all(|v| v.is_finite()) && dot(o, o) > 1e-12) {
                return Err(RgbnError::param(
                    "orientation",
                    format!("{orientation:?} must be a finite, non-zero vector"),
                ));
            }
        }
        Ok(())
    }
}

crate::choice_enum! {
    /// How the tangent frame of a base normal is chosen (the parameter form of [`Frame`]).
    pub enum FrameKind {
        /// Shortest-arc rotation from +z ([`Frame::MinimalRotation`]; Blend = RNM).
        Minimal = "minimal",
        /// Tangent = orientation projected on the tangent plane ([`Frame::Oriented`]).
        Oriented = "oriented",
    }
}

crate::params! {
    /// The tangent frame of a base normal as parameters (the rotation combine's and the
    /// bilateral split's detail frame).
    #[derive(Clone, Debug, PartialEq)]
    pub struct FrameSettings {
        /// Tangent frame of the base normal: minimal (shortest-arc rotation from +z; Blend = RNM) or oriented (tangent = orientation projected on the tangent plane).
        pub frame: FrameKind = FrameKind::Minimal => choice,
        /// Orientation vector of the oriented frame (x right, y up, z to the viewer).
        pub orientation: [f64; 3] = [1.0, 0.0, 0.0] => vec3.range(-1e6, 1e6),
    }
}

impl FrameSettings {
    /// The frame, not checked (see [`Frame::validate`]).
    #[must_use]
    pub fn get(&self) -> Frame {
        self.frame.frame(self.orientation)
    }
    /// Sets the frame `frame` (a minimal frame keeps the orientation vector).
    pub fn set(&mut self, frame: &Frame) {
        (self.frame, self.orientation) = FrameKind::of(frame, self.orientation);
    }
}

impl FrameKind {
    /// The kind and orientation vector of `frame` (`orientation` is kept for a minimal frame):
    /// the parameter form of a [`Frame`].
    #[must_use]
    pub fn of(frame: &Frame, orientation: [f64; 3]) -> (FrameKind, [f64; 3]) {
        match frame {
            Frame::MinimalRotation => (FrameKind::Minimal, orientation),
            Frame::Oriented { orientation } => (FrameKind::Oriented, orientation.map(f64::from)),
        }
    }

    /// The frame of this kind with orientation vector `orientation` (unused by `Minimal`),
    /// not checked (see [`Frame::validate`]).
    #[must_use]
    pub fn frame(self, orientation: [f64; 3]) -> Frame {
        match self {
            FrameKind::Minimal => Frame::MinimalRotation,
            FrameKind::Oriented => Frame::Oriented {
                orientation: orientation.map(|x| x as f32),
            },
        }
    }
}

crate::choice_enum! {
    /// How base and detail combine (module docs).
    pub enum CombineMode {
        /// The existing normal becomes the detail on the base, `b = F d`, inside the region
        /// (`w ≥ ½`); elsewhere it is kept (§VII "replace the existing normal a with b").
        Replace = "replace",
        /// `slerp(a, b, w)`: the existing normal blended towards the detail on the base.
        Blend = "blend",
        /// The existing normal rotated by the rotation taking the base to `b` (§VII), with
        /// `b` saturated first.
        Rotate = "rotate",
        /// Reoriented normal mapping (Barré-Brisebois & Hill), in the image frame.
        Rnm = "rnm",
        /// Unreal Developer Network blend `normalize(n_xy + d_xy, n_z)`.
        Udn = "udn",
        /// Whiteout blend `normalize(n_xy + d_xy, n_z d_z)`.
        Whiteout = "whiteout",
        /// Partial-derivative blend = sum of gradients.
        PartialDerivative = "partial_derivative",
    }
}

crate::params! {
    /// Parameters of [`rotation_combine`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct RotateParams {
        /// replace: the existing normal a becomes the detail on the base, b = F d, where w ≥ ½; blend: slerp(a, b, w); rotate: a rotated by the rotation taking the base to b (§VII); rnm, udn, whiteout, partial_derivative: the blends of Barré-Brisebois & Hill (on the base, ignoring a).
        pub mode: CombineMode = CombineMode::Blend => choice,
        /// The tangent frame (used by replace, blend and rotate; the industry modes ignore it).
        pub tangent: FrameSettings = FrameSettings::default() => flatten,
        /// Global weight multiplying the per-pixel weight.
        pub strength: f64 = 1.0 => float.range(0.0, 1.0),
        /// Move vectors with n_z < min_z back along the great arc to n_z = min_z (§VII's
        /// saturated vector k).
        pub saturate: bool = true => bool,
        /// Saturation threshold on n_z.
        pub min_z: f64 = f64::from(0.05f32) => float.range(0.0, 0.999).soft(0.0, 0.5),
        /// Return the nearest integrable result instead (§VII: a nonlinear combine is not a surface's normals): the change of the slopes is made the gradient of a height change that is 0 outside the edit's support (pixels of weight > 0, or changed), the support's border held at the unedited image's height (module docs, "Integrable").
        pub integrable: bool = false => bool,
    }
}

impl RotateParams {
    /// The tangent frame (used by Replace / Blend / Rotate; the industry modes ignore it).
    #[must_use]
    pub fn tangent_frame(&self) -> Frame {
        self.tangent.get()
    }

    /// These parameters with tangent frame `frame`.
    #[must_use]
    pub fn with_frame(mut self, frame: &Frame) -> Self {
        self.tangent.set(frame);
        self
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        let strength = self.strength as f32;
        if !(strength.is_finite() && (0.0..=1.0).contains(&strength)) {
            return Err(RgbnError::param(
                "strength",
                format!("{strength} must be in [0, 1]"),
            ));
        }
        let min_z = self.min_z as f32;
        if !(min_z.is_finite() && (0.0..1.0).contains(&min_z)) {
            return Err(RgbnError::param(
                "min_z",
                format!("{min_z} must be in [0, 1)"),
            ));
        }
        self.tangent_frame().validate()
    }
}

/// `slerp(e_z, d, w)` for unit `d`.
#[must_use]
pub fn attenuate(d: V3, w: f64) -> V3 {
    if w >= 1.0 {
        return d;
    }
    if w <= 0.0 {
        return [0.0, 0.0, 1.0];
    }
    let theta = d[2].clamp(-1.0, 1.0).acos();
    let s = theta.sin();
    if s < 1e-9 {
        if theta < 1.0 {
            return normalize3(add(scale([0.0, 0.0, 1.0], 1.0 - w), scale(d, w)));
        }
        // d = −e_z: rotate through x.
        let a = w * std::f64::consts::PI;
        return [a.sin(), 0.0, a.cos()];
    }
    let a = ((1.0 - w) * theta).sin() / s;
    let b = (w * theta).sin() / s;
    normalize3(add(scale([0.0, 0.0, 1.0], a), scale(d, b)))
}

/// Saturation of the module docs: returns `r` unchanged if `r_z ≥ min_z`, else the first point
/// with `z = min_z` on the great arc from `from` to `r` (or on the meridian of `r`).
#[must_use]
pub fn saturate(from: V3, r: V3, min_z: f64) -> V3 {
    if r[2] >= min_z {
        return r;
    }
    let meridian = |r: V3| {
        let h = (r[0] * r[0] + r[1] * r[1]).sqrt();
        let (ux, uy) = if h > 1e-12 {
            (r[0] / h, r[1] / h)
        } else {
            (1.0, 0.0)
        };
        let s = (1.0 - min_z * min_z).sqrt();
        [ux * s, uy * s, min_z]
    };
    if from[2] < min_z {
        return meridian(r);
    }
    let c = dot(from, r).clamp(-1.0, 1.0);
    let e = add(r, scale(from, -c));
    let el = dot(e, e).sqrt();
    if el < 1e-9 {
        return meridian(r);
    }
    let e = scale(e, 1.0 / el);
    // z(φ) = cos φ · a_z + sin φ · e_z = R cos(φ − φ0)
    let rr = (from[2] * from[2] + e[2] * e[2]).sqrt();
    if rr < min_z {
        return meridian(r);
    }
    let phi0 = e[2].atan2(from[2]);
    let phi = phi0 + (min_z / rr).clamp(-1.0, 1.0).acos();
    normalize3(add(scale(from, phi.cos()), scale(e, phi.sin())))
}

/// `slerp(a, b, w)` for unit `a`, `b` (the shortest great arc; for antipodal vectors the arc
/// through the pole-ward direction perpendicular to `a`).
#[must_use]
pub fn slerp(a: V3, b: V3, w: f64) -> V3 {
    if w <= 0.0 {
        return a;
    }
    if w >= 1.0 {
        return b;
    }
    let c = dot(a, b).clamp(-1.0, 1.0);
    let theta = c.acos();
    let s = theta.sin();
    if s < 1e-9 {
        if c > 0.0 {
            return normalize3(add(scale(a, 1.0 - w), scale(b, w)));
        }
        // Antipodal: any perpendicular works; take the one towards +z (or +x).
        let mut p = add([0.0, 0.0, 1.0], scale(a, -a[2]));
        if dot(p, p) < 1e-18 {
            p = add([1.0, 0.0, 0.0], scale(a, -a[0]));
        }
        let p = normalize3(p);
        let t = w * std::f64::consts::PI;
        return normalize3(add(scale(a, t.cos()), scale(p, t.sin())));
    }
    let ka = ((1.0 - w) * theta).sin() / s;
    let kb = (w * theta).sin() / s;
    normalize3(add(scale(a, ka), scale(b, kb)))
}

/// The shortest-arc rotation taking unit `from` to unit `to`, applied to `x` (Rodrigues with
/// `v = from × to`, `c = from · to`: `R x = c x + v × x + v (v·x)/(1 + c)`). For antipodal
/// vectors the rotation by π about an axis perpendicular to `from` (towards +z, or +x).
#[must_use]
pub fn rotate_between(from: V3, to: V3, x: V3) -> V3 {
    let c = dot(from, to);
    if 1.0 + c < ANTIPODAL_EPS {
        let mut p = add([0.0, 0.0, 1.0], scale(from, -from[2]));
        if dot(p, p) < 1e-18 {
            p = add([1.0, 0.0, 0.0], scale(from, -from[0]));
        }
        let p = normalize3(p);
        // Rotation by π about p: x ↦ 2 (p·x) p − x.
        return add(scale(p, 2.0 * dot(p, x)), scale(x, -1.0));
    }
    let v = cross(from, to);
    add(
        add(scale(x, c), cross(v, x)),
        scale(v, dot(v, x) / (1.0 + c)),
    )
}

/// Combines one base normal `n`, detail `d` (in the base's frame for Replace/Blend/Rotate,
/// in the image frame for the industry blends), existing normal `a` (the §VII modes) with
/// weight `w` (module docs). Inputs need not be normalised; the output is unit. Returns
/// `(normal, saturated)`.
#[must_use]
pub fn combine_one(
    n: [f32; 3],
    d: [f32; 3],
    a: [f32; 3],
    w: f32,
    params: &RotateParams,
) -> ([f32; 3], bool) {
    let n = normalize3(to64(n));
    let d = normalize3(to64(d));
    let w = f64::from((w * params.strength as f32).clamp(0.0, 1.0));
    let frame = params.tangent_frame();
    // As f32, as the node always passed it.
    let min_z = f64::from(params.min_z as f32);
    let dw = attenuate(d, w);
    let sat = |from: V3, v: V3| {
        if params.saturate && v[2] < min_z {
            (saturate(from, v, min_z), true)
        } else {
            (v, false)
        }
    };
    let (r, start, b_saturated) = match params.mode {
        CombineMode::Replace | CombineMode::Blend | CombineMode::Rotate => {
            let a = normalize3(to64(a));
            let detail = if params.mode == CombineMode::Rotate {
                dw
            } else {
                d
            };
            let (b, b_saturated) = sat(n, frame.to_world(n, detail));
            let r = match params.mode {
                CombineMode::Replace => {
                    if w >= 0.5 {
                        b
                    } else {
                        a
                    }
                }
                CombineMode::Blend => slerp(a, b, w),
                // From the base as saturated the same way: a base below the horizon
                // threshold with no edit (b = n) is then no rotation at all.
                _ => rotate_between(sat(n, n).0, b, a),
            };
            (r, a, b_saturated)
        }
        CombineMode::Rnm => {
            let t = [n[0], n[1], n[2] + 1.0];
            let u = [-dw[0], -dw[1], dw[2]];
            let r = if t[2] < ANTIPODAL_EPS {
                min_rotation_apply(n, dw)
            } else {
                normalize3(add(scale(t, dot(t, u) / t[2]), scale(u, -1.0)))
            };
            (r, n, false)
        }
        CombineMode::Udn => (normalize3([n[0] + dw[0], n[1] + dw[1], n[2]]), n, false),
        CombineMode::Whiteout => (
            normalize3([n[0] + dw[0], n[1] + dw[1], n[2] * dw[2]]),
            n,
            false,
        ),
        CombineMode::PartialDerivative => (
            normalize3([
                n[0] * dw[2] + dw[0] * n[2],
                n[1] * dw[2] + dw[1] * n[2],
                n[2] * dw[2],
            ]),
            n,
            false,
        ),
    };
    let (r, r_saturated) = sat(start, normalize3(r));
    (to32(r), b_saturated || r_saturated)
}

/// What [`rotation_combine`] measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RotateReport {
    /// Pixels moved back to `min_z` by saturation.
    pub saturated: usize,
    /// Curl of the result's gradients (a nonlinear op: reported, not guaranteed small).
    pub curl_after: CurlStats,
    /// With `integrable`: the pixels of the edit's support, whether its border was held
    /// (the support is not the whole image), and the conjugate-gradient iterations.
    pub integrable: Option<(usize, bool, u32)>,
}

fn check_size(
    what: &'static str,
    w: usize,
    h: usize,
    gw: usize,
    gh: usize,
) -> Result<(), RgbnError> {
    if (w, h) != (gw, gh) {
        return Err(RgbnError::SizeMismatch {
            what,
            want_w: w,
            want_h: h,
            got_w: gw,
            got_h: gh,
            path: "".into(),
        });
    }
    Ok(())
}

/// Rotation combine of two images (module docs): colour and mask come from `base`; `existing`
/// (default = `base`) holds the normals the §VII modes edit; `weight` (default 1) is the
/// per-pixel region/falloff weight in `[0, 1]`.
pub fn rotation_combine(
    base: &RgbnImage,
    detail: &RgbnImage,
    existing: Option<&RgbnImage>,
    weight: Option<&Plane>,
    params: &RotateParams,
) -> Result<(RgbnImage, RotateReport), RgbnError> {
    params.validate()?;
    let (w, h) = (base.width(), base.height());
    check_size("detail", w, h, detail.width(), detail.height())?;
    if let Some(e) = existing {
        check_size("existing", w, h, e.width(), e.height())?;
    }
    if let Some(m) = weight {
        check_size("weight", w, h, m.width(), m.height())?;
    }
    let ex = existing.unwrap_or(base);
    let (bn, dn, en) = (base.normal(), detail.normal(), ex.normal());
    let mut out = [
        buf::zeroed_f32(w * h),
        buf::zeroed_f32(w * h),
        buf::zeroed_f32(w * h),
    ];
    let [ox, oy, oz] = &mut out;
    let saturated: usize = ox
        .par_iter_mut()
        .zip(oy.par_iter_mut())
        .zip(oz.par_iter_mut())
        .enumerate()
        .map(|(i, ((x, y), z))| {
            let wt = weight.map_or(1.0, |m| m.data()[i]);
            let wt = if wt.is_finite() { wt } else { 0.0 };
            let (r, s) = combine_one(
                [bn[0][i], bn[1][i], bn[2][i]],
                [dn[0][i], dn[1][i], dn[2][i]],
                [en[0][i], en[1][i], en[2][i]],
                wt,
                params,
            );
            [*x, *y, *z] = r;
            usize::from(s)
        })
        .sum();
    let mut img = base.with_normals(out)?;
    let mut integrable = None;
    if params.integrable {
        // The edit's reference: the existing normals for the §VII modes, the base for the
        // industry blends (which give the base where the weight is 0).
        let reference = match params.mode {
            CombineMode::Replace | CombineMode::Blend | CombineMode::Rotate => ex,
            _ => base,
        };
        let support = edit_support(reference, &img, weight, params);
        let (held, proj) = integrable_edit(reference, &img, &support, &IntegrateParams::default())?;
        img = held;
        let pixels = support.iter().filter(|&&s| s).count();
        integrable = Some((pixels, proj.held, proj.iterations));
    }
    let curl_after = GradientField::from_normals(&img).curl_stats(img.mask());
    Ok((
        img,
        RotateReport {
            saturated,
            curl_after,
            integrable,
        },
    ))
}

/// The support of a combine (module docs, "Integrable"): the pixels whose weight lets the
/// detail act (`w·strength ≥ ½` for Replace, `> 0` otherwise), and any pixel whose normal the
/// combine changed (saturation).
fn edit_support(
    reference: &RgbnImage,
    result: &RgbnImage,
    weight: Option<&Plane>,
    params: &RotateParams,
) -> Vec<bool> {
    let (rn, on) = (reference.normal(), result.normal());
    (0..result.len())
        .into_par_iter()
        .map(|i| {
            let wt = weight.map_or(1.0, |m| m.data()[i]);
            let wt = if wt.is_finite() { wt } else { 0.0 };
            let w = (wt * params.strength as f32).clamp(0.0, 1.0);
            let acts = if params.mode == CombineMode::Replace {
                w >= 0.5
            } else {
                w > 0.0
            };
            acts || (0..3).any(|k| rn[k][i] != on[k][i])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn n2() -> [f32; 3] {
        let l = (0.04f32 + 0.01 + 0.97 * 0.97).sqrt();
        [-0.2 / l, 0.1 / l, 0.97 / l]
    }
    const N1: [f32; 3] = [0.3, 0.4, 0.866];

    fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
    }

    #[test]
    fn blend_in_minimal_frame_equals_rnm_test_vector() {
        let want = [0.0947f32, 0.4946, 0.8640];
        let p = RotateParams::default();
        let (a, _) = combine_one(N1, n2(), N1, 1.0, &p);
        assert!(close(a, want, 1e-4), "{a:?}");
        let (b, _) = combine_one(
            N1,
            n2(),
            N1,
            1.0,
            &RotateParams {
                mode: CombineMode::Rnm,
                ..p.clone()
            },
        );
        assert!(close(b, want, 1e-4), "{b:?}");
        assert!(close(a, b, 1e-5), "{a:?} {b:?}");
        // Rotate mode with existing = base equals Blend.
        let (c, _) = combine_one(
            N1,
            n2(),
            N1,
            1.0,
            &RotateParams {
                mode: CombineMode::Rotate,
                ..p
            },
        );
        assert!(close(a, c, 1e-5), "{a:?} {c:?}");
    }

    #[test]
    fn partial_derivative_mode_equals_gradient_sum() {
        let p = RotateParams {
            mode: CombineMode::PartialDerivative,
            ..RotateParams::default()
        };
        let (a, _) = combine_one(N1, n2(), N1, 1.0, &p);
        assert!(close(a, [0.1212, 0.4883, 0.8642], 1e-4), "{a:?}");
        // UDN and whiteout agree in spirit: tilt towards both.
        for mode in [CombineMode::Udn, CombineMode::Whiteout] {
            let (u, _) = combine_one(N1, n2(), N1, 1.0, &RotateParams { mode, ..p.clone() });
            assert!(u[1] > N1[1] && u[0] < N1[0], "{mode:?} {u:?}");
        }
    }

    #[test]
    fn steep_base_saturates_at_the_threshold_instead_of_the_horizon() {
        let b = 80f64.to_radians();
        let d = 30f64.to_radians();
        let n = [b.sin() as f32, 0.0, b.cos() as f32];
        let det = [d.sin() as f32, 0.0, d.cos() as f32];
        let raw = RotateParams {
            saturate: false,
            ..RotateParams::default()
        };
        let (r, s) = combine_one(n, det, n, 1.0, &raw);
        assert!(r[2] < 0.0 && !s, "RNM goes under the horizon: {r:?}");
        let rnm = combine_one(
            n,
            det,
            n,
            1.0,
            &RotateParams {
                mode: CombineMode::Rnm,
                ..raw
            },
        )
        .0;
        assert!(rnm[2] < 0.0 && close(rnm, r, 1e-5), "{rnm:?}");
        let p = RotateParams::default();
        let (r, s) = combine_one(n, det, n, 1.0, &p);
        assert!(s && (r[2] - p.min_z as f32).abs() < 1e-5, "{r:?}");
        assert!(r[0] > 0.99 && r[1].abs() < 1e-6, "on the arc: {r:?}");
        // Off-plane: the saturated result lies on the great circle through base and raw result.
        let det = [0.3f32, 0.4, 0.866];
        let (raw_r, _) = combine_one(
            n,
            det,
            n,
            1.0,
            &RotateParams {
                saturate: false,
                ..p.clone()
            },
        );
        let (sat, s) = combine_one(n, det, n, 1.0, &p);
        assert!(s && (sat[2] - p.min_z as f32).abs() < 1e-5);
        let c = cross(to64(n), to64(raw_r));
        assert!(dot(c, to64(sat)).abs() < 1e-5, "coplanar");
    }

    #[test]
    fn oriented_frame_is_orthonormal_and_round_trips() {
        let f = Frame::Oriented {
            orientation: [1.0, 0.2, 0.0],
        };
        let n = normalize3([0.2, -0.5, 0.8]);
        let [t, b, nn] = f.axes(n);
        for (a, bb) in [(t, b), (t, nn), (b, nn)] {
            assert!(dot(a, bb).abs() < 1e-12);
        }
        assert!((dot(cross(t, b), nn) - 1.0).abs() < 1e-12, "right-handed");
        let x = normalize3([0.1, 0.7, 0.3]);
        let y = f.to_world(n, f.to_tangent(n, x));
        assert!((0..3).all(|k| (x[k] - y[k]).abs() < 1e-12));
        assert!(f.validate().is_ok());
        let bad = Frame::Oriented {
            orientation: [0.0; 3],
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("orientation"));
    }

    #[test]
    fn bad_params_are_refused_with_the_range() {
        for (p, needle) in [
            (
                RotateParams {
                    strength: f64::NAN,
                    ..RotateParams::default()
                },
                "strength",
            ),
            (
                RotateParams {
                    min_z: 1.0,
                    ..RotateParams::default()
                },
                "[0, 1)",
            ),
        ] {
            let e = p.validate().unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
        let img = RgbnImage::flat(4, 4, [0.5; 3]);
        let other = RgbnImage::flat(5, 4, [0.5; 3]);
        assert!(rotation_combine(&img, &other, None, None, &RotateParams::default()).is_err());
    }

    fn unit() -> impl Strategy<Value = [f32; 3]> {
        (-1.0f32..1.0, -1.0f32..1.0, 0.05f32..1.0).prop_map(|(x, y, z)| {
            let v = normalize3([f64::from(x), f64::from(y), f64::from(z)]);
            to32(v)
        })
    }

    #[test]
    fn rotate_with_no_edit_keeps_the_existing_normal_over_a_grazing_base() {
        // Found by the property below: a base below the horizon threshold (n_z 0.038) with
        // weight 0 once rotated the existing normal by the base's own saturation.
        let n = [0.678_003_4, -0.734_051_2, 0.038_472_26];
        let p = RotateParams {
            mode: CombineMode::Rotate,
            ..RotateParams::default()
        };
        let (r, _) = combine_one(n, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 0.0, &p);
        assert!(
            (0..3).all(|k| (r[k] - [0.0, 0.0, 1.0][k]).abs() < 1e-6),
            "{r:?}"
        );
    }

    proptest! {
        #[test]
        fn minimal_rotation_round_trips_and_is_unit(n in unit(), x in unit()) {
            let (n, x) = (normalize3(to64(n)), normalize3(to64(x)));
            let d = min_rotation_inverse(n, x);
            let y = min_rotation_apply(n, d);
            prop_assert!((0..3).all(|k| (x[k] - y[k]).abs() < 1e-9));
            prop_assert!((dot(d, d) - 1.0).abs() < 1e-9);
            let ez = min_rotation_apply(n, [0.0, 0.0, 1.0]);
            prop_assert!((0..3).all(|k| (ez[k] - n[k]).abs() < 1e-9));
        }

        #[test]
        fn every_mode_gives_finite_unit_normals_above_the_threshold(
            n in unit(), d in unit(), e in unit(), w in 0.0f32..1.0, m in 0usize..7
        ) {
            let mode = [CombineMode::Replace, CombineMode::Blend, CombineMode::Rotate,
                CombineMode::Rnm, CombineMode::Udn, CombineMode::Whiteout,
                CombineMode::PartialDerivative][m];
            let p = RotateParams { mode, ..RotateParams::default() };
            let (r, _) = combine_one(n, d, e, w, &p);
            let l = r.iter().map(|v| v * v).sum::<f32>().sqrt();
            prop_assert!((l - 1.0).abs() < 1e-5);
            prop_assert!(r[2] >= p.min_z as f32 - 1e-5, "{:?}", r);
            // w = 0: the existing normal is returned by the §VII modes, the base by the blends.
            let (r0, _) = combine_one(n, d, e, 0.0, &p);
            let want = if m < 3 { to32(normalize3(to64(e))) } else { to32(normalize3(to64(n))) };
            if want[2] >= p.min_z as f32 {
                prop_assert!((0..3).all(|k| (r0[k] - want[k]).abs() < 1e-5), "{:?} {:?}", r0, want);
            }
        }
    }
}
