//! Photometric-stereo inputs on disk: light and intensity files (rows of three numbers), name
//! lists, photo stacks, and [`load_inputs`], which loads and pairs them up.

use crate::error::RgbnError;
use crate::raster::io;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// How photo files encode light.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum Transfer {
    /// Integer samples are proportional to light (raw / linear data, e.g. DiLiGenT).
    #[default]
    Linear,
    /// Integer samples are sRGB-encoded; decoded with the sRGB curve.
    Srgb,
}

/// Photos of one viewpoint as linear RGB planes, all the same size.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotoStack {
    pub width: usize,
    pub height: usize,
    /// One `[R, G, B]` set of planes (row-major, `width * height` each) per photo.
    pub photos: Vec<[Vec<f32>; 3]>,
}

impl PhotoStack {
    /// Wraps planes, checking that every plane has `width * height` values.
    ///
    /// # Errors
    /// [`RgbnError::InvalidImage`] on a plane of the wrong length.
    pub fn new(width: usize, height: usize, photos: Vec<[Vec<f32>; 3]>) -> Result<Self, RgbnError> {
        let n = width * height;
        if let Some(j) = photos.iter().position(|p| p.iter().any(|c| c.len() != n)) {
            return Err(RgbnError::InvalidImage(format!(
                "photo {j} does not have {width}×{height} values per channel"
            )));
        }
        Ok(Self {
            width,
            height,
            photos,
        })
    }

    /// Loads photos (8/16-bit PNG/TIFF/JPEG or EXR). All must have the first photo's size.
    ///
    /// # Errors
    /// File errors, and [`RgbnError::SizeMismatch`] naming the first photo of another size.
    pub fn load(paths: &[PathBuf], transfer: Transfer) -> Result<Self, RgbnError> {
        let loaded: Vec<_> = paths
            .par_iter()
            .map(|p| match transfer {
                Transfer::Linear => io::load_color_linear(p),
                Transfer::Srgb => io::load_color(p),
            })
            .collect::<Result<_, _>>()?;
        let Some(&(w, h, _)) = loaded.first().map(|(w, h, c)| (w, h, c)).as_ref() else {
            return Err(RgbnError::TooFewLights { count: 0 });
        };
        let (w, h) = (*w, *h);
        let mut photos = Vec::with_capacity(loaded.len());
        for ((pw, ph, planes), path) in loaded.into_iter().zip(paths) {
            if (pw, ph) != (w, h) {
                return Err(RgbnError::SizeMismatch {
                    what: "photo",
                    want_w: w,
                    want_h: h,
                    got_w: pw,
                    got_h: ph,
                    path: path.clone(),
                });
            }
            photos.push(planes);
        }
        Self::new(w, h, photos)
    }
}

/// Light directions (unit after [`photometric_stereo`](crate::capture::photometric::photometric_stereo) normalises them) and optional per-light
/// RGB intensities, one row per photo.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Lights {
    /// `(x, y, z)` per light: `x` right, `y` up, `z` towards the camera.
    pub directions: Vec<[f32; 3]>,
    /// Relative `(r, g, b)` intensity per light; `None` = all 1.
    pub intensities: Option<Vec<[f32; 3]>>,
}

/// Parses rows of three numbers. A first line holding a single integer is a row count (UW
/// `lights.txt` layout) and must match; blank lines and `#` comments are skipped; separators
/// are spaces, tabs or commas.
///
/// # Errors
/// [`RgbnError::NotFound`]/[`RgbnError::Read`] and [`RgbnError::Parse`] naming the line.
pub fn read_rows3(path: &Path) -> Result<Vec<[f32; 3]>, RgbnError> {
    parse_rows3(&read_text(path)?, path)
}

/// A text input file (light files, `.lp` files) as a string.
///
/// # Errors
/// [`RgbnError::NotFound`] when it does not exist, [`RgbnError::Read`] otherwise.
pub(crate) fn read_text(path: &Path) -> Result<String, RgbnError> {
    std::fs::read_to_string(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            RgbnError::NotFound { path: path.into() }
        } else {
            RgbnError::Read {
                path: path.into(),
                source: e,
            }
        }
    })
}

