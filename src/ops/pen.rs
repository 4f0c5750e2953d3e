//! Pen: sculpt a relief along a path (Pereira & Velho §V–VI, Figs. 5–9).
//!
//! A path (polyline, open or closed, pixel coordinates `(x, row)`) with a width `W` and a height
//! profile `f(u)` across it. The stroke's local coordinates `φ(P) = (u, v)` come from the
//! closest point `C` on the path (point-to-segment distances and projections):
//!
//! - `u = σ·|P − C| / (W/2) ∈ [−1, 1]` across the stroke, with `σ = +1` on the left of the
//!   direction of travel (as seen on screen) for open paths, and `σ = +1` **inside** for closed
//!   paths (even–odd test; a closed path that crosses or touches itself is refused, naming the
//!   two segments, since §VI's closed-curve argument holds for curves without
//!   self-intersections);
//! - `v` = arclength of `C` along the path (pixels).
//!
//! The height is `h(P) = f₀ + t(v)·(f(u) − f₀)` where `f₀ = f(−1)` is the level outside the
//! stroke and `t(v)` tapers the ends of an open path (`t = S(v/τ)·S((L−v)/τ)`, `S` the quintic
//! smoothstep, `τ = taper_px`, `t ≡ 1` for closed paths). Its gradient, in the y-up frame of
//! [`crate::raster::gradient`], is
//!
//! `∇h = t(v) f′(u) ∇u + t′(v) (f(u) − f₀) ∇v`, with `∇u = σ (P − C)/(|P − C| · W/2)`
//! (the unit normal of the path, converted to y-up: `(Δx, −Δrow)`) and `∇v` = the path's unit
//! tangent where `C` is inside a segment (0 where `C` is a vertex or an end: `v` is constant
//! there).
//!
//! Three modes ([`PenMode`]):
//! - **Integrable** (default): `h` is evaluated at the pixel corners and each pixel's gradient
//!   is the 2 × 2 difference of its corners ([`GradientField::from_corner_heights`]), so the
//!   field is exactly a surface in the averaged edge model of [`crate::raster::gradient`] —
//!   curl 0 to rounding everywhere — whose height (the corner mean, at pixel centres) is the
//!   returned `height`; it equals the formula above up to the `O(h²)` error of a cell average.
//! - **Analytic**: the formula above sampled at the pixel centres
//!   ([`super::geom::sample_gradient_centres`]): exact `h′(u)∇u`, discrete curl `O(h²)`
//!   wherever `φ` is smooth, but **not** small on the path's *medial axis* (where two parts of
//!   the path are equally close: inside concave corners, T junctions, self-intersections —
//!   and, for a polyline approximating a curve, the bisector at each vertex on its concave
//!   side, where `∇u` turns by the vertex angle), because `u` has a kink there; likewise on the
//!   thin wedges at convex vertices where `v` is constant (the taper term jumps), and along the
//!   crest of kinked profiles (ridge, crease) on curved paths. Measured relative RMS curl
//!   (tests, averaged model): step circle as a 180-gon 1.3e-2, as a 1440-gon 3.9e-3; tapered
//!   scratch on a 400-vertex arc 3.1e-2. The Integrable mode gives ≈ 5e-8 on all of these.
//! - The **distance-transform mode** ([`PenMode::DistanceTransform`]) handles those
//!   shapes: it rasterises the path, takes the exact Euclidean distance transform of the seeds
//!   (Felzenszwalb & Huttenlocher), builds the height `f(u)` from it, and differentiates that
//!   height with [`GradientField::of_height`] — integrable by construction (curl 0 to
//!   rounding; the height comes back blurred by `[1 2 1]/4`) at the cost of distances
//!   quantised to the rasterised path (≤ ½ px) and no end tapering. There
//!   `u = +d/(W/2)` for open paths (the profile's half `u ∈ [0, 1]`, mirrored) and `±` by the
//!   inside test for closed paths.
//!
//! **Along the path** (§VI's normal textures: a stitched seam, beads, a knotted cord). A
//! periodic factor `m(v)` (the `along` samples over one period `along_period_px`, linearly
//! interpolated and wrapped; on a closed path the period is adjusted to `L / round(L /
//! period)` so `m` closes without a seam) multiplies the relief: `h = f₀ + t(v)·m(v)·(f(u) −
//! f₀)`, i.e. `t` becomes `t·m` and `t′` becomes `t′m + t m′` in the gradient above. It is a
//! height like the rest, so the integrable mode stays a surface. The distance-transform mode
//! has no `v` and ignores it.
//!
//! **Patterns along the path** (§VI: a rope, a stitched seam, a braid). `pattern` adds a
//! relief `T(u, v)` that varies across *and* along the stroke to the profile: `f(u)` becomes
//! `f(u) + T(u, v)`, so `h = f₀ + t(v)·m(v)·(f(u) + T(u, v) − f₀)` and the gradient gains
//! `t·m·∂T/∂v ∇v`. `T` repeats every `along_period_px` (adjusted on closed paths as `m` is) and
//! is zero at the stroke's edges `u = ±1`, so the outside is untouched. Like the profile it is
//! a height, so the integrable mode stays exactly a surface.
//! - **rope**: `S` strands (`pattern_strands`) winding around the stroke, one twist per
//!   period. Seen from above, a helix on a cylinder crosses the stroke along `θ − asin(u)/2π =
//!   const` (`θ = v/period`), so with the phase `ψ = S(θ − asin(u)/2π)` the grooves between
//!   strands lie at integer `ψ` and `T = D·(1 − u²)²·(sin(π·frac ψ) − 1)`, `D =
//!   pattern_height_px` the grooves' depth (`T = −D` in a groove on the centre line, 0 on a
//!   strand's crest).
//! - **texture**: the `texture` input, a height image of at most 1024² pixels: column `c` of
//!   `w` lies at `u = −1 + 2c/(w − 1)`, row `r` of `h` at `v = r·period/h` (repeating), values
//!   bilinearly interpolated and multiplied by `pattern_height_px`. Each row is pinned to the
//!   surface: the line between its first and last values is subtracted, so any height image
//!   meets the stroke's edges at zero. Its coordinates are relative to its size, so at a
//!   coarse level of detail it is sampled as it is (the evaluator does not reduce it).
//!
//! The distance-transform mode has no `v` and refuses a pattern.
//!
//! **End caps.** Beyond an end of an open path (the closest point is the end) the stroke
//! finishes in a cap of radius `W/2`. There `u = s/(W/2)` with `s` the signed distance to the
//! line of the last segment (continuous across its extension, so an asymmetric profile has no
//! seam there), `a` the distance beyond the end (`a² + s² = |P − C|²`), and
//! `h = f₀ + t·k·(f(u) − f₀)` with `k = 1 − a/√((W/2)² − s²)`: 1 where the cap meets the
//! stroke, 0 on its round rim. For a profile with `f(±1) = f₀` and steepest slope `σ` (height
//! per pixel) the cap is never steeper than `σ` along either axis (`|f − f₀| ≤ σ(W/2 − |s|)`
//! bounds the `∂k` terms). With a taper the cap is flat (`t = 0` at the ends).
//!
//! **Level changes.** Outside the stroke the gradient is zero, so the two sides of an open path
//! must be at the same level, `f(−1) = f(1)` (i.e. `∫f′du = 0`): otherwise the surface would
//! have to tear around the path's ends. This is validated; the [`Profile::Step`] (and any
//! custom profile with a level change) is accepted only on closed paths, where it raises
//! (or, with a negative height, lowers) the inside by `f(1) − f(−1)`.
//!
//! # References
//! - T. Pereira, L. Velho, "RGBN image editing", SIBGRAPI 2011, §V–VI.
//! - P. Felzenszwalb, D. Huttenlocher, "Distance Transforms of Sampled Functions", Theory of
//!   Computing 8 (2012).

