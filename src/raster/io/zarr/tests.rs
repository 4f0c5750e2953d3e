//! Tests of the OME-Zarr stores: round trips of every data type, sizes that are not a multiple
//! of the chunk, 1 × 1, with and without a mask; the levels against
//! [`crate::raster::pyramid`]; region reads counted chunk by chunk; regions written by
//! concurrent writers; a hand-written NGFF 0.4 / Zarr v2 store; bad stores.

use super::*;
use crate::raster::pyramid::{reduce_plane, reduce_rgba8, reduce_rgbn};
use crate::raster::window::Rect;
use crate::raster::{Plane, RgbnImage};
use std::path::PathBuf;

/// A fresh folder for one test.
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rgbn-zarr-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A `w × h` image: colour ramps, unit normals of a tilted sinusoid (repaired as the reader
/// repairs them, so a float32 round trip is exact), a mask ramp when asked.
fn image(w: usize, h: usize, mask: bool) -> RgbnImage {
    let n = w * h;
    let mut nx = vec![0f32; n];
    let mut ny = vec![0f32; n];
    let mut nz = vec![0f32; n];
    for i in 0..n {
        let (x, y) = ((i % w) as f32, (i / w) as f32);
        nx[i] = 0.4 * (x * 0.31).sin();
        ny[i] = -0.3 * (y * 0.17).cos();
        nz[i] = 1.0;
    }
    crate::raster::strips::repair_normals([&mut nx, &mut ny, &mut nz]);
    let ramp = |f: fn(usize, usize) -> f32| (0..n).map(|i| f(i % w, i / w)).collect::<Vec<_>>();
    RgbnImage::new(
        w,
        h,
        [
            ramp(|x, _| (x % 97) as f32 / 96.0),
            ramp(|_, y| (y % 89) as f32 / 88.0),
            ramp(|x, y| ((x * 7 + y * 3) % 101) as f32 / 100.0),
        ],
        [nx, ny, nz],
        mask.then(|| ramp(|x, y| ((x + 2 * y) % 5) as f32 / 4.0)),
    )
    .unwrap()
}

/// `rect` of `img`.
fn crop(img: &RgbnImage, r: Rect) -> RgbnImage {
    let cut = |p: &[f32]| -> Vec<f32> {
        (r.y..r.bottom())
            .flat_map(|y| p[y * img.width() + r.x..y * img.width() + r.right()].to_vec())
            .collect()
    };
    RgbnImage::new(
        r.w,
        r.h,
        img.color().clone().map(|p| cut(&p)),
        img.normal().clone().map(|p| cut(&p)),
        img.mask().map(cut),
    )
    .unwrap()
}

fn opts(dtype: ZarrDtype, chunk: usize) -> ZarrOptions {
    ZarrOptions {
        dtype,
        chunk,
        ..ZarrOptions::default()
    }
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn every_dtype_round_trips_odd_sizes_and_one_pixel_with_and_without_a_mask() {
    let d = dir("roundtrip");
    for dtype in ZarrDtype::ALL {
        // The quantisation step of each type over [-1, 1].
        let tol = match dtype {
            ZarrDtype::F32 => 0.0,
            ZarrDtype::F16 => 1.0 / 1024.0,
            ZarrDtype::U16 => 1.0 / 65535.0,
        };
        for (w, h) in [(1, 1), (37, 53), (70, 33)] {
            for mask in [false, true] {
                let img = image(w, h, mask);
                let p = d.join(format!("{}-{w}x{h}-{mask}.zarr", dtype.name()));
                save_zarr(&img, &p, &opts(dtype, 16)).unwrap();
                let z = ZarrImage::open(&p).unwrap();
                assert_eq!(z.size(), (w, h));
                let mut want = vec!["R", "G", "B", "nx", "ny", "nz"];
                if mask {
                    want.push("mask");
                }
                assert_eq!(z.labels(), want.as_slice());
                assert_eq!(z.content(), Content::Rgbn { mask });
                let (back, _) = z.read_rgbn(0, Rect::full((w, h))).unwrap();
                for k in 0..3 {
                    let e = max_diff(&back.color()[k], &img.color()[k]);
                    assert!(e <= tol, "{dtype:?} {w}×{h} colour {k}: {e}");
                    // Normals are renormalised after decoding: one more rounding.
                    let e = max_diff(&back.normal()[k], &img.normal()[k]);
                    assert!(e <= 2.0 * tol + 2.5e-7, "{dtype:?} {w}×{h} normal {k}: {e}");
                }
                match (back.mask(), img.mask()) {
                    (Some(a), Some(b)) => assert!(max_diff(a, b) <= tol),
                    (None, None) => {}
                    _ => panic!("mask lost or made up"),
                }
            }
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn levels_are_the_engines_block_means_and_each_levels_chunks_cover_level_0s() {
    let d = dir("levels");
    for mask in [false, true] {
        let img = image(200, 150, mask);
        let p = d.join(format!("l-{mask}.zarr"));
        save_zarr(&img, &p, &opts(ZarrDtype::F32, 128)).unwrap();
        let z = ZarrImage::open(&p).unwrap();
        // 128 → 64 → 32-pixel chunks; level 3 would have 16.
        assert_eq!(z.levels(), 3);
        for k in 1..3 {
            let s = 1 << k;
            assert_eq!(z.chunk(k), (128 / s, 128 / s));
            let want = reduce_rgbn(&img, s);
            let (got, _) = z
                .read_rgbn(k, Rect::full((want.width(), want.height())))
                .unwrap();
            assert_eq!(z.level_size(k), (want.width(), want.height()));
            // Level 1 adds what reduce_rgbn adds in its order; level 2 sums 2 × 2 sums.
            let tol = if k == 1 { 0.0 } else { 2e-7 };
            for c in 0..3 {
                assert!(
                    max_diff(&got.color()[c], &want.color()[c]) <= tol,
                    "level {k}"
                );
                // Renormalised once more on reading.
                assert!(max_diff(&got.normal()[c], &want.normal()[c]) <= tol + 2e-7);
            }
            if mask {
                assert!(max_diff(got.mask().unwrap(), want.mask().unwrap()) <= tol);
            }
        }
        // A level the store does not hold is its coarsest reduced further: the block means of
        // level 0 where every block is whole and unmasked (at the clipped edges, and under a
        // mask, a mean of means weighs pixels differently).
        let want = reduce_rgbn(&img, 8);
        let (got, _) = z
            .read_rgbn(3, Rect::full((want.width(), want.height())))
            .unwrap();
        assert_eq!((got.width(), got.height()), (25, 19));
        assert!(max_diff(&got.color()[0], &want.color()[0]) < 0.05);
        if !mask {
            for y in 0..18 {
                for x in 0..25 {
                    let i = y * 25 + x;
                    assert!((got.color()[0][i] - want.color()[0][i]).abs() < 1e-5);
                }
            }
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn pictures_masks_and_fields_have_their_own_channels_and_exact_levels() {
    let d = dir("content");
    let (w, h) = (90, 70);
    let rgba: Vec<u8> = (0..w * h * 4).map(|i| ((i * 37) % 251) as u8).collect();
    let planes: Vec<Vec<f32>> = (0..4)
        .map(|c| (0..w * h).map(|i| f32::from(rgba[i * 4 + c])).collect())
        .collect();
    let refs: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
    let p = d.join("pic.zarr");
    let o = opts(ZarrDtype::F32, 64);
    save_planes_zarr(&p, (w, h), Content::Picture, &refs, &o, None).unwrap();
    let z = ZarrImage::open(&p).unwrap();
    assert_eq!(z.labels(), ["R", "G", "B", "A"]);
    assert_eq!(z.content(), Content::Picture);
    assert_eq!(z.read(0, Rect::full((w, h))).unwrap(), planes);
    // Integer sums: level 1 is reduce_rgba8's bytes exactly.
    let want = reduce_rgba8(&rgba, w, h, 2);
    let got = z.read(1, Rect::full((45, 35))).unwrap();
    for (i, v) in want.iter().enumerate() {
        assert_eq!(got[i % 4][i / 4], f32::from(*v));
    }
    assert!(
        z.read_rgbn(0, Rect::full((w, h))).is_err(),
        "a picture is no RGBN image"
    );

    let field: Vec<f32> = (0..w * h).map(|i| (i as f32 * 0.37).sin() * 40.0).collect();
    let p = d.join("height.zarr");
    save_planes_zarr(&p, (w, h), Content::Scalar, &[&field], &o, None).unwrap();
    let z = ZarrImage::open(&p).unwrap();
    assert_eq!(
        (z.labels(), z.content()),
        (&["value".to_string()][..], Content::Scalar)
    );
    assert_eq!(z.read(0, Rect::full((w, h))).unwrap()[0], field);
    let want = reduce_plane(&Plane::from_vec(w, h, field.clone()).unwrap(), 2);
    assert_eq!(z.read(1, Rect::full((45, 35))).unwrap()[0], want.data());
    let u16 = opts(ZarrDtype::U16, 64);
    let e = save_planes_zarr(
        &d.join("h16.zarr"),
        (w, h),
        Content::Scalar,
        &[&field],
        &u16,
        None,
    )
    .unwrap_err();
    assert!(e.to_string().contains("float32 or float16"), "{e}");

    let m: Vec<f32> = (0..w * h).map(|i| (i % 3) as f32 / 2.0).collect();
    let p = d.join("mask.zarr");
    save_planes_zarr(&p, (w, h), Content::Mask, &[&m], &o, None).unwrap();
    let z = ZarrImage::open(&p).unwrap();
    assert_eq!(z.content(), Content::Mask);
    assert_eq!(z.read_channel(Role::Mask).unwrap().unwrap(), m);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_region_read_decodes_exactly_the_chunks_that_cover_it() {
    let d = dir("region");
    let img = image(200, 150, true);
    let p = d.join("r.zarr");
    save_zarr(&img, &p, &opts(ZarrDtype::F32, 32)).unwrap();
    for rect in [
        Rect::new(0, 0, 1, 1),
        Rect::new(31, 31, 2, 2),
        Rect::new(40, 20, 64, 64),
        Rect::new(150, 100, 50, 50),
        Rect::full((200, 150)),
    ] {
        let z = ZarrImage::open(&p).unwrap();
        // Independently: chunk columns and rows from the first to the last pixel.
        let cols = (rect.right() - 1) / 32 - rect.x / 32 + 1;
        let rows = (rect.bottom() - 1) / 32 - rect.y / 32 + 1;
        assert_eq!(z.chunks_for(0, rect), cols * rows);
        let before = z.chunks_read();
        let (part, _) = z.read_rgbn(0, rect).unwrap();
        assert_eq!(z.chunks_read() - before, (cols * rows) as u64, "{rect:?}");
        let want = crop(&img, rect);
        assert_eq!(part.color(), want.color(), "{rect:?}");
        assert_eq!(part.mask(), want.mask());
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn rows_read_in_bands_of_any_height_are_the_store_read_whole() {
    let d = dir("rows");
    let img = image(50, 97, true);
    let p = d.join("rows.zarr");
    save_zarr(&img, &p, &opts(ZarrDtype::F16, 16)).unwrap();
    let z = std::sync::Arc::new(ZarrImage::open(&p).unwrap());
    let whole = z.read(0, Rect::full((50, 97))).unwrap();
    let (mut normal, color, mask) = z.rows();
    let (mut color, mut mask) = (color.unwrap(), mask.unwrap());
    let mut y = 0;
    let before = z.chunks_read();
    for band in [1, 7, 16, 30, 3, 40] {
        let mut n = Vec::new();
        let mut c = Vec::new();
        let mut m = Vec::new();
        normal.read_rows(band, &mut n).unwrap();
        color.read_rows(band, &mut c).unwrap();
        mask.read_rows(band, &mut m).unwrap();
        let rows = band.min(97 - y);
        for (k, plane) in n.iter().enumerate() {
            assert_eq!(plane[..], whole[3 + k][y * 50..(y + rows) * 50]);
        }
        for (k, plane) in c.iter().enumerate() {
            assert_eq!(plane[..], whole[k][y * 50..(y + rows) * 50]);
        }
        assert_eq!(m[0][..], whole[6][y * 50..(y + rows) * 50]);
        y += rows;
    }
    assert_eq!(y, 97);
    // Each chunk once, though three readers read its rows.
    assert_eq!(z.chunks_read() - before, (4 * 7) as u64);
    std::fs::remove_dir_all(&d).unwrap();
}

/// Every file of a store (relative path, bytes), sorted.
fn files(root: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut todo = vec![root.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn four_concurrent_region_writers_make_the_whole_store_byte_for_byte() {
    let d = dir("regions");
    let (w, h) = (100, 70);
    let img = image(w, h, true);
    let o = opts(ZarrDtype::F32, 32);
    let whole = d.join("whole.zarr");
    save_zarr(&img, &whole, &o).unwrap();
    let parts = d.join("parts.zarr");
    // Quarters on the 32-pixel grid, the last ones clipped at the edges.
    let quarters = [
        Rect::new(0, 0, 64, 32),
        Rect::new(64, 0, 36, 32),
        Rect::new(0, 32, 64, 38),
        Rect::new(64, 32, 36, 38),
    ];
    std::thread::scope(|s| {
        for q in quarters {
            let (img, parts) = (&img, &parts);
            s.spawn(move || {
                let crop = crop(img, q);
                let [r, g, b] = crop.color();
                let [x, y, z] = crop.normal();
                let planes: Vec<&[f32]> = vec![r, g, b, x, y, z, crop.mask().unwrap()];
                let c = Content::Rgbn { mask: true };
                save_planes_zarr(parts, (w, h), c, &planes, &o, Some(q)).unwrap();
            });
        }
    });
    assert_eq!(files(&parts), files(&whole));
    // No temporary file or folder is left beside them.
    let left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 2, "{left:?}");

    // A region off the grid, and a store of another shape, are refused by name.
    let crop = crop(&img, Rect::new(10, 0, 32, 32));
    let [r, g, b] = crop.color();
    let [x, y, z] = crop.normal();
    let planes: Vec<&[f32]> = vec![r, g, b, x, y, z, crop.mask().unwrap()];
    let c = Content::Rgbn { mask: true };
    let e = save_planes_zarr(
        &parts,
        (w, h),
        c,
        &planes,
        &o,
        Some(Rect::new(10, 0, 32, 32)),
    )
    .unwrap_err();
    assert!(e.to_string().contains("not aligned"), "{e}");
    let e = save_planes_zarr(
        &parts,
        (w + 1, h),
        c,
        &planes,
        &o,
        Some(Rect::new(0, 0, 32, 32)),
    )
    .unwrap_err();
    assert!(e.to_string().contains("other metadata"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn a_whole_write_replaces_a_store_and_a_failed_one_leaves_it() {
    let d = dir("replace");
    let p = d.join("a.zarr");
    save_zarr(&image(40, 30, false), &p, &opts(ZarrDtype::F32, 16)).unwrap();
    save_zarr(&image(20, 10, true), &p, &opts(ZarrDtype::F16, 16)).unwrap();
    let z = ZarrImage::open(&p).unwrap();
    assert_eq!((z.size(), z.labels().len()), ((20, 10), 7));
    // A writer dropped before its commit leaves the store as it was, and no folder beside.
    let layout = Layout::new(5, 5, Content::Mask, &ZarrOptions::default(), &p).unwrap();
    drop(ZarrWriter::create(&p, layout).unwrap());
    assert_eq!(ZarrImage::open(&p).unwrap().size(), (20, 10));
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A NGFF 0.4 store on Zarr v2 written by hand: uncompressed little-endian float32 chunks
/// `0.0.0`-style, channels as the first axis, one chunk along c.
#[test]
fn an_ngff_0_4_store_on_zarr_v2_is_read() {
    let d = dir("v2");
    let p = d.join("v2.zarr");
    let (w, h, cw) = (5usize, 3usize, 4usize);
    std::fs::create_dir_all(p.join("0")).unwrap();
    std::fs::write(p.join(".zgroup"), r#"{"zarr_format": 2}"#).unwrap();
    let labels = ["nx", "ny", "nz"];
    let attrs = serde_json::json!({
        "multiscales": [{
            "version": "0.4",
            "axes": [{"name": "c", "type": "channel"}, {"name": "y", "type": "space"}, {"name": "x", "type": "space"}],
            "datasets": [{"path": "0", "coordinateTransformations": [{"type": "scale", "scale": [1.0, 1.0, 1.0]}]}],
        }],
        "omero": {"channels": labels.iter().map(|l| serde_json::json!({"label": l})).collect::<Vec<_>>()},
    });
    std::fs::write(p.join(".zattrs"), attrs.to_string()).unwrap();
    let zarray = serde_json::json!({
        "zarr_format": 2, "shape": [3, h, w], "chunks": [3, cw, cw], "dtype": "<f4",
        "compressor": null, "fill_value": 0.0, "order": "C", "filters": null,
        "dimension_separator": ".",
    });
    std::fs::write(p.join("0/.zarray"), zarray.to_string()).unwrap();
    // Normal (0.6, 0, 0.8) at even columns, (0, 0, 1) at odd ones.
    let value = |c: usize, x: usize| match (c, x % 2) {
        (0, 0) => 0.6f32,
        (2, 0) => 0.8,
        (2, _) => 1.0,
        _ => 0.0,
    };
    for gx in 0..2 {
        let mut bytes = Vec::new();
        for c in 0..3 {
            for _y in 0..cw {
                for x in 0..cw {
                    bytes.extend_from_slice(&value(c, gx * cw + x).to_le_bytes());
                }
            }
        }
        std::fs::write(p.join(format!("0/0.0.{gx}")), bytes).unwrap();
    }
    let z = ZarrImage::open(&p).unwrap();
    assert_eq!(
        (z.size(), z.content()),
        ((w, h), Content::Rgbn { mask: false })
    );
    let (img, _) = z.read_rgbn(0, Rect::full((w, h))).unwrap();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            assert_eq!(img.normal()[0][i], value(0, x));
            assert_eq!(img.normal()[2][i], value(2, x));
            assert_eq!(img.color()[0][i], crate::raster::io::DEFAULT_ALBEDO);
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// The one-line error of opening and reading `p`.
fn error_of(p: &std::path::Path) -> String {
    match ZarrImage::open(p) {
        Err(e) => e.to_string(),
        Ok(z) => z
            .read_rgbn(0, Rect::full(z.size()))
            .map(|_| "no error".to_string())
            .unwrap_or_else(|e| e.to_string()),
    }
}

#[test]
fn bad_stores_each_get_one_error_naming_the_store_and_the_fault() {
    let d = dir("bad");
    let fresh = |name: &str| {
        let p = d.join(format!("{name}.zarr"));
        save_zarr(&image(40, 40, false), &p, &opts(ZarrDtype::F32, 16)).unwrap();
        p
    };
    let edit = |p: &std::path::Path, file: &str, from: &str, to: &str| {
        let f = p.join(file);
        let s = std::fs::read_to_string(&f).unwrap();
        assert!(s.contains(from), "{file}: {from}");
        std::fs::write(&f, s.replacen(from, to, 1)).unwrap();
    };
    let p = fresh("missing");
    std::fs::remove_file(p.join("0/c/0/1/2")).unwrap();
    let e = error_of(&p);
    assert!(
        e.contains("chunk 0/c/0/1/2 of level 0") && e.contains("missing"),
        "{e}"
    );

    let p = fresh("truncated");
    let f = p.join("0/c/0/2/1");
    let b = std::fs::read(&f).unwrap();
    std::fs::write(&f, &b[..b.len() / 2]).unwrap();
    let e = error_of(&p);
    assert!(
        e.contains("chunk 0/c/0/2/1") && e.contains("truncated or corrupt"),
        "{e}"
    );

    let p = fresh("corrupt");
    std::fs::write(p.join("0/c/0/0/0"), b"not zstd at all").unwrap();
    assert!(error_of(&p).contains("truncated or corrupt"));

    let p = fresh("dtype");
    edit(&p, "0/zarr.json", "\"float32\"", "\"int32\"");
    edit(
        &p,
        "0/zarr.json",
        "\"fill_value\": 0.0",
        "\"fill_value\": 0",
    );
    let e = error_of(&p);
    assert!(e.contains("wrong data type") && e.contains("int32"), "{e}");

    let p = fresh("channels");
    edit(
        &p,
        "zarr.json",
        "\"label\": \"nz\"",
        "\"label\": \"nz\"}, {\"label\": \"extra\"",
    );
    let e = error_of(&p);
    assert!(
        e.contains("wrong channel count") && e.contains("6 channels"),
        "{e}"
    );

    let p = fresh("not-ome");
    edit(&p, "zarr.json", "\"multiscales\"", "\"not_multiscales\"");
    let e = error_of(&p);
    assert!(e.contains("not an OME-Zarr image"), "{e}");

    let p = d.join("plain.zarr");
    std::fs::create_dir(&p).unwrap();
    assert!(error_of(&p).contains("not a Zarr store"));
    assert!(error_of(&d.join("absent.zarr")).contains("not found"));
    for e in [
        "missing",
        "truncated",
        "dtype",
        "channels",
        "not-ome",
        "plain",
    ] {
        let p = d.join(format!("{e}.zarr"));
        assert!(
            error_of(&p).contains(&p.display().to_string()),
            "{e}: names the store"
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}
