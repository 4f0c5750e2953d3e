//! The `extract` node (issue 13, Fig. 4): a rectangle or a region's bounding box cut out of an
//! RGBN image, checked pixel by pixel against the source; bad rectangles and regions are
//! one-line errors naming the node and parameter.

use rgbn::ops::stamp::{extract, ExtractParams};
use rgbn::raster::sample::Surface;
use rgbn::RgbnImage;

fn source() -> RgbnImage {
    let s = Surface::Gaussians {
        bumps: vec![[20.0, 12.0, 6.0, 5.0], [-15.0, -10.0, 4.0, 3.0]],
    };
    s.render(80, 60).0
}

fn params(x: i64, y: i64, w: i64, h: i64) -> ExtractParams {
    ExtractParams {
        x,
        y,
        width: w,
        height: h,
        highpass_sigma_px: 0.0,
    }
}

#[test]
fn a_rectangle_is_cut_pixel_for_pixel() {
    let img = source();
    let out = extract(&img, None, &params(11, 7, 30, 20)).unwrap();
    assert_eq!((out.width(), out.height()), (30, 20));
    for r in 0..20 {
        for x in 0..30 {
            let (i, j) = (r * 30 + x, (r + 7) * 80 + x + 11);
            for k in 0..3 {
                assert_eq!(out.normal()[k][i], img.normal()[k][j]);
                assert_eq!(out.color()[k][i], img.color()[k][j]);
            }
        }
    }
}

#[test]
fn a_region_gives_its_bounding_box_and_its_coverage_as_mask() {
    let img = source();
    // A disc of radius 6 centred at (40, 25), with a soft rim.
    let region: Vec<f32> = (0..80 * 60)
        .map(|i| {
            let (x, r) = ((i % 80) as f32, (i / 80) as f32);
            let d = ((x - 40.0).powi(2) + (r - 25.0).powi(2)).sqrt();
            (7.0 - d).clamp(0.0, 1.0)
        })
        .collect();
    let out = extract(&img, Some(&region), &params(0, 0, 64, 64)).unwrap();
    // Pixels with coverage ≥ ½: |d| ≤ 6.5 → x and rows 34..=46 and 19..=31.
    assert_eq!((out.width(), out.height()), (13, 13));
    let m = out.mask().expect("the region becomes the mask");
    for r in 0..13 {
        for x in 0..13 {
            let j = (r + 19) * 80 + x + 34;
            assert_eq!(m[r * 13 + x], region[j]);
            assert_eq!(out.normal()[2][r * 13 + x], img.normal()[2][j]);
        }
    }
}

#[test]
fn the_high_pass_keeps_only_detail() {
    // A tilted plane (slope 0.3) with fine ripples (slope amplitude 0.2, period 4 px).
    let (w, h) = (64, 48);
    let slope = |x: usize| 0.3 + 0.2 * (std::f32::consts::TAU * x as f32 / 4.0).sin();
    let mut n = [vec![], vec![], vec![]];
    for i in 0..w * h {
        let p = slope(i % w);
        let l = (1.0 + p * p).sqrt();
        n[0].push(-p / l);
        n[1].push(0.0);
        n[2].push(1.0 / l);
    }
    let img = RgbnImage::new(
        w,
        h,
        [vec![0.5; w * h], vec![0.5; w * h], vec![0.5; w * h]],
        n,
        None,
    )
    .unwrap();
    let mean_slope = |i: &RgbnImage| {
        let [nx, _, nz] = i.normal();
        nx.iter().zip(nz).map(|(x, z)| -x / z).sum::<f32>() / nx.len() as f32
    };
    let plain = extract(&img, None, &params(0, 0, 64, 48)).unwrap();
    let mut p = params(0, 0, 64, 48);
    p.highpass_sigma_px = 8.0;
    let hp = extract(&img, None, &p).unwrap();
    assert!(
        (mean_slope(&plain) - 0.3).abs() < 1e-3,
        "{}",
        mean_slope(&plain)
    );
    // The tilt (the lowest frequency) is gone, the ripples (period 4 ≪ σ) stay.
    assert!(mean_slope(&hp).abs() < 0.01, "{}", mean_slope(&hp));
    let ripple = |i: &RgbnImage, x: usize| {
        let [nx, _, nz] = i.normal();
        -nx[x] / nz[x]
    };
    let amp = (ripple(&hp, 33) - ripple(&hp, 31)) / 2.0; // sin at x = 33 (¼) and 31 (¾)
    assert!((amp - 0.2).abs() < 0.03, "ripple amplitude {amp}");
}

#[test]
fn bad_rectangles_and_regions_are_named() {
    let img = source();
    let e = extract(&img, None, &params(60, 0, 30, 20))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("x, y, width, height") && e.contains("inside the 80×60 image"),
        "{e}"
    );
    let e = extract(&img, Some(&vec![0.0; 80 * 60]), &params(0, 0, 8, 8))
        .unwrap_err()
        .to_string();
    assert!(e.contains("region") && e.contains("covers no pixel"), "{e}");
    let e = extract(&img, Some(&[1.0; 10]), &params(0, 0, 8, 8))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("region") && e.contains("not the image's size"),
        "{e}"
    );
}

#[test]
fn the_cli_names_the_node_and_exits_2() {
    let d = tempfile::tempdir().unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(d.path())
        .args([
            "eval",
            &crate::common::graph_path("extract.ron")
                .display()
                .to_string(),
        ])
        .args(["--set", "cut.x=250"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("node 3 \"cut\"") && err.contains("x, y, width, height"),
        "{err}"
    );
}
