//! The memory a plan needs, estimated before it runs, and the budget it must fit in.
//!
//! Every operator states the pixel size of its outputs before running
//! ([`Operator::out_size`](crate::nodes::Operator::out_size): sources from their parameters or
//! file headers, everything else from its first image input), so the sizes of every value
//! propagate through the plan without computing anything. The evaluator keeps every value it
//! computes until the evaluation ends (later nodes and the caller read them), so the estimated
//! peak is the sum of the outputs of the nodes that must run, plus the largest working memory of
//! one of them ([`Operator::SCRATCH`](crate::nodes::Operator::SCRATCH) × its output bytes).
//!
//! The budget is `RGBN_MEMORY_LIMIT` (bytes, or with a unit: `512M`, `2G`, `1.5GiB`, `0` for no
//! limit), by default 80 % of the physical memory. A plan over budget is refused before
//! anything runs, with an error naming the nodes that need the most — never an OOM kill.

use super::Plan;
use crate::graph::{At, GraphError};
use crate::nodes::PortType;
use std::collections::HashMap;

/// Bytes per pixel of a value of type `ty` (an RGBN image with its mask: 7 `f32` planes).
#[must_use]
pub fn bytes_per_pixel(ty: PortType) -> u64 {
    match ty {
        PortType::Rgbn => 28,
        PortType::Mask | PortType::Scalar | PortType::Picture => 4,
        PortType::Number => 0,
    }
}

/// One node's share of an estimate.
#[derive(Clone, Debug)]
pub struct NodeNeed {
    /// The node.
    pub at: At,
    /// Its operator.
    pub op: &'static str,
    /// Bytes of its outputs.
    pub output: u64,
    /// Bytes of working memory while it runs.
    pub scratch: u64,
}

/// A plan's estimated peak memory.
#[derive(Clone, Debug, Default)]
pub struct Estimate {
    /// Estimated peak bytes.
    pub peak: u64,
    /// The nodes that run, with their needs.
    pub nodes: Vec<NodeNeed>,
    /// Nodes whose output size cannot be known before running (counted as 0).
    pub unknown: usize,
}

/// The output sizes of every instance of `plan` (known ones), in plan order. `cached` gives
/// the sizes of values already computed (a cache hit's actual size).
#[must_use]
pub fn sizes(plan: &Plan, cached: &HashMap<usize, (usize, usize)>) -> Vec<Option<(usize, usize)>> {
    let mut out: Vec<Option<(usize, usize)>> = Vec::with_capacity(plan.instances.len());
    for (i, inst) in plan.instances.iter().enumerate() {
        if let Some(s) = cached.get(&i) {
            out.push(Some(*s));
            continue;
        }
        let inputs: Vec<Option<(usize, usize)>> = inst
            .inputs
            .iter()
            .map(|c| match c {
                super::Conn::Slot(j, _) => out.get(*j).copied().flatten(),
                _ => None,
            })
            .collect();
        out.push(inst.op.out_size(&inst.params, &inputs));
    }
    out
}

/// Estimates the peak memory of running the instances `run` of `plan`.
#[must_use]
pub fn estimate(plan: &Plan, run: &[usize], sizes: &[Option<(usize, usize)>]) -> Estimate {
    let mut e = Estimate::default();
    let mut max_scratch = 0u64;
    for &i in run {
        let inst = &plan.instances[i];
        let Some((w, h)) = sizes[i] else {
            e.unknown += 1;
            continue;
        };
        let px = w as u64 * h as u64;
        let output: u64 = inst
            .op
            .spec()
            .outputs
            .iter()
            .map(|p| px * bytes_per_pixel(p.ty))
            .sum();
        let scratch = (output as f64 * inst.op.scratch()) as u64;
        max_scratch = max_scratch.max(scratch);
        e.peak += output;
        e.nodes.push(NodeNeed {
            at: inst.at.clone(),
            op: inst.op.spec().id,
            output,
            scratch,
        });
    }
    e.peak += max_scratch;
    e
}

