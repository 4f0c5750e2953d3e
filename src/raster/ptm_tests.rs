//! Tests of `raster/ptm.rs`.

use super::*;

/// Solves the 6×6 normal equations of a least-squares biquadratic fit.
#[allow(clippy::needless_range_loop)] // matrix indices read best as indices
fn fit(lights: &[[f64; 3]], intensity: impl Fn(&[f64; 3]) -> f64) -> Coefficients {
    let mut a = [[0.0f64; 7]; 6];
    for l in lights {
        let f = [l[0] * l[0], l[1] * l[1], l[0] * l[1], l[0], l[1], 1.0];
        let y = intensity(l);
        for i in 0..6 {
            for j in 0..6 {
                a[i][j] += f[i] * f[j];
            }
            a[i][6] += f[i] * y;
        }
    }
    for c in 0..6 {
        let p = (c..6)
            .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
            .unwrap();
        a.swap(c, p);
        for r in 0..6 {
            if r != c {
                let f = a[r][c] / a[c][c];
                for k in c..7 {
                    a[r][k] -= f * a[c][k];
                }
            }
        }
    }
    std::array::from_fn(|i| a[i][6] / a[i][i])
}

/// Light directions on a grid of the unit disk of radius `rmax` (elevation ≥ acos(rmax)).
fn lights(rmax: f64) -> Vec<[f64; 3]> {
    let k = 10;
    let mut out = Vec::new();
    for i in -k..=k {
        for j in -k..=k {
            let (u, v) = (
                f64::from(i) / f64::from(k) * rmax,
                f64::from(j) / f64::from(k) * rmax,
            );
            if u * u + v * v <= rmax * rmax + 1e-12 {
                out.push([u, v, (1.0 - u * u - v * v).sqrt()]);
            }
        }
    }
    out
}

/// A sphere in rgbn's frame (row 0 at the top, `+y` up), off-centre in a non-square image so
/// that a flipped row order or axis shows. `None` outside the sphere.
struct Sphere {
    w: usize,
    h: usize,
}
impl Sphere {
    const W: usize = 56;
    const H: usize = 44;
    fn new() -> Self {
        Self {
            w: Self::W,
            h: Self::H,
        }
    }
    fn normal(&self, x: usize, row: usize) -> Option<[f64; 3]> {
        let (cx, cy, r) = (30.0, 20.0, 18.0);
        let px = (x as f64 + 0.5 - cx) / r;
        let py = -(row as f64 + 0.5 - cy) / r;
        let d = px * px + py * py;
        (d < 1.0).then(|| [px, py, (1.0 - d).sqrt()])
    }
}

fn angle_deg(a: [f32; 3], b: [f64; 3]) -> f64 {
    let dot = f64::from(a[0]) * b[0] + f64::from(a[1]) * b[1] + f64::from(a[2]) * b[2];
    let len = (f64::from(a[0]).powi(2) + f64::from(a[1]).powi(2) + f64::from(a[2]).powi(2)).sqrt();
    (dot / len).clamp(-1.0, 1.0).acos().to_degrees()
}

/// (mean, max, count) angular error over the unmasked pixels whose true normal satisfies
/// `keep`.
fn errors(img: &RgbnImage, s: &Sphere, keep: impl Fn(&[f64; 3]) -> bool) -> (f64, f64, usize) {
    let mask = img.mask().expect("PTMs carry a mask");
    let (mut sum, mut max, mut count) = (0.0, 0.0f64, 0);
    for row in 0..s.h {
        for x in 0..s.w {
            let n = s
                .normal(x, row)
                .filter(|n| keep(n) && mask[row * s.w + x] > 0.0);
            if let Some(n) = n {
                let e = angle_deg(img.normal_at(x, row), n);
                sum += e;
                max = max.max(e);
                count += 1;
            }
        }
    }
    (sum / count as f64, max, count)
}

