//! Operators: pure functions over RGBN images and their derived fields. One operator per file,
//! with its parameters, maths documentation and tests.

pub mod filter;
pub mod band;
pub mod combine;
pub mod geom;
pub mod rotate;
pub mod normalize;
pub mod pen;
pub mod stamp;
pub mod bilateral;
pub mod brush;
