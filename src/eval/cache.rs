//! The in-memory cache: node outputs by content key, evicted least-recently-used beyond a byte
//! budget.

use crate::nodes::Value;
use std::collections::HashMap;
use std::sync::Arc;

/// A 128-bit content key: hash of op id, op version, canonical params (floats by bits, input
/// files by the hash of their bytes) and the keys of the inputs.
pub type CacheKey = u128;

/// The outputs of one node evaluation, with what was measured on them.
#[derive(Clone, Debug, PartialEq)]
pub struct CacheEntry {
    /// Output values in port order.
    pub values: Vec<Value>,
    /// Relative RMS curl of the first RGBN output, when measured.
    pub curl: Option<f64>,
    /// Its non-integrable fraction F (`raster::integrate::non_integrable_fraction`), when
    /// measured.
    pub fraction: Option<f64>,
    /// Outputs left out (bit `k`: port `k`), for an operator with
    /// [`crate::nodes::OpSpec::lazy_outputs`] whose evaluation read only some: their values are
    /// placeholders, never handed on. 0 for a complete entry.
    pub skipped: u64,
}

impl CacheEntry {
    /// Whether the entry holds every output in `wanted` (bit `k`: port `k`).
    #[must_use]
    pub fn has(&self, wanted: u64) -> bool {
        self.skipped & wanted == 0
    }
    /// Bytes of pixel data held.
    #[must_use]
    pub fn byte_size(&self) -> usize {
        self.values.iter().map(Value::byte_size).sum()
    }
}

/// Byte-budgeted LRU map from [`CacheKey`] to [`CacheEntry`]. One entry may be stored under
/// several keys (a tile an edit did not change, under the old and the new content key), and
/// entries may share pixel planes (a pen's output keeps its input's colour planes): the bytes
/// are counted by shared block ([`Value::parts`]), each once, so [`MemCache::bytes`] is the
/// memory the cache really keeps alive.
#[derive(Debug)]
pub struct MemCache {
    map: HashMap<CacheKey, (Arc<CacheEntry>, u64)>,
    /// Keys by last use (the LRU order).
    order: std::collections::BTreeMap<u64, CacheKey>,
    /// References per shared block of pixel data (by address), with its bytes.
    refs: HashMap<usize, (usize, usize)>,
    bytes: usize,
    budget: usize,
    tick: u64,
}

