//! The core CLI (`info`, `render`, `filter`) as a user runs it: outputs, exit codes, and that bad
//! input gives one clear line naming the file and writes nothing.

use crate::common::{rgbn, stderr, stdout};
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn info_on_the_demo_reports_size_and_near_zero_curl() {
    let o = rgbn(&["info", "--demo", "--demo-size", "96"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("96×96") || out.contains("96x96"), "{out}");
    assert!(out.to_lowercase().contains("curl"), "{out}");
}

#[test]
fn render_writes_a_png_of_the_input_size() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("lit.png");
    let o = rgbn(&[
        "render",
        "--demo",
        "--demo-size",
        "80",
        "--light",
        "-1,1,1.5",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (80, 80));
    // Not a constant image: the relief is visible.
    let px = img.to_luma8();
    let (lo, hi) = px
        .pixels()
        .fold((255u8, 0u8), |(lo, hi), p| (lo.min(p[0]), hi.max(p[0])));
    assert!(hi - lo > 50, "relit demo is flat: {lo}..{hi}");
}

#[test]
fn filter_png_to_exr_to_png_keeps_the_normals() {
    // Filtering with a Gaussian through the CLI equals the library call on the same input.
    let d = tempfile::tempdir().unwrap();
    let exr = d.path().join("f.exr");
    let o = rgbn(&[
        "filter",
        "--demo",
        "--demo-size",
        "64",
        "-k",
        "gauss:2",
        "-o",
        s(&exr),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let back = rgbn::raster::io::load_exr(&exr, &Default::default()).unwrap();
    let demo = rgbn::raster::sample::demo_medallion(64);
    let (want, _) = rgbn::ops::filter::filter_normals(
        &demo,
        &[rgbn::ops::filter::Kernel::Gaussian { sigma_px: 2.0 }],
        &Default::default(),
    )
    .unwrap();
    assert_eq!(back.normal(), want.normal());
}

/// Each bad input: exit code 2, one line on stderr that ends with the offending path, and
/// no output file.
#[test]
fn bad_input_is_one_line_exit_2_and_writes_nothing() {
    let d = tempfile::tempdir().unwrap();
    let dp = d.path();
    let good = dp.join("n.png");
    let o = rgbn(&[
        "filter",
        "--demo",
        "--demo-size",
        "32",
        "-k",
        "scale:1",
        "-o",
        s(&good),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let truncated = dp.join("trunc.png");
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let small = dp.join("small.png");
    image::RgbImage::new(16, 16).save(&small).unwrap();
    let text = dp.join("notes.txt");
    std::fs::write(&text, "hello").unwrap();
    let missing = dp.join("missing.png");
    let out = dp.join("out.png");
    let in_missing_dir = dp.join("no/such/dir/out.png");

    let cases: Vec<(Vec<&str>, &Path, &str)> = vec![
        (
            vec!["filter", s(&missing), "-k", "gauss:1", "-o", s(&out)],
            &missing,
            "not found",
        ),
        (
            vec!["filter", s(&truncated), "-k", "gauss:1", "-o", s(&out)],
            &truncated,
            "decode",
        ),
        (
            vec!["filter", s(&text), "-k", "gauss:1", "-o", s(&out)],
            &text,
            "unsupported format",
        ),
        (
            vec![
                "filter",
                "--color",
                s(&small),
                "--normal",
                s(&good),
                "-k",
                "gauss:1",
                "-o",
                s(&out),
            ],
            &small,
            "size mismatch",
        ),
        (
            vec!["filter", s(&good), "-k", "gauss:1", "-o", s(&good)],
            &good,
            "overwrite an input",
        ),
        (
            vec![
                "filter",
                s(&good),
                "-k",
                "gauss:1",
                "-o",
                s(&in_missing_dir),
            ],
            &in_missing_dir,
            "does not exist",
        ),
    ];
    for (args, path, needle) in cases {
        let o = rgbn(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.to_lowercase().contains(needle),
            "{args:?}: {err:?} lacks {needle:?}"
        );
        assert!(
            err.trim_end().ends_with(s(path)),
            "{args:?}: {err:?} does not end with the path"
        );
        assert!(!out.exists(), "{args:?} wrote an output");
    }
    // The input that was named as output is intact.
    assert_eq!(std::fs::read(&good).unwrap(), bytes);
}

#[test]
fn too_large_is_refused_before_allocating() {
    let d = tempfile::tempdir().unwrap();
    let big = d.path().join("big.png");
    image::RgbImage::new(300, 200).save(&big).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .args(["info", s(&big)])
        .env("RGBN_MAX_PIXELS", "10000")
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("300×200") && err.contains("10000"), "{err}");
}

#[test]
fn bad_kernel_is_a_usage_error() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o.png");
    let o = rgbn(&["filter", "--demo", "-k", "gauss:-3", "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("sigma"), "{}", stderr(&o));
    assert!(!out.exists());
}
