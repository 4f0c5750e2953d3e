//! Structure-aware graphs (issue 15 (b)): the fuzz input drives `arbitrary::Unstructured` to
//! build a graph of random registered operators with parameters at their defaults, inside
//! their ranges or outside them (non-finite included), random edges between type-compatible
//! ports and sources of at most 64² pixels (the demo, an analytic surface, or a loaded RGBN EXR
//! of random finite pixels, grazing and back-facing normals and random masks). The graph is
//! validated, planned and evaluated. Contract: no panic; a refused graph is refused with a
//! one-line error; a graph that evaluates (its parameters were accepted, so inside their
//! ranges) yields finite colours, masks, fields and numbers and finite unit normals.
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::arbitrary::{Result as AResult, Unstructured};
use libfuzzer_sys::fuzz_target;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::{Graph, LoadedGraph, PortRef, Source};
use rgbn::nodes::{registry, PortType, Value};
use rgbn::params::{ParamKind, ParamValue};
use rgbn::RgbnImage;
use std::collections::BTreeMap;
use std::path::Path;

/// Largest side of a source image.
const MAX_SIDE: i64 = 64;

fn number(u: &mut Unstructured, range: Option<(f64, f64)>) -> AResult<f64> {
    let (lo, hi) = range.unwrap_or((-100.0, 100.0));
    Ok(match u.int_in_range(0u8..=9)? {
        0 => lo,
        1 => hi,
        2 => lo - 1.0 - f64::from(u.int_in_range(0u16..=1000)?),
        3 => hi + 1.0 + f64::from(u.int_in_range(0u16..=1000)?),
        4 => [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0][u.choose_index(5)?],
        _ => {
            let t = f64::from(u.int_in_range(0u32..=1_000_000)?) / 1e6;
            // Wide ranges: sample the low end more (sizes, radii, iteration counts).
            let hi = if hi - lo > 1000.0 {
                lo + (hi - lo) * t * t * t
            } else {
                hi
            };
            lo + (hi - lo) * t
        }
    })
}

fn value(
    u: &mut Unstructured,
    kind: &ParamKind,
    range: Option<(f64, f64)>,
) -> AResult<Option<ParamValue>> {
    Ok(Some(match kind {
        ParamKind::Bool => ParamValue::Bool(u.arbitrary()?),
        ParamKind::Int => ParamValue::Int(number(u, range)?.clamp(-1e12, 1e12) as i64),
        ParamKind::Float => ParamValue::Float(number(u, range)?),
        ParamKind::Choice(options) => {
            if u.ratio(1u8, 16)? {
                ParamValue::Choice("no_such_option".into())
            } else {
                ParamValue::Choice(options[u.choose_index(options.len())?].to_string())
            }
        }
        ParamKind::Text => ParamValue::Text(u.arbitrary::<&str>()?.chars().take(32).collect()),
        ParamKind::Vec3 => {
            ParamValue::Vec3([number(u, range)?, number(u, range)?, number(u, range)?])
        }
        ParamKind::Floats | ParamKind::Profile => {
            let n = u.int_in_range(0usize..=12)?;
            let v = (0..n)
                .map(|_| number(u, range))
                .collect::<AResult<Vec<_>>>()?;
            if matches!(kind, ParamKind::Profile) {
                ParamValue::Profile(v)
            } else {
                ParamValue::Floats(v)
            }
        }
        ParamKind::Points => {
            let n = u.int_in_range(0usize..=10)?;
            let r = Some((-16.0, 80.0));
            ParamValue::Points(
                (0..n)
                    .map(|_| Ok([number(u, r)?, number(u, r)?]))
                    .collect::<AResult<Vec<_>>>()?,
            )
        }
        ParamKind::Paths => {
            let n = u.int_in_range(0usize..=3)?;
            let r = Some((-16.0, 80.0));
            let mut paths = Vec::new();
            for _ in 0..n {
                let k = u.int_in_range(0usize..=6)?;
                let points = (0..k)
                    .map(|_| Ok([number(u, r)?, number(u, r)?]))
                    .collect::<AResult<Vec<_>>>()?;
                paths.push(rgbn::params::PathValue::new(points, u.arbitrary()?));
            }
            ParamValue::Paths(paths)
        }
        ParamKind::Path => return Ok(None),
    }))
}

