//! The core on real third-party data (`../shared/data`, see its PROVENANCE files). Each test
//! says when it skips because the data is absent, and fails instead with `RGBN_REQUIRE_DATA=1`.

use crate::common::real_data;
use rgbn::ops::filter::{filter_gradients, FilterOptions, Kernel};
use rgbn::raster::convolve::{self, BorderMode};
use rgbn::raster::gradient::GradientField;
use rgbn::raster::io::{load, InputSpec, LoadOptions, NormalConvention};

fn rosewood(conv: NormalConvention) -> Option<rgbn::raster::io::Loaded> {
    let d = real_data("polyhaven-rosewood-veneer")?;
    let spec = InputSpec {
        color: Some(d.join("rosewood_veneer1_diff_1k.jpg")),
        normal: Some(d.join("rosewood_veneer1_nor_gl_1k.png")),
        ..Default::default()
    };
    Some(
        load(
            &spec,
            &LoadOptions {
                convention: conv,
                ..Default::default()
            },
        )
        .expect("the rosewood texture loads"),
    )
}

fn mean_std(v: &[f32]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / n;
    (m, var.sqrt())
}

/// PROVENANCE.md measured mean n ≈ (−0.002, −0.002, 0.998) and std(n_x) ≈ 0.014 on this file.
#[test]
fn rosewood_texture_loads_with_its_documented_statistics() {
    let Some(l) = rosewood(NormalConvention::OpenGl) else {
        return;
    };
    let img = &l.image;
    assert_eq!((img.width(), img.height()), (1024, 1024));
    // Nothing broken in the file; the 8-bit-ish quantised normals (|n| ≈ 0.998, as PROVENANCE
    // says) are renormalised on load and counted as such.
    let v = l.repaired;
    assert_eq!(
        (v.non_finite_normal, v.zero_length_normal, v.back_facing),
        (0, 0, 0),
        "{v:?}"
    );
    assert!(
        v.non_unit > 0,
        "the decoded normals are not unit before repair: {v:?}"
    );
    assert!(img.validate().is_clean(), "{:?}", img.validate());
    let [nx, ny, nz] = img.normal();
    let (mx, sx) = mean_std(nx);
    let (my, _) = mean_std(ny);
    let (mz, _) = mean_std(nz);
    eprintln!("rosewood: mean n = ({mx:.4}, {my:.4}, {mz:.4}), std n_x = {sx:.4}");
    assert!(
        (mx + 0.002).abs() < 0.002 && (my + 0.002).abs() < 0.002,
        "{mx} {my}"
    );
    // PROVENANCE's 0.998 is before renormalising (|n| ≈ 0.998); unit normals with std(n_x) ≈
    // std(n_y) ≈ 0.014 have mean n_z ≈ 1 − 0.014² ≈ 0.9998.
    assert!((mz - 0.9998).abs() < 3e-4, "{mz}");
    assert!((sx - 0.014).abs() < 0.003, "{sx}");
    // Unit normals after decoding.
    for i in (0..img.len()).step_by(997) {
        let n = img.normal_at(i % 1024, i / 1024);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5);
    }
    // Colour is linear light in [0, 1] and is not grey (it is wood).
    let [r, _, b] = img.color();
    let (mr, _) = mean_std(r);
    let (mb, _) = mean_std(b);
    assert!(r.iter().chain(b.iter()).all(|v| (0.0..=1.0).contains(v)));
    assert!(mr > mb * 1.3, "wood is red-brown: r {mr} b {mb}");
    // Reading the same file as DirectX flips y, and only y.
    let dx = rosewood(NormalConvention::DirectX).unwrap().image;
    assert_eq!(dx.normal()[0], img.normal()[0]);
    for (a, b) in dx.normal()[1].iter().zip(ny.iter()).step_by(101) {
        assert!((a + b).abs() < 1e-6);
    }
}

/// A linear filter commutes with the (linear) curl operator: away from the borders the curl of
/// the Gaussian-filtered gradients equals the Gaussian-filtered curl of the original. This holds
/// for any field, integrable or not, so it checks the filter on real, non-integrable data.
#[test]
fn filtering_real_gradients_filters_their_curl() {
    let Some(l) = rosewood(NormalConvention::OpenGl) else {
        return;
    };
    let mut g = GradientField::from_normals(&l.image);
    let (w, h) = (g.width, g.height);
    let sigma = 4.0;
    let mut want = g.curl().into_vec();
    convolve::gaussian(&mut want, w, h, sigma, BorderMode::Mirror);
    filter_gradients(
        &mut g,
        &[Kernel::Gaussian { sigma_px: sigma }],
        &FilterOptions::default(),
        None,
    )
    .unwrap();
    let got = g.curl().into_vec();
    let m = 24; // > 4σ from the border, where the border extension does not reach
    let (mut err2, mut ref2) = (0.0f64, 0.0f64);
    for r in m..h - m {
        for x in m..w - m {
            let i = r * w + x;
            err2 += ((got[i] - want[i]) as f64).powi(2);
            ref2 += (want[i] as f64).powi(2);
        }
    }
    let rel = (err2 / ref2).sqrt();
    eprintln!("rosewood: relative error of curl(G*g) vs G*curl(g) = {rel:.2e}");
    assert!(rel < 1e-3, "{rel}");
    assert!(
        ref2 > 0.0,
        "the real data is not integrable, so its curl is not zero"
    );
}

/// `rgbn info` tells the green convention from local integrability: the Poly Haven file is the
/// OpenGL one (`_nor_gl`); read as OpenGL its plaquette curl energy is the lower one, and with
/// `--dx` it says to load the file without it, with the contrast negated.
#[test]
fn info_tells_the_rosewood_normal_map_is_opengl() {
    let Some(d) = real_data("polyhaven-rosewood-veneer") else {
        return;
    };
    let file = d.join("rosewood_veneer1_nor_gl_1k.png");
    let file = file.to_str().unwrap();
    let contrast = |line: &str| -> f64 {
        let after = line.split("contrast ").nth(1).expect("a contrast");
        let num = after.split(',').next().unwrap();
        num.parse()
            .unwrap_or_else(|e| panic!("contrast in {line:?}: {num:?} {e}"))
    };
    let o = crate::common::rgbn(&["info", file]);
    let text = crate::common::stdout(&o);
    assert!(o.status.success(), "{}", crate::common::stderr(&o));
    let line = text
        .lines()
        .find(|l| l.starts_with("green:"))
        .expect("a green line");
    assert!(line.contains("OpenGL (+y) most likely"), "{line}");
    let c = contrast(line);
    eprintln!("rosewood: {line}");
    assert!(c >= 0.05, "{line}");
    let f_line = text
        .lines()
        .find(|l| l.starts_with("integrability:"))
        .expect("an integrability line");
    assert!(f_line.contains("non-integrable fraction F"), "{f_line}");
    // Loaded the wrong way round: the same evidence, the contrast negated, and a hint.
    let o = crate::common::rgbn(&["info", "--dx", file]);
    let text = crate::common::stdout(&o);
    let line = text.lines().find(|l| l.starts_with("green:")).unwrap();
    assert!(
        line.contains("OpenGL (+y) most likely") && line.contains("without --dx"),
        "{line}"
    );
    assert!((contrast(line) + c).abs() < 1e-3, "{line}");
}
