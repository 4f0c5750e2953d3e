//! Tests of `raster/convolve.rs`.

use super::*;

/// Exact convolution of a line with the sampled normalised Gaussian under `border`.
fn exact_line(x: &[f32], sigma: f32, border: BorderMode) -> Vec<f32> {
    let r = (6.0 * sigma).ceil() as isize;
    let w: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * f64::from(sigma).powi(2))).exp())
        .collect();
    let sum: f64 = w.iter().sum();
    (0..x.len() as isize)
        .map(|n| {
            let mut acc = 0.0f64;
            for (k, wk) in w.iter().enumerate() {
                if let Some(j) = border.map(n + k as isize - r, x.len()) {
                    acc += wk * f64::from(x[j]);
                }
            }
            (acc / sum) as f32
        })
        .collect()
}

fn run_line<F: LineFilter>(f: &F, x: &[f32], border: BorderMode) -> Vec<f32> {
    let mut line: Vec<Lane> = x.iter().map(|&v| lane_splat(v)).collect();
    f.run(&mut line, &mut Vec::new(), border);
    line.iter().map(|l| l[0]).collect()
}

fn impulse_error(sigma: f32) -> f32 {
    let n = (28.0 * sigma) as usize + 1;
    let mut x = buf::zeroed_f32(n);
    x[n / 2] = 1.0;
    let got = run_line(&Deriche::new(sigma), &x, BorderMode::Zero);
    let want = exact_line(&x, sigma, BorderMode::Zero);
    let peak = want[n / 2];
    got.iter()
        .zip(&want)
        .map(|(g, w)| (g - w).abs() / peak)
        .fold(0.0, f32::max)
}

#[test]
fn deriche_tail_beyond_support() {
    // An impulse farther than the support from a pixel changes it by less than 0.05 % of
    // the peak: what region evaluation's crops rely on.
    for sigma in [3.0f32, 5.0, 8.0, 32.0, 100.0] {
        let n = (28.0 * sigma) as usize + 1;
        let mut x = buf::zeroed_f32(n);
        x[n / 2] = 1.0;
        let got = run_line(&Deriche::new(sigma), &x, BorderMode::Zero);
        let peak = got[n / 2];
        let s = gaussian_support(sigma);
        let tail = got
            .iter()
            .enumerate()
            .filter(|(i, _)| i.abs_diff(n / 2) >= s)
            .map(|(_, v)| v.abs() / peak)
            .fold(0.0, f32::max);
        // Its mass bounds the error on any signal: |Δ| ≤ mass · max |x − x_invented|.
        let mass: f32 = got
            .iter()
            .enumerate()
            .filter(|(i, _)| i.abs_diff(n / 2) >= s)
            .map(|(_, v)| v.abs())
            .sum();
        eprintln!("deriche σ={sigma}: support {s}, tail {tail:.2e}, mass {mass:.2e}");
        assert!(tail < 5e-4, "σ={sigma}: {tail}");
        assert!(mass < 3.5e-4, "σ={sigma}: {mass}");
    }
}

#[test]
fn deriche_accuracy_table() {
    // The documented bounds (module docs): impulse response error relative to the peak.
    for (sigma, bound) in [(3.0, 6e-4), (8.0, 6e-4), (32.0, 6e-4), (100.0, 6e-4)] {
        let e = impulse_error(sigma);
        eprintln!("deriche σ={sigma}: max |error| / peak = {e:.5}");
        assert!(e < bound, "σ={sigma}: {e}");
    }
}

#[test]
fn deriche_on_smooth_signal_matches_exact_convolution() {
    for border in BorderMode::ALL {
        for sigma in [3.0f32, 8.0, 32.0] {
            let n = 600;
            let x: Vec<f32> = (0..n)
                .map(|i| {
                    let t = i as f32 / n as f32;
                    (t * 17.0).sin() + 0.5 * (t * 5.0).cos() + 0.3
                })
                .collect();
            let got = run_line(&Deriche::new(sigma), &x, border);
            let want = exact_line(&x, sigma, border);
            let num: f32 = got.iter().zip(&want).map(|(a, b)| (a - b).powi(2)).sum();
            let den: f32 = want.iter().map(|b| b * b).sum();
            let rel = (num / den).sqrt();
            assert!(rel < 1e-3, "{border:?} σ={sigma}: rel rms {rel}");
        }
    }
}

