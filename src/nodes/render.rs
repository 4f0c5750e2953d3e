//! Rendering nodes: relighting ([`crate::render::relight`]) and the diagnostic views (albedo,
//! normals as colour, curl map), producing display pictures.

use super::{Inputs, OpSpec, Operator, Picture, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::render::{RelightParams, ViewParams};
use crate::render::{self, Shading};
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
    fn run(p: &RelightParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let rgba = render::relight(img, &p.shading())?;
        Ok(vec![picture(img.width(), img.height(), rgba)])
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
        let rgba = render::render(img, p.view.view(), &Shading::default())?;
        Ok(vec![picture(img.width(), img.height(), rgba)])
    }
}
