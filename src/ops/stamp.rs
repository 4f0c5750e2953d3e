//! Stamp: place a small RGBN (its relief and optionally its colour) at one or more positions
//! with an affine map (Pereira & Velho §IV, Fig. 4).
//!
//! # Maths (y-up frame of [`crate::raster::gradient`])
//!
//! Stamp coordinates `s = (u, v)` are centred on the stamp (`u = i − (w_s−1)/2`,
//! `v = (h_s−1)/2 − j` for stamp pixel column `i`, row `j`), image offsets `P − t = (x − t_x,
//! −(row − t_row))`. The stamp is placed by `P = A s + t` with
//!
//! `A = R(angle_rad) · [[1, shear], [0, 1]] · diag(scale_x, scale_y)`
//!
//! (`R` counter-clockwise as seen on screen, because `y` is up). The stamped height is
//! `H(P) = h(A⁻¹(P − t))`, so by the chain rule
//!
//! `∇_P H = (∂s/∂P)ᵀ ∇_s h = A⁻ᵀ ∇_s h`
//!
//! — gradients transform by the inverse transpose ([`transform_gradient`]); a pure rotation
//! rotates them with the stamp, a scale by `s` divides them by `s` (heights are not scaled; use
//! `height_scale`). Mirrors (`det A < 0`) are allowed; a (near) singular `A` is refused.
//!
//! # Integrability by construction
//!
//! To fade the stamp out at its border without breaking integrability, the window `W` (a
//! product of quintic smoothsteps over `falloff_px` stamp pixels from each edge) multiplies
//! the stamp's **height**: the stamped relief is `∇(W·(h − h̄))`, not `W·∇h` (whose curl is
//! `∇W × ∇h ≠ 0`); `h̄` is the mean height on the falloff ring, so the stamp meets the
//! surroundings at level 0. A stamp given as normals is therefore integrated once: a
//! least-squares (Poisson, conjugate-gradient) solve on the small stamp
//! ([`super::geom::integrate_least_squares`]), which also projects away any curl the stamp
//! had. The heights of all placements are summed on the target grid by bilinear sampling of
//! `W·(h − h̄)` at `A⁻¹(P − t)`, and the stamp gradient is the forward difference of that
//! height: its discrete curl is exactly zero (to rounding), whatever `A`.
//!
//! Colour (optional) is composited "over" with `α = opacity · W · mask` sampled the same way
//! (times the region, when there is one).
//!
//! # Stamp masks and regions
//!
//! A stamp with a mask (e.g. a leaf cut out with [`extract`] and a region) carries relief only
//! inside its mask: its normals are integrated by the masked least-squares solver on the mask
//! alone (so the background's normals never enter), and the height is multiplied by the
//! *feathered* mask `F` ([`mask_feather`]: 0 outside, a quintic ramp over `falloff_px` pixels
//! of distance inside) and levelled to 0 on that ring ([`prepare_masked_stamp_height`]). The
//! product is still a height, so the stamp stays integrable. A `region` mask on the target
//! multiplies the summed stamped height, `∇(m·H)` as the integrable linear combine does:
//! placements (or their parts) outside the region vanish, integrably; a hard region edge
//! makes a step in relief there (feather the region for a soft edge).
//!
//! # References
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §IV, Fig. 4.
//! - R. Frankot, R. Chellappa, "A method for enforcing integrability in shape from shading
//!   algorithms", PAMI 10(4), 1988 (least-squares integration).

use super::filter::{filter_gradients, FilterOptions, Kernel, MAX_SIGMA_PX};
use super::geom::{bilinear, distance_transform, integrate_least_squares, smoothstep};
use crate::error::RgbnError;
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::integrate::{integrate_gradients, IntegrateParams, IntegrationMethod};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;

/// Largest stamp side (pixels): the stamp is integrated with an iterative solver whose cost
/// grows as `side³`.
pub const MAX_STAMP_SIDE: usize = 512;
/// Smallest `|det A|` accepted (area scale of the map).
pub const MIN_AFFINE_DET: f64 = 1e-4;
/// Most placements per call.
pub const MAX_POSITIONS: usize = 100_000;

