//! The operators: `ops()` (the registry's declarations, as `rgbn ops` prints them),
//! `run_op` (any registered node, by id), and the common cases as functions that call the same
//! Rust as the nodes and the command line: `filter` (`rgbn filter`), `integrate` (the
//! `integrate` node), `capture` (the `photometric_stereo` node's solver), `render`
//! (`rgbn render`), `info` (`rgbn info`), `main` (the command line itself).

use crate::error::{input, rgbn_err};
use crate::graph::output_value;
use crate::image::Image;
use crate::params::{py_of, values_of};
use crate::run::interruptible;
use numpy::prelude::*;
use numpy::{PyArray2, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rgbn::capture::inputs::{Lights, PhotoStack};
use rgbn::capture::photometric::{photometric_stereo, PhotometricParams, PsMethod};
use rgbn::nodes::{registry, DynOp, PortType, RunContext, Value};
use rgbn::ops::filter::{filter_normals, FilterOptions, Kernel};
use rgbn::params::{nearest, Choice, ParamKind, ParamValue};
use rgbn::raster::convolve::BorderMode;
use rgbn::raster::gradient::{Differences, GradientField};
use rgbn::raster::integrate::{
    green_convention, green_convention_fractions, GreenVerdict, Uncertainty,
};
use rgbn::render::{InspectParams, Light, Shading, View};
use std::collections::BTreeMap;

fn kind_name(k: &ParamKind) -> &'static str {
    match k {
        ParamKind::Bool => "bool",
        ParamKind::Int => "int",
        ParamKind::Float => "float",
        ParamKind::Choice(_) => "choice",
        ParamKind::Text => "text",
        ParamKind::Path => "path",
        ParamKind::Vec3 => "vec3",
        ParamKind::Floats => "floats",
        ParamKind::Profile => "profile",
        ParamKind::Points => "points",
        ParamKind::Paths => "paths",
    }
}

/// Every registered operator, from the same declarations as ``rgbn ops``: a list of dicts
/// ``{"id", "title", "category", "doc", "inputs", "outputs", "params"}``; ports are
/// ``{"name", "type", "optional", "doc"}``, parameters ``{"name", "kind", "choices", "unit",
/// "range", "default", "doc"}``.
#[pyfunction]
pub fn ops(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for op in registry() {
        let s = op.spec();
        let d = PyDict::new(py);
        d.set_item("id", s.id)?;
        d.set_item("title", s.title)?;
        d.set_item("category", s.category)?;
        d.set_item("doc", s.doc)?;
        for (key, ports) in [("inputs", &s.inputs), ("outputs", &s.outputs)] {
            let pl = PyList::empty(py);
            for p in ports {
                let pd = PyDict::new(py);
                pd.set_item("name", &p.name)?;
                pd.set_item("type", p.ty.name())?;
                pd.set_item("optional", p.optional)?;
                pd.set_item("doc", &p.doc)?;
                pl.append(pd)?;
            }
            d.set_item(key, pl)?;
        }
        let params = PyList::empty(py);
        for p in op.params() {
            let pd = PyDict::new(py);
            pd.set_item("name", p.name)?;
            pd.set_item("kind", kind_name(&p.kind))?;
            pd.set_item(
                "choices",
                match &p.kind {
                    ParamKind::Choice(o) => Some(o.clone()),
                    _ => None,
                },
            )?;
            pd.set_item("unit", p.meta.unit)?;
            pd.set_item("range", p.meta.range)?;
            pd.set_item("default", py_of(py, &p.default)?)?;
            pd.set_item("optional", p.meta.optional)?;
            pd.set_item("output", p.meta.output)?;
            pd.set_item("doc", p.meta.doc)?;
            params.append(pd)?;
        }
        d.set_item("params", params)?;
        list.append(d)?;
    }
    Ok(list)
}

