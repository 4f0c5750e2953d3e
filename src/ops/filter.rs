//! Linear filters on foreshorten-corrected gradients (Pereira & Velho §III).
//!
//! Normals → `(p, q) = (−n_x/n_z, −n_y/n_z)` → the same linear, shift-invariant kernel on `p`
//! and `q` → `n = normalize(−p, −q, 1)`. Because the kernel commutes with differentiation,
//! filtering the normals of a height `z` gives the normals of `z ∗ g`, and an integrable field
//! stays integrable (curl ≈ 0 up to the border treatment).
//!
//! # Kernels (CLI syntax in brackets)
//!
//! | kernel | effect on a gradient field `g` |
//! |---|---|
//! | Gaussian σ (`gauss:σ`) | `G_σ ∗ g` (recursive for σ ≥ 3, cost independent of σ) |
//! | Box r (`box:r`) | mean over a `(2r+1)²` window |
//! | Sharpen σ,k (`sharpen:σ,k`) | `g + k·(g − G_σ ∗ g)` (all-pass + k·high-pass) |
//! | Edge enhance σ₁,σ₂,k (`edge:σ₁,σ₂,k`) | `g + k·(G_σ₁ − G_σ₂) ∗ g` (all-pass + k·band-pass) |
//! | High-pass σ (`highpass:σ`) | `g − G_σ ∗ g` |
//! | DoG σ₁,σ₂ (`dog:σ₁,σ₂`) | `(G_σ₁ − G_σ₂) ∗ g` |
//! | LoG σ (`log:σ`) | `−σ²·∇²(G_σ ∗ g)` (scale-normalised, centre-positive) |
//! | Depth scale s (`scale:s`) | `s·g` (exaggerates or flattens relief) |
//! | Separable (`sep:r₀,r₁,…/c₀,c₁,…`) | row kernel then column kernel (odd lengths, as given) |
//! | Dense (`kernel:WxH:k₀,k₁,…`) | direct 2-D kernel, row 0 at the top, odd sizes ≤ 63 |
//!
//! **Borders.** No border extension of a gradient field is the gradient of a height in general,
//! so within the kernel's reach of the image border (≈3σ) the curl of a filtered integrable
//! field is not zero; the curl readout shows it. Away from the border it is zero to rounding.
//!
//! **Mask-aware** filtering uses normalised convolution inside the mask: every smoothing term
//! `S ∗ g` becomes `S ∗ (m·g) / S ∗ m`, so values outside the mask never bleed in, and the result
//! is blended with the original by coverage (`m·filtered + (1−m)·original`).

use crate::error::RgbnError;
use crate::raster::convolve::{self, BorderMode, Fir, LineFilter};
use crate::raster::gradient::{CurlStats, GradientField};
use crate::raster::smooth::smooth_normals;
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// Largest σ or radius accepted (pixels): beyond this a filter is a constant.
pub const MAX_SIGMA_PX: f32 = 4096.0;
/// Smallest σ a parameter accepts (pixels): narrower Gaussians are the identity to `f32`.
pub const MIN_SIGMA_PX: f64 = 0.05;
/// [`MIN_SIGMA_PX`] and [`MAX_SIGMA_PX`] as a parameter's range.
pub const SIGMA_RANGE: (f64, f64) = (MIN_SIGMA_PX, MAX_SIGMA_PX as f64);
/// The σ sliders' range (logarithmic): σ = 2 px sits at a third of it; larger σ can be typed.
pub const SIGMA_SOFT: (f64, f64) = (0.1, 64.0);
/// Largest side of a user kernel.
pub const MAX_USER_KERNEL: usize = 63;

/// A linear kernel applied to gradients. See the module docs for the maths.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Kernel {
    Gaussian {
        sigma_px: f32,
    },
    Box {
        radius_px: u32,
    },
    Sharpen {
        sigma_px: f32,
        amount: f32,
    },
    EdgeEnhance {
        sigma_fine_px: f32,
        sigma_coarse_px: f32,
        amount: f32,
    },
    HighPass {
        sigma_px: f32,
    },
    DoG {
        sigma_fine_px: f32,
        sigma_coarse_px: f32,
    },
    LoG {
        sigma_px: f32,
    },
    DepthScale {
        scale: f32,
    },
    Separable {
        row: Vec<f32>,
        col: Vec<f32>,
    },
    Dense {
        width: usize,
        height: usize,
        weights: Vec<f32>,
    },
}

