//! Operator parameters declared once.
//!
//! A params struct implements [`Params::visit`], calling one [`ParamVisitor`] method per field
//! with its name, metadata (doc, unit, range) and a `&mut` reference to the value. Every consumer
//! is a visitor over that single declaration:
//!
//! - [`describe`] lists names, kinds, docs, ranges and defaults (`rgbn ops`, the editor's widgets);
//! - [`to_values`] turns a struct into the file schema (`BTreeMap<String, ParamValue>`), which is
//!   also the canonical form hashed into cache keys;
//! - [`from_values`] applies a map from a graph file or `--set`, refusing unknown names (with a
//!   suggestion), wrong kinds and out-of-range values.
//!
//! The core never depends on egui: an editor implements [`ParamVisitor`] to draw widgets.
//!
//! ```
//! use rgbn::params::{Params, ParamVisitor, Meta, describe};
//! #[derive(Clone, Debug, PartialEq)]
//! struct Blur { sigma_px: f64 }
//! impl Default for Blur { fn default() -> Self { Self { sigma_px: 2.0 } } }
//! impl Params for Blur {
//!     fn visit(&mut self, v: &mut dyn ParamVisitor) {
//!         v.float("sigma_px", &mut self.sigma_px, &Meta::new("Gaussian σ.").unit("px").range(0.01, 4096.0));
//!     }
//! }
//! assert_eq!(describe::<Blur>()[0].name, "sigma_px");
//! ```

use std::cell::Cell;
use std::collections::BTreeMap;
use std::fmt;

mod meta;
mod nearest;
mod paths;
pub use meta::{Meta, Slider};
pub use nearest::{edit_distance, nearest};
pub use paths::{apply_own, parse_paths, paths_text, visit_except, PathValue};

/// A parameter value as stored in graph files. This is the file schema, independent of the
/// runtime params structs; floats are `f64` and compared/hashed by bits.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ParamValue {
    /// A boolean switch.
    Bool(bool),
    /// An integer (sizes, radii, counts).
    Int(i64),
    /// A real number.
    Float(f64),
    /// One of a fixed set of names (see [`ParamKind::Choice`]).
    Choice(String),
    /// Free text.
    Text(String),
    /// A file path; relative paths are relative to the graph file's folder.
    Path(String),
    /// A 3-vector (directions, colours).
    Vec3([f64; 3]),
    /// A list of numbers (kernel taps).
    Floats(Vec<f64>),
    /// A sampled 1-D profile (values at equally spaced positions over [0, 1]).
    Profile(Vec<f64>),
    /// A list of 2-D points in pixels (pen paths, brush strokes).
    Points(Vec<[f64; 2]>),
    /// A list of paths, each with parameters of its own (a pen's strokes; [`PathValue`]).
    Paths(Vec<PathValue>),
}

impl ParamValue {
    /// The kind name used in messages.
    #[must_use]
    pub fn kind_name(&self) -> &'static str {
        match self {
            ParamValue::Bool(_) => "bool",
            ParamValue::Int(_) => "int",
            ParamValue::Float(_) => "float",
            ParamValue::Choice(_) => "choice",
            ParamValue::Text(_) => "text",
            ParamValue::Path(_) => "path",
            ParamValue::Vec3(_) => "vec3",
            ParamValue::Floats(_) => "floats",
            ParamValue::Profile(_) => "profile",
            ParamValue::Points(_) => "points",
            ParamValue::Paths(_) => "paths",
        }
    }

    /// Feeds a canonical byte form into `h` (floats by bits, tagged by kind).
    pub fn hash_into(&self, h: &mut xxhash_rust::xxh3::Xxh3) {
        fn floats(h: &mut xxhash_rust::xxh3::Xxh3, v: &[f64]) {
            h.update(&(v.len() as u64).to_le_bytes());
            for x in v {
                h.update(&x.to_bits().to_le_bytes());
            }
        }
        h.update(self.kind_name().as_bytes());
        match self {
            ParamValue::Bool(b) => h.update(&[u8::from(*b)]),
            ParamValue::Int(i) => h.update(&i.to_le_bytes()),
            ParamValue::Float(f) => h.update(&f.to_bits().to_le_bytes()),
            ParamValue::Choice(s) | ParamValue::Text(s) | ParamValue::Path(s) => {
                h.update(&(s.len() as u64).to_le_bytes());
                h.update(s.as_bytes());
            }
            ParamValue::Vec3(v) => floats(h, v),
            ParamValue::Floats(v) | ParamValue::Profile(v) => floats(h, v),
            ParamValue::Points(p) => {
                let flat: Vec<f64> = p.iter().flatten().copied().collect();
                floats(h, &flat);
            }
            ParamValue::Paths(p) => paths::hash_paths(h, p),
        }
    }
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let list = |f: &mut fmt::Formatter<'_>, v: &[f64]| {
            let s: Vec<String> = v.iter().map(ToString::to_string).collect();
            write!(f, "{}", s.join(","))
        };
        match self {
            ParamValue::Bool(b) => write!(f, "{b}"),
            ParamValue::Int(i) => write!(f, "{i}"),
            ParamValue::Float(x) => write!(f, "{x}"),
            ParamValue::Choice(s) | ParamValue::Text(s) | ParamValue::Path(s) => {
                write!(f, "{s}")
            }
            ParamValue::Vec3(v) => list(f, v),
            ParamValue::Floats(v) | ParamValue::Profile(v) => list(f, v),
            ParamValue::Points(p) => {
                let s: Vec<String> = p.iter().map(|[x, y]| format!("{x}:{y}")).collect();
                write!(f, "{}", s.join(","))
            }
            ParamValue::Paths(p) => write!(f, "{}", paths_text(p)),
        }
    }
}

