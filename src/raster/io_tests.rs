//! Tests of `raster/io.rs`.

use super::*;
use crate::raster::sample::demo_medallion;
use crate::raster::srgb::srgb_to_linear;

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

#[test]
fn png16_normal_roundtrip_within_quantisation_and_dx_flip() {
    let img = demo_medallion(48);
    let d = tmp();
    for (conv, bits, tol) in [
        (NormalConvention::OpenGl, 16, 2.0 / 65535.0 * 1.01),
        (NormalConvention::DirectX, 16, 2.0 / 65535.0 * 1.01),
        (NormalConvention::OpenGl, 8, 2.0 / 255.0 * 1.01),
    ] {
        let p = d.path().join(format!("n{bits}{conv:?}.png"));
        save_normal_map(&img, &p, bits, conv).unwrap();
        let opts = LoadOptions {
            convention: conv,
            ..Default::default()
        };
        let back = load(
            &InputSpec {
                normal: Some(p.clone()),
                ..Default::default()
            },
            &opts,
        )
        .unwrap()
        .image;
        // half a quantisation step per component, plus renormalisation
        for (a, b) in img.normal().iter().zip(back.normal()) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= tol, "{conv:?} {bits}: {x} vs {y}");
            }
        }
        if conv == NormalConvention::DirectX {
            // Reading the DX file as GL must show the y flip.
            let gl = load_normal_map(&p, &LoadOptions::default()).unwrap();
            let i = img.normal()[1].iter().position(|v| v.abs() > 0.3).unwrap();
            assert!((gl.normal()[1][i] + img.normal()[1][i]).abs() < 1e-3);
        }
    }
}

#[test]
fn colour_png_is_decoded_to_linear() {
    let d = tmp();
    let p = d.path().join("c.png");
    let data: Vec<u8> = [128u8, 0, 255].repeat(4);
    write_raster8(&data, 2, 2, 3, Format::Png, &p).unwrap();
    let (w, h, [r, g, b]) = load_color(&p).unwrap();
    assert_eq!((w, h), (2, 2));
    assert!((r[0] - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
    assert_eq!((g[3], b[3]), (0.0, 1.0));
}

#[test]
fn bad_inputs_give_clear_errors() {
    let d = tmp();
    let missing = d.path().join("nope.png");
    let e = load_normal_map(&missing, &LoadOptions::default()).unwrap_err();
    assert!(
        matches!(e, RgbnError::NotFound { .. }) && e.to_string().ends_with("nope.png"),
        "{e}"
    );

    let txt = d.path().join("x.bmp");
    std::fs::write(&txt, b"hi").unwrap();
    assert!(matches!(
        Format::of(&txt),
        Err(RgbnError::UnsupportedFormat { .. })
    ));

    // truncated PNG
    let img = demo_medallion(32);
    let good = d.path().join("good.png");
    save_normal_map(&img, &good, 16, NormalConvention::OpenGl).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let cut = d.path().join("cut.png");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = load_normal_map(&cut, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, RgbnError::Decode { .. }), "{e:?}");
    assert!(e.to_string().ends_with("cut.png"));

    // garbage EXR
    let bad = d.path().join("bad.exr");
    std::fs::write(&bad, b"not an exr at all").unwrap();
    assert!(matches!(
        load_exr(&bad, &LoadOptions::default()),
        Err(RgbnError::Decode { .. })
    ));

    // colour/normal size mismatch
    let small = d.path().join("small.png");
    write_raster8(&[0u8; 3 * 4], 2, 2, 3, Format::Png, &small).unwrap();
    let spec = InputSpec {
        normal: Some(good.clone()),
        color: Some(small),
        ..Default::default()
    };
    let e = load(&spec, &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("2×2 but the image is 32×32"), "{e}");

    // output equal to an input, output in a missing folder
    assert!(matches!(
        check_output(&good, &[&good]),
        Err(RgbnError::OutputIsInput { .. })
    ));
    let via_dots = d.path().join(".").join("good.png");
    assert!(matches!(
        check_output(&via_dots, &[&good]),
        Err(RgbnError::OutputIsInput { .. })
    ));
    let nodir = d.path().join("missing/out.png");
    assert!(matches!(
        check_output(&nodir, &[]),
        Err(RgbnError::MissingDir { .. })
    ));
}

#[test]
fn strict_refuses_and_default_repairs_zero_normals() {
    let d = tmp();
    let p = d.path().join("z.exr");
    let mut img = RgbnImage::flat(4, 4, [0.5; 3]);
    img.normal_mut()[2][5] = 0.0;
    img.normal_mut()[0][6] = f32::NAN;
    save_exr(&img, &p, ExrPrecision::Full).unwrap();
    let spec = InputSpec {
        rgbn: Some(p),
        ..Default::default()
    };
    let l = load(&spec, &LoadOptions::default()).unwrap();
    assert_eq!(
        (l.repaired.zero_length_normal, l.repaired.non_finite_normal),
        (1, 1)
    );
    assert_eq!(l.image.normal_at(1, 1), [0.0, 0.0, 1.0]);
    let strict = LoadOptions {
        strict: true,
        ..Default::default()
    };
    let e = load(&spec, &strict).unwrap_err();
    assert!(
        e.to_string()
            .contains("1 invalid normals (NaN or infinite)"),
        "{e}"
    );
}

#[test]
fn failed_write_leaves_no_file_and_keeps_the_old_one() {
    let d = tmp();
    let p = d.path().join("keep.png");
    std::fs::write(&p, b"old").unwrap();
    let e = write_atomic(&p, |_| Err("boom".into())).unwrap_err();
    assert!(e.to_string().contains("boom"));
    assert_eq!(std::fs::read(&p).unwrap(), b"old");
    assert_eq!(
        std::fs::read_dir(d.path()).unwrap().count(),
        1,
        "temp file removed"
    );
}
