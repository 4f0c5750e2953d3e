//! Error types of the library. Messages are one line and name the file last, so that a user
//! reading `rgbn: <message>` sees what is wrong, then where.

use std::path::PathBuf;

/// Errors from image I/O, validation and operators.
#[derive(Debug, thiserror::Error)]
pub enum RgbnError {
    /// The input file does not exist.
    #[error("file not found: {}", .path.display())]
    NotFound { path: PathBuf },

    /// The file exists but reading it failed (permissions, I/O error).
    #[error("cannot read ({source}): {}", .path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },

    /// The extension (or content) is not a format rgbn reads or writes.
    #[error("unsupported format {format:?} (use .exr, .zarr, .png, .jpg/.jpeg or .tif/.tiff; .ptm to read): {}", .path.display())]
    UnsupportedFormat { format: String, path: PathBuf },

    /// The file is truncated, corrupt, or lacks what is needed (e.g. normal channels).
    #[error("cannot decode ({detail}): {}", .path.display())]
    Decode { detail: String, path: PathBuf },

    /// Two inputs that must have the same size do not.
    #[error("size mismatch: {what} is {got_w}×{got_h} but the image is {want_w}×{want_h}: {}", .path.display())]
    SizeMismatch {
        what: &'static str,
        want_w: usize,
        want_h: usize,
        got_w: usize,
        got_h: usize,
        path: PathBuf,
    },

    /// Refused before allocating: more pixels than the limit.
    #[error("image too large: {width}×{height} = {} pixels exceeds the limit of {limit} pixels (set RGBN_MAX_PIXELS to raise it): {}", *.width as u64 * *.height as u64, .path.display())]
    TooLarge {
        width: usize,
        height: usize,
        limit: u64,
        path: PathBuf,
    },

    /// Strict loading found normals that would need repair.
    #[error("{count} invalid normals ({kind}); drop --strict to repair them to (0,0,1): {}", .path.display())]
    InvalidNormals {
        count: usize,
        kind: String,
        path: PathBuf,
    },

    /// The output's folder does not exist.
    #[error("output folder does not exist (create it first): {}", .path.display())]
    MissingDir { path: PathBuf },

    /// The output path names one of the inputs; rgbn never overwrites an input.
    #[error("refusing to overwrite an input file (choose another output path): {}", .path.display())]
    OutputIsInput { path: PathBuf },

    /// Writing or renaming the output failed.
    #[error("cannot write ({detail}): {}", .path.display())]
    Write { detail: String, path: PathBuf },

    /// A parameter value that cannot be used (out of range, malformed).
    #[error("invalid parameter {name}: {detail}")]
    InvalidParam { name: String, detail: String },

    /// A text input (e.g. a light-direction file) has a malformed line.
    #[error("cannot parse line {line} ({detail}): {}", .path.display())]
    Parse {
        line: usize,
        detail: String,
        path: PathBuf,
    },

    /// Photometric stereo needs at least three lights (three unknowns per pixel).
    #[error("photometric stereo needs at least 3 photos and lights, got {count}")]
    TooFewLights { count: usize },

    /// The light file (or intensity list) and the photos do not pair up one to one.
    #[error("{what}: {got} rows for {photos} photos (row i belongs to photo i): {}", .path.display())]
    LightCountMismatch {
        what: &'static str,
        got: usize,
        photos: usize,
        path: PathBuf,
    },

    /// The light directions do not span 3-D (coplanar, collinear, repeated or zero vectors), so
    /// normals cannot be recovered.
    #[error("degenerate light directions: {detail}")]
    DegenerateLights { detail: String },

    /// An operation that needs at least one pixel inside the mask got an empty mask.
    #[error("empty mask: {what} has no pixel with coverage ≥ 0.5")]
    EmptyMask { what: &'static str },

    /// Planes that do not form a valid image (wrong lengths); a programming or data error.
    #[error("invalid image: {0}")]
    InvalidImage(String),

    /// The work was cancelled (Ctrl-C, the editor's Cancel or a newer edit); nothing it
    /// computed is kept.
    #[error("cancelled")]
    Cancelled,
}

impl RgbnError {
    /// Shorthand for [`RgbnError::InvalidParam`].
    pub fn param(name: impl Into<String>, detail: impl Into<String>) -> Self {
        Self::InvalidParam {
            name: name.into(),
            detail: detail.into(),
        }
    }
}

/// Result alias for the library.
pub type Result<T, E = RgbnError> = std::result::Result<T, E>;
