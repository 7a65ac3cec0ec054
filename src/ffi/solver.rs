//! `cadmm_solver`: a solver with its factorizations, last iterate and last error message.

use super::arrays::{check_output, check_ptr, contact_len, input, write_output};
use super::panic::{catch, guard, guard_value};
use super::problem::{cadmm_problem, problem_ref};
use super::result::{
    cadmm_result, cadmm_status, status_code, Failure, FfiResult, CADMM_ERR_INVALID_VALUE,
    CADMM_ERR_PANIC,
};
use super::settings::{cadmm_settings, settings_ref};
use super::stats::{cadmm_stats, cadmm_trace_point, write_stats, STATS_MIN_SIZE};
use crate::problem::{NewValues, Problem};
use crate::solver::Solver;
use crate::types::{Phase, TracePoint};
use std::cell::RefCell;
use std::ffi::{c_char, CString};

/// Why a solver refuses every call but `cadmm_solver_last_error` and `cadmm_solver_free`.
#[derive(Debug)]
enum Broken {
    /// A panic was caught inside a call that was changing the solver: its state is unknown.
    /// Only `cadmm_solver_last_error` and `cadmm_solver_free` still work.
    Panicked,
}

/// A solver for one problem and its successors with the same sparsity pattern. Opaque;
/// created by `cadmm_solver_new`, released by `cadmm_solver_free`.
pub struct cadmm_solver {
    solver: Solver,
    n_velocities: usize,
    n_contacts: usize,
    is_global: bool,
    /// Lengths of the value arrays `cadmm_solver_update_values` reads: nnz of M (or W), H
    /// and G, and the number of joint rows.
    value_lens: [usize; 4],
    broken: Option<Broken>,
    /// Message of the last failed call; interior mutability because const calls fail too
    /// (the thread rule makes a solver single-threaded, const calls included).
    last_error: RefCell<CString>,
}

impl cadmm_solver {
    fn record(&self, message: &str) {
        let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
        *self.last_error.borrow_mut() = text;
    }

    fn check_usable(&self) -> FfiResult {
        match &self.broken {
            None => Ok(()),
            Some(Broken::Panicked) => Err(Failure::new(
                CADMM_ERR_PANIC,
                "the solver is unusable after an internal error (panic); free it",
            )),
        }
    }
}

/// Runs a call that changes a solver: NULL check, panic boundary, error message.
///
/// # Safety
/// `sv`, if non-NULL, must be a live handle used by this thread only.
unsafe fn with_solver_mut(
    sv: *mut cadmm_solver,
    body: impl FnOnce(&mut cadmm_solver) -> FfiResult,
) -> cadmm_result {
    guard(|| {
        check_ptr("sv", sv.cast_const())?;
        // SAFETY: a live handle by contract, used by this thread only.
        let outcome = catch(|| body(unsafe { &mut *sv }));
        // SAFETY: as above; the borrow handed to `body` has ended.
        let sv = unsafe { &mut *sv };
        match outcome {
            Ok(Ok(())) => Ok(()),
            Ok(Err(failure)) => {
                sv.record(&failure.message);
                Err(failure)
            }
            Err(message) => {
                sv.record(&message);
                sv.broken = Some(Broken::Panicked);
                Err(Failure::new(CADMM_ERR_PANIC, message))
            }
        }
    })
}

/// Runs a call that only reads a solver (it may still record the last error).
///
/// # Safety
/// `sv`, if non-NULL, must be a live handle not used by another thread meanwhile.
unsafe fn with_solver(
    sv: *const cadmm_solver,
    body: impl FnOnce(&cadmm_solver) -> FfiResult,
) -> cadmm_result {
    guard(|| {
        check_ptr("sv", sv)?;
        // SAFETY: a live handle by contract.
        let sv = unsafe { &*sv };
        let outcome = catch(|| sv.check_usable().and_then(|()| body(sv)));
        match outcome {
            Ok(Ok(())) => Ok(()),
            Ok(Err(failure)) => {
                sv.record(&failure.message);
                Err(failure)
            }
            Err(message) => {
                sv.record(&message);
                Err(Failure::new(CADMM_ERR_PANIC, message))
            }
        }
    })
}