/// The kind of a parameter, with what a widget or parser needs to know.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamKind {
    /// `true`/`false`.
    Bool,
    /// An integer.
    Int,
    /// A real number.
    Float,
    /// One name out of `options`.
    Choice(Vec<&'static str>),
    /// Free text.
    Text,
    /// A file path.
    Path,
    /// Three numbers.
    Vec3,
    /// A list of numbers.
    Floats,
    /// A sampled 1-D profile.
    Profile,
    /// A list of 2-D points.
    Points,
    /// A list of paths ([`PathValue`]).
    Paths,
}

/// Everything known about one parameter (from [`describe`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamInfo {
    /// Name as used in files and `--set`.
    pub name: &'static str,
    /// Kind.
    pub kind: ParamKind,
    /// Doc, unit, range.
    pub meta: Meta,
    /// The default value.
    pub default: ParamValue,
}

impl ParamInfo {
    /// Parses a command-line string (`--set NODE.PARAM=VALUE`) into a value of this kind.
    /// Lists are comma separated; points are `x:y,x:y`.
    pub fn parse_str(&self, s: &str) -> Result<ParamValue, String> {
        let num = |t: &str| -> Result<f64, String> {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("{t:?} is not a number"))
        };
        let nums = |t: &str| -> Result<Vec<f64>, String> {
            if t.trim().is_empty() {
                return Ok(Vec::new());
            }
            t.split(',').map(num).collect()
        };
        Ok(match &self.kind {
            ParamKind::Bool => match s {
                "true" | "1" | "yes" | "on" => ParamValue::Bool(true),
                "false" | "0" | "no" | "off" => ParamValue::Bool(false),
                _ => return Err(format!("{s:?} is not true or false")),
            },
            ParamKind::Int => ParamValue::Int(
                s.trim()
                    .parse()
                    .map_err(|_| format!("{s:?} is not an integer"))?,
            ),
            ParamKind::Float => ParamValue::Float(num(s)?),
            ParamKind::Choice(_) => ParamValue::Choice(s.to_string()),
            ParamKind::Text => ParamValue::Text(s.to_string()),
            ParamKind::Path => ParamValue::Path(s.to_string()),
            ParamKind::Vec3 => match nums(s)?.as_slice() {
                [x, y, z] => ParamValue::Vec3([*x, *y, *z]),
                _ => return Err(format!("{s:?} is not x,y,z")),
            },
            ParamKind::Floats => ParamValue::Floats(nums(s)?),
            ParamKind::Profile => ParamValue::Profile(nums(s)?),
            ParamKind::Points => {
                let mut pts = Vec::new();
                for p in s.split(',').filter(|t| !t.trim().is_empty()) {
                    let (x, y) = p
                        .split_once(':')
                        .ok_or_else(|| format!("point {p:?} is not x:y"))?;
                    pts.push([num(x)?, num(y)?]);
                }
                ParamValue::Points(pts)
            }
            ParamKind::Paths => ParamValue::Paths(parse_paths(s)?),
        })
    }
}

