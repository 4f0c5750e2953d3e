//! Strip streaming: an image whose files are read row by row ([`io::stream`](crate::raster::io::stream)) is processed in
//! horizontal strips, each with `halo` rows of context above and below, and the strips' results
//! are written row by row. Peak memory is a window of `strip + 2·halo` rows, whatever the
//! image's height (issue 12, item 5; libvips' "sequential" access).
//!
//! A strip's window starts and ends either at the image's own edge, where a border mode applies
//! exactly as on the whole image, or at least `halo` rows from the strip: an operation whose
//! footprint is within `halo` gives the strip the rows it gives the whole image (bit for bit for
//! finite kernels; within the documented truncation of a recursive Gaussian,
//! [`crate::raster::convolve::gaussian_support`]). Consecutive windows overlap by `2·halo` rows,
//! which are kept, not read again: each file is read once, top to bottom.

use super::io::stream::{ExrRows, RowMap, Rows, Samples};
use super::io::{Format, InputSpec, LoadOptions, NormalConvention, DEFAULT_ALBEDO};
use super::{RgbnImage, Validation, MIN_NORMAL_LENGTH};
use crate::error::RgbnError;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;

/// Above this many pixels, `rgbn filter` streams by default (`--stream auto`): twice a 4K
/// image, where reading whole would take about 1.6 GB.
pub const AUTO_STREAM_PIXELS: u64 = 16 << 20;

/// From this many pixels, `rgbn eval` and `rgbn batch` stream a graph that can be streamed by
/// default: its strips keep the decoding, which cannot be split, running beside the
/// operators and the compression of the outputs (a whole-image run does one after the other),
/// and the memory is the strip's (BENCHMARKS.md, 2026-12-03, the 4K `rgbn eval` rows). Below
/// (a few strips) there is little to overlap.
pub const AUTO_STREAM_GRAPH_PIXELS: u64 = 2 << 20;

/// Pixels of a strip (its window without the halos) when the caller does not choose: large
/// enough that the halos cost little (two 33-row halos on 512 rows of a 16384-wide image), small
/// enough that a window of a few planes stays far below a GiB.
pub const STRIP_PIXELS: usize = 8 << 20;

/// The rows per strip for an image `width` wide and a `halo`: [`STRIP_PIXELS`] worth, at least
/// 64 rows and four halos.
#[must_use]
pub fn strip_rows(width: usize, halo: usize) -> usize {
    strip_rows_of(width, halo, STRIP_PIXELS)
}

/// The rows per strip for a strip of about `pixels` pixels: at least 64 rows and four halos.
#[must_use]
pub fn strip_rows_of(width: usize, halo: usize, pixels: usize) -> usize {
    (pixels / width.max(1)).max(64).max(4 * halo)
}

/// The files of an RGBN image opened for reading top to bottom: a normal map and optional
/// colour and mask (PNG or TIFF), or the channels of an RGBN EXR.
pub struct StreamInput {
    normal: Rows,
    color: Option<Rows>,
    mask: Option<Rows>,
    opts: LoadOptions,
}

/// What [`StreamInput::open`] found.
pub enum Opened {
    /// The files can be streamed.
    Stream(Box<StreamInput>),
    /// They cannot; the reason, e.g. "the normal map is an EXR" (read them whole).
    Whole(String),
}