/// Creates a solver: validates the settings, picks the first rho and factorizes (symbolic
/// analysis and first numeric factorization). The problem and the settings are copied;
/// both may be freed or changed afterwards.
///
/// On success `*out` receives the solver (release with `cadmm_solver_free`); on failure
/// `*out` is left untouched. Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_SETTING`,
/// `CADMM_ERR_NOT_POSITIVE_DEFINITE` (M, or W + rho I for a symmetric W),
/// `CADMM_ERR_SINGULAR` (W + rho I for a non-symmetric W).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_new(
    p: *const cadmm_problem,
    s: *const cadmm_settings,
    out: *mut *mut cadmm_solver,
) -> cadmm_result {
    guard(|| {
        // SAFETY: live handles by contract.
        let problem = unsafe { problem_ref("p", p)? };
        let settings = unsafe { settings_ref("s", s)? };
        check_ptr("out", out.cast_const())?;
        let solver = Solver::new(problem.clone(), settings.clone())?;
        let handle = Box::into_raw(Box::new(cadmm_solver {
            solver,
            n_velocities: problem.n_velocities(),
            n_contacts: problem.n_contacts(),
            is_global: matches!(problem, Problem::Global(_)),
            value_lens: value_lens(problem),
            broken: None,
            last_error: RefCell::new(CString::default()),
        }));
        // SAFETY: checked non-NULL and aligned.
        unsafe { out.write(handle) };
        Ok(())
    })
}

fn value_lens(p: &Problem) -> [usize; 4] {
    match p {
        Problem::Global(g) => {
            let (g_nnz, p) = g
                .joints
                .as_ref()
                .map_or((0, 0), |j| (j.g.nnz(), j.g.ncols()));
            [g.m.nnz(), g.h.nnz(), g_nnz, p]
        }
        Problem::Local(l) => [l.w.nnz(), 0, 0, 0],
    }
}

/// Runs an update of the solver's problem. A refused update changes nothing: the solver
/// goes on solving the problem it held (`Solver::update_values`).
fn update_with(
    sv: &mut cadmm_solver,
    update: impl FnOnce(&mut Solver) -> Result<(), crate::Error>,
) -> FfiResult {
    sv.check_usable()?;
    update(&mut sv.solver).map_err(Failure::from)
}

/// An optional input array: NULL means "keep the current values".
///
/// # Safety
/// A non-NULL `ptr` must point to `len` readable elements.
unsafe fn optional<'a>(what: &str, ptr: *const f64, len: usize) -> FfiResult<Option<&'a [f64]>> {
    if ptr.is_null() {
        return Ok(None);
    }
    // SAFETY: forwarded contract.
    unsafe { input(what, ptr, len) }.map(Some)
}

/// The per-step path of a global problem: new values for the next time step of the same
/// scene (same sizes and sparsity patterns), without building a problem. Each array may be
/// NULL to keep the current values; matrix values are given in the order of the arrays
/// passed to `cadmm_problem_new_global` / `cadmm_problem_set_joints` (`nnz` entries each),
/// `f` has `n` entries, `w` `3 n_contacts`, `b` one per joint row, `mu` `n_contacts`.
/// The values are scattered into the kept system matrix and refactorized once, without
/// sorting or allocating; M is refactorized on its own to check it is positive definite. The next solve starts cold unless
/// `cadmm_solver_warm_start` is called after this.
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (a non-finite value, a
/// negative friction coefficient), `CADMM_ERR_UNSUPPORTED` (a local solver, or G/b for a
/// problem without joints), `CADMM_ERR_NOT_POSITIVE_DEFINITE`, `CADMM_ERR_SINGULAR`. A
/// refused update changes nothing, whatever it was refused for (an M that does not
/// factorize included): the solver goes on solving the values it held, its warm start,
/// solution and statistics unchanged.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn cadmm_solver_update_values(
    sv: *mut cadmm_solver,
    M_values: *const f64,
    H_values: *const f64,
    G_values: *const f64,
    f: *const f64,
    w: *const f64,
    b: *const f64,
    mu: *const f64,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        if !sv.is_global {
            // Refused like any failed update, before anything changes.
            return update_with(sv, |_| {
                Err(crate::Error::Unsupported(
                    "cadmm_solver_update_values: the solver holds a local problem; use \
                     cadmm_solver_update_local_values"
                        .into(),
                ))
            });
        }
        let [m_nnz, h_nnz, g_nnz, n_joints] = sv.value_lens;
        let m = contact_len(sv.n_contacts)?;
        // SAFETY: lengths from the problem the solver was built for; the caller's contract.
        let values = unsafe {
            NewValues {
                m: optional("M_values", M_values, m_nnz)?,
                h: optional("H_values", H_values, h_nnz)?,
                g: optional("G_values", G_values, g_nnz)?,
                f: optional("f", f, sv.n_velocities)?,
                w: optional("w", w, m)?,
                b: optional("b", b, n_joints)?,
                mu: optional("mu", mu, sv.n_contacts)?,
                ..Default::default()
            }
        };
        update_with(sv, |s| s.update_values(&values))
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver_mut(sv, body) }
}