/// Visits each parameter of a params struct. One method per kind; `value` may be read and
/// written. Implemented by [`describe`], [`to_values`], [`from_values`] and by the editor.
pub trait ParamVisitor {
    /// A boolean switch.
    fn bool(&mut self, name: &'static str, value: &mut bool, meta: &Meta);
    /// An integer, range in `meta.range`.
    fn int(&mut self, name: &'static str, value: &mut i64, meta: &Meta);
    /// A real number, range in `meta.range`.
    fn float(&mut self, name: &'static str, value: &mut f64, meta: &Meta);
    /// An enum given by its option names; `value` is one of `options`.
    fn choice(
        &mut self,
        name: &'static str,
        value: &mut &'static str,
        options: &[&'static str],
        meta: &Meta,
    );
    /// Free text.
    fn text(&mut self, name: &'static str, value: &mut String, meta: &Meta);
    /// A file path (read, or written when `meta.output`).
    fn path(&mut self, name: &'static str, value: &mut String, meta: &Meta);
    /// Three numbers (each within `meta.range` if given).
    fn vec3(&mut self, name: &'static str, value: &mut [f64; 3], meta: &Meta);
    /// A list of numbers.
    fn floats(&mut self, name: &'static str, value: &mut Vec<f64>, meta: &Meta);
    /// A sampled 1-D profile over [0, 1].
    fn profile(&mut self, name: &'static str, value: &mut Vec<f64>, meta: &Meta);
    /// A list of 2-D points in pixels (paths, strokes).
    fn points(&mut self, name: &'static str, value: &mut Vec<[f64; 2]>, meta: &Meta);
    /// A list of paths in pixels, each with parameters of its own.
    fn paths(&mut self, name: &'static str, value: &mut Vec<PathValue>, meta: &Meta);
}

/// A params struct: default values from [`Default`], fields declared in [`Params::visit`].
pub trait Params: Default + Clone + Send + Sync + 'static {
    /// Calls `v` once per field, in a fixed order.
    fn visit(&mut self, v: &mut dyn ParamVisitor);
}

/// An enum parameter: a fixed list of named variants, each with a doc line. Declared with
/// [`choice_enum!`](crate::choice_enum); visited through [`ParamVisitor::choice`] (by name), so
/// files keep storing [`ParamValue::Choice`] and an unknown name is refused with a suggestion.
pub trait Choice: Copy + PartialEq + Send + Sync + 'static {
    /// Every variant, in menu order.
    const ALL: &'static [Self];
    /// The name used in files, `--set` and menus.
    fn name(self) -> &'static str;
    /// One-line documentation of the variant.
    fn doc(self) -> &'static str;
    /// Every name, in [`Choice::ALL`] order.
    #[must_use]
    fn names() -> Vec<&'static str> {
        Self::ALL.iter().map(|c| c.name()).collect()
    }
    /// The variant called `name`.
    #[must_use]
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.name() == name)
    }
}

/// Visits a [`Choice`] field through [`ParamVisitor::choice`] by its name.
pub fn visit_choice<C: Choice>(
    v: &mut dyn ParamVisitor,
    name: &'static str,
    value: &mut C,
    meta: &Meta,
) {
    let names = C::names();
    let mut s = value.name();
    v.choice(name, &mut s, &names, meta);
    if let Some(c) = C::from_name(s) {
        *value = c;
    }
}

/// Declares an enum implementing [`Choice`]: each variant with its doc comment and file name.
///
/// ```
/// rgbn::choice_enum! {
///     /// Keep the band or remove it.
///     pub enum Op {
///         /// The band only.
///         Keep = "keep",
///         /// Everything but the band.
///         Remove = "remove",
///     }
/// }
/// use rgbn::params::Choice;
/// assert_eq!(Op::from_name("remove"), Some(Op::Remove));
/// assert_eq!(Op::default(), Op::Keep); // the first variant
/// assert_eq!(Op::Keep.doc(), "The band only.");
/// ```
#[macro_export]
macro_rules! choice_enum {
    ($(#[$m:meta])* $vis:vis enum $name:ident {
        $(#[doc = $fdoc:expr])* $first:ident = $first_name:literal,
        $($(#[doc = $vdoc:expr])* $variant:ident = $vname:literal,)*
    }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
        $vis enum $name {
            $(#[doc = $fdoc])*
            #[default]
            $first,
            $($(#[doc = $vdoc])* $variant,)*
        }
        impl $crate::params::Choice for $name {
            const ALL: &'static [Self] = &[Self::$first, $(Self::$variant,)*];
            fn name(self) -> &'static str {
                match self {
                    Self::$first => $first_name,
                    $(Self::$variant => $vname,)*
                }
            }
            fn doc(self) -> &'static str {
                match self {
                    Self::$first => concat!($($fdoc),*).trim_ascii(),
                    $(Self::$variant => concat!($($vdoc),*).trim_ascii(),)*
                }
            }
        }
    };
}

/// Declares a params struct, its [`Default`] and its [`Params::visit`] from one field list:
/// each field's doc comment is its documentation (inspector tooltip, `rgbn ops`), then
/// `name: type = default => kind` with the [`Meta`] builder calls (`unit`, `range`, `soft`,
/// `log`, `output`, `optional`). `kind` is a [`ParamVisitor`] method (`float`, `int`, `bool`, `text`, `path`,
/// `vec3`, `floats`, `profile`, `points`, `paths`), `choice` for a [`Choice`] enum, or `flatten` for a
/// field that is itself a params struct (its parameters appear as the parent's, unprefixed:
/// one declaration shared by several operators).
///
/// ```
/// rgbn::params! {
///     /// Parameters of a blur.
///     #[derive(Clone, Debug, PartialEq)]
///     pub struct Blur {
///         /// Gaussian σ.
///         pub sigma_px: f64 = 2.0 => float.unit("px").range(0.01, 4096.0).soft(0.1, 64.0).log(),
///         /// Filter inside the mask only.
///         pub mask_aware: bool = false => bool,
///     }
/// }
/// let info = rgbn::params::describe::<Blur>();
/// assert_eq!((info[0].name, info[0].meta.doc, info[0].meta.unit), ("sigma_px", "Gaussian σ.", "px"));
/// // Files and `--set` may give any σ in [0.01, 4096]; the editor's slider runs over [0.1, 64].
/// let slider = info[0].meta.slider().unwrap();
/// assert_eq!((slider.lo, slider.hi, slider.log), (0.1, 64.0, true));
/// ```
#[macro_export]
macro_rules! params {
    ($(#[$m:meta])* $vis:vis struct $name:ident {
        $($(#[doc = $doc:expr])* $fvis:vis $field:ident : $ty:ty = $default:expr
            => $kind:ident $(. $mc:ident ( $($ma:expr),* ))* ,)*
    }) => {
        $(#[$m])*
        $vis struct $name {
            $($(#[doc = $doc])* $fvis $field: $ty,)*
        }
        impl Default for $name {
            fn default() -> Self {
                Self { $($field: $default,)* }
            }
        }
        impl $crate::params::Params for $name {
            fn visit(&mut self, v: &mut dyn $crate::params::ParamVisitor) {
                $(
                    let meta = $crate::params::Meta::new(concat!($($doc),*).trim_ascii())
                        $(. $mc ( $($ma),* ))*;
                    $crate::params!(@visit $kind, v, stringify!($field), &mut self.$field, &meta);
                )*
            }
        }
    };
    (@visit choice, $v:ident, $n:expr, $f:expr, $meta:expr) => {
        $crate::params::visit_choice($v, $n, $f, $meta)
    };
    (@visit flatten, $v:ident, $n:expr, $f:expr, $meta:expr) => {{
        let _ = $meta;
        $crate::params::Params::visit($f, $v)
    }};
    (@visit $kind:ident, $v:ident, $n:expr, $f:expr, $meta:expr) => {
        $v.$kind($n, $f, $meta)
    };
}

/// No parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NoParams;

impl Params for NoParams {
    fn visit(&mut self, _: &mut dyn ParamVisitor) {}
}

/// A visitor implemented by a closure over `(name, kind, meta, value-as-ParamValue)`, for
/// read-only consumers.
struct Collect<F: FnMut(&'static str, ParamKind, &Meta, ParamValue)>(F);

impl<F: FnMut(&'static str, ParamKind, &Meta, ParamValue)> ParamVisitor for Collect<F> {
    fn bool(&mut self, name: &'static str, value: &mut bool, meta: &Meta) {
        (self.0)(name, ParamKind::Bool, meta, ParamValue::Bool(*value));
    }
    fn int(&mut self, name: &'static str, value: &mut i64, meta: &Meta) {
        (self.0)(name, ParamKind::Int, meta, ParamValue::Int(*value));
    }
    fn float(&mut self, name: &'static str, value: &mut f64, meta: &Meta) {
        (self.0)(name, ParamKind::Float, meta, ParamValue::Float(*value));
    }
    fn choice(
        &mut self,
        name: &'static str,
        value: &mut &'static str,
        options: &[&'static str],
        meta: &Meta,
    ) {
        (self.0)(
            name,
            ParamKind::Choice(options.to_vec()),
            meta,
            ParamValue::Choice((*value).to_string()),
        );
    }
    fn text(&mut self, name: &'static str, value: &mut String, meta: &Meta) {
        (self.0)(name, ParamKind::Text, meta, ParamValue::Text(value.clone()));
    }
    fn path(&mut self, name: &'static str, value: &mut String, meta: &Meta) {
        (self.0)(name, ParamKind::Path, meta, ParamValue::Path(value.clone()));
    }
    fn vec3(&mut self, name: &'static str, value: &mut [f64; 3], meta: &Meta) {
        (self.0)(name, ParamKind::Vec3, meta, ParamValue::Vec3(*value));
    }
    fn floats(&mut self, name: &'static str, value: &mut Vec<f64>, meta: &Meta) {
        (self.0)(
            name,
            ParamKind::Floats,
            meta,
            ParamValue::Floats(value.clone()),
        );
    }
    fn profile(&mut self, name: &'static str, value: &mut Vec<f64>, meta: &Meta) {
        (self.0)(
            name,
            ParamKind::Profile,
            meta,
            ParamValue::Profile(value.clone()),
        );
    }
    fn points(&mut self, name: &'static str, value: &mut Vec<[f64; 2]>, meta: &Meta) {
        (self.0)(
            name,
            ParamKind::Points,
            meta,
            ParamValue::Points(value.clone()),
        );
    }
    fn paths(&mut self, name: &'static str, value: &mut Vec<PathValue>, meta: &Meta) {
        let v = ParamValue::Paths(value.clone());
        (self.0)(name, ParamKind::Paths, meta, v);
    }
}

/// Describes every parameter of `P` with its default.
#[must_use]
pub fn describe<P: Params>() -> Vec<ParamInfo> {
    let mut out = Vec::new();
    let mut p = P::default();
    p.visit(&mut Collect(|name, kind, meta: &Meta, default| {
        out.push(ParamInfo {
            name,
            kind,
            meta: meta.clone(),
            default,
        });
    }));
    out
}

/// The file form of `p`: every parameter, including those at their default.
#[must_use]
pub fn to_values<P: Params>(p: &P) -> BTreeMap<String, ParamValue> {
    let mut out = BTreeMap::new();
    let mut p = p.clone();
    p.visit(&mut Collect(|name: &'static str, _, _: &Meta, v| {
        out.insert(name.to_string(), v);
    }));
    out
}

/// Why a parameter map could not be applied.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamError {
    /// No parameter of that name; `suggestion` is the nearest known name.
    Unknown {
        /// The name given.
        name: String,
        /// The closest parameter name, if any is close.
        suggestion: Option<String>,
    },
    /// The value has the wrong kind.
    Kind {
        /// Parameter name.
        name: String,
        /// The kind the parameter has.
        expected: &'static str,
        /// The kind given.
        found: &'static str,
    },
    /// The value is of the right kind but not acceptable.
    Range {
        /// Parameter name.
        name: String,
        /// What is wrong.
        detail: String,
    },
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamError::Unknown { name, suggestion } => {
                write!(f, "unknown parameter {name:?}")?;
                if let Some(s) = suggestion {
                    write!(f, " (did you mean {s:?}?)")?;
                }
                Ok(())
            }
            ParamError::Kind {
                name,
                expected,
                found,
            } => write!(
                f,
                "parameter {name:?} needs a {expected} value, got a {found}"
            ),
            ParamError::Range { name, detail } => write!(f, "parameter {name:?}: {detail}"),
        }
    }
}

impl ParamError {
    /// The parameter the error is about.
    #[must_use]
    pub fn name(&self) -> &str {
        match self {
            ParamError::Unknown { name, .. }
            | ParamError::Kind { name, .. }
            | ParamError::Range { name, .. } => name,
        }
    }
}

/// The same error as an [`crate::RgbnError::InvalidParam`] named after its parameter.
impl From<ParamError> for crate::RgbnError {
    fn from(e: ParamError) -> Self {
        let detail = match &e {
            ParamError::Unknown { suggestion, .. } => match suggestion {
                Some(s) => format!("no such parameter (did you mean {s:?}?)"),
                None => "no such parameter".into(),
            },
            ParamError::Kind {
                expected, found, ..
            } => format!("needs a {expected} value, got a {found}"),
            ParamError::Range { detail, .. } => detail.clone(),
        };
        crate::RgbnError::param(e.name(), detail)
    }
}

fn set_if<T>(ok: bool, dst: &mut T, v: T) {
    if ok {
        *dst = v;
    }
}

/// Applies values onto a struct, checking kinds and ranges.
struct Apply<'a> {
    values: &'a BTreeMap<String, ParamValue>,
    errors: Vec<ParamError>,
}

impl Apply<'_> {
    fn get(&self, name: &str) -> Option<&ParamValue> {
        self.values.get(name)
    }
    fn kind_err(&mut self, name: &str, expected: &'static str, found: &ParamValue) {
        self.errors.push(ParamError::Kind {
            name: name.to_string(),
            expected,
            found: found.kind_name(),
        });
    }
    fn check_range(&mut self, name: &str, values: &[f64], meta: &Meta) -> bool {
        for v in values {
            if !v.is_finite() {
                self.errors.push(ParamError::Range {
                    name: name.into(),
                    detail: format!("{v} is not a finite number"),
                });
                return false;
            }
            if let Some((lo, hi)) = meta.range {
                if *v < lo || *v > hi {
                    self.errors.push(ParamError::Range {
                        name: name.into(),
                        detail: format!("{v} is out of range [{lo}, {hi}]"),
                    });
                    return false;
                }
            }
        }
        true
    }
}

impl ParamVisitor for Apply<'_> {
    fn bool(&mut self, name: &'static str, value: &mut bool, _: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Bool(b)) => *value = b,
            Some(v) => self.kind_err(name, "bool", &v),
        }
    }
    fn int(&mut self, name: &'static str, value: &mut i64, meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Int(i)) => {
                let ok = self.check_range(name, &[i as f64], meta);
                set_if(ok, value, i);
            }
            Some(v) => self.kind_err(name, "int", &v),
        }
    }
    fn float(&mut self, name: &'static str, value: &mut f64, meta: &Meta) {
        let x = match self.get(name).cloned() {
            None => return,
            Some(ParamValue::Float(x)) => x,
            Some(ParamValue::Int(i)) => i as f64,
            Some(v) => return self.kind_err(name, "float", &v),
        };
        let ok = self.check_range(name, &[x], meta);
        set_if(ok, value, x);
    }
    fn choice(
        &mut self,
        name: &'static str,
        value: &mut &'static str,
        options: &[&'static str],
        _: &Meta,
    ) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Choice(s) | ParamValue::Text(s)) => {
                match options.iter().find(|o| **o == s) {
                    Some(o) => *value = o,
                    None => self.errors.push(ParamError::Range {
                        name: name.into(),
                        detail: format!(
                            "{s:?} is not one of {}{}",
                            options.join(", "),
                            nearest(&s, options.iter().copied())
                                .map(|n| format!(" (did you mean {n:?}?)"))
                                .unwrap_or_default()
                        ),
                    }),
                }
            }
            Some(v) => self.kind_err(name, "choice", &v),
        }
    }
    fn text(&mut self, name: &'static str, value: &mut String, _: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Text(s)) => *value = s,
            Some(v) => self.kind_err(name, "text", &v),
        }
    }
    fn path(&mut self, name: &'static str, value: &mut String, meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Path(s) | ParamValue::Text(s)) => *value = s,
            Some(v) => return self.kind_err(name, "path", &v),
        }
        // A required path refused here, whether given empty or not given at all.
        if value.is_empty() && !meta.optional {
            self.errors.push(ParamError::Range {
                name: name.into(),
                detail: "a file path is required".into(),
            });
        }
    }
    fn vec3(&mut self, name: &'static str, value: &mut [f64; 3], meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Vec3(v)) => {
                let ok = self.check_range(name, &v, meta);
                set_if(ok, value, v);
            }
            Some(v) => self.kind_err(name, "vec3", &v),
        }
    }
    fn floats(&mut self, name: &'static str, value: &mut Vec<f64>, meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Floats(v)) => {
                let ok = self.check_range(name, &v, meta);
                set_if(ok, value, v);
            }
            Some(v) => self.kind_err(name, "floats", &v),
        }
    }
    fn profile(&mut self, name: &'static str, value: &mut Vec<f64>, meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Profile(v) | ParamValue::Floats(v)) => {
                let ok = self.check_range(name, &v, meta);
                set_if(ok, value, v);
            }
            Some(v) => self.kind_err(name, "profile", &v),
        }
    }
    fn points(&mut self, name: &'static str, value: &mut Vec<[f64; 2]>, meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Points(v)) => {
                let flat: Vec<f64> = v.iter().flatten().copied().collect();
                let ok = self.check_range(name, &flat, meta);
                set_if(ok, value, v);
            }
            Some(v) => self.kind_err(name, "points", &v),
        }
    }
    fn paths(&mut self, name: &'static str, value: &mut Vec<PathValue>, meta: &Meta) {
        match self.get(name).cloned() {
            None => {}
            Some(ParamValue::Paths(v)) => {
                let flat: Vec<f64> = v.iter().flat_map(PathValue::numbers).collect();
                let ok = self.check_range(name, &flat, meta);
                set_if(ok, value, v);
            }
            Some(v) => self.kind_err(name, "paths", &v),
        }
    }
}

