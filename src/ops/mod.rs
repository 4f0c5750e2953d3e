//! Operators: pure functions over RGBN images and their derived fields. One operator per file,
//! with its parameters, maths documentation and tests.

pub mod filter;
