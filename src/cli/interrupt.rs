//! Ctrl-C (SIGINT) and SIGTERM in the command line.
//!
//! [`install`] replaces the default action (die at once) with a flag: the evaluator's
//! cancellation token ([`EvalOptions::cancel`](crate::eval::EvalOptions), seen by every
//! operator as [`crate::cancel::Cancel`]) stops the running operator within milliseconds (its
//! kernels check it between bands and iterations) and no further node starts, and each command calls [`check`] before it writes, so an interrupted run writes nothing more
//! — every output already reported as written is complete (writes are atomic), nothing is left
//! half-written — and exits with 130 (SIGINT) or 143 (SIGTERM), as a shell reports a process
//! killed by that signal. The first signal also prints one line; the handler is then reset to
//! the default action, so a second Ctrl-C ends the process at once (its temporary files, if any,
//! are cleaned by the next run).
//!
//! Should some step not check the token (a file being decoded, say), a watcher thread ends the
//! process [`GRACE`] after the signal if the command is still going,
//! as soon as no atomic write is under way ([`writes_in_flight`]): the unfinished node's result
//! is lost, which costs nothing (it was never going to be written), and every file on disk is
//! an old one or a complete new one.

use super::error::CliError;
use crate::raster::io::temp::writes_in_flight;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

/// How long a command may take to stop by itself after a signal before the watcher ends it.
pub const GRACE: Duration = Duration::from_millis(1500);

/// The cancellation flag shared with the evaluator (set by the handler).
static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
/// The signal received (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// SIGINT's number (the same on every Unix).
pub const SIGINT: i32 = 2;
/// SIGTERM's number.
pub const SIGTERM: i32 = 15;

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    // Only async-signal-safe work: atomic stores and one write(2).
    SIGNAL.store(sig, Ordering::SeqCst);
    if let Some(f) = FLAG.get() {
        f.store(true, Ordering::SeqCst);
    }
    const MSG: &[u8] = b"\nrgbn: interrupted: stopping after the running step without writing \
unfinished outputs (press Ctrl-C again to quit at once)\n";
    // SAFETY: write(2) on stderr with a static buffer is async-signal-safe.
    unsafe {
        libc::write(2, MSG.as_ptr().cast(), MSG.len());
    }
}

/// Installs the handler for SIGINT and SIGTERM (once per process) and returns the cancellation
/// flag to pass to the evaluator.
pub fn install() -> Arc<AtomicBool> {
    let flag = FLAG
        .get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone();
    #[cfg(unix)]
    {
        static ONCE: std::sync::Once = std::sync::Once::new();
        ONCE.call_once(|| {
            // SAFETY: a zeroed sigaction is a valid "no flags, empty mask" value; the handler
            // only touches atomics and write(2). SA_RESETHAND restores the default action after
            // the first signal, so a second one ends the process.
            unsafe {
                let mut sa: libc::sigaction = std::mem::zeroed();
                sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                sa.sa_flags = libc::SA_RESETHAND | libc::SA_RESTART;
                libc::sigemptyset(&mut sa.sa_mask);
                libc::sigaction(libc::SIGINT, &sa, std::ptr::null_mut());
                libc::sigaction(libc::SIGTERM, &sa, std::ptr::null_mut());
            }
            let watched = flag.clone();
            // Detached: it sleeps until a signal arrives, and the process exits without it.
            let _ = std::thread::Builder::new()
                .name("rgbn-interrupt".into())
                .spawn(move || watch(&watched));
        });
    }
    flag
}

/// Waits for the flag, gives the command [`GRACE`] to stop by itself, then exits once no write
/// is under way.
fn watch(flag: &AtomicBool) {
    while !flag.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(GRACE);
    while writes_in_flight() > 0 {
        std::thread::sleep(Duration::from_millis(5));
    }
    let signal = received().unwrap_or(SIGINT);
    let code = super::error::report(&CliError::Interrupted { signal });
    std::process::exit(i32::from(u8::from(code)));
}

/// The signal that interrupted this process, if one did.
#[must_use]
pub fn received() -> Option<i32> {
    match SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// `Err(CliError::Interrupted)` once a signal was received: called before every write.
///
/// # Errors
/// [`CliError::Interrupted`] after SIGINT or SIGTERM.
pub fn check() -> Result<(), CliError> {
    match received() {
        None => Ok(()),
        Some(signal) => Err(CliError::Interrupted { signal }),
    }
}

/// The flag for the evaluator when the handler is installed (`None` otherwise: library callers
/// and tests keep the default signal behaviour).
#[must_use]
pub fn flag() -> Option<Arc<AtomicBool>> {
    FLAG.get().cloned()
}

/// [`flag`] as a cancellation token (never set when no handler is installed).
pub fn token() -> crate::cancel::Cancel {
    flag().map_or_else(
        crate::cancel::Cancel::never,
        crate::cancel::Cancel::from_flag,
    )
}
