//! Node overhead per operator: every registered operator run through the evaluator at 4K
//! (3840×2160), beside the same operator run directly on the same inputs.
//!
//! - `node/ID`: a graph of one `ID` node whose inputs are graph inputs bound to values in
//!   memory (`Plan::bind_values`), evaluated by a fresh `Evaluator` each iteration (so the
//!   node runs every time): content keys, the memory estimate, the bound sources, the node,
//!   the cache insertion.
//! - `kernel/ID`: the operator's own `run` on the same parameters and input values (the pure
//!   function and its port adaptation, no engine).
//! - `node/ID:PORT`: for an operator with lazy outputs, the same graph asked for its first
//!   output only (the others left out).
//!
//! `node/ID ÷ kernel/ID` is the engine's overhead per operator (BENCHMARKS.md, "Node
//! overhead"). Parameters come from the operator's first example graph in `graphs/` (sizes
//! of sources set to 4K, file paths to files written here at 4K); inputs are 4K values by
//! port type (an input read whole, such as a stamp, a 128² image; a pattern a 256² field),
//! connected as the example connects them.
//!
//! Run: `cargo bench --no-default-features --bench nodes` (one operator:
//! `-- 'node/filter.gaussian$|kernel/filter.gaussian$'`).

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use criterion::{criterion_group, criterion_main, Criterion};
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::{file, Graph, InputDef, LoadedGraph, PortRef, Source};
use rgbn::nodes::{registry, Mask, PortType, Read, RunContext, Scalar, Value};
use rgbn::params::ParamValue;
use rgbn::raster::gradient::GradientField;
use rgbn::raster::io::{self, SaveOptions};
use rgbn::raster::sample::Surface;
use rgbn::raster::{Plane, RgbnImage};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

const W: usize = 3840;
const H: usize = 2160;

/// A 4K RGBN with relief at several scales and a colour ramp.
fn image(w: usize, h: usize) -> RgbnImage {
    let (mut img, _) = Surface::gaussians_for(h.min(w)).render(w, h);
    let (f, _) = Surface::Sinusoid {
        amplitude_px: 1.5,
        period_px: 23.0,
    }
    .render(w, h);
    let mut g = GradientField::from_normals(&img);
    let gf = GradientField::from_normals(&f);
    g.p.iter_mut().zip(&gf.p).for_each(|(a, b)| *a += b);
    g.q.iter_mut().zip(&gf.q).for_each(|(a, b)| *a += b);
    g.write_normals(&mut img);
    let n = w * h;
    let color = [
        (0..n).map(|i| (i % w) as f32 / w as f32).collect(),
        (0..n).map(|i| (i / w) as f32 / h as f32).collect(),
        vec![0.5; n],
    ];
    img.set_color(color).expect("sizes");
    img.set_mask(None).expect("no mask");
    img
}

/// A soft disc in [0, 1].
fn disc(w: usize, h: usize) -> Plane {
    let (cx, cy, r) = (w as f32 / 2.0, h as f32 / 2.0, h as f32 / 3.0);
    Plane::from_fn(w, h, |x, y| {
        let d = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
        ((r - d) / 16.0).clamp(0.0, 1.0)
    })
}

/// A height in pixels.
fn height(w: usize, h: usize) -> Plane {
    Plane::from_fn(w, h, |x, y| {
        4.0 * ((x as f32 / 41.0).sin() * (y as f32 / 29.0).cos())
    })
}

/// The first example graph node of operator `id`: its parameters and connected inputs.
fn example(id: &str) -> Option<(BTreeMap<String, ParamValue>, Vec<String>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .collect();
    files.sort();
    for f in files {
        let text = std::fs::read_to_string(&f).ok()?;
        let Ok(g) = file::parse(&text, &f.display().to_string()) else {
            continue;
        };
        if let Some(n) = g.nodes.iter().find(|n| n.op == id) {
            return Some((n.params.clone(), n.inputs.keys().cloned().collect()));
        }
    }
    None
}

/// Files the 4K parameters point at, written once.
struct Files {
    dir: tempfile::TempDir,
}

impl Files {
    fn new(img: &RgbnImage, mask: &Plane) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        io::save(img, &dir.path().join("in.exr"), &SaveOptions::default()).expect("exr");
        let m16: Vec<u16> = mask.data().iter().map(|v| (v * 65535.0) as u16).collect();
        io::write_raster16(&m16, W, H, 1, io::Format::Png, &dir.path().join("mask.png"))
            .expect("mask");
        // Photometric stereo: six Lambertian renders under known lights, listed.
        let lights = [
            [0.0, 0.0, 1.0],
            [0.5, 0.0, 0.866],
            [-0.5, 0.0, 0.866],
            [0.0, 0.5, 0.866],
            [0.0, -0.5, 0.866],
            [0.35, 0.35, 0.868],
        ];
        let mut names = String::new();
        let mut rows = String::new();
        for (k, l) in lights.iter().enumerate() {
            let [nx, ny, nz] = img.normal();
            let c = &img.color()[0];
            let v: Vec<u16> = (0..W * H)
                .map(|i| {
                    let s = (nx[i] * l[0] + ny[i] * l[1] + nz[i] * l[2]).max(0.0) * c[i];
                    (s.clamp(0.0, 1.0) * 65535.0) as u16
                })
                .collect();
            let name = format!("p{k}.png");
            io::write_raster16(&v, W, H, 1, io::Format::Png, &dir.path().join(&name))
                .expect("photo");
            names.push_str(&format!("{name}\n"));
            rows.push_str(&format!("{} {} {}\n", l[0], l[1], l[2]));
        }
        std::fs::write(dir.path().join("photos.txt"), names).expect("list");
        std::fs::write(dir.path().join("lights.txt"), rows).expect("lights");
        Self { dir }
    }
    fn path(&self, name: &str) -> String {
        self.dir.path().join(name).display().to_string()
    }
}

