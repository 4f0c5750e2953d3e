// Index loops mirror the formulas (pixel i, channel c) in these test images.
#![allow(clippy::needless_range_loop)]

//! Tests of `raster/integrate/green.rs`: analytic surfaces rendered to normals in each
//! convention, alone and laid out like a UV atlas.

use super::*;
use crate::raster::gradient::{normal_of_gradient, Differences};
use crate::raster::integrate::gradients_of_height;
use crate::raster::sample::Surface;
use crate::raster::Plane;

/// Normals of a `w × h` height `f(u, v)` (u right, v up, origin at the centre) in the averaged
/// model: the samples of a surface.
fn normals_of(w: usize, h: usize, f: impl Fn(f64, f64) -> f64 + Sync) -> [Vec<f32>; 3] {
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let z = Plane::from_fn(w, h, |x, r| f(x as f64 - cx, cy - r as f64) as f32);
    let g = gradients_of_height(&z, None, None, Differences::Averaged);
    let mut n = [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]];
    for i in 0..w * h {
        let v = normal_of_gradient(g.p[i], g.q[i]);
        for c in 0..3 {
            n[c][i] = v[c];
        }
    }
    n
}

fn image(w: usize, h: usize, n: [Vec<f32>; 3]) -> RgbnImage {
    RgbnImage::flat(w, h, [0.5; 3]).with_normals(n).unwrap()
}

fn green_flipped(img: &RgbnImage) -> RgbnImage {
    let [x, y, z] = img.normal();
    img.with_normals([x.clone(), y.iter().map(|v| -v).collect(), z.clone()])
        .unwrap()
}

fn bumps(size: usize) -> impl Fn(f64, f64) -> f64 + Sync {
    let s = Surface::gaussians_for(size);
    move |u, v| s.height(u, v)
}

#[test]
fn a_surface_reads_as_held_and_its_flipped_twin_the_other_way() {
    let img = image(96, 96, normals_of(96, 96, bumps(96)));
    let g = green_convention(&img);
    assert_eq!(g.verdict, GreenVerdict::OpenGl, "{g:?}");
    // An exact surface of the model: the curl as held is rounding only.
    assert!(g.evidence.contrast > 0.99, "{g:?}");
    assert!(g.evidence.relief_plaquettes >= RELIEF_PLAQUETTES_MIN);
    let f = green_convention(&green_flipped(&img));
    assert_eq!(f.verdict, GreenVerdict::DirectX, "{f:?}");
    assert!((f.evidence.contrast + g.evidence.contrast).abs() < 1e-6);
    assert_eq!(f.evidence.relief_plaquettes, g.evidence.relief_plaquettes);
    assert_eq!(
        (f.evidence.islands_as_read, f.evidence.islands_flipped),
        (g.evidence.islands_flipped, g.evidence.islands_as_read)
    );
    assert!(g
        .describe("OpenGL (+y)", "DirectX (-y)")
        .starts_with("OpenGL (+y) most likely"));
    assert!(f
        .describe("OpenGL (+y)", "DirectX (-y)")
        .starts_with("DirectX (-y) most likely"));
}

/// Copies a `s × s` tile into the canvas at `(x0, r0)`.
fn paste(
    canvas: &mut [Vec<f32>; 3],
    cw: usize,
    tile: &[Vec<f32>; 3],
    s: usize,
    x0: usize,
    r0: usize,
) {
    for r in 0..s {
        for x in 0..s {
            for c in 0..3 {
                canvas[c][(r0 + r) * cw + x0 + x] = tile[c][r * s + x];
            }
        }
    }
}

/// A UV atlas: flat filler, black (invalid) filler, and islands of relief — one as is, one
/// mirrored, one rotated a quarter turn, one tilted (its border a seam against the filler),
/// one whose tangent frame is turned by 25° (normals rotated about z: not a surface, as on a
/// twisted frame), and ribs along one axis.
fn atlas() -> RgbnImage {
    let (cw, ch, s) = (176, 128, 48);
    let mut n = [vec![0.0; cw * ch], vec![0.0; cw * ch], vec![1.0; cw * ch]];
    let b = bumps(s);
    let b2 = bumps(s);
    let b3 = bumps(s);
    let b4 = bumps(s);
    paste(&mut n, cw, &normals_of(s, s, b), s, 4, 4);
    paste(
        &mut n,
        cw,
        &normals_of(s, s, move |u, v| b2(-u, v)),
        s,
        60,
        4,
    );
    paste(
        &mut n,
        cw,
        &normals_of(s, s, move |u, v| b3(v, -u)),
        s,
        4,
        68,
    );
    paste(
        &mut n,
        cw,
        &normals_of(s, s, move |u, v| b4(u, v) + 0.4 * u - 0.2 * v),
        s,
        60,
        68,
    );
    let mut turned = normals_of(s, s, bumps(s));
    let (c, si) = (25f32.to_radians().cos(), 25f32.to_radians().sin());
    for i in 0..s * s {
        let (x, y) = (turned[0][i], turned[1][i]);
        turned[0][i] = c * x - si * y;
        turned[1][i] = si * x + c * y;
    }
    paste(&mut n, cw, &turned, s, 116, 4);
    let ribs = normals_of(s, s, |u, _| 3.0 * (u / 2.5).sin());
    paste(&mut n, cw, &ribs, s, 116, 68);
    // Black filler: an 8-bit (0, 0, 0) decodes to (-1, -1, -1), normalised here: unusable.
    for r in 120..ch {
        for x in 0..cw {
            for c in 0..3 {
                n[c][r * cw + x] = if c == 2 { -1.0 } else { -0.577 };
            }
        }
    }
    image(cw, ch, n)
}