crate::params! {
    /// Parameters of the stamp operator (module docs). Computations use these values rounded
    /// to `f32`.
    #[derive(Clone, Debug, PartialEq)]
    pub struct StampParams {
        /// Where the stamp's centre goes, in pixels (x, row); at least one.
        pub positions: Vec<[f64; 2]> = vec![[64.0, 64.0]] => points.unit("px"),
        /// Scale along the stamp's own u axis (negative mirrors).
        pub scale_x: f64 = 1.0 => float.range(-1e4, 1e4).soft(-4.0, 4.0),
        /// Scale along the stamp's own v axis (negative mirrors).
        pub scale_y: f64 = 1.0 => float.range(-1e4, 1e4).soft(-4.0, 4.0),
        /// Rotation, counter-clockwise on screen.
        pub angle_rad: f64 = 0.0 => float.range(-1e4, 1e4).soft(-std::f64::consts::PI, std::f64::consts::PI).unit("rad"),
        /// Shear u += shear·v in the stamp frame (before the rotation).
        pub shear: f64 = 0.0 => float.range(-1e4, 1e4).soft(-2.0, 2.0),
        /// Multiplies the relief (−1 engraves instead of embossing).
        pub height_scale: f64 = 1.0 => float.range(-1e4, 1e4).soft(-4.0, 4.0),
        /// Width of the fade at each stamp edge, in stamp pixels (0 = hard edge).
        pub falloff_px: f64 = 4.0 => float.unit("px").range(0.0, 1e4).soft(0.0, 32.0),
        /// Composite the stamp's colour over the image (else relief only).
        pub color: bool = true => bool,
        /// Opacity of the stamp's colour.
        pub opacity: f64 = 1.0 => float.range(0.0, 1.0),
    }
}

fn finite_in(name: &str, v: f32, lo: f32, hi: f32) -> Result<(), RgbnError> {
    if !(v.is_finite() && v >= lo && v <= hi) {
        return Err(RgbnError::param(
            name,
            format!("{v} must be finite, in [{lo}, {hi}]"),
        ));
    }
    Ok(())
}

impl StampParams {
    /// The positions as used (`f32`).
    fn positions_f32(&self) -> Vec<[f32; 2]> {
        self.positions.iter().map(|p| p.map(|v| v as f32)).collect()
    }

    /// The width of the window's fade as used (`f32`).
    fn falloff(&self) -> f32 {
        self.falloff_px as f32
    }

    /// The colour's opacity when the colour is composited.
    fn color_opacity(&self) -> Option<f32> {
        self.color.then_some(self.opacity as f32)
    }

    /// The map `A` (y-up, `[[a, b], [c, d]]` row-major) of the module docs.
    #[must_use]
    pub fn affine(&self) -> [[f64; 2]; 2] {
        let (c, s) = (
            f64::from(self.angle_rad as f32).cos(),
            f64::from(self.angle_rad as f32).sin(),
        );
        let (sx, sy, k) = (
            f64::from(self.scale_x as f32),
            f64::from(self.scale_y as f32),
            f64::from(self.shear as f32),
        );
        // Sh · S = [[sx, k·sy], [0, sy]]; then R.
        let m = [[sx, k * sy], [0.0, sy]];
        [
            [c * m[0][0] - s * m[1][0], c * m[0][1] - s * m[1][1]],
            [s * m[0][0] + c * m[1][0], s * m[0][1] + c * m[1][1]],
        ]
    }