use super::geom::{
    check_points, closed_path_crossing, distance_transform, sample_gradient_centres, smoothstep,
    smoothstep_deriv, Polyline, SegmentGrid,
};
use crate::error::RgbnError;
use crate::raster::gradient::{corner_samples, CurlStats, GradientField};
use crate::raster::{Plane, RgbnImage};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Largest pen width, taper and |profile height| accepted (pixels).
pub const MAX_PEN_PX: f32 = 10_000.0;
/// Most samples of a custom profile.
pub const MAX_PROFILE_SAMPLES: usize = 4096;

/// The height profile across the stroke, `u ∈ [−1, 1]` (heights in pixels).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Profile {
    /// Smooth bump `A·(1 + cos πu)/2`.
    Bump { height_px: f32 },
    /// Sharp ridge (tent) `A·(1 − |u|)`.
    Ridge { height_px: f32 },
    /// V-shaped crease `−D·(1 − |u|)`.
    Crease { depth_px: f32 },
    /// Scratch: a groove with raised lips, `D·(1 − u²)²(3u² − 1)` (−D in the middle, lips of
    /// ≈ 0.12·D at `|u| = 0.75`), smooth at the stroke's border.
    Scratch { depth_px: f32 },
    /// Level change `A·S((u + 1)/2)` (quintic smoothstep): closed paths only.
    Step { height_px: f32 },
    /// Samples `f(u_k)` at `u_k = −1 + 2k/(n−1)`, linearly interpolated (≥ 2 samples).
    Custom { samples_px: Vec<f32> },
}

impl Default for Profile {
    fn default() -> Self {
        Profile::Bump { height_px: 2.0 }
    }
}

fn check_amp(name: &str, a: f32) -> Result<(), RgbnError> {
    if !(a.is_finite() && a.abs() <= MAX_PEN_PX) {
        return Err(RgbnError::param(
            name,
            format!("{a} must be finite, in [-{MAX_PEN_PX}, {MAX_PEN_PX}] pixels"),
        ));
    }
    Ok(())
}

impl Profile {
    /// Checks amplitudes and samples (not the open-path level condition: see [`PenParams`]).
    pub fn validate(&self) -> Result<(), RgbnError> {
        match self {
            Profile::Bump { height_px }
            | Profile::Ridge { height_px }
            | Profile::Step { height_px } => check_amp("height_px", *height_px),
            Profile::Crease { depth_px } | Profile::Scratch { depth_px } => {
                check_amp("depth_px", *depth_px)
            }
            Profile::Custom { samples_px } => {
                if samples_px.len() < 2 || samples_px.len() > MAX_PROFILE_SAMPLES {
                    return Err(RgbnError::param(
                        "samples_px",
                        format!(
                            "needs 2..={MAX_PROFILE_SAMPLES} samples, got {}",
                            samples_px.len()
                        ),
                    ));
                }
                for s in samples_px {
                    check_amp("samples_px", *s)?;
                }
                Ok(())
            }
        }
    }

