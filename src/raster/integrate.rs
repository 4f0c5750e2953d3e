//! Integration of normals / gradients to a height, and the integrability projection.
//!
//! # Discretisation
//!
//! The unknown is a height `z(x, r)` on the pixel grid (`r` = row, downwards; `y` up, see
//! [`gradient`](super::gradient)). Each gradient sample is one *edge equation* with the forward
//! differences of [`GradientField::from_height`]:
//!
//! - horizontal edge `(x, r)`, `x ≤ W−2`: `z(x+1, r) − z(x, r) = p(x, r)`,
//! - vertical edge `(x, r)`, `r ≥ 1`: `z(x, r−1) − z(x, r) = q(x, r)`.
//!
//! Writing these as `D z = g`, the least-squares height solves the normal equations
//! `Dᵀ D z = Dᵀ g`. `L = DᵀD` is the graph Laplacian of the grid with *natural Neumann*
//! boundaries, and `b = Dᵀg` is the discrete divergence
//! `b(x,r) = p(x−1,r) − p(x,r) + q(x,r+1) − q(x,r)` (terms whose edge does not exist dropped).
//! Because this is exactly the operator whose range holds every discrete gradient,
//! **integrating the discrete gradient of any height returns that height** up to a constant and
//! rounding, and the normals of the result have zero curl (to rounding).
//!
//! # Solvers
//!
//! - [`IntegrationMethod::PoissonDct`] (Simchony, Chellappa & Shao 1990): `L` is diagonalised by
//!   the 2-D DCT-II, with eigenvalues `λ(k,l) = (2 − 2cos(πk/W)) + (2 − 2cos(πl/H))`. So
//!   `z = DCT⁻¹[ DCT(b) / λ ]` with the `(0,0)` term (the free constant) set to 0: the result has
//!   zero mean. Cost: three passes over one buffer — row pairs (divergence fused, DCT-II along
//!   x); groups of 16 columns gathered in cache-line row segments (DCT-II along y, eigenvalue
//!   division, DCT-III along y, scattered back); row pairs (DCT-III along x) — no transposes.
//!   Each real DCT is Makhoul's reordering + one complex FFT, **two sequences per FFT** (packed
//!   as real and imaginary parts: the work of a half-length real FFT each); rustfft plans and
//!   twiddles are cached across calls; rustdct serves as the test oracle.
//!   **Precision: `f32` throughout** (as the input gradients and output heights). It keeps
//!   integration of exact discrete gradients to < 2e-3 px max error and the sum-of-Gaussians
//!   RMSE at ≈ 0.045 px (tests below), and matches an `f64` rustdct reference to 1e-4 of the
//!   amplitude; `f64` would double memory traffic for no visible gain at these tolerances.
//! - [`IntegrationMethod::FrankotChellappa`] (Frankot & Chellappa 1988): the same least squares
//!   but with **periodic** boundaries, solved with FFTs: with `a = e^{2πi k/W} − 1`,
//!   `c = e^{−2πi l/H} − 1` (the transfer functions of the two forward differences),
//!   `Ẑ = (ā P̂ + c̄ Q̂) / (|a|² + |c|²)`. Every gradient sample is used, including the last
//!   column's `p` and the top row's `q` as wrap-around edges. Exact for periodic heights; for
//!   others the wrap-around edges disagree and the error concentrates at the borders.
//!   Real-input packing (rows of `p + i q` split into half spectra, column FFTs on `W/2 + 1`
//!   bins with the solve fused, two Hermitian rows per inverse FFT): the FFT work of scipy's
//!   `rfft2` ×2 + `irfft2`, `f32`.
//! - [`IntegrationMethod::MaskedPoisson`]: only edges with both ends inside the mask
//!   (coverage ≥ 0.5) are equations, so nothing outside the object (background normals,
//!   depth discontinuities at the silhouette) leaks in. The masked Laplacian is solved by
//!   conjugate gradients with a Jacobi (node degree) preconditioner, in `f64`, warm-started from
//!   the DCT solution of the field with its off-domain edges set to 0. Each connected component
//!   of the mask has its own free constant (kept from the warm start); the result has zero mean
//!   over the mask. Pixels outside the mask keep the warm start (a smooth fill carrying no
//!   information).
//!
//! # Sampled normals are staggered
//!
//! A forward difference `z(x+1) − z(x)` is a central difference at `x + ½`. Feeding normals
//! sampled *at pixel centres* (as photometric stereo and renderers produce) therefore gives, to
//! second order, the height at `(x − ½, row + ½)`, not at `(x, row)`. The tests compare analytic
//! surfaces at that staggered position.
//!
//! # Integrability projection
//!
//! [`project_integrable`] replaces a normal field by the normals of its integrated height: the
//! gradient field nearest to it (least squares over the edges) among all discrete gradients,
//! i.e. the orthogonal projection onto the conservative fields. It reports the curl before and
//! after. An already integrable field is returned unchanged (to rounding).
//!
//! # References
//!
//! - T. Simchony, R. Chellappa, M. Shao, "Direct analytical methods for solving Poisson
//!   equations in computer vision problems", IEEE PAMI 12(5), 1990.
//! - R. T. Frankot, R. Chellappa, "A method for enforcing integrability in shape from shading
//!   algorithms", IEEE PAMI 10(4), 1988.
//! - A. Agrawal, R. Raskar, R. Chellappa, "What is the range of surface reconstructions from a
//!   gradient field?", ECCV 2006 (and Agrawal et al. 2005 for the curl readout).
//! - Y. Quéau, J.-D. Durou, J.-F. Aujol, "Normal integration: a survey", JMIV 60, 2018
//!   (discrete Poisson with Neumann boundaries on non-rectangular domains).

use super::gradient::{CurlStats, GradientField};
use super::{Plane, RgbnImage};
use crate::error::RgbnError;
use crate::raster::buf;
use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock, PoisonError};

/// How gradients become a height. See the module docs for the maths of each.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum IntegrationMethod {
    /// Least squares with Neumann boundaries on the full rectangle, DCT solver (fast, exact for
    /// discrete gradients). The mask is ignored.
    #[default]
    PoissonDct,
    /// Least squares with periodic boundaries, FFT solver. The mask is ignored.
    FrankotChellappa,
    /// Least squares over the edges inside the mask, Jacobi-preconditioned conjugate gradients
    /// warm-started from the DCT solution. Without a mask it equals `PoissonDct`.
    MaskedPoisson,
}

/// Parameters of [`integrate_gradients`] / [`integrate_normals`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IntegrateParams {
    pub method: IntegrationMethod,
    /// Conjugate-gradient iteration cap (masked method only), ≥ 1.
    pub max_iterations: u32,
    /// Stop when `‖b − L z‖ ≤ tolerance · ‖b‖` (masked method only), in (0, 1).
    pub tolerance: f64,
}

impl Default for IntegrateParams {
    fn default() -> Self {
        Self {
            method: IntegrationMethod::PoissonDct,
            max_iterations: 2000,
            tolerance: 1e-6,
        }
    }
}

impl IntegrateParams {
    /// Checks the ranges documented on the fields.
    pub fn validate(&self) -> Result<(), RgbnError> {
        if self.max_iterations == 0 {
            return Err(RgbnError::param("max_iterations", "must be at least 1"));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(RgbnError::param(
                "tolerance",
                format!("must be in (0, 1), got {}", self.tolerance),
            ));
        }
        Ok(())
    }
}

/// What an integration did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IntegrationReport {
    pub method: IntegrationMethod,
    /// Pixels in the integration domain (all pixels, or the mask).
    pub domain_pixels: usize,
    /// Conjugate-gradient iterations (0 for the direct solvers).
    pub iterations: u32,
    /// Final `‖b − L z‖ / ‖b‖` of the conjugate gradients (0 for the direct solvers).
    pub relative_residual: f64,
    /// RMS over the domain's edges of `D z − g`: how far the field is from integrable, in
    /// height units per pixel (0 for an integrable field).
    pub rms_residual: f64,
}

/// Coverage ≥ 0.5 counts as inside.
#[inline(always)]
fn inside(m: f32) -> bool {
    m >= 0.5
}

