//! No NaN or infinity out of any operator (issue 15):
//!
//! - every registered operator, run directly on small finite images — random, grazing
//!   (`nz = 0`) and back-facing (`nz < 0`) unit normals, all-0 / all-1 / partial / no masks —
//!   with its default parameters, must not panic, and either refuses with a clear one-line
//!   error or returns finite unit normals and finite colours, masks, fields and numbers;
//! - every numeric parameter set outside its declared range (or to NaN / ±inf) is refused when
//!   the node's parameters are checked, with a one-line error naming the parameter, before
//!   anything runs.
//!
//! (Non-finite pixels never reach an operator: loading repairs or refuses them, see
//! `RgbnImage::repair`; the loaders' own tests cover that.)

use proptest::prelude::*;
use rgbn::nodes::{registry, DynOp, Picture, PortType, RunContext, Value};
use rgbn::params::{ParamKind, ParamValue};
use rgbn::{Plane, RgbnImage};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Default parameters, with every path parameter inside `dir` (the first extension the
/// operator accepts: outputs are written there, inputs are missing and give an error).
fn params(op: &dyn DynOp, dir: &Path) -> rgbn::nodes::Parsed {
    let mut last = None;
    for ext in ["exr", "png", "obj", "ply", "lp", "txt", "json", ""] {
        let mut given = BTreeMap::new();
        for p in op.params() {
            if p.kind == ParamKind::Path {
                let f = dir.join(format!("{}_{}.{ext}", op.spec().id, p.name));
                given.insert(
                    p.name.to_string(),
                    ParamValue::Path(f.display().to_string()),
                );
            }
        }
        match op.parse(&given) {
            Ok(v) => return v,
            Err(e) => last = Some(e),
        }
    }
    panic!("{}: no default parameters accepted: {last:?}", op.spec().id)
}

/// One generated pixel: a normal kind, two free coordinates, a colour kind and a mask value.
type Px = (u8, f32, f32, u8, f32);

fn normal(kind: u8, a: f32, b: f32) -> [f32; 3] {
    let unit = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if l > 1e-6 {
            [v[0] / l, v[1] / l, v[2] / l]
        } else {
            [0.0, 0.0, 1.0]
        }
    };
    match kind {
        0..=2 => unit([a, b, 0.3 + (a * b).abs()]),
        3 => unit([a, b, 0.0]),  // grazing
        _ => unit([a, b, -0.5]), // back-facing
    }
}

fn color(kind: u8, v: f32) -> [f32; 3] {
    match kind {
        0..=3 => [v, 1.0 - v, 0.5 * v],
        4 => [0.0; 3],
        5 => [1.0; 3],
        _ => [4.0 * v, v, 0.0], // HDR
    }
}

fn mask_plane(w: usize, h: usize, px: &[Px], which: u8) -> Vec<f32> {
    (0..w * h)
        .map(|i| match which {
            0 => 0.0,
            1 => 1.0,
            _ => px[i].4,
        })
        .collect()
}

fn image(w: usize, h: usize, px: &[Px], mask: u8) -> RgbnImage {
    let n = w * h;
    let (mut c, mut nn) = ([vec![], vec![], vec![]], [vec![], vec![], vec![]]);
    for p in &px[..n] {
        let nv = normal(p.0, p.1, p.2);
        let cv = color(p.3, p.4);
        for k in 0..3 {
            nn[k].push(nv[k]);
            c[k].push(cv[k]);
        }
    }
    let m = (mask < 3).then(|| mask_plane(w, h, px, mask));
    RgbnImage::new(w, h, c, nn, m).unwrap()
}

fn input(ty: PortType, w: usize, h: usize, px: &[Px], mask: u8) -> Value {
    match ty {
        PortType::Rgbn => Value::Rgbn(image(w, h, px, mask)),
        PortType::Mask => Value::Mask(Arc::new(
            Plane::from_vec(w, h, mask_plane(w, h, px, mask % 3)).unwrap(),
        )),
        PortType::Scalar => Value::Scalar(Arc::new(
            Plane::from_vec(w, h, px[..w * h].iter().map(|p| p.1 * 10.0).collect()).unwrap(),
        )),
        PortType::Picture => Value::Picture(Arc::new(Picture {
            width: w,
            height: h,
            rgba: px[..w * h]
                .iter()
                .flat_map(|p| [p.3 * 30, p.0 * 25, 128, 255])
                .collect(),
        })),
        PortType::Number => Value::Number(f64::from(px[0].1)),
    }
}

fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Why `v` breaks the contract, if it does.
fn bad_output(v: &Value) -> Option<String> {
    match v {
        Value::Rgbn(img) => {
            let [nx, ny, nz] = img.normal();
            for (i, ((&x, &y), &z)) in nx.iter().zip(ny).zip(nz).enumerate() {
                let len = (x * x + y * y + z * z).sqrt();
                if !len.is_finite() || (len - 1.0).abs() > 1e-3 {
                    return Some(format!("normal {i} = ({x}, {y}, {z})"));
                }
            }
            if !img.color().iter().all(|c| finite(c)) {
                return Some("non-finite colour".into());
            }
            if img.mask().is_some_and(|m| !finite(m)) {
                return Some("non-finite mask".into());
            }
            None
        }
        Value::Mask(p) | Value::Scalar(p) => {
            (!finite(p.data())).then(|| "non-finite mask or scalar field".into())
        }
        Value::Number(x) => (!x.is_finite()).then(|| format!("number {x}")),
        Value::Picture(_) => None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn no_operator_panics_or_returns_non_finite_values_on_finite_images(
        w in 2usize..=8,
        h in 2usize..=8,
        px in proptest::collection::vec(
            (0u8..5, -1.0f32..1.0, -1.0f32..1.0, 0u8..7, 0.0f32..1.0),
            64,
        ),
        mask in 0u8..4,
        connect_optional in proptest::bool::ANY,
    ) {
        let dir = tempfile::tempdir().unwrap();
        let ctx = RunContext::default();
        let (mut tried, mut ran) = (0, 0);
        for op in registry() {
            let s = op.spec();
            // Operators without input ports (demo, surface, load, load_mask, photometric_stereo:
            // sources that make an image from parameters or files) cannot receive the planes
            // generated here; the golden graph tests cover them.
            if s.inputs.is_empty() {
                continue;
            }
            let values = params(op.as_ref(), dir.path());
            tried += 1;
            let inputs: Vec<Option<Value>> = s
                .inputs
                .iter()
                .map(|p| {
                    (!p.optional || connect_optional).then(|| input(p.ty, w, h, &px, mask))
                })
                .collect();
            let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                op.run(&values, inputs.clone(), &ctx)
            }));
            match run {
                Err(_) => prop_assert!(false, "{} panicked on a {w}×{h} image", s.id),
                Ok(Err(e)) => {
                    let msg = e.to_string();
                    prop_assert!(
                        !msg.trim().is_empty() && !msg.contains('\n'),
                        "{}: unclear error {msg:?}",
                        s.id
                    );
                }
                Ok(Ok(outs)) => {
                    ran += 1;
                    for (port, v) in s.outputs.iter().zip(&outs) {
                        if let Some(why) = bad_output(v) {
                            prop_assert!(false, "{}.{}: {why} ({w}×{h})", s.id, port.name);
                        }
                    }
                }
            }
        }
        // Most operators accept these images: a test where everything errored would prove nothing.
        prop_assert!(2 * ran > tried, "only {ran} of {tried} operators ran");
    }
}

/// Values outside `range` (and non-finite ones) for a parameter of `kind`, or none when the
/// kind has no numbers.
fn out_of_range(kind: &ParamKind, range: (f64, f64)) -> Vec<ParamValue> {
    let (lo, hi) = range;
    let bad = [
        lo - 1.0,
        hi + 1.0,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    match kind {
        ParamKind::Int => [lo - 1.0, hi + 1.0]
            .iter()
            .filter(|v| v.abs() < 9e18)
            .map(|&v| ParamValue::Int(v as i64))
            .collect(),
        ParamKind::Float => bad.iter().map(|&v| ParamValue::Float(v)).collect(),
        ParamKind::Vec3 => bad
            .iter()
            .map(|&v| ParamValue::Vec3([v, lo.max(0.0).min(hi), lo.max(0.0).min(hi)]))
            .collect(),
        ParamKind::Floats => bad.iter().map(|&v| ParamValue::Floats(vec![v])).collect(),
        ParamKind::Profile => bad
            .iter()
            .map(|&v| ParamValue::Profile(vec![lo, v, lo]))
            .collect(),
        _ => Vec::new(),
    }
}

#[test]
fn every_parameter_outside_its_range_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for op in registry() {
        let good = params(op.as_ref(), dir.path());
        for p in op.params() {
            let Some(range) = p.meta.range else { continue };
            for v in out_of_range(&p.kind, range) {
                let mut values = good.values().clone();
                values.insert(p.name.to_string(), v.clone());
                let id = op.spec().id;
                match op.parse(&values) {
                    Ok(_) => panic!("{id}.{}: {v:?} outside {range:?} was accepted", p.name),
                    Err(e) => {
                        let msg = e.to_string();
                        assert!(
                            msg.contains(p.name) && !msg.contains('\n'),
                            "{id}.{}: unclear error {msg:?} for {v:?}",
                            p.name
                        );
                    }
                }
                checked += 1;
            }
        }
    }
    // Every operator family has ranged numbers: a registry that lost them would pass vacuously.
    assert!(checked > 100, "only {checked} out-of-range values tried");
}
