//! OME-Zarr stores through the `rgbn` binary: four `rgbn eval --region` processes filling one
//! store equal one whole (streamed) `rgbn eval` byte for byte; a region reads only the chunks
//! covering it and its halo; bad stores exit 2 naming the store and the fault, and nothing is
//! written over an input.

use crate::common::*;
use rgbn::raster::io::zarr::{save_zarr, ZarrImage, ZarrOptions};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("rgbn runs")
}

/// A 200 × 150 RGBN store (the demo medallion, cut) with 64-pixel chunks at `dir/in.zarr`.
fn input_store(dir: &Path) -> PathBuf {
    let img = demo_cut();
    let p = dir.join("in.zarr");
    let o = ZarrOptions {
        chunk: 64,
        ..ZarrOptions::default()
    };
    save_zarr(&img, &p, &o).unwrap();
    p
}

/// The demo medallion cut to 200 × 150.
fn demo_cut() -> rgbn::RgbnImage {
    let full = rgbn::raster::sample::demo_medallion(200);
    let cut = |p: &[f32]| p[..200 * 150].to_vec();
    rgbn::RgbnImage::new(
        200,
        150,
        full.color().clone().map(|p| cut(&p)),
        full.normal().clone().map(|p| cut(&p)),
        None,
    )
    .unwrap()
}