    /// `(f(u), f′(u))`; `u` is clamped to `[−1, 1]` (and `f′ = 0` outside).
    #[must_use]
    pub fn eval(&self, u: f64) -> (f64, f64) {
        let inside = (-1.0..=1.0).contains(&u);
        let u = u.clamp(-1.0, 1.0);
        let (f, df) = match self {
            Profile::Bump { height_px } => {
                let a = f64::from(*height_px);
                (
                    a * (1.0 + (PI * u).cos()) / 2.0,
                    -a * PI * (PI * u).sin() / 2.0,
                )
            }
            Profile::Ridge { height_px } => {
                let a = f64::from(*height_px);
                (a * (1.0 - u.abs()), -a * u.signum() * f64::from(u != 0.0))
            }
            Profile::Crease { depth_px } => {
                let d = f64::from(*depth_px);
                (-d * (1.0 - u.abs()), d * u.signum() * f64::from(u != 0.0))
            }
            Profile::Scratch { depth_px } => {
                let d = f64::from(*depth_px);
                let s = 1.0 - u * u;
                (
                    d * s * s * (3.0 * u * u - 1.0),
                    d * s * u * (10.0 - 18.0 * u * u),
                )
            }
            Profile::Step { height_px } => {
                let a = f64::from(*height_px);
                (
                    a * smoothstep(-1.0, 1.0, u),
                    a * smoothstep_deriv(-1.0, 1.0, u),
                )
            }
            Profile::Custom { samples_px } => {
                let n = samples_px.len().max(2) - 1;
                let t = (u + 1.0) / 2.0 * n as f64;
                let k = (t.floor() as usize).min(n - 1);
                let (a, b) = (
                    f64::from(samples_px[k]),
                    f64::from(samples_px[(k + 1).min(samples_px.len() - 1)]),
                );
                let fr = t - k as f64;
                (a + (b - a) * fr, (b - a) * n as f64 / 2.0)
            }
        };
        (f, if inside { df } else { 0.0 })
    }

    /// `f(1) − f(−1)`: the level change across the stroke.
    #[must_use]
    pub fn level_change(&self) -> f64 {
        self.eval(1.0).0 - self.eval(-1.0).0
    }
}

crate::choice_enum! {
    /// How the stroke coordinates and the gradient are computed.
    pub enum PenMode {
        /// Exact projections; the height `h` is evaluated at the pixel corners and each pixel's
        /// gradient is the 2 × 2 (averaged) difference of its four corners
        /// ([`GradientField::from_corner_heights`]): exactly a surface in the averaged edge
        /// model (curl 0 to rounding everywhere, medial axes included), its height the corner
        /// mean; the gradient equals `h′(u)∇u` up to the `O(h²)` error of that cell average.
        Integrable = "integrable",
        /// Exact projections, the analytic gradient `h′(u)∇u + …` sampled at the staggered points
        /// (curl `O(h²)` where `φ` is smooth, `O(1)` on medial-axis lines — which for a polyline
        /// include the bisectors at every vertex on its concave side).
        Analytic = "analytic",
        /// Euclidean distance transform of the rasterised path; integrable everywhere (T shapes,
        /// self-intersections), quantised to the raster.
        DistanceTransform = "distance_transform",
    }
}

crate::choice_enum! {
    /// A relief that varies along the path as well as across it, added to the profile (module
    /// docs, "Patterns along the path").
    pub enum PenPattern {
        /// None: the profile alone.
        None = "none",
        /// Twisted strands: `pattern_strands` strands winding around the stroke, one full twist
        /// per `along_period_px`, with grooves `pattern_height_px` deep between them.
        Rope = "rope",
        /// The `texture` input: a small height image, its columns across the stroke (u = −1 …
        /// 1), its rows along one period of the path, repeated.
        Texture = "texture",
    }
}

crate::choice_enum! {
    /// The kind of a [`Profile`] (its parameter form, with `height_px` and `samples_px`).
    pub enum ProfileKind {
        /// Smooth bump `A·(1 + cos πu)/2`.
        Bump = "bump",
        /// Sharp ridge (tent) `A·(1 − |u|)`.
        Ridge = "ridge",
        /// V-shaped crease `−D·(1 − |u|)`.
        Crease = "crease",
        /// A groove with raised lips.
        Scratch = "scratch",
        /// Level change (closed paths only).
        Step = "step",
        /// Samples, linearly interpolated.
        Custom = "custom",
    }
}

