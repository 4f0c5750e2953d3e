//! A list of paths as one parameter ([`ParamValue::Paths`]): each path its points, open or
//! closed, and the parameters it sets for itself (the rest are its node's). The pen keeps every
//! stroke of a node in one such list.
//!
//! File form (RON): `"paths": Paths([(points: [(10.0, 20.0), (40.0, 25.0)]), (points: [...],
//! closed: true, params: {"height_px": Float(-2.0)})])`.
//!
//! Text form (`--set NODE.paths=…`, Python): paths separated by `;`, each its points `x:y`
//! separated by `,`, then optionally `closed` and `name=value` items (a number, a name, or a
//! list `a/b/c`): `10:20,40:25;5:5,50:5,30:40,closed,height_px=-2`.

use super::{nearest, Meta, ParamError, ParamInfo, ParamValue, ParamVisitor, Params};
use std::collections::BTreeMap;

/// One path of a [`ParamValue::Paths`] list.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PathValue {
    /// Vertices in pixels `(x, row)`.
    pub points: Vec<[f64; 2]>,
    /// The last point joins the first.
    #[serde(default, skip_serializing_if = "is_false")]
    pub closed: bool,
    /// Parameters of the node this path sets for itself; the others are the node's.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub params: BTreeMap<String, ParamValue>,
}

// serde's `skip_serializing_if` passes a reference.
#[allow(clippy::trivially_copy_pass_by_ref)]
fn is_false(b: &bool) -> bool {
    !*b
}

impl PathValue {
    /// A path with the node's parameters.
    #[must_use]
    pub fn new(points: Vec<[f64; 2]>, closed: bool) -> Self {
        Self {
            points,
            closed,
            params: BTreeMap::new(),
        }
    }

    /// Feeds a canonical byte form into `h` (see [`ParamValue::hash_into`]).
    fn hash_into(&self, h: &mut xxhash_rust::xxh3::Xxh3) {
        h.update(&(self.points.len() as u64).to_le_bytes());
        for p in &self.points {
            h.update(&p[0].to_bits().to_le_bytes());
            h.update(&p[1].to_bits().to_le_bytes());
        }
        h.update(&[u8::from(self.closed)]);
        h.update(&(self.params.len() as u64).to_le_bytes());
        for (name, v) in &self.params {
            h.update(&(name.len() as u64).to_le_bytes());
            h.update(name.as_bytes());
            v.hash_into(h);
        }
    }

    /// Every number of the path (points and its own numeric parameters), for range checks.
    pub(super) fn numbers(&self) -> impl Iterator<Item = f64> + '_ {
        let own = self.params.values().flat_map(|v| match v {
            ParamValue::Float(x) => vec![*x],
            ParamValue::Floats(x) | ParamValue::Profile(x) => x.clone(),
            ParamValue::Vec3(x) => x.to_vec(),
            _ => Vec::new(),
        });
        self.points.iter().flatten().copied().chain(own)
    }
}

/// Feeds a canonical byte form of `paths` into `h` (see [`ParamValue::hash_into`]).
pub(super) fn hash_paths(h: &mut xxhash_rust::xxh3::Xxh3, paths: &[PathValue]) {
    h.update(&(paths.len() as u64).to_le_bytes());
    for p in paths {
        p.hash_into(h);
    }
}

/// The text form of a list of paths (module docs).
#[must_use]
pub fn paths_text(paths: &[PathValue]) -> String {
    let one = |p: &PathValue| {
        let mut items: Vec<String> = p.points.iter().map(|[x, y]| format!("{x}:{y}")).collect();
        if p.closed {
            items.push("closed".into());
        }
        for (name, v) in &p.params {
            let v = match v {
                ParamValue::Floats(l) | ParamValue::Profile(l) => l
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join("/"),
                other => other.to_string(),
            };
            items.push(format!("{name}={v}"));
        }
        items.join(",")
    };
    paths.iter().map(one).collect::<Vec<_>>().join(";")
}