impl StreamInput {
    /// Opens the files of `spec` for streaming, or says why they must be read whole (a PTM or
    /// JPEG, an interlaced PNG, a tiled TIFF or EXR, a colour or mask file in EXR). Errors are
    /// those of reading the headers (missing file, not an image, sizes that differ).
    ///
    /// An EXR is read as [`super::io::load_exr`] reads it: normals `N.X,N.Y,N.Z` (or `R,G,B`
    /// with [`LoadOptions::exr_rgb_is_normal`]), colour `R,G,B` and mask `A` when present,
    /// unless a colour or mask file is named.
    pub fn open(spec: &InputSpec, opts: &LoadOptions) -> Result<Opened, RgbnError> {
        let Some(normal_path) = spec.rgbn.as_ref().or(spec.normal.as_ref()) else {
            return Ok(Opened::Whole("no normal map is named".into()));
        };
        let open = |what: &str, p: &Path| -> Result<Result<Rows, String>, RgbnError> {
            if what != "normal map" && Format::of(p)? == Format::Exr {
                return Ok(Err(format!("the {what} is an EXR (read whole)")));
            }
            Ok(Rows::open(p)?.map_err(|why| format!("the {what} is {why}")))
        };
        let (mut exr_color, mut exr_mask) = (None, None);
        let normal = if Format::of(normal_path)? == Format::Zarr {
            if spec.color.is_some() || spec.mask.is_some() {
                return Ok(Opened::Whole(
                    "a colour or mask file is named beside the store (read whole)".into(),
                ));
            }
            let z = std::sync::Arc::new(super::io::zarr::ZarrImage::open(normal_path)?);
            if !matches!(z.content(), super::io::zarr::Content::Rgbn { .. }) {
                // Read whole: the loader says what the store holds.
                return Ok(Opened::Whole("the store holds no RGBN image".into()));
            }
            let (n, c, m) = z.rows();
            exr_color = c.map(|r| Rows::Zarr(Box::new(r)));
            exr_mask = m.map(|r| Rows::Zarr(Box::new(r)));
            Rows::Zarr(Box::new(n))
        } else if Format::of(normal_path)? == Format::Exr {
            let p = normal_path.as_path();
            let names = if opts.exr_rgb_is_normal {
                ["R", "G", "B"]
            } else {
                ["N.X", "N.Y", "N.Z"]
            };
            let have = ExrRows::channel_names(p)?;
            let has = |names: &[&str]| names.iter().all(|n| have.iter().any(|h| h == n));
            if !has(&names) {
                // Read whole, the loader says what is missing.
                return Ok(Opened::Whole(format!(
                    "the normal map is an EXR without channels {}",
                    names.join(",")
                )));
            }
            let exr = |names: &[&str]| -> Result<Result<Rows, String>, RgbnError> {
                Ok(ExrRows::open(p, names)?
                    .map(|r| Rows::Exr(Box::new(r)))
                    .map_err(|why| format!("the normal map is {why}")))
            };
            let normal = match exr(&names)? {
                Ok(r) => r,
                Err(why) => return Ok(Opened::Whole(why)),
            };
            if !opts.exr_rgb_is_normal && spec.color.is_none() && has(&["R", "G", "B"]) {
                exr_color = exr(&["R", "G", "B"])?.ok();
            }
            if spec.mask.is_none() && has(&["A"]) {
                exr_mask = exr(&["A"])?.ok();
            }
            normal
        } else {
            match open("normal map", normal_path)? {
                Ok(r) => r,
                Err(why) => return Ok(Opened::Whole(why)),
            }
        };
        if normal.channels() < 3 {
            return Err(RgbnError::Decode {
                detail: format!(
                    "a normal map needs 3 channels, this image has {}",
                    normal.channels()
                ),
                path: normal.path().into(),
            });
        }
        let (w, h) = normal.size();
        let part = |what: &'static str, p: &Option<std::path::PathBuf>| {
            let Some(p) = p else { return Ok(Ok(None)) };
            match open(what, p)? {
                Ok(r) if r.size() != (w, h) => Err(RgbnError::SizeMismatch {
                    what: if what == "colour image" {
                        "colour image"
                    } else {
                        "mask"
                    },
                    want_w: w,
                    want_h: h,
                    got_w: r.size().0,
                    got_h: r.size().1,
                    path: p.clone(),
                }),
                Ok(r) => Ok(Ok(Some(r))),
                Err(why) => Ok(Err(why)),
            }
        };
        let color = match part("colour image", &spec.color)? {
            Ok(c) => c.or(exr_color),
            Err(why) => return Ok(Opened::Whole(why)),
        };
        let mask = match part("mask", &spec.mask)? {
            Ok(m) => m.or(exr_mask),
            Err(why) => return Ok(Opened::Whole(why)),
        };
        Ok(Opened::Stream(Box::new(StreamInput {
            normal,
            color,
            mask,
            opts: opts.clone(),
        })))
    }

    /// Width and height in pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        self.normal.size()
    }

    /// Reads only `window` of the image from now on, before the first strip (only OME-Zarr
    /// stores: [`Rows::set_window`]); the strips are then the window's, whose edges the
    /// operators take for the image's (a caller keeps only what lies a halo inside them).
    pub fn set_window(&mut self, window: crate::raster::window::Rect) -> Result<(), String> {
        self.normal.set_window(window)?;
        if let Some(c) = &mut self.color {
            c.set_window(window)?;
        }
        if let Some(m) = &mut self.mask {
            m.set_window(window)?;
        }
        Ok(())
    }

    /// Whether a colour image is read (else the colour is [`DEFAULT_ALBEDO`]).
    #[must_use]
    pub fn has_color(&self) -> bool {
        self.color.is_some()
    }

    /// Whether a mask is read.
    #[must_use]
    pub fn has_mask(&self) -> bool {
        self.mask.is_some()
    }
}

