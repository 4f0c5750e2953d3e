//! Row-streamed writes: PNG and EXR targets filled a band of rows at a time (the writing
//! side of [`super::stream`]).
//!
//! - [`PngTarget`] / [`PngRowWriter`] encode rows of normals or colour with the encoding and
//!   compression of [`super::save_normal_map`] / [`super::save_color`] into an [`AtomicFile`]:
//!   the target appears, complete, only when [`PngTarget::commit`] succeeds.
//! - [`ExrTarget`] writes an RGBN EXR band by band through a writer thread.

use super::exr_write::{ExrFormat, RowBlocks};
use super::temp;
use super::{png_format, NormalConvention};
use crate::error::RgbnError;
use crate::raster::srgb::{linear_to_srgb, linear_to_srgb8};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file written under a temporary name beside its target and renamed over it by
/// [`commit`](Self::commit); dropped uncommitted (an error, a panic), it removes the temporary
/// and leaves the target as it was. See [`temp`].
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    file: File,
    _writing: temp::WriteGuard,
}

impl AtomicFile {
    /// Starts writing `path` (its folder must exist).
    pub fn create(path: &Path) -> Result<Self, RgbnError> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !dir.is_dir() {
            return Err(RgbnError::MissingDir { path: path.into() });
        }
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
        let writing = temp::WriteGuard::begin();
        // Temporaries of this target left by a killed process are removed first.
        temp::clean_stale(dir, Some(name));
        let tmp = temp::temp_path(dir, name);
        forget_cached(path);
        let file = File::create(&tmp).map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: path.into(),
        })?;
        Ok(Self {
            path: path.into(),
            tmp,
            file,
            _writing: writing,
        })
    }

    /// A handle to write the bytes through (flush what buffers it before
    /// [`commit`](Self::commit)).
    pub fn handle(&self) -> Result<TargetFile, RgbnError> {
        let file = self.file.try_clone().map_err(|e| self.error(e))?;
        Ok(TargetFile { file, dirty: 0 })
    }

    /// The error of writing the target, `detail` saying what failed.
    #[must_use]
    pub fn error(&self, detail: impl ToString) -> RgbnError {
        RgbnError::Write {
            detail: detail.to_string(),
            path: self.path.clone(),
        }
    }

    /// Flushes, syncs and renames the temporary over the target.
    pub fn commit(mut self) -> Result<(), RgbnError> {
        self.file.sync_data().map_err(|e| self.error(e))?;
        let replaced = replaced::hold(&self.path);
        std::fs::rename(&self.tmp, &self.path).map_err(|e| self.error(e))?;
        // Renamed: nothing left to remove.
        self.tmp = PathBuf::new();
        if let Some(old) = replaced {
            replaced::free_after_exit(old);
        }
        Ok(())
    }
}

/// Leaving the blocks of a file that a commit replaces to be freed after the process exits.
///
/// A rename over a file frees that file when its last name goes, inside the `rename` call:
/// every block given back to the file system (and, on a file system mounted with `discard`,
/// trimmed), 13–20 ms for a 100 MB EXR on this machine's ext4 against 0.1 ms for a rename over
/// no file — at the end of a run, with nothing left to overlap (BENCHMARKS.md, tenth session).
/// A file still open is not freed by the rename, only when it is closed: with
/// [`free_replaced_after_exit`](replaced::free_replaced_after_exit) on (the command line; not the editor, whose process lives on),
/// the commit opens a big target it replaces before renaming and hands the descriptor to a
/// helper process (`cat`, reading a pipe this process holds open) that exits when this process
/// does, freeing the file then. The replaced file has no name from the rename on, as without
/// this; only its blocks are given back later. At most [`HELD_MAX`](replaced::HELD_MAX) bytes are held at once
/// (a batch replacing many big files frees the rest at once), and any failure (no `cat`, no
/// process) frees the file at once, as before.
pub mod replaced {
    use std::fs::File;
    use std::path::Path;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

