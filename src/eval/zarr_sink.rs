//! A streamed output written into an OME-Zarr store: each strip's rows handed to a
//! [`ZarrRowWriter`], made at the first strip (when the output's channels are known: a mask or
//! not). The whole store (`rgbn eval`, streamed), or one chunk-aligned region of it cut out of
//! strips of a larger window (an `rgbn.dask` task, [`super::stream::StreamPlan::set_window`]).

use super::stream::{StreamPlan, Streamable};
use super::Plan;
use crate::cancel::Cancel;
use crate::error::RgbnError;
use crate::graph::GraphError;
use crate::nodes::Value;
use crate::raster::io::zarr::{Content, Layout, ZarrOptions, ZarrRowWriter};
use crate::raster::window::Rect;
use std::ops::Range;
use std::path::PathBuf;

/// One output's store.
pub struct ZarrSink {
    path: PathBuf,
    size: (usize, usize),
    /// The level-0 pixels written (`None`: the whole store, made aside and swapped in).
    area: Option<Rect>,
    opts: ZarrOptions,
    writer: Option<ZarrRowWriter>,
}

impl ZarrSink {
    /// The whole store at `path` of a `size` output.
    #[must_use]
    pub fn new(path: PathBuf, size: (usize, usize), opts: ZarrOptions) -> Self {
        Self {
            path,
            size,
            area: None,
            opts,
            writer: None,
        }
    }

    /// Region `area` (chunk-aligned) of the store at `path` of a `size` output, written in
    /// place; the store is created at `size` if it does not exist
    /// ([`crate::raster::io::zarr::ZarrWriter::create_region`]).
    #[must_use]
    pub fn region(path: PathBuf, size: (usize, usize), area: Rect, opts: ZarrOptions) -> Self {
        Self {
            area: Some(area),
            ..Self::new(path, size, opts)
        }
    }

    /// Writes the `core` rows of a strip's value (an image or a picture), whole rows.
    pub fn write(&mut self, v: &Value, core: Range<usize>) -> Result<(), RgbnError> {
        let w = match v {
            Value::Rgbn(img) => img.width(),
            Value::Picture(p) => p.width,
            _ => 0,
        };
        self.write_part(v, core, 0..w)
    }

    /// Writes rows `rows` of a strip's value, columns `cols` of them.
    pub fn write_part(
        &mut self,
        v: &Value,
        rows: Range<usize>,
        cols: Range<usize>,
    ) -> Result<(), RgbnError> {
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
            self.writer = Some(match self.area {
                None => ZarrRowWriter::create(&self.path, layout)?,
                Some(a) => ZarrRowWriter::create_region(&self.path, layout, a)?,
            });
        }
        let writer = self.writer.as_mut().expect("made above");
        // Rows `rows`, columns `cols` of a plane `w` wide: borrowed when whole rows, else copied.
        let whole = cols.start == 0 && cols.end == w;
        let cut = |p: &[f32]| -> Vec<f32> {
            let mut out = Vec::with_capacity(rows.len() * cols.len());
            for y in rows.clone() {
                out.extend_from_slice(&p[y * w + cols.start..y * w + cols.end]);
            }
            out
        };
        match v {
            Value::Rgbn(img) => {
                let [r, g, b] = img.color();
                let [x, y, z] = img.normal();
                let mut all: Vec<&[f32]> = vec![r, g, b, x, y, z];
                all.extend(img.mask());
                if whole {
                    let span = rows.start * w..rows.end * w;
                    let planes: Vec<&[f32]> = all.iter().map(|p| &p[span.clone()]).collect();
                    writer.write(&planes)
                } else {
                    let owned: Vec<Vec<f32>> = all.iter().map(|p| cut(p)).collect();
                    let planes: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
                    writer.write(&planes)
                }
            }
            Value::Picture(p) => {
                let bytes: Vec<u8>;
                let rgba = if whole {
                    &p.rgba[rows.start * w * 4..rows.end * w * 4]
                } else {
                    bytes = rows
                        .clone()
                        .flat_map(|y| &p.rgba[(y * w + cols.start) * 4..(y * w + cols.end) * 4])
                        .copied()
                        .collect();
                    &bytes[..]
                };
                let planes = crate::raster::io::zarr::rgba_planes(rgba);
                let refs: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
                writer.write(&refs)
            }
            _ => unreachable!("checked above"),
        }
    }

    /// Moves the finished store into place (a region's chunks are in place already).
    pub fn commit(self) -> Result<(), RgbnError> {
        match self.writer {
            Some(w) => w.commit(),
            None => Err(RgbnError::Write {
                detail: "no rows were written".into(),
                path: self.path,
            }),
        }
    }
}

