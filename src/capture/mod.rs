//! Capture: building RGBN images from photographs.
//!
//! - [`inputs`]: what is read from disk — light and intensity files, name lists, photo stacks,
//!   and [`inputs::load_inputs`], which pairs them up.
//! - [`photometric`]: photometric stereo (several photos from one viewpoint under known
//!   directional lights → albedo + normals + mask), least-squares and trimmed estimators.
//! - [`chrome`]: light calibration from photos of a chrome sphere.
//! - [`linalg`]: the `3 × 3` light-matrix algebra the solver uses, and [`linalg::angle_deg`].
//! - [`lp`]: RTI light-position files (`.lp`: photo names and light directions in one file).

pub mod chrome;
pub mod inputs;
pub mod linalg;
pub mod lp;
pub mod photometric;
pub mod robust;

#[cfg(test)]
mod diligent_mat;
#[cfg(test)]
mod real_data_tests;