/// The per-step path of a local problem: new values of `W` (its `nnz` entries, in the order
/// of the arrays passed to `cadmm_problem_new_local`), `q` (`3 n_contacts`) and `mu`
/// (`n_contacts`), each NULL to keep the current values; same pattern, same behaviour and
/// errors as `cadmm_solver_update_values` (`CADMM_ERR_UNSUPPORTED` for a global solver).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_update_local_values(
    sv: *mut cadmm_solver,
    W_values: *const f64,
    q: *const f64,
    mu: *const f64,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        if sv.is_global {
            // Refused like any failed update, before anything changes.
            return update_with(sv, |_| {
                Err(crate::Error::Unsupported(
                    "cadmm_solver_update_local_values: the solver holds a global problem; use \
                     cadmm_solver_update_values"
                        .into(),
                ))
            });
        }
        let m = contact_len(sv.n_contacts)?;
        // SAFETY: lengths from the problem the solver was built for; the caller's contract.
        let values = unsafe {
            NewValues {
                delassus: optional("W_values", W_values, sv.value_lens[0])?,
                q: optional("q", q, m)?,
                mu: optional("mu", mu, sv.n_contacts)?,
                ..Default::default()
            }
        };
        update_with(sv, |s| s.update_values(&values))
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver_mut(sv, body) }
}

/// Replaces the solver's problem by `p`, the next time step of the same scene: same form,
/// sizes and sparsity patterns, new values (numeric refactorization only). `p` is copied.
/// The next solve starts cold unless `cadmm_solver_warm_start` is called after this.
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_DIMENSION` (other sizes),
/// `CADMM_ERR_PATTERN_CHANGED` (other pattern), `CADMM_ERR_INVALID_VALUE` (a value out of
/// range), `CADMM_ERR_UNSUPPORTED` (a problem of the
/// other form, global or local), `CADMM_ERR_NOT_POSITIVE_DEFINITE`, `CADMM_ERR_SINGULAR`. A refused
/// update changes nothing, as for `cadmm_solver_update_values`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_update(
    sv: *mut cadmm_solver,
    p: *const cadmm_problem,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        // SAFETY: a live handle by contract.
        let problem = unsafe { problem_ref("p", p)? };
        update_with(sv, |s| s.update(problem.clone()))
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver_mut(sv, body) }
}

/// Changes the settings of the next solves: the tolerance, the iteration and time limits,
/// the trace and the threads of `s` are taken (`s` is copied). Every other setting of `s`
/// must equal the solver's: changing the variant, the initial rho, the s update, Anderson,
/// the Newton phase or islands needs a new solver.
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_SETTING` (an invalid value, or a
/// setting that needs a new solver; the message names it). On failure nothing changes.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_update_settings(
    sv: *mut cadmm_solver,
    s: *const cadmm_settings,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        sv.check_usable()?;
        // SAFETY: a live handle by contract.
        let settings = unsafe { settings_ref("s", s)? };
        sv.solver.update_settings(settings.clone())?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver_mut(sv, body) }
}

