//! Cancellation of running work: a token the caller sets, checked by long kernels.
//!
//! A [`Cancel`] is a shared flag. The evaluator hands one to every operator through
//! `nodes::RunContext`; the editor sets it when the user presses Cancel or makes a newer edit,
//! the command line when it receives Ctrl-C or SIGTERM.
//!
//! **How a kernel sees it.** While an operator runs, its token is the calling thread's
//! *current* token ([`Cancel::enter`], done by the node layer around `Operator::run`), so a
//! pure kernel needs no extra argument: it takes [`Cancel::current`] once, on the thread that
//! called it, and checks [`Cancel::is_cancelled`] between units of work (a row band, a solver
//! iteration, a pyramid level: every few milliseconds, well under the 50 ms a user notices).
//! Inside `rayon` closures a kernel uses the token it captured, never `current()`: a pool
//! worker may be running another evaluation's job, with another token.
//!
//! **What a cancelled kernel returns.** As soon as it sees the flag it may stop and return
//! anything well-formed (planes of the right size, any values), never panic. The node layer
//! checks the token after the operator returns and turns the result into
//! [`RgbnError::Cancelled`], so a result computed after cancellation is never used, cached or
//! written. Kernels therefore stay simple: `if cancel.is_cancelled() { break }`.
//!
//! **Jobs that are not an operator's run.** A pool worker running an operator keeps that
//! operator's token current while it waits inside a `join`, and may meanwhile run a job stolen
//! from elsewhere. A job that calls kernels and is not itself an operator's run (the
//! evaluator's readouts, for instance) therefore enters its own token (or
//! [`Cancel::never`]) first, so it never sees a token that is not its own.
//!
//! Code outside an evaluation (the library called directly, Python's `rgbn` functions) has no
//! current token: [`Cancel::current`] is then [`Cancel::never`], whose checks are one branch.

use crate::error::RgbnError;
use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// A cancellation token: cheap to clone, shared by everyone who may set or check it.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Option<Arc<Shared>>);

#[derive(Debug, Default)]
struct Shared {
    flag: Arc<AtomicBool>,
    /// [`Cancel::after_checks`]: the token sets itself at the check that makes this many.
    limit: Option<u64>,
    /// Checks made ([`Cancel::checks`]), counted only with a limit.
    checks: AtomicU64,
}

thread_local! {
    /// The token of the operator running on this thread ([`Cancel::enter`]).
    static CURRENT: RefCell<Cancel> = const { RefCell::new(Cancel(None)) };
}

impl Cancel {
    /// A token nobody can set: its checks are always false.
    #[must_use]
    pub const fn never() -> Self {
        Self(None)
    }

    /// A new token, not set.
    #[must_use]
    pub fn new() -> Self {
        Self::from_flag(Arc::new(AtomicBool::new(false)))
    }

    /// A token sharing `flag` (set by whoever holds it: a signal handler, another thread).
    #[must_use]
    pub fn from_flag(flag: Arc<AtomicBool>) -> Self {
        Self(Some(Arc::new(Shared {
            flag,
            ..Shared::default()
        })))
    }

    /// A token that sets itself at its `n`-th check ([`is_cancelled`](Self::is_cancelled)
    /// counts as one): a cancellation arriving at a chosen point of the work, the same on
    /// every run, for tests.
    #[must_use]
    pub fn after_checks(n: u64) -> Self {
        Self(Some(Arc::new(Shared {
            limit: Some(n),
            ..Shared::default()
        })))
    }

    /// Checks made so far of a token from [`after_checks`](Self::after_checks) (0 for others).
    #[must_use]
    pub fn checks(&self) -> u64 {
        self.0
            .as_ref()
            .map_or(0, |s| s.checks.load(Ordering::Relaxed))
    }

    /// The shared flag, if this token can be set.
    #[must_use]
    pub fn flag(&self) -> Option<&Arc<AtomicBool>> {
        self.0.as_ref().map(|s| &s.flag)
    }

    /// Sets the token: every holder sees it at its next check. A [`never`](Self::never) token
    /// ignores it.
    pub fn cancel(&self) {
        if let Some(s) = &self.0 {
            s.flag.store(true, Ordering::Relaxed);
        }
    }

    /// Whether the token has been set.
    #[inline]
    #[must_use]
    pub fn is_cancelled(&self) -> bool {
        let Some(s) = &self.0 else {
            return false;
        };
        if let Some(limit) = s.limit {
            if s.checks.fetch_add(1, Ordering::Relaxed) + 1 >= limit {
                s.flag.store(true, Ordering::Relaxed);
            }
        }
        s.flag.load(Ordering::Relaxed)
    }

    /// `Err(RgbnError::Cancelled)` once the token is set.
    ///
    /// # Errors
    /// [`RgbnError::Cancelled`] when the token is set.
    pub fn check(&self) -> Result<(), RgbnError> {
        if self.is_cancelled() {
            Err(RgbnError::Cancelled)
        } else {
            Ok(())
        }
    }

    /// The token of the operator running on this thread ([`never`](Self::never) outside one).
    #[must_use]
    pub fn current() -> Self {
        CURRENT.with(|c| c.borrow().clone())
    }

    /// Makes this token the current one on this thread until the guard is dropped (the
    /// previous one is then restored, so scopes nest).
    #[must_use = "the token is current only while the guard lives"]
    pub fn enter(&self) -> Entered {
        let previous = CURRENT.with(|c| c.replace(self.clone()));
        Entered {
            previous,
            _not_send: std::marker::PhantomData,
        }
    }
}

/// While alive, a token is the thread's current one ([`Cancel::enter`]).
#[derive(Debug)]
pub struct Entered {
    previous: Cancel,
    /// The guard restores this thread's state: it must not move to another thread.
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Drop for Entered {
    fn drop(&mut self) {
        let previous = std::mem::take(&mut self.previous);
        CURRENT.with(|c| *c.borrow_mut() = previous);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_token_is_seen_by_every_clone_and_never_is_never_set() {
        let a = Cancel::new();
        let b = a.clone();
        assert!(!b.is_cancelled() && b.check().is_ok());
        a.cancel();
        assert!(b.is_cancelled());
        assert!(matches!(b.check(), Err(RgbnError::Cancelled)));
        let n = Cancel::never();
        n.cancel();
        assert!(!n.is_cancelled());
    }

    #[test]
    fn a_token_after_checks_sets_itself_at_that_check_and_counts() {
        let t = Cancel::after_checks(3);
        assert!(!t.is_cancelled());
        assert!(!t.clone().is_cancelled());
        assert!(t.is_cancelled());
        assert!(t.is_cancelled());
        assert_eq!(t.checks(), 4);
        assert_eq!(Cancel::new().checks(), 0);
    }

    #[test]
    fn the_current_token_follows_nested_scopes_and_stays_on_its_thread() {
        assert!(Cancel::current().flag().is_none());
        let outer = Cancel::new();
        let inner = Cancel::new();
        inner.cancel();
        {
            let _o = outer.enter();
            assert!(!Cancel::current().is_cancelled());
            {
                let _i = inner.enter();
                assert!(Cancel::current().is_cancelled());
                // Another thread has its own (none).
                std::thread::scope(|s| {
                    s.spawn(|| assert!(Cancel::current().flag().is_none()));
                });
            }
            assert!(Arc::ptr_eq(
                Cancel::current().flag().unwrap(),
                outer.flag().unwrap()
            ));
        }
        assert!(Cancel::current().flag().is_none());
    }
}
