//! A streamed `rgbn eval` output written as an OME-Zarr store: each strip's core rows handed to
//! a [`ZarrRowWriter`], made at the first strip (when the output's channels are known: a mask
//! or not).

use crate::error::RgbnError;
use crate::nodes::Value;
use crate::raster::io::zarr::{Content, Layout, ZarrOptions, ZarrRowWriter};
use std::ops::Range;
use std::path::PathBuf;

/// One output's store.
pub(super) struct ZarrSink {
    path: PathBuf,
    size: (usize, usize),
    opts: ZarrOptions,
    writer: Option<ZarrRowWriter>,
}

impl ZarrSink {
    /// The store at `path` of a `size` output.
    pub(super) fn new(path: PathBuf, size: (usize, usize), opts: ZarrOptions) -> Self {
        Self {
            path,
            size,
            opts,
            writer: None,
        }
    }

    /// Writes the `core` rows of a strip's value (an image or a picture).
    pub(super) fn write(&mut self, v: &Value, core: Range<usize>) -> Result<(), RgbnError> {
        let (content, w) = match v {
            Value::Rgbn(img) => (
                Content::Rgbn {
                    mask: img.mask().is_some(),
                },
                img.width(),
            ),
            Value::Picture(p) => (Content::Picture, p.width),
            other => {
                return Err(RgbnError::InvalidImage(format!(
                    "a streamed OME-Zarr output is an image or a picture, not {other:?}"
                )))
            }
        };
        if self.writer.is_none() {
            let layout = Layout::new(self.size.0, self.size.1, content, &self.opts, &self.path)?;
            self.writer = Some(ZarrRowWriter::create(&self.path, layout)?);
        }
        let writer = self.writer.as_mut().expect("made above");
        let rows = core.start * w..core.end * w;
        match v {
            Value::Rgbn(img) => {
                let [r, g, b] = img.color();
                let [x, y, z] = img.normal();
                let mut planes: Vec<&[f32]> = [r, g, b, x, y, z]
                    .into_iter()
                    .map(|p| &p[rows.clone()])
                    .collect();
                planes.extend(img.mask().map(|m| &m[rows.clone()]));
                writer.write(&planes)
            }
            Value::Picture(p) => {
                let planes =
                    crate::raster::io::zarr::rgba_planes(&p.rgba[rows.start * 4..rows.end * 4]);
                let refs: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
                writer.write(&refs)
            }
            _ => unreachable!("checked above"),
        }
    }

    /// Moves the finished store into place.
    pub(super) fn commit(self) -> Result<(), RgbnError> {
        match self.writer {
            Some(w) => w.commit(),
            None => Err(RgbnError::Write {
                detail: "no rows were written".into(),
                path: self.path,
            }),
        }
    }
}