    /// Checks every parameter (finite values, `|det A| ≥ 1e-4`, positions present).
    pub fn validate(&self) -> Result<(), RgbnError> {
        if self.positions.is_empty() || self.positions.len() > MAX_POSITIONS {
            return Err(RgbnError::param(
                "positions",
                format!(
                    "needs 1..={MAX_POSITIONS} positions, got {}",
                    self.positions.len()
                ),
            ));
        }
        super::geom::check_points("positions", &self.positions_f32(), 1)?;
        finite_in("scale_x", self.scale_x as f32, -1e4, 1e4)?;
        finite_in("scale_y", self.scale_y as f32, -1e4, 1e4)?;
        finite_in("angle_rad", self.angle_rad as f32, -1e4, 1e4)?;
        finite_in("shear", self.shear as f32, -1e4, 1e4)?;
        finite_in("height_scale", self.height_scale as f32, -1e4, 1e4)?;
        finite_in("falloff_px", self.falloff(), 0.0, 1e4)?;
        if let Some(opacity) = self.color_opacity() {
            finite_in("opacity", opacity, 0.0, 1.0)?;
        }
        let a = self.affine();
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        if det.is_nan() || det.abs() < MIN_AFFINE_DET {
            return Err(RgbnError::param(
                "scale_x",
                format!(
                    "the affine map has zero area (det = {det:e}); |scale_x·scale_y| must be ≥ {MIN_AFFINE_DET}"
                ),
            ));
        }
        Ok(())
    }
}

/// `A⁻ᵀ g`: how a gradient of the stamp transforms when the stamp is mapped by `A` (module
/// docs). `None` for a singular `A`.
#[must_use]
pub fn transform_gradient(a: [[f64; 2]; 2], g: [f64; 2]) -> Option<[f64; 2]> {
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // A⁻¹ = [[d, −b], [−c, a]]/det; A⁻ᵀ = [[d, −c], [−b, a]]/det.
    Some([
        (a[1][1] * g[0] - a[1][0] * g[1]) / det,
        (-a[0][1] * g[0] + a[0][0] * g[1]) / det,
    ])
}

/// The stamp window `W(i, j)` (module docs): 1 inside, 0 on the edge pixels.
#[must_use]
pub fn stamp_window(width: usize, height: usize, falloff_px: f32) -> Plane {
    let f = f64::from(falloff_px);
    let ramp = |d: f64| if f <= 0.0 { 1.0 } else { smoothstep(0.0, f, d) };
    Plane::from_fn(width, height, |i, j| {
        let (i, j) = (i as f64, j as f64);
        let (w1, h1) = ((width - 1) as f64, (height - 1) as f64);
        (ramp(i) * ramp(w1 - i) * ramp(j) * ramp(h1 - j)) as f32
    })
}

/// `W·(h − h̄)` (module docs): the stamp height ready to be placed. `h̄` is the mean of `h`
/// weighted by `1 − W` (the falloff ring; the edge pixels when `falloff_px = 0`).
#[must_use]
pub fn prepare_stamp_height(h: &Plane, falloff_px: f32) -> Plane {
    let (w, hh) = (h.width(), h.height());
    let win = stamp_window(w, hh, falloff_px);
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for j in 0..hh {
        for i in 0..w {
            let edge = i == 0 || j == 0 || i + 1 == w || j + 1 == hh;
            let ring = if falloff_px > 0.0 {
                1.0 - f64::from(win.at(i, j))
            } else {
                f64::from(u8::from(edge))
            };
            num += ring * f64::from(h.at(i, j));
            den += ring;
        }
    }
    let mean = if den > 0.0 { (num / den) as f32 } else { 0.0 };
    Plane::from_fn(w, hh, |i, j| win.at(i, j) * (h.at(i, j) - mean))
}

fn check_stamp_size(w: usize, h: usize) -> Result<(), RgbnError> {
    if w < 2 || h < 2 || w > MAX_STAMP_SIDE || h > MAX_STAMP_SIDE {
        return Err(RgbnError::param(
            "stamp",
            format!("size {w}×{h} must be between 2×2 and {MAX_STAMP_SIDE}×{MAX_STAMP_SIDE}"),
        ));
    }
    Ok(())
}

/// Inverse placement: target pixel `(x, row)` → stamp pixel `(i, j)` for placement `t`.
fn to_stamp(ainv: &[[f64; 2]; 2], t: [f32; 2], sw: usize, sh: usize, x: f64, row: f64) -> [f64; 2] {
    let (dx, dy) = (x - f64::from(t[0]), -(row - f64::from(t[1])));
    let u = ainv[0][0] * dx + ainv[0][1] * dy;
    let v = ainv[1][0] * dx + ainv[1][1] * dy;
    [u + (sw - 1) as f64 / 2.0, (sh - 1) as f64 / 2.0 - v]
}

