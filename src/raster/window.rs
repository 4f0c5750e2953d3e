//! Rectangles of images: [`Window`] (a rectangle at a level of detail) and [`Rect`] (a pixel
//! rectangle), with the row copies that cut and assemble planes by rectangle. The value-level
//! forms (crop, reduce, window of a graph value) are `crate::nodes::value`'s.

use rayon::prelude::*;

/// A rectangle of an image: columns `x..x + w`, rows `y..y + h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
    /// Pixels of the full image per pixel of the window's grid along each axis (`2^level` at a
    /// level of detail; 1 at full resolution): pixel `(x, row)` covers full-image pixels
    /// `x·scale .. (x + 1)·scale`, and heights are in the window's pixels.
    pub scale: usize,
}

impl Window {
    /// The whole `w × h` image at full resolution.
    #[must_use]
    pub fn full(w: usize, h: usize) -> Self {
        Self {
            x: 0,
            y: 0,
            w,
            h,
            scale: 1,
        }
    }
}

/// A pixel rectangle: columns `x..x + w`, rows `y..y + h` (row 0 at the top).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Rect {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Columns.
    pub w: usize,
    /// Rows.
    pub h: usize,
}

impl Rect {
    /// The rectangle at `(x, y)` of `w × h` pixels.
    #[must_use]
    pub fn new(x: usize, y: usize, w: usize, h: usize) -> Self {
        Self { x, y, w, h }
    }
    /// A whole `w × h` image.
    #[must_use]
    pub fn full((w, h): (usize, usize)) -> Self {
        Self::new(0, 0, w, h)
    }
    /// One past the last column.
    #[must_use]
    pub fn right(&self) -> usize {
        self.x + self.w
    }
    /// One past the last row.
    #[must_use]
    pub fn bottom(&self) -> usize {
        self.y + self.h
    }
    /// No pixel.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.w == 0 || self.h == 0
    }
    /// The pixels both cover (possibly empty).
    #[must_use]
    pub fn intersect(&self, o: &Rect) -> Rect {
        let (x, y) = (self.x.max(o.x), self.y.max(o.y));
        let (r, b) = (self.right().min(o.right()), self.bottom().min(o.bottom()));
        Rect::new(x, y, r.saturating_sub(x), b.saturating_sub(y))
    }
    /// Grown by `halo` on every side, then clamped to a `size` image.
    #[must_use]
    pub fn grow(&self, halo: usize, size: (usize, usize)) -> Rect {
        let (x, y) = (self.x.saturating_sub(halo), self.y.saturating_sub(halo));
        let r = (self.right() + halo).min(size.0);
        let b = (self.bottom() + halo).min(size.1);
        Rect::new(x, y, r.saturating_sub(x), b.saturating_sub(y))
    }
    /// Parses `X,Y,W,H` (pixels).
    pub fn parse(s: &str) -> Result<Rect, String> {
        let v: Vec<&str> = s.split(',').map(str::trim).collect();
        let bad = || format!("region {s:?} must be X,Y,W,H in whole pixels, e.g. 0,0,512,512");
        if v.len() != 4 {
            return Err(bad());
        }
        let mut n = [0usize; 4];
        for (o, t) in n.iter_mut().zip(&v) {
            *o = t.parse().map_err(|_| bad())?;
        }
        let r = Rect::new(n[0], n[1], n[2], n[3]);
        if r.is_empty() {
            return Err(format!("region {s:?} is empty: W and H must be at least 1"));
        }
        Ok(r)
    }
}

impl std::fmt::Display for Rect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x, self.y, self.w, self.h)
    }
}

/// Fills `dst`, the rectangle `r` with `c` values per pixel, from `parts` (each covering a
/// rectangle, its values row by row), in parallel over rows. `rows[k]` lists the parts that
/// can cover row `r.y + k` (by index into `parts`).
pub fn gather<T: Copy + Send + Sync>(
    dst: &mut [T],
    r: Rect,
    c: usize,
    parts: &[(Rect, &[T])],
    rows: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync),
) {
    dst.par_chunks_mut(r.w * c)
        .enumerate()
        .for_each(|(row, out)| {
            let y = r.y + row;
            for (at, src) in &parts[rows(y)] {
                if y < at.y || y >= at.bottom() {
                    continue;
                }
                let (x0, x1) = (r.x.max(at.x), r.right().min(at.right()));
                if x0 >= x1 {
                    continue;
                }
                let s = ((y - at.y) * at.w + (x0 - at.x)) * c;
                let d = (x0 - r.x) * c;
                let n = (x1 - x0) * c;
                out[d..d + n].copy_from_slice(&src[s..s + n]);
            }
        });
}
