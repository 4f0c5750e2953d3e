//! PTM input through the command line and the `load` node: a synthetic sphere PTM is read by
//! `info`, `filter` and a graph, and bad PTM-like files are one line naming the format, exit 2.

use crate::common::{rgbn, stderr, stdout};
use rgbn::raster::ptm::{write_ptm, Coefficients, PtmData};
use std::path::{Path, PathBuf};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const W: usize = 40;
const H: usize = 30;

/// An LRGB PTM of a sphere (centre (20, 14), radius 12; `+y` up): per pixel a concave
/// biquadratic peaking at the normal's `(x, y)`; flat outside the sphere (no maximum → masked).
fn sphere_ptm(dir: &Path) -> PathBuf {
    let lum: Vec<Coefficients> = (0..W * H)
        .map(|i| {
            let (x, row) = ((i % W) as f64 + 0.5, (i / W) as f64 + 0.5);
            let (nx, ny) = ((x - 20.0) / 12.0, -(row - 14.0) / 12.0);
            if nx * nx + ny * ny < 1.0 {
                let p = 200.0 * 0.5;
                [
                    -p,
                    -p,
                    0.0,
                    2.0 * p * nx,
                    2.0 * p * ny,
                    200.0 - p * (nx * nx + ny * ny),
                ]
            } else {
                [0.0, 0.0, 0.0, 0.0, 0.0, 20.0]
            }
        })
        .collect();
    let rgb = vec![[200u8, 120, 40]; W * H];
    let p = dir.join("sphere.ptm");
    write_ptm(&p, W, H, &PtmData::Lrgb { lum, rgb }).unwrap();
    p
}

#[test]
fn info_filter_and_a_graph_read_a_ptm() {
    let d = tempfile::tempdir().unwrap();
    let ptm = sphere_ptm(d.path());
    let o = rgbn(&["info", s(&ptm)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("40×30"), "{out}");
    assert!(out.contains("mask yes"), "{out}");

    // filter → EXR keeps the PTM's normals (identity kernel: scale 1) and mask.
    let exr = d.path().join("out.exr");
    let o = rgbn(&["filter", s(&ptm), "-k", "scale:1", "-o", s(&exr)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = rgbn::raster::io::load_exr(&exr, &Default::default()).unwrap();
    let mask = img.mask().expect("the PTM mask is kept");
    // Top of the sphere (row 4, x 20): normal points up; centre: towards the viewer.
    let up = img.normal_at(20, 4);
    assert!(up[1] > 0.7 && mask[4 * W + 20] == 1.0, "{up:?}");
    let c = img.normal_at(20, 14);
    assert!(c[2] > 0.99, "{c:?}");
    assert_eq!(mask[0], 0.0, "background has no maximum");

    // A graph input bound to the PTM (the `load` node).
    let png = d.path().join("relit.png");
    let graph = crate::common::graph_path("input_image.ron");
    let o = rgbn(&[
        "eval",
        s(&graph),
        "--input",
        &format!("image={}", s(&ptm)),
        "-o",
        &format!("relit={}", s(&png)),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(png.exists());

    // `batch` over a glob of PTMs.
    let out_dir = d.path().join("batch");
    std::fs::create_dir(&out_dir).unwrap();
    let o = rgbn(&[
        "batch",
        s(&graph),
        "--input",
        &format!("image={}/*.ptm", s(d.path())),
        "--out-dir",
        s(&out_dir),
        "-j",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let made: Vec<_> = std::fs::read_dir(&out_dir).unwrap().flatten().collect();
    assert!(
        made.iter()
            .any(|e| e.file_name().to_string_lossy().starts_with("sphere.")),
        "{made:?}"
    );
}

#[test]
fn bad_ptms_are_one_line_naming_the_format_exit_2() {
    let d = tempfile::tempdir().unwrap();
    let good = std::fs::read(sphere_ptm(d.path())).unwrap();
    let truncated = d.path().join("truncated.ptm");
    std::fs::write(&truncated, &good[..good.len() - 100]).unwrap();
    let jpeg = d.path().join("jpeg.ptm");
    std::fs::write(
        &jpeg,
        "PTM_1.2\nPTM_FORMAT_JPEG_LRGB\n40\n30\n1 1 1 1 1 1\n0 0 0 0 0 0\n75\n",
    )
    .unwrap();
    let hsh_ptm = d.path().join("hsh.ptm");
    std::fs::write(&hsh_ptm, "#HSH1.2\n3\n40 30 3\n9 2 1\n").unwrap();
    let hsh_rti = d.path().join("hsh.rti");
    std::fs::write(&hsh_rti, "#HSH1.2\n3\n40 30 3\n9 2 1\n").unwrap();
    let out = d.path().join("out.exr");
    let cases: [(&Path, &str); 4] = [
        (&truncated, "truncated ptm_format_lrgb ptm"),
        (&jpeg, "compressed ptm ptm_format_jpeg_lrgb"),
        (&hsh_ptm, "hsh"),
        (&hsh_rti, "hsh"),
    ];
    for (path, needle) in cases {
        for args in [
            vec!["info", s(path)],
            vec!["filter", s(path), "-k", "gauss:1", "-o", s(&out)],
        ] {
            let o = rgbn(&args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
            assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
            assert!(
                err.to_lowercase().contains(needle),
                "{args:?}: {err:?} lacks {needle:?}"
            );
            assert!(err.trim_end().ends_with(s(path)), "{args:?}: {err:?}");
            assert!(!out.exists(), "{args:?} wrote an output");
        }
    }
    // An RGBN output written as .ptm is an LRGB PTM (docs/cli.md, "Writing PTM").
    let o = rgbn(&[
        "filter",
        "--demo",
        "--demo-size",
        "32",
        "-k",
        "gauss:1",
        "-o",
        s(&d.path().join("x.ptm")),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let bytes = std::fs::read(d.path().join("x.ptm")).unwrap();
    assert!(
        bytes.starts_with(b"PTM_1.2"),
        "{:?}",
        &bytes[..16.min(bytes.len())]
    );
}
