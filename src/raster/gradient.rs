//! Normal ↔ gradient conversion and the integrability (curl) readout. **The only place that
//! knows the sign conventions.**
//!
//! - Height `z(x, y)` in pixel units with `y` **up**; rows go **down** in memory, so moving one
//!   row down is `Δy = −1`.
//! - Gradient `(p, q) = (∂z/∂x, ∂z/∂y) = (−n_x/n_z, −n_y/n_z)`; back:
//!   `n = normalize(−p, −q, 1)` (Pereira & Velho §III).
//! - `n_z` is clamped to at least [`NZ_EPSILON`] before dividing, so grazing or back-facing
//!   normals give a finite (steep, slope ≤ 1000) gradient instead of NaN/inf; such pixels are
//!   counted in [`GradientField::clamped`].
//! - Discrete gradients of a sampled height use forward differences in this frame:
//!   `p(x, r) = z(x+1, r) − z(x, r)`, `q(x, r) = z(x, r−1) − z(x, r)`.
//! - Curl `c = ∂p/∂y − ∂q/∂x` with the same forward differences:
//!   `c(x, r) = (p(x, r−1) − p(x, r)) − (q(x+1, r) − q(x, r))`, defined for `r ≥ 1`,
//!   `x ≤ W−2` (0 on the top row and right column). It is exactly zero (to rounding) for
//!   the discrete gradient of any height (Agrawal et al. 2005).
//!
//! # Edge models ([`Differences`])
//!
//! Integration, the integrability projection and the curl readout of the integration
//! module all read a gradient field through **one** discretisation: the *edge values* of
//! [`GradientField::edge_values`]. The height lives at pixel centres; the edge between two
//! neighbouring pixels carries one slope value:
//!
//! - [`Differences::Averaged`] (the default): the edge value is the average of the two pixel
//!   samples, `e_p(x, r) = ½(p(x, r) + p(x+1, r))` on the edge `(x, r)–(x+1, r)` and
//!   `e_q(x, r) = ½(q(x, r) + q(x, r−1))` on the edge `(x, r)–(x, r−1)`: the trapezoidal rule,
//!   exact to second order for normals *sampled at pixel centres* (photometric stereo,
//!   renderers), so integrated heights are registered at pixel centres.
//! - [`Differences::Forward`]: the edge value is the sample of the pixel at the edge's start,
//!   `e_p(x, r) = p(x, r)`, `e_q(x, r) = q(x, r)`: exact for the forward differences of
//!   [`GradientField::from_height`]; for centre-sampled normals the height comes out staggered
//!   by half a pixel.
//!
//! The curl of a model is the circulation of the edge values around the plaquette of the four
//! pixels `(x, r)`, `(x+1, r)`, `(x, r−1)`, `(x+1, r−1)`:
//! `c = (e_p(x, r−1) − e_p(x, r)) − (e_q(x+1, r) − e_q(x, r))` — with the forward model the
//! formula above; with the averaged model the same 2 × 2 pixel stencil (so the same
//! [`crate::raster::integrate::curl_interior`]), a box-averaged curl centred on the plaquette.
//!
//! **Checkerboard null space.** Averaging cannot see a slope component alternating in sign
//! along its axis (`p = (−1)^x` along a row, `q = (−1)^r` along a column): its edge values are
//! 0. Such a component carries no height and no curl in the averaged model. The integrators
//! ignore it; the projection keeps it as it is (it changes the samples as little as possible,
//! see [`crate::raster::integrate::gradients_of_height`]). The plain [`GradientField::curl`] /
//! [`GradientField::curl_stats`] — every operator's readout, the curl node, `rgbn info` — are
//! the averaged model; [`GradientField::curl_forward`] / [`GradientField::curl_stats_forward`]
//! read the field as forward edge values.

use super::{Plane, RgbnImage};
use crate::raster::buf;
use crate::raster::par::OrderedReduce;
use rayon::prelude::*;

/// Smallest `n_z` used when dividing; slopes are thus bounded by `1/NZ_EPSILON = 1000`.
pub const NZ_EPSILON: f32 = 1e-3;

/// How pixel samples of a gradient become the slope of an edge between two pixels (module
/// docs).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Differences {
    /// Edge value = average of the two pixel samples (samples at pixel centres).
    #[default]
    Averaged,
    /// Edge value = the sample of the edge's first pixel (forward differences, staggered).
    Forward,
}