fn inverse(a: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    [
        [a[1][1] / det, -a[0][1] / det],
        [-a[1][0] / det, a[0][0] / det],
    ]
}

/// Each placement's target-pixel box `[x0, y0, x1, y1]` (unclamped) for a `sw × sh` stamp,
/// grown by two pixels beyond what [`stamp_image`] touches (its boxes' margin and the gradient's
/// differencing): where moving the placement can change the result.
#[must_use]
pub fn placement_bounds(params: &StampParams, sw: usize, sh: usize) -> Vec<[f64; 4]> {
    let a = params.affine();
    let (hw, hh) = ((sw.max(1) - 1) as f64 / 2.0, (sh.max(1) - 1) as f64 / 2.0);
    params
        .positions_f32()
        .into_iter()
        .map(|t| {
            let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
            for (u, v) in [(-hw, -hh), (hw, -hh), (-hw, hh), (hw, hh)] {
                let x = f64::from(t[0]) + a[0][0] * u + a[0][1] * v;
                let r = f64::from(t[1]) - (a[1][0] * u + a[1][1] * v);
                b = [b[0].min(x), b[1].min(r), b[2].max(x), b[3].max(r)];
            }
            [b[0] - 4.0, b[1] - 4.0, b[2] + 4.0, b[3] + 4.0]
        })
        .collect()
}

