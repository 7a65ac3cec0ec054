//! The panic boundary: every exported function runs its body through one of these helpers,
//! so that a Rust panic never unwinds into C (which would abort the process).

use super::result::{cadmm_result, FfiResult, CADMM_ERR_PANIC, CADMM_OK};
use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Runs the body of a function that returns a `cadmm_result`; a panic becomes
/// `CADMM_ERR_PANIC`.
pub(crate) fn guard(body: impl FnOnce() -> FfiResult) -> cadmm_result {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => CADMM_OK,
        Ok(Err(failure)) => failure.code,
        Err(_) => CADMM_ERR_PANIC,
    }
}

/// Runs the body of a function that returns a pointer or a size; a panic returns
/// `on_panic` (NULL or 0).
pub(crate) fn guard_value<T>(on_panic: T, body: impl FnOnce() -> T) -> T {
    catch_unwind(AssertUnwindSafe(body)).unwrap_or(on_panic)
}

/// Runs a body and hands back a panic as its message, for callers (the solver) that keep
/// the text for `cadmm_solver_last_error`.
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
        assert_eq!(guard(|| panic!("boom")), CADMM_ERR_PANIC);
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
