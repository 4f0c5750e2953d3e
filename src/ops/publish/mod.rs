//! Publishing an RGBN image to the web: a folder of Deep Zoom tiles (albedo and normals as
//! separate images) with a WebGL2 viewer that relights them in the browser. Used by
//! `rgbn publish` and the `publish` node ([`crate::nodes::publish`]); `docs/publishing.md` says
//! how to show the folder here, in OpenSeadragon and in OpenLIME.
//!
//! # The folder
//!
//! - `index.html`: the page (the metadata inlined, so it needs no request for it);
//! - `viewer.js`: the WebGL2 viewer and its shaders (plain JavaScript, no build step);
//! - `rgbn.json`: size, Deep Zoom geometry, default shading, specular-enhancement parameters,
//!   curvature scale;
//! - `albedo.dzi` + `albedo_files/K/C_R.png`: colour, sRGB 8-bit (RGBA with the coverage in
//!   alpha when the image has a mask, else RGB);
//! - `normals.dzi` + `normals_files/K/C_R.png`: normals, 8-bit RGB `(n+1)/2` (OpenGL frame);
//! - `fallback/K.js`: the small levels again as `data:` URLs, for a page opened from disk
//!   ([`fallback`]);
//! - `.rgbn-publish`: the marker that lets a later publish replace this folder.
//!
//! The tiles are a standard Deep Zoom pyramid ([`pyramid`]): 512² tiles with one pixel of
//! overlap, levels halving down to one pixel, written level by level as the rows arrive —
//! [`publish_stream`] reads the files in strips ([`crate::raster::strips`]), so memory is
//! bounded by a strip and a band of tiles per level, not by the image.
//!
//! The folder is built beside the target (`.DIR.PID.SEQ.tmp`, see [`temp`]) and swapped into
//! place; a killed publish leaves the earlier one (or none) and a temporary removed next time; a non-empty
//! target that is not an earlier publish (no marker) is refused, and so is a target holding an
//! input file.

pub mod fallback;
pub mod pyramid;

pub use pyramid::{Level, Written};

use crate::error::RgbnError;
use crate::raster::io::temp;
use crate::raster::strips::{self, StreamInput};
use crate::raster::{RgbnImage, Validation};
use crate::render::curvature::ScaleOfStrips;
use crate::render::{LightSettings, Shading};
use pyramid::{PlaneRows, Pyramid};
use std::path::Path;

/// The page, with `/*RGBN_META*/` replaced by the metadata.
const INDEX_HTML: &str = include_str!("../../../web/index.html");
/// The viewer (script and shaders).
const VIEWER_JS: &str = include_str!("../../../web/viewer.js");
/// Marker file of a published folder.
pub const MARKER: &str = ".rgbn-publish";

/// Specular enhancement's defaults (RTIViewer): diffuse, specular strength, exponent.
pub const SPEC_KD: f32 = 0.4;
/// See [`SPEC_KD`].
pub const SPEC_KS: f32 = 0.7;
/// See [`SPEC_KD`].
pub const SPEC_ALPHA: f32 = 75.0;

crate::choice_enum! {
    /// The views the web viewer offers.
    pub enum WebView {
        /// Relit (Lambert + Blinn-Phong), as `rgbn render`.
        Relit = "relit",
        /// Normals encoded (n+1)/2.
        Normals = "normals",
        /// RTIViewer's specular enhancement: a grey, shiny material (albedo removed).
        SpecularEnhancement = "specular_enhancement",
        /// Mean curvature, red convex, blue concave.
        Curvature = "curvature",
    }
}

crate::params! {
    /// Parameters of the web publisher: the folder and the viewer's initial settings.
    #[derive(Clone, Debug, PartialEq)]
    pub struct PublishParams {
        /// Output folder (created; replaced only when it is an earlier publish).
        pub path: String = String::new() => path.output(),
        /// The viewer's initial light and shading (the relight node's parameters).
        pub shading: LightSettings = LightSettings::default() => flatten,
        /// The view the page opens with.
        pub view: WebView = WebView::Relit => choice,
    }
}

impl PublishParams {
    /// The viewer settings these parameters describe.
    #[must_use]
    pub fn options(&self) -> PublishOptions {
        PublishOptions {
            shading: self.shading.shading(),
            view: self.view,
        }
    }
}

/// What the published viewer starts with.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct PublishOptions {
    /// Lights (at most [`MAX_LIGHTS`]), ambient, specular, exposure.
    pub shading: Shading,
    /// The initial view.
    pub view: WebView,
}

/// Most lights the viewer's shader takes.
pub const MAX_LIGHTS: usize = 8;