/// Builds `P` from defaults overridden by `values`. Unknown names, wrong kinds and values out of
/// range are errors (the first one found is returned).
pub fn from_values<P: Params>(values: &BTreeMap<String, ParamValue>) -> Result<P, ParamError> {
    PARSES.with(|n| n.set(n.get() + 1));
    apply(values)
}

/// Checks the values of `p` against their declarations (ranges, finite numbers, required
/// paths): the checks [`from_values`] makes, on a struct built in code.
pub fn check_ranges<P: Params>(p: &P) -> Result<(), ParamError> {
    apply::<P>(&to_values(p)).map(|_| ())
}

/// Applies `values` onto `p` as [`from_values`] does onto the defaults (names not checked).
fn apply_onto<P: Params>(
    p: &mut P,
    values: &BTreeMap<String, ParamValue>,
) -> Result<(), ParamError> {
    let mut apply = Apply {
        values,
        errors: Vec::new(),
    };
    p.visit(&mut apply);
    apply.errors.into_iter().next().map_or(Ok(()), Err)
}

fn apply<P: Params>(values: &BTreeMap<String, ParamValue>) -> Result<P, ParamError> {
    let known: Vec<&'static str> = describe::<P>().iter().map(|i| i.name).collect();
    if let Some(name) = values.keys().find(|k| !known.contains(&k.as_str())) {
        return Err(ParamError::Unknown {
            name: name.clone(),
            suggestion: nearest(name, known.iter().copied()),
        });
    }
    let mut p = P::default();
    apply_onto(&mut p, values).map(|()| p)
}