/// The planes of a window: rows `y0 .. y0 + rows` of the image.
#[derive(Default)]
struct Planes {
    y0: usize,
    rows: usize,
    normal: [Vec<f32>; 3],
    color: Option<[Vec<f32>; 3]>,
    mask: Option<Vec<f32>>,
}

impl Planes {
    fn all_mut(&mut self) -> impl Iterator<Item = &mut Vec<f32>> {
        self.normal
            .iter_mut()
            .chain(self.color.iter_mut().flatten())
            .chain(self.mask.as_mut())
    }
}

/// One strip as its callback sees it.
pub struct Window<'a> {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// The image row of the window's first row.
    pub y0: usize,
    /// The window's rows that this strip produces (window rows; the rest is halo).
    pub core: Range<usize>,
    /// Normal x, y, z planes of the window (repaired: unit length, `(0, 0, 1)` where the file
    /// had none).
    pub normal: [&'a [f32]; 3],
    /// Linear colour planes, when a colour image is read.
    pub color: Option<[&'a [f32]; 3]>,
    /// Coverage, when a mask is read.
    pub mask: Option<&'a [f32]>,
}

impl Window<'_> {
    /// Rows in the window.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.normal[0].len() / self.width
    }

    /// The core rows of a window plane.
    #[must_use]
    pub fn core_of<'p>(&self, plane: &'p [f32]) -> &'p [f32] {
        &plane[self.core.start * self.width..self.core.end * self.width]
    }

    /// The window as an image (copies its planes; colour [`DEFAULT_ALBEDO`] without a colour
    /// image).
    pub fn image(&self) -> Result<RgbnImage, RgbnError> {
        let n = self.normal[0].len();
        let color = match self.color {
            Some(c) => c.map(<[f32]>::to_vec),
            None => std::array::from_fn(|_| vec![DEFAULT_ALBEDO; n]),
        };
        RgbnImage::new(
            self.width,
            self.rows(),
            color,
            self.normal.map(<[f32]>::to_vec),
            self.mask.map(<[f32]>::to_vec),
        )
    }
}

/// Normalises decoded normals as [`RgbnImage::repair`] does (zero-length ones become
/// `(0, 0, 1)`) and counts what needed it. The loop is branch-free (selects and mask counts),
/// so it vectorises; a pixel at a time through three zipped parallel iterators was a tenth of
/// a streamed 4K graph's CPU time.
pub(crate) fn repair_normals([nx, ny, nz]: [&mut [f32]; 3]) -> Validation {
    let (mut zero, mut non_unit, mut back) = (0usize, 0usize, 0usize);
    for ((x, y), z) in nx.iter_mut().zip(ny.iter_mut()).zip(nz.iter_mut()) {
        let len = (*x * *x + *y * *y + *z * *z).sqrt();
        let is_zero = len < MIN_NORMAL_LENGTH;
        zero += usize::from(is_zero);
        non_unit += usize::from(!is_zero & ((len - 1.0).abs() > 1e-3));
        back += usize::from(!is_zero & (*z <= 0.0));
        (*x, *y, *z) = if is_zero {
            (0.0, 0.0, 1.0)
        } else {
            (*x / len, *y / len, *z / len)
        };
    }
    Validation {
        pixels: nx.len(),
        zero_length_normal: zero,
        non_unit,
        back_facing: back,
        ..Validation::default()
    }
}

/// Rows `y0..y1` of the files, decoded and not yet mapped ([`Samples`]; the normals not yet
/// repaired either: [`append_band`]).
struct Band {
    y0: usize,
    y1: usize,
    normal: Samples,
    color: Option<Samples>,
    mask: Option<Samples>,
}

