//! The disk cache (`--cache-dir`): one file per node evaluation, named by its content key.
//!
//! Format (little-endian): magic `RGBNCACH`, format version `u32`, the producing crate
//! (`rgbn` and its version, NUL-padded to 16 bytes), key `u128`, payload length
//! `u64`, XXH3-64 of the payload `u64`, then the payload: value count `u32`; per value a tag
//! byte and its data (RGBN: width, height `u32`, mask flag `u8`, then R,G,B,N.X,N.Y,N.Z\[,A\] as
//! raw `f32` planes; mask/scalar: width, height, one plane; picture: width, height, RGBA
//! bytes; number: `f64`); finally a curl flag `u8` and `f64`, and a flag `u8` and `f64` for
//! the non-integrable fraction F.
//!
//! Entries are written to a temporary file and renamed into place. An entry that is truncated,
//! corrupt, of another format version, written by another version of the crate or for another
//! key is ignored (and recomputed). Within one crate version an operator whose maths changes
//! bumps its `OpSpec::version`, which is in the key: `tests/it/op_versions.rs` pins every
//! operator's output with its version and fails, naming the operator, when one changes alone.

use super::cache::{CacheEntry, CacheKey};
use crate::nodes::{Picture, Value};
use crate::raster::{Plane, RgbnImage};
use std::path::{Path, PathBuf};
use std::sync::Arc;

const MAGIC: &[u8; 8] = b"RGBNCACH";
const FORMAT: u32 = 3;
const HEADER: usize = 8 + 4 + 16 + 16 + 8 + 8;

/// The crate that wrote an entry: `rgbn` and its version, NUL-padded.
const PRODUCER: [u8; 16] = producer(concat!("rgbn ", env!("CARGO_PKG_VERSION")));

const fn producer(s: &str) -> [u8; 16] {
    let b = s.as_bytes();
    assert!(b.len() <= 16, "crate version too long for the cache header");
    let mut out = [0u8; 16];
    let mut i = 0;
    while i < b.len() {
        out[i] = b[i];
        i += 1;
    }
    out
}

/// A folder of cached node outputs.
#[derive(Debug, Clone)]
pub struct DiskCache {
    dir: PathBuf,
}