/// The smoothing building blocks kernels are made of.
#[derive(Clone, Debug, PartialEq)]
enum Smoother<'a> {
    Gaussian(f32),
    Box(usize),
    Separable(&'a [f32], &'a [f32]),
    Dense(usize, usize, &'a [f32]),
}

/// Refuses a σ that is not in (0, [`MAX_SIGMA_PX`]] pixels, naming the parameter.
pub fn check_sigma(name: &str, s: f32) -> Result<(), RgbnError> {
    if !(s.is_finite() && s > 0.0 && s <= MAX_SIGMA_PX) {
        return Err(RgbnError::param(
            name,
            format!("{s} must be in (0, {MAX_SIGMA_PX}] pixels"),
        ));
    }
    Ok(())
}

fn check_finite(name: &str, v: f32) -> Result<(), RgbnError> {
    if !v.is_finite() || v.abs() > 1e6 {
        return Err(RgbnError::param(
            name,
            format!("{v} must be a finite number (|v| ≤ 1e6)"),
        ));
    }
    Ok(())
}

fn check_taps(name: &str, taps: &[f32]) -> Result<(), RgbnError> {
    if taps.is_empty() || taps.len().is_multiple_of(2) || taps.len() > MAX_USER_KERNEL {
        return Err(RgbnError::param(
            name,
            format!(
                "needs an odd number of taps (1..={MAX_USER_KERNEL}), got {}",
                taps.len()
            ),
        ));
    }
    if let Some(v) = taps.iter().find(|v| !v.is_finite()) {
        return Err(RgbnError::param(name, format!("tap {v} is not finite")));
    }
    Ok(())
}

impl Kernel {
    /// How far (pixels) an output gradient reaches into the input: the largest Gaussian's
    /// [`convolve::gaussian_support`], the box radius, half a user kernel (plus one for the
    /// Laplacian of LoG). Region evaluation crops with it (see
    /// [`crate::nodes::Footprint`]).
    #[must_use]
    pub fn support_px(&self) -> usize {
        let g = |s: &f32| convolve::gaussian_support(*s);
        match self {
            Kernel::Gaussian { sigma_px }
            | Kernel::Sharpen { sigma_px, .. }
            | Kernel::HighPass { sigma_px } => g(sigma_px),
            Kernel::LoG { sigma_px } => g(sigma_px) + 1,
            Kernel::EdgeEnhance {
                sigma_fine_px,
                sigma_coarse_px,
                ..
            }
            | Kernel::DoG {
                sigma_fine_px,
                sigma_coarse_px,
            } => g(sigma_fine_px).max(g(sigma_coarse_px)),
            Kernel::Box { radius_px } => *radius_px as usize,
            Kernel::DepthScale { .. } => 0,
            Kernel::Separable { row, col } => row.len().max(col.len()) / 2,
            Kernel::Dense { width, height, .. } => (*width).max(*height) / 2,
        }
    }