/// Writes `rect` (chunk-aligned, level 0) of each output into its store (`(name, store)`),
/// streamed, when the outputs can be (`Ok(false)`: they cannot; use the region plan): images
/// and pictures that depend through local operators on one OME-Zarr store, as for a streamed
/// `rgbn eval` ([`StreamPlan`]). The store is read in a window — `rect` grown by the plan's
/// halo — top to bottom, each chunk row of the window decoded once and dropped when passed,
/// and each output's rows of `rect` go into its store as soon as a row of chunks is complete
/// (the store is created at the output's size if it does not exist; chunks are written
/// atomically). So the memory is a few strips and chunk rows of the window, whatever its size.
/// The rectangle's pixels are the whole evaluation's: each one kept lies at least the halo
/// inside the window's edges that are not the image's. One `rgbn.dask` task.
pub fn stream_region_into_stores<E: From<GraphError> + From<RgbnError>>(
    plan: &Plan,
    outputs: &[(String, PathBuf)],
    rect: Rect,
    opts: &ZarrOptions,
    cancel: &Cancel,
) -> Result<bool, E> {
    let asked: Vec<&str> = outputs.iter().map(|(n, _)| n.as_str()).collect();
    let Some(mut sp) = windowable(plan, &asked)? else {
        return Ok(false);
    };
    let (w, h) = sp.size();
    let halo = sp.halo();
    if rect.is_empty() || rect.right() > w || rect.bottom() > h {
        return Err(RgbnError::InvalidParam {
            name: "region".into(),
            detail: format!(
                "{},{},{},{} is not inside the {w}×{h} output",
                rect.x, rect.y, rect.w, rect.h
            ),
        }
        .into());
    }
    let (x0, y0) = (rect.x.saturating_sub(halo), rect.y.saturating_sub(halo));
    let window = Rect::new(
        x0,
        y0,
        (rect.right() + halo).min(w) - x0,
        (rect.bottom() + halo).min(h) - y0,
    );
    sp.set_window(window)
        .map_err(|why| RgbnError::InvalidParam {
            name: "region".into(),
            detail: why,
        })?;
    let mut sinks: Vec<ZarrSink> = outputs
        .iter()
        .map(|(_, p)| ZarrSink::region(p.clone(), (w, h), rect, *opts))
        .collect();
    let cols = rect.x - x0..rect.right() - x0;
    sp.run(None, cancel, |first, values, core| -> Result<(), E> {
        // The strip's core rows as image rows, cut to the rectangle's.
        let (a, b) = (first.max(rect.y), (first + core.len()).min(rect.bottom()));
        if a < b {
            let rows = core.start + (a - first)..core.start + (b - first);
            for (s, v) in sinks.iter_mut().zip(values) {
                s.write_part(v, rows.clone(), cols.clone())?;
            }
        }
        Ok(())
    })?;
    for s in sinks {
        s.commit()?;
    }
    Ok(true)
}

/// Whether `outputs` stream in windows ([`stream_region_into_stores`] writes them): the
/// client of `rgbn.dask` asks, to choose large tasks.
pub fn streams_in_windows(plan: &Plan, outputs: &[&str]) -> Result<bool, GraphError> {
    Ok(windowable(plan, outputs)?.is_some())
}

/// The streamed plan of `outputs` (its window the whole image) when they stream from an input
/// that can be read in windows (an OME-Zarr store; files are read in whole rows).
fn windowable<'p>(plan: &'p Plan, outputs: &[&str]) -> Result<Option<StreamPlan<'p>>, GraphError> {
    let mut sp = match StreamPlan::check(plan, outputs)? {
        Streamable::Yes(sp) => *sp,
        Streamable::No(_) => return Ok(None),
    };
    // The whole image as the window: only tests that the input can be read in windows.
    let full = Rect::full(sp.size());
    Ok(sp.set_window(full).is_ok().then_some(sp))
}
