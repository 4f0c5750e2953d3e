//! rgbn's errors as Python exceptions. The message is the command line's one line without its
//! `rgbn: ` prefix (`rgbn::cli::error::message`), so a script and a shell see the same words.
//!
//! - `Error`: the base of everything rgbn raises;
//! - `InputError` (bad input: arrays, parameters, graph files, names, sizes);
//! - `FileError` (files: not found, unreadable, undecodable, unwritable);
//! - `EvalError` (valid input on which an operator failed, or a cancelled evaluation).

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyUserWarning};
use pyo3::PyErr;
use rgbn::cli::CliError;
use rgbn::error::RgbnError;
use rgbn::graph::GraphError;

create_exception!(
    rgbn,
    Error,
    PyException,
    "Any error rgbn reports (the message is the command line's one line)."
);
create_exception!(
    rgbn,
    InputError,
    Error,
    "Bad input: arrays, parameters, graph files, names or sizes."
);
create_exception!(
    rgbn,
    FileError,
    Error,
    "A file that cannot be found, read, decoded or written."
);
create_exception!(
    rgbn,
    EvalError,
    Error,
    "An operator failed on valid input, or the evaluation was cancelled."
);
create_exception!(
    rgbn,
    RepairWarning,
    PyUserWarning,
    "Normals or colours were repaired on the way in (the command line's note)."
);

/// Which exception class a library error is.
fn class_of(e: &RgbnError) -> fn(String) -> PyErr {
    match e {
        RgbnError::NotFound { .. }
        | RgbnError::Read { .. }
        | RgbnError::Decode { .. }
        | RgbnError::MissingDir { .. }
        | RgbnError::OutputIsInput { .. }
        | RgbnError::Write { .. } => FileError::new_err,
        RgbnError::InvalidImage(_) | RgbnError::Cancelled => EvalError::new_err,
        _ => InputError::new_err,
    }
}

/// A library error as an exception.
pub fn rgbn_err(e: RgbnError) -> PyErr {
    let class = class_of(&e);
    class(e.to_string())
}

/// A graph error as an exception.
pub fn graph_err(e: GraphError) -> PyErr {
    let class: fn(String) -> PyErr = match &e {
        GraphError::Node { source, .. } => class_of(source),
        GraphError::Io { .. } | GraphError::InputFile { .. } => FileError::new_err,
        GraphError::Cancelled => EvalError::new_err,
        _ => InputError::new_err,
    };
    class(e.to_string())
}

/// A command-line error (the `rgbn` helpers of `rgbn::cli`) as an exception.
pub fn cli_err(e: CliError) -> PyErr {
    match e {
        CliError::Rgbn(e) => rgbn_err(e),
        CliError::Graph(g) => graph_err(*g),
        other => InputError::new_err(other.to_string()),
    }
}

/// An `InputError` with `message`.
pub fn input(message: impl Into<String>) -> PyErr {
    InputError::new_err(message.into())
}
