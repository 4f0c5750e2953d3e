//! PNG / TIFF bytes → `raster::io::load` as a normal map (`--normal`), then as a mask. The
//! extension follows the data's magic (`II`/`MM` → TIFF, else PNG), as a user's file would.
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use rgbn::raster::io::{load, load_mask, InputSpec, LoadOptions, NormalConvention};

fuzz_target!(|data: &[u8]| {
    common::init();
    let ext = if data.starts_with(b"II") || data.starts_with(b"MM") {
        "tif"
    } else {
        "png"
    };
    let p = common::scratch(data, ext);
    let _ = load_mask(&p);
    let spec = InputSpec {
        normal: Some(p),
        ..InputSpec::default()
    };
    let opts = LoadOptions {
        convention: if data.len() % 2 == 0 {
            NormalConvention::OpenGl
        } else {
            NormalConvention::DirectX
        },
        ..LoadOptions::default()
    };
    let _ = load(&spec, &opts);
});
