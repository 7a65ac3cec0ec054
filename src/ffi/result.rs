//! Result codes (why a call failed) and solve status codes (how a solve ended).

use crate::types::{Error, ErrorKind, Status};
use std::ffi::CStr;

/// Outcome of a call: `CADMM_OK` (0) or one of the `CADMM_ERR_*` codes. A plain integer
/// rather than an enum, so that any value read back from C is well defined.
pub type cadmm_result = i32;

/// The call succeeded.
pub const CADMM_OK: cadmm_result = 0;
/// A required pointer argument was NULL.
pub const CADMM_ERR_NULL_POINTER: cadmm_result = 1;
/// Two sizes that must agree do not (a matrix shape, a dimension, a vector length).
pub const CADMM_ERR_DIMENSION: cadmm_result = 2;
/// A `cadmm_csc` matrix is malformed (column pointers, row indices, duplicates).
pub const CADMM_ERR_INVALID_CSC: cadmm_result = 3;
/// A value is NaN, infinite or out of range (negative friction coefficient, bad index...).
pub const CADMM_ERR_INVALID_VALUE: cadmm_result = 4;
/// A matrix that must be symmetric positive definite (M, M + rho H H^T, W + rho I) is not.
pub const CADMM_ERR_NOT_POSITIVE_DEFINITE: cadmm_result = 5;
/// The factorization of a non-symmetric matrix failed: it is singular.
pub const CADMM_ERR_SINGULAR: cadmm_result = 6;
/// A setting is unknown or out of range.
pub const CADMM_ERR_INVALID_SETTING: cadmm_result = 7;
/// Reading or writing a file failed.
pub const CADMM_ERR_IO: cadmm_result = 8;
/// The operation does not apply (FCLib I/O in a build without it, joints on a local
/// problem, updating a solver with a problem of the other form).
pub const CADMM_ERR_UNSUPPORTED: cadmm_result = 9;
/// An internal error (a Rust panic) was caught at the API boundary. A solver (one-process
/// or distributed) that reported it is unusable afterwards: every later call on it returns
/// this code again. Free it.
pub const CADMM_ERR_PANIC: cadmm_result = 10;
/// A new problem or new values do not have the sparsity pattern the solver was built for
/// (same sizes, other non-zero positions): build a new solver instead.
pub const CADMM_ERR_PATTERN_CHANGED: cadmm_result = 11;
/// Memory for a system or its factorization could not be allocated.
pub const CADMM_ERR_OUT_OF_MEMORY: cadmm_result = 12;

/// How a solve that ran ended, written by `cadmm_solver_solve`. A plain integer like
/// `cadmm_result`.
pub type cadmm_status = i32;

/// The error measure reached the tolerance.
pub const CADMM_STATUS_SOLVED: cadmm_status = 0;
/// The iteration limit was reached first; the solution is the best iterate the last ADMM
/// run measured.
pub const CADMM_STATUS_MAX_ITERATIONS: cadmm_status = 1;
/// The time limit was reached first; the solution is the best iterate measured, as for
/// `CADMM_STATUS_MAX_ITERATIONS`.
pub const CADMM_STATUS_TIME_LIMIT: cadmm_status = 2;
/// An iterate became non-finite; the solution is the best iterate the run measured (the
/// last finite one when none was measured).
pub const CADMM_STATUS_NUMERICAL_ERROR: cadmm_status = 3;
/// The method stopped making progress before the tolerance (only the "newton" variant,
/// which has no ADMM to fall back on); the solution is its best iterate.
pub const CADMM_STATUS_STALLED: cadmm_status = 4;
/// The problem has no solution: some contact's normal relative velocity cannot change (its
/// normal column of H, or normal row of W, is zero) and it approaches (`w_N < 0`, `q_N < 0`),
/// or the impulses grew along a direction that pushes no body against approaching
/// velocities (docs/algorithms.md section 13). The solution returned is not one.
pub const CADMM_STATUS_INFEASIBLE: cadmm_status = 5;
/// No solve has run yet: the status of a new solver's statistics.
pub const CADMM_STATUS_UNSOLVED: cadmm_status = 6;

