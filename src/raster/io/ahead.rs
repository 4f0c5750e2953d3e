//! Input files read with the kernel asked to fetch ahead of the reads.
//!
//! Image files are read front to back, a buffer at a time. Pages of the file that are not in
//! the page cache (a first read, or pages the kernel reclaimed since the last one) are then
//! read from the disk one readahead window at a time, each synchronously, when the decoder
//! reaches them, and such a read waits behind whatever the disk is already doing: while
//! `rgbn eval` writes its outputs, a decoder that met a few reclaimed pages of a cached 4K PNG
//! stalled 10–90 ms per run (off-CPU in `filemap_read`, measured with `perf record -e
//! sched:sched_switch`; none when the same file was read from tmpfs; BENCHMARKS.md). The
//! decoding is the one part of a streamed evaluation that cannot be split, so the whole run
//! waited.
//!
//! [`ReadAhead`] asks for [`WINDOW`] bytes beyond the read position (`posix_fadvise` with
//! `POSIX_FADV_WILLNEED`: the kernel starts reading the pages it lacks and returns; pages
//! already cached cost a lookup, 0.1–0.2 ms for a 38 MB file here), half a window at a time,
//! so the disk works ahead of the decoder and the memory asked for stays bounded whatever the
//! file's size. A seek (EXR and TIFF readers jump to offset tables and strips) starts a window
//! at the new position. On other systems it is a plain file.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

/// Bytes asked for ahead of the read position.
pub const WINDOW: u64 = 32 << 20;

/// A file read with [`WINDOW`] bytes ahead of the reads asked of the kernel (module docs).
pub struct ReadAhead {
    file: File,
    len: u64,
    pos: u64,
    window: u64,
    /// Bytes `[start, end)` asked for.
    asked: (u64, u64),
}

impl ReadAhead {
    /// Wraps `file` (positioned at its start) and asks for its first [`WINDOW`].
    #[must_use]
    pub fn new(file: File) -> Self {
        Self::with_window(file, WINDOW)
    }

    /// As [`new`](Self::new), asking `window` bytes ahead.
    #[must_use]
    pub fn with_window(file: File, window: u64) -> Self {
        let len = file.metadata().map_or(0, |m| m.len());
        let mut r = Self {
            file,
            len,
            pos: 0,
            window,
            asked: (0, 0),
        };
        r.ask();
        r
    }

    /// Asks for what [`next_ask`] says the position needs.
    fn ask(&mut self) {
        if let Some(ask) = next_ask(self.pos, self.asked, self.len, self.window) {
            will_need(&self.file, ask.0, ask.1 - ask.0);
            self.asked = asked_after(self.asked, ask);
        }
    }
}

/// The bytes `[from, to)` to ask for next when reading at `pos` of a file of `len` bytes,
/// `asked` being asked already, `window` bytes ahead; `None` while at least half a window
/// ahead is asked for (or the file's end). Inside the asked range the next half window follows
/// it; outside (a seek, or nothing asked yet), a whole window starts at `pos`.
#[must_use]
pub fn next_ask(pos: u64, asked: (u64, u64), len: u64, window: u64) -> Option<(u64, u64)> {
    let (start, end) = asked;
    let half = window / 2;
    if pos >= len {
        return None;
    }
    if start == end || pos < start || pos > end {
        return Some((pos, (pos + window).min(len)));
    }
    if end >= len || end >= pos + half {
        return None;
    }
    // Here pos ≤ end < pos + half: the next half window from `end` reaches past pos + half.
    Some((end, (end + half).min(len)))
}

/// The range asked for once `ask` (from [`next_ask`]) is asked after `asked`: one range when
/// it follows on, else the new one alone.
#[must_use]
pub fn asked_after(asked: (u64, u64), ask: (u64, u64)) -> (u64, u64) {
    if ask.0 == asked.1 {
        (asked.0, ask.1)
    } else {
        ask
    }
}

/// Asks the kernel to start reading `len` bytes of `file` from `offset`.
fn will_need(file: &File, offset: u64, len: u64) {
    #[cfg(target_os = "linux")]
    advise(file, offset, len, libc::POSIX_FADV_WILLNEED);
    #[cfg(not(target_os = "linux"))]
    let _ = (file, offset, len);
}

/// `posix_fadvise(file, offset, len, advice)` (`len` 0: to the end of the file). A hint: its
/// result is ignored, and a file system without a page cache ignores it too.
#[cfg(target_os = "linux")]
pub(crate) fn advise(file: &File, offset: u64, len: u64, advice: libc::c_int) {
    use std::os::fd::AsRawFd;
    let (Ok(off), Ok(n)) = (libc::off_t::try_from(offset), libc::off_t::try_from(len)) else {
        return;
    };
    // SAFETY: a valid open descriptor and a byte range; advice changes no file's contents.
    unsafe {
        libc::posix_fadvise(file.as_raw_fd(), off, n, advice);
    }
}

