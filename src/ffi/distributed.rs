//! One problem shared out among MPI processes (built with `CADMM_WITH_MPI`, the Cargo
//! feature `mpi`). Each process of the host's communicator hands its part
//! (`cadmm_rank_part`) to `cadmm_distributed_solver_new`, and every process then makes
//! the same calls in the same order: the calls marked collective communicate, and return
//! on every process with the same result code. An error one process meets (a NULL array,
//! a non-finite value, a contact naming a body no process owns) is every process's, with
//! the message naming that process's rank and the item. A NULL solver handle returns at
//! once, on that process alone (it has no communicator to tell the others).
//!
//! The communicator is passed as a Fortran handle (`MPI_Fint`, from `MPI_Comm_c2f`), so
//! that this header needs no `mpi.h`: it works with the MPI the library was built with.

use super::arrays::{check_output, check_ptr, contact_len, copy, input, write_output};
use super::handle::{last_error, release, with_mut, with_ref, Boundary, Handle};
use super::panic::guard;
use super::result::{
    cadmm_result, cadmm_status, kind_code, status_code, Failure, FfiResult, CADMM_ERR_DIMENSION,
    CADMM_ERR_INVALID_CSC, CADMM_ERR_INVALID_VALUE, CADMM_ERR_UNSUPPORTED,
};
use super::settings::{cadmm_settings, settings_ref};
use super::stats::cadmm_stats;
use crate::distributed::{agree_code, DistributedSolver, RankError, RankProblem};
use mpi::raw::FromRaw;
use mpi::topology::SimpleCommunicator;
use std::ffi::{c_char, c_int};
use std::mem::ManuallyDrop;

/// A process's part of a global problem shared out among MPI processes. Arrays are read
/// during `cadmm_distributed_solver_new` only; their lengths follow from the counts.
/// Bodies are named by global ids (any `uint64_t`, each owned by exactly one process);
/// the velocities of this process's bodies are numbered body after body.
#[repr(C)]
pub struct cadmm_rank_part {
    /// Bodies this process owns.
    pub n_bodies: usize,
    /// Their global ids (`n_bodies`).
    pub body_ids: *const u64,
    /// Their velocities: 1 to 12 each, 6 for a rigid body (`n_bodies`).
    pub body_dofs: *const usize,
    /// Each body's mass matrix, `dofs x dofs` column-major, body after body (the sum of
    /// `dofs^2`).
    pub mass: *const f64,
    /// Free-motion term, one entry per owned velocity (the sum of `dofs`).
    pub f: *const f64,
    /// Contacts this process owns.
    pub n_contacts: usize,
    /// Start of each of the `3 n_contacts` columns of H (normal first) in the entry arrays
    /// below (`3 n_contacts + 1`, from 0).
    pub h_colptr: *const usize,
    /// Each entry's body, by global id: one this process owns or another one does
    /// (`h_colptr[3 n_contacts]`).
    pub h_body: *const u64,
    /// Each entry's velocity within its body, from 0 (`h_colptr[3 n_contacts]`).
    pub h_dof: *const usize,
    /// Each entry's value (`h_colptr[3 n_contacts]`).
    pub h_values: *const f64,
    /// Relative velocity offset `w` (`3 n_contacts`).
    pub w: *const f64,
    /// Friction coefficients (`n_contacts`).
    pub mu: *const f64,
}

/// A solver for one problem shared out among MPI processes, each process holding its own
/// handle. Opaque; created by `cadmm_distributed_solver_new`, released by
/// `cadmm_distributed_solver_free`. A call that reports `CADMM_ERR_PANIC` leaves this
/// process's handle unusable, as for `cadmm_solver`: every later call on it returns
/// `CADMM_ERR_PANIC` at once, without communicating, except
/// `cadmm_distributed_solver_last_error` and `cadmm_distributed_solver_free`. The other
/// processes may be left waiting in the collective call the panic interrupted: end the job
/// (`MPI_Abort`).
pub struct cadmm_distributed_solver {
    solver: DistributedSolver,
    boundary: Boundary,
}

impl Handle for cadmm_distributed_solver {
    fn boundary(&self) -> &Boundary {
        &self.boundary
    }
}

impl From<RankError> for Failure {
    fn from(e: RankError) -> Self {
        Self::new(kind_code(e.kind), e.to_string())
    }
}

