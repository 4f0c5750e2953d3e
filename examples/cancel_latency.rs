//! How fast cancellation stops a running evaluation (issue: "Cancel during a 4K masked-Poisson
//! integration: time until the worker is idle"; "Ctrl-C during `rgbn eval graphs/integrate.ron`
//! on a 4K input: time to exit 130 with nothing partial").
//!
//! 1. In process, as the editor's worker runs it: a 4096² masked sphere into `integrate`
//!    (masked Poisson, then the DCT solver), the token set `--after` seconds into the run; the
//!    time from `cancel()` to `eval` returning `Cancelled`.
//! 2. Whole process: `rgbn eval graphs/integrate.ron --set 1.size=4096 -o height=…` (the binary
//!    beside this example, or `$RGBN_CLI`), SIGINT `--after` seconds in; the time from the
//!    signal to exit, its code, and whether anything was written. The CLI's fallback fires
//!    1.5 s after the signal: a time well under it means the work itself stopped.
//!
//! `cargo run --release --example cancel_latency -- [runs] [after_s]` (defaults 5, 1.5).

use rgbn::cancel::Cancel;
use rgbn::eval::{EvalOptions, Evaluator, Plan};
use rgbn::graph::{GraphError, LoadedGraph};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn graph(method: &str) -> LoadedGraph {
    let text = format!(
        r#"(
    version: 2,
    next_id: 3,
    outputs: {{ "out": (node: 2, port: "height") }},
    nodes: [
        (id: 1, op: "surface", params: {{ "shape": Choice("sphere"), "width": Int(4096), "height": Int(4096), "radius_px": Float(1900.0) }}),
        (id: 2, op: "integrate", params: {{ "method": Choice("{method}") }}, inputs: {{ "image": Node(1, "image") }}),
    ],
)"#
    );
    LoadedGraph::from_text(&text, "cancel_latency.ron", PathBuf::from(".")).expect("graph")
}

/// Seconds from `cancel()` to the evaluation returning, and whether it returned `Cancelled`.
fn in_process(lg: &LoadedGraph, after: Duration) -> (f64, bool, f64) {
    let plan = Plan::new(lg, &BTreeMap::new(), Path::new(".")).expect("plan");
    let token = Cancel::new();
    let t = token.clone();
    let start = Instant::now();
    let run = std::thread::spawn(move || {
        let r = Evaluator::default().eval(
            &plan,
            &["out"],
            &EvalOptions {
                cancel: t,
                ..EvalOptions::default()
            },
        );
        (r.map(|_| ()), Instant::now())
    });
    std::thread::sleep(after);
    let at = Instant::now();
    token.cancel();
    let (r, done) = run.join().expect("evaluation thread");
    let cancelled = matches!(r, Err(GraphError::Cancelled));
    (
        done.saturating_duration_since(at).as_secs_f64(),
        cancelled,
        start.elapsed().as_secs_f64(),
    )
}

fn cli() -> PathBuf {
    std::env::var_os("RGBN_CLI").map_or_else(
        || {
            let exe = std::env::current_exe().expect("exe");
            exe.parent().unwrap().parent().unwrap().join("rgbn")
        },
        PathBuf::from,
    )
}

/// Seconds from SIGINT to exit, the exit code, and whether the output exists.
#[cfg(unix)]
fn whole_process(after: Duration) -> (f64, Option<i32>, bool) {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("height.exr");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut child = std::process::Command::new(cli())
        .arg("eval")
        .arg(root.join("graphs/integrate.ron"))
        .args(["--set", "1.size=4096", "-o"])
        .arg(format!("height={}", out.display()))
        // The graph's own save nodes write beside it: in the temporary folder, not here.
        .current_dir(dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("rgbn (build it: cargo build --release)");
    std::thread::sleep(after);
    let at = Instant::now();
    // SAFETY: kill(2) on our own child's pid.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    let st = child.wait().expect("wait");
    let t = at.elapsed().as_secs_f64();
    let code = st.code().or(st.signal().map(|s| 128 + s));
    (t, code, out.exists())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(5);
    let after = Duration::from_secs_f64(args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1.5));
    for method in ["masked_poisson", "poisson_dct"] {
        let lg = graph(method);
        let mut times = Vec::new();
        for _ in 0..runs {
            let (t, cancelled, total) = in_process(&lg, after);
            println!(
                "in process, {method}: cancel → idle {:.1} ms (cancelled: {cancelled}; run {total:.2} s)",
                t * 1e3
            );
            times.push(t);
        }
        println!(
            "in process, {method}: median {:.1} ms, max {:.1} ms over {runs} runs",
            median(times.clone()) * 1e3,
            times.iter().copied().fold(0.0, f64::max) * 1e3
        );
    }
    #[cfg(unix)]
    whole_processes(runs, after);
}

#[cfg(unix)]
fn whole_processes(runs: usize, after: Duration) {
    let mut times = Vec::new();
    for _ in 0..runs {
        let (t, code, written) = whole_process(after);
        println!(
            "rgbn eval graphs/integrate.ron 4096²: SIGINT → exit {:.1} ms, code {code:?}, output written: {written}",
            t * 1e3
        );
        times.push(t);
    }
    println!(
        "whole process: median {:.1} ms, max {:.1} ms over {runs} runs",
        median(times.clone()) * 1e3,
        times.iter().copied().fold(0.0, f64::max) * 1e3
    );
}
