//! Ports declared once: an operator's inputs and outputs are plain structs declared with
//! [`inputs!`](crate::inputs) and [`outputs!`](crate::outputs). Each field is a port — its name
//! is the field's, its type follows from the field's type, its documentation is the doc
//! comment — so the spec (`rgbn ops`, the editor's pins, connection checks) and the values a
//! node receives and returns come from one declaration, and a missing or misspelt port is a
//! compile error.
//!
//! | field type | port type |
//! |---|---|
//! | [`RgbnImage`] | [`PortType::Rgbn`] |
//! | [`Mask`] | [`PortType::Mask`] |
//! | [`Scalar`] | [`PortType::Scalar`] |
//! | `Arc<`[`Picture`]`>` | [`PortType::Picture`] |
//! | `f64` | [`PortType::Number`] |
//!
//! An input of type `Option<T>` is optional (unconnected: `None`). An input may say how the
//! engine reads it when that differs from the operator's [`Kind`](super::Kind): `=> whole` (the
//! input is needed whole, as a stamp placed anywhere) or `=> pattern` (whole and never reduced
//! at a coarse level: a small pattern sampled relative to its own size).
//!
//! ```
//! use rgbn::nodes::{InPorts, Mask, OutPorts, PortType};
//! use rgbn::RgbnImage;
//! rgbn::inputs! {
//!     /// Inputs of a masked blur.
//!     pub struct BlurIn {
//!         /// Image to blur.
//!         pub image: RgbnImage,
//!         /// Where to blur (everywhere when unconnected).
//!         pub mask: Option<Mask>,
//!     }
//! }
//! rgbn::outputs! {
//!     /// Outputs of a masked blur.
//!     pub struct BlurOut {
//!         /// The blurred image.
//!         pub image: RgbnImage,
//!         /// RMS curl of the result.
//!         pub curl: f64,
//!     }
//! }
//! let ports = BlurIn::ports();
//! assert_eq!((ports[1].name.as_str(), ports[1].ty, ports[1].optional), ("mask", PortType::Mask, true));
//! assert_eq!(BlurOut::ports()[1].doc, "RMS curl of the result.");
//! ```

use super::value::{Picture, PortType, Value};
use crate::error::RgbnError;
use crate::raster::{Plane, RgbnImage};
use std::sync::Arc;

/// How the engine reads an input, beyond what the operator's kind says.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Read {
    /// As the operator's kind says (a point or area operator reads the pixels near each
    /// output pixel).
    #[default]
    ByKind,
    /// Whole, reduced with the image at a coarse level (a stamp used everywhere).
    Whole,
    /// Whole and at its own resolution at every level (a small pattern sampled in coordinates
    /// relative to its size).
    Pattern,
}

/// One input or output port.
#[derive(Clone, Debug, PartialEq)]
pub struct PortSpec {
    /// Name, unique among the node's inputs (or outputs).
    pub name: String,
    /// Type.
    pub ty: PortType,
    /// One-sentence doc.
    pub doc: String,
    /// Inputs only: may stay unconnected.
    pub optional: bool,
    /// Inputs only: how the engine reads it.
    pub read: Read,
}

impl PortSpec {
    /// A required port.
    #[must_use]
    pub fn new(name: &str, ty: PortType, doc: &str) -> Self {
        Self {
            name: name.into(),
            ty,
            doc: doc.into(),
            optional: false,
            read: Read::ByKind,
        }
    }
    /// Marks an input as optional.
    #[must_use]
    pub fn optional(mut self) -> Self {
        self.optional = true;
        self
    }
    /// Marks an input as read whole ([`Read::Whole`]).
    #[must_use]
    pub fn whole(mut self) -> Self {
        self.read = Read::Whole;
        self
    }
    /// Marks an input as a pattern ([`Read::Pattern`]).
    #[must_use]
    pub fn pattern(mut self) -> Self {
        self.read = Read::Pattern;
        self
    }
    /// The port of a field of type `T`.
    #[must_use]
    pub fn of<T: InValue>(name: &str, doc: &str) -> Self {
        let p = Self::new(name, T::TY, doc);
        if T::OPTIONAL {
            p.optional()
        } else {
            p
        }
    }
    /// The output port of a field of type `T`.
    #[must_use]
    pub fn out<T: OutValue>(name: &str, doc: &str) -> Self {
        Self::new(name, T::TY, doc)
    }
}

/// A coverage mask in [0, 1] on a port ([`PortType::Mask`]); derefs to its [`Plane`].
#[derive(Clone, Debug, PartialEq)]
pub struct Mask(pub Arc<Plane>);

/// A scalar field on a port (a height, a curl map: [`PortType::Scalar`]); derefs to its
/// [`Plane`].
#[derive(Clone, Debug, PartialEq)]
pub struct Scalar(pub Arc<Plane>);

impl Mask {
    /// Wraps a plane.
    #[must_use]
    pub fn new(p: Plane) -> Self {
        Self(Arc::new(p))
    }
}

impl Scalar {
    /// Wraps a plane.
    #[must_use]
    pub fn new(p: Plane) -> Self {
        Self(Arc::new(p))
    }
}

impl std::ops::Deref for Mask {
    type Target = Plane;
    fn deref(&self) -> &Plane {
        &self.0
    }
}

