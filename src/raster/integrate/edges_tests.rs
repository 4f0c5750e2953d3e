//! Tests of `raster/integrate/edges.rs`.

use super::*;

/// Deterministic uniform numbers in [0, 1).
fn lcg(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Weights log-uniform in [lo, 1] on every edge inside the grid.
fn weights(w: usize, h: usize, lo: f64, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let mut r = lcg(seed);
    let mut wt = |ok: bool| {
        let v = lo.powf(r()) as f32;
        if ok {
            v
        } else {
            0.0
        }
    };
    let n = w * h;
    let wx = (0..n).map(|i| wt(i % w + 1 < w)).collect();
    let wy = (0..n).map(|i| wt(i + w < n)).collect();
    (wx, wy)
}

fn analytic(w: usize, h: usize) -> Vec<f64> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (0.3 * x).sin() * 2.0 + 0.05 * x * y - (0.2 * y).cos()
        })
        .collect()
}

/// Exact targets `z[j] − z[i]` of a height.
fn targets(z: &[f64], w: usize) -> (Vec<f32>, Vec<f32>) {
    let n = z.len();
    let ex = (0..n)
        .map(|i| {
            if i % w + 1 < w {
                (z[i + 1] - z[i]) as f32
            } else {
                0.0
            }
        })
        .collect();
    let ey = (0..n)
        .map(|i| {
            if i + w < n {
                (z[i + w] - z[i]) as f32
            } else {
                0.0
            }
        })
        .collect();
    (ex, ey)
}

fn max_err_up_to_constant(got: &[f32], want: &[f64], sel: impl Fn(usize) -> bool) -> f64 {
    let idx: Vec<usize> = (0..got.len()).filter(|&i| sel(i)).collect();
    let off = idx
        .iter()
        .map(|&i| f64::from(got[i]) - want[i])
        .sum::<f64>()
        / idx.len() as f64;
    idx.iter()
        .map(|&i| (f64::from(got[i]) - want[i] - off).abs())
        .fold(0.0, f64::max)
}

#[test]
fn exact_targets_with_random_weights_recover_the_height() {
    let (w, h) = (70, 50);
    let z = analytic(w, h);
    let (ex, ey) = targets(&z, w);
    let (wx, wy) = weights(w, h, 1e-4, 1);
    let sys = EdgeSystem {
        w,
        h,
        wx: &wx,
        ex: &ex,
        wy: &wy,
        ey: &ey,
    };
    let s = solve_edges(&sys, None, 1e-9, 500).unwrap();
    eprintln!(
        "exact targets: {} iterations, {:.2e}",
        s.iterations, s.relative_residual
    );
    let e = max_err_up_to_constant(&s.z, &z, |_| true);
    assert!(e < 1e-5, "max error {e}");
    let mean = s.z.iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64;
    assert!(mean.abs() < 1e-5, "mean {mean}");
}

#[test]
fn a_zero_column_splits_the_grid_into_two_components_keeping_z0_means() {
    let (w, h) = (30, 20);
    let z = analytic(w, h);
    let (ex, ey) = targets(&z, w);
    let (mut wx, mut wy) = weights(w, h, 1e-2, 2);
    for r in 0..h {
        wx[r * w + 11] = 0.0;
    }
    // An isolated pixel inside the right part: no edge, height 0.
    let iso = 5 * w + 20;
    wx[iso] = 0.0;
    wx[iso - 1] = 0.0;
    wy[iso] = 0.0;
    wy[iso - w] = 0.0;
    let z0: Vec<f32> = (0..w * h)
        .map(|i| {
            if i % w <= 11 {
                7.0
            } else {
                -3.0 + (i % 7) as f32
            }
        })
        .collect();
    let sys = EdgeSystem {
        w,
        h,
        wx: &wx,
        ex: &ex,
        wy: &wy,
        ey: &ey,
    };
    let s = solve_edges(&sys, Some(&z0), 1e-9, 500).unwrap();
    assert_eq!(s.z[iso], 0.0);
    for part in [|x: usize| x <= 11, |x: usize| x > 11] {
        let sel = |i: usize| part(i % w) && i != iso;
        let e = max_err_up_to_constant(&s.z, &z, sel);
        assert!(e < 1e-5, "max error {e}");
        let idx: Vec<usize> = (0..w * h).filter(|&i| sel(i)).collect();
        let mean =
            |v: &dyn Fn(usize) -> f64| idx.iter().map(|&i| v(i)).sum::<f64>() / idx.len() as f64;
        let (got, want) = (mean(&|i| f64::from(s.z[i])), mean(&|i| f64::from(z0[i])));
        assert!(
            (got - want).abs() < 1e-5,
            "component mean {got}, z0's {want}"
        );
    }
}

