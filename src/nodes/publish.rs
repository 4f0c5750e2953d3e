//! The `publish` node: writes the web viewer folder of [`crate::ops::publish`].

use super::{Kind, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::publish::{publish, PublishParams};
use crate::RgbnImage;
use std::path::{Path, PathBuf};

crate::inputs! {
    /// Inputs of [`PublishNode`].
    pub struct PublishIn {
        /// Image to publish.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`PublishNode`].
    pub struct PublishOut {
        /// The same image.
        pub image: RgbnImage,
    }
}

/// Writes a self-contained web folder relighting its input and passes the input through.
pub struct PublishNode;

impl Operator for PublishNode {
    type Params = PublishParams;
    type In = PublishIn;
    type Out = PublishOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "publish",
            "Publish to the web",
            "output",
            "Writes a web folder (index.html, viewer.js, rgbn.json; albedo and normals as Deep Zoom tile pyramids that OpenSeadragon and OpenLIME also read) that relights the image in any WebGL2 browser with no network access (rgbn serve DIR shows it): drag the light, zoom, pan, switch relit / normals / specular_enhancement / curvature, exposure. Replaces only an earlier publish; passes the image through.",
        )
        .side_effect()
    }
    fn check(p: &PublishParams) -> Result<(), RgbnError> {
        p.options().shading.validate()
    }
    fn kind(_: &PublishParams) -> Kind {
        // Writes the whole image.
        Kind::GLOBAL
    }
    fn run(p: &PublishParams, i: PublishIn, ctx: &RunContext) -> Result<PublishOut, RgbnError> {
        let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
        publish(&i.image, Path::new(&p.path), &p.options(), &protected)?;
        Ok(PublishOut { image: i.image })
    }
}