/// The C status code of a [`Status`].
pub(crate) fn status_code(s: Status) -> cadmm_status {
    match s {
        Status::Solved => CADMM_STATUS_SOLVED,
        Status::MaxIterations => CADMM_STATUS_MAX_ITERATIONS,
        Status::TimeLimit => CADMM_STATUS_TIME_LIMIT,
        Status::NumericalError => CADMM_STATUS_NUMERICAL_ERROR,
        Status::Stalled => CADMM_STATUS_STALLED,
        Status::Infeasible => CADMM_STATUS_INFEASIBLE,
        Status::Unsolved => CADMM_STATUS_UNSOLVED,
    }
}

/// The C result code of an [`Error`].
pub(crate) fn error_code(e: &Error) -> cadmm_result {
    kind_code(e.kind())
}

/// The C result code of an [`ErrorKind`]. Exhaustive on purpose: a new kind must be mapped.
pub(crate) fn kind_code(kind: ErrorKind) -> cadmm_result {
    match kind {
        ErrorKind::Dimension => CADMM_ERR_DIMENSION,
        ErrorKind::InvalidCsc => CADMM_ERR_INVALID_CSC,
        ErrorKind::InvalidValue => CADMM_ERR_INVALID_VALUE,
        ErrorKind::NotPositiveDefinite => CADMM_ERR_NOT_POSITIVE_DEFINITE,
        ErrorKind::Singular => CADMM_ERR_SINGULAR,
        ErrorKind::InvalidSetting => CADMM_ERR_INVALID_SETTING,
        ErrorKind::Io => CADMM_ERR_IO,
        ErrorKind::Unsupported => CADMM_ERR_UNSUPPORTED,
        ErrorKind::PatternChanged => CADMM_ERR_PATTERN_CHANGED,
        ErrorKind::OutOfMemory => CADMM_ERR_OUT_OF_MEMORY,
    }
}

/// A failed call inside the FFI layer: the code returned to C and a message for
/// `cadmm_solver_last_error`.
#[derive(Debug, Clone)]
pub(crate) struct Failure {
    pub(crate) code: cadmm_result,
    pub(crate) message: String,
}

impl Failure {
    pub(crate) fn new(code: cadmm_result, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
        }
    }

    /// A required pointer argument `what` was NULL.
    pub(crate) fn null(what: &str) -> Self {
        Self::new(CADMM_ERR_NULL_POINTER, format!("{what} is NULL"))
    }
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        Self::new(error_code(&e), e.to_string())
    }
}

/// Result of the FFI layer's internal functions.
pub(crate) type FfiResult<T = ()> = Result<T, Failure>;

/// The static text of a result code.
pub(crate) fn message(code: cadmm_result) -> &'static CStr {
    match code {
        CADMM_OK => c"ok",
        CADMM_ERR_NULL_POINTER => c"a required pointer argument is NULL",
        CADMM_ERR_DIMENSION => c"dimension mismatch",
        CADMM_ERR_INVALID_CSC => c"invalid compressed sparse column matrix",
        CADMM_ERR_INVALID_VALUE => c"invalid value (NaN, infinite or out of range)",
        CADMM_ERR_NOT_POSITIVE_DEFINITE => c"matrix is not positive definite",
        CADMM_ERR_SINGULAR => c"matrix is singular",
        CADMM_ERR_INVALID_SETTING => c"invalid setting",
        CADMM_ERR_IO => c"i/o error",
        CADMM_ERR_UNSUPPORTED => c"unsupported operation",
        CADMM_ERR_PANIC => c"internal error (panic caught at the API boundary)",
        CADMM_ERR_PATTERN_CHANGED => c"sparsity pattern differs from the solver's",
        CADMM_ERR_OUT_OF_MEMORY => c"out of memory",
        _ => c"unknown result code",
    }
}
