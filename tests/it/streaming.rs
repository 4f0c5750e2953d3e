//! Streaming (issue 12, item 5): an image filtered strip by strip from row-streamed PNGs equals
//! the whole-image filter; a truncated file is a one-line error that leaves no output behind.

use super::common::{rgbn, stderr};
use rgbn::ops::filter::{filter_normals, filter_streamed, stream_halo, FilterOptions, Kernel};
use rgbn::raster::convolve::BorderMode;
use rgbn::raster::io::{self, Format, InputSpec, LoadOptions, NormalConvention};
use rgbn::raster::strips::{Opened, StreamInput};
use rgbn::raster::RgbnImage;
use rgbn::RgbnError;
use std::path::Path;

/// A relief of sines and a bump, its normals (exact for the height), a colour ramp and a soft
/// disc mask.
fn relief(w: usize, h: usize, seed: u64) -> RgbnImage {
    let s = seed as f32;
    let n = w * h;
    let (mut nx, mut ny, mut nz) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut c = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    let mut m = vec![0.0; n];
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32, y as f32);
            let p = 0.6 * (fx / (3.0 + s)).cos() * (fy / 5.0).cos() + 0.3 * ((fx + fy) / 2.3).cos();
            let q =
                -0.4 * (fx / (3.0 + s)).sin() * (fy / 5.0).sin() + 0.3 * ((fx + fy) / 2.3).cos();
            let l = (1.0 + p * p + q * q).sqrt();
            let i = y * w + x;
            (nx[i], ny[i], nz[i]) = (-p / l, -q / l, 1.0 / l);
            c[0][i] = fx / w as f32;
            c[1][i] = fy / h as f32;
            c[2][i] = 0.5;
            let r = ((fx - w as f32 / 2.0).powi(2) + (fy - h as f32 / 2.0).powi(2)).sqrt();
            m[i] = (w.min(h) as f32 / 2.5 - r).clamp(0.0, 1.0);
        }
    }
    RgbnImage::new(w, h, c, [nx, ny, nz], Some(m)).unwrap()
}

/// Writes `img` as a normal map PNG of `bits`, an 8-bit colour PNG and an 8-bit mask PNG.
fn write_files(dir: &Path, img: &RgbnImage, bits: u8) -> InputSpec {
    let (w, h) = (img.width(), img.height());
    let normal = dir.join(format!("n{bits}.png"));
    io::save_normal_map(img, &normal, bits, NormalConvention::OpenGl).unwrap();
    let color = dir.join("c.png");
    io::save_color(img, &color, 8).unwrap();
    let mask = dir.join("m.png");
    let bytes: Vec<u8> = img
        .mask()
        .unwrap()
        .iter()
        .map(|v| (v * 255.0).round() as u8)
        .collect();
    io::write_raster8(&bytes, w, h, 1, Format::Png, &mask).unwrap();
    InputSpec {
        rgbn: None,
        color: Some(color),
        normal: Some(normal),
        mask: Some(mask),
    }
}

/// A run that failed with exit code 2 and a one-line error naming `file`.
fn assert_fails_naming(o: &std::process::Output, file: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains(file), "{err}");
}

/// The streamed filter's normals (all rows) and report.
fn streamed(
    spec: &InputSpec,
    kernels: &[Kernel],
    opts: &FilterOptions,
    strip: usize,
) -> ([Vec<f32>; 3], rgbn::ops::filter::FilterReport) {
    let Opened::Stream(mut input) = StreamInput::open(spec, &LoadOptions::default()).unwrap()
    else {
        panic!("PNG files stream")
    };
    let mut out: [Vec<f32>; 3] = Default::default();
    let mut cores = Vec::new();
    let (report, _) = filter_streamed(&mut input, kernels, opts, Some(strip), |win, n| {
        cores.push((win.y0 + win.core.start, win.core.len()));
        for (o, p) in out.iter_mut().zip(n) {
            o.extend_from_slice(p);
        }
        Ok::<(), RgbnError>(())
    })
    .unwrap();
    // The strips tile the image top to bottom, each `strip` rows but the last.
    let mut y = 0;
    for (y0, rows) in &cores {
        assert_eq!(*y0, y);
        y += rows;
    }
    (out, report)
}

fn max_diff(a: &[Vec<f32>; 3], b: &[Vec<f32>; 3]) -> f32 {
    a.iter()
        .zip(b)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f32::max)
}