/// [`read_rows3`] on text already in memory (`path` only names it in errors).
///
/// # Errors
/// [`RgbnError::Parse`] naming the line.
pub fn parse_rows3(text: &str, path: &Path) -> Result<Vec<[f32; 3]>, RgbnError> {
    let perr = |line: usize, detail: String| RgbnError::Parse {
        line,
        detail,
        path: path.into(),
    };
    let mut rows = Vec::new();
    let mut count: Option<(usize, usize)> = None;
    let mut first = true;
    for (ln, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let toks: Vec<&str> = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
            .collect();
        if first && toks.len() == 1 {
            let n = toks[0]
                .parse::<usize>()
                .map_err(|_| perr(ln + 1, format!("expected a row count, got {:?}", toks[0])))?;
            count = Some((n, ln + 1));
            first = false;
            continue;
        }
        first = false;
        if toks.len() != 3 {
            return Err(perr(
                ln + 1,
                format!("expected 3 numbers, got {}", toks.len()),
            ));
        }
        let mut v = [0.0f32; 3];
        for (k, t) in toks.iter().enumerate() {
            v[k] = t
                .parse::<f32>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| perr(ln + 1, format!("not a finite number: {t:?}")))?;
        }
        rows.push(v);
    }
    if let Some((n, line)) = count {
        if n != rows.len() {
            return Err(perr(
                line,
                format!("header says {n} rows, file has {}", rows.len()),
            ));
        }
    }
    Ok(rows)
}

/// Reads a list of file names, one per line (DiLiGenT `filenames.txt`).
///
/// # Errors
/// File errors.
pub fn read_name_list(path: &Path) -> Result<Vec<String>, RgbnError> {
    let text = std::fs::read_to_string(path).map_err(|e| RgbnError::Read {
        path: path.into(),
        source: e,
    })?;
    Ok(text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .map(String::from)
        .collect())
}

/// Where to find the photometric-stereo inputs on disk.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PsInputSpec {
    /// The photos, in light order unless `names` is given.
    pub photos: Vec<PathBuf>,
    /// Light directions: rows `x y z`, optionally preceded by a count line; or an RTI `.lp`
    /// light-position file ([`super::lp`]), which also names the photos when `photos` is empty.
    pub lights: PathBuf,
    /// Optional per-light RGB intensities, same layout.
    pub intensities: Option<PathBuf>,
    /// Optional list of file names, row `i` naming the photo of light row `i` (DiLiGenT
    /// `filenames.txt`): photos are matched to light rows by file name, so a subset of the
    /// photos can be used with the full light file.
    pub names: Option<PathBuf>,
    /// Optional mask (white = object), the photos' size.
    pub mask: Option<PathBuf>,
    pub transfer: Transfer,
}

/// Photos, lights and mask loaded and checked against each other.
#[derive(Clone, Debug, PartialEq)]
pub struct PsInputs {
    pub stack: PhotoStack,
    pub lights: Lights,
    pub mask: Option<Vec<f32>>,
    /// Remarks for the user about the inputs (e.g. light directions normalised), each naming
    /// its file and line.
    pub notes: Vec<String>,
}

