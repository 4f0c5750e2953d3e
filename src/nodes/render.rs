//! Rendering nodes: relighting ([`crate::render::relight`]) and the views of
//! [`crate::render::View`] (albedo, normals as colour, curl map and the inspection views),
//! producing display pictures.
//!
//! Parameters of the render nodes (the nodes below); the renderers themselves are
//! [`crate::render::relight`] and [`crate::render::render`].

use super::{Kind, OpSpec, Operator, Picture, RunContext};
use crate::error::RgbnError;
use crate::params::{visit_choice, Meta, ParamVisitor, Params};
use crate::render::InspectParams;
use crate::render::{self, View};
use crate::RgbnImage;
use std::sync::Arc;

/// Parameters of the relight node: one directional white light and its shading (declared
/// once in [`crate::render::LightSettings`], shared with the publisher's viewer settings).
pub use crate::render::LightSettings as RelightParams;

/// Parameters of the view node: which view, the shading of the views that light the image
/// (the relight node's parameters) and every view's own parameters ([`InspectParams`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewParams {
    /// The view shown.
    pub view: View,
    /// Light, ambient, specular, shininess and exposure (for the views that light the image).
    pub shading: RelightParams,
    /// The inspection views' parameters.
    pub inspect: InspectParams,
}

impl Default for ViewParams {
    fn default() -> Self {
        Self {
            view: View::Normals,
            shading: RelightParams::default(),
            inspect: InspectParams::default(),
        }
    }
}

impl Params for ViewParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        visit_choice(
            v,
            "view",
            &mut self.view,
            &Meta::new(
                "What to show: each view's documentation lists its reference and parameters.",
            ),
        );
        self.shading.visit(v);
        self.inspect.visit(v);
    }
}

crate::inputs! {
    /// Inputs of [`Relight`].
    pub struct RelightIn {
        /// Image to light.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`Relight`].
    pub struct RelightOut {
        /// The relit picture.
        pub picture: Arc<Picture>,
    }
}

fn picture(w: usize, h: usize, rgba: Vec<u8>) -> Arc<Picture> {
    Arc::new(Picture {
        width: w,
        height: h,
        rgba,
    })
}

/// Relights an image.
pub struct Relight;

impl Operator for Relight {
    type Params = RelightParams;
    type In = RelightIn;
    type Out = RelightOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "relight",
            "Relight",
            "render",
            "Lambert + Blinn-Phong relighting with one directional light, ambient and exposure, to an sRGB picture (masked-out pixels transparent).",
        )
    }
    fn check(p: &RelightParams) -> Result<(), RgbnError> {
        p.shading().validate()
    }
    fn kind(_: &RelightParams) -> Kind {
        Kind::POINT
    }
    fn run(p: &RelightParams, i: RelightIn, _: &RunContext) -> Result<RelightOut, RgbnError> {
        let rgba = render::relight(&i.image, &p.shading())?;
        Ok(RelightOut {
            picture: picture(i.image.width(), i.image.height(), rgba),
        })
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

crate::inputs! {
    /// Inputs of [`ViewOp`].
    pub struct ViewIn {
        /// Image to show.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`ViewOp`].
    pub struct ViewOut {
        /// The view.
        pub picture: Arc<Picture>,
    }
}

/// A view of an image (any [`View`]).
pub struct ViewOp;

impl Operator for ViewOp {
    type Params = ViewParams;
    type In = ViewIn;
    type Out = ViewOut;
    fn spec() -> OpSpec {
        OpSpec::new("view", "View", "render", view_doc())
    }
    fn check(p: &ViewParams) -> Result<(), RgbnError> {
        if p.view.lit() {
            p.shading.shading().validate()?;
        }
        p.inspect.validate()
    }
    fn kind(_: &ViewParams) -> Kind {
        // Curvature, lines, occlusion and the enhancement views read neighbourhoods of
        // different sizes (some the whole image): computed whole.
        Kind::GLOBAL
    }
    fn run(p: &ViewParams, i: ViewIn, _: &RunContext) -> Result<ViewOut, RgbnError> {
        let img = &i.image;
        let rgba = render::render_with(img, p.view, &p.shading.shading(), &p.inspect)?;
        Ok(ViewOut {
            picture: picture(img.width(), img.height(), rgba),
        })
    }
}
