//! The README's examples, run as written.
//!
//! Every line of a fenced `sh` block in README.md that starts with `rgbn ` or `mkdir `
//! (continuation lines ending in `\` joined, comments left to the shell) runs through `sh -c`, in
//! order, in one temporary folder holding a fresh copy of `graphs/`, with the built `rgbn` first
//! on `PATH`, `HOME` a temporary folder too (examples that install completions or man pages write
//! there, never into the user's home) and `RGBN_DATA` pointing at the third-party data. A command
//! must exit 0 and every file it names with `-o`/`--output` (or `NAME=FILE`) or redirects to with
//! `>` must exist and be non-empty afterwards; `--out-dir` folders must be non-empty. (`cargo`
//! lines are the newcomer's build and test commands, run by CI itself.) Commands that use `$RGBN_DATA` are skipped (with a note) when the data is absent;
//! under `RGBN_REQUIRE_DATA=1` (CI) the absence fails the test instead.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// One runnable example: the README line it starts on and the command text.
#[derive(Debug, PartialEq)]
struct Example {
    line: usize,
    command: String,
}

/// The `rgbn` commands of the fenced `sh` blocks of `markdown`.
fn examples(markdown: &str) -> Vec<Example> {
    let mut out = Vec::new();
    let mut in_sh = false;
    let mut in_block = false;
    let mut pending: Option<Example> = None;
    for (i, raw) in markdown.lines().enumerate() {
        let line = raw.trim();
        if line.starts_with("```") {
            if in_block {
                in_block = false;
                in_sh = false;
            } else {
                in_block = true;
                in_sh = matches!(line.trim_start_matches('`').trim(), "sh" | "bash" | "shell");
            }
            continue;
        }
        if !in_sh {
            continue;
        }
        if let Some(p) = pending.as_mut() {
            p.command.push('\n');
            p.command.push_str(raw);
        } else if line.starts_with("rgbn ") || line.starts_with("mkdir ") {
            pending = Some(Example {
                line: i + 1,
                command: line.to_string(),
            });
        } else {
            continue;
        }
        if !line.ends_with('\\') {
            out.extend(pending.take());
        }
    }
    out
}

/// The files a command says it writes: the values of `-o`/`--output` (after `NAME=` when
/// present), and its `--out-dir` folder (second element true).
fn named_outputs(command: &str) -> Vec<(String, bool)> {
    let words: Vec<&str> = command
        .lines()
        .map(|l| l.split(" #").next().unwrap_or(""))
        .flat_map(str::split_whitespace)
        .filter(|w| *w != "\\")
        .collect();
    let mut out = Vec::new();
    for pair in words.windows(2) {
        match pair[0] {
            "-o" | "--output" => {
                let v = pair[1].rsplit_once('=').map_or(pair[1], |(_, f)| f);
                out.push((v.trim_matches('\'').to_string(), false));
            }
            "--out-dir" => out.push((pair[1].trim_matches('\'').to_string(), true)),
            ">" => out.push((pair[1].to_string(), false)),
            _ => {}
        }
    }
    out
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let p = e.path();
        let name = e.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue; // editor recovery files are not part of the repository
        }
        if p.is_dir() {
            copy_dir(&p, &to.join(name));
        } else {
            std::fs::copy(&p, to.join(name)).unwrap();
        }
    }
}

#[test]
fn the_extractor_finds_commands_continuations_and_outputs() {
    let md = "text `rgbn inline`\n```sh\ncargo test\n# rgbn comment\nrgbn a -o x.png  # note\nrgbn b \\\n    --out-dir out -o y=z.exr\n```\n```ron\nrgbn not shell\n```\n```sh\nmkdir -p d\nrgbn c > d/f.txt\n```\n";
    let ex = examples(md);
    assert_eq!(ex.len(), 4, "{ex:?}");
    assert_eq!(ex[2].command, "mkdir -p d");
    assert_eq!(
        named_outputs(&ex[3].command),
        vec![("d/f.txt".into(), false)]
    );
    assert_eq!(ex[0].line, 5);
    assert_eq!(ex[0].command, "rgbn a -o x.png  # note");
    assert_eq!(ex[1].command, "rgbn b \\\n    --out-dir out -o y=z.exr");
    assert_eq!(named_outputs(&ex[0].command), vec![("x.png".into(), false)]);
    assert_eq!(
        named_outputs(&ex[1].command),
        vec![("out".into(), true), ("z.exr".into(), false)]
    );
}

#[test]
fn readme_examples_run_as_written() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let examples = examples(&readme);
    assert!(
        examples.len() >= 20,
        "only {} rgbn commands found in README.md's sh blocks",
        examples.len()
    );
    let tmp = tempfile::tempdir().unwrap();
    copy_dir(&root().join("graphs"), &tmp.path().join("graphs"));
    let home = tempfile::tempdir().unwrap();
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_rgbn"));
    let path = std::env::join_paths(std::iter::once(bin.parent().unwrap().to_path_buf()).chain(
        std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()),
    ))
    .unwrap();
    // The data folder itself (skips with a note when absent; fails under RGBN_REQUIRE_DATA=1).
    let data = rgbn::test_data::real_data(".");
    let mut failures = Vec::new();
    let mut ran = 0;
    for ex in &examples {
        if ex.command.contains("$RGBN_DATA") && data.is_none() {
            eprintln!(
                "SKIPPED README.md line {} (no data): {}",
                ex.line, ex.command
            );
            continue;
        }
        let mut cmd = Command::new("sh");
        cmd.arg("-c")
            .arg(&ex.command)
            .current_dir(tmp.path())
            .env("PATH", &path)
            .env("HOME", home.path())
            .env_remove("RGBN_CACHE_DIR");
        if let Some(d) = &data {
            cmd.env("RGBN_DATA", d);
        }
        let o = cmd.output().expect("sh runs");
        ran += 1;
        if !o.status.success() {
            failures.push(format!(
                "README.md line {}: `{}` exited {:?}: {}",
                ex.line,
                ex.command,
                o.status.code(),
                stderr(&o).trim()
            ));
            continue;
        }
        for (f, is_dir) in named_outputs(&ex.command) {
            let p = match f.strip_prefix("~/") {
                Some(rest) => home.path().join(rest),
                None => tmp.path().join(&f),
            };
            let ok = if is_dir {
                std::fs::read_dir(&p).is_ok_and(|mut d| d.next().is_some())
            } else {
                std::fs::metadata(&p).is_ok_and(|m| m.len() > 0)
            };
            if !ok {
                failures.push(format!(
                    "README.md line {}: `{}` did not write {f}",
                    ex.line, ex.command
                ));
            }
        }
    }
    eprintln!("ran {ran} of {} README examples", examples.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