/// A gradient field `(p, q)` in the frame of the module docs.
#[derive(Clone, Debug, PartialEq)]
pub struct GradientField {
    pub width: usize,
    pub height: usize,
    pub p: Vec<f32>,
    pub q: Vec<f32>,
    /// Pixels whose `n_z` was below [`NZ_EPSILON`] and got clamped when converting.
    pub clamped: usize,
}

/// `(p, q)` of one normal, with the `n_z` clamp.
#[inline(always)]
#[must_use]
pub fn gradient_of_normal(n: [f32; 3]) -> [f32; 2] {
    let inv = 1.0 / n[2].max(NZ_EPSILON);
    [-n[0] * inv, -n[1] * inv]
}

/// The unit normal of slope `(p, q)`.
#[inline(always)]
#[must_use]
pub fn normal_of_gradient(p: f32, q: f32) -> [f32; 3] {
    let inv = (p * p + q * q + 1.0).sqrt().recip();
    [-p * inv, -q * inv, inv]
}

impl GradientField {
    /// Zero gradient (a flat surface).
    #[must_use]
    pub fn zeros(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            p: buf::zeroed_f32(width * height),
            q: buf::zeroed_f32(width * height),
            clamped: 0,
        }
    }

    /// Foreshorten-corrected gradients of an image's normals.
    #[must_use]
    pub fn from_normals(img: &RgbnImage) -> Self {
        let (w, h) = (img.width(), img.height());
        let [nx, ny, nz] = img.normal();
        let mut p = buf::zeroed_f32(w * h);
        let mut q = buf::zeroed_f32(w * h);
        let clamped = p
            .par_chunks_mut(w.max(1))
            .zip(q.par_chunks_mut(w.max(1)))
            .enumerate()
            .map(|(row, (pr, qr))| {
                let o = row * w;
                let (nx, ny, nz) = (&nx[o..o + w], &ny[o..o + w], &nz[o..o + w]);
                let mut clamped = 0usize;
                for x in 0..w {
                    let [pp, qq] = gradient_of_normal([nx[x], ny[x], nz[x]]);
                    pr[x] = pp;
                    qr[x] = qq;
                    clamped += usize::from(nz[x] < NZ_EPSILON);
                }
                clamped
            })
            .sum();
        Self {
            width: w,
            height: h,
            p,
            q,
            clamped,
        }
    }

    /// The gradient and height of a surface sampled at the `(w + 1) × (h + 1)` pixel corners
    /// (`zc` row-major, corner `(x, r)` the top-left corner of pixel `(x, r)`; see
    /// [`corner_samples`]): each pixel's `(p, q)` is the gradient of the bilinear interpolation
    /// at its centre — the 2 × 2 differences `p = A_y Δ_x z_c`, `q = A_x Δ_y z_c` (y up) — and
    /// its height the mean of its four corners. Such a field is *exactly* integrable under the
    /// averaged model ([`Differences::Averaged`]): every 2 × 2 circulation of its averaged edge
    /// values cancels (both terms are `Δ_x Δ_y A_x A_y z_c`), and the returned height, at pixel
    /// centres, is the one that integrating it gives back. This is how every operator that
    /// makes relief from a height (demo, analytic surfaces, pen) turns it into normals.
    #[must_use]
    pub fn from_corner_heights(w: usize, h: usize, zc: &[f64]) -> (Self, Plane) {
        assert_eq!(zc.len(), (w + 1) * (h + 1), "corner grid size");
        let cw = w + 1;
        let n = w * h;
        let (mut p, mut q, mut z) = (buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n));
        p.par_chunks_mut(w.max(1))
            .zip(q.par_chunks_mut(w.max(1)))
            .zip(z.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(r, ((pr, qr), zr))| {
                let (top, bottom) = (&zc[r * cw..(r + 1) * cw], &zc[(r + 1) * cw..(r + 2) * cw]);
                for x in 0..w {
                    let (tl, tr, bl, br) = (top[x], top[x + 1], bottom[x], bottom[x + 1]);
                    pr[x] = (0.5 * ((tr - tl) + (br - bl))) as f32;
                    qr[x] = (0.5 * ((tl - bl) + (tr - br))) as f32;
                    zr[x] = (0.25 * (tl + tr + bl + br)) as f32;
                }
            });
        let g = Self {
            width: w,
            height: h,
            p,
            q,
            clamped: 0,
        };
        (
            g,
            Plane::from_vec(w, h, z).expect("sizes match by construction"),
        )
    }

    /// An exactly integrable (averaged model) field from a height sampled at pixel centres:
    /// [`from_corner_heights`](Self::from_corner_heights) of [`corners_of_centres`]. The field
    /// is that of the height blurred by `[1 2 1]/4` in x and y (returned with it): the
    /// well-posed choice — samples whose *averages* are the raw height's differences exist
    /// only up to a checkerboard that rings across a whole row at every step.
    #[must_use]
    pub fn of_height(z: &Plane) -> (Self, Plane) {
        Self::from_corner_heights(z.width(), z.height(), &corners_of_centres(z))
    }

    /// Forward-difference gradient of a sampled height (see module docs). The last column's `p`
    /// and the top row's `q` repeat their neighbours (the curl does not use them).
    #[must_use]
    pub fn from_height(z: &Plane) -> Self {
        let (w, h) = (z.width(), z.height());
        let d = z.data();
        let mut p = buf::zeroed_f32(w * h);
        let mut q = buf::zeroed_f32(w * h);
        p.par_chunks_mut(w.max(1))
            .zip(q.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(r, (pr, qr))| {
                let row = &d[r * w..(r + 1) * w];
                for x in 0..w {
                    pr[x] = if x + 1 < w {
                        row[x + 1] - row[x]
                    } else if w > 1 {
                        row[x] - row[x - 1]
                    } else {
                        0.0
                    };
                    qr[x] = if r >= 1 {
                        d[(r - 1) * w + x] - row[x]
                    } else if h > 1 {
                        row[x] - d[w + x]
                    } else {
                        0.0
                    };
                }
            });
        Self {
            width: w,
            height: h,
            p,
            q,
            clamped: 0,
        }
    }

    /// Writes `normalize(−p, −q, 1)` into the image's normal planes (colour kept).
    pub fn write_normals(&self, img: &mut RgbnImage) {
        assert_eq!((img.width(), img.height()), (self.width, self.height));
        let w = self.width.max(1);
        let [nx, ny, nz] = img.normal_mut();
        nx.par_chunks_mut(w)
            .zip(ny.par_chunks_mut(w))
            .zip(nz.par_chunks_mut(w))
            .zip(self.p.par_chunks(w).zip(self.q.par_chunks(w)))
            .for_each(|(((x, y), z), (p, q))| {
                for i in 0..x.len() {
                    let [a, b, c] = normal_of_gradient(p[i], q[i]);
                    x[i] = a;
                    y[i] = b;
                    z[i] = c;
                }
            });
    }

    /// `normalize(−p, −q, 1)` as three new planes (x, y, z).
    #[must_use]
    pub fn to_normals(&self) -> [Vec<f32>; 3] {
        let n = self.width * self.height;
        let mut out = [buf::zeroed_f32(n), buf::zeroed_f32(n), buf::zeroed_f32(n)];
        let w = self.width.max(1);
        let [nx, ny, nz] = &mut out;
        nx.par_chunks_mut(w)
            .zip(ny.par_chunks_mut(w))
            .zip(nz.par_chunks_mut(w))
            .zip(self.p.par_chunks(w).zip(self.q.par_chunks(w)))
            .for_each(|(((x, y), z), (p, q))| {
                for ((((x, y), z), p), q) in x.iter_mut().zip(y).zip(z).zip(p).zip(q) {
                    [*x, *y, *z] = normal_of_gradient(*p, *q);
                }
            });
        out
    }

    /// The edge values of a model (module docs), stored where the forward model stores its
    /// samples: the edge `(x, r)–(x+1, r)` at `p[(x, r)]`, the edge `(x, r)–(x, r−1)` at
    /// `q[(x, r)]`. Slots without an edge (last column's `p`, top row's `q`) keep the sample.
    /// The forward model borrows the field unchanged.
    #[must_use]
    pub fn edge_values(&self, d: Differences) -> std::borrow::Cow<'_, GradientField> {
        if d == Differences::Forward {
            return std::borrow::Cow::Borrowed(self);
        }
        let (w, h) = (self.width, self.height);
        let mut out = GradientField::zeros(w, h);
        out.clamped = self.clamped;
        let (p, q) = (&self.p, &self.q);
        out.p
            .par_chunks_mut(w.max(1))
            .zip(out.q.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(r, (pr, qr))| {
                let row = r * w..(r + 1) * w;
                let (ps, qs) = (&p[row.clone()], &q[row]);
                for (o, pair) in pr.iter_mut().zip(ps.windows(2)) {
                    *o = 0.5 * (pair[0] + pair[1]);
                }
                if let (Some(o), Some(&v)) = (pr.last_mut(), ps.last()) {
                    *o = v;
                }
                if r >= 1 {
                    let qu = &q[(r - 1) * w..r * w];
                    for ((o, &a), &b) in qr.iter_mut().zip(qs).zip(qu) {
                        *o = 0.5 * (a + b);
                    }
                } else {
                    qr.copy_from_slice(qs);
                }
            });
        std::borrow::Cow::Owned(out)
    }

    /// The curl map of a model: the circulation of its [edge values](Self::edge_values)
    /// (module docs), 0 where undefined.
    #[must_use]
    pub fn curl_of(&self, d: Differences) -> Plane {
        self.edge_values(d).curl_forward()
    }

    /// [`curl_stats`](Self::curl_stats) in a given model.
    #[must_use]
    pub fn curl_stats_of(&self, d: Differences, mask: Option<&[f32]>) -> CurlStats {
        match d {
            Differences::Averaged => self.curl_stats(mask),
            Differences::Forward => self.curl_stats_forward(mask),
        }
    }

    /// The curl map in the averaged model (module docs; every readout uses it), 0 where
    /// undefined.
    #[must_use]
    pub fn curl(&self) -> Plane {
        self.curl_of(Differences::Averaged)
    }

    /// The curl map of the field read as forward edge values (module docs), 0 where undefined.
    #[must_use]
    pub fn curl_forward(&self) -> Plane {
        let (w, h) = (self.width, self.height);
        let (p, q) = (&self.p, &self.q);
        Plane::from_fn_rows(w, h, |r, out| {
            if r == 0 || w < 2 {
                out.fill(0.0);
                return;
            }
            let (pu, pc) = (&p[(r - 1) * w..r * w], &p[r * w..(r + 1) * w]);
            let qc = &q[r * w..(r + 1) * w];
            let dp = pu.iter().zip(pc);
            let dq = qc.iter().zip(&qc[1..]);
            for (o, ((&a, &b), (&q0, &q1))) in out[..w - 1].iter_mut().zip(dp.zip(dq)) {
                *o = (a - b) - (q1 - q0);
            }
            out[w - 1] = 0.0;
        })
    }

    /// `RMS(curl) / RMS(|e|)` in the averaged model over the plaquettes where the curl is
    /// defined (and, with a mask, whose four pixels have coverage ≥ 0.5). 0 for a flat field.
    #[must_use]
    pub fn relative_rms_curl(&self, mask: Option<&[f32]>) -> f64 {
        self.curl_stats(mask).relative
    }

    /// Curl statistics in the averaged model (module docs) without allocating a curl map:
    /// the same numbers as [`curl_stats_forward`](Self::curl_stats_forward) of the
    /// [averaged edge values](Self::edge_values), bit for bit.
    #[must_use]
    pub fn curl_stats(&self, mask: Option<&[f32]>) -> CurlStats {
        self.rows_of_curl(mask, |r, w, m| {
            let (u, c) = ((r - 1) * w..r * w, r * w..(r + 1) * w);
            let (p, q) = (&self.p, &self.q);
            CurlSums::of_row(&p[u.clone()], &q[u], &p[c.clone()], &q[c], m)
        })
    }

    /// Curl statistics of the field read as forward edge values.
    #[must_use]
    pub fn curl_stats_forward(&self, mask: Option<&[f32]>) -> CurlStats {
        self.rows_of_curl(mask, |r, w, m| {
            let (u, c) = ((r - 1) * w..r * w, r * w..(r + 1) * w);
            let (p, q) = (&self.p, &self.q);
            CurlSums::of_forward_row(&p[u], &p[c.clone()], &q[c], m)
        })
    }

    fn rows_of_curl(
        &self,
        mask: Option<&[f32]>,
        row: impl Fn(usize, usize, Option<(&[f32], &[f32])>) -> CurlSums + Sync,
    ) -> CurlStats {
        let (w, h) = (self.width, self.height);
        if w < 2 || h < 2 {
            return CurlStats::default();
        }
        (1..h)
            .into_par_iter()
            .map(|r| {
                row(
                    r,
                    w,
                    mask.map(|m| (&m[(r - 1) * w..r * w], &m[r * w..(r + 1) * w])),
                )
            })
            .ordered_reduce(CurlSums::default, CurlSums::merge)
            .stats()
    }
}

