//! Rendering nodes: relighting ([`crate::render::relight`]) and the views of
//! [`crate::render::View`] (albedo, normals as colour, curl map and the inspection views),
//! producing display pictures.

use super::{Footprint, Inputs, OpSpec, Operator, Picture, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::render::{RelightParams, ViewParams};
use crate::render::{self, View};
use std::sync::Arc;

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
    fn footprint(_: &RelightParams, _input: usize) -> Footprint {
        Footprint::POINT
    }
    fn scaled(p: &RelightParams, _: f64) -> Option<RelightParams> {
        Some(p.clone())
    }
    fn run(p: &RelightParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let rgba = render::relight(img, &p.shading())?;
        Ok(vec![picture(img.width(), img.height(), rgba)])
    }
}

/// The view node's documentation: what it does, then every view with its reference.
fn view_doc() -> &'static str {
    static DOC: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    DOC.get_or_init(|| {
        let views: Vec<String> = View::ALL
            .iter()
            .map(|v| format!("{}: {}", v.name(), v.doc()))
            .collect();
        format!(
            "A picture of an image for inspection: albedo, normals as colour, curl, mean curvature, exaggerated shading, radiance scaling, specular enhancement, normal unsharp masking, toon shading, lines, ambient occlusion or multi-light detail enhancement (each view's parameters are prefixed by its short name; the light parameters are used by the views that light the image). Views — {}",
            views.join(" ")
        )
    })
}

/// A view of an image (any [`View`]).
pub struct ViewOp;

impl Operator for ViewOp {
    type Params = ViewParams;
    fn spec() -> OpSpec {
        OpSpec::new("view", "View", "render", view_doc())
            .input(PortSpec::new("image", PortType::Rgbn, "Image to show."))
            .output(PortSpec::new("picture", PortType::Picture, "The view."))
    }
    fn check(p: &ViewParams) -> Result<(), RgbnError> {
        if p.view.lit() {
            p.shading.shading().validate()?;
        }
        p.inspect.validate()
    }
    fn run(p: &ViewParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let rgba = render::render_with(img, p.view, &p.shading.shading(), &p.inspect)?;
        Ok(vec![picture(img.width(), img.height(), rgba)])
    }
}
