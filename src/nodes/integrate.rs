//! Integration as nodes: normals → height ([`integrate_normals`]), the integrability projection
//! ([`project_integrable`]), and two writers: a height to EXR (`save.height`) and a height +
//! image to a mesh (`save.mesh`, [`save_mesh`]), with their parameters. The solvers are
//! [`crate::raster::integrate`] and [`crate::raster::mesh`].

use super::save::write_value;
use super::{Coarse, Kind, OpSpec, Operator, RunContext, Scalar, Value};
use crate::error::RgbnError;
use crate::params::Choice;
use crate::raster::integrate::{
    integrate_normals, project_integrable, IntegrationMethod, ProjectParams,
};
use crate::raster::integrate::{Camera, Differences, IntegrateParams, Pinhole};
use crate::raster::io::{self, SaveOptions};
use crate::raster::mesh::save_mesh;
use crate::raster::mesh::{MeshFormat, MeshParams};
use crate::RgbnImage;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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

crate::params! {
    /// The camera of the integrate, project and mesh nodes.
    #[derive(Clone, Debug, PartialEq)]
    pub struct CameraSettings {
        /// orthographic: parallel projection (heights in pixels; mesh vertices at (x·pixel_size, −row·pixel_size, height·z_scale)); pinhole: a pinhole camera (focal_px, principal point): integration works on the log-depth and its height is −Z for a depth Z up to scale (geometric mean focal_px over the domain), and a mesh places the 3-D points z_scale·((x − cx)·Z/fx, −(row − cy)·Z/fy, −Z) (camera at the origin looking along −z); k_file: the same camera from a 3×3 K matrix in a text file.
        pub camera: CameraModel = CameraModel::Orthographic => choice,
        /// Pinhole focal length (x; also y unless focal_y_px is set).
        pub focal_px: f64 = 1000.0 => float.unit("px").range(-1e9, 1e9).soft(100.0, 1e4).log(),
        /// Pinhole focal length along y; 0 = the same as focal_px.
        pub focal_y_px: f64 = 0.0 => float.unit("px").range(-1e9, 1e9).soft(0.0, 1e4).log(),
        /// Principal point at the image centre ((W−1)/2, (H−1)/2); off: principal_x, principal_y.
        pub principal_centred: bool = true => bool,
        /// Principal point column (pixel centres at integers), when principal_centred is off.
        pub principal_x: f64 = 0.0 => float.unit("px").range(-1e9, 1e9).soft(-1024.0, 4096.0),
        /// Principal point row (downwards, pixel centres at integers), when principal_centred is off.
        pub principal_y: f64 = 0.0 => float.unit("px").range(-1e9, 1e9).soft(-1024.0, 4096.0),
        /// Text file with the 3×3 intrinsic matrix K (rows of numbers, NumPy savetxt form) for camera k_file.
        pub k_file: String = String::new() => path.optional(),
    }
}

