//! EXR writing by blocks: the planes of an image, or its rows as they come, are cut into the
//! scan-line blocks of the chosen compression (1 line for none, RLE and ZIPS; 16 for ZIP; 32
//! for PIZ), each block laid out as the format wants it (per line, the channels in name order),
//! compressed on every core, and written in order. Whole planes are never copied: a block's
//! bytes are built from the planes and dropped once it is written.

use super::openexr::{ExrCompression, ExrPrecision};
use exr::block::writer::ChunksWriter;
use exr::block::{BlockIndex, UncompressedBlock};
use exr::math::Vec2;
use exr::meta::attribute::{ChannelDescription, LineOrder, SampleType};
use exr::meta::header::Header;
use rayon::prelude::*;
use std::io::{Seek, Write};

/// How an EXR is stored: sample type and compression.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ExrFormat {
    /// 16- or 32-bit floats.
    pub precision: ExrPrecision,
    /// Compression.
    pub compression: ExrCompression,
}

/// Blocks compressed at once: enough to keep every core busy, few enough to bound memory (a
/// 16-line block of a 4K RGBN image is 1.7 MB).
const BATCH: usize = 32;

/// The single-layer scan-line header of a `width × height` image with channels `names`
/// (sorted by name, as the format requires).
fn header(width: usize, height: usize, names: &[&str], f: ExrFormat) -> Header {
    let ty = match f.precision {
        ExrPrecision::Half => SampleType::F16,
        ExrPrecision::Full => SampleType::F32,
    };
    let channels = names
        .iter()
        .map(|n| ChannelDescription::named(*n, ty))
        .collect();
    Header::new("rgbn".into(), (width, height), channels).with_encoding(
        f.compression.to_exr(),
        exr::meta::BlockDescription::ScanLines,
        LineOrder::Increasing,
    )
}

/// The rows of a block of rows `rows` of `planes` (each `width` values a row) in the order
/// the format lays them out: per image row, each channel's row.
fn block_rows<'a>(
    planes: &'a [&'a [f32]],
    width: usize,
    rows: std::ops::Range<usize>,
) -> impl Iterator<Item = &'a [f32]> + 'a {
    rows.flat_map(move |r| planes.iter().map(move |p| &p[r * width..(r + 1) * width]))
}

/// The uncompressed bytes of rows `rows` of `planes` ([`block_rows`]' order), each sample in
/// native byte order.
fn block_bytes(
    planes: &[&[f32]],
    width: usize,
    rows: std::ops::Range<usize>,
    half: bool,
) -> Vec<u8> {
    let size = if half { 2 } else { 4 };
    let mut out = Vec::with_capacity(rows.len() * planes.len() * width * size);
    for row in block_rows(planes, width, rows) {
        if half {
            for v in row {
                out.extend_from_slice(&half::f16::from_f32(*v).to_ne_bytes());
            }
        } else {
            for v in row {
                out.extend_from_slice(&v.to_ne_bytes());
            }
        }
    }
    out
}

/// The zlib level of the compressed runs of ZIP blocks (level 1 is zlib's fixed-code fast path,
/// which grows incompressible bytes; 2 is about as fast here and smaller: BENCHMARKS.md, "EXR
/// compression").
const ZIP_LEVEL: u32 = 2;

/// Bits of order-0 entropy per byte above which a segment is stored rather than compressed:
/// the low bytes of float mantissas (7.9–8 bits) are stored, constant and smooth planes, and
/// the high bytes, compressed.
const NOISE_BITS: f64 = 7.5;

