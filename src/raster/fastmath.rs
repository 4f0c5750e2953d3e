//! Branch-free `f32` approximations of `log2` and `exp2` that vectorise (the relit preview's
//! Blinn-Phong power) and the fused multiply-add switch of the kernels' twins. Their accuracy is tested in
//! `render`'s tests against `f64`.

/// `log2(x)` for normal `x > 0`, within 3e-7 of the exact value (absolute for `|log2 x| ≤ 1`,
/// relative beyond): `x = m · 2^e` with `m ∈ [√½, √2)`, then `log2 m = 2/ln 2 · atanh(t)`,
/// `t = (m − 1)/(m + 1)`, as an odd series to `t⁹` (`|t| < 0.172`, first dropped term `< 2e-10`).
/// Branch-free, so it vectorises.
#[inline(always)]
pub(crate) fn log2_fast(x: f32) -> f32 {
    let bits = x.to_bits();
    // 0x3f35_04f3 is √½: subtracting its bits makes the exponent field that of x/√½ (so e is
    // the exponent with m ∈ [√½, √2)); adding them back to the mantissa bits rebuilds m.
    let shifted = bits.wrapping_sub(0x3f35_04f3);
    let e = (shifted as i32) >> 23;
    let m = f32::from_bits((shifted & 0x007f_ffff).wrapping_add(0x3f35_04f3));
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let series =
        t * (2.0 + t2 * (2.0 / 3.0 + t2 * (2.0 / 5.0 + t2 * (2.0 / 7.0 + t2 * (2.0 / 9.0)))));
    e as f32 + series * std::f32::consts::LOG2_E
}

/// `1.5 · 2²³`: adding it to `|v| < 2²²` rounds `v` to the nearest integer (ties to even), which
/// is then the low bits of the sum's bit pattern — a float → int conversion that vectorises
/// (Rust's saturating `as i32` does not, on x86).
pub(crate) const ROUND: f32 = 12_582_912.0;

/// `2^y` for `y ≤ 127` (flushed to `2^−126` below −126), within 3e-7 relative of `f32::exp2`
/// (tested for `y ≤ 0` by `render`, up to 20 by `capture::photometric`'s `pow_fast`):
/// nearest integer `i` by [`ROUND`], `2^f` for `f ∈ [−½, ½]` by its Taylor series to `f⁶`
/// (remainder `< 2e-7`), scaled by building `2^i`'s bits. Branch-free.
#[inline(always)]
pub(crate) fn exp2_fast(y: f32) -> f32 {
    let y = y.max(-126.0);
    let big = y + ROUND;
    let r = big - ROUND;
    let f = (y - r) * std::f32::consts::LN_2;
    let p = 1.0
        + f * (1.0
            + f * (1.0 / 2.0
                + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0))))));
    // big's bits are 0x4b40_0000 + i; (i + 127) << 23 is 2^i (the 0x4b40_0000 shifts out).
    let scale = f32::from_bits(big.to_bits().wrapping_add(127) << 23);
    p * scale
}

/// `a · b + c`, fused into one instruction (and one rounding) when `F` — for kernels whose
/// vector twins are compiled with FMA; plain multiply-add otherwise (`mul_add` without hardware
/// FMA is a slow library call).
#[inline(always)]
pub(crate) fn madd<const F: bool>(a: f32, b: f32, c: f32) -> f32 {
    if F {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}
