//! Cancelling a long computation from another thread.
//!
//! A [`Cancel`] token is shared between the code that runs a long
//! computation (Monte Carlo campaigns, a log's filter pass and scoring)
//! and the code that may abandon it (a Python caller's Ctrl-C). The loops
//! look at the token between their steps ([`Cancel::stop_if_cancelled`]);
//! once it is set they stop by unwinding with a [`Cancelled`] payload —
//! through rayon's worker threads too, which pass a job's unwinding on to
//! the caller — so no loop needs an error type for it. The caller that set
//! the token turns the unwinding back into a value with [`Cancel::catch`].
//! Nothing is printed: the unwinding does not go through the panic hook.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A cancellation token: cheap to clone (the clones share one flag), never
/// set unless [`cancel`](Self::cancel) is called.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

/// The payload a cancelled computation unwinds with, and the error
/// [`Cancel::catch`] returns for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

impl Cancel {
    /// A token not yet set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Ask every computation watching this token (or a clone) to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`cancel`](Self::cancel) was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// Stop the computation (unwind with [`Cancelled`]) if the token is
    /// set; called by long loops between their steps.
    pub fn stop_if_cancelled(&self) {
        if self.is_cancelled() {
            std::panic::resume_unwind(Box::new(Cancelled));
        }
    }

    /// Run `work`; `Err(Cancelled)` if it stopped because a token was set.
    /// Any other panic goes on unwinding.
    pub fn catch<T>(work: impl FnOnce() -> T) -> Result<T, Cancelled> {
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)) {
            Ok(v) => Ok(v),
            Err(payload) if payload.is::<Cancelled>() => Err(Cancelled),
            Err(payload) => std::panic::resume_unwind(payload),
        }
    }
}

/// Two tokens are equal when they share one flag.
impl PartialEq for Cancel {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl Eq for Cancel {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_token_stops_a_loop_and_catch_says_so() {
        let cancel = Cancel::new();
        let watcher = cancel.clone();
        let mut steps = 0;
        let r = Cancel::catch(|| {
            for k in 0..1000 {
                if k == 10 {
                    cancel.cancel();
                }
                watcher.stop_if_cancelled();
                steps += 1;
            }
        });
        assert_eq!(r, Err(Cancelled));
        assert_eq!(steps, 10);
        assert!(Cancel::catch(|| 3).is_ok_and(|v| v == 3));
        assert_ne!(Cancel::new(), Cancel::new());
        assert_eq!(cancel, watcher);
    }

    #[test]
    fn other_panics_go_on_unwinding() {
        let r = std::panic::catch_unwind(|| Cancel::catch(|| panic!("a bug")));
        assert!(r.is_err());
    }
}
