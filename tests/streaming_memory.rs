//! Streaming under a memory budget (issue 12, item 5): a 20000 × 12000 normal map (240 Mpx,
//! ten times what fits whole in this test's budget) goes through `rgbn filter` and `rgbn eval`
//! in this process while a counting global allocator records the peak of live heap bytes; the
//! filter's output equals the whole-image filter on crops of the input, and the graph's output
//! (the same Gaussian as a node) equals the filter's, every row.
//!
//! Its own test binary: the counting allocator sees every allocation of the process.

use rgbn::ops::filter::{filter_normals, stream_halo, FilterOptions, Kernel};
use rgbn::raster::io::stream::{PngRows, RowMap};
use rgbn::raster::io::targets::{PngTarget, RowEncoding};
use rgbn::raster::io::NormalConvention;
use rgbn::raster::RgbnImage;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            if new >= l.size() {
                let now = LIVE.fetch_add(new - l.size(), Ordering::Relaxed) + new - l.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(l.size() - new, Ordering::Relaxed);
            }
        }
        q
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

const W: usize = 20_000;
const H: usize = 12_000;
/// The budget: 480 MiB. Reading the image whole would take 240 Mpx × 24 bytes = 5.8 GB for the
/// normals and colour alone. (It was 400 MiB until the fused filter began parking its
/// row-filtered `p`, `q` in two lane-order planes of its own, 8 bytes per pixel of a strip:
/// 447 MiB measured for `filter`, for a 1.9× faster 4K Gaussian; BENCHMARKS.md.)
const BUDGET: usize = 480 << 20;

/// The relief: slopes `p = ½ cos(x/9) cos(y/13) + 0.2 sin((x−y)/4.7)`,
/// `q = −½ sin(x/9) sin(y/13) − 0.2 sin((x−y)/4.7)`, from tables of their factors.
struct Relief {
    cx: Vec<f32>,
    sx: Vec<f32>,
    cy: Vec<f32>,
    sy: Vec<f32>,
    /// `sin((x − y)/4.7)` at `x − y + H`.
    d: Vec<f32>,
}

impl Relief {
    fn new() -> Self {
        let t = |n: usize, f: fn(f32) -> f32, s: f32| (0..n).map(|i| f(i as f32 / s)).collect();
        Self {
            cx: t(W, f32::cos, 9.0),
            sx: t(W, f32::sin, 9.0),
            cy: t(H, f32::cos, 13.0),
            sy: t(H, f32::sin, 13.0),
            d: (0..W + H)
                .map(|i| ((i as f32 - H as f32) / 4.7).sin())
                .collect(),
        }
    }
    /// The unit normal at pixel (x, y).
    fn normal(&self, x: usize, y: usize) -> [f32; 3] {
        let d = 0.2 * self.d[x + H - y];
        let p = 0.5 * self.cx[x] * self.cy[y] + d;
        let q = -0.5 * self.sx[x] * self.sy[y] - d;
        let l = (1.0 + p * p + q * q).sqrt();
        [-p / l, -q / l, 1.0 / l]
    }
}

/// Writes the input, 8-bit, a band of rows at a time.
fn write_input(path: &std::path::Path) {
    let relief = Relief::new();
    let mut t = PngTarget::create(path, W, H, 8).unwrap();
    {
        let mut rows = t
            .rows(RowEncoding::Normal(NormalConvention::OpenGl))
            .unwrap();
        let band = 256;
        let mut planes = [
            vec![0.0; W * band],
            vec![0.0; W * band],
            vec![0.0; W * band],
        ];
        for y0 in (0..H).step_by(band) {
            let n = band.min(H - y0);
            for r in 0..n {
                for x in 0..W {
                    let v = relief.normal(x, y0 + r);
                    for k in 0..3 {
                        planes[k][r * W + x] = v[k];
                    }
                }
            }
            let [a, b, c] = &planes;
            rows.write([&a[..n * W], &b[..n * W], &c[..n * W]]).unwrap();
        }
        rows.finish().unwrap();
    }
    t.commit().unwrap();
}

/// A PNG normal map read from the top, a range of rows at a time.
struct Rows(PngRows, usize);

impl Rows {
    fn open(path: &std::path::Path) -> Self {
        let r = PngRows::open(path).unwrap().unwrap();
        assert_eq!(r.size(), (W, H));
        Self(r, 0)
    }
    /// Rows `y0..y1` (`y0` at or after the rows read so far).
    fn rows(&mut self, y0: usize, y1: usize) -> [Vec<f32>; 3] {
        let map = RowMap::Normal(NormalConvention::OpenGl);
        let mut skip = [vec![0.0; W], vec![0.0; W], vec![0.0; W]];
        for _ in self.1..y0 {
            let [a, b, c] = &mut skip;
            self.0.read(&mut [a, b, c], map).unwrap();
        }
        let n = (y1 - y0) * W;
        let mut out = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let [a, b, c] = &mut out;
        self.0.read(&mut [a, b, c], map).unwrap();
        self.1 = y1;
        out
    }
}