/// Parses a byte count: a number with an optional unit K, M, G, T (powers of 1024; `KB`,
/// `KiB`… accepted alike, case-insensitive). `0` means no limit.
///
/// # Errors
/// A message saying what is wrong.
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let v: f64 = num
        .parse()
        .map_err(|_| format!("{s:?} is not a byte count (e.g. 4G, 512M, 1.5GiB)"))?;
    let unit = unit.trim().to_ascii_lowercase();
    let unit = unit.trim_end_matches('b').trim_end_matches('i');
    let k = match unit {
        "" => 1u64,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => return Err(format!("{s:?}: unknown unit (use K, M, G or T)")),
    };
    if !v.is_finite() || v < 0.0 || v * k as f64 > u64::MAX as f64 {
        return Err(format!("{s:?} is not a byte count"));
    }
    Ok((v * k as f64) as u64)
}

/// The physical memory of this machine, if known.
#[must_use]
pub fn physical_memory() -> Option<u64> {
    #[cfg(unix)]
    {
        // SAFETY: sysconf only reads configuration values.
        let (pages, size) = unsafe {
            (
                libc::sysconf(libc::_SC_PHYS_PAGES),
                libc::sysconf(libc::_SC_PAGESIZE),
            )
        };
        (pages > 0 && size > 0).then(|| pages as u64 * size as u64)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The memory budget: `RGBN_MEMORY_LIMIT`, else 80 % of the physical memory; `None` for no
/// limit (`RGBN_MEMORY_LIMIT=0`, or the machine's memory unknown).
///
/// # Errors
/// [`GraphError::Memory`]-free: a usage error naming the variable when it does not parse.
pub fn budget() -> Result<Option<u64>, GraphError> {
    match std::env::var("RGBN_MEMORY_LIMIT") {
        Ok(s) => {
            let b = parse_bytes(&s).map_err(|detail| GraphError::Env {
                var: "RGBN_MEMORY_LIMIT",
                detail,
            })?;
            Ok((b > 0).then_some(b))
        }
        Err(_) => Ok(physical_memory().map(|m| m / 5 * 4)),
    }
}

/// Human-readable bytes in binary units (MiB / GiB, as `RGBN_MEMORY_LIMIT` takes them).
#[must_use]
pub fn human(b: u64) -> String {
    if b >= 1 << 30 {
        format!("{:.2} GiB", b as f64 / f64::from(1u32 << 30))
    } else {
        format!("{:.1} MiB", b as f64 / f64::from(1u32 << 20))
    }
}

/// The peak resident memory of this process so far (Linux `VmHWM`), if known.
#[must_use]
pub fn measured_peak() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Refuses an estimate over `budget`: the error lists the nodes needing the most.
///
/// # Errors
/// [`GraphError::Memory`].
pub fn check(e: &Estimate, budget: Option<u64>, at: &At) -> Result<(), GraphError> {
    let Some(budget) = budget else {
        return Ok(());
    };
    if e.peak <= budget {
        return Ok(());
    }
    let mut nodes: Vec<&NodeNeed> = e.nodes.iter().collect();
    nodes.sort_by_key(|n| std::cmp::Reverse(n.output + n.scratch));
    let list: Vec<String> = nodes
        .iter()
        .take(4)
        .map(|n| format!("{} {} {}", n.at.short(), n.op, human(n.output + n.scratch)))
        .collect();
    let more = nodes.len().saturating_sub(4);
    Err(GraphError::Memory {
        need: human(e.peak),
        budget: human(budget),
        nodes: if more > 0 {
            format!("{}, and {more} more", list.join(", "))
        } else {
            list.join(", ")
        },
        at: at.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_counts_parse_with_binary_units() {
        assert_eq!(parse_bytes("1024"), Ok(1024));
        assert_eq!(parse_bytes("2G"), Ok(2 << 30));
        assert_eq!(parse_bytes("512 MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5gb"), Ok(3 << 29));
        assert_eq!(parse_bytes("0"), Ok(0));
        for bad in ["", "G", "-1G", "1X", "1.2.3", "nan"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }
}