    /// Checks every parameter; filtering calls this first.
    pub fn validate(&self) -> Result<(), RgbnError> {
        match self {
            Kernel::Gaussian { sigma_px }
            | Kernel::HighPass { sigma_px }
            | Kernel::LoG { sigma_px } => check_sigma("sigma_px", *sigma_px),
            Kernel::Box { radius_px } => {
                if *radius_px == 0 || *radius_px as f32 > MAX_SIGMA_PX {
                    return Err(RgbnError::param(
                        "radius_px",
                        format!("{radius_px} must be in 1..={MAX_SIGMA_PX}"),
                    ));
                }
                Ok(())
            }
            Kernel::Sharpen { sigma_px, amount } => {
                check_sigma("sigma_px", *sigma_px)?;
                check_finite("amount", *amount)
            }
            Kernel::EdgeEnhance {
                sigma_fine_px,
                sigma_coarse_px,
                amount,
            } => {
                check_sigma("sigma_fine_px", *sigma_fine_px)?;
                check_sigma("sigma_coarse_px", *sigma_coarse_px)?;
                check_finite("amount", *amount)
            }
            Kernel::DoG {
                sigma_fine_px,
                sigma_coarse_px,
            } => {
                check_sigma("sigma_fine_px", *sigma_fine_px)?;
                check_sigma("sigma_coarse_px", *sigma_coarse_px)
            }
            Kernel::DepthScale { scale } => check_finite("scale", *scale),
            Kernel::Separable { row, col } => {
                check_taps("row", row)?;
                check_taps("col", col)
            }
            Kernel::Dense {
                width,
                height,
                weights,
            } => {
                for (n, v) in [("width", width), ("height", height)] {
                    if *v == 0 || v % 2 == 0 || *v > MAX_USER_KERNEL {
                        return Err(RgbnError::param(
                            n,
                            format!("{v} must be odd, 1..={MAX_USER_KERNEL}"),
                        ));
                    }
                }
                if weights.len() != width * height {
                    return Err(RgbnError::param(
                        "weights",
                        format!(
                            "a {width}x{height} kernel needs {} weights, got {}",
                            width * height,
                            weights.len()
                        ),
                    ));
                }
                check_taps("weights", &[0.0]).and_then(|()| {
                    weights.iter().find(|v| !v.is_finite()).map_or(Ok(()), |v| {
                        Err(RgbnError::param("weights", format!("{v} is not finite")))
                    })
                })
            }
        }
    }

    /// Parses the CLI syntax of the module docs, e.g. `gauss:8`, `sharpen:2,1.5`.
    pub fn parse(s: &str) -> Result<Self, RgbnError> {
        let (name, args) = s.split_once(':').unwrap_or((s, ""));
        let nums = |a: &str| -> Result<Vec<f32>, RgbnError> {
            a.split(',')
                .filter(|t| !t.trim().is_empty())
                .map(|t| {
                    t.trim().parse::<f32>().map_err(|_| {
                        RgbnError::param("kernel", format!("{t:?} in {s:?} is not a number"))
                    })
                })
                .collect()
        };
        let want = |v: Vec<f32>, n: usize, usage: &str| -> Result<Vec<f32>, RgbnError> {
            if v.len() == n {
                Ok(v)
            } else {
                Err(RgbnError::param(
                    "kernel",
                    format!("{s:?}: expected {usage}"),
                ))
            }
        };
        let k = match name.to_ascii_lowercase().as_str() {
            "gauss" | "gaussian" => Kernel::Gaussian {
                sigma_px: want(nums(args)?, 1, "gauss:SIGMA")?[0],
            },
            "box" => {
                let r = want(nums(args)?, 1, "box:RADIUS")?[0];
                if r.fract() != 0.0 || r < 1.0 {
                    return Err(RgbnError::param("kernel", format!("{s:?}: box radius must be a whole number ≥ 1")));
                }
                Kernel::Box { radius_px: r as u32 }
            }
            "sharpen" => {
                let v = want(nums(args)?, 2, "sharpen:SIGMA,AMOUNT")?;
                Kernel::Sharpen {
                    sigma_px: v[0],
                    amount: v[1],
                }
            }
            "edge" => {
                let v = want(nums(args)?, 3, "edge:SIGMA_FINE,SIGMA_COARSE,AMOUNT")?;
                Kernel::EdgeEnhance {
                    sigma_fine_px: v[0],
                    sigma_coarse_px: v[1],
                    amount: v[2],
                }
            }
            "highpass" => Kernel::HighPass {
                sigma_px: want(nums(args)?, 1, "highpass:SIGMA")?[0],
            },
            "dog" => {
                let v = want(nums(args)?, 2, "dog:SIGMA_FINE,SIGMA_COARSE")?;
                Kernel::DoG {
                    sigma_fine_px: v[0],
                    sigma_coarse_px: v[1],
                }
            }
            "log" => Kernel::LoG {
                sigma_px: want(nums(args)?, 1, "log:SIGMA")?[0],
            },
            "scale" => Kernel::DepthScale {
                scale: want(nums(args)?, 1, "scale:FACTOR")?[0],
            },
            "sep" => {
                let (r, c) = args.split_once('/').ok_or_else(|| {
                    RgbnError::param("kernel", format!("{s:?}: expected sep:ROW_TAPS/COLUMN_TAPS, e.g. sep:1,2,1/1,2,1"))
                })?;
                Kernel::Separable {
                    row: nums(r)?,
                    col: nums(c)?,
                }
            }
            "kernel" => {
                let (size, w) = args.split_once(':').ok_or_else(|| {
                    RgbnError::param("kernel", format!("{s:?}: expected kernel:WxH:WEIGHTS, e.g. kernel:3x3:0,-1,0,-1,5,-1,0,-1,0"))
                })?;
                let (kw, kh) = size
                    .split_once(['x', 'X'])
                    .and_then(|(a, b)| Some((a.trim().parse().ok()?, b.trim().parse().ok()?)))
                    .ok_or_else(|| RgbnError::param("kernel", format!("{s:?}: size {size:?} is not WxH")))?;
                Kernel::Dense {
                    width: kw,
                    height: kh,
                    weights: nums(w)?,
                }
            }
            other => {
                return Err(RgbnError::param(
                    "kernel",
                    format!("unknown kernel {other:?} (gauss, box, sharpen, edge, highpass, dog, log, scale, sep, kernel)"),
                ))
            }
        };
        k.validate()?;
        Ok(k)
    }