/// With `strict` loading, rows with a normal that needed repair are an error (its count is
/// theirs; `rows` names them).
fn check_strict(
    repaired: Validation,
    strict: bool,
    path: &Path,
    rows: Range<usize>,
) -> Result<Validation, RgbnError> {
    if strict && !repaired.is_clean() {
        let (count, kind) = if repaired.zero_length_normal > 0 {
            (repaired.zero_length_normal, "zero-length")
        } else {
            (repaired.non_unit, "not unit length")
        };
        return Err(RgbnError::InvalidNormals {
            count,
            kind: format!("{kind}, in rows {}..{}", rows.start, rows.end),
            path: path.into(),
        });
    }
    Ok(repaired)
}

/// Rows of the window appended from one band at a time, mapped on the pool in blocks of this
/// many rows.
const APPEND_ROWS: usize = 8;

/// Appends `band`'s rows to the window's planes: each file's samples mapped to `f32`
/// ([`Samples::map_rows`]) straight into the planes' new rows and the normals repaired there
/// ([`repair_normals`], as [`crate::raster::io::load`] does), blocks of rows in parallel, one
/// pass. This is the caller's work, between two strips' parallel work; the reading thread,
/// whose decoding is the one part that cannot be split, only decodes. Returns what was
/// repaired.
fn append_band(
    win: &mut Planes,
    band: &Band,
    w: usize,
    convention: NormalConvention,
) -> Validation {
    let rows = band.y1 - band.y0;
    let n = rows * w;
    if n == 0 {
        return Validation::default();
    }
    // The files in the order of `Planes::all_mut`, with their planes' count.
    let files: Vec<(&Samples, RowMap, usize)> = [
        Some((&band.normal, RowMap::Normal(convention), 3)),
        band.color.as_ref().map(|c| (c, RowMap::Srgb, 3)),
        band.mask.as_ref().map(|m| (m, RowMap::Unit, 1)),
    ]
    .into_iter()
    .flatten()
    .collect();
    let blocks = rows.div_ceil(APPEND_ROWS);
    let mut per_block: Vec<Vec<&mut [MaybeUninit<f32>]>> =
        (0..blocks).map(|_| Vec::with_capacity(7)).collect();
    let mut planes = 0;
    for p in win.all_mut() {
        // Exactly: a doubling growth would hold up to twice the window.
        p.reserve_exact(n);
        for (b, part) in p.spare_capacity_mut()[..n]
            .chunks_mut(APPEND_ROWS * w)
            .enumerate()
        {
            per_block[b].push(part);
        }
        planes += 1;
    }
    assert_eq!(planes, files.iter().map(|f| f.2).sum::<usize>());
    let repaired = per_block
        .into_par_iter()
        .enumerate()
        .map(|(b, mut parts)| {
            let r = b * APPEND_ROWS..((b + 1) * APPEND_ROWS).min(rows);
            let mut rest = &mut parts[..];
            for &(samples, map, k) in &files {
                let (mine, more) = rest.split_at_mut(k);
                samples.map_rows(r.clone(), mine, map);
                rest = more;
            }
            // The normals (the first three planes), written just above.
            let [x, y, z] = &mut parts[..3] else {
                unreachable!("three normal planes")
            };
            // SAFETY: `map_rows` wrote every value of these parts (`MaybeUninit<f32>` has
            // `f32`'s layout).
            let init = |p: &mut [MaybeUninit<f32>]| unsafe {
                &mut *(std::ptr::from_mut::<[MaybeUninit<f32>]>(p) as *mut [f32])
            };
            repair_normals([init(x), init(y), init(z)])
        })
        .reduce(Validation::default, Validation::merge);
    for p in win.all_mut() {
        // SAFETY: `reserve_exact` made room for `n` more values, and the blocks above wrote
        // every one of them (`map_rows` writes all of its rows of every plane it is given; the
        // blocks cover rows `0..rows` of every plane).
        unsafe { p.set_len(p.len() + n) };
    }
    repaired
}

