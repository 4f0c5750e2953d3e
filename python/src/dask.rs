//! The native half of `rgbn.dask` (python/rgbn/dask.py): what one Dask task and the client
//! that builds the task graph need from the engine. No scheduling here — Dask's scheduler runs
//! the tasks.
//!
//! - [`_dask_graph`]: a graph (a file, or an `rgbn.Graph` with its parameters) as RON text
//!   and the folder its relative paths are relative to, so that a worker process rebuilds the
//!   very graph the client has;
//! - [`_dask_plan`]: on the client, before any task: the outputs' whole sizes at the level, and
//!   the refusal of a graph whose outputs depend on a global operator;
//! - [`_dask_region`]: one task: the graph evaluated over one chunk-aligned rectangle with the
//!   engine's region plan (the plan of `rgbn eval --region`: tiles plus every operator's halo,
//!   input stores read only in the chunks that cover it), each output written into its store's
//!   chunks of the rectangle (atomically; the store is created race-safely when missing), or
//!   returned as arrays for the lazy form.

// Graph errors carry their location by value, as in the crate (cold paths).
#![allow(clippy::result_large_err)]

use crate::error::{graph_err, input, rgbn_err};
use crate::graph::{output_value, Graph};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rgbn::eval::plan::Conn;
use rgbn::eval::region::RegionOptions;
use rgbn::eval::zarr_sink::{stream_region_into_stores, streams_in_windows};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::{GraphError, LoadedGraph};
use rgbn::nodes::{Kind, PortType, Value};
use rgbn::raster::io::zarr::ZarrOptions;
use rgbn::raster::window::Rect;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The graph as `(ron_text, label, base_dir)`: a path is read and `sets` (``NODE.PARAM=VALUE``)
/// applied; an `rgbn.Graph` is taken with the parameters set on it (then `sets` on top).
#[pyfunction]
#[pyo3(signature = (graph, sets=Vec::new()))]
pub fn _dask_graph(
    py: Python<'_>,
    graph: &Bound<'_, PyAny>,
    sets: Vec<String>,
) -> PyResult<(String, String, PathBuf)> {
    let mut lg = if let Ok(g) = graph.cast::<Graph>() {
        g.borrow().loaded().clone()
    } else {
        let path: PathBuf = graph
            .extract()
            .map_err(|_| input("graph: give a graph file path (.ron) or an rgbn.Graph"))?;
        py.detach(|| LoadedGraph::load(&path)).map_err(graph_err)?
    };
    rgbn::cli::apply_sets(&mut lg, &sets).map_err(crate::error::cli_err)?;
    let label = lg.at().file;
    Ok((lg.to_text(), label, lg.base_dir.clone()))
}

fn loaded(text: &str, label: &str, base_dir: &Path) -> Result<LoadedGraph, GraphError> {
    LoadedGraph::from_text(text, label, base_dir.to_path_buf())
}

fn plan_of(
    lg: &LoadedGraph,
    inputs: &BTreeMap<String, PathBuf>,
    base_dir: &Path,
) -> Result<Plan, GraphError> {
    Plan::new(lg, inputs, base_dir)
}

/// The instances output `name` depends on (its own included).
fn upstream(plan: &Plan, name: &str) -> Vec<usize> {
    let mut seen = vec![false; plan.instances.len()];
    let mut stack: Vec<usize> = match plan.outputs.get(name) {
        Some(Conn::Slot(i, _)) => vec![*i],
        _ => Vec::new(),
    };
    let mut out = Vec::new();
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut seen[i], true) {
            continue;
        }
        out.push(i);
        for c in &plan.instances[i].inputs {
            if let Conn::Slot(j, _) = c {
                stack.push(*j);
            }
        }
    }
    out
}

