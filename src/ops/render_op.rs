//! Rendering nodes: relighting ([`crate::render::relight`]) and the diagnostic views (albedo,
//! normals as colour, curl map), producing display pictures.

use super::params::{Meta, ParamVisitor, Params};
use super::{Inputs, OpSpec, Operator, Picture, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::render::{self, Light, Shading, View};
use std::sync::Arc;

/// Parameters of [`Relight`] (one directional white light).
#[derive(Clone, Debug, PartialEq)]
pub struct RelightParams {
    /// Towards the light.
    pub light: [f64; 3],
    /// Ambient term.
    pub ambient: f64,
    /// Specular strength.
    pub specular: f64,
    /// Blinn-Phong exponent.
    pub shininess: f64,
    /// Exposure in stops.
    pub exposure_ev: f64,
}

impl Default for RelightParams {
    fn default() -> Self {
        let s = Shading::default();
        let d = s.lights[0].direction;
        Self {
            light: d.map(f64::from),
            ambient: f64::from(s.ambient),
            specular: f64::from(s.specular),
            shininess: f64::from(s.shininess),
            exposure_ev: f64::from(s.exposure_ev),
        }
    }
}

impl Params for RelightParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.vec3(
            "light",
            &mut self.light,
            &Meta::new("Direction towards the light (+x right, +y up, +z to the viewer).")
                .range(-1e3, 1e3),
        );
        v.float(
            "ambient",
            &mut self.ambient,
            &Meta::new("Ambient light added to the diffuse term.").range(0.0, 10.0),
        );
        v.float(
            "specular",
            &mut self.specular,
            &Meta::new("Blinn-Phong specular strength (0 = Lambert only).").range(0.0, 10.0),
        );
        v.float(
            "shininess",
            &mut self.shininess,
            &Meta::new("Blinn-Phong exponent.").range(0.0, 10000.0),
        );
        v.float(
            "exposure_ev",
            &mut self.exposure_ev,
            &Meta::new("Exposure.").unit("EV").range(-32.0, 32.0),
        );
    }
}

impl RelightParams {
    fn shading(&self) -> Shading {
        Shading {
            lights: vec![Light::white(self.light.map(|c| c as f32))],
            ambient: self.ambient as f32,
            specular: self.specular as f32,
            shininess: self.shininess as f32,
            exposure_ev: self.exposure_ev as f32,
        }
    }
}

/// Relights an image.
pub struct Relight;

fn picture(w: usize, h: usize, rgba: Vec<u8>) -> Value {
    Value::Picture(Arc::new(Picture {
        width: w,
        height: h,
        rgba,
    }))
}

impl Operator for Relight {
    type Params = RelightParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "relight",
            "Relight",
            "render",
            "Lambert + Blinn-Phong relighting with one directional light, ambient and exposure, to an sRGB picture (masked-out pixels transparent).",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to light."))
        .output(PortSpec::new("picture", PortType::Picture, "The relit picture."))
    }
    fn check(p: &RelightParams) -> Result<(), RgbnError> {
        p.shading().validate()
    }
    fn run(p: &RelightParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let rgba = render::relight(img, &p.shading())?;
        Ok(vec![picture(img.width(), img.height(), rgba)])
    }
}

/// Parameters of [`ViewOp`].
#[derive(Clone, Debug, PartialEq)]
pub struct ViewParams {
    /// `albedo`, `normals` or `curl`.
    pub view: &'static str,
}

impl Default for ViewParams {
    fn default() -> Self {
        Self { view: "normals" }
    }
}

impl Params for ViewParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.choice(
            "view",
            &mut self.view,
            &["albedo", "normals", "curl"],
            &Meta::new("albedo: colour; normals: (n+1)/2; curl: blue (−) – white – red (+)."),
        );
    }
}

/// A diagnostic view of an image.
pub struct ViewOp;

impl Operator for ViewOp {
    type Params = ViewParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "view",
            "View",
            "render",
            "A diagnostic picture of an image: its albedo, its normals as colour, or its curl map.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to show."))
        .output(PortSpec::new("picture", PortType::Picture, "The view."))
    }
    fn run(p: &ViewParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let view = p
            .view
            .parse::<View>()
            .map_err(|e| RgbnError::param("view", e))?;
        let rgba = render::render(img, view, &Shading::default())?;
        Ok(vec![picture(img.width(), img.height(), rgba)])
    }
}
