//! `cadmm_settings`: solver settings, each value validated when it is set.

use super::arrays::{check_ptr, utf8};
use super::handle::release;
use super::panic::guard;
use super::result::{cadmm_result, Failure, FfiResult, CADMM_ERR_INVALID_SETTING};
use crate::admm::SUpdate;
use crate::settings::InitialRho;
use crate::settings::{LinearSolver, Settings, VariantChoice};
use std::ffi::c_char;

/// Solver settings. Opaque; created by `cadmm_settings_new` with the defaults (tolerance
/// 1e-8, 100000 iterations, no time limit, variant "auto", the variant's initial rho rule
/// and Anderson memory, internal s-update, no trace), released by `cadmm_settings_free`.
/// A solver keeps its own copy, so settings may be changed or freed once the solver exists.
pub struct cadmm_settings {
    pub(crate) inner: Settings,
}

impl cadmm_settings {
    /// The settings this handle holds (Rust side only, e.g. for tests).
    pub fn settings(&self) -> &Settings {
        &self.inner
    }
}

/// Borrows a settings handle.
///
/// # Safety
/// `s`, if non-NULL, must come from this library and not be freed.
pub(crate) unsafe fn settings_ref<'a>(
    what: &str,
    s: *const cadmm_settings,
) -> FfiResult<&'a Settings> {
    check_ptr(what, s)?;
    // SAFETY: a live handle by contract.
    Ok(unsafe { &(*s).inner })
}

/// Applies `change` to a copy of the settings and keeps it only if it validates, so a
/// rejected value leaves the settings unchanged.
///
/// # Safety
/// `s`, if non-NULL, must be a live handle used by this thread only.
unsafe fn change(
    s: *mut cadmm_settings,
    change: impl FnOnce(&mut Settings) -> FfiResult,
) -> cadmm_result {
    guard(|| {
        check_ptr("s", s.cast_const())?;
        // SAFETY: a live handle by contract, used by this thread only.
        let settings = unsafe { &mut (*s).inner };
        let mut copy = settings.clone();
        change(&mut copy)?;
        copy.validate()?;
        *settings = copy;
        Ok(())
    })
}

/// Creates settings with the defaults. On success `*out` receives them (release with
/// `cadmm_settings_free`); on failure `*out` is left untouched. Errors:
/// `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_new(out: *mut *mut cadmm_settings) -> cadmm_result {
    guard(|| {
        check_ptr("out", out.cast_const())?;
        let handle = Box::into_raw(Box::new(cadmm_settings {
            inner: Settings::default(),
        }));
        // SAFETY: checked non-NULL and aligned.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// Chooses the variant: "auto" (the default: ADMM finished by the semismooth Newton
/// phase), "newton" (semismooth Newton alone from the initial guess), or one of the ADMM
/// variants "cp-N", "cp-R", "cp-RR", "vp-N-He", "vp-R-He", "vp-RR-He", "vp-N-Wohlberg",
/// "vp-R-Wohlberg", "vp-RR-Wohlberg", "vp-N-Spectral", "vp-R-Spectral", "vp-RR-Spectral"
/// (docs/algorithms.md §6.5, §9). Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_SETTING` (unknown name; the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_variant(
    s: *mut cadmm_settings,
    name: *const c_char,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            let name = utf8("name", name, CADMM_ERR_INVALID_SETTING)?;
            set.variant = VariantChoice::from_name(name)?;
            Ok(())
        })
    }
}

/// Chooses how the first penalty rho is picked: "normal" (rho = 1), "acary", "ghadimi",
/// "dicairano", or "given" with `rho` (positive, finite; ignored by the other rules).
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_SETTING` (the settings are
/// unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_initial_rho(
    s: *mut cadmm_settings,
    rule: *const c_char,
    rho: f64,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            let rule = utf8("rule", rule, CADMM_ERR_INVALID_SETTING)?;
            set.initial_rho = Some(InitialRho::from_name(rule, rho)?);
            Ok(())
        })
    }
}

/// Sets the tolerance on the error measure (positive, finite; default 1e-8). Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_SETTING` (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_tolerance(
    s: *mut cadmm_settings,
    tol: f64,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.tolerance = tol;
            Ok(())
        })
    }
}

/// Sets the iteration limit (at least 1; default 100000). Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_SETTING` (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_max_iterations(
    s: *mut cadmm_settings,
    n: u32,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.max_iterations = n as usize;
            Ok(())
        })
    }
}

/// Sets the wall-clock limit of one solve in seconds (positive; `INFINITY`, the default,
/// for none). It bounds `cadmm_solver_solve` only, checked between steps: after every
/// ADMM iteration, conjugate-gradient iteration and Newton step, and before each island.
/// A step under way is finished, so a solve can overrun by one step: with the factorized
/// backend, a refactorization when rho changes or a Newton factorization (tens of
/// milliseconds on a large problem). `cadmm_solver_new` (analysis, first factorization)
/// and the updates are outside the limit. A solver built with settings that have a limit
/// and the variant `auto` (an engine's budget per step) starts each solve of a global
/// problem whose M is block diagonal with Gauss-Seidel sweeps, at least 4 of them, and
/// builds its islands (analysis, factorization) only if the sweeps hand over to ADMM and
/// Newton; at most 16 contacts, with every joint row an equality, are solved at once by
/// Newton after the first sweeps when the time left allows (docs/algorithms.md §17).
/// `cadmm_stats.gauss_seidel_sweeps` counts the sweeps. Otherwise a
/// limit that is not reached does not change the solve: it ends with the same answer,
/// bitwise, as without the limit. Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_SETTING` (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_time_limit(
    s: *mut cadmm_settings,
    seconds: f64,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.time_limit = seconds;
            Ok(())
        })
    }
}

