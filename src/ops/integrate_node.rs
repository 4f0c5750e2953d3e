//! Integration as nodes: normals → height ([`integrate_normals`]), the integrability projection
//! ([`project_integrable`]), and two writers: a height to EXR (`save.height`) and a height +
//! image to a mesh (`save.mesh`, [`save_mesh`]). The pure functions live in
//! [`crate::raster::integrate`] and [`crate::raster::mesh`]; the node layer stays in `ops`.

use super::params::{Meta, ParamVisitor, Params};
use super::save::write_value;
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::raster::integrate::{
    integrate_normals, project_integrable, IntegrateParams, IntegrationMethod, ProjectParams,
};
use crate::raster::io::{self, SaveOptions};
use crate::raster::mesh::{save_mesh, MeshFormat, MeshParams};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Method names, in [`IntegrationMethod`] order.
pub const METHODS: [&str; 3] = ["poisson_dct", "frankot_chellappa", "masked_poisson"];

/// Parameters of [`IntegrateNode`] and [`ProjectNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct IntegrateNodeParams {
    /// Method name ([`METHODS`]).
    pub method: &'static str,
    /// CG iteration cap.
    pub max_iterations: i64,
    /// CG tolerance.
    pub tolerance: f64,
}

impl Default for IntegrateNodeParams {
    fn default() -> Self {
        let d = IntegrateParams::default();
        Self {
            method: "poisson_dct",
            max_iterations: i64::from(d.max_iterations),
            tolerance: d.tolerance,
        }
    }
}

impl Params for IntegrateNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.choice(
            "method",
            &mut self.method,
            &METHODS,
            &Meta::new("poisson_dct: least squares, Neumann borders, DCT solver (mask ignored); frankot_chellappa: periodic borders, FFT; masked_poisson: only edges inside the image's mask, conjugate gradients."),
        );
        v.int(
            "max_iterations",
            &mut self.max_iterations,
            &Meta::new("Conjugate-gradient iteration cap (masked_poisson only).").range(1.0, 1e7),
        );
        v.float(
            "tolerance",
            &mut self.tolerance,
            &Meta::new("Stop when ‖b − Lz‖ ≤ tolerance·‖b‖ (masked_poisson only).")
                .range(1e-12, 0.5),
        );
    }
}

impl IntegrateNodeParams {
    fn to_params(&self) -> Result<IntegrateParams, RgbnError> {
        let method = match self.method {
            "frankot_chellappa" => IntegrationMethod::FrankotChellappa,
            "masked_poisson" => IntegrationMethod::MaskedPoisson,
            _ => IntegrationMethod::PoissonDct,
        };
        let p = IntegrateParams {
            method,
            max_iterations: u32::try_from(self.max_iterations)
                .map_err(|_| RgbnError::param("max_iterations", "out of range"))?,
            tolerance: self.tolerance,
        };
        p.validate()?;
        Ok(p)
    }
}

/// Normals → height.
pub struct IntegrateNode;

impl Operator for IntegrateNode {
    type Params = IntegrateNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "integrate",
            "Integrate to height",
            "analysis",
            "Integrates the normals' gradients to a height (least squares, Simchony et al. / Frankot & Chellappa / masked Poisson): zero mean over the domain, in pixels, y up.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image (its mask is the masked_poisson domain)."))
        .output(PortSpec::new("height", PortType::Scalar, "Height in pixels."))
        .output(PortSpec::new(
            "rms_residual",
            PortType::Number,
            "RMS over the domain's edges of ∇z − g in pixels per pixel: how far the field is from integrable.",
        ))
    }
    fn check(p: &IntegrateNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(
        p: &IntegrateNodeParams,
        i: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let (z, rep) = integrate_normals(i.rgbn("image")?, &p.to_params()?)?;
        Ok(vec![
            Value::Scalar(Arc::new(z)),
            Value::Number(rep.rms_residual),
        ])
    }
}

/// Integrability projection.
pub struct ProjectNode;

impl Operator for ProjectNode {
    type Params = IntegrateNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "project",
            "Integrability projection",
            "filter",
            "Replaces the normals by those of their integrated height: the nearest integrable field in the least-squares sense. Use after nonlinear edits (brush feathers, rotation combines) that left curl.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to project."))
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Projected normals; colour and mask unchanged.",
        ))
        .output(PortSpec::new("height", PortType::Scalar, "The integrated height in pixels."))
        .output(PortSpec::new(
            "curl_before",
            PortType::Number,
            "Relative RMS curl of the input (over the mask interior).",
        ))
        .output(PortSpec::new(
            "curl_after",
            PortType::Number,
            "Relative RMS curl of the output (≈ 0).",
        ))
    }
    fn check(p: &IntegrateNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(
        p: &IntegrateNodeParams,
        i: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let params = ProjectParams {
            integrate: p.to_params()?,
        };
        let (img, z, rep) = project_integrable(i.rgbn("image")?, &params)?;
        Ok(vec![
            Value::Rgbn(img),
            Value::Scalar(Arc::new(z)),
            Value::Number(rep.before.relative),
            Value::Number(rep.after.relative),
        ])
    }
}

