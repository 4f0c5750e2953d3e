//! The one integration-test binary (modules under `tests/it/`).

#[path = "it/common.rs"]
mod common;

#[path = "it/cli_core.rs"]
mod cli_core;
#[path = "it/real_data.rs"]
mod real_data;
