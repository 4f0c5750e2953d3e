//! Faults (issue 15): `kill -9` at random moments while `rgbn eval` writes its outputs, a
//! `save` node writes its file, the disk cache stores entries, and a graph is saved (the
//! editor's save and autosave path); two processes sharing a cache folder; Ctrl-C.
//!
//! After every kill each target is the old file or a complete new one (byte-equal to a
//! reference run), a later run leaves no temporary files behind, and a cache filled by killed
//! runs gives the same results as no cache.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const GRAPH: &str = r#"(
    version: 1,
    next_id: 5,
    outputs: {
        "image": (node: 2, port: "image"),
        "saved": (node: 3, port: "image"),
        "relit": (node: 4, port: "picture"),
    },
    nodes: [
        (id: 1, op: "demo", name: Some("source"), params: {"size": Int(384)}),
        (
            id: 2,
            op: "filter.sharpen",
            name: Some("sharpen"),
            params: {"amount": Float(1.0)},
            inputs: {"image": Node(1, "image")},
        ),
        (
            id: 3,
            op: "save",
            name: Some("save"),
            params: {"path": Path("saved.exr")},
            inputs: {"image": Node(2, "image")},
        ),
        (id: 4, op: "relight", name: Some("light"), inputs: {"image": Node(2, "image")}),
    ],
)"#;

/// The files a run writes (relative to its folder).
const TARGETS: [&str; 4] = ["image.exr", "relit.png", "saved.exr", "saved_out.exr"];

/// A small deterministic generator (the moments of the kills).
struct Lcg(u64);
impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `rgbn eval` of [`GRAPH`] with sharpen amount `amount`, writing [`TARGETS`] into `dir`.
fn eval_cmd(dir: &Path, amount: f64, cache: Option<&Path>) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rgbn"));
    c.current_dir(dir)
        .args(["eval", "graph.ron", "--set"])
        .arg(format!("sharpen.amount={amount}"))
        .args(["-o", "image=image.exr", "-o", "relit=relit.png"])
        .args(["-o", "saved=saved_out.exr"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    if let Some(c2) = cache {
        c.arg("--cache-dir").arg(c2);
    }
    c
}

fn setup() -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("graph.ron"), GRAPH).unwrap();
    d
}

fn run_ok(mut c: Command) {
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn read_targets(dir: &Path) -> Vec<Vec<u8>> {
    TARGETS
        .iter()
        .map(|t| std::fs::read(dir.join(t)).unwrap_or_default())
        .collect()
}

fn temporaries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "tmp"))
        .collect()
}