/// Checks a mask's length and that it is not empty.
fn check_mask(mask: Option<&[f32]>, w: usize, h: usize) -> Result<(), RgbnError> {
    if let Some(m) = mask {
        if m.len() != w * h {
            return Err(RgbnError::InvalidImage(format!(
                "mask has {} values for a {w}×{h} field",
                m.len()
            )));
        }
        if !m.par_iter().any(|&v| inside(v)) {
            return Err(RgbnError::EmptyMask {
                what: "the integration domain",
            });
        }
    }
    Ok(())
}

/// Integrates a gradient field to a height (pixels, mean 0 over the domain).
///
/// `mask` (coverage per pixel, ≥ 0.5 inside) is used by [`IntegrationMethod::MaskedPoisson`]
/// only; a mask with no pixel inside is an error for every method.
///
/// # Errors
/// Invalid parameters, a field whose planes do not match its size, a mask of the wrong size or
/// an empty mask.
pub fn integrate_gradients(
    g: &GradientField,
    mask: Option<&[f32]>,
    params: &IntegrateParams,
) -> Result<(Plane, IntegrationReport), RgbnError> {
    params.validate()?;
    let (w, h) = (g.width, g.height);
    if w == 0 || h == 0 || g.p.len() != w * h || g.q.len() != w * h {
        return Err(RgbnError::InvalidImage(format!(
            "gradient field {w}×{h} with {} p and {} q values",
            g.p.len(),
            g.q.len()
        )));
    }
    check_mask(mask, w, h)?;
    let mut report = IntegrationReport {
        method: params.method,
        domain_pixels: w * h,
        ..Default::default()
    };
    let z = match (params.method, mask) {
        (IntegrationMethod::FrankotChellappa, _) => frankot_chellappa(g),
        (IntegrationMethod::MaskedPoisson, Some(m)) => {
            report.domain_pixels = m.iter().filter(|&&v| inside(v)).count();
            let (z, it, rel) = masked_poisson(g, m, params);
            report.iterations = it;
            report.relative_residual = rel;
            z
        }
        _ => poisson_dct(g, None),
    };
    let dom = if params.method == IntegrationMethod::MaskedPoisson {
        mask
    } else {
        None
    };
    report.rms_residual = edge_residual_rms(&z, g, dom);
    Ok((z, report))
}

/// Integrates an image's normals (through [`GradientField::from_normals`]); the image's mask is
/// the domain of [`IntegrationMethod::MaskedPoisson`].
///
/// # Errors
/// As [`integrate_gradients`].
pub fn integrate_normals(
    img: &RgbnImage,
    params: &IntegrateParams,
) -> Result<(Plane, IntegrationReport), RgbnError> {
    integrate_gradients(&GradientField::from_normals(img), img.mask(), params)
}

/// Parameters of [`project_integrable`].
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProjectParams {
    /// The integration used for the projection. `MaskedPoisson` projects inside the mask and
    /// keeps the normals outside it.
    pub integrate: IntegrateParams,
}

impl ProjectParams {
    /// Checks the integration parameters.
    pub fn validate(&self) -> Result<(), RgbnError> {
        self.integrate.validate()
    }
}

/// Integrability before and after [`project_integrable`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProjectionReport {
    /// Curl of the input's gradients (over the mask's [`curl_interior`] if masked).
    pub before: CurlStats,
    /// Curl of the output's gradients (from its normals, so including unit-vector rounding).
    pub after: CurlStats,
    pub integration: IntegrationReport,
}

/// Replaces the normals by those of their integrated height: the nearest integrable field in
/// the least-squares sense (module docs). Colour and mask are shared with the input. Returns
/// the projected image, the height and the curl report.
///
/// # Errors
/// As [`integrate_gradients`].
pub fn project_integrable(
    img: &RgbnImage,
    params: &ProjectParams,
) -> Result<(RgbnImage, Plane, ProjectionReport), RgbnError> {
    params.validate()?;
    let g = GradientField::from_normals(img);
    let interior = img
        .mask()
        .map(|m| curl_interior(m, img.width(), img.height()));
    let before = g.curl_stats(interior.as_deref());
    let (z, integration) = integrate_gradients(&g, img.mask(), &params.integrate)?;
    let masked = params.integrate.method == IntegrationMethod::MaskedPoisson;
    let dom = if masked { img.mask() } else { None };
    let g2 = gradients_of_height(&z, dom, Some(&g));
    let mut out = img.clone();
    g2.write_normals(&mut out);
    let after = GradientField::from_normals(&out).curl_stats(interior.as_deref());
    Ok((
        out,
        z,
        ProjectionReport {
            before,
            after,
            integration,
        },
    ))
}

/// Pixels whose curl stencil (itself, above, right, above-right: every value the forward
/// differences of `p(x, r−1)`, `p(x, r)`, `q(x, r)`, `q(x+1, r)` read) lies inside the
/// mask: the curl readout of a masked field, free of values across the silhouette.
#[must_use]
pub fn curl_interior(mask: &[f32], w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, r) = (i % w, i / w);
            let ok = inside(mask[i])
                && r >= 1
                && inside(mask[i - w])
                && x + 1 < w
                && inside(mask[i + 1])
                && inside(mask[i - w + 1]);
            f32::from(u8::from(ok))
        })
        .collect()
}

/// Forward-difference gradients of a height restricted to a domain.
///
/// Without a domain this is [`GradientField::from_height`]. With one, a pixel inside uses the
/// forward difference if its forward neighbour is inside, else the backward difference if that
/// neighbour is inside, else `fallback`'s value (or 0); pixels outside take `fallback`'s values
/// (or 0). `fallback` must have the height's size.
#[must_use]
pub fn gradients_of_height(
    z: &Plane,
    domain: Option<&[f32]>,
    fallback: Option<&GradientField>,
) -> GradientField {
    let Some(m) = domain else {
        return GradientField::from_height(z);
    };
    let (w, h) = (z.width(), z.height());
    let d = z.data();
    let mut out = GradientField::zeros(w, h);
    out.p
        .par_chunks_mut(w)
        .zip(out.q.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, (pr, qr))| {
            for x in 0..w {
                let i = r * w + x;
                let (fp, fq) = fallback.map_or((0.0, 0.0), |f| (f.p[i], f.q[i]));
                if !inside(m[i]) {
                    (pr[x], qr[x]) = (fp, fq);
                    continue;
                }
                pr[x] = if x + 1 < w && inside(m[i + 1]) {
                    d[i + 1] - d[i]
                } else if x >= 1 && inside(m[i - 1]) {
                    d[i] - d[i - 1]
                } else {
                    fp
                };
                qr[x] = if r >= 1 && inside(m[i - w]) {
                    d[i - w] - d[i]
                } else if r + 1 < h && inside(m[i + w]) {
                    d[i] - d[i + w]
                } else {
                    fq
                };
            }
        });
    out
}