/// [`GradientField::curl_stats`] of an image's normals (`GradientField::from_normals(img)
/// .curl_stats(img.mask())`, bit for bit) without allocating the two gradient planes: each
/// row pair is converted on the fly.
#[must_use]
pub fn curl_stats_of_normals(img: &RgbnImage) -> CurlStats {
    let [nx, ny, nz] = img.normal();
    curl_sums_of_normal_rows([nx, ny, nz], img.mask(), img.width(), 1..img.height()).stats()
}

/// The curl sums of [`curl_stats_of_normals`] over rows `rows` only (each row `r ≥ 1` pairs with
/// row `r − 1`), of normal planes `w` wide: a strip's share of a whole image's sums.
#[must_use]
pub fn curl_sums_of_normal_rows(
    [nx, ny, nz]: [&[f32]; 3],
    mask: Option<&[f32]>,
    w: usize,
    rows: std::ops::Range<usize>,
) -> CurlSums {
    if w < 2 {
        return CurlSums::default();
    }
    let grad = |r: usize, p: &mut Vec<f32>, q: &mut Vec<f32>| {
        p.resize(w, 0.0);
        q.resize(w, 0.0);
        let o = r * w..(r + 1) * w;
        let (nx, ny, nz) = (&nx[o.clone()], &ny[o.clone()], &nz[o]);
        for x in 0..w {
            [p[x], q[x]] = gradient_of_normal([nx[x], ny[x], nz[x]]);
        }
    };
    (rows.start.max(1)..rows.end)
        .into_par_iter()
        .map_init(
            || [(); 4].map(|()| Vec::with_capacity(w)),
            |[pu, qu, pc, qc], r| {
                grad(r - 1, pu, qu);
                grad(r, pc, qc);
                let m = mask.map(|m| (&m[(r - 1) * w..r * w], &m[r * w..(r + 1) * w]));
                CurlSums::of_row(pu, qu, pc, qc, m)
            },
        )
        .ordered_reduce(CurlSums::default, CurlSums::merge)
}