#[test]
fn finite_kernels_streamed_equal_the_whole_image_bit_for_bit() {
    // 8-bit normals are not unit length once decoded, so both paths renormalise every pixel
    // with the same arithmetic: the inputs agree bit for bit, and so must every FIR result.
    let d = tempfile::tempdir().unwrap();
    let img = relief(53, 71, 1);
    let spec = write_files(d.path(), &img, 8);
    let whole_in = io::load(&spec, &LoadOptions::default()).unwrap().image;
    let kernel_lists: [&[Kernel]; 4] = [
        &[Kernel::Gaussian { sigma_px: 1.5 }],
        &[Kernel::Sharpen {
            sigma_px: 1.2,
            amount: 0.8,
        }],
        &[
            Kernel::Gaussian { sigma_px: 0.8 },
            Kernel::DepthScale { scale: 2.0 },
        ],
        &[Kernel::LoG { sigma_px: 1.0 }],
    ];
    for kernels in kernel_lists {
        for border in [BorderMode::Mirror, BorderMode::Clamp, BorderMode::Zero] {
            for mask_aware in [false, true] {
                let opts = FilterOptions { border, mask_aware };
                let (want, wr) = filter_normals(&whole_in, kernels, &opts).unwrap();
                let want = want.normal().clone();
                let halo = stream_halo(kernels, &opts).unwrap();
                for strip in [1, 5, 17, 200] {
                    let (got, r) = streamed(&spec, kernels, &opts, strip);
                    let what = format!(
                        "{kernels:?} {border:?} mask_aware={mask_aware} strip={strip} halo={halo}"
                    );
                    assert_eq!(max_diff(&got, &want), 0.0, "{what}");
                    assert_eq!(r.clamped, wr.clamped, "{what}");
                    // The report sums the same rows: equal up to summation order.
                    let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-12);
                    assert!(
                        rel(r.curl_before.rms_curl, wr.curl_before.rms_curl) < 1e-9,
                        "{what}"
                    );
                    assert!(
                        rel(r.curl_after.rms_curl, wr.curl_after.rms_curl) < 1e-4,
                        "{what}: {} vs {}",
                        r.curl_after.rms_curl,
                        wr.curl_after.rms_curl
                    );
                }
            }
        }
    }
}

#[test]
fn sixteen_bit_and_box_streamed_agree_within_a_millionth() {
    // 16-bit normals decode within 1e-3 of unit length: the whole-image loader keeps them,
    // the stream renormalises (p = −nx/nz is unchanged but for rounding); a box filter runs a
    // sum along each column, whose rounding depends on where the column starts.
    let d = tempfile::tempdir().unwrap();
    let img = relief(40, 90, 2);
    let spec = write_files(d.path(), &img, 16);
    let whole_in = io::load(&spec, &LoadOptions::default()).unwrap().image;
    for kernels in [
        vec![Kernel::Gaussian { sigma_px: 2.0 }],
        vec![Kernel::Box { radius_px: 3 }],
    ] {
        let opts = FilterOptions::default();
        let (want, _) = filter_normals(&whole_in, &kernels, &opts).unwrap();
        for strip in [3, 16, 64] {
            let (got, _) = streamed(&spec, &kernels, &opts, strip);
            let e = max_diff(&got, want.normal());
            assert!(e <= 1e-6, "{kernels:?} strip {strip}: {e:e}");
        }
    }
}

#[test]
fn a_recursive_gaussian_streamed_is_within_its_documented_truncation() {
    // σ ≥ 3 runs Deriche's recursive filter, cut at 4σ for a strip: per column pass a pixel
    // moves by at most the tail's mass (< 3.5e-4) times the largest difference between the
    // samples beyond the cut and those the border mode invents (≤ 2·max|g|); a normal moves
    // no more than its gradient.
    let d = tempfile::tempdir().unwrap();
    let img = relief(48, 160, 3);
    let spec = write_files(d.path(), &img, 8);
    let whole_in = io::load(&spec, &LoadOptions::default()).unwrap().image;
    let g = rgbn::GradientField::from_normals(&whole_in);
    let gmax = g.p.iter().chain(&g.q).fold(0.0f32, |a, v| a.max(v.abs()));
    for sigma_px in [3.0, 6.5] {
        let kernels = [Kernel::Gaussian { sigma_px }];
        let opts = FilterOptions::default();
        let (want, _) = filter_normals(&whole_in, &kernels, &opts).unwrap();
        let mut worst = 0.0f32;
        for strip in [7, 30] {
            let (got, _) = streamed(&spec, &kernels, &opts, strip);
            worst = worst.max(max_diff(&got, want.normal()));
        }
        let bound = 3.5e-4 * 2.0 * gmax;
        assert!(worst <= bound, "σ {sigma_px}: {worst:e} > {bound:e}");
        // And the cut is where it matters: a strip of the whole height is exact.
        let (got, _) = streamed(&spec, &kernels, &opts, 160);
        assert_eq!(max_diff(&got, want.normal()), 0.0);
    }
}

