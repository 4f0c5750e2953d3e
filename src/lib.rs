//! # rgbn — editing RGBN images (colour + normals) without breaking integrability
//!
//! An RGBN image holds linear colour and a unit surface normal per pixel. rgbn edits the
//! normals through their foreshorten-corrected gradients `(p, q) = (−n_x/n_z, −n_y/n_z)`, after
//! Pereira & Velho, "RGBN image editing", so that linear edits keep the field integrable, and it
//! reports integrability as curl everywhere.
//!
//! Modules:
//! - [`params`](mod@params): parameters declared once ([`params!`], [`choice_enum!`]): the visitor every
//!   consumer (files, `--set`, `rgbn ops`, the editor's widgets) walks.
//! - [`raster`]: the image model ([`RgbnImage`]), file I/O, gradient maths and curl,
//!   convolution kernels, built-in sample and analytic surfaces.
//! - [`capture`]: photometric stereo and light calibration (photos → RGBN).
//! - [`ops`]: the pure operators (filters, combines, pen, …; no graph types) and their
//!   parameters.
//! - [`nodes`]: each operator's node form ([`nodes::Operator`], [`nodes::OpSpec`], typed ports)
//!   and the registry.
//! - [`graph`]: graphs of nodes, the versioned RON file format, validation.
//! - [`eval`]: the lazy, content-keyed, cached evaluator.
//! - [`render`]: relighting and the diagnostic views.
//! - [`gallery`]: the paper's figures as graphs, their pictures and numbers (`docs/gallery.md`).
//! - [`cli`]: the command line (used by the `rgbn` binary).
//! - [`cancel`]: the cancellation token long kernels check ([`cancel::Cancel`]).
//! - [`recycle`]: the global allocator the binary installs (reuses image-sized blocks).
//! - `app` (feature `gui`): the egui editor, the only module that uses egui.
//!
//! The library never depends on the GUI: build with `--no-default-features` for the core.
//!
//! ## Layers
//!
//! The modules form layers, listed bottom first on the line below; a module uses only modules
//! listed before it (`tests/it/layers.rs` checks every `crate::` path in `src/` against it):
//!
//! ```text
//! layers: error cancel test_data recycle params raster capture render ops nodes graph eval gallery app cli
//! ```

#[cfg(feature = "gui")]
pub mod app;
pub mod cancel;
pub mod capture;
pub mod cli;
pub mod error;
pub mod eval;
pub mod gallery;
pub mod graph;
pub mod nodes;
pub mod ops;
pub mod params;
pub mod raster;
pub mod recycle;
pub mod render;
#[doc(hidden)]
pub mod test_data;

pub use error::RgbnError;
pub use raster::gradient::GradientField;
pub use raster::{Plane, RgbnImage};