fn find_op(id: &str) -> PyResult<&'static dyn DynOp> {
    rgbn::nodes::find(id).ok_or_else(|| {
        input(format!(
            "unknown operator {id:?}{}",
            nearest(id, registry().iter().map(|o| o.spec().id))
                .map(|s| format!(" (did you mean {s:?}?)"))
                .unwrap_or_default()
        ))
    })
}

/// A Python value for input port `name` of type `ty`.
fn port_value(py: Python<'_>, name: &str, ty: PortType, obj: &Bound<'_, PyAny>) -> PyResult<Value> {
    if let Ok(img) = obj.cast::<Image>() {
        if ty == PortType::Rgbn {
            return img.get().to_value(py);
        }
    }
    if ty == PortType::Number {
        return Ok(Value::Number(obj.extract()?));
    }
    if matches!(ty, PortType::Mask | PortType::Scalar) {
        if let Ok(a) = obj.cast::<PyArray2<f32>>() {
            let (h, w) = (a.shape()[0], a.shape()[1]);
            let data = a
                .to_vec()
                .or_else(|_| Ok::<_, PyErr>(a.to_owned_array().iter().copied().collect()))?;
            let p = std::sync::Arc::new(rgbn::Plane::from_vec(w, h, data).map_err(rgbn_err)?);
            return Ok(if ty == PortType::Mask {
                Value::Mask(p)
            } else {
                Value::Scalar(p)
            });
        }
    }
    if ty == PortType::Rgbn && obj.cast::<PyUntypedArray>().is_ok() {
        return Image::new(py, obj, None, None, false)?.to_value(py);
    }
    Err(input(format!(
        "input {name:?} takes a {} value: give {}",
        ty.name(),
        match ty {
            PortType::Rgbn => "an rgbn.Image",
            PortType::Mask | PortType::Scalar => "an H×W float32 array",
            PortType::Picture => "a picture",
            PortType::Number => "a number",
        }
    )))
}

/// Runs the registered operator ``op`` (its id, as in graph files and ``rgbn ops``) on
/// ``inputs`` (``{port: value}``) with parameters ``params`` (``{name: value}``, parsed as
/// ``rgbn eval --set`` parses them, unset ones at their defaults): the node's own code.
/// Returns ``{output port: value}``.
#[pyfunction]
#[pyo3(signature = (op, inputs=None, params=None))]
pub fn run_op<'py>(
    py: Python<'py>,
    op: &str,
    inputs: Option<BTreeMap<String, Bound<'py, PyAny>>>,
    params: Option<BTreeMap<String, Bound<'py, PyAny>>>,
) -> PyResult<Bound<'py, PyDict>> {
    let dynop = find_op(op)?;
    let values = run_values(
        py,
        dynop,
        inputs.unwrap_or_default(),
        &params.unwrap_or_default(),
    )?;
    let d = PyDict::new(py);
    for (port, v) in dynop.spec().outputs.iter().zip(&values) {
        d.set_item(&port.name, output_value(py, v)?)?;
    }
    Ok(d)
}

/// Runs `op` (without the GIL, interruptible) and returns its outputs in port order.
fn run_values<'py>(
    py: Python<'py>,
    op: &'static dyn DynOp,
    inputs: BTreeMap<String, Bound<'py, PyAny>>,
    params: &BTreeMap<String, Bound<'py, PyAny>>,
) -> PyResult<Vec<Value>> {
    let spec = op.spec();
    let values = values_of(spec.id, op.params(), params)?;
    run_parsed(py, op, inputs, values)
}