/// Sets the Anderson acceleration memory (0 switches it off; at most 64). Without this
/// call the variant decides ("auto" uses 5, named variants 0). Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_SETTING` (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_anderson(
    s: *mut cadmm_settings,
    memory: u32,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.anderson = Some(memory as usize);
            Ok(())
        })
    }
}

/// Tries an Anderson step every `every` iterations (default 1: every iteration; the
/// history is recorded at every iteration either way). Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_SETTING` for 0 (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_anderson_interval(
    s: *mut cadmm_settings,
    every: u32,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.anderson_interval = every as usize;
            Ok(())
        })
    }
}

/// Chooses when the De Saxce parameter s is updated: "internal" (every iteration, the
/// default) or "external" (after each inner convex solve). Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_SETTING` (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_s_update(
    s: *mut cadmm_settings,
    mode: *const c_char,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.s_update = match utf8("mode", mode, CADMM_ERR_INVALID_SETTING)? {
                "internal" => SUpdate::Internal,
                "external" => SUpdate::External,
                other => {
                    return Err(Failure::new(
                        CADMM_ERR_INVALID_SETTING,
                        format!(
                            "invalid setting s_update: unknown mode '{other}' \
                             (expected internal or external)"
                        ),
                    ))
                }
            };
            Ok(())
        })
    }
}

/// Chooses how the v-update systems `M + rho H H^T` of the global form are solved:
/// "auto" (the default: per island, a cost model weighs the factor's predicted fill
/// against the products of conjugate gradients), "direct" (factorized) or "iterative"
/// (matrix-free preconditioned conjugate gradients, without the Newton phase; joint rows,
/// equalities included, are then rows of the ADMM splitting; a non-symmetric M stays
/// direct). The statistics' `linear_iterations`
/// counts the conjugate-gradient iterations. Errors: `CADMM_ERR_NULL_POINTER` (`s` or
/// `name`), `CADMM_ERR_INVALID_SETTING` (the settings are unchanged).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_linear_solver(
    s: *mut cadmm_settings,
    name: *const c_char,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            let name = utf8("name", name, CADMM_ERR_INVALID_SETTING)?;
            set.linear_solver = LinearSolver::from_name(name)?;
            Ok(())
        })
    }
}

/// Switches the per-iteration trace on or off (default off); read it with
/// `cadmm_solver_trace_len` and `cadmm_solver_get_trace`. Errors: `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_trace(
    s: *mut cadmm_settings,
    on: bool,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.trace = on;
            Ok(())
        })
    }
}

/// Switches the semismooth Newton finishing phase on or off (docs/algorithms.md §9), and
/// with it Newton on few contacts under a time limit (§17). By default it is on for "auto"
/// and off for the named ADMM variants; with "newton" the setting is ignored. Errors:
/// `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_newton(
    s: *mut cadmm_settings,
    on: bool,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.newton_polish = Some(on);
            Ok(())
        })
    }
}

/// Switches contact islands on or off (default on): with islands, the problem is split into
/// the connected parts of its coupling graph (bodies, contacts, joints; the blocks of W in
/// the local form), each solved on its own with its own penalty, stopping test and
/// factorization, and velocities no contact reaches get `v = M^-1 f` (docs/algorithms.md
/// §12). Errors: `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_islands(
    s: *mut cadmm_settings,
    on: bool,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.islands = on;
            Ok(())
        })
    }
}

/// Threads the solver may use (default 1: everything runs on the calling thread and the
/// library starts no thread). With `n > 1`:
/// - a problem split into several islands: each `cadmm_solver_solve` starts up to `n`
///   threads that solve islands side by side, and joins them before it returns;
/// - a problem solved whole (one island, or islands off) with the matrix-free v-update and
///   at least 200 000 entries in M and H: `cadmm_solver_new` (or
///   `cadmm_solver_update_settings`) starts a pool of `n` threads for the products of the
///   conjugate gradients, kept (idle between solves) until the solver is freed or the
///   count changes;
/// - otherwise no thread is started.
///
/// An engine that owns its threads keeps 1 and runs separate solvers on its own threads
/// instead. The solution does not depend on `n`. Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_SETTING` (0, or above 256).
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_set_threads(
    s: *mut cadmm_settings,
    n: usize,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    unsafe {
        change(s, |set| {
            set.threads = n;
            Ok(())
        })
    }
}

/// Releases settings. NULL is a no-op. The handle must not be used afterwards.
#[no_mangle]
pub unsafe extern "C" fn cadmm_settings_free(s: *mut cadmm_settings) {
    // SAFETY: made with Box::into_raw by `cadmm_settings_new`, released once by contract.
    unsafe { release(s) }
}