impl Read for ReadAhead {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read(buf)?;
        self.pos += n as u64;
        self.ask();
        Ok(n)
    }
}

impl Seek for ReadAhead {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.pos = self.file.seek(to)?;
        self.ask();
        Ok(self.pos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MB: u64 = 1 << 20;

    /// Walks a front-to-back read of `len` bytes in `step`-byte reads and returns every ask.
    fn asks_of_a_read(len: u64, step: u64) -> Vec<(u64, u64)> {
        let mut asked = (0, 0);
        let mut out = Vec::new();
        let mut pos = 0;
        loop {
            if let Some(ask) = next_ask(pos, asked, len, WINDOW) {
                out.push(ask);
                asked = asked_after(asked, ask);
            }
            // Whatever is read next lies in what was asked, at least half a window on.
            assert!(pos >= len || (asked.0 <= pos && asked.1 >= (pos + WINDOW / 2).min(len)));
            if pos >= len {
                return out;
            }
            pos = (pos + step).min(len);
        }
    }

    #[test]
    fn a_front_to_back_read_asks_each_byte_once_and_ahead_of_the_reads() {
        for (len, step) in [
            (100 * MB, MB),
            (100 * MB + 12_345, 8192),
            (38 * MB, 64 * 1024),
            (5 * MB, MB),
        ] {
            let asks = asks_of_a_read(len, step);
            // The first ask is a whole window (or the file) from the start.
            assert_eq!(asks[0], (0, WINDOW.min(len)), "len {len}");
            // Then contiguous half windows: every byte asked for exactly once, up to the end.
            for pair in asks.windows(2) {
                assert_eq!(pair[1].0, pair[0].1, "len {len}: {asks:?}");
                assert!(
                    pair[1].1 - pair[1].0 <= WINDOW / 2 + step,
                    "len {len}: {asks:?}"
                );
            }
            assert_eq!(asks.last().unwrap().1, len, "len {len}");
        }
    }

    #[test]
    fn a_seek_outside_what_was_asked_starts_a_window_there() {
        // Asked [0, 32 MB): a seek to 80 MB of a 100 MB file asks [80, 100).
        assert_eq!(
            next_ask(80 * MB, (0, 32 * MB), 100 * MB, WINDOW),
            Some((80 * MB, 100 * MB))
        );
        // A seek back before the asked range (a TIFF's header read at its end, then strips).
        assert_eq!(
            next_ask(MB, (90 * MB, 100 * MB), 100 * MB, WINDOW),
            Some((MB, MB + WINDOW))
        );
        // Nothing to ask at or past the end, or while half a window ahead is asked.
        assert_eq!(next_ask(100 * MB, (0, 32 * MB), 100 * MB, WINDOW), None);
        assert_eq!(next_ask(10 * MB, (0, 32 * MB), 100 * MB, WINDOW), None);
        // Just under half a window ahead: the next half window.
        assert_eq!(
            next_ask(17 * MB, (0, 32 * MB), 100 * MB, WINDOW),
            Some((32 * MB, 32 * MB + WINDOW / 2))
        );
    }

    #[test]
    fn reads_and_seeks_return_the_files_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.bin");
        // Three windows of 64 KiB and a bit (so reads cross several asks), bytes from a
        // simple generator.
        const W: u64 = 64 << 10;
        let len = 3 * W as usize + 4097;
        let bytes: Vec<u8> = (0..len)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        std::fs::write(&path, &bytes).unwrap();
        let mut r = ReadAhead::with_window(File::open(&path).unwrap(), W);
        let mut got = Vec::new();
        let mut buf = vec![0u8; 10_007];
        loop {
            let n = r.read(&mut buf).unwrap();
            if n == 0 {
                break;
            }
            got.extend_from_slice(&buf[..n]);
        }
        assert!(got == bytes, "a front-to-back read differs");
        // The reads asked the kernel for the whole file, up to its end.
        assert_eq!(r.asked.1, len as u64);
        for at in [len as u64 - 10, 7, W + 3] {
            assert_eq!(r.seek(SeekFrom::Start(at)).unwrap(), at);
            let mut b = [0u8; 10];
            let n = r.read(&mut b).unwrap();
            assert_eq!(&b[..n], &bytes[at as usize..at as usize + n], "at {at}");
        }
    }
}