/// A random finite RGBN image of at most `MAX_SIDE`² pixels.
fn image(u: &mut Unstructured) -> AResult<RgbnImage> {
    let w = u.int_in_range(1usize..=MAX_SIDE as usize)?;
    let h = u.int_in_range(1usize..=MAX_SIDE as usize)?;
    let masked = u.int_in_range(0u8..=3)?;
    let (mut c, mut n, mut m) = ([vec![], vec![], vec![]], [vec![], vec![], vec![]], vec![]);
    for _ in 0..w * h {
        let a = f32::from(u.int_in_range(0u8..=200)?) / 100.0 - 1.0;
        let b = f32::from(u.int_in_range(0u8..=200)?) / 100.0 - 1.0;
        let z = match u.int_in_range(0u8..=5)? {
            0 => 0.0,  // grazing
            1 => -0.4, // back-facing
            _ => 0.2 + (a * b).abs(),
        };
        let l = (a * a + b * b + z * z).sqrt().max(1e-6);
        let v = if l > 1e-3 {
            [a / l, b / l, z / l]
        } else {
            [0.0, 0.0, 1.0]
        };
        for k in 0..3 {
            n[k].push(v[k]);
            c[k].push(f32::from(u.int_in_range(0u8..=255)?) / 255.0);
        }
        m.push(match masked {
            0 => 0.0,
            1 => 1.0,
            _ => f32::from(u.int_in_range(0u8..=4)?) / 4.0,
        });
    }
    let mask = (masked < 3).then_some(m);
    Ok(RgbnImage::new(w, h, c, n, mask).expect("a valid generated image"))
}