/// Reads a part, or what is wrong with its arrays.
///
/// # Safety
/// The pointers of `part` must be valid for the lengths its counts give.
unsafe fn read_part(part: &cadmm_rank_part) -> FfiResult<RankProblem> {
    // SAFETY (every `copy` below): valid for the given lengths by the caller's contract.
    // Each count is checked against what it sizes before anything is allocated by it, and
    // every copy is allocated fallibly (OUT_OF_MEMORY, never an abort).
    let dofs: Vec<usize> = unsafe { copy("part->body_dofs", part.body_dofs, part.n_bodies)? };
    if let Some(b) = dofs.iter().position(|k| !(1..=12).contains(k)) {
        return Err(Failure::new(
            CADMM_ERR_INVALID_VALUE,
            format!(
                "part->body_dofs[{b}] = {}: a body has 1 to 12 velocities",
                dofs[b]
            ),
        ));
    }
    // At most 144 and 12 per body: no overflow below n_bodies = usize::MAX / 144.
    let too_many = || {
        Failure::new(
            CADMM_ERR_DIMENSION,
            format!("part->n_bodies = {} is too large", part.n_bodies),
        )
    };
    let square = dofs
        .iter()
        .try_fold(0usize, |sum, &k| sum.checked_add(k * k))
        .ok_or_else(too_many)?;
    let velocities = dofs.iter().sum::<usize>();
    let l = contact_len(part.n_contacts)?;
    let columns = l.checked_add(1).ok_or_else(|| {
        Failure::new(
            CADMM_ERR_DIMENSION,
            format!("part->n_contacts = {} is too large", part.n_contacts),
        )
    })?;
    let colptr: Vec<usize> = unsafe { copy("part->h_colptr", part.h_colptr, columns)? };
    // The entry arrays are as long as the last pointer says: the pointers must start at 0
    // and never decrease before that length is trusted.
    if colptr[0] != 0 {
        return Err(Failure::new(
            CADMM_ERR_INVALID_CSC,
            format!("part->h_colptr[0] = {}, expected 0", colptr[0]),
        ));
    }
    if let Some(j) = colptr.windows(2).position(|w| w[1] < w[0]) {
        return Err(Failure::new(
            CADMM_ERR_INVALID_CSC,
            format!("part->h_colptr decreases at column {j}"),
        ));
    }
    let entries = colptr[l];
    Ok(RankProblem {
        bodies: unsafe { copy("part->body_ids", part.body_ids, part.n_bodies)? },
        mass: unsafe { copy("part->mass", part.mass, square)? },
        f: unsafe { copy("part->f", part.f, velocities)? },
        h_colptr: colptr,
        h_body: unsafe { copy("part->h_body", part.h_body, entries)? },
        h_dof: unsafe { copy("part->h_dof", part.h_dof, entries)? },
        h_values: unsafe { copy("part->h_values", part.h_values, entries)? },
        w: unsafe { copy("part->w", part.w, l)? },
        mu: unsafe { copy("part->mu", part.mu, part.n_contacts)? },
        dofs,
    })
}

/// The host's communicator from its Fortran handle, borrowed: never freed here.
fn host_communicator(comm: c_int) -> FfiResult<ManuallyDrop<SimpleCommunicator>> {
    if !mpi::environment::is_initialized() || mpi::environment::is_finalized() {
        return Err(Failure::new(
            CADMM_ERR_UNSUPPORTED,
            "MPI is not initialized (or already finalized): call MPI_Init first",
        ));
    }
    // SAFETY: the conversion of a handle, which MPI defines for any value it returns.
    let raw = unsafe { mpi::ffi::RSMPI_Comm_f2c(comm) };
    // SAFETY: reading MPI's constant.
    if raw == unsafe { mpi::ffi::RSMPI_COMM_NULL } {
        return Err(Failure::new(
            CADMM_ERR_INVALID_VALUE,
            "comm is MPI_COMM_NULL (pass MPI_Comm_c2f of the host's communicator)",
        ));
    }
    // MPI's own communicators have handles of their own kind: `from_raw` is for the
    // communicators a program creates.
    // SAFETY: reading MPI's constants.
    let (world, own) = unsafe { (mpi::ffi::RSMPI_COMM_WORLD, mpi::ffi::RSMPI_COMM_SELF) };
    Ok(ManuallyDrop::new(match raw {
        r if r == world => SimpleCommunicator::world(),
        r if r == own => SimpleCommunicator::self_comm(),
        // SAFETY: a live communicator of the host's; ManuallyDrop keeps it from being freed.
        _ => unsafe { SimpleCommunicator::from_raw(raw) },
    }))
}

