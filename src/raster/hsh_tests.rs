//! Tests of `raster/hsh.rs`.

use super::*;

/// The pseudo-inverse `(BᵀB)⁻¹ Bᵀ` (`terms × m`) of the basis matrix `B` (`m × terms`) of the
/// lights: least-squares HSH fitting, as an RTI fitter does it.
#[allow(clippy::needless_range_loop)]
fn fitter(lights: &[[f64; 3]], terms: usize) -> Vec<Vec<f64>> {
    let b: Vec<[f64; MAX_TERMS]> = lights.iter().map(|&l| hsh_basis(l, terms)).collect();
    // [BᵀB | I] → [I | (BᵀB)⁻¹] by Gauss–Jordan with partial pivoting.
    let mut a = vec![vec![0.0; 2 * terms]; terms];
    for (i, row) in a.iter_mut().enumerate() {
        for j in 0..terms {
            row[j] = b.iter().map(|h| h[i] * h[j]).sum();
        }
        row[terms + i] = 1.0;
    }
    for c in 0..terms {
        let p = (c..terms)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        a.swap(c, p);
        let d = a[c][c];
        for v in &mut a[c] {
            *v /= d;
        }
        for r in 0..terms {
            if r != c {
                let f = a[r][c];
                for k in 0..2 * terms {
                    a[r][k] -= f * a[c][k];
                }
            }
        }
    }
    (0..terms)
        .map(|i| {
            b.iter()
                .map(|h| (0..terms).map(|k| a[i][terms + k] * h[k]).sum())
                .collect()
        })
        .collect()
}

/// A dome of lights: rings of elevation 15°..75° plus the zenith (RTI domes look like this).
fn dome() -> Vec<[f64; 3]> {
    let mut out = vec![[0.0, 0.0, 1.0]];
    for (ring, count) in [(15.0f64, 16), (30.0, 16), (45.0, 12), (60.0, 10), (75.0, 6)] {
        let e = ring.to_radians();
        for k in 0..count {
            let a = std::f64::consts::TAU * (f64::from(k) + 0.5 * (ring / 15.0)) / f64::from(count);
            out.push([e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]);
        }
    }
    out
}

/// A sphere in rgbn's frame, off-centre in a non-square image so that a flipped row order or
/// axis shows; `None` outside.
fn sphere_normal(x: usize, row: usize) -> Option<[f64; 3]> {
    let (cx, cy, r) = (26.0, 19.0, 16.0);
    let px = (x as f64 + 0.5 - cx) / r;
    let py = -(row as f64 + 0.5 - cy) / r;
    let d = px * px + py * py;
    (d < 1.0).then(|| [px, py, (1.0 - d).sqrt()])
}
const W: usize = 50;
const H: usize = 40;

fn albedo(x: usize, row: usize) -> [f64; 3] {
    [
        0.3 + 0.5 * x as f64 / W as f64,
        0.6,
        0.2 + 0.4 * row as f64 / H as f64,
    ]
}

