//! Photometric stereo and chrome calibration on real third-party data (never committed):
//! `$RGBN_DATA` or `../shared/data`; each test is skipped with a message when its data is absent.

use super::chrome::{calibrate_chrome, ChromeParams};
use super::diligent_mat::read_mat_normals;
use super::inputs::{load_inputs, PsInputSpec, Transfer};
use super::linalg::angle_deg;
use super::photometric::{photometric_stereo, PhotometricParams, PsMethod};
use crate::raster::RgbnImage;
use std::path::{Path, PathBuf};

fn mean_angle_deg(out: &RgbnImage, gt: &[Vec<f32>; 3], mask: &[f32]) -> f64 {
    let (s, n) = (0..out.len())
        .filter(|&i| mask[i] >= 0.5 && gt[2][i] != 0.0)
        .map(|i| {
            angle_deg(
                out.normal_at(i % out.width(), i / out.width()),
                [gt[0][i], gt[1][i], gt[2][i]],
            )
        })
        .fold((0.0, 0usize), |(s, n), a| (s + a, n + 1));
    s / n as f64
}

#[test]
fn diligent_ball_to_height_and_mesh() {
    use crate::raster::integrate::{
        integrate_normals, project_integrable, IntegrateParams, IntegrationMethod, ProjectParams,
    };
    let Some(d) = data_dir("diligent-ball-subset") else {
        return;
    };
    let names = ["001", "008", "041", "048", "052", "089", "096"];
    let spec = diligent_spec(&d, &names);
    let inputs = load_inputs(&spec).unwrap();
    let (w, h) = (inputs.stack.width, inputs.stack.height);
    let mut mask = inputs.mask.clone().unwrap();
    let (ps, _) = photometric_stereo(
        &inputs.stack,
        &inputs.lights,
        Some(&mask),
        &PhotometricParams::default(),
    )
    .unwrap();
    let gt_n = read_mat_normals(&d.join("Normal_gt.mat"), "Normal_gt", w, h);
    // Integrate where the surface is not grazing (GT n_z ≥ 0.3): at the silhouette slopes
    // grow without bound and no integrator is meaningful there.
    for (m, &nz) in mask.iter_mut().zip(&gt_n[2]) {
        if nz < 0.3 {
            *m = 0.0;
        }
    }
    // Also drop PS outliers (n_z < 0.2 where GT says ≥ 0.3): least-squares integration is
    // not robust to a few huge slopes.
    let mut outliers = 0;
    for (m, &nz) in mask.iter_mut().zip(&ps.normal()[2]) {
        if *m >= 0.5 && nz < 0.2 {
            *m = 0.0;
            outliers += 1;
        }
    }
    eprintln!("DiLiGenT ball, 7 lights: {outliers} PS outlier pixels (n_z < 0.2) excluded");
    let mut ps = ps;
    ps.set_mask(Some(mask.clone())).unwrap();
    let mut gt = RgbnImage::new(w, h, ps.color().clone(), gt_n, Some(mask.clone())).unwrap();
    gt.repair();
    let params = IntegrateParams {
        method: IntegrationMethod::MaskedPoisson,
        ..Default::default()
    };
    let (z_ps, rep) = integrate_normals(&ps, &params).unwrap();
    let (z_gt, _) = integrate_normals(&gt, &params).unwrap();
    let inside: Vec<usize> = (0..w * h).filter(|&i| mask[i] >= 0.5).collect();
    let diff: Vec<f64> = inside
        .iter()
        .map(|&i| f64::from(z_ps.data()[i] - z_gt.data()[i]))
        .collect();
    let mean = diff.iter().sum::<f64>() / diff.len() as f64;
    let rmse = (diff.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / diff.len() as f64).sqrt();
    let (lo, hi) = inside.iter().fold((f32::MAX, f32::MIN), |(lo, hi), &i| {
        (lo.min(z_gt.data()[i]), hi.max(z_gt.data()[i]))
    });
    eprintln!(
        "DiLiGenT ball, 7 lights → masked Poisson height: RMSE vs GT-normal height {rmse:.3} px              over a {:.1} px relief; CG {} iterations, residual {:.1e}",
        hi - lo,
        rep.iterations,
        rep.relative_residual
    );
    assert!(rmse < 0.05 * f64::from(hi - lo), "{rmse}");
    let (proj, _, prep) = project_integrable(&ps, &ProjectParams { integrate: params }).unwrap();
    eprintln!(
        "DiLiGenT ball projection: relative curl {:.3e} → {:.3e}",
        prep.before.relative, prep.after.relative
    );
    assert!(prep.after.relative < 0.1 * prep.before.relative);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.ply");
    let (nv, nf) = crate::raster::mesh::save_mesh(
        &z_ps,
        &proj,
        &path,
        &[],
        &crate::raster::mesh::MeshParams::default(),
    )
    .unwrap();
    assert_eq!(nv, inside.len());
    assert!(nf > nv);
}

