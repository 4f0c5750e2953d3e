//! Every operator's output is pinned with its version, so a cache can never serve old maths.
//!
//! A node's cache key (memory and `--cache-dir`) holds its operator's id and `OpSpec::version`,
//! not its code: if an operator's maths changes and its version does not, a disk cache made by
//! the old binary serves the old pixels. `tests/op_versions.txt` holds, for every registered
//! operator with outputs, its version and the statistics of its outputs (per channel, as the
//! golden files: mean, spread, extremes, 16 samples) at its first node in the example graphs.
//! An output that changes while the version stays fails here, naming the operator and what to
//! bump. `UPDATE_GOLDEN=1 cargo test --test tests op_versions` rewrites the table after a bump.
//! (GEGL pins a reference hash per operation for the same reason; statistics within a tolerance
//! rather than a hash, because SIMD twins and thread counts change the last bits.)

use crate::common::*;
use rgbn::eval::Evaluator;
use rgbn::graph::{LoadedGraph, PortRef};
use rgbn::nodes::registry;
use std::collections::BTreeMap;

/// Per operator: its version and its output lines (`label value…`).
type Table = BTreeMap<String, (u32, Vec<String>)>;

const TABLE: &str = "tests/op_versions.txt";

/// Operators that have outputs to pin (those without only write files: `save`).
fn pinnable() -> BTreeMap<&'static str, u32> {
    registry()
        .iter()
        .map(|op| op.spec())
        .filter(|s| !s.outputs.is_empty())
        .map(|s| (s.id, s.version))
        .collect()
}

/// Evaluates the example graphs and pins each operator at its first node (graphs in name
/// order, nodes in id order; the top-level graphs first, then the library and paper graphs for
/// operators only they use).
fn current() -> Table {
    let want = pinnable();
    let mut table = Table::new();
    let out_dir = tempfile::tempdir().unwrap();
    let mut graphs = top_graphs();
    let rest: Vec<_> = all_graphs()
        .into_iter()
        .filter(|p| !graphs.contains(p))
        .collect();
    graphs.extend(rest);
    for path in graphs {
        if table.len() == want.len() {
            break;
        }
        let stem = path
            .strip_prefix(root().join("graphs"))
            .unwrap()
            .with_extension("")
            .display()
            .to_string();
        let mut lg = LoadedGraph::load(&path).unwrap_or_else(|e| panic!("{e}"));
        // The first node of each operator not pinned yet, its ports as extra graph outputs.
        let mut here: Vec<(String, u64, Vec<String>)> = Vec::new();
        for n in lg.graph.nodes.values() {
            if !want.contains_key(n.op.as_str())
                || table.contains_key(&n.op)
                || here.iter().any(|(op, ..)| *op == n.op)
            {
                continue;
            }
            let spec = rgbn::nodes::find(&n.op).unwrap().spec();
            let ports: Vec<String> = spec.outputs.iter().map(|p| p.name.clone()).collect();
            here.push((n.op.clone(), n.id, ports));
        }
        if here.is_empty() {
            continue;
        }
        for (_, id, ports) in &here {
            for port in ports {
                lg.graph.outputs.insert(
                    format!("pin.{id}.{port}"),
                    PortRef {
                        node: *id,
                        port: port.clone(),
                    },
                );
            }
        }
        // Graphs needing inputs the examples do not bind (library graphs) are skipped.
        let plan = rgbn::eval::Plan::new(&lg, &example_bindings(&lg), out_dir.path());
        let Ok(plan) = plan else { continue };
        let names: Vec<String> = here
            .iter()
            .flat_map(|(_, id, ports)| ports.iter().map(move |p| format!("pin.{id}.{p}")))
            .collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let r = Evaluator::default()
            .eval(&plan, &names, &rgbn::eval::EvalOptions::default())
            .unwrap_or_else(|e| panic!("{stem}: {e}"));
        for (op, id, ports) in here {
            let mut lines = Vec::new();
            for port in ports {
                let v = &r.outputs[&format!("pin.{id}.{port}")];
                let text = summarise(&format!("{stem}#{id}.{port}"), v);
                lines.extend(text.lines().map(str::to_string));
            }
            table.insert(op.clone(), (want[op.as_str()], lines));
        }
    }
    table
}

fn write_table(t: &Table) -> String {
    let mut s = String::from(
        "# Every operator's output at its first example node, with its OpSpec::version\n\
         # (tests/it/op_versions.rs). Rewrite after a version bump: UPDATE_GOLDEN=1 cargo test --test tests op_versions\n",
    );
    for (op, (v, lines)) in t {
        for l in lines {
            s.push_str(&format!("{op} {v} {l}\n"));
        }
    }
    s
}