/// RMS of `D z − g` over the edges (inside the domain if given).
fn edge_residual_rms(z: &Plane, g: &GradientField, domain: Option<&[f32]>) -> f64 {
    let (w, h) = (g.width, g.height);
    let d = z.data();
    let ins = |i: usize| domain.is_none_or(|m| inside(m[i]));
    let (s, n) = (0..h)
        .into_par_iter()
        .map(|r| {
            let (mut s, mut n) = (0.0f64, 0usize);
            for x in 0..w {
                let i = r * w + x;
                if x + 1 < w && ins(i) && ins(i + 1) {
                    let e = f64::from(d[i + 1] - d[i] - g.p[i]);
                    s += e * e;
                    n += 1;
                }
                if r >= 1 && ins(i) && ins(i - w) {
                    let e = f64::from(d[i - w] - d[i] - g.q[i]);
                    s += e * e;
                    n += 1;
                }
            }
            (s, n)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// The divergence `b = Dᵀ g` (module docs); with a domain only edges inside it count.
fn divergence(g: &GradientField, domain: Option<&[f32]>) -> Vec<f32> {
    let mut b = buf::zeroed_f32(g.width * g.height);
    b.par_chunks_mut(g.width)
        .enumerate()
        .for_each(|(r, out)| divergence_row(g, domain, r, out));
    b
}

/// Row `r` of [`divergence`] into `out`.
fn divergence_row(g: &GradientField, domain: Option<&[f32]>, r: usize, out: &mut [f32]) {
    let (w, h) = (g.width, g.height);
    let row = r * w..(r + 1) * w;
    let Some(m) = domain else {
        // Every edge counts: p(x−1) − p(x) (ends dropped), + q below, − q here.
        let p = &g.p[row.clone()];
        out[0] = 0.0;
        out[1..].copy_from_slice(&p[..w - 1]);
        for (o, v) in out[..w - 1].iter_mut().zip(p) {
            *o -= v;
        }
        if r + 1 < h {
            for (o, v) in out.iter_mut().zip(&g.q[row.start + w..row.end + w]) {
                *o += v;
            }
        }
        if r >= 1 {
            for (o, v) in out.iter_mut().zip(&g.q[row]) {
                *o -= v;
            }
        }
        return;
    };
    let (p, q) = (&g.p, &g.q);
    let ins = |i: usize| inside(m[i]);
    for (x, o) in out.iter_mut().enumerate() {
        let i = r * w + x;
        let mut s = 0.0f32;
        if ins(i) {
            if x >= 1 && ins(i - 1) {
                s += p[i - 1];
            }
            if x + 1 < w && ins(i + 1) {
                s -= p[i];
            }
            if r + 1 < h && ins(i + w) {
                s += q[i + w];
            }
            if r >= 1 && ins(i - w) {
                s -= q[i];
            }
        }
        *o = s;
    }
}

type C32 = Complex<f32>;

const C_ZERO: C32 = Complex::new(0.0, 0.0);

/// Plans shared by every call: rustfft's planner (it caches its FFTs) and the DCT twiddles.
/// Planning a 4K transform costs about as much as running it once, so caching matters for
/// repeated calls (the editor, batch runs). Bounded: past [`MAX_CACHED_DCT_SIZES`] sizes the DCT
/// map is cleared (the planner's own cache is small: a few twiddle tables per size).
struct Plans {
    planner: FftPlanner<f32>,
    dct: HashMap<usize, Arc<PairedDct>>,
}

/// See [`Plans`].
const MAX_CACHED_DCT_SIZES: usize = 64;

fn plans() -> MutexGuard<'static, Plans> {
    static PLANS: OnceLock<Mutex<Plans>> = OnceLock::new();
    PLANS
        .get_or_init(|| {
            Mutex::new(Plans {
                planner: FftPlanner::new(),
                dct: HashMap::new(),
            })
        })
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
}

/// The cached [`PairedDct`] of one length.
fn dct_plan(len: usize) -> Arc<PairedDct> {
    let mut guard = plans();
    let Plans { planner, dct } = &mut *guard;
    if dct.len() >= MAX_CACHED_DCT_SIZES && !dct.contains_key(&len) {
        dct.clear();
    }
    dct.entry(len)
        .or_insert_with(|| Arc::new(PairedDct::new(len, planner)))
        .clone()
}

/// A cached complex FFT of one length (unnormalised in both directions).
fn fft_plan(len: usize, inverse: bool) -> Arc<dyn Fft<f32>> {
    let mut guard = plans();
    if inverse {
        guard.planner.plan_fft_inverse(len)
    } else {
        guard.planner.plan_fft_forward(len)
    }
}

/// A raw pointer that rayon tasks share to write disjoint column groups of one buffer.
struct SharedMut<T>(*mut T);

impl<T> Clone for SharedMut<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for SharedMut<T> {}

impl<T> SharedMut<T> {
    /// The pointer. A method (not field access) so closures capture the whole `Sync` wrapper.
    fn get(self) -> *mut T {
        self.0
    }
}
// SAFETY: only used by `par_column_groups`, whose tasks touch disjoint columns.
unsafe impl<T: Send> Send for SharedMut<T> {}
unsafe impl<T: Send> Sync for SharedMut<T> {}

/// Columns `c0..c0 + cols` of every row of a row-major buffer, owned by one rayon task.
struct ColumnGroup<'a, T> {
    ptr: SharedMut<T>,
    width: usize,
    height: usize,
    c0: usize,
    cols: usize,
    _data: std::marker::PhantomData<&'a mut [T]>,
}

impl<T> ColumnGroup<'_, T> {
    /// The group's part of row `r` (borrowing the group, so one row slice at a time).
    fn row(&mut self, r: usize) -> &mut [T] {
        assert!(r < self.height);
        // SAFETY: columns c0..c0+cols of row r lie inside the buffer (r < height and
        // c0 + cols ≤ width by construction in `par_column_groups`); no other task touches
        // these columns while the group lives, and `&mut self` allows one slice at a time.
        unsafe {
            std::slice::from_raw_parts_mut(self.ptr.get().add(r * self.width + self.c0), self.cols)
        }
    }
}

/// Runs `f(state, group)` for groups of `group` columns (fewer in the last) of a row-major
/// `width`-wide buffer, groups in parallel, with one `init()` state per rayon job. Columns are
/// gathered / scattered in row segments a cache line wide, so a column transform moves no
/// more memory than a row pass and needs no transpose.
fn par_column_groups<T: Send, S: Send>(
    data: &mut [T],
    width: usize,
    group: usize,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, &mut ColumnGroup<'_, T>) + Sync + Send,
) {
    if width == 0 || data.is_empty() {
        return;
    }
    let height = data.len() / width;
    assert_eq!(data.len(), width * height);
    let ptr = SharedMut(data.as_mut_ptr());
    (0..width.div_ceil(group))
        .into_par_iter()
        .for_each_init(init, |state, gi| {
            let c0 = gi * group;
            let mut cg = ColumnGroup {
                ptr,
                width,
                height,
                c0,
                cols: group.min(width - c0),
                _data: std::marker::PhantomData,
            };
            f(state, &mut cg);
        });
}

/// Runs `f(r, a, b, buf, scratch)` on pairs of rows (`a` = row `r`, `b` = row `r + 1`, absent
/// for an odd last row) of a row-major buffer of rows of `len`, pairs in parallel, with one
/// complex buffer of `len` and one FFT scratch of `scratch_len` per rayon job.
fn for_row_pairs(
    data: &mut [f32],
    len: usize,
    scratch_len: usize,
    f: impl Fn(usize, &mut [f32], Option<&mut [f32]>, &mut [C32], &mut [C32]) + Sync + Send,
) {
    data.par_chunks_mut(2 * len)
        .enumerate()
        .with_min_len(4)
        .for_each_init(
            || (vec![C_ZERO; len], vec![C_ZERO; scratch_len]),
            |(buf, scratch), (i, rows)| {
                let (a, b) = rows.split_at_mut(len);
                let b = (!b.is_empty()).then_some(b);
                f(2 * i, a, b, buf, scratch);
            },
        );
}

/// Unnormalised DCT-II / DCT-III of real sequences of one length, two sequences per complex
/// FFT.
///
/// Makhoul (1980): with the reordering `v[n] = x[2n]`, `v[N−1−n] = x[2n+1]` and `V = FFT(v)`,
/// `DCT-II(x)[k] = Σ x_n cos(π(2n+1)k/2N) = Re(e^{−iπk/2N} V_k)`; conversely
/// `V_k = e^{iπk/2N} (X_k − i X_{N−k})` (`X_N = 0`) and the inverse FFT gives `v` back.
/// Because `v` is real, two sequences `a`, `b` share one FFT of `a + i b`, separated by
/// `A_k = (C_k + C̄_{N−k})/2`, `B_k = (C_k − C̄_{N−k})/2i` — the same work as one real-input FFT
/// of half length per sequence. The DCT-III here is rustdct's convention
/// (`X_0/2 + Σ_{k≥1} X_k cos(…)`), so `DCT-III(DCT-II(x)) = N/2 · x`.
struct PairedDct {
    len: usize,
    fwd: Arc<dyn Fft<f32>>,
    inv: Arc<dyn Fft<f32>>,
    /// `e^{−iπk/2N} / 2` (the ½ of the separation folded in).
    half_twiddle: Vec<C32>,
    /// `e^{+iπk/2N} / 2` (the ½ of the DCT-III convention folded in).
    half_twiddle_inv: Vec<C32>,
    /// Makhoul position of sample `n`: `v[pos[n]] = x[n]`.
    pos: Vec<usize>,
    scratch_len: usize,
}

