//! Integration as nodes: normals → height ([`integrate_normals`]), the integrability projection
//! ([`project_integrable`]), and two writers: a height to EXR (`save.height`) and a height +
//! image to a mesh (`save.mesh`, [`save_mesh`]). The pure functions live in
//! [`crate::raster::integrate`] and [`crate::raster::mesh`], the parameters in
//! [`crate::ops::integrate`].

use super::save::write_value;
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::integrate::{CameraModel, IntegrateSettings, SaveHeightParams, SaveMeshSettings};
use crate::raster::integrate::{
    integrate_normals, project_integrable, IntegrationMethod, ProjectParams,
};
use crate::raster::io::{self, SaveOptions};
use crate::raster::mesh::save_mesh;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The integration's form at a level of detail (the normals reduced by `s`): lengths in pixels
/// divided by `s` (a pinhole's focal lengths and principal point), and the bilateral sharpness
/// times `s²`, so that a depth jump of `J` pixels, `J/s` on the coarse grid, is weighed as at
/// full resolution. A K file has no such form (it states full-resolution pixels).
fn integrate_at_level(p: &IntegrateSettings, s: f64) -> Option<IntegrateSettings> {
    if p.camera == CameraModel::KFile {
        return None;
    }
    let [principal_x, principal_y] = super::scale_point([p.principal_x, p.principal_y], s);
    Some(IntegrateSettings {
        focal_px: p.focal_px / s,
        focal_y_px: p.focal_y_px / s,
        principal_x,
        principal_y,
        sharpness: if p.method == IntegrationMethod::Bilateral {
            p.sharpness * s * s
        } else {
            p.sharpness
        },
        ..p.clone()
    })
}

/// Output `k` (a height in coarse pixels) multiplied by `s`: full-resolution pixels.
fn height_times(mut outputs: Vec<Value>, k: usize, s: f64) -> Vec<Value> {
    if let Some(Value::Scalar(z)) = outputs.get_mut(k) {
        let mut z2 = (**z).clone();
        let s = s as f32;
        z2.data_mut().iter_mut().for_each(|v| *v *= s);
        *z = Arc::new(z2);
    }
    outputs
}

/// Normals → height.
pub struct IntegrateNode;

impl Operator for IntegrateNode {
    type Params = IntegrateSettings;
    /// Working memory: the solvers' f64 vectors and transforms: up to ≈ 96 bytes per pixel over a 4-byte height (measured peak RSS of graphs/integrate.ron on a 2048² demo: 453 MB).
    const SCRATCH: f64 = 24.0;
    fn spec() -> OpSpec {
        OpSpec::new(
            "integrate",
            "Integrate to height",
            "analysis",
            "Integrates the normals' gradients to a height (least squares, Simchony et al. / Frankot & Chellappa / masked Poisson; bilateral normal integration, Cao et al. 2022, keeps depth discontinuities): zero mean over the domain, in pixels, y up. With a pinhole camera (focal length and principal point, or a K file) the log-depth is integrated and the height is −Z for a depth Z up to scale.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image (its mask is the masked_poisson domain)."))
        .output(PortSpec::new(
            "height",
            PortType::Scalar,
            "Height in pixels (orthographic), or −Z for the depth Z (pinhole; geometric mean focal_px over the domain).",
        ))
        .output(PortSpec::new(
            "rms_residual",
            PortType::Number,
            "RMS over the domain's edges of ∇z − g in pixels per pixel: how far the field is from integrable.",
        ))
    }
    fn check(p: &IntegrateSettings) -> Result<(), RgbnError> {
        p.params().map(|_| ())
    }
    fn scaled(p: &IntegrateSettings, s: f64) -> Option<IntegrateSettings> {
        integrate_at_level(p, s)
    }
    fn level_outputs(_: &IntegrateSettings, s: f64, outputs: Vec<Value>) -> Vec<Value> {
        height_times(outputs, 0, s)
    }
    fn run(p: &IntegrateSettings, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let (z, rep) = integrate_normals(img, &p.params_for(img.width(), img.height())?)?;
        Ok(vec![
            Value::Scalar(Arc::new(z)),
            Value::Number(rep.rms_residual),
        ])
    }
}

/// Integrability projection.
pub struct ProjectNode;

impl Operator for ProjectNode {
    type Params = IntegrateSettings;
    /// Working memory: the integration's buffers over the RGBN and height outputs.
    const SCRATCH: f64 = 2.0;
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
    fn check(p: &IntegrateSettings) -> Result<(), RgbnError> {
        p.params().map(|_| ())
    }
    fn scaled(p: &IntegrateSettings, s: f64) -> Option<IntegrateSettings> {
        integrate_at_level(p, s)
    }
    fn level_outputs(_: &IntegrateSettings, s: f64, outputs: Vec<Value>) -> Vec<Value> {
        height_times(outputs, 1, s)
    }
    fn run(p: &IntegrateSettings, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let params = ProjectParams {
            integrate: p.params_for(img.width(), img.height())?,
        };
        let (img, z, rep) = project_integrable(img, &params)?;
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

/// Writes a grid mesh of a height and an image.
pub struct SaveMesh;

impl Operator for SaveMesh {
    type Params = SaveMeshSettings;
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
    fn check(p: &SaveMeshSettings) -> Result<(), RgbnError> {
        if p.path.is_empty() {
            return Err(RgbnError::param("path", "a file path is required"));
        }
        p.params().map(|_| ())
    }
    fn run(
        p: &SaveMeshSettings,
        i: &Inputs<'_>,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let params = p.params_for(img.width(), img.height())?;
        let path = check_output(&p.path, ctx)?;
        let height = i
            .scalar("height")?
            .ok_or_else(|| RgbnError::InvalidImage("input \"height\" is not connected".into()))?;
        let protected: Vec<&Path> = ctx.protected.iter().map(PathBuf::as_path).collect();
        let (v, t) = save_mesh(height, img, &path, &protected, &params)?;
        Ok(vec![Value::Number(v as f64), Value::Number(t as f64)])
    }
}
