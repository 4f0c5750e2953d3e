//! Source nodes: files (RGBN EXR, colour + normal map + mask), the built-in demo medallion,
//! analytic surfaces; and masks (load one, apply one to an image).
//!
//! File paths in graph files are relative to the graph file's folder. The evaluator keys loaded
//! files by the hash of their bytes, so editing a file on disk invalidates its dependants and
//! moving it does not.
//!
//! Parameters of the source nodes (the nodes below): files, the demo, analytic surfaces
//! and masks; the images come from [`crate::raster::io`] and [`crate::raster::sample`].

use super::{Kind, Mask, NoInputs, OpSpec, Operator, RunContext, Scalar};
use crate::error::RgbnError;
use crate::raster::io;
use crate::raster::io::{Format, InputSpec, LoadOptions};
use crate::raster::sample::Surface;
use crate::raster::sample::{demo_medallion, demo_window};
use crate::raster::window::Window;
use crate::raster::{check_size, Plane};
use crate::RgbnImage;
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
        pub width: i64 = 128 => int.unit("px").range(1.0, 16384.0).soft(16.0, 2048.0).log(),
        /// Image size.
        pub height: i64 = 128 => int.unit("px").range(1.0, 16384.0).soft(16.0, 2048.0).log(),
        /// Sphere radius.
        pub radius_px: f64 = 48.0 => float.unit("px").range(0.5, 1e5).soft(1.0, 1024.0).log(),
        /// Paraboloid z = −curvature·(u² + v²).
        pub curvature: f64 = 0.005 => float.unit("1/px").range(-10.0, 10.0).soft(-0.05, 0.05),
        /// Sinusoid amplitude.
        pub amplitude_px: f64 = 4.0 => float.unit("px").range(-1e4, 1e4).soft(-16.0, 16.0),
        /// Sinusoid period.
        pub period_px: f64 = 32.0 => float.unit("px").range(0.5, 1e5).soft(2.0, 512.0).log(),
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
        pub size: i64 = 256 => int.unit("px").range(16.0, 16384.0).soft(16.0, 4096.0).log(),
    }
}

crate::params! {
    /// Parameters of the image loader ([`crate::raster::io::load`]).
    #[derive(Clone, Debug, PartialEq)]
    pub struct LoadParams {
        /// RGBN EXR (R,G,B + N.X,N.Y,N.Z [+ A]), an OME-Zarr store (.zarr: R,G,B, nx,ny,nz [, mask]; a region or level reads only its chunks), a normal map (PNG/TIFF/EXR) or a Polynomial Texture Map (.ptm, LRGB or RGB).
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
        let is_rgbn = match Format::of(&path)? {
            Format::Exr => !self.exr_rgb_is_normal,
            Format::Zarr => true,
            _ => false,
        };
        let opt = |s: &str| (!s.is_empty()).then(|| PathBuf::from(s));
        Ok(InputSpec {
            rgbn: is_rgbn.then(|| path.clone()),
            normal: (!is_rgbn).then_some(path),
            color: opt(&self.color),
            mask: opt(&self.mask),
        })
    }

    /// Whether the image is a chunked store read window by window at any level: an OME-Zarr
    /// store with no separate colour or mask file.
    #[must_use]
    pub fn is_store(&self) -> bool {
        io::zarr::is_zarr(std::path::Path::new(&self.path))
            && self.color.is_empty()
            && self.mask.is_empty()
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

crate::outputs! {
    /// Outputs of [`Demo`].
    pub struct DemoOut {
        /// The demo image.
        pub image: RgbnImage,
    }
}

/// The built-in demo medallion ([`demo_medallion`]).
pub struct Demo;

impl Operator for Demo {
    type Params = DemoParams;
    type In = NoInputs;
    type Out = DemoOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "demo",
            "Demo medallion",
            "input",
            "The built-in procedural RGBN demo: a relief medallion whose normals are exactly a surface's, no files needed.",
        )
    }
    fn kind(_: &DemoParams) -> Kind {
        Kind::Source
    }
    fn out_size(p: &DemoParams, _: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        Some((p.size as usize, p.size as usize))
    }
    fn run(p: &DemoParams, _: NoInputs, _: &RunContext) -> Result<DemoOut, RgbnError> {
        let s = p.size as usize;
        check_size(s, s, "demo")?;
        Ok(DemoOut {
            image: demo_medallion(s),
        })
    }
    fn run_region(
        p: &DemoParams,
        _: NoInputs,
        win: Window,
        _: &RunContext,
    ) -> Result<DemoOut, RgbnError> {
        check_size(win.w, win.h, "demo")?;
        Ok(DemoOut {
            image: demo_window(p.size as usize, win),
        })
    }
}

