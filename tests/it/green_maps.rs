//! The green-convention rule on the published maps of `tests/data/green_convention_maps.tsv`
//! (docs/green-convention.md), when they have been fetched (`examples/fetch_green_maps.sh`):
//! no scored map reads the wrong way except the two the page explains (their islands read
//! DirectX almost throughout although glTF declares OpenGL), and those two still read DirectX.
//! The maps are third-party data that CI does not have, so without them the test says SKIPPED
//! and passes (whatever `RGBN_REQUIRE_DATA` says).

use rgbn::raster::integrate::green_convention;
use rgbn::raster::integrate::GreenVerdict;
use rgbn::raster::io::{load, InputSpec, LoadOptions};
use rgbn::test_data::green_maps::{dir, judge, manifest, Outcome};

/// Scored maps the rule reads the other way than declared (docs/green-convention.md, "Wrong").
const KNOWN_WRONG: [&str; 2] = [
    "AntiqueCamera_tripod_Normal.png",
    "GlassBrokenWindow_Normal.png",
];

#[test]
fn no_published_map_reads_the_wrong_way() {
    let dir = dir();
    let present: Vec<_> = manifest()
        .into_iter()
        .filter(|e| dir.join(&e.file).exists())
        .collect();
    if present.is_empty() {
        eprintln!(
            "SKIPPED: no green-convention maps in {} (sh examples/fetch_green_maps.sh; RGBN_GREEN_MAPS)",
            dir.display()
        );
        return;
    }
    let mut wrong = Vec::new();
    for e in &present {
        let spec = InputSpec {
            rgbn: Some(dir.join(&e.file)),
            ..Default::default()
        };
        let img = load(&spec, &LoadOptions::default())
            .unwrap_or_else(|err| panic!("{}: {err}", e.file))
            .image;
        let g = green_convention(&img);
        let known = KNOWN_WRONG.contains(&e.file.as_str());
        if known {
            assert_eq!(
                g.verdict,
                GreenVerdict::DirectX,
                "{}: {:?}",
                e.file,
                g.evidence
            );
        } else if judge(e.expected, g.verdict.reads_opengl()) == Outcome::Wrong {
            wrong.push(format!("{}: {:?} {:?}", e.file, g.verdict, g.evidence));
        }
    }
    eprintln!("{} maps checked, {} wrong", present.len(), wrong.len());
    assert!(wrong.is_empty(), "{wrong:#?}");
}
