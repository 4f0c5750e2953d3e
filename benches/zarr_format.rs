//! OME-Zarr chunk size and compression, measured (issue 52): write and read time and bytes of
//! one RGBN image as an OME-Zarr store for each compression (zstd, blosc, none) and chunk side
//! (256, 512, 1024), against the same image as rgbn's EXR ZIP, every configuration once per
//! round, the rounds alternated. Prints one line per configuration: medians of the rounds.
//!
//! `cargo bench --bench zarr_format` (environment: `RGBN_ZARR_BENCH_ROUNDS`, default 5;
//! `RGBN_ZARR_BENCH_SIZE=WxH`, default 3840x2160, the demo medallion of the larger side cut
//! to W × H; `RGBN_ZARR_BENCH_DIR`, default a folder in the system temp dir;
//! `RGBN_ZARR_BENCH_LEVELS`: levels written, default 1 (level 0 only, so the format and not
//! the pyramid is compared; 0 = rgbn's default, every level).
//!
//! Write: `save_zarr` / `save_exr_with` of the image in memory into a new path (atomic:
//! written beside and renamed, as the CLI does). Read: `ZarrImage::open` + `read` of level 0
//! whole / `load_exr`. Both from and into the page cache; `sync` before each write round.

/// The allocator the `rgbn` binary runs with (image-sized blocks recycled).
#[global_allocator]
static ALLOC: rgbn::recycle::Recycler = rgbn::recycle::Recycler;

use rgbn::raster::io::zarr::{save_zarr, ZarrCompression, ZarrImage, ZarrOptions};
use rgbn::raster::io::{load_exr, save_exr_with, ExrCompression, ExrPrecision, LoadOptions};
use rgbn::raster::window::{Rect, Window};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Bytes of a file, or of every file under a folder.
fn bytes(p: &Path) -> u64 {
    let m = std::fs::metadata(p).expect("output exists");
    if m.is_file() {
        return m.len();
    }
    std::fs::read_dir(p)
        .expect("store folder")
        .map(|e| bytes(&e.expect("entry").path()))
        .sum()
}

fn remove(p: &Path) {
    if p.is_dir() {
        std::fs::remove_dir_all(p).expect("remove store");
    } else if p.exists() {
        std::fs::remove_file(p).expect("remove file");
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[derive(Clone, Copy)]
enum Config {
    Zarr(ZarrCompression, usize),
    Exr,
}

impl Config {
    fn name(self) -> String {
        match self {
            Config::Zarr(c, k) => format!("zarr {} chunk {k}", c.name()),
            Config::Exr => "exr zip (rgbn)".into(),
        }
    }
    fn path(self, dir: &Path) -> PathBuf {
        match self {
            Config::Zarr(c, k) => dir.join(format!("{}-{k}.zarr", c.name())),
            Config::Exr => dir.join("img.exr"),
        }
    }
}

fn main() {
    // `cargo bench` passes `--bench`; nothing else is read from the arguments.
    let rounds = env_usize("RGBN_ZARR_BENCH_ROUNDS", 5);
    let (w, h) = std::env::var("RGBN_ZARR_BENCH_SIZE")
        .ok()
        .and_then(|s| {
            let (a, b) = s.split_once('x')?;
            Some((a.parse().ok()?, b.parse().ok()?))
        })
        .unwrap_or((3840usize, 2160usize));
    let levels = match env_usize("RGBN_ZARR_BENCH_LEVELS", 1) {
        0 => None,
        n => Some(n),
    };
    let dir = std::env::var_os("RGBN_ZARR_BENCH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join(format!("rgbn-zarr-bench-{}", std::process::id())));
    std::fs::create_dir_all(&dir).expect("bench dir");
    let img = rgbn::raster::sample::demo_window(w.max(h), Window::full(w, h));
    eprintln!(
        "{w}×{h} demo medallion, {rounds} rounds, levels {levels:?}, threads {}, in {}",
        rayon::current_num_threads(),
        dir.display()
    );
    let mut configs = vec![Config::Exr];
    for c in ZarrCompression::ALL {
        for k in [256, 512, 1024] {
            configs.push(Config::Zarr(c, k));
        }
    }
    let n = configs.len();
    let (mut wt, mut rt, mut sz) = (vec![Vec::new(); n], vec![Vec::new(); n], vec![0u64; n]);
    for round in 0..rounds {
        // Alternate the order between rounds so no configuration always follows the same one.
        let order: Vec<usize> = if round % 2 == 0 {
            (0..n).collect()
        } else {
            (0..n).rev().collect()
        };
        for &i in &order {
            let cfg = configs[i];
            let p = cfg.path(&dir);
            remove(&p);
            let _ = std::process::Command::new("sync").status();
            let t = Instant::now();
            match cfg {
                Config::Zarr(c, k) => {
                    let o = ZarrOptions {
                        compression: c,
                        chunk: k,
                        levels,
                        ..ZarrOptions::default()
                    };
                    save_zarr(&img, &p, &o).expect("zarr write");
                }
                Config::Exr => {
                    save_exr_with(&img, &p, ExrPrecision::Full, ExrCompression::Zip)
                        .expect("exr write");
                }
            }
            wt[i].push(t.elapsed().as_secs_f64() * 1e3);
            sz[i] = bytes(&p);
            let t = Instant::now();
            match cfg {
                Config::Zarr(..) => {
                    let z = ZarrImage::open(&p).expect("zarr open");
                    black_box(z.read(0, Rect::full((w, h))).expect("zarr read"));
                }
                Config::Exr => {
                    black_box(load_exr(&p, &LoadOptions::default()).expect("exr read"));
                }
            }
            rt[i].push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let exr = sz[0] as f64;
    println!("| format | write ms (median) | read ms (median) | bytes | bytes / EXR ZIP | writes (ms) | reads (ms) |");
    println!("|---|---|---|---|---|---|---|");
    for i in 0..n {
        let ws: Vec<String> = wt[i].iter().map(|x| format!("{x:.0}")).collect();
        let rs: Vec<String> = rt[i].iter().map(|x| format!("{x:.0}")).collect();
        println!(
            "| {} | {:.0} | {:.0} | {} | {:.3} | {} | {} |",
            configs[i].name(),
            median(&mut wt[i].clone()),
            median(&mut rt[i].clone()),
            sz[i],
            sz[i] as f64 / exr,
            ws.join(" "),
            rs.join(" ")
        );
    }
    for c in &configs {
        remove(&c.path(&dir));
    }
    if std::env::var_os("RGBN_ZARR_BENCH_DIR").is_none() {
        let _ = std::fs::remove_dir(&dir);
    }
}
