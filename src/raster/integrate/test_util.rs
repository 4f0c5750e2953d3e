//! Test helpers shared by the solvers' tests.

use super::inside;
use crate::raster::gradient::GradientField;
use crate::raster::Plane;

/// A rough, non-smooth height (no structure a smooth solver could exploit).
pub(super) fn rough(w: usize, h: usize) -> Plane {
    Plane::from_fn(w, h, |x, r| {
        ((x * 7919 + r * 104_729) % 1000) as f32 * 0.01 + (x as f32 * 0.3).sin() * 3.0
    })
}

/// Max |a − b − (mean difference)| over `sel` pixels (all if None).
pub(super) fn max_err_up_to_constant(a: &Plane, b: &Plane, sel: Option<&[f32]>) -> f64 {
    let ins = |i: usize| sel.is_none_or(|m| inside(m[i]));
    let idx: Vec<usize> = (0..a.data().len()).filter(|&i| ins(i)).collect();
    let off = idx
        .iter()
        .map(|&i| f64::from(a.data()[i]) - f64::from(b.data()[i]))
        .sum::<f64>()
        / idx.len() as f64;
    idx.iter()
        .map(|&i| (f64::from(a.data()[i]) - f64::from(b.data()[i]) - off).abs())
        .fold(0.0, f64::max)
}

pub(super) fn rmse_up_to_constant(a: &Plane, b: &Plane, sel: Option<&[f32]>) -> f64 {
    let ins = |i: usize| sel.is_none_or(|m| inside(m[i]));
    let idx: Vec<usize> = (0..a.data().len()).filter(|&i| ins(i)).collect();
    let d: Vec<f64> = idx
        .iter()
        .map(|&i| f64::from(a.data()[i]) - f64::from(b.data()[i]))
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
}

/// A gradient field with no structure (not integrable), values in about [−2, 2].
pub(super) fn rough_field(w: usize, h: usize) -> GradientField {
    let mut g = GradientField::zeros(w, h);
    for i in 0..w * h {
        g.p[i] = ((i * 7919 + 13) % 1009) as f32 / 250.0 - 2.0;
        g.q[i] = ((i * 104_729 + 7) % 997) as f32 / 250.0 - 2.0;
    }
    g
}

/// Sizes that exercise odd lengths, a single row / column, and column groups that are
/// partial or end in an unpaired column.
pub(super) const ODD_SIZES: [(usize, usize); 11] = [
    (1, 1),
    (1, 7),
    (7, 1),
    (2, 2),
    (17, 3),
    (16, 16),
    (33, 20),
    (40, 9),
    (18, 31),
    (35, 2),
    (9, 8),
];

/// `max |got − want| ≤ tol · max |want|` (plus a tiny absolute floor).
pub(super) fn assert_close(got: &[f32], want: &[f64], tol: f64, what: &str) {
    let amp = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let err = got
        .iter()
        .zip(want)
        .map(|(&a, b)| (f64::from(a) - b).abs())
        .fold(0.0, f64::max);
    assert!(
        err <= tol * amp + 1e-6,
        "{what}: max error {err:.3e}, amplitude {amp:.3e}"
    );
}