#[test]
fn the_cli_streams_png_to_png_and_the_result_matches_reading_whole() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(64, 48, 4);
    let spec = write_files(d.path(), &img, 16);
    let n = spec.normal.as_ref().unwrap().display().to_string();
    let c = spec.color.as_ref().unwrap().display().to_string();
    let m = spec.mask.as_ref().unwrap().display().to_string();
    let run = |mode: &str| {
        let (o, co) = (
            d.path().join(format!("o_{mode}.png")),
            d.path().join(format!("c_{mode}.png")),
        );
        let out = rgbn(&[
            "filter",
            "--normal",
            &n,
            "--color",
            &c,
            "--mask",
            &m,
            "--mask-aware",
            "-k",
            "gauss:1.5",
            "-k",
            "sharpen:1,0.5",
            "--bits",
            "16",
            "--stream",
            mode,
            "-o",
            o.to_str().unwrap(),
            "--color-out",
            co.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        (
            std::fs::read(o).unwrap(),
            std::fs::read(co).unwrap(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    let (sn, sc, sline) = run("always");
    let (wn, wc, wline) = run("never");
    // Pixels: decode both and compare (the encoders are the same, so are the bytes).
    let decode = |b: &[u8]| image::load_from_memory(b).unwrap().into_rgb16().into_raw();
    let (a, b) = (decode(&sn), decode(&wn));
    let worst = a.iter().zip(&b).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
    // Within one 16-bit step (the streamed input is renormalised, see above).
    assert!(worst <= 1, "{worst}");
    assert_eq!(decode(&sc), decode(&wc), "colour passes through unchanged");
    assert_eq!(
        sline.split(';').next(),
        wline.split(';').next(),
        "{sline} / {wline}"
    );
}

#[test]
fn a_truncated_png_is_a_one_line_error_and_the_target_is_untouched() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(96, 120, 5);
    let spec = write_files(d.path(), &img, 16);
    let full = std::fs::read(spec.normal.as_ref().unwrap()).unwrap();
    let cut = d.path().join("cut.png");
    std::fs::write(&cut, &full[..full.len() * 3 / 5]).unwrap();
    let target = d.path().join("out.png");
    std::fs::write(&target, b"the previous output").unwrap();
    for mode in ["always", "never"] {
        let o = rgbn(&[
            "filter",
            cut.to_str().unwrap(),
            "-k",
            "gauss:2",
            "--stream",
            mode,
            "-o",
            target.to_str().unwrap(),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{mode}: {err}");
        assert_eq!(err.lines().count(), 1, "{mode}: {err}");
        assert!(err.contains("cut.png"), "{mode}: {err}");
        assert_eq!(std::fs::read(&target).unwrap(), b"the previous output");
        let names: Vec<String> = std::fs::read_dir(d.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(
            names.iter().all(|n| !n.ends_with(".tmp")),
            "{mode}: {names:?}"
        );
        if mode == "always" {
            // The streamed reader says where the data ran out.
            assert!(err.contains("row"), "{err}");
        }
    }
}

#[test]
fn what_cannot_stream_says_why() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(32, 24, 6);
    let spec = write_files(d.path(), &img, 16);
    let n = spec.normal.as_ref().unwrap().to_str().unwrap().to_string();
    // A tiled EXR (the exr crate's default encoding) of normals in R,G,B.
    let exr = d.path().join("in.exr");
    exr::prelude::write_rgba_file(&exr, 32, 24, |x, y| {
        let i = y * 32 + x;
        let [a, b, c] = [0, 1, 2].map(|k| img.normal()[k][i]);
        (a, b, c, 1.0f32)
    })
    .unwrap();
    let cases: [(&[&str], &str); 3] = [
        (&["--border", "wrap"], "wrap border"),
        (&["-o", "x.exr"], "output is not a PNG"),
        (&["--exr-rgb-is-normal"], "tiled EXR"),
    ];
    for (extra, why) in cases {
        let input = if why == "tiled EXR" {
            exr.to_str().unwrap()
        } else {
            &n
        };
        let mut args = vec!["filter", input, "-k", "gauss:1", "--stream", "always"];
        args.extend_from_slice(extra);
        if !extra.contains(&"-o") {
            args.extend_from_slice(&["-o", "y.png"]);
        }
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
            .current_dir(d.path())
            .args(&args)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("cannot stream") && err.contains(why), "{err}");
    }
    // Over the pixel limit, whole reading is refused and the refusal says why it was needed.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(d.path())
        .env("RGBN_MAX_PIXELS", "100")
        .args([
            "filter",
            exr.to_str().unwrap(),
            "--exr-rgb-is-normal",
            "-k",
            "gauss:1",
            "-o",
            "z.png",
        ])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("too large")
            && err.contains("needs PNG, TIFF or scan-line EXR in")
            && err.contains("tiled EXR"),
        "{err}"
    );
    // A PNG over the limit streams whatever --stream auto's own threshold.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(d.path())
        .env("RGBN_MAX_PIXELS", "100")
        .args(["filter", &n, "-k", "gauss:1", "-o", "z.png"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A graph: image → pen stroke (positional) → Gaussian → outputs the image and its relighting.
const PEN_GRAPH: &str = r#"(
    version: 1,
    next_id: 4,
    inputs: { "image": (ty: Rgbn, doc: "The input.") },
    outputs: {
        "image": (node: 2, port: "image"),
        "relit": (node: 3, port: "picture"),
    },
    nodes: [
        (
            id: 1,
            op: "pen",
            pos: (0.0, 0.0),
            params: {
                "height_px": Float(3.0),
                "points": Points([(5.0, 10.0), (40.0, 60.0), (20.0, 110.0)]),
                "profile": Choice("bump"),
                "width_px": Float(8.0),
                "taper_px": Float(6.0),
            },
            inputs: { "image": Input("image") },
        ),
        (
            id: 2,
            op: "filter.gaussian",
            pos: (200.0, 0.0),
            params: { "sigma_px": Float(1.5) },
            inputs: { "image": Node(1, "image") },
        ),
        (
            id: 3,
            op: "relight",
            pos: (400.0, 0.0),
            inputs: { "image": Node(2, "image") },
        ),
    ],
)"#;

#[test]
fn eval_streams_a_graph_of_local_nodes_and_equals_the_whole_image_run() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(48, 128, 7);
    let spec = write_files(d.path(), &img, 8);
    let graph = d.path().join("pen.ron");
    std::fs::write(&graph, PEN_GRAPH).unwrap();
    let n = spec.normal.as_ref().unwrap().display().to_string();
    let run = |mode: &str, strip: &str| {
        let (o, r) = (
            d.path().join(format!("o_{mode}{strip}.png")),
            d.path().join(format!("r_{mode}{strip}.png")),
        );
        let mut args = vec![
            "eval".to_string(),
            graph.display().to_string(),
            "-i".into(),
            format!("image={n}"),
            "-o".into(),
            format!("image={}", o.display()),
            "-o".into(),
            format!("relit={}", r.display()),
            "--stream".into(),
            mode.into(),
        ];
        if !strip.is_empty() {
            args.extend(["--strip-rows".into(), strip.into()]);
        }
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = rgbn(&a);
        assert!(out.status.success(), "{}", stderr(&out));
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert_eq!(text.contains("streamed"), mode == "always", "{text}");
        let img = |p: &Path| image::open(p).unwrap();
        (
            img(&o).into_rgb16().into_raw(),
            img(&r).into_rgba8().into_raw(),
        )
    };
    let (wi, wr) = run("never", "");
    for strip in ["1", "9", "40", ""] {
        let (si, sr) = run("always", strip);
        // 8-bit normals: both paths renormalise alike, and every kernel here is finite: the
        // same numbers, so the same samples (the stroke moved by a strip's offset would not be).
        let differ = |a: &[u16], b: &[u16]| a.iter().zip(b).filter(|(x, y)| x != y).count();
        assert_eq!(si.len(), wi.len());
        assert_eq!(differ(&si, &wi), 0, "image samples differ, strip {strip}");
        assert_eq!(sr.len(), wr.len());
        let relit_differ = sr.iter().zip(&wr).filter(|(x, y)| x != y).count();
        assert_eq!(relit_differ, 0, "relit samples differ, strip {strip}");
    }
}

#[test]
fn eval_says_why_a_graph_cannot_stream() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(32, 24, 8);
    let spec = write_files(d.path(), &img, 16);
    let n = spec.normal.as_ref().unwrap().display().to_string();
    let graphs = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs");
    let cases: [(&str, Vec<String>, &str); 3] = [
        // The demo source is not a file.
        (
            "demo.ron",
            vec!["-o".into(), "relit=r.png".into()],
            "source other than a file",
        ),
        // Integration needs the whole image.
        (
            "input_image.ron",
            vec![
                "-i".into(),
                format!("image={n}"),
                "-o".into(),
                "relit=r.exr".into(),
            ],
            "not written row by row",
        ),
        (
            "input_image.ron",
            vec![
                "-i".into(),
                format!("image={n}"),
                "-o".into(),
                "image=i.png".into(),
                "--stats".into(),
            ],
            "--stats",
        ),
    ];
    for (g, extra, why) in cases {
        let mut args = vec![
            "eval".to_string(),
            graphs.join(g).display().to_string(),
            "--stream".into(),
            "always".into(),
        ];
        args.extend(extra);
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
            .current_dir(d.path())
            .args(&args)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.contains("cannot stream") && err.contains(why),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn render_streams_its_per_pixel_views_and_equals_reading_whole() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(50, 70, 9);
    let spec = write_files(d.path(), &img, 8);
    let arg = |p: &Option<std::path::PathBuf>| p.as_ref().unwrap().display().to_string();
    let (n, c, m) = (arg(&spec.normal), arg(&spec.color), arg(&spec.mask));
    for view in ["relit", "albedo", "normals"] {
        let run = |mode: &str| {
            let o = d.path().join(format!("{view}_{mode}.png"));
            let out = rgbn(&[
                "render",
                "--normal",
                &n,
                "--color",
                &c,
                "--mask",
                &m,
                "--view",
                view,
                "--light",
                "-1,1,1",
                "--stream",
                mode,
                "-o",
                o.to_str().unwrap(),
            ]);
            assert!(out.status.success(), "{}", stderr(&out));
            let text = String::from_utf8_lossy(&out.stdout).into_owned();
            assert_eq!(text.contains("streamed"), mode == "always", "{text}");
            image::open(&o).unwrap().into_rgba8().into_raw()
        };
        let (s, w) = (run("always"), run("never"));
        assert_eq!(s.len(), 50 * 70 * 4);
        let differ = s.iter().zip(&w).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{view}: {differ} bytes differ");
    }
    let o = rgbn(&[
        "render",
        &n,
        "--view",
        "curvature",
        "--stream",
        "always",
        "-o",
        d.path().join("k.png").to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cannot stream") && err.contains("curvature"),
        "{err}"
    );
}

/// `rgbn batch` streams each file as `rgbn eval` does: a graph of local nodes over PNG files
/// runs strip by strip and writes the same samples as the whole-image run, images as 16-bit
/// PNG (`--images png`) or as EXR (the default, bit for bit the same floats).
#[test]
fn batch_streams_each_file_and_equals_the_whole_image_run() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in");
    std::fs::create_dir(&input).unwrap();
    for seed in [7, 8] {
        let img = relief(48, 128, seed);
        let path = input.join(format!("f{seed}.png"));
        io::save_normal_map(&img, &path, 8, NormalConvention::OpenGl).unwrap();
    }
    let graph = d.path().join("pen.ron");
    std::fs::write(&graph, PEN_GRAPH).unwrap();
    let glob = format!("image={}/*.png", input.display());
    let run = |out: &str, extra: &[&str]| {
        let out_dir = d.path().join(out);
        let mut args = vec![
            "batch",
            graph.to_str().unwrap(),
            "--input",
            &glob,
            "--out-dir",
            out_dir.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        (rgbn(&args), out_dir)
    };
    let (whole, wdir) = run("whole", &["--images", "png", "--stream", "never"]);
    assert!(whole.status.success(), "{}", stderr(&whole));
    let (strips, sdir) = run(
        "strips",
        &["--images", "png", "--stream", "always", "--strip-rows", "9"],
    );
    assert!(strips.status.success(), "{}", stderr(&strips));
    let text = String::from_utf8_lossy(&strips.stdout).into_owned();
    assert!(
        text.contains("processed 2 files (2 streamed strip by strip), wrote 4 outputs"),
        "{text}"
    );
    for seed in [7, 8] {
        let image = |dir: &Path| {
            image::open(dir.join(format!("f{seed}.image.png")))
                .unwrap()
                .into_rgb16()
                .into_raw()
        };
        let relit = |dir: &Path| {
            image::open(dir.join(format!("f{seed}.relit.png")))
                .unwrap()
                .into_rgba8()
                .into_raw()
        };
        assert_eq!(
            image(&sdir),
            image(&wdir),
            "image samples differ, file f{seed}"
        );
        assert_eq!(
            relit(&sdir),
            relit(&wdir),
            "relit samples differ, file f{seed}"
        );
    }
    // Images as EXR (the default) stream too: the same 32-bit planes as the whole run.
    let (exr_s, edir_s) = run("exr_strips", &["--stream", "always", "--strip-rows", "9"]);
    assert!(exr_s.status.success(), "{}", stderr(&exr_s));
    let text = String::from_utf8_lossy(&exr_s.stdout).into_owned();
    assert!(text.contains("(2 streamed strip by strip)"), "{text}");
    let (exr_w, edir_w) = run("exr_whole", &["--stream", "never"]);
    assert!(exr_w.status.success(), "{}", stderr(&exr_w));
    for seed in [7, 8] {
        let load = |dir: &Path| {
            io::load_exr(
                &dir.join(format!("f{seed}.image.exr")),
                &LoadOptions::default(),
            )
            .unwrap()
        };
        let (a, b) = (load(&edir_s), load(&edir_w));
        assert_eq!(a.normal(), b.normal(), "EXR normals differ, file f{seed}");
        assert_eq!(a.color(), b.color(), "EXR colour differs, file f{seed}");
        assert_eq!(a.mask(), b.mask(), "EXR mask differs, file f{seed}");
    }
}

/// A TIFF stored in strips streams like a PNG: normal map (16-bit), colour (8-bit) and mask
/// read strip by strip give the filter the same samples as reading them whole; a TIFF cut
/// short is a one-line error (exit 2) naming the file, and leaves no output.
#[test]
fn tiff_in_strips_streams_and_equals_reading_whole() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(72, 40, 5);
    // Written as PNGs, then as TIFFs of a few rows per strip (an encoder's default strips hold
    // about 1 MB, so a small image would be one strip).
    use tiff::encoder::{colortype, TiffEncoder};
    let (w, h) = (72u32, 40u32);
    let png = d.path().join("n.png");
    io::save_normal_map(&img, &png, 16, NormalConvention::OpenGl).unwrap();
    let n = d.path().join("n.tif");
    let samples = image::open(&png).unwrap().into_rgb16().into_raw();
    let mut enc = TiffEncoder::new(std::fs::File::create(&n).unwrap()).unwrap();
    let mut im = enc.new_image::<colortype::RGB16>(w, h).unwrap();
    im.rows_per_strip(3).unwrap();
    im.write_data(&samples).unwrap();
    let cpng = d.path().join("c.png");
    io::save_color(&img, &cpng, 8).unwrap();
    let c = d.path().join("c.tif");
    let samples = image::open(&cpng).unwrap().into_rgb8().into_raw();
    let mut enc = TiffEncoder::new(std::fs::File::create(&c).unwrap()).unwrap();
    let mut im = enc.new_image::<colortype::RGB8>(w, h).unwrap();
    im.rows_per_strip(5).unwrap();
    im.write_data(&samples).unwrap();
    for p in [&n, &c] {
        let mut dec = tiff::decoder::Decoder::new(std::fs::File::open(p).unwrap()).unwrap();
        let strips = dec.strip_count().unwrap();
        assert!(strips >= 8, "{} has {strips} strips", p.display());
    }
    let run = |mode: &str, normal: &Path| {
        let (o, co) = (
            d.path().join(format!("o_{mode}.png")),
            d.path().join(format!("c_{mode}.png")),
        );
        let out = rgbn(&[
            "filter",
            "--normal",
            normal.to_str().unwrap(),
            "--color",
            c.to_str().unwrap(),
            "-k",
            "box:2",
            "--bits",
            "16",
            "--stream",
            mode,
            "--strip-rows",
            "7",
            "-o",
            o.to_str().unwrap(),
            "--color-out",
            co.to_str().unwrap(),
        ]);
        (out, o, co)
    };
    let (so, sn, sc) = run("always", &n);
    // `--stream always` refuses, saying why, whatever it cannot read row by row.
    assert!(so.status.success(), "{}", stderr(&so));
    let (wo, wn, wc) = run("never", &n);
    assert!(wo.status.success(), "{}", stderr(&wo));
    let rgb16 = |p: &Path| image::open(p).unwrap().into_rgb16().into_raw();
    // The box filter is finite: the same numbers, so the same samples.
    assert_eq!(rgb16(&sn), rgb16(&wn), "normals differ");
    assert_eq!(rgb16(&sc), rgb16(&wc), "colour differs");
    // Cut short: the end of the file (strips or the directory) is missing.
    let bytes = std::fs::read(&n).unwrap();
    let cut = d.path().join("cut.tif");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let target = d.path().join("o_always.png");
    std::fs::remove_file(&target).unwrap();
    let (co, _, _) = run("always", &cut);
    assert_fails_naming(&co, "cut.tif");
    assert!(!target.exists(), "a partial output was left");
}

/// A scan-line EXR streams as well: an RGBN EXR (normals, colour and mask; 32- and 16-bit
/// floats; uncompressed one row a block and ZIP 16 rows a block) filtered strip by strip gives
/// the same samples as read whole; a tiled one is read whole and `--stream always` says so; a
/// file cut short is a one-line error (exit 2) naming it, leaving no output.
#[test]
fn scan_line_exr_streams_and_equals_reading_whole() {
    use rgbn::raster::io::{save_exr_with, ExrCompression, ExrPrecision};
    let d = tempfile::tempdir().unwrap();
    let img = relief(60, 45, 6);
    let run = |mode: &str, input: &Path, tag: &str| {
        let (o, co) = (
            d.path().join(format!("o_{tag}_{mode}.png")),
            d.path().join(format!("c_{tag}_{mode}.png")),
        );
        let out = rgbn(&[
            "filter",
            input.to_str().unwrap(),
            "--mask-aware",
            "-k",
            "box:2",
            "--bits",
            "16",
            "--stream",
            mode,
            "--strip-rows",
            "7",
            "-o",
            o.to_str().unwrap(),
            "--color-out",
            co.to_str().unwrap(),
        ]);
        (out, o, co)
    };
    let rgb16 = |p: &Path| image::open(p).unwrap().into_rgb16().into_raw();
    for (precision, compression, tag) in [
        (ExrPrecision::Full, ExrCompression::None, "f32"),
        (ExrPrecision::Half, ExrCompression::Zip, "f16zip"),
    ] {
        let p = d.path().join(format!("{tag}.exr"));
        save_exr_with(&img, &p, precision, compression).unwrap();
        let (so, sn, sc) = run("always", &p, tag);
        assert!(so.status.success(), "{tag}: {}", stderr(&so));
        let (wo, wn, wc) = run("never", &p, tag);
        assert!(wo.status.success(), "{tag}: {}", stderr(&wo));
        // The samples read are the loader's, and the box filter is finite; half floats are
        // not unit length, and a streamed band is renormalised as read (as a streamed PNG):
        // within one 16-bit step.
        let (a, b) = (rgb16(&sn), rgb16(&wn));
        let worst = a.iter().zip(&b).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
        let limit = u16::from(precision == ExrPrecision::Half);
        assert!(worst <= limit, "{tag}: normals differ by {worst}");
        assert_eq!(rgb16(&sc), rgb16(&wc), "{tag}: colour differs");
    }
    // Tiled (the exr crate's default encoding: 64² RLE tiles): read whole, and said so.
    let tiled = d.path().join("tiled.exr");
    exr::prelude::write_rgba_file(&tiled, 60, 45, |_, _| (0.0f32, 0.0f32, 1.0f32, 1.0f32)).unwrap();
    let out = rgbn(&[
        "filter",
        tiled.to_str().unwrap(),
        "--exr-rgb-is-normal",
        "-k",
        "box:1",
        "--stream",
        "always",
        "-o",
        d.path().join("t.png").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("cannot stream") && err.contains("tiled EXR"),
        "{err}"
    );
    // Cut short mid-file.
    let full = d.path().join("f32.exr");
    let bytes = std::fs::read(&full).unwrap();
    let cut = d.path().join("cut.exr");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let (co, o, _) = run("always", &cut, "cut");
    assert_fails_naming(&co, "cut.exr");
    assert!(!o.exists(), "a partial output was left");
}

/// `rgbn eval` streaming into an EXR: an input cut short mid-stream is a one-line error (exit
/// 2), the previous target is untouched and no temporary file is left (the EXR writer thread
/// stops before its file is removed).
#[test]
fn a_streamed_exr_output_of_a_truncated_input_leaves_the_target_untouched() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(48, 128, 9);
    let spec = write_files(d.path(), &img, 16);
    let full = std::fs::read(spec.normal.as_ref().unwrap()).unwrap();
    let cut = d.path().join("cut.png");
    std::fs::write(&cut, &full[..full.len() * 3 / 5]).unwrap();
    let graph = d.path().join("pen.ron");
    std::fs::write(&graph, PEN_GRAPH).unwrap();
    let target = d.path().join("out.exr");
    std::fs::write(&target, b"the previous output").unwrap();
    let o = rgbn(&[
        "eval",
        graph.to_str().unwrap(),
        "-i",
        &format!("image={}", cut.display()),
        "-o",
        &format!("image={}", target.display()),
        "--stream",
        "always",
        "--strip-rows",
        "16",
    ]);
    assert_fails_naming(&o, "cut.png");
    assert!(stderr(&o).contains("row"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&target).unwrap(), b"the previous output");
    let names: Vec<String> = std::fs::read_dir(d.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
}

/// `RAYON_NUM_THREADS=1` runs every pipeline's stages in turn on one thread (the strip reader,
/// the PNG and EXR writers, the whole-image decoder's converter, outputs one after the other);
/// two threads run them side by side. Both write the same files, byte for byte: the stages
/// only move, the numbers and their order do not. Streamed in strips of 7 rows (the first
/// three ramping up), and whole.
#[test]
fn one_thread_and_two_write_the_same_bytes_streamed_and_whole() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(96, 80, 11);
    let spec = write_files(d.path(), &img, 16);
    let n = spec.normal.as_ref().unwrap().display().to_string();
    let graph = super::common::graph_path("input_image.ron");
    let run = |threads: &str, mode: &str| {
        let (o, r) = (
            d.path().join(format!("o_{threads}_{mode}.exr")),
            d.path().join(format!("r_{threads}_{mode}.png")),
        );
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
            .env("RAYON_NUM_THREADS", threads)
            .args([
                "eval",
                graph.to_str().unwrap(),
                "-i",
                &format!("image={n}"),
                "-o",
                &format!("image={}", o.display()),
                "-o",
                &format!("relit={}", r.display()),
                "--stream",
                mode,
                "--strip-rows",
                "7",
            ])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        (std::fs::read(o).unwrap(), std::fs::read(r).unwrap())
    };
    for mode in ["always", "never"] {
        let (o1, r1) = run("1", mode);
        let (o2, r2) = run("2", mode);
        assert!(o1.len() > 1000, "an EXR was written ({mode})");
        assert!(
            o1 == o2,
            "the EXR differs between one thread and two ({mode})"
        );
        assert!(
            r1 == r2,
            "the relit PNG differs between one thread and two ({mode})"
        );
    }
}

/// The bands are decoded by tasks on the pool when the strips are driven from outside it, on a
/// thread of their own from a worker of a pool, inline with one thread: the same windows, bit
/// for bit, whichever way (the reading must not depend on where it runs).
#[test]
fn strips_read_alike_outside_a_pool_inside_one_and_on_one_thread() {
    let d = tempfile::tempdir().unwrap();
    let img = relief(40, 300, 3);
    let spec = write_files(d.path(), &img, 16);
    let kernels = [Kernel::Gaussian { sigma_px: 1.5 }];
    let opts = FilterOptions::default();
    let outside = streamed(&spec, &kernels, &opts, 24);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let inside = pool.install(|| streamed(&spec, &kernels, &opts, 24));
        assert_eq!(inside.0, outside.0, "{threads} threads");
        assert_eq!(inside.1.clamped, outside.1.clamped);
    }
}
