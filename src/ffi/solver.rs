//! `cadmm_solver`: a solver with its factorizations, last iterate and last error message.

use super::arrays::{check_output, check_ptr, contact_len, input, write_output};
use super::handle::{last_error, release, with_mut, with_ref, with_value, Boundary, Handle};
use super::panic::guard;
use super::problem::{cadmm_problem, problem_ref};
use super::result::{
    cadmm_result, cadmm_status, status_code, Failure, FfiResult, CADMM_ERR_INVALID_VALUE,
};
use super::settings::{cadmm_settings, settings_ref};
use super::stats::{
    cadmm_phase, cadmm_stats, cadmm_trace_point, phase_code, write_stats, STATS_MIN_SIZE,
};
use crate::problem::{NewValues, Problem};
use crate::solver::Solver;
use crate::types::TracePoint;
use std::ffi::c_char;

/// A solver for one problem and its successors with the same sparsity pattern. Opaque;
/// created by `cadmm_solver_new`, released by `cadmm_solver_free`. A call that reports
/// `CADMM_ERR_PANIC` leaves it unusable: every later call on it returns `CADMM_ERR_PANIC`
/// (`cadmm_solver_trace_len` returns 0) and changes nothing, except
/// `cadmm_solver_last_error` and `cadmm_solver_free`.
pub struct cadmm_solver {
    solver: Solver,
    n_velocities: usize,
    n_contacts: usize,
    is_global: bool,
    /// Lengths of the value arrays `cadmm_solver_update_values` reads: nnz of M (or W), H
    /// and G, and the number of joint rows.
    value_lens: [usize; 4],
    boundary: Boundary,
}

