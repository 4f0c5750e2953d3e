//! Capture: building RGBN images from photographs.
//!
//! - [`photometric`]: photometric stereo (several photos from one viewpoint under known
//!   directional lights → albedo + normals + mask), light files, and light calibration from a
//!   chrome sphere.
//! - [`lp`]: RTI light-position files (`.lp`: photo names and light directions in one file).

pub mod lp;
pub mod photometric;
