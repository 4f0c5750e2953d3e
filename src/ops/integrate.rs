//! Parameters of the integration and mesh nodes ([`crate::nodes::integrate`]); the solvers
//! are [`crate::raster::integrate`] and [`crate::raster::mesh`].

use super::params::Choice;
use crate::error::RgbnError;
use crate::raster::integrate::{Camera, Differences, IntegrateParams, IntegrationMethod, Pinhole};
use crate::raster::mesh::{MeshFormat, MeshParams};

impl Choice for IntegrationMethod {
    const ALL: &'static [Self] = &[
        IntegrationMethod::PoissonDct,
        IntegrationMethod::FrankotChellappa,
        IntegrationMethod::MaskedPoisson,
        IntegrationMethod::Bilateral,
    ];
    fn name(self) -> &'static str {
        match self {
            IntegrationMethod::PoissonDct => "poisson_dct",
            IntegrationMethod::FrankotChellappa => "frankot_chellappa",
            IntegrationMethod::MaskedPoisson => "masked_poisson",
            IntegrationMethod::Bilateral => "bilateral",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            IntegrationMethod::PoissonDct => {
                "Least squares, Neumann borders, DCT solver (mask ignored)."
            }
            IntegrationMethod::FrankotChellappa => "Periodic borders, FFT (mask ignored).",
            IntegrationMethod::MaskedPoisson => {
                "Only edges inside the image's mask, conjugate gradients."
            }
            IntegrationMethod::Bilateral => {
                "Bilateral normal integration (Cao et al. 2022): keeps depth discontinuities; over the mask."
            }
        }
    }
}

impl Choice for Differences {
    const ALL: &'static [Self] = &[Differences::Averaged, Differences::Forward];
    fn name(self) -> &'static str {
        match self {
            Differences::Averaged => "averaged",
            Differences::Forward => "forward",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            Differences::Averaged => {
                "Edge slope = average of the two pixel samples: heights at pixel centres."
            }
            Differences::Forward => {
                "Edge slope = one pixel's sample (forward differences): half a pixel staggered for centre-sampled normals."
            }
        }
    }
}

impl Choice for MeshFormat {
    const ALL: &'static [Self] = &[MeshFormat::PlyBinary, MeshFormat::PlyAscii, MeshFormat::Obj];
    fn name(self) -> &'static str {
        match self {
            MeshFormat::PlyBinary => "ply",
            MeshFormat::PlyAscii => "ply_ascii",
            MeshFormat::Obj => "obj",
        }
    }
    fn doc(self) -> &'static str {
        match self {
            MeshFormat::PlyBinary => "PLY, binary little-endian.",
            MeshFormat::PlyAscii => "PLY, ASCII.",
            MeshFormat::Obj => "Wavefront OBJ (v x y z r g b, vn, f).",
        }
    }
}

crate::choice_enum! {
    /// The camera model of the integrate node.
    pub enum CameraModel {
        /// Parallel projection: heights in pixels.
        Orthographic = "orthographic",
        /// A pinhole camera from focal_px (focal_y_px) and the principal point.
        Pinhole = "pinhole",
        /// A pinhole camera from a 3×3 intrinsic matrix K in a text file (k_file).
        KFile = "k_file",
    }
}

/// The camera fields shared by the integrate and mesh nodes.
struct CameraSpec<'a> {
    model: CameraModel,
    focal_px: f64,
    focal_y_px: f64,
    principal_centred: bool,
    principal_x: f64,
    principal_y: f64,
    k_file: &'a str,
}

impl CameraSpec<'_> {
    /// The camera for a `w × h` image (reads the K file).
    fn camera(&self, w: usize, h: usize) -> Result<Camera, RgbnError> {
        Ok(match self.model {
            CameraModel::Orthographic => Camera::Orthographic,
            CameraModel::Pinhole => {
                if self.focal_px.is_nan() || self.focal_px <= 0.0 {
                    return Err(RgbnError::param(
                        "focal_px",
                        format!("a focal length must be > 0, got {}", self.focal_px),
                    ));
                }
                if self.focal_y_px.is_nan() || self.focal_y_px < 0.0 {
                    return Err(RgbnError::param(
                        "focal_y_px",
                        format!(
                            "a focal length must be > 0 (0 = focal_px), got {}",
                            self.focal_y_px
                        ),
                    ));
                }
                let mut c = Pinhole::centred(self.focal_px, w, h);
                if self.focal_y_px > 0.0 {
                    c.fy = self.focal_y_px;
                }
                if !self.principal_centred {
                    (c.cx, c.cy) = (self.principal_x, self.principal_y);
                }
                c.validate()?;
                Camera::Pinhole(c)
            }
            CameraModel::KFile => {
                if self.k_file.is_empty() {
                    return Err(RgbnError::param(
                        "k_file",
                        "camera k_file needs a K file path",
                    ));
                }
                Camera::Pinhole(Pinhole::from_k_file(std::path::Path::new(self.k_file))?)
            }
        })
    }
}

