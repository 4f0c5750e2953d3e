//! Small geometry shared by the region-based operators (brush, pen, stamp): polyline distance
//! and projection, stroke masks, smoothstep, bilinear sampling, the exact Euclidean distance
//! transform, sampling of analytic gradients and a least-squares integrator.
//!
//! Coordinates: points are given in **pixel coordinates** `(x, row)` — `x` right, `row` down,
//! pixel centres at integer values — as a user clicks them. Vector maths that involves
//! gradients converts to the y-up frame of [`crate::raster::gradient`] with `y = −row`.
//!
//! # Sampling analytic gradients
//!
//! Readouts and integration read a field in the averaged edge model of
//! [`crate::raster::gradient`]: the slope of the edge between two pixels is the mean of their
//! samples. Sampling an analytic gradient at the pixel centres ([`sample_gradient_centres`])
//! makes each edge value a trapezoid-rule estimate of the slope and the discrete curl a
//! trapezoid-rule circulation, `O(h²)`.
//!
//! # References
//! - P. Felzenszwalb, D. Huttenlocher, "Distance Transforms of Sampled Functions", Theory of
//!   Computing 8 (2012).
//! - M. Hestenes, E. Stiefel, "Methods of conjugate gradients for solving linear systems" (1952).

use crate::error::RgbnError;
use crate::raster::buf;
use crate::raster::gradient::GradientField;
use crate::raster::par::ordered_dot;
use crate::raster::Plane;
use rayon::prelude::*;

/// Quintic smoothstep `6t⁵ − 15t⁴ + 10t³` of `t = (x − e0)/(e1 − e0)` clamped to `[0, 1]`
/// (C² at both ends).
#[inline]
#[must_use]
pub fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    if e1 <= e0 {
        return if x < e0 { 0.0 } else { 1.0 };
    }
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * t * (t * (6.0 * t - 15.0) + 10.0)
}

/// Derivative of [`smoothstep`] with respect to `x`.
#[inline]
#[must_use]
pub fn smoothstep_deriv(e0: f64, e1: f64, x: f64) -> f64 {
    if e1 <= e0 {
        return 0.0;
    }
    let t = (x - e0) / (e1 - e0);
    if !(0.0..=1.0).contains(&t) {
        return 0.0;
    }
    30.0 * t * t * (t - 1.0) * (t - 1.0) / (e1 - e0)
}

/// Where a point projects onto a polyline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// Euclidean distance (pixels) to the closest point.
    pub dist_px: f64,
    /// Closest point, pixel coordinates `(x, row)`.
    pub closest: [f64; 2],
    /// Arclength (pixels) from the first point to the closest point.
    pub arclength_px: f64,
    /// Unit tangent of the closest segment in pixel coordinates `(x, row)`.
    pub tangent: [f64; 2],
    /// Whether the closest point is strictly inside a segment (not a clamped end or vertex).
    pub interior: bool,
    /// Cross product sign of the tangent and `point − closest` in the **y-up** frame: `> 0` when
    /// the point lies to the left of the direction of travel as seen on screen.
    pub side: f64,
}

/// Validates a polyline (at least one point, all finite, within ±1e7 px).
pub fn check_points(name: &str, points: &[[f32; 2]], min: usize) -> Result<(), RgbnError> {
    if points.len() < min {
        return Err(RgbnError::param(
            name,
            format!("needs at least {min} point(s), got {}", points.len()),
        ));
    }
    if let Some(p) = points
        .iter()
        .find(|p| !(p[0].is_finite() && p[1].is_finite() && p[0].abs() < 1e7 && p[1].abs() < 1e7))
    {
        return Err(RgbnError::param(
            name,
            format!("point {p:?} must be finite with |coordinate| < 1e7 px"),
        ));
    }
    Ok(())
}

/// A polyline prepared for many distance queries (segments, cumulative arclength).
#[derive(Clone, Debug)]
pub struct Polyline {
    pts: Vec<[f64; 2]>,
    cum: Vec<f64>,
    closed: bool,
}