impl PairedDct {
    fn new(len: usize, planner: &mut FftPlanner<f32>) -> Self {
        let tw = |sign: f64| -> Vec<C32> {
            (0..len)
                .map(|k| {
                    let a = sign * std::f64::consts::PI * k as f64 / (2.0 * len as f64);
                    Complex::new((0.5 * a.cos()) as f32, (0.5 * a.sin()) as f32)
                })
                .collect()
        };
        let fwd = planner.plan_fft_forward(len);
        let inv = planner.plan_fft_inverse(len);
        let scratch_len = fwd
            .get_inplace_scratch_len()
            .max(inv.get_inplace_scratch_len());
        Self {
            len,
            fwd,
            inv,
            half_twiddle: tw(-1.0),
            half_twiddle_inv: tw(1.0),
            pos: (0..len)
                .map(|n| if n % 2 == 0 { n / 2 } else { len - 1 - n / 2 })
                .collect(),
            scratch_len,
        }
    }

    /// Makhoul-reorders `a` (real parts) and `b` (imaginary parts, 0 if absent) into `buf`.
    fn load(&self, a: &[f32], b: Option<&[f32]>, buf: &mut [C32]) {
        let n = self.len;
        // lo[m] = x[2m], hi reversed: buf[N−1−m] = x[2m+1].
        let (lo, hi) = buf.split_at_mut(n - n / 2);
        match b {
            Some(b) => {
                for (((l, u), pa), pb) in lo
                    .iter_mut()
                    .zip(hi.iter_mut().rev())
                    .zip(a.chunks_exact(2))
                    .zip(b.chunks_exact(2))
                {
                    *l = Complex::new(pa[0], pb[0]);
                    *u = Complex::new(pa[1], pb[1]);
                }
                if n % 2 == 1 {
                    lo[n / 2] = Complex::new(a[n - 1], b[n - 1]);
                }
            }
            None => {
                for ((l, u), pa) in lo
                    .iter_mut()
                    .zip(hi.iter_mut().rev())
                    .zip(a.chunks_exact(2))
                {
                    *l = Complex::new(pa[0], 0.0);
                    *u = Complex::new(pa[1], 0.0);
                }
                if n % 2 == 1 {
                    lo[n / 2] = Complex::new(a[n - 1], 0.0);
                }
            }
        }
    }

    /// From the forward FFT `buf` of a loaded pair: the DCT-II of the real parts into `xa` and
    /// of the imaginary parts into `xb`.
    fn post2(&self, buf: &[C32], xa: &mut [f32], xb: Option<&mut [f32]>) {
        let n = self.len;
        xa[0] = buf[0].re;
        // (C_k, C_{N−k}) for k = 1..N.
        let (t, c) = (&self.half_twiddle[1..n], &buf[1..n]);
        for (((o, t), c), d) in xa[1..n].iter_mut().zip(t).zip(c).zip(c.iter().rev()) {
            *o = t.re * (c.re + d.re) - t.im * (c.im - d.im);
        }
        if let Some(xb) = xb {
            xb[0] = buf[0].im;
            for (((o, t), c), d) in xb[1..n].iter_mut().zip(t).zip(c).zip(c.iter().rev()) {
                *o = t.re * (c.im + d.im) + t.im * (c.re - d.re);
            }
        }
    }

    /// The inverse-FFT input whose result holds the reordered DCT-IIIs of `xa` (real parts) and
    /// `xb` (imaginary parts, 0 if absent).
    fn pre3(&self, xa: &[f32], xb: Option<&[f32]>, buf: &mut [C32]) {
        let n = self.len;
        let t = &self.half_twiddle_inv;
        // V_k = t_k·(X_k − i X_{N−k}) (X_N = 0); C = Va + i Vb.
        let v = |t: C32, x: f32, y: f32| Complex::new(t.re * x + t.im * y, t.im * x - t.re * y);
        let join = |va: C32, vb: C32| Complex::new(va.re - vb.im, va.im + vb.re);
        let (ta, xa1) = (&t[1..n], &xa[1..n]);
        match xb {
            Some(xb) => {
                buf[0] = join(v(t[0], xa[0], 0.0), v(t[0], xb[0], 0.0));
                let xb1 = &xb[1..n];
                for ((((o, &t), (&a, &ar)), &b), &br) in buf[1..n]
                    .iter_mut()
                    .zip(ta)
                    .zip(xa1.iter().zip(xa1.iter().rev()))
                    .zip(xb1)
                    .zip(xb1.iter().rev())
                {
                    *o = join(v(t, a, ar), v(t, b, br));
                }
            }
            None => {
                buf[0] = v(t[0], xa[0], 0.0);
                for ((o, &t), (&a, &ar)) in buf[1..n]
                    .iter_mut()
                    .zip(ta)
                    .zip(xa1.iter().zip(xa1.iter().rev()))
                {
                    *o = v(t, a, ar);
                }
            }
        }
    }

    /// Undoes the Makhoul order of an inverse FFT `buf` into `a` (real parts) and `b`.
    fn store(&self, buf: &[C32], a: &mut [f32], b: Option<&mut [f32]>) {
        let n = self.len;
        let (lo, hi) = buf.split_at(n - n / 2);
        for ((l, u), pa) in lo.iter().zip(hi.iter().rev()).zip(a.chunks_exact_mut(2)) {
            pa[0] = l.re;
            pa[1] = u.re;
        }
        if n % 2 == 1 {
            a[n - 1] = lo[n / 2].re;
        }
        if let Some(b) = b {
            for ((l, u), pb) in lo.iter().zip(hi.iter().rev()).zip(b.chunks_exact_mut(2)) {
                pb[0] = l.im;
                pb[1] = u.im;
            }
            if n % 2 == 1 {
                b[n - 1] = lo[n / 2].im;
            }
        }
    }

    /// In-place DCT-II of `a` and (if present) `b`.
    fn dct2_pair(&self, a: &mut [f32], b: Option<&mut [f32]>, buf: &mut [C32], s: &mut [C32]) {
        self.load(a, b.as_deref(), buf);
        self.fwd.process_with_scratch(buf, s);
        self.post2(buf, a, b);
    }

    /// In-place DCT-III (rustdct convention) of `a` and (if present) `b`.
    fn dct3_pair(&self, a: &mut [f32], b: Option<&mut [f32]>, buf: &mut [C32], s: &mut [C32]) {
        self.pre3(a, b.as_deref(), buf);
        self.inv.process_with_scratch(buf, s);
        self.store(buf, a, b);
    }

    /// In-place DCT-II of every row of `data` (rows of `self.len`), rows in parallel.
    #[cfg(test)]
    fn dct2_rows(&self, data: &mut [f32]) {
        for_row_pairs(data, self.len, self.scratch_len, |_, a, b, buf, s| {
            self.dct2_pair(a, b, buf, s);
        });
    }

    /// In-place DCT-III (rustdct convention) of every row of `data`.
    #[cfg(test)]
    fn dct3_rows(&self, data: &mut [f32]) {
        for_row_pairs(data, self.len, self.scratch_len, |_, a, b, buf, s| {
            self.dct3_pair(a, b, buf, s);
        });
    }
}

/// Columns per group of the column passes: one 64-byte cache line of `f32` per row.
const DCT_COLUMN_GROUP: usize = 16;