impl Handle for cadmm_solver {
    fn boundary(&self) -> &Boundary {
        &self.boundary
    }
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
            boundary: Boundary::default(),
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

/// The refusal of an update of the other form, before anything changes.
fn other_form(message: &str) -> Failure {
    crate::Error::Unsupported(message.into()).into()
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
            return Err(other_form(
                "cadmm_solver_update_values: the solver holds a local problem; use \
                 cadmm_solver_update_local_values",
            ));
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
        // A refused update changes nothing (`Solver::update_values`).
        sv.solver.update_values(&values)?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
}

/// New bounds and compliances of a global problem's joint rows (see
/// `cadmm_problem_set_joint_bounds` and `cadmm_problem_set_joint_compliance`), for the next
/// time step: `lo`, `hi` and `c` have one entry per joint row, each NULL to keep the current
/// values. Which rows are bounded (a finite bound on either side) must stay the same, since
/// bounded rows and equalities take different places in the solver's system; a step that
/// makes an equality a bounded row or back needs a new solver (`CADMM_ERR_PATTERN_CHANGED`).
/// Same behaviour otherwise as `cadmm_solver_update_values` (a refused update changes
/// nothing; the next solve starts cold unless `cadmm_solver_warm_start` follows).
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (NaN, `lo > hi`, a negative
/// compliance), `CADMM_ERR_PATTERN_CHANGED`, `CADMM_ERR_UNSUPPORTED` (a local solver, or a
/// problem without joints given any of the three).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_update_joint_rows(
    sv: *mut cadmm_solver,
    lo: *const f64,
    hi: *const f64,
    c: *const f64,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        if !sv.is_global {
            return Err(other_form(
                "cadmm_solver_update_joint_rows: the solver holds a local problem, which has \
                 no joint rows",
            ));
        }
        let n_joints = sv.value_lens[3];
        // SAFETY: lengths from the problem the solver was built for; the caller's contract.
        let values = unsafe {
            NewValues {
                lo: optional("lo", lo, n_joints)?,
                hi: optional("hi", hi, n_joints)?,
                compliance: optional("c", c, n_joints)?,
                ..Default::default()
            }
        };
        sv.solver.update_values(&values)?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
}

/// New coefficients of the joint rows bounded by contacts' normal impulses (see
/// `cadmm_problem_set_joint_friction`), for the next time step: `coefficient` has one
/// entry per joint row (0 on the rows without a contact). Which rows are bounded by which
/// contact cannot change (`CADMM_ERR_PATTERN_CHANGED` then needs a new solver). Same
/// behaviour otherwise as `cadmm_solver_update_values`.
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (a negative coefficient or
/// one on a row without a contact), `CADMM_ERR_UNSUPPORTED` (a local solver, or a problem
/// without joints).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_update_joint_friction(
    sv: *mut cadmm_solver,
    coefficient: *const f64,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        if !sv.is_global {
            return Err(other_form(
                "cadmm_solver_update_joint_friction: the solver holds a local problem, which \
                 has no joint rows",
            ));
        }
        let n_joints = sv.value_lens[3];
        // SAFETY: lengths from the problem the solver was built for; the caller's contract.
        let values = unsafe {
            NewValues {
                friction: Some(input("coefficient", coefficient, n_joints)?),
                ..Default::default()
            }
        };
        sv.solver.update_values(&values)?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
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
            return Err(other_form(
                "cadmm_solver_update_local_values: the solver holds a global problem; use \
                 cadmm_solver_update_values",
            ));
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
        // A refused update changes nothing (`Solver::update_values`).
        sv.solver.update_values(&values)?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
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
        sv.solver.update(problem.clone())?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
}

/// Replaces the solver's problem by `p`, of any form, sizes and sparsity patterns (the next
/// time step of a scene whose contacts changed), keeping the solver's settings: the solver
/// becomes what `cadmm_solver_new` builds from `p` and those settings, without a new
/// handle. A solver with a time limit (started by Gauss-Seidel sweeps, `auto`) builds the
/// new problem's sweeps in the memory of those it replaced the time before, where a new
/// solver would allocate it afresh. `p` is copied. The next solve starts cold unless
/// `cadmm_solver_warm_start` is called after this.
///
/// Errors: as `cadmm_solver_new` (`CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_NOT_POSITIVE_DEFINITE`, `CADMM_ERR_SINGULAR`). A refused problem changes
/// nothing: the solver keeps its problem, settings and last solution.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_rebuild(
    sv: *mut cadmm_solver,
    p: *const cadmm_problem,
) -> cadmm_result {
    let body = |sv: &mut cadmm_solver| -> FfiResult {
        // SAFETY: a live handle by contract.
        let problem = unsafe { problem_ref("p", p)? };
        sv.solver.rebuild(problem)?;
        sv.n_velocities = problem.n_velocities();
        sv.n_contacts = problem.n_contacts();
        sv.is_global = matches!(problem, Problem::Global(_));
        sv.value_lens = value_lens(problem);
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
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
        // SAFETY: a live handle by contract.
        let settings = unsafe { settings_ref("s", s)? };
        sv.solver.update_settings(settings.clone())?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
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
    unsafe { with_mut(sv, body) }
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
        check_ptr("status", status.cast_const())?;
        let s = sv.solver.solve()?;
        // SAFETY: checked non-NULL and aligned.
        unsafe { status.write(status_code(s)) };
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
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
    unsafe { with_ref(sv, body) }
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
    unsafe { with_ref(sv, body) }
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
    unsafe { with_ref(sv, body) }
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
    unsafe { with_ref(sv, body) }
}

/// Number of points in the trace of the last solve (0 unless the trace was switched on
/// with `cadmm_settings_set_trace`; 0 for a NULL or unusable solver).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_trace_len(sv: *const cadmm_solver) -> usize {
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_value(sv, 0, |sv| sv.solver.trace().len()) }
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
    unsafe { with_ref(sv, body) }
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

/// The phase of trace point `i` (`0 <= i < cadmm_solver_trace_len`): `CADMM_PHASE_ADMM`
/// for an ADMM iteration, `CADMM_PHASE_NEWTON` for the end of a semismooth Newton phase
/// (whose point has NaN residuals). Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_INVALID_VALUE` (index out of range).
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_get_trace_phase(
    sv: *const cadmm_solver,
    i: usize,
    phase: *mut cadmm_phase,
) -> cadmm_result {
    let body = |sv: &cadmm_solver| -> FfiResult {
        check_ptr("phase", phase.cast_const())?;
        let point = trace_point(sv, i)?;
        // SAFETY: checked non-NULL and aligned.
        unsafe { phase.write(phase_code(point.phase)) };
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_ref(sv, body) }
}

/// The message of the last failed call on this solver ("" if none has failed), naming the
/// argument and index at fault. The string belongs to the solver and stays valid until the
/// next call on it; copy it to keep it. A NULL `sv` gives a static message.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_last_error(sv: *const cadmm_solver) -> *const c_char {
    // SAFETY: the caller's contract, forwarded.
    unsafe { last_error(sv, c"cadmm_solver_last_error: the solver pointer is NULL") }
}

