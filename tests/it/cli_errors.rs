//! The command line as a user runs it: errors handled once (exit codes by the error's kind,
//! one line on stderr), the one stdout writer (a closed pipe is not an error, a full device is),
//! library warnings reaching stderr, `batch --out-dir` creating its folder, shell completions
//! and the man page.

use crate::common::*;
use std::path::Path;
use std::process::{Command, Output, Stdio};

fn rgbn_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(dir)
        .args(args)
        .env_remove("RUST_LOG")
        .output()
        .expect("rgbn runs")
}

/// Exit code and the one stderr line of a failed run.
fn failed(o: &Output) -> (Option<i32>, String) {
    let err = stderr(o);
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    (o.status.code(), err.trim_end().to_string())
}

/// A failed write of an output is the same kind of error whichever command (or node) writes:
/// exit 2, one line naming the file last.
#[test]
fn a_failed_write_exits_2_from_filter_eval_and_a_save_node() {
    let d = tempfile::tempdir().unwrap();
    // An existing folder where the file should go: every check passes, the rename fails.
    for taken in ["taken.png", "taken.exr"] {
        std::fs::create_dir(d.path().join(taken)).unwrap();
    }
    let runs: Vec<Vec<String>> = vec![
        vec![
            "filter".into(),
            "--demo".into(),
            "--demo-size".into(),
            "32".into(),
            "-k".into(),
            "gauss:1".into(),
            "-o".into(),
            "taken.png".into(),
        ],
        vec![
            "eval".into(),
            graph_path("demo.ron").display().to_string(),
            "--set".into(),
            "source.size=32".into(),
            "-o".into(),
            "relit=taken.png".into(),
        ],
        vec![
            "eval".into(),
            graph_path("save.ron").display().to_string(),
            "--set".into(),
            "2.path=taken.exr".into(),
        ],
    ];
    for args in runs {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = rgbn_in(d.path(), &a);
        let (code, err) = failed(&o);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(
            err.starts_with("rgbn: ") && err.contains("cannot write"),
            "{args:?}: {err}"
        );
        assert!(err.contains("taken."), "{args:?}: {err}");
    }
}

/// Every command prints through one writer: stdout on a full device is an error (exit 2, one
/// line), the same for each.
#[cfg(target_os = "linux")]
#[test]
fn stdout_on_a_full_device_is_one_error_for_every_command() {
    let demo = graph_path("demo.ron").display().to_string();
    let runs: [&[&str]; 4] = [
        &["ops"],
        &["check", &demo],
        &["info", "--demo", "--demo-size", "16"],
        &["completions", "bash"],
    ];
    for args in runs {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_rgbn"))
            .args(args)
            .stdout(full)
            .output()
            .unwrap();
        let (code, err) = failed(&o);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains("cannot write to stdout"), "{args:?}: {err}");
    }
}

/// A closed pipe (`rgbn ops | head -1`) is not an error: exit 0, nothing on stderr.
#[test]
fn a_closed_stdout_pipe_is_not_an_error() {
    for args in [
        &["ops"][..],
        &["man"],
        &["info", "--demo", "--demo-size", "16"],
    ] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = Command::new(env!("CARGO_BIN_EXE_rgbn"))
            .args(args)
            .stdout(Stdio::from(writer))
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert_eq!(stderr(&o), "", "{args:?}");
    }
}