/// Reads the next `y1 − y0` rows of `input` (rows `y0..y1`), as stored, into the memory of
/// `spare` (a band read earlier and appended since) where it has some.
fn read_band(
    input: &mut StreamInput,
    y0: usize,
    y1: usize,
    spare: Option<Band>,
) -> Result<Band, RgbnError> {
    let rows = y1 - y0;
    let (normal, mut color, mut mask) = match spare {
        Some(b) => (Some(b.normal), b.color, b.mask),
        None => (None, None, None),
    };
    Ok(Band {
        y0,
        y1,
        normal: input.normal.read_samples_reusing(rows, normal)?,
        color: match input.color.as_mut() {
            Some(r) => Some(r.read_samples_reusing(rows, color.take())?),
            None => None,
        },
        mask: match input.mask.as_mut() {
            Some(r) => Some(r.read_samples_reusing(rows, mask.take())?),
            None => None,
        },
    })
}

/// The strips: `(y0, y1)` rows each, `strip` rows but the first three and the last few. The
/// first three ramp up (an eighth, a quarter and half of `strip`, at least 16 rows): the work on
/// the strips can start once a few rows are decoded instead of a whole strip's, while the
/// decoding, which cannot be split, runs on beside it (the first strip of 512 rows of a 4K PNG
/// is a tenth of a second of decoding with the other core idle). The last ramp down: once at
/// most a strip and a half is left, each strip takes half of what is left, down to an eighth of
/// `strip` (at least 16 rows, and at least `halo`: a strip's own rows stay more than the context
/// recomputed around it). What follows the last band's decoding (the last strip's
/// operators, the last rows compressed and written, with the decoding's core otherwise idle) is
/// then a small strip's work instead of a whole one's. An image of at most `strip` rows is one
/// strip.
fn strip_ranges(h: usize, strip: usize, halo: usize) -> impl Iterator<Item = (usize, usize)> {
    let least = (strip >> 3).max(16).max(halo);
    let mut k = 0u32;
    let mut y0 = 0;
    std::iter::from_fn(move || {
        if y0 >= h {
            return None;
        }
        let left = h - y0;
        // One strip that holds the image stays one (exact, with no cut at all).
        let rows = if k < 3 && h > strip {
            (strip >> (3 - k)).max(16).min(strip)
        } else if h > strip && left <= strip + strip / 2 && left > 2 * least {
            left.div_ceil(2)
        } else {
            strip
        };
        k += 1;
        let r = (y0, (y0 + rows).min(h));
        y0 = r.1;
        Some(r)
    })
}

