//! Which green convention (OpenGL `+y` up or DirectX `+y` down) a normal map's relief belongs
//! to: [`green_convention`].
//!
//! # The rule
//!
//! A normal map read in the wrong convention is the gradient field `(p, −q)`. On a 2 × 2
//! plaquette of pixel samples the averaged edge model (module docs of
//! [`integrate`](super)) gives two estimates of the mixed slope `∂²z/∂x∂y`:
//! `A = ∂p/∂y` (the column-averaged `p` differenced between the two rows) and `B = ∂q/∂x`
//! (the row-averaged `q` differenced between the two columns). The plaquette's curl is
//! `A − B` as read and `A + B` with green flipped, so the two readings' local curl energies
//! differ by `(A + B)² − (A − B)² = 4AB`: the reading whose relief is a surface's is the one
//! where `A` and `B` agree. The statistic is the **contrast**
//! `C = (E_flipped − E_read)/(E_flipped + E_read) = ΣAB / Σ½(A² + B²)` over the plaquettes
//! that carry relief: `+1` for an exact surface as read, `−1` for one stored the other way
//! round, `≈ 0` when the relief cannot tell.
//!
//! Only plaquettes that carry relief vote. A plaquette votes when
//! - its four samples are usable: inside the mask, `n_z ≥ 0.1` (steeper than 84° the slope
//!   `−n_xy/n_z` is not a height field's any more — back-facing, black or empty atlas filler
//!   is excluded here);
//! - it does not straddle a discontinuity: across its four samples `p` and `q` each vary by
//!   less than [`SEAM_JUMP`] = 1 (a 45° turn of the normal between neighbours — atlas seams,
//!   island borders against filler, hard bevel edges carry no smooth relief);
//! - its mixed slope is measurable: `√(A² + B²) ≥` [`RELIEF_MIN`] = 0.02, 2.5 steps of an
//!   8-bit map (`2/255`), so quantisation steps and flat filler do not vote.
//!
//! **What cannot be told.** Both readings are surfaces exactly when `∂²z/∂x∂y = 0`, i.e.
//! `z = f(x) + g(y)`: relief that varies along one axis only (ribs, grooves, extrusions
//! aligned with the image axes) and flat maps carry no vote. A map whose normals are not a
//! surface's at all (noise, velvet fibres painted as normals, flakes) votes about evenly.
//!
//! **Robustness.** Voting with `AB` keeps the sign where the whole-image integrability
//! projection can be misled: a tangent frame rotated by `θ` against the image axes
//! (atlas islands, twisted frames) changes `A`, `B` to `cos θ·z_xy − sin θ·z_yy`,
//! `cos θ·z_xy + sin θ·z_xx`, whose product keeps its sign for `|θ| < 45°` on relief that
//! varies in both directions, and vanishes on one-axis relief at any angle; anisotropic UV
//! stretch scales `A` and `B` by positive factors. Mirrored islands are read in image space
//! like every other island (a correctly baked mirrored island is a surface in image space).
//!
//! # When it says "uncertain"
//!
//! - fewer than [`RELIEF_PLAQUETTES_MIN`] = 256 plaquettes (a 16 × 16 patch) vote: too little
//!   relief that tells the conventions apart;
//! - `|C| <` [`CONTRAST_MIN`] = 0.05 (the two curl energies within ≈ 10% of each other: small
//!   systematic effects — compression, resampling, frame twist — reach that size) or the
//!   contrast is not significant, `|z| <` [`Z_MIN`] = 5. `z = C / se(C)`; the standard error is
//!   the ratio estimator's over **units** — the pieces of each island (8-connected component
//!   of voting plaquettes) inside each 32 × 32 block — so spatially correlated votes are not
//!   counted as independent, and one big island (a tileable texture) still has many units.
//!
//! Islands also vote one by one for the evidence: an island of ≥ 16 plaquettes whose own
//! contrast is ≥ 0.05 in size counts for its side ([`GreenEvidence::islands_as_read`],
//! [`GreenEvidence::islands_flipped`]). The decision itself is the energy contrast, so the
//! many faint islands of a speckle texture cannot outvote a few strong relief islands; the
//! island count shows when islands disagree. The checks on published maps are in
//! `docs/green-convention.md`.

use super::inside;
use crate::raster::RgbnImage;
use rayon::prelude::*;