/// Solves `L z = Dᵀ g` (full rectangle, Neumann) with DCTs; the domain restricts the edges of
/// the divergence only (used for the masked warm start).
///
/// Three passes over one buffer: (1) row pairs: divergence, DCT-II along x; (2) groups of 16
/// columns gathered into pair buffers: DCT-II along y, division by the eigenvalues, DCT-III
/// along y, scattered back; (3) row pairs: DCT-III along x.
fn poisson_dct(g: &GradientField, domain: Option<&[f32]>) -> Plane {
    let (w, h) = (g.width, g.height);
    let (dw, dh) = (dct_plan(w), dct_plan(h));
    let mut z = buf::zeroed_f32(w * h);
    for_row_pairs(&mut z, w, dw.scratch_len, |r, a, mut b, buf, s| {
        divergence_row(g, domain, r, a);
        if let Some(b) = b.as_deref_mut() {
            divergence_row(g, domain, r + 1, b);
        }
        dw.dct2_pair(a, b, buf, s);
    });
    // Eigenvalues; DCT-III ∘ DCT-II = N/2 per axis, so scale by 4/(W·H).
    let eig = |n: usize| -> Vec<f32> {
        (0..n)
            .map(|k| (2.0 - 2.0 * (std::f64::consts::PI * k as f64 / n as f64).cos()) as f32)
            .collect()
    };
    let (lx, ly) = (eig(w), eig(h));
    let scale = (4.0 / (w as f64 * h as f64)) as f32;
    let divide = |x: &mut [f32], kx: usize| {
        for (v, &l) in x.iter_mut().zip(&ly) {
            let lam = lx[kx] + l;
            *v = if lam > 0.0 { *v * scale / lam } else { 0.0 };
        }
    };
    let pairs_max = DCT_COLUMN_GROUP / 2;
    par_column_groups(
        &mut z,
        w,
        DCT_COLUMN_GROUP,
        || {
            (
                vec![C_ZERO; pairs_max * h],
                vec![C_ZERO; dh.scratch_len],
                buf::zeroed_f32(2 * h),
            )
        },
        |(buf, scratch, x2), grp| {
            let (c0, cols) = (grp.c0, grp.cols);
            let buf = &mut buf[..cols.div_ceil(2) * h];
            for (r, &pos) in dh.pos.iter().enumerate() {
                let row = grp.row(r);
                let mut pairs = row.chunks_exact(2);
                for (col, pair) in buf.chunks_exact_mut(h).zip(&mut pairs) {
                    col[pos] = Complex::new(pair[0], pair[1]);
                }
                if let [x] = pairs.remainder() {
                    buf[cols / 2 * h + pos] = Complex::new(*x, 0.0);
                }
            }
            dh.fwd.process_with_scratch(buf, scratch);
            let (xa, xb) = x2.split_at_mut(h);
            for (j, col) in buf.chunks_exact_mut(h).enumerate() {
                let has_b = 2 * j + 1 < cols;
                dh.post2(col, xa, has_b.then_some(&mut *xb));
                divide(xa, c0 + 2 * j);
                if has_b {
                    divide(xb, c0 + 2 * j + 1);
                }
                dh.pre3(xa, has_b.then_some(&*xb), col);
            }
            dh.inv.process_with_scratch(buf, scratch);
            for (r, &pos) in dh.pos.iter().enumerate() {
                let row = grp.row(r);
                let mut pairs = row.chunks_exact_mut(2);
                for (col, pair) in buf.chunks_exact(h).zip(&mut pairs) {
                    pair[0] = col[pos].re;
                    pair[1] = col[pos].im;
                }
                if let [x] = pairs.into_remainder() {
                    *x = buf[cols / 2 * h + pos].re;
                }
            }
        },
    );
    for_row_pairs(&mut z, w, dw.scratch_len, |_, a, b, buf, s| {
        dw.dct3_pair(a, b, buf, s);
    });
    Plane::from_vec(w, h, z).expect("sizes match by construction")
}

/// Frequency bins per group of the Frankot–Chellappa column pass (P and Q interleaved: two
/// 64-byte lines per row).
const FFT_COLUMN_GROUP: usize = 8;

/// Frankot–Chellappa: periodic least squares with FFTs (module docs).
///
/// Real-input transforms without waste: (1) each row of `p + i q` is one complex FFT, split
/// into the half spectra (`W/2 + 1` bins) of the `p` and `q` rows, stored interleaved;
/// (2) groups of 8 bins: FFT along y of both, `Ẑ = (ā P̂ + c̄ Q̂)/(|a|² + |c|²)`, inverse FFT
/// along y; (3) two rows of `Ẑ` (Hermitian along x) per inverse FFT of length `W` give two
/// height rows. That is the work of scipy's `rfft2` ×2 + `irfft2`, half the complex 2-D FFTs.
fn frankot_chellappa(g: &GradientField) -> Plane {
    let (w, h) = (g.width, g.height);
    let (fw, iw) = (fft_plan(w, false), fft_plan(w, true));
    let (fh, ih) = (fft_plan(h, false), fft_plan(h, true));
    let hw = w / 2 + 1;
    // (1) Row r of `spec`: [P_0, Q_0, P_1, Q_1, …, P_{hw−1}, Q_{hw−1}].
    let mut spec = vec![C_ZERO; h * 2 * hw];
    spec.par_chunks_mut(2 * hw)
        .zip(g.p.par_chunks(w).zip(g.q.par_chunks(w)))
        .with_min_len(4)
        .for_each_init(
            || (vec![C_ZERO; w], vec![C_ZERO; fw.get_inplace_scratch_len()]),
            |(buf, scratch), (s, (p, q))| {
                for ((o, &pv), &qv) in buf.iter_mut().zip(p).zip(q) {
                    *o = Complex::new(pv, qv);
                }
                fw.process_with_scratch(buf, scratch);
                for (k, pq) in s.chunks_exact_mut(2).enumerate() {
                    let c = buf[k];
                    let d = buf[if k == 0 { 0 } else { w - k }].conj();
                    pq[0] = (c + d) * 0.5;
                    pq[1] = (c - d) * Complex::new(0.0, -0.5);
                }
            },
        );
    // (2) ā per x bin, c̄ per y bin (transfer functions of the forward differences), 1/(W·H).
    let tau = std::f64::consts::TAU;
    let abar: Vec<C32> = (0..hw)
        .map(|k| {
            let t = tau * k as f64 / w as f64;
            Complex::new((t.cos() - 1.0) as f32, -t.sin() as f32)
        })
        .collect();
    let cbar: Vec<C32> = (0..h)
        .map(|l| {
            let t = -tau * l as f64 / h as f64;
            Complex::new((t.cos() - 1.0) as f32, -t.sin() as f32)
        })
        .collect();
    let scale = (1.0 / (w as f64 * h as f64)) as f32;
    let scratch_len = fh
        .get_inplace_scratch_len()
        .max(ih.get_inplace_scratch_len());
    let g_max = FFT_COLUMN_GROUP;
    par_column_groups(
        &mut spec,
        2 * hw,
        2 * g_max,
        || (vec![C_ZERO; 2 * g_max * h], vec![C_ZERO; scratch_len]),
        |(buf, scratch), grp| {
            let (k0, bins) = (grp.c0 / 2, grp.cols / 2);
            let (pb, qb) = buf.split_at_mut(g_max * h);
            let (pb, qb) = (&mut pb[..bins * h], &mut qb[..bins * h]);
            for r in 0..h {
                for (j, pq) in grp.row(r).chunks_exact(2).enumerate() {
                    pb[j * h + r] = pq[0];
                    qb[j * h + r] = pq[1];
                }
            }
            fh.process_with_scratch(pb, scratch);
            fh.process_with_scratch(qb, scratch);
            for (j, (pc, qc)) in pb.chunks_exact_mut(h).zip(qb.chunks_exact(h)).enumerate() {
                let kx = k0 + j;
                let a = abar[kx];
                let na = a.norm_sqr();
                for (l, (pv, qv)) in pc.iter_mut().zip(qc).enumerate() {
                    let c = cbar[l];
                    let den = na + c.norm_sqr();
                    *pv = if kx == 0 && l == 0 {
                        C_ZERO
                    } else {
                        (a * *pv + c * *qv) * (scale / den)
                    };
                }
            }
            ih.process_with_scratch(pb, scratch);
            for r in 0..h {
                for (j, pq) in grp.row(r).chunks_exact_mut(2).enumerate() {
                    pq[0] = pb[j * h + r];
                }
            }
        },
    );
    // (3) Two Hermitian rows per inverse FFT: z_r + i z_{r+1} = IFFT(Ẑ_r + i Ẑ_{r+1}).
    let mut z = buf::zeroed_f32(w * h);
    z.par_chunks_mut(2 * w)
        .zip(spec.par_chunks(4 * hw))
        .with_min_len(4)
        .for_each_init(
            || (vec![C_ZERO; w], vec![C_ZERO; iw.get_inplace_scratch_len()]),
            |(buf, scratch), (out, s)| {
                let z1 = |k: usize| s[2 * k];
                let z2 = |k: usize| s.get(2 * hw + 2 * k).copied().unwrap_or(C_ZERO);
                // Ẑ_0 and (W even) Ẑ_{W/2} are real by symmetry: drop their rounding.
                let real = |v: C32| Complex::new(v.re, 0.0);
                let join = |u: C32, v: C32| Complex::new(u.re - v.im, u.im + v.re);
                buf[0] = join(real(z1(0)), real(z2(0)));
                let (lo, hi) = buf.split_at_mut(hw.min(w));
                for (k, o) in lo.iter_mut().enumerate().skip(1) {
                    *o = join(z1(k), z2(k));
                }
                for (k, o) in (hw..w).zip(hi.iter_mut()) {
                    *o = join(z1(w - k).conj(), z2(w - k).conj());
                }
                if w % 2 == 0 && w > 1 {
                    buf[w / 2] = join(real(z1(w / 2)), real(z2(w / 2)));
                }
                iw.process_with_scratch(buf, scratch);
                let (a, b) = out.split_at_mut(w);
                for (x, v) in buf.iter().enumerate() {
                    a[x] = v.re;
                    if let Some(o) = b.get_mut(x) {
                        *o = v.im;
                    }
                }
            },
        );
    Plane::from_vec(w, h, z).expect("sizes match by construction")
}

