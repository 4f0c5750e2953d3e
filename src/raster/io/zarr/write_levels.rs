//! The levels of one chunk-grid cell, from its level-0 pixels: the block means of
//! [`crate::raster::pyramid`] (RGBN: colour and normals weighted by coverage, normals
//! renormalised, the mask the covered fraction; masks and fields: plain means; pictures:
//! rounded means of the bytes). Sums are kept per coarse pixel and added up level after level
//! (level `k + 1` from level `k`'s sums, not from the pixels), so each level costs a quarter of
//! the one before. Level 1 adds the pixels in the order `reduce_rgbn` does, so it is that
//! function's result bit for bit; coarser levels add the same numbers grouped by 2 × 2 blocks,
//! within `f64` rounding of it (exact for pictures, whose sums are integers).
//!
//! A cell's origin is a multiple of its side, which is a multiple of `2^k` for every level
//! written, so the blocks of a cell are the blocks of the whole image (clipped at its right
//! and bottom edges as the whole image's are).

use super::Content;

/// The sums of a cell at one level: `k` values per coarse pixel.
pub(super) struct Pyramid {
    content: Content,
    /// Width and height of the level the sums are of (0 × 0 before the first).
    w: usize,
    h: usize,
    /// Level-0 size, for the first level.
    w0: usize,
    h0: usize,
    /// Values per coarse pixel.
    k: usize,
    sums: Vec<f64>,
}

impl Pyramid {
    /// The sums of level 1 of a `cw × ch` cell from its level-0 planes (one per channel of
    /// `content`).
    pub(super) fn new(content: Content, cw: usize, ch: usize, planes: &[Vec<f32>]) -> Self {
        let (w, h) = (cw.div_ceil(2), ch.div_ceil(2));
        let k = match content {
            // Σm·c (3), Σm·n (3), Σm, count.
            Content::Rgbn { .. } => 8,
            // Σv per channel, count.
            Content::Picture => 5,
            Content::Mask | Content::Scalar => 2,
        };
        let mut sums = vec![0f64; w * h * k];
        for (cy, row) in sums.chunks_mut(w * k).enumerate() {
            for (cx, acc) in row.chunks_mut(k).enumerate() {
                let (x0, x1) = (2 * cx, (2 * cx + 2).min(cw));
                let (y0, y1) = (2 * cy, (2 * cy + 2).min(ch));
                match content {
                    Content::Rgbn { mask } => {
                        for y in y0..y1 {
                            for x in x0..x1 {
                                let i = y * cw + x;
                                let m = if mask { f64::from(planes[6][i]) } else { 1.0 };
                                acc[6] += m;
                                acc[7] += 1.0;
                                for c in 0..3 {
                                    acc[c] += m * f64::from(planes[c][i]);
                                    acc[3 + c] += m * f64::from(planes[3 + c][i]);
                                }
                            }
                        }
                    }
                    _ => {
                        let nc = k - 1;
                        for y in y0..y1 {
                            for (c, a) in acc[..nc].iter_mut().enumerate() {
                                // A row's part first, then the rows (as `reduce_plane`).
                                let p = &planes[c][y * cw + x0..y * cw + x1];
                                *a += p.iter().map(|&v| f64::from(v)).sum::<f64>();
                            }
                            acc[nc] += (x1 - x0) as f64;
                        }
                    }
                }
            }
        }
        Self {
            content,
            w: 0,
            h: 0,
            w0: w,
            h0: h,
            k,
            sums,
        }
    }

    /// The next level's planes (level 1 first) and its size.
    pub(super) fn next_level(&mut self) -> (usize, usize, Vec<Vec<f32>>) {
        if self.w == 0 {
            (self.w, self.h) = (self.w0, self.h0);
        } else {
            // Sums of 2 × 2 blocks of the previous level's sums.
            let (pw, ph, k) = (self.w, self.h, self.k);
            let (w, h) = (pw.div_ceil(2), ph.div_ceil(2));
            let mut next = vec![0f64; w * h * k];
            for cy in 0..h {
                for cx in 0..w {
                    let acc = &mut next[(cy * w + cx) * k..(cy * w + cx + 1) * k];
                    for y in 2 * cy..(2 * cy + 2).min(ph) {
                        for x in 2 * cx..(2 * cx + 2).min(pw) {
                            let s = &self.sums[(y * pw + x) * k..(y * pw + x + 1) * k];
                            for (a, v) in acc.iter_mut().zip(s) {
                                *a += v;
                            }
                        }
                    }
                }
            }
            self.sums = next;
            (self.w, self.h) = (w, h);
        }
        (self.w, self.h, self.finish())
    }

    /// The means of the current sums, one plane per channel.
    fn finish(&self) -> Vec<Vec<f32>> {
        let n = self.w * self.h;
        let k = self.k;
        match self.content {
            Content::Rgbn { mask } => {
                let mut out: Vec<Vec<f32>> = (0..if mask { 7 } else { 6 })
                    .map(|_| Vec::with_capacity(n))
                    .collect();
                for acc in self.sums.chunks(k) {
                    let cov = acc[6];
                    for c in 0..3 {
                        out[c].push(if cov > 0.0 { acc[c] / cov } else { 0.0 } as f32);
                    }
                    let v = [acc[3], acc[4], acc[5]];
                    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    let nrm = if len > 1e-12 && len.is_finite() {
                        v.map(|c| c / len)
                    } else {
                        [0.0, 0.0, 1.0]
                    };
                    for c in 0..3 {
                        out[3 + c].push(nrm[c] as f32);
                    }
                    if mask {
                        out[6].push((cov / acc[7]) as f32);
                    }
                }
                out
            }
            Content::Picture => (0..4)
                .map(|c| {
                    self.sums
                        .chunks(k)
                        .map(|acc| {
                            let (a, n) = (acc[c] as u64, acc[4] as u64);
                            ((a + n / 2) / n) as f32
                        })
                        .collect()
                })
                .collect(),
            Content::Mask | Content::Scalar => {
                vec![self
                    .sums
                    .chunks(k)
                    .map(|acc| (acc[0] / acc[1]) as f32)
                    .collect()]
            }
        }
    }
}