/// An "ideal" PTM of the normal `n`: a concave biquadratic whose maximum is exactly at
/// `(n_x, n_y)`, with a per-pixel anisotropy and `uv` term (so that every coefficient and
/// its position matter), peak value `peak` (0..255 units).
fn ideal(n: [f64; 3], peak: f64, x: usize) -> Coefficients {
    let t = x as f64 * 0.37;
    let (k1, k2, k12) = (
        0.5 + 0.2 * t.sin(),
        0.5 - 0.15 * t.cos(),
        0.2 * (1.3 * t).sin(),
    );
    let (du, dv) = (n[0], n[1]);
    // peak · (1 − [d]ᵀ Q [d]) with d = (u − du, v − dv), Q = [[k1, k12], [k12, k2]]
    let p = peak;
    [
        -p * k1,
        -p * k2,
        -p * 2.0 * k12,
        p * (2.0 * k1 * du + 2.0 * k12 * dv),
        p * (2.0 * k2 * dv + 2.0 * k12 * du),
        p * (1.0 - k1 * du * du - k2 * dv * dv - 2.0 * k12 * du * dv),
    ]
}

const ALBEDO: [f64; 3] = [0.8, 0.45, 0.0];

fn lrgb_rgb(s: &Sphere) -> Vec<[u8; 3]> {
    (0..s.w * s.h)
        .map(|i| [(i % 251) as u8, 200, (i * 7 % 256) as u8])
        .collect()
}

#[test]
fn ideal_sphere_lrgb_and_rgb_recover_normals_within_2_degrees() {
    let s = Sphere::new();
    let d = tempfile::tempdir().unwrap();
    let flat: Coefficients = [0.0, 0.0, 0.0, 0.0, 0.0, 10.0];
    let lum: Vec<Coefficients> = (0..s.w * s.h)
        .map(|i| {
            let (x, row) = (i % s.w, i / s.w);
            s.normal(x, row).map_or(flat, |n| ideal(n, 200.0, x))
        })
        .collect();
    let rgb = lrgb_rgb(&s);
    let p = d.path().join("ideal_lrgb.ptm");
    write_ptm(
        &p,
        s.w,
        s.h,
        &PtmData::Lrgb {
            lum: lum.clone(),
            rgb: rgb.clone(),
        },
    )
    .unwrap();
    let ptm = read_ptm(&p).unwrap();
    assert_eq!(ptm.format, PtmFormat::Lrgb);
    let img = &ptm.image;
    assert_eq!((img.width(), img.height()), (s.w, s.h));
    // Sphere interior: the pixels with tilt ≤ 60° (n_z ≥ 0.5, the inner 87 % of the radius); nearer the rim the 8-bit coefficient steps move the maximum more
    // (measured: max 2.5° at tilt ≤ 72.5°).
    let (mean, max, count) = errors(img, &s, |n| n[2] >= 0.5);
    eprintln!("ideal LRGB, tilt ≤ 60°: mean {mean:.3}°, max {max:.3}° over {count} px");
    assert!(count > 700, "{count}");
    assert!(mean < 2.0 && max < 2.0, "mean {mean}°, max {max}°");
    let (mean, max, count) = errors(img, &s, |n| n[2] >= 0.3);
    eprintln!("ideal LRGB, tilt ≤ 72.5°: mean {mean:.3}°, max {max:.3}° over {count} px");
    // Colour is the stored bytes, sRGB-decoded; flat (background) pixels are masked.
    let lin = srgb8_to_linear();
    for (i, c) in rgb.iter().enumerate() {
        let (x, row) = (i % s.w, i / s.w);
        let got = img.color_at(x, row);
        for k in 0..3 {
            assert_eq!(got[k], lin[usize::from(c[k])], "colour at {x},{row}");
        }
    }
    let mask = img.mask().unwrap();
    let outside = (0..s.w * s.h)
        .filter(|&i| s.normal(i % s.w, i / s.w).is_none())
        .count();
    // Flat background pixels are masked, with the fallback normal; the interior is not.
    assert!(
        ptm.no_maximum >= outside && ptm.no_maximum < outside + 60,
        "{}",
        ptm.no_maximum
    );
    assert_eq!(img.normal_at(0, 0), [0.0, 0.0, 1.0]);
    assert_eq!(mask[0], 0.0);
    for (i, &m) in mask.iter().enumerate() {
        if s.normal(i % s.w, i / s.w).is_some_and(|n| n[2] >= 0.3) {
            assert_eq!(m, 1.0, "pixel {i}");
        }
    }

    // RGB: three channels with albedo (0.8, 0.45, 0): blue is flat zero everywhere.
    let channels: [Vec<Coefficients>; 3] = std::array::from_fn(|c| {
        (0..s.w * s.h)
            .map(|i| {
                let (x, row) = (i % s.w, i / s.w);
                s.normal(x, row)
                    .map_or([0.0; 6], |n| ideal(n, 255.0 * ALBEDO[c], x))
            })
            .collect()
    });
    let p = d.path().join("ideal_rgb.ptm");
    write_ptm(&p, s.w, s.h, &PtmData::Rgb { channels }).unwrap();
    let ptm = read_ptm(&p).unwrap();
    assert_eq!(ptm.format, PtmFormat::Rgb);
    let (mean, max, count) = errors(&ptm.image, &s, |n| n[2] >= 0.5);
    eprintln!("ideal RGB, tilt ≤ 60°: mean {mean:.3}°, max {max:.3}° over {count} px");
    assert!(mean < 2.0 && max < 2.0, "mean {mean}°, max {max}°");
    let (mean, max, count) = errors(&ptm.image, &s, |n| n[2] >= 0.3);
    eprintln!("ideal RGB, tilt ≤ 72.5°: mean {mean:.3}°, max {max:.3}° over {count} px");
    assert!(
        ptm.no_maximum >= outside && ptm.no_maximum < outside + 60,
        "{}",
        ptm.no_maximum
    );
    // Colour at the maximum is the albedo (the peak), sRGB-decoded.
    let c = ptm.image.color_at(30, 20);
    for k in 0..3 {
        let want = srgb_to_linear(ALBEDO[k] as f32);
        assert!(
            (c[k] - want).abs() < 0.02,
            "channel {k}: {} vs {want}",
            c[k]
        );
    }
}

