//! The gallery of the paper's figures (`docs/gallery.md` and its pictures in `docs/gallery/`),
//! produced by the project itself and kept true by a test.
//!
//! Every figure graph under `graphs/paper/` is evaluated with the integrability readout on; its
//! picture outputs become `docs/gallery/STEM.OUTPUT.png` and its numbers fill the tables of
//! `docs/gallery.md` between the markers `<!-- gallery: NAME -->` and `<!-- /gallery -->` (the
//! prose around them is written by hand). [`generate`] computes everything, [`write`](fn@write) puts it
//! in place, [`check`] lists where the page or the pictures disagree with it: a number that
//! differs from the recomputed one by more than half a unit of its last printed digit, a table
//! whose words differ, a picture missing, extra, or differing by more than
//! [`PICTURE_MAX_LEVELS`] 8-bit levels anywhere or [`PICTURE_MEAN_LEVELS`] on average.
//!
//! ```text
//! cargo run --release --example gallery            # regenerate the pictures and the tables
//! cargo run --release --example gallery -- --check # list disagreements, exit 1 if any
//! ```
//!
//! F is the non-integrable fraction of a node's normals
//! ([`crate::raster::integrate::non_integrable_fraction`]).

use crate::error::RgbnError;
use crate::eval::{EvalOptions, Evaluator, Plan};
use crate::graph::{GraphError, LoadedGraph};
use crate::nodes::{Picture, Value};
use crate::raster::integrate::non_integrable_fraction;
pub use crate::raster::sample::noise_field;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A row of a figure's table: F of node `before` and of node `after`.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    /// What the row compares (the table's first column).
    pub label: &'static str,
    /// The node whose output is the edit's input.
    pub before: u64,
    /// The node whose output is the edit's result.
    pub after: u64,
}

/// The RMS difference of two picture outputs of a figure graph (full scale = 1).
#[derive(Clone, Copy, Debug)]
pub struct Rms {
    /// What is compared.
    pub label: &'static str,
    /// One picture output.
    pub a: &'static str,
    /// The other.
    pub b: &'static str,
}

/// One figure of the paper as a graph.
#[derive(Clone, Copy, Debug)]
pub struct Figure {
    /// The paper's figure number.
    pub number: u32,
    /// The graph's file stem under `graphs/paper/` (also the table's block name).
    pub stem: &'static str,
    /// The table rows.
    pub rows: &'static [Row],
    /// Picture differences printed under the table.
    pub rms: &'static [Rms],
}

/// The figures with a graph: every figure of the paper that shows an edit.
pub const FIGURES: &[Figure] = &[
    Figure {
        number: 1,
        stem: "fig01_brush",
        rows: &[Row {
            label: "the demo → both brush strokes",
            before: 1,
            after: 3,
        }],
        rms: &[],
    },
    Figure {
        number: 2,
        stem: "fig02_highpass",
        rows: &[Row {
            label: "the demo relief on grey → high-passed",
            before: 6,
            after: 2,
        }],
        rms: &[],
    },
    Figure {
        number: 4,
        stem: "fig04_cut_and_stamp",
        rows: &[Row {
            label: "the plate → stamped twice",
            before: 2,
            after: 4,
        }],
        rms: &[],
    },
    Figure {
        number: 5,
        stem: "fig05_pen_stroke",
        rows: &[Row {
            label: "the plate → ridge and scratch",
            before: 1,
            after: 3,
        }],
        rms: &[],
    },
    Figure {
        number: 6,
        stem: "fig06_custom_profiles",
        rows: &[Row {
            label: "the body → four custom profiles",
            before: 2,
            after: 6,
        }],
        rms: &[],
    },
    Figure {
        number: 9,
        stem: "fig09_pen_closed_regions",
        rows: &[Row {
            label: "the demo → one region raised, one lowered",
            before: 1,
            after: 3,
        }],
        rms: &[],
    },
    Figure {
        number: 10,
        stem: "fig10_linear_vs_rotation",
        rows: &[
            Row {
                label: "the dome → linear combine",
                before: 1,
                after: 3,
            },
            Row {
                label: "the dome → rotation combine",
                before: 1,
                after: 5,
            },
            Row {
                label: "the dome → rotation combine, integrable: true",
                before: 1,
                after: 8,
            },
        ],
        rms: &[Rms {
            label: "relit rotation combine, integrable: true against false",
            a: "rotation_picture",
            b: "rotation_integrable_picture",
        }],
    },
    Figure {
        number: 11,
        stem: "fig11_bilateral_split",
        rows: &[Row {
            label: "the demo → its bilateral base",
            before: 1,
            after: 2,
        }],
        rms: &[],
    },
    Figure {
        number: 12,
        stem: "fig12_stamps_in_region",
        rows: &[
            Row {
                label: "the demo → three stamps in the region",
                before: 1,
                after: 4,
            },
            Row {
                label: "the demo → rotation combine weighted by the region",
                before: 1,
                after: 9,
            },
            Row {
                label: "the demo → the same, integrable: true",
                before: 1,
                after: 10,
            },
        ],
        rms: &[Rms {
            label: "relit rotation combine, integrable: true against false",
            a: "rotation_picture",
            b: "rotation_integrable_picture",
        }],
    },
];

