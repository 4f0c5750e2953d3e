//! Perspective (pinhole) cameras: normals → log-depth gradients, log-depth → depth, and the
//! 3-D points of a depth map.
//!
//! # Model
//!
//! A pinhole camera with focal lengths `fx`, `fy` and principal point `(cx, cy)` in pixels
//! (pixel `(x, row)` has its centre at `(x, row)`, as in an OpenCV `K` matrix). The camera
//! looks along `−z` of the normals' frame (`x` right, `y` up, `z` towards the viewer), so the
//! surface point seen at pixel `(x, row)` at depth `Z > 0` is
//!
//! `P = Z · ((x − cx)/fx, −(row − cy)/fy, −1)`.
//!
//! `P` lies on the tangent plane of normal `n`: `n · ∂P/∂x = n · ∂P/∂row = 0`. With
//! `d = n_z − n_x (x − cx)/fx + n_y (row − cy)/fy` (`= −n · P / Z > 0` for a surface facing the
//! camera) this gives, for the log-depth `ℓ = ln Z` (Quéau, Durou & Aujol, "Normal integration:
//! a survey", JMIV 2018, §2.2),
//!
//! `∂ℓ/∂x = n_x / (fx · d)`,  `∂ℓ/∂y = n_y / (fy · d)` (`y` up, `∂/∂y = −∂/∂row`).
//!
//! So the log-depth is integrated exactly like a height, by any solver of the module, from
//! this gradient field; its free constant is the unknown scale of the depth. The result is
//! returned as a *height* `−Z` (towards the viewer, the convention of every height in rgbn),
//! scaled so that the geometric mean of `Z` over the domain is `fx`: near the principal
//! point one unit of depth is then about one pixel of image-plane width at the object's
//! distance, like the orthographic heights in pixels.
//!
//! `d ≤ ε` (a normal seen edge-on or from behind; `ε` = [`NZ_EPSILON`]) is clamped to `ε` and
//! counted in [`GradientField::clamped`], as `n_z` is in the orthographic case: never NaN.

use super::super::gradient::{GradientField, NZ_EPSILON};
use crate::error::RgbnError;
use crate::raster::par::ordered_sum_of;
use rayon::prelude::*;
use std::path::Path;

/// A pinhole camera: focal lengths and principal point in pixels (module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// The camera the normals were seen with.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Camera {
    /// Parallel projection: heights in pixels (the default, and every method's old behaviour).
    #[default]
    Orthographic,
    /// A pinhole camera: the log-depth is integrated and a depth returned up to scale.
    Pinhole(Pinhole),
}

impl Pinhole {
    /// Focal length `f` (both axes) with the principal point at the centre of a `w × h` image.
    #[must_use]
    pub fn centred(f: f64, w: usize, h: usize) -> Self {
        Self {
            fx: f,
            fy: f,
            cx: (w as f64 - 1.0) / 2.0,
            cy: (h as f64 - 1.0) / 2.0,
        }
    }

    /// Focal lengths finite and > 0, principal point finite.
    ///
    /// # Errors
    /// A one-line error naming the parameter.
    pub fn validate(&self) -> Result<(), RgbnError> {
        for (name, v) in [("focal_px", self.fx), ("focal_y_px", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(RgbnError::param(
                    name,
                    format!("a focal length must be finite and > 0, got {v}"),
                ));
            }
        }
        for (name, v) in [("principal_x", self.cx), ("principal_y", self.cy)] {
            if !v.is_finite() {
                return Err(RgbnError::param(name, format!("must be finite, got {v}")));
            }
        }
        Ok(())
    }

    /// `d` of the module docs (unclamped) for normal `n` at pixel `(x, row)`.
    #[inline(always)]
    #[must_use]
    pub fn facing(&self, n: [f32; 3], x: usize, row: usize) -> f64 {
        f64::from(n[2]) - f64::from(n[0]) * (x as f64 - self.cx) / self.fx
            + f64::from(n[1]) * (row as f64 - self.cy) / self.fy
    }

    /// The camera-frame point (`x` right, `y` up, `z` towards the viewer) at depth `z` seen at
    /// pixel `(x, row)`.
    #[inline(always)]
    #[must_use]
    pub fn point(&self, x: usize, row: usize, z: f64) -> [f64; 3] {
        [
            (x as f64 - self.cx) * z / self.fx,
            -(row as f64 - self.cy) * z / self.fy,
            -z,
        ]
    }

