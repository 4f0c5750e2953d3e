//! `rgbn check` and `rgbn ops` (a part of [`crate::cli`]): a graph file validated, and every
//! operator's documentation from the registry.

use super::error::CliError;
use super::graph::CheckArgs;
use super::out::Out;
use crate::graph::LoadedGraph;
use crate::nodes::{registry, PortType};
use crate::params::{ParamKind, ParamValue};

/// `rgbn check`.
pub fn check_cmd(a: &CheckArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let lg = LoadedGraph::load(&a.graph)?;
    let ins: Vec<String> = lg
        .graph
        .inputs
        .iter()
        .map(|(n, d)| format!("{n} ({})", d.ty.name()))
        .collect();
    let outs: Vec<String> = lg
        .graph
        .outputs
        .keys()
        .map(|n| format!("{n} ({})", lg.output_type(n).map_or("?", PortType::name)))
        .collect();
    out.line(format_args!(
        "ok: {} nodes; inputs: {}; outputs: {}: {}",
        lg.graph.nodes.len(),
        if ins.is_empty() {
            "none".into()
        } else {
            ins.join(", ")
        },
        if outs.is_empty() {
            "none".into()
        } else {
            outs.join(", ")
        },
        a.graph.display()
    ))
}

fn kind_name(k: &ParamKind) -> String {
    match k {
        ParamKind::Bool => "bool".into(),
        ParamKind::Int => "int".into(),
        ParamKind::Float => "float".into(),
        ParamKind::Choice(o) => format!("one of {}", o.join("|")),
        ParamKind::Text => "text".into(),
        ParamKind::Path => "path".into(),
        ParamKind::Vec3 => "x,y,z".into(),
        ParamKind::Floats => "numbers a,b,…".into(),
        ParamKind::Profile => "profile a,b,…".into(),
        ParamKind::Points => "points x:y,…".into(),
        ParamKind::Paths => "paths x:y,…[,closed][,name=value];…".into(),
    }
}

/// `rgbn ops`: every operator with its doc, ports and parameters, from the specs.
pub fn ops_cmd(out: &mut Out<'_>) -> Result<(), CliError> {
    for op in registry() {
        let s = op.spec();
        out.line(format_args!("{} — {} [{}]", s.id, s.title, s.category))?;
        out.line(format_args!("    {}", s.doc))?;
        for (dir, ports) in [("in ", &s.inputs), ("out", &s.outputs)] {
            for p in ports {
                out.line(format_args!(
                    "    {dir} {}: {}{} — {}",
                    p.name,
                    p.ty.name(),
                    if p.optional { " (optional)" } else { "" },
                    p.doc
                ))?;
            }
        }
        for p in op.params() {
            let range = p.meta.ranges_text();
            let default = match &p.default {
                ParamValue::Path(s) | ParamValue::Text(s) if s.is_empty() => "none".into(),
                v => v.to_string(),
            };
            out.line(format_args!(
                "    param {}: {}{}{range}, default {default} — {}",
                p.name,
                kind_name(&p.kind),
                if p.meta.unit.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", p.meta.unit)
                },
                p.meta.doc
            ))?;
        }
        out.line("")?;
    }
    out.line(format_args!(
            "{} — Graph file as a node [graph]\n    Uses another graph file (param path, relative to this file): its inputs, outputs and exposed parameters become the node's ports and parameters.",
            crate::nodes::GRAPH_NODE_OP
        ),
    )
}