/// `f(x, r)` at the `(w + 1) × (h + 1)` pixel corners, row-major: corner `(x, r)` is the
/// top-left corner of pixel `(x, r)` (at `(x − ½, r − ½)` in coordinates where pixel centres
/// are integers). Rows in parallel. See [`GradientField::from_corner_heights`].
#[must_use]
pub fn corner_samples(w: usize, h: usize, f: impl Fn(usize, usize) -> f64 + Sync) -> Vec<f64> {
    let cw = w + 1;
    let mut z = vec![0.0; cw * (h + 1)];
    // Cancelled: the remaining rows stay 0 and the caller discards them (crate::cancel).
    let cancel = crate::cancel::Cancel::current();
    z.par_chunks_mut(cw).enumerate().for_each(|(r, line)| {
        if cancel.is_cancelled() {
            return;
        }
        for (x, out) in line.iter_mut().enumerate() {
            *out = f(x, r);
        }
    });
    z
}

/// Corner heights of a height sampled at pixel centres: each corner the mean of the (up to)
/// four pixels around it, the bilinear interpolation at the corner. With
/// [`GradientField::from_corner_heights`] this turns any centre-sampled height into an exactly
/// integrable field whose height is the centre samples blurred by `[1 2 1]/4` in x and y.
#[must_use]
pub fn corners_of_centres(z: &Plane) -> Vec<f64> {
    let (w, h) = (z.width(), z.height());
    let d = z.data();
    corner_samples(w, h, |x, r| {
        let xs = [x.saturating_sub(1), x.min(w - 1)];
        let rs = [r.saturating_sub(1), r.min(h - 1)];
        let mut s = 0.0;
        for &rr in &rs {
            for &xx in &xs {
                s += f64::from(d[rr * w + xx]);
            }
        }
        0.25 * s
    })
}

