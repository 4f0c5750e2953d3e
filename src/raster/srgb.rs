//! The sRGB transfer function (IEC 61966-2-1) and its tables: decoding 8/16-bit files to
//! linear light, and encoding linear light to 8 bits (files, the renderer, mesh colours).

/// 8-bit sRGB → linear table.
pub(crate) fn srgb8_lut() -> &'static [f32; 256] {
    static LUT: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    LUT.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// 16-bit sRGB → linear table.
pub(crate) fn srgb16_lut() -> &'static [f32] {
    static LUT: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        (0..65536)
            .map(|i| srgb_to_linear(i as f32 / 65535.0))
            .collect()
    })
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1), value in [0, 1].
#[must_use]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Inverse of [`srgb_to_linear`].
#[must_use]
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Entries of the linear → sRGB 8-bit table.
pub const SRGB8_LUT_SIZE: usize = 16384;

/// The linear \[0,1\] → sRGB 8-bit table; index with [`srgb8_index`].
#[must_use]
pub fn srgb8_lut_encode() -> &'static [u8] {
    static LUT: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        (0..SRGB8_LUT_SIZE)
            .map(|i| (linear_to_srgb(i as f32 / (SRGB8_LUT_SIZE - 1) as f32) * 255.0 + 0.5) as u8)
            .collect()
    })
}

/// Table index of a linear value (clamped to [0, 1]; NaN maps to 0).
#[inline(always)]
#[must_use]
pub fn srgb8_index(v: f32) -> usize {
    ((v.clamp(0.0, 1.0) * (SRGB8_LUT_SIZE - 1) as f32 + 0.5) as usize).min(SRGB8_LUT_SIZE - 1)
}

/// Linear \[0,1\] → sRGB 8-bit via a 16384-entry table (within 1 level of the formula).
#[inline]
#[must_use]
pub fn linear_to_srgb8(v: f32) -> u8 {
    srgb8_lut_encode()[srgb8_index(v)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_roundtrip_and_known_values() {
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-5);
        for i in 0..=255u8 {
            let lin = srgb8_lut()[usize::from(i)];
            assert_eq!(linear_to_srgb8(lin), i, "8-bit sRGB round trip of {i}");
        }
    }
}
