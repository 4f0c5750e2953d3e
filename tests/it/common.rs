//! Shared helpers of the integration tests.

#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

/// The third-party test data (`$RGBN_DATA`, else `../shared/data` beside the checkout), or
/// `None` with a note on stderr so a skipped test says so.
pub fn data_dir(test: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("RGBN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "SKIPPED {test}: test data not found at {} (set RGBN_DATA)",
            dir.display()
        );
        None
    }
}

/// Runs the `rgbn` binary.
pub fn rgbn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .args(args)
        .output()
        .expect("the rgbn binary runs")
}

/// Stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Stdout as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}
