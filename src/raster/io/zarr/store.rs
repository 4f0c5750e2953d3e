//! The storage under rgbn's Zarr arrays: zarrs' filesystem store for reading, with every chunk
//! read counted, and writes that are atomic (a temporary file beside the key, renamed over it),
//! so a chunk is either absent or whole, whoever reads it and whenever its writer is killed,
//! and a retried write of the same chunk leaves the same bytes.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use zarrs::filesystem::FilesystemStore;
use zarrs::storage::byte_range::ByteRangeIterator;
use zarrs::storage::{
    Bytes, MaybeBytesIterator, OffsetBytesIterator, ReadableStorageTraits, StorageError, StoreKey,
    StorePrefix, WritableStorageTraits,
};

/// Chunks (array values other than metadata) read by every store of this process.
static CHUNKS_READ: AtomicU64 = AtomicU64::new(0);

/// Chunk files (or shards) read by this process so far: every read of a value that is not
/// metadata (`zarr.json`, `.zarray`, `.zattrs`, `.zgroup`) through any store rgbn opened. The
/// region tests and `rgbn eval --stats` compare it with the chunks a region needs.
#[must_use]
pub fn chunks_read() -> u64 {
    CHUNKS_READ.load(Ordering::Relaxed)
}

/// Temporary files made by this process (their names must differ between the threads of one
/// process and between processes).
static TEMPS: AtomicU64 = AtomicU64::new(0);

/// Whether `key` names metadata rather than a chunk.
fn is_metadata(key: &StoreKey) -> bool {
    let name = key.as_str().rsplit('/').next().unwrap_or_default();
    matches!(
        name,
        "zarr.json" | ".zarray" | ".zattrs" | ".zgroup" | ".zmetadata"
    )
}

/// A folder holding a Zarr hierarchy (see the module docs).
#[derive(Debug)]
pub struct Store {
    fs: FilesystemStore,
    root: PathBuf,
    /// Chunks read through this store.
    reads: AtomicU64,
}

impl Store {
    /// The store in folder `root` (which must exist).
    pub fn open(root: &Path) -> Result<Self, String> {
        let fs = FilesystemStore::new(root).map_err(|e| e.to_string())?;
        Ok(Self {
            fs,
            root: root.to_path_buf(),
            reads: AtomicU64::new(0),
        })
    }

    /// Chunks read through this store so far.
    pub fn reads(&self) -> u64 {
        self.reads.load(Ordering::Relaxed)
    }

    /// The file of `key`.
    fn file(&self, key: &StoreKey) -> PathBuf {
        self.root.join(key.as_str())
    }
}

/// Writes `bytes` to `path` atomically: into a temporary file beside it (named after the
/// process and a counter, so concurrent writers never share one), then renamed over it. The
/// folders on the way are created.
pub(super) fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = dir.join(format!(
        ".{name}.rgbn-tmp-{}-{}",
        std::process::id(),
        TEMPS.fetch_add(1, Ordering::Relaxed)
    ));
    let r = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if r.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    r
}

impl ReadableStorageTraits for Store {
    fn get_partial_many<'a>(
        &'a self,
        key: &StoreKey,
        byte_ranges: ByteRangeIterator<'a>,
    ) -> Result<MaybeBytesIterator<'a>, StorageError> {
        if !is_metadata(key) {
            CHUNKS_READ.fetch_add(1, Ordering::Relaxed);
            self.reads.fetch_add(1, Ordering::Relaxed);
        }
        self.fs.get_partial_many(key, byte_ranges)
    }

    fn size_key(&self, key: &StoreKey) -> Result<Option<u64>, StorageError> {
        self.fs.size_key(key)
    }

    fn supports_get_partial(&self) -> bool {
        self.fs.supports_get_partial()
    }
}

impl WritableStorageTraits for Store {
    fn set(&self, key: &StoreKey, value: Bytes) -> Result<(), StorageError> {
        write_atomic(&self.file(key), &value).map_err(StorageError::from)
    }

    fn set_partial_many(
        &self,
        key: &StoreKey,
        _offset_values: OffsetBytesIterator,
    ) -> Result<(), StorageError> {
        Err(StorageError::Unsupported(format!(
            "partial writes (of {key}): rgbn writes whole chunks"
        )))
    }

    fn erase(&self, key: &StoreKey) -> Result<(), StorageError> {
        match std::fs::remove_file(self.file(key)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(()),
        }
    }

    fn erase_prefix(&self, prefix: &StorePrefix) -> Result<(), StorageError> {
        match std::fs::remove_dir_all(self.root.join(prefix.as_str())) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
            _ => Ok(()),
        }
    }

    fn supports_set_partial(&self) -> bool {
        false
    }
}