/// What [`publish`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Published {
    /// Width and height of the image.
    pub size: (usize, usize),
    /// The Deep Zoom levels (level 0: one pixel; the last: the image).
    pub levels: Vec<Level>,
    /// Curvature scale passed to the viewer (px: the colour map shows `H · scale`).
    pub curvature_scale: f32,
    /// Tile files written and their bytes.
    pub tiles: Written,
    /// Files written in all (tiles, fallback scripts, descriptors, page, script, metadata).
    pub files: usize,
    /// Bytes written in all.
    pub bytes: u64,
    /// The Deep Zoom levels also written as `fallback/K.js`.
    pub fallback_levels: Vec<usize>,
}

/// Writes the web folder for `img` at `dir` (see the module docs). `inputs` are files the
/// caller read: a target equal to or containing one is refused.
///
/// # Errors
/// The parent folder is missing, `dir` is a file, a non-empty folder that is not an earlier
/// publish, or holds an input; shading parameters are invalid; writing fails (then nothing at
/// `dir` has changed).
pub fn publish(
    img: &RgbnImage,
    dir: &Path,
    opts: &PublishOptions,
    inputs: &[&Path],
) -> Result<Published, RgbnError> {
    let (w, h) = (img.width(), img.height());
    let cancel = crate::cancel::Cancel::current();
    build(dir, opts, inputs, (w, h), img.mask().is_some(), |pyr| {
        // In bands, so the pyramid's own band stays small.
        let rows = pyramid::TILE * 2;
        let mut y = 0;
        while y < h {
            // Cancelled: nothing is written (the folder is built aside and renamed at the end).
            cancel.check()?;
            let e = (y + rows).min(h);
            pyr.push(&plane_rows(img, y * w, e * w))?;
            y = e;
        }
        Ok(crate::render::curvature_scale(img, 0.0))
    })
}

/// [`publish`] from files read in strips (`strip` rows each; default
/// [`strips::strip_rows`]): memory is bounded by the strip and one band of tiles per level, and
/// the folder is byte for byte [`publish`]'s. `check` is called once per strip (e.g. to stop on
/// Ctrl-C). Returns what was written and what was repaired in the normals (as
/// [`crate::raster::io::load`] reports it).
///
/// # Errors
/// As [`publish`], and reading the files.
pub fn publish_stream<E: From<RgbnError>>(
    input: &mut StreamInput,
    dir: &Path,
    opts: &PublishOptions,
    inputs: &[&Path],
    strip: Option<usize>,
    check: impl Fn() -> Result<(), E>,
) -> Result<(Published, Validation), E> {
    let (w, h) = input.size();
    let mut repaired = Validation::default();
    let mut failed: Option<E> = None;
    let r = build(dir, opts, inputs, (w, h), input.has_mask(), |pyr| {
        let mut scale = ScaleOfStrips::new(w * h);
        // One row of context each way: the curvature's central differences.
        let strip = strip.unwrap_or_else(|| strips::strip_rows(w, 1)).max(1);
        let res = strips::for_each_strip_image(input, 1, strip, |img, _, core| {
            if let Err(e) = check() {
                failed = Some(e);
                return Err(RgbnError::Write {
                    detail: "stopped".into(),
                    path: dir.into(),
                });
            }
            let (a, b) = (core.start * w, core.end * w);
            let hv = crate::render::curvature::mean_curvature(img);
            scale.add(&hv[a..b], img.mask().map(|m| &m[a..b]));
            pyr.push(&plane_rows(img, a, b))
        });
        repaired = res?;
        Ok(scale.scale())
    });
    match (r, failed) {
        (_, Some(e)) => Err(e),
        (Ok(p), None) => Ok((p, repaired)),
        (Err(e), None) => Err(e.into()),
    }
}

/// Pixels `a..b` (whole rows) of `img` as rows for the pyramid.
fn plane_rows(img: &RgbnImage, a: usize, b: usize) -> PlaneRows<'_> {
    let [r, g, bl] = img.color();
    let [nx, ny, nz] = img.normal();
    PlaneRows {
        width: img.width(),
        color: Some([&r[a..b], &g[a..b], &bl[a..b]]),
        normal: [&nx[a..b], &ny[a..b], &nz[a..b]],
        coverage: img.mask().map(|m| &m[a..b]),
    }
}