/// Library warnings reach the user with `RUST_LOG` unset (the default level is `warn`), as
/// `rgbn: warning: …` lines; `RUST_LOG=error` silences them.
#[test]
fn a_disk_cache_warning_reaches_stderr_with_rust_log_unset() {
    let d = tempfile::tempdir().unwrap();
    let args = |out: &str| -> Vec<String> {
        vec![
            "eval".into(),
            graph_path("demo.ron").display().to_string(),
            "--set".into(),
            "source.size=32".into(),
            "-o".into(),
            format!("relit={out}"),
            "--cache-dir".into(),
            "cache".into(),
        ]
    };
    let a1 = args("a.png");
    let o = rgbn_in(d.path(), &a1.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stderr(&o), "");
    // Each cache entry becomes a folder: entries cannot be read (miss) nor written (warning).
    let mut entries = 0;
    for e in std::fs::read_dir(d.path().join("cache")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "rgbnc") {
            std::fs::remove_file(&p).unwrap();
            std::fs::create_dir(&p).unwrap();
            entries += 1;
        }
    }
    assert!(entries > 0);
    let a2 = args("b.png");
    let a2: Vec<&str> = a2.iter().map(String::as_str).collect();
    let o = rgbn_in(d.path(), &a2);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.lines()
            .any(|l| l.starts_with("rgbn: warning: disk cache write failed")),
        "{err}"
    );
    assert!(d.path().join("b.png").is_file());
    let quiet = Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(d.path())
        .args(&a2)
        .env("RUST_LOG", "error")
        .output()
        .unwrap();
    assert_eq!(quiet.status.code(), Some(0));
    assert_eq!(stderr(&quiet), "");
}

