//! Publishing an RGBN image to the web: a self-contained folder (`index.html`, `viewer.js`,
//! `image.json` and the image as PNG textures) that relights the image in any WebGL2 browser
//! with no network access. Used by `rgbn publish` and the `publish` node
//! ([`crate::nodes::publish`]).
//!
//! # The folder
//!
//! - `index.html`: the page (the metadata is also inlined in it, so that no request other than
//!   the textures is needed);
//! - `viewer.js`: the WebGL2 viewer and its shaders (plain JavaScript, no build step);
//! - `image.json`: size, levels, default shading, specular-enhancement parameters and the
//!   curvature scale;
//! - `tiles/L/C_R.albedo.png`: colour, sRGB 8-bit RGBA with the coverage in alpha;
//! - `tiles/L/C_R.normals.png`: normals, 8-bit RGB `(n+1)/2` (OpenGL convention);
//! - `tiles/L/C_R.*.js`: the same PNGs as `data:` URLs in scripts, used by the viewer when
//!   the page is opened from `file://` (browsers refuse plain image files there as WebGL
//!   textures, but accept `data:` URLs);
//! - `.rgbn-publish`: the marker that lets a later publish replace this folder.
//!
//! Level `L` halves level `L − 1` (2×2 means: colour and normals weighted by coverage, normals
//! renormalised); level 0 is the image. Images of at most [`MAX_LEVEL_SIDE`] pixels a side
//! have one level of one tile; larger images get levels down to one that fits in
//! [`MAX_LEVEL_SIDE`], cut into tiles of [`TILE`]² pixels (column `C`, row `R`).
//!
//! The folder is built beside the target (`.DIR.PID.SEQ.tmp`, see [`temp`]) and swapped into
//! place; a killed publish leaves the earlier one (or none) and a temporary removed next time; a non-empty
//! target that is not an earlier publish (no marker) is refused, and so is a target holding an
//! input file.

use crate::error::RgbnError;
use crate::raster::io::{self, temp, Format};
use crate::raster::srgb::linear_to_srgb;
use crate::raster::RgbnImage;
use crate::render::{Light, Shading};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The page, with `/*RGBN_META*/` replaced by the metadata.
const INDEX_HTML: &str = include_str!("../../web/index.html");
/// The viewer (script and shaders).
const VIEWER_JS: &str = include_str!("../../web/viewer.js");
/// Marker file of a published folder.
pub const MARKER: &str = ".rgbn-publish";
/// Largest side of a level loaded as one texture; larger images get a pyramid.
pub const MAX_LEVEL_SIDE: usize = 4096;
/// Tile side of pyramid levels.
pub const TILE: usize = 1024;

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
        /// Initial direction towards the light (+x right, +y up, +z to the viewer).
        pub light: [f64; 3] = Shading::default().lights[0].direction.map(f64::from)
            => vec3.range(-1e3, 1e3),
        /// Ambient light added to the diffuse term.
        pub ambient: f64 = f64::from(Shading::default().ambient) => float.range(0.0, 10.0),
        /// Blinn-Phong specular strength (0 = Lambert only).
        pub specular: f64 = f64::from(Shading::default().specular) => float.range(0.0, 10.0),
        /// Blinn-Phong exponent.
        pub shininess: f64 = f64::from(Shading::default().shininess)
            => float.range(0.0, 10000.0),
        /// Initial exposure.
        pub exposure_ev: f64 = f64::from(Shading::default().exposure_ev)
            => float.unit("EV").range(-32.0, 32.0),
        /// The view the page opens with.
        pub view: WebView = WebView::Relit => choice,
    }
}

