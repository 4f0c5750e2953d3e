//! Levels of detail: an image reduced by a whole factor `s` (`2^level`), each coarse pixel the
//! mean of the `s × s` block of fine pixels it covers (clipped at the right and bottom edges,
//! so a `w × h` image gives `⌈w/s⌉ × ⌈h/s⌉`).
//!
//! RGBN: colour and normals weighted by coverage (the mask, 1 without one), normals
//! renormalised (a zero mean becomes straight up); the coarse mask, if any, is the covered
//! fraction. Scalar planes and 8-bit pictures: plain means.

use super::{Plane, RgbnImage};
use rayon::prelude::*;

/// The size of a `size` image reduced by `s`.
#[must_use]
pub fn reduced_size(size: (usize, usize), s: usize) -> (usize, usize) {
    let s = s.max(1);
    (size.0.div_ceil(s), size.1.div_ceil(s))
}

/// The fine pixels (start, end) of coarse index `i` along an axis of `n` fine pixels.
fn span(i: usize, s: usize, n: usize) -> (usize, usize) {
    (i * s, ((i + 1) * s).min(n))
}

/// `img` reduced by `s` (module docs); `s ≤ 1` returns a copy.
#[must_use]
pub fn reduce_rgbn(img: &RgbnImage, s: usize) -> RgbnImage {
    if s <= 1 {
        return img.clone();
    }
    let (w, h) = (img.width(), img.height());
    let (cw, ch) = reduced_size((w, h), s);
    let (color, normal, mask) = (img.color(), img.normal(), img.mask());
    // Per coarse row: 3 colour, 3 normal, 1 coverage values per coarse pixel.
    #[allow(clippy::needless_range_loop)] // `cx` indexes seven planes and the span
    let rows: Vec<[Vec<f32>; 7]> = (0..ch)
        .into_par_iter()
        .map(|cy| {
            let (y0, y1) = span(cy, s, h);
            let mut out: [Vec<f32>; 7] = std::array::from_fn(|_| vec![0.0; cw]);
            for cx in 0..cw {
                let (x0, x1) = span(cx, s, w);
                let mut acc = [0.0f64; 6];
                let (mut cov, mut count) = (0.0f64, 0usize);
                for y in y0..y1 {
                    for x in x0..x1 {
                        let i = y * w + x;
                        let m = mask.map_or(1.0, |m| f64::from(m[i]));
                        cov += m;
                        count += 1;
                        for k in 0..3 {
                            acc[k] += m * f64::from(color[k][i]);
                            acc[3 + k] += m * f64::from(normal[k][i]);
                        }
                    }
                }
                let c: [f64; 3] =
                    std::array::from_fn(|k| if cov > 0.0 { acc[k] / cov } else { 0.0 });
                let v = [acc[3], acc[4], acc[5]];
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                let n = if len > 1e-12 && len.is_finite() {
                    v.map(|c| c / len)
                } else {
                    [0.0, 0.0, 1.0]
                };
                for k in 0..3 {
                    out[k][cx] = c[k] as f32;
                    out[3 + k][cx] = n[k] as f32;
                }
                out[6][cx] = (cov / count as f64) as f32;
            }
            out
        })
        .collect();
    let plane = |k: usize| -> Vec<f32> { rows.iter().flat_map(|r| r[k].iter().copied()).collect() };
    let color = std::array::from_fn(&plane);
    let normal = std::array::from_fn(|k| plane(3 + k));
    let mask = mask.map(|_| plane(6));
    RgbnImage::new(cw, ch, color, normal, mask).expect("planes of the reduced size")
}

