//! The `rgbn` binary: the command line (and, with the `gui` feature, the editor).

use std::process::ExitCode;

fn main() -> ExitCode {
    ExitCode::from(rgbn::cli::run(std::env::args_os()))
}
