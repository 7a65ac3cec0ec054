//! `cadmm_problem`: a validated global or local frictional contact problem.

use super::arrays::{check_ptr, contact_len, copy, input, path};
use super::csc::{cadmm_csc, read_csc, Shape};
use super::handle::release;
use super::panic::guard;
use super::result::{
    cadmm_result, Failure, FfiResult, CADMM_ERR_INVALID_VALUE, CADMM_ERR_UNSUPPORTED,
};
use crate::measure::problem_error;
use crate::problem::{GlobalProblem, LocalProblem, Problem};
use std::ffi::c_char;

/// A frictional contact problem, global (M, H, f, w, mu, optional joints G, b) or local
/// (W, q, mu). Opaque; created by `cadmm_problem_new_global`, `cadmm_problem_new_local` or
/// `cadmm_problem_read_fclib`, released by `cadmm_problem_free`. A solver keeps its own copy,
/// so a problem may be freed or reused as soon as the call that took it returns.
pub struct cadmm_problem {
    pub(crate) inner: Problem,
}

impl cadmm_problem {
    /// The problem this handle holds (Rust side only, e.g. for tests).
    pub fn problem(&self) -> &Problem {
        &self.inner
    }
}

/// Borrows a problem handle.
///
/// # Safety
/// `p`, if non-NULL, must come from this library and not be freed.
pub(crate) unsafe fn problem_ref<'a>(
    what: &str,
    p: *const cadmm_problem,
) -> FfiResult<&'a Problem> {
    check_ptr(what, p)?;
    // SAFETY: a live handle by contract.
    Ok(unsafe { &(*p).inner })
}

/// Boxes a problem into `*out` (already checked non-NULL).
unsafe fn put(out: *mut *mut cadmm_problem, inner: Problem) {
    let handle = Box::into_raw(Box::new(cadmm_problem { inner }));
    // SAFETY: checked non-NULL and aligned by the caller.
    unsafe { out.write(handle) };
}

/// Builds a global problem: `M v = H r + f`, `u = H^T v + w`, with `n` velocities and
/// `n_contacts` contacts.
///
/// `M` is `n x n` (symmetric positive definite, both triangles; definiteness is checked by
/// `cadmm_solver_new`), `H` is `n x 3 n_contacts`, `f` has `n` entries, `w` has
/// `3 n_contacts`, `mu` has `n_contacts` (non-negative). Every input is copied. On success
/// `*out` receives a new problem to release with `cadmm_problem_free`; on failure `*out` is
/// left untouched. Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_DIMENSION` (a matrix whose
/// shape disagrees with `n` and `n_contacts`, checked before anything sized by them is read),
/// `CADMM_ERR_INVALID_CSC`, `CADMM_ERR_INVALID_VALUE`, `CADMM_ERR_OUT_OF_MEMORY` (sizes too
/// large for the copies).
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_new_global(
    n: usize,
    n_contacts: usize,
    M: *const cadmm_csc,
    H: *const cadmm_csc,
    f: *const f64,
    w: *const f64,
    mu: *const f64,
    out: *mut *mut cadmm_problem,
) -> cadmm_result {
    guard(|| {
        check_ptr("out", out)?;
        let l = contact_len(n_contacts)?;
        // Each matrix's shape is checked against n and n_contacts before anything sized by
        // them is read or allocated; the vectors are read only once the matrices agree.
        let shape_m = Shape {
            nrows: n,
            ncols: Some(n),
            rule: "n x n",
        };
        let shape_h = Shape {
            nrows: n,
            ncols: Some(l),
            rule: "n x 3 n_contacts",
        };
        // SAFETY (all reads): lengths from the dimensions, as documented above.
        let m = unsafe { read_csc("M", M, shape_m)? };
        let h = unsafe { read_csc("H", H, shape_h)? };
        let f = unsafe { copy("f", f, n)? };
        let w = unsafe { copy("w", w, l)? };
        let mu = unsafe { copy("mu", mu, n_contacts)? };
        let p = GlobalProblem::new(m, h, f, w, mu)?;
        unsafe { put(out, Problem::Global(p)) };
        Ok(())
    })
}