    /// Reads a 3 × 3 intrinsic matrix `K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` written as
    /// text (three rows of three numbers separated by spaces, commas or tabs, as NumPy's
    /// `savetxt` writes it; `#` starts a comment).
    ///
    /// # Errors
    /// A missing or unreadable file, not 3 × 3 numbers, a skew or last row that is not
    /// `[0, 0, 1]`, a focal length ≤ 0 — one line naming the file.
    pub fn from_k_file(path: &Path) -> Result<Self, RgbnError> {
        let text = std::fs::read_to_string(path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                RgbnError::NotFound {
                    path: path.to_path_buf(),
                }
            } else {
                RgbnError::Read {
                    path: path.to_path_buf(),
                    source: e,
                }
            }
        })?;
        let bad =
            |detail: String| RgbnError::param("k_file", format!("{detail}: {}", path.display()));
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for line in text.lines() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let row = line
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|s| !s.is_empty())
                .map(|s| {
                    s.parse::<f64>()
                        .map_err(|_| bad(format!("not a number {s:?}")))
                })
                .collect::<Result<Vec<f64>, _>>()?;
            rows.push(row);
        }
        if rows.len() != 3 || rows.iter().any(|r| r.len() != 3) {
            let shape: Vec<usize> = rows.iter().map(Vec::len).collect();
            return Err(bad(format!(
                "a K matrix is 3 rows of 3 numbers, got rows of {shape:?}"
            )));
        }
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err(bad("K has a non-finite entry".into()));
        }
        let tiny = |v: f64, want: f64| (v - want).abs() <= 1e-9 * (1.0 + want.abs());
        if !(tiny(rows[1][0], 0.0)
            && tiny(rows[2][0], 0.0)
            && tiny(rows[2][1], 0.0)
            && tiny(rows[2][2], 1.0))
        {
            return Err(bad("K's last row must be [0, 0, 1] and K[1][0] = 0".into()));
        }
        if !tiny(rows[0][1], 0.0) {
            return Err(bad("a skewed K (K[0][1] ≠ 0) is not supported".into()));
        }
        let cam = Self {
            fx: rows[0][0],
            fy: rows[1][1],
            cx: rows[0][2],
            cy: rows[1][2],
        };
        cam.validate()
            .map_err(|e| bad(format!("K gives an invalid camera ({e})")))?;
        Ok(cam)
    }
}

/// The log-depth gradients `(∂ℓ/∂x, ∂ℓ/∂y)` of the module docs for a `w × h` image's normal
/// planes, `d` clamped to [`NZ_EPSILON`] (counted in `clamped`).
#[must_use]
pub fn log_depth_gradients(
    normal: &[Vec<f32>; 3],
    w: usize,
    h: usize,
    cam: &Pinhole,
) -> GradientField {
    let mut g = GradientField::zeros(w, h);
    let eps = f64::from(NZ_EPSILON);
    let clamped =
        g.p.par_chunks_mut(w.max(1))
            .zip(g.q.par_chunks_mut(w.max(1)))
            .enumerate()
            .map(|(r, (pr, qr))| {
                let mut clamped = 0usize;
                for x in 0..w {
                    let i = r * w + x;
                    let n = [normal[0][i], normal[1][i], normal[2][i]];
                    let d = cam.facing(n, x, r);
                    clamped += usize::from(d.is_nan() || d < eps);
                    let d = if d >= eps { d } else { eps };
                    pr[x] = (f64::from(n[0]) / (cam.fx * d)) as f32;
                    qr[x] = (f64::from(n[1]) / (cam.fy * d)) as f32;
                }
                clamped
            })
            .sum();
    g.clamped = clamped;
    g
}

/// Largest |log-depth| exponentiated (a relief of e^±60 is far beyond any camera): keeps the
/// depth finite whatever the solver returns outside the domain.
const MAX_LOG: f64 = 60.0;

