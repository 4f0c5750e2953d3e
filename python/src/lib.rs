//! `rgbn._rgbn`: the native half of the Python package `rgbn` (docs/python.md).
//!
//! Every function is a thin call into the `rgbn` crate — the same code the command line and the
//! graph nodes run: images through [`rgbn::raster::io`], graphs through
//! [`rgbn::graph::LoadedGraph`], [`rgbn::eval::Plan`] and [`rgbn::eval::Evaluator`], operators
//! through the registry ([`rgbn::nodes::registry`]) or the pure functions the nodes call.
//!
//! - `image`: the `Image` class (NumPy arrays in and out), `read`, `write`;
//! - `graph`: the `Graph` class (load, set, eval with a lazy cache it owns);
//! - `ops`: `ops()`, `run_op`, `filter`, `integrate`, `capture`, `render`, `info`, `main`;
//! - `error`: `rgbn.Error` and its subclasses, carrying the command line's one-line messages;
//! - `run`: work off the interpreter's lock, stopped by Ctrl-C (`KeyboardInterrupt`).

use pyo3::prelude::*;

mod dask;
mod error;
mod graph;
mod image;
mod ops;
mod params;
mod run;

// The allocator the `rgbn` binary installs: freed image-sized blocks are reused instead of
// being returned to the kernel and faulted in again (src/recycle.rs).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

#[pymodule]
fn _rgbn(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<error::Error>())?;
    m.add("InputError", py.get_type::<error::InputError>())?;
    m.add("FileError", py.get_type::<error::FileError>())?;
    m.add("EvalError", py.get_type::<error::EvalError>())?;
    m.add("RepairWarning", py.get_type::<error::RepairWarning>())?;
    m.add_class::<image::Image>()?;
    m.add_class::<graph::Graph>()?;
    m.add_function(wrap_pyfunction!(image::read, m)?)?;
    m.add_function(wrap_pyfunction!(image::read_color, m)?)?;
    m.add_function(wrap_pyfunction!(image::read_mask, m)?)?;
    m.add_function(wrap_pyfunction!(image::write, m)?)?;
    m.add_function(wrap_pyfunction!(image::planar_copies, m)?)?;
    m.add_function(wrap_pyfunction!(ops::ops, m)?)?;
    m.add_function(wrap_pyfunction!(ops::run_op, m)?)?;
    m.add_function(wrap_pyfunction!(ops::filter, m)?)?;
    m.add_function(wrap_pyfunction!(ops::integrate, m)?)?;
    m.add_function(wrap_pyfunction!(ops::integrate_depth, m)?)?;
    m.add_function(wrap_pyfunction!(ops::capture, m)?)?;
    m.add_function(wrap_pyfunction!(ops::render, m)?)?;
    m.add_function(wrap_pyfunction!(ops::info, m)?)?;
    m.add_function(wrap_pyfunction!(ops::main, m)?)?;
    m.add_function(wrap_pyfunction!(ops::_kernel_time, m)?)?;
    m.add_function(wrap_pyfunction!(dask::_dask_graph, m)?)?;
    m.add_function(wrap_pyfunction!(dask::_dask_plan, m)?)?;
    m.add_function(wrap_pyfunction!(dask::_dask_region, m)?)?;
    m.add_function(wrap_pyfunction!(dask::_dask_streams, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
