//! EXR bytes → `raster::io::load` as an RGBN EXR (colour + `N.*`), then as a normal pass
//! (`R,G,B` as normals), each with repair and validation.
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use rgbn::raster::io::{load, InputSpec, LoadOptions};

fuzz_target!(|data: &[u8]| {
    common::init();
    let p = common::scratch(data, "exr");
    let spec = InputSpec {
        rgbn: Some(p),
        ..InputSpec::default()
    };
    for rgb in [false, true] {
        let opts = LoadOptions {
            exr_rgb_is_normal: rgb,
            ..LoadOptions::default()
        };
        let _ = load(&spec, &opts);
    }
});