fn angle_deg(a: [f32; 3], b: [f64; 3]) -> f64 {
    let a = a.map(f64::from);
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let la = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let lb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    (d / (la * lb)).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The sphere rendered under the dome (Lambertian, sRGB-encoded 8-bit-like values in 0..1 as
/// an RTI fitter sees them), fitted per pixel and channel; `None` outside the sphere.
fn fitted_sphere(terms: usize) -> [Vec<Vec<f64>>; 3] {
    let lights = dome();
    let p = fitter(&lights, terms);
    std::array::from_fn(|c| {
        (0..W * H)
            .map(|i| {
                let (x, row) = (i % W, i / W);
                let obs: Vec<f64> = lights
                    .iter()
                    .map(|l| match sphere_normal(x, row) {
                        Some(n) => {
                            let s = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0);
                            f64::from(crate::raster::srgb::linear_to_srgb(
                                (albedo(x, row)[c] * s) as f32,
                            ))
                        }
                        None => 0.0,
                    })
                    .collect();
                p.iter()
                    .map(|row| row.iter().zip(&obs).map(|(a, b)| a * b).sum())
                    .collect()
            })
            .collect()
    })
}

/// Mean and max angular error against the sphere over the pixels with `n_z ≥ nz_min`, and
/// how many of them the reader masked out.
fn sphere_errors(img: &RgbnImage, nz_min: f64) -> (f64, f64, usize, usize) {
    let (mut sum, mut max, mut count, mut masked) = (0.0, 0.0f64, 0, 0);
    for row in 0..H {
        for x in 0..W {
            let Some(n) = sphere_normal(x, row) else {
                continue;
            };
            if n[2] < nz_min {
                continue;
            }
            if img.mask().unwrap()[row * W + x] < 0.5 {
                masked += 1;
                continue;
            }
            let e = angle_deg(img.normal_at(x, row), n);
            sum += e;
            max = max.max(e);
            count += 1;
        }
    }
    (sum / count as f64, max, count, masked)
}

#[allow(clippy::needless_range_loop)]
#[test]
fn the_basis_is_orthonormal_over_the_hemisphere() {
    // ∫ H_i H_j dω = δ_ij (Gautron et al. 2004): checks every formula, sign-free, against an
    // independent quadrature (midpoint rule in cos θ and φ; dω = d(cos θ) dφ).
    let (nz, nphi) = (400, 400);
    let mut g = [[0.0f64; MAX_TERMS]; MAX_TERMS];
    for i in 0..nz {
        let z = (i as f64 + 0.5) / nz as f64;
        let s = (1.0 - z * z).sqrt();
        for j in 0..nphi {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / nphi as f64;
            let h = hsh_basis([s * phi.cos(), s * phi.sin(), z], 16);
            let w = std::f64::consts::TAU / (nz * nphi) as f64;
            for a in 0..16 {
                for b in 0..16 {
                    g[a][b] += w * h[a] * h[b];
                }
            }
        }
    }
    for a in 0..16 {
        for b in 0..16 {
            let want = if a == b { 1.0 } else { 0.0 };
            assert!((g[a][b] - want).abs() < 2e-3, "⟨H{a}, H{b}⟩ = {}", g[a][b]);
        }
    }
    // Fewer terms leave the rest zero.
    let h = hsh_basis([0.3, -0.2, 0.9327], 4);
    assert!(h[4..].iter().all(|&v| v == 0.0));
}

#[test]
fn fitted_lambertian_sphere_gives_its_normals_and_albedo() {
    let dir = tempfile::tempdir().unwrap();
    for terms in [9, 16, 4] {
        let channels = fitted_sphere(terms);
        let path = dir.path().join(format!("sphere{terms}.rti"));
        write_hsh(&path, W, H, &HshData::Rgb { channels }).unwrap();
        let hsh = read_hsh(&path).unwrap();
        assert_eq!((hsh.terms, hsh.layout), (terms, HshLayout::Rgb));
        let (mean, max, count, masked) = sphere_errors(&hsh.image, 0.0);
        let (mean_30, max_30, _, _) = sphere_errors(&hsh.image, 0.5);
        eprintln!(
            "HSH {terms} terms, fitted from {} Lambertian photos of a sphere: mean {mean:.3}°, max {max:.2}° over {count} px ({masked} masked); n_z ≥ 0.5: mean {mean_30:.3}°, max {max_30:.2}°",
            dome().len()
        );
        // The background (black in every photo) has no normal.
        assert!(hsh.image.mask().unwrap()[0] == 0.0);
        if terms >= 9 {
            // The goal of issue 55: 1° mean over the whole visible hemisphere (measured: order 3
            // 0.90°, order 4 0.66°; 1.43° and 1.82° without the tilt correction).
            assert!(mean <= 1.0, "{terms} terms: mean {mean}°");
            assert!(
                mean_30 <= 1.0,
                "{terms} terms: mean {mean_30}° where n_z ≥ 0.5"
            );
            assert!(masked <= count / 50, "{masked} of {count} masked");
            // Colour: the albedo (sRGB-encoded in the file, linear in rgbn) within 2 %.
            let i = 19 * W + 26; // the sphere's centre
            for c in 0..3 {
                let got = f64::from(hsh.image.color()[c][i]);
                let want = albedo(26, 19)[c];
                assert!((got - want).abs() < 0.02, "channel {c}: {got} vs {want}");
            }
        } else {
            // Order 2 is a smooth lobe: only roughly right, and pulled towards the viewer.
            assert!(mean_30 <= 5.0, "4 terms: mean {mean_30}° where n_z ≥ 0.5");
        }
    }
}

#[test]
fn lrgb_round_trip_keeps_colour_bytes_and_normals() {
    let terms = 9;
    let [r, g, b] = fitted_sphere(terms);
    let lum: Vec<Vec<f64>> = (0..W * H)
        .map(|i| {
            (0..terms)
                .map(|t| (r[i][t] + g[i][t] + b[i][t]) / 3.0)
                .collect()
        })
        .collect();
    let rgb: Vec<[u8; 3]> = (0..W * H)
        .map(|i| [(i % 256) as u8, (i / 7 % 256) as u8, 200])
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lrgb.rti");
    write_hsh(
        &path,
        W,
        H,
        &HshData::Lrgb {
            lum,
            rgb: rgb.clone(),
        },
    )
    .unwrap();
    let hsh = read_hsh(&path).unwrap();
    assert_eq!(hsh.layout, HshLayout::Lrgb);
    let (mean, ..) = sphere_errors(&hsh.image, 0.0);
    assert!(mean <= 1.0, "{mean}");
    let lut = srgb8_to_linear();
    for (i, c) in rgb.iter().enumerate() {
        for k in 0..3 {
            assert_eq!(hsh.image.color()[k][i], lut[usize::from(c[k])]);
        }
    }
}

/// A header and the scale/bias floats for a file with `terms` terms.
fn head(dims: &str, basis: &str, terms: usize, scale: f32, bias: f32) -> Vec<u8> {
    let mut v = format!("#HSH1.2\r\n3\r\n{dims}\r\n{basis}\r\n").into_bytes();
    for _ in 0..terms {
        v.extend_from_slice(&scale.to_le_bytes());
    }
    for _ in 0..terms {
        v.extend_from_slice(&bias.to_le_bytes());
    }
    v
}

fn read_bytes(bytes: &[u8]) -> Result<Hsh, RgbnError> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.rti");
    std::fs::write(&p, bytes).unwrap();
    read_hsh(&p)
}