/// The §VII sweep on the Figure 10 graph: the bilateral split's spatial sigma (the base band).
pub const SWEEP_SIGMAS_PX: [f64; 3] = [2.0, 4.0, 8.0];
/// The §VII sweep: the ripples' amplitude (the detail).
pub const SWEEP_AMPLITUDES_PX: [f64; 3] = [0.5, 1.0, 2.0];
/// The §VII sweep's graph, its split node, its detail node, and its rotation nodes without and
/// with `integrable`.
const SWEEP: (&str, &str, &str, u64, u64) = ("fig10_linear_vs_rotation", "4", "2", 5, 8);
/// Side of the noise field of the noise block.
pub const NOISE_SIDE: usize = 512;

/// Largest difference, in 8-bit levels, allowed between a stored picture and the recomputed one.
pub const PICTURE_MAX_LEVELS: u8 = 2;
/// Largest mean absolute difference, in 8-bit levels, allowed between them.
pub const PICTURE_MEAN_LEVELS: f64 = 0.05;

/// Everything the gallery shows, recomputed.
#[derive(Clone, Debug, Default)]
pub struct Gallery {
    /// Per figure stem, per row: (label, F before, F after).
    pub rows: BTreeMap<&'static str, Vec<(&'static str, f64, f64)>>,
    /// Per figure stem: (label, RMS difference of two pictures, full scale 1).
    pub rms: BTreeMap<&'static str, Vec<(&'static str, f64)>>,
    /// The §VII sweep: (sigma, amplitude, F of the rotation, F with `integrable`).
    pub sweep: Vec<(f64, f64, f64, f64)>,
    /// F of i.i.d. noise: the formula √(2/π) and the measurement.
    pub noise: (f64, f64),
    /// The pictures: file name under `docs/gallery/` → picture.
    pub pictures: BTreeMap<String, Arc<Picture>>,
    /// The generated tables, by block name.
    pub blocks: BTreeMap<String, String>,
}

