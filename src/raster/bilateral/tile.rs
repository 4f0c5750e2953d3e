//! The tile loops of the bilateral kernel ([`super`]), written once over [`Vf`] and
//! instantiated per twin: the pair weights' exponent, the one-weight-per-tap loop and the
//! symmetric (pair) loop, and the output of a pixel.

use super::vector::Vf;
use super::{
    BandOut, Input, Kernel, TileAt, ACC, ACCS, C0, MAX_L, NRM_ANGLE, NRM_ANGLE_NARROW, NRM_NONE,
    NX, NY, NZ, P, PLANES, Q, STRIDE, VALID,
};
use crate::raster::fastmath::{madd, ROUND};
use crate::raster::gradient::normal_of_gradient;

/// `2^−e` (flushed to `2^−126` beyond 126; `e` may be slightly negative), within 1.6e-7
/// relative: nearest integer `i` of `−e` by [`ROUND`], then `2^−g` for the rest
/// `g ∈ [−½, ½]` by a degree-5 minimax polynomial (fitted in `f64` to the relative error,
/// coefficients rounded to `f32`; 1.5e-7) by Estrin's scheme, scaled by building `2^i`'s bits.
/// Branch-free.
#[inline(always)]
fn exp2_neg<V: Vf, const F: bool>(e: V) -> V {
    const C: [f32; 6] = [
        1.000_000_1,
        -0.693_146_94,
        0.240_221_2,
        -0.055_507_135,
        0.009_675_542,
        -0.001_327_647,
    ];
    let c = V::splat;
    let e = e.min(c(126.0));
    let big = c(ROUND).sub(e);
    let g = e.add(big.sub(c(ROUND)));
    let g2 = g.mul(g);
    let g4 = g2.mul(g2);
    let lo = g2.madd::<F>(c(C[3]).madd::<F>(g, c(C[2])), c(C[1]).madd::<F>(g, c(C[0])));
    let hi = c(C[5]).madd::<F>(g, c(C[4]));
    g4.madd::<F>(hi, lo).mul(big.pow2_of_rounded())
}

/// `acos(1 − t)² = t · G(t)` for `t ∈ [0, 1]` (angles up to 90°), `G` of degree 6 (Chebyshev
/// fit in `f64`, coefficients rounded to `f32`), from `t⁰` up: relative error ≤ 8e-7, so a
/// weight `exp(−k δ²)` is off by at most `8e-7 · max(x e^−x) < 3e-7`. No square root. Beyond
/// 90° `t · G(t)` keeps growing (every coefficient but `t⁵`'s is positive and `G(t) > G(1)`
/// on [1, 2]), so there the weight stays below its value at 90°, < 1e-8 where it is used.
pub(super) const NARROW_G: [f32; 7] = [
    2.000_001_2,
    0.333_264_56,
    0.089_773_22,
    0.023_973_45,
    0.021_646_81,
    -0.010_330_418,
    0.009_070_478,
];

/// `acos(1 − t)` for `t ∈ [0, 2]`: Abramowitz & Stegun 4.4.46, `acos x = √(1 − x) · Σ aᵢ xⁱ`
/// for `x ∈ [0, 1]` (error ≤ 2e-8), and `π − acos(−x)` below 0. `√(1 − x)` is `√t` (or
/// `√(2 − t)`), exact from the chord. Branch-free.
#[inline(always)]
fn acos_one_minus<V: Vf, const F: bool>(t: V) -> V {
    let c = V::splat;
    let one_minus = c(1.0).sub(t);
    let u = one_minus.max(c(0.0).sub(one_minus));
    let s = c(1.0).sub(u);
    let mut poly = c(-0.001_262_491).madd::<F>(u, c(0.006_670_09));
    for k in [
        -0.017_088_126,
        0.030_891_88,
        -0.050_174_305,
        0.088_978_99,
        -0.214_598_8,
        std::f32::consts::FRAC_PI_2,
    ] {
        poly = poly.madd::<F>(u, c(k));
    }
    let a = s.max(c(0.0)).sqrt().mul(poly);
    t.select_le(c(1.0), a, c(std::f32::consts::PI).sub(a))
}