crate::outputs! {
    /// Outputs of [`SurfaceOp`].
    pub struct SurfaceOut {
        /// The surface's normals; masked where the slope is undefined.
        pub image: RgbnImage,
        /// Height in pixels (y up).
        pub height: Scalar,
    }
}

/// An analytic surface ([`crate::raster::sample::Surface`]) sampled at the pixel corners with normals from their
/// differences (exactly integrable; [`crate::raster::sample::Surface::render_sampled`]), or with the analytic normals
/// at pixel centres, and its height.
pub struct SurfaceOp;

impl Operator for SurfaceOp {
    type Params = SurfaceParams;
    type In = NoInputs;
    type Out = SurfaceOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "surface",
            "Analytic surface",
            "input",
            "An analytic height field (sphere, paraboloid, sinusoid, Gaussian bumps) with grey albedo and its height; normals from the height's differences (exactly a surface) or analytic.",
        )
    }
    fn kind(_: &SurfaceParams) -> Kind {
        Kind::Source
    }
    fn out_size(p: &SurfaceParams, _: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        Some((p.width as usize, p.height as usize))
    }
    fn run(p: &SurfaceParams, i: NoInputs, ctx: &RunContext) -> Result<SurfaceOut, RgbnError> {
        let (w, h) = (p.width as usize, p.height as usize);
        Self::run_region(p, i, Window::full(w, h), ctx)
    }
    fn run_region(
        p: &SurfaceParams,
        _: NoInputs,
        win: Window,
        _: &RunContext,
    ) -> Result<SurfaceOut, RgbnError> {
        let full = (p.width as usize, p.height as usize);
        check_size(win.w, win.h, "surface")?;
        let s = p.surface(full.0, full.1);
        let (image, z) = if p.analytic_normals {
            s.render_window(full, win)
        } else {
            s.render_sampled_window(full, win)
        };
        Ok(SurfaceOut {
            image,
            height: Scalar::new(z),
        })
    }
}

crate::outputs! {
    /// Outputs of [`Load`].
    pub struct LoadOut {
        /// The loaded image.
        pub image: RgbnImage,
    }
}

/// Loads an RGBN image from files.
pub struct Load;

impl Operator for Load {
    type Params = LoadParams;
    type In = NoInputs;
    type Out = LoadOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "load",
            "Load image",
            "input",
            "Loads an RGBN EXR, a PTM, or a normal map with an optional colour image and mask; bad normals are repaired (or refused with strict).",
        )
    }
    fn kind(p: &LoadParams) -> Kind {
        if p.is_store() {
            // A chunked store: any window at any level, read from its chunks and levels.
            Kind::Source
        } else {
            // Reads files whole.
            Kind::GLOBAL
        }
    }
    fn out_size(p: &LoadParams, _: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        io::dimensions(std::path::Path::new(&p.path))
    }
    fn run(p: &LoadParams, _: NoInputs, _: &RunContext) -> Result<LoadOut, RgbnError> {
        let (spec, opts) = (p.input_spec()?, p.load_options());
        Ok(LoadOut {
            image: io::load(&spec, &opts)?.image,
        })
    }
    fn run_region(
        p: &LoadParams,
        i: NoInputs,
        win: Window,
        ctx: &RunContext,
    ) -> Result<LoadOut, RgbnError> {
        if !p.is_store() {
            return Self::run(p, i, ctx);
        }
        // The window at its level, read from the store's chunks that cover it (the level
        // the store holds; a coarser one from its coarsest, reduced).
        let path = std::path::Path::new(&p.path);
        let z = io::zarr::ZarrImage::open(path)?;
        let level = win.scale.max(1).trailing_zeros() as usize;
        let rect = crate::raster::window::Rect::new(win.x, win.y, win.w, win.h);
        let (image, repaired) = z.read_rgbn(level, rect)?;
        if p.strict {
            if let Some(e) = repaired.strict_error(path) {
                return Err(e);
            }
        }
        Ok(LoadOut { image })
    }
}

