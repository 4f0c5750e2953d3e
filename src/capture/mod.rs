//! Capture: building RGBN images from photographs.
//!
//! - [`photometric`]: photometric stereo (several photos from one viewpoint under known
//!   directional lights → albedo + normals + mask), light files, and light calibration from a
//!   chrome sphere.

pub mod photometric;