/// A ZIP or ZIPS block of rows `rows` of `planes` prepared as OpenEXR does it — the block's
/// bytes ([`block_bytes`]) split into even and odd halves, each byte replaced by its difference
/// to the previous one plus 128 ([`predicted_block`] builds that straight from the planes) —
/// then deflated segment by segment ([`deflate_segments`]: noise stored, the rest compressed
/// with zlib-rs), where the exr crate's own deflate compresses everything at level 4, several
/// times slower for about the same size on float data. `None` for the other compressions. A
/// block that does not shrink is stored as it is, as the format allows.
fn zip_chunk(
    headers: &[Header],
    planes: &[&[f32]],
    width: usize,
    rows: std::ops::Range<usize>,
    y: usize,
) -> Option<exr::block::chunk::Chunk> {
    use exr::compression::Compression as C;
    // The format's bytes are little-endian and the stored fallback below is built in native
    // order: on a big-endian machine the exr crate, which swaps them, compresses the block.
    if !matches!(headers[0].compression, C::ZIP1 | C::ZIP16) || cfg!(target_endian = "big") {
        return None;
    }
    let half = headers[0].channels.list[0].sample_type == SampleType::F16;
    let t = predicted_block(planes, width, rows.clone(), half);
    let seg = (width * if half { 2 } else { 4 } / 2).max(1);
    let packed = deflate_segments(&t, seg)?;
    let compressed_pixels_le = if packed.len() < t.len() {
        packed
    } else {
        block_bytes(planes, width, rows, half)
    };
    Some(exr::block::chunk::Chunk {
        layer_index: 0,
        compressed_block: exr::block::chunk::CompressedBlock::ScanLine(
            exr::block::chunk::CompressedScanLineBlock {
                y_coordinate: i32::try_from(y).ok()?,
                compressed_pixels_le,
            },
        ),
    })
}

/// `predict(&block_bytes(planes, width, rows, half))` (little-endian samples) without building
/// the block first: each sample's bytes go straight to their halves (a 32-bit sample's bytes
/// 0 and 2 to the even half, 1 and 3 to the odd; a 16-bit one's byte 0 and byte 1), then the
/// differences are taken in one pass over neighbouring bytes. Two passes over a block that
/// stays in cache, where building the block and predicting it byte pair by byte pair was half
/// of the EXR writer's time (`perf`, BENCHMARKS.md).
fn predicted_block(
    planes: &[&[f32]],
    width: usize,
    rows: std::ops::Range<usize>,
    half: bool,
) -> Vec<u8> {
    let size = if half { 2 } else { 4 };
    let n = rows.len() * planes.len() * width * size;
    if n == 0 {
        return Vec::new();
    }
    // Every sample has an even number of bytes: the halves are equal.
    let h = n / 2;
    let mut split = vec![0u8; n];
    let (even, odd) = split.split_at_mut(h);
    let step = width * size / 2;
    let halves = even.chunks_exact_mut(step).zip(odd.chunks_exact_mut(step));
    for (row, (e, o)) in block_rows(planes, width, rows).zip(halves) {
        if half {
            for ((v, e), o) in row.iter().zip(e.iter_mut()).zip(o.iter_mut()) {
                let [b0, b1] = half::f16::from_f32(*v).to_le_bytes();
                (*e, *o) = (b0, b1);
            }
        } else {
            let (e, _) = e.as_chunks_mut::<2>();
            let (o, _) = o.as_chunks_mut::<2>();
            for ((v, e), o) in row.iter().zip(e.iter_mut()).zip(o.iter_mut()) {
                let [b0, b1, b2, b3] = v.to_le_bytes();
                (*e, *o) = ([b0, b2], [b1, b3]);
            }
        }
    }
    let mut t = vec![0u8; n];
    t[0] = split[0];
    for ((d, c), p) in t[1..].iter_mut().zip(&split[1..]).zip(&split[..n - 1]) {
        *d = c.wrapping_sub(*p).wrapping_add(128);
    }
    t
}