/// Runs `f` on every strip of `input`, top to bottom: strips of `strip` rows (see
/// [`strip_rows`]) in windows grown by `halo` rows each way. Returns what was repaired in the
/// normals (as [`crate::raster::io::load`] reports it). With `strict` loading, the first band
/// of rows with a normal that needs repair stops with [`RgbnError::InvalidNormals`] (its count
/// is that band's).
///
/// With more than one thread, the files are decoded one or two bands ahead of `f`: decoding
/// (inflate) is sequential, and overlaps the strips' parallel work. The decoding runs as tasks
/// on the pool when the caller is outside it (so the process runs no more threads of work than
/// the pool has: BENCHMARKS.md, twelfth session), on a thread of its own otherwise.
pub fn for_each_strip<E: From<RgbnError>>(
    input: &mut StreamInput,
    halo: usize,
    strip: usize,
    mut f: impl FnMut(&Window<'_>) -> Result<(), E>,
) -> Result<Validation, E> {
    let (w, h) = input.size();
    drive(input, halo, strip, |win, y0, core| {
        let [nx, ny, nz] = &win.normal;
        f(&Window {
            width: w,
            height: h,
            y0,
            core,
            normal: [nx, ny, nz],
            color: win.color.as_ref().map(|[r, g, b]| [&r[..], &g[..], &b[..]]),
            mask: win.mask.as_deref(),
        })
    })
}

/// [`for_each_strip`] handing `f` each window as an image, lent without a copy (colour
/// [`DEFAULT_ALBEDO`] without a colour image), with the image row of its first row and its core
/// rows. Clones of the image that `f` keeps are its own.
pub fn for_each_strip_image<E: From<RgbnError>>(
    input: &mut StreamInput,
    halo: usize,
    strip: usize,
    mut f: impl FnMut(&RgbnImage, usize, Range<usize>) -> Result<(), E>,
) -> Result<Validation, E> {
    let w = input.size().0;
    // Without a colour image, the default albedo's planes, shared by every strip's image (an
    // output written on another thread holds them without a copy) and only resized.
    let mut albedo: Arc<[Vec<f32>; 3]> = Arc::default();
    drive(input, halo, strip, |win, y0, core| {
        let rows = win.rows;
        let n = rows * w;
        let had_color = win.color.is_some();
        let color = match win.color.take() {
            Some(c) => Arc::new(c),
            None => {
                if albedo[0].len() != n {
                    // Resized in place; while a writer still holds an earlier strip's, new
                    // planes (the old ones are not copied to be resized).
                    match Arc::get_mut(&mut albedo) {
                        Some(planes) => planes
                            .par_iter_mut()
                            .for_each(|p| p.resize(n, DEFAULT_ALBEDO)),
                        None => {
                            let mut planes: [Vec<f32>; 3] = Default::default();
                            planes
                                .par_iter_mut()
                                .for_each(|p| *p = vec![DEFAULT_ALBEDO; n]);
                            albedo = Arc::new(planes);
                        }
                    }
                }
                albedo.clone()
            }
        };
        let img = RgbnImage::with_shared_color(
            w,
            rows,
            color,
            std::mem::take(&mut win.normal),
            win.mask.take(),
        )?;
        let r = f(&img, y0, core);
        let (color, normal, mask) = img.into_shared_color();
        win.normal = normal;
        if had_color {
            win.color = Some(Arc::try_unwrap(color).unwrap_or_else(|c| (*c).clone()));
        }
        win.mask = mask;
        r
    })
}

/// The loop of the strip drivers: `f` gets the window's planes, the image row of their first
/// row and the core rows; it must leave the planes as it found them.
fn drive<E: From<RgbnError>>(
    input: &mut StreamInput,
    halo: usize,
    strip: usize,
    mut f: impl FnMut(&mut Planes, usize, Range<usize>) -> Result<(), E>,
) -> Result<Validation, E> {
    let (w, h) = input.size();
    let strip = strip.max(1);
    let mut win = Planes {
        color: input.color.as_ref().map(|_| Default::default()),
        mask: input.mask.as_ref().map(|_| Vec::new()),
        ..Planes::default()
    };
    let path = input.normal.path().to_path_buf();
    let strict = input.opts.strict;
    let convention = input.opts.convention;
    // The bands to read: each strip's window ends `halo` rows below it.
    let bands = move || {
        let mut read = 0;
        strip_ranges(h, strip, halo).filter_map(move |(_, y1)| {
            let b = (y1 + halo).min(h);
            (b != read).then(|| (std::mem::replace(&mut read, b), b))
        })
    };
    // Runs every strip, taking the bands from `next` as their rows are needed and handing it
    // back each band once appended (for its memory to be read into again).
    let mut strips =
        |next: &mut dyn FnMut(Option<Band>) -> Result<Band, RgbnError>| -> Result<Validation, E> {
            let mut repaired = Validation::default();
            let mut spare = None;
            for (y0, y1) in strip_ranges(h, strip, halo) {
                let (a, b) = (y0.saturating_sub(halo), (y1 + halo).min(h));
                // Drop the rows above the new window; keep the overlap; append what was read.
                let drop_rows = a.saturating_sub(win.y0).min(win.rows);
                for p in win.all_mut() {
                    p.drain(..drop_rows * w);
                }
                win.y0 = a;
                win.rows -= drop_rows;
                while win.y0 + win.rows < b {
                    let band = next(spare.take())?;
                    debug_assert_eq!(band.y0, win.y0 + win.rows);
                    let band_repaired = check_strict(
                        append_band(&mut win, &band, w, convention),
                        strict,
                        &path,
                        band.y0..band.y1,
                    )?;
                    win.rows += band.y1 - band.y0;
                    repaired = repaired.merge(band_repaired);
                    spare = Some(band);
                }
                f(&mut win, a, y0 - a..y1 - a)?;
            }
            Ok(repaired)
        };
    if !crate::raster::par::pipelined() {
        // One thread: each band is read when its rows are needed.
        let mut todo = bands();
        return strips(&mut |spare| {
            let (a, b) = todo.next().expect("a band for every window's rows");
            read_band(input, a, b, spare)
        });
    }
    // One band decoded ahead, waiting; a second decoded behind it while its planes are small
    // (a 4K strip's: 12 MB), so that the reading never waits on the strips' joins, never for
    // big bands (the memory bound of `tests/streaming_memory.rs`).
    let planes = 3 + input.color.as_ref().map_or(0, |_| 3) + usize::from(input.mask.is_some());
    let band_bytes = (strip + halo) * w * planes * 4;
    let ahead = usize::from(band_bytes <= 16 << 20);
    if rayon::current_thread_index().is_none() {
        // A caller outside the pool (the command line's main thread) may wait for the bands:
        // they are decoded by tasks on the pool.
        return decode_on_pool(input, bands(), ahead + 1, &path, &mut strips);
    }
    // A worker of a pool (`rgbn eval --jobs`: one file per worker) must not wait for tasks
    // queued on its own pool: the bands are decoded on a thread of their own.
    std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Band, RgbnError>>(ahead);
        // The bands appended, back to the reader to be read into again: as many as can be
        // out at once (waiting, being read, being appended), so handing one back never waits.
        let (spare_tx, spare_rx) = std::sync::mpsc::sync_channel::<Band>(ahead + 2);
        scope.spawn(move || {
            for (a, b) in bands() {
                let band = read_band(input, a, b, spare_rx.try_recv().ok());
                let failed = band.is_err();
                // A closed channel: the consumer stopped (an error of its own).
                if tx.send(band).is_err() || failed {
                    return;
                }
            }
        });
        // Only a panic ends the reader without a band or an error (and the scope re-raises
        // it).
        strips(&mut |spare| {
            if let Some(band) = spare {
                // The reader may be gone (its last band read): the band is then dropped.
                let _ = spare_tx.try_send(band);
            }
            rx.recv().map_err(|_| RgbnError::Decode {
                detail: "the reading thread stopped".into(),
                path: path.clone(),
            })?
        })
    })
}

