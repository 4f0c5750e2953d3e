//! The green-convention rule ([`rgbn::raster::integrate::green_convention`]) on published
//! normal maps whose convention is known: the manifest `tests/data/green_convention_maps.tsv`
//! (sources pinned by repository and commit), the maps fetched by
//! `examples/fetch_green_maps.sh` (third-party data, never committed).
//!
//! `cargo run --release --example green_maps -- [DIR]` (DIR: `$RGBN_GREEN_MAPS`, else
//! `target/green-maps`). Prints one row per map — expected, verdict, evidence, outcome — then
//! the counts. Each map is loaded as `rgbn info` loads it without `--dx` (OpenGL), so an
//! OpenGL verdict means "the file is OpenGL". Absent files are listed and skipped.

use rgbn::raster::integrate::{green_convention, GreenVerdict, Uncertainty};
use rgbn::raster::io::{load, InputSpec, LoadOptions};
use rgbn::test_data::green_maps::{dir, judge, manifest, Expected, Outcome};
use std::collections::BTreeMap;
use std::path::PathBuf;

fn main() {
    let dir = std::env::args_os().nth(1).map_or_else(dir, PathBuf::from);
    println!("maps from {}", dir.display());
    println!(
        "{:<44} {:<8} {:<9} {:<10} {:>8} {:>8} {:>9} {:>11}  outcome",
        "file", "kind", "expected", "verdict", "contrast", "z", "plaquettes", "islands gl/dx"
    );
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    let mut per_kind: BTreeMap<(String, &str), usize> = BTreeMap::new();
    let mut absent = 0;
    for e in manifest() {
        let path = dir.join(&e.file);
        if !path.exists() {
            println!("{:<44} absent", e.file);
            absent += 1;
            continue;
        }
        let spec = InputSpec {
            rgbn: Some(path.clone()),
            ..Default::default()
        };
        let img = match load(&spec, &LoadOptions::default()) {
            Ok(l) => l.image,
            Err(err) => {
                println!("{:<44} unreadable: {err}", e.file);
                continue;
            }
        };
        let g = green_convention(&img);
        let verdict = match g.verdict {
            GreenVerdict::OpenGl => "opengl",
            GreenVerdict::DirectX => "directx",
            GreenVerdict::Uncertain(Uncertainty::TooLittleRelief) => "unc:relief",
            GreenVerdict::Uncertain(Uncertainty::Balanced) => "unc:balance",
        };
        let expected = match e.expected {
            Expected::OpenGl => "opengl",
            Expected::DirectX => "directx",
            Expected::Disputed => "disputed",
        };
        let outcome = match judge(e.expected, g.verdict.reads_opengl()) {
            Outcome::Right => "right",
            Outcome::Uncertain => "uncertain",
            Outcome::Wrong => "WRONG",
            Outcome::Disputed => "disputed",
        };
        *counts.entry(outcome).or_default() += 1;
        *per_kind.entry((e.kind.clone(), expected)).or_default() += 1;
        let ev = &g.evidence;
        println!(
            "{:<44} {:<8} {:<9} {:<10} {:>+8.3} {:>8.1} {:>9} {:>5}/{:<5}  {outcome}",
            e.file,
            e.kind,
            expected,
            verdict,
            ev.contrast,
            ev.z,
            ev.relief_plaquettes,
            ev.islands_as_read,
            ev.islands_flipped
        );
    }
    println!();
    for ((kind, conv), n) in &per_kind {
        println!("{n:>3} {conv} {kind}");
    }
    let c = |k: &str| counts.get(k).copied().unwrap_or(0);
    println!(
        "scored: {} right, {} uncertain, {} wrong; {} disputed (not scored); {absent} absent",
        c("right"),
        c("uncertain"),
        c("WRONG"),
        c("disputed")
    );
    if absent > 0 {
        println!(
            "fetch the maps with: sh examples/fetch_green_maps.sh {}",
            dir.display()
        );
    }
}