    /// Whether commits hand replaced files over ([`free_replaced_after_exit`]).
    static ON: AtomicBool = AtomicBool::new(false);
    /// Bytes of replaced files held so far.
    static HELD: AtomicU64 = AtomicU64::new(0);
    /// Bytes of replaced files held at most.
    pub const HELD_MAX: u64 = 1 << 30;
    /// Files from this size up are handed over (smaller ones cost little to free): the size
    /// from which a replaced file's cached pages are dropped too.
    pub const FROM: u64 = super::FORGET_FROM;

    /// Turns the hand-over on for the rest of the process (a command that exits when done).
    pub fn free_replaced_after_exit() {
        ON.store(true, Ordering::Relaxed);
    }

    /// The big regular file at `path` that a rename is about to replace, open, when it is to be
    /// handed over.
    pub(super) fn hold(path: &Path) -> Option<File> {
        if !cfg!(target_os = "linux") || !ON.load(Ordering::Relaxed) {
            return None;
        }
        // A symbolic link is replaced, not what it points to: nothing to hold.
        if !std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) {
            return None;
        }
        let f = File::open(path).ok()?;
        let len = f.metadata().ok().filter(|m| m.is_file())?.len();
        if len < FROM {
            return None;
        }
        HELD.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |h| {
            (h + len <= HELD_MAX).then_some(h + len)
        })
        .ok()?;
        Some(f)
    }

    /// Hands `old` (renamed over, so nameless) to a helper process that holds it until this
    /// process exits; without one, `old` is closed here and freed now.
    #[cfg(target_os = "linux")]
    pub(super) fn free_after_exit(old: File) {
        use std::os::fd::AsRawFd;
        use std::process::{Command, Stdio};
        // The helper inherits the descriptor: close-on-exec cleared on it (rgbn opens every
        // file with it set, so nothing else is inherited).
        // SAFETY: `fcntl` on a descriptor `old` owns; it changes only its flags.
        if unsafe { libc::fcntl(old.as_raw_fd(), libc::F_SETFD, 0) } != 0 {
            return;
        }
        let helper = Command::new("cat")
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn();
        drop(old);
        if let Ok(mut child) = helper {
            // The pipe's writing end stays open until this process exits; then `cat` reads
            // the end of its input and exits, and the file is freed. The child is not waited
            // for: once this process has exited, init reaps it.
            std::mem::forget(child.stdin.take());
        }
    }

    #[cfg(not(target_os = "linux"))]
    pub(super) fn free_after_exit(_old: File) {}
}

/// Files from this size up that a new target replaces have their cached pages dropped
/// beforehand ([`forget_cached`]).
const FORGET_FROM: u64 = 8 << 20;

/// Drops the page cache of the file at `path` that the target being written will replace (a
/// big one: [`FORGET_FROM`]), on a thread of its own (Linux; elsewhere nothing). The commit's
/// rename frees the replaced file, and freeing its cached pages was most of what the rename
/// cost beside the disk's own work: 6–7 ms of a 21 ms rename over a 100 MB EXR here, at the
/// end of the run with nothing else left to overlap (BENCHMARKS.md). Dropped now, beside the
/// work, the rename does not wait for it. The file itself is untouched (the pages are clean
/// copies of what is on disk): a run that fails leaves it as it was.
#[cfg(target_os = "linux")]
fn forget_cached(path: &Path) {
    let big = std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() >= FORGET_FROM);
    if !big {
        return;
    }
    let path = path.to_path_buf();
    // A hint: a thread that cannot start, or a file that cannot be opened, changes nothing.
    let _ = std::thread::Builder::new()
        .name("rgbn-forget-cached".into())
        .spawn(move || {
            if let Ok(f) = File::open(&path) {
                super::ahead::advise(&f, 0, 0, libc::POSIX_FADV_DONTNEED);
            }
        });
}

#[cfg(not(target_os = "linux"))]
fn forget_cached(_path: &Path) {}