fn run_parsed<'py>(
    py: Python<'py>,
    op: &'static dyn DynOp,
    mut inputs: BTreeMap<String, Bound<'py, PyAny>>,
    values: BTreeMap<String, ParamValue>,
) -> PyResult<Vec<Value>> {
    let spec = op.spec();
    let parsed = op
        .parse(&values)
        .map_err(|e| input(format!("{e}: {}", spec.id)))?;
    let mut ins = Vec::with_capacity(spec.inputs.len());
    for p in &spec.inputs {
        ins.push(match inputs.remove(&p.name) {
            Some(obj) if !obj.is_none() => Some(port_value(py, &p.name, p.ty, &obj)?),
            _ if p.optional => None,
            _ => {
                return Err(input(format!(
                    "{} needs input {:?} ({})",
                    spec.id,
                    p.name,
                    p.ty.name()
                )))
            }
        });
    }
    if let Some(name) = inputs.keys().next() {
        return Err(input(format!(
            "{} has no input {name:?}{}",
            spec.id,
            nearest(name, spec.inputs.iter().map(|p| p.name.as_str()))
                .map(|s| format!(" (did you mean {s:?}?)"))
                .unwrap_or_default()
        )));
    }
    interruptible(py, None, move || {
        op.run(&parsed, ins, &RunContext::default())
            .map_err(rgbn_err)
    })
}

/// Filters the normals through their gradients with linear kernels, in order — ``rgbn filter
/// -k KERNEL``: ``gauss:SIGMA``, ``box:R``, ``sharpen:SIGMA,AMOUNT``,
/// ``edge:SIGMA_FINE,SIGMA_COARSE,AMOUNT``, ``highpass:SIGMA``, ``dog:SIGMA_FINE,SIGMA_COARSE``,
/// ``log:SIGMA``, ``scale:FACTOR``, ``sep:ROW/COL``, ``kernel:WxH:WEIGHTS``. ``border``:
/// mirror, clamp, wrap or zero; ``mask_aware``: normalised convolution inside the mask.
/// Returns a new ``Image`` (colour and mask shared).
#[pyfunction]
#[pyo3(signature = (image, kernels, *, border="mirror", mask_aware=false))]
pub fn filter(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    kernels: &Bound<'_, PyAny>,
    border: &str,
    mask_aware: bool,
) -> PyResult<Image> {
    let kernels: Vec<String> = match kernels.extract::<String>() {
        Ok(k) => vec![k],
        Err(_) => kernels.extract()?,
    };
    if kernels.is_empty() {
        return Err(input("filter needs at least one kernel"));
    }
    let kernels: Vec<Kernel> = kernels
        .iter()
        .map(|k| Kernel::parse(k))
        .collect::<Result<_, _>>()
        .map_err(rgbn_err)?;
    let border: BorderMode = border.parse().map_err(|e: String| input(e))?;
    let img = image_arg(py, image)?;
    let opts = FilterOptions { border, mask_aware };
    let (out, _report) = py
        .detach(|| filter_normals(&img, &kernels, &opts))
        .map_err(rgbn_err)?;
    Ok(Image::planar(out, Default::default()))
}

/// An `Image` argument (an H×W×3 float32 normals array is taken as `Image(normals)`).
fn image_arg(py: Python<'_>, obj: &Bound<'_, PyAny>) -> PyResult<rgbn::RgbnImage> {
    match obj.cast::<Image>() {
        Ok(img) => img.get().to_rgbn(py),
        Err(_) => Image::new(py, obj, None, None, false)?.to_rgbn(py),
    }
}

