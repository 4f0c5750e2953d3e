//! Parameters of the source nodes ([`crate::nodes::load`]) that have choices; the images come
//! from [`crate::raster::io`] and [`crate::raster::sample`].

use crate::raster::sample::Surface;

crate::choice_enum! {
    /// The analytic surfaces offered by the `surface` node.
    pub enum SurfaceShape {
        /// A spherical cap of radius `radius_px`.
        Sphere = "sphere",
        /// `z = −curvature·(u² + v²)`.
        Paraboloid = "paraboloid",
        /// A sinusoid of `amplitude_px` and `period_px`.
        Sinusoid = "sinusoid",
        /// Three Gaussian bumps scaled to the image.
        Gaussians = "gaussians",
    }
}

crate::params! {
    /// Parameters of the analytic-surface source.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SurfaceParams {
        /// Which analytic surface (gaussians: three bumps scaled to the image).
        pub shape: SurfaceShape = SurfaceShape::Sphere => choice,
        /// Image size.
        pub width: i64 = 128 => int.unit("px").range(1.0, 16384.0),
        /// Image size.
        pub height: i64 = 128 => int.unit("px").range(1.0, 16384.0),
        /// Sphere radius.
        pub radius_px: f64 = 48.0 => float.unit("px").range(0.5, 1e5),
        /// Paraboloid z = −curvature·(u² + v²).
        pub curvature: f64 = 0.005 => float.unit("1/px").range(-10.0, 10.0),
        /// Sinusoid amplitude.
        pub amplitude_px: f64 = 4.0 => float.unit("px").range(-1e4, 1e4),
        /// Sinusoid period.
        pub period_px: f64 = 32.0 => float.unit("px").range(0.5, 1e5),
    }
}

impl SurfaceParams {
    /// The surface on a `w × h` image.
    #[must_use]
    pub fn surface(&self, w: usize, h: usize) -> Surface {
        match self.shape {
            SurfaceShape::Sphere => Surface::Sphere {
                radius_px: self.radius_px,
            },
            SurfaceShape::Paraboloid => Surface::Paraboloid {
                curvature: self.curvature,
            },
            SurfaceShape::Sinusoid => Surface::Sinusoid {
                amplitude_px: self.amplitude_px,
                period_px: self.period_px,
            },
            SurfaceShape::Gaussians => Surface::gaussians_for(w.min(h)),
        }
    }
}