/// Adds bilateral (joint) constraints `G^T v + b = 0` to a global problem, replacing any
/// earlier ones: `M v = H r + G lambda + f`.
///
/// `G` is `n x p`, `b` has `p` entries (`p` = `G->ncols`). A `G` with no column removes the
/// joints. On failure the problem is unchanged. Errors: `CADMM_ERR_NULL_POINTER`,
/// `CADMM_ERR_DIMENSION`, `CADMM_ERR_INVALID_CSC`, `CADMM_ERR_INVALID_VALUE`,
/// `CADMM_ERR_UNSUPPORTED` (a local problem), `CADMM_ERR_OUT_OF_MEMORY`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_set_joints(
    p: *mut cadmm_problem,
    G: *const cadmm_csc,
    b: *const f64,
) -> cadmm_result {
    guard(|| {
        check_ptr("p", p.cast_const())?;
        // SAFETY: a live handle by contract, used by this thread only.
        let problem = unsafe { &mut (*p).inner };
        let Problem::Global(global) = problem else {
            return Err(Failure::new(
                CADMM_ERR_UNSUPPORTED,
                "joints apply to global problems only",
            ));
        };
        // SAFETY: lengths from the dimensions, as documented above.
        let shape = Shape {
            nrows: global.n(),
            ncols: None,
            rule: "n x p",
        };
        let g = unsafe { read_csc("G", G, shape)? };
        let b = unsafe { copy("b", b, g.ncols())? };
        *global = global.clone().with_joints(g, b)?;
        Ok(())
    })
}

/// The global problem a joint-row setter changes, or why not: a local problem has none.
fn joint_rows_of<'a>(problem: &'a mut Problem, what: &str) -> FfiResult<&'a mut GlobalProblem> {
    match problem {
        Problem::Global(global) => Ok(global),
        Problem::Local(_) => Err(Failure::new(
            CADMM_ERR_UNSUPPORTED,
            format!("{what} apply to the joint rows of global problems only"),
        )),
    }
}

/// Bounds the multipliers of the joint rows given to `cadmm_problem_set_joints`:
/// `lo[k] <= lambda_k <= hi[k]`, replacing any earlier bounds.
///
/// Row `k`'s velocity is `y_k = G_k^T v + b_k + c_k lambda_k` (`c` the compliance, see
/// `cadmm_problem_set_joint_compliance`). A row with both bounds infinite (`-INFINITY`,
/// `INFINITY`, which every row has until this call) is an equality, `y_k = 0`: a bilateral
/// joint. A bounded row holds `y_k = 0` while its multiplier is strictly inside its
/// bounds, `y_k >= 0` at `lo[k]` and `y_k <= 0` at `hi[k]`. `lambda` is an impulse (force
/// times the time step) acting along `G`'s column, `y` a velocity, `b` a velocity (a bias
/// or minus a motor's target velocity). Examples: a joint limit is `[0, INFINITY)` with
/// `b` the position error over the time step (so the row reads "do not close the gap
/// faster than it is"); a motor or dry joint friction is `[-F h, F h]` with `b` minus the
/// target velocity (0 for friction).
///
/// `lo` and `hi` have `p` entries each (`p` the number of joint rows; 0 without joints,
/// when both may be NULL). Infinite bounds are allowed; NaN, `lo[k] > hi[k]`,
/// `lo[k] = +INFINITY` and `hi[k] = -INFINITY` are not. On failure the problem is unchanged.
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (naming `lo` or `hi` and
/// the row), `CADMM_ERR_UNSUPPORTED` (a local problem). A problem with bounded rows cannot
/// be written as an FCLib file (`cadmm_problem_write_fclib` refuses it).
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_set_joint_bounds(
    p: *mut cadmm_problem,
    lo: *const f64,
    hi: *const f64,
) -> cadmm_result {
    guard(|| {
        check_ptr("p", p.cast_const())?;
        // SAFETY: a live handle by contract, used by this thread only.
        let global = joint_rows_of(unsafe { &mut (*p).inner }, "bounds")?;
        let np = global.n_joints();
        // SAFETY: lengths from the problem, as documented above.
        let lo = unsafe { input("lo", lo, np)? }.to_vec();
        let hi = unsafe { input("hi", hi, np)? }.to_vec();
        *global = global.clone().with_joint_bounds(lo, hi)?;
        Ok(())
    })
}

/// Sets the compliance `c[k] >= 0` of each joint row, replacing any earlier one: row `k`
/// reads `G_k^T v + b_k + c_k lambda_k` (a velocity per unit impulse; 0, every row's
/// value until this call, is a rigid row). A spring of stiffness `k` and damping `d`
/// integrated implicitly over a step `h` is the equality row with `c = 1 / (h (h k + d))`
/// and `b = x k / (h k + d)`, `x` its extension (Bullet's and ODE's CFM is `c / h`, their
/// ERP `h k / (h k + d)`).
///
/// `c` has `p` entries (`p` the number of joint rows; 0 without joints, when it may be
/// NULL), finite and non-negative. On failure the problem is unchanged. Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (naming the row),
/// `CADMM_ERR_UNSUPPORTED` (a local problem). A problem with compliance cannot be written
/// as an FCLib file.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_set_joint_compliance(
    p: *mut cadmm_problem,
    c: *const f64,
) -> cadmm_result {
    guard(|| {
        check_ptr("p", p.cast_const())?;
        // SAFETY: a live handle by contract, used by this thread only.
        let global = joint_rows_of(unsafe { &mut (*p).inner }, "compliances")?;
        let np = global.n_joints();
        // SAFETY: lengths from the problem, as documented above.
        let c = unsafe { input("c", c, np)? }.to_vec();
        *global = global.clone().with_joint_compliance(c)?;
        Ok(())
    })
}