/// Integration parameters from the keyword arguments and a 3×3 `camera` matrix.
fn integrate_values(
    op: &'static dyn DynOp,
    method: &str,
    camera: Option<&Bound<'_, PyAny>>,
    params: &BTreeMap<String, Bound<'_, PyAny>>,
) -> PyResult<BTreeMap<String, ParamValue>> {
    let mut values = values_of("integrate", op.params(), params)?;
    values.insert("method".into(), ParamValue::Choice(method.into()));
    if let Some(k) = camera.filter(|c| !c.is_none()) {
        let k: Vec<Vec<f64>> = k
            .call_method0("tolist")
            .unwrap_or_else(|_| k.clone())
            .extract()
            .map_err(|_| input("camera must be a 3×3 intrinsic matrix K (rows of numbers)"))?;
        if k.len() != 3 || k.iter().any(|r| r.len() != 3) {
            return Err(input(
                "camera must be a 3×3 intrinsic matrix K (rows of numbers)",
            ));
        }
        // As a K file is read (`Pinhole::from_k_file`): fx = K[0][0], fy = K[1][1],
        // cx = K[0][2], cy = K[1][2].
        values.insert("camera".into(), ParamValue::Choice("pinhole".into()));
        values.insert("focal_px".into(), ParamValue::Float(k[0][0]));
        values.insert("focal_y_px".into(), ParamValue::Float(k[1][1]));
        values.insert("principal_centred".into(), ParamValue::Bool(false));
        values.insert("principal_x".into(), ParamValue::Float(k[0][2]));
        values.insert("principal_y".into(), ParamValue::Float(k[1][2]));
    }
    Ok(values)
}

fn integrate_run<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    method: &str,
    mask: Option<&Bound<'py, PyAny>>,
    camera: Option<&Bound<'py, PyAny>>,
    params: Option<BTreeMap<String, Bound<'py, PyAny>>>,
) -> PyResult<(Vec<Value>, bool)> {
    let op = find_op("integrate")?;
    let values = integrate_values(op, method, camera, &params.unwrap_or_default())?;
    let pinhole =
        matches!(values.get("camera"), Some(ParamValue::Choice(c)) if c != "orthographic");
    let mut img = image_arg(py, image)?;
    if let Some(m) = mask.filter(|m| !m.is_none()) {
        img = Image::planar(img, Default::default()).with_mask_value(py, m)?;
    }
    let mut inputs = BTreeMap::new();
    inputs.insert(
        "image".to_string(),
        Bound::new(py, Image::planar(img, Default::default()))?.into_any(),
    );
    Ok((run_parsed(py, op, inputs, values)?, pinhole))
}

/// Integrates the normals to a height (H×W float32, pixels, zero mean over the domain, y up)
/// — the ``integrate`` node. ``method``: poisson_dct, frankot_chellappa, masked_poisson or
/// bilateral (Cao et al. 2022, keeps depth discontinuities; over the mask). ``mask``: H×W
/// float32 domain (else the image's own). ``camera``: a 3×3 intrinsic matrix K for a pinhole
/// camera (the log-depth is integrated; the height is −Z up to scale). Other keyword arguments
/// are the node's parameters (``rgbn.ops()``), e.g. ``sharpness``, ``irls_iterations``,
/// ``tolerance``.
#[pyfunction]
#[pyo3(signature = (image, method="poisson_dct", *, mask=None, camera=None, **params))]
pub fn integrate<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    method: &str,
    mask: Option<&Bound<'py, PyAny>>,
    camera: Option<&Bound<'py, PyAny>>,
    params: Option<BTreeMap<String, Bound<'py, PyAny>>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (values, _) = integrate_run(py, image, method, mask, camera, params)?;
    output_value(py, &values[0])
}

/// The depth Z (H×W float32, camera units up to one scale: geometric mean ``fx`` over the
/// domain) of a pinhole integration: ``−integrate(..., camera=K)``. ``camera`` is required.
#[pyfunction]
#[pyo3(signature = (image, method="bilateral", *, camera, mask=None, **params))]
pub fn integrate_depth<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    method: &str,
    camera: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    params: Option<BTreeMap<String, Bound<'py, PyAny>>>,
) -> PyResult<Bound<'py, PyAny>> {
    if camera.is_none() {
        return Err(input(
            "integrate_depth needs camera=K (a 3×3 intrinsic matrix)",
        ));
    }
    let (values, pinhole) = integrate_run(py, image, method, mask, Some(camera), params)?;
    if !pinhole {
        return Err(input("integrate_depth needs a pinhole camera"));
    }
    let Value::Scalar(z) = &values[0] else {
        return Err(input("integrate gave no height"));
    };
    let depth: Vec<f32> = z.data().iter().map(|h| -h).collect();
    Ok(crate::image::array2(py, z.height(), z.width(), depth)?.into_any())
}