/// Creates the solver of this process's part (collective over `comm`): checks every
/// process's part, learns which process owns which body, picks the first rho and prepares
/// the distributed v-update system. The solver talks on its own duplicate of `comm`.
///
/// `comm` is the Fortran handle of the host's communicator, `MPI_Comm_c2f(comm)`; MPI
/// must be initialized. The settings apply as for one process, with the v-update always
/// matrix-free and no Newton phase (a Newton polish asked for is left out); `direct`, the
/// variant `newton` and the spectral first penalties are refused
/// (`CADMM_ERR_UNSUPPORTED`). Every process must pass the same settings, all but the
/// thread count (tolerance, limits, variant, penalty, Anderson, s update, trace, Newton,
/// islands, linear solver): the processes take the solve's decisions together, and
/// settings that differ are every process's `CADMM_ERR_INVALID_SETTING`, naming the
/// setting and two ranks that differ. The solver must be freed before `MPI_Finalize`.
///
/// On success `*out` receives this process's solver; on failure, on every process, `*out`
/// is left untouched and `cadmm_last_error` names the failing rank and item. Errors:
/// `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_DIMENSION`, `CADMM_ERR_INVALID_CSC`,
/// `CADMM_ERR_INVALID_VALUE` (a non-finite value, a body id owned twice or by no
/// process), `CADMM_ERR_NOT_POSITIVE_DEFINITE`, `CADMM_ERR_INVALID_SETTING`,
/// `CADMM_ERR_UNSUPPORTED`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_new(
    comm: c_int,
    part: *const cadmm_rank_part,
    s: *const cadmm_settings,
    out: *mut *mut cadmm_distributed_solver,
) -> cadmm_result {
    guard(|| {
        let comm = host_communicator(comm)?;
        // What this process alone finds wrong, agreed before anything else communicates.
        let local = (|| {
            check_ptr("part", part)?;
            check_ptr("out", out.cast_const())?;
            // SAFETY: checked non-NULL and aligned; valid by contract.
            let part = unsafe { read_part(&*part)? };
            // SAFETY: a live handle by contract.
            let settings = unsafe { settings_ref("s", s)? }.clone();
            Ok((part, settings))
        })();
        let local = agreed(&comm, local)?;
        let (part, settings) = local;
        let solver = DistributedSolver::new(&comm, part, settings)?;
        let handle = Box::into_raw(Box::new(cadmm_distributed_solver {
            solver,
            boundary: Boundary::default(),
        }));
        // SAFETY: checked non-NULL and aligned above.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// What one process found wrong before a collective call, made every process's error
/// (the lowest failing rank's code and message).
fn agreed<T>(comm: &SimpleCommunicator, local: FfiResult<T>) -> FfiResult<T> {
    let failure = local
        .as_ref()
        .err()
        .map(|f| (f.code as u8, f.message.clone()));
    agree_code(comm, failure).map_err(|(rank, code, message)| {
        Failure::new(cadmm_result::from(code), format!("rank {rank}: {message}"))
    })?;
    local
}

/// Starts the next solve from impulses `r` of this process's contacts (`3 n_contacts`)
/// and, unless NULL, velocities `v` of its bodies (collective). Errors:
/// `CADMM_ERR_NULL_POINTER` (`r`), `CADMM_ERR_DIMENSION`, `CADMM_ERR_INVALID_VALUE`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_warm_start(
    sv: *mut cadmm_distributed_solver,
    r: *const f64,
    v: *const f64,
) -> cadmm_result {
    let body = |sv: &mut cadmm_distributed_solver| -> FfiResult {
        let (l, n) = (3 * sv.solver.n_contacts(), sv.solver.n_velocities());
        let local = (|| {
            // SAFETY: valid for `l` and `n` entries by contract.
            let r = unsafe { input("r", r, l)? };
            let v = match v.is_null() {
                true => None,
                // SAFETY: as above.
                false => Some(unsafe { input("v", v, n)? }),
            };
            Ok((r, v))
        })();
        let (r, v) = agreed(sv.solver.comm(), local)?;
        sv.solver.warm_start(r, v)?;
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
}

/// Solves (collective); `*status` receives how the solve ended, the same on every
/// process. The solve starts from `cadmm_distributed_solver_warm_start`'s point when it
/// was called since the last solve, from zero otherwise. Errors: `CADMM_ERR_NULL_POINTER` (`status`, after the solve),
/// `CADMM_ERR_NOT_POSITIVE_DEFINITE`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_solve(
    sv: *mut cadmm_distributed_solver,
    status: *mut cadmm_status,
) -> cadmm_result {
    let body = |sv: &mut cadmm_distributed_solver| -> FfiResult {
        let s = sv.solver.solve()?;
        check_ptr("status", status.cast_const())?;
        // SAFETY: checked non-NULL and aligned.
        unsafe { status.write(status_code(s)) };
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_mut(sv, body) }
}

/// Copies this process's part of the solution (not collective): impulses `r` and relative
/// velocities `u` of its contacts (`3 n_contacts` each) and velocities `v` of its bodies;
/// any may be NULL to skip it. Errors: `CADMM_ERR_NULL_POINTER` (`sv`).
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_get_solution(
    sv: *const cadmm_distributed_solver,
    r: *mut f64,
    u: *mut f64,
    v: *mut f64,
) -> cadmm_result {
    let body = |sv: &cadmm_distributed_solver| -> FfiResult {
        let s = &sv.solver;
        let parts = [(r, "r", s.r()), (u, "u", s.u()), (v, "v", s.v())];
        for (ptr, what, data) in parts {
            if !ptr.is_null() {
                check_output(what, ptr, data.len())?;
            }
        }
        for (ptr, _, data) in parts {
            if !ptr.is_null() {
                // SAFETY: checked; lengths from the part as documented.
                unsafe { write_output(ptr, data) };
            }
        }
        Ok(())
    };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_ref(sv, body) }
}

/// Fills `*out` with the statistics of the last solve (not collective; the same on every
/// process but for the timings). Set `out->struct_size = sizeof(cadmm_stats)` first.
/// Errors: `CADMM_ERR_NULL_POINTER`, `CADMM_ERR_INVALID_VALUE`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_get_stats(
    sv: *const cadmm_distributed_solver,
    out: *mut cadmm_stats,
) -> cadmm_result {
    // SAFETY: the caller's contract, forwarded.
    let body =
        |sv: &cadmm_distributed_solver| unsafe { super::solver::put_stats(out, sv.solver.stats()) };
    // SAFETY: the caller's contract, forwarded.
    unsafe { with_ref(sv, body) }
}