#[test]
fn hand_written_bytes_pin_the_layout_row_order_and_formula() {
    // 2 × 1 pixels, 4 terms, RGB. Coefficient t = c/255 · (255/127) − 1, so byte 127 is 0
    // and 254 is 1. Each pixel: the constant term only, so the band's value is c0 · H0 =
    // c0 / √(2π) everywhere and its colour is that value. Pixel 0 (left): red bright, green
    // and blue black; pixel 1 (right): blue bright.
    let s = 255.0 / 127.0;
    let mut v = head("2 1 3", "4 2 1", 4, s, -1.0);
    let k = |c0: f64| ((c0 + 1.0) * 127.0).round() as u8;
    let mid = k(0.0);
    let h0 = 1.0 / (2.0 * std::f64::consts::PI).sqrt();
    // Band-major per pixel: 4 red terms, 4 green, 4 blue.
    for (r, g, b) in [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)] {
        for c0 in [r, g, b] {
            v.extend([k(c0), mid, mid, mid]);
        }
    }
    let hsh = read_bytes(&v).unwrap();
    let col = hsh.image.color();
    let want = srgb_to_linear(h0 as f32);
    assert!((col[0][0] - want).abs() < 0.01, "{} vs {want}", col[0][0]);
    assert!((col[2][1] - want).abs() < 0.01, "{} vs {want}", col[2][1]);
    assert_eq!((col[2][0], col[0][1]), (0.0, 0.0));
    // Row order: 1 × 2 pixels, the file's first row is the image's bottom row. A term-1
    // (cos φ: brighter towards +x) lobe in the first row: the bottom pixel's normal leans to
    // +x; the top pixel's constant function gives no lean. A black pixel has no normal.
    let mut v = head("1 3 3", "4 2 1", 4, s, -1.0);
    let lobe = [k(1.0), k(0.6), mid, mid];
    let flat = [k(1.0), mid, mid, mid];
    let black = [mid, mid, mid, mid];
    for px in [lobe, flat, black] {
        for _ in 0..3 {
            v.extend(px);
        }
    }
    let hsh = read_bytes(&v).unwrap();
    let (bottom, middle) = (hsh.image.normal_at(0, 2), hsh.image.normal_at(0, 1));
    assert!(bottom[0] > 0.2 && bottom[1].abs() < 0.02, "{bottom:?}");
    assert!(
        middle[0].abs() < 0.02 && middle[1].abs() < 0.02,
        "{middle:?}"
    );
    let m = hsh.image.mask().unwrap();
    assert_eq!(
        (m[2], m[1], m[0]),
        (1.0, 1.0, 0.0),
        "the black top pixel is masked"
    );
    assert_eq!(hsh.no_maximum, 1);
}