#[test]
fn matches_a_dense_normal_equations_solve() {
    let (w, h) = (12, 9);
    let n = w * h;
    for (seed, lo) in [(3, 1e-1), (4, 1e-4)] {
        let (wx, wy) = weights(w, h, lo, seed);
        let mut r = lcg(seed + 100);
        let ex: Vec<f32> = (0..n).map(|_| (2.0 * r() - 1.0) as f32).collect();
        let ey: Vec<f32> = (0..n).map(|_| (2.0 * r() - 1.0) as f32).collect();
        // Dense (A + 11ᵀ/n) z = b: the zero-mean least-squares solution.
        let mut a = vec![vec![1.0 / n as f64; n + 1]; n];
        for row in a.iter_mut() {
            row[n] = 0.0;
        }
        let mut edge = |i: usize, j: usize, wt: f32, e: f32| {
            let (wt, e) = (f64::from(wt), f64::from(e));
            a[i][i] += wt;
            a[j][j] += wt;
            a[i][j] -= wt;
            a[j][i] -= wt;
            a[j][n] += wt * e;
            a[i][n] -= wt * e;
        };
        for i in 0..n {
            if i % w + 1 < w {
                edge(i, i + 1, wx[i], ex[i]);
            }
            if i + w < n {
                edge(i, i + w, wy[i], ey[i]);
            }
        }
        for c in 0..n {
            let p = (c..n)
                .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
                .unwrap();
            a.swap(c, p);
            let (top, rest) = a.split_at_mut(c + 1);
            let pivot = &top[c];
            for row in rest {
                let f = row[c] / pivot[c];
                for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                    *x -= f * p;
                }
            }
        }
        let mut want = vec![0.0f64; n];
        for c in (0..n).rev() {
            let s: f64 = (c + 1..n).map(|k| a[c][k] * want[k]).sum();
            want[c] = (a[c][n] - s) / a[c][c];
        }
        let sys = EdgeSystem {
            w,
            h,
            wx: &wx,
            ex: &ex,
            wy: &wy,
            ey: &ey,
        };
        let s = solve_edges(&sys, None, 1e-10, 500).unwrap();
        let err =
            s.z.iter()
                .zip(&want)
                .map(|(&g, w)| (f64::from(g) - w).abs())
                .fold(0.0, f64::max);
        eprintln!(
            "dense check (weights {lo}..1): {} iterations, max error {err:.2e}",
            s.iterations
        );
        assert!(err < 1e-4, "max error {err}");
    }
}

#[test]
fn the_preconditioner_stays_good_for_weights_spanning_four_decades() {
    // Smooth weights with sharp steps (as bilateral integration makes them): 1 in most of
    // the grid, 1e-4 across two curves, a log-ramp region; exact targets.
    let (w, h) = (256, 192);
    let n = w * h;
    let z = analytic(w, h);
    let (ex, ey) = targets(&z, w);
    let wt = |x: usize, y: usize| -> f32 {
        let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
        let d1 = ((u - 0.4).powi(2) + (v - 0.5).powi(2)).sqrt() - 0.25;
        if d1.abs() < 0.006 || (u - 0.8).abs() < 0.004 {
            1e-4
        } else {
            10f32.powf(-4.0 * u * v)
        }
    };
    let wx: Vec<f32> = (0..n)
        .map(|i| if i % w + 1 < w { wt(i % w, i / w) } else { 0.0 })
        .collect();
    let wy: Vec<f32> = (0..n)
        .map(|i| if i + w < n { wt(i % w, i / w) } else { 0.0 })
        .collect();
    let sys = EdgeSystem {
        w,
        h,
        wx: &wx,
        ex: &ex,
        wy: &wy,
        ey: &ey,
    };
    let (s, restarted) = solve_edges_guarded(&sys, None, 1e-6, 500).unwrap();
    eprintln!(
        "four decades: {} iterations, {:.2e}",
        s.iterations, s.relative_residual
    );
    assert!(!restarted);
    assert!(s.relative_residual <= 1e-6);
    assert!(s.iterations <= 60, "{} iterations", s.iterations);
    assert!(max_err_up_to_constant(&s.z, &z, |_| true) < 1e-3);
}