impl Polyline {
    /// From pixel-coordinate points; `closed` adds the segment back to the start. Consecutive
    /// duplicate points are dropped.
    #[must_use]
    pub fn new(points: &[[f32; 2]], closed: bool) -> Self {
        let mut pts: Vec<[f64; 2]> = Vec::with_capacity(points.len() + 1);
        for p in points {
            let p = [f64::from(p[0]), f64::from(p[1])];
            if pts.last().is_none_or(|l| l[0] != p[0] || l[1] != p[1]) {
                pts.push(p);
            }
        }
        if closed && pts.len() > 1 && pts.first() == pts.last() {
            pts.pop();
        }
        let closed = closed && pts.len() >= 3;
        if closed {
            pts.push(pts[0]);
        }
        let mut cum = vec![0.0; pts.len()];
        for i in 1..pts.len() {
            cum[i] = cum[i - 1] + (pts[i][0] - pts[i - 1][0]).hypot(pts[i][1] - pts[i - 1][1]);
        }
        Self { pts, cum, closed }
    }

    /// Total length in pixels.
    #[must_use]
    pub fn length_px(&self) -> f64 {
        self.cum.last().copied().unwrap_or(0.0)
    }

    /// Whether the polyline is closed (≥ 3 distinct points and asked to be closed).
    #[must_use]
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Axis-aligned bounds `[min_x, min_row, max_x, max_row]`.
    #[must_use]
    pub fn bounds(&self) -> [f64; 4] {
        self.pts.iter().fold(
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
            |b, p| {
                [
                    b[0].min(p[0]),
                    b[1].min(p[1]),
                    b[2].max(p[0]),
                    b[3].max(p[1]),
                ]
            },
        )
    }

    /// Closest point on the polyline to `p` (pixel coordinates). `None` for an empty polyline.
    #[must_use]
    pub fn project(&self, p: [f64; 2]) -> Option<Projection> {
        self.project_among(p, 0..self.pts.len().saturating_sub(1))
    }

    /// Segments: segment `i` joins points `i` and `i + 1` (the closing one included).
    #[must_use]
    pub fn segment_count(&self) -> usize {
        self.pts.len().saturating_sub(1)
    }