/// Releases a solver. NULL is a no-op. The handle, and any string it returned, must not be
/// used afterwards.
#[no_mangle]
pub unsafe extern "C" fn cadmm_solver_free(sv: *mut cadmm_solver) {
    // SAFETY: made by `cadmm_solver_new` with Box::into_raw, released once by contract.
    unsafe { release(sv) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ffi::{
        cadmm_csc, cadmm_problem_free, cadmm_problem_new_local, cadmm_settings_free,
        cadmm_settings_new, CADMM_ERR_NULL_POINTER, CADMM_ERR_PANIC, CADMM_OK,
    };
    use std::ffi::CStr;
    use std::ptr::{null, null_mut};

    /// Every call on `sv` but `last_error` and `free` returns `CADMM_ERR_PANIC`, whatever
    /// its other arguments (NULL ones included), and writes nothing.
    unsafe fn refuses_every_call(sv: *mut cadmm_solver, p: *const cadmm_problem) {
        let s = null();
        let (x, mut status, mut phase) = ([0.0; 3], -1, -1);
        let (mut point, mut stats) = (cadmm_trace_point::default(), cadmm_stats::default());
        stats.struct_size = std::mem::size_of::<cadmm_stats>();
        let nul = null_mut();
        unsafe {
            let rcs = [
                cadmm_solver_solve(sv, &mut status),
                cadmm_solver_update(sv, p),
                cadmm_solver_update(sv, null()),
                cadmm_solver_update_values(
                    sv,
                    null(),
                    null(),
                    null(),
                    null(),
                    null(),
                    null(),
                    null(),
                ),
                cadmm_solver_update_local_values(sv, x.as_ptr(), null(), null()),
                cadmm_solver_update_settings(sv, s),
                cadmm_solver_warm_start(sv, x.as_ptr(), null()),
                cadmm_solver_get_solution(sv, nul, nul, nul),
                cadmm_solver_get_joint_multipliers(sv, nul, null_mut()),
                cadmm_solver_get_stats(sv, &mut stats),
                cadmm_solver_get_island_stats(sv, 0, &mut stats),
                cadmm_solver_get_trace(sv, 0, &mut point),
                cadmm_solver_get_trace_phase(sv, 0, &mut phase),
            ];
            assert_eq!(rcs, [CADMM_ERR_PANIC; 13]);
            assert_eq!(cadmm_solver_trace_len(sv), 0);
            assert_eq!((status, phase, stats.iterations), (-1, -1, 0));
            let text = CStr::from_ptr(cadmm_solver_last_error(sv))
                .to_str()
                .unwrap();
            assert!(text.starts_with("the solver is unusable after"), "{text}");
            assert!(text.contains("injected"), "{text}");
        }
    }

    // No input of the library is known to panic inside a solver call, so a panic is injected
    // through the boundary every call runs through (handle.rs), in a call that changes the
    // solver and in one that reads it.
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
            let (mut p, mut s) = (null_mut(), null_mut());
            assert_eq!(
                cadmm_problem_new_local(1, &w, q.as_ptr(), mu.as_ptr(), &mut p),
                CADMM_OK
            );
            assert_eq!(cadmm_settings_new(&mut s), CADMM_OK);
            let panics: [&dyn Fn(*mut cadmm_solver) -> cadmm_result; 2] = [
                &|sv| with_mut(sv, |_| panic!("injected in a change")),
                &|sv| with_ref(sv, |_| panic!("injected in a read")),
            ];
            for panic_in in panics {
                let mut sv = null_mut();
                assert_eq!(cadmm_solver_new(p, s, &mut sv), CADMM_OK);
                let mut status = -1;
                assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
                assert_eq!(panic_in(sv), CADMM_ERR_PANIC);
                let text = CStr::from_ptr(cadmm_solver_last_error(sv))
                    .to_str()
                    .unwrap();
                assert!(text.contains("injected"), "{text}");
                refuses_every_call(sv, p);
                cadmm_solver_free(sv);
            }
            // A NULL solver is still NULL_POINTER, not a panic.
            assert_eq!(
                cadmm_solver_solve(null_mut(), null_mut()),
                CADMM_ERR_NULL_POINTER
            );
            cadmm_settings_free(s);
            cadmm_problem_free(p);
        }
    }
}
