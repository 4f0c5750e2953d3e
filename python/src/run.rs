//! Work off the interpreter's lock, stopped by Ctrl-C.
//!
//! [`interruptible`] runs a closure on its own thread while the calling thread, without the
//! GIL, waits for it and every [`POLL`] asks Python whether a signal arrived
//! (`PyErr_CheckSignals`, which runs Python's SIGINT handler on the main thread). On
//! `KeyboardInterrupt` it sets the evaluation's cancel flag — the evaluator stops before its
//! next node, as `rgbn eval` does on Ctrl-C — waits up to [`GRACE`] for the work to stop (a
//! write under way finishes; writes are atomic, so no file is left half-written), and raises.
//! Work still running after the grace (one long node: operators check no flag while they run)
//! is left to finish on its own thread and its result is dropped: like the command line, the
//! caller is not kept waiting, and nothing it started writes after it stopped at a node
//! boundary.
//!
//! Other threads of the process keep running Python while the work runs (the GIL is released).

use crate::error::EvalError;
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Arc;
use std::time::Duration;

/// How often the waiting thread checks for signals.
pub const POLL: Duration = Duration::from_millis(20);
/// How long an interrupted run may take to stop (the command line's grace).
pub const GRACE: Duration = rgbn::cli::interrupt::GRACE;

/// Runs `f` on a worker thread; see the module docs. `cancel` is set on Ctrl-C.
pub fn interruptible<T, F>(py: Python<'_>, cancel: Option<Arc<AtomicBool>>, f: F) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce() -> PyResult<T> + Send + 'static,
{
    let (tx, rx) = channel();
    std::thread::Builder::new()
        .name("rgbn-work".into())
        .spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
            let _ = tx.send(r);
        })
        .map_err(|e| EvalError::new_err(format!("cannot start a worker thread: {e}")))?;
    let mut rx = rx;
    loop {
        // The receiver moves into the GIL-free wait and back (it is `Send`, not `Sync`).
        let (got, back) = py.detach(move || (rx.recv_timeout(POLL), rx));
        rx = back;
        match got {
            Ok(Ok(r)) => return r,
            Ok(Err(panic)) => {
                let what = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                return Err(EvalError::new_err(format!(
                    "internal error (a panic; please report it): {what}"
                )));
            }
            Err(RecvTimeoutError::Timeout) => {
                if let Err(e) = py.check_signals() {
                    if let Some(c) = &cancel {
                        c.store(true, Ordering::SeqCst);
                    }
                    let _ = py.detach(move || rx.recv_timeout(GRACE).is_ok());
                    return Err(e);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(EvalError::new_err(
                    "the worker thread ended without a result",
                ))
            }
        }
    }
}