#[test]
fn diligent_ball_angular_error() {
    let Some(d) = data_dir("diligent-ball-subset") else {
        return;
    };
    let names = [
        "001", "008", "019", "023", "041", "045", "048", "052", "068", "071", "089", "093", "096",
    ];
    let spec = diligent_spec(&d, &names);
    let inputs = load_inputs(&spec).unwrap();
    let (w, h) = (inputs.stack.width, inputs.stack.height);
    let gt = read_mat_normals(&d.join("Normal_gt.mat"), "Normal_gt", w, h);
    let mask = inputs.mask.as_deref().unwrap();
    let baseline = read_mat_normals(&d.join("ballPNG_Normal_l2.mat"), "Normal_L2", w, h);
    let base_img = RgbnImage::new(
        w,
        h,
        [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]],
        baseline,
        None,
    )
    .unwrap();
    let e_base = mean_angle_deg(&base_img, &gt, mask);
    let mut errs = Vec::new();
    for &method in <PsMethod as crate::params::Choice>::ALL {
        let params = PhotometricParams {
            method,
            ..Default::default()
        };
        let (out, rep) =
            photometric_stereo(&inputs.stack, &inputs.lights, Some(mask), &params).unwrap();
        let e = mean_angle_deg(&out, &gt, mask);
        eprintln!("DiLiGenT ball, 13 lights, {method:?}: mean angular error {e:.3}° ({rep:?})");
        assert!(out.validate().is_clean());
        errs.push((method, e));
    }
    eprintln!("DiLiGenT ball, benchmark's own 96-light L2 map: {e_base:.3}°");
    let err = |m: PsMethod| errs.iter().find(|(k, _)| *k == m).unwrap().1;
    // Measured (docs/capture.md): ls 4.16°, trimmed 2.29°, l1 BOUND_L1, sbl BOUND_SBL; bounds
    // with a margin of ~0.1°.
    // Measured (docs/capture.md), shading exponent estimated (k ≈ 1.07): ls 3.76°, trimmed
    // 1.25°, l1 and sbl 1.37°; bounds with a margin of ~0.1°. The goal of the default is 1.9°.
    assert!(err(PsMethod::LeastSquares) <= 3.9, "least squares");
    assert!(err(PsMethod::Trimmed) <= 1.35, "trimmed");
    assert!(err(PsMethod::L1) <= 1.5, "l1");
    assert!(err(PsMethod::Sbl) <= 1.5, "sbl");
    // Woodham's model (k = 1) on the same photos: the exponent is worth about 1°.
    let lambert = PhotometricParams {
        exponent: Some(1.0),
        ..Default::default()
    };
    let (out, _) = photometric_stereo(&inputs.stack, &inputs.lights, Some(mask), &lambert).unwrap();
    let e1 = mean_angle_deg(&out, &gt, mask);
    eprintln!("DiLiGenT ball, 13 lights, trimmed with k = 1: {e1:.3}°");
    assert!(e1 > err(PsMethod::Trimmed) + 0.5, "{e1}°");
    // The default estimator on the 6-photo subset of docs/capture.md: the first six of the
    // farthest-point order of the 13 lights (examples/diligent_ps.rs prints it).
    let six = ["052", "048", "041", "096", "089", "008"];
    let inputs6 = load_inputs(&diligent_spec(&d, &six)).unwrap();
    let (out, _) = photometric_stereo(
        &inputs6.stack,
        &inputs6.lights,
        Some(mask),
        &PhotometricParams::default(),
    )
    .unwrap();
    let e6 = mean_angle_deg(&out, &gt, mask);
    eprintln!(
        "DiLiGenT ball, 6 lights ({}), default estimator: {e6:.3}°",
        six.join(" ")
    );
    assert!(e6 <= 3.0, "6 photos: {e6}°");
}

