//! The C API: opaque handles, result codes and the panic boundary. `include/cadmm.h` is
//! generated from this module by cbindgen (`tests/header.rs` checks it is up to date), so
//! the documentation here is the header's.
//!
//! Conventions every function follows:
//!
//! - Functions return a `cadmm_result`: `CADMM_OK` (0) or a `CADMM_ERR_*` code;
//!   `cadmm_result_message` describes a code; `cadmm_last_error` gives the detailed
//!   message of the last failed call on the calling thread (any function: building a
//!   problem, a setter, `cadmm_solver_new`...), and `cadmm_solver_last_error` that of the
//!   last failed call on one solver. The outcome of a solve is a separate `cadmm_status`.
//! - Every pointer argument is checked: a NULL where one is required returns
//!   `CADMM_ERR_NULL_POINTER`. Out-parameters are written only on success; a failed
//!   `_new` leaves `*out` untouched. `_free(NULL)` is a no-op.
//! - Array lengths are never passed: they follow from the dimensions (`n`, `n_contacts`,
//!   a matrix's `colptr[ncols]`). An array of length 0 may be NULL.
//! - Objects take copies of their inputs; no pointer passed in is kept after the call.
//! - A Rust panic never crosses the boundary: it becomes `CADMM_ERR_PANIC` (NULL or 0 for
//!   functions returning a pointer or a size).
//! - Threads: one problem, settings or solver object must not be used from two threads at
//!   once (this includes the solver functions taking a `const cadmm_solver *`, which record
//!   the last error). Different objects may be used concurrently, and a problem may be
//!   shared read-only by functions taking a `const cadmm_problem *` (building solvers from
//!   it in several threads, for instance).
#![allow(non_camel_case_types, non_snake_case)]
// The safety contract of every exported function is the C contract documented above and
// on each function (pointer validity and array lengths); repeating a `# Safety` section on
// each would only pad the generated header.
#![allow(clippy::missing_safety_doc)]
// Every unsafe operation inside an unsafe function names its own `unsafe` block and SAFETY.
#![deny(unsafe_op_in_unsafe_fn)]

mod arrays;
pub mod csc;
#[cfg(feature = "mpi")]
pub mod distributed;
mod handle;
mod panic;
pub mod problem;
pub mod result;
pub mod settings;
pub mod solver;
pub mod stats;

// Every public item of the C API under one path, `cadmm::ffi::*`, as C sees them in one
// header. Whole modules, so that a new function needs no list kept in step (cbindgen reads
// the modules themselves; these re-exports are for Rust callers and tests).
pub use csc::*;
#[cfg(feature = "mpi")]
pub use distributed::*;
pub use problem::*;
pub use result::*;
pub use settings::*;
pub use solver::*;
pub use stats::*;

use std::ffi::c_char;

/// The library version, e.g. "0.1.0" (the Cargo package version, equal to
/// `CADMM_VERSION_STRING` of the header the program was compiled with). A static string;
/// never free it.
#[no_mangle]
pub extern "C" fn cadmm_version() -> *const c_char {
    panic::guard_value(std::ptr::null(), || {
        concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
    })
}

/// The detailed message of the last call that failed on the calling thread, e.g.
/// "invalid CSC matrix M: row index 7 out of range in column 2"; "" when none has failed.
/// Every function returning a `cadmm_result` other than `CADMM_OK` sets it first; a
/// successful call leaves it unchanged. The string belongs to the library and stays valid
/// until the next failing call on the same thread; copy it to keep it. Never free it.
#[no_mangle]
pub extern "C" fn cadmm_last_error() -> *const c_char {
    panic::guard_value(std::ptr::null(), panic::last_error)
}

/// A static, NUL-terminated English description of a result code; "unknown result code"
/// for a value that is not a `CADMM_OK`/`CADMM_ERR_*` code. Never free it.
#[no_mangle]
pub extern "C" fn cadmm_result_message(code: cadmm_result) -> *const c_char {
    panic::guard_value(std::ptr::null(), || result::message(code).as_ptr())
}