#[test]
fn bad_files_are_one_line_errors_never_panics() {
    let good = {
        let mut v = head("2 2 3", "9 2 1", 9, 1.0, 0.0);
        v.extend(vec![128u8; 2 * 2 * 27]);
        v
    };
    assert!(read_bytes(&good).is_ok());
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (good[..good.len() - 1].to_vec(), "truncated HSH RGB file"),
        (good[..40].to_vec(), "truncated"),
        (b"#HSH1.2\n".to_vec(), "truncated before the type line"),
        (b"#HSH1.2\n4\n".to_vec(), "RTI type 4 (RBF)"),
        (b"#HSH1.2\n1\n2 2 3\n6 1 1\n".to_vec(), "PTM-basis"),
        (b"hello\n".to_vec(), "not an RTI file"),
        (b"PTM_1.2\nPTM_FORMAT_LRGB\n".to_vec(), "rename it to .ptm"),
        (
            b"#HSH1.2\n3\n2 2\n9 2 1\n".to_vec(),
            "should hold 3 numbers",
        ),
        (
            b"#HSH1.2\n3\n2 -2 3\n9 2 1\n".to_vec(),
            "not a whole number",
        ),
        (b"#HSH1.2\n3\n2 2 3\n7 2 1\n".to_vec(), "7 HSH terms"),
        (b"#HSH1.2\n3\n2 2 3\n9 5 1\n".to_vec(), "colour layout 5"),
        (b"#HSH1.2\n3\n2 2 4\n9 2 1\n".to_vec(), "4 bands"),
        (
            b"#HSH1.2\n3\n2 2 3\n9 2 2\n".to_vec(),
            "2 bytes per coefficient",
        ),
        (b"#HSH1.2\n3\n4000000000 4000000000 3\n9 2 1\n".to_vec(), ""),
        (vec![b'#'; 5000], "longer than"),
    ];
    for (bytes, want) in cases {
        let e = read_bytes(&bytes).unwrap_err().to_string();
        assert!(e.contains(want), "{e:?} should contain {want:?}");
        assert!(!e.contains('\n'), "{e:?}");
    }
    let mut nan = head("2 2 3", "9 2 1", 9, f32::NAN, 0.0);
    nan.extend(vec![128u8; 2 * 2 * 27]);
    let e = read_bytes(&nan).unwrap_err().to_string();
    assert!(e.contains("scale 0 is not a finite number"), "{e}");
}

#[test]
fn loads_through_io_and_refuses_to_be_written() {
    use crate::raster::io::{load, save, InputSpec, LoadOptions, SaveOptions};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.rti");
    write_hsh(
        &path,
        W,
        H,
        &HshData::Rgb {
            channels: fitted_sphere(9),
        },
    )
    .unwrap();
    let spec = InputSpec {
        rgbn: Some(path.clone()),
        ..InputSpec::default()
    };
    let img = load(&spec, &LoadOptions::default()).unwrap().image;
    assert_eq!((img.width(), img.height()), (W, H));
    assert_eq!(crate::raster::io::dimensions(&path), Some((W, H)));
    let e = save(&img, &dir.path().join("out.rti"), &SaveOptions::default()).unwrap_err();
    assert!(e.to_string().contains("write .ptm"), "{e}");
}
