//! Capture text files and command-line arguments (issue 15 (e)). The first byte picks the
//! parser, the rest is its text:
//! - light and intensity files (`capture::inputs::parse_rows3`: `x y z` rows, optional count);
//! - photo name lists (`capture::inputs::read_name_list`, from a file: UTF-8 check included);
//! - `--set NODE.PARAM=VALUE` arguments (one per line) applied to an example graph
//!   (`cli::apply_sets`: node lookup, parameter parsing by kind, re-validation), then planned;
//! - `--input NAME=PATH` arguments (`cli::parse_inputs`) bound to a graph with an RGBN input.
//!
//! Contract: no panic; errors are one line; accepted light rows are finite.
#![no_main]
#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use rgbn::eval::Plan;
use rgbn::graph::LoadedGraph;
use std::collections::BTreeMap;
use std::path::Path;

const GRAPHS: [&str; 4] = [
    include_str!("../../graphs/demo.ron"),
    include_str!("../../graphs/pen.ron"),
    include_str!("../../graphs/combine_rotation.ron"),
    include_str!("../../graphs/surface.ron"),
];
const INPUT_GRAPH: &str = include_str!("../../graphs/input_image.ron");

fn one_line(e: &dyn std::fmt::Display) {
    let msg = e.to_string();
    assert!(
        !msg.trim().is_empty() && !msg.contains('\n'),
        "unclear error {msg:?}"
    );
}

fuzz_target!(|data: &[u8]| {
    common::init();
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let dir = common::scratch(b"", "none")
        .parent()
        .expect("scratch folder")
        .to_path_buf();
    let text = String::from_utf8_lossy(rest);
    let args: Vec<String> = text.lines().map(str::to_string).collect();
    match which % 5 {
        0 => match rgbn::capture::inputs::parse_rows3(&text, Path::new("lights.txt")) {
            Ok(rows) => assert!(rows.iter().flatten().all(|v| v.is_finite()), "{rows:?}"),
            Err(e) => one_line(&e),
        },
        1 => {
            let p = common::scratch(rest, "txt");
            if let Err(e) = rgbn::capture::inputs::read_name_list(&p) {
                one_line(&e);
            }
        }
        2 | 3 => {
            let src = GRAPHS[usize::from(which / 5) % GRAPHS.len()];
            let mut lg = LoadedGraph::from_text(src, "example.ron", dir.clone())
                .expect("example graphs are valid");
            match rgbn::cli::apply_sets(&mut lg, &args) {
                Ok(()) => {
                    if let Err(e) = Plan::new(&lg, &BTreeMap::new(), &dir) {
                        one_line(&e);
                    }
                }
                Err(e) => one_line(&e),
            }
        }
        _ => {
            let lg = LoadedGraph::from_text(INPUT_GRAPH, "input_image.ron", dir.clone())
                .expect("example graph is valid");
            match rgbn::cli::parse_inputs(&args) {
                Ok(bind) => {
                    if let Err(e) = Plan::new(&lg, &bind, &dir) {
                        one_line(&e);
                    }
                }
                Err(e) => one_line(&e),
            }
        }
    }
});