/// The example's parameters made 4K: sizes of sources, files read and written here.
fn params_4k(
    id: &str,
    mut p: BTreeMap<String, ParamValue>,
    files: &Files,
) -> BTreeMap<String, ParamValue> {
    let set = |p: &mut BTreeMap<String, ParamValue>, k: &str, v: ParamValue| {
        p.insert(k.to_string(), v);
    };
    match id {
        "demo" => set(&mut p, "size", ParamValue::Int(H as i64)),
        "surface" => {
            set(&mut p, "width", ParamValue::Int(W as i64));
            set(&mut p, "height", ParamValue::Int(H as i64));
        }
        "load" => {
            p.retain(|k, _| k != "color" && k != "mask" && k != "normal");
            set(&mut p, "path", ParamValue::Path(files.path("in.exr")));
        }
        "load_mask" => set(&mut p, "path", ParamValue::Path(files.path("mask.png"))),
        "photometric_stereo" => {
            p.clear();
            set(&mut p, "photos", ParamValue::Path(files.path("photos.txt")));
            set(&mut p, "lights", ParamValue::Path(files.path("lights.txt")));
        }
        "save" => set(&mut p, "path", ParamValue::Path(files.path("out.exr"))),
        "save.height" => set(&mut p, "path", ParamValue::Path(files.path("height.exr"))),
        "save.mesh" => set(&mut p, "path", ParamValue::Path(files.path("mesh.ply"))),
        "publish" => set(&mut p, "path", ParamValue::Path(files.path("web"))),
        _ => {}
    }
    p
}

fn bench(c: &mut Criterion) {
    let img = image(W, H);
    let mask = disc(W, H);
    let z = height(W, H);
    let small = image(128, 128);
    let pattern = height(256, 64);
    let files = Files::new(&img, &mask);
    let mut group = c.benchmark_group("nodes_4k");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for op in registry() {
        let spec = op.spec();
        let Some((params, connected)) = example(spec.id) else {
            eprintln!("{}: no example graph", spec.id);
            continue;
        };
        let params = params_4k(spec.id, params, &files);
        // The inputs: a graph input per connected port, with a 4K value of its type.
        let mut graph = Graph::default();
        let node = graph.add_node(spec.id, [0.0, 0.0]);
        let mut values = BTreeMap::new();
        let mut direct = Vec::new();
        for port in &spec.inputs {
            let wanted = !port.optional || connected.contains(&port.name);
            let value = match (port.ty, port.read) {
                _ if !wanted => None,
                (PortType::Rgbn, Read::Whole) => Some(Value::Rgbn(small.clone())),
                (PortType::Rgbn, _) => Some(Value::Rgbn(img.clone())),
                (PortType::Mask, _) => Some(Value::Mask(Mask::new(mask.clone()).0)),
                (PortType::Scalar, Read::Pattern) => {
                    Some(Value::Scalar(Scalar::new(pattern.clone()).0))
                }
                (PortType::Scalar, _) => Some(Value::Scalar(Scalar::new(z.clone()).0)),
                (ty, _) => panic!("{}: no 4K value of type {}", spec.id, ty.name()),
            };
            if let Some(v) = &value {
                graph.inputs.insert(
                    port.name.clone(),
                    InputDef {
                        ty: port.ty,
                        doc: String::new(),
                    },
                );
                values.insert(port.name.clone(), v.clone());
                let n = graph.nodes.get_mut(&node).expect("added");
                n.inputs
                    .insert(port.name.clone(), Source::Input(port.name.clone()));
            }
            direct.push(value);
        }
        graph.nodes.get_mut(&node).expect("added").params = params.clone();
        for out in &spec.outputs {
            graph.outputs.insert(
                out.name.clone(),
                PortRef {
                    node,
                    port: out.name.clone(),
                },
            );
        }
        let lg = match LoadedGraph::from_graph(graph, None, PathBuf::from(".")) {
            Ok(lg) => lg,
            Err(e) => {
                eprintln!("{}: {e}", spec.id);
                continue;
            }
        };
        let mut plan = Plan::new(&lg, &BTreeMap::new(), Path::new(".")).expect("plan");
        let _bindings = plan.bind_values(&lg, values).expect("bound inputs");
        let parsed = op.parse(&params).expect("parameters");
        let ctx = RunContext::default();
        let opts = EvalOptions::default();
        group.bench_function(format!("node/{}", spec.id), |b| {
            b.iter(|| {
                let ev = Evaluator::new(8 << 30);
                ev.eval(&plan, &[], &opts).expect("evaluates")
            });
        });
        group.bench_function(format!("kernel/{}", spec.id), |b| {
            b.iter(|| op.run(&parsed, direct.clone(), &ctx).expect("runs"));
        });
        // An operator that computes only the outputs read: its first output alone (the
        // bilateral's base, against OpenCV's bilateralFilter).
        if spec.lazy_outputs {
            let first = spec.outputs[0].name.as_str();
            group.bench_function(format!("node/{}:{first}", spec.id), |b| {
                b.iter(|| {
                    let ev = Evaluator::new(8 << 30);
                    ev.eval(&plan, &[first], &opts).expect("evaluates")
                });
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