#[test]
fn lambertian_sphere_fit_recovers_normals_where_the_biquadratic_model_holds() {
    // The PTM of a diffuse sphere as a fitter makes it: per pixel, the least-squares
    // biquadratic through max(0, n·l) under 317 lights of elevation ≥ 53° (|l_uv| ≤ 0.6),
    // quantised to 8 bits with scale and bias.
    let s = Sphere::new();
    let ls = lights(0.6);
    let fit_px = |i: usize, albedo: f64| -> Coefficients {
        let (x, row) = (i % s.w, i / s.w);
        match s.normal(x, row) {
            Some(n) => fit(&ls, |l| {
                255.0 * albedo * (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]).max(0.0)
            }),
            None => [0.0; 6],
        }
    };
    let d = tempfile::tempdir().unwrap();
    let lum: Vec<Coefficients> = (0..s.w * s.h).map(|i| fit_px(i, 0.9)).collect();
    let p = d.path().join("lambert_lrgb.ptm");
    write_ptm(
        &p,
        s.w,
        s.h,
        &PtmData::Lrgb {
            lum,
            rgb: lrgb_rgb(&s),
        },
    )
    .unwrap();
    let lrgb = read_ptm(&p).unwrap();
    let channels: [Vec<Coefficients>; 3] =
        std::array::from_fn(|c| (0..s.w * s.h).map(|i| fit_px(i, ALBEDO[c])).collect());
    let p = d.path().join("lambert_rgb.ptm");
    write_ptm(&p, s.w, s.h, &PtmData::Rgb { channels }).unwrap();
    let rgb = read_ptm(&p).unwrap();
    for (name, ptm) in [("LRGB", &lrgb), ("RGB", &rgb)] {
        // The biquadratic's maximum of a fitted cosine lobe is only near the true normal
        // for moderate tilts (a biquadratic only approximates a cosine lobe); with these lights
        // the model error is ≤ 1.5° up to 30° of tilt and grows beyond (≈ 4° at 35°,
        // ≈ 9° at 40°); steeper pixels get no interior maximum and are masked.
        let (mean, max, count) = errors(&ptm.image, &s, |n| n[2] >= 30f64.to_radians().cos());
        eprintln!("Lambertian {name}, tilt ≤ 30°: mean {mean:.3}°, max {max:.3}° over {count} px");
        assert!(count > 250, "{count}");
        assert!(mean < 2.0 && max < 2.0, "{name}: mean {mean}°, max {max}°");
        let (mean, max, count) = errors(&ptm.image, &s, |_| true);
        eprintln!(
            "Lambertian {name}, every unmasked sphere pixel: mean {mean:.2}°, max {max:.2}° over {count} px; {} px masked in the image",
            ptm.no_maximum
        );
        // Masked pixels are exactly those without an interior maximum; none at the centre.
        let mask = ptm.image.mask().unwrap();
        assert_eq!(mask[20 * s.w + 30], 1.0);
        assert_eq!(mask.iter().filter(|&&m| m == 0.0).count(), ptm.no_maximum);
    }
}