/// OpenEXR's ZIP predictor: the bytes split into even and odd halves, then each byte but the
/// first replaced by its difference to the one before it (in that order) plus 128. Computed in
/// one pass from pairs of bytes and the pair before them (no step waits on the previous one).
/// The writer uses [`predicted_block`]; this is its reference in the tests.
#[cfg(test)]
fn predict(data: &[u8]) -> Vec<u8> {
    let n = data.len();
    if n < 2 {
        return data.to_vec();
    }
    let half = n.div_ceil(2);
    let d = |cur: u8, prev: u8| cur.wrapping_sub(prev).wrapping_add(128);
    let mut t = vec![0u8; n];
    let (even, odd) = t.split_at_mut(half);
    let (pairs, last) = data.as_chunks::<2>();
    for ((e, o), (c, p)) in even[1..]
        .iter_mut()
        .zip(odd[1..].iter_mut())
        .zip(pairs[1..].iter().zip(pairs))
    {
        (*e, *o) = (d(c[0], p[0]), d(c[1], p[1]));
    }
    even[0] = data[0];
    if let [x] = last {
        // An odd length: the even half ends with the last byte.
        even[half - 1] = d(*x, data[n - 3]);
    }
    // The first odd byte follows the last even one.
    odd[0] = d(data[1], data[2 * (half - 1)]);
    t
}

/// The order-0 entropy of `b` in bits per byte.
fn entropy(b: &[u8]) -> f64 {
    // Four histograms, bytes dealt round-robin: consecutive equal bytes (smooth data) do not
    // wait on each other's increments.
    let mut h = [[0u32; 256]; 4];
    let mut quads = b.chunks_exact(4);
    for q in &mut quads {
        h[0][q[0] as usize] += 1;
        h[1][q[1] as usize] += 1;
        h[2][q[2] as usize] += 1;
        h[3][q[3] as usize] += 1;
    }
    for v in quads.remainder() {
        h[0][*v as usize] += 1;
    }
    let n = b.len() as f64;
    (0..256)
        .map(|k| h[0][k] + h[1][k] + h[2][k] + h[3][k])
        .filter(|c| *c > 0)
        .map(|c| {
            let p = f64::from(c) / n;
            -p * p.log2()
        })
        .sum()
}

/// Adler-32 of `b` (the zlib trailer).
fn adler32(b: &[u8]) -> u32 {
    let mut a = simd_adler32::Adler32::new();
    a.write(b);
    a.finish()
}

/// `t` as one zlib stream, `seg` bytes at a time: a run of segments that look like noise
/// (order-0 entropy over [`NOISE_BITS`]: the low bytes of float mantissas) is written as stored
/// deflate blocks, a run of the others is compressed at [`ZIP_LEVEL`] by a compressor without
/// history (what comes before it may be stored, which a compressor's window would not know)
/// and sync-flushed, so every run ends on a byte and the blocks simply follow one another.
fn deflate_segments(t: &[u8], seg: usize) -> Option<Vec<u8>> {
    use flate2::{Compress, Compression, FlushCompress};
    let (level, limit) = (ZIP_LEVEL, NOISE_BITS);
    // zlib header: deflate with a 32 KiB window, no dictionary, (CMF·256 + FLG) % 31 == 0.
    let mut out = Vec::with_capacity(t.len() + t.len() / 64 + 64);
    out.extend_from_slice(&[0x78, 0x01]);
    let mut c = Compress::new(Compression::new(level), false);
    // A segment that repeats with period two after its first byte (a constant plane's row,
    // predicted: its samples' two bytes in this half alternate) holds at most three byte
    // values, at most log2 3 bits of entropy: compressed, without counting its bytes.
    let flat = |p: &[u8]| p.len() < 4 || p[3..] == p[1..p.len() - 2];
    let noisy: Vec<bool> = t
        .chunks(seg)
        .map(|p| !flat(p) && entropy(p) > limit)
        .collect();
    let mut k = 0;
    while k < noisy.len() {
        let mut end = k + 1;
        while end < noisy.len() && noisy[end] == noisy[k] {
            end += 1;
        }
        let run = &t[k * seg..(end * seg).min(t.len())];
        if noisy[k] {
            // Stored blocks of at most 65535 bytes: header byte (not final, type 00), LEN, NLEN.
            for b in run.chunks(65_535) {
                let len = u16::try_from(b.len()).ok()?;
                out.push(0);
                out.extend_from_slice(&len.to_le_bytes());
                out.extend_from_slice(&(!len).to_le_bytes());
                out.extend_from_slice(b);
            }
        } else {
            c.reset();
            let mut done = 0;
            loop {
                out.reserve(run.len() - done + 1024);
                let before = c.total_in();
                let status = c
                    .compress_vec(&run[done..], &mut out, FlushCompress::Sync)
                    .ok()?;
                done += usize::try_from(c.total_in() - before).ok()?;
                if done == run.len() && out.capacity() > out.len() && status == flate2::Status::Ok {
                    // A sync flush that had room finished: the output ends on a byte.
                    break;
                }
            }
        }
        k = end;
    }
    // The final block (empty, stored), then the Adler-32 of the data, big-endian.
    out.extend_from_slice(&[1, 0, 0, 0xff, 0xff]);
    out.extend_from_slice(&adler32(t).to_be_bytes());
    Some(out)
}

