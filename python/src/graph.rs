//! `rgbn.Graph`: a graph file, its parameters, and a lazy cache of node results that lives as
//! long as the object ([`Evaluator`]).

// Graph errors carry their location by value, as in the crate (cold paths).
#![allow(clippy::result_large_err)]

use crate::error::{graph_err, input};
use crate::image::{array2, Image};
use crate::params::{py_of, text_of};
use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rgbn::eval::{EvalOptions, EvalResult, Evaluator, Plan, Status};
use rgbn::graph::LoadedGraph;
use rgbn::nodes::{PortType, Value};
use rgbn::raster::Plane;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// A node graph (a ``.ron`` file) with a cache of node results.
///
/// ``Graph.load(path)`` reads and validates it; ``set("node.param", value)`` changes a parameter
/// (``node`` an id or a name, the value parsed as ``rgbn eval --set`` parses it);
/// ``eval(inputs, outputs)`` computes outputs. Results are cached by content (operator,
/// parameters, inputs), so a second ``eval`` after one ``set`` recomputes only the nodes
/// downstream of that parameter: ``hits`` and ``misses`` count the last evaluation.
#[pyclass(module = "rgbn")]
pub struct Graph {
    lg: LoadedGraph,
    ev: Arc<Evaluator>,
    last: Option<EvalResult>,
}

impl Graph {
    /// The validated graph with the parameters set on it.
    pub fn loaded(&self) -> &LoadedGraph {
        &self.lg
    }
}

/// A Python value as a graph value for an input of type `ty`.
fn input_value(
    py: Python<'_>,
    name: &str,
    ty: PortType,
    obj: &Bound<'_, PyAny>,
) -> PyResult<Value> {
    if let Ok(img) = obj.cast::<Image>() {
        return img.get().to_value(py);
    }
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        if a.ndim() == 2 && matches!(ty, PortType::Mask | PortType::Scalar) {
            let a = obj.cast::<PyArray2<f32>>().map_err(|_| {
                input(format!(
                    "graph input {name:?}: an H×W array must be float32"
                ))
            })?;
            let (h, w) = (a.shape()[0], a.shape()[1]);
            let data = py_vec(a)?;
            let p = Arc::new(Plane::from_vec(w, h, data).map_err(crate::error::rgbn_err)?);
            return Ok(if ty == PortType::Mask {
                Value::Mask(p)
            } else {
                Value::Scalar(p)
            });
        }
        if a.ndim() == 3 && ty == PortType::Rgbn {
            let img = Image::new(py, obj, None, None, false)?;
            return img.to_value(py);
        }
    }
    Err(input(format!(
        "graph input {name:?} takes {} values: give an rgbn.Image{}, or a file path",
        ty.name(),
        if ty == PortType::Rgbn {
            " (or an H×W×3 float32 normals array)"
        } else {
            " or an H×W float32 array"
        }
    )))
}

fn py_vec(a: &Bound<'_, PyArray2<f32>>) -> PyResult<Vec<f32>> {
    a.to_vec()
        .or_else(|_| Ok(a.to_owned_array().iter().copied().collect()))
}

/// A graph value as a Python object: `Image`, H×W float32 array, H×W×4 uint8 array or float.
pub fn output_value<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Rgbn(img) => {
            Bound::new(py, Image::planar(img.clone(), Default::default()))?.into_any()
        }
        Value::Mask(p) | Value::Scalar(p) => {
            array2(py, p.height(), p.width(), p.data().to_vec())?.into_any()
        }
        Value::Picture(p) => {
            let a = numpy::ndarray::Array::from_shape_vec((p.height, p.width, 4), p.rgba.clone())
                .map_err(|e| input(e.to_string()))?;
            PyArray3::from_owned_array(py, a).into_any()
        }
        Value::Number(x) => x.into_pyobject(py)?.into_any(),
    })
}

