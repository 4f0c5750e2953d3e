//! The gallery of the paper's figures (`docs/gallery.md`, `rgbn::gallery`): the page's numbers
//! and pictures are recomputed from the figure graphs under `graphs/paper/` and must agree with
//! them; and the F values say of each edit what the paper proves, or what we measure where the
//! paper proves nothing.

use crate::common::*;
use rgbn::gallery::{self, Gallery, FIGURES};
use std::sync::OnceLock;

/// The gallery, computed once for the tests of this module.
fn computed() -> &'static Gallery {
    static G: OnceLock<Gallery> = OnceLock::new();
    G.get_or_init(|| gallery::generate(&root()).unwrap_or_else(|e| panic!("{e}")))
}

/// F (before, after) of row `row` of figure graph `stem`.
fn f(stem: &str, row: usize) -> (f64, f64) {
    let (_, before, after) = computed().rows[stem][row];
    (before, after)
}

/// The page is true: every table number within half its last printed digit of the recomputed
/// one (values at the rounding floor, under 1e-4, within 5 %: their last digits follow the
/// order of parallel sums), every picture within a level or two of the recomputed one, nothing missing or stale.
/// Regenerate with `cargo run --release --example gallery`.
#[test]
fn the_gallery_page_and_pictures_agree_with_the_figure_graphs() {
    let problems = gallery::check(&root(), computed()).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        problems.is_empty(),
        "docs/gallery.md disagrees with the figure graphs (regenerate with `cargo run --release \
         --example gallery`):\n{}",
        problems.join("\n")
    );
}

/// Every figure of the paper that shows an edit (1, 2, 4, 5, 6, 9, 10, 11, 12) has one graph
/// and a gallery entry, and every graph under `graphs/paper/` is one of them.
#[test]
fn every_figure_that_shows_an_edit_has_a_graph() {
    let numbers: Vec<u32> = FIGURES.iter().map(|f| f.number).collect();
    assert_eq!(numbers, [1, 2, 4, 5, 6, 9, 10, 11, 12]);
    let mut stems: Vec<String> = std::fs::read_dir(root().join("graphs/paper"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    stems.sort();
    let listed: Vec<&str> = FIGURES.iter().map(|f| f.stem).collect();
    assert_eq!(stems, listed);
    for fig in FIGURES {
        assert!(
            fig.stem.starts_with(&format!("fig{:02}_", fig.number)),
            "{}",
            fig.stem
        );
        let lg = rgbn::graph::LoadedGraph::load(&graph_path(&format!("paper/{}.ron", fig.stem)))
            .unwrap();
        assert!(
            example_bindings(&lg).is_empty(),
            "{} needs no input file",
            fig.stem
        );
    }
}

/// The edits the paper shows to keep a surface a surface: the stamp and the linear combine
/// (§IV, §VI; Figs. 4, 10 left, 12), the pen along open paths with equal levels at both sides
/// and along closed paths without self-intersections (§V–VI; Figs. 5, 6, 9). Their inputs are
/// surfaces and so are their results: F ≤ 1e-4 (rounding). (The linear filter of Fig. 2: the
/// next test.)
#[test]
fn the_edits_the_paper_proves_integrable_keep_a_surface() {
    for (stem, row) in [
        ("fig04_cut_and_stamp", 0),
        ("fig05_pen_stroke", 0),
        ("fig06_custom_profiles", 0),
        ("fig09_pen_closed_regions", 0),
        ("fig10_linear_vs_rotation", 0),
        ("fig12_stamps_in_region", 0),
    ] {
        let (before, after) = f(stem, row);
        eprintln!("{stem}: F {before:.2e} -> {after:.2e}");
        assert!(
            before <= 1e-4 && after <= 1e-4,
            "{stem}: F {before:e} -> {after:e}"
        );
    }
}

/// A linear filter of the gradients is the gradient of the filtered height (§III, Fig. 2):
/// away from the image's border (3σ = 9 px and a pixel) the high-passed field reads as a
/// surface (F ≤ 1e-4 over that interior); over the whole image F is larger only because the
/// filter mirrors gradient samples at the border (documented in the gallery), and stays small.
#[test]
fn a_high_pass_of_a_surface_is_a_surface_away_from_the_border() {
    let (_, whole) = f("fig02_highpass", 0);
    let lg = rgbn::graph::LoadedGraph::load(&graph_path("paper/fig02_highpass.ron")).unwrap();
    let r = eval_all(
        &rgbn::eval::Evaluator::default(),
        &lg,
        std::env::temp_dir().as_path(),
    );
    let rgbn::nodes::Value::Rgbn(img) = &r.outputs["image"] else {
        panic!("an image")
    };
    let (w, h) = (img.width(), img.height());
    let m = 10;
    let interior: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, r) = (i % w, i / w);
            f32::from(u8::from(x >= m && x + m < w && r >= m && r + m < h))
        })
        .collect();
    let g = rgbn::GradientField::from_normals(img);
    let inside = rgbn::raster::integrate::non_integrable_fraction(&g, Some(&interior)).unwrap();
    eprintln!("fig02: F {whole:.2e} over the image, {inside:.2e} {m} px inside its border");
    assert!(inside <= 1e-4, "{inside}");
    assert!(whole <= 1e-2, "{whole}");
}

