//! The `rgbn` binary's graph commands: exit codes, messages, files written, cache reuse across
//! processes.

use crate::common::*;
use std::path::Path;
use std::process::{Command, Output};

fn rgbn(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rgbn"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("rgbn runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn demo() -> String {
    graph_path("demo.ron").display().to_string()
}

#[test]
fn eval_writes_outputs_and_a_new_process_reuses_the_disk_cache() {
    let d = tempfile::tempdir().unwrap();
    let args = [
        "eval",
        &demo(),
        "--set",
        "source.size=64",
        "--set",
        "3.amount=0.5",
        "-o",
        "relit=relit.png",
        "-o",
        "image=image.exr",
        "--stats",
        "--cache-dir",
        "cache",
    ];
    let o = rgbn(d.path(), &args);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("wrote relit (picture 64×64)"), "{out}");
    assert!(out.contains("0 hits, 4 misses"), "{out}");
    let png = image::open(d.path().join("relit.png")).unwrap();
    assert_eq!((png.width(), png.height()), (64, 64));
    let exr = rgbn::raster::io::load_exr(&d.path().join("image.exr"), &Default::default()).unwrap();
    assert_eq!(exr.width(), 64);

    // A new process: everything from disk (the outputs exist: write elsewhere).
    let args2: Vec<&str> = args
        .iter()
        .map(|a| match *a {
            "relit=relit.png" => "relit=relit2.png",
            "image=image.exr" => "image=image2.exr",
            other => other,
        })
        .collect();
    let o = rgbn(d.path(), &args2);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("0 misses"), "{out}");
    assert!(out.contains(" disk "), "{out}");
    assert_eq!(
        std::fs::read(d.path().join("relit.png")).unwrap(),
        std::fs::read(d.path().join("relit2.png")).unwrap()
    );

    // Changing a downstream parameter: upstream from disk, two misses.
    let mut args3 = args2.clone();
    args3[5] = "3.amount=0.7";
    let o = rgbn(d.path(), &args3);
    let out = text(&o.stdout);
    assert!(out.contains("2 misses"), "{out}");
}

#[test]
fn usage_and_input_errors_exit_2_with_one_line() {
    let d = tempfile::tempdir().unwrap();
    let bad = write(
        d.path(),
        "bad.ron",
        "(version: 1, next_id: 3, outputs: { \"o\": (node: 2, port: \"image\") }, nodes: [(id: 1, op: \"demo\"), (id: 2, op: \"filter.gausian\", inputs: { \"image\": Node(1, \"image\") })])",
    );
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (
            vec!["check".into(), bad.display().to_string()],
            vec![
                "unknown operator",
                "did you mean \"filter.gaussian\"",
                "node 2",
                "bad.ron",
            ],
        ),
        (
            vec![
                "eval".into(),
                demo(),
                "--set".into(),
                "nosuch.size=3".into(),
            ],
            vec!["unknown node \"nosuch\"", "demo.ron"],
        ),
        (
            vec![
                "eval".into(),
                demo(),
                "--set".into(),
                "source.sise=3".into(),
            ],
            vec![
                "unknown parameter \"sise\"",
                "did you mean \"size\"",
                "node 1",
            ],
        ),
        (
            vec![
                "eval".into(),
                demo(),
                "--set".into(),
                "source.size=3".into(),
            ],
            vec!["size", "out of range", "node 1"],
        ),
        (
            vec!["eval".into(), demo(), "--set".into(), "nodot=3".into()],
            vec!["NODE.PARAM=VALUE"],
        ),
        (
            vec!["eval".into(), demo(), "-o".into(), "relt=x.png".into()],
            vec!["unknown graph output \"relt\"", "did you mean \"relit\""],
        ),
        (
            vec!["eval".into(), "missing.ron".into()],
            vec!["cannot read graph file", "missing.ron"],
        ),
        (
            vec![
                "eval".into(),
                graph_path("input_image.ron").display().to_string(),
                "-i".into(),
                "image=absent.exr".into(),
            ],
            vec!["absent.exr", "file not found"],
        ),
        (
            vec![
                "eval".into(),
                graph_path("input_image.ron").display().to_string(),
                "-i".into(),
                format!("image={}", root().join("graphs/data/image.exr").display()),
                "-o".into(),
                format!("image={}", root().join("graphs/data/image.exr").display()),
            ],
            vec!["refusing to overwrite an input file"],
        ),
    ];
    for (args, words) in cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = rgbn(d.path(), &a);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        for w in words {
            assert!(err.contains(w), "{args:?}: {w:?} not in {err}");
        }
    }
    // The input file is untouched.
    assert!(
        rgbn::raster::io::load_exr(&root().join("graphs/data/image.exr"), &Default::default())
            .is_ok()
    );
}