fn check_output(path: &str, ctx: &RunContext) -> Result<PathBuf, RgbnError> {
    if path.is_empty() {
        return Err(RgbnError::param("path", "a file path is required"));
    }
    let path = PathBuf::from(path);
    let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
    io::check_output(&path, &protected)?;
    Ok(path)
}

/// Parameters of [`SaveHeight`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SaveHeightParams {
    /// Output `.exr`.
    pub path: String,
}

impl Params for SaveHeightParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.path(
            "path",
            &mut self.path,
            &Meta::new("Output .exr (one f32 channel Y).").output(),
        );
    }
}

/// Writes a height (any scalar field) to EXR.
pub struct SaveHeight;

impl Operator for SaveHeight {
    type Params = SaveHeightParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "save.height",
            "Save height",
            "output",
            "Writes a scalar field (a height, a curl map) to a single-channel f32 EXR, atomically and never over a file the graph reads, and passes it through; runs whenever its output is requested.",
        )
        .input(PortSpec::new("height", PortType::Scalar, "Field to write."))
        .output(PortSpec::new("height", PortType::Scalar, "The same field."))
        .side_effect()
    }
    fn check(p: &SaveHeightParams) -> Result<(), RgbnError> {
        if p.path.is_empty() {
            return Err(RgbnError::param("path", "a file path is required"));
        }
        if !p.path.to_ascii_lowercase().ends_with(".exr") {
            return Err(RgbnError::param("path", "a height is written as .exr"));
        }
        Ok(())
    }
    fn run(
        p: &SaveHeightParams,
        i: &Inputs<'_>,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        Self::check(p)?;
        let path = check_output(&p.path, ctx)?;
        let v = i
            .get("height")
            .ok_or_else(|| RgbnError::InvalidImage("input \"height\" is not connected".into()))?;
        write_value(v, &path, &SaveOptions::default())?;
        Ok(vec![v.clone()])
    }
}

/// Mesh format names.
pub const MESH_FORMATS: [&str; 3] = ["ply", "ply_ascii", "obj"];

/// Parameters of [`SaveMesh`].
#[derive(Clone, Debug, PartialEq)]
pub struct SaveMeshParams {
    /// Output file.
    pub path: String,
    /// Format name ([`MESH_FORMATS`]).
    pub format: &'static str,
    /// Height multiplier.
    pub z_scale: f64,
    /// Pixel spacing.
    pub pixel_size: f64,
}

impl Default for SaveMeshParams {
    fn default() -> Self {
        Self {
            path: String::new(),
            format: "ply",
            z_scale: 1.0,
            pixel_size: 1.0,
        }
    }
}

impl Params for SaveMeshParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.path(
            "path",
            &mut self.path,
            &Meta::new("Output mesh (.ply or .obj).").output(),
        );
        v.choice(
            "format",
            &mut self.format,
            &MESH_FORMATS,
            &Meta::new("ply (binary little-endian), ply_ascii, or obj (v x y z r g b, vn, f)."),
        );
        v.float(
            "z_scale",
            &mut self.z_scale,
            &Meta::new("Multiplies the height (relief exaggeration; not 0).").range(-1e6, 1e6),
        );
        v.float(
            "pixel_size",
            &mut self.pixel_size,
            &Meta::new("World size of one pixel.").range(1e-9, 1e9),
        );
    }
}

impl SaveMeshParams {
    fn to_params(&self) -> Result<MeshParams, RgbnError> {
        let format = match self.format {
            "ply_ascii" => MeshFormat::PlyAscii,
            "obj" => MeshFormat::Obj,
            _ => MeshFormat::PlyBinary,
        };
        let p = MeshParams {
            format,
            z_scale: self.z_scale as f32,
            pixel_size: self.pixel_size as f32,
        };
        p.validate()?;
        Ok(p)
    }
}

/// Writes a grid mesh of a height and an image.
pub struct SaveMesh;

impl Operator for SaveMesh {
    type Params = SaveMeshParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "save.mesh",
            "Save mesh",
            "output",
            "Writes a triangle mesh of a height with the image's colours and normals (one vertex per pixel inside the mask; PLY or OBJ; x right, y up, z towards the viewer), atomically and never over a file the graph reads; runs whenever its output is requested.",
        )
        .input(PortSpec::new("height", PortType::Scalar, "Height in pixels."))
        .input(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Colour, normals and mask (the height's size).",
        ))
        .output(PortSpec::new("vertices", PortType::Number, "Vertices written."))
        .output(PortSpec::new("triangles", PortType::Number, "Triangles written."))
        .side_effect()
    }
    fn check(p: &SaveMeshParams) -> Result<(), RgbnError> {
        if p.path.is_empty() {
            return Err(RgbnError::param("path", "a file path is required"));
        }
        p.to_params().map(|_| ())
    }
    fn run(p: &SaveMeshParams, i: &Inputs<'_>, ctx: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let params = p.to_params()?;
        let path = check_output(&p.path, ctx)?;
        let height = i
            .scalar("height")?
            .ok_or_else(|| RgbnError::InvalidImage("input \"height\" is not connected".into()))?;
        let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
        let (v, t) = save_mesh(height, i.rgbn("image")?, &path, &protected, &params)?;
        Ok(vec![Value::Number(v as f64), Value::Number(t as f64)])
    }
}