    /// Applies the kernel to one plane (in place). `mask_norm` holds the mask and, per smoother,
    /// its smoothed version, for normalised convolution.
    fn apply_plane(
        &self,
        x: &mut [f32],
        w: usize,
        h: usize,
        border: BorderMode,
        mask: Option<&[f32]>,
    ) {
        let smooth = |s: Smoother<'_>, src: &[f32]| -> Vec<f32> {
            smooth_plane(&s, src, w, h, border, mask)
        };
        if mask.is_none() {
            // Plain smoothers run in place: no copy of the plane in or out.
            match self {
                Kernel::Gaussian { sigma_px } => {
                    return convolve::gaussian(x, w, h, *sigma_px, border);
                }
                Kernel::Box { radius_px } => {
                    return convolve::box_blur(x, w, h, *radius_px as usize, border);
                }
                _ => {}
            }
        }
        match self {
            Kernel::Gaussian { sigma_px } => {
                let y = smooth(Smoother::Gaussian(*sigma_px), x);
                x.copy_from_slice(&y);
            }
            Kernel::Box { radius_px } => {
                let y = smooth(Smoother::Box(*radius_px as usize), x);
                x.copy_from_slice(&y);
            }
            Kernel::Sharpen { sigma_px, amount } => {
                let y = smooth(Smoother::Gaussian(*sigma_px), x);
                let k = *amount;
                x.par_iter_mut()
                    .zip(&y)
                    .for_each(|(a, b)| *a += k * (*a - b));
            }
            Kernel::EdgeEnhance {
                sigma_fine_px,
                sigma_coarse_px,
                amount,
            } => {
                let f = smooth(Smoother::Gaussian(*sigma_fine_px), x);
                let c = smooth(Smoother::Gaussian(*sigma_coarse_px), x);
                let k = *amount;
                x.par_iter_mut()
                    .zip(f.par_iter().zip(&c))
                    .for_each(|(a, (f, c))| *a += k * (f - c));
            }
            Kernel::HighPass { sigma_px } => {
                let y = smooth(Smoother::Gaussian(*sigma_px), x);
                x.par_iter_mut().zip(&y).for_each(|(a, b)| *a -= b);
            }
            Kernel::DoG {
                sigma_fine_px,
                sigma_coarse_px,
            } => {
                let f = smooth(Smoother::Gaussian(*sigma_fine_px), x);
                let c = smooth(Smoother::Gaussian(*sigma_coarse_px), x);
                x.par_iter_mut()
                    .zip(f.par_iter().zip(&c))
                    .for_each(|(a, (f, c))| *a = f - c);
            }
            Kernel::LoG { sigma_px } => {
                let y = smooth(Smoother::Gaussian(*sigma_px), x);
                let lap = convolve::laplacian(&y, w, h, border);
                let s2 = sigma_px * sigma_px;
                x.par_iter_mut().zip(&lap).for_each(|(a, l)| *a = -s2 * l);
            }
            Kernel::DepthScale { scale } => x.par_iter_mut().for_each(|a| *a *= scale),
            Kernel::Separable { row, col } => {
                let y = smooth(Smoother::Separable(row, col), x);
                x.copy_from_slice(&y);
            }
            Kernel::Dense {
                width,
                height,
                weights,
            } => {
                let y = smooth(Smoother::Dense(*width, *height, weights), x);
                x.copy_from_slice(&y);
            }
        }
    }
}