/// Target-pixel bounding box `[x0, x1) × [r0, r1)` of a placement.
fn placement_box(
    a: &[[f64; 2]; 2],
    t: [f32; 2],
    sw: usize,
    sh: usize,
    width: usize,
    height: usize,
) -> (usize, usize, usize, usize) {
    let (hw, hh) = ((sw - 1) as f64 / 2.0, (sh - 1) as f64 / 2.0);
    let (mut x0, mut x1, mut r0, mut r1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (u, v) in [(-hw, -hh), (hw, -hh), (-hw, hh), (hw, hh)] {
        let x = f64::from(t[0]) + a[0][0] * u + a[0][1] * v;
        let r = f64::from(t[1]) - (a[1][0] * u + a[1][1] * v);
        (x0, x1, r0, r1) = (x0.min(x), x1.max(x), r0.min(r), r1.max(r));
    }
    let clampi = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
    (
        clampi(x0.floor() - 1.0, width),
        clampi(x1.ceil() + 2.0, width),
        clampi(r0.floor() - 1.0, height),
        clampi(r1.ceil() + 2.0, height),
    )
}

/// The summed stamped height `Σ H(P)` on a `width × height` grid, from a *prepared* stamp
/// height (see [`prepare_stamp_height`]), times `height_scale`.
pub fn stamp_height_field(
    width: usize,
    height: usize,
    prepared: &Plane,
    params: &StampParams,
) -> Result<Plane, RgbnError> {
    params.validate()?;
    crate::raster::check_size(width, height, "stamp target")?;
    let (sw, sh) = (prepared.width(), prepared.height());
    check_stamp_size(sw, sh)?;
    let a = params.affine();
    let ainv = inverse(a);
    let hs = params.height_scale as f32;
    let boxes: Vec<_> = params
        .positions_f32()
        .into_iter()
        .map(|t| (t, placement_box(&a, t, sw, sh, width, height)))
        .collect();
    Ok(Plane::from_fn_rows(width, height, |r, out| {
        out.fill(0.0);
        for &(t, (x0, x1, r0, r1)) in &boxes {
            if r < r0 || r >= r1 {
                continue;
            }
            for (x, o) in out.iter_mut().enumerate().take(x1).skip(x0) {
                let [i, j] = to_stamp(&ainv, t, sw, sh, x as f64, r as f64);
                if let Some(v) = bilinear(prepared.data(), sw, sh, i, j) {
                    *o += hs * v;
                }
            }
        }
    }))
}

/// The stamp's gradient field on the target grid: [`GradientField::of_height`] of
/// [`stamp_height_field`] (curl-free by construction in the averaged model).
pub fn stamp_gradients(
    width: usize,
    height: usize,
    prepared: &Plane,
    params: &StampParams,
) -> Result<GradientField, RgbnError> {
    Ok(GradientField::of_height(&stamp_height_field(width, height, prepared, params)?).0)
}

/// Integrates a stamp's normals once (least squares, module docs) and prepares its height.
/// A stamp with a mask carries relief only inside it ("Stamp masks" in the module docs).
pub fn stamp_height_from_normals(stamp: &RgbnImage, falloff_px: f32) -> Result<Plane, RgbnError> {
    check_stamp_size(stamp.width(), stamp.height())?;
    let g = GradientField::from_normals(stamp);
    let Some(mask) = stamp.mask() else {
        let h = integrate_least_squares(&g, 1e-7, 4 * (stamp.width() + stamp.height()) + 500);
        return Ok(prepare_stamp_height(&h, falloff_px));
    };
    let (w, hh) = (stamp.width(), stamp.height());
    let params = IntegrateParams {
        method: IntegrationMethod::MaskedPoisson,
        ..IntegrateParams::default()
    };
    let (h, _) = integrate_gradients(&g, Some(mask), &params).map_err(|e| match e {
        RgbnError::InvalidParam { detail, .. } => {
            RgbnError::param("stamp", format!("its mask: {detail}"))
        }
        other => other,
    })?;
    let feather = mask_feather(mask, w, hh, falloff_px);
    Ok(prepare_masked_stamp_height(&h, &feather, falloff_px))
}

/// [`stamp_height_from_normals`], remembered for the last few stamps (by the hash of their
/// normals and mask, and the falloff): a stamp placed region by region, or edited placement
/// by placement, is integrated once.
fn prepared_stamp_height(
    stamp: &RgbnImage,
    falloff_px: f32,
) -> Result<std::sync::Arc<Plane>, RgbnError> {
    use parking_lot::Mutex;
    use std::sync::Arc;
    static MEMO: Mutex<Vec<(u128, Arc<Plane>)>> = Mutex::new(Vec::new());
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(&(stamp.width() as u64).to_le_bytes());
    h.update(&(stamp.height() as u64).to_le_bytes());
    h.update(&falloff_px.to_bits().to_le_bytes());
    let mut feed = |vals: &[f32]| {
        let mut buf = [0u8; 4096];
        for chunk in vals.chunks(1024) {
            for (b, v) in buf.chunks_exact_mut(4).zip(chunk) {
                b.copy_from_slice(&v.to_bits().to_le_bytes());
            }
            h.update(&buf[..4 * chunk.len()]);
        }
    };
    for plane in stamp.normal() {
        feed(plane);
    }
    if let Some(m) = stamp.mask() {
        feed(&[f32::NAN]);
        feed(m);
    }
    let key = h.digest128();
    let lock = || MEMO.lock();
    if let Some((_, p)) = lock().iter().find(|(k, _)| *k == key) {
        return Ok(p.clone());
    }
    let p = Arc::new(stamp_height_from_normals(stamp, falloff_px)?);
    let mut memo = lock();
    if memo.len() >= 8 {
        memo.remove(0);
    }
    memo.push((key, p.clone()));
    Ok(p)
}

/// The feathered stamp mask (module docs, "Stamp masks"): 0 outside the mask (coverage < ½),
/// rising by a quintic smoothstep over `falloff_px` pixels of distance from the outside (1
/// beyond; a hard edge when `falloff_px` is 0). The stamp's border counts as outside.
#[must_use]
pub fn mask_feather(mask: &[f32], width: usize, height: usize, falloff_px: f32) -> Plane {
    // Distance to the nearest outside pixel, the frame around the stamp included.
    let (fw, fh) = (width + 2, height + 2);
    let seeds: Vec<bool> = (0..fw * fh)
        .map(|k| {
            let (x, r) = (k % fw, k / fw);
            x == 0 || r == 0 || x == fw - 1 || r == fh - 1 || mask[(r - 1) * width + x - 1] < 0.5
        })
        .collect();
    let d = distance_transform(&seeds, fw, fh);
    let f = f64::from(falloff_px);
    Plane::from_fn(width, height, |x, r| {
        let dist = f64::from(d.at(x + 1, r + 1));
        if dist <= 0.0 {
            0.0
        } else if f <= 0.0 {
            1.0
        } else {
            // The first pixel inside is 1 px from the outside: the ramp starts there (at 0).
            smoothstep(0.0, f, dist - 1.0) as f32
        }
    })
}

/// `F·(h − h̄)` for a masked stamp: `F` the feathered mask ([`mask_feather`]) times the
/// stamp window, `h̄` the mean of `h` on the feather ring (weights `1 − F` inside the mask;
/// the mask's edge pixels when nothing is feathered), so the relief meets the target at level
/// 0 all round the mask and is exactly 0 outside it.
#[must_use]
pub fn prepare_masked_stamp_height(h: &Plane, feather: &Plane, falloff_px: f32) -> Plane {
    let (w, hh) = (h.width(), h.height());
    let win = stamp_window(w, hh, falloff_px);
    let weight = Plane::from_fn(w, hh, |i, j| win.at(i, j) * feather.at(i, j));
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for j in 0..hh {
        for i in 0..w {
            let f = f64::from(feather.at(i, j));
            if f > 0.0 {
                let ring = if f < 1.0 { 1.0 - f } else { 0.0 };
                num += ring * f64::from(h.at(i, j));
                den += ring;
            }
        }
    }
    if den == 0.0 {
        // No ring (a hard edge): the mask's edge pixels (a neighbour outside) set the level.
        for j in 0..hh {
            for i in 0..w {
                let inside = |x: isize, y: isize| {
                    x >= 0
                        && y >= 0
                        && (x as usize) < w
                        && (y as usize) < hh
                        && feather.at(x as usize, y as usize) > 0.0
                };
                let (x, y) = (i as isize, j as isize);
                if inside(x, y)
                    && !(inside(x - 1, y)
                        && inside(x + 1, y)
                        && inside(x, y - 1)
                        && inside(x, y + 1))
                {
                    num += f64::from(h.at(i, j));
                    den += 1.0;
                }
            }
        }
    }
    let mean = if den > 0.0 { (num / den) as f32 } else { 0.0 };
    Plane::from_fn(w, hh, |i, j| weight.at(i, j) * (h.at(i, j) - mean))
}

/// What [`stamp_image`] measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StampReport {
    /// Curl of the stamp's own gradients (0 to rounding by construction).
    pub curl_stamp: CurlStats,
    /// Curl of the result's gradients.
    pub curl_after: CurlStats,
}