/// A compressed block and its index in the file's offset table.
type Compressed = exr::error::Result<(usize, exr::block::chunk::Chunk)>;

/// Compresses and writes the blocks covering rows `0..rows` of `planes` (local rows; image row
/// `first_row + r`), `first_row` a multiple of the block height. Returns the rows written: all
/// of them when `last` (the image's final rows), else only whole blocks.
///
/// Blocks are compressed [`BATCH`] at a time on the rayon pool while the calling thread writes
/// the batch before (a pipeline of two): the write — a copy into the page cache, a tenth of
/// a second per 100 MB on this machine — no longer leaves the pool idle between batches. The
/// calling thread's cancellation token ([`crate::cancel::Cancel::current`]) stops it between
/// batches with `Error::Aborted`.
fn write_rows<W: ChunksWriter>(
    writer: &mut W,
    headers: &[Header],
    planes: &[&[f32]],
    (width, height): (usize, usize),
    first_row: usize,
    rows: usize,
    last: bool,
) -> exr::error::Result<usize> {
    let lines = headers[0].compression.scan_lines_per_block();
    let half = headers[0].channels.list[0].sample_type == SampleType::F16;
    let whole = if last { rows } else { rows / lines * lines };
    let blocks = whole.div_ceil(lines);
    let compress = |b: usize| -> Vec<Compressed> {
        (b..(b + BATCH).min(blocks))
            .into_par_iter()
            .map(|k| {
                let (r0, r1) = (k * lines, ((k + 1) * lines).min(whole));
                let y = first_row + r0;
                if let Some(zipped) = zip_chunk(headers, planes, width, r0..r1, y) {
                    return Ok((y / lines, zipped));
                }
                let data = block_bytes(planes, width, r0..r1, half);
                let block = UncompressedBlock {
                    index: BlockIndex {
                        layer: 0,
                        pixel_position: Vec2(0, y),
                        pixel_size: Vec2(width, r1 - r0),
                        level: Vec2(0, 0),
                    },
                    data,
                };
                Ok((y / lines, block.compress_to_chunk(headers)?))
            })
            .collect()
    };
    // Cancelled (the command line's Ctrl-C enters its token around writes): the write stops
    // between batches and its temporary file is removed; nothing is renamed into place.
    let cancel = crate::cancel::Cancel::current();
    let mut batch = if blocks > 0 { compress(0) } else { Vec::new() };
    let mut b = 0;
    while !batch.is_empty() {
        if cancel.is_cancelled() {
            return Err(exr::error::Error::Aborted);
        }
        let next_b = b + BATCH;
        let mut next = Vec::new();
        // The next batch is compressed on the pool while this thread writes the current one
        // (`in_place_scope` runs this closure here, not on a pool thread).
        let mut write = |batch: &mut Vec<Compressed>| {
            batch
                .drain(..)
                .try_for_each(|c| c.and_then(|(index, chunk)| writer.write_chunk(index, chunk)))
        };
        if crate::raster::par::pipelined() {
            let written = rayon::in_place_scope(|s| {
                if next_b < blocks {
                    s.spawn(|_| next = compress(next_b));
                }
                write(&mut batch)
            });
            written?;
        } else {
            // One thread: write, then compress the next batch.
            write(&mut batch)?;
            if next_b < blocks {
                next = compress(next_b);
            }
        }
        batch = next;
        b = next_b;
    }
    debug_assert!(first_row + whole <= height);
    Ok(whole)
}