/// Runs the CLI in this process; returns the peak of live heap bytes above the start.
fn peak_of(args: &[&str]) -> usize {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let mut all = vec!["rgbn"];
    all.extend_from_slice(args);
    let code = rgbn::cli::run(all);
    assert_eq!(code, rgbn::cli::error::Exit::Ok, "{args:?}");
    PEAK.load(Ordering::Relaxed) - base
}

fn mib(b: usize) -> f64 {
    b as f64 / 1048576.0
}

/// The Gaussian of the filter command as a graph node.
const GRAPH: &str = r#"(
    version: 1,
    next_id: 2,
    inputs: { "image": (ty: Rgbn, doc: "The input.") },
    outputs: { "image": (node: 1, port: "image") },
    nodes: [
        (
            id: 1,
            op: "filter.gaussian",
            pos: (0.0, 0.0),
            params: { "sigma_px": Float(1.5) },
            inputs: { "image": Input("image") },
        ),
    ],
)"#;

#[test]
fn a_240_megapixel_image_streams_through_filter_and_eval_within_a_400_mib_budget() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("big.png");
    let output = d.path().join("out.png");
    let t0 = std::time::Instant::now();
    write_input(&input);
    eprintln!("input written in {:?}", t0.elapsed());

    let kernel = "gauss:1.5";
    let t0 = std::time::Instant::now();
    let peak = peak_of(&[
        "filter",
        input.to_str().unwrap(),
        "-k",
        kernel,
        "-o",
        output.to_str().unwrap(),
    ]);
    eprintln!(
        "filter {W}×{H} in {:?}: peak heap {:.0} MiB (budget {} MiB)",
        t0.elapsed(),
        mib(peak),
        BUDGET >> 20
    );
    assert!(
        peak <= BUDGET,
        "filter: peak heap {:.0} MiB over the budget",
        mib(peak)
    );

    let graph = d.path().join("gauss.ron");
    std::fs::write(&graph, GRAPH).unwrap();
    let evaluated = d.path().join("eval.png");
    let t0 = std::time::Instant::now();
    let peak = peak_of(&[
        "eval",
        graph.to_str().unwrap(),
        "-i",
        &format!("image={}", input.display()),
        "-o",
        &format!("image={}", evaluated.display()),
    ]);
    eprintln!(
        "eval {W}×{H} in {:?}: peak heap {:.0} MiB (budget {} MiB)",
        t0.elapsed(),
        mib(peak),
        BUDGET >> 20
    );
    assert!(
        peak <= BUDGET,
        "eval: peak heap {:.0} MiB over the budget",
        mib(peak)
    );
    let (mut a, mut b) = (Rows::open(&output), Rows::open(&evaluated));
    for y in (0..H).step_by(500) {
        let y1 = (y + 500).min(H);
        assert!(
            a.rows(y, y1) == b.rows(y, y1),
            "eval and filter differ in rows {y}..{y1}"
        );
    }

    // Crops of full rows: at the top edge, in the middle (across a strip boundary, wherever it
    // falls), at the bottom edge. The whole-image filter runs on the crop grown by the halo.
    let kernels = [Kernel::parse(kernel).unwrap()];
    let opts = FilterOptions::default();
    let halo = stream_halo(&kernels, &opts).unwrap();
    let (mut inp, mut outp) = (Rows::open(&input), Rows::open(&output));
    for (y0, y1) in [(0, 40), (6000 - 300, 6000 + 300), (H - 40, H)] {
        let (a, b) = (y0.saturating_sub(halo), (y1 + halo).min(H));
        let n = inp.rows(a, b);
        let albedo = || vec![0.75; (b - a) * W];
        let mut crop = RgbnImage::new(W, b - a, [albedo(), albedo(), albedo()], n, None).unwrap();
        // As the loader does for 8-bit normals (not unit length once decoded).
        crop.repair();
        let (want, _) = filter_normals(&crop, &kernels, &opts).unwrap();
        let got = outp.rows(y0, y1);
        // Compare as written: both through the same 16-bit encoding.
        let enc = |v: f32| ((v.clamp(-1.0, 1.0) + 1.0) * 0.5 * 65535.0 + 0.5).min(65535.0) as u16;
        let dec = |v: u16| f32::from(v) * (2.0 / 65535.0) - 1.0;
        let off = (y0 - a) * W;
        for (k, (got, want)) in got.iter().zip(want.normal()).enumerate() {
            for (i, g) in got.iter().enumerate() {
                let w = dec(enc(want[off + i]));
                assert_eq!(*g, w, "rows {y0}..{y1}, plane {k}, pixel {i}");
            }
        }
    }
}