/// Where the paper proves nothing — the brush's blend of a filtered and an unfiltered field
/// ("the above integrability property may not hold", §III) and the nonlinear rotation combine
/// (§VII) — we measure results that are not surfaces: F ≥ 1 % (Figs. 1 and 10), over a
/// thousand times the input's.
#[test]
fn the_brush_and_the_rotation_combine_measure_as_not_integrable() {
    for (stem, row) in [("fig01_brush", 0), ("fig10_linear_vs_rotation", 1)] {
        let (before, after) = f(stem, row);
        eprintln!("{stem}: measured F {before:.2e} -> {after:.2e}");
        assert!(
            after >= 0.01 && after >= 1000.0 * before,
            "{stem}: measured F {before:e} -> {after:e}"
        );
    }
}

/// `integrable: true` on the rotation combine (issue 35): on Figure 10 the result's F falls
/// from the rotation's 0.30 to at most 1e-3 (the goal), and on Figure 12, where the weight
/// restricts the edit to a band and its border is held, it falls by more than 20×; the relit
/// pictures stay close (RMS difference reported in the gallery). In the §VII sweep every
/// integrable F is at most 1e-3 and below the plain rotation's.
#[test]
fn the_integrable_rotation_combine_is_a_surface_where_the_rotation_is_not() {
    let (_, rotation) = f("fig10_linear_vs_rotation", 1);
    let (_, held) = f("fig10_linear_vs_rotation", 2);
    eprintln!("fig10: rotation F {rotation:.3e}, integrable {held:.3e}");
    assert!(rotation >= 0.1 && held <= 1e-3, "{rotation} {held}");
    let (_, rotation) = f("fig12_stamps_in_region", 1);
    let (_, held) = f("fig12_stamps_in_region", 2);
    eprintln!("fig12: rotation F {rotation:.3e}, integrable {held:.3e}");
    assert!(held * 20.0 <= rotation, "{rotation} {held}");
    for (stem, rms) in &computed().rms {
        for (label, v) in rms {
            eprintln!("{stem}: RMS difference of the {label}: {v:.3e}");
            assert!(*v > 0.0 && *v < 0.1, "{stem}: {v}");
        }
    }
    for &(sigma, amp, rot, held) in &computed().sweep {
        eprintln!("§VII sweep σ {sigma} px, ripples {amp} px: F {rot:.3e} -> {held:.3e}");
        assert!(
            held <= 1e-3 && held < rot,
            "σ {sigma}, amplitude {amp}: {rot} {held}"
        );
    }
}

/// F of i.i.d. noise under the averaged model is √(2/π) ≈ 0.798 (derivation in the docs of
/// `non_integrable_fraction`): a 512 × 512 field of uniform samples reads it within 1 %.
#[test]
fn noise_reads_root_two_over_pi() {
    let (formula, measured) = computed().noise;
    eprintln!("noise: F {measured:.4} against √(2/π) = {formula:.4}");
    assert!((formula - 0.797_884_560_8).abs() < 1e-9);
    assert!((measured - formula).abs() < 0.01 * formula, "{measured}");
}