crate::params! {
    /// Parameters of the integrate and project nodes (the graph form of [`IntegrateParams`]).
    #[derive(Clone, Debug, PartialEq)]
    pub struct IntegrateSettings {
        /// poisson_dct: least squares, Neumann borders, DCT solver (mask ignored); frankot_chellappa: periodic borders, FFT; masked_poisson: only edges inside the image's mask, conjugate gradients.
        pub method: IntegrationMethod = IntegrationMethod::PoissonDct => choice,
        /// Conjugate-gradient iteration cap (masked_poisson only).
        pub max_iterations: i64 = i64::from(IntegrateParams::default().max_iterations)
            => int.range(1.0, 1e7),
        /// Stop when ‖b − Lz‖ ≤ tolerance·‖b‖ (masked_poisson only).
        pub tolerance: f64 = IntegrateParams::default().tolerance => float.range(1e-12, 0.5),
        /// averaged: an edge's slope is the average of its two pixel samples (normals sampled at pixel centres; heights registered at pixel centres); forward: one pixel's sample per edge (exact for forward differences of a height; half a pixel staggered otherwise). Graphs that do not name it get averaged.
        pub differences: Differences = Differences::Averaged => choice,
        /// orthographic: heights in pixels; pinhole: a pinhole camera (focal_px, principal point) — the log-depth is integrated and the height output is −Z for a depth Z up to scale (geometric mean focal_px over the domain); k_file: the same camera from a 3×3 K matrix in a text file.
        pub camera: CameraModel = CameraModel::Orthographic => choice,
        /// Pinhole focal length (x; also y unless focal_y_px is set).
        pub focal_px: f64 = 1000.0 => float.unit("px").range(-1e9, 1e9),
        /// Pinhole focal length along y; 0 = the same as focal_px.
        pub focal_y_px: f64 = 0.0 => float.unit("px").range(-1e9, 1e9),
        /// Principal point at the image centre ((W−1)/2, (H−1)/2); off: principal_x, principal_y.
        pub principal_centred: bool = true => bool,
        /// Principal point column (pixel centres at integers), when principal_centred is off.
        pub principal_x: f64 = 0.0 => float.unit("px").range(-1e9, 1e9),
        /// Principal point row (downwards, pixel centres at integers), when principal_centred is off.
        pub principal_y: f64 = 0.0 => float.unit("px").range(-1e9, 1e9),
        /// Text file with the 3×3 intrinsic matrix K (rows of numbers, NumPy savetxt form) for camera k_file.
        pub k_file: String = String::new() => path.optional(),
        /// Bilateral: sigmoid sharpness k (larger keeps discontinuities more easily; 0 = least squares).
        pub sharpness: f64 = 2.0 => float.range(0.0, 1e3),
        /// Bilateral: cap on reweighting iterations.
        pub irls_iterations: i64 = 150 => int.range(1.0, 1e6),
        /// Bilateral: stop when the relative energy change is below this.
        pub irls_tolerance: f64 = 1e-4 => float.range(1e-12, 0.5),
        /// Bilateral: each reweighting step's change is taken this many times over when that lowers the energy (1 = the reference's plain steps).
        pub over_relaxation: f64 = 2.0 => float.range(1.0, 10.0),
    }
}

impl IntegrateSettings {
    /// The solver parameters, checked, for an image of `w × h` pixels (the pinhole camera's
    /// centred principal point; the K file is read here).
    ///
    /// # Errors
    /// A parameter out of range, a focal length ≤ 0, an unreadable or malformed K file.
    pub fn params_for(&self, w: usize, h: usize) -> Result<IntegrateParams, RgbnError> {
        let camera = CameraSpec {
            model: self.camera,
            focal_px: self.focal_px,
            focal_y_px: self.focal_y_px,
            principal_centred: self.principal_centred,
            principal_x: self.principal_x,
            principal_y: self.principal_y,
            k_file: &self.k_file,
        }
        .camera(w, h)?;
        let p = IntegrateParams {
            method: self.method,
            max_iterations: u32::try_from(self.max_iterations)
                .map_err(|_| RgbnError::param("max_iterations", "out of range"))?,
            tolerance: self.tolerance,
            differences: self.differences,
            camera,
            sharpness: self.sharpness,
            irls_iterations: u32::try_from(self.irls_iterations)
                .map_err(|_| RgbnError::param("irls_iterations", "out of range"))?,
            irls_tolerance: self.irls_tolerance,
            over_relaxation: self.over_relaxation,
        };
        p.validate()?;
        Ok(p)
    }