/// Bytes written between two requests to start writing back ([`TargetFile`]).
const WRITEBACK_EVERY: usize = 8 << 20;

/// The writing side of an [`AtomicFile`]: a file that, every `WRITEBACK_EVERY` bytes, asks
/// the kernel to start writing its dirty pages to the disk (Linux `sync_file_range` with
/// `SYNC_FILE_RANGE_WRITE`: asynchronous, a hint). The disk then works while the rest of the
/// file is encoded, and the sync in [`AtomicFile::commit`] waits only for the last pages
/// instead of the whole file (≈ 0.2 s for a 100 MB EXR on this machine).
pub struct TargetFile {
    file: File,
    dirty: usize,
}

impl TargetFile {
    fn wrote(&mut self, n: usize) {
        self.dirty += n;
        if self.dirty >= WRITEBACK_EVERY {
            self.dirty = 0;
            start_writeback(&self.file);
        }
    }
}

/// Starts writing `file`'s dirty pages back, without waiting (Linux; elsewhere nothing).
#[cfg(target_os = "linux")]
fn start_writeback(file: &File) {
    use std::os::fd::AsRawFd;
    // SAFETY: a valid open descriptor; offset 0 and length 0 mean the whole file. The result
    // is ignored: it is a hint, and the sync at commit is what guarantees the data.
    unsafe {
        libc::sync_file_range(file.as_raw_fd(), 0, 0, libc::SYNC_FILE_RANGE_WRITE);
    }
}

#[cfg(not(target_os = "linux"))]
fn start_writeback(_file: &File) {}