/// The bands decoded and not yet taken, and the reader's state ([`decode_on_pool`]).
struct Decoded {
    ready: std::collections::VecDeque<Result<Band, RgbnError>>,
    /// Bands appended, to be read into again.
    spare: Vec<Band>,
    /// A decoding task is queued or running.
    running: bool,
    /// No more bands will come (all read, an error, or the consumer stopped).
    finished: bool,
    /// The consumer stopped: the task ends after its band.
    stop: bool,
}

/// [`drive`]'s strips with the bands decoded by tasks on the pool, not on a thread of their
/// own: the process runs as many threads of work as the pool has (no decoding thread
/// competing with the pool's workers for the cores, whose preemption mid-join stalls the
/// other workers). A task decodes bands while fewer than `limit` wait, then ends; taking a
/// band queues a new one. For a caller outside the pool only (it waits for the bands, which a
/// worker of the pool must not).
#[allow(clippy::type_complexity)] // `strips`: [`drive`]'s loop over the bands it is handed
fn decode_on_pool<E: From<RgbnError>>(
    input: &mut StreamInput,
    bands: impl Iterator<Item = (usize, usize)> + Send,
    limit: usize,
    path: &Path,
    strips: &mut dyn FnMut(
        &mut dyn FnMut(Option<Band>) -> Result<Band, RgbnError>,
    ) -> Result<Validation, E>,
) -> Result<Validation, E> {
    use parking_lot::{Condvar, Mutex};
    let state = Mutex::new(Decoded {
        ready: std::collections::VecDeque::new(),
        spare: Vec::new(),
        running: false,
        finished: false,
        stop: false,
    });
    let cv = Condvar::new();
    let reader = Mutex::new((input, bands));
    let lock = || state.lock();
    // Marks the task ended however it ends (a panic included: the consumer then sees the
    // bands end, and the scope re-raises the panic).
    struct Ended<'a>(&'a Mutex<Decoded>, &'a Condvar);
    impl Drop for Ended<'_> {
        fn drop(&mut self) {
            let mut q = self.0.lock();
            q.running = false;
            // A panic while reading: no more bands (the consumer stops waiting for them).
            q.finished |= std::thread::panicking();
            self.1.notify_all();
        }
    }
    let task = || {
        let _ended = Ended(&state, &cv);
        let mut r = reader.lock();
        loop {
            let spare = {
                let mut q = lock();
                if q.stop || q.ready.len() >= limit {
                    return;
                }
                q.spare.pop()
            };
            let (input, bands) = &mut *r;
            let Some((a, b)) = bands.next() else {
                lock().finished = true;
                return;
            };
            let band = read_band(input, a, b, spare);
            let mut q = lock();
            q.finished |= band.is_err();
            q.ready.push_back(band);
            cv.notify_all();
            if q.finished {
                return;
            }
        }
    };
    rayon::in_place_scope(|scope| {
        let task = &task;
        let start = |q: &mut Decoded| {
            if !q.running && !q.finished && !q.stop && q.ready.len() < limit {
                q.running = true;
                scope.spawn(move |_| task());
            }
        };
        let r = strips(&mut |spare| {
            let mut q = lock();
            if let Some(b) = spare {
                q.spare.push(b);
            }
            start(&mut q);
            loop {
                if let Some(band) = q.ready.pop_front() {
                    start(&mut q);
                    return band;
                }
                if q.finished && !q.running {
                    return Err(RgbnError::Decode {
                        detail: "the reading stopped".into(),
                        path: path.to_path_buf(),
                    });
                }
                // A task that found the queue full and was still ending when the band above was
                // taken (`running` still set, so nothing was started) has ended since: start
                // another, or this wait would never be woken again.
                start(&mut q);
                cv.wait(&mut q);
            }
        });
        lock().stop = true;
        r
    })
}