/// Kills `c` with SIGKILL `delay` after its start (or lets it finish first); true if killed.
fn kill_after(mut c: Command, delay: Duration) -> bool {
    let mut child = c.spawn().unwrap();
    let t0 = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        if t0.elapsed() >= delay {
            child.kill().unwrap(); // SIGKILL on Unix
            child.wait().unwrap();
            return true;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Reference outputs of the two versions, from complete runs in their own folders; and how
/// long one complete run takes.
fn references() -> ([Vec<Vec<u8>>; 2], Duration) {
    let mut out = [Vec::new(), Vec::new()];
    let mut longest = Duration::ZERO;
    for (v, amount) in [0.5, 2.0].into_iter().enumerate() {
        let d = setup();
        let t0 = Instant::now();
        run_ok(eval_cmd(d.path(), amount, None));
        longest = longest.max(t0.elapsed());
        out[v] = read_targets(d.path());
        assert!(out[v].iter().all(|b| !b.is_empty()));
    }
    assert_ne!(
        out[0], out[1],
        "the two versions must differ to tell them apart"
    );
    (out, longest)
}

#[test]
fn kill_9_during_eval_save_and_cache_writes_leaves_old_or_complete_new_files() {
    let (refs, full) = references();
    let mut rng = Lcg(0x5eed_f00d);
    let (d, cache) = (setup(), tempfile::tempdir().unwrap());
    run_ok(eval_cmd(d.path(), 0.5, None));
    // Kill until 50 runs were killed mid-way; a run that finished first sets the time window
    // of the next kills (cache hits make runs faster).
    let (mut killed, mut window) = (0, full);
    for i in 0..200 {
        if killed == 50 {
            break;
        }
        let amount = if i % 2 == 0 { 2.0 } else { 0.5 };
        // From the 35th kill on, the runs also fill a disk cache (entries written while killed).
        let c = (killed >= 35).then_some(cache.path());
        let t0 = Instant::now();
        if kill_after(eval_cmd(d.path(), amount, c), window.mul_f64(rng.unit())) {
            killed += 1;
        } else {
            window = t0.elapsed();
        }
        for (k, (t, now)) in TARGETS.iter().zip(read_targets(d.path())).enumerate() {
            assert!(
                now == refs[0][k] || now == refs[1][k],
                "run {i}: {t} is neither the old file nor a complete new one ({} bytes)",
                now.len()
            );
        }
    }
    assert_eq!(killed, 50, "runs finished before their kill too often");
    // A complete run (with the cache the killed runs filled) gives the reference results and
    // leaves no temporary file, neither beside its outputs nor in the cache.
    run_ok(eval_cmd(d.path(), 2.0, Some(cache.path())));
    assert_eq!(read_targets(d.path()), refs[1]);
    assert_eq!(temporaries(d.path()), Vec::<PathBuf>::new());
    assert_eq!(temporaries(cache.path()), Vec::<PathBuf>::new());
    run_ok(eval_cmd(d.path(), 0.5, Some(cache.path())));
    assert_eq!(read_targets(d.path()), refs[0]);
}

#[test]
fn two_processes_sharing_a_cache_folder_agree_with_no_cache() {
    let (refs, _) = references();
    let cache = tempfile::tempdir().unwrap();
    let (a, b) = (setup(), setup());
    let mut ca = eval_cmd(a.path(), 2.0, Some(cache.path())).spawn().unwrap();
    let mut cb = eval_cmd(b.path(), 2.0, Some(cache.path())).spawn().unwrap();
    assert!(ca.wait().unwrap().success() && cb.wait().unwrap().success());
    assert_eq!(read_targets(a.path()), refs[1]);
    assert_eq!(read_targets(b.path()), refs[1]);
}

/// Two versions of a graph file, saved alternately by the child below.
fn graph_versions() -> [String; 2] {
    let lg = rgbn::graph::LoadedGraph::from_text(GRAPH, "graph.ron", PathBuf::from(".")).unwrap();
    let mut g2 = lg.graph.clone();
    for n in g2.nodes.values_mut() {
        n.pos = [n.pos[0] + 1000.0, n.pos[1] + 7.0];
        n.name = n
            .name
            .as_ref()
            .map(|s| format!("{s} (moved, with a longer name)"));
    }
    [lg.graph.to_text(), g2.to_text()]
}

/// Saving a graph (the editor's save and autosave write through `Graph::save`) round-trips;
/// with `RGBN_FAULT_CHILD=PATH` set (by the next test) it instead saves the two versions to
/// PATH alternately until killed.
#[test]
fn graph_save_round_trips_or_serves_as_a_kill_target() {
    let versions = graph_versions();
    let graphs: Vec<rgbn::graph::Graph> = versions
        .iter()
        .map(|t| {
            rgbn::graph::LoadedGraph::from_text(t, "v.ron", PathBuf::from("."))
                .unwrap()
                .graph
        })
        .collect();
    if let Some(path) = std::env::var_os("RGBN_FAULT_CHILD") {
        for i in 0.. {
            graphs[i % 2].save(Path::new(&path)).unwrap();
        }
    }
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("g.ron");
    for (g, text) in graphs.iter().zip(&versions) {
        g.save(&p).unwrap();
        assert_eq!(&std::fs::read_to_string(&p).unwrap(), text);
    }
}

#[test]
fn kill_9_during_graph_saves_leaves_one_complete_version() {
    let versions = graph_versions();
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("autosave.ron");
    std::fs::write(&p, &versions[0]).unwrap();
    let mut rng = Lcg(42);
    for i in 0..10 {
        let mut c = Command::new(std::env::current_exe().unwrap());
        c.args([
            "faults::graph_save_round_trips_or_serves_as_a_kill_target",
            "--exact",
            "--test-threads=1",
        ])
        .env("RGBN_FAULT_CHILD", &p)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
        // The child saves for ever: every run is killed, at 20–220 ms, mid-stream or not.
        assert!(kill_after(
            c,
            Duration::from_millis(20 + (200.0 * rng.unit()) as u64)
        ));
        let now = std::fs::read_to_string(&p).unwrap();
        assert!(
            versions.contains(&now),
            "kill {i}: the graph file is torn ({} bytes)",
            now.len()
        );
    }
    // The next save of that file removes the killed processes' temporaries.
    let g = rgbn::graph::LoadedGraph::from_text(&versions[1], "v.ron", PathBuf::from("."))
        .unwrap()
        .graph;
    g.save(&p).unwrap();
    assert_eq!(temporaries(d.path()), Vec::<PathBuf>::new());
}

#[cfg(unix)]
#[test]
fn ctrl_c_cancels_eval_exits_130_and_writes_nothing() {
    let d = setup();
    // Large enough that the run is still going after 0.5 s on any machine (the demo node alone
    // takes seconds at 2048²): the evaluator stops after the running node, or the process ends
    // 1.5 s after the signal with no write under way.
    let mut c = Command::new(env!("CARGO_BIN_EXE_rgbn"));
    c.current_dir(d.path())
        .args(["eval", "graph.ron", "--set", "source.size=2048"])
        .args(["-o", "image=image.exr", "-o", "relit=relit.png"])
        .args(["-o", "saved=saved_out.exr"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let child = c.spawn().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let t0 = Instant::now();
    let k = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(k.success());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted by Ctrl-C"), "{stderr}");
    let stop = t0.elapsed();
    eprintln!("stopped {stop:?} after SIGINT");
    assert!(stop < Duration::from_secs(10), "took {stop:?} to stop");
    for t in TARGETS {
        assert!(!d.path().join(t).exists(), "{t} was written after Ctrl-C");
    }
    assert_eq!(temporaries(d.path()), Vec::<PathBuf>::new());
}