/// Whether the curl plaquette at column `x` of row `r ≥ 1` counts under a mask: all four
/// pixels of its block `{x, x+1} × {r−1, r}` have coverage ≥ 0.5 (see [`CurlSums::of_row`]).
/// `x + 1 < w` is the caller's contract.
#[inline(always)]
#[must_use]
pub fn plaquette_covered(m: &[f32], w: usize, r: usize, x: usize) -> bool {
    let (u, c) = ((r - 1) * w + x, r * w + x);
    m[u] >= 0.5 && m[u + 1] >= 0.5 && m[c] >= 0.5 && m[c + 1] >= 0.5
}

/// Plaquettes of a row summed together in [`CurlSums::of_row`] (one AVX-512 register).
const ACC_LANES: usize = 16;

/// The values a row of plaquettes reads, [`ACC_LANES`] plaquettes at a time (a trait rather
/// than a closure so that it is always inlined into the vectorised callers).
trait PlaquetteValues {
    /// `(p above, p, q right, q)` of the `m ≤ ACC_LANES` plaquettes from `x0`, lane by lane
    /// (zeros past `m`).
    fn block(&self, x0: usize, m: usize) -> [[f32; ACC_LANES]; 4];
}

/// Edge values given directly: `p` above, `p`, `q` right, `q`.
struct Edges<'a>([&'a [f32]; 4]);