#[pymethods]
impl Graph {
    /// Reads and validates a graph file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let lg = py.detach(|| LoadedGraph::load(&path)).map_err(graph_err)?;
        Ok(Self {
            lg,
            ev: Arc::new(Evaluator::default()),
            last: None,
        })
    }

    /// Sets ``"node.param"`` (node id or name) to ``value`` — as ``rgbn eval --set
    /// node.param=value``; the graph is validated again.
    fn set(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut d = BTreeMap::new();
        d.insert(name.to_string(), value.clone());
        self.set_many(d)
    }

    /// Sets several parameters at once (``{"node.param": value}``), validated together.
    fn set_many(&mut self, values: BTreeMap<String, Bound<'_, PyAny>>) -> PyResult<()> {
        let mut sets = Vec::new();
        for (k, v) in &values {
            sets.push(format!("{k}={}", text_of(v)?));
        }
        rgbn::cli::apply_sets(&mut self.lg, &sets).map_err(crate::error::cli_err)
    }

    /// The value of ``"node.param"``.
    fn get<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let (node, param) = name
            .rsplit_once('.')
            .ok_or_else(|| input(format!("{name:?} is not of the form NODE.PARAM")))?;
        let id = self
            .lg
            .graph
            .find_node(node)
            .ok_or_else(|| input(format!("unknown node {node:?}: {}", self.lg.at())))?;
        let n = &self.lg.graph.nodes[&id];
        if let Some(v) = n.params.get(param) {
            return py_of(py, v);
        }
        match self.lg.param_info(id, param) {
            Some(info) => py_of(py, &info.default),
            None => Err(input(format!(
                "unknown parameter {param:?} of node {node:?}"
            ))),
        }
    }

    /// Graph inputs: ``{name: type}`` (``"rgbn"``, ``"mask"``, …).
    #[getter]
    fn inputs(&self) -> BTreeMap<String, &'static str> {
        self.lg
            .graph
            .inputs
            .iter()
            .map(|(n, d)| (n.clone(), d.ty.name()))
            .collect()
    }

    /// Graph outputs: ``{name: type}``.
    #[getter]
    fn outputs(&self) -> BTreeMap<String, &'static str> {
        self.lg
            .graph
            .outputs
            .keys()
            .map(|n| {
                (
                    n.clone(),
                    self.lg.output_type(n).map_or("?", PortType::name),
                )
            })
            .collect()
    }

    /// Evaluates the graph. ``inputs`` binds graph inputs to ``Image``s, arrays (masks) or
    /// file paths; ``outputs`` names the outputs wanted (all when ``None``); relative paths of
    /// ``save`` nodes are written under ``out_dir``. Returns ``{name: value}``: ``Image`` for
    /// images, H×W float32 arrays for masks and scalar fields, H×W×4 uint8 arrays for pictures,
    /// floats for numbers. The GIL is released while it runs; Ctrl-C raises
    /// ``KeyboardInterrupt`` (the evaluation stops before its next node and writes nothing more).
    #[pyo3(signature = (inputs=None, outputs=None, out_dir=None))]
    fn eval<'py>(
        &mut self,
        py: Python<'py>,
        inputs: Option<BTreeMap<String, Bound<'py, PyAny>>>,
        outputs: Option<Vec<String>>,
        out_dir: Option<PathBuf>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut files = BTreeMap::new();
        let mut values = BTreeMap::new();
        for (name, obj) in inputs.unwrap_or_default() {
            let is_path =
                obj.is_instance_of::<pyo3::types::PyString>() || obj.hasattr("__fspath__")?;
            if is_path {
                files.insert(name, PathBuf::from(text_of(&obj)?));
                continue;
            }
            let ty = self
                .lg
                .graph
                .inputs
                .get(&name)
                .map_or(PortType::Rgbn, |d| d.ty);
            values.insert(name.clone(), input_value(py, &name, ty, &obj)?);
        }
        let out_dir = out_dir.unwrap_or_else(|| PathBuf::from("."));
        let lg = &self.lg;
        let (plan, bindings) = py
            .detach(|| {
                let mut plan = Plan::new(lg, &files, &out_dir)?;
                let b = plan.bind_values(lg, values)?;
                Ok((plan, b))
            })
            .map_err(graph_err)?;
        let names = outputs.unwrap_or_default();
        let cancel = Arc::new(AtomicBool::new(false));
        let opts = EvalOptions {
            cancel: rgbn::cancel::Cancel::from_flag(cancel.clone()),
            ..EvalOptions::default()
        };
        let ev = self.ev.clone();
        let r = crate::run::interruptible(py, Some(cancel), move || {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let r = ev.eval(&plan, &names, &opts).map_err(graph_err);
            drop(bindings);
            r
        })?;
        let d = PyDict::new(py);
        for (name, v) in &r.outputs {
            d.set_item(name, output_value(py, v)?)?;
        }
        self.last = Some(r);
        Ok(d)
    }

    /// Nodes of the last evaluation served from the cache.
    #[getter]
    fn hits(&self) -> usize {
        self.last.as_ref().map_or(0, EvalResult::hits)
    }
    /// Nodes of the last evaluation computed (not cached).
    #[getter]
    fn misses(&self) -> usize {
        self.last.as_ref().map_or(0, EvalResult::misses)
    }
    /// Per node of the last evaluation: ``{"node", "name", "op", "status", "time_ms"}``
    /// (``status``: ``"hit"``, ``"miss"``, ``"disk"`` or ``"effect"``).
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let l = PyList::empty(py);
        for s in self.last.iter().flat_map(|r| &r.stats) {
            let d = PyDict::new(py);
            d.set_item("node", s.at.node)?;
            d.set_item("name", s.at.name.clone())?;
            d.set_item("file", s.at.file.clone())?;
            d.set_item("op", s.op)?;
            d.set_item(
                "status",
                match s.status {
                    Status::Hit => "hit",
                    Status::DiskHit => "disk",
                    Status::Miss => "miss",
                    Status::Effect => "effect",
                },
            )?;
            d.set_item("time_ms", s.time.as_secs_f64() * 1e3)?;
            l.append(d)?;
        }
        Ok(l)
    }
    /// Empties the cache of node results.
    fn clear_cache(&self) {
        self.ev.clear_memory();
    }
    fn __repr__(&self) -> String {
        format!(
            "rgbn.Graph({}: {} nodes)",
            self.lg.at().file,
            self.lg.graph.nodes.len()
        )
    }
}