impl Kernel {
    /// The exponent `e` of the weight `2^−e` of the pairs (P, P + off) for the lanes of P at
    /// `base` (centre planes `cen`: normal, colour), `st` the tap's spatial exponent.
    #[inline(always)]
    fn exponent<V: Vf, const COL: bool, const NRM: u8, const F: bool>(
        &self,
        vals: &[f32],
        base: usize,
        (off, st): (isize, f32),
        cen: &[V; 6],
    ) -> V {
        let j = base.wrapping_add_signed(off);
        // All planes of this tap in one slice: one bounds check, then constant offsets.
        let blk = &vals[j..j + (PLANES - 1) * STRIDE + V::L];
        let at = |k: usize| V::load(&blk[k * STRIDE..]);
        let mut e = V::splat(st);
        if COL {
            let d0 = at(C0).sub(cen[3]);
            let d1 = at(C0 + 1).sub(cen[4]);
            let d2 = at(C0 + 2).sub(cen[5]);
            let d = d2.madd::<F>(d2, d1.madd::<F>(d1, d0.mul(d0)));
            e = V::splat(self.kc).madd::<F>(d, e);
        }
        if NRM != NRM_NONE {
            let dot = at(NZ).madd::<F>(cen[2], at(NY).madd::<F>(cen[1], at(NX).mul(cen[0])));
            let t = V::splat(1.0).sub(dot).max(V::splat(0.0));
            match NRM {
                NRM_ANGLE_NARROW => {
                    // kn·δ² = t · Σ hᵢ tⁱ, by Estrin's scheme (a short dependency chain).
                    let h = |i: usize| V::splat(self.hn[i]);
                    let t2 = t.mul(t);
                    let t4 = t2.mul(t2);
                    let hi = t2.madd::<F>(h(6), h(5).madd::<F>(t, h(4)));
                    let lo = t2.madd::<F>(h(3).madd::<F>(t, h(2)), h(1).madd::<F>(t, h(0)));
                    e = t.madd::<F>(t4.madd::<F>(hi, lo), e);
                }
                NRM_ANGLE => {
                    let d = acos_one_minus::<V, F>(t.min(V::splat(2.0)));
                    e = V::splat(self.kn).madd::<F>(d.mul(d), e);
                }
                _ => e = V::splat(self.kn).madd::<F>(t.mul(t), e),
            }
        }
        e
    }

    /// The filter over one filled tile (`tw` columns at `x0`, `rows` rows).
    #[inline(always)]
    pub(super) fn tile<V: Vf, const COL: bool, const NRM: u8, const FC: bool, const F: bool>(
        &self,
        input: &Input<'_>,
        at: TileAt,
        s: &[f32],
        out: &mut BandOut<'_>,
    ) {
        let TileAt { r0, x0, tw, rows } = at;
        let (w, lw, l) = (input.width, self.lw, V::L);
        for ty in 0..rows {
            for tx in (0..tw).step_by(l) {
                let base = (ty + self.ry) * lw + tx + self.rx;
                let c = |k: usize| V::load(&s[k * STRIDE + base..]);
                let cen = [c(NX), c(NY), c(NZ), c(C0), c(C0 + 1), c(C0 + 2)];
                let zero = V::splat(0.0);
                let (mut ap, mut aq, mut aw) = (zero, zero, zero);
                let mut ac = [zero; 3];
                for &tap in &self.taps {
                    let e = self.exponent::<V, COL, NRM, F>(s, base, tap, &cen);
                    let j = base.wrapping_add_signed(tap.0);
                    let blk = &s[j..j + (PLANES - 1) * STRIDE + l];
                    let at = |k: usize| V::load(&blk[k * STRIDE..]);
                    let mut wt = exp2_neg::<V, F>(e);
                    if !COL {
                        // With colour an invalid pixel's FAR_COLOR already weighs 2^−126.
                        wt = at(VALID).mul(wt);
                    }
                    ap = wt.madd::<F>(at(P), ap);
                    aq = wt.madd::<F>(at(Q), aq);
                    aw = aw.add(wt);
                    if FC {
                        for (k, a) in ac.iter_mut().enumerate() {
                            *a = wt.madd::<F>(at(C0 + k), *a);
                        }
                    }
                }
                let mut sums = [[0.0f32; MAX_L]; 6];
                for (o, v) in sums.iter_mut().zip([ap, aq, aw, ac[0], ac[1], ac[2]]) {
                    v.store(o);
                }
                let cv = c(VALID);
                let mut valid = [0.0f32; MAX_L];
                cv.store(&mut valid);
                let o = ty * w + x0 + tx;
                for i in 0..l.min(tw - tx) {
                    let px = std::array::from_fn(|k| sums[k][i]);
                    let g = (r0 + ty) * w + x0 + tx + i;
                    emit(input, out, o + i, g, valid[i] > 0.0, px);
                }
            }
        }
    }