/// Starts the next solve from impulses `r` (`3 n_contacts` entries) and, for a global
/// problem, velocities `v` (`n` entries, may be NULL: then only `r` is used; ignored for a
/// local problem). Typically the previous time step's solution.
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (a non-finite entry).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_warm_start(
    sv: *mut cadmm_solver,
    r: *const f64,
    v: *const f64,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        sv.check_usable()?;
        let l = contact_len(sv.n_contacts)?;
        // SAFETY (reads): lengths from the problem, as documented above.
        let r = unsafe { input("r", r, l)? };
        let v = if sv.is_global && !v.is_null() {
            Some(unsafe { input("v", v, sv.n_velocities)? })
        } else {
            None
        };
        sv.solver.warm_start(r, v)?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver_mut(sv, body) }
}

/// Runs ADMM until the error measure reaches the tolerance or a limit is hit, and writes
/// how it ended to `*status` (`CADMM_STATUS_*`). Hitting a limit is a status, not a
/// failure: the call returns `CADMM_OK` and the solution is the best iterate ADMM measured
/// (after a non-finite iterate too; the last finite one when none was measured).
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_NOT_POSITIVE_DEFINITE`/`CADMM_ERR_SINGULAR`
/// (a refactorization for a new rho failed).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_solve(
    sv: *mut cadmm_solver,
    status: *mut cadmm_status,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        sv.check_usable()?;
        check_ptr("status", status.cast_const())?;
        let s = sv.solver.solve()?;
        // SAFETY: checked non-NULL and aligned.
        unsafe { status.write(status_code(s)) };
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver_mut(sv, body) }
}

/// Copies the current solution (the last solve's, or zeros before any solve): impulses
/// `r` and local velocities `u` (`3 n_contacts` entries each) and, for a global problem,
/// velocities `v` (`n` entries; ignored for a local problem). Any of the three may be NULL
/// to skip it. Errors: `CADMM_ERR_NULL_POINTER` (`sv`).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_solution(
    sv: *const cadmm_solver,
    r: *mut f64,
    u: *mut f64,
    v: *mut f64,
) -> cadmm_result {
    let body = |sv: &cadmm_solver| -> FfiResult {
        let l = contact_len(sv.n_contacts)?;
        let nv = if sv.is_global { sv.n_velocities } else { 0 };
        let want_v = sv.is_global && !v.is_null();
        if !r.is_null() {
            check_output("r", r, l)?;
        }
        if !u.is_null() {
            check_output("u", u, l)?;
        }
        if want_v {
            check_output("v", v, nv)?;
        }
        let solution = sv.solver.solution();
        // SAFETY: checked, lengths from the problem as documented above.
        unsafe {
            if !r.is_null() {
                write_output(r, &solution.r);
            }
            if !u.is_null() {
                write_output(u, &solution.u);
            }
            if want_v {
                write_output(v, &solution.v);
            }
        }
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver(sv, body) }
}

/// Copies the joint multipliers `lambda` of the current solution (`p` entries, the number of
/// columns of the `G` given to `cadmm_problem_set_joints`), so that `M v = H r + G lambda + f`.
/// `*n_joints` (may be NULL) receives `p`; `lambda` may be NULL to ask for `p` only. A
/// problem without joints has `p = 0`. Errors: `CADMM_ERR_NULL_POINTER` (`sv`).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_joint_multipliers(
    sv: *const cadmm_solver,
    lambda: *mut f64,
    n_joints: *mut usize,
) -> cadmm_result {
    let body = |sv: &cadmm_solver| -> FfiResult {
        let solution = sv.solver.solution();
        let np = solution.lambda.len();
        if !lambda.is_null() {
            check_output("lambda", lambda, np)?;
        }
        // SAFETY: checked, length from the problem as documented above.
        unsafe {
            if !lambda.is_null() {
                write_output(lambda, &solution.lambda);
            }
            if !n_joints.is_null() {
                n_joints.write(np);
            }
        }
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver(sv, body) }
}

/// Writes `stats` into the caller's `*out`, as much of it as `out->struct_size` covers.
///
/// # Safety
/// `out`, if non-NULL, must point to a writable `cadmm_stats` of `struct_size` bytes.
pub(crate) unsafe fn put_stats(out: *mut cadmm_stats, stats: &crate::types::Stats) -> FfiResult {
    check_ptr("out", out.cast_const())?;
    // SAFETY: non-NULL and aligned; `struct_size` is the first field, present in every
    // version of the struct.
    let size = unsafe { out.cast::<usize>().read() };
    if size < STATS_MIN_SIZE {
        return Err(Failure::new(
            CADMM_ERR_INVALID_VALUE,
            format!(
                "out->struct_size = {size} is smaller than the {STATS_MIN_SIZE} bytes \
                 required (set it to sizeof(cadmm_stats))"
            ),
        ));
    }
    // SAFETY: the caller's struct holds `size` bytes by contract.
    unsafe { write_stats(out, size, &cadmm_stats::from(stats)) };
    Ok(())
}

/// Fills `*out` with the statistics of the last solve; set `out->struct_size =
/// sizeof(cadmm_stats)` first (see `cadmm_stats`). Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_VALUE` (`struct_size` too small; nothing is written).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_stats(
    sv: *const cadmm_solver,
    out: *mut cadmm_stats,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    let body = |sv: &cadmm_solver| unsafe { put_stats(out, sv.solver.stats()) };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver(sv, body) }
}