thread_local! {
    /// Parameter maps parsed into structs by [`from_values`] on this thread: a graph's nodes
    /// are parsed once per change where the graph is built, and this counts it.
    static PARSES: Cell<usize> = const { Cell::new(0) };
}

/// How many times [`from_values`] has run on this thread.
#[must_use]
pub fn parses() -> usize {
    PARSES.with(Cell::get)
}

/// A position of a full-resolution image (pixel centres at whole numbers) on the grid reduced
/// by `s`, whose pixel `X` covers full-resolution pixels `X·s .. (X + 1)·s`.
#[must_use]
pub fn scale_point(p: [f64; 2], s: f64) -> [f64; 2] {
    p.map(|c| (c - (s - 1.0) / 2.0) / s)
}

/// Rewrites the lengths and positions of a params struct from their declarations.
struct Rescale {
    /// Divides lengths (`px` floats, lists and profiles); `None`: leaves them.
    scale: Option<f64>,
    /// Maps each point.
    point: Box<dyn Fn([f64; 2]) -> [f64; 2]>,
    /// The declarations of the struct rescaled: a path's own parameters are its node's.
    own: Vec<ParamInfo>,
}

impl Rescale {
    fn length(&self, v: f64, meta: &Meta) -> f64 {
        match self.scale {
            Some(s) if meta.unit == "px" => {
                let x = v / s;
                match meta.range {
                    Some((lo, hi)) => x.clamp(lo, hi),
                    None => x,
                }
            }
            _ => v,
        }
    }
}