crate::params! {
    /// Parameters of [`pen_field`].
    #[derive(Clone, Debug, PartialEq)]
    pub struct PenParams {
        /// Path vertices in pixels (x, row): ≥ 2 for an open path, ≥ 3 distinct for a closed one, which must not cross or touch itself.
        pub points: Vec<[f64; 2]> = vec![[16.0, 16.0], [112.0, 112.0]] => points.unit("px"),
        /// Join the last point back to the first; the profile's inside is then the enclosed region.
        pub closed: bool = false => bool,
        /// Full stroke width (u = ±1 at ±width/2).
        pub width_px: f64 = 8.0 => float.unit("px").range(0.01, 10_000.0).soft(0.5, 128.0).log(),
        /// Height across the stroke, u ∈ [−1, 1]: bump A(1+cos πu)/2, ridge A(1−|u|), crease −D(1−|u|), scratch (groove with lips), step A·S((u+1)/2) (closed paths only: raises the inside), custom (samples_px).
        pub profile: ProfileKind = ProfileKind::Bump => choice,
        /// Amplitude: the height A of bump, ridge and step, the depth D of crease and scratch (negative inverts).
        pub height_px: f64 = 2.0 => float.unit("px").range(-10_000.0, 10_000.0).soft(-8.0, 8.0),
        /// Custom profile: heights at equally spaced u from −1 to 1 (≥ 2 samples, linearly interpolated); an open path needs equal first and last samples.
        pub samples_px: Vec<f64> = vec![0.0, 1.0, 0.0] => profile.unit("px"),
        /// Length over which an open path's relief fades in and out at its ends.
        pub taper_px: f64 = 16.0 => float.unit("px").range(0.0, 10_000.0).soft(0.0, 128.0),
        /// integrable: the height at the pixel corners, each pixel's slope the averaged 2 × 2 difference of its corners (exactly a surface, curl 0); analytic: the analytic gradient at pixel centres (curl on medial axes); distance_transform: EDT of the rasterised path (integrable, no taper, no along-path variation).
        pub mode: PenMode = PenMode::Integrable => choice,
        /// Relief along the path (§VI normal textures: a stitched seam, beads, a knotted cord): factors at equally spaced points over one period, repeated along the path (periodic, linearly interpolated), multiplying the profile's relief; one value = the same relief all along.
        pub along: Vec<f64> = vec![1.0] => profile,
        /// Length of one period of along in pixels (on a closed path adjusted so that a whole number of periods fits).
        pub along_period_px: f64 = 16.0 => float.unit("px").range(0.5, 10_000.0).soft(2.0, 128.0).log(),
        /// A relief varying across and along the path, added to the profile (§VI normal textures): none, rope (twisted strands, one twist per along_period_px), texture (the texture input: columns across the stroke, rows over one period). Not in distance_transform mode.
        pub pattern: PenPattern = PenPattern::None => choice,
        /// Rope: depth of the grooves between strands (negative raises them). Texture: the height of a texture value of 1.
        pub pattern_height_px: f64 = 0.5 => float.unit("px").range(-10_000.0, 10_000.0).soft(-4.0, 4.0),
        /// Rope: number of strands.
        pub pattern_strands: i64 = 3 => int.range(1.0, 64.0).soft(1.0, 12.0),
    }
}

impl PenParams {
    /// The profile across the stroke.
    #[must_use]
    pub fn shape(&self) -> Profile {
        let a = self.height_px as f32;
        match self.profile {
            ProfileKind::Bump => Profile::Bump { height_px: a },
            ProfileKind::Ridge => Profile::Ridge { height_px: a },
            ProfileKind::Crease => Profile::Crease { depth_px: a },
            ProfileKind::Scratch => Profile::Scratch { depth_px: a },
            ProfileKind::Step => Profile::Step { height_px: a },
            ProfileKind::Custom => Profile::Custom {
                samples_px: self.samples_px.iter().map(|v| *v as f32).collect(),
            },
        }
    }

    /// These parameters with the profile `profile`.
    #[must_use]
    pub fn with_profile(mut self, profile: &Profile) -> Self {
        let (kind, a) = match profile {
            Profile::Bump { height_px } => (ProfileKind::Bump, *height_px),
            Profile::Ridge { height_px } => (ProfileKind::Ridge, *height_px),
            Profile::Crease { depth_px } => (ProfileKind::Crease, *depth_px),
            Profile::Scratch { depth_px } => (ProfileKind::Scratch, *depth_px),
            Profile::Step { height_px } => (ProfileKind::Step, *height_px),
            Profile::Custom { samples_px } => {
                self.samples_px = samples_px.iter().map(|v| f64::from(*v)).collect();
                (ProfileKind::Custom, self.height_px as f32)
            }
        };
        self.profile = kind;
        self.height_px = f64::from(a);
        self
    }

    /// The path vertices as `f32`.
    fn points_f32(&self) -> Vec<[f32; 2]> {
        self.points.iter().map(|p| p.map(|v| v as f32)).collect()
    }