impl std::fmt::Display for Kernel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let list = |v: &[f32]| v.iter().map(f32::to_string).collect::<Vec<_>>().join(",");
        match self {
            Kernel::Gaussian { sigma_px } => write!(f, "gauss:{sigma_px}"),
            Kernel::Box { radius_px } => write!(f, "box:{radius_px}"),
            Kernel::Sharpen { sigma_px, amount } => write!(f, "sharpen:{sigma_px},{amount}"),
            Kernel::EdgeEnhance {
                sigma_fine_px,
                sigma_coarse_px,
                amount,
            } => write!(f, "edge:{sigma_fine_px},{sigma_coarse_px},{amount}"),
            Kernel::HighPass { sigma_px } => write!(f, "highpass:{sigma_px}"),
            Kernel::DoG {
                sigma_fine_px,
                sigma_coarse_px,
            } => write!(f, "dog:{sigma_fine_px},{sigma_coarse_px}"),
            Kernel::LoG { sigma_px } => write!(f, "log:{sigma_px}"),
            Kernel::DepthScale { scale } => write!(f, "scale:{scale}"),
            Kernel::Separable { row, col } => write!(f, "sep:{}/{}", list(row), list(col)),
            Kernel::Dense {
                width,
                height,
                weights,
            } => write!(f, "kernel:{width}x{height}:{}", list(weights)),
        }
    }
}

/// `S ∗ src`, or with a mask the normalised convolution `S ∗ (m·src) / S ∗ m` (falling back to
/// `src` where `S ∗ m` vanishes).
fn smooth_plane(
    s: &Smoother<'_>,
    src: &[f32],
    w: usize,
    h: usize,
    border: BorderMode,
    mask: Option<&[f32]>,
) -> Vec<f32> {
    let run = |buf: &mut Vec<f32>| match s {
        Smoother::Gaussian(sigma) => convolve::gaussian(buf, w, h, *sigma, border),
        Smoother::Box(r) => convolve::box_blur(buf, w, h, *r, border),
        Smoother::Separable(row, col) => convolve::convolve_separable(
            buf,
            w,
            h,
            &Fir { taps: row.to_vec() },
            &Fir { taps: col.to_vec() },
            border,
        ),
        Smoother::Dense(kw, kh, k) => *buf = convolve::convolve_2d(buf, w, h, k, *kw, *kh, border),
    };
    match mask {
        None => {
            let mut y = src.to_vec();
            run(&mut y);
            y
        }
        Some(m) => {
            let dc: f32 = match s {
                Smoother::Separable(r, c) => r.iter().sum::<f32>() * c.iter().sum::<f32>(),
                Smoother::Dense(_, _, k) => k.iter().sum(),
                _ => 1.0,
            };
            let mut num: Vec<f32> = src.par_iter().zip(m).map(|(v, m)| v * m).collect();
            let mut den = m.to_vec();
            run(&mut num);
            run(&mut den);
            num.par_iter_mut()
                .zip(den.par_iter().zip(src))
                .for_each(|(n, (d, s))| *n = if d.abs() > 1e-6 { *n / d * dc } else { *s });
            num
        }
    }
}

crate::params! {
    /// Options shared by every kernel.
    #[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    pub struct FilterOptions {
        /// How the image is extended beyond its border.
        pub border: BorderMode = BorderMode::Mirror => choice,
        /// Filter inside the image's mask only (normalised convolution).
        pub mask_aware: bool = false => bool,
    }
}

/// What a filter run measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FilterReport {
    /// Pixels whose `n_z` was clamped when converting to gradients.
    pub clamped: usize,
    pub curl_before: CurlStats,
    pub curl_after: CurlStats,
}