/// Bounds joint rows by a contact's normal impulse, replacing any earlier such bounds:
/// row `k` with `contact[k] = i >= 0` holds `-e_k r_n(i) <= lambda_k <= e_k r_n(i)`
/// (`e_k = coefficient[k] >= 0`, `r_n(i)` contact `i`'s normal impulse in the solution),
/// and is otherwise a bounded row as in `cadmm_problem_set_joint_bounds`: `y_k = 0` inside
/// its bounds, `y_k >= 0` at the lower one, `y_k <= 0` at the upper one.
///
/// This is rolling and spinning friction. Rolling friction is two such rows per contact,
/// on the bodies' relative angular velocity about the contact's two tangents (`G`'s column
/// holds `+t` on one body's angular velocity and `-t` on the other's), spinning friction
/// one row about the normal; `e` is then a length (the torque impulse per unit normal
/// impulse), `lambda` a torque impulse. A row with `contact[k] = -1` keeps its own bounds and
/// must have `coefficient[k] = 0`; a row bounded by a contact must have infinite `lo` and
/// `hi` and at least one entry in `G`'s column.
///
/// `contact` and `coefficient` have `p` entries each (`p` the number of joint rows; 0
/// without joints, when both may be NULL). The Newton phase does not take such rows: a
/// problem with them is solved by ADMM (`CADMM_VARIANT_NEWTON` refuses it with
/// `CADMM_ERR_UNSUPPORTED`). On failure the problem is unchanged. Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE` (a contact index out of range, a
/// negative coefficient or one on a row without a contact, a row bounded by a contact with
/// a finite bound or an empty column), `CADMM_ERR_UNSUPPORTED` (a local problem). Such a
/// problem cannot be written as an FCLib file.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_set_joint_friction(
    p: *mut cadmm_problem,
    contact: *const i64,
    coefficient: *const f64,
) -> cadmm_result {
    guard(|| {
        check_ptr("p", p.cast_const())?;
        // SAFETY: a live handle by contract, used by this thread only.
        let global = joint_rows_of(unsafe { &mut (*p).inner }, "friction bounds")?;
        let (np, nc) = (global.n_joints(), global.n_contacts());
        // SAFETY: lengths from the problem, as documented above.
        let raw = unsafe { input("contact", contact, np)? };
        let e = unsafe { input("coefficient", coefficient, np)? }.to_vec();
        let mut contacts = Vec::with_capacity(np);
        for (k, &i) in raw.iter().enumerate() {
            contacts.push(match i {
                -1 => None,
                i if i >= 0 && (i as u64) < nc as u64 => Some(i as usize),
                _ => {
                    return Err(Failure::new(
                        CADMM_ERR_INVALID_VALUE,
                        format!(
                            "invalid value in contact[{k}]: {i} is neither -1 nor a contact \
                             index below {nc}"
                        ),
                    ))
                }
            });
        }
        *global = global.clone().with_joint_friction(contacts, e)?;
        Ok(())
    })
}