    /// [`Polyline::project`] onto the segments `segs` only (increasing indices): the same
    /// result whenever the closest segment is among them.
    pub fn project_among(
        &self,
        p: [f64; 2],
        segs: impl IntoIterator<Item = usize>,
    ) -> Option<Projection> {
        let first = *self.pts.first()?;
        if self.pts.len() == 1 {
            let d = (p[0] - first[0]).hypot(p[1] - first[1]);
            return Some(Projection {
                dist_px: d,
                closest: first,
                arclength_px: 0.0,
                tangent: [1.0, 0.0],
                interior: false,
                side: 0.0,
            });
        }
        let mut best: Option<(f64, usize, f64)> = None;
        for i in segs {
            let (a, b) = (self.pts[i], self.pts[i + 1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let l2 = dx * dx + dy * dy;
            let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0);
            let (cx, cy) = (a[0] + t * dx, a[1] + t * dy);
            let d2 = (p[0] - cx).powi(2) + (p[1] - cy).powi(2);
            if best.is_none_or(|(bd, _, _)| d2 < bd) {
                best = Some((d2, i, t));
            }
        }
        let (d2, i, t) = best?;
        let (a, b) = (self.pts[i], self.pts[i + 1]);
        let len = self.cum[i + 1] - self.cum[i];
        let tangent = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
        let closest = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
        // y-up: tangent (tx, −trow), offset (ox, −orow); cross = tx·(−orow) − (−trow)·ox.
        let (ox, orow) = (p[0] - closest[0], p[1] - closest[1]);
        let side = -tangent[0] * orow + tangent[1] * ox;
        Some(Projection {
            dist_px: d2.sqrt(),
            closest,
            arclength_px: self.cum[i] + t * len,
            tangent,
            interior: t > 0.0 && t < 1.0,
            side,
        })
    }

    /// Even–odd inside test (closed polylines only; `false` when open).
    #[must_use]
    pub fn contains(&self, p: [f64; 2]) -> bool {
        if !self.closed {
            return false;
        }
        let mut inside = false;
        for i in 0..self.pts.len() - 1 {
            let (a, b) = (self.pts[i], self.pts[i + 1]);
            if (a[1] > p[1]) != (b[1] > p[1]) {
                let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                if p[0] < x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Points spaced at most `step_px` apart along the polyline (for rasterising).
    #[must_use]
    pub fn densify(&self, step_px: f64) -> Vec<[f64; 2]> {
        let mut out = Vec::new();
        if let Some(&f) = self.pts.first() {
            out.push(f);
        }
        for i in 0..self.pts.len().saturating_sub(1) {
            let (a, b) = (self.pts[i], self.pts[i + 1]);
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            let n = (len / step_px).ceil().max(1.0) as usize;
            for k in 1..=n {
                let t = k as f64 / n as f64;
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        out
    }
}

/// Bilinear sample of a plane at continuous pixel coordinates `(x, row)` (pixel centres at
/// integers); `None` outside `[0, w−1] × [0, h−1]`.
#[inline]
#[must_use]
pub fn bilinear(plane: &[f32], w: usize, h: usize, x: f64, row: f64) -> Option<f32> {
    if w == 0 || h == 0 || plane.len() < w * h {
        return None;
    }
    if !(x >= 0.0 && row >= 0.0 && x <= (w - 1) as f64 && row <= (h - 1) as f64) {
        return None;
    }
    let (x0, r0) = (x.floor() as usize, row.floor() as usize);
    let (x1, r1) = ((x0 + 1).min(w - 1), (r0 + 1).min(h - 1));
    let (fx, fr) = ((x - x0 as f64) as f32, (row - r0 as f64) as f32);
    let a = plane[r0 * w + x0] * (1.0 - fx) + plane[r0 * w + x1] * fx;
    let b = plane[r1 * w + x0] * (1.0 - fx) + plane[r1 * w + x1] * fx;
    Some(a * (1.0 - fr) + b * fr)
}

/// Samples an analytic gradient `f(x, row) → (∂z/∂x, ∂z/∂y)` (y up) at the pixel centres
/// (module docs).
#[must_use]
pub fn sample_gradient_centres(
    width: usize,
    height: usize,
    f: impl Fn(f64, f64) -> [f64; 2] + Sync,
) -> GradientField {
    let mut g = GradientField::zeros(width, height);
    g.p.par_chunks_mut(width.max(1))
        .zip(g.q.par_chunks_mut(width.max(1)))
        .enumerate()
        .for_each(|(r, (pr, qr))| {
            for x in 0..width {
                let [gp, gq] = f(x as f64, r as f64);
                (pr[x], qr[x]) = (gp as f32, gq as f32);
            }
        });
    g
}

/// Stand-in for "no seed" in the 1-D transform (keeps the parabola maths finite).
const EDT_FAR: f64 = 1e20;

/// One-dimensional squared-distance transform of Felzenszwalb & Huttenlocher: `d[i] =
/// min_j ((i − j)² + f[j])`, in `O(n)` with the lower envelope of parabolas.
fn edt_1d(f: &[f64], d: &mut [f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    if n == 0 {
        return;
    }
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let sq = |i: usize| (i * i) as f64;
    for q in 1..n {
        let mut s;
        loop {
            let p = v[k];
            s = ((f[q] + sq(q)) - (f[p] + sq(p))) / (2.0 * (q - p) as f64);
            if s <= z[k] && k > 0 {
                k -= 1;
            } else {
                break;
            }
        }
        if s <= z[k] {
            // k == 0 and the new parabola is below the old one everywhere.
            v[0] = q;
            z[0] = f64::NEG_INFINITY;
            z[1] = f64::INFINITY;
            continue;
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        *out = (q as f64 - p as f64).powi(2) + f[p];
    }
}

/// Exact Euclidean distance (pixels) from every pixel to the nearest `true` seed (Felzenszwalb
/// & Huttenlocher 2012: 1-D transform along columns, then rows). `+∞` when there is no seed.
#[must_use]
pub fn distance_transform(seeds: &[bool], width: usize, height: usize) -> Plane {
    let mut f: Vec<f64> = seeds
        .iter()
        .map(|&s| if s { 0.0 } else { EDT_FAR })
        .collect();
    // Columns.
    let cols: Vec<Vec<f64>> = (0..width)
        .into_par_iter()
        .map(|x| {
            let col: Vec<f64> = (0..height).map(|r| f[r * width + x]).collect();
            let mut d = vec![0.0; height];
            let (mut v, mut z) = (vec![0usize; height], vec![0.0; height + 1]);
            edt_1d(&col, &mut d, &mut v, &mut z);
            d
        })
        .collect();
    for (x, col) in cols.iter().enumerate() {
        for (r, val) in col.iter().enumerate() {
            f[r * width + x] = *val;
        }
    }
    // Rows.
    let mut out = buf::zeroed_f32(width * height);
    out.par_chunks_mut(width.max(1))
        .zip(f.par_chunks(width.max(1)))
        .for_each(|(o, row)| {
            let mut d = vec![0.0; width];
            let (mut v, mut z) = (vec![0usize; width], vec![0.0; width + 1]);
            edt_1d(row, &mut d, &mut v, &mut z);
            for (o, d) in o.iter_mut().zip(&d) {
                *o = if *d >= EDT_FAR * 0.5 {
                    f32::INFINITY
                } else {
                    d.sqrt() as f32
                };
            }
        });
    Plane::from_vec(width, height, out).expect("sizes match by construction")
}

/// Least-squares height of a gradient field: minimises `Σ (z(x+1,r) − z(x,r) − p)² +
/// (z(r−1,x) − z(r,x) − q)²` over the differences inside the image (the forward-difference
/// convention of [`GradientField::from_height`]), by conjugate gradients on the normal equations
/// `DᵀD z = Dᵀg` (the discrete Neumann Poisson problem). The result has zero mean. For an
/// integrable field it recovers the height exactly (to the tolerance); meant for small fields
/// (stamps): unpreconditioned CG needs `O(side)` iterations, so the cost is `O(side³)`
/// (rows in parallel).
#[must_use]
pub fn integrate_least_squares(g: &GradientField, rel_tol: f64, max_iter: usize) -> Plane {
    let (w, h) = (g.width, g.height);
    let n = w * h;
    // DᵀD z in gather form: Σ over the 4-neighbours inside the image of (z_i − z_j)
    // (the Neumann Laplacian), rows in parallel.
    let apply_dtd = |z: &[f64], out: &mut [f64]| {
        out.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(r, orow)| {
                for (x, o) in orow.iter_mut().enumerate() {
                    let i = r * w + x;
                    let zi = z[i];
                    let mut acc = 0.0;
                    if x >= 1 {
                        acc += zi - z[i - 1];
                    }
                    if x + 1 < w {
                        acc += zi - z[i + 1];
                    }
                    if r >= 1 {
                        acc += zi - z[i - w];
                    }
                    if r + 1 < h {
                        acc += zi - z[i + w];
                    }
                    *o = acc;
                }
            });
    };
    let pdot = ordered_dot;
    let mut b = vec![0.0f64; n];
    for r in 0..h {
        for x in 0..w {
            let i = r * w + x;
            if x + 1 < w {
                let p = f64::from(g.p[i]);
                b[i + 1] += p;
                b[i] -= p;
            }
            if r >= 1 {
                let q = f64::from(g.q[i]);
                b[i - w] += q;
                b[i] -= q;
            }
        }
    }
    let mut z = vec![0.0f64; n];
    let mut res = b.clone();
    let mut dir = res.clone();
    let mut ad = vec![0.0f64; n];
    let b_norm = pdot(&b, &b).sqrt();
    let mut rr: f64 = pdot(&res, &res);
    if b_norm > 0.0 {
        for _ in 0..max_iter {
            if rr.sqrt() <= rel_tol * b_norm {
                break;
            }
            apply_dtd(&dir, &mut ad);
            let dad: f64 = pdot(&dir, &ad);
            if dad <= 0.0 {
                break;
            }
            let alpha = rr / dad;
            z.par_iter_mut()
                .zip(dir.par_iter())
                .for_each(|(z, d)| *z += alpha * d);
            res.par_iter_mut()
                .zip(ad.par_iter())
                .for_each(|(r, a)| *r -= alpha * a);
            let rr_new: f64 = pdot(&res, &res);
            let beta = rr_new / rr;
            rr = rr_new;
            dir.par_iter_mut()
                .zip(res.par_iter())
                .for_each(|(d, r)| *d = r + beta * *d);
        }
    }
    // Constants are the null space of DᵀD: remove the mean.
    let mean = z.iter().sum::<f64>() / n.max(1) as f64;
    Plane::from_vec(w, h, z.iter().map(|v| (v - mean) as f32).collect())
        .expect("sizes match by construction")
}

/// Test fixture: a `size × size` crop (top-left) of the Poly Haven rosewood veneer (colour +
/// GL normal map) from the real test data ([`crate::test_data`]); `None` when it is absent.
#[cfg(test)]
pub(crate) fn rosewood_crop(size: usize) -> Option<crate::raster::RgbnImage> {
    use crate::raster::io::{load, InputSpec, LoadOptions};
    let dir = crate::test_data::real_data("polyhaven-rosewood-veneer")?;
    let (color, normal) = (
        dir.join("rosewood_veneer1_diff_1k.jpg"),
        dir.join("rosewood_veneer1_nor_gl_1k.png"),
    );
    let spec = InputSpec {
        color: Some(color),
        normal: Some(normal),
        ..InputSpec::default()
    };
    // The data is there: failing to read or crop it fails the test (never a silent skip).
    let img = load(&spec, &LoadOptions::default())
        .expect("the rosewood texture loads")
        .image;
    let crop = super::stamp::extract_stamp(
        &img,
        0,
        0,
        size.min(img.width()),
        size.min(img.height()),
        None,
    )
    .expect("the crop is inside the texture");
    Some(crop)
}

/// The segments of a polyline that come within `reach` pixels of each cell of a grid: a point
/// farther than `reach` from every segment listed for its cell is farther than `reach` from
/// the polyline, and the closest segment of a point within `reach` is listed.
#[derive(Clone, Debug)]
pub struct SegmentGrid {
    cell: f64,
    origin: [f64; 2],
    cols: usize,
    rows: usize,
    /// `start[c]..start[c + 1]` indexes `segs` for cell `c` (row-major).
    start: Vec<u32>,
    segs: Vec<u32>,
}

impl SegmentGrid {
    /// Over the area `[x0, y0, x1, y1]` with square cells of `cell` pixels.
    #[must_use]
    pub fn new(pl: &Polyline, reach: f64, area: [f64; 4], cell: f64) -> Self {
        let cols = (((area[2] - area[0]) / cell).ceil().max(0.0) as usize) + 1;
        let rows = (((area[3] - area[1]) / cell).ceil().max(0.0) as usize) + 1;
        let origin = [area[0], area[1]];
        let n = pl.segment_count();
        // The cells each segment's box, grown by `reach`, overlaps (clamped to the grid).
        let span = |i: usize| -> Option<[usize; 4]> {
            let (a, b) = (pl.pts[i], pl.pts[i + 1]);
            let lo = [a[0].min(b[0]) - reach, a[1].min(b[1]) - reach];
            let hi = [a[0].max(b[0]) + reach, a[1].max(b[1]) + reach];
            let c =
                |v: f64, o: f64, m: usize| ((v - o) / cell).floor().clamp(0.0, m as f64) as usize;
            if hi[0] < origin[0] || hi[1] < origin[1] || lo[0] > area[2] || lo[1] > area[3] {
                return None;
            }
            Some([
                c(lo[0], origin[0], cols - 1),
                c(lo[1], origin[1], rows - 1),
                c(hi[0], origin[0], cols - 1),
                c(hi[1], origin[1], rows - 1),
            ])
        };
        let mut count = vec![0u32; cols * rows + 1];
        for i in 0..n {
            if let Some([c0, r0, c1, r1]) = span(i) {
                for r in r0..=r1 {
                    for c in c0..=c1 {
                        count[r * cols + c + 1] += 1;
                    }
                }
            }
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let mut fill = count.clone();
        let mut segs = vec![0u32; count[cols * rows] as usize];
        for i in 0..n {
            if let Some([c0, r0, c1, r1]) = span(i) {
                for r in r0..=r1 {
                    for c in c0..=c1 {
                        let k = r * cols + c;
                        segs[fill[k] as usize] = i as u32;
                        fill[k] += 1;
                    }
                }
            }
        }
        Self {
            cell,
            origin,
            cols,
            rows,
            start: count,
            segs,
        }
    }

    /// The segments listed for the cell of `(x, y)` (increasing; empty outside the area).
    #[must_use]
    pub fn at(&self, x: f64, y: f64) -> &[u32] {
        let (c, r) = (
            ((x - self.origin[0]) / self.cell).floor(),
            ((y - self.origin[1]) / self.cell).floor(),
        );
        if !(c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows) {
            return &[];
        }
        let k = r as usize * self.cols + c as usize;
        &self.segs[self.start[k] as usize..self.start[k + 1] as usize]
    }
}

/// Boxes `[x0, y0, x1, y1]` covering where a stroke along `old` and one along `new` can differ,
/// for strokes whose effect at a point depends on the path within `reach_px` of it and on the
/// arclength from the path's start, plus — `back_px` — on the distance to its end (a taper).
/// Points are compared as the `f32` operators use. The paths share a prefix; what follows it
/// differs, and so does the part within `back_px` before its end. Empty when equal.
#[must_use]
pub fn changed_path_bounds(
    old: &[[f64; 2]],
    new: &[[f64; 2]],
    back_px: f64,
    reach_px: f64,
) -> Vec<[f64; 4]> {
    let f = |p: &[f64; 2]| p.map(|v| v as f32);
    let k = old
        .iter()
        .zip(new)
        .take_while(|(a, b)| f(a) == f(b))
        .count();
    if k == old.len() && k == new.len() {
        return Vec::new();
    }
    let mut out = Vec::new();
    for path in [old, new] {
        let pts: Vec<[f32; 2]> = path.iter().map(f).collect();
        let mut cum = vec![0.0f64; pts.len()];
        for i in 1..pts.len() {
            cum[i] = cum[i - 1]
                + f64::from(pts[i][0] - pts[i - 1][0]).hypot(f64::from(pts[i][1] - pts[i - 1][1]));
        }
        // From the last shared vertex at least `back_px` (of arclength) before the prefix's end.
        let start = match k {
            0 => 0,
            _ => {
                let at = cum[k - 1] - back_px;
                (0..k).rev().find(|&j| cum[j] <= at).unwrap_or(0)
            }
        };
        let part = &pts[start..];
        if part.is_empty() {
            continue;
        }
        let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for p in part {
            let (x, y) = (f64::from(p[0]), f64::from(p[1]));
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
        out.push([
            b[0] - reach_px,
            b[1] - reach_px,
            b[2] + reach_px,
            b[3] + reach_px,
        ]);
    }
    out
}

/// The bounding box of all `paths`' points grown by `reach_px` (`None` without points).
#[must_use]
pub fn paths_bounds(paths: &[&[[f64; 2]]], reach_px: f64) -> Option<[f64; 4]> {
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    let mut any = false;
    for p in paths.iter().flat_map(|p| p.iter()) {
        let (x, y) = (f64::from(p[0] as f32), f64::from(p[1] as f32));
        b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        any = true;
    }
    any.then(|| {
        [
            b[0] - reach_px,
            b[1] - reach_px,
            b[2] + reach_px,
            b[3] + reach_px,
        ]
    })
}

/// Where a closed path meets itself: segment `first` and segment `second` (segment `k` joins
/// points `k` and `k + 1` of the path as given, the last one the last point and point 0;
/// `first < second`) share the point `at`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfCrossing {
    /// The lower-numbered segment.
    pub first: usize,
    /// The other segment.
    pub second: usize,
    /// A point both segments contain (pixels, `(x, row)`).
    pub at: [f64; 2],
}

/// `(b − a) × (c − a)`: > 0 when `c` is to the left of `a → b` in `(x, row)` coordinates.
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether `p`, collinear with `a → b`, lies within the segment's bounding box.
fn within(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

/// A point shared by segments `a → b` and `c → d`, if any (crossing, touching or overlapping).
fn segments_meet(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> Option<[f64; 2]> {
    let (o1, o2) = (orient(a, b, c), orient(a, b, d));
    let (o3, o4) = (orient(c, d, a), orient(c, d, b));
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        let t = o3 / (o3 - o4);
        return Some([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
    }
    // Touching or collinear: an end of one segment on the other.
    [(o1, a, b, c), (o2, a, b, d), (o3, c, d, a), (o4, c, d, b)]
        .into_iter()
        .find(|&(o, s, e, p)| o == 0.0 && within(s, e, p))
        .map(|(_, _, _, p)| p)
}

/// The first place (lowest pair of segment numbers) where the closed path through `points`
/// meets itself, or `None` for a simple closed path. Two segments that follow each other
/// (zero-length segments of repeated points skipped) meet only if the second turns back along
/// the first; any other two meet if they share any point — crossing, touching at a vertex, or
/// overlapping. Paths with fewer than three distinct points are not checked (`None`).
///
/// Segments are swept in order of their leftmost `x`, so only pairs whose `x` ranges overlap
/// are compared (about linear in the number of points for paths drawn by hand).
#[must_use]
pub fn closed_path_crossing(points: &[[f64; 2]]) -> Option<SelfCrossing> {
    let n = points.len();
    // Non-degenerate segments, in path order: (segment number, start, end).
    let segs: Vec<(usize, [f64; 2], [f64; 2])> = (0..n)
        .map(|k| (k, points[k], points[(k + 1) % n]))
        .filter(|(_, a, b)| a != b)
        .collect();
    let m = segs.len();
    if m < 3 {
        return None;
    }
    let mut best: Option<SelfCrossing> = None;
    let mut found = |i: usize, j: usize, at: [f64; 2]| {
        let (first, second) = (segs[i.min(j)].0, segs[i.max(j)].0);
        if best.is_none_or(|b| (first, second) < (b.first, b.second)) {
            best = Some(SelfCrossing { first, second, at });
        }
    };
    // Consecutive segments share the vertex between them: they meet elsewhere only when the
    // second goes back along the first (collinear, opposite directions).
    for i in 0..m {
        let j = (i + 1) % m;
        let (_, a, b) = segs[i];
        let (_, _, d) = segs[j];
        let (u, v) = ([b[0] - a[0], b[1] - a[1]], [d[0] - b[0], d[1] - b[1]]);
        if u[0] * v[1] - u[1] * v[0] == 0.0 && u[0] * v[0] + u[1] * v[1] < 0.0 {
            // The shorter of the two, measured from the shared vertex, lies on the other.
            let short = if u[0].hypot(u[1]) < v[0].hypot(v[1]) {
                a
            } else {
                d
            };
            found(i, j, short);
        }
    }
    let lo = |s: &(usize, [f64; 2], [f64; 2])| s.1[0].min(s.2[0]);
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| lo(&segs[i]).total_cmp(&lo(&segs[j])));
    for (k, &i) in order.iter().enumerate() {
        let (_, a, b) = segs[i];
        let (x_hi, y_lo, y_hi) = (a[0].max(b[0]), a[1].min(b[1]), a[1].max(b[1]));
        for &j in &order[k + 1..] {
            let (_, c, d) = segs[j];
            if c[0].min(d[0]) > x_hi {
                break;
            }
            let adjacent = (i + 1) % m == j || (j + 1) % m == i;
            if adjacent || c[1].max(d[1]) < y_lo || c[1].min(d[1]) > y_hi {
                continue;
            }
            if let Some(at) = segments_meet(a, b, c, d) {
                found(i, j, at);
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edt_matches_brute_force() {
        let (w, h) = (23, 17);
        let seeds: Vec<bool> = (0..w * h).map(|i| (i * 7919) % 37 == 3).collect();
        let d = distance_transform(&seeds, w, h);
        for r in 0..h {
            for x in 0..w {
                let mut best = f64::INFINITY;
                for (j, s) in seeds.iter().enumerate() {
                    if *s {
                        let (sx, sr) = ((j % w) as f64, (j / w) as f64);
                        best = best.min((x as f64 - sx).hypot(r as f64 - sr));
                    }
                }
                assert!((f64::from(d.at(x, r)) - best).abs() < 1e-5, "({x},{r})");
            }
        }
        assert!(distance_transform(&[false; 6], 3, 2)
            .data()
            .iter()
            .all(|v| v.is_infinite()));
    }

    #[test]
    fn projection_side_and_arclength() {
        // Path going right along row 10; a point above it on screen (smaller row) is on the
        // left of the direction of travel.
        let pl = Polyline::new(&[[0.0, 10.0], [20.0, 10.0]], false);
        let pr = pl.project([5.0, 7.0]).unwrap();
        assert!((pr.dist_px - 3.0).abs() < 1e-12 && pr.side > 0.0 && pr.interior);
        assert!((pr.arclength_px - 5.0).abs() < 1e-12);
        assert!(pl.project([5.0, 12.0]).unwrap().side < 0.0);
        let sq = Polyline::new(&[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]], true);
        assert!(sq.contains([5.0, 5.0]) && !sq.contains([15.0, 5.0]));
        assert!((sq.length_px() - 40.0).abs() < 1e-12);
    }

    #[test]
    fn least_squares_integration_recovers_a_height() {
        let z = Plane::from_fn(31, 24, |x, r| {
            ((x as f32) * 0.3).sin() * 4.0 + (r as f32 * 0.2).cos() * 3.0 + 0.01 * (x * r) as f32
        });
        let g = GradientField::from_height(&z);
        let zi = integrate_least_squares(&g, 1e-10, 5000);
        let mean = z.data().iter().sum::<f32>() / z.data().len() as f32;
        let err = z
            .data()
            .iter()
            .zip(zi.data())
            .map(|(a, b)| (a - mean - b).abs())
            .fold(0.0f32, f32::max);
        assert!(err < 1e-3, "{err}");
    }

    /// Brute force over every pair of segments: the reference for the sweep.
    fn crossing_brute(points: &[[f64; 2]]) -> Option<(usize, usize)> {
        let n = points.len();
        let segs: Vec<(usize, [f64; 2], [f64; 2])> = (0..n)
            .map(|k| (k, points[k], points[(k + 1) % n]))
            .filter(|(_, a, b)| a != b)
            .collect();
        let m = segs.len();
        if m < 3 {
            return None;
        }
        for i in 0..m {
            for j in i + 1..m {
                let adjacent = j == i + 1 || (i == 0 && j == m - 1);
                let (_, a, b) = segs[i];
                let (_, c, d) = segs[j];
                let meet = if adjacent {
                    // Shared vertex; anything more is a turn back along the first.
                    let (p, q, r) = if j == i + 1 { (a, b, d) } else { (c, d, b) };
                    let (u, v) = ([q[0] - p[0], q[1] - p[1]], [r[0] - q[0], r[1] - q[1]]);
                    u[0] * v[1] - u[1] * v[0] == 0.0 && u[0] * v[0] + u[1] * v[1] < 0.0
                } else {
                    segments_meet(a, b, c, d).is_some()
                };
                if meet {
                    return Some((segs[i].0, segs[j].0));
                }
            }
        }
        None
    }

    #[test]
    fn closed_path_crossings_are_found_with_their_segments() {
        // A square: simple, in either direction, with a repeated point or the start repeated.
        let square = [[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        assert_eq!(closed_path_crossing(&square), None);
        let mut rev = square;
        rev.reverse();
        assert_eq!(closed_path_crossing(&rev), None);
        let dup = [
            square[0], square[1], square[1], square[2], square[3], square[0],
        ];
        assert_eq!(closed_path_crossing(&dup), None);
        // A bow tie: segment 1 (points 1 → 2) crosses segment 3 (points 3 → 0) at (30, 30).
        let bow = [[10.0, 10.0], [50.0, 10.0], [10.0, 50.0], [50.0, 50.0]];
        let c = closed_path_crossing(&bow).unwrap();
        assert_eq!((c.first, c.second), (1, 3));
        assert!(
            (c.at[0] - 30.0).abs() < 1e-12 && (c.at[1] - 30.0).abs() < 1e-12,
            "{c:?}"
        );
        // A vertex touching another segment (a figure eight pinched at a point).
        let pinch = [
            [0.0, 0.0],
            [20.0, 0.0],
            [10.0, 10.0],
            [20.0, 20.0],
            [0.0, 20.0],
            [10.0, 10.0],
        ];
        let c = closed_path_crossing(&pinch).unwrap();
        assert_eq!(c.at, [10.0, 10.0]);
        // A spike: the path goes out and comes back along the same line.
        let spike = [
            [0.0, 0.0],
            [20.0, 0.0],
            [20.0, 20.0],
            [20.0, 40.0],
            [20.0, 30.0],
            [0.0, 20.0],
        ];
        let c = closed_path_crossing(&spike).unwrap();
        assert_eq!((c.first, c.second), (2, 3));
        // Fewer than three distinct points: not a closed path, not checked here.
        assert_eq!(
            closed_path_crossing(&[[0.0, 0.0], [5.0, 5.0], [0.0, 0.0]]),
            None
        );
    }

    #[test]
    fn the_sweep_finds_a_crossing_exactly_when_brute_force_does() {
        // Random polygons on a small integer grid (many touching and collinear cases).
        let mut state = 12345u64;
        let mut next = |k: u64| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) % k) as f64
        };
        let (mut simple, mut crossing) = (0, 0);
        for _ in 0..4000 {
            let n = 3 + next(6) as usize;
            let pts: Vec<[f64; 2]> = (0..n).map(|_| [next(6), next(6)]).collect();
            let got = closed_path_crossing(&pts);
            let want = crossing_brute(&pts);
            assert_eq!(got.map(|c| (c.first, c.second)), want, "{pts:?}");
            if let Some(c) = got {
                crossing += 1;
                // The reported point lies on both segments.
                for k in [c.first, c.second] {
                    let (a, b) = (pts[k], pts[(k + 1) % n]);
                    assert!(orient(a, b, c.at).abs() < 1e-9 * 100.0, "{pts:?} {c:?}");
                    let eps = 1e-9;
                    assert!(
                        c.at[0] >= a[0].min(b[0]) - eps && c.at[0] <= a[0].max(b[0]) + eps,
                        "{pts:?} {c:?}"
                    );
                }
            } else {
                simple += 1;
            }
        }
        assert!(simple > 100 && crossing > 100, "{simple} {crossing}");
    }
}