/// Writes a `width × height` image given as named planes (any order) to `out`.
///
/// # Errors
/// The exr crate's errors, as text.
pub(crate) fn write_planes<W: Write + Seek>(
    out: W,
    (width, height): (usize, usize),
    channels: &[(&str, &[f32])],
    f: ExrFormat,
) -> Result<(), String> {
    let mut sorted: Vec<(&str, &[f32])> = channels.to_vec();
    sorted.sort_by(|a, b| a.0.cmp(b.0));
    let names: Vec<&str> = sorted.iter().map(|c| c.0).collect();
    let planes: Vec<&[f32]> = sorted.iter().map(|c| c.1).collect();
    let headers: exr::meta::Headers = std::iter::once(header(width, height, &names, f)).collect();
    exr::block::write(out, headers, true, |meta, writer| {
        write_rows(
            writer,
            &meta.headers,
            &planes,
            (width, height),
            0,
            height,
            true,
        )
        .map(|_| ())
    })
    .map_err(|e| e.to_string())
}

/// Rows arriving band by band (the streaming writer): every whole block is compressed and
/// written as soon as its rows are in; the rows of a block begun (fewer than a block) wait in
/// a carry buffer for the next band.
pub(crate) struct RowBlocks {
    width: usize,
    height: usize,
    names: Vec<&'static str>,
    carry: Vec<Vec<f32>>,
    carry_rows: usize,
    written: usize,
}

impl RowBlocks {
    /// A writer of the channels `names` (sorted), `width × height`.
    pub(crate) fn new(width: usize, height: usize, names: Vec<&'static str>) -> Self {
        let carry = vec![Vec::new(); names.len()];
        Self {
            width,
            height,
            names,
            carry,
            carry_rows: 0,
            written: 0,
        }
    }

    /// The header of the file.
    pub(crate) fn header(&self, f: ExrFormat) -> Header {
        header(self.width, self.height, &self.names, f)
    }

    /// Appends a band of `rows` rows (planes in `names` order) and writes the whole blocks:
    /// the block begun by the carried rows completed from the band's first rows, then the
    /// band's whole blocks compressed straight from its planes; only the rows after the last
    /// whole block (fewer than a block) are copied, to wait for the next band. (Copying every
    /// band into the carry first cost a copy of the image and, while the bands ramp up, fresh
    /// pages faulted in on the writer's thread with the pipeline waiting on it.)
    pub(crate) fn push<W: ChunksWriter>(
        &mut self,
        writer: &mut W,
        headers: &[Header],
        planes: &[&[f32]],
        rows: usize,
    ) -> exr::error::Result<()> {
        let (w, h) = (self.width, self.height);
        let lines = headers[0].compression.scan_lines_per_block();
        let mut from = 0;
        if self.carry_rows > 0 {
            let take = (lines - self.carry_rows).min(rows);
            for (c, p) in self.carry.iter_mut().zip(planes) {
                c.extend_from_slice(&p[..take * w]);
            }
            self.carry_rows += take;
            from = take;
            let last = self.written + self.carry_rows >= h;
            if self.carry_rows < lines && !last {
                // The band went into the carried block, which is still short.
                return Ok(());
            }
            let views: Vec<&[f32]> = self.carry.iter().map(Vec::as_slice).collect();
            let done = write_rows(
                writer,
                headers,
                &views,
                (w, h),
                self.written,
                self.carry_rows,
                last,
            )?;
            debug_assert_eq!(done, self.carry_rows);
            self.written += done;
            self.carry_rows = 0;
            self.carry.iter_mut().for_each(Vec::clear);
        }
        let left = rows - from;
        if left == 0 {
            return Ok(());
        }
        let last = self.written + left >= h;
        let views: Vec<&[f32]> = planes.iter().map(|p| &p[from * w..rows * w]).collect();
        let done = write_rows(writer, headers, &views, (w, h), self.written, left, last)?;
        self.written += done;
        for (c, p) in self.carry.iter_mut().zip(planes) {
            c.extend_from_slice(&p[(from + done) * w..rows * w]);
        }
        self.carry_rows = left - done;
        Ok(())
    }