    /// The checks that need no image (the camera is checked by [`Self::params_for`]; a K
    /// file is only read then).
    ///
    /// # Errors
    /// As [`Self::params_for`] without the K file.
    pub fn params(&self) -> Result<IntegrateParams, RgbnError> {
        let no_file = Self {
            camera: if self.camera == CameraModel::KFile {
                if self.k_file.is_empty() {
                    return Err(RgbnError::param(
                        "k_file",
                        "camera k_file needs a K file path",
                    ));
                }
                CameraModel::Orthographic
            } else {
                self.camera
            },
            ..self.clone()
        };
        no_file.params_for(1, 1)
    }
}

crate::params! {
    /// Parameters of the mesh-writing node.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SaveMeshSettings {
        /// Output mesh (.ply or .obj).
        pub path: String = String::new() => path.output(),
        /// ply (binary little-endian), ply_ascii, or obj (v x y z r g b, vn, f).
        pub format: MeshFormat = MeshFormat::PlyBinary => choice,
        /// Multiplies the height (relief exaggeration; not 0).
        pub z_scale: f64 = 1.0 => float.range(-1e6, 1e6),
        /// World size of one pixel.
        pub pixel_size: f64 = 1.0 => float.range(1e-9, 1e9),
        /// orthographic: vertices at (x·pixel_size, −row·pixel_size, height·z_scale); pinhole / k_file: the height is −Z of a pinhole integration and vertices are the 3-D points z_scale·((x − cx)·Z/fx, −(row − cy)·Z/fy, −Z) (camera at the origin looking along −z; use the integrate node's camera).
        pub camera: CameraModel = CameraModel::Orthographic => choice,
        /// Pinhole focal length (x; also y unless focal_y_px is set).
        pub focal_px: f64 = 1000.0 => float.unit("px").range(-1e9, 1e9),
        /// Pinhole focal length along y; 0 = the same as focal_px.
        pub focal_y_px: f64 = 0.0 => float.unit("px").range(-1e9, 1e9),
        /// Principal point at the image centre ((W−1)/2, (H−1)/2); off: principal_x, principal_y.
        pub principal_centred: bool = true => bool,
        /// Principal point column (pixel centres at integers), when principal_centred is off.
        pub principal_x: f64 = 0.0 => float.unit("px").range(-1e9, 1e9),
        /// Principal point row (downwards), when principal_centred is off.
        pub principal_y: f64 = 0.0 => float.unit("px").range(-1e9, 1e9),
        /// Text file with the 3×3 intrinsic matrix K for camera k_file.
        pub k_file: String = String::new() => path.optional(),
    }
}

impl SaveMeshSettings {
    /// The mesh parameters for a `w × h` image, checked (reads the K file).
    ///
    /// # Errors
    /// A parameter out of range, a focal length ≤ 0, an unreadable or malformed K file.
    pub fn params_for(&self, w: usize, h: usize) -> Result<MeshParams, RgbnError> {
        let camera = match (CameraSpec {
            model: self.camera,
            focal_px: self.focal_px,
            focal_y_px: self.focal_y_px,
            principal_centred: self.principal_centred,
            principal_x: self.principal_x,
            principal_y: self.principal_y,
            k_file: &self.k_file,
        })
        .camera(w, h)?
        {
            Camera::Orthographic => None,
            Camera::Pinhole(c) => Some(c),
        };
        let p = MeshParams {
            format: self.format,
            z_scale: self.z_scale as f32,
            pixel_size: self.pixel_size as f32,
            camera,
        };
        p.validate()?;
        Ok(p)
    }

    /// The checks that need no image (a K file is only read by [`Self::params_for`]).
    ///
    /// # Errors
    /// As [`Self::params_for`] without the K file.
    pub fn params(&self) -> Result<MeshParams, RgbnError> {
        if self.camera == CameraModel::KFile {
            if self.k_file.is_empty() {
                return Err(RgbnError::param(
                    "k_file",
                    "camera k_file needs a K file path",
                ));
            }
            return Self {
                camera: CameraModel::Orthographic,
                ..self.clone()
            }
            .params_for(1, 1);
        }
        self.params_for(1, 1)
    }
}

crate::params! {
    /// Parameters of writing a height (any scalar field) to EXR.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SaveHeightParams {
        /// Output .exr (one f32 channel Y).
        pub path: String = String::new() => path.output(),
    }
}
