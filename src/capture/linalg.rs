//! `3 × 3` linear algebra for light Gram matrices, and angles between directions.

/// Smallest accepted `det(A) / (tr(A)/3)³` of a `3 × 3` light Gram matrix `A = LᵀL`: 1 for
/// isotropic lights, 0 for coplanar ones.
pub const MIN_LIGHT_CONDITION: f64 = 1e-5;

pub(crate) type M3 = [[f64; 3]; 3];

pub(crate) fn gram(dirs: impl Iterator<Item = [f64; 3]>) -> M3 {
    let mut a = [[0.0; 3]; 3];
    for l in dirs {
        for r in 0..3 {
            for c in 0..3 {
                a[r][c] += l[r] * l[c];
            }
        }
    }
    a
}

pub(crate) fn det3(a: &M3) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// `det(A) / (tr(A)/3)³` (scale-free conditioning of a Gram matrix).
pub(crate) fn condition(a: &M3) -> f64 {
    let t = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    if t <= 0.0 {
        0.0
    } else {
        det3(a) / (t * t * t)
    }
}

/// The adjugate of `A` (`A⁻¹ = adj(A) / det(A)`).
fn adj3(a: &M3) -> M3 {
    [
        [
            a[1][1] * a[2][2] - a[1][2] * a[2][1],
            a[0][2] * a[2][1] - a[0][1] * a[2][2],
            a[0][1] * a[1][2] - a[0][2] * a[1][1],
        ],
        [
            a[1][2] * a[2][0] - a[1][0] * a[2][2],
            a[0][0] * a[2][2] - a[0][2] * a[2][0],
            a[0][2] * a[1][0] - a[0][0] * a[1][2],
        ],
        [
            a[1][0] * a[2][1] - a[1][1] * a[2][0],
            a[0][1] * a[2][0] - a[0][0] * a[2][1],
            a[0][0] * a[1][1] - a[0][1] * a[1][0],
        ],
    ]
}

/// Solves `A x = y` for a well-conditioned symmetric `A` (adjugate).
pub(crate) fn solve3(a: &M3, y: [f64; 3]) -> [f64; 3] {
    let d = det3(a);
    let inv = adj3(a);
    std::array::from_fn(|r| (inv[r][0] * y[0] + inv[r][1] * y[1] + inv[r][2] * y[2]) / d)
}

/// Angle between two directions in degrees (not necessarily unit; 0 for a zero vector).
#[must_use]
pub fn angle_deg(a: [f32; 3], b: [f32; 3]) -> f64 {
    let a = a.map(f64::from);
    let b = b.map(f64::from);
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let la = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let lb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
    if la == 0.0 || lb == 0.0 {
        return 0.0;
    }
    (d / (la * lb)).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The inverse of a symmetric `3 × 3` matrix (adjugate over determinant); `None` when the
/// matrix is ill-conditioned (`condition(a) < MIN_LIGHT_CONDITION`) or not finite.
pub(crate) fn inverse3(a: &M3) -> Option<M3> {
    let cond = condition(a);
    if cond.is_nan() || cond < MIN_LIGHT_CONDITION {
        return None;
    }
    let d = det3(a);
    let adj = adj3(a);
    let inv = adj.map(|row| row.map(|v| v / d));
    inv.iter().flatten().all(|v| v.is_finite()).then_some(inv)
}

/// `A x` for a `3 × 3` matrix.
pub(crate) fn mul3(a: &M3, x: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2])
}

/// `x · y`.
pub(crate) fn dot3(x: [f64; 3], y: [f64; 3]) -> f64 {
    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
}