/// Loads and pairs up everything in `spec`.
///
/// # Errors
/// File and parse errors; [`RgbnError::TooFewLights`]; [`RgbnError::SizeMismatch`] for photos or
/// mask of another size; [`RgbnError::LightCountMismatch`] when the light (or intensity) rows do
/// not pair with the photos (or a photo is missing from `names`).
pub fn load_inputs(spec: &PsInputSpec) -> Result<PsInputs, RgbnError> {
    // An RTI `.lp` file as `lights` gives the directions, and the photos when none are listed.
    let lp = if super::lp::is_lp(&spec.lights) {
        Some(super::lp::read_lp(&spec.lights)?)
    } else {
        None
    };
    let from_lp;
    let spec = match &lp {
        Some(lp) if spec.photos.is_empty() => {
            from_lp = PsInputSpec {
                photos: lp.photos.clone(),
                ..spec.clone()
            };
            &from_lp
        }
        _ => spec,
    };
    if spec.photos.len() < 3 {
        return Err(RgbnError::TooFewLights {
            count: spec.photos.len(),
        });
    }
    let (dirs, notes) = match lp {
        Some(lp) => (lp.directions, lp.notes),
        None => (read_rows3(&spec.lights)?, Vec::new()),
    };
    let ints = spec.intensities.as_deref().map(read_rows3).transpose()?;
    let m = spec.photos.len();
    // Row of each photo.
    let rows: Vec<usize> = match &spec.names {
        Some(names_path) => {
            let names = read_name_list(names_path)?;
            spec.photos
                .iter()
                .map(|p| {
                    let f = p.file_name().and_then(|f| f.to_str()).unwrap_or("");
                    names
                        .iter()
                        .position(|n| n == f)
                        .ok_or_else(|| RgbnError::LightCountMismatch {
                            what: "photo not listed in the names file",
                            got: names.len(),
                            photos: m,
                            path: p.clone(),
                        })
                })
                .collect::<Result<_, _>>()?
        }
        None => (0..m).collect(),
    };
    let pick = |rows_in: &[[f32; 3]], what: &'static str, path: &Path| {
        let n_expected = spec
            .names
            .as_ref()
            .map_or(m, |_| rows.iter().max().map_or(0, |&r| r + 1));
        let ok = if spec.names.is_some() {
            rows_in.len() >= n_expected
        } else {
            rows_in.len() == m
        };
        if !ok {
            return Err(RgbnError::LightCountMismatch {
                what,
                got: rows_in.len(),
                photos: m,
                path: path.into(),
            });
        }
        Ok(rows.iter().map(|&r| rows_in[r]).collect::<Vec<_>>())
    };
    let directions = pick(&dirs, "light directions", &spec.lights)?;
    let intensities = match (&ints, &spec.intensities) {
        (Some(i), Some(p)) => Some(pick(i, "light intensities", p)?),
        _ => None,
    };
    let stack = PhotoStack::load(&spec.photos, spec.transfer)?;
    let mask = match &spec.mask {
        Some(p) => {
            let (w, h, m) = io::load_mask(p)?;
            if (w, h) != (stack.width, stack.height) {
                return Err(RgbnError::SizeMismatch {
                    what: "mask",
                    want_w: stack.width,
                    want_h: stack.height,
                    got_w: w,
                    got_h: h,
                    path: p.clone(),
                });
            }
            Some(m)
        }
        None => None,
    };
    Ok(PsInputs {
        stack,
        lights: Lights {
            directions,
            intensities,
        },
        mask,
        notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn light_files_in_both_layouts_parse() {
        let p = Path::new("lights.txt");
        let dil = "-0.0635 -0.4317 0.8998\n-0.0629 -0.3178 0.9461\n\n0.1 0.2 0.97\n";
        assert_eq!(parse_rows3(dil, p).unwrap().len(), 3);
        let uw = "3\n0.49 0.46 0.73\n0.24,0.13,0.96\n# comment\n-0.03 0.17 0.98 # tail\n";
        let rows = parse_rows3(uw, p).unwrap();
        assert_eq!(rows.len(), 3);
        assert!((rows[1][2] - 0.96).abs() < 1e-6);
        let e = parse_rows3("4\n1 0 0\n0 1 0\n0 0 1\n", p).unwrap_err();
        assert!(matches!(e, RgbnError::Parse { line: 1, .. }), "{e}");
        let e = parse_rows3("1 0 0\n0 1\n", p).unwrap_err();
        assert!(matches!(e, RgbnError::Parse { line: 2, .. }), "{e}");
        let e = parse_rows3("1 0 nan\n", p).unwrap_err();
        assert!(e.to_string().ends_with("lights.txt"), "{e}");
    }

    #[test]
    fn photos_of_different_sizes_are_refused_on_load() {
        let dir = tempfile::tempdir().unwrap();
        let mut paths = Vec::new();
        for (k, (w, h)) in [(8u32, 6u32), (8, 6), (7, 6)].into_iter().enumerate() {
            let p = dir.path().join(format!("{k}.png"));
            image::RgbImage::from_pixel(w, h, image::Rgb([100, 100, 100]))
                .save(&p)
                .unwrap();
            paths.push(p);
        }
        let lights = dir.path().join("l.txt");
        std::fs::write(&lights, "3\n0 0 1\n0.5 0 0.8\n0 0.5 0.8\n").unwrap();
        let spec = PsInputSpec {
            photos: paths.clone(),
            lights: lights.clone(),
            ..Default::default()
        };
        let e = load_inputs(&spec).unwrap_err();
        assert!(matches!(e, RgbnError::SizeMismatch { got_w: 7, .. }), "{e}");
        let spec = PsInputSpec {
            photos: paths[..2].to_vec(),
            lights,
            ..Default::default()
        };
        assert!(matches!(
            load_inputs(&spec),
            Err(RgbnError::TooFewLights { count: 2 })
        ));
    }
}
