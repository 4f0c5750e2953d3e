//! Viewing from disk (`file://`): browsers refuse image files as WebGL textures in a page
//! opened from disk, but run its scripts. The small levels — both sides at most
//! [`FALLBACK_SIDE`] — are therefore also written as one script per level,
//! `fallback/K.js`, that hands the viewer their tiles as `data:` URLs:
//! `rgbnFallback(K, {"albedo/C_R": "data:image/png;base64,…", "normals/C_R": …});`.
//! From disk the viewer shows the image up to that resolution; `rgbn serve DIR` (or any web
//! server) shows every level. Only these small levels are stored twice (for a 16384² image,
//! about 2 % of the tile bytes).

use super::pyramid::Level;
use crate::error::RgbnError;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Levels whose width and height are both at most this many pixels get a fallback script.
pub const FALLBACK_SIDE: usize = 2048;

/// The scripts being collected, by Deep Zoom level.
pub(super) struct Fallback {
    levels: BTreeMap<usize, String>,
}

impl Fallback {
    pub(super) fn new() -> Self {
        Self {
            levels: BTreeMap::new(),
        }
    }

    /// Whether `level` gets a fallback script.
    pub(super) fn wants(&self, level: Level) -> bool {
        level.width.max(level.height) <= FALLBACK_SIDE
    }

    /// Adds tile `(c, r)` of `level` (its albedo and normal PNG bytes).
    pub(super) fn add(&mut self, level: Level, c: usize, r: usize, albedo: &[u8], normals: &[u8]) {
        let s = self.levels.entry(level.level).or_default();
        for (layer, bytes) in [("albedo", albedo), ("normals", normals)] {
            let _ = write!(
                s,
                "{}\"{layer}/{c}_{r}\": \"data:image/png;base64,{}\"",
                if s.is_empty() { "" } else { ",\n" },
                base64(bytes)
            );
        }
    }

    /// The Deep Zoom levels that have a script.
    pub(super) fn levels(&self) -> Vec<usize> {
        self.levels.keys().copied().collect()
    }

    /// Writes `fallback/K.js` for every level.
    pub(super) fn write(&self, dir: &Path) -> Result<(), RgbnError> {
        let d = dir.join("fallback");
        std::fs::create_dir_all(&d).map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: d.clone(),
        })?;
        for (k, body) in &self.levels {
            let text = format!("rgbnFallback({k}, {{\n{body}\n}});\n");
            let p = d.join(format!("{k}.js"));
            std::fs::write(&p, text).map_err(|e| RgbnError::Write {
                detail: e.to_string(),
                path: p.clone(),
            })?;
        }
        Ok(())
    }
}

/// Standard base64 (RFC 4648, padded).
#[must_use]
pub fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ABC[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648() {
        for (raw, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(raw.as_bytes()), enc);
        }
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }
}
