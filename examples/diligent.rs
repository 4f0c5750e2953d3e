//! DiLiGenT depth accuracy of rgbn's perspective integrators (the evaluation of Cao et al.,
//! "Bilateral Normal Integration", ECCV 2022, Fig. 7).
//!
//! ```text
//! cargo run --release --example diligent -- DIR [--solve-tol 1e-6] [--k 2] [--iters 100]
//!     [--over-relaxation 2]
//! ```
//!
//! `DIR` holds one folder per object with `normal_map.png` (16-bit RGB: red = x right,
//! green = y up, blue = towards the camera, `n = v/65535·2 − 1`, not renormalised, as the
//! reference evaluation reads it), `mask.png` (non-zero = inside), `K.txt` (3 × 3 intrinsics)
//! and `depth_gt.npy` (float32, `(h, w)`, NaN outside). The metric is the reference's MADE:
//! `s = median(z_gt / z)` over the pixels where both are defined, then `mean |s·z − z_gt|`
//! (mm). Bilateral runs with k = 2, at most 100 reweighting iterations, energy tolerance
//! 1e-4 (the reference's settings); masked_poisson is the plain least squares on the same
//! log-depth gradients. The data is not ours: nothing of it is in the repository.

use rgbn::raster::integrate::{
    integrate_normals, Camera, IntegrateParams, IntegrationMethod, Pinhole,
};
use rgbn::raster::RgbnImage;
use std::path::{Path, PathBuf};
use std::time::Instant;

const OBJECTS: [&str; 9] = [
    "bear", "buddha", "cat", "cow", "goblet", "harvest", "pot1", "pot2", "reading",
];
/// The reference implementation's own baseline (optimization_log.md), same metric.
const REFERENCE_MADE: [f64; 9] = [
    0.334, 1.098, 0.074, 0.058, 9.018, 1.838, 0.635, 0.220, 0.257,
];

type Res<T> = Result<T, String>;

/// A tiny `.npy` reader: little-endian `f4` or `f8`, 2-D, C or Fortran order → row-major f64.
fn read_npy(path: &Path) -> Res<(usize, usize, Vec<f64>)> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err(format!("{}: not a .npy file", path.display()));
    }
    let (hlen, start) = if b[6] == 1 {
        (u16::from_le_bytes([b[8], b[9]]) as usize, 10)
    } else {
        (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12)
    };
    let header = std::str::from_utf8(&b[start..start + hlen]).map_err(|e| e.to_string())?;
    let size = if header.contains("'<f4'") {
        4
    } else if header.contains("'<f8'") {
        8
    } else {
        return Err(format!(
            "{}: only <f4/<f8 are read: {header}",
            path.display()
        ));
    };
    let fortran = header.contains("'fortran_order': True");
    let shape = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or("no shape")?;
    let dims: Vec<usize> = shape
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse().map_err(|_| format!("bad shape {shape}")))
        .collect::<Res<_>>()?;
    let [h, w] = dims[..] else {
        return Err(format!("{}: not 2-D: {shape}", path.display()));
    };
    let data = &b[start + hlen..];
    if data.len() < w * h * size {
        return Err(format!("{}: truncated", path.display()));
    }
    let at = |k: usize| -> f64 {
        let o = k * size;
        if size == 4 {
            f64::from(f32::from_le_bytes(data[o..o + 4].try_into().unwrap()))
        } else {
            f64::from_le_bytes(data[o..o + 8].try_into().unwrap())
        }
    };
    let mut out = vec![0.0; w * h];
    for r in 0..h {
        for c in 0..w {
            out[r * w + c] = if fortran {
                at(c * h + r)
            } else {
                at(r * w + c)
            };
        }
    }
    Ok((w, h, out))
}

fn load(dir: &Path) -> Res<(RgbnImage, Pinhole, Vec<f64>)> {
    let nm = image::open(dir.join("normal_map.png"))
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .to_rgb16();
    let (w, h) = (nm.width() as usize, nm.height() as usize);
    let mask_img = image::open(dir.join("mask.png"))
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .to_luma8();
    let n = w * h;
    let mut normal = [vec![0.0f32; n], vec![0.0f32; n], vec![1.0f32; n]];
    let mut mask = vec![0.0f32; n];
    for (i, px) in nm.pixels().enumerate() {
        for k in 0..3 {
            normal[k][i] = (f64::from(px[k]) / 65535.0 * 2.0 - 1.0) as f32;
        }
    }
    for (i, px) in mask_img.pixels().enumerate() {
        mask[i] = f32::from(u8::from(px[0] > 0));
    }
    let col = [vec![0.5; n], vec![0.5; n], vec![0.5; n]];
    let img = RgbnImage::new(w, h, col, normal, Some(mask)).map_err(|e| e.to_string())?;
    let cam = Pinhole::from_k_file(&dir.join("K.txt")).map_err(|e| e.to_string())?;
    let (gw, gh, gt) = read_npy(&dir.join("depth_gt.npy"))?;
    if (gw, gh) != (w, h) {
        return Err(format!("depth_gt is {gw}×{gh}, the normal map {w}×{h}"));
    }
    Ok((img, cam, gt))
}

