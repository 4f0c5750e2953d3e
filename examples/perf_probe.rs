//! Ad-hoc timing probe for the hot kernels (min of N runs, variants interleaved so machine
//! load affects them alike). `cargo run --release --no-default-features --example perf_probe`.
use rgbn::raster::convolve::{self, BorderMode, Deriche};
use std::time::Instant;

fn min_ms(n: usize, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    if std::env::args().nth(1).as_deref() == Some("exr") {
        use rgbn::raster::io::{self, ExrCompression as C, ExrPrecision};
        let (img, _) = rgbn::raster::sample::Surface::gaussians_for(2160).render(3840, 2160);
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
    let (w, h) = (3840, 2160);
    let base: Vec<f32> = (0..w * h)
        .map(|i| ((i * 7919) % 1013) as f32 * 1e-3)
        .collect();
    let d = Deriche::new(8.0);
    let b = BorderMode::Mirror;
    let mut x = base.clone();
    for _ in 0..3 {
        let rows = min_ms(5, || convolve::filter_rows(&mut x, w, h, &d, b));
        let cols_gather = min_ms(5, || convolve::filter_columns(&mut x, w, h, &d, b));
        let cols_strip = 0.0;
        let copy = min_ms(5, || x.copy_from_slice(&base));
        println!(
            "rows {rows:.1} ms  cols(gather) {cols_gather:.1} ms  cols(strip) {cols_strip:.1} ms  memcpy {copy:.1} ms"
        );
    }
}