/// Photometric stereo from a stack of photos of one viewpoint — the ``photometric_stereo``
/// node's solver (Woodham 1980; ``method="trimmed"`` drops the darkest, brightest and
/// shadowed observations). ``photos``: N arrays H×W×3 float32 (linear), or one N×H×W×3 array;
/// ``lights``: N×3 directions (x right, y up, z towards the camera); ``intensities``: N×3 RGB
/// (all 1 when ``None``); ``mask``: H×W float32; ``exponent``: the shading exponent k of
/// ``I ∝ ρ (n·l)^k`` in [0.5, 2] (1 = Lambert), ``None`` estimates it from the photos (``rgbn
/// capture --exponent auto``). Returns an ``Image`` (albedo colour, normals, mask of the solved
/// pixels).
#[pyfunction]
#[pyo3(signature = (photos, lights, *, intensities=None, mask=None, method="trimmed", exponent=None))]
pub fn capture<'py>(
    py: Python<'py>,
    photos: &Bound<'py, PyAny>,
    lights: &Bound<'py, PyAny>,
    intensities: Option<&Bound<'py, PyAny>>,
    mask: Option<&Bound<'py, PyAny>>,
    method: &str,
    exponent: Option<f32>,
) -> PyResult<Image> {
    let method = PsMethod::from_name(method).ok_or_else(|| {
        input(format!(
            "unknown method {method:?}{} (methods: {})",
            nearest(method, PsMethod::names())
                .map(|s| format!(" (did you mean {s:?}?)"))
                .unwrap_or_default(),
            PsMethod::names().join(", ")
        ))
    })?;
    let rows = |obj: &Bound<'_, PyAny>, what: &str| -> PyResult<Vec<[f32; 3]>> {
        let v: Vec<Vec<f32>> = obj
            .call_method0("tolist")
            .unwrap_or_else(|_| obj.clone())
            .extract()
            .map_err(|_| input(format!("{what} must be N×3 numbers")))?;
        v.into_iter()
            .map(|r| {
                <[f32; 3]>::try_from(r.as_slice()).map_err(|_| {
                    input(format!(
                        "{what} must be N×3 numbers, got a row of {}",
                        r.len()
                    ))
                })
            })
            .collect()
    };
    let lights = Lights {
        directions: rows(lights, "lights")?,
        intensities: match intensities.filter(|i| !i.is_none()) {
            Some(i) => Some(rows(i, "intensities")?),
            None => None,
        },
    };
    let mut planes = Vec::new();
    let (mut w, mut h) = (0, 0);
    for (j, p) in photos.try_iter()?.enumerate() {
        let p = p?;
        let a = p
            .cast::<numpy::PyArray3<f32>>()
            .map_err(|_| input(format!("photo {j} must be an H×W×3 float32 array")))?;
        let s = a.shape();
        if s[2] != 3 {
            return Err(input(format!("photo {j} must be an H×W×3 float32 array")));
        }
        if j == 0 {
            (h, w) = (s[0], s[1]);
        } else if (s[0], s[1]) != (h, w) {
            return Err(input(format!(
                "photo {j} is {}×{}, photo 0 is {w}×{h}",
                s[1], s[0]
            )));
        }
        let data = a
            .to_vec()
            .or_else(|_| Ok::<_, PyErr>(a.to_owned_array().iter().copied().collect()))?;
        planes.push(py.detach(|| crate::image::split3(&data)));
    }
    let stack = PhotoStack::new(w, h, planes).map_err(rgbn_err)?;
    let mask: Option<Vec<f32>> = match mask.filter(|m| !m.is_none()) {
        Some(m) => {
            let m = m
                .cast::<PyArray2<f32>>()
                .map_err(|_| input("mask must be an H×W float32 array"))?;
            if m.shape() != [h, w] {
                return Err(input(format!(
                    "size mismatch: mask is {}×{} but the photos are {w}×{h}: mask",
                    m.shape()[1],
                    m.shape()[0]
                )));
            }
            Some(
                m.to_vec()
                    .or_else(|_| Ok::<_, PyErr>(m.to_owned_array().iter().copied().collect()))?,
            )
        }
        None => None,
    };
    let params = PhotometricParams {
        method,
        exponent,
        ..PhotometricParams::default()
    };
    let (img, _report) = interruptible(py, None, move || {
        photometric_stereo(&stack, &lights, mask.as_deref(), &params).map_err(rgbn_err)
    })?;
    Ok(Image::planar(img, Default::default()))
}