impl Write for TargetFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.wrote(n);
        Ok(n)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.file.write_all(buf)?;
        self.wrote(buf.len());
        Ok(())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl std::io::Seek for TargetFile {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.file.seek(pos)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Rows of an RGBN image on their way to an [`ExrTarget`]'s writer thread: the image (its
/// planes shared, not copied) and the rows to write.
struct ExrBand {
    img: crate::raster::RgbnImage,
    rows: std::ops::Range<usize>,
}

impl ExrBand {
    /// The band's rows of each plane, in the file's (alphabetical) channel order: `A` (with a
    /// mask), `B`, `G`, `N.X`, `N.Y`, `N.Z`, `R`.
    fn planes(&self) -> Vec<&[f32]> {
        let w = self.img.width();
        let (a, b) = (self.rows.start * w, self.rows.end * w);
        let [r, g, bl] = self.img.color();
        let [nx, ny, nz] = self.img.normal();
        let mut planes: Vec<&[f32]> = Vec::with_capacity(7);
        if let Some(m) = self.img.mask() {
            planes.push(&m[a..b]);
        }
        planes.extend([bl, g, nx, ny, nz, r].map(|p| &p[a..b]));
        planes
    }
}

/// An RGBN image written to an EXR a band of rows at a time, as [`super::save_exr_with`]
/// writes it: `R,G,B`, `N.X,N.Y,N.Z` and `A` when there is a mask, in the given
/// [`ExrFormat`]; whole blocks are compressed on every core as soon as their rows arrive. The
/// exr crate writes a file within one call, so a thread owns the writer and the bands are sent
/// to it (one band in flight). The target appears, complete, only when [`ExrTarget::commit`]
/// succeeds.
pub struct ExrTarget {
    tx: Option<std::sync::mpsc::SyncSender<ExrBand>>,
    /// With one thread ([`crate::raster::par::pipelined`]), the writer says when a band is
    /// written and [`write`](Self::write) waits for it: the band is compressed and written
    /// while the caller waits, not beside its next strip.
    done: Option<std::sync::mpsc::Receiver<()>>,
    thread: Option<std::thread::JoinHandle<Result<(), String>>>,
    file: Option<AtomicFile>,
    width: usize,
}

impl ExrTarget {
    /// Starts writing a `width × height` RGBN EXR at `path` (its folder must exist).
    pub fn create(
        path: &Path,
        width: usize,
        height: usize,
        format: ExrFormat,
    ) -> Result<Self, RgbnError> {
        let file = AtomicFile::create(path)?;
        let handle = file.handle()?;
        let (tx, rx) = std::sync::mpsc::sync_channel::<ExrBand>(1);
        let (done_tx, done) = if crate::raster::par::pipelined() {
            (None, None)
        } else {
            let (t, r) = std::sync::mpsc::sync_channel::<()>(1);
            (Some(t), Some(r))
        };
        let thread = std::thread::Builder::new()
            .name("rgbn-exr-writer".into())
            .spawn(move || -> Result<(), String> {
                let Ok(first) = rx.recv() else {
                    return Err("no rows were written".into());
                };
                let mask = first.img.mask().is_some();
                let names: Vec<&'static str> = if mask {
                    vec!["A", "B", "G", "N.X", "N.Y", "N.Z", "R"]
                } else {
                    vec!["B", "G", "N.X", "N.Y", "N.Z", "R"]
                };
                let mut rows = RowBlocks::new(width, height, names);
                let mut out = BufWriter::with_capacity(1 << 20, handle);
                let headers: exr::meta::Headers = std::iter::once(rows.header(format)).collect();
                exr::block::write(&mut out, headers, true, |meta, writer| {
                    let mut band = Some(first);
                    while let Some(b) = band.take().or_else(|| rx.recv().ok()) {
                        if b.img.mask().is_some() != mask {
                            return Err(exr::error::Error::Invalid(
                                "a band with a mask and one without in the same image".into(),
                            ));
                        }
                        rows.push(writer, &meta.headers, &b.planes(), b.rows.len())?;
                        // The band's planes go back to their owner (or are freed) now.
                        drop(b);
                        if let Some(d) = &done_tx {
                            // The caller may be gone (an error of its own): nothing to tell.
                            let _ = d.send(());
                        }
                    }
                    if rows.written() == height {
                        Ok(())
                    } else {
                        Err(exr::error::Error::Invalid(
                            format!("only {} of {height} rows were written", rows.written()).into(),
                        ))
                    }
                })
                .map_err(|e| e.to_string())?;
                out.flush().map_err(|e| e.to_string())
            })
            .map_err(|e| RgbnError::Write {
                detail: format!("cannot start the EXR writer: {e}"),
                path: path.into(),
            })?;
        Ok(Self {
            tx: Some(tx),
            done,
            thread: Some(thread),
            file: Some(file),
            width,
        })
    }

    /// Writes rows `rows` of `img` (whose width is the target's) as the next rows of the file.
    pub fn write(
        &mut self,
        img: &crate::raster::RgbnImage,
        rows: std::ops::Range<usize>,
    ) -> Result<(), RgbnError> {
        if img.width() != self.width || rows.end > img.height() {
            return Err(self.error(format!(
                "rows {rows:?} of a {}×{} image do not fit a {}-wide EXR",
                img.width(),
                img.height(),
                self.width
            )));
        }
        // The planes are shared with the writer, not copied: the caller's next strip starts
        // at once, and the memory of a copy is never touched.
        let band = ExrBand {
            img: img.clone(),
            rows,
        };
        let sent = self.tx.as_ref().is_some_and(|tx| tx.send(band).is_ok())
            && self.done.as_ref().is_none_or(|d| d.recv().is_ok());
        if sent {
            Ok(())
        } else {
            // The writer stopped: its error.
            Err(self
                .finish()
                .err()
                .unwrap_or_else(|| self.error("the EXR writer stopped")))
        }
    }

    fn error(&self, detail: impl ToString) -> RgbnError {
        match &self.file {
            Some(f) => f.error(detail),
            None => RgbnError::Write {
                detail: detail.to_string(),
                path: PathBuf::new(),
            },
        }
    }

    /// Ends the rows and waits for the writer.
    fn finish(&mut self) -> Result<(), RgbnError> {
        self.tx.take();
        match self.thread.take().map(std::thread::JoinHandle::join) {
            Some(Ok(Ok(()))) | None => Ok(()),
            Some(Ok(Err(e))) => Err(self.error(e)),
            Some(Err(_)) => Err(self.error("the EXR writer panicked")),
        }
    }

    /// Completes the file (every row must have been written) and renames it over the target.
    pub fn commit(mut self) -> Result<(), RgbnError> {
        self.finish()?;
        self.file.take().expect("committed once").commit()
    }
}

