//! Photometric-stereo accuracy and time on the DiLiGenT ball (the table of docs/capture.md):
//! every estimator on 6 to 13 of the 13 photos of `$RGBN_DATA/diligent-ball-subset`.
//!
//! ```text
//! cargo run --release --no-default-features --example diligent_ps -- [DIR] [--repeat 5]
//!     [--methods ls,trimmed,l1,sbl] [--sizes 6-13] [--all-subsets]
//!     [--shadow-level F] [--robust-min-shading F] [--lambda F] [--iters N] [--delta F]
//!     [--exponent auto|K]
//! ```
//!
//! **Rows.** `woodham` is least squares with the Lambertian exponent `k = 1` (Woodham 1980,
//! the benchmark's L2); every other row runs its estimator with `--exponent` (default `auto`:
//! `k` estimated from the photos, printed in the `k` column).
//!
//! **Subsets.** The `k`-photo subset is the first `k` of a farthest-point order of the 13
//! lights: the most frontal light first, then repeatedly the light whose smallest angle to the
//! lights already taken is largest (ties: the lower file number). Every size is then a
//! well-spread subset of the next. `--all-subsets` also prints, per size, the mean and the worst
//! of the mean angular error over every `C(13, k)` subset (accuracy only).
//!
//! **Error.** The angle between the estimated and the ground-truth normal (`Normal_gt.mat`) at
//! every pixel of `mask.png`: mean, median and 90th percentile (a pixel the estimator leaves
//! unsolved counts with its fallback normal `(0, 0, 1)`).
//!
//! **Time.** The wall time of `photometric_stereo` alone (the photos already in memory), on
//! the machine's threads, per megapixel of the whole image (612 × 512 = 0.313 MP; the
//! estimators skip the pixels outside the mask alike); the median of `--repeat` runs, the
//! estimators alternated run by run, so every ratio is a same-minutes ratio.
//!
//! The data is not ours: nothing of it is in the repository.

use rgbn::capture::inputs::{load_inputs, Lights, PhotoStack, PsInputSpec, Transfer};
use rgbn::capture::linalg::angle_deg;
use rgbn::capture::photometric::{photometric_stereo, PhotometricParams, PsMethod};
use rgbn::params::Choice;
#[path = "../src/capture/diligent_mat.rs"]
mod diligent_mat;
use diligent_mat::read_mat_normals;
use std::path::PathBuf;
use std::time::Instant;

const NAMES: [&str; 13] = [
    "001", "008", "019", "023", "041", "045", "048", "052", "068", "071", "089", "093", "096",
];

/// Farthest-point order of the light directions (module docs).
fn farthest_point_order(dirs: &[[f32; 3]]) -> Vec<usize> {
    let first = (0..dirs.len())
        .max_by(|&a, &b| dirs[a][2].total_cmp(&dirs[b][2]).then(b.cmp(&a)))
        .unwrap();
    let mut order = vec![first];
    while order.len() < dirs.len() {
        let next = (0..dirs.len())
            .filter(|j| !order.contains(j))
            .map(|j| {
                let d = order
                    .iter()
                    .map(|&o| angle_deg(dirs[j], dirs[o]))
                    .fold(f64::MAX, f64::min);
                (j, d)
            })
            .fold(None, |best: Option<(usize, f64)>, (j, d)| match best {
                Some((_, bd)) if bd >= d => best,
                _ => Some((j, d)),
            })
            .unwrap()
            .0;
        order.push(next);
    }
    order
}

struct Stats {
    mean: f64,
    median: f64,
    p90: f64,
}

fn errors(n: &rgbn::RgbnImage, gt: &[Vec<f32>; 3], inside: &[usize]) -> Stats {
    let mut e: Vec<f64> = inside
        .iter()
        .map(|&i| {
            angle_deg(
                [n.normal()[0][i], n.normal()[1][i], n.normal()[2][i]],
                [gt[0][i], gt[1][i], gt[2][i]],
            )
        })
        .collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    e.sort_by(f64::total_cmp);
    let q = |p: f64| e[((p * (e.len() - 1) as f64).round() as usize).min(e.len() - 1)];
    Stats {
        mean,
        median: q(0.5),
        p90: q(0.9),
    }
}

