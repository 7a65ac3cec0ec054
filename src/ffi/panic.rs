//! The panic boundary: every exported function runs its body through one of these helpers,
//! so that a Rust panic never unwinds into C (which would abort the process).

use super::result::{cadmm_result, FfiResult, CADMM_ERR_PANIC, CADMM_OK};
use std::any::Any;
use std::cell::RefCell;
use std::ffi::{c_char, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// A message kept for C: a NUL-terminated copy whose pointer stays valid until the next
/// [`ErrorText::set`]. Interior mutability, because calls through const pointers fail too.
#[derive(Default)]
pub(crate) struct ErrorText(RefCell<CString>);

impl ErrorText {
    /// Keeps `message` (a NUL inside it becomes a space).
    pub(crate) fn set(&self, message: &str) {
        *self.0.borrow_mut() = CString::new(message.replace('\0', " ")).unwrap_or_default();
    }

    /// The kept message.
    pub(crate) fn as_ptr(&self) -> *const c_char {
        self.0.borrow().as_ptr()
    }
}

thread_local! {
    /// Message of the last failed call on this thread (`cadmm_last_error`).
    static LAST_ERROR: ErrorText = ErrorText::default();
}

/// Records `message` as this thread's last error.
fn set_last_error(message: &str) {
    LAST_ERROR.with(|e| e.set(message));
}

/// This thread's last error message; the pointer stays valid until the next failed call on
/// this thread.
pub(crate) fn last_error() -> *const c_char {
    LAST_ERROR.with(ErrorText::as_ptr)
}

/// Runs the body of a function that returns a `cadmm_result`; a failure's message becomes
/// this thread's last error, and a panic becomes `CADMM_ERR_PANIC`.
pub(crate) fn guard(body: impl FnOnce() -> FfiResult) -> cadmm_result {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => CADMM_OK,
        Ok(Err(failure)) => {
            set_last_error(&failure.message);
            failure.code
        }
        Err(payload) => {
            set_last_error(&panic_message(payload.as_ref()));
            CADMM_ERR_PANIC
        }
    }
}

/// Runs the body of a function that returns a pointer or a size; a panic returns
/// `on_panic` (NULL or 0).
pub(crate) fn guard_value<T>(on_panic: T, body: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(body)).unwrap_or(on_panic)
}

/// Runs a body and hands back a panic as its message, for the handles that keep the text
/// for their own last error (`handle.rs`).
pub(crate) fn catch<T>(body: impl FnOnce() -> T) -> Result<T, String> {
    catch_unwind(AssertUnwindSafe(body)).map_err(|payload| panic_message(payload.as_ref()))
}

/// The text of a panic payload (`panic!` with a literal or a formatted message).
fn panic_message(payload: &(dyn Any + Send)) -> String {
    let text = if let Some(s) = payload.downcast_ref::<&str>() {
        s
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.as_str()
    } else {
        "unknown panic payload"
    };
    format!("internal error (panic): {text}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ffi::result::{Failure, CADMM_ERR_DIMENSION};

    // The library has no input that panics, so the boundary is exercised directly. The
    // default hook still prints the panic to stderr; that is expected in this test.

    #[test]
    fn guard_maps_outcomes() {
        assert_eq!(guard(|| Ok(())), CADMM_OK);
        assert_eq!(
            guard(|| Err(Failure::new(CADMM_ERR_DIMENSION, "x"))),
            CADMM_ERR_DIMENSION
        );
        let text = |p: *const c_char| unsafe { std::ffi::CStr::from_ptr(p) }.to_str().unwrap();
        assert_eq!(text(last_error()), "x");
        assert_eq!(guard(|| panic!("boom")), CADMM_ERR_PANIC);
        assert_eq!(text(last_error()), "internal error (panic): boom");
        // A success leaves the last failure's message in place (errno-like).
        assert_eq!(guard(|| Ok(())), CADMM_OK);
        assert_eq!(text(last_error()), "internal error (panic): boom");
    }

    #[test]
    fn guard_value_returns_fallback() {
        assert_eq!(guard_value(7usize, || 3), 3);
        assert_eq!(guard_value(0usize, || panic!("boom")), 0);
    }

    #[test]
    fn catch_keeps_the_message() {
        let n = 3;
        assert_eq!(catch(|| n + 1), Ok(4));
        let e = catch(|| -> () { panic!("bad {n}") }).unwrap_err();
        assert_eq!(e, "internal error (panic): bad 3");
        let e = catch(|| -> () { panic!("static") }).unwrap_err();
        assert_eq!(e, "internal error (panic): static");
        let e = catch(|| -> () { std::panic::panic_any(5u8) }).unwrap_err();
        assert_eq!(e, "internal error (panic): unknown panic payload");
    }
}