/// An output's `(width, height, type, channels)` at a level.
type OutputShape = (usize, usize, &'static str, usize);

/// Client side, before any task: `{output: (width, height, type, channels)}` at `level`, for
/// the outputs named (every image-like output when none is). A graph whose outputs depend on a global operator (one that needs its input whole:
/// integration, the integrability projection, statistics) is refused with an `InputError`
/// naming the node and saying what to do; files read whole by `load` nodes are not refused
/// (each task reads them, which costs their decoding per task).
#[pyfunction]
pub fn _dask_plan(
    py: Python<'_>,
    graph: (String, String, PathBuf),
    inputs: BTreeMap<String, PathBuf>,
    outputs: Vec<String>,
    level: u32,
) -> PyResult<BTreeMap<String, OutputShape>> {
    let (text, label, base) = graph;
    // Each OME-Zarr input is opened here, on the client, so a store that is not one (a plain
    // Zarr array, a missing folder) is an error naming the store before any task is built.
    for path in inputs.values() {
        if matches!(
            rgbn::raster::io::Format::of(path),
            Ok(rgbn::raster::io::Format::Zarr)
        ) {
            rgbn::raster::io::zarr::ZarrImage::open(path).map_err(rgbn_err)?;
        }
    }
    let lg = loaded(&text, &label, &base).map_err(graph_err)?;
    let plan = plan_of(&lg, &inputs, &base).map_err(graph_err)?;
    let outputs: Vec<String> = if outputs.is_empty() {
        plan.output_types
            .iter()
            .filter(|(_, t)| **t != PortType::Number)
            .map(|(n, _)| n.clone())
            .collect()
    } else {
        outputs
    };
    let mut sizes = BTreeMap::new();
    for name in &outputs {
        if !plan.outputs.contains_key(name) {
            let known: Vec<&str> = plan.outputs.keys().map(String::as_str).collect();
            return Err(input(format!(
                "unknown graph output {name:?} of {}: the graph's outputs are {}",
                label,
                known.join(", ")
            )));
        }
        let ty = plan.output_types.get(name).copied();
        if ty == Some(PortType::Number) {
            return Err(input(format!(
                "graph output {name:?} of {label} is a number, which has no chunks: rgbn.dask writes image, mask, field and picture outputs"
            )));
        }
        for i in upstream(&plan, name) {
            let inst = &plan.instances[i];
            if matches!(inst.op.kind(&inst.params), Kind::Global { .. })
                && !inst.op.spec().id.starts_with("load")
            {
                return Err(input(format!(
                    "{} ({}) is a global operator: it needs its whole input, so output {name:?} cannot be computed chunk by chunk on a cluster. Evaluate the graph at a level on one machine (rgbn eval --level K, or rgbn.dask.evaluate(..., level=K) after cutting), or cut the graph before that node: compute its input with rgbn.dask, run the global node on one machine, and distribute what follows it",
                    inst.at, inst.op.spec().id
                )));
            }
        }
        let ev = Evaluator::default();
        let ropts = RegionOptions { tile: 16, level };
        let r = py
            .detach(|| {
                ev.eval_region(
                    &plan,
                    name,
                    Rect::new(0, 0, 1, 1),
                    &ropts,
                    &EvalOptions::default(),
                )
            })
            .map_err(graph_err)?;
        let channels = match &r.value {
            Value::Rgbn(img) => 6 + usize::from(img.mask().is_some()),
            Value::Picture(_) => 4,
            _ => 1,
        };
        sizes.insert(
            name.clone(),
            (r.size.0, r.size.1, ty.map_or("?", PortType::name), channels),
        );
    }
    Ok(sizes)
}

/// Runs `f` on a rayon pool of `threads` threads (the task's share of its worker), without
/// the interpreter's lock.
fn on_pool<T: Send>(py: Python<'_>, threads: usize, f: impl FnOnce() -> T + Send) -> PyResult<T> {
    // One pool per thread count for the life of the worker process: a task starts no threads,
    // and the pool's threads keep their scratch buffers from one task to the next.
    static POOLS: std::sync::OnceLock<
        parking_lot::Mutex<BTreeMap<usize, std::sync::Arc<rayon::ThreadPool>>>,
    > = std::sync::OnceLock::new();
    // A Dask worker's allocator is set to hand freed memory back at once (its nanny sets
    // MALLOC_TRIM_THRESHOLD_=65536, which also pins glibc's mmap threshold at 128 KiB): every
    // chunk buffer of every task was then a fresh mapping, page-faulted and zero-filled (half
    // the workers' time was system time; BENCHMARKS.md, "rgbn.dask on 16384²"). A task keeps
    // freed memory for the next, as the command line does (`recycle::keep_freed_memory`).
    static KEEP: std::sync::Once = std::sync::Once::new();
    KEEP.call_once(rgbn::recycle::keep_freed_memory);
    let threads = threads.max(1);
    let pool = {
        let mut pools = POOLS.get_or_init(Default::default).lock();
        match pools.get(&threads) {
            Some(p) => p.clone(),
            None => {
                let p = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|i| format!("rgbn-task-{i}"))
                    .build()
                    .map_err(|e| {
                        crate::error::EvalError::new_err(format!("cannot start threads: {e}"))
                    })?;
                let p = std::sync::Arc::new(p);
                pools.insert(threads, p.clone());
                p
            }
        }
    };
    Ok(py.detach(move || pool.install(f)))
}

