//! Tests of `app/preview.rs`.

use super::*;
use crate::nodes::Picture;
use crate::render;

#[test]
fn direct_rendering_gives_the_pixels_of_the_general_path() {
    // Every view, unmasked (straight into Color32s) and masked with partial coverage
    // (relit and albedo then go through the RGBA picture and the unmultiplied conversion):
    // the same pixels as render → display_image.
    let img = crate::raster::sample::demo_medallion(45);
    let mut masked = img.clone();
    let m: Vec<f32> = (0..img.len()).map(|i| (i % 5) as f32 / 4.0).collect();
    masked.set_mask(Some(m)).unwrap();
    for view in View::ALL.iter().map(|v| Mode::View(*v)) {
        let s = PreviewSettings {
            view,
            ..PreviewSettings::default()
        };
        for im in [&img, &masked] {
            let fast = color_image(&Value::Rgbn(im.clone()), &s).unwrap();
            let rgba = render::render(im, view.render_view().unwrap(), &s.shading()).unwrap();
            let want = display_image(&Picture {
                width: im.width(),
                height: im.height(),
                rgba,
            });
            assert_eq!(fast.size, [45, 45]);
            assert!(fast.pixels == want.pixels, "{view:?}");
        }
    }
}

#[test]
fn a_viewport_pixel_covers_its_block_of_full_resolution_pixels() {
    use crate::raster::window::Rect;
    let r = RegionShown {
        key: 1,
        rect: Rect::new(10, 20, 5, 4),
        level: 2,
        coarse: false,
        full_size: (100, 120),
        value: Value::Number(0.0),
    };
    // Level 2: level pixel (10, 20) covers full pixels 40..44 × 80..84.
    assert_eq!(r.pixel_of(40, 80), Some((0, 0)));
    assert_eq!(r.pixel_of(43, 83), Some((0, 0)));
    assert_eq!(r.pixel_of(44, 84), Some((1, 1)));
    assert_eq!(r.pixel_of(59, 95), Some((4, 3)));
    assert_eq!(r.pixel_of(60, 95), None, "right of the viewport");
    assert_eq!(r.pixel_of(39, 90), None, "left of it");
    assert_eq!(r.pixel_of(50, 96), None, "below it");
}

#[test]
fn the_visible_rectangle_follows_zoom_and_pan_in_whole_tiles() {
    use crate::raster::window::Rect;
    // 1:1 on a 4096² image in a 1000×800 panel, centred: image pixels 1548..2548 ×
    // 1648..2448 are on screen, grown to 64-pixel tiles.
    let mut v = ViewSpec {
        panel: [1000.0, 800.0],
        zoom: Some(1.0),
        pan: [0.0, 0.0],
    };
    assert_eq!(
        v.visible((4096, 4096), 64),
        Some((Rect::new(1536, 1600, 2560 - 1536, 2496 - 1600), 0))
    );
    // Panned right by 300 points: the image moves right, the view sees 300 pixels less far.
    v.pan = [300.0, 0.0];
    let (r, _) = v.visible((4096, 4096), 1).unwrap();
    assert_eq!((r.x, r.right()), (1248, 2248));
    // Panned off the image: nothing to evaluate.
    v.pan = [5000.0, 0.0];
    assert_eq!(v.visible((4096, 4096), 64), None);
    // A 16384² image fitted into 1600×1000: zoom 1000/16384, level 4 (1:16), all of its
    // 1024² pixels.
    let fit = ViewSpec {
        panel: [1600.0, 1000.0],
        zoom: None,
        pan: [0.0, 0.0],
    };
    assert_eq!(
        fit.visible((16384, 16384), 64),
        Some((Rect::new(0, 0, 1024, 1024), 4))
    );
    // Zoomed to 1:2 with the top-left corner of a 5000×3000 image at the panel's: level 1
    // (2500×1500), one level pixel per point, so the panel's 1000×800 points show level
    // pixels 0..1000 × 0..800.
    let corner = ViewSpec {
        panel: [1000.0, 800.0],
        zoom: Some(0.5),
        pan: [1250.0 - 500.0, 750.0 - 400.0],
    };
    assert_eq!(
        corner.visible((5000, 3000), 1),
        Some((Rect::new(0, 0, 1000, 800), 1))
    );
}

#[test]
fn zoomed_out_previews_render_a_block_mean_level_without_aliasing() {
    assert_eq!(Preview::stride_for_zoom(1.0), 1);
    assert_eq!(Preview::stride_for_zoom(4.0), 1);
    assert_eq!(Preview::stride_for_zoom(0.5), 2);
    assert_eq!(Preview::stride_for_zoom(0.34), 2);
    assert_eq!(Preview::stride_for_zoom(0.3), 2);
    assert_eq!(Preview::stride_for_zoom(0.25), 4);
    assert_eq!(Preview::stride_for_zoom(0.061), 16);
    assert_eq!(Preview::stride_for_zoom(0.01), 64);
    // Ridges one pixel wide, tilted left and right in turn (a relief finer than the
    // screen): every 2nd pixel would show one tilt everywhere; the block mean of each pair
    // is flat, as the surface seen from afar is.
    let (w, h) = (16usize, 6usize);
    let t = 0.6f32;
    let nx: Vec<f32> = (0..w * h)
        .map(|i| if i % 2 == 0 { t } else { -t })
        .collect();
    let img = crate::RgbnImage::new(
        w,
        h,
        [vec![0.5; w * h], vec![0.5; w * h], vec![0.5; w * h]],
        [nx, vec![0.0; w * h], vec![(1.0 - t * t).sqrt(); w * h]],
        None,
    )
    .unwrap();
    let small = preview_level(&img, 2);
    assert_eq!((small.width(), small.height()), (8, 3));
    for r in 0..3 {
        for x in 0..8 {
            let n = small.normal_at(x, r);
            assert!(n[0].abs() < 1e-6 && (n[2] - 1.0).abs() < 1e-6, "{n:?}");
        }
    }
    // Relit, the level is one even tone: no stripes, no bias to either tilt.
    let s = PreviewSettings::default();
    let part = render_value(&Value::Rgbn(small), &s).unwrap();
    let first = &part.rgba[0..4];
    assert!(part.rgba.chunks(4).all(|p| p == first));
}

#[test]
fn preview_request_is_plain_data_keyed_apart_from_evaluation() {
    let img = Value::Rgbn(crate::raster::sample::demo_medallion(16));
    let mut s = PreviewSettings::default();
    let a = Preview::request(&img, 42, &s);
    assert_eq!(a, Preview::request(&img, 42, &s));
    s.light = [0.0, 0.0, 1.0];
    let b = Preview::request(&img, 42, &s);
    assert_ne!(a, b, "moving the light changes the request, not the key");
    assert_eq!(a.key, b.key);
    // Pictures ignore display settings.
    let pic = Value::Number(1.0);
    assert_eq!(
        Preview::request(&pic, 1, &s),
        Preview::request(&pic, 1, &PreviewSettings::default())
    );
    let p = render_value(&img, &s).unwrap();
    assert_eq!(p.rgba.len(), 16 * 16 * 4);
}
