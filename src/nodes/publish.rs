//! The `publish` node: writes the web viewer folder of [`crate::ops::publish`].

use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::publish::{publish, PublishParams};
use std::path::{Path, PathBuf};

/// Writes a self-contained web folder relighting its input and passes the input through.
pub struct PublishNode;

impl Operator for PublishNode {
    type Params = PublishParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "publish",
            "Publish to the web",
            "output",
            "Writes a self-contained folder (index.html, viewer.js, image.json, PNG textures; a tile pyramid over 4096²) that relights the image in any WebGL2 browser with no network access: drag the light, zoom, pan, switch relit / normals / specular_enhancement / curvature, exposure. Replaces only an earlier publish; passes the image through.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to publish."))
        .output(PortSpec::new("image", PortType::Rgbn, "The same image."))
        .side_effect()
    }
    fn check(p: &PublishParams) -> Result<(), RgbnError> {
        if p.path.is_empty() {
            return Err(RgbnError::param("path", "a folder path is required"));
        }
        p.options().shading.validate()
    }
    fn run(p: &PublishParams, i: &Inputs<'_>, ctx: &RunContext) -> Result<Vec<Value>, RgbnError> {
        Self::check(p)?;
        let img = i.rgbn("image")?;
        let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
        publish(img, Path::new(&p.path), &p.options(), &protected)?;
        Ok(vec![Value::Rgbn(img.clone())])
    }
}