fn put_plane(out: &mut Vec<u8>, p: &[f32]) {
    out.reserve(p.len() * 4);
    for v in p {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        if self.0.len() < n {
            return None;
        }
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        Some(a)
    }
    fn u8(&mut self) -> Option<u8> {
        Some(self.take(1)?[0])
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn size(&mut self) -> Option<(usize, usize)> {
        let (w, h) = (self.u32()? as usize, self.u32()? as usize);
        crate::raster::check_size(w, h, "cache").ok()?;
        Some((w, h))
    }
    fn plane(&mut self, n: usize) -> Option<Vec<f32>> {
        let b = self.take(n.checked_mul(4)?)?;
        Some(
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect(),
        )
    }
}

/// Serialises an entry's payload.
fn encode(e: &CacheEntry) -> Vec<u8> {
    let mut out = Vec::with_capacity(e.byte_size() + 64);
    out.extend_from_slice(&(e.values.len() as u32).to_le_bytes());
    for v in &e.values {
        let dims = |out: &mut Vec<u8>, w: usize, h: usize| {
            out.extend_from_slice(&(w as u32).to_le_bytes());
            out.extend_from_slice(&(h as u32).to_le_bytes());
        };
        match v {
            Value::Rgbn(img) => {
                out.push(0);
                dims(&mut out, img.width(), img.height());
                out.push(u8::from(img.mask().is_some()));
                for p in img.color().iter().chain(img.normal().iter()) {
                    put_plane(&mut out, p);
                }
                if let Some(m) = img.mask() {
                    put_plane(&mut out, m);
                }
            }
            Value::Mask(p) | Value::Scalar(p) => {
                out.push(if matches!(v, Value::Mask(_)) { 1 } else { 2 });
                dims(&mut out, p.width(), p.height());
                put_plane(&mut out, p.data());
            }
            Value::Picture(p) => {
                out.push(3);
                dims(&mut out, p.width, p.height);
                out.extend_from_slice(&p.rgba);
            }
            Value::Number(x) => {
                out.push(4);
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    for m in [e.curl, e.fraction] {
        out.push(u8::from(m.is_some()));
        out.extend_from_slice(&m.unwrap_or(0.0).to_le_bytes());
    }
    out
}

fn decode(payload: &[u8]) -> Option<CacheEntry> {
    let mut r = Reader(payload);
    let n = r.u32()? as usize;
    if n > 64 {
        return None;
    }
    let mut values = Vec::with_capacity(n);
    for _ in 0..n {
        let v = match r.u8()? {
            0 => {
                let (w, h) = r.size()?;
                let masked = r.u8()? != 0;
                let mut planes: Vec<Vec<f32>> = Vec::with_capacity(7);
                for _ in 0..6 {
                    planes.push(r.plane(w * h)?);
                }
                let mask = if masked { Some(r.plane(w * h)?) } else { None };
                let mut it = planes.into_iter();
                let mut next = || it.next().unwrap_or_default();
                let color = [next(), next(), next()];
                let normal = [next(), next(), next()];
                Value::Rgbn(RgbnImage::new(w, h, color, normal, mask).ok()?)
            }
            t @ (1 | 2) => {
                let (w, h) = r.size()?;
                let p = Arc::new(Plane::from_vec(w, h, r.plane(w * h)?).ok()?);
                if t == 1 {
                    Value::Mask(p)
                } else {
                    Value::Scalar(p)
                }
            }
            3 => {
                let (w, h) = r.size()?;
                let rgba = r.take(w * h * 4)?.to_vec();
                Value::Picture(Arc::new(Picture {
                    width: w,
                    height: h,
                    rgba,
                }))
            }
            4 => Value::Number(r.f64()?),
            _ => return None,
        };
        values.push(v);
    }
    let mut measured = || -> Option<Option<f64>> {
        let has = r.u8()? != 0;
        let v = r.f64()?;
        Some(has.then_some(v))
    };
    let curl = measured()?;
    let fraction = measured()?;
    if !r.0.is_empty() {
        return None;
    }
    Some(CacheEntry {
        values,
        curl,
        fraction,
        skipped: 0,
    })
}

impl DiskCache {
    /// Uses (and creates if needed) `dir`.
    pub fn new(dir: &Path) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        // Entries half-written by a process killed meanwhile.
        crate::raster::io::temp::clean_stale(dir, None);
        Ok(Self { dir: dir.into() })
    }

    /// The folder.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file holding `key`.
    #[must_use]
    pub fn path_of(&self, key: CacheKey) -> PathBuf {
        self.dir.join(format!("{key:032x}.rgbnc"))
    }

    /// Reads the entry for `key`; `None` if absent, truncated, corrupt or foreign.
    #[must_use]
    pub fn get(&self, key: CacheKey) -> Option<CacheEntry> {
        let bytes = std::fs::read(self.path_of(key)).ok()?;
        let mut r = Reader(&bytes);
        if r.take(8)? != MAGIC || r.u32()? != FORMAT || r.take(16)? != PRODUCER {
            return None;
        }
        let k = u128::from_le_bytes(r.take(16)?.try_into().ok()?);
        let len = u64::from_le_bytes(r.take(8)?.try_into().ok()?) as usize;
        let sum = u64::from_le_bytes(r.take(8)?.try_into().ok()?);
        if k != key || r.0.len() != len || xxhash_rust::xxh3::xxh3_64(r.0) != sum {
            return None;
        }
        decode(r.0)
    }

    /// Stores `entry` under `key` (temporary file + rename). Failures are reported to the
    /// caller, who may ignore them: the cache is an optimisation.
    pub fn put(&self, key: CacheKey, entry: &CacheEntry) -> std::io::Result<()> {
        self.put_as(key, entry, &PRODUCER)
    }

    fn put_as(
        &self,
        key: CacheKey,
        entry: &CacheEntry,
        producer: &[u8; 16],
    ) -> std::io::Result<()> {
        let payload = encode(entry);
        let mut out = Vec::with_capacity(HEADER + payload.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT.to_le_bytes());
        out.extend_from_slice(producer);
        out.extend_from_slice(&key.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&xxhash_rust::xxh3::xxh3_64(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        let _writing = crate::raster::io::temp::WriteGuard::begin();
        let tmp = crate::raster::io::temp::temp_path(&self.dir, &format!("{key:032x}"));
        let r = std::fs::write(&tmp, &out).and_then(|()| std::fs::rename(&tmp, self.path_of(key)));
        if r.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_corruption_ignored() {
        let dir = tempfile::tempdir().unwrap();
        let c = DiskCache::new(dir.path()).unwrap();
        let mut img = RgbnImage::flat(3, 2, [0.1, 0.2, 0.3]);
        img.set_mask(Some(vec![1.0, 0.5, 0.0, 1.0, 1.0, 1.0]))
            .unwrap();
        let e = CacheEntry {
            values: vec![
                Value::Rgbn(img),
                Value::Scalar(Arc::new(Plane::filled(2, 2, -1.5))),
                Value::Picture(Arc::new(Picture {
                    width: 1,
                    height: 1,
                    rgba: vec![1, 2, 3, 4],
                })),
                Value::Number(0.25),
            ],
            curl: Some(1e-3),
            fraction: Some(0.25),
            skipped: 0,
        };
        c.put(7, &e).unwrap();
        assert_eq!(c.get(7), Some(e.clone()));
        assert_eq!(c.get(8), None);
        // Truncated and bit-flipped files are ignored.
        let p = c.path_of(7);
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 3]).unwrap();
        assert_eq!(c.get(7), None);
        let mut flipped = bytes.clone();
        let last = flipped.len() - 20;
        flipped[last] ^= 0x40;
        std::fs::write(&p, &flipped).unwrap();
        assert_eq!(c.get(7), None);
        std::fs::write(&p, b"garbage").unwrap();
        assert_eq!(c.get(7), None);
        // An entry another version of the crate wrote is not served, though intact.
        c.put_as(7, &e, &producer("rgbn 0.0.9")).unwrap();
        assert_eq!(c.get(7), None);
        c.put(7, &e).unwrap();
        assert_eq!(c.get(7), Some(e));
    }
}