/// Parses the text form of a list of paths (module docs).
pub fn parse_paths(s: &str) -> Result<Vec<PathValue>, String> {
    let num = |t: &str| -> Result<f64, String> {
        t.trim()
            .parse::<f64>()
            .map_err(|_| format!("{t:?} is not a number"))
    };
    let mut out = Vec::new();
    for (k, part) in s.split(';').enumerate() {
        if part.trim().is_empty() {
            continue;
        }
        let mut path = PathValue::default();
        for item in part.split(',').map(str::trim).filter(|t| !t.is_empty()) {
            if item == "closed" {
                path.closed = true;
            } else if let Some((name, v)) = item.split_once('=') {
                let v = v.trim();
                let value = if v.contains('/') {
                    ParamValue::Profile(v.split('/').map(num).collect::<Result<_, _>>()?)
                } else if let Ok(x) = v.parse::<f64>() {
                    ParamValue::Float(x)
                } else if v == "true" || v == "false" {
                    ParamValue::Bool(v == "true")
                } else {
                    ParamValue::Choice(v.to_string())
                };
                path.params.insert(name.trim().to_string(), value);
            } else if let Some((x, y)) = item.split_once(':') {
                path.points.push([num(x)?, num(y)?]);
            } else {
                return Err(format!(
                    "path {}: {item:?} is not x:y, closed or name=value",
                    k + 1
                ));
            }
        }
        out.push(path);
    }
    Ok(out)
}

/// Visits every parameter of `p` but those named in `skip`, through `v`: a params struct
/// reused inside another one without some of its fields (the pen's per-stroke parameters
/// without the stroke's own path).
pub fn visit_except<P: Params>(p: &mut P, v: &mut dyn ParamVisitor, skip: &[&str]) {
    struct Except<'a> {
        inner: &'a mut dyn ParamVisitor,
        skip: &'a [&'a str],
    }
    macro_rules! forward {
        ($($m:ident: $t:ty),*) => {$(
            fn $m(&mut self, name: &'static str, value: $t, meta: &Meta) {
                if !self.skip.contains(&name) {
                    self.inner.$m(name, value, meta);
                }
            }
        )*};
    }
    impl ParamVisitor for Except<'_> {
        forward!(bool: &mut bool, int: &mut i64, float: &mut f64, text: &mut String,
            path: &mut String, vec3: &mut [f64; 3], floats: &mut Vec<f64>,
            profile: &mut Vec<f64>, points: &mut Vec<[f64; 2]>, paths: &mut Vec<PathValue>);
        fn choice(
            &mut self,
            name: &'static str,
            value: &mut &'static str,
            options: &[&'static str],
            meta: &Meta,
        ) {
            if !self.skip.contains(&name) {
                self.inner.choice(name, value, options, meta);
            }
        }
    }
    p.visit(&mut Except { inner: v, skip });
}

/// Applies the parameters a path sets for itself onto `p` (a copy of its node's), allowing
/// only the names in `own`; kinds and ranges are checked as [`super::from_values`] checks them.
pub fn apply_own<P: Params>(
    p: &mut P,
    values: &BTreeMap<String, ParamValue>,
    own: &[&str],
) -> Result<(), ParamError> {
    if let Some(name) = values.keys().find(|k| !own.contains(&k.as_str())) {
        return Err(ParamError::Range {
            name: name.clone(),
            detail: format!(
                "a path cannot set {name:?} for itself (it may set {}){}",
                own.join(", "),
                nearest(name, own.iter().copied())
                    .map(|s| format!("; did you mean {s:?}?"))
                    .unwrap_or_default()
            ),
        });
    }
    super::apply_onto(p, values)
}

/// Divides the lengths among a path's own parameters by `s`, as [`super::scaled`] divides its
/// node's (`infos`: the node's declarations): those with unit `px`, kept within their range.
pub(super) fn scale_own(values: &mut BTreeMap<String, ParamValue>, infos: &[ParamInfo], s: f64) {
    for (name, v) in values.iter_mut() {
        let Some(info) = infos.iter().find(|i| i.name == name) else {
            continue;
        };
        if info.meta.unit != "px" {
            continue;
        }
        let scale = |x: f64| {
            let y = x / s;
            match info.meta.range {
                Some((lo, hi)) => y.clamp(lo, hi),
                None => y,
            }
        };
        match v {
            ParamValue::Float(x) => *x = scale(*x),
            ParamValue::Int(i) if info.kind == super::ParamKind::Float => {
                *v = ParamValue::Float(scale(*i as f64));
            }
            ParamValue::Floats(l) | ParamValue::Profile(l) => {
                for x in l {
                    *x = scale(*x);
                }
            }
            _ => {}
        }
    }
}
