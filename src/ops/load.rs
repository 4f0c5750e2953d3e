//! Parameters of the source nodes ([`crate::nodes::load`]): files, the demo, analytic surfaces
//! and masks; the images come from [`crate::raster::io`] and [`crate::raster::sample`].

use crate::raster::io::{Format, InputSpec, LoadOptions};
use crate::raster::sample::Surface;
use std::path::PathBuf;

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
        /// Normals from the analytic derivative at each pixel centre (not exactly integrable on
        /// the pixel grid) instead of the differences of the height sampled at the pixel corners
        /// (the default: exactly a surface, curl 0, as a capture of a real surface would be).
        pub analytic_normals: bool = false => bool,
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

crate::params! {
    /// Parameters of the demo medallion ([`crate::raster::sample::demo_medallion`]).
    #[derive(Clone, Debug, PartialEq)]
    pub struct DemoParams {
        /// Side of the square image.
        pub size: i64 = 256 => int.unit("px").range(16.0, 16384.0),
    }
}

crate::params! {
    /// Parameters of the image loader ([`crate::raster::io::load`]).
    #[derive(Clone, Debug, PartialEq)]
    pub struct LoadParams {
        /// RGBN EXR (R,G,B + N.X,N.Y,N.Z [+ A]), a normal map (PNG/TIFF/EXR) or a Polynomial Texture Map (.ptm, LRGB or RGB).
        pub path: String = String::new() => path,
        /// Colour image (sRGB PNG/JPEG/TIFF or linear EXR); empty: none.
        pub color: String = String::new() => path.optional(),
        /// Coverage mask (greyscale); empty: none.
        pub mask: String = String::new() => path.optional(),
        /// Normal maps use the DirectX convention (green = −y).
        pub dx: bool = false => bool,
        /// Read an EXR's R,G,B as the normal (Blender-style normal pass).
        pub exr_rgb_is_normal: bool = false => bool,
        /// Refuse NaN/inf/zero-length normals instead of repairing them.
        pub strict: bool = false => bool,
    }
}

impl LoadParams {
    /// The files to read: an RGBN EXR (unless its RGB is a normal pass), else a normal map,
    /// with the optional colour and mask.
    pub fn input_spec(&self) -> Result<InputSpec, crate::error::RgbnError> {
        let path = PathBuf::from(&self.path);
        let is_rgbn = Format::of(&path)? == Format::Exr && !self.exr_rgb_is_normal;
        let opt = |s: &str| (!s.is_empty()).then(|| PathBuf::from(s));
        Ok(InputSpec {
            rgbn: is_rgbn.then(|| path.clone()),
            normal: (!is_rgbn).then_some(path),
            color: opt(&self.color),
            mask: opt(&self.mask),
        })
    }

    /// How to decode them.
    #[must_use]
    pub fn load_options(&self) -> LoadOptions {
        LoadOptions::of_flags(self.dx, self.exr_rgb_is_normal, self.strict)
    }
}

crate::params! {
    /// Parameters of the mask loader ([`crate::raster::io::load_mask`]).
    #[derive(Clone, Debug, PartialEq)]
    pub struct LoadMaskParams {
        /// Greyscale image: white = covered, black = not.
        pub path: String = String::new() => path,
    }
}

crate::params! {
    /// Parameters of replacing an image's mask.
    #[derive(Clone, Debug, PartialEq)]
    pub struct ApplyMaskParams {
        /// Use 1 − mask (cover what the mask leaves out).
        pub invert: bool = false => bool,
    }
}
