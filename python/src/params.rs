//! Parameters from Python values, through the command line's `--set` parser: a Python value
//! becomes the text `--set` would take (floats by `repr`, which reads back to the same bits),
//! and [`ParamInfo::parse_str`] parses it by the parameter's kind, so a script gets the same
//! values and the same messages as `rgbn eval --set`.

use crate::error::input;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use rgbn::params::{nearest, ParamInfo, ParamKind, ParamValue};
use std::collections::BTreeMap;

/// The `--set` text of a Python value: `True`/`False`, numbers by `repr`, strings and paths
/// as they are, sequences comma separated (pairs as `x:y`).
pub fn text_of(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if v.is_instance_of::<PyBool>() {
        return Ok(if v.extract::<bool>()? {
            "true"
        } else {
            "false"
        }
        .into());
    }
    if v.is_instance_of::<PyInt>() || v.is_instance_of::<PyFloat>() {
        return Ok(v.repr()?.to_string());
    }
    if v.is_instance_of::<PyString>() {
        return v.extract::<String>();
    }
    if v.hasattr("__fspath__")? {
        return Ok(v.call_method0("__fspath__")?.str()?.to_string());
    }
    // NumPy scalars and arrays, lists, tuples.
    if v.hasattr("tolist")? {
        return text_of(&v.call_method0("tolist")?);
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut parts = Vec::new();
        for item in v.try_iter()? {
            let item = item?;
            let pair = (item.is_instance_of::<PyList>() || item.is_instance_of::<PyTuple>())
                && item.len()? == 2;
            parts.push(if pair {
                format!(
                    "{}:{}",
                    text_of(&item.get_item(0)?)?,
                    text_of(&item.get_item(1)?)?
                )
            } else {
                text_of(&item)?
            });
        }
        return Ok(parts.join(","));
    }
    Ok(v.str()?.to_string())
}

/// A parameter value as a Python object.
pub fn py_of<'py>(py: Python<'py>, v: &ParamValue) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        ParamValue::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        ParamValue::Int(i) => i.into_pyobject(py)?.into_any(),
        ParamValue::Float(x) => x.into_pyobject(py)?.into_any(),
        ParamValue::Choice(s) | ParamValue::Text(s) | ParamValue::Path(s) => {
            s.into_pyobject(py)?.into_any()
        }
        ParamValue::Vec3(a) => PyTuple::new(py, a)?.into_any(),
        ParamValue::Floats(a) | ParamValue::Profile(a) => PyList::new(py, a)?.into_any(),
        ParamValue::Points(p) => {
            PyList::new(py, p.iter().map(|[x, y]| (*x, *y)).collect::<Vec<_>>())?.into_any()
        }
        ParamValue::Paths(paths) => {
            let list = PyList::empty(py);
            for p in paths {
                let d = PyDict::new(py);
                d.set_item("points", py_of(py, &ParamValue::Points(p.points.clone()))?)?;
                d.set_item("closed", p.closed)?;
                let own = PyDict::new(py);
                for (k, v) in &p.params {
                    own.set_item(k, py_of(py, v)?)?;
                }
                d.set_item("params", own)?;
                list.append(d)?;
            }
            list.into_any()
        }
    })
}

/// The `--set` text of a list of paths: each a sequence of `(x, y)` or a dict with `points`,
/// optionally `closed` and `params` (the path's own parameters); a string as it is.
fn paths_text_of(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if v.is_instance_of::<PyString>() {
        return v.extract::<String>();
    }
    let mut paths = Vec::new();
    for item in v.try_iter()? {
        let item = item?;
        let Ok(d) = item.cast::<PyDict>() else {
            paths.push(text_of(&item)?);
            continue;
        };
        let points = d
            .get_item("points")?
            .ok_or_else(|| input("a path dict needs \"points\""))?;
        let mut parts = vec![text_of(&points)?];
        if let Some(c) = d.get_item("closed")? {
            if c.extract::<bool>()? {
                parts.push("closed".into());
            }
        }
        if let Some(own) = d.get_item("params")? {
            for (k, v) in own.cast::<PyDict>()?.iter() {
                // A list (custom samples) as a/b/c.
                let text = text_of(&v)?.replace(',', "/");
                parts.push(format!("{}={text}", k.str()?));
            }
        }
        paths.push(parts.join(","));
    }
    Ok(paths.join(";"))
}

/// Parses `kwargs` for an operator with parameters `infos` (unknown names refused with the
/// nearest one, as `--set` refuses them).
pub fn values_of(
    op: &str,
    infos: &[ParamInfo],
    kwargs: &BTreeMap<String, Bound<'_, PyAny>>,
) -> PyResult<BTreeMap<String, ParamValue>> {
    let mut out = BTreeMap::new();
    for (name, v) in kwargs {
        let Some(info) = infos.iter().find(|i| i.name == name) else {
            return Err(input(format!(
                "unknown parameter {name:?} of {op}{}",
                nearest(name, infos.iter().map(|i| i.name))
                    .map(|s| format!(" (did you mean {s:?}?)"))
                    .unwrap_or_default()
            )));
        };
        let text = if info.kind == ParamKind::Paths {
            paths_text_of(v)?
        } else {
            text_of(v)?
        };
        let value = info
            .parse_str(&text)
            .map_err(|detail| input(format!("cannot set {name:?} to {text:?}: {detail}: {op}")))?;
        out.insert(name.clone(), value);
    }
    Ok(out)
}