/// Builds a local problem `u = W r + q` with `n_contacts` contacts.
///
/// `W` (the Delassus matrix) is `3 n_contacts x 3 n_contacts`, both triangles, possibly
/// non-symmetric; `q` has `3 n_contacts` entries; `mu` has `n_contacts` (non-negative).
/// Every input is copied. On success `*out` receives a new problem to release with
/// `cadmm_problem_free`; on failure `*out` is left untouched. Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_DIMENSION` (W's shape checked first, as for
/// `cadmm_problem_new_global`), `CADMM_ERR_INVALID_CSC`, `CADMM_ERR_INVALID_VALUE`,
/// `CADMM_ERR_OUT_OF_MEMORY`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_new_local(
    n_contacts: usize,
    W: *const cadmm_csc,
    q: *const f64,
    mu: *const f64,
    out: *mut *mut cadmm_problem,
) -> cadmm_result {
    guard(|| {
        check_ptr("out", out)?;
        let l = contact_len(n_contacts)?;
        // W's shape is checked first, as for the global form.
        let shape = Shape {
            nrows: l,
            ncols: Some(l),
            rule: "3 n_contacts x 3 n_contacts",
        };
        // SAFETY (all reads): lengths from the dimensions, as documented above.
        let w = unsafe { read_csc("W", W, shape)? };
        let q = unsafe { copy("q", q, l)? };
        let mu = unsafe { copy("mu", mu, n_contacts)? };
        let p = LocalProblem::new(w, q, mu)?;
        unsafe { put(out, Problem::Local(p)) };
        Ok(())
    })
}

/// Reads an FCLib HDF5 file (`fclib_global`, with its joints if any, or `fclib_local`).
///
/// On success `*out` receives a new problem; on failure `*out` is left untouched. Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_IO` (missing or unreadable file, a path that is not
/// a regular file, such as a FIFO, which is never opened; size fields that disagree with the
/// datasets or with each other, naming the field), the validation
/// errors of `cadmm_problem_new_global`/`_new_local`, and `CADMM_ERR_UNSUPPORTED` when the
/// library was built without FCLib support (Cargo feature `fclib`). Read only files you
/// trust: libhdf5 itself can crash on a corrupt file (found by fuzzing) before cadmm's own
/// checks run.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_read_fclib(
    path: *const c_char,
    out: *mut *mut cadmm_problem,
) -> cadmm_result {
    guard(|| {
        check_ptr("out", out)?;
        // SAFETY: a NUL-terminated string by contract.
        let path = unsafe { self::path("path", path)? };
        #[cfg(feature = "fclib")]
        let read = crate::fclib::read(path).map_err(Failure::from);
        #[cfg(not(feature = "fclib"))]
        let read: FfiResult<Problem> = Err(no_fclib(path));
        let problem = read?;
        // SAFETY: `out` checked non-NULL and aligned.
        unsafe { put(out, problem) };
        Ok(())
    })
}