fn build(u: &mut Unstructured, dir: &Path) -> AResult<Graph> {
    let ops = registry();
    let mut g = Graph::default();
    // Outputs so far: (node, port, type).
    let mut outs: Vec<(u64, String, PortType)> = Vec::new();
    // One to three sources.
    for s in 0..u.int_in_range(1u8..=3)? {
        let id = match u.int_in_range(0u8..=2)? {
            0 => {
                let id = g.add_node("demo", [0.0, 0.0]);
                let size = u.int_in_range(16..=MAX_SIDE)?;
                g.nodes
                    .get_mut(&id)
                    .unwrap()
                    .params
                    .insert("size".into(), ParamValue::Int(size));
                id
            }
            1 => {
                let id = g.add_node("surface", [0.0, 0.0]);
                let p = &mut g.nodes.get_mut(&id).unwrap().params;
                p.insert(
                    "width".into(),
                    ParamValue::Int(u.int_in_range(1..=MAX_SIDE)?),
                );
                p.insert(
                    "height".into(),
                    ParamValue::Int(u.int_in_range(1..=MAX_SIDE)?),
                );
                let shapes = ["sphere", "paraboloid", "sinusoid", "gaussians"];
                p.insert(
                    "shape".into(),
                    ParamValue::Choice(shapes[u.choose_index(4)?].into()),
                );
                id
            }
            _ => {
                let img = image(u)?;
                let path = dir.join(format!("source{s}.exr"));
                rgbn::raster::io::save(&img, &path, &Default::default())
                    .expect("scratch EXR written");
                let id = g.add_node("load", [0.0, 0.0]);
                g.nodes
                    .get_mut(&id)
                    .unwrap()
                    .params
                    .insert("path".into(), ParamValue::Path(path.display().to_string()));
                id
            }
        };
        let spec = ops
            .iter()
            .find(|o| o.spec().id == g.nodes[&id].op)
            .unwrap()
            .spec();
        for p in &spec.outputs {
            outs.push((id, p.name.clone(), p.ty));
        }
    }
    // Up to six operators without file parameters.
    for _ in 0..u.int_in_range(1u8..=6)? {
        let candidates: Vec<_> = ops
            .iter()
            .filter(|o| {
                !o.spec().inputs.is_empty() && !o.params().iter().any(|p| p.kind == ParamKind::Path)
            })
            .collect();
        let op = candidates[u.choose_index(candidates.len())?];
        let id = g.add_node(op.spec().id, [0.0, 0.0]);
        for p in op.params() {
            let v = match u.int_in_range(0u8..=3)? {
                0 => None, // default
                1 => value(u, &p.kind, None)?,
                _ => value(u, &p.kind, p.meta.range)?,
            };
            if let Some(v) = v {
                g.nodes
                    .get_mut(&id)
                    .unwrap()
                    .params
                    .insert(p.name.into(), v);
            }
        }
        for port in &op.spec().inputs {
            let matching: Vec<_> = outs.iter().filter(|o| o.2 == port.ty).collect();
            // Rarely leave a required input open (a validation error to report).
            if matching.is_empty() || u.ratio(1u8, if port.optional { 3 } else { 20 })? {
                continue;
            }
            let (from, from_port, _) = matching[u.choose_index(matching.len())?];
            g.nodes.get_mut(&id).unwrap().inputs.insert(
                port.name.clone(),
                Source::Node(*from, from_port.to_string()),
            );
        }
        for p in &op.spec().outputs {
            outs.push((id, p.name.clone(), p.ty));
        }
    }
    for (i, (node, port, _)) in outs.iter().enumerate() {
        g.outputs.insert(
            format!("o{i}"),
            PortRef {
                node: *node,
                port: port.to_string(),
            },
        );
    }
    Ok(g)
}

fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn check(name: &str, v: &Value) {
    match v {
        Value::Rgbn(img) => {
            let [nx, ny, nz] = img.normal();
            for (i, ((&x, &y), &z)) in nx.iter().zip(ny).zip(nz).enumerate() {
                let len = (x * x + y * y + z * z).sqrt();
                assert!(
                    len.is_finite() && (len - 1.0).abs() <= 1e-3,
                    "{name}: normal {i} = ({x}, {y}, {z})"
                );
            }
            assert!(
                img.color().iter().all(|c| finite(c)),
                "{name}: non-finite colour"
            );
            assert!(img.mask().is_none_or(finite), "{name}: non-finite mask");
        }
        Value::Mask(p) | Value::Scalar(p) => assert!(finite(p.data()), "{name}: non-finite field"),
        Value::Number(x) => assert!(x.is_finite(), "{name}: number {x}"),
        Value::Picture(_) => {}
    }
}

fuzz_target!(|data: &[u8]| {
    common::init();
    let dir = common::scratch(b"", "none")
        .parent()
        .expect("scratch folder")
        .to_path_buf();
    let mut u = Unstructured::new(data);
    let Ok(graph) = build(&mut u, &dir) else {
        return;
    };
    let lg = match LoadedGraph::from_graph(graph, None, dir.clone()) {
        Ok(lg) => lg,
        Err(e) => {
            let msg = e.to_string();
            assert!(
                !msg.trim().is_empty() && !msg.contains('\n'),
                "unclear error {msg:?}"
            );
            return;
        }
    };
    let Ok(plan) = Plan::new(&lg, &BTreeMap::new(), &dir) else {
        return;
    };
    match Evaluator::new(256 << 20).eval(&plan, &[], &EvalOptions::default()) {
        Ok(r) => {
            for (name, v) in &r.outputs {
                check(name, v);
            }
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                !msg.trim().is_empty() && !msg.contains('\n'),
                "unclear error {msg:?}"
            );
        }
    }
});
