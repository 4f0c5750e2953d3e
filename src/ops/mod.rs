//! Operators: pure functions over RGBN images and their derived fields. One operator per file,
//! with its parameters, maths documentation and tests.

pub mod band;
pub mod bilateral;
pub mod brush;
pub mod combine;
pub mod filter;
pub mod geom;
pub mod normalize;
pub mod pen;
pub mod rotate;
pub mod stamp;
