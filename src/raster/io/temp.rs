//! Temporary names beside a target, and the cleaning of those a killed process left behind.
//!
//! Every atomic write in rgbn (image and graph files through [`write_atomic`](super::write_atomic),
//! disk-cache entries, published folders) builds its result under a name
//! `.STEM.PID.SEQ.tmp` in the target's folder and renames it into place. A process killed
//! with `kill -9` (or a power cut) leaves that temporary behind, never a torn target. The next
//! write of the same target — or, for the disk cache, the next process opening the cache —
//! removes temporaries whose process no longer runs ([`clean_stale`]); those of a live process
//! (another rgbn writing the same folder right now) are left alone.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Atomic writes under way in this process.
static IN_FLIGHT: AtomicUsize = AtomicUsize::new(0);

/// Marks an atomic write under way until dropped (see [`writes_in_flight`]).
#[must_use = "the write counts as under way only while the guard lives"]
pub struct WriteGuard(());

impl WriteGuard {
    /// Starts counting one write.
    pub fn begin() -> Self {
        IN_FLIGHT.fetch_add(1, Ordering::SeqCst);
        Self(())
    }
}

impl Drop for WriteGuard {
    fn drop(&mut self) {
        IN_FLIGHT.fetch_sub(1, Ordering::SeqCst);
    }
}

/// How many atomic writes are under way in this process: an interrupted command waits for
/// zero before it exits, so it leaves no temporary file.
#[must_use]
pub fn writes_in_flight() -> usize {
    IN_FLIGHT.load(Ordering::SeqCst)
}

/// A fresh temporary path for `stem` in `dir`: `.STEM.PID.SEQ.tmp`, unique within this process.
#[must_use]
pub fn temp_path(dir: &Path, stem: &str) -> PathBuf {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    dir.join(format!(
        ".{stem}.{}.{}.tmp",
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ))
}

/// The stem and process id of a temporary name made by [`temp_path`], if `name` is one.
#[must_use]
pub fn parse(name: &str) -> Option<(&str, u32)> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (rest, seq) = rest.rsplit_once('.')?;
    let (stem, pid) = rest.rsplit_once('.')?;
    seq.parse::<u64>().ok()?;
    Some((stem, pid.parse().ok()?))
}

/// Whether process `pid` runs (unknown platforms: assume it does, so nothing is removed).
#[must_use]
pub fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    #[cfg(unix)]
    {
        let Ok(p) = libc::pid_t::try_from(pid) else {
            return false;
        };
        // SAFETY: signal 0 only checks that the process exists (and that we may signal it).
        let r = unsafe { libc::kill(p, 0) };
        r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
    #[cfg(not(unix))]
    {
        true
    }
}

/// Removes the temporaries in `dir` left by processes that no longer run: those of `stem`
/// only, or all of them when `stem` is `None`. Files and folders (a published folder under
/// construction) alike; errors are ignored (the next write tries again). Returns how many were
/// removed.
pub fn clean_stale(dir: &Path, stem: Option<&str>) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        let Some((s, pid)) = name.to_str().and_then(parse) else {
            continue;
        };
        if stem.is_some_and(|want| want != s) || alive(pid) {
            continue;
        }
        let path = e.path();
        let ok = if e.file_type().is_ok_and(|t| t.is_dir()) {
            std::fs::remove_dir_all(&path).is_ok()
        } else {
            std::fs::remove_file(&path).is_ok()
        };
        removed += usize::from(ok);
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_other_files_are_not_temporaries() {
        let p = temp_path(Path::new("/x"), "a.b.png");
        let name = p.file_name().unwrap().to_str().unwrap();
        assert_eq!(parse(name), Some(("a.b.png", std::process::id())));
        for other in [
            ".a.png.tmp",
            "a.png",
            ".a.png.12.x.tmp",
            ".a.png.x.3.tmp",
            ".autosave.ron",
        ] {
            assert_eq!(parse(other), None, "{other}");
        }
    }

    #[test]
    fn only_dead_processes_temporaries_are_removed() {
        let d = tempfile::tempdir().unwrap();
        // A process id that cannot run: above Linux's pid_max limit (2^22).
        let dead = (1u32 << 22) + 7;
        let live = std::process::id();
        for (name, _) in [
            (format!(".out.png.{dead}.0.tmp"), ()),
            (format!(".out.png.{live}.0.tmp"), ()),
            (format!(".other.png.{dead}.1.tmp"), ()),
            ("out.png".to_string(), ()),
        ] {
            std::fs::write(d.path().join(name), b"x").unwrap();
        }
        std::fs::create_dir(d.path().join(format!(".site.{dead}.2.tmp"))).unwrap();
        assert_eq!(clean_stale(d.path(), Some("out.png")), 1);
        let left = |n: &str| d.path().join(n).exists();
        assert!(!left(&format!(".out.png.{dead}.0.tmp")));
        assert!(
            left(&format!(".out.png.{live}.0.tmp")),
            "a live writer's file is kept"
        );
        assert!(
            left(&format!(".other.png.{dead}.1.tmp")),
            "another target's is kept"
        );
        assert_eq!(
            clean_stale(d.path(), None),
            2,
            "the rest of the dead ones, folder included"
        );
        assert!(left("out.png") && left(&format!(".out.png.{live}.0.tmp")));
    }
}