    /// Rows written so far.
    pub(crate) fn written(&self) -> usize {
        self.written
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes of pseudo-random noise.
    fn noise(n: usize, mut s: u64) -> Vec<u8> {
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 32) as u8
            })
            .collect()
    }

    /// The predictor equals OpenEXR's definition (`ImfZip.cpp`: reorder even bytes first, then
    /// `t[i] = t[i] − t[i−1] + 128` from the first to the last), for even and odd lengths.
    #[test]
    fn the_predictor_is_openexrs() {
        for n in [0, 1, 2, 7, 64, 1001, 4096] {
            let data = noise(n, 3 + n as u64);
            let mut want = Vec::with_capacity(n);
            want.extend(data.iter().step_by(2));
            want.extend(data.iter().skip(1).step_by(2));
            let mut prev = want.first().copied().unwrap_or(0);
            for v in want.iter_mut().skip(1) {
                let cur = *v;
                *v = cur.wrapping_sub(prev).wrapping_add(128);
                prev = cur;
            }
            assert_eq!(predict(&data), want, "{n} bytes");
        }
    }

    /// The predictor applied straight to the planes gives the predictor of the block's bytes,
    /// for 32- and 16-bit samples, one and several rows and channels, odd widths.
    #[test]
    #[cfg(target_endian = "little")]
    fn the_block_is_predicted_from_the_planes_as_from_its_bytes() {
        let bytes = noise(4 * 3 * 37 * 5, 11);
        let planes: Vec<Vec<f32>> = bytes
            .chunks(4 * 37 * 5)
            .map(|c| {
                c.chunks(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3] & 0x3f]))
                    .collect()
            })
            .collect();
        let views: Vec<&[f32]> = planes.iter().map(Vec::as_slice).collect();
        for half in [false, true] {
            for (width, rows) in [(37, 0..5), (37, 2..3), (1, 0..1), (5, 4..9)] {
                for k in [1, 3] {
                    let want = predict(&block_bytes(&views[..k], width, rows.clone(), half));
                    let got = predicted_block(&views[..k], width, rows.clone(), half);
                    assert_eq!(
                        got, want,
                        "half {half}, width {width}, rows {rows:?}, {k} planes"
                    );
                }
            }
        }
    }

    #[test]
    fn mixed_segments_make_one_zlib_stream_that_inflates_to_the_data() {
        // Runs of noise (stored) between runs of smooth data (compressed), with a short last
        // segment: the stream must decode, by another implementation, to exactly the input.
        let seg = 4000;
        let mut t = Vec::new();
        for k in 0..9 {
            if k % 3 == 1 {
                t.extend(noise(seg, 7 + k));
            } else {
                t.extend((0..seg).map(|i| (i / 40 % 7) as u8));
            }
        }
        t.extend(noise(123, 99));
        let z = deflate_segments(&t, seg).expect("compressed");
        let mut back = Vec::new();
        std::io::Read::read_to_end(&mut flate2::read::ZlibDecoder::new(&z[..]), &mut back)
            .expect("a valid zlib stream");
        assert_eq!(back, t);
        // The smooth runs shrank to a small part of their size; the noise was kept.
        let noisy = 3 * seg + 123;
        assert!(z.len() > noisy, "{} bytes", z.len());
        assert!(
            z.len() < noisy + (t.len() - noisy) / 10,
            "{} bytes",
            z.len()
        );
        // A flat segment (one odd first byte, then two values in turn, as a constant plane
        // gives) is compressed like any smooth one: its entropy is under log2 3 bits.
        let mut f: Vec<u8> = (0..seg)
            .map(|i| if i % 2 == 0 { 17 } else { 145 })
            .collect();
        f[0] = 200;
        assert!(entropy(&f) < 1.6);
        let z = deflate_segments(&f, seg).expect("compressed");
        assert!(z.len() < seg / 20, "{} bytes", z.len());
        // An order-0 entropy estimate: one symbol 0 bits, uniform bytes 8.
        assert_eq!(entropy(&[5; 100]), 0.0);
        let all: Vec<u8> = (0..=255).collect();
        assert!((entropy(&all) - 8.0).abs() < 1e-12);
        // Adler-32 of "Wikipedia" (the textbook example).
        assert_eq!(adler32(b"Wikipedia"), 0x11E6_0398);
    }

    /// Bands of every awkward size (one row, a block minus one, a block and one, past several
    /// blocks, ending mid-block) make the same file, byte for byte, as the whole image written
    /// at once, for each block height (1, 16, 32 lines) and precision.
    #[test]
    fn rows_pushed_in_bands_write_the_bytes_of_the_whole_image() {
        use crate::raster::io::openexr::{ExrCompression, ExrPrecision};
        let (w, h) = (19, 101);
        let names = vec!["A", "N.X", "R"];
        let planes: Vec<Vec<f32>> = (0..names.len())
            .map(|c| {
                noise(4 * w * h, 5 + c as u64)
                    .chunks(4)
                    .map(|b| f32::from(b[0]) / 255.0 + f32::from(b[1]) / 65536.0)
                    .collect()
            })
            .collect();
        for compression in [
            ExrCompression::None,
            ExrCompression::Zips,
            ExrCompression::Zip,
            ExrCompression::Piz,
        ] {
            for precision in [ExrPrecision::Full, ExrPrecision::Half] {
                let f = ExrFormat {
                    precision,
                    compression,
                };
                let mut whole = std::io::Cursor::new(Vec::new());
                let named: Vec<(&str, &[f32])> = names
                    .iter()
                    .zip(&planes)
                    .map(|(n, p)| (*n, p.as_slice()))
                    .collect();
                write_planes(&mut whole, (w, h), &named, f).unwrap();
                for bands in [
                    vec![1, 15, 17, 16, 33, 19],
                    vec![40, 40, 21],
                    vec![101],
                    vec![3; 33].into_iter().chain([2]).collect::<Vec<_>>(),
                ] {
                    assert_eq!(bands.iter().sum::<usize>(), h);
                    let mut rows = RowBlocks::new(w, h, names.clone());
                    let mut out = std::io::Cursor::new(Vec::new());
                    let headers: exr::meta::Headers = std::iter::once(rows.header(f)).collect();
                    exr::block::write(&mut out, headers, true, |meta, writer| {
                        let mut y = 0;
                        for &n in &bands {
                            let band: Vec<&[f32]> =
                                planes.iter().map(|p| &p[y * w..(y + n) * w]).collect();
                            rows.push(writer, &meta.headers, &band, n)?;
                            y += n;
                        }
                        Ok(())
                    })
                    .unwrap();
                    assert_eq!(rows.written(), h);
                    assert!(
                        out.get_ref() == whole.get_ref(),
                        "{compression:?} {precision:?} bands {bands:?}"
                    );
                }
            }
        }
    }
}