/// Every file of a store (relative path, bytes), sorted.
fn files(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut todo = vec![root.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn four_region_processes_fill_one_store_equal_to_one_whole_eval() {
    let d = tempfile::tempdir().unwrap();
    input_store(d.path());
    let g = graph_path("input_image.ron").display().to_string();
    let common = [
        "eval",
        &g,
        "--input",
        "image=in.zarr",
        "--chunk",
        "64",
        "--tile",
        "64",
    ];
    let mut whole: Vec<&str> = common.to_vec();
    whole.extend([
        "--stream",
        "always",
        "-o",
        "image=whole.zarr",
        "-o",
        "relit=whole_relit.zarr",
    ]);
    let o = run(d.path(), &whole);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("streamed"), "{}", stdout(&o));
    // Four processes at once, one chunk-aligned quarter each, no store made beforehand.
    let quarters = ["0,0,128,64", "128,0,72,64", "0,64,128,86", "128,64,72,86"];
    let children: Vec<_> = quarters
        .iter()
        .map(|q| {
            let mut args: Vec<&str> = common.to_vec();
            args.extend([
                "--region",
                q,
                "-o",
                "image=parts.zarr",
                "-o",
                "relit=parts_relit.zarr",
            ]);
            Command::new(env!("CARGO_BIN_EXE_rgbn"))
                .current_dir(d.path())
                .args(&args)
                .output()
        })
        .collect();
    for c in children {
        let o = c.unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    assert_eq!(
        files(&d.path().join("parts.zarr")),
        files(&d.path().join("whole.zarr"))
    );
    assert_eq!(
        files(&d.path().join("parts_relit.zarr")),
        files(&d.path().join("whole_relit.zarr"))
    );
    // A region off the chunk grid is refused before anything is computed.
    let mut args: Vec<&str> = common.to_vec();
    args.extend(["--region", "10,0,64,64", "-o", "image=other.zarr"]);
    let o = run(d.path(), &args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("not aligned to the 64-pixel chunks"),
        "{}",
        stderr(&o)
    );
    assert!(!d.path().join("other.zarr").exists());
}

#[test]
fn a_region_reads_only_the_chunks_covering_it_and_its_halo() {
    let d = tempfile::tempdir().unwrap();
    input_store(d.path());
    let g = graph_path("input_image.ron").display().to_string();
    // The sharpen's halo is under a chunk: the 64 × 64 region at (64, 64), grown by it, covers
    // the chunks of columns 0–2 and rows 0–2 (9 of the store's 4 × 3 = 12).
    let o = run(
        d.path(),
        &[
            "eval",
            &g,
            "--input",
            "image=in.zarr",
            "--region",
            "64,64,64,64",
            "--tile",
            "64",
            "--stats",
            "-o",
            "image=part.exr",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("zarr chunks read: 9\n"),
        "{}",
        stdout(&o)
    );
    // At level 1 the store's level 1 is read (32-pixel chunks of the same cells), not level 0.
    let o = run(
        d.path(),
        &[
            "eval",
            &g,
            "--input",
            "image=in.zarr",
            "--level",
            "1",
            "--region",
            "0,0,32,32",
            "--tile",
            "32",
            "--stats",
            "-o",
            "image=part1.exr",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Rows and columns 0–1 of level 1's 32-pixel chunks.
    assert!(
        stdout(&o).contains("zarr chunks read: 4\n"),
        "{}",
        stdout(&o)
    );
}

#[test]
fn bad_stores_exit_2_naming_the_store_and_nothing_is_written_over_an_input() {
    let d = tempfile::tempdir().unwrap();
    let g = graph_path("input_image.ron").display().to_string();
    let fresh = |name: &str| {
        let p = input_store(d.path());
        let q = d.path().join(format!("{name}.zarr"));
        std::fs::rename(&p, &q).unwrap();
        q
    };
    let edit = |p: &Path, file: &str, from: &str, to: &str| {
        let f = p.join(file);
        let s = std::fs::read_to_string(&f).unwrap();
        assert!(s.contains(from), "{file}: {from}");
        std::fs::write(&f, s.replacen(from, to, 1)).unwrap();
    };
    #[allow(clippy::type_complexity)] // (name, how to break the store, what the error says)
    let cases: Vec<(&str, Box<dyn Fn(&Path)>, &str)> = vec![
        (
            "missing",
            Box::new(|p: &Path| std::fs::remove_file(p.join("0/c/0/1/2")).unwrap()),
            "chunk 0/c/0/1/2 of level 0 (array \"0\") is missing",
        ),
        (
            "truncated",
            Box::new(|p: &Path| {
                let f = p.join("0/c/0/0/1");
                let b = std::fs::read(&f).unwrap();
                std::fs::write(&f, &b[..b.len() / 3]).unwrap();
            }),
            "truncated or corrupt",
        ),
        (
            "dtype",
            Box::new(move |p: &Path| {
                edit(p, "0/zarr.json", "\"float32\"", "\"int16\"");
                edit(p, "0/zarr.json", "\"fill_value\": 0.0", "\"fill_value\": 0");
            }),
            "wrong data type",
        ),
        (
            "channels",
            Box::new(move |p: &Path| {
                edit(
                    p,
                    "zarr.json",
                    "\"label\": \"B\",",
                    "\"label\": \"B\"}, {\"label\": \"extra\",",
                )
            }),
            "wrong channel count",
        ),
        (
            "not-ome",
            Box::new(move |p: &Path| edit(p, "zarr.json", "\"ome\"", "\"something_else\"")),
            "not an OME-Zarr image",
        ),
    ];
    for (name, spoil, what) in cases {
        let p = fresh(name);
        spoil(&p);
        let before = files(&p);
        let input = format!("image={name}.zarr");
        for stream in ["always", "never"] {
            let o = run(
                d.path(),
                &[
                    "eval",
                    &g,
                    "--input",
                    &input,
                    "--stream",
                    stream,
                    "-o",
                    "image=out.zarr",
                ],
            );
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{name} {stream}: {err}");
            assert!(err.contains(what), "{name} {stream}: {err}");
            assert!(
                err.contains(&format!("{name}.zarr")),
                "{name}: names the store: {err}"
            );
            assert_eq!(err.trim().lines().count(), 1, "{name}: one line: {err}");
            assert!(
                !d.path().join("out.zarr").exists(),
                "{name}: nothing written"
            );
        }
        // The input as the output: refused, the store untouched.
        let o = run(
            d.path(),
            &[
                "eval",
                &g,
                "--input",
                &input,
                "-o",
                &format!("image={name}.zarr"),
            ],
        );
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert_eq!(files(&p), before, "{name}: the input is untouched");
    }
}

/// `rgbn.dask`'s streamed task (`stream_region_into_stores`): each chunk-aligned quarter read
/// in a window of the store (the quarter grown by the halo) and written into one store equals
/// one whole streamed `rgbn eval` byte for byte — a sharpen and relight (a 9-pixel halo, inside
/// one 64-pixel chunk) and a σ 8 px Gaussian (whose halo reaches past the next chunk) — and a
/// graph whose input is read in whole rows (an EXR) is left to the region plan.
#[test]
fn streamed_windows_of_a_store_fill_one_store_equal_to_one_whole_eval() {
    use rgbn::eval::zarr_sink::stream_region_into_stores;
    use rgbn::raster::window::Rect;
    let d = tempfile::tempdir().unwrap();
    let store = input_store(d.path());
    let gauss = d.path().join("gauss.ron");
    std::fs::write(
        &gauss,
        r#"(
    version: 2,
    next_id: 2,
    inputs: { "image": (ty: Rgbn) },
    outputs: { "image": (node: 1, port: "image") },
    nodes: [ (id: 1, op: "filter.gaussian", pos: (0.0, 0.0),
              params: { "sigma_px": Float(8.0) }, inputs: { "image": Input("image") }) ],
)"#,
    )
    .unwrap();
    let opts = ZarrOptions {
        chunk: 64,
        ..ZarrOptions::default()
    };
    for (g, names) in [
        (graph_path("input_image.ron"), vec!["image", "relit"]),
        (gauss, vec!["image"]),
    ] {
        let tag = g.file_stem().unwrap().to_string_lossy().into_owned();
        let mut args = vec![
            "eval".to_string(),
            g.display().to_string(),
            "--input".into(),
            "image=in.zarr".into(),
            "--chunk".into(),
            "64".into(),
            "--stream".into(),
            "always".into(),
        ];
        for n in &names {
            args.extend(["-o".into(), format!("{n}=whole_{tag}_{n}.zarr")]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run(d.path(), &args);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let lg = rgbn::graph::LoadedGraph::load(&g).unwrap();
        let inputs = [("image".to_string(), store.clone())].into_iter().collect();
        let plan = rgbn::eval::Plan::new(&lg, &inputs, d.path()).unwrap();
        let outs: Vec<(String, PathBuf)> = names
            .iter()
            .map(|n| {
                (
                    n.to_string(),
                    d.path().join(format!("parts_{tag}_{n}.zarr")),
                )
            })
            .collect();
        let cancel = rgbn::cancel::Cancel::default();
        for q in [
            Rect::new(0, 0, 128, 64),
            Rect::new(128, 0, 72, 64),
            Rect::new(0, 64, 128, 86),
            Rect::new(128, 64, 72, 86),
        ] {
            let streamed = stream_region_into_stores::<Box<dyn std::error::Error>>(
                &plan, &outs, q, &opts, &cancel,
            )
            .unwrap();
            assert!(streamed, "{tag}: a store input streams");
        }
        for n in &names {
            let parts = d.path().join(format!("parts_{tag}_{n}.zarr"));
            let whole = d.path().join(format!("whole_{tag}_{n}.zarr"));
            if tag == "input_image" {
                // Finite kernels: byte for byte.
                assert_eq!(files(&parts), files(&whole), "{tag} {n}");
                continue;
            }
            // The recursive Gaussian (σ ≥ 3) is cut at 4σ where a window ends (as the whole
            // run's strips are in y): per pass a value moves by at most the tail's mass
            // (< 3.5e-4, `raster::convolve::gaussian_support`) times twice the largest gradient,
            // and a window adds the pass in x: the same files, every level's values within
            // twice that (colour untouched; unit normals move less than their gradients).
            let names = |p: &Path| files(p).into_iter().map(|(n, _)| n).collect::<Vec<_>>();
            assert_eq!(names(&parts), names(&whole), "{tag} {n}");
            let (a, b) = (
                ZarrImage::open(&parts).unwrap(),
                ZarrImage::open(&whole).unwrap(),
            );
            let mut worst = 0f32;
            for k in 0..a.levels() {
                let full = Rect::full(a.level_size(k));
                let (pa, pb) = (a.read(k, full).unwrap(), b.read(k, full).unwrap());
                for (x, y) in pa.iter().flatten().zip(pb.iter().flatten()) {
                    worst = worst.max((x - y).abs());
                }
            }
            let g = rgbn::GradientField::from_normals(&demo_cut());
            let gmax = g.p.iter().chain(&g.q).fold(0.0f32, |a, v| a.max(v.abs()));
            let bound = 2.0 * 3.5e-4 * 2.0 * gmax;
            assert!(worst <= bound, "{tag} {n}: {worst:e} > {bound:e}");
        }
    }
    // An EXR input is read in whole rows: not streamed in a window (the caller uses the region
    // plan), and nothing is written.
    let exr = d.path().join("in.exr");
    rgbn::raster::io::save_exr(&demo_cut(), &exr, Default::default()).unwrap();
    let lg = rgbn::graph::LoadedGraph::load(&graph_path("input_image.ron")).unwrap();
    let inputs = [("image".to_string(), exr)].into_iter().collect();
    let plan = rgbn::eval::Plan::new(&lg, &inputs, d.path()).unwrap();
    let outs = vec![("image".to_string(), d.path().join("exr_part.zarr"))];
    let streamed = stream_region_into_stores::<Box<dyn std::error::Error>>(
        &plan,
        &outs,
        Rect::new(0, 0, 64, 64),
        &opts,
        &rgbn::cancel::Cancel::default(),
    )
    .unwrap();
    assert!(!streamed);
    assert!(!d.path().join("exr_part.zarr").exists());
}