const OBJECTS: [&str; 6] = ["buddha", "cat", "gray", "horse", "owl", "rock"];

fn uw_spec(d: &Path, obj: &str) -> PsInputSpec {
    PsInputSpec {
        photos: (0..12)
            .map(|i| d.join(obj).join(format!("{obj}.{i}.png")))
            .collect(),
        lights: d.join("lights.txt"),
        intensities: None,
        names: None,
        mask: Some(d.join(obj).join(format!("{obj}.mask.png"))),
        transfer: Transfer::Linear,
    }
}

#[test]
fn uw_objects_give_plausible_rgbn() {
    let Some(d) = data_dir("uw-psm-images") else {
        return;
    };
    for obj in OBJECTS {
        let inputs = load_inputs(&uw_spec(&d, obj)).unwrap();
        let mask = inputs.mask.as_deref().unwrap();
        let (out, rep) = photometric_stereo(
            &inputs.stack,
            &inputs.lights,
            Some(mask),
            &PhotometricParams::default(),
        )
        .unwrap();
        let v = out.validate();
        let inside: Vec<usize> = (0..out.len()).filter(|&i| mask[i] >= 0.5).collect();
        let facing = inside.iter().filter(|&&i| out.normal()[2][i] > 0.0).count();
        let frac = facing as f64 / inside.len() as f64;
        eprintln!(
            "UW {obj}: {} mask px, n_z > 0 for {:.2}%, {rep:?}",
            inside.len(),
            100.0 * frac
        );
        assert!(v.is_clean() && v.non_finite_color == 0, "{obj}: {v:?}");
        assert!(frac >= 0.99, "{obj}: {frac}");
        assert!(
            rep.solved as f64 >= 0.95 * inside.len() as f64,
            "{obj}: {rep:?}"
        );
    }
}

/// The UW grey sphere's normals from its mask: a circle fitted (least squares) to the mask's
/// boundary above the stand (the upper 60 % of its rows), orthographic sphere normals inside
/// 0.95 of its radius and above the stand. Returns the normals and the selection.
fn sphere_from_mask(mask: &[f32], w: usize, h: usize) -> ([Vec<f32>; 3], Vec<f32>) {
    let inside = |x: usize, y: usize| mask[y * w + x] >= 0.5;
    let rows: Vec<usize> = (0..h).filter(|&y| (0..w).any(|x| inside(x, y))).collect();
    let (top, bottom) = (rows[0], *rows.last().unwrap());
    let cut = top as f64 + 0.6 * (bottom - top) as f64;
    // Boundary: inside pixels with an outside 4-neighbour; rows x² + y² = 2ax + 2by + c.
    let (mut a, mut v) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let edge = inside(x, y)
                && (!inside(x - 1, y)
                    || !inside(x + 1, y)
                    || !inside(x, y - 1)
                    || !inside(x, y + 1));
            if edge && (y as f64) < cut {
                let (fx, fy) = (x as f64, y as f64);
                let row = [2.0 * fx, 2.0 * fy, 1.0];
                for i in 0..3 {
                    for j in 0..3 {
                        a[i][j] += row[i] * row[j];
                    }
                    v[i] += row[i] * (fx * fx + fy * fy);
                }
            }
        }
    }
    let [cx, cy, c] = crate::capture::linalg::solve3(&a, v);
    let r = (c + cx * cx + cy * cy).sqrt();
    let mut n = [
        vec![0.0f32; w * h],
        vec![0.0f32; w * h],
        vec![0.0f32; w * h],
    ];
    let mut sel = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let (nx, ny) = ((x as f64 - cx) / r, -(y as f64 - cy) / r);
            let r2 = nx * nx + ny * ny;
            let i = y * w + x;
            if inside(x, y) && r2 < 0.95 * 0.95 && (y as f64) < cy + 0.5 * r {
                n[0][i] = nx as f32;
                n[1][i] = ny as f32;
                n[2][i] = (1.0 - r2).sqrt() as f32;
                sel[i] = 1.0;
            }
        }
    }
    (n, sel)
}

