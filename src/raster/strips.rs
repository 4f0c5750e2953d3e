//! Strip streaming: an image whose files are read row by row ([`io::stream`]) is processed in
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

use super::io::stream::{PngRows, RowMap};
use super::io::{Format, InputSpec, LoadOptions, DEFAULT_ALBEDO};
use super::{RgbnImage, Validation, MIN_NORMAL_LENGTH};
use crate::error::RgbnError;
use rayon::prelude::*;
use std::ops::Range;
use std::path::Path;

/// Above this many pixels, `rgbn filter` streams by default (`--stream auto`): twice a 4K
/// image, where reading whole would take about 1.6 GB.
pub const AUTO_STREAM_PIXELS: u64 = 16 << 20;

/// Pixels of a strip (its window without the halos) when the caller does not choose: large
/// enough that the halos cost little (two 33-row halos on 512 rows of a 16384-wide image), small
/// enough that a window of a few planes stays far below a GiB.
pub const STRIP_PIXELS: usize = 8 << 20;

/// The rows per strip for an image `width` wide and a `halo`: [`STRIP_PIXELS`] worth, at least
/// 64 rows and four halos.
#[must_use]
pub fn strip_rows(width: usize, halo: usize) -> usize {
    (STRIP_PIXELS / width.max(1)).max(64).max(4 * halo)
}

/// The files of an RGBN image opened for reading top to bottom: a normal map and optional
/// colour and mask, all PNG.
pub struct StreamInput {
    normal: PngRows,
    color: Option<PngRows>,
    mask: Option<PngRows>,
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
    /// Opens the files of `spec` for streaming, or says why they must be read whole (an EXR
    /// or PTM, a TIFF or JPEG, an interlaced PNG). Errors are those of reading the headers
    /// (missing file, not a PNG, sizes that differ).
    pub fn open(spec: &InputSpec, opts: &LoadOptions) -> Result<Opened, RgbnError> {
        let Some(normal) = spec.rgbn.as_ref().or(spec.normal.as_ref()) else {
            return Ok(Opened::Whole("no normal map is named".into()));
        };
        let open = |what: &str, p: &Path| -> Result<Result<PngRows, String>, RgbnError> {
            let fmt = Format::of(p)?;
            if fmt != Format::Png {
                return Ok(Err(format!(
                    "the {what} is {} (only PNG is read row by row)",
                    format!("{fmt:?}").to_uppercase()
                )));
            }
            Ok(PngRows::open(p)?.ok_or_else(|| {
                format!("the {what} is an interlaced PNG (its rows are not stored in order)")
            }))
        };
        let normal = match open("normal map", normal)? {
            Ok(r) => r,
            Err(why) => return Ok(Opened::Whole(why)),
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
            Ok(c) => c,
            Err(why) => return Ok(Opened::Whole(why)),
        };
        let mask = match part("mask", &spec.mask)? {
            Ok(m) => m,
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
/// `(0, 0, 1)`) and counts what needed it.
fn repair_normals([nx, ny, nz]: [&mut [f32]; 3]) -> Validation {
    (nx.par_iter_mut(), ny.par_iter_mut(), nz.par_iter_mut())
        .into_par_iter()
        .fold(Validation::default, |mut v, (x, y, z)| {
            let len = (*x * *x + *y * *y + *z * *z).sqrt();
            v.pixels += 1;
            if len < MIN_NORMAL_LENGTH {
                v.zero_length_normal += 1;
                (*x, *y, *z) = (0.0, 0.0, 1.0);
            } else {
                if (len - 1.0).abs() > 1e-3 {
                    v.non_unit += 1;
                }
                if *z <= 0.0 {
                    v.back_facing += 1;
                }
                (*x, *y, *z) = (*x / len, *y / len, *z / len);
            }
            v
        })
        .reduce(Validation::default, add_validation)
}

fn add_validation(a: Validation, b: Validation) -> Validation {
    Validation {
        pixels: a.pixels + b.pixels,
        non_finite_color: a.non_finite_color + b.non_finite_color,
        non_finite_normal: a.non_finite_normal + b.non_finite_normal,
        zero_length_normal: a.zero_length_normal + b.zero_length_normal,
        back_facing: a.back_facing + b.back_facing,
        non_unit: a.non_unit + b.non_unit,
    }
}

/// Runs `f` on every strip of `input`, top to bottom: strips of `strip` rows (see
/// [`strip_rows`]) in windows grown by `halo` rows each way. Returns what was repaired in the
/// normals (as [`crate::raster::io::load`] reports it). With `strict` loading, the first strip
/// with a normal that needs repair stops with [`RgbnError::InvalidNormals`] (its count is that
/// strip's).
pub fn for_each_strip<E: From<RgbnError>>(
    input: &mut StreamInput,
    halo: usize,
    strip: usize,
    mut f: impl FnMut(&Window<'_>) -> Result<(), E>,
) -> Result<Validation, E> {
    let (w, h) = input.size();
    let strip = strip.max(1);
    let mut win = Planes {
        color: input.color.as_ref().map(|_| Default::default()),
        mask: input.mask.as_ref().map(|_| Vec::new()),
        ..Planes::default()
    };
    let mut repaired = Validation::default();
    let mut y0 = 0;
    while y0 < h {
        let y1 = (y0 + strip).min(h);
        let (a, b) = (y0.saturating_sub(halo), (y1 + halo).min(h));
        // Drop the rows above the new window; keep the overlap; read the rest.
        let drop_rows = a.saturating_sub(win.y0).min(win.rows);
        for p in win.all_mut() {
            p.drain(..drop_rows * w);
        }
        win.y0 = a;
        win.rows -= drop_rows;
        let have = win.y0 + win.rows;
        let new = b - have;
        let old = win.rows * w;
        let len = (win.rows + new) * w;
        for p in win.all_mut() {
            p.resize(len, 0.0);
        }
        {
            let [nx, ny, nz] = &mut win.normal;
            let mut planes = [&mut nx[old..], &mut ny[old..], &mut nz[old..]];
            input
                .normal
                .read(&mut planes, RowMap::Normal(input.opts.convention))?;
            let v = repair_normals(planes);
            if input.opts.strict && !v.is_clean() {
                let (count, kind) = if v.zero_length_normal > 0 {
                    (v.zero_length_normal, "zero-length")
                } else {
                    (v.non_unit, "not unit length")
                };
                return Err(RgbnError::InvalidNormals {
                    count,
                    kind: format!("{kind}, in rows {have}..{b}"),
                    path: input.normal.path().into(),
                }
                .into());
            }
            repaired = add_validation(repaired, v);
        }
        if let (Some(r), Some([c0, c1, c2])) = (input.color.as_mut(), win.color.as_mut()) {
            r.read(
                &mut [&mut c0[old..], &mut c1[old..], &mut c2[old..]],
                RowMap::Srgb,
            )?;
        }
        if let (Some(r), Some(m)) = (input.mask.as_mut(), win.mask.as_mut()) {
            r.read(&mut [&mut m[old..]], RowMap::Unit)?;
        }
        win.rows += new;
        let [nx, ny, nz] = &win.normal;
        let view = Window {
            width: w,
            height: h,
            y0: a,
            core: y0 - a..y1 - a,
            normal: [nx, ny, nz],
            color: win.color.as_ref().map(|[r, g, b]| [&r[..], &g[..], &b[..]]),
            mask: win.mask.as_deref(),
        };
        f(&view)?;
        y0 = y1;
    }
    Ok(repaired)
}