impl MemCache {
    /// An empty cache holding at most `budget` bytes.
    #[must_use]
    pub fn new(budget: usize) -> Self {
        Self {
            map: HashMap::new(),
            order: std::collections::BTreeMap::new(),
            refs: HashMap::new(),
            bytes: 0,
            budget,
            tick: 0,
        }
    }
    /// The entry for `key`, marking it recently used.
    pub fn get(&mut self, key: CacheKey) -> Option<Arc<CacheEntry>> {
        self.tick += 1;
        let t = self.tick;
        let (e, used) = self.map.get_mut(&key)?;
        self.order.remove(used);
        *used = t;
        self.order.insert(t, key);
        Some(e.clone())
    }
    /// Stores `entry`, evicting least-recently-used entries beyond the budget. An entry larger
    /// than the whole budget is not stored.
    pub fn insert(&mut self, key: CacheKey, entry: Arc<CacheEntry>) {
        let size = entry.byte_size();
        if size > self.budget {
            return;
        }
        self.tick += 1;
        self.add_ref(&entry);
        self.order.insert(self.tick, key);
        if let Some((old, used)) = self.map.insert(key, (entry, self.tick)) {
            self.order.remove(&used);
            self.drop_ref(&old);
        }
        while self.bytes > self.budget {
            let Some((_, k)) = self.order.pop_first() else {
                break;
            };
            if let Some((e, _)) = self.map.remove(&k) {
                self.drop_ref(&e);
            }
        }
    }
    fn add_ref(&mut self, e: &Arc<CacheEntry>) {
        for v in &e.values {
            for (addr, bytes) in v.parts() {
                let n = self.refs.entry(addr).or_insert((0, bytes));
                if n.0 == 0 {
                    self.bytes += bytes;
                }
                n.0 += 1;
            }
        }
    }
    fn drop_ref(&mut self, e: &Arc<CacheEntry>) {
        for v in &e.values {
            for (addr, _) in v.parts() {
                if let Some(n) = self.refs.get_mut(&addr) {
                    n.0 -= 1;
                    if n.0 == 0 {
                        self.bytes -= n.1;
                        self.refs.remove(&addr);
                    }
                }
            }
        }
    }
    /// Whether `key` is stored (without marking it used).
    #[must_use]
    pub fn contains(&self, key: CacheKey) -> bool {
        self.map.contains_key(&key)
    }
    /// Bytes of `values` that the cache does not keep alive itself (blocks shared among
    /// `values` counted once): what holding them costs on top of [`MemCache::bytes`].
    #[must_use]
    pub fn outside<'a>(&self, values: impl IntoIterator<Item = &'a Value>) -> usize {
        let mut seen = std::collections::HashSet::new();
        values
            .into_iter()
            .flat_map(Value::parts)
            .filter(|(a, _)| !self.refs.contains_key(a) && seen.insert(*a))
            .map(|(_, b)| b)
            .sum()
    }
    /// The byte budget.
    #[must_use]
    pub fn budget(&self) -> usize {
        self.budget
    }
    /// Number of entries.
    #[must_use]
    pub fn len(&self) -> usize {
        self.map.len()
    }
    /// True when empty.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }
    /// Bytes held.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.bytes
    }
    /// Drops everything.
    pub fn clear(&mut self) {
        self.map.clear();
        self.order.clear();
        self.refs.clear();
        self.bytes = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(n: f64) -> Arc<CacheEntry> {
        Arc::new(CacheEntry {
            values: vec![Value::Number(n)],
            curl: None,
            fraction: None,
            skipped: 0,
        })
    }

    #[test]
    fn lru_evicts_oldest_within_budget() {
        let mut c = MemCache::new(16); // two numbers of 8 bytes
        c.insert(1, entry(1.0));
        c.insert(2, entry(2.0));
        assert!(c.get(1).is_some()); // 1 is now newer than 2
        c.insert(3, entry(3.0));
        assert_eq!(c.len(), 2);
        assert!(c.get(2).is_none());
        assert!(c.get(1).is_some() && c.get(3).is_some());
        assert_eq!(c.bytes(), 16);
    }

    #[test]
    fn an_entry_under_several_keys_counts_once_until_its_last_key_goes() {
        let mut c = MemCache::new(24); // three numbers
        let e = entry(1.0);
        c.insert(1, e.clone());
        c.insert(2, e.clone());
        assert_eq!(c.bytes(), 8);
        c.insert(3, entry(3.0));
        c.insert(4, entry(4.0));
        assert_eq!((c.len(), c.bytes()), (4, 24));
        // Over budget: the oldest key (1) goes, its entry stays under key 2 (still counted);
        // then key 2 goes too and the bytes drop.
        c.insert(5, entry(5.0));
        assert!(c.get(1).is_none());
        assert_eq!(c.bytes(), 24);
        assert!(c.get(2).is_none());
        assert_eq!(c.len(), 3);
    }

    fn rgbn(values: Vec<Value>) -> Arc<CacheEntry> {
        Arc::new(CacheEntry {
            values,
            curl: None,
            fraction: None,
            skipped: 0,
        })
    }

    #[test]
    fn planes_shared_between_entries_count_once() {
        // 4×4 pixels: three f32 planes of 16 values each, 192 bytes of colour, 192 of normals.
        let set = 3 * 16 * 4;
        let a = crate::raster::RgbnImage::flat(4, 4, [0.5; 3]);
        let b = a.with_normals(a.normal().clone()).unwrap(); // shares a's colour only
        let mut c = MemCache::new(1 << 20);
        c.insert(1, rgbn(vec![Value::Rgbn(a.clone())]));
        assert_eq!(c.bytes(), 2 * set);
        c.insert(2, rgbn(vec![Value::Rgbn(b.clone())]));
        assert_eq!(c.bytes(), 3 * set);
        // Held outside: a's planes are in the cache; a fresh image is not; b twice counts once.
        let fresh = crate::raster::RgbnImage::flat(4, 4, [0.5; 3]);
        let (va, vb, vf) = (Value::Rgbn(a), Value::Rgbn(b), Value::Rgbn(fresh));
        assert_eq!(c.outside([&va, &vb, &vb]), 0);
        assert_eq!(c.outside([&vf, &vf, &va]), 2 * set);
        // Key 1 goes: the shared colour stays counted under key 2.
        c.insert(3, entry(1.0));
        c.budget = 2 * set + 16;
        c.insert(4, entry(2.0));
        assert!(!c.contains(1) && c.contains(2));
        assert_eq!(c.bytes(), 2 * set + 16);
    }
}