/// Stamps `stamp` (relief from its normals, colour optionally) onto `target` at every position;
/// with a `region` (the target's size) the stamped height is multiplied by it, so placements
/// are restricted to the region and the result stays integrable (module docs).
pub fn stamp_image(
    target: &RgbnImage,
    stamp: &RgbnImage,
    region: Option<&[f32]>,
    params: &StampParams,
) -> Result<(RgbnImage, StampReport), RgbnError> {
    params.validate()?;
    let (w, h) = (target.width(), target.height());
    if region.is_some_and(|m| m.len() != w * h) {
        return Err(RgbnError::param(
            "region",
            format!("the mask is not the target image's size ({w}×{h})"),
        ));
    }
    let prepared = prepared_stamp_height(stamp, params.falloff())?;
    let mut height = stamp_height_field(w, h, &prepared, params)?;
    if let Some(m) = region {
        height
            .data_mut()
            .par_iter_mut()
            .zip(m.par_iter())
            .for_each(|(v, m)| *v *= m.clamp(0.0, 1.0));
    }
    let sg = GradientField::of_height(&height).0;
    let mut g = GradientField::from_normals(target);
    g.p.par_iter_mut()
        .zip(sg.p.par_iter())
        .for_each(|(a, b)| *a += b);
    g.q.par_iter_mut()
        .zip(sg.q.par_iter())
        .for_each(|(a, b)| *a += b);
    let mut out = target.clone();
    g.write_normals(&mut out);
    if let Some(opacity) = params.color_opacity() {
        let (sw, sh) = (stamp.width(), stamp.height());
        let win = stamp_window(sw, sh, params.falloff());
        let alpha_src: Vec<f32> = match stamp.mask() {
            Some(m) => win.data().iter().zip(m).map(|(a, b)| a * b).collect(),
            None => win.into_vec(),
        };
        let region_alpha =
            |x: usize, r: usize| region.map_or(1.0, |m| m[r * w + x].clamp(0.0, 1.0));
        let a = params.affine();
        let ainv = inverse(a);
        let sc = stamp.color();
        let boxes: Vec<_> = params
            .positions_f32()
            .into_iter()
            .map(|t| (t, placement_box(&a, t, sw, sh, w, h)))
            .collect();
        let color = out.color_mut();
        let [cr, cg, cb] = color;
        cr.par_chunks_mut(w)
            .zip(cg.par_chunks_mut(w))
            .zip(cb.par_chunks_mut(w))
            .enumerate()
            .for_each(|(r, ((cr, cg), cb))| {
                for &(t, (x0, x1, r0, r1)) in &boxes {
                    if r < r0 || r >= r1 {
                        continue;
                    }
                    for x in x0..x1 {
                        let [i, j] = to_stamp(&ainv, t, sw, sh, x as f64, r as f64);
                        let Some(al) = bilinear(&alpha_src, sw, sh, i, j) else {
                            continue;
                        };
                        let al = (al * opacity * region_alpha(x, r)).clamp(0.0, 1.0);
                        for (dst, src) in [
                            (&mut cr[x], &sc[0]),
                            (&mut cg[x], &sc[1]),
                            (&mut cb[x], &sc[2]),
                        ] {
                            if let Some(s) = bilinear(src, sw, sh, i, j) {
                                *dst = (1.0 - al) * *dst + al * s;
                            }
                        }
                    }
                }
            });
    }
    Ok((
        out,
        StampReport {
            curl_stamp: sg.curl_stats(None),
            curl_after: g.curl_stats(target.mask()),
        },
    ))
}