/// Checks the options and the target, builds the folder beside `dir` (`feed` pushes the
/// image's rows into the pyramid and returns the curvature scale) and swaps it into place.
fn build(
    dir: &Path,
    opts: &PublishOptions,
    inputs: &[&Path],
    (w, h): (usize, usize),
    masked: bool,
    feed: impl FnOnce(&mut Pyramid<'_>) -> Result<f32, RgbnError>,
) -> Result<Published, RgbnError> {
    opts.shading.validate()?;
    if opts.shading.lights.len() > MAX_LIGHTS {
        return Err(RgbnError::param(
            "lights",
            format!(
                "the web viewer takes at most {MAX_LIGHTS} lights, got {}",
                opts.shading.lights.len()
            ),
        ));
    }
    check_target(dir, inputs)?;
    let parent = parent_of(dir);
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "published".into());
    let _writing = temp::WriteGuard::begin();
    recover_or_clean(parent, dir, &name);
    let tmp = temp::temp_path(parent, &name);
    std::fs::create_dir(&tmp).map_err(|e| RgbnError::Write {
        detail: format!("cannot create a folder beside it: {e}"),
        path: dir.into(),
    })?;
    let result =
        write_folder(&tmp, opts, (w, h), masked, feed).and_then(|p| install(&tmp, dir).map(|()| p));
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

fn parent_of(p: &Path) -> &Path {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Refuses a target that would lose data: see [`publish`].
fn check_target(dir: &Path, inputs: &[&Path]) -> Result<(), RgbnError> {
    let parent = parent_of(dir);
    if !parent.is_dir() {
        return Err(RgbnError::MissingDir { path: dir.into() });
    }
    if dir.file_name().is_none() {
        return Err(RgbnError::Write {
            detail: "not a folder name".into(),
            path: dir.into(),
        });
    }
    let Ok(meta) = std::fs::symlink_metadata(dir) else {
        return Ok(()); // a new folder
    };
    let dir_abs = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    for input in inputs {
        if std::fs::canonicalize(input).is_ok_and(|i| i.starts_with(&dir_abs)) {
            return Err(RgbnError::OutputIsInput { path: dir.into() });
        }
    }
    if !meta.is_dir() {
        return Err(RgbnError::Write {
            detail: "exists and is not a folder".into(),
            path: dir.into(),
        });
    }
    let non_empty = std::fs::read_dir(dir)
        .map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: dir.into(),
        })?
        .next()
        .is_some();
    if non_empty && !dir.join(MARKER).is_file() {
        return Err(RgbnError::Write {
            detail: format!(
                "folder is not empty and is not an earlier rgbn publish (no {MARKER}); choose a new or empty folder"
            ),
            path: dir.into(),
        });
    }
    Ok(())
}

/// Moves the finished folder `tmp` to `dir`, replacing an earlier publish there: swapped in one
/// step where the system can (Linux `renameat2(RENAME_EXCHANGE)`), else renamed aside first
/// (a process killed between the two renames leaves the earlier publish aside, and the next
/// publish puts it back: [`recover_or_clean`]).
fn install(tmp: &Path, dir: &Path) -> Result<(), RgbnError> {
    let werr = |e: std::io::Error| RgbnError::Write {
        detail: e.to_string(),
        path: dir.into(),
    };
    if std::fs::symlink_metadata(dir).is_err() {
        return std::fs::rename(tmp, dir).map_err(werr);
    }
    if exchange(tmp, dir) {
        // `tmp` now holds the earlier publish.
        let _ = std::fs::remove_dir_all(tmp);
        return Ok(());
    }
    let name = dir.file_name().unwrap_or_default().to_string_lossy();
    let old = temp::temp_path(parent_of(dir), &format!("{name}{OLD}"));
    std::fs::rename(dir, &old).map_err(werr)?;
    if let Err(e) = std::fs::rename(tmp, dir) {
        let _ = std::fs::rename(&old, dir);
        return Err(werr(e));
    }
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// Suffix of the stem under which an earlier publish is set aside while being replaced.
const OLD: &str = ".old";

/// Swaps two paths atomically; false where the system cannot (then nothing changed).
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> bool {
    use std::os::unix::ffi::OsStrExt;
    let (Ok(a), Ok(b)) = (
        std::ffi::CString::new(a.as_os_str().as_bytes()),
        std::ffi::CString::new(b.as_os_str().as_bytes()),
    ) else {
        return false;
    };
    // SAFETY: two valid NUL-terminated paths relative to the working directory.
    let r = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    r == 0
}
#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> bool {
    false
}