/// Fills `*out` with the statistics of island `index` in the last solve (`0 <= index <
/// islands` of `cadmm_solver_get_stats`; islands are ordered by their first contact; an
/// island's `error` is by its own measure). Set `out->struct_size` first, as for
/// `cadmm_solver_get_stats`. Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE`
/// (`struct_size` too small, or no such island; nothing is written).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_island_stats(
    sv: *const cadmm_solver,
    index: usize,
    out: *mut cadmm_stats,
) -> cadmm_result {
    let body = |sv: &cadmm_solver| -> FfiResult {
        let islands = sv.solver.island_stats();
        let Some(island) = islands.get(index) else {
            check_ptr("out", out.cast_const())?;
            return Err(Failure::new(
                CADMM_ERR_INVALID_VALUE,
                format!("island {index} does not exist ({} islands)", islands.len()),
            ));
        };
        // SAFETY: the caller's contract, forwarded.
        unsafe { put_stats(out, island) }
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver(sv, body) }
}

/// Number of points in the trace of the last solve (0 unless the trace was switched on
/// with `cadmm_settings_set_trace`; 0 for a NULL or unusable solver).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_trace_len(sv: *const cadmm_solver) -> usize {
    guard_value(0, || {
        if sv.is_null() {
            return 0;
        }
        // SAFETY: a live handle by contract.
        let sv = unsafe { &*sv };
        if sv.check_usable().is_err() {
            return 0;
        }
        sv.solver.trace().len()
    })
}

/// Copies point `i` (0-based, below `cadmm_solver_trace_len`) of the last solve's trace to
/// `*out`. Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (`i` out of range).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_trace(
    sv: *const cadmm_solver,
    i: usize,
    out: *mut cadmm_trace_point,
) -> cadmm_result {
    let body = |sv: &cadmm_solver| -> FfiResult {
        check_ptr("out", out.cast_const())?;
        let point = trace_point(sv, i)?;
        // SAFETY: checked non-NULL and aligned.
        unsafe { out.write(cadmm_trace_point::from(point)) };
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver(sv, body) }
}

/// Trace point `i` of the last solve, or a failure naming the index and the length.
fn trace_point(sv: &cadmm_solver, i: usize) -> FfiResult<&TracePoint> {
    let trace = sv.solver.trace();
    trace.get(i).ok_or_else(|| {
        Failure::new(
            CADMM_ERR_INVALID_VALUE,
            format!("trace index {i} is out of range (length {})", trace.len()),
        )
    })
}

/// The phase of trace point `i` (`0 <= i < cadmm_solver_trace_len`): 0 for an ADMM
/// iteration, 1 for the end of a semismooth Newton phase (whose point has NaN residuals).
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (index out of range).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_trace_phase(
    sv: *const cadmm_solver,
    i: usize,
    phase: *mut i32,
) -> cadmm_result {
    let body = |sv: &cadmm_solver| -> FfiResult {
        check_ptr("phase", phase.cast_const())?;
        let point = trace_point(sv, i)?;
        let code = match point.phase {
            Phase::Admm => 0,
            Phase::Newton => 1,
        };
        // SAFETY: checked non-NULL and aligned.
        unsafe { phase.write(code) };
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_solver(sv, body) }
}