crate::params! {
    /// Parameters of the `extract` operator: the rectangle cut out of an image as a stamp.
    #[derive(Clone, Debug, PartialEq)]
    pub struct ExtractParams {
        /// Left column of the rectangle.
        pub x: i64 = 0 => int.unit("px").range(0.0, 16384.0).soft(0.0, 4096.0),
        /// Top row of the rectangle (rows count downwards).
        pub y: i64 = 0 => int.unit("px").range(0.0, 16384.0).soft(0.0, 4096.0),
        /// Width of the rectangle (ignored when a region mask is connected).
        pub width: i64 = 64 => int.unit("px").range(2.0, 512.0),
        /// Height of the rectangle (ignored when a region mask is connected).
        pub height: i64 = 64 => int.unit("px").range(2.0, 512.0),
        /// Remove the piece's low frequencies: a high-pass of this σ on its gradients, so only
        /// its detail is stamped (0 = keep everything).
        pub highpass_sigma_px: f64 = 0.0 => float.unit("px").range(0.0, 4096.0).soft(0.0, 32.0),
    }
}

/// The bounding box `(x, row, width, height)` of the pixels where `mask ≥ ½`, or `None` when
/// there are none.
#[must_use]
pub fn mask_bounds(mask: &[f32], width: usize) -> Option<(usize, usize, usize, usize)> {
    let (mut x0, mut r0, mut x1, mut r1) = (usize::MAX, usize::MAX, 0, 0);
    for (i, &m) in mask.iter().enumerate() {
        if m >= 0.5 {
            let (x, r) = (i % width, i / width);
            x0 = x0.min(x);
            r0 = r0.min(r);
            x1 = x1.max(x);
            r1 = r1.max(r);
        }
    }
    (x0 != usize::MAX).then(|| (x0, r0, x1 - x0 + 1, r1 - r0 + 1))
}