/// Renders an ``Image`` as an H×W×4 uint8 sRGB picture — ``rgbn render``: ``view`` (relit,
/// albedo, normals, curl, curvature, exaggerated, radiance_scaling, …), ``light`` one
/// direction (x, y, z towards the light) or a list of them, ``ambient``, ``specular``,
/// ``shininess``, ``exposure`` (stops); other keyword arguments are the view's parameters
/// (``rgbn render --param NAME=VALUE``).
#[pyfunction]
#[pyo3(signature = (image, *, view="relit", light=None, ambient=0.08, specular=0.25, shininess=40.0, exposure=0.0, **params))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    view: &str,
    light: Option<&Bound<'py, PyAny>>,
    ambient: f32,
    specular: f32,
    shininess: f32,
    exposure: f32,
    params: Option<BTreeMap<String, Bound<'py, PyAny>>>,
) -> PyResult<Bound<'py, PyAny>> {
    let view: View = view.parse().map_err(|e: String| input(e))?;
    let lights: Vec<[f32; 3]> = match light.filter(|l| !l.is_none()) {
        None => Vec::new(),
        Some(l) => {
            let l = l.call_method0("tolist").unwrap_or_else(|_| l.clone());
            match l.extract::<[f32; 3]>() {
                Ok(one) => vec![one],
                Err(_) => l
                    .extract::<Vec<[f32; 3]>>()
                    .map_err(|_| input("light must be (x, y, z) or a list of them"))?,
            }
        }
    };
    let shading = Shading {
        lights: if lights.is_empty() {
            Shading::default().lights
        } else {
            lights.iter().map(|d| Light::white(*d)).collect()
        },
        ambient,
        specular,
        shininess,
        exposure_ev: exposure,
    };
    shading.validate().map_err(rgbn_err)?;
    let mut assignments = Vec::new();
    for (k, v) in params.unwrap_or_default() {
        assignments.push(format!("{k}={}", crate::params::text_of(&v)?));
    }
    let vparams = InspectParams::from_assignments(&assignments).map_err(rgbn_err)?;
    let img = image_arg(py, image)?;
    let rgba = py
        .detach(|| rgbn::render::render_with(&img, view, &shading, &vparams))
        .map_err(rgbn_err)?;
    let a = numpy::ndarray::Array::from_shape_vec((img.height(), img.width(), 4), rgba)
        .map_err(|e| input(e.to_string()))?;
    Ok(numpy::PyArray3::from_owned_array(py, a).into_any())
}

