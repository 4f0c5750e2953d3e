//! `.lp` light-file bytes → `capture::lp::read_lp` (read, UTF-8 check, parse, photo-name
//! resolution).
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    common::init();
    let p = common::scratch(data, "lp");
    if let Ok(lp) = rgbn::capture::lp::read_lp(&p) {
        assert_eq!(lp.photos.len(), lp.directions.len());
        for d in &lp.directions {
            assert!(
                d.iter().all(|c| c.is_finite()),
                "non-finite direction {d:?}"
            );
        }
    }
});