#[test]
fn hand_written_bytes_pin_the_layout_row_order_and_formula() {
    // A 1×2 LRGB PTM_1.2 written byte by byte: the FIRST stored pixel is the BOTTOM row.
    // Bottom pixel: L = −u² − v² + 0.5·u + 5 → maximum at (0.25, 0); top pixel: maximum at
    // (0, −0.5) (v down). scale 0.5 for all, bias 100: a = (c − 100)·0.5.
    let enc = |a: f64| (a / 0.5 + 100.0) as u8;
    let mut f =
        b"PTM_1.2\r\nPTM_FORMAT_LRGB\n1 2\n0.5 0.5 0.5 0.5 0.5 0.5\n100 100 100 100 100 100\n"
            .to_vec();
    f.extend([-1.0, -1.0, 0.0, 0.5, 0.0, 5.0].map(enc)); // bottom (row 1)
    f.extend([-1.0, -1.0, 0.0, 0.0, -1.0, 5.0].map(enc)); // top (row 0)
    f.extend([10, 20, 30, 40, 50, 60]); // RGB: bottom, then top
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("hand.ptm");
    std::fs::write(&p, &f).unwrap();
    let img = read_ptm(&p).unwrap().image;
    let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6);
    let z = |u: f32, v: f32| (1.0 - u * u - v * v).sqrt();
    assert!(
        close(img.normal_at(0, 1), [0.25, 0.0, z(0.25, 0.0)]),
        "{:?}",
        img.normal_at(0, 1)
    );
    assert!(
        close(img.normal_at(0, 0), [0.0, -0.5, z(0.0, 0.5)]),
        "{:?}",
        img.normal_at(0, 0)
    );
    let lin = srgb8_to_linear();
    assert_eq!(img.color_at(0, 1), [lin[10], lin[20], lin[30]]);
    assert_eq!(img.color_at(0, 0), [lin[40], lin[50], lin[60]]);

    // The same as PTM_1.1 (coefficients and colour interleaved per pixel).
    let mut f =
        b"PTM_1.1\nPTM_FORMAT_LRGB\n1\n2\n0.5 0.5 0.5 0.5 0.5 0.5\n100 100 100 100 100 100\n"
            .to_vec();
    f.extend([-1.0, -1.0, 0.0, 0.5, 0.0, 5.0].map(enc));
    f.extend([10, 20, 30]);
    f.extend([-1.0, -1.0, 0.0, 0.0, -1.0, 5.0].map(enc));
    f.extend([40, 50, 60]);
    std::fs::write(&p, &f).unwrap();
    let img = read_ptm(&p).unwrap().image;
    assert!(close(img.normal_at(0, 1), [0.25, 0.0, z(0.25, 0.0)]));
    assert_eq!(img.color_at(0, 0), [lin[40], lin[50], lin[60]]);
}