/// `batch --out-dir` creates a missing folder (as `mkdir -p`) and says so; the batch
/// example of docs/graphs.md as written.
#[test]
fn batch_creates_a_missing_out_dir_and_says_so() {
    let d = tempfile::tempdir().unwrap();
    let data = d.path().join("graphs/data");
    std::fs::create_dir_all(&data).unwrap();
    std::fs::copy(root().join("graphs/data/image.exr"), data.join("image.exr")).unwrap();
    std::fs::copy(
        graph_path("input_image.ron"),
        d.path().join("graphs/input_image.ron"),
    )
    .unwrap();
    let o = rgbn_in(
        d.path(),
        &[
            "batch",
            "graphs/input_image.ron",
            "--input",
            "image=graphs/data/*.exr",
            "--out-dir",
            "out/nested",
            "-j",
            "2",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("created folder out/nested"), "{out}");
    assert!(
        d.path().join("out/nested/image.relit.png").is_file(),
        "{out}"
    );
    // Again: the folder exists, nothing to say about it.
    let o = rgbn_in(
        d.path(),
        &[
            "batch",
            "graphs/input_image.ron",
            "--input",
            "image=graphs/data/*.exr",
            "--out-dir",
            "out/nested",
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!stdout(&o).contains("created folder"), "{}", stdout(&o));
    // A file in the way: one line naming the folder, exit 2, nothing evaluated.
    std::fs::write(d.path().join("blocker"), "x").unwrap();
    let o = rgbn_in(
        d.path(),
        &[
            "batch",
            "graphs/input_image.ron",
            "--input",
            "image=graphs/data/*.exr",
            "--out-dir",
            "blocker/out",
        ],
    );
    let (code, err) = failed(&o);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.ends_with("blocker/out"), "{err}");
}

/// The subcommands users type, for completions and man pages.
fn subcommands() -> Vec<String> {
    use clap::CommandFactory;
    rgbn::cli::Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect()
}

#[test]
fn completions_know_every_subcommand() {
    let subs = subcommands();
    assert!(subs.iter().any(|s| s == "eval") && subs.iter().any(|s| s == "man"));
    let o = rgbn(&["completions", "bash"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let script = stdout(&o);
    assert!(
        script.contains("complete -F"),
        "not a bash completion script"
    );
    for s in &subs {
        assert!(script.contains(s.as_str()), "bash completion lacks {s}");
    }
    for shell in ["zsh", "fish", "elvish", "powershell"] {
        let o = rgbn(&["completions", shell]);
        assert_eq!(o.status.code(), Some(0), "{shell}: {}", stderr(&o));
        assert!(stdout(&o).contains("batch"), "{shell}");
    }
    let o = rgbn(&["completions", "tcsh"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn man_page_names_every_subcommand_and_man_out_dir_writes_one_page_each() {
    let o = rgbn(&["man"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let page = stdout(&o);
    assert!(page.contains("\n.TH rgbn 1"), "{page}");
    for s in subcommands() {
        assert!(page.contains(&s), "the man page lacks {s}");
    }
    let d = tempfile::tempdir().unwrap();
    let o = rgbn_in(d.path(), &["man", "-o", "man/man1"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("created folder man/man1"));
    let dir = d.path().join("man/man1");
    let eval = std::fs::read_to_string(dir.join("rgbn-eval.1")).unwrap();
    // roff escapes the hyphens of options.
    assert!(
        eval.contains(".TH rgbn-eval 1") && eval.contains(r"\-\-cache\-dir"),
        "{eval}"
    );
    for s in subcommands() {
        assert!(dir.join(format!("rgbn-{s}.1")).is_file(), "no page for {s}");
    }
    assert!(dir.join("rgbn.1").is_file());
}

/// A parameter error met while running a node names the parameter (never `parameter ""`).
#[test]
fn parameter_errors_name_their_parameter() {
    use rgbn::params::ParamError;
    let e = rgbn::RgbnError::from(ParamError::Kind {
        name: "sigma_px".into(),
        expected: "float",
        found: "text",
    });
    assert_eq!(
        e.to_string(),
        "invalid parameter sigma_px: needs a float value, got a text"
    );
    let e = rgbn::RgbnError::from(ParamError::Unknown {
        name: "sigma".into(),
        suggestion: Some("sigma_px".into()),
    });
    assert_eq!(
        e.to_string(),
        "invalid parameter sigma: no such parameter (did you mean \"sigma_px\"?)"
    );
}

/// Bad camera input to `integrate` (issue 17): a K file that is not 3 × 3, one with a word in
/// it, a missing K file and a focal length ≤ 0 are one-line errors naming the node and the
/// parameter (or the file), exit 2, and no output is written.
#[test]
fn bad_camera_parameters_are_one_line_errors_naming_node_and_parameter() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("k23.txt"), "500 0 48\n0 500 48\n").unwrap();
    std::fs::write(d.path().join("kword.txt"), "500 0 48\n0 five 48\n0 0 1\n").unwrap();
    let graph = graph_path("integrate.ron").display().to_string();
    // (Relative paths in a graph are relative to the graph's folder.)
    let k = |name: &str| format!("2.k_file={}", d.path().join(name).display());
    let cases: [([String; 2], &str); 4] = [
        (["2.camera=k_file".into(), k("k23.txt")], "k_file"),
        (["2.camera=k_file".into(), k("kword.txt")], "k_file"),
        (["2.camera=k_file".into(), k("missing.txt")], "missing.txt"),
        (
            ["2.camera=pinhole".into(), "2.focal_px=0".into()],
            "focal_px",
        ),
    ];
    for (sets, names) in &cases {
        let mut args = vec!["eval", graph.as_str(), "-o", "height=h.exr"];
        for s in sets {
            args.extend(["--set", s.as_str()]);
        }
        let o = rgbn_in(d.path(), &args);
        let (code, err) = failed(&o);
        assert_eq!(code, Some(2), "{sets:?}: {err}");
        assert!(err.contains(names), "{sets:?}: {err}");
        assert!(
            err.contains("node 2") || err.contains("integrate"),
            "{sets:?}: {err}"
        );
        assert!(!d.path().join("h.exr").exists(), "{sets:?}");
    }
    // The same --set order with a good K file works: the graph is validated after all sets.
    std::fs::write(d.path().join("k.txt"), "500 0 47.5\n0 500 47.5\n0 0 1\n").unwrap();
    let o = rgbn_in(
        d.path(),
        &[
            "eval",
            graph.as_str(),
            "-o",
            "height=h.exr",
            "--set",
            "2.camera=k_file",
            "--set",
            &k("k.txt"),
        ],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(d.path().join("h.exr").is_file());
}