#[test]
fn an_atlas_with_filler_seams_mirrored_rotated_and_turned_islands_reads_as_held() {
    let img = atlas();
    let g = green_convention(&img);
    assert_eq!(g.verdict, GreenVerdict::OpenGl, "{g:?}");
    assert!(g.evidence.islands_as_read >= 5, "{g:?}");
    assert_eq!(g.evidence.islands_flipped, 0, "{g:?}");
    let f = green_convention(&green_flipped(&img));
    assert_eq!(f.verdict, GreenVerdict::DirectX, "{f:?}");
    assert!(f.evidence.islands_flipped >= 5, "{f:?}");
}

#[test]
fn relief_along_one_axis_at_a_time_cannot_tell() {
    // z = f(x) + g(y): ∂²z/∂x∂y = 0, both readings are surfaces. Normals exact, so both mixed
    // slope estimates vanish on every plaquette.
    let (w, h) = (96, 80);
    let mut n = [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]];
    for r in 0..h {
        for x in 0..w {
            let p = 0.8 * (x as f32 / 5.0).cos();
            let q = -0.6 * (r as f32 / 7.0).sin();
            let v = normal_of_gradient(p, q);
            for c in 0..3 {
                n[c][r * w + x] = v[c];
            }
        }
    }
    let g = green_convention(&image(w, h, n));
    assert_eq!(
        g.verdict,
        GreenVerdict::Uncertain(Uncertainty::TooLittleRelief),
        "{g:?}"
    );
    assert_eq!(g.evidence.relief_plaquettes, 0);
    assert!(g
        .describe("OpenGL (+y)", "DirectX (-y)")
        .starts_with("uncertain — too little relief"));
}

#[test]
fn flat_and_tiny_images_are_too_little_relief() {
    for (w, h) in [(64, 64), (1, 1), (1, 9), (9, 1), (2, 2)] {
        let g = green_convention(&RgbnImage::flat(w, h, [0.5; 3]));
        assert_eq!(
            g.verdict,
            GreenVerdict::Uncertain(Uncertainty::TooLittleRelief),
            "{w}×{h}"
        );
        assert_eq!(g.evidence.z, 0.0);
    }
}

#[test]
fn normals_that_are_no_surface_vote_about_evenly() {
    // Independent random slopes in [-0.4, 0.4]: no seam, every plaquette votes, A and B
    // uncorrelated.
    let (w, h) = (128, 128);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 * 0.8 - 0.4
    };
    let mut n = [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]];
    for i in 0..w * h {
        let v = normal_of_gradient(rnd(), rnd());
        for c in 0..3 {
            n[c][i] = v[c];
        }
    }
    let g = green_convention(&image(w, h, n));
    assert_eq!(
        g.verdict,
        GreenVerdict::Uncertain(Uncertainty::Balanced),
        "{g:?}"
    );
    assert!(g.evidence.contrast.abs() < 0.03, "{g:?}");
    assert!(g.evidence.relief_plaquettes > 10_000, "{g:?}");
    assert!(g
        .describe("OpenGL (+y)", "DirectX (-y)")
        .starts_with("uncertain — the two readings are about as integrable"));
}

#[test]
fn pixels_outside_the_mask_do_not_vote() {
    // Inside a disc a surface as held; outside, a surface stored flipped: read whole, the two
    // pull against each other and it is no longer OpenGL; with the mask only the disc votes.
    let (w, h) = (96, 96);
    let inner = normals_of(w, h, bumps(96));
    let outer = normals_of(w, h, |u, v| 2.0 * (u / 4.0).sin() * (v / 5.0).sin());
    let mask: Vec<f32> = (0..w * h)
        .map(|i| {
            let (u, v) = ((i % w) as f64 - 48.0, (i / w) as f64 - 48.0);
            f32::from(u8::from(u * u + v * v < 30.0 * 30.0))
        })
        .collect();
    let mut n = inner.clone();
    for i in 0..w * h {
        if mask[i] < 0.5 {
            n[0][i] = outer[0][i];
            n[1][i] = -outer[1][i];
            n[2][i] = outer[2][i];
        }
    }
    let unmasked = image(w, h, n.clone());
    assert_ne!(green_convention(&unmasked).verdict, GreenVerdict::OpenGl);
    let masked = RgbnImage::new(
        w,
        h,
        [vec![0.5; w * h], vec![0.5; w * h], vec![0.5; w * h]],
        n,
        Some(mask),
    )
    .unwrap();
    let g = green_convention(&masked);
    assert_eq!(g.verdict, GreenVerdict::OpenGl, "{g:?}");
    assert!(g.evidence.relief_plaquettes < 30 * 30 * 4, "{g:?}");
}

#[test]
fn an_8_bit_map_of_a_surface_still_decides() {
    let (w, h) = (128, 128);
    let mut n = normals_of(w, h, bumps(128));
    for c in &mut n {
        for v in c.iter_mut() {
            *v = ((*v * 0.5 + 0.5) * 255.0).round() / 255.0 * 2.0 - 1.0;
        }
    }
    let img = image(w, h, n);
    let g = green_convention(&img);
    assert_eq!(g.verdict, GreenVerdict::OpenGl, "{g:?}");
    assert_eq!(
        green_convention(&green_flipped(&img)).verdict,
        GreenVerdict::DirectX
    );
}