#[test]
fn maximum_rules() {
    // Convex, saddle, flat: no maximum.
    assert_eq!(biquadratic_maximum(&[1.0, 1.0, 0.0, 0.0, 0.0, 0.0]), None);
    assert_eq!(biquadratic_maximum(&[-1.0, 1.0, 0.0, 0.0, 0.0, 0.0]), None);
    assert_eq!(biquadratic_maximum(&[0.0; 6]), None);
    // Concave but the maximum (1.5, 0) is outside the unit disk.
    assert_eq!(biquadratic_maximum(&[-1.0, -1.0, 0.0, 3.0, 0.0, 0.0]), None);
    // With a uv term: −u² − v² + uv + u → ∂u: −2u + v + 1 = 0, ∂v: −2v + u = 0 → (2/3, 1/3).
    let (u, v) = biquadratic_maximum(&[-1.0, -1.0, 1.0, 1.0, 0.0, 0.0]).unwrap();
    assert!((u - 2.0 / 3.0).abs() < 1e-12 && (v - 1.0 / 3.0).abs() < 1e-12);
    let n = normal_from_coefficients(&[-1.0, -1.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
    assert_eq!(n, [0.0, 0.0, 1.0]);
}

fn header(version: &str, format: &str, dims: &str) -> Vec<u8> {
    format!("{version}\n{format}\n{dims}\n1 1 1 1 1 1\n0 0 0 0 0 0\n").into_bytes()
}

fn err_of(bytes: &[u8]) -> String {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("bad.ptm");
    std::fs::write(&p, bytes).unwrap();
    let e = read_ptm(&p).unwrap_err();
    let s = e.to_string();
    assert!(!s.contains('\n'), "one line: {s}");
    assert!(s.ends_with("bad.ptm"), "names the file: {s}");
    s
}

#[test]
fn bad_headers_are_one_line_errors_never_panics() {
    let mut trunc = header("PTM_1.2", "PTM_FORMAT_LRGB", "4\n4");
    trunc.extend([0u8; 4 * 4 * 9 - 1]);
    let e = err_of(&trunc);
    assert!(
        e.contains("truncated PTM_FORMAT_LRGB PTM") && e.contains("144") && e.contains("143"),
        "{e}"
    );
    let mut trunc = header("PTM_1.2", "PTM_FORMAT_RGB", "4\n4");
    trunc.extend([0u8; 100]);
    assert!(err_of(&trunc).contains("truncated PTM_FORMAT_RGB"));
    let e = err_of(b"PTM_1.2\nPTM_FORMAT_LRGB\n4\n4\n1 1 1");
    assert!(e.contains("truncated"), "{e}");
    let e = err_of(&header("PTM_1.2", "PTM_FORMAT_JPEG_LRGB", "4\n4"));
    assert!(e.contains("compressed PTM PTM_FORMAT_JPEG_LRGB"), "{e}");
    let e = err_of(&header("PTM_1.2", "PTM_FORMAT_JPEGLS_RGB", "4\n4"));
    assert!(e.contains("PTM_FORMAT_JPEGLS_RGB"), "{e}");
    let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LUM", "4\n4"));
    assert!(e.contains("PTM_FORMAT_LUM is not supported"), "{e}");
    let e = err_of(b"#HSH1.2\n3\n4 4 2\n1 2 3\n");
    assert!(e.contains("HSH"), "{e}");
    let e = err_of(b"P6\n4 4\n255\n");
    assert!(e.contains("not a PTM file"), "{e}");
    let e = err_of(&header("PTM_2.0", "PTM_FORMAT_LRGB", "4\n4"));
    assert!(e.contains("unsupported PTM version"), "{e}");
    let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LRGB", "-4\n4"));
    assert!(e.contains("width \"-4\" is negative"), "{e}");
    let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LRGB", "4\nfour"));
    assert!(e.contains("height \"four\" is not a whole number"), "{e}");
    let e = err_of(&header("PTM_1.2", "PTM_FORMAT_LRGB", "0\n4"));
    assert!(e.contains("no pixels"), "{e}");
    let e = err_of(&header(
        "PTM_1.2",
        "PTM_FORMAT_LRGB",
        "99999999999999999999\n4",
    ));
    assert!(e.contains("width"), "{e}");
    // Huge sizes are refused by the pixel limit before anything is allocated.
    let e = err_of(&header(
        "PTM_1.2",
        "PTM_FORMAT_RGB",
        "4000000000\n4000000000",
    ));
    assert!(e.contains("too large"), "{e}");
    let e = err_of(b"PTM_1.2\nPTM_FORMAT_RGB\n4\n4\n1 1 nan 1 1 1\n0 0 0 0 0 0\n");
    assert!(e.contains("scale 2"), "{e}");
    let e = err_of(b"PTM_1.2\nPTM_FORMAT_RGB\n4\n4\n1 1 1 1 1 1\n0 0 0 0 0 1.5\n");
    assert!(e.contains("bias 5"), "{e}");
    let e = err_of(b"PTM_1.2\nPTM_FORMAT_RGB\n4\n4\n1 1 1 1 1 1 1\n0 0 0 0 0 0\n");
    assert!(e.contains("15 values"), "{e}");
    let e = err_of(&[b'P'; 10_000]);
    assert!(e.contains("longer than"), "{e}");
    let e = err_of(b"");
    assert!(e.contains("truncated"), "{e}");
    // Every truncation of a valid file is an error (never a panic); the whole file reads.
    let mut full = header("PTM_1.2", "PTM_FORMAT_LRGB", "2\n2");
    full.extend([7u8; 36]);
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("cut.ptm");
    for cut in 0..full.len() {
        std::fs::write(&p, &full[..cut]).unwrap();
        assert!(read_ptm(&p).is_err(), "cut at {cut}");
    }
    std::fs::write(&p, &full).unwrap();
    assert_eq!(
        read_ptm(&p).unwrap().no_maximum,
        4,
        "constant polynomials: no maximum"
    );
}

#[test]
fn rgbn_written_as_ptm_reads_back_within_half_a_degree_and_one_level() {
    // A sphere (exact normals, mask outside) with a colour ramp, written as an LRGB PTM and
    // read back by the PTM reader.
    let (mut img, _) = crate::raster::sample::Surface::Sphere { radius_px: 20.0 }.render(56, 44);
    let (w, h) = (img.width(), img.height());
    let color: [Vec<f32>; 3] = std::array::from_fn(|c| {
        (0..w * h)
            .map(|i| match c {
                0 => (i % w) as f32 / w as f32,
                1 => (i / w) as f32 / h as f32,
                _ => 0.25,
            })
            .collect()
    });
    img.set_color(color).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.ptm");
    crate::raster::io::save(&img, &path, &crate::raster::io::SaveOptions::default()).unwrap();
    let back = read_ptm(&path).unwrap();
    assert_eq!(back.format, PtmFormat::Lrgb);
    let (mut sum, mut max, mut max_steep, mut count) = (0.0, 0.0f64, 0.0f64, 0usize);
    let (m0, m1) = (img.mask().unwrap(), back.image.mask().unwrap());
    for i in 0..w * h {
        let n = img.normal_at(i % w, i / w);
        if m0[i] < 0.5 {
            assert_eq!(m1[i], 0.0, "outside the mask: no maximum, masked out");
            continue;
        }
        let e = angle_deg(back.image.normal_at(i % w, i / w), n.map(f64::from));
        if n[2] >= 0.2 {
            max = max.max(e);
            sum += e;
            count += 1;
        } else if m1[i] > 0.5 {
            max_steep = max_steep.max(e);
        }
        for c in 0..3 {
            let (a, b) = (
                crate::raster::srgb::linear_to_srgb8(img.color()[c][i]),
                crate::raster::srgb::linear_to_srgb8(back.image.color()[c][i]),
            );
            assert!(a.abs_diff(b) <= 1, "colour {a} vs {b} at {i}");
        }
    }
    eprintln!(
        "RGBN → PTM → RGBN: mean {:.3}°, max {max:.3}° over {count} px with n_z ≥ 0.2; max {max_steep:.2}° at grazing n_z < 0.2",
        sum / count as f64
    );
    assert!(max <= 0.5, "max {max}°");
}
