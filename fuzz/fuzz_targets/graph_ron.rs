//! RON graph text → parse, migrate, validate (`LoadedGraph::from_text`) and flatten into an
//! evaluation plan (`Plan::new`). Never evaluates: a valid graph may legitimately ask for huge
//! images.
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use rgbn::eval::Plan;
use rgbn::graph::LoadedGraph;
use std::collections::BTreeMap;

fuzz_target!(|data: &[u8]| {
    common::init();
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Relative paths (subgraphs, loads) resolve against an empty scratch folder.
    let base = common::scratch(b"", "none")
        .parent()
        .expect("scratch folder")
        .to_path_buf();
    if let Ok(lg) = LoadedGraph::from_text(text, "fuzz.ron", base.clone()) {
        let _ = lg.to_text();
        let _ = Plan::new(&lg, &BTreeMap::new(), &base);
    }
});
