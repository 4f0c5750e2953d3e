//! The memory budget (issue 15): a plan is estimated before it runs and refused over
//! `RGBN_MEMORY_LIMIT`, naming the nodes; the estimate is checked against the measured peak.

use std::path::Path;
use std::process::{Command, Output};

fn rgbn(dir: &Path, limit: Option<&str>, args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rgbn"));
    c.current_dir(dir).args(args);
    match limit {
        Some(l) => c.env("RGBN_MEMORY_LIMIT", l),
        None => c.env_remove("RGBN_MEMORY_LIMIT"),
    };
    c.output().unwrap()
}

fn graph(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("graphs")
        .join(name)
        .display()
        .to_string()
}

#[test]
fn a_plan_far_over_the_budget_is_refused_before_anything_runs() {
    let d = tempfile::tempdir().unwrap();
    // 16384² demo: 7.5 GB for its image alone; the budget is 64 MiB.
    let t0 = std::time::Instant::now();
    let o = rgbn(
        d.path(),
        Some("64M"),
        &[
            "eval",
            &graph("demo.ron"),
            "--set",
            "source.size=16384",
            "-o",
            "relit=r.png",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("over the budget of 64.0 MiB"), "{err}");
    assert!(err.contains("node 1 \"source\" demo"), "{err}");
    assert!(err.contains("RGBN_MEMORY_LIMIT"), "{err}");
    assert!(!d.path().join("r.png").exists());
    // Refused from the sizes alone: no 7.5 GB image was made.
    assert!(t0.elapsed().as_secs() < 10, "took {:?}", t0.elapsed());
}

#[test]
fn a_bad_limit_is_a_one_line_error_and_zero_means_none() {
    let d = tempfile::tempdir().unwrap();
    let o = rgbn(d.path(), Some("lots"), &["eval", &graph("surface.ron")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("RGBN_MEMORY_LIMIT") && err.contains("\"lots\""),
        "{err}"
    );
    let o = rgbn(
        d.path(),
        Some("0"),
        &["eval", &graph("surface.ron"), "--stats"],
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("budget none"), "{out}");
}

/// `(estimated, measured)` peak bytes printed by `--stats`.
fn peaks(stdout: &str) -> (f64, f64) {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("memory: "))
        .unwrap_or_else(|| panic!("no memory line in {stdout}"));
    let num = |after: &str| -> f64 {
        let rest = &line[line.find(after).unwrap() + after.len()..];
        let mut it = rest.split_whitespace();
        let v: f64 = it.next().unwrap().trim_end_matches(',').parse().unwrap();
        let unit = it.next().unwrap().trim_end_matches(',');
        v * match unit {
            "GiB" => f64::from(1u32 << 30),
            "MiB" => f64::from(1u32 << 20),
            u => panic!("unit {u}"),
        }
    };
    (num("estimated peak "), num("measured peak RSS "))
}

#[cfg(target_os = "linux")]
#[test]
fn the_estimate_covers_the_measured_peak_of_large_evaluations() {
    let d = tempfile::tempdir().unwrap();
    // The process itself (code, rayon stacks, allocator) before any image.
    let baseline = 40.0 * f64::from(1u32 << 20);
    for (g, set) in [
        ("demo.ron", "source.size=1024"),
        ("integrate.ron", "1.size=1024"),
        ("bilateral_split.ron", "1.size=1024"),
        ("pen.ron", "1.size=1024"),
    ] {
        let o = rgbn(
            d.path(),
            None,
            &["eval", &graph(g), "--set", set, "--stats"],
        );
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{g}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let (est, measured) = peaks(&out);
        eprintln!("{g}: estimated {est:.3e} B, measured {measured:.3e} B");
        assert!(
            est + baseline >= measured,
            "{g}: estimate {est} under the measured peak {measured}"
        );
        assert!(
            est <= 4.0 * measured,
            "{g}: estimate {est} far over {measured}"
        );
    }
}