#[test]
fn evaluation_failure_exits_1() {
    let d = tempfile::tempdir().unwrap();
    // A 48×48 mask on a 32×32 image: valid graph, failing evaluation.
    let g = format!(
        "(version: 1, next_id: 4, outputs: {{ \"o\": (node: 3, port: \"image\") }}, nodes: [(id: 1, op: \"surface\", params: {{ \"width\": Int(32), \"height\": Int(32) }}), (id: 2, op: \"load_mask\", params: {{ \"path\": Path({:?}) }}), (id: 3, op: \"apply_mask\", inputs: {{ \"image\": Node(1, \"image\"), \"mask\": Node(2, \"mask\") }})])",
        root().join("graphs/data/mask.png").display().to_string()
    );
    let p = write(d.path(), "mismatch.ron", &g);
    let o = rgbn(d.path(), &["check", &p.display().to_string()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let o = rgbn(d.path(), &["eval", &p.display().to_string()]);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("apply_mask failed") && err.contains("node 3"),
        "{err}"
    );
}

#[test]
fn ops_lists_every_operator_from_the_specs() {
    let o = rgbn(Path::new("."), &["ops"]);
    assert_eq!(o.status.code(), Some(0));
    let out = text(&o.stdout);
    for op in rgbn::nodes::registry() {
        let s = op.spec();
        assert!(out.contains(&format!("{} — {}", s.id, s.title)), "{}", s.id);
        assert!(out.contains(s.doc), "{}", s.id);
        for p in op.params() {
            assert!(
                out.contains(&format!("param {}:", p.name)),
                "{}.{}",
                s.id,
                p.name
            );
        }
    }
    // Both ranges: the hard one (what a file or --set may hold) and the slider's.
    for line in [
        "param sigma_normal: float in [0, 1000000], slider [0, 1], default",
        "param sigma_px: float (px) in [0.05, 4096], slider [0.1, 64] log, default 2",
        "param angle_rad: float (rad) in [-10000, 10000], slider [-3.141592653589793, 3.141592653589793], default 0",
        // A slider over the whole hard range says nothing more.
        "param opacity: float in [0, 1], default 1",
    ] {
        assert!(out.contains(line), "{line}");
    }
}

#[test]
fn batch_continues_past_bad_files_and_lists_them() {
    let d = tempfile::tempdir().unwrap();
    let inp = d.path().join("in");
    let outd = d.path().join("out");
    std::fs::create_dir_all(&inp).unwrap();
    std::fs::create_dir_all(&outd).unwrap();
    std::fs::copy(root().join("graphs/data/image.exr"), inp.join("a.exr")).unwrap();
    std::fs::copy(root().join("graphs/data/image.exr"), inp.join("b.exr")).unwrap();
    std::fs::write(inp.join("broken.exr"), b"not an exr").unwrap();
    let o = rgbn(
        d.path(),
        &[
            "batch",
            &graph_path("input_image.ron").display().to_string(),
            "--input",
            "image=in/*.exr",
            "--out-dir",
            "out",
            "-j",
            "2",
        ],
    );
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("1 of 3 files failed") && err.contains("broken.exr"),
        "{err}"
    );
    assert!(
        text(&o.stdout).contains("wrote 4 outputs"),
        "{}",
        text(&o.stdout)
    );
    for f in ["a.relit.png", "a.image.exr", "b.relit.png", "b.image.exr"] {
        assert!(outd.join(f).is_file(), "{f}");
    }
    assert!(!outd.join("broken.relit.png").exists());
}

#[test]
fn batch_shards_are_disjoint_and_cover_every_file() {
    let d = tempfile::tempdir().unwrap();
    let inp = d.path().join("in");
    std::fs::create_dir_all(&inp).unwrap();
    let names = ["a", "b", "c", "d", "e"];
    for n in names {
        std::fs::copy(
            root().join("graphs/data/image.exr"),
            inp.join(format!("{n}.exr")),
        )
        .unwrap();
    }
    let mut seen = Vec::new();
    for k in 1..=3 {
        let out = format!("out{k}");
        let o = rgbn(
            d.path(),
            &[
                "batch",
                &graph_path("input_image.ron").display().to_string(),
                "--input",
                "image=in/*.exr",
                "--out-dir",
                &out,
                "--shard",
                &format!("{k}/3"),
            ],
        );
        assert!(o.status.success(), "{}", text(&o.stderr));
        let expected = if k < 3 { 2 } else { 1 };
        assert!(
            text(&o.stdout).contains(&format!("shard {k}/3: {expected} of 5 files")),
            "{}",
            text(&o.stdout)
        );
        for e in std::fs::read_dir(d.path().join(&out)).unwrap().flatten() {
            let f = e.file_name().to_string_lossy().into_owned();
            if let Some(stem) = f.strip_suffix(".relit.png") {
                seen.push(stem.to_string());
            }
        }
    }
    seen.sort();
    assert_eq!(seen, names, "every file in exactly one shard");
    for bad in ["0/3", "4/3", "1", "x/2"] {
        let o = rgbn(
            d.path(),
            &[
                "batch",
                &graph_path("input_image.ron").display().to_string(),
                "--input",
                "image=in/*.exr",
                "--out-dir",
                "o",
                "--shard",
                bad,
            ],
        );
        assert_eq!(o.status.code(), Some(2), "{bad}: {}", text(&o.stderr));
    }
}

/// Without the editor (`--no-default-features`), no command prints the help; with it, no
/// command opens the editor (not run here: it needs a display).
#[cfg(not(feature = "gui"))]
#[test]
fn no_command_prints_help_without_the_editor() {
    let dir = tempfile::tempdir().unwrap();
    let out = rgbn(dir.path(), &[]);
    assert_eq!(out.status.code(), Some(2));
    let all = text(&out.stdout) + &text(&out.stderr);
    assert!(all.contains("Usage"), "{all}");
    assert!(
        !all.contains(" edit "),
        "no edit command without the gui feature: {all}"
    );
}

#[cfg(feature = "gui")]
#[test]
fn help_lists_the_edit_command() {
    let dir = tempfile::tempdir().unwrap();
    let out = rgbn(dir.path(), &["--help"]);
    assert_eq!(out.status.code(), Some(0));
    assert!(text(&out.stdout).contains("edit"), "{}", text(&out.stdout));
}