/// A plaquette whose `p` or `q` varies by this much or more across its four samples straddles
/// a discontinuity (seam) and does not vote.
pub const SEAM_JUMP: f32 = 1.0;
/// Smallest `√(A² + B²)` (mixed-slope estimates) of a voting plaquette.
pub const RELIEF_MIN: f32 = 0.02;
/// Samples with `n_z` below this do not vote (no height-field slope).
pub const NZ_MIN: f32 = 0.1;
/// Fewer voting plaquettes than this: too little relief to tell.
pub const RELIEF_PLAQUETTES_MIN: usize = 256;
/// Smallest contrast `|C|` that decides.
pub const CONTRAST_MIN: f64 = 0.05;
/// Smallest significance `|C| / se(C)` that decides.
pub const Z_MIN: f64 = 5.0;
/// Side of the blocks that split islands into units for the standard error.
const BLOCK: usize = 32;
/// Islands smaller than this do not count in the island tally.
const ISLAND_MIN: usize = 16;

/// The convention of the normals **as held** (rgbn's frame is OpenGL, `+y` up).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GreenVerdict {
    /// The normals as held are a surface's: the file was read in its own convention.
    OpenGl,
    /// They become a surface's with `n_y` negated: the file uses the other convention.
    DirectX,
    /// The relief cannot tell (see [`Uncertainty`]).
    Uncertain(Uncertainty),
}

impl GreenVerdict {
    /// `Some(true)` for OpenGL, `Some(false)` for DirectX, `None` when uncertain.
    #[must_use]
    pub fn reads_opengl(self) -> Option<bool> {
        match self {
            Self::OpenGl => Some(true),
            Self::DirectX => Some(false),
            Self::Uncertain(_) => None,
        }
    }
}

/// Why [`green_convention`] does not decide.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Uncertainty {
    /// Fewer than `RELIEF_PLAQUETTES_MIN` plaquettes carry a measurable mixed slope.
    TooLittleRelief,
    /// The curl energies of the two readings are too close (`|C| <` `CONTRAST_MIN` or
    /// `|z| <` `Z_MIN`).
    Balanced,
}

/// The numbers behind a [`GreenVerdict`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GreenEvidence {
    /// Plaquettes that vote.
    pub relief_plaquettes: usize,
    /// `Σ(A − B)²` over them: local curl energy as held.
    pub curl_energy_as_read: f64,
    /// `Σ(A + B)²`: local curl energy with green flipped.
    pub curl_energy_flipped: f64,
    /// `C = (E_flipped − E_read)/(E_flipped + E_read)` (0 when nothing votes).
    pub contrast: f64,
    /// `C / se(C)` (0 when nothing votes; infinite when every unit agrees exactly).
    pub z: f64,
    /// Islands (≥ 16 plaquettes, `|C_island| ≥ 0.05`) whose relief reads as held.
    pub islands_as_read: usize,
    /// Islands whose relief reads with green flipped.
    pub islands_flipped: usize,
}

/// [`green_convention`]'s answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GreenConvention {
    /// What the relief says.
    pub verdict: GreenVerdict,
    /// The numbers it says it from.
    pub evidence: GreenEvidence,
}

impl GreenConvention {
    /// [`describe`](Self::describe) for normals loaded as DirectX (`dx`) or OpenGL.
    #[must_use]
    pub fn describe_loaded(&self, dx: bool) -> String {
        if dx {
            self.describe("DirectX (-y)", "OpenGL (+y)")
        } else {
            self.describe("OpenGL (+y)", "DirectX (-y)")
        }
    }

