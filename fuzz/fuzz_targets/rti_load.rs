//! HSH `.rti` bytes → `raster::io::load` (which reads the HSH file and finds each pixel's maximum), with repair and
//! validation.
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use rgbn::raster::io::{load, InputSpec, LoadOptions};

fuzz_target!(|data: &[u8]| {
    common::init();
    let p = common::scratch(data, "rti");
    let spec = InputSpec {
        rgbn: Some(p),
        ..InputSpec::default()
    };
    let _ = load(&spec, &LoadOptions::default());
});
