//! The in-memory cache: node outputs by content key, evicted least-recently-used beyond a byte
//! budget.

use crate::ops::Value;
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
}

impl CacheEntry {
    /// Bytes of pixel data held.
    #[must_use]
    pub fn byte_size(&self) -> usize {
        self.values.iter().map(Value::byte_size).sum()
    }
}

/// Byte-budgeted LRU map from [`CacheKey`] to [`CacheEntry`].
#[derive(Debug)]
pub struct MemCache {
    map: HashMap<CacheKey, (Arc<CacheEntry>, u64)>,
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
            bytes: 0,
            budget,
            tick: 0,
        }
    }
    /// The entry for `key`, marking it recently used.
    pub fn get(&mut self, key: CacheKey) -> Option<Arc<CacheEntry>> {
        self.tick += 1;
        let t = self.tick;
        self.map.get_mut(&key).map(|(e, used)| {
            *used = t;
            e.clone()
        })
    }
    /// Stores `entry`, evicting least-recently-used entries beyond the budget. An entry larger
    /// than the whole budget is not stored.
    pub fn insert(&mut self, key: CacheKey, entry: Arc<CacheEntry>) {
        let size = entry.byte_size();
        if size > self.budget {
            return;
        }
        self.tick += 1;
        if let Some((old, _)) = self.map.insert(key, (entry, self.tick)) {
            self.bytes -= old.byte_size();
        }
        self.bytes += size;
        while self.bytes > self.budget {
            let Some((&k, _)) = self.map.iter().min_by_key(|(_, (_, used))| *used) else {
                break;
            };
            if let Some((e, _)) = self.map.remove(&k) {
                self.bytes -= e.byte_size();
            }
        }
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
}