/// The `extract` operator: [`extract_stamp`] on the rectangle of `p`, or — with a `region`
/// mask (the image's size) — on the bounding box of the region, whose coverage then becomes
/// the piece's mask (times the image's own, if any).
///
/// # Errors
/// A rectangle not inside the image, a region of another size, empty or over
/// [`MAX_STAMP_SIDE`] a side.
pub fn extract(
    img: &RgbnImage,
    region: Option<&[f32]>,
    p: &ExtractParams,
) -> Result<RgbnImage, RgbnError> {
    let sigma = (p.highpass_sigma_px > 0.0).then_some(p.highpass_sigma_px as f32);
    let Some(region) = region else {
        return extract_stamp(
            img,
            p.x as usize,
            p.y as usize,
            p.width as usize,
            p.height as usize,
            sigma,
        )
        .map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "region" => {
                RgbnError::param("x, y, width, height", detail)
            }
            other => other,
        });
    };
    if region.len() != img.width() * img.height() {
        return Err(RgbnError::param(
            "region",
            format!(
                "the mask is not the image's size ({}×{})",
                img.width(),
                img.height()
            ),
        ));
    }
    let (x, r, w, h) = mask_bounds(region, img.width()).ok_or_else(|| {
        RgbnError::param(
            "region",
            "the mask covers no pixel (none ≥ 0.5)".to_string(),
        )
    })?;
    // At least 2×2 (a one-pixel region still makes a valid stamp).
    let (w2, h2) = (w.max(2).min(img.width()), h.max(2).min(img.height()));
    let (x, r) = (x.min(img.width() - w2), r.min(img.height() - h2));
    let mut out = extract_stamp(img, x, r, w2, h2, sigma).map_err(|e| match e {
        RgbnError::InvalidParam { detail, .. } => RgbnError::param(
            "region",
            format!("its bounding box {w}×{h} at ({x}, {r}): {detail}"),
        ),
        other => other,
    })?;
    let cover: Vec<f32> = (0..h2)
        .flat_map(|j| {
            let o = (r + j) * img.width() + x;
            region[o..o + w2].iter().map(|m| m.clamp(0.0, 1.0))
        })
        .zip(
            out.mask()
                .map_or_else(|| vec![1.0; w2 * h2], <[f32]>::to_vec),
        )
        .map(|(a, b)| a * b)
        .collect();
    out.set_mask(Some(cover))?;
    Ok(out)
}

/// Cuts a stamp out of an image: the `width × height` region whose top-left pixel is
/// `(x0, row0)`, with its low frequencies removed by a high-pass of `highpass_sigma_px` on the
/// gradients (`None` = keep everything). Colour and mask are cropped.
pub fn extract_stamp(
    img: &RgbnImage,
    x0: usize,
    row0: usize,
    width: usize,
    height: usize,
    highpass_sigma_px: Option<f32>,
) -> Result<RgbnImage, RgbnError> {
    check_stamp_size(width, height)?;
    if x0.checked_add(width).is_none_or(|e| e > img.width())
        || row0.checked_add(height).is_none_or(|e| e > img.height())
    {
        return Err(RgbnError::param(
            "region",
            format!(
                "{width}×{height} at ({x0}, {row0}) must lie inside the {}×{} image",
                img.width(),
                img.height()
            ),
        ));
    }
    if let Some(s) = highpass_sigma_px {
        if !(s.is_finite() && s > 0.0 && s <= MAX_SIGMA_PX) {
            return Err(RgbnError::param(
                "highpass_sigma_px",
                format!("{s} must be in (0, {MAX_SIGMA_PX}] pixels"),
            ));
        }
    }
    let crop = |plane: &[f32]| -> Vec<f32> {
        (0..height)
            .flat_map(|r| {
                let o = (row0 + r) * img.width() + x0;
                plane[o..o + width].iter().copied()
            })
            .collect()
    };
    let color = img.color().clone().map(|c| crop(&c));
    let normal = img.normal().clone().map(|c| crop(&c));
    let mask = img.mask().map(crop);
    let mut out = RgbnImage::new(width, height, color, normal, mask)?;
    if let Some(s) = highpass_sigma_px {
        let mut g = GradientField::from_normals(&out);
        filter_gradients(
            &mut g,
            &[Kernel::HighPass { sigma_px: s }],
            &FilterOptions::default(),
            None,
        )?;
        g.write_normals(&mut out);
    }
    Ok(out)
}

#[cfg(test)]
#[path = "stamp_tests.rs"]
mod tests;
