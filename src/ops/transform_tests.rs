//! Tests of `ops/transform.rs`.

use super::*;
use crate::raster::integrate::non_integrable_fraction;
use crate::raster::sample::Surface;

/// A deterministic image with every channel different at every pixel, and a mask.
fn varied(w: usize, h: usize) -> RgbnImage {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let n = w * h;
    let color = [(); 3].map(|_| (0..n).map(|_| next()).collect());
    let mut normal = [Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..n {
        let (a, b) = (next() - 0.5, next() - 0.5);
        let l = (a * a + b * b + 1.0).sqrt();
        normal[0].push(a / l);
        normal[1].push(b / l);
        normal[2].push(1.0 / l);
    }
    let mask = (0..n).map(|_| next()).collect();
    RgbnImage::new(w, h, color, normal, Some(mask)).unwrap()
}

fn with(f: impl FnOnce(&mut TransformParams)) -> TransformParams {
    let mut p = TransformParams::default();
    f(&mut p);
    p
}

#[test]
fn mirrored_twice_flipped_twice_or_turned_full_circle_is_the_original_bit_for_bit() {
    let img = varied(13, 7);
    let mirror = with(|p| p.mirror = true);
    let twice = transform(&transform(&img, &mirror).unwrap(), &mirror).unwrap();
    assert_eq!(twice, img);
    let flip = with(|p| p.flip = true);
    assert_eq!(
        transform(&transform(&img, &flip).unwrap(), &flip).unwrap(),
        img
    );
    let quarter = with(|p| p.rotate = QuarterTurn::Ccw90);
    let mut t = img.clone();
    for _ in 0..4 {
        t = transform(&t, &quarter).unwrap();
    }
    assert_eq!(t, img);
    let back = with(|p| p.rotate = QuarterTurn::Ccw270);
    let t = transform(&transform(&img, &quarter).unwrap(), &back).unwrap();
    assert_eq!(t, img);
    // A mirror is not the identity: n_x changed sign.
    let once = transform(&img, &mirror).unwrap();
    assert_eq!(once.normal()[0][0], -img.normal()[0][12]);
}

/// Unit normal of slope `(zx, zy)`.
fn unit(zx: f64, zy: f64) -> [f64; 3] {
    let l = (zx * zx + zy * zy + 1.0).sqrt();
    [-zx / l, -zy / l, 1.0 / l]
}

/// A tilted, off-centre bump: no symmetry a wrong transform could hide behind.
fn bump() -> Surface {
    Surface::Gaussians {
        bumps: vec![[4.0, -3.0, 6.0, 5.0], [-7.0, 2.0, -2.5, 3.0]],
    }
}

/// The analytic normals of `z(x, y)` (pixel centres, x right, y up) for a `w × h` image.
fn analytic(w: usize, h: usize, z: &dyn Fn(f64, f64) -> [f64; 2]) -> RgbnImage {
    let n = w * h;
    let mut normal = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
    for row in 0..h {
        for x in 0..w {
            let [zx, zy] = z(x as f64, (h - 1 - row) as f64);
            let u = unit(zx, zy);
            for k in 0..3 {
                normal[k][row * w + x] = u[k] as f32;
            }
        }
    }
    RgbnImage::new(w, h, [(); 3].map(|_| vec![0.5; n]), normal, None).unwrap()
}

fn max_normal_diff(a: &RgbnImage, b: &RgbnImage) -> f32 {
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    (0..3)
        .flat_map(|k| {
            a.normal()[k]
                .iter()
                .zip(&b.normal()[k])
                .map(|(x, y)| (x - y).abs())
        })
        .fold(0.0, f32::max)
}

#[test]
fn turned_and_mirrored_normals_are_those_of_the_turned_and_mirrored_surface() {
    let (w, h) = (40usize, 24usize);
    let s = bump();
    // The surface in pixel coordinates (x right, y up), centred on the image.
    let (cx, cy) = ((w - 1) as f64 / 2.0, (h - 1) as f64 / 2.0);
    let g = &move |x: f64, y: f64| s.gradient(x - cx, y - cy).unwrap();
    let img = analytic(w, h, g);
    let (wm, hm) = ((w - 1) as f64, (h - 1) as f64);
    // Output (x′, y′) of a counter-clockwise quarter turn shows input (y′, h−1−x′): the turned
    // surface z′(x′, y′) = z(y′, h−1−x′) has ∂z′/∂x′ = −z_y, ∂z′/∂y′ = z_x there.
    type Slopes<'a> = Box<dyn Fn(f64, f64) -> [f64; 2] + 'a>;
    let cases: [(TransformParams, (usize, usize), Slopes); 4] = [
        (
            with(|p| p.rotate = QuarterTurn::Ccw90),
            (h, w),
            Box::new(move |x, y| {
                let [zx, zy] = g(y, hm - x);
                [-zy, zx]
            }),
        ),
        (
            with(|p| p.rotate = QuarterTurn::Half),
            (w, h),
            Box::new(move |x, y| {
                let [zx, zy] = g(wm - x, hm - y);
                [-zx, -zy]
            }),
        ),
        (
            with(|p| p.rotate = QuarterTurn::Ccw270),
            (h, w),
            Box::new(move |x, y| {
                let [zx, zy] = g(wm - y, x);
                [zy, -zx]
            }),
        ),
        (
            with(|p| p.mirror = true),
            (w, h),
            Box::new(move |x, y| {
                let [zx, zy] = g(wm - x, y);
                [-zx, zy]
            }),
        ),
    ];
    for (p, (ow, oh), z) in &cases {
        let got = transform(&img, p).unwrap();
        let want = analytic(*ow, *oh, z.as_ref());
        let d = max_normal_diff(&got, &want);
        assert!(d < 1e-6, "{p:?}: max |Δn| {d}");
    }
}

#[test]
fn an_integrable_field_stays_integrable_when_cropped_turned_and_mirrored() {
    let (img, _) = Surface::Sinusoid {
        amplitude_px: 3.0,
        period_px: 23.0,
    }
    .render_sampled(48, 40);
    let f0 = non_integrable_fraction(&GradientField::from_normals(&img), None).unwrap();
    assert!(f0 < 1e-5, "input F {f0}");
    let p = with(|p| {
        p.crop_x = 5;
        p.crop_y = 3;
        p.crop_width = 37;
        p.crop_height = 29;
        p.mirror = true;
        p.rotate = QuarterTurn::Ccw90;
    });
    let out = transform(&img, &p).unwrap();
    assert_eq!((out.width(), out.height()), (29, 37));
    let f = non_integrable_fraction(&GradientField::from_normals(&out), None).unwrap();
    assert!(f < 1e-5, "transformed F {f}");
}

#[test]
fn a_uniform_resize_keeps_the_slopes_and_stays_near_integrable() {
    // A smooth bump sampled at 96² and reduced to 48²: the reduced normals are those of the
    // surface scaled with the image (slopes unchanged) within the filter's smoothing.
    let s = Surface::Gaussians {
        bumps: vec![[3.0, -2.0, 9.0, 14.0]],
    };
    let big = analytic(96, 96, &|x, y| s.gradient(x - 47.5, y - 47.5).unwrap());
    let small = transform(
        &big,
        &with(|p| {
            p.resize_width = 48;
            p.resize_height = 48;
        }),
    )
    .unwrap();
    // Output pixel X covers input pixels 2X, 2X+1: its centre is input coordinate 2X + 0.5,
    // where the half-size surface has the same slopes.
    let want = analytic(48, 48, &|x, y| {
        s.gradient(2.0 * x + 0.5 - 47.5, 2.0 * y + 0.5 - 47.5)
            .unwrap()
    });
    let d = max_normal_diff(&small, &want);
    assert!(d < 0.02, "max |Δn| {d}");
    let f = non_integrable_fraction(&GradientField::from_normals(&small), None).unwrap();
    assert!(f < 5e-3, "F after resizing {f}");
    // Only the width: the aspect ratio follows.
    let p = with(|p| p.resize_width = 24);
    assert_eq!(p.out_size((96, 64)).unwrap(), (24, 16));
}

#[test]
fn an_anisotropic_resize_scales_the_slopes_by_the_stretch() {
    // A plane z = a·x + b·y stretched by (2, 1/2): s = 1, so p′ = p/2 and q′ = 2q.
    let (a, b) = (0.3, -0.2);
    let img = analytic(20, 20, &|_, _| [a, b]);
    let out = transform(
        &img,
        &with(|p| {
            p.resize_width = 40;
            p.resize_height = 10;
        }),
    )
    .unwrap();
    let want = unit(a / 2.0, b * 2.0);
    for (plane, w) in out.normal().iter().zip(want) {
        for v in plane {
            assert!((f64::from(*v) - w).abs() < 1e-6, "{v} vs {w}");
        }
    }
}

#[test]
fn crops_outside_the_image_are_refused_naming_the_parameter() {
    let img = varied(10, 8);
    for (p, name) in [
        (with(|p| p.crop_x = 10), "crop_x"),
        (with(|p| p.crop_y = 8), "crop_y"),
        (
            with(|p| {
                p.crop_x = 4;
                p.crop_width = 7;
            }),
            "crop_width",
        ),
        (
            with(|p| {
                p.crop_y = 1;
                p.crop_height = 8;
            }),
            "crop_height",
        ),
    ] {
        let e = transform(&img, &p).unwrap_err().to_string();
        assert!(e.contains(name) && !e.contains('\n'), "{e}");
    }
}
