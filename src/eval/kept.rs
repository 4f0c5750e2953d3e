//! Evaluating many outputs while keeping few values: the editor's whole-graph refresh.
//!
//! [`Evaluator::eval`] keeps every value it computed until the evaluation ends (they are its
//! result). The editor needs each node's value only for a moment (its thumbnail, its key) and
//! keeps whole values for a few outputs only (the one viewed, the input of a before/after
//! split): [`Evaluator::eval_kept`] hands each value obtained to a callback and drops it as
//! soon as no node still to run reads it, unless it is one to keep. Eighty chained pen nodes
//! on a 2048² image then hold two or three images at once beside the cache, not eighty
//! (issue 36 item 6: 15.3 GB RSS against a 5.9 GiB cache).

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{CacheEntry, CacheKey, Conn, EvalOptions, EvalResult, Evaluator, Plan};
use crate::graph::GraphError;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::Arc;

/// Called with each value an evaluation obtains (computed or from a cache): the instance's
/// index in the plan, its content key and its outputs.
pub type ValueFn = Arc<dyn Fn(usize, CacheKey, &Arc<CacheEntry>) + Send + Sync>;

/// What [`Evaluator::eval_kept`] keeps, and whom it tells.
pub(super) struct Keep<'a> {
    /// Instances whose values are kept to the end (the result's outputs).
    pub kept: HashSet<usize>,
    /// Told of every value obtained.
    pub on_value: Option<&'a ValueFn>,
}

impl Keep<'_> {
    /// Tells the callback of the value of instance `i`.
    pub(super) fn tell(&self, i: usize, key: CacheKey, e: &Arc<CacheEntry>) {
        if let Some(f) = self.on_value {
            f(i, key, e);
        }
    }
}

/// How many nodes still to run read each instance (an input read twice counts twice).
pub(super) fn readers(plan: &Plan, to_run: &[usize]) -> HashMap<usize, usize> {
    let mut n = HashMap::new();
    for &i in to_run {
        for c in &plan.instances[i].inputs {
            if let Conn::Slot(j, _) = c {
                *n.entry(*j).or_insert(0) += 1;
            }
        }
    }
    n
}

/// After instance `i` ran: one reader less for each of its inputs, and the values no node
/// still reads (and not kept) are dropped from `results` — `i`'s own too when nothing reads it.
pub(super) fn release(
    plan: &Plan,
    i: usize,
    keep: &Keep,
    readers: &mut HashMap<usize, usize>,
    results: &mut HashMap<usize, Arc<CacheEntry>>,
) {
    for c in &plan.instances[i].inputs {
        if let Conn::Slot(j, _) = c {
            if let Some(n) = readers.get_mut(j) {
                *n -= 1;
                if *n == 0 && !keep.kept.contains(j) {
                    results.remove(j);
                }
            }
        }
    }
    if !readers.contains_key(&i) && !keep.kept.contains(&i) {
        results.remove(&i);
    }
}

impl Evaluator {
    /// Evaluates the graph outputs `keep` and `visit` (names of [`Plan::outputs`]) and returns
    /// the values of `keep` only: every value obtained on the way (computed, or taken from a
    /// cache) is handed to `on_value`, then dropped as soon as no node still to run reads it.
    /// The memory held beyond the cache is the kept values and the nodes running with their
    /// inputs. With [`EvalOptions::curl_stats`], only the kept values get readouts.
    ///
    /// # Errors
    /// As [`Evaluator::eval`].
    pub fn eval_kept(
        &self,
        plan: &Plan,
        keep: &[&str],
        visit: &[&str],
        opts: &EvalOptions,
        on_value: Option<&ValueFn>,
    ) -> Result<EvalResult, GraphError> {
        let slot = |name: &str| -> Result<Option<(usize, usize)>, GraphError> {
            match plan.output(name)? {
                Conn::Slot(i, p) => Ok(Some((*i, *p))),
                Conn::Unbound { name, at } => Err(GraphError::UnboundInput {
                    name: name.clone(),
                    at: at.clone(),
                }),
                Conn::None => Ok(None),
            }
        };
        let mut kept = Vec::new();
        for name in keep {
            if let Some(s) = slot(name)? {
                kept.push((name.to_string(), s));
            }
        }
        let mut roots: Vec<usize> = kept.iter().map(|(_, (i, _))| *i).collect();
        for name in visit {
            if let Some((i, _)) = slot(name)? {
                roots.push(i);
            }
        }
        let k = Keep {
            kept: kept.iter().map(|(_, (i, _))| *i).collect(),
            on_value,
        };
        let whole = self.eval_instances(plan, &roots, opts, Some(&k), None)?;
        let outputs: BTreeMap<String, crate::nodes::Value> = kept
            .into_iter()
            .filter_map(|(name, (i, p))| {
                Some((name, whole.results.get(&i)?.values.get(p)?.clone()))
            })
            .collect();
        Ok(EvalResult {
            outputs,
            stats: whole.stats,
            memory: whole.memory,
        })
    }

    /// The content key of every instance `plan` names as a graph output, by output name:
    /// (the instance's key, the output's port). Nothing is evaluated (input files are hashed).
    ///
    /// # Errors
    /// An unbound input, or an input file that cannot be read.
    pub fn output_keys(
        &self,
        plan: &Plan,
    ) -> Result<BTreeMap<String, (CacheKey, usize)>, GraphError> {
        let mut keys = HashMap::new();
        let mut out = BTreeMap::new();
        for (name, c) in &plan.outputs {
            if let Conn::Slot(i, p) = c {
                out.insert(name.clone(), (self.key(plan, *i, &mut keys)?, *p));
            }
        }
        Ok(out)
    }

    /// Bytes of `values` and of the last viewport result (kept to patch after an edit) that
    /// the memory cache does not keep alive.
    #[must_use]
    pub fn held_outside<'a>(
        &self,
        values: impl IntoIterator<Item = &'a crate::nodes::Value>,
    ) -> usize {
        let seen = self.seen.lock();
        let mut all: Vec<&crate::nodes::Value> = values.into_iter().collect();
        all.extend(seen.last_value());
        let bytes = self.mem.lock().outside(all);
        bytes
    }

    /// The memory cache's byte budget.
    #[must_use]
    pub fn mem_budget(&self) -> usize {
        self.mem.lock().budget()
    }
}