impl PlaquetteValues for Edges<'_> {
    #[inline(always)]
    fn block(&self, x0: usize, m: usize) -> [[f32; ACC_LANES]; 4] {
        let mut o = [[0.0f32; ACC_LANES]; 4];
        for (o, s) in o.iter_mut().zip(self.0) {
            o[..m].copy_from_slice(&s[x0..x0 + m]);
        }
        o
    }
}

/// Samples of two rows, averaged into edge values as [`GradientField::edge_values`] does
/// (`½(a + b)`); each pair is `[..len]` and `[1..]` of one row's plane.
struct Samples<'a> {
    pu: [&'a [f32]; 2],
    pc: [&'a [f32]; 2],
    qc: [&'a [f32]; 2],
    qu: [&'a [f32]; 2],
}

impl PlaquetteValues for Samples<'_> {
    #[inline(always)]
    fn block(&self, x0: usize, m: usize) -> [[f32; ACC_LANES]; 4] {
        let mut o = [[0.0f32; ACC_LANES]; 4];
        let r = x0..x0 + m;
        let (a, b) = (&self.pu[0][r.clone()], &self.pu[1][r.clone()]);
        let (c, d) = (&self.pc[0][r.clone()], &self.pc[1][r.clone()]);
        let (e, f) = (&self.qc[1][r.clone()], &self.qu[1][r.clone()]);
        let (g, h) = (&self.qc[0][r.clone()], &self.qu[0][r]);
        for l in 0..m {
            o[0][l] = 0.5 * (a[l] + b[l]);
            o[1][l] = 0.5 * (c[l] + d[l]);
            o[2][l] = 0.5 * (e[l] + f[l]);
            o[3][l] = 0.5 * (g[l] + h[l]);
        }
        o
    }
}

/// [`CurlSums`] of one row, [`ACC_LANES`] partial sums in `f32`.
#[derive(Default)]
struct LaneSums {
    c2: [f32; ACC_LANES],
    g2: [f32; ACC_LANES],
    max: [f32; ACC_LANES],
    n: [u32; ACC_LANES],
}

impl LaneSums {
    /// Adds the `m` plaquettes from `x0` whose values are `block` (see [`PlaquetteValues`]).
    #[inline(always)]
    fn add(
        &mut self,
        block: [[f32; ACC_LANES]; 4],
        x0: usize,
        m: usize,
        keep: &impl Fn(usize) -> bool,
    ) {
        let [pu, pc, qn, qc] = block;
        for l in 0..ACC_LANES {
            let c = (pu[l] - pc[l]) - (qn[l] - qc[l]);
            let g = pc[l] * pc[l] + qc[l] * qc[l];
            // Lanes past `m` hold zeros and are not kept.
            let k = l < m && keep(x0 + l);
            let (c, g) = if k { (c, g) } else { (0.0, 0.0) };
            self.c2[l] += c * c;
            self.g2[l] += g;
            let a = c.abs();
            self.max[l] = if a > self.max[l] { a } else { self.max[l] };
            self.n[l] += u32::from(k);
        }
    }
}

/// Running sums behind [`CurlStats`], so that a kernel can gather them piecewise (rows,
/// column groups) and merge. Squares are summed in `f32` over at most a row or a short run of
/// rows and then in `f64`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurlSums {
    /// Σ curl².
    pub c2: f64,
    /// Σ (p² + q²).
    pub g2: f64,
    /// Pixels counted.
    pub n: usize,
    /// max |curl|.
    pub max: f32,
}

impl CurlSums {
    /// Both sums together.
    #[must_use]
    pub fn merge(self, o: Self) -> Self {
        Self {
            c2: self.c2 + o.c2,
            g2: self.g2 + o.g2,
            n: self.n + o.n,
            max: self.max.max(o.max),
        }
    }

    /// The sums of one row `r ≥ 1` (module docs): `pu` = p of row `r−1`, `pc`, `qc` = p, q of
    /// row `r`, `mask` = rows `r−1` and `r` of the mask. The plaquette at `x` reads the samples
    /// of the 2 × 2 block `{x, x+1} × {r−1, r}` (in both models), so it counts only when all
    /// four pixels have coverage ≥ 0.5: a covered pixel beside the silhouette must not be judged
    /// by the filler normal of its uncovered neighbour. The right column (no `x+1`) is not
    /// counted. Accumulates in 8 interleaved partial sums so the loop vectorises.
    #[inline(always)]
    #[must_use]
    pub fn of_forward_row(
        pu: &[f32],
        pc: &[f32],
        qc: &[f32],
        mask: Option<(&[f32], &[f32])>,
    ) -> Self {
        match mask {
            None => Self::of_row_where(pu, pc, qc, |_| true),
            Some((mu, mc)) => Self::of_row_where(pu, pc, qc, |x| {
                mu[x] >= 0.5 && mu[x + 1] >= 0.5 && mc[x] >= 0.5 && mc[x + 1] >= 0.5
            }),
        }
    }

    /// [`of_forward_row`](Self::of_forward_row) in the averaged model, from the *samples*:
    /// `pu`, `qu` = p, q of row `r−1`, `pc`, `qc` = p, q of row `r`. The edge values are formed
    /// with the arithmetic of [`GradientField::edge_values`] (`½(a + b)`), so the sums equal
    /// those of the forward sums of the edge values bit for bit; the gradient term is that of
    /// the edge values.
    #[inline(always)]
    #[must_use]
    pub fn of_row(
        pu: &[f32],
        qu: &[f32],
        pc: &[f32],
        qc: &[f32],
        mask: Option<(&[f32], &[f32])>,
    ) -> Self {
        let w = pc.len();
        if w < 2 {
            return Self::default();
        }
        // The edge values of `GradientField::edge_values`, formed on the fly (no row buffers).
        let len = w - 1;
        let vals = Samples {
            pu: [&pu[..len], &pu[1..w]],
            pc: [&pc[..len], &pc[1..w]],
            qc: [&qc[..len], &qc[1..w]],
            qu: [&qu[..len], &qu[1..w]],
        };
        match mask {
            None => Self::accumulate(len, &vals, |_| true),
            Some((mu, mc)) => Self::accumulate(len, &vals, |x| {
                mu[x] >= 0.5 && mu[x + 1] >= 0.5 && mc[x] >= 0.5 && mc[x + 1] >= 0.5
            }),
        }
    }

    #[inline(always)]
    fn of_row_where(pu: &[f32], pc: &[f32], qc: &[f32], keep: impl Fn(usize) -> bool) -> Self {
        let w = pc.len();
        if w < 2 {
            return Self::default();
        }
        let len = w - 1;
        let vals = Edges([&pu[..len], &pc[..len], &qc[1..w], &qc[..len]]);
        Self::accumulate(len, &vals, keep)
    }

    /// The sums of `len` plaquettes, whose `(p above, p, q right, q)` `vals` gives
    /// [`ACC_LANES`] at a time; they are summed lane by lane into `ACC_LANES` partial sums, so
    /// both steps vectorise.
    #[inline(always)]
    fn accumulate(len: usize, vals: &impl PlaquetteValues, keep: impl Fn(usize) -> bool) -> Self {
        let mut acc = LaneSums::default();
        let body = len - len % ACC_LANES;
        for x0 in (0..body).step_by(ACC_LANES) {
            acc.add(vals.block(x0, ACC_LANES), x0, ACC_LANES, &keep);
        }
        if body < len {
            acc.add(vals.block(body, len - body), body, len - body, &keep);
        }
        Self {
            c2: acc.c2.iter().map(|&v| f64::from(v)).sum(),
            g2: acc.g2.iter().map(|&v| f64::from(v)).sum(),
            n: acc.n.iter().map(|&v| v as usize).sum(),
            max: acc.max.iter().copied().fold(0.0, f32::max),
        }
    }

    /// The statistics (all zero when nothing was counted).
    #[must_use]
    pub fn stats(self) -> CurlStats {
        if self.n == 0 {
            return CurlStats::default();
        }
        let rms_curl = (self.c2 / self.n as f64).sqrt();
        let rms_grad = (self.g2 / self.n as f64).sqrt();
        CurlStats {
            rms_curl,
            rms_gradient: rms_grad,
            max_abs_curl: f64::from(self.max),
            relative: if rms_grad > 0.0 {
                rms_curl / rms_grad
            } else {
                0.0
            },
        }
    }
}

/// Integrability numbers of a gradient field.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurlStats {
    pub rms_curl: f64,
    pub rms_gradient: f64,
    pub max_abs_curl: f64,
    /// `rms_curl / rms_gradient` (0 for a flat field).
    pub relative: f64,
}