    /// One line for people: the verdict named in the file's terms (`as_read`: the convention
    /// the file was loaded in, e.g. "OpenGL (+y)"; `other`: the other one) and its evidence.
    #[must_use]
    pub fn describe(&self, as_read: &str, other: &str) -> String {
        let e = &self.evidence;
        let islands = format!(
            "islands {} {as_read}, {} {other}",
            e.islands_as_read, e.islands_flipped
        );
        match self.verdict {
            GreenVerdict::OpenGl | GreenVerdict::DirectX => {
                let (name, ratio) = if self.verdict == GreenVerdict::OpenGl {
                    (as_read, e.curl_energy_flipped / e.curl_energy_as_read)
                } else {
                    (other, e.curl_energy_as_read / e.curl_energy_flipped)
                };
                format!(
                    "{name} most likely: local curl energy {ratio:.2}× lower read as {name} \
                     (contrast {:+.3}, z = {:.1}, {} relief plaquettes, {islands})",
                    e.contrast, e.z, e.relief_plaquettes
                )
            }
            GreenVerdict::Uncertain(Uncertainty::TooLittleRelief) => format!(
                "uncertain — too little relief to tell: {} plaquettes with a measurable \
                 ∂²z/∂x∂y ({RELIEF_PLAQUETTES_MIN} needed; flat, or relief along one axis only)",
                e.relief_plaquettes
            ),
            GreenVerdict::Uncertain(Uncertainty::Balanced) => format!(
                "uncertain — the two readings are about as integrable: contrast {:+.3}, z = {:.1} \
                 over {} relief plaquettes (deciding needs |contrast| ≥ {CONTRAST_MIN} and \
                 |z| ≥ {Z_MIN}; {islands})",
                e.contrast, e.z, e.relief_plaquettes
            ),
        }
    }
}

/// The green convention of an image's normals (module docs: the rule, its thresholds and why).
/// Pixels outside the mask do not vote. Never fails: an image too small or flat is
/// [`Uncertainty::TooLittleRelief`].
#[must_use]
pub fn green_convention(img: &RgbnImage) -> GreenConvention {
    let (w, h) = (img.width(), img.height());
    let (pw, ph) = (w.saturating_sub(1), h.saturating_sub(1));
    // Per plaquette (x, t) with top row t and bottom row t + 1: (A, B), or NaN if it does
    // not vote.
    let ab = plaquette_slopes(img);
    let votes = |k: usize| !ab[k][0].is_nan();
    let labels = islands(&ab, pw, ph);
    // Per unit (island piece inside a block): Σ AB, Σ ½(A² + B²); per island the same.
    let bw = pw.div_ceil(BLOCK).max(1);
    let blocks = bw * ph.div_ceil(BLOCK).max(1);
    let units: Vec<Vec<(u32, f64, f64)>> = (0..blocks)
        .into_par_iter()
        .map(|blk| {
            let (bx, by) = ((blk % bw) * BLOCK, (blk / bw) * BLOCK);
            let mut v: Vec<(u32, f64, f64)> = Vec::new();
            for t in by..(by + BLOCK).min(ph) {
                for x in bx..(bx + BLOCK).min(pw) {
                    let k = t * pw + x;
                    if votes(k) {
                        let [a, b] = ab[k].map(f64::from);
                        v.push((labels[k], a * b, 0.5 * (a * a + b * b)));
                    }
                }
            }
            v.sort_unstable_by_key(|u| u.0);
            let mut merged: Vec<(u32, f64, f64)> = Vec::new();
            for (l, s, e) in v {
                match merged.last_mut() {
                    Some(m) if m.0 == l => {
                        m.1 += s;
                        m.2 += e;
                    }
                    _ => merged.push((l, s, e)),
                }
            }
            merged
        })
        .collect();
    let n = (0..pw * ph).filter(|&k| votes(k)).count();
    let (mut s_ab, mut s_e) = (0.0f64, 0.0f64);
    let n_islands = labels
        .iter()
        .filter(|&&l| l != NONE)
        .max()
        .map_or(0, |&m| m as usize + 1);
    let mut isl = vec![(0usize, 0.0f64, 0.0f64); n_islands];
    for u in units.iter().flatten() {
        s_ab += u.1;
        s_e += u.2;
        let i = &mut isl[u.0 as usize];
        i.1 += u.1;
        i.2 += u.2;
    }
    for k in 0..pw * ph {
        if votes(k) {
            isl[labels[k] as usize].0 += 1;
        }
    }
    let contrast = if s_e > 0.0 { s_ab / s_e } else { 0.0 };
    // Ratio estimator's standard error over the units.
    let var: f64 = units
        .iter()
        .flatten()
        .map(|u| (u.1 - contrast * u.2).powi(2))
        .sum();
    let z = if s_e > 0.0 {
        let se = var.sqrt() / s_e;
        if se > 0.0 {
            contrast / se
        } else if contrast == 0.0 {
            0.0
        } else {
            contrast.signum() * f64::INFINITY
        }
    } else {
        0.0
    };
    let decided = |i: &&(usize, f64, f64)| i.0 >= ISLAND_MIN && i.2 > 0.0;
    let evidence = GreenEvidence {
        relief_plaquettes: n,
        curl_energy_as_read: 2.0 * (s_e - s_ab),
        curl_energy_flipped: 2.0 * (s_e + s_ab),
        contrast,
        z,
        islands_as_read: isl
            .iter()
            .filter(decided)
            .filter(|i| i.1 / i.2 >= CONTRAST_MIN)
            .count(),
        islands_flipped: isl
            .iter()
            .filter(decided)
            .filter(|i| i.1 / i.2 <= -CONTRAST_MIN)
            .count(),
    };
    let verdict = if n < RELIEF_PLAQUETTES_MIN {
        GreenVerdict::Uncertain(Uncertainty::TooLittleRelief)
    } else if contrast.abs() < CONTRAST_MIN || z.abs() < Z_MIN {
        GreenVerdict::Uncertain(Uncertainty::Balanced)
    } else if contrast > 0.0 {
        GreenVerdict::OpenGl
    } else {
        GreenVerdict::DirectX
    };
    GreenConvention { verdict, evidence }
}