/// Writes a problem to an FCLib HDF5 file (created or overwritten).
///
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_IO`, and `CADMM_ERR_UNSUPPORTED` when the
/// library was built without FCLib support (Cargo feature `fclib`).
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_write_fclib(
    p: *const cadmm_problem,
    path: *const c_char,
) -> cadmm_result {
    guard(|| {
        // SAFETY: a live handle and a NUL-terminated string by contract.
        let problem = unsafe { problem_ref("p", p)? };
        let path = unsafe { self::path("path", path)? };
        #[cfg(feature = "fclib")]
        let written = crate::fclib::write_problem(path, problem).map_err(Failure::from);
        #[cfg(not(feature = "fclib"))]
        let written = {
            let _ = problem;
            Err(no_fclib(path))
        };
        written
    })
}

#[cfg(not(feature = "fclib"))]
fn no_fclib(path: &std::path::Path) -> Failure {
    Failure::new(
        CADMM_ERR_UNSUPPORTED,
        format!(
            "{}: this build of cadmm has no FCLib support (Cargo feature fclib)",
            path.display()
        ),
    )
}

/// Computes the error measure of a candidate solution (the one `cadmm_solver_solve` stops
/// on; docs/algorithms.md §3), from any source.
///
/// `r` has `3 n_contacts` entries. For a global problem `v` (`n` entries) is required and
/// `u` is recomputed as `H^T v + w`; for a local problem `v` is ignored (may be NULL) and
/// `u` is recomputed as `W r + q`. `u` is accepted for symmetry with
/// `cadmm_solver_get_solution` and never read (may be NULL). For a global problem with
/// joints, the multipliers are recomputed as the least-squares solution of
/// `G lambda = M v - H r - f` (the best ones for this `r` and `v`, regardless of any joint
/// bounds; `cadmm_problem_error_with_multipliers` takes them instead), and the joint rows'
/// residual is part of the error (docs/algorithms.md §3.2). A non-finite `r` or `v` gives
/// an infinite error (not a failure). `*error` is written on
/// success only. Errors: `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_error(
    p: *const cadmm_problem,
    r: *const f64,
    u: *const f64,
    v: *const f64,
    error: *mut f64,
) -> cadmm_result {
    let _ = u;
    guard(|| {
        // SAFETY: a live handle by contract.
        let problem = unsafe { problem_ref("p", p)? };
        check_ptr("error", error.cast_const())?;
        let l = contact_len(problem.n_contacts())?;
        // SAFETY (reads): lengths from the problem, as documented above.
        let r = unsafe { input("r", r, l)? };
        let v = match problem {
            Problem::Global(g) => unsafe { input("v", v, g.n())? },
            Problem::Local(_) => &[],
        };
        let e = problem_error(problem, r, v, &[]);
        // SAFETY: checked non-NULL and aligned.
        unsafe { error.write(e) };
        Ok(())
    })
}

/// `cadmm_problem_error` with the joint multipliers given: `lambda` has `p` entries (the
/// number of joint rows; 0 without joints, when it may be NULL), as
/// `cadmm_solver_get_joint_multipliers` returns them. A problem with bounded joint rows is
/// measured best this way: the least-squares multipliers `cadmm_problem_error` computes
/// know nothing of the bounds. A non-finite `r`, `v` or `lambda` gives an infinite error.
/// Errors: `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_error_with_multipliers(
    p: *const cadmm_problem,
    r: *const f64,
    v: *const f64,
    lambda: *const f64,
    error: *mut f64,
) -> cadmm_result {
    guard(|| {
        // SAFETY: a live handle by contract.
        let problem = unsafe { problem_ref("p", p)? };
        check_ptr("error", error.cast_const())?;
        let l = contact_len(problem.n_contacts())?;
        // SAFETY (reads): lengths from the problem, as documented above.
        let r = unsafe { input("r", r, l)? };
        let (v, lambda) = match problem {
            Problem::Global(g) => unsafe {
                (
                    input("v", v, g.n())?,
                    input("lambda", lambda, g.n_joints())?,
                )
            },
            Problem::Local(_) => (&[][..], &[][..]),
        };
        let e = problem_error(problem, r, v, lambda);
        // SAFETY: checked non-NULL and aligned.
        unsafe { error.write(e) };
        Ok(())
    })
}

/// Reports the sizes of a problem: `*n_velocities` (`n`; 0 for a local problem),
/// `*n_contacts`, and `*is_global`. All three pointers are required; they are written on
/// success only. Errors: `CADMM_ERR_NULL_POINTER`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_dims(
    p: *const cadmm_problem,
    n_velocities: *mut usize,
    n_contacts: *mut usize,
    is_global: *mut bool,
) -> cadmm_result {
    guard(|| {
        // SAFETY: a live handle by contract.
        let problem = unsafe { problem_ref("p", p)? };
        check_ptr("n_velocities", n_velocities.cast_const())?;
        check_ptr("n_contacts", n_contacts.cast_const())?;
        check_ptr("is_global", is_global.cast_const())?;
        // SAFETY: checked non-NULL and aligned.
        unsafe {
            n_velocities.write(problem.n_velocities());
            n_contacts.write(problem.n_contacts());
            is_global.write(matches!(problem, Problem::Global(_)));
        }
        Ok(())
    })
}

/// Releases a problem. NULL is a no-op. The handle must not be used afterwards.
#[no_mangle]
pub unsafe extern "C" fn cadmm_problem_free(p: *mut cadmm_problem) {
    // SAFETY: made with Box::into_raw by `cadmm_problem_new_global`, `_new_local` or
    // `_read_fclib`, released once by contract.
    unsafe { release(p) }
}
