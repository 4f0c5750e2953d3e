//! `rgbn completions SHELL` (clap_complete) and `rgbn man` (clap_mangen), both generated from
//! the command tree, so they never drift from the program (a part of [`crate::cli`]).

use super::error::CliError;
use super::out::Out;
use super::Cli;
use crate::error::RgbnError;
use crate::raster::io;
use clap::{Args, CommandFactory};
use clap_complete::Shell;
use std::io::Write;
use std::path::PathBuf;

/// `rgbn completions`.
#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell: bash, zsh, fish, elvish, powershell.
    #[arg(value_enum)]
    pub shell: Shell,
}

/// `rgbn man`.
#[derive(Args, Debug)]
pub struct ManArgs {
    /// Write one page per command (`rgbn.1`, `rgbn-eval.1`, …) into this folder (created if
    /// missing) instead of printing `rgbn.1`.
    #[arg(short = 'o', long = "out-dir", value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
}

/// The command tree, named as the binary.
fn command() -> clap::Command {
    Cli::command().bin_name("rgbn")
}

/// Renders a man page to text.
fn render(cmd: clap::Command) -> String {
    man_page(cmd).1
}

/// A man page: its file name (`rgbn-eval.1`) and its roff text.
fn man_page(cmd: clap::Command) -> (String, String) {
    let man = clap_mangen::Man::new(cmd).source(format!("rgbn {}", env!("CARGO_PKG_VERSION")));
    let mut buf = Vec::new();
    // Rendering into memory cannot fail (a `Vec` never returns an I/O error).
    let _ = man.render(&mut buf);
    (
        man.get_filename(),
        String::from_utf8_lossy(&buf).into_owned(),
    )
}

/// Prints the completion script for `a.shell`.
pub(super) fn completions_cmd(a: &CompletionsArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let mut cmd = command();
    let mut buf = Vec::new();
    clap_complete::generate(a.shell, &mut cmd, "rgbn", &mut buf);
    out.line(String::from_utf8_lossy(&buf).trim_end())
}

/// Prints `rgbn.1`, or writes a page per command into `--out-dir`.
pub(super) fn man_cmd(a: &ManArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let cmd = command();
    let Some(dir) = &a.out_dir else {
        return out.line(render(cmd).trim_end());
    };
    if !dir.is_dir() {
        std::fs::create_dir_all(dir).map_err(|e| RgbnError::Write {
            detail: format!("cannot create the folder: {e}"),
            path: dir.clone(),
        })?;
        out.line(format_args!("created folder {}", dir.display()))?;
    }
    // Built, the subcommands have their display names (`rgbn-eval`): titles and file names.
    let mut cmd = cmd.disable_help_subcommand(true);
    cmd.build();
    let mut pages = vec![man_page(cmd.clone())];
    pages.extend(
        cmd.get_subcommands()
            .filter(|s| !s.is_hide_set())
            .map(|s| man_page(s.clone())),
    );
    for (file, text) in &pages {
        let path = dir.join(file);
        io::write_atomic(&path, |w| {
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
    }
    out.line(format_args!(
        "wrote {} man pages (rgbn.1 and rgbn-COMMAND.1) to {}",
        pages.len(),
        dir.display()
    ))
}