    /// Checks every parameter, including the open-path level condition of the module docs;
    /// errors name these parameters.
    pub fn validate(&self) -> Result<(), RgbnError> {
        self.validate_inner().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "depth_px" => {
                RgbnError::param("height_px", detail)
            }
            other => other,
        })
    }

    fn validate_inner(&self) -> Result<(), RgbnError> {
        let points = self.points_f32();
        let (width_px, taper_px) = (self.width_px as f32, self.taper_px as f32);
        check_points("points", &points, if self.closed { 3 } else { 2 })?;
        let pl = Polyline::new(&points, self.closed);
        if pl.length_px() <= 0.0 {
            return Err(RgbnError::param(
                "points",
                "the path has zero length (all points coincide)",
            ));
        }
        if self.closed && !pl.is_closed() {
            return Err(RgbnError::param(
                "points",
                "a closed path needs at least 3 distinct points",
            ));
        }
        if self.closed {
            let pts: Vec<[f64; 2]> = points.iter().map(|p| p.map(f64::from)).collect();
            if let Some(c) = closed_path_crossing(&pts) {
                let n = pts.len();
                return Err(RgbnError::param(
                    "points",
                    format!(
                        "the closed path crosses itself: segment {} (points {} → {}) meets \
                         segment {} (points {} → {}) at ({:.1}, {:.1}); the inside of a closed \
                         path is defined only when it does not cross itself (§VI): move the \
                         points apart, or draw two paths",
                        c.first,
                        c.first,
                        (c.first + 1) % n,
                        c.second,
                        c.second,
                        (c.second + 1) % n,
                        c.at[0],
                        c.at[1]
                    ),
                ));
            }
        }
        if !(width_px.is_finite() && width_px > 0.0 && width_px <= MAX_PEN_PX) {
            return Err(RgbnError::param(
                "width_px",
                format!("{width_px} must be in (0, {MAX_PEN_PX}] pixels"),
            ));
        }
        if !(taper_px.is_finite() && (0.0..=MAX_PEN_PX).contains(&taper_px)) {
            return Err(RgbnError::param(
                "taper_px",
                format!("{taper_px} must be in [0, {MAX_PEN_PX}] pixels"),
            ));
        }
        if self.along.is_empty() || self.along.iter().any(|v| !v.is_finite() || v.abs() > 1e6) {
            return Err(RgbnError::param(
                "along",
                "needs at least one finite factor (|factor| ≤ 1e6)",
            ));
        }
        if !(self.along_period_px.is_finite() && self.along_period_px > 0.0) {
            return Err(RgbnError::param(
                "along_period_px",
                format!("{} must be a finite length > 0", self.along_period_px),
            ));
        }
        if !(self.pattern_height_px.is_finite() && self.pattern_height_px.abs() <= 10_000.0) {
            return Err(RgbnError::param(
                "pattern_height_px",
                format!(
                    "{} must be finite, in [-10000, 10000] pixels",
                    self.pattern_height_px
                ),
            ));
        }
        if !(1..=64).contains(&self.pattern_strands) {
            return Err(RgbnError::param(
                "pattern_strands",
                format!("{} must be between 1 and 64", self.pattern_strands),
            ));
        }
        if self.pattern != PenPattern::None && self.mode == PenMode::DistanceTransform {
            return Err(RgbnError::param(
                "pattern",
                "the distance_transform mode has no coordinate along the path: use the \
                 integrable or analytic mode for a pattern, or set pattern: none",
            ));
        }
        let profile = self.shape();
        profile.validate()?;
        if !self.closed {
            let (lo, hi) = (profile.eval(-1.0).0, profile.eval(1.0).0);
            let scale = lo.abs().max(hi.abs()).max(1.0);
            if (hi - lo).abs() > 1e-6 * scale {
                return Err(RgbnError::param(
                    "profile",
                    format!(
                        "an open path needs h(-1) = h(1) (∫h'du = 0, no level change outside \
                         the stroke), got h(-1) = {lo}, h(1) = {hi}; step/level-change profiles \
                         are only valid on closed paths"
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The pen's relief: gradients to add to an image's gradients, and the height that they are
/// the gradient of (pixel centres, `f(−1)` far from the stroke).
#[derive(Clone, Debug, PartialEq)]
pub struct PenOutput {
    pub gradients: GradientField,
    pub height: Plane,
}

struct Stroke<'a> {
    pl: Polyline,
    half_w: f64,
    taper: f64,
    profile: &'a Profile,
    f0: f64,
    closed: bool,
    along: Along,
    detail: Option<Detail<'a>>,
}

/// Largest side of a pen texture (it holds one period of a pattern, not an image).
pub const MAX_TEXTURE_SIDE: usize = 1024;

/// A pattern `T(u, v)` added to the profile (module docs, "Patterns along the path"), zero at
/// the stroke's edges `u = ±1`.
#[derive(Clone, Debug)]
enum Detail<'a> {
    /// Twisted strands: `depth` (px), `strands`, over `period` px of path.
    Rope { depth: f64, strands: f64 },
    /// A height image, `w` columns across (u = −1 … 1) and `h` rows along one period,
    /// row-major, scaled by `scale` px and pinned to zero at its first and last columns as it
    /// is sampled (the region evaluator runs the pen tile by tile: nothing is copied per tile).
    Texture {
        t: &'a [f32],
        w: usize,
        h: usize,
        scale: f64,
    },
}

impl<'a> Detail<'a> {
    /// The pattern of `params` (`texture`: the `texture` input), `None` for no pattern.
    fn new(params: &PenParams, texture: Option<&'a Plane>) -> Result<Option<Self>, RgbnError> {
        match (params.pattern, texture) {
            (PenPattern::None | PenPattern::Rope, Some(_)) => Err(RgbnError::param(
                "texture",
                "the texture input is connected but pattern is not texture: set pattern: \
                 texture to use it, or disconnect it",
            )),
            (PenPattern::None, None) => Ok(None),
            (PenPattern::Rope, None) => Ok(Some(Detail::Rope {
                depth: params.pattern_height_px,
                strands: params.pattern_strands as f64,
            })),
            (PenPattern::Texture, None) => Err(RgbnError::param(
                "texture",
                "pattern is texture but nothing is connected to the texture input: connect a \
                 small height image (a scalar field) to it",
            )),
            (PenPattern::Texture, Some(tex)) => {
                let (w, h) = (tex.width(), tex.height());
                if w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE || w == 0 || h == 0 {
                    return Err(RgbnError::param(
                        "texture",
                        format!(
                            "is {w}×{h}: a pen texture holds one period of a pattern, between \
                             1×1 and {MAX_TEXTURE_SIDE}×{MAX_TEXTURE_SIDE} pixels"
                        ),
                    ));
                }
                let data = tex.data();
                if let Some(i) = data.iter().position(|v| !v.is_finite()) {
                    return Err(RgbnError::param(
                        "texture",
                        format!("pixel ({}, {}) is not a finite height", i % w, i / w),
                    ));
                }
                Ok(Some(Detail::Texture {
                    t: data,
                    w,
                    h,
                    scale: params.pattern_height_px,
                }))
            }
        }
    }

    /// `(T, ∂T/∂u, ∂T/∂v)` at `u ∈ [−1, 1]` and arclength `v`, the pattern repeating every
    /// `period` px.
    fn eval(&self, u: f64, v: f64, period: f64) -> (f64, f64, f64) {
        let u = u.clamp(-1.0, 1.0);
        let theta = (v / period).rem_euclid(1.0);
        match self {
            Detail::Rope { depth, strands } => {
                // A strand is a helix around the stroke: seen from above, the groove between
                // two strands at phase ψ = S(θ − asin(u)/2π) ∈ ℤ. Its depth profile across a
                // strand is sin(π·frac ψ) − 1, windowed by (1 − u²)² to vanish at the edges.
                let s1 = (1.0 - u * u).max(0.0);
                let psi = strands * (theta - u.asin() / std::f64::consts::TAU);
                let x = psi.rem_euclid(1.0);
                let (sn, cs) = (PI * x).sin_cos();
                let g = sn - 1.0;
                let dg = PI * cs;
                let win = s1 * s1;
                let dwin = -4.0 * u * s1;
                // w·∂ψ/∂u = −S/2π · (1 − u²)^{3/2} (finite at u = ±1).
                let w_dpsi_du = -strands / std::f64::consts::TAU * s1 * s1.sqrt();
                let t = depth * win * g;
                let dt_du = depth * (dwin * g + dg * w_dpsi_du);
                let dt_dv = depth * win * dg * strands / period;
                (t, dt_du, dt_dv)
            }
            Detail::Texture { t, w, h, scale } => {
                let (w, h) = (*w, *h);
                if w < 2 {
                    // One column is both edges: pinned to zero.
                    return (0.0, 0.0, 0.0);
                }
                // Columns at u_c = −1 + 2c/(w−1); rows at θ_r = r/h, wrapping.
                let cx = (u + 1.0) / 2.0 * (w - 1) as f64;
                let c0 = (cx.floor() as usize).min(w - 2);
                let fx = cx - c0 as f64;
                let ry = theta * h as f64;
                let r0 = (ry.floor() as usize).min(h - 1);
                let r1 = (r0 + 1) % h;
                let fy = ry - r0 as f64;
                // Pinned: the line between the row's first and last values is subtracted, so
                // the relief meets the surface at the stroke's edges.
                let at = |r: usize, c: usize| {
                    let row = &t[r * w..(r + 1) * w];
                    let (first, last) = (f64::from(row[0]), f64::from(row[w - 1]));
                    let edge = first + (last - first) * c as f64 / (w - 1) as f64;
                    scale * (f64::from(row[c]) - edge)
                };
                let (a, b) = (at(r0, c0), at(r0, c0 + 1));
                let (c, d) = (at(r1, c0), at(r1, c0 + 1));
                let top = a + (b - a) * fx;
                let bottom = c + (d - c) * fx;
                let value = top + (bottom - top) * fy;
                let d_dcx = (b - a) + ((d - c) - (b - a)) * fy;
                let d_dry = bottom - top;
                (
                    value,
                    d_dcx * (w - 1) as f64 / 2.0,
                    d_dry * h as f64 / period,
                )
            }
        }
    }
}

/// The periodic factor `m(v)` along the path (module docs, "Along the path").
#[derive(Clone, Debug)]
struct Along {
    factors: Vec<f64>,
    period: f64,
}

impl Along {
    /// From the parameters; on a closed path of length `l` the period becomes `l / round(l /
    /// period)` so that `m` closes without a seam.
    fn new(params: &PenParams, l: f64) -> Self {
        let mut period = params.along_period_px;
        if params.closed && l > 0.0 {
            period = l / (l / period).round().max(1.0);
        }
        Self {
            factors: params.along.clone(),
            period,
        }
    }

    /// `(m(v), m′(v))`.
    fn eval(&self, v: f64) -> (f64, f64) {
        let n = self.factors.len();
        if n == 1 {
            return (self.factors[0], 0.0);
        }
        let t = (v / self.period).rem_euclid(1.0) * n as f64;
        let k = (t.floor() as usize).min(n - 1);
        let (a, b) = (self.factors[k], self.factors[(k + 1) % n]);
        let fr = t - k as f64;
        (a + (b - a) * fr, (b - a) * n as f64 / self.period)
    }
}

impl Stroke<'_> {
    /// The relief across and along the stroke, `(f, ∂f/∂u, ∂f/∂v)`: the profile plus the
    /// pattern.
    fn shape(&self, u: f64, v: f64) -> (f64, f64, f64) {
        let (f, df) = self.profile.eval(u);
        match &self.detail {
            None => (f, df, 0.0),
            Some(d) => {
                let (t, dtu, dtv) = d.eval(u, v, self.along.period);
                (f + t, df + dtu, dtv)
            }
        }
    }

    /// Sign σ and (height, gradient in y-up) at pixel coordinates `(x, row)`.
    fn eval(&self, x: f64, row: f64, segs: &[u32]) -> (f64, [f64; 2]) {
        let Some(pr) = self
            .pl
            .project_among([x, row], segs.iter().map(|&i| i as usize))
        else {
            return (self.f0, [0.0, 0.0]);
        };
        let d = pr.dist_px;
        let sigma = if self.closed {
            if self.pl.contains([x, row]) {
                1.0
            } else {
                -1.0
            }
        } else if pr.side >= 0.0 {
            1.0
        } else {
            -1.0
        };
        let u = sigma * d / self.half_w;
        if u.abs() >= 1.0 {
            // Outside the stroke: f₀ beside an open path (f(1) = f(−1) = f₀ up to the
            // tolerance of `validate`, taken exactly so no side switches show), f(±1) inside
            // or outside a closed one.
            let level = if self.closed {
                self.profile.eval(u.signum()).0
            } else {
                self.f0
            };
            return (level, [0.0, 0.0]);
        }
        if let Some(cap) = self.end_cap(&pr) {
            return cap;
        }
        let (f, df, dfv) = self.shape(u, pr.arclength_px);
        let (t, dt) = if self.closed || self.taper <= 0.0 {
            (1.0, 0.0)
        } else {
            let (v, l, tau) = (pr.arclength_px, self.pl.length_px(), self.taper);
            let (a, b) = (smoothstep(0.0, tau, v), smoothstep(0.0, tau, l - v));
            let (da, db) = (
                smoothstep_deriv(0.0, tau, v),
                smoothstep_deriv(0.0, tau, l - v),
            );
            (a * b, da * b - a * db)
        };
        // The factor along the path folds into the taper: t·m and (t·m)′ = t′m + t m′.
        let (m, dm) = self.along.eval(pr.arclength_px);
        let (t, dt) = (t * m, dt * m + t * dm);
        let h = self.f0 + t * (f - self.f0);
        // ∇u (y-up): σ (P − C)/|P − C| / half_w.
        let grad_u = if d > 1e-12 {
            let (ox, oy) = ((x - pr.closest[0]) / d, -(row - pr.closest[1]) / d);
            [sigma * ox / self.half_w, sigma * oy / self.half_w]
        } else {
            // On the path: the left normal (y-up (t_row, t_x)) for open paths; for closed
            // paths the normal pointing inside (σ = +1 there), whatever the orientation.
            let n = [pr.tangent[1], pr.tangent[0]];
            let flip = self.closed && !self.pl.contains([x + 1e-3 * n[0], row - 1e-3 * n[1]]);
            let s = if flip { -1.0 } else { 1.0 };
            [s * n[0] / self.half_w, s * n[1] / self.half_w]
        };
        let grad_v = if pr.interior {
            [pr.tangent[0], -pr.tangent[1]]
        } else {
            [0.0, 0.0]
        };
        let k = dt * (f - self.f0) + t * dfv;
        (
            h,
            [
                t * df * grad_u[0] + k * grad_v[0],
                t * df * grad_u[1] + k * grad_v[1],
            ],
        )
    }
}

impl Stroke<'_> {
    /// Height and y-up gradient beyond an end of an open path (module docs, "End caps"), or
    /// `None` where the closest point is not an end. `pr` is the projection of a point within
    /// `W/2` of the path.
    fn end_cap(&self, pr: &super::geom::Projection) -> Option<(f64, [f64; 2])> {
        let l = self.pl.length_px();
        if self.closed || pr.interior || l <= 0.0 {
            return None;
        }
        // Outward along the path at this end: −tangent at the start, +tangent at the end.
        let out = if pr.arclength_px <= 0.0 {
            -1.0
        } else if pr.arclength_px >= l {
            1.0
        } else {
            return None;
        };
        let [tx, trow] = pr.tangent;
        // `side` is the signed distance to the path's line (continuous across its extension);
        // `a` the distance beyond the end along it: d² = a² + side².
        let perp = pr.side;
        let a = (pr.dist_px * pr.dist_px - perp * perp).max(0.0).sqrt();
        let r = self.half_w;
        let dd = (r * r - perp * perp).max(1e-300);
        let sd = dd.sqrt();
        let k = (1.0 - a / sd).max(0.0);
        let u = (perp / r).clamp(-1.0, 1.0);
        // The pattern at the end's arclength (constant over the cap, as the along factor).
        let (f, df, _) = self.shape(u, pr.arclength_px);
        // The taper at this end (0 when tapered, so the cap is flat there).
        let t = if self.taper <= 0.0 {
            1.0
        } else {
            let (v, tau) = (pr.arclength_px, self.taper);
            smoothstep(0.0, tau, v) * smoothstep(0.0, tau, l - v)
        };
        // The factor along the path at this end (constant over the cap: v is the end's).
        let t = t * self.along.eval(pr.arclength_px).0;
        let h = self.f0 + t * k * (f - self.f0);
        if k <= 0.0 {
            return Some((h, [0.0, 0.0]));
        }
        // y-up gradients: ∇perp = (t_row, t_x) (the left normal), ∇a = out · (t_x, −t_row).
        let g_perp = [trow, tx];
        let g_a = [out * tx, -out * trow];
        // k = 1 − a/√D, D = R² − perp²: ∂k/∂a = −1/√D, ∂k/∂perp = −a·perp/D^{3/2}.
        let dk_da = -1.0 / sd;
        let dk_dp = -a * perp / (dd * sd);
        let df_dp = df / r;
        let c_p = t * (df_dp * k + (f - self.f0) * dk_dp);
        let c_a = t * (f - self.f0) * dk_da;
        Some((
            h,
            [
                c_p * g_perp[0] + c_a * g_a[0],
                c_p * g_perp[1] + c_a * g_a[1],
            ],
        ))
    }
}

/// The pen's gradient field and height on a `width × height` image (module docs).
pub fn pen_field(width: usize, height: usize, params: &PenParams) -> Result<PenOutput, RgbnError> {
    pen_field_with(width, height, params, None)
}

/// [`pen_field`] with the `texture` input of the texture pattern.
pub fn pen_field_with(
    width: usize,
    height: usize,
    params: &PenParams,
    texture: Option<&Plane>,
) -> Result<PenOutput, RgbnError> {
    params.validate()?;
    crate::raster::check_size(width, height, "pen")?;
    let detail = Detail::new(params, texture)?;
    let profile = params.shape();
    // Lengths as f32, as the node always passed them (same results as before).
    let pl = Polyline::new(&params.points_f32(), params.closed);
    let along = Along::new(params, pl.length_px());
    let stroke = Stroke {
        pl,
        half_w: f64::from(params.width_px as f32) / 2.0,
        taper: f64::from(params.taper_px as f32),
        profile: &profile,
        f0: profile.eval(-1.0).0,
        closed: params.closed,
        along,
        detail,
    };
    match params.mode {
        PenMode::Analytic | PenMode::Integrable => {
            // Only pixels within the half width of a segment are in the stroke: each is
            // projected onto the segments near its 16-pixel cell only.
            let grid = SegmentGrid::new(
                &stroke.pl,
                stroke.half_w + 1.0,
                [-1.0, -1.0, width as f64 + 1.0, height as f64 + 1.0],
                16.0,
            );
            let outside_level = |x: f64, r: f64| {
                if stroke.closed && stroke.pl.contains([x, r]) {
                    profile.eval(1.0).0
                } else {
                    stroke.f0
                }
            };
            let height_at = |x: f64, r: f64| {
                let segs = grid.at(x, r);
                if segs.is_empty() {
                    outside_level(x, r)
                } else {
                    stroke.eval(x, r, segs).0
                }
            };
            if params.mode == PenMode::Analytic {
                let height_plane =
                    Plane::from_fn(width, height, |x, r| height_at(x as f64, r as f64) as f32);
                let gradients = sample_gradient_centres(width, height, |x, r| {
                    let segs = grid.at(x, r);
                    if segs.is_empty() {
                        [0.0, 0.0]
                    } else {
                        stroke.eval(x, r, segs).1
                    }
                });
                return Ok(PenOutput {
                    gradients,
                    height: height_plane,
                });
            }
            // Integrable: the height at the pixel corners, (p, q) from each pixel's four
            // corners — exactly a surface under the averaged model, its height the corner mean.
            let zc = corner_samples(width, height, |x, r| {
                height_at(x as f64 - 0.5, r as f64 - 0.5)
            });
            let (gradients, height_plane) = GradientField::from_corner_heights(width, height, &zc);
            Ok(PenOutput {
                gradients,
                height: height_plane,
            })
        }
        PenMode::DistanceTransform => {
            let mut seeds = vec![false; width * height];
            for p in stroke.pl.densify(0.25) {
                let (x, r) = (p[0].round(), p[1].round());
                if x >= 0.0 && r >= 0.0 && (x as usize) < width && (r as usize) < height {
                    seeds[r as usize * width + x as usize] = true;
                }
            }
            let dist = distance_transform(&seeds, width, height);
            let mut z = dist.into_vec();
            z.par_chunks_mut(width).enumerate().for_each(|(r, row)| {
                for (x, v) in row.iter_mut().enumerate() {
                    let d = f64::from(*v);
                    let sigma = if stroke.closed && !stroke.pl.contains([x as f64, r as f64]) {
                        -1.0
                    } else {
                        1.0
                    };
                    let u = if d.is_finite() {
                        sigma * d / stroke.half_w
                    } else {
                        sigma
                    };
                    *v = profile.eval(u.clamp(-1.0, 1.0)).0 as f32;
                }
            });
            let (gradients, height_plane) =
                GradientField::of_height(&Plane::from_vec(width, height, z)?);
            Ok(PenOutput {
                gradients,
                height: height_plane,
            })
        }
    }
}

/// What [`apply_pen`] made and measured.
#[derive(Clone, Debug, PartialEq)]
pub struct PenReport {
    /// The pen's height in pixels (its gradients are what was added).
    pub height: Plane,
    /// Curl of the pen's own field (≈ 0 away from the medial axis; see module docs).
    pub curl_pen: CurlStats,
    /// Curl of the edited image's gradients.
    pub curl_after: CurlStats,
}

/// Adds the pen's relief to an image's gradients (colour and mask kept); the report holds the
/// pen's height.
pub fn apply_pen(img: &RgbnImage, params: &PenParams) -> Result<(RgbnImage, PenReport), RgbnError> {
    apply_pen_with(img, params, None)
}

/// [`apply_pen`] with the `texture` input of the texture pattern.
pub fn apply_pen_with(
    img: &RgbnImage,
    params: &PenParams,
    texture: Option<&Plane>,
) -> Result<(RgbnImage, PenReport), RgbnError> {
    let pen = pen_field_with(img.width(), img.height(), params, texture)?;
    Ok(add_relief(img, pen))
}

/// `img` with `pen`'s gradients added to its own (colour and mask kept), and the report: the
/// curl of the pen's field and of the result, the pen's height.
pub(super) fn add_relief(img: &RgbnImage, pen: PenOutput) -> (RgbnImage, PenReport) {
    let mut g = GradientField::from_normals(img);
    g.p.par_iter_mut()
        .zip(pen.gradients.p.par_iter())
        .for_each(|(a, b)| *a += b);
    g.q.par_iter_mut()
        .zip(pen.gradients.q.par_iter())
        .for_each(|(a, b)| *a += b);
    let mut out = img.clone();
    g.write_normals(&mut out);
    (
        out,
        PenReport {
            curl_pen: pen.gradients.curl_stats(None),
            height: pen.height,
            curl_after: g.curl_stats(img.mask()),
        },
    )
}

#[cfg(test)]
#[path = "pen_tests.rs"]
mod tests;