impl Drop for ExrTarget {
    fn drop(&mut self) {
        // The writer stops (missing rows are its error) before the temporary file goes.
        let _ = self.finish();
    }
}

/// What a [`PngRowWriter`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowEncoding {
    /// Normals as a normal map: `round((n+1)/2·(2^bits−1))` (RGB).
    Normal(NormalConvention),
    /// Linear colour as sRGB (RGB).
    Srgb,
}

/// A PNG being written: its header is out, its rows go through [`rows`](Self::rows), and
/// [`commit`](Self::commit) ends it and renames it into place.
pub struct PngTarget {
    file: AtomicFile,
    writer: png::Writer<BufWriter<TargetFile>>,
    width: usize,
    height: usize,
    bits: u8,
}

impl PngTarget {
    /// Starts `path`: a `width × height` RGB PNG of `bits` (8 or 16) per sample, compressed
    /// as [`super::save_normal_map`] does.
    pub fn create(path: &Path, width: usize, height: usize, bits: u8) -> Result<Self, RgbnError> {
        Self::start(path, width, height, bits, png::ColorType::Rgb)
    }

    /// Starts `path`: a `width × height` 8-bit RGBA PNG (pictures), written with
    /// [`PngRowWriter::write_rgba8`].
    pub fn create_rgba8(path: &Path, width: usize, height: usize) -> Result<Self, RgbnError> {
        Self::start(path, width, height, 8, png::ColorType::Rgba)
    }

    fn start(
        path: &Path,
        width: usize,
        height: usize,
        bits: u8,
        color: png::ColorType,
    ) -> Result<Self, RgbnError> {
        let file = AtomicFile::create(path)?;
        let out = BufWriter::with_capacity(1 << 20, file.handle()?);
        let (w, h) = (
            u32::try_from(width).map_err(|e| file.error(e))?,
            u32::try_from(height).map_err(|e| file.error(e))?,
        );
        let mut enc = png::Encoder::new(out, w, h);
        png_format(&mut enc, color, bits == 16);
        let writer = enc.write_header().map_err(|e| file.error(e))?;
        Ok(Self {
            file,
            writer,
            width,
            height,
            bits,
        })
    }

    /// The row writer (call once; its [`finish`](PngRowWriter::finish) before
    /// [`commit`](Self::commit)).
    pub fn rows(&mut self, encoding: RowEncoding) -> Result<PngRowWriter<'_>, RgbnError> {
        let stream = self
            .writer
            .stream_writer_with_size(1 << 16)
            .map_err(|e| self.file.error(e))?;
        Ok(PngRowWriter {
            stream,
            path: &self.file.path,
            width: self.width,
            height: self.height,
            sixteen: self.bits == 16,
            encoding,
            row: 0,
            bytes: Vec::new(),
        })
    }

    /// Ends the PNG and renames it over the target.
    pub fn commit(self) -> Result<(), RgbnError> {
        let Self { file, writer, .. } = self;
        writer.finish().map_err(|e| file.error(e))?;
        file.commit()
    }
}

/// The rows of a [`PngTarget`], a band at a time.
pub struct PngRowWriter<'a> {
    stream: png::StreamWriter<'a, BufWriter<TargetFile>>,
    path: &'a Path,
    width: usize,
    height: usize,
    sixteen: bool,
    encoding: RowEncoding,
    /// Rows written so far.
    row: usize,
    bytes: Vec<u8>,
}

