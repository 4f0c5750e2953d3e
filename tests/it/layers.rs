//! The layer order of `src/lib.rs` holds: no module uses a module above it.
//!
//! `src/lib.rs` lists the top-level modules bottom first on its `layers:` line. Every path
//! `crate::NAME` in code (comments and doc comments are not imports) of a file under
//! `src/MODULE/` (or `src/MODULE.rs`) must name a module at or below `MODULE`. Items the crate
//! root re-exports (`crate::RgbnImage`, the `params!` and `choice_enum!` macros) count as the
//! module that defines them. With a total order and no upward path there is no cycle between
//! top-level modules.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The `layers:` line of `src/lib.rs`, bottom first.
fn layers(root: &Path) -> Vec<String> {
    let lib = std::fs::read_to_string(root.join("src/lib.rs")).expect("src/lib.rs");
    let line = lib
        .lines()
        .find_map(|l| l.trim_start_matches("//!").trim().strip_prefix("layers:"))
        .expect("src/lib.rs documents its layers on a `layers:` line");
    line.split_whitespace().map(str::to_string).collect()
}

/// The module an item of the crate root belongs to.
fn root_item(name: &str) -> &str {
    match name {
        "RgbnError" => "error",
        "RgbnImage" | "Plane" | "GradientField" => "raster",
        "params" | "choice_enum" => "params",
        other => other,
    }
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("readable src") {
        let p = e.expect("dir entry").path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Every `(file, line, used module)` whose used module lies above the file's module.
fn upward_paths(root: &Path, order: &[String]) -> Vec<(String, usize, String, String)> {
    let rank: BTreeMap<&str, usize> = order
        .iter()
        .enumerate()
        .map(|(i, m)| (m.as_str(), i))
        .collect();
    let src = root.join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let mut bad = Vec::new();
    for f in files {
        let rel = f.strip_prefix(&src).expect("under src");
        let first = rel.components().next().expect("a component");
        let module = first.as_os_str().to_string_lossy();
        let module = module.trim_end_matches(".rs");
        // A sibling test file (`params_tests.rs`, included by `#[path]`) belongs to its module.
        let module = module.strip_suffix("_tests").unwrap_or(module);
        if module == "lib" || module == "main" {
            continue;
        }
        let Some(&own) = rank.get(module) else {
            panic!(
                "module {module} ({}) is missing from the layers line of src/lib.rs",
                rel.display()
            );
        };
        let text = std::fs::read_to_string(&f).expect("readable source");
        for (n, line) in text.lines().enumerate() {
            let code = line.trim_start();
            if code.starts_with("//") {
                continue;
            }
            let code = code.split(" // ").next().unwrap_or(code);
            let mut rest = code;
            while let Some(at) = rest.find("crate::") {
                let before = &rest[..at];
                rest = &rest[at + "crate::".len()..];
                if before.ends_with('$') {
                    continue; // `$crate::` in a macro names the defining crate's root
                }
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                let used = root_item(&name);
                let Some(&r) = rank.get(used) else { continue };
                if r > own {
                    bad.push((
                        rel.display().to_string(),
                        n + 1,
                        module.to_string(),
                        used.to_string(),
                    ));
                }
            }
        }
    }
    bad
}

#[test]
fn no_module_uses_a_module_above_it() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let order = layers(root);
    let bad = upward_paths(root, &order);
    let list: Vec<String> = bad
        .iter()
        .map(|(f, l, m, u)| format!("src/{f}:{l}: {m} uses {u}, a layer above it"))
        .collect();
    assert!(list.is_empty(), "upward imports:\n{}", list.join("\n"));
}

#[test]
fn the_checker_sees_an_upward_path() {
    // A copy of the tree with one deliberate upward import: the checker must report it.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let order = layers(root);
    let tmp = tempfile::tempdir().expect("temp dir");
    std::fs::create_dir_all(tmp.path().join("src/raster")).expect("mkdir");
    std::fs::copy(root.join("src/lib.rs"), tmp.path().join("src/lib.rs")).expect("copy lib.rs");
    std::fs::write(
        tmp.path().join("src/raster/bad.rs"),
        "// crate::eval in a comment is not an import\nuse crate::eval::Evaluator;\n",
    )
    .expect("write");
    let bad = upward_paths(tmp.path(), &order);
    assert_eq!(
        bad,
        vec![("raster/bad.rs".into(), 2, "raster".into(), "eval".into())]
    );
}

/// Files that hold only tests: a module's sibling `*_tests.rs` or a `tests.rs`.
fn is_test_file(p: &Path) -> bool {
    let name = p
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    name == "tests.rs" || name.ends_with("_tests.rs")
}

#[test]
fn no_source_file_is_over_1000_lines() {
    // docs/ARCHITECTURE.md promises it; this keeps the promise checked.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    files.sort();
    let long: Vec<String> = files
        .iter()
        .filter(|f| !is_test_file(f))
        .filter_map(|f| {
            let n = std::fs::read_to_string(f)
                .expect("readable")
                .lines()
                .count();
            (n > 1000).then(|| format!("{}: {n} lines", f.display()))
        })
        .collect();
    assert!(
        long.is_empty(),
        "over 1000 lines (split the module, tests into a sibling *_tests.rs):\n{}",
        long.join("\n")
    );
}

#[test]
fn the_architecture_doc_lists_the_layers_of_lib_rs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let order = layers(root);
    let doc = std::fs::read_to_string(root.join("docs/ARCHITECTURE.md")).expect("docs");
    let line = doc
        .lines()
        .find_map(|l| l.trim().strip_prefix("layers:"))
        .expect("docs/ARCHITECTURE.md writes the `layers:` line");
    let in_doc: Vec<String> = line.split_whitespace().map(str::to_string).collect();
    assert_eq!(
        in_doc, order,
        "docs/ARCHITECTURE.md's layers: line differs from src/lib.rs's"
    );
    // Every layer has a row in the module map.
    let missing: Vec<&String> = order
        .iter()
        .filter(|m| !doc.contains(&format!("\n| `{m}` |")))
        .collect();
    assert!(
        missing.is_empty(),
        "no module-map row for {missing:?} in docs/ARCHITECTURE.md"
    );
    // Every top-level module in src/ is a layer.
    for e in std::fs::read_dir(root.join("src")).expect("src") {
        let p = e.expect("entry").path();
        let stem = p.file_stem().expect("name").to_string_lossy().to_string();
        if matches!(stem.as_str(), "lib" | "main") || (p.is_file() && is_test_file(&p)) {
            continue;
        }
        assert!(
            order.contains(&stem),
            "src/{stem} is not on the layers: line"
        );
    }
}