fn read_table(text: &str) -> Table {
    let mut t = Table::new();
    for l in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let mut w = l.splitn(3, ' ');
        let (op, v, rest) = (w.next().unwrap(), w.next().unwrap(), w.next().unwrap());
        let e = t
            .entry(op.to_string())
            .or_insert_with(|| (v.parse().unwrap(), Vec::new()));
        e.1.push(rest.to_string());
    }
    t
}

/// Where the pinned table and the current outputs disagree, one message each.
fn check(pinned: &Table, now: &Table) -> Vec<String> {
    let mut errs = Vec::new();
    let regen = "UPDATE_GOLDEN=1 cargo test --test tests op_versions";
    for (op, (v, lines)) in now {
        let Some((pv, plines)) = pinned.get(op) else {
            errs.push(format!(
                "operator {op} is not pinned in {TABLE}: run {regen}"
            ));
            continue;
        };
        if pv != v {
            errs.push(format!(
                "operator {op} is version {v}, {TABLE} pins version {pv}: after a bump, run {regen}"
            ));
            continue;
        }
        let changed = first_difference(plines, lines);
        if let Some(what) = changed {
            errs.push(format!(
                "operator {op}'s output changed ({what}) but its OpSpec::version is still {v}: \
                 bump `version` in {op}'s spec (src/nodes/) so caches made with the old maths \
                 are not served, then run {regen}"
            ));
        }
    }
    for op in pinned.keys().filter(|op| !now.contains_key(*op)) {
        errs.push(format!(
            "{TABLE} pins {op}, which is no longer registered: run {regen}"
        ));
    }
    errs
}

fn first_difference(pinned: &[String], now: &[String]) -> Option<String> {
    if pinned.len() != now.len() {
        return Some(format!("{} channels, pinned {}", now.len(), pinned.len()));
    }
    for (p, n) in pinned.iter().zip(now) {
        let pw: Vec<&str> = p.split_whitespace().collect();
        let nw: Vec<&str> = n.split_whitespace().collect();
        if pw[0] != nw[0] || pw.len() != nw.len() {
            return Some(format!("channel {} where {} was pinned", nw[0], pw[0]));
        }
        for (a, b) in pw[1..].iter().zip(&nw[1..]) {
            let (a, b): (f64, f64) = (a.parse().unwrap(), b.parse().unwrap());
            if (a - b).abs() > tolerance(pw[0], a) {
                return Some(format!("{}: pinned {a}, now {b}", pw[0]));
            }
        }
    }
    None
}

#[test]
fn every_operator_output_is_pinned_with_its_version() {
    let now = current();
    let want = pinnable();
    let missing: Vec<&&str> = want.keys().filter(|op| !now.contains_key(**op)).collect();
    assert!(missing.is_empty(), "no example graph evaluates {missing:?}");
    let path = root().join(TABLE);
    if std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v == "1") {
        std::fs::write(&path, write_table(&now)).unwrap();
        return;
    }
    let pinned = read_table(&std::fs::read_to_string(&path).unwrap_or_default());
    let errs = check(&pinned, &now);
    assert!(errs.is_empty(), "{}", errs.join("\n"));
}

#[test]
fn a_changed_output_without_a_version_bump_is_named() {
    // The pinned table against a copy with one operator's output moved: the check names that
    // operator and asks for a bump; with the version bumped too it asks for the table instead.
    let pinned = read_table(&std::fs::read_to_string(root().join(TABLE)).unwrap());
    let op = "filter.gaussian";
    let mut moved = pinned.clone();
    let (_, lines) = moved.get_mut(op).expect("filter.gaussian is pinned");
    let mut w: Vec<String> = lines[0].split_whitespace().map(str::to_string).collect();
    let mean: f64 = w[1].parse().unwrap();
    w[1] = format!("{:.6e}", mean + 1e-3 + 1e-2 * mean.abs());
    lines[0] = w.join(" ");
    let errs = check(&pinned, &moved);
    assert_eq!(errs.len(), 1, "{errs:?}");
    assert!(errs[0].starts_with(&format!("operator {op}'s output changed")));
    assert!(errs[0].contains("bump `version`"), "{}", errs[0]);
    moved.get_mut(op).unwrap().0 += 1;
    let errs = check(&pinned, &moved);
    assert_eq!(errs.len(), 1, "{errs:?}");
    assert!(errs[0].contains("pins version"), "{}", errs[0]);
    // Unchanged outputs pass.
    assert!(check(&pinned, &pinned).is_empty());
}