/// What can stop the gallery.
#[derive(Debug, thiserror::Error)]
pub enum GalleryError {
    /// A figure graph could not be read or evaluated.
    #[error(transparent)]
    Graph(#[from] Box<GraphError>),
    /// An image or file error.
    #[error(transparent)]
    Rgbn(#[from] RgbnError),
    /// The page or a figure graph is not as the gallery needs it.
    #[error("{detail}: {}", .path.display())]
    Page {
        /// What is wrong.
        detail: String,
        /// The file.
        path: PathBuf,
    },
}

impl From<GraphError> for GalleryError {
    fn from(e: GraphError) -> Self {
        GalleryError::Graph(Box::new(e))
    }
}

/// `docs/gallery.md` under `root`.
#[must_use]
pub fn page_path(root: &Path) -> PathBuf {
    root.join("docs/gallery.md")
}

/// `docs/gallery/` under `root`.
#[must_use]
pub fn pictures_dir(root: &Path) -> PathBuf {
    root.join("docs/gallery")
}

/// A number as the gallery prints it: three significant digits.
#[must_use]
pub fn number(v: f64) -> String {
    format!("{v:.2e}")
}

/// A graph's outputs by name.
type Outputs = BTreeMap<String, Value>;
/// F of each node's output, by node id.
type FByNode = BTreeMap<u64, f64>;

/// Evaluates every figure graph of the repository at `root` and computes the page's tables
/// and pictures.
///
/// # Errors
/// A figure graph that cannot be read or evaluated, or that lacks a node or output the
/// gallery names.
pub fn generate(root: &Path) -> Result<Gallery, GalleryError> {
    let ev = Evaluator::default();
    let opts = EvalOptions {
        curl_stats: true,
        ..Default::default()
    };
    let scratch = std::env::temp_dir();
    let graph_path = |stem: &str| root.join("graphs/paper").join(format!("{stem}.ron"));
    let run = |lg: &LoadedGraph| -> Result<(Outputs, FByNode), GalleryError> {
        let plan = Plan::new(lg, &BTreeMap::new(), &scratch)?;
        let r = ev.eval(&plan, &[], &opts)?;
        let f = r
            .stats
            .iter()
            .filter_map(|s| Some((s.at.node?, s.fraction?)))
            .collect();
        Ok((r.outputs, f))
    };
    let mut g = Gallery::default();
    for fig in FIGURES {
        let path = graph_path(fig.stem);
        let lg = LoadedGraph::load(&path)?;
        let (outputs, f) = run(&lg)?;
        let at = |id: u64| {
            f.get(&id).copied().ok_or_else(|| GalleryError::Page {
                detail: format!(
                    "the gallery reads F of node {id}, which is not an image node that an output \
                     needs"
                ),
                path: path.clone(),
            })
        };
        let mut rows = Vec::new();
        for row in fig.rows {
            rows.push((row.label, at(row.before)?, at(row.after)?));
        }
        g.rows.insert(fig.stem, rows);
        let picture = |name: &str| match outputs.get(name) {
            Some(Value::Picture(p)) => Ok(p.clone()),
            _ => Err(GalleryError::Page {
                detail: format!("the gallery needs a picture output {name:?}"),
                path: path.clone(),
            }),
        };
        let mut rms = Vec::new();
        for d in fig.rms {
            let (a, b) = (picture(d.a)?, picture(d.b)?);
            rms.push((d.label, rms_difference(&a, &b)));
        }
        g.rms.insert(fig.stem, rms);
        for (name, v) in &outputs {
            if let Value::Picture(p) = v {
                g.pictures
                    .insert(format!("{}.{name}.png", fig.stem), p.clone());
            }
        }
    }
    // §VII: F of the rotation combine against the base band and the detail amplitude.
    let (stem, split, detail, rot, held) = SWEEP;
    let base = LoadedGraph::load(&graph_path(stem))?;
    for sigma in SWEEP_SIGMAS_PX {
        for amp in SWEEP_AMPLITUDES_PX {
            let mut lg = base.clone();
            let (s, a) = (sigma.to_string(), amp.to_string());
            lg.set_params(&[
                (split, "sigma_spatial_px", s.as_str()),
                (detail, "amplitude_px", a.as_str()),
            ])?;
            let (_, f) = run(&lg)?;
            let get = |id: u64| f.get(&id).copied().unwrap_or(f64::NAN);
            g.sweep.push((sigma, amp, get(rot), get(held)));
        }
    }
    g.noise = (
        (2.0 / std::f64::consts::PI).sqrt(),
        non_integrable_fraction(&noise_field(NOISE_SIDE, NOISE_SIDE, 7), None)?,
    );
    g.blocks = blocks(&g);
    Ok(g)
}

/// RMS of the difference of two pictures' RGB, full scale 1 (`NaN` when their sizes differ).
#[must_use]
pub fn rms_difference(a: &Picture, b: &Picture) -> f64 {
    if (a.width, a.height) != (b.width, b.height) {
        return f64::NAN;
    }
    let (mut s, mut n) = (0.0f64, 0usize);
    for (pa, pb) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        for k in 0..3 {
            s += ((f64::from(pa[k]) - f64::from(pb[k])) / 255.0).powi(2);
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// The tables, by block name.
fn blocks(g: &Gallery) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for fig in FIGURES {
        let mut t = String::from("| | F before | F after |\n|---|---|---|\n");
        for (label, before, after) in &g.rows[fig.stem] {
            let _ = writeln!(t, "| {label} | {} | {} |", number(*before), number(*after));
        }
        for (label, v) in &g.rms[fig.stem] {
            let _ = writeln!(t, "\nRMS difference of the {label}: {}", number(*v));
        }
        out.insert(fig.stem.to_string(), t);
    }
    let mut t = String::from("| base: bilateral σ_s |");
    for a in SWEEP_AMPLITUDES_PX {
        let _ = write!(t, " F, ripples {a} px |");
    }
    t.push_str("\n|---|");
    t.push_str(&"---|".repeat(SWEEP_AMPLITUDES_PX.len()));
    t.push('\n');
    for (integrable, label) in [(false, ""), (true, ", integrable: true")] {
        for sigma in SWEEP_SIGMAS_PX {
            let _ = write!(t, "| {sigma} px{label} |");
            for amp in SWEEP_AMPLITUDES_PX {
                let f = g
                    .sweep
                    .iter()
                    .find(|s| s.0 == sigma && s.1 == amp)
                    .map_or(f64::NAN, |s| if integrable { s.3 } else { s.2 });
                let _ = write!(t, " {} |", number(f));
            }
            t.push('\n');
        }
    }
    out.insert("sec7_rotation_bands".to_string(), t);
    out.insert(
        "noise".to_string(),
        format!(
            "| | F |\n|---|---|\n| √(2/π) | {} |\n| i.i.d. uniform samples, {NOISE_SIDE} × \
             {NOISE_SIDE} | {} |\n",
            number(g.noise.0),
            number(g.noise.1)
        ),
    );
    out
}

const OPEN: &str = "<!-- gallery: ";
const CLOSE: &str = "<!-- /gallery -->";

/// The blocks of a page: name → (byte range of the content, content).
fn page_blocks(text: &str) -> Result<BTreeMap<String, (std::ops::Range<usize>, String)>, String> {
    let mut out = BTreeMap::new();
    let mut from = 0;
    while let Some(k) = text[from..].find(OPEN) {
        let start = from + k;
        let head_end = text[start..]
            .find("-->")
            .map(|e| start + e + 3)
            .ok_or_else(|| format!("an unclosed marker at byte {start}"))?;
        let name = text[start + OPEN.len()..head_end - 3].trim().to_string();
        let body_start = head_end + usize::from(text[head_end..].starts_with('\n'));
        let end = text[body_start..]
            .find(CLOSE)
            .map(|e| body_start + e)
            .ok_or_else(|| format!("block {name:?} has no {CLOSE}"))?;
        if text[body_start..end].contains(OPEN) {
            return Err(format!("block {name:?} is not closed before the next one"));
        }
        if out
            .insert(
                name.clone(),
                (body_start..end, text[body_start..end].to_string()),
            )
            .is_some()
        {
            return Err(format!("block {name:?} appears twice"));
        }
        from = end + CLOSE.len();
    }
    Ok(out)
}

/// Whether `token` is a number as [`number`] prints it; its value and half a unit of its last
/// digit.
fn printed(token: &str) -> Option<(f64, f64)> {
    let (mantissa, exp) = token.split_once('e')?;
    let exp: i32 = exp.parse().ok()?;
    let digits = mantissa.split_once('.').map_or(0, |(_, f)| f.len());
    if !mantissa
        .trim_start_matches('-')
        .chars()
        .all(|c| c.is_ascii_digit() || c == '.')
    {
        return None;
    }
    let v: f64 = token.parse().ok()?;
    Some((v, 0.5 * 10f64.powi(exp - digits as i32)))
}

/// Values below this are at the rounding floor of `f32` normals (F of a surface: about 1e-6):
/// their last digits follow the order of the parallel sums, which varies from run to run, so
/// they agree within [`FLOOR_RELATIVE`] of their size rather than half their last digit.
const ROUNDING_FLOOR: f64 = 1e-4;
/// How far two values under [`ROUNDING_FLOOR`] may differ, relative to the written one.
const FLOOR_RELATIVE: f64 = 0.05;

/// The disagreements between a block as written and as recomputed, one line each.
fn compare_block(name: &str, written: &str, computed: &str) -> Vec<String> {
    let split = |s: &str| -> Vec<(usize, String)> {
        s.lines()
            .enumerate()
            .flat_map(|(l, line)| {
                line.split(|c: char| c.is_whitespace() || c == '|')
                    .filter(|t| !t.is_empty())
                    .map(move |t| (l + 1, t.to_string()))
            })
            .collect()
    };
    let (w, c) = (split(written), split(computed));
    let mut out = Vec::new();
    for ((line, a), (_, b)) in w.iter().zip(&c) {
        match (printed(a), printed(b)) {
            (Some((va, half)), Some((vb, _))) => {
                let floor = va.abs() < ROUNDING_FLOOR && vb.abs() < ROUNDING_FLOOR;
                let allowed = if floor {
                    half.max(FLOOR_RELATIVE * va.abs())
                } else {
                    half
                };
                if (va - vb).abs().is_nan() || (va - vb).abs() > allowed * (1.0 + 1e-9) {
                    out.push(format!(
                        "block {name}, line {line}: {a} written, {b} recomputed (more than ± \
                         {allowed:.0e}{})",
                        if floor {
                            ", 5 % at the rounding floor"
                        } else {
                            ", half its last digit"
                        }
                    ));
                }
            }
            _ if a == b => {}
            _ => out.push(format!(
                "block {name}, line {line}: {a:?} written, {b:?} recomputed"
            )),
        }
        if out.len() >= 20 {
            break;
        }
    }
    if w.len() != c.len() && out.is_empty() {
        out.push(format!(
            "block {name}: {} words written, {} recomputed (the table's shape changed)",
            w.len(),
            c.len()
        ));
    }
    out
}

/// The page's text with every block replaced by the recomputed one.
///
/// # Errors
/// Malformed markers, or a block of `g` that the page lacks (with where to add it).
pub fn updated_page(text: &str, g: &Gallery) -> Result<String, String> {
    let blocks = page_blocks(text)?;
    for name in g.blocks.keys() {
        if !blocks.contains_key(name) {
            return Err(format!(
                "no block {name:?}: add `{OPEN}{name} -->` and `{CLOSE}` on lines of their own \
                 where its table belongs"
            ));
        }
    }
    let mut out = String::with_capacity(text.len());
    let mut last = 0;
    let mut ordered: Vec<(&String, &std::ops::Range<usize>)> =
        blocks.iter().map(|(n, (r, _))| (n, r)).collect();
    ordered.sort_by_key(|(_, r)| r.start);
    for (name, range) in ordered {
        out.push_str(&text[last..range.start]);
        match g.blocks.get(name.as_str()) {
            Some(b) => out.push_str(b),
            None => out.push_str(&text[range.clone()]),
        }
        last = range.end;
    }
    out.push_str(&text[last..]);
    Ok(out)
}

/// Where the page at `root` and its pictures disagree with `g`, one line each (empty: the page
/// is true).
///
/// # Errors
/// The page or a picture cannot be read.
pub fn check(root: &Path, g: &Gallery) -> Result<Vec<String>, GalleryError> {
    let path = page_path(root);
    let text = std::fs::read_to_string(&path).map_err(|e| GalleryError::Page {
        detail: format!("cannot read the gallery page ({e})"),
        path: path.clone(),
    })?;
    let mut out = Vec::new();
    let blocks = page_blocks(&text).map_err(|detail| GalleryError::Page {
        detail,
        path: path.clone(),
    })?;
    for (name, computed) in &g.blocks {
        match blocks.get(name) {
            Some((_, written)) => out.extend(compare_block(name, written, computed)),
            None => out.push(format!("docs/gallery.md has no block {name:?}")),
        }
    }
    for name in blocks.keys() {
        if !g.blocks.contains_key(name) {
            out.push(format!(
                "docs/gallery.md has a block {name:?} that nothing computes"
            ));
        }
    }
    // Pictures: every one stored, referenced by the page and close to the recomputed one;
    // nothing else in the folder.
    let dir = pictures_dir(root);
    for (file, pic) in &g.pictures {
        if !text.contains(&format!("gallery/{file}")) {
            out.push(format!("docs/gallery.md does not show gallery/{file}"));
        }
        let p = dir.join(file);
        match image::open(&p) {
            Ok(img) => {
                let img = img.to_rgba8();
                if (img.width() as usize, img.height() as usize) != (pic.width, pic.height) {
                    out.push(format!(
                        "docs/gallery/{file} is {}×{}, the graph's picture {}×{}",
                        img.width(),
                        img.height(),
                        pic.width,
                        pic.height
                    ));
                    continue;
                }
                let (mut worst, mut sum) = (0u8, 0u64);
                for (a, b) in img.as_raw().iter().zip(&pic.rgba) {
                    let d = a.abs_diff(*b);
                    worst = worst.max(d);
                    sum += u64::from(d);
                }
                let mean = sum as f64 / pic.rgba.len().max(1) as f64;
                if worst > PICTURE_MAX_LEVELS || mean > PICTURE_MEAN_LEVELS {
                    out.push(format!(
                        "docs/gallery/{file} differs from the graph's picture: up to {worst} \
                         levels, {mean:.3} on average (allowed {PICTURE_MAX_LEVELS} and \
                         {PICTURE_MEAN_LEVELS})"
                    ));
                }
            }
            Err(e) => out.push(format!("docs/gallery/{file}: {e}")),
        }
    }
    for file in stored_pictures(&dir) {
        if !g.pictures.contains_key(&file) {
            out.push(format!(
                "docs/gallery/{file} is no figure graph's picture (stale)"
            ));
        }
    }
    Ok(out)
}

/// The `.png` files in `dir` (sorted; none when it cannot be read).
fn stored_pictures(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".png"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Writes the pictures (atomically), removes stale ones from `docs/gallery/`, and replaces the
/// page's tables. Returns the files written or removed, one line each.
///
/// # Errors
/// A page without a block that `g` has, or a file that cannot be written.
pub fn write(root: &Path, g: &Gallery) -> Result<Vec<String>, GalleryError> {
    // The page first: a page without a block the gallery fills changes nothing.
    let path = page_path(root);
    let text = std::fs::read_to_string(&path).map_err(|e| GalleryError::Page {
        detail: format!("cannot read the gallery page ({e})"),
        path: path.clone(),
    })?;
    let new = updated_page(&text, g).map_err(|detail| GalleryError::Page {
        detail,
        path: path.clone(),
    })?;
    let dir = pictures_dir(root);
    std::fs::create_dir_all(&dir).map_err(|e| GalleryError::Page {
        detail: format!("cannot create the folder ({e})"),
        path: dir.clone(),
    })?;
    let mut done = Vec::new();
    for (file, pic) in &g.pictures {
        let p = dir.join(file);
        crate::raster::io::write_png8_text(&pic.rgba, pic.width, pic.height, &[], &p)?;
        done.push(format!("wrote docs/gallery/{file}"));
    }
    for file in stored_pictures(&dir) {
        if !g.pictures.contains_key(&file) {
            std::fs::remove_file(dir.join(&file)).map_err(|e| GalleryError::Page {
                detail: format!("cannot remove a stale picture ({e})"),
                path: dir.join(&file),
            })?;
            done.push(format!("removed docs/gallery/{file}"));
        }
    }
    if new != text {
        crate::raster::io::write_atomic(&path, |out| {
            use std::io::Write as _;
            out.write_all(new.as_bytes()).map_err(|e| e.to_string())
        })?;
        done.push("updated docs/gallery.md".to_string());
    }
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gallery_with(blocks: &[(&str, &str)]) -> Gallery {
        Gallery {
            blocks: blocks
                .iter()
                .map(|(n, b)| ((*n).to_string(), (*b).to_string()))
                .collect(),
            ..Gallery::default()
        }
    }

    #[test]
    fn printed_numbers_carry_half_their_last_digit() {
        assert_eq!(number(0.300_12), "3.00e-1");
        let (v, half) = printed("3.00e-1").unwrap();
        assert!((v - 0.3).abs() < 1e-15 && (half - 5e-4).abs() < 1e-15);
        let (v, half) = printed("1.64e-6").unwrap();
        assert!((v - 1.64e-6).abs() < 1e-18 && (half - 5e-9).abs() < 1e-20);
        assert_eq!(printed("0.00e0").map(|p| p.1), Some(0.005));
        for word in ["F", "e", "1e", "px", "(node", "2/π"] {
            assert_eq!(printed(word), None, "{word}");
        }
    }

    /// A block checks when its numbers agree within half their last digit, and fails on a
    /// number changed beyond that, a changed word, or a changed shape.
    #[test]
    fn a_changed_number_or_word_is_a_disagreement() {
        let computed = "| | F before | F after |\n|---|---|---|\n| a → b | 1.04e-6 | 3.00e-1 |\n";
        assert!(compare_block("x", computed, computed).is_empty());
        // Within printed precision: 0.30049 prints as 3.00e-1.
        assert!(compare_block("x", computed, &computed.replace("3.00e-1", "3.0049e-1")).is_empty());
        // At the rounding floor the last digits follow the summation order: 5 % apart is
        // agreement, 10 % is not.
        let tiny = computed.replace("1.04e-6", "1.08e-6");
        assert!(compare_block("x", &tiny, computed).is_empty());
        let off = computed.replace("1.04e-6", "1.15e-6");
        assert_eq!(compare_block("x", &off, computed).len(), 1);
        let changed = computed.replace("3.00e-1", "3.01e-1");
        let d = compare_block("x", &changed, computed);
        assert_eq!(d.len(), 1, "{d:?}");
        assert!(
            d[0].contains("3.01e-1 written, 3.00e-1 recomputed"),
            "{d:?}"
        );
        let worded = computed.replace("a → b", "a → c");
        assert_eq!(compare_block("x", &worded, computed).len(), 1);
        let longer = format!("{computed}| c | 1.00e0 | 1.00e0 |\n");
        assert_eq!(compare_block("x", computed, &longer).len(), 1);
    }

    #[test]
    fn the_page_is_updated_between_its_markers_only() {
        let page = "intro\n<!-- gallery: a -->\nold a\n<!-- /gallery -->\nmiddle\n\
                    <!-- gallery: b -->\nold b\n<!-- /gallery -->\nend\n";
        let g = gallery_with(&[("a", "new a\n"), ("b", "new b\n")]);
        let new = updated_page(page, &g).unwrap();
        assert_eq!(
            new,
            "intro\n<!-- gallery: a -->\nnew a\n<!-- /gallery -->\nmiddle\n\
             <!-- gallery: b -->\nnew b\n<!-- /gallery -->\nend\n"
        );
        assert_eq!(updated_page(&new, &g).unwrap(), new);
        let e = updated_page(page, &gallery_with(&[("c", "x")])).unwrap_err();
        assert!(e.contains("no block \"c\""), "{e}");
        let e = page_blocks("<!-- gallery: a -->\nno end").unwrap_err();
        assert!(e.contains("has no"), "{e}");
    }
}
