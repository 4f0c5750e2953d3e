//! Shared set-up of the fuzz targets: a small pixel limit (so a forged header cannot make a
//! target allocate gigabytes: the loaders refuse over `RGBN_MAX_PIXELS` before allocating) and a
//! per-process scratch file, since the public loaders take paths.

use std::path::PathBuf;
use std::sync::Once;

/// Pixel limit while fuzzing (1 Mpx: big enough for every seed, small enough for libFuzzer's
/// RSS limit).
const FUZZ_MAX_PIXELS: &str = "1048576";

pub fn init() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // Single-threaded at this point (called first thing in the target).
        std::env::set_var("RGBN_MAX_PIXELS", FUZZ_MAX_PIXELS);
    });
}

/// Writes `data` to this process's scratch file `rgbn-fuzz-<pid>.<ext>` and returns its path.
pub fn scratch(data: &[u8], ext: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rgbn-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let p = dir.join(format!("input.{ext}"));
    std::fs::write(&p, data).expect("scratch file");
    p
}
