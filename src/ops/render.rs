//! Parameters of the render nodes ([`crate::nodes::render`]); the renderers themselves are
//! [`crate::render::relight`] and [`crate::render::render`].

use crate::render::{Light, Shading, View};

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

crate::choice_enum! {
    /// The diagnostic views offered by the view node.
    pub enum ViewKind {
        /// Colour.
        Albedo = "albedo",
        /// Normals encoded (n+1)/2.
        Normals = "normals",
        /// Curl map, blue (−) – white – red (+).
        Curl = "curl",
    }
}

impl ViewKind {
    /// The renderer's view.
    #[must_use]
    pub fn view(self) -> View {
        match self {
            ViewKind::Albedo => View::Albedo,
            ViewKind::Normals => View::Normals,
            ViewKind::Curl => View::Curl,
        }
    }
}

crate::params! {
    /// Parameters of a diagnostic view.
    #[derive(Clone, Debug, PartialEq)]
    pub struct ViewParams {
        /// albedo: colour; normals: (n+1)/2; curl: blue (−) – white – red (+).
        pub view: ViewKind = ViewKind::Normals => choice,
    }
}