impl Plane {
    /// Fills each row with `f(row, out)`, rows in parallel.
    #[must_use]
    pub fn from_fn_rows(
        width: usize,
        height: usize,
        f: impl Fn(usize, &mut [f32]) + Sync + Send,
    ) -> Self {
        let mut data = buf::zeroed_f32(width * height);
        data.par_chunks_mut(width.max(1))
            .enumerate()
            .for_each(|(r, out)| f(r, out));
        Plane::from_vec(width, height, data).expect("sizes match by construction")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signs_follow_the_opengl_frame() {
        // A surface rising to the right (z = 0.5 x) tilts its normal to the left (n_x < 0).
        let [p, q] = gradient_of_normal(normal_of_gradient(0.5, 0.0));
        assert!((p - 0.5).abs() < 1e-6 && q.abs() < 1e-6);
        assert!(normal_of_gradient(0.5, 0.0)[0] < 0.0);
        // A surface rising upwards (z = y, y up) tilts its normal down (n_y < 0).
        assert!(normal_of_gradient(0.0, 1.0)[1] < 0.0);
        // Height rising towards the top of the image: rows above are higher → q > 0.
        let z = Plane::from_fn(5, 5, |_, r| -(r as f32));
        let g = GradientField::from_height(&z);
        assert!(g.q.iter().all(|&q| (q - 1.0).abs() < 1e-6));
        assert!(g.p.iter().all(|&p| p == 0.0));
    }

    #[test]
    fn grazing_and_back_facing_normals_are_clamped_not_nan() {
        let [p, q] = gradient_of_normal([1.0, 0.0, 0.0]);
        assert!((p + 1000.0).abs() < 1e-3 && q == 0.0, "{p}");
        let [p, _] = gradient_of_normal([0.6, 0.0, -0.8]);
        assert!(p.is_finite() && (p + 600.0).abs() < 1e-3, "{p}");
    }

    #[test]
    fn roundtrip_normal_gradient_normal() {
        for &(p, q) in &[(0.0, 0.0), (0.3, -2.0), (-5.0, 7.0), (100.0, 0.1)] {
            let n = normal_of_gradient(p, q);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6);
            let [p2, q2] = gradient_of_normal(n);
            assert!((p2 - p).abs() <= 1e-5 * p.abs().max(1.0), "{p} {p2}");
            assert!((q2 - q).abs() <= 1e-5 * q.abs().max(1.0), "{q} {q2}");
        }
    }