/// What ``rgbn info`` prints, as a dict: size, mask, validation counts (as given, before any
/// repair), clamped pixels, RMS gradient, curl (relative RMS, RMS, max), the non-integrable
/// fraction ``F`` as read and with green flipped, and the green convention from local
/// integrability: ``green`` is ``"as read"``, ``"flipped"`` or ``"uncertain"``, with
/// ``green_reason`` (``"too little relief"``, ``"balanced"`` or ``None``), ``green_contrast``,
/// ``green_z``, ``relief_plaquettes``, ``islands_as_read``, ``islands_flipped`` and the line
/// ``rgbn info`` prints, ``green_line``.
#[pyfunction]
pub fn info<'py>(py: Python<'py>, image: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
    let (img, repaired) = match image.cast::<Image>() {
        Ok(i) => (i.get().to_rgbn(py)?, i.get().repaired_counts()),
        Err(_) => {
            let i = Image::new(py, image, None, None, false)?;
            (i.to_rgbn(py)?, i.repaired_counts())
        }
    };
    let (g, c, fr, gc) = py
        .detach(|| {
            let g = GradientField::from_normals(&img);
            let c = g.curl_stats_of(Differences::Averaged, img.mask());
            green_convention_fractions(&img).map(|f| (g, c, f, green_convention(&img)))
        })
        .map_err(rgbn_err)?;
    let d = PyDict::new(py);
    d.set_item("width", img.width())?;
    d.set_item("height", img.height())?;
    d.set_item("mask", img.mask().is_some())?;
    d.set_item("validation", crate::image::validation_dict(py, &repaired)?)?;
    d.set_item("clamped", g.clamped)?;
    d.set_item("rms_gradient", c.rms_gradient)?;
    d.set_item("curl_relative", c.relative)?;
    d.set_item("curl_rms", c.rms_curl)?;
    d.set_item("curl_max", c.max_abs_curl)?;
    d.set_item("F", fr[0])?;
    d.set_item("F_green_flipped", fr[1])?;
    let (green, reason) = match gc.verdict {
        GreenVerdict::OpenGl => ("as read", None),
        GreenVerdict::DirectX => ("flipped", None),
        GreenVerdict::Uncertain(Uncertainty::TooLittleRelief) => {
            ("uncertain", Some("too little relief"))
        }
        GreenVerdict::Uncertain(Uncertainty::Balanced) => ("uncertain", Some("balanced")),
    };
    d.set_item("green", green)?;
    d.set_item("green_reason", reason)?;
    d.set_item("green_contrast", gc.evidence.contrast)?;
    d.set_item("green_z", gc.evidence.z)?;
    d.set_item("relief_plaquettes", gc.evidence.relief_plaquettes)?;
    d.set_item("islands_as_read", gc.evidence.islands_as_read)?;
    d.set_item("islands_flipped", gc.evidence.islands_flipped)?;
    d.set_item("green_line", gc.describe("OpenGL (+y)", "DirectX (-y)"))?;
    Ok(d)
}

/// Runs the command line in this process (``rgbn ARGS…``) and returns its exit code — the
/// ``rgbn`` console script. It installs the command line's Ctrl-C handler: meant for a process
/// of its own, not inside an interactive session.
#[pyfunction]
pub fn main(py: Python<'_>, args: Vec<String>) -> i32 {
    let argv: Vec<String> = std::iter::once("rgbn".to_string()).chain(args).collect();
    let code = py.detach(|| rgbn::cli::run(argv));
    i32::from(u8::from(code))
}

/// Benchmark helper (``bench/bench_calls.py``): the mean time in nanoseconds of
/// `filter_normals(image, kernel)` called `repeats` times inside Rust — the kernel without the
/// Python call around it.
#[pyfunction]
pub fn _kernel_time(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    kernel: &str,
    repeats: u32,
) -> PyResult<f64> {
    let k = [Kernel::parse(kernel).map_err(rgbn_err)?];
    let img = image_arg(py, image)?;
    let opts = FilterOptions {
        border: BorderMode::Mirror,
        mask_aware: false,
    };
    py.detach(|| {
        let t = std::time::Instant::now();
        for _ in 0..repeats.max(1) {
            std::hint::black_box(filter_normals(&img, &k, &opts)?);
        }
        Ok(t.elapsed().as_nanos() as f64 / f64::from(repeats.max(1)))
    })
    .map_err(rgbn_err)
}
