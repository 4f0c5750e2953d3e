//! Where a new node goes in the graph view: the free spot nearest a preferred position, so that
//! new nodes (Add menu, File ▸ Open image…, a dropped image) never land on existing ones.
//!
//! Pure geometry in graph coordinates (y down, like the node view), no egui: positions are
//! scanned on a [`GRID`]-spaced lattice around the preferred spot, ring by ring, and the
//! nearest one where the new node's rectangle keeps a [`GAP`] from every existing rectangle
//! wins (ties go below, then right).

/// Spacing of the candidate positions around the preferred spot.
pub const GRID: f32 = 20.0;

/// Free space kept between a new node and its neighbours.
pub const GAP: f32 = 16.0;

/// The size assumed for a node that has not been drawn yet (a header, a pin or two, a
/// thumbnail).
pub const DEFAULT_NODE_SIZE: [f32; 2] = [230.0, 150.0];

/// Rings scanned at most (beyond, the node goes below everything).
const MAX_RINGS: i64 = 400;

/// An axis-aligned rectangle: top-left corner and size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Top-left corner `[x, y]`.
    pub min: [f32; 2],
    /// Width and height (negative counts as 0).
    pub size: [f32; 2],
}

impl Rect {
    /// The rectangle at `min` of `size`.
    #[must_use]
    pub fn new(min: [f32; 2], size: [f32; 2]) -> Self {
        Self {
            min,
            size: [size[0].max(0.0), size[1].max(0.0)],
        }
    }

    /// Bottom-right corner.
    #[must_use]
    pub fn max(&self) -> [f32; 2] {
        [self.min[0] + self.size[0], self.min[1] + self.size[1]]
    }

    /// True when the two rectangles come closer than `gap` (touching at exactly `gap` is
    /// fine).
    #[must_use]
    pub fn overlaps(&self, other: &Rect, gap: f32) -> bool {
        let (a, b) = (self.max(), other.max());
        self.min[0] < b[0] + gap
            && other.min[0] < a[0] + gap
            && self.min[1] < b[1] + gap
            && other.min[1] < a[1] + gap
    }

    fn is_finite(&self) -> bool {
        self.min.iter().chain(&self.size).all(|v| v.is_finite())
    }
}