#[cfg(test)]
mod tests {
    use super::strip_ranges;

    /// The strips tile the rows exactly once, in order; the first three are an eighth, a
    /// quarter and half of the strip (at least 16 rows, at most the strip); the last halve what
    /// is left once at most a strip and a half is; whole strips between; an image within one
    /// strip is one strip.
    #[test]
    fn strips_ramp_up_and_down_and_cover_every_row_once() {
        for (h, strip, first, last) in [
            (
                2160,
                256,
                vec![(0, 32), (32, 96), (96, 224), (224, 480)],
                // 2016 + 144: 72, then 36 and 36 (no halving below 2 · 32 rows).
                vec![(1760, 2016), (2016, 2088), (2088, 2124), (2124, 2160)],
            ),
            (
                100,
                64,
                vec![(0, 16), (16, 32), (32, 64)],
                vec![(32, 64), (64, 82), (82, 100)],
            ),
            (10, 7, vec![(0, 7), (7, 10)], vec![(7, 10)]),
            (5, 1, vec![(0, 1), (1, 2), (2, 3), (3, 4)], vec![(4, 5)]),
            (100, 100, vec![(0, 100)], vec![(0, 100)]),
            (100, 200, vec![(0, 100)], vec![(0, 100)]),
        ] {
            let r: Vec<(usize, usize)> = strip_ranges(h, strip, 8).collect();
            assert_eq!(&r[..first.len()], &first[..], "h {h}, strip {strip}");
            assert_eq!(
                &r[r.len() - last.len()..],
                &last[..],
                "h {h}, strip {strip}"
            );
            assert_eq!(r[0].0, 0);
            assert_eq!(r.last().unwrap().1, h);
            for w in r.windows(2) {
                assert_eq!(w[0].1, w[1].0, "contiguous");
            }
            for &(a, b) in &r {
                let left = h - a;
                let whole = b - a == strip.min(left);
                let halved = b - a == left.div_ceil(2) && left <= strip + strip / 2;
                let ramp_up = a < (strip >> 1).max(16) * 2;
                assert!(
                    whole || halved || ramp_up,
                    "strip {a}..{b} of {h}, strip {strip}"
                );
            }
        }
    }

    /// The ramp down stops at the halo: with 60 rows of context, 144 rows left are two strips
    /// of 72 (halved once), not 72, 36 and 36.
    #[test]
    fn the_ramp_down_keeps_strips_above_the_halo() {
        let r: Vec<(usize, usize)> = strip_ranges(2160, 256, 60).collect();
        assert_eq!(
            &r[r.len() - 3..],
            &[(1760, 2016), (2016, 2088), (2088, 2160)]
        );
        assert!(r.iter().skip(3).all(|&(a, b)| b - a >= 60));
    }
}
