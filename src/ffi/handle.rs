//! The boundary of a solver handle, the same for the one-process and the distributed
//! solver: every call runs through [`with_mut`], [`with_ref`] or [`with_value`], which check
//! the pointer, catch a panic, keep the message of the last failed call and refuse every
//! call on a handle a panic has left in an unknown state.

use super::arrays::check_ptr;
use super::panic::{catch, guard, guard_value, ErrorText};
use super::result::{cadmm_result, Failure, FfiResult, CADMM_ERR_PANIC};
use std::cell::OnceCell;
use std::ffi::{c_char, CStr};

/// What the boundary keeps with a handle.
#[derive(Default)]
pub(crate) struct Boundary {
    /// Message of the last failed call on the handle. Calls through a const pointer fail
    /// too, hence the interior mutability (the thread rule makes a handle single-threaded).
    last_error: ErrorText,
    /// The message of the panic that made the handle unusable, once one was caught.
    poisoned: OnceCell<String>,
}

impl Boundary {
    /// Refuses a call on a handle a panic has made unusable.
    fn check_usable(&self) -> FfiResult {
        match self.poisoned.get() {
            None => Ok(()),
            Some(why) => Err(Failure::new(
                CADMM_ERR_PANIC,
                format!("the solver is unusable after an earlier {why}; free it"),
            )),
        }
    }

    /// Keeps the message of a failed call; a caught panic also poisons the handle.
    fn settle(&self, outcome: Result<FfiResult, String>) -> FfiResult {
        let outcome = outcome.unwrap_or_else(|panic| {
            let _ = self.poisoned.set(panic.clone());
            Err(Failure::new(CADMM_ERR_PANIC, panic))
        });
        if let Err(failure) = &outcome {
            self.last_error.set(&failure.message);
        }
        outcome
    }
}

/// A handle given to C whose calls run through this boundary.
pub(crate) trait Handle {
    /// The handle's boundary state.
    fn boundary(&self) -> &Boundary;
}

/// Runs a call that changes a handle: NULL check, refusal of a poisoned handle, panic
/// boundary (a panic poisons the handle), last error.
///
/// # Safety
/// `h`, if non-NULL, must be a live handle used by this thread only.
pub(crate) unsafe fn with_mut<H: Handle>(
    h: *mut H,
    body: impl FnOnce(&mut H) -> FfiResult,
) -> cadmm_result {
    guard(|| {
        check_ptr("sv", h.cast_const())?;
        let outcome = catch(|| {
            // SAFETY: a live handle by contract, used by this thread only.
            let h = unsafe { &mut *h };
            h.boundary().check_usable()?;
            body(h)
        });
        // SAFETY: as above; the borrow handed to `body` has ended.
        unsafe { (*h).boundary() }.settle(outcome)
    })
}

/// Runs a call that only reads a handle, as [`with_mut`] (it may still record the last
/// error, and a panic still poisons the handle).
///
/// # Safety
/// `h`, if non-NULL, must be a live handle not used by another thread meanwhile.
pub(crate) unsafe fn with_ref<H: Handle>(
    h: *const H,
    body: impl FnOnce(&H) -> FfiResult,
) -> cadmm_result {
    guard(|| {
        check_ptr("sv", h)?;
        // SAFETY: a live handle by contract.
        let h = unsafe { &*h };
        let outcome = catch(|| {
            h.boundary().check_usable()?;
            body(h)
        });
        h.boundary().settle(outcome)
    })
}

/// Runs a call that returns a size, not a result: `fallback` for a NULL or unusable handle
/// and after a panic (which poisons the handle like any other).
///
/// # Safety
/// As for [`with_ref`].
pub(crate) unsafe fn with_value<H: Handle, T>(
    h: *const H,
    fallback: T,
    body: impl FnOnce(&H) -> T,
) -> T {
    // SAFETY: the caller's contract, forwarded.
    let Some(h) = (unsafe { h.as_ref() }) else {
        return fallback;
    };
    let outcome = catch(|| h.boundary().check_usable().map(|()| body(h)));
    match outcome {
        Ok(Ok(value)) => value,
        Ok(Err(_)) => fallback,
        Err(panic) => {
            let _ = h.boundary().settle(Err(panic));
            fallback
        }
    }
}