/// The message of the last failed call on this solver ("" when none); valid until the
/// next failing call on it. A NULL solver gets a static message saying so.
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_last_error(
    sv: *const cadmm_distributed_solver,
) -> *const c_char {
    let if_null = c"cadmm_distributed_solver_last_error: the solver pointer is NULL";
    // SAFETY: the caller's contract, forwarded.
    unsafe { last_error(sv, if_null) }
}

/// Frees a solver (NULL is a no-op). Its communicator is freed with it: call it on every
/// process, before `MPI_Finalize`.
#[no_mangle]
pub unsafe extern "C" fn cadmm_distributed_solver_free(sv: *mut cadmm_distributed_solver) {
    // SAFETY: made by `cadmm_distributed_solver_new` with Box::into_raw, released once by
    // contract.
    unsafe { release(sv) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ffi::{cadmm_settings_free, cadmm_settings_new, CADMM_ERR_PANIC, CADMM_OK};
    use std::ffi::CStr;
    use std::ptr::{null, null_mut};

    fn part() -> cadmm_rank_part {
        cadmm_rank_part {
            n_bodies: 0,
            body_ids: null(),
            body_dofs: null(),
            mass: null(),
            f: null(),
            n_contacts: 0,
            h_colptr: null(),
            h_body: null(),
            h_dof: null(),
            h_values: null(),
            w: null(),
            mu: null(),
        }
    }

    fn code(p: &cadmm_rank_part) -> (cadmm_result, String) {
        // SAFETY: every array of `p` holds what its counts say, or the count is refused
        // before the array is read (what these tests check).
        match unsafe { read_part(p) } {
            Ok(_) => (0, String::new()),
            Err(f) => (f.code, f.message),
        }
    }

    /// Counts that would size an allocation or a read are checked first: a body of 13
    /// velocities, column pointers that do not start at 0 or decrease (whose last entry
    /// would size the entry arrays), a contact count whose `3 n + 1` overflows.
    #[test]
    fn counts_are_checked_before_they_size_anything() {
        let (ids, dofs) = ([7u64], [13usize]);
        let p = cadmm_rank_part {
            n_bodies: 1,
            body_ids: ids.as_ptr(),
            body_dofs: dofs.as_ptr(),
            ..part()
        };
        let (c, m) = code(&p);
        assert_eq!(c, CADMM_ERR_INVALID_VALUE, "{m}");
        assert!(m.contains("body_dofs[0] = 13"), "{m}");

        let (w, mu) = ([0.0; 3], [0.5]);
        for (colptr, says) in [
            ([1usize, 1, 1, 1], "h_colptr[0] = 1"),
            ([0, 1_000_000_000_000, 2, 3], "decreases at column 1"),
        ] {
            let p = cadmm_rank_part {
                n_contacts: 1,
                h_colptr: colptr.as_ptr(),
                w: w.as_ptr(),
                mu: mu.as_ptr(),
                ..part()
            };
            let (c, m) = code(&p);
            assert_eq!(c, CADMM_ERR_INVALID_CSC, "{m}");
            assert!(m.contains(says), "{m}");
        }

        let p = cadmm_rank_part {
            n_contacts: usize::MAX / 3,
            ..part()
        };
        let (c, m) = code(&p);
        assert_eq!(c, CADMM_ERR_DIMENSION, "{m}");
        assert!(m.contains("n_contacts"), "{m}");
    }

    /// A panic poisons a distributed solver as it does a one-process one: after a panic
    /// injected through the boundary both handles share (handle.rs), in a call that changes
    /// the solver or in one that reads it, every call on it returns `CADMM_ERR_PANIC` at
    /// once, without communicating. Each process holds one body of 3 velocities on the
    /// ground through one contact.
    #[test]
    fn a_panic_poisons_the_distributed_solver() {
        let name = "ffi::distributed::tests::a_panic_poisons_the_distributed_solver";
        if !crate::distributed::mpirun::is_child() {
            let out = crate::distributed::mpirun::run(name, 2, &[]);
            assert_eq!(out.matches("refused after the panic").count(), 4, "{out}");
            return;
        }
        use mpi::raw::AsRaw;
        use mpi::traits::Communicator;
        let universe = mpi::initialize().expect("MPI starts");
        let world = universe.world();
        let rank = world.rank();
        let (ids, dofs, f) = ([rank as u64], [3usize], [0.0, 0.1, -1.0]);
        let mass = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let (colptr, h_body, h_dof) = ([0usize, 1, 2, 3], [ids[0]; 3], [0usize, 1, 2]);
        let (h_values, w, mu) = ([1.0; 3], [0.0; 3], [0.5]);
        let p = cadmm_rank_part {
            n_bodies: 1,
            body_ids: ids.as_ptr(),
            body_dofs: dofs.as_ptr(),
            mass: mass.as_ptr(),
            f: f.as_ptr(),
            n_contacts: 1,
            h_colptr: colptr.as_ptr(),
            h_body: h_body.as_ptr(),
            h_dof: h_dof.as_ptr(),
            h_values: h_values.as_ptr(),
            w: w.as_ptr(),
            mu: mu.as_ptr(),
        };
        // SAFETY: MPI is initialized and `world` is a live communicator.
        let comm = unsafe { mpi::ffi::RSMPI_Comm_c2f(world.as_raw()) };
        let panics: [&dyn Fn(*mut cadmm_distributed_solver) -> cadmm_result; 2] = [
            &|sv| unsafe { with_mut(sv, |_| panic!("injected in a change")) },
            &|sv| unsafe { with_ref(sv, |_| panic!("injected in a read")) },
        ];
        // SAFETY (every call below): live handles and arrays of the lengths documented.
        unsafe {
            let mut s = null_mut();
            assert_eq!(cadmm_settings_new(&mut s), CADMM_OK);
            for panic_in in panics {
                let mut sv = null_mut();
                assert_eq!(cadmm_distributed_solver_new(comm, &p, s, &mut sv), CADMM_OK);
                let mut status = -1;
                assert_eq!(cadmm_distributed_solver_solve(sv, &mut status), CADMM_OK);
                assert_eq!(panic_in(sv), CADMM_ERR_PANIC);
                let (mut r, mut stats) = ([7.0; 3], cadmm_stats::default());
                stats.struct_size = std::mem::size_of::<cadmm_stats>();
                let rcs = [
                    cadmm_distributed_solver_warm_start(sv, r.as_ptr(), null()),
                    cadmm_distributed_solver_warm_start(sv, null(), null()),
                    cadmm_distributed_solver_solve(sv, &mut status),
                    cadmm_distributed_solver_get_solution(
                        sv,
                        r.as_mut_ptr(),
                        null_mut(),
                        null_mut(),
                    ),
                    cadmm_distributed_solver_get_stats(sv, &mut stats),
                ];
                assert_eq!(rcs, [CADMM_ERR_PANIC; 5]);
                assert_eq!((r, stats.iterations), ([7.0; 3], 0), "nothing written");
                let text = CStr::from_ptr(cadmm_distributed_solver_last_error(sv));
                let text = text.to_str().unwrap();
                assert!(text.starts_with("the solver is unusable after"), "{text}");
                assert!(text.contains("injected"), "{text}");
                println!("rank {rank}: refused after the panic: {text}");
                cadmm_distributed_solver_free(sv);
            }
            cadmm_settings_free(s);
        }
    }
}