impl PngRowWriter<'_> {
    fn error(&self, detail: impl ToString) -> RgbnError {
        RgbnError::Write {
            detail: detail.to_string(),
            path: self.path.into(),
        }
    }

    /// Encodes planes `[a, b, c]` (normal x, y, z or linear R, G, B) into `self.bytes` as PNG
    /// samples, with the arithmetic of the whole-image writers.
    fn encode(&mut self, planes: [&[f32]; 3]) {
        use rayon::prelude::*;
        const CHUNK: usize = 4096;
        let n = planes[0].len();
        let sixteen = self.sixteen;
        let per = if sixteen { 6 } else { 3 };
        self.bytes.clear();
        self.bytes.resize(n * per, 0);
        let scale = if sixteen { 65535.0 } else { 255.0 };
        let enc = self.encoding;
        let sample = move |v: f32, k: usize| -> u16 {
            match enc {
                RowEncoding::Normal(conv) => {
                    let v = if k == 1 && conv == NormalConvention::DirectX {
                        -v
                    } else {
                        v
                    };
                    ((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * scale + 0.5).min(scale) as u16
                }
                RowEncoding::Srgb if sixteen => {
                    (linear_to_srgb(v.clamp(0.0, 1.0)) * 65535.0 + 0.5) as u16
                }
                RowEncoding::Srgb => u16::from(linear_to_srgb8(v)),
            }
        };
        self.bytes
            .par_chunks_mut(CHUNK * per)
            .enumerate()
            .for_each(|(ci, out)| {
                let base = ci * CHUNK;
                for (i, px) in out.chunks_exact_mut(per).enumerate() {
                    for (k, plane) in planes.iter().enumerate() {
                        let s = sample(plane[base + i], k);
                        if sixteen {
                            px[2 * k..2 * k + 2].copy_from_slice(&s.to_be_bytes());
                        } else {
                            px[k] = s as u8;
                        }
                    }
                }
            });
    }

    /// Appends the next rows: planes `[a, b, c]` of the same whole number of rows.
    pub fn write(&mut self, planes: [&[f32]; 3]) -> Result<(), RgbnError> {
        let rows = planes[0].len() / self.width;
        if self.row + rows > self.height {
            return Err(self.error(format!(
                "{} rows written to a {}-row image",
                self.row + rows,
                self.height
            )));
        }
        self.encode(planes);
        self.row += rows;
        let r = self.stream.write_all(&self.bytes);
        r.map_err(|e| self.error(e))
    }

    /// Appends the next rows of an RGBA target: `4 · width` bytes per row.
    pub fn write_rgba8(&mut self, bytes: &[u8]) -> Result<(), RgbnError> {
        let rows = bytes.len() / (4 * self.width);
        if self.row + rows > self.height {
            return Err(self.error(format!(
                "{} rows written to a {}-row image",
                self.row + rows,
                self.height
            )));
        }
        self.row += rows;
        let r = self.stream.write_all(bytes);
        r.map_err(|e| self.error(e))
    }

    /// Checks that every row was written and ends the image data.
    pub fn finish(self) -> Result<(), RgbnError> {
        if self.row != self.height {
            return Err(self.error(format!(
                "only {} of {} rows were written",
                self.row, self.height
            )));
        }
        let path = self.path;
        self.stream.finish().map_err(|e| RgbnError::Write {
            detail: e.to_string(),
            path: path.into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Seek, SeekFrom};

    #[test]
    fn a_target_written_past_several_writebacks_and_patched_by_seeking_reads_back_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.bin");
        std::fs::write(&path, b"the old target").unwrap();
        // 2.5 writeback intervals of a byte pattern, odd-sized writes, then the first 8 bytes
        // patched after seeking back (as the EXR writer patches its offset table).
        let n = WRITEBACK_EVERY * 5 / 2 + 12_345;
        let expected: Vec<u8> = (0..n)
            .map(|i| if i < 8 { 0xEE } else { (i * 7 % 251) as u8 })
            .collect();
        let file = AtomicFile::create(&path).unwrap();
        let mut out = file.handle().unwrap();
        let mut at = 0;
        for chunk in (0..n)
            .map(|i| (i * 7 % 251) as u8)
            .collect::<Vec<_>>()
            .chunks(1_000_003)
        {
            out.write_all(chunk).unwrap();
            at += chunk.len();
        }
        assert_eq!(at, n);
        out.seek(SeekFrom::Start(0)).unwrap();
        out.write_all(&[0xEE; 8]).unwrap();
        out.flush().unwrap();
        // Before the commit the old target is untouched.
        assert_eq!(std::fs::read(&path).unwrap(), b"the old target");
        file.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), expected);
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "no temporary left beside the target");
    }

    /// With the hand-over on, a commit over a big file renames at once and the replaced file
    /// lives on, nameless, held open by a helper child of this process (freed when the process
    /// exits); the target holds the new bytes. A small file is not handed over.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_big_replaced_file_is_held_by_a_helper_until_the_process_exits() {
        use std::os::unix::fs::MetadataExt;
        if std::process::Command::new("cat")
            .arg("/dev/null")
            .status()
            .is_err()
        {
            eprintln!("skipped: no `cat` to hand the replaced file to");
            return;
        }
        replaced::free_replaced_after_exit();
        let dir = tempfile::tempdir().unwrap();
        let (big, small) = (dir.path().join("big.exr"), dir.path().join("small.png"));
        std::fs::write(&big, vec![7u8; replaced::FROM as usize + 1]).unwrap();
        std::fs::write(&small, b"small").unwrap();
        let (big_ino, small_ino) = (
            std::fs::metadata(&big).unwrap().ino(),
            std::fs::metadata(&small).unwrap().ino(),
        );
        for path in [&big, &small] {
            let file = AtomicFile::create(path).unwrap();
            file.handle().unwrap().write_all(b"new bytes").unwrap();
            file.commit().unwrap();
            assert_eq!(std::fs::read(path).unwrap(), b"new bytes");
        }
        // The descriptors of this process's children that point at a replaced file.
        let me = std::process::id().to_string();
        let held: Vec<u64> = std::fs::read_dir("/proc")
            .unwrap()
            .flatten()
            .filter(|p| {
                std::fs::read_to_string(p.path().join("stat")).is_ok_and(|st| {
                    // Field 4 (after the parenthesised name) is the parent's pid.
                    st.rsplit_once(") ")
                        .and_then(|(_, rest)| rest.split(' ').nth(1).map(|pp| pp == me))
                        .unwrap_or(false)
                })
            })
            .filter_map(|p| std::fs::read_dir(p.path().join("fd")).ok())
            .flatten()
            .flatten()
            .filter_map(|fd| std::fs::metadata(fd.path()).ok())
            .map(|m| m.ino())
            .collect();
        assert!(
            held.contains(&big_ino),
            "the replaced big file is held by a helper child"
        );
        assert!(!held.contains(&small_ino), "a small file is freed at once");
    }

    /// A big file that a target replaces has its cached pages dropped when the target is
    /// created; its bytes stay: a target dropped uncommitted leaves them, a committed one
    /// replaces them.
    #[test]
    fn a_big_replaced_file_keeps_its_bytes_until_the_commit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.exr");
        let old: Vec<u8> = (0..FORGET_FROM as usize + 4097)
            .map(|i| (i * 13 % 241) as u8)
            .collect();
        std::fs::write(&path, &old).unwrap();
        {
            let file = AtomicFile::create(&path).unwrap();
            file.handle()
                .unwrap()
                .write_all(b"half a new file")
                .unwrap();
            // Dropped uncommitted (an error): the old file as it was.
        }
        assert_eq!(std::fs::read(&path).unwrap(), old);
        let file = AtomicFile::create(&path).unwrap();
        file.handle().unwrap().write_all(b"the new file").unwrap();
        file.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"the new file");
    }
}
