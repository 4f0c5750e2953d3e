//! RTI light-position files (`.lp`), as written by RTIBuilder and RelightLab.
//!
//! The layout is a count line followed by one line per photo:
//!
//! ```text
//! 3
//! img_001.jpg 0.2588 0.0000 0.9659
//! img_002.jpg -0.1294 0.2241 0.9659
//! C:\capture\img_003.jpg -0.1294 -0.2241 0.9659
//! ```
//!
//! Each photo line is a file name (which may contain spaces) and the light direction `x y z`
//! in the RTI convention, which is rgbn's own: `x` right, `y` up, `z` towards the camera
//! (checked against a synthetic capture rendered in `tests/it/capture.rs`). File names are
//! relative to the `.lp` file's folder. Captures moved from another machine often hold absolute
//! (even Windows) paths: a name that does not exist as written is looked up by its last path
//! component (split at `/` and `\`) in the `.lp` file's folder.
//!
//! Directions that are not unit length are normalised and reported in [`LpFile::notes`]
//! (RTIBuilder's highlight-based estimates are often a little off unit length); a zero or
//! non-finite direction is an error. A count that disagrees with the number of photo lines is
//! an error naming the line.

use crate::error::RgbnError;
use std::path::{Path, PathBuf};

/// The contents of a `.lp` file.
#[derive(Clone, Debug, PartialEq)]
pub struct LpFile {
    /// Photo paths, resolved against the `.lp` file's folder, in file order.
    pub photos: Vec<PathBuf>,
    /// Unit light directions (`x` right, `y` up, `z` towards the camera), one per photo.
    pub directions: Vec<[f32; 3]>,
    /// Remarks for the user (normalised directions), each naming its line.
    pub notes: Vec<String>,
}

/// Whether `path` names a `.lp` file (by extension, case-insensitive).
#[must_use]
pub fn is_lp(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("lp"))
}

/// Reads a `.lp` file and resolves its photo names (see the module docs).
///
/// # Errors
/// [`RgbnError::NotFound`] / [`RgbnError::Read`] for the file, [`RgbnError::Parse`] naming the
/// line for a bad count, a bad direction or a count that disagrees with the photo lines.
pub fn read_lp(path: &Path) -> Result<LpFile, RgbnError> {
    let mut lp = parse_lp(&super::inputs::read_text(path)?, path)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    lp.photos = lp.photos.iter().map(|p| resolve_photo(dir, p)).collect();
    Ok(lp)
}