    #[test]
    fn curl_is_zero_for_discrete_gradients_of_any_height() {
        // A rough, non-smooth height: forward differences are still exactly integrable.
        let z = Plane::from_fn(37, 23, |x, r| {
            ((x * 7919 + r * 104_729) % 1000) as f32 * 0.01 + (x as f32 * 0.3).sin()
        });
        let g = GradientField::from_height(&z);
        let s = g.curl_stats_forward(None);
        assert!(s.rms_gradient > 1.0);
        assert!(s.relative < 1e-6, "{s:?}");
        // ... in the forward model only: the averaged model reads them as far from a surface.
        assert!(g.curl_stats(None).relative > 0.1);
        // The averaged model's counterpart: heights at the pixel corners, 2 × 2 differences
        // (and `of_height` of centre samples) are exactly integrable there.
        let zc = corners_of_centres(&z);
        for (g, _) in [
            GradientField::from_corner_heights(37, 23, &zc),
            GradientField::of_height(&z),
        ] {
            let s = g.curl_stats(None);
            assert!(s.rms_gradient > 0.5 && s.relative < 1e-6, "{s:?}");
            // the map agrees with the statistics
            assert!(g.curl().data().iter().all(|c| c.abs() < 1e-5));
        }
    }

    #[test]
    fn curl_of_a_rotational_field_is_its_known_value() {
        // (p, q) = (−y, x) has curl ∂p/∂y − ∂q/∂x = −1 − 1 = −2 everywhere.
        let (w, h) = (9, 7);
        let mut g = GradientField::zeros(w, h);
        for r in 0..h {
            for x in 0..w {
                let y = -(r as f32);
                g.p[r * w + x] = -y;
                g.q[r * w + x] = x as f32;
            }
        }
        let c = g.curl();
        for r in 1..h {
            for x in 0..w - 1 {
                assert!((c.at(x, r) + 2.0).abs() < 1e-6);
            }
        }
        assert_eq!(c.at(0, 0), 0.0);
        assert!((g.curl_stats(None).rms_curl - 2.0).abs() < 1e-9);
    }
}