/// No island.
const NONE: u32 = u32::MAX;

/// `(A, B)` of every plaquette that votes, `[NaN, NaN]` for the others; row-major over the
/// `(w − 1) × (h − 1)` plaquettes.
fn plaquette_slopes(img: &RgbnImage) -> Vec<[f32; 2]> {
    let (w, h) = (img.width(), img.height());
    let (pw, ph) = (w.saturating_sub(1), h.saturating_sub(1));
    let [nx, ny, nz] = img.normal();
    let mask = img.mask();
    // Slope of a usable sample, None otherwise.
    let slope = |i: usize| -> Option<[f32; 2]> {
        let z = nz[i];
        let ok = mask.is_none_or(|m| inside(m[i]))
            && z >= NZ_MIN
            && nx[i].is_finite()
            && ny[i].is_finite()
            && z.is_finite();
        ok.then(|| [-nx[i] / z, -ny[i] / z])
    };
    let mut out = vec![[f32::NAN; 2]; pw * ph];
    out.par_chunks_mut(pw.max(1))
        .enumerate()
        .for_each(|(t, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let (top, bot) = (t * w + x, (t + 1) * w + x);
                let (Some(t0), Some(t1), Some(b0), Some(b1)) =
                    (slope(top), slope(top + 1), slope(bot), slope(bot + 1))
                else {
                    continue;
                };
                let span = |c: usize| {
                    let v = [t0[c], t1[c], b0[c], b1[c]];
                    v.iter().fold(f32::MIN, |a, &b| a.max(b))
                        - v.iter().fold(f32::MAX, |a, &b| a.min(b))
                };
                if span(0) >= SEAM_JUMP || span(1) >= SEAM_JUMP {
                    continue;
                }
                // y up: the top row is at larger y.
                let a = 0.5 * (t0[0] + t1[0] - b0[0] - b1[0]);
                let b = 0.5 * (t1[1] + b1[1] - t0[1] - b0[1]);
                if (a * a + b * b).sqrt() >= RELIEF_MIN {
                    *o = [a, b];
                }
            }
        });
    out
}

/// 8-connected components of the voting plaquettes, numbered from 0 ([`NONE`] elsewhere).
fn islands(ab: &[[f32; 2]], pw: usize, ph: usize) -> Vec<u32> {
    let mut label = vec![NONE; ab.len()];
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..ab.len() {
        if label[start] != NONE || ab[start][0].is_nan() {
            continue;
        }
        label[start] = next;
        stack.push(start);
        while let Some(k) = stack.pop() {
            let (x, t) = (k % pw, k / pw);
            for dt in -1isize..=1 {
                for dx in -1isize..=1 {
                    let (nxp, ntp) = (x as isize + dx, t as isize + dt);
                    if nxp < 0 || ntp < 0 || nxp >= pw as isize || ntp >= ph as isize {
                        continue;
                    }
                    let j = ntp as usize * pw + nxp as usize;
                    if label[j] == NONE && !ab[j][0].is_nan() {
                        label[j] = next;
                        stack.push(j);
                    }
                }
            }
        }
        next += 1;
    }
    label
}

#[cfg(test)]
#[path = "green_tests.rs"]
mod tests;
