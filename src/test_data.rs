//! Real third-party test data for tests (never committed): the one place every real-data test,
//! unit or integration, finds its files. Not part of the library's API.
//!
//! The data lives in `$RGBN_DATA`, else in `../shared/data` beside the checkout. When it is
//! absent a test skips with a `SKIPPED …` line on stderr — unless `RGBN_REQUIRE_DATA=1` (set by
//! CI), which turns the skip into a failure, so a run that should have exercised real data
//! cannot pass silently without it.

use std::path::{Path, PathBuf};

/// The data folder: `$RGBN_DATA`, else `../shared/data` beside the checkout.
#[must_use]
pub fn root() -> PathBuf {
    std::env::var_os("RGBN_DATA").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
        PathBuf::from,
    )
}

/// Whether a missing data set fails the test (`RGBN_REQUIRE_DATA=1`).
#[must_use]
pub fn required() -> bool {
    std::env::var_os("RGBN_REQUIRE_DATA").is_some_and(|v| v == "1")
}

/// `sub` (a folder or file) under the data folder, or `None` with a `SKIPPED` note when it is
/// absent.
///
/// # Panics
/// When the data is absent and `RGBN_REQUIRE_DATA=1`: the test fails instead of skipping.
#[must_use]
pub fn real_data(sub: &str) -> Option<PathBuf> {
    match find(&root(), sub, required()) {
        Ok(found) => found,
        Err(message) => panic!("{message}"),
    }
}

/// `Ok(Some(path))` if `root/sub` exists; else `Ok(None)` after a `SKIPPED` note, or `Err` when
/// the data is required.
fn find(root: &Path, sub: &str, required: bool) -> Result<Option<PathBuf>, String> {
    let p = root.join(sub);
    if p.exists() {
        return Ok(Some(p));
    }
    let what = format!("real data not found: {} (set RGBN_DATA)", p.display());
    if required {
        return Err(format!("RGBN_REQUIRE_DATA=1 and {what}"));
    }
    eprintln!("SKIPPED: {what}");
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::find;

    #[test]
    fn absent_data_skips_or_fails_when_required() {
        let d = tempfile::tempdir().unwrap();
        std::fs::create_dir(d.path().join("set")).unwrap();
        assert_eq!(find(d.path(), "set", true), Ok(Some(d.path().join("set"))));
        assert_eq!(find(d.path(), "absent", false), Ok(None));
        let e = find(d.path(), "absent", true).unwrap_err();
        assert!(
            e.contains("RGBN_REQUIRE_DATA=1") && e.contains("absent"),
            "{e}"
        );
    }
}
