//! Unit tests of the region engine's pieces: the tile grid, damage bookkeeping and assembly.

use super::damage::{boxes_to_rects, damage_since};
use super::grid::{assemble, covering, tile_key, tile_rect, TileMap};
use crate::eval::CacheEntry;
use crate::nodes::Value;
use crate::raster::window::Rect;
use crate::raster::Plane;
use std::sync::Arc;

#[test]
fn covering_lists_exactly_the_tiles_a_rectangle_touches() {
    // Columns 30..70 and rows 0..17 of a 32-pixel grid: tile columns 0, 1, 2 and rows 0.
    let t: Vec<(usize, usize)> = covering(&Rect::new(30, 0, 40, 17), 32).collect();
    assert_eq!(t, vec![(0, 0), (1, 0), (2, 0)]);
    // A rectangle on tile boundaries covers no neighbour.
    let t: Vec<(usize, usize)> = covering(&Rect::new(32, 64, 32, 32), 32).collect();
    assert_eq!(t, vec![(1, 2)]);
    assert_eq!(covering(&Rect::new(5, 5, 0, 3), 32).count(), 0);
}

#[test]
fn edge_tiles_are_clipped_to_the_image() {
    assert_eq!(tile_rect((2, 1), 32, (70, 40)), Rect::new(64, 32, 6, 8));
    assert_eq!(tile_rect((0, 0), 32, (70, 40)), Rect::new(0, 0, 32, 32));
}

#[test]
fn tile_keys_differ_by_every_coordinate() {
    let k = 0x1234_u128;
    let base = tile_key(k, 64, 0, 1, 2);
    assert_eq!(base, tile_key(k, 64, 0, 1, 2));
    for other in [
        tile_key(k + 1, 64, 0, 1, 2),
        tile_key(k, 32, 0, 1, 2),
        tile_key(k, 64, 1, 1, 2),
        tile_key(k, 64, 0, 2, 1),
    ] {
        assert_ne!(base, other);
    }
}

#[test]
fn damage_boxes_cover_the_pixels_whose_centres_they_contain() {
    // A box from (3.5, 2.0) to (10.2, 4.0) touches pixel columns 3..=11 (floor of the start,
    // ceil of the end) and rows 2..=4.
    let r = boxes_to_rects(&[[3.5, 2.0, 10.2, 4.0]], (100, 100));
    assert_eq!(r, vec![Rect::new(3, 2, 9, 3)]);
    // Outside the image: nothing; partly outside: clamped to the image; NaN counts as 0.
    assert!(boxes_to_rects(&[[200.0, 200.0, 300.0, 300.0]], (100, 100)).is_empty());
    assert_eq!(
        boxes_to_rects(&[[-5.0, -5.0, 1.0, 1.0]], (100, 100)),
        vec![Rect::new(0, 0, 2, 2)]
    );
    assert_eq!(
        boxes_to_rects(&[[f64::NAN, 1.0, 2.0, 2.0]], (100, 100)),
        vec![Rect::new(0, 1, 3, 2)]
    );
}

#[test]
fn damage_since_accumulates_edits_back_to_the_key_asked_for() {
    let a = vec![Rect::new(0, 0, 4, 4)];
    let b = vec![Rect::new(10, 10, 2, 2)];
    // Keys 1 → 2 → 3: from 1 everything both edits touched; from 2 only the last edit's.
    let trail = vec![(1u128, Some(a.clone())), (2u128, Some(b.clone()))];
    let mut both = damage_since(&trail, 1).expect("known key");
    both.sort();
    let mut want = [a.clone(), b.clone()].concat();
    want.sort();
    assert_eq!(both, want);
    assert_eq!(damage_since(&trail, 2), Some(b));
    // An unknown key, or an edit that may have changed anything, is damage everywhere.
    assert_eq!(damage_since(&trail, 9), None);
    let trail = vec![(1u128, None), (2u128, Some(a))];
    assert_eq!(damage_since(&trail, 1), None);
}

#[test]
fn assemble_puts_each_tile_where_it_belongs() {
    // A 5 × 3 plane whose value is 10·row + column, cut into 2-pixel tiles and assembled back
    // over a rectangle that spans several of them.
    let (w, h, t) = (5usize, 3usize, 2usize);
    let full = |x: usize, y: usize| (10 * y + x) as f32;
    let mut have = TileMap::new();
    for ty in 0..h.div_ceil(t) {
        for tx in 0..w.div_ceil(t) {
            let r = tile_rect((tx, ty), t, (w, h));
            let p = Plane::from_fn(r.w, r.h, |x, y| full(r.x + x, r.y + y));
            let e = CacheEntry {
                values: vec![Value::Scalar(Arc::new(p))],
                curl: None,
                fraction: None,
                skipped: 0,
            };
            have.insert((tx, ty), Arc::new(e));
        }
    }
    let r = Rect::new(1, 1, 4, 2);
    let Value::Scalar(p) = assemble(&have, 0, t, (w, h), r) else {
        panic!("a scalar field")
    };
    assert_eq!((p.width(), p.height()), (4, 2));
    for y in 0..2 {
        for x in 0..4 {
            assert_eq!(p.data()[y * 4 + x], full(x + 1, y + 1));
        }
    }
}