/// Applies `kernels` in order to a gradient field (both components).
pub fn filter_gradients(
    g: &mut GradientField,
    kernels: &[Kernel],
    opts: &FilterOptions,
    mask: Option<&[f32]>,
) -> Result<(), RgbnError> {
    for k in kernels {
        k.validate()?;
    }
    let (w, h) = (g.width, g.height);
    let m = if opts.mask_aware { mask } else { None };
    let orig = m.map(|_| (g.p.clone(), g.q.clone()));
    for k in kernels {
        k.apply_plane(&mut g.p, w, h, opts.border, m);
        k.apply_plane(&mut g.q, w, h, opts.border, m);
    }
    if let (Some(m), Some((p0, q0))) = (m, orig) {
        for (plane, orig) in [(&mut g.p, p0), (&mut g.q, q0)] {
            plane
                .par_iter_mut()
                .zip(orig.par_iter().zip(m))
                .for_each(|(v, (o, c))| *v = c * *v + (1.0 - c) * o);
        }
    }
    Ok(())
}

/// Filters the normals of `img` (colour and mask are shared, unchanged).
///
/// A single Gaussian or box kernel without mask-aware filtering runs fused (two sweeps over
/// the image, see [`crate::raster::smooth`]), a single sharpen, high-pass, edge-enhance or
/// difference of Gaussians as fused smoothings and one pointwise combination
/// (`filter_fused.rs`); everything else runs [`filter_normals_general`]. All give the same
/// normals (to rounding).
pub fn filter_normals(
    img: &RgbnImage,
    kernels: &[Kernel],
    opts: &FilterOptions,
) -> Result<(RgbnImage, FilterReport), RgbnError> {
    filter_with(img, kernels, opts, true)
}

/// [`filter_normals`] without the report's curl statistics where they would cost a pass of
/// their own (the graph's node: its readouts are taken apart from it, `Evaluator::readouts`).
///
/// # Errors
/// As [`filter_normals`].
pub fn filter_image(
    img: &RgbnImage,
    kernels: &[Kernel],
    opts: &FilterOptions,
) -> Result<RgbnImage, RgbnError> {
    Ok(filter_with(img, kernels, opts, false)?.0)
}

/// [`filter_normals`]; with `report` false the curl statistics that need a pass of their own
/// are left at their defaults.
fn filter_with(
    img: &RgbnImage,
    kernels: &[Kernel],
    opts: &FilterOptions,
    report: bool,
) -> Result<(RgbnImage, FilterReport), RgbnError> {
    let masked = opts.mask_aware && img.mask().is_some();
    match kernels {
        [k @ Kernel::Gaussian { sigma_px }] if !masked => {
            k.validate()?;
            if *sigma_px < convolve::IIR_MIN_SIGMA {
                filter_normals_fused(img, &Fir::gaussian(*sigma_px), opts.border)
            } else {
                filter_normals_fused(img, &convolve::Deriche::new(*sigma_px), opts.border)
            }
        }
        [k @ Kernel::Box { radius_px }] if !masked => {
            k.validate()?;
            let radius = *radius_px as usize;
            filter_normals_fused(img, &convolve::BoxFilter { radius }, opts.border)
        }
        [k] if !masked => {
            k.validate()?;
            let Some((normal, clamped, before)) = fused::combination(img, k, opts.border) else {
                return general(img, kernels, opts, report);
            };
            let out = img.with_normals(normal)?;
            let curl_after = if report {
                GradientField::from_normals(&out).curl_stats(img.mask())
            } else {
                CurlStats::default()
            };
            Ok((
                out,
                FilterReport {
                    clamped,
                    curl_before: before.stats(),
                    curl_after,
                },
            ))
        }
        _ => general(img, kernels, opts, report),
    }
}

fn filter_normals_fused<F: LineFilter>(
    img: &RgbnImage,
    f: &F,
    border: BorderMode,
) -> Result<(RgbnImage, FilterReport), RgbnError> {
    let [nx, ny, nz] = img.normal();
    let s = smooth_normals(
        [nx, ny, nz],
        img.mask(),
        img.width(),
        img.height(),
        f,
        border,
    );
    Ok((
        img.with_normals(s.normal)?,
        FilterReport {
            clamped: s.clamped,
            curl_before: s.curl_before.stats(),
            curl_after: s.curl_after.stats(),
        },
    ))
}