    /// [`Self::tile`] with each pair's weight computed once (it is symmetric: w(P, Q) =
    /// w(Q, P)) and added to both ends: P runs over the output pixels and the halo pixels above
    /// and beside them, Q = P + o over the half disc (`dy > 0`, or `dy = 0 < dx`); P's sums
    /// stay in registers, Q's go to accumulator planes. About 0.55× the exponentials of the
    /// full disc at 64-row tiles. Needs `rx = 2r`, `ry = r` and the accumulator planes.
    ///
    /// Software-pipelined: the exponent of the next tap is computed with the `exp2` and the
    /// sums of this one, so the two halves of each weight's long dependency chain overlap.
    #[inline(always)]
    pub(super) fn tile_sym<V: Vf, const COL: bool, const NRM: u8, const FC: bool, const F: bool>(
        &self,
        input: &Input<'_>,
        at: TileAt,
        s: &mut [f32],
        out: &mut BandOut<'_>,
    ) {
        let TileAt { r0, x0, tw, rows } = at;
        let (w, lw, r, l) = (input.width, self.lw, self.ry, V::L);
        let span = lw * self.lh;
        let (vals, accs) = s.split_at_mut(ACC * STRIDE);
        for k in 0..ACCS {
            accs[k * STRIDE..k * STRIDE + span].fill(0.0);
        }
        let taps = &self.half_taps;

        // P columns: the output's (from rx = 2r) and r on each side, in whole lane groups.
        let groups = (tw + 2 * r).div_ceil(l);
        for lr in 0..r + rows {
            for g in 0..groups {
                let base = lr * lw + r + g * l;
                let c = |k: usize| V::load(&vals[k * STRIDE + base..]);
                let cen = [c(NX), c(NY), c(NZ), c(C0), c(C0 + 1), c(C0 + 2)];
                let cval = c(VALID);
                let (gp, gq) = (c(P), c(Q));
                // P's own sums start with itself (weight 1 when valid).
                let (mut mp, mut mq, mut mw) = (cval.mul(gp), cval.mul(gq), cval);
                let mut m = [cval.mul(cen[3]), cval.mul(cen[4]), cval.mul(cen[5])];
                let mut e = self.exponent::<V, COL, NRM, F>(vals, base, taps[0], &cen);
                for (&(off, _), &next) in taps.iter().zip(&self.half_next) {
                    // The last iteration computes its own tap's exponent again (unused).
                    let e_next = self.exponent::<V, COL, NRM, F>(vals, base, next, &cen);
                    let j = base.wrapping_add_signed(off);
                    let blk = &vals[j..j + (PLANES - 1) * STRIDE + l];
                    let at = |k: usize| V::load(&blk[k * STRIDE..]);
                    let mut wt = exp2_neg::<V, F>(e);
                    if !COL {
                        wt = at(VALID).mul(wt).mul(cval);
                    }
                    mp = wt.madd::<F>(at(P), mp);
                    mq = wt.madd::<F>(at(Q), mq);
                    mw = mw.add(wt);
                    if FC {
                        for (i, a) in m.iter_mut().enumerate() {
                            *a = wt.madd::<F>(at(C0 + i), *a);
                        }
                    }
                    // Q's sums, in the accumulator planes.
                    let ablk = &mut accs[j..j + (ACCS - 1) * STRIDE + l];
                    let mut add = |k: usize, v: V| {
                        let d = &mut ablk[k * STRIDE..];
                        wt.madd::<F>(v, V::load(d)).store(d);
                    };
                    add(0, gp);
                    add(1, gq);
                    if FC {
                        for i in 0..3 {
                            add(3 + i, cen[3 + i]);
                        }
                    }
                    let d = &mut ablk[2 * STRIDE..];
                    V::load(d).add(wt).store(d);
                    e = e_next;
                }
                let ablk = &mut accs[base..base + (ACCS - 1) * STRIDE + l];
                let sums = [mp, mq, mw, m[0], m[1], m[2]];
                for (k, v) in sums.iter().enumerate().take(if FC { ACCS } else { 3 }) {
                    let d = &mut ablk[k * STRIDE..];
                    V::load(d).add(*v).store(d);
                }
            }
        }
        // Row by row, branch-free (it vectorises): the normal of the mean gradient and the
        // mean colour where the centre is valid, else the input.
        for ty in 0..rows {
            let j = (ty + r) * lw + self.rx;
            let acc = |k: usize| &accs[k * STRIDE + j..k * STRIDE + j + tw];
            let (sp, sq, sw) = (acc(0), acc(1), acc(2));
            let valid = &vals[VALID * STRIDE + j..VALID * STRIDE + j + tw];
            let (o, g) = (ty * w + x0, (r0 + ty) * w + x0);
            let [ox, oy, oz] = out.n.each_mut().map(|p| &mut p[o..o + tw]);
            let [ix, iy, iz] = input.normal.map(|p| &p[g..g + tw]);
            for x in 0..tw {
                // Both sides of each choice computed, then selected (a blend: no masked
                // loads or stores, which are slow on AMD).
                let inv = 1.0 / sw[x];
                let (p, q) = (sp[x] * inv, sq[x] * inv);
                let l = 1.0 / madd::<F>(q, q, madd::<F>(p, p, 1.0)).sqrt();
                let ok = valid[x] > 0.0;
                let (nx, ny, nz) = (-p * l, -q * l, l);
                let (kx, ky, kz) = (ix[x], iy[x], iz[x]);
                ox[x] = if ok { nx } else { kx };
                oy[x] = if ok { ny } else { ky };
                oz[x] = if ok { nz } else { kz };
            }
            if let Some(c) = out.c.as_mut() {
                for (k, (oc, ic)) in c.iter_mut().zip(&input.color).enumerate() {
                    let (oc, ic, sc) = (&mut oc[o..o + tw], &ic[g..g + tw], acc(3 + k));
                    for x in 0..tw {
                        let (mean, keep) = (sc[x] / sw[x], ic[x]);
                        oc[x] = if valid[x] > 0.0 { mean } else { keep };
                    }
                }
            }
        }
    }
}

/// Writes output pixel `i` of the band (image pixel `g`): the normal of the mean gradient and
/// the mean colour from `sums` = (Σwp, Σwq, Σw, Σwc₀, Σwc₁, Σwc₂) when `valid`, else the input.
#[inline(always)]
fn emit(input: &Input<'_>, out: &mut BandOut<'_>, i: usize, g: usize, valid: bool, sums: [f32; 6]) {
    if valid {
        let inv = 1.0 / sums[2];
        let nrm = normal_of_gradient(sums[0] * inv, sums[1] * inv);
        for (o, v) in out.n.iter_mut().zip(nrm) {
            o[i] = v;
        }
        if let Some(c) = out.c.as_mut() {
            for (o, a) in c.iter_mut().zip(&sums[3..]) {
                o[i] = a * inv;
            }
        }
    } else {
        // Masked out or not finite: the input, unchanged.
        for (o, v) in out.n.iter_mut().zip(&input.normal) {
            o[i] = v[g];
        }
        if let Some(c) = out.c.as_mut() {
            for (o, v) in c.iter_mut().zip(&input.color) {
                o[i] = v[g];
            }
        }
    }
}
