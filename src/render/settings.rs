//! The lighting settings shared by the relight node and the published viewer.

use super::{Light, Shading};

crate::params! {
    /// One directional white light and its shading: the relight node's parameters and the
    /// published viewer's initial lighting.
    #[derive(Clone, Debug, PartialEq)]
    pub struct LightSettings {
        /// Direction towards the light (+x right, +y up, +z to the viewer).
        pub light: [f64; 3] = Shading::default().lights[0].direction.map(f64::from)
            => vec3.range(-1e3, 1e3),
        /// Ambient light added to the diffuse term.
        pub ambient: f64 = f64::from(Shading::default().ambient) => float.range(0.0, 10.0).soft(0.0, 1.0),
        /// Blinn-Phong specular strength (0 = Lambert only).
        pub specular: f64 = f64::from(Shading::default().specular) => float.range(0.0, 10.0).soft(0.0, 2.0),
        /// Blinn-Phong exponent.
        pub shininess: f64 = f64::from(Shading::default().shininess)
            => float.range(0.0, 10000.0).soft(1.0, 1000.0).log(),
        /// Exposure.
        pub exposure_ev: f64 = f64::from(Shading::default().exposure_ev)
            => float.unit("EV").range(-32.0, 32.0).soft(-8.0, 8.0),
    }
}

impl LightSettings {
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