#[test]
fn uw_grey_sphere_estimated_exponent_is_no_worse_than_lambert() {
    // The one UW object with a known shape. Its photos are 8-bit of undocumented response
    // and its lights come from a chrome ball, so the errors are large for every model; the
    // exponent estimate must not make them much larger (a residual normalised by Σ g² instead
    // of the variance picked k = 1.41 here and doubled the error). Measured: k = 1.02, 5.87°
    // against 5.58° with k = 1 (this sphere's error moves ~0.15° per 0.01 of k).
    let Some(d) = data_dir("uw-psm-images") else {
        return;
    };
    let inputs = load_inputs(&uw_spec(&d, "gray")).unwrap();
    let (w, h) = (inputs.stack.width, inputs.stack.height);
    let (gt, sel) = sphere_from_mask(inputs.mask.as_deref().unwrap(), w, h);
    let run = |exponent| {
        let params = PhotometricParams {
            exponent,
            ..Default::default()
        };
        let (out, rep) =
            photometric_stereo(&inputs.stack, &inputs.lights, Some(&sel), &params).unwrap();
        (mean_angle_deg(&out, &gt, &sel), rep.exponent)
    };
    let (e_auto, k) = run(None);
    let (e_lambert, _) = run(Some(1.0));
    eprintln!(
        "UW grey sphere vs its mask's sphere: k = {k:.3} → {e_auto:.2}°; k = 1 → {e_lambert:.2}°"
    );
    assert!(e_auto <= e_lambert + 0.5, "{e_auto}° vs {e_lambert}°");
    assert!((0.9..=1.15).contains(&k), "k {k}");
}

#[test]
fn chrome_calibration_matches_lights_txt() {
    let Some(d) = data_dir("uw-psm-images") else {
        return;
    };
    let spec = uw_spec(&d, "chrome");
    let inputs = load_inputs(&spec).unwrap();
    let cal = calibrate_chrome(
        &inputs.stack,
        inputs.mask.as_deref().unwrap(),
        &ChromeParams::default(),
    )
    .unwrap();
    let angles: Vec<f64> = cal
        .directions
        .iter()
        .zip(&inputs.lights.directions)
        .map(|(a, b)| angle_deg(*a, *b))
        .collect();
    eprintln!(
        "chrome sphere: centre ({:.1}, {:.1}) px, radius {:.1} px; per-light angle to              lights.txt (°): {}",
        cal.centre_px[0],
        cal.centre_px[1],
        cal.radius_px,
        angles
            .iter()
            .map(|a| format!("{a:.2}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    let max = angles.iter().copied().fold(0.0, f64::max);
    assert!(max < 3.0, "max {max}°");
}

/// The DiLiGenT ball inputs for a subset of its photos (`names` like `"001"`).
fn diligent_spec(d: &Path, names: &[&str]) -> PsInputSpec {
    PsInputSpec {
        photos: names.iter().map(|n| d.join(format!("{n}.png"))).collect(),
        lights: d.join("light_directions.txt"),
        intensities: Some(d.join("light_intensities.txt")),
        names: Some(d.join("filenames.txt")),
        mask: Some(d.join("mask.png")),
        transfer: Transfer::Linear,
    }
}

/// `$RGBN_DATA/<sub>` (default `../shared/data/<sub>`), or `None` with a SKIPPED message.
fn data_dir(sub: &str) -> Option<PathBuf> {
    crate::test_data::real_data(sub)
}