#[test]
fn bad_input_is_an_error_naming_it() {
    let (w, h) = (4, 3);
    let ok = vec![1.0f32; 12];
    let mut neg = ok.clone();
    neg[5] = -1.0;
    let e = solve_edges(
        &EdgeSystem {
            w,
            h,
            wx: &neg,
            ex: &ok,
            wy: &ok,
            ey: &ok,
        },
        None,
        1e-6,
        10,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("wx") && e.contains("(1, 1)"), "{e}");
    let e = solve_edges(
        &EdgeSystem {
            w,
            h,
            wx: &ok[..11],
            ex: &ok,
            wy: &ok,
            ey: &ok,
        },
        None,
        1e-6,
        10,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("wx has 11 values"), "{e}");
}

#[test]
fn multigrid_cg_itself_converges_on_the_mask_where_it_diverged() {
    // 1920 × 2160, the half-frame wobbly ellipse: the old V-cycle (Gauss–Seidel on the
    // singular coarsest level) made CG fall to 3e-5, then diverge; now MG-PCG must reach
    // 1e-6 with no Jacobi restart, in few iterations.
    let (w, h) = (1920, 2160);
    let n = w * h;
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let k = (2.0 / std::f64::consts::PI).sqrt();
    let m: Vec<bool> = (0..n)
        .map(|i| {
            let (u, v) = (((i % w) as f64 - cx) / cx, ((i / w) as f64 - cy) / cy);
            u.hypot(v) < k * (1.0 + 0.08 * (5.0 * v.atan2(u)).sin())
        })
        .collect();
    let wx: Vec<f32> = (0..n)
        .map(|i| f32::from(u8::from(i % w + 1 < w && m[i] && m[i + 1])))
        .collect();
    let wy: Vec<f32> = (0..n)
        .map(|i| f32::from(u8::from(i + w < n && m[i] && m[i + w])))
        .collect();
    // Rough targets (not a gradient: a least-squares problem), f32 as from normals.
    let mut r = lcg(9);
    let ex: Vec<f32> = (0..n)
        .map(|i| ((i % w) as f32 * 0.01).sin() + 0.1 * r() as f32)
        .collect();
    let ey: Vec<f32> = (0..n)
        .map(|i| ((i / w) as f32 * 0.013).cos() + 0.1 * r() as f32)
        .collect();
    let sys = EdgeSystem {
        w,
        h,
        wx: &wx,
        ex: &ex,
        wy: &wy,
        ey: &ey,
    };
    let (s, restarted) = solve_edges_guarded(&sys, None, 1e-6, 100).unwrap();
    eprintln!(
        "1920×2160 MG-PCG: {} iterations, {:.2e}",
        s.iterations, s.relative_residual
    );
    assert!(!restarted, "the Jacobi guard fired");
    assert!(s.relative_residual <= 1e-6);
    assert!(s.iterations <= 15, "{} iterations", s.iterations);
}

#[test]
fn the_jacobi_restart_recovers_when_the_preconditioner_is_indefinite() {
    // The multigrid preconditioner is symmetric positive semi-definite, and no system found
    // makes it misbehave (above). The guard exists for one that does: CG started on an
    // indefinite preconditioner (Jacobi with checkerboard signs) breaks down or runs away; the
    // guard must restart with Jacobi from where CG got to and reach the tolerance, with the
    // solution the multigrid solve finds.
    let (w, h) = (48, 36);
    let n = w * h;
    let (wx, wy) = weights(w, h, 1e-2, 11);
    let mut r = lcg(5);
    let ex: Vec<f32> = (0..n)
        .map(|i| ((i % w) as f32 * 0.2).sin() + 0.3 * r() as f32)
        .collect();
    let ey: Vec<f32> = (0..n)
        .map(|i| ((i / w) as f32 * 0.15).cos() + 0.3 * r() as f32)
        .collect();
    let (bad, restarted) = solve_edges_from(
        w,
        h,
        wx.clone(),
        &ex,
        wy.clone(),
        &ey,
        None,
        (1e-10, 20_000),
        Preconditioner::Indefinite,
    )
    .unwrap();
    assert!(restarted, "the guard did not fire: {bad:?}");
    assert!(bad.relative_residual <= 1e-10, "{bad:?}");
    let (good, restarted) = solve_edges_owned(w, h, wx, &ex, wy, &ey, None, 1e-10, 500).unwrap();
    assert!(!restarted);
    // Both solutions have mean 0 on the one component: equal up to the tolerance's error.
    let scale = good.z.iter().fold(0f32, |m, v| m.max(v.abs()));
    let diff = bad
        .z
        .iter()
        .zip(&good.z)
        .fold(0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        diff <= 1e-4 * scale,
        "max difference {diff} (scale {scale})"
    );
}