/// The message of the last failed call on a handle; `if_null` for a NULL handle. The
/// string stays valid until the next failing call on the handle or its release.
///
/// # Safety
/// `h`, if non-NULL, must be a live handle.
pub(crate) unsafe fn last_error<H: Handle>(h: *const H, if_null: &'static CStr) -> *const c_char {
    guard_value(std::ptr::null(), || {
        // SAFETY: the caller's contract, forwarded.
        match unsafe { h.as_ref() } {
            None => if_null.as_ptr(),
            Some(h) => h.boundary().last_error.as_ptr(),
        }
    })
}

/// Releases a handle made by `Box::into_raw`; NULL is a no-op.
///
/// # Safety
/// `h`, if non-NULL, must come from `Box::into_raw` and be released once.
pub(crate) unsafe fn release<T>(h: *mut T) {
    guard_value((), || {
        if !h.is_null() {
            // SAFETY: the caller's contract.
            drop(unsafe { Box::from_raw(h) });
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ffi::result::{CADMM_ERR_DIMENSION, CADMM_OK};

    // No input of the library is known to panic, so panics are injected through the
    // boundary's own entry points. The default hook prints them to stderr: expected here.

    #[derive(Default)]
    struct Counter {
        calls: usize,
        boundary: Boundary,
    }

    impl Handle for Counter {
        fn boundary(&self) -> &Boundary {
            &self.boundary
        }
    }

    fn text(h: &Counter) -> String {
        let p = unsafe { last_error(h, c"null") };
        unsafe { CStr::from_ptr(p) }.to_str().unwrap().to_owned()
    }

    #[test]
    fn a_failure_is_recorded_and_the_handle_stays_usable() {
        let mut h = Counter::default();
        let failing = |_: &mut Counter| Err(Failure::new(CADMM_ERR_DIMENSION, "bad size"));
        assert_eq!(unsafe { with_mut(&mut h, failing) }, CADMM_ERR_DIMENSION);
        assert_eq!(text(&h), "bad size");
        let counting = |h: &mut Counter| {
            h.calls += 1;
            Ok(())
        };
        assert_eq!(unsafe { with_mut(&mut h, counting) }, CADMM_OK);
        assert_eq!(h.calls, 1);
        assert_eq!(
            text(&h),
            "bad size",
            "a success keeps the last failure's message"
        );
        let null = std::ptr::null_mut::<Counter>();
        assert_eq!(unsafe { with_mut(null, counting) }, 1, "NULL_POINTER");
        assert_eq!(unsafe { with_value(null, 7, |_| 3) }, 7);
        assert_eq!(
            unsafe { CStr::from_ptr(last_error(null, c"null")) },
            c"null"
        );
    }

    /// A panic in any kind of call poisons the handle: every later call is refused with
    /// `CADMM_ERR_PANIC` before its body runs, and the message names the first panic.
    #[test]
    fn a_panic_in_any_call_poisons_the_handle() {
        let panics: [&dyn Fn(&mut Counter) -> cadmm_result; 3] = [
            &|h| unsafe { with_mut(h, |_| panic!("in a change")) },
            &|h| unsafe { with_ref(h, |_| panic!("in a read")) },
            &|h| unsafe { with_value(h, 0, |_| -> cadmm_result { panic!("in a size") }) },
        ];
        for (k, panic_in) in panics.iter().enumerate() {
            let mut h = Counter::default();
            panic_in(&mut h);
            assert!(text(&h).starts_with("internal error (panic): in a"), "{k}");
            let count = |h: &mut Counter| {
                h.calls += 1;
                Ok(())
            };
            assert_eq!(unsafe { with_mut(&mut h, count) }, CADMM_ERR_PANIC, "{k}");
            assert_eq!(unsafe { with_ref(&h, |_| Ok(())) }, CADMM_ERR_PANIC, "{k}");
            assert_eq!(unsafe { with_value(&h, 5, |_| 9) }, 5, "{k}");
            assert_eq!(h.calls, 0, "{k}: a refused call runs nothing");
            let why = text(&h);
            assert!(
                why.starts_with("the solver is unusable after an earlier internal error")
                    && why.contains("in a"),
                "{k}: {why}"
            );
        }
    }
}