/// Turns a log-depth (any constant) into the height `−Z` of the module docs: `Z = fx ·
/// exp(ℓ − mean_domain ℓ)`. `domain` (coverage ≥ 0.5) selects the pixels of the mean (all
/// without one); every pixel is converted and finite.
pub fn height_of_log_depth(ell: &mut [f32], domain: Option<&[f32]>, fx: f64) {
    let ins = |i: usize| domain.is_none_or(|m| m[i] >= 0.5);
    let (s, n) = ordered_sum_of(ell.len(), |i| {
        let v = ell[i];
        (ins(i) && v.is_finite()).then_some(f64::from(v))
    });
    let mean = if n > 0 { s / n as f64 } else { 0.0 };
    ell.par_iter_mut().for_each(|v| {
        let l = f64::from(*v) - mean;
        let l = if l.is_finite() {
            l.clamp(-MAX_LOG, MAX_LOG)
        } else {
            0.0
        };
        *v = (-fx * l.exp()) as f32;
    });
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::raster::{Plane, RgbnImage};

    /// A rendered perspective scene (exact per pixel by ray casting): a sphere of radius `rad`
    /// centred at camera-frame `centre` (`z < 0` in front of the camera), optionally with a
    /// plane through the sphere's centre with normal `plane` (towards the camera): the nearest
    /// hit is seen. Returns the image (mask = every hit), the true depth `Z` (0 where nothing
    /// is hit) and the pixels that see the sphere.
    pub(crate) fn render_sphere(
        w: usize,
        h: usize,
        cam: &Pinhole,
        centre: [f64; 3],
        rad: f64,
        plane: Option<[f64; 3]>,
    ) -> (RgbnImage, Plane, Vec<f32>) {
        let n = w * h;
        let mut normal = [vec![0.0f32; n], vec![0.0f32; n], vec![1.0f32; n]];
        let mut depth = vec![0.0f32; n];
        let mut mask = vec![0.0f32; n];
        let mut sphere = vec![0.0f32; n];
        for r in 0..h {
            for x in 0..w {
                let i = r * w + x;
                let d = [
                    (x as f64 - cam.cx) / cam.fx,
                    -(r as f64 - cam.cy) / cam.fy,
                    -1.0,
                ];
                let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                let dc = d[0] * centre[0] + d[1] * centre[1] + d[2] * centre[2];
                let cc = centre.iter().map(|v| v * v).sum::<f64>();
                let disc = dc * dc - dd * (cc - rad * rad);
                let t_sphere = (disc > 0.0).then(|| (dc - disc.sqrt()) / dd);
                let t_plane = plane.and_then(|np| {
                    let nd = np[0] * d[0] + np[1] * d[1] + np[2] * d[2];
                    let nc = np[0] * centre[0] + np[1] * centre[1] + np[2] * centre[2];
                    (nd < 0.0).then(|| nc / nd).filter(|t| *t > 0.0)
                });
                let hit = match (t_sphere, t_plane) {
                    (Some(ts), Some(tp)) if tp < ts => Some((tp, false)),
                    (Some(ts), _) => Some((ts, true)),
                    (None, Some(tp)) => Some((tp, false)),
                    (None, None) => None,
                };
                let Some((t, on_sphere)) = hit else { continue };
                let nn = if on_sphere {
                    let p = [t * d[0], t * d[1], t * d[2]];
                    [
                        (p[0] - centre[0]) / rad,
                        (p[1] - centre[1]) / rad,
                        (p[2] - centre[2]) / rad,
                    ]
                } else {
                    let np = plane.unwrap_or([0.0, 0.0, 1.0]);
                    let l = (np[0] * np[0] + np[1] * np[1] + np[2] * np[2]).sqrt();
                    [np[0] / l, np[1] / l, np[2] / l]
                };
                for k in 0..3 {
                    normal[k][i] = nn[k] as f32;
                }
                depth[i] = t as f32;
                mask[i] = 1.0;
                sphere[i] = f32::from(u8::from(on_sphere));
            }
        }
        let col = [vec![0.5; n], vec![0.5; n], vec![0.5; n]];
        let img = RgbnImage::new(w, h, col, normal, Some(mask)).unwrap();
        (img, Plane::from_vec(w, h, depth).unwrap(), sphere)
    }

    /// `min_s ‖s·z − z_gt‖ / ‖z_gt − mean z_gt‖` over the selected pixels (depth error after
    /// the best scale, relative to the relief).
    pub(crate) fn scaled_depth_error(z: &[f32], gt: &[f32], sel: &[f32]) -> f64 {
        let idx: Vec<usize> = (0..z.len()).filter(|&i| sel[i] >= 0.5).collect();
        let (zz, zg) = idx.iter().fold((0.0, 0.0), |a, &i| {
            let (z, g) = (f64::from(z[i]), f64::from(gt[i]));
            (a.0 + z * z, a.1 + z * g)
        });
        let s = zg / zz;
        let mean = idx.iter().map(|&i| f64::from(gt[i])).sum::<f64>() / idx.len() as f64;
        let err = idx
            .iter()
            .map(|&i| (s * f64::from(z[i]) - f64::from(gt[i])).powi(2))
            .sum::<f64>();
        let relief = idx
            .iter()
            .map(|&i| (f64::from(gt[i]) - mean).powi(2))
            .sum::<f64>();
        (err / relief).sqrt()
    }

    #[test]
    fn log_depth_gradients_match_the_rendered_depth() {
        // Finite differences of ln Z of the rendered sphere vs the formula, inside.
        let (w, h) = (96, 80);
        let cam = Pinhole {
            fx: 150.0,
            fy: 140.0,
            cx: 50.3,
            cy: 37.8,
        };
        let centre = [0.1, -0.05, -3.0];
        let (img, _, sphere) = render_sphere(w, h, &cam, centre, 1.0, None);
        let g = log_depth_gradients(img.normal(), w, h, &cam);
        assert_eq!(g.clamped, 0);
        // ln Z by ray casting in f64 at sub-pixel offsets: central differences with step 1e-3.
        let ln = |x: f64, r: f64| {
            let d = [(x - cam.cx) / cam.fx, -(r - cam.cy) / cam.fy, -1.0];
            let dd = d.iter().map(|v| v * v).sum::<f64>();
            let dc = d.iter().zip(centre).map(|(a, b)| a * b).sum::<f64>();
            let cc = centre.iter().map(|v| v * v).sum::<f64>();
            ((dc - (dc * dc - dd * (cc - 1.0)).sqrt()) / dd).ln()
        };
        let (mut worst, mut max_slope) = (0.0f64, 0.0f64);
        let hh = 1e-3;
        for r in 1..h - 1 {
            for x in 1..w - 1 {
                let i = r * w + x;
                if sphere[i] < 0.5 || sphere[i - 1] < 0.5 || sphere[i + 1] < 0.5 {
                    continue;
                }
                if sphere[i - w] < 0.5 || sphere[i + w] < 0.5 {
                    continue;
                }
                let (xf, rf) = (x as f64, r as f64);
                let dx = (ln(xf + hh, rf) - ln(xf - hh, rf)) / (2.0 * hh);
                let dy = (ln(xf, rf - hh) - ln(xf, rf + hh)) / (2.0 * hh);
                worst = worst
                    .max((dx - f64::from(g.p[i])).abs())
                    .max((dy - f64::from(g.q[i])).abs());
                max_slope = max_slope.max(dx.abs()).max(dy.abs());
            }
        }
        let worst = worst / max_slope;
        eprintln!("log-depth gradients: max error {worst:.2e} of the max slope {max_slope:.3}");
        assert!(worst < 1e-3, "relative slope error {worst}");
    }

    #[test]
    fn a_rendered_perspective_sphere_is_recovered_up_to_scale() {
        // A unit sphere at distance 3 seen by a wide camera (f = 150 px, the sphere ≈ 100 px
        // across): pinhole masked_poisson vs the ray-cast depth after the best scale, relative
        // to the relief. Integrating the same normals orthographically is the wrong model.
        use super::super::{integrate_normals, Camera, IntegrateParams, IntegrationMethod};
        let (w, h) = (128, 112);
        let cam = Pinhole {
            fx: 150.0,
            fy: 150.0,
            cx: 60.5,
            cy: 58.0,
        };
        let (mut img, z, sphere) = render_sphere(w, h, &cam, [0.3, -0.2, -3.0], 1.0, None);
        // The sphere without its grazing rim (facing term d ≥ 0.15: slopes ≲ 7), like the
        // orthographic caps: at the outline itself the slope is unbounded.
        let sphere: Vec<f32> = (0..w * h)
            .map(|i| {
                let n = [img.normal()[0][i], img.normal()[1][i], img.normal()[2][i]];
                f32::from(u8::from(
                    sphere[i] > 0.5 && cam.facing(n, i % w, i / w) >= 0.15,
                ))
            })
            .collect();
        img.set_mask(Some(sphere.clone())).unwrap();
        let mut params = IntegrateParams {
            method: IntegrationMethod::MaskedPoisson,
            camera: Camera::Pinhole(cam),
            ..Default::default()
        };
        let (height, rep) = integrate_normals(&img, &params).unwrap();
        assert!(height.data().iter().all(|v| v.is_finite() && *v < 0.0));
        let zp: Vec<f32> = height.data().iter().map(|v| -v).collect();
        let ep = scaled_depth_error(&zp, z.data(), &sphere);
        params.camera = Camera::Orthographic;
        let (ho, _) = integrate_normals(&img, &params).unwrap();
        // Orthographic: height in pixels; the best affine map to depth is the fairest reading.
        let zo: Vec<f32> = ho.data().iter().map(|v| -v).collect();
        let idx: Vec<usize> = (0..w * h).filter(|&i| sphere[i] > 0.5).collect();
        let (mo, mg) = idx.iter().fold((0.0, 0.0), |a, &i| {
            (a.0 + f64::from(zo[i]), a.1 + f64::from(z.data()[i]))
        });
        let (mo, mg) = (mo / idx.len() as f64, mg / idx.len() as f64);
        let (so, oo) = idx.iter().fold((0.0, 0.0), |a, &i| {
            let d = f64::from(zo[i]) - mo;
            (a.0 + d * (f64::from(z.data()[i]) - mg), a.1 + d * d)
        });
        let s = so / oo;
        let zo_fit: Vec<f32> = zo
            .iter()
            .map(|&v| (s * (f64::from(v) - mo) + mg) as f32)
            .collect();
        let eo = scaled_depth_error(&zo_fit, z.data(), &sphere);
        eprintln!(
            "perspective sphere {w}×{h}: pinhole masked_poisson relative depth error {ep:.4} \
             ({} CG iterations, {} clamped); orthographic (best affine fit) {eo:.3}",
            rep.iterations, rep.clamped_pixels
        );
        assert!(ep <= 0.02, "{ep}");
        assert!(eo >= 5.0 * ep, "{eo}");
    }

    #[test]
    fn k_files_are_read_and_bad_ones_are_one_line_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("K.txt");
        std::fs::write(
            &p,
            "3.772077471010729823e+03 0.000000000000000000e+00 3.058750000000000000e+02\n\
             0.000000000000000000e+00 3.759005431071329895e+03 2.551250000000000000e+02\n\
             0.000000000000000000e+00 0.000000000000000000e+00 1.000000000000000000e+00\n",
        )
        .unwrap();
        let k = Pinhole::from_k_file(&p).unwrap();
        assert_eq!(
            (k.fx, k.cy),
            ("3.772077471010729823e+03".parse().unwrap(), 255.125)
        );
        for bad in [
            "1 0 2\n0 1 2\n",
            "1 0 2 3\n0 1 2\n0 0 1\n",
            "1 0 2\n0 1 2\n0 0 2\n",
            "-5 0 2\n0 5 2\n0 0 1\n",
            "0 0 2\n0 5 2\n0 0 1\n",
            "5 0 x\n0 5 2\n0 0 1\n",
            "5 1 2\n0 5 2\n0 0 1\n",
        ] {
            std::fs::write(&p, bad).unwrap();
            let e = Pinhole::from_k_file(&p).unwrap_err();
            let s = e.to_string();
            assert!(s.contains("k_file") && !s.contains('\n'), "{s}");
        }
        let e = Pinhole::from_k_file(&dir.path().join("none.txt")).unwrap_err();
        assert!(matches!(e, RgbnError::NotFound { .. }), "{e}");
        let mut c = Pinhole::centred(0.0, 4, 4);
        assert!(c.validate().unwrap_err().to_string().contains("focal_px"));
        (c.fx, c.fy) = (1.0, 1.0);
        c.cy = f64::NAN;
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("principal_y"));
    }

    #[test]
    fn height_of_log_depth_is_finite_and_has_geometric_mean_f() {
        let mut l = vec![0.1f32, -0.1, 1e30, f32::NAN, 0.0];
        let m = [1.0, 1.0, 0.0, 0.0, 1.0];
        height_of_log_depth(&mut l, Some(&m), 100.0);
        assert!(l.iter().all(|v| v.is_finite() && *v < 0.0), "{l:?}");
        let g = (f64::from(-l[0]) * f64::from(-l[1]) * f64::from(-l[4])).cbrt();
        assert!((g - 100.0).abs() < 1e-3, "{g}");
    }
}
