//! A streamed PNG output's rows, encoded where the strips are computed or handed to tasks on
//! the pool or a thread of its own (a part of [`crate::cli`]'s streamed `eval`).

use crate::error::RgbnError;
use crate::raster::io::targets::{PngRowWriter, PngTarget, RowEncoding};
use std::sync::Arc;

/// Rows of a streamed PNG output: the strip's value (its planes or bytes shared, not copied)
/// and the strip's rows of it.
pub(super) enum PngBand {
    /// Normals of an image.
    Normals(crate::raster::RgbnImage, std::ops::Range<usize>),
    /// A picture's RGBA bytes.
    Rgba(Arc<crate::nodes::value::Picture>, std::ops::Range<usize>),
}

impl PngBand {
    /// Encodes the rows into `rows`.
    fn write_to(&self, rows: &mut PngRowWriter<'_>) -> Result<(), RgbnError> {
        match self {
            PngBand::Normals(img, r) => {
                let (a, b) = (r.start * img.width(), r.end * img.width());
                let [x, y, z] = img.normal();
                rows.write([&x[a..b], &y[a..b], &z[a..b]])
            }
            PngBand::Rgba(p, r) => {
                rows.write_rgba8(&p.rgba[4 * r.start * p.width..4 * r.end * p.width])
            }
        }
    }
}

/// A streamed PNG written by tasks on the pool ([`PngSink::pool`]).
type PoolPng<'r, 's> = crate::raster::par::Sequenced<
    'r,
    's,
    PngBand,
    PngRowWriter<'s>,
    fn(&mut PngRowWriter<'s>, PngBand) -> Result<(), RgbnError>,
>;

/// [`PngBand::write_to`] as a function for [`PoolPng`].
fn write_png_band(rows: &mut PngRowWriter<'_>, band: PngBand) -> Result<(), RgbnError> {
    band.write_to(rows)
}

/// Where a streamed PNG output's rows go: encoded here, or (with more than one thread,
/// [`crate::raster::par::pipelined`]) handed to tasks on the pool (a caller outside it) or to
/// a thread of its own (a worker of a pool), that filter and compress them while the next
/// strip is computed. The band shares the strip's planes: the
/// main thread copies nothing (a copy of every band, 33 MB for a 4K picture, was serial work
/// between two strips' parallel work).
pub(super) enum PngSink<'r, 's> {
    Here(Box<PngRowWriter<'s>>),
    Pool(Box<PoolPng<'r, 's>>),
    Thread {
        tx: std::sync::mpsc::SyncSender<PngBand>,
        writer: std::thread::ScopedJoinHandle<'s, Result<(), RgbnError>>,
    },
}

impl<'r, 's> PngSink<'r, 's> {
    /// A writing thread for `target`'s rows (one band waiting, one being written).
    pub(super) fn thread<'e>(
        scope: &'s std::thread::Scope<'s, 'e>,
        target: &'s mut PngTarget,
        encoding: RowEncoding,
    ) -> Self {
        let (tx, rx) = std::sync::mpsc::sync_channel::<PngBand>(1);
        let writer = scope.spawn(move || {
            let mut rows = target.rows(encoding)?;
            for band in rx {
                band.write_to(&mut rows)?;
            }
            rows.finish()
        });
        PngSink::Thread { tx, writer }
    }

    /// Writing tasks on the pool for `target`'s rows ([`crate::raster::par::Sequenced`]: one
    /// band waiting, one being written).
    pub(super) fn pool(
        scope: &'r rayon::Scope<'s>,
        target: &'s mut PngTarget,
        encoding: RowEncoding,
    ) -> Result<Self, RgbnError> {
        let rows = target.rows(encoding)?;
        Ok(PngSink::Pool(Box::new(crate::raster::par::Sequenced::new(
            scope,
            rows,
            1,
            write_png_band,
        ))))
    }

    /// Writes the next rows. `Err(None)`: the writing thread stopped (its error comes from
    /// [`finish`](Self::finish)).
    pub(super) fn write(&mut self, band: PngBand) -> Result<(), Option<RgbnError>> {
        match self {
            PngSink::Here(rows) => band.write_to(rows).map_err(Some),
            PngSink::Pool(s) => s.push(band).map_err(|()| None),
            PngSink::Thread { tx, .. } => tx.send(band).map_err(|_| None),
        }
    }

    /// Ends the rows (every row must have been written).
    pub(super) fn finish(self) -> Result<(), RgbnError> {
        match self {
            PngSink::Here(rows) => rows.finish(),
            PngSink::Pool(s) => s.finish()?.finish(),
            PngSink::Thread { tx, writer } => {
                drop(tx);
                writer
                    .join()
                    .unwrap_or_else(|p| std::panic::resume_unwind(p))
            }
        }
    }
}
