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
    env_or_checkout("RGBN_DATA", "../shared/data")
}

/// The folder named by environment variable `var`, else `relative` to the checkout.
fn env_or_checkout(var: &str, relative: &str) -> PathBuf {
    std::env::var_os(var).map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join(relative),
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

/// Published normal maps whose green convention is known (`tests/data/green_convention_maps.tsv`,
/// `docs/green-convention.md`): the manifest, where the fetched files are, and how a verdict is
/// judged against it. The maps are third-party data and never committed.
pub mod green_maps {
    use std::path::PathBuf;

    /// The manifest's text.
    pub const MANIFEST: &str = include_str!("../tests/data/green_convention_maps.tsv");

    /// What a map is known to be.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Expected {
        OpenGl,
        DirectX,
        /// Declared OpenGL by its source, but its authoring pipeline is documented to have
        /// passed DirectX maps through (the reason column says which); not scored.
        Disputed,
    }

    /// One line of the manifest.
    #[derive(Clone, Debug, PartialEq, Eq)]
    pub struct Entry {
        /// Local file name under [`dir`].
        pub file: String,
        pub expected: Expected,
        /// `tileable` or `atlas`.
        pub kind: String,
        pub repository: String,
        pub commit: String,
        pub path: String,
        pub reason: String,
    }

    /// How a verdict compares with what is known.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Outcome {
        Right,
        Uncertain,
        Wrong,
        /// The map's expectation is disputed: not scored.
        Disputed,
    }

    /// The manifest's entries (comment lines start with `#`).
    ///
    /// # Panics
    /// On a malformed line (the manifest is part of the repository).
    #[must_use]
    pub fn manifest() -> Vec<Entry> {
        MANIFEST
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .map(|l| {
                let c: Vec<&str> = l.split('\t').collect();
                assert_eq!(c.len(), 7, "manifest line {l:?}");
                let expected = match c[1] {
                    "opengl" => Expected::OpenGl,
                    "directx" => Expected::DirectX,
                    "disputed" => Expected::Disputed,
                    other => panic!("manifest convention {other:?}"),
                };
                Entry {
                    file: c[0].into(),
                    expected,
                    kind: c[2].into(),
                    repository: c[3].into(),
                    commit: c[4].into(),
                    path: c[5].into(),
                    reason: c[6].into(),
                }
            })
            .collect()
    }

    /// Where the fetched maps are: `$RGBN_GREEN_MAPS`, else `target/green-maps` in the checkout
    /// (`examples/fetch_green_maps.sh` fills it).
    #[must_use]
    pub fn dir() -> PathBuf {
        super::env_or_checkout("RGBN_GREEN_MAPS", "target/green-maps")
    }

    /// A verdict on a map loaded as OpenGL (without `--dx`) against its expectation:
    /// `opengl` is `Some(true)` for OpenGL, `Some(false)` for DirectX, `None` for uncertain
    /// (`GreenVerdict::reads_opengl`; this module sits below `raster` and does not name it).
    #[must_use]
    pub fn judge(expected: Expected, opengl: Option<bool>) -> Outcome {
        match (expected, opengl) {
            (Expected::Disputed, _) => Outcome::Disputed,
            (_, None) => Outcome::Uncertain,
            (Expected::OpenGl, Some(true)) | (Expected::DirectX, Some(false)) => Outcome::Right,
            _ => Outcome::Wrong,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::find;

    #[test]
    fn the_green_map_manifest_parses_and_names_pinned_sources() {
        use super::green_maps::{manifest, Expected};
        let m = manifest();
        assert!(m.len() >= 20);
        for e in &m {
            assert_eq!(e.commit.len(), 40, "{e:?}");
            assert!(e.repository.contains('/') && !e.path.is_empty() && !e.reason.is_empty());
        }
        let count = |x: Expected| m.iter().filter(|e| e.expected == x).count();
        assert!(count(Expected::OpenGl) > 0 && count(Expected::DirectX) > 0);
        let mut files: Vec<&str> = m.iter().map(|e| e.file.as_str()).collect();
        files.sort_unstable();
        files.dedup();
        assert_eq!(files.len(), m.len(), "local file names are unique");
    }

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
