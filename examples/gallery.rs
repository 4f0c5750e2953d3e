//! Regenerates the gallery of the paper's figures (`docs/gallery.md`, `docs/gallery/*.png`)
//! from the figure graphs under `graphs/paper/`, or checks it (see [`rgbn::gallery`]).
//!
//! ```text
//! cargo run --release --example gallery            # write the pictures and the tables
//! cargo run --release --example gallery -- --check # list disagreements, exit 1 if any
//! ```
//!
//! Run from anywhere: the repository is the one this example belongs to.

use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let check = match args.as_slice() {
        [] => false,
        [a] if a == "--check" => true,
        _ => {
            eprintln!("usage: gallery [--check]");
            return ExitCode::from(2);
        }
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let g = match rgbn::gallery::generate(root) {
        Ok(g) => g,
        Err(e) => {
            eprintln!("gallery: {e}");
            return ExitCode::from(2);
        }
    };
    let result = if check {
        rgbn::gallery::check(root, &g)
    } else {
        rgbn::gallery::write(root, &g)
    };
    match result {
        Ok(lines) => {
            for l in &lines {
                println!("{l}");
            }
            if check && !lines.is_empty() {
                eprintln!(
                    "gallery: docs/gallery.md disagrees with the figure graphs in {} place(s); \
                     regenerate with `cargo run --release --example gallery`",
                    lines.len()
                );
                return ExitCode::from(1);
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gallery: {e}");
            ExitCode::from(2)
        }
    }
}