impl CameraSettings {
    /// The camera for a `w × h` image (reads the K file).
    ///
    /// # Errors
    /// A focal length ≤ 0, a missing, unreadable or malformed K file.
    pub fn camera_for(&self, w: usize, h: usize) -> Result<Camera, RgbnError> {
        Ok(match self.camera {
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
                self.check_k_file()?;
                Camera::Pinhole(Pinhole::from_k_file(Path::new(&self.k_file))?)
            }
        })
    }

    /// The same camera without reading a K file (an orthographic stand-in for it), for the
    /// checks that need no image.
    ///
    /// # Errors
    /// Camera `k_file` without a file.
    fn without_file(&self) -> Result<Self, RgbnError> {
        if self.camera != CameraModel::KFile {
            return Ok(self.clone());
        }
        self.check_k_file()?;
        Ok(Self {
            camera: CameraModel::Orthographic,
            ..self.clone()
        })
    }

    fn check_k_file(&self) -> Result<(), RgbnError> {
        if self.k_file.is_empty() {
            return Err(RgbnError::param(
                "k_file",
                "camera k_file needs a K file path",
            ));
        }
        Ok(())
    }

    /// The camera for the normals reduced by `s`: focal lengths ÷ `s`, the principal point on
    /// the coarse grid. A K file states full-resolution pixels: no such form.
    fn at_level(&self, s: f64) -> Option<Self> {
        if self.camera == CameraModel::KFile {
            return None;
        }
        let [principal_x, principal_y] =
            crate::params::scale_point([self.principal_x, self.principal_y], s);
        Some(Self {
            focal_px: self.focal_px / s,
            focal_y_px: self.focal_y_px / s,
            principal_x,
            principal_y,
            ..self.clone()
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
            => int.range(1.0, 1e7).soft(10.0, 1e5).log(),
        /// Stop when ‖b − Lz‖ ≤ tolerance·‖b‖ (masked_poisson only).
        pub tolerance: f64 = IntegrateParams::default().tolerance => float.range(1e-12, 0.5).soft(1e-9, 1e-2).log(),
        /// averaged: an edge's slope is the average of its two pixel samples (normals sampled at pixel centres; heights registered at pixel centres); forward: one pixel's sample per edge (exact for forward differences of a height; half a pixel staggered otherwise). Graphs that do not name it get averaged.
        pub differences: Differences = Differences::Averaged => choice,
        /// The camera.
        pub camera: CameraSettings = CameraSettings::default() => flatten,
        /// Bilateral: sigmoid sharpness k (larger keeps discontinuities more easily; 0 = least squares).
        pub sharpness: f64 = 2.0 => float.range(0.0, 1e3).soft(0.0, 10.0),
        /// Bilateral: cap on reweighting iterations.
        pub irls_iterations: i64 = 150 => int.range(1.0, 1e6).soft(10.0, 1000.0).log(),
        /// Bilateral: stop when the relative energy change is below this.
        pub irls_tolerance: f64 = 1e-4 => float.range(1e-12, 0.5).soft(1e-9, 1e-2).log(),
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
        let p = IntegrateParams {
            method: self.method,
            max_iterations: u32::try_from(self.max_iterations)
                .map_err(|_| RgbnError::param("max_iterations", "out of range"))?,
            tolerance: self.tolerance,
            differences: self.differences,
            camera: self.camera.camera_for(w, h)?,
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
        Self {
            camera: self.camera.without_file()?,
            ..self.clone()
        }
        .params_for(1, 1)
    }

    /// The integration at a level of detail (the normals reduced by `s`): the camera's
    /// lengths in pixels ÷ `s`, and the bilateral sharpness × `s²`, so that a depth jump of
    /// `J` pixels, `J/s` on the coarse grid, is weighed as at full resolution.
    fn at_level(&self, s: f64) -> Option<Self> {
        Some(Self {
            camera: self.camera.at_level(s)?,
            sharpness: if self.method == IntegrationMethod::Bilateral {
                self.sharpness * s * s
            } else {
                self.sharpness
            },
            ..self.clone()
        })
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

crate::params! {
    /// Parameters of the mesh-writing node.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SaveMeshSettings {
        /// Output mesh (.ply or .obj).
        pub path: String = String::new() => path.output(),
        /// ply (binary little-endian), ply_ascii, or obj (v x y z r g b, vn, f).
        pub format: MeshFormat = MeshFormat::PlyBinary => choice,
        /// Multiplies the height (relief exaggeration; not 0).
        pub z_scale: f64 = 1.0 => float.range(-1e6, 1e6).soft(-4.0, 4.0),
        /// World size of one pixel.
        pub pixel_size: f64 = 1.0 => float.range(1e-9, 1e9).soft(0.01, 100.0).log(),
        /// The camera (use the integrate node's).
        pub camera: CameraSettings = CameraSettings::default() => flatten,
    }
}

impl SaveMeshSettings {
    /// The mesh parameters for a `w × h` image, checked (reads the K file).
    ///
    /// # Errors
    /// A parameter out of range, a focal length ≤ 0, an unreadable or malformed K file.
    pub fn params_for(&self, w: usize, h: usize) -> Result<MeshParams, RgbnError> {
        let camera = match self.camera.camera_for(w, h)? {
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
        Self {
            camera: self.camera.without_file()?,
            ..self.clone()
        }
        .params_for(1, 1)
    }
}

/// `z` (a height in coarse pixels) multiplied by `s`: full-resolution pixels.
fn height_times(z: Scalar, s: f64) -> Scalar {
    let mut z = Arc::unwrap_or_clone(z.0);
    let s = s as f32;
    z.data_mut().iter_mut().for_each(|v| *v *= s);
    Scalar::new(z)
}

crate::inputs! {
    /// Inputs of [`IntegrateNode`].
    pub struct IntegrateIn {
        /// Image (its mask is the masked_poisson domain).
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`IntegrateNode`].
    pub struct IntegrateOut {
        /// Height in pixels (orthographic), or −Z for the depth Z (pinhole; geometric mean focal_px over the domain).
        pub height: Scalar,
        /// RMS over the domain's edges of ∇z − g in pixels per pixel: how far the field is from integrable.
        pub rms_residual: f64,
    }
}

/// Normals → height.
pub struct IntegrateNode;

impl Operator for IntegrateNode {
    type Params = IntegrateSettings;
    type In = IntegrateIn;
    type Out = IntegrateOut;
    /// Working memory: the solvers' f64 vectors and transforms: up to ≈ 96 bytes per pixel over a 4-byte height (measured peak RSS of graphs/integrate.ron on a 2048² demo: 453 MB).
    const SCRATCH: f64 = 24.0;
    fn spec() -> OpSpec {
        OpSpec::new(
            "integrate",
            "Integrate to height",
            "analysis",
            "Integrates the normals' gradients to a height (least squares, Simchony et al. / Frankot & Chellappa / masked Poisson; bilateral normal integration, Cao et al. 2022, keeps depth discontinuities): zero mean over the domain, in pixels, y up. With a pinhole camera (focal length and principal point, or a K file) the log-depth is integrated and the height is −Z for a depth Z up to scale.",
        )
    }
    fn check(p: &IntegrateSettings) -> Result<(), RgbnError> {
        p.params().map(|_| ())
    }
    fn kind(_: &IntegrateSettings) -> Kind {
        // Every height depends on every normal; a coarse level integrates the reduced normals.
        Kind::Global {
            coarse: Coarse::Scaled,
        }
    }
    fn scaled(p: &IntegrateSettings, s: f64) -> Option<IntegrateSettings> {
        p.at_level(s)
    }
    fn level_outputs(_: &IntegrateSettings, s: f64, o: IntegrateOut) -> IntegrateOut {
        IntegrateOut {
            height: height_times(o.height, s),
            ..o
        }
    }
    fn run(
        p: &IntegrateSettings,
        i: IntegrateIn,
        _: &RunContext,
    ) -> Result<IntegrateOut, RgbnError> {
        let img = &i.image;
        let (z, rep) = integrate_normals(img, &p.params_for(img.width(), img.height())?)?;
        Ok(IntegrateOut {
            height: Scalar::new(z),
            rms_residual: rep.rms_residual,
        })
    }
}

crate::inputs! {
    /// Inputs of [`ProjectNode`].
    pub struct ProjectIn {
        /// Image to project.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`ProjectNode`].
    pub struct ProjectOut {
        /// Projected normals; colour and mask unchanged.
        pub image: RgbnImage,
        /// The integrated height in pixels.
        pub height: Scalar,
        /// Relative RMS curl of the input (over the mask interior).
        pub curl_before: f64,
        /// Relative RMS curl of the output (≈ 0).
        pub curl_after: f64,
    }
}

/// Integrability projection.
pub struct ProjectNode;

impl Operator for ProjectNode {
    type Params = IntegrateSettings;
    type In = ProjectIn;
    type Out = ProjectOut;
    /// Working memory: the integration's buffers over the RGBN and height outputs.
    const SCRATCH: f64 = 2.0;
    fn spec() -> OpSpec {
        OpSpec::new(
            "project",
            "Integrability projection",
            "filter",
            "Replaces the normals by those of their integrated height: the nearest integrable field in the least-squares sense. Use after nonlinear edits (brush feathers, rotation combines) that left curl.",
        )
    }
    fn check(p: &IntegrateSettings) -> Result<(), RgbnError> {
        p.params().map(|_| ())
    }
    fn kind(_: &IntegrateSettings) -> Kind {
        Kind::Global {
            coarse: Coarse::Scaled,
        }
    }
    fn scaled(p: &IntegrateSettings, s: f64) -> Option<IntegrateSettings> {
        p.at_level(s)
    }
    fn level_outputs(_: &IntegrateSettings, s: f64, o: ProjectOut) -> ProjectOut {
        ProjectOut {
            height: height_times(o.height, s),
            ..o
        }
    }
    fn run(p: &IntegrateSettings, i: ProjectIn, _: &RunContext) -> Result<ProjectOut, RgbnError> {
        let img = &i.image;
        let params = ProjectParams {
            integrate: p.params_for(img.width(), img.height())?,
        };
        let (image, z, rep) = project_integrable(img, &params)?;
        Ok(ProjectOut {
            image,
            height: Scalar::new(z),
            curl_before: rep.before.relative,
            curl_after: rep.after.relative,
        })
    }
}

/// `path` as an output file the graph may write: not one it reads.
fn check_output(path: &str, ctx: &RunContext) -> Result<PathBuf, RgbnError> {
    let path = PathBuf::from(path);
    let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
    io::check_output(&path, &protected)?;
    Ok(path)
}

crate::inputs! {
    /// Inputs of [`SaveHeight`].
    pub struct SaveHeightIn {
        /// Field to write.
        pub height: Scalar,
    }
}

crate::outputs! {
    /// Outputs of [`SaveHeight`].
    pub struct SaveHeightOut {
        /// The same field.
        pub height: Scalar,
    }
}

/// Writes a height (any scalar field) to EXR.
pub struct SaveHeight;

impl Operator for SaveHeight {
    type Params = SaveHeightParams;
    type In = SaveHeightIn;
    type Out = SaveHeightOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "save.height",
            "Save height",
            "output",
            "Writes a scalar field (a height, a curl map) to a single-channel f32 EXR, atomically and never over a file the graph reads, and passes it through; runs whenever its output is requested.",
        )
        .side_effect()
    }
    fn check(p: &SaveHeightParams) -> Result<(), RgbnError> {
        if !p.path.to_ascii_lowercase().ends_with(".exr") {
            return Err(RgbnError::param("path", "a height is written as .exr"));
        }
        Ok(())
    }
    fn kind(_: &SaveHeightParams) -> Kind {
        // Writes the whole field.
        Kind::GLOBAL
    }
    fn run(
        p: &SaveHeightParams,
        i: SaveHeightIn,
        ctx: &RunContext,
    ) -> Result<SaveHeightOut, RgbnError> {
        let path = check_output(&p.path, ctx)?;
        write_value(
            &Value::Scalar(i.height.0.clone()),
            &path,
            &SaveOptions::default(),
        )?;
        Ok(SaveHeightOut { height: i.height })
    }
}

crate::inputs! {
    /// Inputs of [`SaveMesh`].
    pub struct SaveMeshIn {
        /// Height in pixels.
        pub height: Scalar,
        /// Colour, normals and mask (the height's size).
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of [`SaveMesh`].
    pub struct SaveMeshOut {
        /// Vertices written.
        pub vertices: f64,
        /// Triangles written.
        pub triangles: f64,
    }
}

/// Writes a grid mesh of a height and an image.
pub struct SaveMesh;

impl Operator for SaveMesh {
    type Params = SaveMeshSettings;
    type In = SaveMeshIn;
    type Out = SaveMeshOut;
    fn spec() -> OpSpec {
        OpSpec::new(
            "save.mesh",
            "Save mesh",
            "output",
            "Writes a triangle mesh of a height with the image's colours and normals (one vertex per pixel inside the mask; PLY or OBJ; x right, y up, z towards the viewer), atomically and never over a file the graph reads; runs whenever its output is requested.",
        )
        .side_effect()
    }
    fn check(p: &SaveMeshSettings) -> Result<(), RgbnError> {
        p.params().map(|_| ())
    }
    fn kind(_: &SaveMeshSettings) -> Kind {
        // Writes the whole mesh.
        Kind::GLOBAL
    }
    fn run(
        p: &SaveMeshSettings,
        i: SaveMeshIn,
        ctx: &RunContext,
    ) -> Result<SaveMeshOut, RgbnError> {
        let img = &i.image;
        let params = p.params_for(img.width(), img.height())?;
        let path = check_output(&p.path, ctx)?;
        let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
        let (v, t) = save_mesh(&i.height, img, &path, &protected, &params)?;
        Ok(SaveMeshOut {
            vertices: v as f64,
            triangles: t as f64,
        })
    }
}
