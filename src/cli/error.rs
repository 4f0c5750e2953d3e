//! Errors handled once. Every command returns a [`CliError`]; [`CliError::exit`] is the one
//! place where an error becomes an exit code, and [`report`] prints it as one line on stderr.
//!
//! The rule, by the error's kind:
//! - **0** ([`Exit::Ok`]): success; also `--help`, `--version`, and a closed stdout pipe
//!   (`rgbn ops | head`).
//! - **1** ([`Exit::Failed`]): an evaluation failure — valid input on which an operator failed,
//!   a cancelled evaluation, or files of a `batch` that failed (each reported as it failed).
//! - **130 / 143** ([`Exit::Interrupted`] / [`Exit::Terminated`]): stopped by Ctrl-C (SIGINT)
//!   or SIGTERM before finishing; nothing unfinished was written (see `interrupt`).
//! - **2** ([`Exit::Usage`]): bad usage or bad input — arguments, input files, graph files,
//!   parameters, and outputs that cannot be written (a missing folder, a full disk, stdout on a
//!   full device: an I/O problem of the user's target, whichever command or node writes it).

use crate::error::RgbnError;
use crate::graph::GraphError;

/// The exit codes of `rgbn`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Exit {
    /// Success.
    Ok = 0,
    /// Evaluation failure.
    Failed = 1,
    /// Bad usage or bad input (including outputs that cannot be written).
    Usage = 2,
    /// Interrupted by Ctrl-C (SIGINT): 128 + 2, as shells report it.
    Interrupted = 130,
    /// Stopped by SIGTERM: 128 + 15.
    Terminated = 143,
}

impl From<Exit> for u8 {
    fn from(e: Exit) -> u8 {
        e as u8
    }
}

impl From<Exit> for std::process::ExitCode {
    fn from(e: Exit) -> Self {
        Self::from(u8::from(e))
    }
}

/// Everything a command can fail with. Each message is one line: what is wrong, then where.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The command line could not be parsed (clap prints its own message and usage).
    #[error("{0}")]
    Clap(#[from] clap::Error),

    /// Arguments that parse but cannot be used (`--set` without `=`, no input, …).
    #[error("{0}")]
    Usage(String),

    /// An image, file or parameter error from the library.
    #[error(transparent)]
    Rgbn(#[from] RgbnError),

    /// A graph file, graph or evaluation error (boxed: it carries its location by value).
    #[error(transparent)]
    Graph(Box<GraphError>),

    /// Some files of a batch failed (each was reported when it failed).
    #[error("{failed} of {total} files failed: {list}")]
    Batch {
        /// How many failed.
        failed: usize,
        /// How many were processed.
        total: usize,
        /// The failed files, comma separated.
        list: String,
    },

    /// Writing to stdout failed (a closed pipe is not an error).
    #[error("cannot write to stdout ({0})")]
    Stdout(std::io::Error),

    /// The editor could not start or open its graph.
    #[error("{0}")]
    Editor(String),

    /// Stopped by a signal before finishing (nothing unfinished was written).
    #[error(
        "interrupted by {}: stopped before writing the unfinished outputs (outputs reported as \
         written are complete)",
        if *signal == super::interrupt::SIGTERM { "SIGTERM" } else { "Ctrl-C (SIGINT)" }
    )]
    Interrupted {
        /// The signal number.
        signal: i32,
    },
}

impl From<GraphError> for CliError {
    fn from(e: GraphError) -> Self {
        CliError::Graph(Box::new(e))
    }
}

impl CliError {
    /// The exit code of this error: the one mapping from errors to codes (see the module doc).
    #[must_use]
    pub fn exit(&self) -> Exit {
        let library_error = match self {
            CliError::Clap(e) if !e.use_stderr() => return Exit::Ok,
            CliError::Rgbn(e) => e,
            CliError::Graph(g) => match g.as_ref() {
                GraphError::Node { source, .. } => source,
                GraphError::Cancelled => return Exit::Failed,
                _ => return Exit::Usage,
            },
            CliError::Batch { .. } => return Exit::Failed,
            CliError::Interrupted { signal } => {
                return if *signal == super::interrupt::SIGTERM {
                    Exit::Terminated
                } else {
                    Exit::Interrupted
                }
            }
            CliError::Clap(_) | CliError::Usage(_) | CliError::Stdout(_) | CliError::Editor(_) => {
                return Exit::Usage
            }
        };
        match library_error {
            // An operator met an image it cannot process (inconsistent sizes, …).
            RgbnError::InvalidImage(_) | RgbnError::Cancelled => Exit::Failed,
            // Everything else is about the user's files, parameters or targets.
            _ => Exit::Usage,
        }
    }
}

/// Shorthand for a [`CliError::Usage`].
pub(crate) fn usage(message: impl Into<String>) -> CliError {
    CliError::Usage(message.into())
}

/// The one line printed for an error: `rgbn: <what is wrong>: <where>`.
#[must_use]
pub fn message(e: &CliError) -> String {
    format!("rgbn: {e}")
}

/// Prints `e` on stderr (clap's own format for command-line errors) and returns its exit code.
pub fn report(e: &CliError) -> Exit {
    match e {
        CliError::Clap(c) => {
            let _ = c.print();
        }
        _ => eprintln!("{}", message(e)),
    }
    e.exit()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn write_error() -> RgbnError {
        RgbnError::Write {
            detail: "disk full".into(),
            path: PathBuf::from("out.exr"),
        }
    }

    #[test]
    fn a_failed_write_is_a_usage_error_from_a_command_and_from_a_node() {
        let node = GraphError::Node {
            op: "save".into(),
            source: write_error(),
            at: crate::graph::At::file("g.ron"),
        };
        assert_eq!(CliError::from(write_error()).exit(), Exit::Usage);
        assert_eq!(CliError::from(node).exit(), Exit::Usage);
    }

    #[test]
    fn evaluation_failures_exit_1() {
        let node = GraphError::Node {
            op: "apply_mask".into(),
            source: RgbnError::InvalidImage("sizes differ".into()),
            at: crate::graph::At::file("g.ron"),
        };
        assert_eq!(CliError::from(node).exit(), Exit::Failed);
        assert_eq!(CliError::from(GraphError::Cancelled).exit(), Exit::Failed);
        let batch = CliError::Batch {
            failed: 1,
            total: 2,
            list: "a.exr".into(),
        };
        assert_eq!(batch.exit(), Exit::Failed);
        assert_eq!(u8::from(Exit::Failed), 1);
    }

    #[test]
    fn messages_are_one_line_with_the_prefix() {
        let e = CliError::Stdout(std::io::Error::other("no space"));
        assert_eq!(message(&e), "rgbn: cannot write to stdout (no space)");
        assert_eq!(e.exit(), Exit::Usage);
    }
}
