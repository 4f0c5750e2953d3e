//! Ad-hoc timing probe for the hot kernels at 4K (min of N runs). Build the same probe at two
//! commits and alternate the binaries for same-moment before/after comparisons.
//! `cargo run --release --no-default-features --example perf_probe [filter|relight|curl|png|exr]`
use rgbn::ops::filter::{filter_normals, filter_normals_general, FilterOptions, Kernel};
use rgbn::raster::gradient::GradientField;
use rgbn::raster::io::{self, NormalConvention};
use rgbn::raster::sample::Surface;
use rgbn::render::{self, Shading};
use std::time::Instant;

/// CPU seconds (user + system) used by this process so far, from `/proc/self/stat`
/// (clock ticks of 10 ms; summed over many runs this is the load-robust measure).
fn cpu_s() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .map_or("", |(_, r)| r)
        .split_whitespace()
        .collect();
    let ticks = |i: usize| {
        fields
            .get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0 // utime, stime (fields 14, 15 of the man page)
}

/// Min wall time of `n` runs (ms); prints the mean CPU time per run beside it.
fn min_ms(n: usize, mut f: impl FnMut()) -> f64 {
    let c0 = cpu_s();
    let wall = (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min);
    print!("[cpu {:.1} ms/run] ", (cpu_s() - c0) * 1e3 / n as f64);
    wall
}

fn main() {
    let what = std::env::args().nth(1).unwrap_or_else(|| "filter".into());
    let n: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(7);
    let (w, h) = (3840, 2160);
    if what == "exr" {
        use rgbn::raster::io::{ExrCompression as C, ExrPrecision};
        let (img, _) = Surface::gaussians_for(h).render(w, h);
        let dir = std::env::temp_dir().join("rgbn_perf_probe.exr");
        for c in [C::None, C::Rle, C::Zip16, C::Piz] {
            let t = min_ms(2, || {
                io::save_exr_with(&img, &dir, ExrPrecision::Full, c).unwrap()
            });
            let size = std::fs::metadata(&dir).unwrap().len() as f64 / 1e6;
            let r = min_ms(2, || drop(io::load_exr(&dir, &Default::default()).unwrap()));
            println!("{c:?}: write {t:.0} ms, read {r:.0} ms, {size:.0} MB");
        }
        let _ = std::fs::remove_file(dir);
        return;
    }
    let (mut img, _) = Surface::gaussians_for(h).render(w, h);
    let (fine, _) = Surface::Sinusoid {
        amplitude_px: 1.5,
        period_px: 23.0,
    }
    .render(w, h);
    let mut g = GradientField::from_normals(&img);
    let gf = GradientField::from_normals(&fine);
    g.p.iter_mut().zip(&gf.p).for_each(|(a, b)| *a += b);
    g.q.iter_mut().zip(&gf.q).for_each(|(a, b)| *a += b);
    g.write_normals(&mut img);
    let opts = FilterOptions::default();
    match what.as_str() {
        "filter" => {
            for sigma in [8.0f32, 32.0] {
                let k = [Kernel::Gaussian { sigma_px: sigma }];
                let t = min_ms(n, || drop(filter_normals(&img, &k, &opts).unwrap()));
                println!("filter_normals (fused) gauss{sigma}: {t:.1} ms");
                let t = min_ms(n, || drop(filter_normals_general(&img, &k, &opts).unwrap()));
                println!("filter_normals_general (unfused) gauss{sigma}: {t:.1} ms");
            }
        }
        "fused" => {
            let k = [Kernel::Gaussian { sigma_px: 8.0 }];
            let t = min_ms(n, || drop(filter_normals(&img, &k, &opts).unwrap()));
            println!("filter_normals (fused) gauss8: {t:.1} ms");
        }
        "relight_demo" => {
            let demo = rgbn::raster::sample::demo_medallion(2048);
            let s = Shading::default();
            println!("demo 2048²: mask {}", demo.mask().is_some());
            let t = min_ms(n, || drop(render::relight(&demo, &s).unwrap()));
            println!("relight demo 2048²: {t:.1} ms");
        }
        "relight" => {
            let s = Shading::default();
            let t = min_ms(n, || drop(render::relight(&img, &s).unwrap()));
            println!("relight: {t:.1} ms");
            let mut out = vec![0u8; img.len() * 4];
            let t = min_ms(n, || render::relight_into(&img, &s, &mut out).unwrap());
            println!("relight_into (buffer reused): {t:.1} ms");
        }
        "curl" => {
            let t = min_ms(n, || drop(g.curl()));
            let s = min_ms(n, || {
                std::hint::black_box(g.curl_stats(None));
            });
            println!("curl map: {t:.2} ms, curl stats: {s:.2} ms");
        }
        "png" => {
            let p = std::env::temp_dir().join("rgbn_perf_probe.png");
            let t = min_ms(n.min(3), || {
                io::save_normal_map(&img, &p, 16, NormalConvention::OpenGl).unwrap()
            });
            let r = min_ms(n.min(3), || {
                drop(io::load_normal_map(&p, &Default::default()).unwrap())
            });
            println!("png16 write {t:.0} ms, read {r:.0} ms");
            let _ = std::fs::remove_file(p);
        }
        other => eprintln!("unknown probe {other:?} (filter, fused, relight, curl, png, exr)"),
    }
}