impl PublishParams {
    /// The viewer settings these parameters describe.
    #[must_use]
    pub fn options(&self) -> PublishOptions {
        PublishOptions {
            shading: Shading {
                lights: vec![Light::white(self.light.map(|c| c as f32))],
                ambient: self.ambient as f32,
                specular: self.specular as f32,
                shininess: self.shininess as f32,
                exposure_ev: self.exposure_ev as f32,
            },
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

/// One level of the pyramid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Level {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Tile side in pixels (the last column and row may be smaller).
    pub tile: usize,
    /// Tile columns.
    pub cols: usize,
    /// Tile rows.
    pub rows: usize,
}

/// The levels for a `width × height` image: one level, one tile when both sides are at most
/// [`MAX_LEVEL_SIDE`]; else halvings (rounding up) until both sides fit, in [`TILE`]² tiles.
#[must_use]
pub fn levels(width: usize, height: usize) -> Vec<Level> {
    let (w, h) = (width.max(1), height.max(1));
    if w.max(h) <= MAX_LEVEL_SIDE {
        return vec![Level {
            width: w,
            height: h,
            tile: w.max(h),
            cols: 1,
            rows: 1,
        }];
    }
    let mut out = Vec::new();
    let (mut lw, mut lh) = (w, h);
    loop {
        out.push(Level {
            width: lw,
            height: lh,
            tile: TILE,
            cols: lw.div_ceil(TILE),
            rows: lh.div_ceil(TILE),
        });
        if lw.max(lh) <= MAX_LEVEL_SIDE {
            return out;
        }
        (lw, lh) = (lw.div_ceil(2), lh.div_ceil(2));
    }
}

/// What [`publish`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Published {
    /// The pyramid levels (level 0 = the image).
    pub levels: Vec<Level>,
    /// Curvature scale passed to the viewer (px: the colour map shows `H · scale`).
    pub curvature_scale: f32,
    /// Files written (textures, page, script, metadata).
    pub files: usize,
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
    let result = write_folder(img, &tmp, opts).and_then(|p| install(&tmp, dir).map(|()| p));
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

/// Planes of one level: linear colour, unit normals, coverage.
struct Planes {
    width: usize,
    height: usize,
    color: [Vec<f32>; 3],
    normal: [Vec<f32>; 3],
    coverage: Vec<f32>,
}

impl Planes {
    fn of(img: &RgbnImage) -> Self {
        Self {
            width: img.width(),
            height: img.height(),
            color: img.color().clone(),
            normal: img.normal().clone(),
            coverage: img
                .mask()
                .map_or_else(|| vec![1.0; img.len()], <[f32]>::to_vec),
        }
    }

    /// The next level: 2×2 means (the last column/row alone when the side is odd), colour and
    /// normals weighted by coverage, normals renormalised.
    fn half(&self) -> Self {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let n = w * h;
        let mut out = Self {
            width: w,
            height: h,
            color: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            normal: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            coverage: vec![0.0; n],
        };
        for y in 0..h {
            for x in 0..w {
                let mut src = Vec::with_capacity(4);
                for sy in 2 * y..(2 * y + 2).min(self.height) {
                    for sx in 2 * x..(2 * x + 2).min(self.width) {
                        src.push(sy * self.width + sx);
                    }
                }
                let cov: f32 = src.iter().map(|&i| self.coverage[i]).sum();
                let wsum = if cov > 0.0 { cov } else { src.len() as f32 };
                let weight = |i: usize| {
                    if cov > 0.0 {
                        self.coverage[i]
                    } else {
                        1.0
                    }
                };
                let o = y * w + x;
                for j in 0..3 {
                    out.color[j][o] = src
                        .iter()
                        .map(|&i| weight(i) * self.color[j][i])
                        .sum::<f32>()
                        / wsum;
                }
                let v: [f32; 3] = std::array::from_fn(|j| {
                    src.iter().map(|&i| weight(i) * self.normal[j][i]).sum()
                });
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                let v = if len > 1e-12 && len.is_finite() {
                    v.map(|c| c / len)
                } else {
                    [0.0, 0.0, 1.0]
                };
                for (plane, c) in out.normal.iter_mut().zip(v) {
                    plane[o] = c;
                }
                out.coverage[o] = cov / src.len() as f32;
            }
        }
        out
    }

    /// RGBA8 sRGB albedo (coverage in alpha) and RGB8 normals of the tile at `(x0, y0)`.
    fn tile_bytes(&self, x0: usize, y0: usize, tw: usize, th: usize) -> (Vec<u8>, Vec<u8>) {
        let mut albedo = Vec::with_capacity(tw * th * 4);
        let mut normals = Vec::with_capacity(tw * th * 3);
        let srgb8 = |v: f32| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8;
        let unit8 = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 127.5 + 0.5) as u8;
        for y in y0..y0 + th {
            for x in x0..x0 + tw {
                let i = y * self.width + x;
                albedo.extend(self.color.iter().map(|p| srgb8(p[i])));
                albedo.push((self.coverage[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
                normals.extend(self.normal.iter().map(|p| unit8(p[i])));
            }
        }
        (albedo, normals)
    }
}

/// Writes every file of the folder into `dir` (an empty folder).
fn write_folder(
    img: &RgbnImage,
    dir: &Path,
    opts: &PublishOptions,
) -> Result<Published, RgbnError> {
    let lv = levels(img.width(), img.height());
    let mut files = 0;
    let mut planes = Planes::of(img);
    for (l, level) in lv.iter().enumerate() {
        if l > 0 {
            planes = planes.half();
        }
        debug_assert_eq!((planes.width, planes.height), (level.width, level.height));
        let ldir = dir.join("tiles").join(l.to_string());
        std::fs::create_dir_all(&ldir).map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: ldir.clone(),
        })?;
        for r in 0..level.rows {
            for c in 0..level.cols {
                let (x0, y0) = (c * level.tile, r * level.tile);
                let tw = level.tile.min(level.width - x0);
                let th = level.tile.min(level.height - y0);
                let (albedo, normals) = planes.tile_bytes(x0, y0, tw, th);
                let stem = format!("{c}_{r}");
                for (what, bytes, channels) in [("albedo", &albedo, 4), ("normals", &normals, 3)] {
                    let png = ldir.join(format!("{stem}.{what}.png"));
                    io::write_raster8(bytes, tw, th, channels, Format::Png, &png)?;
                    write_embedded(&png, &format!("tiles/{l}/{stem}.{what}"))?;
                }
                files += 4;
            }
        }
    }
    let scale = crate::render::curvature_scale(img, 0.0);
    let json = metadata_json(img, &lv, scale, opts);
    let write_text = |name: &str, text: &str| {
        io::write_atomic(&dir.join(name), |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })
    };
    write_text("image.json", &json)?;
    write_text("viewer.js", VIEWER_JS)?;
    write_text("index.html", &INDEX_HTML.replace("/*RGBN_META*/", &json))?;
    write_text(
        MARKER,
        "This folder was written by `rgbn publish`; a later publish may replace it.\n",
    )?;
    files += 4;
    Ok(Published {
        levels: lv,
        curvature_scale: scale,
        files,
    })
}

/// Writes `NAME.js` beside the PNG `NAME.png`: a script handing the PNG as a `data:` URL to
/// the viewer (`rgbnTexture(name, url)`), which browsers let a page opened from `file://` use
/// as a WebGL texture (the plain PNG they refuse there).
fn write_embedded(png: &Path, name: &str) -> Result<(), RgbnError> {
    let bytes = std::fs::read(png).map_err(|e| RgbnError::Write {
        detail: e.to_string(),
        path: png.into(),
    })?;
    let js = png.with_extension("js");
    io::write_atomic(&js, |w| {
        use std::io::Write;
        write!(w, "rgbnTexture(\"{name}\", \"data:image/png;base64,")
            .and_then(|()| w.write_all(base64(&bytes).as_bytes()))
            .and_then(|()| w.write_all(b"\");\n"))
            .map_err(|e| e.to_string())
    })
}

/// Standard base64 (RFC 4648, padded).
fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ABC[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// `image.json`: everything the viewer needs besides the textures.
fn metadata_json(img: &RgbnImage, levels: &[Level], scale: f32, opts: &PublishOptions) -> String {
    let s = &opts.shading;
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
    let mut lv = String::new();
    for (i, l) in levels.iter().enumerate() {
        let _ = write!(
            lv,
            "{}\n    {{\"width\": {}, \"height\": {}, \"tile\": {}, \"cols\": {}, \"rows\": {}, \"path\": \"tiles/{i}\"}}",
            if i == 0 { "" } else { "," },
            l.width,
            l.height,
            l.tile,
            l.cols,
            l.rows
        );
    }
    format!(
        r#"{{
  "format": "rgbn-publish",
  "version": 1,
  "generator": "rgbn {}",
  "width": {},
  "height": {},
  "masked": {},
  "view": "{}",
  "curvature_scale": {scale},
  "shading": {{
    "lights": [{}],
    "ambient": {},
    "specular": {},
    "shininess": {},
    "exposure_ev": {}
  }},
  "specular_enhancement": {{"kd": {SPEC_KD}, "ks": {SPEC_KS}, "alpha": {SPEC_ALPHA}}},
  "levels": [{lv}
  ]
}}
"#,
        env!("CARGO_PKG_VERSION"),
        img.width(),
        img.height(),
        img.mask().is_some(),
        crate::params::Choice::name(opts.view),
        lights.join(", "),
        s.ambient,
        s.specular,
        s.shininess,
        s.exposure_ev,
    )
}