/// `p` reduced by `s` (plain block means); `s ≤ 1` returns a copy.
#[must_use]
pub fn reduce_plane(p: &Plane, s: usize) -> Plane {
    if s <= 1 {
        return p.clone();
    }
    let (w, h) = (p.width(), p.height());
    let (cw, ch) = reduced_size((w, h), s);
    let d = p.data();
    Plane::from_fn(cw, ch, |cx, cy| {
        let ((x0, x1), (y0, y1)) = (span(cx, s, w), span(cy, s, h));
        let mut sum = 0.0f64;
        for y in y0..y1 {
            sum += d[y * w + x0..y * w + x1]
                .iter()
                .map(|&v| f64::from(v))
                .sum::<f64>();
        }
        (sum / ((x1 - x0) * (y1 - y0)) as f64) as f32
    })
}

/// Interleaved 8-bit RGBA of a `w × h` picture reduced by `s` (rounded block means).
#[must_use]
pub fn reduce_rgba8(rgba: &[u8], w: usize, h: usize, s: usize) -> Vec<u8> {
    let (cw, ch) = reduced_size((w, h), s.max(1));
    let s = s.max(1);
    (0..ch)
        .into_par_iter()
        .flat_map_iter(|cy| {
            let (y0, y1) = span(cy, s, h);
            (0..cw).flat_map(move |cx| {
                let (x0, x1) = span(cx, s, w);
                let mut acc = [0u32; 4];
                for y in y0..y1 {
                    for x in x0..x1 {
                        for (k, a) in acc.iter_mut().enumerate() {
                            *a += u32::from(rgba[(y * w + x) * 4 + k]);
                        }
                    }
                }
                let n = ((x1 - x0) * (y1 - y0)) as u32;
                acc.map(|a| ((a + n / 2) / n) as u8)
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_rgbn_is_the_coverage_weighted_block_mean_with_clipped_edges() {
        // 3 × 2 image, s = 2: coarse 2 × 1; the right block is one column wide.
        let n = [0.0f32, 0.6, 0.8];
        let img = RgbnImage::new(
            3,
            2,
            [
                vec![0.1, 0.3, 0.5, 0.2, 0.4, 0.7],
                vec![0.0; 6],
                vec![1.0; 6],
            ],
            [vec![n[0]; 6], vec![n[1]; 6], vec![n[2]; 6]],
            Some(vec![1.0, 1.0, 1.0, 0.0, 1.0, 0.0]),
        )
        .unwrap();
        let r = reduce_rgbn(&img, 2);
        assert_eq!((r.width(), r.height()), (2, 1));
        // Left block: pixels 0, 1, 3 (covered 1, 1, 0) and 4 (covered 1).
        let want = (0.1 + 0.3 + 0.4) / 3.0;
        assert!((r.color()[0][0] - want).abs() < 1e-6);
        assert!((r.mask().unwrap()[0] - 0.75).abs() < 1e-6);
        // Right block: pixels 2 (covered) and 5 (not).
        assert!((r.color()[0][1] - 0.5).abs() < 1e-6);
        assert!((r.mask().unwrap()[1] - 0.5).abs() < 1e-6);
        // Equal unit normals stay themselves.
        for (plane, want) in r.normal().iter().zip(n) {
            assert!((plane[0] - want).abs() < 1e-6);
        }
    }

    #[test]
    fn reduced_planes_and_pictures_are_block_means() {
        let p = Plane::from_fn(5, 3, |x, y| (x + 10 * y) as f32);
        let r = reduce_plane(&p, 2);
        assert_eq!((r.width(), r.height()), (3, 2));
        assert_eq!(r.data()[0], (0.0 + 1.0 + 10.0 + 11.0) / 4.0);
        assert_eq!(r.data()[2], (4.0 + 14.0) / 2.0);
        assert_eq!(r.data()[5], 24.0);
        let rgba: Vec<u8> = (0..4 * 4).map(|i| (i * 10) as u8).collect();
        let r = reduce_rgba8(&rgba, 2, 2, 2);
        // Channel 0 of the four pixels: 0, 40, 80, 120.
        assert_eq!(r[0], 60);
        assert_eq!(r.len(), 4);
    }
}
