//! The pen of [`super::pen`] as a node: sculpt a relief along an open or closed path with a
//! profile ([`pen_field`], added like [`super::pen::apply_pen`]).

use super::node_kit::curl_port;
use super::params::{Meta, ParamVisitor, Params};
use super::pen::{pen_field, PenMode, PenParams, Profile};
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::raster::gradient::GradientField;
use rayon::prelude::*;
use std::sync::Arc;

/// Profile names.
pub const PROFILES: [&str; 6] = ["bump", "ridge", "crease", "scratch", "step", "custom"];
/// Mode names, in [`PenMode`] order.
pub const PEN_MODES: [&str; 3] = ["integrable", "analytic", "distance_transform"];

/// Parameters of [`PenNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct PenNodeParams {
    /// Path `(x, row)`.
    pub points: Vec<[f64; 2]>,
    /// Closed path.
    pub closed: bool,
    /// Stroke width.
    pub width_px: f64,
    /// Profile name ([`PROFILES`]).
    pub profile: &'static str,
    /// Height (bump, ridge, step) or depth (crease, scratch).
    pub height_px: f64,
    /// Custom profile samples.
    pub samples_px: Vec<f64>,
    /// End taper.
    pub taper_px: f64,
    /// Mode name ([`PEN_MODES`]).
    pub mode: &'static str,
}

impl Default for PenNodeParams {
    fn default() -> Self {
        let d = PenParams::default();
        Self {
            points: d.points.iter().map(|p| p.map(f64::from)).collect(),
            closed: d.closed,
            width_px: f64::from(d.width_px),
            profile: "bump",
            height_px: 2.0,
            samples_px: vec![0.0, 1.0, 0.0],
            taper_px: f64::from(d.taper_px),
            mode: "integrable",
        }
    }
}

impl Params for PenNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.points(
            "points",
            &mut self.points,
            &Meta::new("Path vertices in pixels (x, row): ≥ 2 for an open path, ≥ 3 distinct for a closed one.")
                .unit("px"),
        );
        v.bool(
            "closed",
            &mut self.closed,
            &Meta::new("Join the last point back to the first; the profile's inside is then the enclosed region."),
        );
        v.float(
            "width_px",
            &mut self.width_px,
            &Meta::new("Full stroke width (u = ±1 at ±width/2).")
                .unit("px")
                .range(0.01, 10_000.0),
        );
        v.choice(
            "profile",
            &mut self.profile,
            &PROFILES,
            &Meta::new("Height across the stroke, u ∈ [−1, 1]: bump A(1+cos πu)/2, ridge A(1−|u|), crease −D(1−|u|), scratch (groove with lips), step A·S((u+1)/2) (closed paths only: raises the inside), custom (samples_px)."),
        );
        v.float(
            "height_px",
            &mut self.height_px,
            &Meta::new("Amplitude: the height A of bump, ridge and step, the depth D of crease and scratch (negative inverts).")
                .unit("px")
                .range(-10_000.0, 10_000.0),
        );
        v.profile(
            "samples_px",
            &mut self.samples_px,
            &Meta::new("Custom profile: heights at equally spaced u from −1 to 1 (≥ 2 samples, linearly interpolated); an open path needs equal first and last samples.")
                .unit("px"),
        );
        v.float(
            "taper_px",
            &mut self.taper_px,
            &Meta::new("Length over which an open path's relief fades in and out at its ends.")
                .unit("px")
                .range(0.0, 10_000.0),
        );
        v.choice(
            "mode",
            &mut self.mode,
            &PEN_MODES,
            &Meta::new("integrable: forward differences of the analytic height (curl 0); analytic: the analytic gradient (curl on medial axes); distance_transform: EDT of the rasterised path (integrable, no taper)."),
        );
    }
}

impl PenNodeParams {
    /// The library parameters; errors name this node's parameters.
    pub fn to_params(&self) -> Result<PenParams, RgbnError> {
        let a = self.height_px as f32;
        let profile = match self.profile {
            "ridge" => Profile::Ridge { height_px: a },
            "crease" => Profile::Crease { depth_px: a },
            "scratch" => Profile::Scratch { depth_px: a },
            "step" => Profile::Step { height_px: a },
            "custom" => Profile::Custom {
                samples_px: self.samples_px.iter().map(|v| *v as f32).collect(),
            },
            _ => Profile::Bump { height_px: a },
        };
        let mode = match self.mode {
            "analytic" => PenMode::Analytic,
            "distance_transform" => PenMode::DistanceTransform,
            _ => PenMode::Integrable,
        };
        let p = PenParams {
            points: self.points.iter().map(|p| p.map(|v| v as f32)).collect(),
            closed: self.closed,
            width_px: self.width_px as f32,
            profile,
            taper_px: self.taper_px as f32,
            mode,
        };
        p.validate().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "depth_px" => {
                RgbnError::param("height_px", detail)
            }
            other => other,
        })?;
        Ok(p)
    }
}

/// Pen.
pub struct PenNode;

impl Operator for PenNode {
    type Params = PenNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "pen",
            "Pen",
            "draw",
            "Sculpts a relief along a path (Pereira & Velho §V–VI): a profile across an open or closed polyline, added to the image's gradients. Open paths must end at the level they start (bump, ridge, crease, scratch); a step raises the inside of a closed path.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to draw on."))
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Image with the relief added; colour and mask unchanged.",
        ))
        .output(PortSpec::new(
            "height",
            PortType::Scalar,
            "The pen's height in pixels (its gradients are what was added).",
        ))
        .output(curl_port("result's gradients"))
    }
    fn check(p: &PenNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(p: &PenNodeParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let pen = pen_field(img.width(), img.height(), &p.to_params()?)?;
        let mut g = GradientField::from_normals(img);
        g.p.par_iter_mut()
            .zip(pen.gradients.p.par_iter())
            .for_each(|(a, b)| *a += b);
        g.q.par_iter_mut()
            .zip(pen.gradients.q.par_iter())
            .for_each(|(a, b)| *a += b);
        let mut out = img.clone();
        g.write_normals(&mut out);
        let curl = g.curl_stats(img.mask()).relative;
        Ok(vec![
            Value::Rgbn(out),
            Value::Scalar(Arc::new(pen.height)),
            Value::Number(curl),
        ])
    }
}