/// The position nearest `preferred` where a node of `size` keeps [`GAP`] from every rectangle
/// in `existing`: `preferred` itself when that is free, else the nearest free point of the
/// [`GRID`] lattice around it (ties: below first, then right). Non-finite rectangles are
/// ignored; a non-finite `preferred` counts as the origin.
#[must_use]
pub fn free_position(existing: &[Rect], size: [f32; 2], preferred: [f32; 2]) -> [f32; 2] {
    let preferred = if preferred.iter().all(|v| v.is_finite()) {
        preferred
    } else {
        [0.0, 0.0]
    };
    let size = [
        if size[0].is_finite() { size[0] } else { 0.0 },
        if size[1].is_finite() { size[1] } else { 0.0 },
    ];
    let existing: Vec<Rect> = existing.iter().filter(|r| r.is_finite()).copied().collect();
    let fits = |p: [f32; 2]| {
        let r = Rect::new(p, size);
        existing.iter().all(|e| !r.overlaps(e, GAP))
    };
    if fits(preferred) {
        return preferred;
    }
    // Beyond the bounding box of everything (plus the node and the gap) every spot is free:
    // that bounds the rings to scan.
    let (mut lo, mut hi) = (preferred, preferred);
    for r in &existing {
        let m = r.max();
        lo = [lo[0].min(r.min[0]), lo[1].min(r.min[1])];
        hi = [hi[0].max(m[0]), hi[1].max(m[1])];
    }
    let reach = [
        (preferred[0] - lo[0]).max(hi[0] - preferred[0]) + size[0] + GAP,
        (preferred[1] - lo[1]).max(hi[1] - preferred[1]) + size[1] + GAP,
    ];
    let rings = ((reach[0].max(reach[1]) / GRID).ceil() as i64 + 1).clamp(1, MAX_RINGS);
    let at = |i: i64, j: i64| {
        [
            preferred[0] + i as f32 * GRID,
            preferred[1] + j as f32 * GRID,
        ]
    };
    // Best so far, keyed by (squared lattice distance, below first, right first).
    let mut best: Option<((i64, i64, i64), [f32; 2])> = None;
    for k in 1..=rings {
        // Every point of ring k is at least k steps away.
        if best.is_some_and(|(key, _)| key.0 < k * k) {
            break;
        }
        for j in -k..=k {
            for i in -k..=k {
                if i.abs() != k && j.abs() != k {
                    continue;
                }
                let key = (i * i + j * j, -j, -i);
                if best.is_some_and(|(b, _)| b <= key) {
                    continue;
                }
                let p = at(i, j);
                if fits(p) {
                    best = Some((key, p));
                }
            }
        }
    }
    best.map_or([preferred[0], hi[1] + GAP], |(_, p)| p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_overlaps(rects: &[Rect]) {
        for (a, ra) in rects.iter().enumerate() {
            for rb in &rects[a + 1..] {
                assert!(!ra.overlaps(rb, 0.0), "{ra:?} overlaps {rb:?}");
            }
        }
    }

    #[test]
    fn the_preferred_spot_is_kept_when_free() {
        let existing = [
            Rect::new([0.0, 0.0], [200.0, 100.0]),
            Rect::new([400.0, 0.0], [200.0, 100.0]),
        ];
        // Between the two, with room to spare.
        assert_eq!(
            free_position(&existing, [100.0, 80.0], [230.0, 7.5]),
            [230.0, 7.5]
        );
        // Nothing there at all.
        assert_eq!(free_position(&[], [100.0, 80.0], [-3.0, 9.0]), [-3.0, 9.0]);
        // Exactly GAP away is free.
        assert_eq!(
            free_position(&existing, [10.0, 10.0], [0.0, 100.0 + GAP]),
            [0.0, 100.0 + GAP]
        );
    }

    #[test]
    fn an_occupied_spot_moves_to_the_nearest_free_one() {
        let existing = [Rect::new([0.0, 0.0], [200.0, 100.0])];
        let size = [100.0, 40.0];
        let p = free_position(&existing, size, [50.0, 30.0]);
        assert!(
            !Rect::new(p, size).overlaps(&existing[0], GAP - 1e-3),
            "{p:?}"
        );
        // Nearest: 5 grid steps straight up (30 + 40 + GAP ≤ 100) or down (100 + GAP − 30
        // ≤ 100); the tie goes below.
        assert_eq!(p, [50.0, 30.0 + 5.0 * GRID]);
        // Brute force over the lattice: nothing free is nearer.
        let d = |q: [f32; 2]| (q[0] - 50.0).hypot(q[1] - 30.0);
        for j in -20..=20 {
            for i in -20..=20 {
                let q = [50.0 + i as f32 * GRID, 30.0 + j as f32 * GRID];
                if !Rect::new(q, size).overlaps(&existing[0], GAP) {
                    assert!(d(q) >= d(p) - 1e-3, "{q:?} is free and nearer than {p:?}");
                }
            }
        }
    }

    #[test]
    fn many_nodes_placed_at_the_same_spot_never_overlap() {
        let size = DEFAULT_NODE_SIZE;
        let mut rects = vec![Rect::new([0.0, 0.0], [300.0, 200.0])];
        for n in 0..60 {
            // Sizes vary a little, the preferred spot is always the same occupied one.
            let s = [
                size[0] + (n % 3) as f32 * 25.0,
                size[1] + (n % 4) as f32 * 20.0,
            ];
            let p = free_position(&rects, s, [10.0, 10.0]);
            let r = Rect::new(p, s);
            for e in &rects {
                assert!(
                    !r.overlaps(e, GAP - 1e-3),
                    "node {n} at {p:?} overlaps {e:?}"
                );
            }
            rects.push(r);
        }
        no_overlaps(&rects);
        // They stay packed around the spot rather than flying off.
        let far = rects
            .iter()
            .map(|r| r.min[0].abs().max(r.min[1].abs()))
            .fold(0.0, f32::max);
        assert!(far < 2500.0, "{far}");
    }

    #[test]
    fn a_dense_random_field_and_bad_input() {
        // A pseudo-random jumble of overlapping rectangles; the new node still finds room.
        let mut s = 12345u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 33) % 1000) as f32
        };
        let rects: Vec<Rect> = (0..200)
            .map(|_| Rect::new([next(), next()], [next() / 4.0, next() / 6.0]))
            .collect();
        let size = [180.0, 120.0];
        let p = free_position(&rects, size, [500.0, 500.0]);
        let r = Rect::new(p, size);
        assert!(rects.iter().all(|e| !r.overlaps(e, GAP - 1e-3)), "{p:?}");
        // Non-finite rectangles are ignored; a non-finite preferred spot counts as the origin.
        let odd = [Rect::new([f32::NAN, 0.0], [10.0, 10.0])];
        assert_eq!(free_position(&odd, size, [f32::INFINITY, 0.0]), [0.0, 0.0]);
        // Huge far-away rectangles do not make the search slow: still a nearby spot.
        let big = [
            Rect::new([0.0, 0.0], [100.0, 100.0]),
            Rect::new([1e9, 1e9], [10.0, 10.0]),
        ];
        let p = free_position(&big, size, [0.0, 0.0]);
        assert!(p[0].abs() < 1000.0 && p[1].abs() < 1000.0, "{p:?}");
    }
}