/// Before publishing to `dir` (named `name` in `parent`): an earlier publish that a killed
/// process had set aside while replacing it is put back when `dir` is missing, and the
/// temporaries of killed processes are removed.
fn recover_or_clean(parent: &Path, dir: &Path, name: &str) {
    let aside = format!("{name}{OLD}");
    if std::fs::symlink_metadata(dir).is_err() {
        if let Ok(entries) = std::fs::read_dir(parent) {
            for e in entries.flatten() {
                let n = e.file_name();
                let stale = n
                    .to_str()
                    .and_then(temp::parse)
                    .is_some_and(|(s, pid)| s == aside && !temp::alive(pid));
                if stale && std::fs::rename(e.path(), dir).is_ok() {
                    break;
                }
            }
        }
    }
    temp::clean_stale(parent, Some(&aside));
    temp::clean_stale(parent, Some(name));
}

/// Writes every file of the folder into `dir` (an empty folder).
fn write_folder(
    dir: &Path,
    opts: &PublishOptions,
    (w, h): (usize, usize),
    masked: bool,
    feed: impl FnOnce(&mut Pyramid<'_>) -> Result<f32, RgbnError>,
) -> Result<Published, RgbnError> {
    let mut pyr = Pyramid::new(dir, w, h, masked);
    let levels = pyr.levels();
    let scale = feed(&mut pyr)?;
    let (tiles, fallback_levels) = pyr.finish()?;
    let meta = Meta {
        size: (w, h),
        masked,
        levels: &levels,
        fallback_levels: &fallback_levels,
        scale,
        opts,
    };
    let json = meta.json();
    let mut files = tiles.tiles + fallback_levels.len();
    let mut bytes = tiles.bytes
        + fallback_levels
            .iter()
            .map(|k| file_len(&dir.join(format!("fallback/{k}.js"))))
            .sum::<u64>();
    let dzi = pyramid::dzi(w, h);
    let html = INDEX_HTML.replace("/*RGBN_META*/", &json);
    for (name, text) in [
        ("albedo.dzi", dzi.as_str()),
        ("normals.dzi", dzi.as_str()),
        ("rgbn.json", json.as_str()),
        ("viewer.js", VIEWER_JS),
        ("index.html", html.as_str()),
        (
            MARKER,
            "This folder was written by `rgbn publish`; a later publish may replace it.\n",
        ),
    ] {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: p.clone(),
        })?;
        files += 1;
        bytes += text.len() as u64;
    }
    Ok(Published {
        size: (w, h),
        levels,
        curvature_scale: scale,
        tiles,
        files,
        bytes,
        fallback_levels,
    })
}

fn file_len(p: &Path) -> u64 {
    std::fs::metadata(p).map_or(0, |m| m.len())
}

/// What `rgbn.json` says.
struct Meta<'a> {
    size: (usize, usize),
    masked: bool,
    levels: &'a [Level],
    fallback_levels: &'a [usize],
    scale: f32,
    opts: &'a PublishOptions,
}

impl Meta<'_> {
    /// `rgbn.json`: everything the viewer needs besides the tiles.
    fn json(&self) -> String {
        let s = &self.opts.shading;
        let v3 = |v: [f32; 3]| format!("[{}, {}, {}]", v[0], v[1], v[2]);
        let lights: Vec<String> = s
            .lights
            .iter()
            .map(|l| {
                format!(
                    "{{\"direction\": {}, \"color\": {}}}",
                    v3(l.direction),
                    v3(l.color)
                )
            })
            .collect();
        let sizes: Vec<String> = self
            .levels
            .iter()
            .map(|l| format!("[{}, {}]", l.width, l.height))
            .collect();
        let fb: Vec<String> = self.fallback_levels.iter().map(usize::to_string).collect();
        format!(
            r#"{{
  "format": "rgbn-publish",
  "version": 2,
  "generator": "rgbn {}",
  "width": {},
  "height": {},
  "masked": {},
  "view": "{}",
  "curvature_scale": {},
  "shading": {{
    "lights": [{}],
    "ambient": {},
    "specular": {},
    "shininess": {},
    "exposure_ev": {}
  }},
  "specular_enhancement": {{"kd": {SPEC_KD}, "ks": {SPEC_KS}, "alpha": {SPEC_ALPHA}}},
  "tiles": {{
    "layout": "deepzoom",
    "layers": {{"albedo": "albedo.dzi", "normals": "normals.dzi"}},
    "format": "png",
    "tile_size": {},
    "overlap": {},
    "levels": [{}],
    "fallback_levels": [{}]
  }}
}}
"#,
            env!("CARGO_PKG_VERSION"),
            self.size.0,
            self.size.1,
            self.masked,
            crate::params::Choice::name(self.opts.view),
            self.scale,
            lights.join(", "),
            s.ambient,
            s.specular,
            s.shininess,
            s.exposure_ev,
            pyramid::TILE,
            pyramid::OVERLAP,
            sizes.join(", "),
            fb.join(", "),
        )
    }
}