fn subset(stack: &PhotoStack, lights: &Lights, idx: &[usize]) -> (PhotoStack, Lights) {
    let photos = idx.iter().map(|&j| stack.photos[j].clone()).collect();
    (
        PhotoStack::new(stack.width, stack.height, photos).unwrap(),
        Lights {
            directions: idx.iter().map(|&j| lights.directions[j]).collect(),
            intensities: lights
                .intensities
                .as_ref()
                .map(|i| idx.iter().map(|&j| i[j]).collect()),
        },
    )
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mut dir: Option<PathBuf> = None;
    let mut repeat = 5usize;
    let mut methods = vec![
        PsMethod::LeastSquares,
        PsMethod::LeastSquares,
        PsMethod::Trimmed,
        PsMethod::L1,
        PsMethod::Sbl,
    ];
    let (mut lo, mut hi) = (6usize, 13usize);
    let mut all_subsets = false;
    let mut diagnose = false;
    let mut base = PhotometricParams::default();
    while let Some(a) = args.next() {
        let mut val = || args.next().expect("a value after the flag");
        match a.as_str() {
            "--repeat" => repeat = val().parse().unwrap(),
            "--methods" => {
                methods = val()
                    .split(',')
                    .map(|m| {
                        if m == "woodham" {
                            PsMethod::LeastSquares
                        } else {
                            PsMethod::from_name(m).expect("a method name")
                        }
                    })
                    .collect();
            }
            "--sizes" => {
                let v = val();
                let (a, b) = v.split_once('-').unwrap_or((&v, &v));
                (lo, hi) = (a.parse().unwrap(), b.parse().unwrap());
            }
            "--all-subsets" => all_subsets = true,
            "--shadow-level" => base.shadow_level = val().parse().unwrap(),
            "--robust-min-shading" => base.robust_min_shading = val().parse().unwrap(),
            "--lambda" => base.robust.sbl_lambda = val().parse().unwrap(),
            "--iters" => base.robust.max_iterations = val().parse().unwrap(),
            "--delta" => base.robust.l1_delta = val().parse().unwrap(),
            "--tol" => base.robust.tolerance = val().parse().unwrap(),
            "--clean" => base.robust.clean_residual = val().parse().unwrap(),
            "--saturation" => base.saturation_level = val().parse().unwrap(),
            "--diagnose" => diagnose = true,
            "--exponent" => {
                let v = val();
                base.exponent = (v != "auto").then(|| v.parse().expect("auto or a number"));
            }
            f if f.starts_with("--") => panic!("unknown flag {f}"),
            d => dir = Some(PathBuf::from(d)),
        }
    }
    let dir = dir.unwrap_or_else(|| {
        std::env::var_os("RGBN_DATA")
            .map_or_else(|| PathBuf::from("../shared/data"), PathBuf::from)
            .join("diligent-ball-subset")
    });
    let spec = PsInputSpec {
        photos: NAMES.iter().map(|n| dir.join(format!("{n}.png"))).collect(),
        lights: dir.join("light_directions.txt"),
        intensities: Some(dir.join("light_intensities.txt")),
        names: Some(dir.join("filenames.txt")),
        mask: Some(dir.join("mask.png")),
        transfer: Transfer::Linear,
    };
    let inputs = load_inputs(&spec).expect("the DiLiGenT ball");
    let (w, h) = (inputs.stack.width, inputs.stack.height);
    let mask = inputs.mask.clone().unwrap();
    let gt = read_mat_normals(&dir.join("Normal_gt.mat"), "Normal_gt", w, h);
    let inside: Vec<usize> = (0..w * h)
        .filter(|&i| mask[i] >= 0.5 && gt[2][i] != 0.0)
        .collect();
    let l2 = read_mat_normals(&dir.join("ballPNG_Normal_l2.mat"), "Normal_L2", w, h);
    let l2_img = rgbn::RgbnImage::new(
        w,
        h,
        [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]],
        l2,
        None,
    )
    .unwrap();
    let e2 = errors(&l2_img, &gt, &inside);
    let order = farthest_point_order(&inputs.lights.directions);
    let mp = (w * h) as f64 / 1e6;
    println!(
        "DiLiGenT ball {w}×{h}, {} mask pixels; threads {}; load {}",
        inside.len(),
        rayon::current_num_threads(),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    println!(
        "farthest-point order: {}",
        order
            .iter()
            .map(|&j| NAMES[j])
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "benchmark's 96-photo L2 map (ballPNG_Normal_l2.mat): mean {:.2}° median {:.2}° p90 {:.2}° (published 4.10°)",
        e2.mean, e2.median, e2.p90
    );
    println!("params: {base:?}");
    // The first least-squares row is Woodham's (k = 1), the time baseline.
    let woodham = methods.iter().position(|&m| m == PsMethod::LeastSquares);
    let params_of = |mi: usize, method: PsMethod| PhotometricParams {
        method,
        exponent: if Some(mi) == woodham {
            Some(1.0)
        } else {
            base.exponent
        },
        ..base.clone()
    };
    let name_of = |mi: usize, method: PsMethod| {
        if Some(mi) == woodham {
            "woodham"
        } else {
            method.name()
        }
    };
    println!("| photos | estimator | k | mean | median | p90 | ms / MP | × woodham |");
    println!("|---|---|---|---|---|---|---|---|");
    for k in lo..=hi {
        let (stack, lights) = subset(&inputs.stack, &inputs.lights, &order[..k]);
        let mut times = vec![Vec::new(); methods.len()];
        let mut outs = vec![None; methods.len()];
        let mut ks = vec![1.0f32; methods.len()];
        for _ in 0..repeat.max(1) {
            for (mi, &method) in methods.iter().enumerate() {
                let p = params_of(mi, method);
                let t = Instant::now();
                let (out, rep) = photometric_stereo(&stack, &lights, Some(&mask), &p).unwrap();
                times[mi].push(t.elapsed().as_secs_f64());
                outs[mi] = Some(out);
                ks[mi] = rep.exponent;
            }
        }
        let ls_t = woodham.map(|i| median(times[i].clone()));
        for (mi, &method) in methods.iter().enumerate() {
            let e = errors(outs[mi].as_ref().unwrap(), &gt, &inside);
            let t = median(times[mi].clone());
            println!(
                "| {k} | {} | {:.3} | {:.2}° | {:.2}° | {:.2}° | {:.1} | {} |",
                name_of(mi, method),
                ks[mi],
                e.mean,
                e.median,
                e.p90,
                1e3 * t / mp,
                ls_t.map_or("–".into(), |l| format!("{:.2}", t / l))
            );
        }
        if diagnose {
            for (mi, &method) in methods.iter().enumerate() {
                diagnose_errors(
                    name_of(mi, method),
                    outs[mi].as_ref().unwrap(),
                    &gt,
                    &inside,
                );
            }
        }
        if all_subsets {
            for (mi, &method) in methods.iter().enumerate() {
                let p = params_of(mi, method);
                let (mut sum, mut worst, mut count) = (0.0, 0.0f64, 0usize);
                for_each_subset(13, k, &mut |idx| {
                    let (st, li) = subset(&inputs.stack, &inputs.lights, idx);
                    if let Ok((out, _)) = photometric_stereo(&st, &li, Some(&mask), &p) {
                        let e = errors(&out, &gt, &inside).mean;
                        sum += e;
                        worst = worst.max(e);
                        count += 1;
                    }
                });
                println!(
                    "|   all {count} subsets of {k} | {} | | mean of means {:.2}°, worst {:.2}° | | | | |",
                    name_of(mi, method),
                    sum / count as f64,
                    worst
                );
            }
        }
    }
    println!(
        "load at end {}",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}

/// Calls `f` with every `k`-subset of `0..n` in lexicographic order.
fn for_each_subset(n: usize, k: usize, f: &mut dyn FnMut(&[usize])) {
    let mut idx: Vec<usize> = (0..k).collect();
    loop {
        f(&idx);
        let Some(i) = (0..k).rev().find(|&i| idx[i] < n - k + i) else {
            return;
        };
        idx[i] += 1;
        for j in i + 1..k {
            idx[j] = idx[j - 1] + 1;
        }
    }
}

/// The mean difference vector and the error by the ground truth's tilt (diagnostics).
fn diagnose_errors(name: &str, n: &rgbn::RgbnImage, gt: &[Vec<f32>; 3], inside: &[usize]) {
    let mut d = [0.0f64; 3];
    let mut bins = [(0.0f64, 0usize); 9];
    for &i in inside {
        let e = [n.normal()[0][i], n.normal()[1][i], n.normal()[2][i]];
        let g = [gt[0][i], gt[1][i], gt[2][i]];
        for k in 0..3 {
            d[k] += f64::from(e[k] - g[k]);
        }
        let tilt = f64::from(g[2]).clamp(-1.0, 1.0).acos().to_degrees();
        let b = ((tilt / 10.0) as usize).min(8);
        bins[b].0 += angle_deg(e, g);
        bins[b].1 += 1;
    }
    let c = inside.len() as f64;
    println!(
        "  {name}: mean (n − gt) = ({:+.4}, {:+.4}, {:+.4}); error by tilt (10° bins): {}",
        d[0] / c,
        d[1] / c,
        d[2] / c,
        bins.iter()
            .map(|(s, k)| if *k > 0 {
                format!("{:.2}({k})", s / *k as f64)
            } else {
                "-".into()
            })
            .collect::<Vec<_>>()
            .join(" ")
    );
}