/// Where [`publish`] puts a level's tile (relative to the folder).
#[must_use]
pub fn tile_path(level: usize, col: usize, row: usize, what: &str) -> PathBuf {
    PathBuf::from(format!("tiles/{level}/{col}_{row}.{what}.png"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::sample::Surface;

    #[test]
    fn small_images_have_one_level_of_one_tile_large_ones_a_pyramid() {
        assert_eq!(
            levels(300, 200),
            vec![Level {
                width: 300,
                height: 200,
                tile: 300,
                cols: 1,
                rows: 1
            }]
        );
        let l = levels(9000, 300);
        let sizes: Vec<(usize, usize, usize, usize)> = l
            .iter()
            .map(|l| (l.width, l.height, l.cols, l.rows))
            .collect();
        assert_eq!(
            sizes,
            [(9000, 300, 9, 1), (4500, 150, 5, 1), (2250, 75, 3, 1)]
        );
    }

    #[test]
    fn base64_matches_rfc_4648() {
        for (raw, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(raw.as_bytes()), enc);
        }
        assert_eq!(base64(&[0xff, 0xfe, 0x00]), "//4A");
    }

    #[test]
    fn halving_keeps_unit_normals_and_coverage_means() {
        let (img, _) = Surface::Sphere { radius_px: 10.0 }.render(25, 23);
        let p = Planes::of(&img).half();
        assert_eq!((p.width, p.height), (13, 12));
        for i in 0..p.width * p.height {
            let n = [p.normal[0][i], p.normal[1][i], p.normal[2][i]];
            assert!((n.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-5);
            assert!((0.0..=1.0).contains(&p.coverage[i]));
        }
    }
}