/// MADE of the reference evaluation: `s = median(gt / z)`, `mean |s z − gt|`.
fn made(height: &[f32], gt: &[f64], mask: &[f32]) -> f64 {
    let idx: Vec<usize> = (0..gt.len())
        .filter(|&i| mask[i] >= 0.5 && gt[i].is_finite())
        .collect();
    let z = |i: usize| -f64::from(height[i]);
    let mut ratios: Vec<f64> = idx.iter().map(|&i| gt[i] / z(i)).collect();
    ratios.sort_by(f64::total_cmp);
    let m = ratios.len();
    let s = if m % 2 == 1 {
        ratios[m / 2]
    } else {
        0.5 * (ratios[m / 2 - 1] + ratios[m / 2])
    };
    idx.iter().map(|&i| (s * z(i) - gt[i]).abs()).sum::<f64>() / m as f64
}

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut dir = None;
    let (mut solve_tol, mut k, mut iters) = (IntegrateParams::default().tolerance, 2.0, 100u32);
    let mut beta = IntegrateParams::default().over_relaxation;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut num = |name: &str| -> f64 {
            it.next()
                .and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("{name} needs a number"))
        };
        match a.as_str() {
            "--solve-tol" => solve_tol = num("--solve-tol"),
            "--k" => k = num("--k"),
            "--iters" => iters = num("--iters") as u32,
            "--over-relaxation" => beta = num("--over-relaxation"),
            _ => dir = Some(PathBuf::from(a)),
        }
    }
    let Some(dir) = dir else {
        eprintln!("usage: diligent DIR [--solve-tol T] [--k K] [--iters N] [--over-relaxation B]");
        return std::process::ExitCode::from(2);
    };
    println!(
        "DiLiGenT MADE (mm), pinhole camera from K.txt; bilateral k = {k}, ≤ {iters} IRLS \
         iterations, energy tolerance 1e-4, solve tolerance {solve_tol:e}, over-relaxation {beta}"
    );
    println!(
        "| object | rgbn bilateral | rgbn masked_poisson | reference BiNI | bilateral time (s) | IRLS it. | pixels |"
    );
    println!("|---|---|---|---|---|---|---|");
    let (mut sb, mut sl, mut sr, mut st) = (0.0, 0.0, 0.0, 0.0);
    for (obj, reference) in OBJECTS.iter().zip(REFERENCE_MADE) {
        let (img, cam, gt) = match load(&dir.join(obj)) {
            Ok(v) => v,
            Err(e) => {
                eprintln!("{obj}: {e}");
                return std::process::ExitCode::from(2);
            }
        };
        let base = IntegrateParams {
            camera: Camera::Pinhole(cam),
            tolerance: solve_tol,
            sharpness: k,
            irls_iterations: iters,
            irls_tolerance: 1e-4,
            over_relaxation: beta,
            ..Default::default()
        };
        let t = Instant::now();
        let (hb, rep) = integrate_normals(
            &img,
            &IntegrateParams {
                method: IntegrationMethod::Bilateral,
                ..base.clone()
            },
        )
        .expect("bilateral");
        let tb = t.elapsed().as_secs_f64();
        let (hl, _) = integrate_normals(
            &img,
            &IntegrateParams {
                method: IntegrationMethod::MaskedPoisson,
                ..base
            },
        )
        .expect("masked_poisson");
        let mask = img.mask().unwrap();
        let (mb, ml) = (made(hb.data(), &gt, mask), made(hl.data(), &gt, mask));
        println!(
            "| {obj} | {mb:.3} | {ml:.3} | {reference:.3} | {tb:.2} | {} ({} CG) | {} |",
            rep.irls_iterations, rep.iterations, rep.domain_pixels
        );
        (sb, sl, sr, st) = (sb + mb, sl + ml, sr + reference, st + tb);
    }
    println!(
        "| mean | {:.3} | {:.3} | {:.3} | {st:.2} (total) | | |",
        sb / 9.0,
        sl / 9.0,
        sr / 9.0
    );
    std::process::ExitCode::SUCCESS
}
