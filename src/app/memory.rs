//! The editor's memory budget, and what it holds against it (issue 36 item 6).
//!
//! One budget bounds the images the editor keeps: by default a quarter of the physical memory
//! (at least 1 GiB; [`DEFAULT_SHARE`]), set with `rgbn edit --memory SIZE` or the
//! `RGBN_EDITOR_MEMORY` variable (`2G`, `1536M`…). It is shared so:
//!
//! - the **recycle pool** (freed image-sized blocks kept for reuse, [`crate::recycle`]) gets an
//!   eighth, at most 512 MiB;
//! - the **value cache** gets the rest: node values and the tiles of viewports, evicted
//!   least-recently-used ([`crate::eval::MemCache`], which counts a plane shared by several
//!   values once);
//! - beyond it the editor holds only the values it shows — the viewed output, the input of a
//!   before/after split, a stamp's source, an output being exported — usually the cache's own
//!   (the refresh keeps no other whole value: [`super::refresh`]), and the thumbnails (96² each).
//!
//! The status bar shows the sum ([`MemoryUse`]) against the budget, and the process's resident
//! memory beside it. While a node runs, its output and working memory come on top (a 2048²
//! RGBN image is 117 MB); the window, fonts and textures are not counted (tens of MB).

use crate::eval::memory::{parse_bytes, physical_memory};
use std::sync::atomic::{AtomicU64, Ordering};

/// The default budget's share of the physical memory.
pub const DEFAULT_SHARE: u64 = 4;

/// The variable that sets the budget.
pub const ENV: &str = "RGBN_EDITOR_MEMORY";

/// Set by `rgbn edit --memory` (0: not set).
static SET: AtomicU64 = AtomicU64::new(0);

/// Sets the budget for editors started from now on (`rgbn edit --memory`).
pub fn set_budget(bytes: u64) {
    SET.store(bytes, Ordering::Relaxed);
}

/// Parses a budget (`--memory`, `RGBN_EDITOR_MEMORY`): a byte count with an optional unit, at
/// least 64 MiB.
///
/// # Errors
/// A one-line message.
pub fn parse_budget(s: &str) -> Result<u64, String> {
    let b = parse_bytes(s)?;
    if b < 64 << 20 {
        return Err(format!(
            "{s:?}: the editor needs a memory budget of at least 64M"
        ));
    }
    Ok(b)
}

/// The budget: `--memory`, else `RGBN_EDITOR_MEMORY`, else a quarter of the physical memory
/// (at least [`crate::eval::DEFAULT_BUDGET`]).
///
/// # Errors
/// `RGBN_EDITOR_MEMORY` does not parse.
pub fn budget() -> Result<u64, String> {
    let set = SET.load(Ordering::Relaxed);
    if set > 0 {
        return Ok(set);
    }
    if let Ok(s) = std::env::var(ENV) {
        return parse_budget(&s).map_err(|e| format!("{ENV}: {e}"));
    }
    Ok(physical_memory()
        .map_or(0, |m| m / DEFAULT_SHARE)
        .max(crate::eval::DEFAULT_BUDGET as u64))
}

/// The recycle pool's share of `budget`: an eighth, at most [`crate::recycle::KEEP_BYTES`].
#[must_use]
pub fn pool_share(budget: u64) -> usize {
    usize::try_from(budget / 8)
        .unwrap_or(usize::MAX)
        .min(crate::recycle::KEEP_BYTES)
}

/// The value cache's share of `budget`: the rest.
#[must_use]
pub fn cache_share(budget: u64) -> usize {
    usize::try_from(budget)
        .unwrap_or(usize::MAX)
        .saturating_sub(pool_share(budget))
}

/// What the editor holds against its budget, in bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryUse {
    /// The budget.
    pub budget: u64,
    /// Values in the cache (node values and viewport tiles).
    pub cache: usize,
    /// Entries in the cache.
    pub cache_values: usize,
    /// Values shown or kept that the cache does not hold.
    pub shown: usize,
    /// Thumbnails.
    pub thumbs: usize,
    /// Freed blocks kept for reuse.
    pub pool: usize,
}

impl MemoryUse {
    /// Everything counted.
    #[must_use]
    pub fn total(&self) -> u64 {
        (self.cache + self.shown + self.thumbs + self.pool) as u64
    }
}

/// The process's resident memory now (Linux `VmRSS`), if known.
#[must_use]
pub fn resident() -> Option<u64> {
    proc_status("VmRSS:")
}

/// The process's peak resident memory so far (Linux `VmHWM`), if known.
#[must_use]
pub fn peak_resident() -> Option<u64> {
    proc_status("VmHWM:")
}

fn proc_status(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Hands the allocator's free memory back to the system (glibc keeps freed small blocks in
/// its arenas: tiles, rows), so that the resident memory follows what the editor holds. The
/// worker calls it after each whole evaluation.
pub fn trim() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free memory of the allocator's arenas to the system.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// The status bar's memory figure: everything held against the budget, what it is made of
/// on hover, and the process's resident memory beside it.
pub fn status_ui(ui: &mut egui::Ui, m: &MemoryUse) {
    let gib = |b: u64| b as f64 / f64::from(1u32 << 30);
    let rss = resident();
    let text = format!(
        "memory {:.2} of {:.2} GiB{}",
        gib(m.total()),
        gib(m.budget),
        rss.map_or_else(String::new, |r| format!(" · process {:.2} GiB", gib(r)))
    );
    ui.label(text).on_hover_text(format!(
        "Held against the editor's memory budget (rgbn edit --memory, {ENV}): cache {} ({} values and viewport tiles), shown outside the cache {}, thumbnails {}, freed blocks kept for reuse {}. The process's resident memory also holds the window, its textures and the node running.",
        crate::eval::memory::human(m.cache as u64),
        m.cache_values,
        crate::eval::memory::human(m.shown as u64),
        crate::eval::memory::human(m.thumbs as u64),
        crate::eval::memory::human(m.pool as u64),
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_is_shared_between_the_pool_and_the_cache() {
        let g = 1u64 << 30;
        assert_eq!(pool_share(g), 128 << 20);
        assert_eq!(cache_share(g), (1 << 30) - (128 << 20));
        // The pool's share stops at 512 MiB.
        assert_eq!(pool_share(16 * g), 512 << 20);
        assert_eq!(cache_share(16 * g) as u64, 16 * g - (512 << 20));
        assert_eq!(parse_budget("2G"), Ok(2 << 30));
        assert!(parse_budget("10M").unwrap_err().contains("at least 64M"));
        assert!(parse_budget("lots").is_err());
    }
}
