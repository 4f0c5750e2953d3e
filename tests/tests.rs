//! The integration tests: one binary, one module per area (add yours with another `#[path]`).

#[path = "it/common.rs"]
mod common;

#[path = "it/cli_core.rs"]
mod cli_core;
#[path = "it/green_maps.rs"]
mod green_maps;
#[path = "it/real_data.rs"]
mod real_data;

#[path = "it/graphs.rs"]
mod graphs;

#[path = "it/op_versions.rs"]
mod op_versions;

#[path = "it/gallery.rs"]
mod gallery;

#[path = "it/golden.rs"]
mod golden;

#[path = "it/graph_errors.rs"]
mod graph_errors;

#[path = "it/structure.rs"]
mod structure;

#[path = "it/cache.rs"]
mod cache;

#[path = "it/cancel.rs"]
mod cancel;

#[path = "it/combine.rs"]
mod combine;

#[path = "it/cli.rs"]
mod cli;

#[path = "it/cli_errors.rs"]
mod cli_errors;

#[cfg(feature = "gui")]
#[path = "it/editor.rs"]
mod editor;

#[cfg(feature = "gui")]
#[path = "it/editor_images.rs"]
mod editor_images;

#[cfg(feature = "gui")]
#[path = "it/editor_start.rs"]
mod editor_start;

#[cfg(feature = "gui")]
#[path = "it/editor_menu.rs"]
mod editor_menu;

#[path = "it/nodes.rs"]
mod nodes;

#[path = "it/capture.rs"]
mod capture;

#[path = "it/readme.rs"]
mod readme;

#[path = "it/ptm.rs"]
mod ptm;

#[path = "it/publish.rs"]
mod publish;

#[path = "it/publish_web.rs"]
mod publish_web;

#[path = "it/views.rs"]
mod views;

#[path = "it/nan_ops.rs"]
mod nan_ops;

#[path = "it/sliders.rs"]
mod sliders;

#[path = "it/faults.rs"]
mod faults;

#[path = "it/memory.rs"]
mod memory;

#[path = "it/stamp_regions.rs"]
mod stamp_regions;

#[path = "it/extract.rs"]
mod extract;

#[path = "it/pen_patterns.rs"]
mod pen_patterns;

#[path = "it/pen_paths.rs"]
mod pen_paths;

#[path = "it/region.rs"]
mod region;

#[path = "it/region_props.rs"]
mod region_props;

#[path = "it/streaming.rs"]
mod streaming;

// The integration tests run with the allocator of the `rgbn` binary (as the benchmarks do).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

#[path = "it/fused_filter.rs"]
mod fused_filter;

#[path = "it/layers.rs"]
mod layers;

#[path = "it/parse_once.rs"]
mod parse_once;

#[cfg(feature = "gui")]
#[path = "it/editor_structure.rs"]
mod editor_structure;

#[path = "it/zarr.rs"]
mod zarr;