/// [`filter_normals`] for any kernel list, unfused: normals → gradient planes → curl
/// statistics → kernels plane by plane → statistics → normals. Also the reference the fused
/// path is tested and benchmarked against.
pub fn filter_normals_general(
    img: &RgbnImage,
    kernels: &[Kernel],
    opts: &FilterOptions,
) -> Result<(RgbnImage, FilterReport), RgbnError> {
    general(img, kernels, opts, true)
}

/// [`filter_normals_general`], its curl statistics taken only when `report` is set.
fn general(
    img: &RgbnImage,
    kernels: &[Kernel],
    opts: &FilterOptions,
    report: bool,
) -> Result<(RgbnImage, FilterReport), RgbnError> {
    let mut g = GradientField::from_normals(img);
    let stats = |g: &GradientField| {
        if report {
            g.curl_stats(img.mask())
        } else {
            CurlStats::default()
        }
    };
    let curl_before = stats(&g);
    filter_gradients(&mut g, kernels, opts, img.mask())?;
    let curl_after = stats(&g);
    // New normal planes; colour and mask stay shared with `img` (no copy of planes that are
    // about to be overwritten).
    let out = img.with_normals(g.to_normals())?;
    Ok((
        out,
        FilterReport {
            clamped: g.clamped,
            curl_before,
            curl_after,
        },
    ))
}

/// The parameters of one kernel as a graph node shows them (`filter.gaussian`, …): declared once
/// with [`crate::params!`], each with the [`Kernel`] it describes. The node form
/// (`crate::nodes::filter`) adds the operator id, title and doc, and the shared
/// [`FilterOptions`].
pub trait KernelParams: crate::params::Params {
    /// The kernel these parameters describe (validated by [`Kernel::validate`]).
    fn kernel(&self) -> Kernel;
    /// Whether the same filter on gradients reduced by `s` (a level of detail) is this one
    /// with its widths in pixels divided by `s` (as their declarations say: see
    /// `crate::params::scaled`); not for box radii (whole pixels), a LoG (its response scales
    /// with σ⁻²) or free kernels (taps).
    const COARSE: bool;
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|x| *x as f32).collect()
}

crate::params! {
    /// Gaussian blur.
    #[derive(Clone, Debug, PartialEq)]
    pub struct GaussianParams {
        /// Standard deviation of the Gaussian.
        pub sigma_px: f64 = 2.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
    }
}

impl KernelParams for GaussianParams {
    const COARSE: bool = true;
    fn kernel(&self) -> Kernel {
        Kernel::Gaussian {
            sigma_px: self.sigma_px as f32,
        }
    }
}

crate::params! {
    /// Box filter.
    #[derive(Clone, Debug, PartialEq)]
    pub struct BoxParams {
        /// Half-width: the mean over a (2r+1)² window.
        pub radius_px: i64 = 2 => int.unit("px").range(1.0, 4096.0).soft(1.0, 32.0).log(),
    }
}

impl KernelParams for BoxParams {
    const COARSE: bool = false;
    fn kernel(&self) -> Kernel {
        Kernel::Box {
            radius_px: self.radius_px.clamp(0, i64::from(u32::MAX)) as u32,
        }
    }
}

crate::params! {
    /// Unsharp masking.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SharpenParams {
        /// σ of the Gaussian whose residual is added.
        pub sigma_px: f64 = 2.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// How much of the high-pass is added.
        pub amount: f64 = 1.0 => float.range(-100.0, 100.0).soft(-2.0, 4.0),
    }
}

impl KernelParams for SharpenParams {
    const COARSE: bool = true;
    fn kernel(&self) -> Kernel {
        Kernel::Sharpen {
            sigma_px: self.sigma_px as f32,
            amount: self.amount as f32,
        }
    }
}

crate::params! {
    /// Band-pass enhancement.
    #[derive(Clone, Debug, PartialEq)]
    pub struct EdgeParams {
        /// σ of the finer Gaussian.
        pub sigma_fine_px: f64 = 1.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// σ of the coarser Gaussian.
        pub sigma_coarse_px: f64 = 4.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// How much of the band-pass is added.
        pub amount: f64 = 1.0 => float.range(-100.0, 100.0).soft(-2.0, 4.0),
    }
}

impl KernelParams for EdgeParams {
    const COARSE: bool = true;
    fn kernel(&self) -> Kernel {
        Kernel::EdgeEnhance {
            sigma_fine_px: self.sigma_fine_px as f32,
            sigma_coarse_px: self.sigma_coarse_px as f32,
            amount: self.amount as f32,
        }
    }
}