impl std::ops::Deref for Scalar {
    type Target = Plane;
    fn deref(&self) -> &Plane {
        &self.0
    }
}

fn missing(name: &str, ty: PortType) -> RgbnError {
    RgbnError::InvalidImage(format!(
        "input {name:?} is not connected or is not a {}",
        ty.name()
    ))
}

/// A type an input field may have.
pub trait InValue: Sized {
    /// The port type.
    const TY: PortType;
    /// Whether the port may stay unconnected.
    const OPTIONAL: bool = false;
    /// The field from the value on port `name` (`None`: unconnected).
    fn take(name: &str, v: Option<Value>) -> Result<Self, RgbnError>;
}

/// A type an output field may have.
pub trait OutValue {
    /// The port type.
    const TY: PortType;
    /// The value on the port.
    fn give(self) -> Value;
}

macro_rules! port_value {
    ($t:ty, $ty:ident, $v:pat => $e:expr, $x:ident => $give:expr) => {
        impl InValue for $t {
            const TY: PortType = PortType::$ty;
            fn take(name: &str, v: Option<Value>) -> Result<Self, RgbnError> {
                match v {
                    Some($v) => Ok($e),
                    _ => Err(missing(name, PortType::$ty)),
                }
            }
        }
        impl OutValue for $t {
            const TY: PortType = PortType::$ty;
            fn give(self) -> Value {
                let $x = self;
                $give
            }
        }
    };
}

port_value!(RgbnImage, Rgbn, Value::Rgbn(i) => i, x => Value::Rgbn(x));
port_value!(Mask, Mask, Value::Mask(p) => Mask(p), x => Value::Mask(x.0));
port_value!(Scalar, Scalar, Value::Scalar(p) => Scalar(p), x => Value::Scalar(x.0));
port_value!(Arc<Picture>, Picture, Value::Picture(p) => p, x => Value::Picture(x));
port_value!(f64, Number, Value::Number(n) => n, x => Value::Number(x));

impl<T: InValue> InValue for Option<T> {
    const TY: PortType = T::TY;
    const OPTIONAL: bool = true;
    fn take(name: &str, v: Option<Value>) -> Result<Self, RgbnError> {
        match v {
            None => Ok(None),
            v => T::take(name, v).map(Some),
        }
    }
}

/// An operator's inputs ([`inputs!`](crate::inputs)).
pub trait InPorts: Sized {
    /// The ports, in field order.
    fn ports() -> Vec<PortSpec>;
    /// The fields from the values on the ports, in port order.
    fn from_values(values: Vec<Option<Value>>) -> Result<Self, RgbnError>;
}

/// An operator's outputs ([`outputs!`](crate::outputs)).
pub trait OutPorts: Sized {
    /// The ports, in field order.
    fn ports() -> Vec<PortSpec>;
    /// The values, in port order.
    fn into_values(self) -> Vec<Value>;
}

/// Declares an operator's inputs: a struct whose fields are its ports (module docs of
/// [`crate::nodes::ports`]).
#[macro_export]
macro_rules! inputs {
    ($(#[$m:meta])* $vis:vis struct $name:ident {
        $($(#[doc = $doc:expr])* $fvis:vis $field:ident : $fty:ty $(=> $read:ident)?,)*
    }) => {
        $(#[$m])*
        $vis struct $name {
            $($(#[doc = $doc])* $fvis $field: $fty,)*
        }
        impl $crate::nodes::InPorts for $name {
            fn ports() -> Vec<$crate::nodes::PortSpec> {
                vec![$(
                    $crate::nodes::PortSpec::of::<$fty>(
                        stringify!($field),
                        concat!($($doc),*).trim_ascii(),
                    )$(.$read())?,
                )*]
            }
            #[allow(unused_mut, unused_variables)]
            fn from_values(
                values: Vec<Option<$crate::nodes::Value>>,
            ) -> Result<Self, $crate::error::RgbnError> {
                let mut it = values.into_iter();
                Ok(Self {
                    $($field: <$fty as $crate::nodes::InValue>::take(
                        stringify!($field),
                        it.next().flatten(),
                    )?,)*
                })
            }
        }
    };
}

/// Declares an operator's outputs: a struct whose fields are its ports (module docs of
/// [`crate::nodes::ports`]).
#[macro_export]
macro_rules! outputs {
    ($(#[$m:meta])* $vis:vis struct $name:ident {
        $($(#[doc = $doc:expr])* $fvis:vis $field:ident : $fty:ty,)*
    }) => {
        $(#[$m])*
        $vis struct $name {
            $($(#[doc = $doc])* $fvis $field: $fty,)*
        }
        impl $crate::nodes::OutPorts for $name {
            fn ports() -> Vec<$crate::nodes::PortSpec> {
                vec![$(
                    $crate::nodes::PortSpec::out::<$fty>(
                        stringify!($field),
                        concat!($($doc),*).trim_ascii(),
                    ),
                )*]
            }
            fn into_values(self) -> Vec<$crate::nodes::Value> {
                vec![$(<$fty as $crate::nodes::OutValue>::give(self.$field),)*]
            }
        }
    };
}

crate::inputs! {
    /// The inputs of an operator without any (a source).
    pub struct NoInputs {}
}
