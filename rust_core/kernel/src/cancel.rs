//! Stopping a long computation from another thread: the computation asks a [`Stop`] between
//! pieces of its long loops and ends with [`KernelError::Cancelled`] once it says true.

use crate::error::KernelError;

/// Asked (from any thread) between pieces of a long computation: true once it is to stop.
pub type Stop<'a> = &'a (dyn Fn() -> bool + Sync);

fn never_stop() -> bool {
    false
}

/// A [`Stop`] that never says stop.
pub const NEVER: Stop<'static> = &never_stop;

/// `Err(KernelError::Cancelled { what })` once `stop` says true, else `Ok(())`.
///
/// # Errors
/// [`KernelError::Cancelled`] when `stop` says true.
pub fn check(stop: Stop<'_>, what: &'static str) -> Result<(), KernelError> {
    if stop() {
        Err(KernelError::Cancelled { what })
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_check_fails_only_once_stop_says_so() {
        assert_eq!(check(NEVER, "test"), Ok(()));
        assert_eq!(
            check(&|| true, "wrap step"),
            Err(KernelError::Cancelled { what: "wrap step" })
        );
    }
}