/// The message of the last failed call on this solver ("" if none has failed), naming the
/// argument and index at fault. The string belongs to the solver and stays valid until the
/// next call on it; copy it to keep it. A NULL `sv` gives a static message.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_last_error(sv: *const cadmm_solver) -> *const c_char {
    guard_value(std::ptr::null(), || {
        if sv.is_null() {
            return c"cadmm_solver_last_error: the solver pointer is NULL".as_ptr();
        }
        // SAFETY: a live handle by contract; the CString's buffer lives until replaced by
        // a later failing call or freed with the solver.
        unsafe { (*sv).last_error.borrow().as_ptr() }
    })
}

/// Releases a solver. NULL is a no-op. The handle, and any string it returned, must not be
/// used afterwards.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_free(sv: *mut cadmm_solver) {
    guard_value((), || {
        if !sv.is_null() {
            // SAFETY: created by Box::into_raw in this module, freed once by contract.
            drop(unsafe { Box::from_raw(sv) });
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ffi::{
        cadmm_csc, cadmm_problem_free, cadmm_problem_new_local, cadmm_settings_free,
        cadmm_settings_new, cadmm_solver_get_solution, CADMM_OK,
    };
    use std::ffi::CStr;
    use std::ptr::null_mut;

    // No input of the library is known to panic inside a call that changes a solver, so the
    // poisoning is exercised by running a panicking body through the same helper.
    #[test]
    fn a_panic_poisons_the_solver() {
        let (colptr, rowind, values) = ([0i64, 1, 2, 3], [0i64, 1, 2], [1.0; 3]);
        let w = cadmm_csc {
            nrows: 3,
            ncols: 3,
            colptr: colptr.as_ptr(),
            rowind: rowind.as_ptr(),
            values: values.as_ptr(),
        };
        let (q, mu) = ([-1.0, 0.0, 0.0], [0.5]);
        unsafe {
            let (mut p, mut s, mut sv) = (null_mut(), null_mut(), null_mut());
            assert_eq!(
                cadmm_problem_new_local(1, &w, q.as_ptr(), mu.as_ptr(), &mut p),
                CADMM_OK
            );
            assert_eq!(cadmm_settings_new(&mut s), CADMM_OK);
            assert_eq!(cadmm_solver_new(p, s, &mut sv), CADMM_OK);
            let rc = with_solver_mut(sv, |_| panic!("injected"));
            assert_eq!(rc, CADMM_ERR_PANIC);
            let text = CStr::from_ptr(cadmm_solver_last_error(sv))
                .to_str()
                .unwrap();
            assert!(text.contains("injected"), "{text}");
            let mut status = -1;
            assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_ERR_PANIC);
            assert_eq!(status, -1);
            assert_eq!(
                cadmm_solver_update(sv, p),
                CADMM_ERR_PANIC,
                "an update does not repair a panicked solver"
            );
            assert_eq!(
                cadmm_solver_get_solution(sv, null_mut(), null_mut(), null_mut()),
                CADMM_ERR_PANIC
            );
            assert_eq!(cadmm_solver_trace_len(sv), 0);
            // A panic in a read-only call is reported but does not poison.
            let (mut s2, mut sv2) = (null_mut(), null_mut());
            assert_eq!(cadmm_settings_new(&mut s2), CADMM_OK);
            assert_eq!(cadmm_solver_new(p, s2, &mut sv2), CADMM_OK);
            assert_eq!(with_solver(sv2, |_| panic!("read")), CADMM_ERR_PANIC);
            let mut status = -1;
            assert_eq!(cadmm_solver_solve(sv2, &mut status), CADMM_OK);
            cadmm_solver_free(sv2);
            cadmm_settings_free(s2);
            cadmm_solver_free(sv);
            cadmm_settings_free(s);
            cadmm_problem_free(p);
        }
    }
}