#[test]
fn fir_gaussian_matches_exact_and_keeps_constants() {
    let x: Vec<f32> = (0..50).map(|i| ((i * 37) % 11) as f32).collect();
    for border in BorderMode::ALL {
        let got = run_line(&Fir::gaussian(1.5), &x, border);
        let want = exact_line(&x, 1.5, border);
        for (a, b) in got.iter().zip(&want) {
            assert!((a - b).abs() < 1e-4, "{border:?}: {a} vs {b}");
        }
    }
    let c = vec![2.5f32; 40];
    for f in [Deriche::new(5.0)] {
        for border in [BorderMode::Mirror, BorderMode::Clamp, BorderMode::Wrap] {
            let got = run_line(&f, &c, border);
            assert!(
                got.iter().all(|v| (v - 2.5).abs() < 1e-4),
                "{border:?} {got:?}"
            );
        }
    }
}

#[test]
fn box_filter_is_the_running_mean() {
    let x: Vec<f32> = (0..30).map(|i| (i * i % 7) as f32).collect();
    let got = run_line(&BoxFilter { radius: 2 }, &x, BorderMode::Clamp);
    for n in 0..x.len() {
        let mut s = 0.0;
        for k in -2..=2isize {
            s += x[BorderMode::Clamp.map(n as isize + k, x.len()).unwrap()];
        }
        assert!((got[n] - s / 5.0).abs() < 1e-5);
    }
}

#[test]
fn band_transposes_match_their_definition() {
    // Widths around the 8-column blocks, full and partial bands; lanes beyond the band's
    // rows are zero; the way back restores the band exactly.
    for width in [1, 7, 8, 9, 16, 23, 40] {
        for rows in [1, 5, LANES] {
            let band: Vec<f32> = (0..rows * width).map(|i| i as f32 * 0.5 - 3.0).collect();
            let mut lanes = vec![lane_splat(9.0); 3];
            rows_to_lanes(&band, width, &mut lanes);
            assert_eq!(lanes.len(), width);
            for (x, lane) in lanes.iter().enumerate() {
                for (k, &v) in lane.iter().enumerate() {
                    let want = if k < rows { band[k * width + x] } else { 0.0 };
                    assert_eq!(v, want, "{width}×{rows} lane {x} row {k}");
                }
            }
            let mut back = vec![f32::NAN; rows * width];
            lanes_to_rows(&lanes, width, &mut back);
            assert_eq!(back, band, "{width}×{rows}");
        }
    }
}

#[test]
fn rows_and_columns_agree_with_a_transposed_run() {
    // A non-square, non-multiple-of-LANES image: filtering columns equals filtering the
    // rows of the transpose.
    let (w, h) = (37, 21);
    let img: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 101) as f32).collect();
    let mut cols = img.clone();
    filter_columns(&mut cols, w, h, &Deriche::new(4.0), BorderMode::Mirror);
    let mut t: Vec<f32> = (0..w * h).map(|i| img[(i % h) * w + i / h]).collect();
    filter_rows(&mut t, h, w, &Deriche::new(4.0), BorderMode::Mirror);
    for r in 0..h {
        for x in 0..w {
            assert!((cols[r * w + x] - t[x * h + r]).abs() < 1e-4);
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[test]
fn avx2_and_avx512_paths_are_bit_identical() {
    if !(std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma"))
    {
        return;
    }
    let x: Vec<f32> = (0..300)
        .map(|i| ((i * 7919) % 101) as f32 * 0.1 - 3.0)
        .collect();
    for border in BorderMode::ALL {
        for sigma in [3.0f32, 8.0, 32.0] {
            let d = Deriche::new(sigma);
            let mut a: Vec<Lane> = x.iter().map(|&v| lane_splat(v)).collect();
            let mut b = a.clone();
            // SAFETY: AVX2 and FMA presence checked above.
            unsafe { d.run_avx2(&mut a, &mut Vec::new(), border) };
            d.run_portable(&mut b, &mut Vec::new(), border);
            let same = |a: &[Lane], b: &[Lane]| {
                a.iter()
                    .flatten()
                    .zip(b.iter().flatten())
                    .all(|(p, q)| p.to_bits() == q.to_bits())
            };
            assert!(same(&a, &b));
            if std::arch::is_x86_feature_detected!("avx512f") {
                let mut c: Vec<Lane> = x.iter().map(|&v| lane_splat(v)).collect();
                // SAFETY: AVX-512F presence just checked.
                unsafe { d.run_avx512(&mut c, &mut Vec::new(), border) };
                assert!(same(&c, &b));
            }
        }
    }
}

#[test]
fn border_map() {
    let m = BorderMode::Mirror;
    assert_eq!(
        (m.map(-1, 4), m.map(-2, 4), m.map(4, 4), m.map(5, 4)),
        (Some(0), Some(1), Some(3), Some(2))
    );
    assert_eq!(BorderMode::Wrap.map(-1, 4), Some(3));
    assert_eq!(BorderMode::Clamp.map(9, 4), Some(3));
    assert_eq!(BorderMode::Zero.map(-1, 4), None);
    assert_eq!(m.map(-9, 4), Some(0)); // reflections repeat with period 2n
}
