//! Values held in memory as graph inputs: an image, mask or scalar field that a host program
//! (the Python package, an embedding application) already has, bound to a graph input without
//! writing a file ([`crate::eval::bind`] puts them into a plan).
//!
//! A bound value is a source node whose only parameter is the **content hash** of the value
//! (with its size): the evaluator's cache keys it like a loaded file, by what it holds, so the
//! same pixels bound again are a cache hit and different pixels are a miss. The value itself
//! lives in a process-wide table for as long as a [`Binding`] holds it (one evaluation), so the
//! node can run on any thread. These operators are not in the [`registry`](super::registry):
//! graph files cannot name them.

use super::{InValue, Kind, Mask, NoInputs, OpSpec, Operator, PortType, RunContext, Scalar, Value};
use crate::error::RgbnError;
use crate::RgbnImage;
use parking_lot::Mutex;
use std::collections::HashMap;
use std::sync::OnceLock;

crate::params! {
    /// Parameters of a bound value: which value (by content), and its size.
    #[derive(Clone, Debug, PartialEq)]
    pub struct BoundParams {
        /// The content hash of the value (hexadecimal), its key in the table of bound values.
        pub key: String = String::new() => text,
        /// Width of the value in pixels.
        pub width: i64 = 0 => int.range(0.0, 1e9),
        /// Height of the value in pixels.
        pub height: i64 = 0 => int.range(0.0, 1e9),
    }
}

/// The table of bound values: content key → (value, number of live bindings).
fn table() -> &'static Mutex<HashMap<String, (Value, usize)>> {
    static TABLE: OnceLock<Mutex<HashMap<String, (Value, usize)>>> = OnceLock::new();
    TABLE.get_or_init(|| Mutex::new(HashMap::new()))
}

fn lock() -> parking_lot::MutexGuard<'static, HashMap<String, (Value, usize)>> {
    table().lock()
}

/// Keeps a value in the table of bound values while it lives (bindings of equal content share
/// one entry, counted).
#[derive(Debug)]
pub struct Binding {
    key: String,
}

impl Binding {
    /// Holds `value` under `key` until the binding is dropped.
    #[must_use]
    pub fn new(key: String, value: Value) -> Self {
        lock()
            .entry(key.clone())
            .and_modify(|e| e.1 += 1)
            .or_insert((value, 1));
        Self { key }
    }
    /// The key the value is held under.
    #[must_use]
    pub fn key(&self) -> &str {
        &self.key
    }
}

impl Drop for Binding {
    fn drop(&mut self) {
        let mut t = lock();
        if let Some(e) = t.get_mut(&self.key) {
            e.1 -= 1;
            if e.1 == 0 {
                t.remove(&self.key);
            }
        }
    }
}

/// The content hash of a value: its type, size and every sample (floats by bits), as 32
/// hexadecimal digits.
#[must_use]
pub fn content_key(value: &Value) -> String {
    use rayon::prelude::*;
    use xxhash_rust::xxh3::{xxh3_128, Xxh3};
    /// Each plane hashed on its own (in parallel), then the plane hashes in order.
    fn planes(h: &mut Xxh3, planes: &[&[f32]]) {
        let hashes: Vec<u128> = planes
            .par_iter()
            .map(|p| {
                // SAFETY: `f32` has no padding and alignment 4 ≥ 1; the bytes are the floats'
                // bits in native order (a key of this process only).
                let bytes =
                    unsafe { std::slice::from_raw_parts(p.as_ptr().cast::<u8>(), 4 * p.len()) };
                xxh3_128(bytes)
            })
            .collect();
        for (p, k) in planes.iter().zip(hashes) {
            h.update(&(p.len() as u64).to_le_bytes());
            h.update(&k.to_le_bytes());
        }
    }
    let mut h = Xxh3::new();
    h.update(b"rgbn-bound-value-1\0");
    h.update(value.port_type().name().as_bytes());
    match value {
        Value::Rgbn(img) => {
            h.update(&(img.width() as u64).to_le_bytes());
            h.update(&(img.height() as u64).to_le_bytes());
            let [r, g, b] = img.color();
            let [x, y, z] = img.normal();
            planes(&mut h, &[r, g, b, x, y, z]);
            match img.mask() {
                Some(m) => planes(&mut h, &[m]),
                None => h.update(b"no mask"),
            }
        }
        Value::Mask(p) | Value::Scalar(p) => {
            h.update(&(p.width() as u64).to_le_bytes());
            h.update(&(p.height() as u64).to_le_bytes());
            planes(&mut h, &[p.data()]);
        }
        Value::Picture(p) => {
            h.update(&(p.width as u64).to_le_bytes());
            h.update(&(p.height as u64).to_le_bytes());
            h.update(&p.rgba);
        }
        Value::Number(x) => h.update(&x.to_bits().to_le_bytes()),
    }
    format!("{:032x}", h.digest128())
}

/// The value held under `key`, if it is of type `ty`.
fn held(key: &str, ty: PortType) -> Result<Value, RgbnError> {
    match lock().get(key) {
        Some((v, _)) if v.port_type() == ty => Ok(v.clone()),
        _ => Err(RgbnError::InvalidImage(format!(
            "the {} value bound as {key} is no longer held (bind it again for each evaluation)",
            ty.name()
        ))),
    }
}

/// One bound-value source node per port type: `$node` with output struct `$out` holding a
/// `$ty` under the operator id `$id`.
macro_rules! bound_node {
    ($node:ident, $out:ident, $ty:ty, $port:ident, $id:literal) => {
        crate::outputs! {
            /// Output of a bound value.
            pub struct $out {
                /// The bound value.
                pub value: $ty,
            }
        }

        /// The source node of a bound value (module docs).
        pub struct $node;

        impl Operator for $node {
            type Params = BoundParams;
            type In = NoInputs;
            type Out = $out;
            fn spec() -> OpSpec {
                OpSpec::new(
                    $id,
                    "Bound value",
                    "input",
                    "A value held in memory by the host program (e.g. a NumPy array from Python), bound to a graph input; keyed by its content hash.",
                )
            }
            fn kind(_: &BoundParams) -> Kind {
                // Held whole; no coarse form of its own (a coarse level reduces it).
                Kind::GLOBAL
            }
            fn out_size(p: &BoundParams, _: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
                Some((
                    usize::try_from(p.width).ok()?,
                    usize::try_from(p.height).ok()?,
                ))
            }
            fn run(p: &BoundParams, _: NoInputs, _: &RunContext) -> Result<$out, RgbnError> {
                let value = <$ty as InValue>::take("value", Some(held(&p.key, PortType::$port)?))?;
                Ok($out { value })
            }
        }
    };
}

bound_node!(BoundRgbn, BoundRgbnOut, RgbnImage, Rgbn, "bound.rgbn");
bound_node!(BoundMask, BoundMaskOut, Mask, Mask, "bound.mask");
bound_node!(BoundScalar, BoundScalarOut, Scalar, Scalar, "bound.scalar");
