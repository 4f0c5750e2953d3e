//! Operators: pure functions over RGBN images and their derived fields. One operator per file,
//! with its parameters, maths documentation and tests; no graph types (their node forms are in
//! [`crate::nodes`], one file of the same name each).
//!
//! Parameters are declared once with [`params!`](macro@crate::params) (and choices with
//! [`choice_enum!`](crate::choice_enum)): the struct, its defaults and its
//! [`Params::visit`](crate::params::Params::visit), with each field's doc comment as its documentation. See
//! `CONTRIBUTING.md` for how to add an operator.
//!
//! ```
//! use rgbn::params::{describe, from_values, ParamKind, ParamValue};
//! use rgbn::ops::band::{band_filter_image, BandOp, BandParams};
//!
//! // The same struct is the pure function's argument and the node's parameters.
//! let p = BandParams { op: BandOp::Remove, ..BandParams::default() };
//! let (img, _curl) = band_filter_image(&rgbn::RgbnImage::flat(8, 8, [0.5; 3]), &p).unwrap();
//! assert_eq!(img.width(), 8);
//! let op = describe::<BandParams>().into_iter().find(|i| i.name == "op").unwrap();
//! assert_eq!(op.kind, ParamKind::Choice(vec!["keep", "remove"]));
//! // An unknown choice name is refused with the closest one.
//! let bad = [("op".to_string(), ParamValue::Choice("remve".into()))].into();
//! let e = from_values::<BandParams>(&bad).unwrap_err().to_string();
//! assert!(e.contains("did you mean \"remove\""), "{e}");
//! ```

pub mod band;
pub mod bilateral;
pub mod brush;
pub mod combine;
pub mod filter;
pub mod geom;
pub mod normalize;
pub mod pen;
pub mod pen_paths;
pub mod publish;
pub mod rotate;
pub mod stamp;
pub mod transform;