/// `y = L x` for the masked Laplacian (edges with both ends inside).
fn apply_masked_laplacian(x: &[f64], m: &[f32], w: usize, h: usize, y: &mut [f64]) {
    y.par_chunks_mut(w).enumerate().for_each(|(r, out)| {
        for (xx, o) in out.iter_mut().enumerate() {
            let i = r * w + xx;
            if !inside(m[i]) {
                *o = 0.0;
                continue;
            }
            let mut s = 0.0;
            let xi = x[i];
            if xx >= 1 && inside(m[i - 1]) {
                s += xi - x[i - 1];
            }
            if xx + 1 < w && inside(m[i + 1]) {
                s += xi - x[i + 1];
            }
            if r >= 1 && inside(m[i - w]) {
                s += xi - x[i - w];
            }
            if r + 1 < h && inside(m[i + w]) {
                s += xi - x[i + w];
            }
            *o = s;
        }
    });
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.par_chunks(1 << 14)
        .zip(b.par_chunks(1 << 14))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>())
        .sum()
}

/// Masked Poisson by Jacobi-preconditioned CG from the DCT warm start. Returns the height,
/// iterations and final relative residual.
fn masked_poisson(g: &GradientField, m: &[f32], params: &IntegrateParams) -> (Plane, u32, f64) {
    let (w, h) = (g.width, g.height);
    let n = w * h;
    let warm = poisson_dct(g, Some(m));
    let b: Vec<f64> = divergence(g, Some(m)).into_iter().map(f64::from).collect();
    let mut x: Vec<f64> = warm.data().iter().map(|&v| f64::from(v)).collect();
    // Inverse node degrees (0 outside and for isolated pixels).
    let inv_deg: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| {
            if !inside(m[i]) {
                return 0.0;
            }
            let (xx, r) = (i % w, i / w);
            let d = usize::from(xx >= 1 && inside(m[i - 1]))
                + usize::from(xx + 1 < w && inside(m[i + 1]))
                + usize::from(r >= 1 && inside(m[i - w]))
                + usize::from(r + 1 < h && inside(m[i + w]));
            if d == 0 {
                0.0
            } else {
                1.0 / d as f64
            }
        })
        .collect();
    let b_norm = dot(&b, &b).sqrt();
    let mut ax = vec![0.0f64; n];
    apply_masked_laplacian(&x, m, w, h, &mut ax);
    let mut res: Vec<f64> = b.par_iter().zip(&ax).map(|(b, a)| b - a).collect();
    let mut zv: Vec<f64> = res.par_iter().zip(&inv_deg).map(|(r, d)| r * d).collect();
    let mut dir = zv.clone();
    let mut rz = dot(&res, &zv);
    let mut iterations = 0u32;
    let mut rel = if b_norm > 0.0 {
        dot(&res, &res).sqrt() / b_norm
    } else {
        0.0
    };
    while iterations < params.max_iterations && rel > params.tolerance && rz > 0.0 {
        apply_masked_laplacian(&dir, m, w, h, &mut ax);
        let dad = dot(&dir, &ax);
        if dad <= 0.0 {
            break;
        }
        let alpha = rz / dad;
        x.par_iter_mut()
            .zip(&dir)
            .for_each(|(x, d)| *x += alpha * d);
        res.par_iter_mut()
            .zip(&ax)
            .for_each(|(r, a)| *r -= alpha * a);
        zv.par_iter_mut()
            .zip(&res)
            .zip(&inv_deg)
            .for_each(|((z, r), d)| *z = r * d);
        let rz_new = dot(&res, &zv);
        let beta = rz_new / rz;
        rz = rz_new;
        dir.par_iter_mut()
            .zip(&zv)
            .for_each(|(d, z)| *d = z + beta * *d);
        iterations += 1;
        rel = dot(&res, &res).sqrt() / b_norm;
    }
    // Zero mean over the mask; outside keeps the warm start, shifted by the same constant.
    let (s, c) = x
        .iter()
        .zip(m)
        .filter(|(_, &mv)| inside(mv))
        .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
    let mean = if c > 0 { s / c as f64 } else { 0.0 };
    let z: Vec<f32> = x.iter().map(|&v| (v - mean) as f32).collect();
    (
        Plane::from_vec(w, h, z).expect("sizes match by construction"),
        iterations,
        rel,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::Surface;

    /// A rough, non-smooth height (no structure a smooth solver could exploit).
    fn rough(w: usize, h: usize) -> Plane {
        Plane::from_fn(w, h, |x, r| {
            ((x * 7919 + r * 104_729) % 1000) as f32 * 0.01 + (x as f32 * 0.3).sin() * 3.0
        })
    }

    /// Max |a − b − (mean difference)| over `sel` pixels (all if None).
    fn max_err_up_to_constant(a: &Plane, b: &Plane, sel: Option<&[f32]>) -> f64 {
        let ins = |i: usize| sel.is_none_or(|m| inside(m[i]));
        let idx: Vec<usize> = (0..a.data().len()).filter(|&i| ins(i)).collect();
        let off = idx
            .iter()
            .map(|&i| f64::from(a.data()[i]) - f64::from(b.data()[i]))
            .sum::<f64>()
            / idx.len() as f64;
        idx.iter()
            .map(|&i| (f64::from(a.data()[i]) - f64::from(b.data()[i]) - off).abs())
            .fold(0.0, f64::max)
    }

    fn rmse_up_to_constant(a: &Plane, b: &Plane, sel: Option<&[f32]>) -> f64 {
        let ins = |i: usize| sel.is_none_or(|m| inside(m[i]));
        let idx: Vec<usize> = (0..a.data().len()).filter(|&i| ins(i)).collect();
        let d: Vec<f64> = idx
            .iter()
            .map(|&i| f64::from(a.data()[i]) - f64::from(b.data()[i]))
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
    }

    #[test]
    fn paired_dct_matches_rustdct() {
        let mut fp = FftPlanner::<f32>::new();
        let mut dp = rustdct::DctPlanner::<f32>::new();
        for &n in &[1usize, 2, 3, 5, 8, 15, 64, 100] {
            for rows in [1usize, 2, 3] {
                let x: Vec<f32> = (0..n * rows)
                    .map(|i| ((i * 37 + 11) % 17) as f32 * 0.3 - 2.0)
                    .collect();
                let pd = PairedDct::new(n, &mut fp);
                let oracle = dp.plan_dct2(n);
                let mut want = x.clone();
                for r in want.chunks_mut(n) {
                    oracle.process_dct2(r);
                }
                let mut got = x.clone();
                pd.dct2_rows(&mut got);
                for (a, b) in got.iter().zip(&want) {
                    assert!((a - b).abs() < 1e-3, "dct2 n={n} rows={rows}: {a} vs {b}");
                }
                let mut want3 = x.clone();
                for r in want3.chunks_mut(n) {
                    oracle.process_dct3(r);
                }
                let mut got3 = x.clone();
                pd.dct3_rows(&mut got3);
                for (a, b) in got3.iter().zip(&want3) {
                    assert!((a - b).abs() < 1e-3, "dct3 n={n} rows={rows}: {a} vs {b}");
                }
            }
        }
    }

    /// A gradient field with no structure (not integrable), values in about [−2, 2].
    fn rough_field(w: usize, h: usize) -> GradientField {
        let mut g = GradientField::zeros(w, h);
        for i in 0..w * h {
            g.p[i] = ((i * 7919 + 13) % 1009) as f32 / 250.0 - 2.0;
            g.q[i] = ((i * 104_729 + 7) % 997) as f32 / 250.0 - 2.0;
        }
        g
    }

    /// Sizes that exercise odd lengths, a single row / column, and column groups that are
    /// partial or end in an unpaired column.
    const ODD_SIZES: [(usize, usize); 11] = [
        (1, 1),
        (1, 7),
        (7, 1),
        (2, 2),
        (17, 3),
        (16, 16),
        (33, 20),
        (40, 9),
        (18, 31),
        (35, 2),
        (9, 8),
    ];

    /// `max |got − want| ≤ tol · max |want|` (plus a tiny absolute floor).
    fn assert_close(got: &[f32], want: &[f64], tol: f64, what: &str) {
        let amp = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let err = got
            .iter()
            .zip(want)
            .map(|(&a, b)| (f64::from(a) - b).abs())
            .fold(0.0, f64::max);
        assert!(
            err <= tol * amp + 1e-6,
            "{what}: max error {err:.3e}, amplitude {amp:.3e}"
        );
    }

    #[test]
    fn poisson_dct_matches_a_rustdct_reference() {
        // Independent expectation: divergence straight from the edge equations, 2-D DCT-II /
        // DCT-III with rustdct in f64 (columns extracted explicitly), same eigenvalues.
        let mut dp = rustdct::DctPlanner::<f64>::new();
        for &(w, h) in &ODD_SIZES {
            let g = rough_field(w, h);
            let mut b = vec![0.0f64; w * h];
            for r in 0..h {
                for x in 0..w {
                    let i = r * w + x;
                    if x + 1 < w {
                        b[i] -= f64::from(g.p[i]);
                        b[i + 1] += f64::from(g.p[i]);
                    }
                    if r >= 1 {
                        b[i] -= f64::from(g.q[i]);
                        b[i - w] += f64::from(g.q[i]);
                    }
                }
            }
            let (dx, dy) = (dp.plan_dct2(w), dp.plan_dct2(h));
            let (ix, iy) = (dp.plan_dct3(w), dp.plan_dct3(h));
            let cols = |data: &mut [f64], f: &dyn Fn(&mut [f64])| {
                for x in 0..w {
                    let mut c: Vec<f64> = (0..h).map(|r| data[r * w + x]).collect();
                    f(&mut c);
                    for (r, v) in c.into_iter().enumerate() {
                        data[r * w + x] = v;
                    }
                }
            };
            b.chunks_mut(w).for_each(|r| dx.process_dct2(r));
            cols(&mut b, &|c| dy.process_dct2(c));
            for r in 0..h {
                for x in 0..w {
                    let lam = 4.0
                        - 2.0 * (std::f64::consts::PI * x as f64 / w as f64).cos()
                        - 2.0 * (std::f64::consts::PI * r as f64 / h as f64).cos();
                    let v = &mut b[r * w + x];
                    *v = if x + r == 0 {
                        0.0
                    } else {
                        *v / lam * 4.0 / (w * h) as f64
                    };
                }
            }
            cols(&mut b, &|c| iy.process_dct3(c));
            b.chunks_mut(w).for_each(|r| ix.process_dct3(r));
            let z = poisson_dct(&g, None);
            assert_close(z.data(), &b, 1e-4, &format!("DCT Poisson {w}×{h}"));
        }
    }

    #[test]
    fn frankot_chellappa_matches_a_direct_dft() {
        // Independent expectation: the FC formula with O(N²) DFTs in f64.
        use rustfft::num_complex::Complex64;
        let tau = std::f64::consts::TAU;
        for &(w, h) in &ODD_SIZES {
            let g = rough_field(w, h);
            let dft2 = |v: &dyn Fn(usize) -> Complex64, sign: f64| -> Vec<Complex64> {
                (0..w * h)
                    .map(|o| {
                        let (k, l) = (o % w, o / w);
                        (0..w * h)
                            .map(|i| {
                                let (x, r) = (i % w, i / w);
                                let ph = sign
                                    * tau
                                    * ((k * x) as f64 / w as f64 + (l * r) as f64 / h as f64);
                                v(i) * Complex64::new(ph.cos(), ph.sin())
                            })
                            .sum()
                    })
                    .collect()
            };
            let pf = dft2(&|i| Complex64::new(f64::from(g.p[i]), 0.0), -1.0);
            let qf = dft2(&|i| Complex64::new(f64::from(g.q[i]), 0.0), -1.0);
            let zf: Vec<Complex64> = (0..w * h)
                .map(|o| {
                    let (k, l) = (o % w, o / w);
                    let a = Complex64::from_polar(1.0, tau * k as f64 / w as f64) - 1.0;
                    let c = Complex64::from_polar(1.0, -tau * l as f64 / h as f64) - 1.0;
                    let den = a.norm_sqr() + c.norm_sqr();
                    if o == 0 {
                        Complex64::new(0.0, 0.0)
                    } else {
                        (a.conj() * pf[o] + c.conj() * qf[o]) / den
                    }
                })
                .collect();
            let want: Vec<f64> = dft2(&|i| zf[i], 1.0)
                .into_iter()
                .map(|v| v.re / (w * h) as f64)
                .collect();
            let z = frankot_chellappa(&g);
            assert_close(z.data(), &want, 1e-4, &format!("Frankot–Chellappa {w}×{h}"));
        }
    }

    #[test]
    fn dct_poisson_recovers_any_height_from_its_discrete_gradient() {
        for &(w, h) in &[(37, 23), (64, 64), (1, 9), (9, 1), (128, 96)] {
            let z = rough(w, h);
            let g = GradientField::from_height(&z);
            let (zi, rep) = integrate_gradients(&g, None, &IntegrateParams::default()).unwrap();
            let e = max_err_up_to_constant(&zi, &z, None);
            assert!(e < 2e-3, "{w}×{h}: max error {e}");
            assert!(rep.rms_residual < 1e-3, "{rep:?}");
            let mean = zi.data().iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64;
            assert!(mean.abs() < 1e-3, "zero mean, got {mean}");
        }
    }

    #[test]
    fn frankot_chellappa_is_exact_for_periodic_discrete_gradients() {
        let (w, h) = (48, 40);
        let z = rough(w, h);
        let d = z.data();
        let mut g = GradientField::zeros(w, h);
        for r in 0..h {
            for x in 0..w {
                let i = r * w + x;
                g.p[i] = d[r * w + (x + 1) % w] - d[i];
                g.q[i] = d[((r + h - 1) % h) * w + x] - d[i];
            }
        }
        let params = IntegrateParams {
            method: IntegrationMethod::FrankotChellappa,
            ..Default::default()
        };
        let (zi, _) = integrate_gradients(&g, None, &params).unwrap();
        let e = max_err_up_to_constant(&zi, &z, None);
        assert!(e < 2e-3, "max error {e}");
    }

    #[test]
    fn masked_poisson_recovers_the_height_inside_an_irregular_mask() {
        let (w, h) = (96, 80);
        let z = rough(w, h);
        // Two blobs (two components) and a hole; garbage gradients outside.
        let mask = Plane::from_fn(w, h, |x, r| {
            let (u, v) = (x as f32 - 30.0, r as f32 - 40.0);
            let blob1 = u * u + v * v < 25.0 * 25.0 && u * u + v * v > 6.0 * 6.0;
            let blob2 = (x as f32 - 80.0).abs() < 10.0 && (r as f32 - 20.0).abs() < 15.0;
            f32::from(u8::from(blob1 || blob2))
        });
        let mut g = GradientField::from_height(&z);
        for (i, &m) in mask.data().iter().enumerate() {
            if m < 0.5 {
                g.p[i] = 50.0;
                g.q[i] = -70.0;
            }
        }
        let params = IntegrateParams {
            method: IntegrationMethod::MaskedPoisson,
            ..Default::default()
        };
        let (zi, rep) = integrate_gradients(&g, Some(mask.data()), &params).unwrap();
        eprintln!("masked CG: {rep:?}");
        assert!(rep.relative_residual <= 1e-6, "{rep:?}");
        // Each component has its own constant: check them separately.
        for comp in [|x: usize, _r: usize| x < 60, |x: usize, _r: usize| x >= 60] {
            let sel = Plane::from_fn(w, h, |x, r| {
                f32::from(u8::from(comp(x, r) && mask.at(x, r) > 0.5))
            });
            let e = max_err_up_to_constant(&zi, &z, Some(sel.data()));
            assert!(e < 2e-3, "max error {e}");
        }
        // The DCT solver on the full grid is badly hurt by the garbage outside.
        let (zd, _) = integrate_gradients(&g, None, &IntegrateParams::default()).unwrap();
        assert!(max_err_up_to_constant(&zd, &z, Some(mask.data())) > 1.0);
    }

    #[test]
    fn analytic_surfaces_are_recovered_at_the_staggered_position() {
        let size = 128;
        let c = size as f64 / 2.0;
        // Sum of Gaussians (zero slope at the borders): DCT and masked solvers.
        let s = Surface::gaussians_for(size);
        let (img, z_centre) = s.render(size, size);
        let z_stag = Plane::from_fn(size, size, |x, r| {
            s.height(x as f64 - 0.5 - c, c - r as f64 - 0.5) as f32
        });
        let amp = z_stag.data().iter().fold(0.0f32, |a, &v| a.max(v.abs()));
        for method in [
            IntegrationMethod::PoissonDct,
            IntegrationMethod::FrankotChellappa,
        ] {
            let params = IntegrateParams {
                method,
                ..Default::default()
            };
            let (zi, _) = integrate_normals(&img, &params).unwrap();
            let rmse = rmse_up_to_constant(&zi, &z_stag, None);
            let rmse_centre = rmse_up_to_constant(&zi, &z_centre, None);
            eprintln!(
                "gaussians {size}² {method:?}: RMSE {rmse:.5} px (vs centre samples \
                 {rmse_centre:.4} px), amplitude {amp:.1} px"
            );
            assert!(rmse < 0.06, "{method:?}: {rmse}");
            // Normals of the integrated height are integrable.
            let g = GradientField::from_height(&zi);
            assert!(g.curl_stats(None).relative < 1e-5);
        }

        // A spherical cap (radius R, cut at ρ = a) on a flat plane: a kink at the rim.
        let (rr, a) = (0.5 * size as f64, 0.35 * size as f64);
        let cap = |u: f64, v: f64| {
            let rho2 = u * u + v * v;
            if rho2 < a * a {
                (rr * rr - rho2).sqrt() - (rr * rr - a * a).sqrt()
            } else {
                0.0
            }
        };
        let sphere = Surface::Sphere { radius_px: rr };
        let n = size * size;
        let mut normal = [
            buf::zeroed_f32(n),
            buf::zeroed_f32(n),
            buf::filled_f32(n, 1.0),
        ];
        for i in 0..n {
            let (u, v) = ((i % size) as f64 - c, c - (i / size) as f64);
            if u * u + v * v < a * a {
                let [p, q] = sphere.gradient(u, v).unwrap();
                let nn = crate::raster::gradient::normal_of_gradient(p as f32, q as f32);
                for (plane, v) in normal.iter_mut().zip(nn) {
                    plane[i] = v;
                }
            }
        }
        let col = [vec![0.5; n], vec![0.5; n], vec![0.5; n]];
        let img = RgbnImage::new(size, size, col, normal, None).unwrap();
        let z_stag = Plane::from_fn(size, size, |x, r| {
            cap(x as f64 - 0.5 - c, c - r as f64 - 0.5) as f32
        });
        let (zi, _) = integrate_normals(&img, &IntegrateParams::default()).unwrap();
        let rmse = rmse_up_to_constant(&zi, &z_stag, None);
        let cap_h = cap(0.0, 0.0);
        eprintln!("sphere cap {size}² (height {cap_h:.1} px): DCT RMSE {rmse:.4} px");
        assert!(rmse < 0.1, "{rmse}");
        let (out, _, rep) = project_integrable(&img, &ProjectParams::default()).unwrap();
        eprintln!(
            "sphere cap projection: relative curl {:.2e} → {:.2e}",
            rep.before.relative, rep.after.relative
        );
        assert!(rep.after.relative < 1e-4 && out.validate().is_clean());
    }

    #[test]
    fn projection_keeps_integrable_fields_and_removes_rotation() {
        let size = 96;
        let s = Surface::gaussians_for(size);
        let (_, z) = s.render(size, size);
        let mut img = RgbnImage::flat(size, size, [0.5; 3]);
        GradientField::from_height(&z).write_normals(&mut img);
        for method in [
            IntegrationMethod::PoissonDct,
            IntegrationMethod::MaskedPoisson,
        ] {
            let params = ProjectParams {
                integrate: IntegrateParams {
                    method,
                    ..Default::default()
                },
            };
            let (out, _, rep) = project_integrable(&img, &params).unwrap();
            let max_dn = (0..3)
                .flat_map(|k| {
                    img.normal()[k]
                        .iter()
                        .zip(&out.normal()[k])
                        .map(|(a, b)| (a - b).abs())
                })
                .fold(0.0f32, f32::max);
            eprintln!(
                "{method:?} projection of an integrable field: max |Δn| {max_dn:.2e}, curl \
                 {:.2e} → {:.2e}",
                rep.before.relative, rep.after.relative
            );
            assert!(max_dn <= 1e-4, "{max_dn}");
        }

        // Add a divergence-free vortex g_rot = (∂ψ/∂v, −∂ψ/∂u) of a Gaussian stream function
        // ψ (tangential at the border, so it carries no height under Neumann boundaries).
        let (amp, s2) = (3.0f32, 2.0 * 8.0f32 * 8.0);
        let mut g = GradientField::from_height(&z);
        for r in 0..size {
            for x in 0..size {
                let (u, v) = (x as f32 - 40.0, 50.0 - r as f32);
                let psi = amp * (-(u * u + v * v) / s2).exp();
                let (dpu, dpv) = (-2.0 * u / s2 * psi, -2.0 * v / s2 * psi);
                g.p[r * size + x] += dpv;
                g.q[r * size + x] -= dpu;
            }
        }
        let mut bad = img.clone();
        g.write_normals(&mut bad);
        let (out, zi, rep) = project_integrable(&bad, &ProjectParams::default()).unwrap();
        eprintln!(
            "vortex added: relative curl {:.3e} → {:.3e} (rms curl {:.3e} → {:.3e})",
            rep.before.relative, rep.after.relative, rep.before.rms_curl, rep.after.rms_curl
        );
        assert!(rep.before.relative > 0.03);
        assert!(rep.after.relative < 1e-4);
        // The vortex has no height: the projection recovers the original height (to the
        // O(h²) divergence of the sampled vortex).
        let e = rmse_up_to_constant(&zi, &z, None);
        eprintln!("height RMSE after removing the rotation: {e:.4} px");
        assert!(e < 0.05, "{e}");
        assert!(out.validate().is_clean());
    }

    #[test]
    fn height_round_trips_through_exr() {
        let z = rough(13, 7);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("h.exr");
        crate::raster::io::save_plane_exr(&z, "Z", &path).unwrap();
        let img = exr::prelude::read_first_flat_layer_from_file(&path).unwrap();
        let ch = &img.layer_data.channel_data.list[0];
        assert_eq!(ch.name.to_string(), "Z");
        let back: Vec<f32> = ch.sample_data.values_as_f32().collect();
        assert_eq!(back, z.data());
        assert!(crate::raster::io::save_plane_exr(&z, "Z", &dir.path().join("h.png")).is_err());
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let g = GradientField::zeros(8, 8);
        let empty = buf::zeroed_f32(64);
        for method in [
            IntegrationMethod::PoissonDct,
            IntegrationMethod::FrankotChellappa,
            IntegrationMethod::MaskedPoisson,
        ] {
            let params = IntegrateParams {
                method,
                ..Default::default()
            };
            let e = integrate_gradients(&g, Some(&empty), &params).unwrap_err();
            assert!(matches!(e, RgbnError::EmptyMask { .. }), "{e}");
        }
        let e = integrate_gradients(&g, Some(&[1.0; 10]), &IntegrateParams::default());
        assert!(matches!(e, Err(RgbnError::InvalidImage(_))));
        let bad = IntegrateParams {
            tolerance: 0.0,
            ..Default::default()
        };
        assert!(integrate_gradients(&g, None, &bad).is_err());
        let bad = IntegrateParams {
            max_iterations: 0,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
        // A single pixel and an isolated masked pixel work.
        let one = GradientField::zeros(1, 1);
        let (z, _) = integrate_gradients(&one, None, &IntegrateParams::default()).unwrap();
        assert_eq!(z.data(), &[0.0]);
        let mut m = buf::zeroed_f32(64);
        m[9] = 1.0;
        let params = IntegrateParams {
            method: IntegrationMethod::MaskedPoisson,
            ..Default::default()
        };
        let (z, _) = integrate_gradients(&g, Some(&m), &params).unwrap();
        assert!(z.data().iter().all(|v| v.is_finite()));
    }
}
