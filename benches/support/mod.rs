//! Shared by the benches (included with `#[path]`; not a bench target of its own).

/// A 500 px path of 10 px segments from `start`, a gentle arc.
pub fn base_path(start: [f64; 2]) -> Vec<[f64; 2]> {
    let mut p = vec![start];
    for k in 0..50 {
        let a = 0.02 * k as f64;
        let last = p[p.len() - 1];
        p.push([last[0] + 10.0 * a.cos(), last[1] + 10.0 * a.sin()]);
    }
    p
}