/// Parses `.lp` text; photo names are returned as written (`path` only names the file in
/// errors and notes).
///
/// # Errors
/// [`RgbnError::Parse`] naming the line.
pub fn parse_lp(text: &str, path: &Path) -> Result<LpFile, RgbnError> {
    let perr = |line: usize, detail: String| RgbnError::Parse {
        line,
        detail,
        path: path.into(),
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (count_line, count_text) = lines.next().ok_or_else(|| {
        perr(
            1,
            "empty light-position file: expected a photo count".into(),
        )
    })?;
    let count: usize = count_text.parse().map_err(|_| {
        perr(
            count_line,
            format!("expected the number of photos on the first line, got {count_text:?}"),
        )
    })?;
    let mut lp = LpFile {
        photos: Vec::new(),
        directions: Vec::new(),
        notes: Vec::new(),
    };
    for (ln, line) in lines {
        if lp.photos.len() == count {
            return Err(perr(
                ln,
                format!(
                    "the count on line {count_line} says {count} photos, but this is photo line {}",
                    count + 1
                ),
            ));
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() < 4 {
            return Err(perr(
                ln,
                format!(
                    "expected a file name and a light direction x y z, got {} field(s)",
                    toks.len()
                ),
            ));
        }
        let mut d = [0.0f64; 3];
        for (k, t) in toks[toks.len() - 3..].iter().enumerate() {
            d[k] = t
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| perr(ln, format!("not a finite number: {t:?}")))?;
        }
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if len < 1e-6 {
            return Err(perr(ln, "the light direction is zero".into()));
        }
        if (len - 1.0).abs() > 1e-3 {
            lp.notes.push(format!(
                "line {ln} of {}: light direction has length {len:.4}; normalised",
                path.display()
            ));
        }
        // The name is everything before the last three fields, spaces included.
        let name_end = {
            let mut rest = line;
            for _ in 0..3 {
                rest = rest.trim_end();
                rest = &rest[..rest.rfind(char::is_whitespace).unwrap_or(0)];
            }
            rest.trim()
        };
        lp.photos.push(PathBuf::from(name_end));
        lp.directions.push([
            (d[0] / len) as f32,
            (d[1] / len) as f32,
            (d[2] / len) as f32,
        ]);
    }
    if lp.photos.len() != count {
        return Err(perr(
            count_line,
            format!(
                "the count says {count} photos, the file has {} photo line(s)",
                lp.photos.len()
            ),
        ));
    }
    Ok(lp)
}

/// A photo name from a `.lp` file as a path: as written when absolute and present, else
/// relative to `dir`; when that does not exist either, the last path component (split at `/`
/// and `\`) in `dir`, if present there. Otherwise `dir/name`, whose absence the loader reports.
#[must_use]
pub fn resolve_photo(dir: &Path, name: &Path) -> PathBuf {
    if name.is_absolute() && name.exists() {
        return name.to_path_buf();
    }
    let joined = dir.join(name);
    if joined.exists() {
        return joined;
    }
    let text = name.to_string_lossy();
    if let Some(base) = text.rsplit(['/', '\\']).next().filter(|b| !b.is_empty()) {
        let candidate = dir.join(base);
        if candidate.exists() {
            return candidate;
        }
    }
    joined
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<LpFile, RgbnError> {
        parse_lp(text, Path::new("caps/set.lp"))
    }

    #[test]
    fn reads_names_with_spaces_and_unit_directions() {
        let lp = parse("2\nimg 001.jpg 0.6 0 0.8\n\n  b.png\t-0.6 0.0 0.8  \n").unwrap();
        assert_eq!(
            lp.photos,
            vec![PathBuf::from("img 001.jpg"), PathBuf::from("b.png")]
        );
        assert_eq!(lp.directions, vec![[0.6, 0.0, 0.8], [-0.6, 0.0, 0.8]]);
        assert!(lp.notes.is_empty());
    }

    #[test]
    fn non_unit_directions_are_normalised_with_a_note() {
        let lp = parse("1\na.jpg 0 3 4\n").unwrap();
        assert_eq!(lp.directions, vec![[0.0, 0.6, 0.8]]);
        assert_eq!(lp.notes.len(), 1);
        assert!(lp.notes[0].contains("line 2") && lp.notes[0].contains("5.0000"));
    }

    #[test]
    fn count_disagreements_name_the_line() {
        // Fewer photo lines than counted: the count's line.
        let e = parse("3\na.jpg 0 0 1\nb.jpg 0 0 1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line 1") && e.contains("3 photos") && e.contains("2 photo line"),
            "{e}"
        );
        // More: the first extra line.
        let e = parse("1\na.jpg 0 0 1\nb.jpg 0 0 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3"), "{e}");
        let e = parse("two\na.jpg 0 0 1\n").unwrap_err().to_string();
        assert!(
            e.contains("line 1") && e.contains("number of photos"),
            "{e}"
        );
        let e = parse("1\na.jpg 0 x 1\n").unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("\"x\""), "{e}");
        let e = parse("1\na.jpg 0 0 0\n").unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("zero"), "{e}");
        let e = parse("1\n0 0 1\n").unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("file name"), "{e}");
        assert!(parse("").is_err());
    }

    #[test]
    fn windows_paths_fall_back_to_the_file_name_beside_the_lp() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(tmp.path().join("img_003.jpg"), b"x").unwrap();
        let got = resolve_photo(tmp.path(), Path::new(r"C:\capture\img_003.jpg"));
        assert_eq!(got, tmp.path().join("img_003.jpg"));
        // Missing everywhere: relative to the folder, for the loader to report.
        let got = resolve_photo(tmp.path(), Path::new("sub/none.jpg"));
        assert_eq!(got, tmp.path().join("sub/none.jpg"));
    }
}