impl ParamVisitor for Rescale {
    fn bool(&mut self, _: &'static str, _: &mut bool, _: &Meta) {}
    fn int(&mut self, _: &'static str, _: &mut i64, _: &Meta) {}
    fn float(&mut self, _: &'static str, value: &mut f64, meta: &Meta) {
        *value = self.length(*value, meta);
    }
    fn choice(&mut self, _: &'static str, _: &mut &'static str, _: &[&'static str], _: &Meta) {}
    fn text(&mut self, _: &'static str, _: &mut String, _: &Meta) {}
    fn path(&mut self, _: &'static str, _: &mut String, _: &Meta) {}
    fn vec3(&mut self, _: &'static str, _: &mut [f64; 3], _: &Meta) {}
    fn floats(&mut self, _: &'static str, value: &mut Vec<f64>, meta: &Meta) {
        for v in value {
            *v = self.length(*v, meta);
        }
    }
    fn profile(&mut self, _: &'static str, value: &mut Vec<f64>, meta: &Meta) {
        self.floats("", value, meta);
    }
    fn points(&mut self, _: &'static str, value: &mut Vec<[f64; 2]>, _: &Meta) {
        for p in value {
            *p = (self.point)(*p);
        }
    }
    fn paths(&mut self, _: &'static str, value: &mut Vec<PathValue>, _: &Meta) {
        for path in value {
            for p in &mut path.points {
                *p = (self.point)(*p);
            }
            if let Some(s) = self.scale {
                paths::scale_own(&mut path.params, &self.own, s);
            }
        }
    }
}

/// `p` on a grid `s` times coarser, from its declarations: every `float`, `floats` and
/// `profile` with unit `px` divided by `s` and kept within its declared range, every `points`
/// list and path mapped with [`scale_point`] (a path's own parameters scaled by the same
/// declarations). Integers (kernel radii and sizes in whole pixels) are left as they are: an
/// operator with such lengths has no coarse form from its declarations.
#[must_use]
pub fn scaled<P: Params>(p: &P, s: f64) -> P {
    let mut out = p.clone();
    out.visit(&mut Rescale {
        scale: Some(s),
        point: Box::new(move |q| scale_point(q, s)),
        own: describe::<P>(),
    });
    out
}

/// `p` on the crop of the image whose top-left pixel is `(dx, dy)`: every `points` list and
/// path moved by `(−dx, −dy)`. Operators use their points as `f32`; the shift is applied to those values,
/// where moving by whole pixels is exact, so a crop sees a path exactly where the whole image
/// does.
#[must_use]
pub fn shifted<P: Params>(p: &P, dx: f64, dy: f64) -> P {
    let mut out = p.clone();
    out.visit(&mut Rescale {
        scale: None,
        point: Box::new(move |q| [f64::from(q[0] as f32) - dx, f64::from(q[1] as f32) - dy]),
        own: Vec::new(),
    });
    out
}

/// Passes every path parameter of `p` (name, metadata, value) through `f`.
pub fn map_paths<P: Params>(p: &mut P, f: &mut dyn FnMut(&'static str, &Meta, &mut String)) {
    struct Paths<'a>(&'a mut dyn FnMut(&'static str, &Meta, &mut String));
    impl ParamVisitor for Paths<'_> {
        fn bool(&mut self, _: &'static str, _: &mut bool, _: &Meta) {}
        fn int(&mut self, _: &'static str, _: &mut i64, _: &Meta) {}
        fn float(&mut self, _: &'static str, _: &mut f64, _: &Meta) {}
        fn choice(&mut self, _: &'static str, _: &mut &'static str, _: &[&'static str], _: &Meta) {}
        fn text(&mut self, _: &'static str, _: &mut String, _: &Meta) {}
        fn path(&mut self, name: &'static str, value: &mut String, meta: &Meta) {
            (self.0)(name, meta, value);
        }
        fn vec3(&mut self, _: &'static str, _: &mut [f64; 3], _: &Meta) {}
        fn floats(&mut self, _: &'static str, _: &mut Vec<f64>, _: &Meta) {}
        fn profile(&mut self, _: &'static str, _: &mut Vec<f64>, _: &Meta) {}
        fn points(&mut self, _: &'static str, _: &mut Vec<[f64; 2]>, _: &Meta) {}
        fn paths(&mut self, _: &'static str, _: &mut Vec<PathValue>, _: &Meta) {}
    }
    p.visit(&mut Paths(f));
}

#[cfg(test)]
#[path = "params_tests.rs"]
mod tests;
