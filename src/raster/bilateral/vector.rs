//! Vectors of `f32` lanes for the bilateral kernel's twins: one kernel written over [`Vf`],
//! instantiated with [`Lanes`] (plain arrays whose lane loops the compiler vectorises: the
//! portable and AVX-512 twins) and with [`Avx2`] (256-bit intrinsics: the AVX2 twin, whose
//! sixteen registers the array form spills). Every operation is the same IEEE operation in
//! every lane of every form, so the twins differ only where `F` (fused multiply-add) does.

/// A vector of [`Vf::L`] `f32` lanes.
pub(crate) trait Vf: Copy {
    /// Lanes.
    const L: usize;
    fn splat(v: f32) -> Self;
    /// The first `L` values of `s`.
    fn load(s: &[f32]) -> Self;
    /// Into the first `L` values of `s`.
    fn store(self, s: &mut [f32]);
    fn add(self, b: Self) -> Self;
    fn sub(self, b: Self) -> Self;
    fn mul(self, b: Self) -> Self;
    fn min(self, b: Self) -> Self;
    fn max(self, b: Self) -> Self;
    fn sqrt(self) -> Self;
    /// `self · b + c`, fused (one rounding) when `F`.
    fn madd<const F: bool>(self, b: Self, c: Self) -> Self;
    /// `2^i` where `self = ROUND + i` exactly (`|i| ≤ 126`): the bits of `self` plus 127,
    /// shifted left by 23.
    fn pow2_of_rounded(self) -> Self;
    /// Per lane `if self ≤ t { a } else { b }`.
    fn select_le(self, t: Self, a: Self, b: Self) -> Self;
}

/// `L` lanes as an array: each operation a lane loop the compiler vectorises.
#[derive(Clone, Copy)]
pub(crate) struct Lanes<const L: usize>(pub [f32; L]);

impl<const L: usize> Lanes<L> {
    #[inline(always)]
    fn map2(self, b: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Lanes(std::array::from_fn(|l| f(self.0[l], b.0[l])))
    }
}

impl<const L: usize> Vf for Lanes<L> {
    const L: usize = L;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Lanes([v; L])
    }
    #[inline(always)]
    fn load(s: &[f32]) -> Self {
        Lanes(s[..L].try_into().expect("L values"))
    }
    #[inline(always)]
    fn store(self, s: &mut [f32]) {
        s[..L].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self.map2(b, |x, y| x + y)
    }
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self.map2(b, |x, y| x - y)
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self.map2(b, |x, y| x * y)
    }
    #[inline(always)]
    fn min(self, b: Self) -> Self {
        // As `minps`: the second operand when either is NaN.
        self.map2(b, |x, y| if x < y { x } else { y })
    }
    #[inline(always)]
    fn max(self, b: Self) -> Self {
        self.map2(b, |x, y| if x > y { x } else { y })
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let mut o = self.0;
        for v in &mut o {
            *v = v.sqrt();
        }
        Lanes(o)
    }
    #[inline(always)]
    fn madd<const F: bool>(self, b: Self, c: Self) -> Self {
        Lanes(std::array::from_fn(|l| {
            if F {
                self.0[l].mul_add(b.0[l], c.0[l])
            } else {
                self.0[l] * b.0[l] + c.0[l]
            }
        }))
    }
    #[inline(always)]
    fn pow2_of_rounded(self) -> Self {
        let mut o = self.0;
        for v in &mut o {
            *v = f32::from_bits(v.to_bits().wrapping_add(127) << 23);
        }
        Lanes(o)
    }
    #[inline(always)]
    fn select_le(self, t: Self, a: Self, b: Self) -> Self {
        Lanes(std::array::from_fn(|l| {
            if self.0[l] <= t.0[l] {
                a.0[l]
            } else {
                b.0[l]
            }
        }))
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::Vf;
    use std::arch::x86_64::*;

    /// Eight lanes in one 256-bit register. Only the AVX2 twin (a `target_feature(enable =
    /// "avx2,fma")` function, called after both were detected) creates and uses it.
    #[derive(Clone, Copy)]
    pub(crate) struct Avx2(__m256);

    // SAFETY (every `unsafe` below): the intrinsics need AVX2 and FMA, which the only caller,
    // the AVX2 twin, runs with (detected at run time before it is called); loads and stores
    // are of slices checked to hold 8 values.
    impl Vf for Avx2 {
        const L: usize = 8;
        #[inline(always)]
        fn splat(v: f32) -> Self {
            Avx2(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn load(s: &[f32]) -> Self {
            let s = &s[..8];
            Avx2(unsafe { _mm256_loadu_ps(s.as_ptr()) })
        }
        #[inline(always)]
        fn store(self, s: &mut [f32]) {
            let s = &mut s[..8];
            unsafe { _mm256_storeu_ps(s.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn add(self, b: Self) -> Self {
            Avx2(unsafe { _mm256_add_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn sub(self, b: Self) -> Self {
            Avx2(unsafe { _mm256_sub_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn mul(self, b: Self) -> Self {
            Avx2(unsafe { _mm256_mul_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn min(self, b: Self) -> Self {
            Avx2(unsafe { _mm256_min_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn max(self, b: Self) -> Self {
            Avx2(unsafe { _mm256_max_ps(self.0, b.0) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Avx2(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn madd<const F: bool>(self, b: Self, c: Self) -> Self {
            Avx2(unsafe {
                if F {
                    _mm256_fmadd_ps(self.0, b.0, c.0)
                } else {
                    _mm256_add_ps(_mm256_mul_ps(self.0, b.0), c.0)
                }
            })
        }
        #[inline(always)]
        fn pow2_of_rounded(self) -> Self {
            Avx2(unsafe {
                let i = _mm256_add_epi32(_mm256_castps_si256(self.0), _mm256_set1_epi32(127));
                _mm256_castsi256_ps(_mm256_slli_epi32::<23>(i))
            })
        }
        #[inline(always)]
        fn select_le(self, t: Self, a: Self, b: Self) -> Self {
            Avx2(unsafe {
                let m = _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, t.0);
                _mm256_blendv_ps(b.0, a.0, m)
            })
        }
    }
}
