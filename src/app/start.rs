//! What the editor opens on: `rgbn` and `rgbn edit` with no file (the demo graph), a graph
//! file, or an image (`rgbn IMAGE`, `rgbn edit IMAGE`) on a new, unsaved graph built as
//! File ▸ Open image… builds it: a `load` node for the image, viewed, with the colour, mask and
//! normal convention the command line names.

use super::state::Document;
use super::EditorApp;
use crate::params::ParamValue;
use crate::raster::io::Format;
use std::path::{Path, PathBuf};

/// The kinds of file the editor opens, for messages.
pub const ACCEPTED: &str =
    "a graph (.ron) or an image: a normal map (PNG, JPEG, TIFF or EXR), an RGBN EXR or a PTM";

/// An image to open on a new graph, with the options `rgbn info` takes for it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImageStart {
    /// The normal map, RGBN EXR or PTM.
    pub path: PathBuf,
    /// A colour image.
    pub color: Option<PathBuf>,
    /// A coverage mask.
    pub mask: Option<PathBuf>,
    /// The normal map uses the DirectX convention (green = −y).
    pub dx: bool,
    /// An EXR's R,G,B are the normal.
    pub exr_rgb_is_normal: bool,
}

/// What the editor opens on.
#[derive(Clone, Debug, PartialEq)]
pub enum Start {
    /// `graphs/demo.ron` when it exists, else the built-in demo graph.
    Demo,
    /// A graph file.
    Graph(PathBuf),
    /// An image on a new graph.
    Image(ImageStart),
}

impl Start {
    /// What `file` (with the image options) opens, or a one-line error naming the file and
    /// the kinds accepted. A graph takes no image options.
    pub fn of(file: Option<&Path>, image: ImageStart) -> Result<Self, String> {
        let has_options =
            image.color.is_some() || image.mask.is_some() || image.dx || image.exr_rgb_is_normal;
        let Some(file) = file else {
            if has_options {
                return Err(
                    "--color, --mask, --dx and --exr-rgb-is-normal go with an image to open (rgbn edit IMAGE --color …)"
                        .into(),
                );
            }
            return Ok(Start::Demo);
        };
        let is_graph = file
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("ron"));
        if !is_graph && Format::of(file).is_err() {
            return Err(format!(
                "cannot open this kind of file; rgbn edit opens {ACCEPTED}: {}",
                file.display()
            ));
        }
        if !file.is_file() {
            return Err(format!("no such file: {}", file.display()));
        }
        if is_graph {
            if has_options {
                return Err(format!(
                    "--color, --mask, --dx and --exr-rgb-is-normal apply to an image, not to a graph: {}",
                    file.display()
                ));
            }
            return Ok(Start::Graph(file.to_path_buf()));
        }
        for (what, p) in [("--color", &image.color), ("--mask", &image.mask)] {
            if let Some(p) = p {
                if Format::of(p).is_err() || !p.is_file() {
                    return Err(format!(
                        "{what} needs an image file (PNG, JPEG, TIFF or EXR): {}",
                        p.display()
                    ));
                }
            }
        }
        Ok(Start::Image(ImageStart {
            path: file.to_path_buf(),
            ..image
        }))
    }

    /// The editor on it (graph files are read here: an unreadable one is an error).
    pub fn app(&self) -> Result<EditorApp, String> {
        Ok(match self {
            Start::Demo => {
                let p = Path::new("graphs/demo.ron");
                let doc = if p.is_file() {
                    Document::open(p).unwrap_or_else(|_| Document::demo())
                } else {
                    Document::demo()
                };
                EditorApp::new(doc)
            }
            Start::Graph(p) => EditorApp::new(Document::open(p).map_err(|e| e.to_string())?),
            Start::Image(img) => EditorApp::on_image(img)?,
        })
    }
}

impl EditorApp {
    /// The editor on a new, unsaved graph around an image: File ▸ Open image… on a new
    /// document ([`open_image`](Self::open_image)), the load node given the colour, mask and
    /// convention, the document titled by the image's name. One step, nothing to undo.
    pub fn on_image(img: &ImageStart) -> Result<Self, String> {
        let mut app = EditorApp::new(Document::new());
        let Some(id) = app.open_image(&img.path) else {
            return Err(app.status.text.clone());
        };
        let abs = |p: &Path| super::recent::absolute(p).to_string_lossy().into_owned();
        let doc = &mut app.session.doc;
        if let Some(n) = doc.graph.nodes.get_mut(&id) {
            if let Some(c) = &img.color {
                n.params.insert("color".into(), ParamValue::Path(abs(c)));
            }
            if let Some(m) = &img.mask {
                n.params.insert("mask".into(), ParamValue::Path(abs(m)));
            }
            if img.dx {
                n.params.insert("dx".into(), ParamValue::Bool(true));
            }
            if img.exr_rgb_is_normal {
                n.params
                    .insert("exr_rgb_is_normal".into(), ParamValue::Bool(true));
            }
        }
        doc.history.clear();
        doc.name = img
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned());
        Ok(app)
    }
}
