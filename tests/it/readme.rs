//! The examples of the README and of the user guide, run as written.
//!
//! Every line of a fenced `sh` block in README.md and in each `docs/*.md` that starts with
//! `rgbn ` or `mkdir ` (continuation lines ending in `\` joined, comments left to the shell) runs
//! through `sh -c`, in order; each file's commands run in a temporary folder of their own holding
//! a fresh copy of `graphs/`, with the built `rgbn` first on `PATH`, `HOME` a temporary folder
//! too (examples that install completions or man pages write there, never into the user's home)
//! and `RGBN_DATA` pointing at the third-party data. A command must exit 0 and every file it
//! names with `-o`/`--output` (or `NAME=FILE`) or redirects to with `>` must exist and be
//! non-empty afterwards; `--out-dir` folders must be non-empty. Failures name the file and line.
//! (`cargo` lines are the newcomer's build and test commands, run by CI itself.) Commands that
//! use `$RGBN_DATA` are skipped (with a note) when the data is absent; under
//! `RGBN_REQUIRE_DATA=1` (CI) the absence fails the test instead.

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

/// README.md and every `docs/*.md`, as paths relative to the repository root, sorted.
fn documents() -> Vec<String> {
    let mut docs: Vec<String> = std::fs::read_dir(root().join("docs"))
        .expect("docs/ folder")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("docs/{n}"))
        .collect();
    docs.sort();
    docs.insert(0, "README.md".into());
    docs
}

/// What running one document's examples found.
struct Run {
    found: usize,
    ran: usize,
    failures: Vec<String>,
}

/// Runs the examples of `doc` (a path relative to the repository root) in a fresh folder.
fn run_document(doc: &str, bin_dir: &Path, data: Option<&Path>) -> Run {
    let text = std::fs::read_to_string(root().join(doc)).unwrap();
    let examples = examples(&text);
    let tmp = tempfile::tempdir().unwrap();
    copy_dir(&root().join("graphs"), &tmp.path().join("graphs"));
    let home = tempfile::tempdir().unwrap();
    let path = std::env::join_paths(std::iter::once(bin_dir.to_path_buf()).chain(
        std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()),
    ))
    .unwrap();
    let mut failures = Vec::new();
    let mut ran = 0;
    for ex in &examples {
        if ex.command.contains("$RGBN_DATA") && data.is_none() {
            eprintln!("SKIPPED {doc} line {} (no data): {}", ex.line, ex.command);
            continue;
        }
        let mut cmd = Command::new("sh");
        cmd.arg("-c")
            .arg(&ex.command)
            .current_dir(tmp.path())
            .env("PATH", &path)
            .env("HOME", home.path())
            .env_remove("RGBN_CACHE_DIR");
        if let Some(d) = data {
            cmd.env("RGBN_DATA", d);
        }
        let o = cmd.output().expect("sh runs");
        ran += 1;
        if !o.status.success() {
            failures.push(format!(
                "{doc} line {}: `{}` exited {:?}: {}",
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
                    "{doc} line {}: `{}` did not write {f}",
                    ex.line, ex.command
                ));
            }
        }
    }
    Run {
        found: examples.len(),
        ran,
        failures,
    }
}

#[test]
fn the_user_guide_is_in_docs() {
    let docs = documents();
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    for page in [
        "docs/editor.md",
        "docs/cli.md",
        "docs/graphs.md",
        "docs/integration.md",
        "docs/capture.md",
        "docs/publishing.md",
        "docs/reliability.md",
        "docs/ARCHITECTURE.md",
    ] {
        assert!(docs.iter().any(|d| d == page), "{page} is missing");
        // The README points to every page of the guide.
        let link = page.trim_start_matches("docs/");
        assert!(
            readme.contains(&format!("(docs/{link})")),
            "README.md does not link {page}"
        );
    }
}

#[test]
fn readme_and_docs_examples_run_as_written() {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_rgbn"));
    let bin_dir = bin.parent().unwrap();
    // The data folder itself (skips with a note when absent; fails under RGBN_REQUIRE_DATA=1).
    let data = rgbn::test_data::real_data(".");
    let mut failures = Vec::new();
    let mut total = 0;
    let mut readme = 0;
    for doc in documents() {
        let run = run_document(&doc, bin_dir, data.as_deref());
        eprintln!("{doc}: ran {} of {} examples", run.ran, run.found);
        total += run.found;
        if doc == "README.md" {
            readme = run.found;
        }
        failures.extend(run.failures);
    }
    assert!(
        readme >= 5,
        "only {readme} rgbn commands found in README.md's sh blocks"
    );
    assert!(
        total >= 60,
        "only {total} rgbn commands found in the sh blocks of README.md and docs/"
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