crate::params! {
    /// High-pass.
    #[derive(Clone, Debug, PartialEq)]
    pub struct HighPassParams {
        /// σ of the Gaussian removed.
        pub sigma_px: f64 = 4.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
    }
}

impl KernelParams for HighPassParams {
    const COARSE: bool = true;
    fn kernel(&self) -> Kernel {
        Kernel::HighPass {
            sigma_px: self.sigma_px as f32,
        }
    }
}

crate::params! {
    /// Difference of Gaussians.
    #[derive(Clone, Debug, PartialEq)]
    pub struct DogParams {
        /// σ of the finer Gaussian.
        pub sigma_fine_px: f64 = 1.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
        /// σ of the coarser Gaussian.
        pub sigma_coarse_px: f64 = 4.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
    }
}

impl KernelParams for DogParams {
    const COARSE: bool = true;
    fn kernel(&self) -> Kernel {
        Kernel::DoG {
            sigma_fine_px: self.sigma_fine_px as f32,
            sigma_coarse_px: self.sigma_coarse_px as f32,
        }
    }
}

crate::params! {
    /// Laplacian of Gaussian.
    #[derive(Clone, Debug, PartialEq)]
    pub struct LogParams {
        /// σ of the Gaussian.
        pub sigma_px: f64 = 2.0 => float.unit("px").range(SIGMA_RANGE.0, SIGMA_RANGE.1).soft(SIGMA_SOFT.0, SIGMA_SOFT.1).log(),
    }
}

impl KernelParams for LogParams {
    const COARSE: bool = false;
    fn kernel(&self) -> Kernel {
        Kernel::LoG {
            sigma_px: self.sigma_px as f32,
        }
    }
}

crate::params! {
    /// Depth scale.
    #[derive(Clone, Debug, PartialEq)]
    pub struct ScaleParams {
        /// Factor on the gradients.
        pub scale: f64 = 2.0 => float.range(-100.0, 100.0).soft(-4.0, 8.0),
    }
}

impl KernelParams for ScaleParams {
    const COARSE: bool = true;
    fn kernel(&self) -> Kernel {
        Kernel::DepthScale {
            scale: self.scale as f32,
        }
    }
}

crate::params! {
    /// A separable user kernel.
    #[derive(Clone, Debug, PartialEq)]
    pub struct SeparableParams {
        /// Taps (odd count ≤ 63), applied as given.
        pub row: Vec<f64> = vec![0.25, 0.5, 0.25] => floats.range(-1e6, 1e6),
        /// Taps (odd count ≤ 63), applied as given.
        pub col: Vec<f64> = vec![0.25, 0.5, 0.25] => floats.range(-1e6, 1e6),
    }
}

impl KernelParams for SeparableParams {
    const COARSE: bool = false;
    fn kernel(&self) -> Kernel {
        Kernel::Separable {
            row: f32s(&self.row),
            col: f32s(&self.col),
        }
    }
}

crate::params! {
    /// A dense user kernel.
    #[derive(Clone, Debug, PartialEq)]
    pub struct DenseParams {
        /// Kernel size (odd).
        pub width: i64 = 3 => int.unit("px").range(1.0, 63.0).soft(1.0, 15.0),
        /// Kernel size (odd).
        pub height: i64 = 3 => int.unit("px").range(1.0, 63.0).soft(1.0, 15.0),
        /// width × height weights, row-major, row 0 at the top.
        pub weights: Vec<f64> = vec![0.0, 0.125, 0.0, 0.125, 0.5, 0.125, 0.0, 0.125, 0.0]
            => floats.range(-1e6, 1e6),
    }
}

impl KernelParams for DenseParams {
    const COARSE: bool = false;
    fn kernel(&self) -> Kernel {
        Kernel::Dense {
            width: self.width.max(0) as usize,
            height: self.height.max(0) as usize,
            weights: f32s(&self.weights),
        }
    }
}

#[path = "filter_fused.rs"]
mod fused;

#[path = "filter_stream.rs"]
mod stream;
pub use stream::{filter_streamed, stream_halo};

#[cfg(test)]
#[path = "filter_tests.rs"]
mod tests;