crate::outputs! {
    /// Outputs of [`LoadMask`].
    pub struct LoadMaskOut {
        /// The mask.
        pub mask: Mask,
    }
}

/// Loads a mask from a greyscale image.
pub struct LoadMask;

impl Operator for LoadMask {
    type Params = LoadMaskParams;
    type In = NoInputs;
    type Out = LoadMaskOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "load_mask",
            "Load mask",
            "input",
            "Loads a coverage mask from a greyscale image (values in [0, 1]).",
        )
    }
    fn kind(_: &LoadMaskParams) -> Kind {
        // Reads a file whole.
        Kind::GLOBAL
    }
    fn out_size(p: &LoadMaskParams, _: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        io::dimensions(std::path::Path::new(&p.path))
    }
    fn run(p: &LoadMaskParams, _: NoInputs, _: &RunContext) -> Result<LoadMaskOut, RgbnError> {
        let (w, h, m) = io::load_mask(std::path::Path::new(&p.path))?;
        Ok(LoadMaskOut {
            mask: Mask::new(Plane::from_vec(w, h, m)?),
        })
    }
}

crate::inputs! {
    /// Inputs of [`ApplyMask`].
    pub struct ApplyMaskIn {
        /// The image.
        pub image: RgbnImage,
        /// The new mask (same size).
        pub mask: Option<Mask>,
    }
}

crate::outputs! {
    /// Outputs of [`ApplyMask`].
    pub struct ApplyMaskOut {
        /// The image with the mask.
        pub image: RgbnImage,
    }
}

/// Replaces an image's mask.
pub struct ApplyMask;

impl Operator for ApplyMask {
    type Params = ApplyMaskParams;
    type In = ApplyMaskIn;
    type Out = ApplyMaskOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "apply_mask",
            "Apply mask",
            "input",
            "Sets the image's coverage mask (mask-aware operators then work inside it); without a mask input, removes the mask.",
        )
    }
    fn kind(_: &ApplyMaskParams) -> Kind {
        // Per pixel; a reduced image's normals are weighed by its old mask, so applying the
        // reduced mask is not the reduced result: no coarse form.
        Kind::Point {
            coarse: super::Coarse::None,
        }
    }
    fn run(p: &ApplyMaskParams, i: ApplyMaskIn, _: &RunContext) -> Result<ApplyMaskOut, RgbnError> {
        let mut img = i.image;
        match i.mask {
            None => img.set_mask(None)?,
            Some(m) => {
                if (m.width(), m.height()) != (img.width(), img.height()) {
                    return Err(RgbnError::InvalidImage(format!(
                        "mask is {}×{} but the image is {}×{}",
                        m.width(),
                        m.height(),
                        img.width(),
                        img.height()
                    )));
                }
                let data = if p.invert {
                    m.data().iter().map(|v| 1.0 - v).collect()
                } else {
                    m.data().to_vec()
                };
                img.set_mask(Some(data))?;
            }
        }
        Ok(ApplyMaskOut { image: img })
    }
}
