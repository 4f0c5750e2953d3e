//! Parameters of the render nodes ([`crate::nodes::render`]); the renderers themselves are
//! [`crate::render::relight`] and [`crate::render::render`].

use crate::ops::params::{visit_choice, Meta, ParamVisitor, Params};
use crate::render::{InspectParams, Light, Shading, View};

crate::params! {
    /// Parameters of relighting with one directional white light.
    #[derive(Clone, Debug, PartialEq)]
    pub struct RelightParams {
        /// Direction towards the light (+x right, +y up, +z to the viewer).
        pub light: [f64; 3] = Shading::default().lights[0].direction.map(f64::from)
            => vec3.range(-1e3, 1e3),
        /// Ambient light added to the diffuse term.
        pub ambient: f64 = f64::from(Shading::default().ambient) => float.range(0.0, 10.0),
        /// Blinn-Phong specular strength (0 = Lambert only).
        pub specular: f64 = f64::from(Shading::default().specular) => float.range(0.0, 10.0),
        /// Blinn-Phong exponent.
        pub shininess: f64 = f64::from(Shading::default().shininess)
            => float.range(0.0, 10000.0),
        /// Exposure.
        pub exposure_ev: f64 = f64::from(Shading::default().exposure_ev)
            => float.unit("EV").range(-32.0, 32.0),
    }
}

impl RelightParams {
    /// The shading these parameters describe.
    #[must_use]
    pub fn shading(&self) -> Shading {
        Shading {
            lights: vec![Light::white(self.light.map(|c| c as f32))],
            ambient: self.ambient as f32,
            specular: self.specular as f32,
            shininess: self.shininess as f32,
            exposure_ev: self.exposure_ev as f32,
        }
    }
}

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
