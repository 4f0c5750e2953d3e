//! Graph inputs bound to values in memory ([`Plan::bind_values`]): the way a host program
//! (the Python package) evaluates a graph on images it already holds, without files.
//!
//! Each value becomes a bound-value source node ([`crate::nodes::bound`]) keyed by the value's
//! content hash, so caching works as for files: the same pixels again are a hit.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{Conn, Instance, Plan};
use crate::graph::{At, GraphError, LoadedGraph};
use crate::nodes::bound::{content_key, Binding};
use crate::nodes::Value;
use crate::params::{nearest, ParamValue};
use std::collections::BTreeMap;

impl Plan {
    /// Binds graph inputs of `lg` (the graph this plan was made from, with those inputs left
    /// unbound) to `values`. The returned bindings hold the values for the bound nodes: keep
    /// them alive until the evaluations of this plan are done.
    ///
    /// # Errors
    /// An unknown input name (with the nearest one), a value whose type is not the input's, or
    /// an input already bound to a file.
    pub fn bind_values(
        &mut self,
        lg: &LoadedGraph,
        values: BTreeMap<String, Value>,
    ) -> Result<Vec<Binding>, GraphError> {
        let mut front = Vec::with_capacity(values.len());
        let mut bindings = Vec::with_capacity(values.len());
        let mut slot_of = BTreeMap::new();
        for (name, value) in values {
            let Some(def) = lg.graph.inputs.get(&name) else {
                return Err(GraphError::Unknown {
                    what: "graph input",
                    name: name.clone(),
                    suggestion: nearest(&name, lg.graph.inputs.keys().map(String::as_str)),
                    at: lg.at(),
                });
            };
            let ty = value.port_type();
            let param_error = |detail: String| GraphError::Param {
                param: name.clone(),
                detail,
                at: lg.at(),
            };
            if def.ty != ty {
                return Err(param_error(format!(
                    "graph input {name:?} takes {} values, got {}",
                    def.ty.name(),
                    ty.name()
                )));
            }
            let op = crate::nodes::bound_op(ty).ok_or_else(|| {
                param_error(format!(
                    "graph input {name:?}: {} values cannot be bound from memory",
                    ty.name()
                ))
            })?;
            let (w, h) = match &value {
                Value::Rgbn(i) => (i.width(), i.height()),
                Value::Mask(p) | Value::Scalar(p) => (p.width(), p.height()),
                Value::Picture(p) => (p.width, p.height),
                Value::Number(_) => (0, 0),
            };
            let key = content_key(&value);
            let params: BTreeMap<String, ParamValue> = [
                ("key".to_string(), ParamValue::Text(key.clone())),
                ("width".to_string(), ParamValue::Int(w as i64)),
                ("height".to_string(), ParamValue::Int(h as i64)),
            ]
            .into();
            let params = op.parse(&params).map_err(|e| param_error(e.to_string()))?;
            bindings.push(Binding::new(key, value));
            slot_of.insert(name.clone(), front.len());
            front.push(Instance {
                op,
                params,
                inputs: Vec::new(),
                at: At::file(format!("bound input {name}")),
            });
        }
        if front.is_empty() {
            return Ok(bindings);
        }
        // The bound sources go first (instances are in topological order); every other index
        // moves by their number.
        let k = front.len();
        let mut used = vec![false; k];
        let mut remap = |c: &mut Conn| match c {
            Conn::Slot(j, _) => *j += k,
            Conn::Unbound { name, .. } => {
                if let Some(&s) = slot_of.get(name.as_str()) {
                    used[s] = true;
                    *c = Conn::Slot(s, 0);
                }
            }
            Conn::None => {}
        };
        for inst in &mut self.instances {
            inst.inputs.iter_mut().for_each(&mut remap);
        }
        self.outputs.values_mut().for_each(&mut remap);
        // A value for an input the plan already reads from a file: refuse rather than ignore.
        if let Some((name, _)) = slot_of.iter().find(|(_, &s)| !used[s]) {
            let bound_to_file = self
                .instances
                .iter()
                .any(|i| i.at.file.starts_with(&format!("--input {name}=")));
            if bound_to_file {
                return Err(GraphError::Param {
                    param: name.clone(),
                    detail: format!("graph input {name:?} is given both a file and a value"),
                    at: lg.at(),
                });
            }
        }
        front.append(&mut self.instances);
        self.instances = front;
        Ok(bindings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::{EvalOptions, Evaluator};
    use crate::raster::sample::demo_medallion;
    use std::path::Path;

    fn graph() -> LoadedGraph {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs");
        LoadedGraph::load(&dir.join("input_image.ron")).unwrap()
    }

    #[test]
    fn a_bound_image_equals_the_same_image_loaded_from_a_file() {
        let lg = graph();
        let img = demo_medallion(48);
        let d = tempfile::tempdir().unwrap();
        let file = d.path().join("in.exr");
        crate::raster::io::save(&img, &file, &Default::default()).unwrap();
        let ev = Evaluator::default();
        let opts = EvalOptions::default();
        let by_file = Plan::new(&lg, &[("image".into(), file)].into(), d.path()).unwrap();
        let want = ev.eval(&by_file, &[], &opts).unwrap();
        let mut plan = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let held = plan
            .bind_values(&lg, [("image".into(), Value::Rgbn(img.clone()))].into())
            .unwrap();
        let got = ev.eval(&plan, &[], &opts).unwrap();
        assert_eq!(got.outputs, want.outputs);
        // The same content again: both outputs' nodes are hits (a cached node is not
        // descended into); other content: every node misses.
        let again = ev.eval(&plan, &[], &opts).unwrap();
        assert_eq!((again.hits(), again.misses()), (2, 0));
        drop(held);
        let mut other = img;
        other.normal_mut()[0][5] = 0.25;
        other.normalize();
        let mut plan2 = Plan::new(&lg, &BTreeMap::new(), d.path()).unwrap();
        let _held = plan2
            .bind_values(&lg, [("image".into(), Value::Rgbn(other))].into())
            .unwrap();
        let r = ev.eval(&plan2, &[], &opts).unwrap();
        assert_eq!((r.hits(), r.misses()), (0, 3));
    }

    #[test]
    fn wrong_type_unknown_name_and_a_dropped_binding_are_errors() {
        let lg = graph();
        let d = Path::new(".");
        let mut plan = Plan::new(&lg, &BTreeMap::new(), d).unwrap();
        let mask = Value::Mask(std::sync::Arc::new(crate::Plane::filled(4, 4, 1.0)));
        let e = plan
            .bind_values(&lg, [("image".into(), mask)].into())
            .unwrap_err()
            .to_string();
        assert!(e.contains("takes rgbn values, got mask"), "{e}");
        let img = Value::Rgbn(demo_medallion(16));
        let e = plan
            .bind_values(&lg, [("imag".into(), img.clone())].into())
            .unwrap_err()
            .to_string();
        assert!(e.contains("did you mean \"image\""), "{e}");
        let held = plan
            .bind_values(&lg, [("image".into(), img)].into())
            .unwrap();
        drop(held);
        let e = Evaluator::default()
            .eval(&plan, &[], &EvalOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("is no longer held"), "{e}");
    }
}