/// Client side: whether the tasks of `outputs` stream ([`stream_region_into_stores`]): then a task's memory
/// does not grow with its side, and the client picks large tasks.
#[pyfunction]
pub fn _dask_streams(
    py: Python<'_>,
    graph: (String, String, PathBuf),
    inputs: BTreeMap<String, PathBuf>,
    outputs: Vec<String>,
) -> PyResult<bool> {
    let (text, label, base) = graph;
    py.detach(|| {
        let lg = loaded(&text, &label, &base).map_err(graph_err)?;
        let plan = plan_of(&lg, &inputs, &base).map_err(graph_err)?;
        let asked: Vec<&str> = outputs.iter().map(String::as_str).collect();
        streams_in_windows(&plan, &asked).map_err(graph_err)
    })
}

/// What stops a streamed task: the graph's error, or writing its chunks.
enum TaskError {
    Graph(GraphError),
    Py(PyErr),
}

impl From<GraphError> for TaskError {
    fn from(e: GraphError) -> Self {
        TaskError::Graph(e)
    }
}

impl From<rgbn::RgbnError> for TaskError {
    fn from(e: rgbn::RgbnError) -> Self {
        TaskError::Py(rgbn_err(e))
    }
}

impl From<TaskError> for PyErr {
    fn from(e: TaskError) -> Self {
        match e {
            TaskError::Graph(g) => graph_err(g),
            TaskError::Py(p) => p,
        }
    }
}

/// One task: the graph over `region` (x, y, w, h, in the level's pixels) at `level`. With
/// `outputs` mapping names to store paths, each output's chunks of the region are written
/// (chunk side `chunk`; at most `levels` pyramid levels, every level when `None`) and `None`
/// is returned; with `outputs` a list of names, returns `{name: value}` over the region
/// (`rgbn.Image`, H×W float32, H×W×4 uint8).
#[pyfunction]
#[pyo3(signature = (graph, inputs, outputs, region, level=0, chunk=512, tile=512, threads=1, levels=None))]
#[allow(clippy::too_many_arguments)]
pub fn _dask_region<'py>(
    py: Python<'py>,
    graph: (String, String, PathBuf),
    inputs: BTreeMap<String, PathBuf>,
    outputs: &Bound<'py, PyAny>,
    region: (usize, usize, usize, usize),
    level: u32,
    chunk: usize,
    tile: usize,
    threads: usize,
    levels: Option<usize>,
) -> PyResult<Option<Bound<'py, PyDict>>> {
    if levels == Some(0) {
        return Err(input("levels: at least 1 (level 0 alone), or None for every level"));
    }
    let (text, label, base) = graph;
    let files: Option<BTreeMap<String, PathBuf>> = outputs.extract().ok();
    let names: Vec<String> = match &files {
        Some(f) => f.keys().cloned().collect(),
        None => outputs
            .extract()
            .map_err(|_| input("outputs: a dict {name: store path} or a list of names"))?,
    };
    let rect = Rect::new(region.0, region.1, region.2, region.3);
    let zopts = ZarrOptions {
        chunk,
        levels,
        ..ZarrOptions::default()
    };
    let ropts = RegionOptions { tile, level };
    let run = || -> Result<Vec<(String, Value)>, PyErr> {
        let lg = loaded(&text, &label, &base).map_err(graph_err)?;
        let plan = plan_of(&lg, &inputs, &base).map_err(graph_err)?;
        if let Some(files) = &files {
            let protected: Vec<&Path> = plan.protected.iter().map(PathBuf::as_path).collect();
            for p in files.values() {
                rgbn::raster::io::check_output(p, &protected).map_err(rgbn_err)?;
            }
        }
        if let Some(files) = &files {
            // Streamed when it can be (`stream_region_into_stores`): a task's memory is then a
            // few strips of its window, whatever its side.
            let outs: Vec<(String, PathBuf)> = names
                .iter()
                .map(|n| (n.clone(), files[n].clone()))
                .collect();
            let cancel = rgbn::cancel::Cancel::default();
            if level == 0
                && stream_region_into_stores::<TaskError>(&plan, &outs, rect, &zopts, &cancel)?
            {
                return Ok(Vec::new());
            }
        }
        let ev = Evaluator::default();
        let mut kept: Vec<(String, Value)> = Vec::new();
        for name in &names {
            let r = ev
                .eval_region(&plan, name, rect, &ropts, &EvalOptions::default())
                .map_err(graph_err)?;
            match files.as_ref().and_then(|f| f.get(name)) {
                Some(path) => rgbn::nodes::save::write_value_zarr(
                    &r.value,
                    path,
                    &zopts,
                    Some((r.size, r.rect)),
                )
                .map_err(rgbn_err)?,
                None => kept.push((name.clone(), r.value)),
            }
        }
        Ok(kept)
    };
    let kept = on_pool(py, threads, run)??;
    if files.is_some() {
        return Ok(None);
    }
    let d = PyDict::new(py);
    for (name, v) in &kept {
        d.set_item(name, output_value(py, v)?)?;
    }
    Ok(Some(d))
}
