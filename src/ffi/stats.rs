//! `cadmm_stats` and `cadmm_trace_point`: what a solve reports.

use super::result::{cadmm_status, status_code};
use crate::types::{Phase, Stats, TracePoint};
use std::mem::{offset_of, size_of};

/// Summary of the last solve, filled by `cadmm_solver_get_stats`.
///
/// Set `struct_size` to `sizeof(cadmm_stats)` before the call: the library writes only the
/// fields that fit in `struct_size` bytes, so a program built against an older, shorter
/// version of this struct keeps working when fields are appended. `struct_size` must cover
/// at least the fields up to `solve_seconds` (`offsetof(cadmm_stats, anderson_accepted)`).
/// Before the first solve, `status` is `CADMM_STATUS_UNSOLVED`, `iterations` 0 and
/// the residuals infinite, while `rho`, `refactorizations` and `setup_seconds` describe the
/// setup.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct cadmm_stats {
    /// Size of this struct as the caller knows it: set by the caller, never written.
    pub struct_size: usize,
    /// Outcome of the last solve (`CADMM_STATUS_*`).
    pub status: cadmm_status,
    /// Iterations done: ADMM iterations and semismooth Newton steps.
    pub iterations: u64,
    /// Final error measure (docs/algorithms.md §3).
    pub error: f64,
    /// Final primal residual.
    pub primal_residual: f64,
    /// Final dual residual.
    pub dual_residual: f64,
    /// Final penalty rho.
    pub rho: f64,
    /// Numeric factorizations done so far (setup and solves).
    pub refactorizations: u64,
    /// Seconds spent building the solver (symbolic and first numeric factorization).
    pub setup_seconds: f64,
    /// Seconds spent in the last solve.
    pub solve_seconds: f64,
    /// Anderson acceleration steps accepted in the last solve.
    pub anderson_accepted: u64,
    /// Anderson acceleration steps rejected by the safeguard in the last solve.
    pub anderson_rejected: u64,
    /// Of `iterations`, the semismooth Newton steps of the last solve.
    pub newton_iterations: u64,
    /// Numeric factorizations of the Newton phases of the last solve.
    pub newton_factorizations: u64,
    /// Newton phases run in the last solve.
    pub newton_phases: u64,
    /// Newton phases that ended above the tolerance, after which ADMM resumed.
    pub newton_fallbacks: u64,
    /// Contact islands the problem was solved as (1 when islands are off or the problem is
    /// one island, 0 without contacts); read each with `cadmm_solver_get_island_stats`.
    pub islands: u64,
    /// The first island that ended unsolved when the solve is not solved because of one,
    /// otherwise -1.
    pub failed_island: i64,
    /// Rows of the contact space in the linear systems: `3 nc`, less two for each
    /// contact of an island whose contacts are all frictionless.
    pub rows: u64,
    /// Conjugate-gradient iterations of the matrix-free v-updates (0 when the systems are
    /// factorized; see `cadmm_settings_set_linear_solver`).
    pub linear_iterations: u64,
    /// Gauss-Seidel sweeps of a solver built with a time limit (not counted in
    /// `iterations`; 0 otherwise).
    pub gauss_seidel_sweeps: u64,
}

/// Smallest `struct_size` accepted: the fields up to and including `solve_seconds`.
pub(crate) const STATS_MIN_SIZE: usize = offset_of!(cadmm_stats, anderson_accepted);

impl From<&Stats> for cadmm_stats {
    fn from(s: &Stats) -> Self {
        Self {
            struct_size: size_of::<Self>(),
            status: status_code(s.status),
            iterations: s.iterations as u64,
            error: s.error,
            primal_residual: s.primal_residual,
            dual_residual: s.dual_residual,
            rho: s.rho,
            refactorizations: s.refactorizations as u64,
            setup_seconds: s.setup_seconds,
            solve_seconds: s.solve_seconds,
            anderson_accepted: s.anderson_accepted as u64,
            anderson_rejected: s.anderson_rejected as u64,
            newton_iterations: s.newton_iterations as u64,
            newton_factorizations: s.newton_factorizations as u64,
            newton_phases: s.newton_phases as u64,
            newton_fallbacks: s.newton_fallbacks as u64,
            islands: s.islands as u64,
            failed_island: s.failed_island.map_or(-1, |k| k as i64),
            rows: s.rows as u64,
            linear_iterations: s.linear_iterations as u64,
            gauss_seidel_sweeps: s.gauss_seidel_sweeps as u64,
        }
    }
}

/// Writes one field of `src` into the caller's struct at `dst` if it lies entirely within
/// the caller's `size` bytes.
///
/// # Safety
/// `dst` must be valid for writes of `size` bytes and aligned for `cadmm_stats`.
unsafe fn put_field<T: Copy>(dst: *mut cadmm_stats, size: usize, offset: usize, value: T) {
    if offset + size_of::<T>() <= size {
        // SAFETY: within the caller's `size` bytes; the offset comes from offset_of! so the
        // field is aligned when the struct is.
        unsafe { dst.cast::<u8>().add(offset).cast::<T>().write(value) };
    }
}

/// Writes the fields of `src` that fit in `size` bytes (the caller's `struct_size`),
/// leaving `struct_size` and any byte past `size_of::<cadmm_stats>()` untouched.
///
/// # Safety
/// As for [`put_field`].
pub(crate) unsafe fn write_stats(dst: *mut cadmm_stats, size: usize, src: &cadmm_stats) {
    macro_rules! put {
        ($($field:ident),*) => {
            // SAFETY: forwarded from this function's contract.
            $(unsafe { put_field(dst, size, offset_of!(cadmm_stats, $field), src.$field) };)*
        };
    }
    put!(
        status,
        iterations,
        error,
        primal_residual,
        dual_residual,
        rho,
        refactorizations,
        setup_seconds,
        solve_seconds,
        anderson_accepted,
        anderson_rejected,
        newton_iterations,
        newton_factorizations,
        newton_phases,
        newton_fallbacks,
        islands,
        failed_island,
        rows,
        linear_iterations,
        gauss_seidel_sweeps
    );
}

/// One recorded iteration of the last solve (see `cadmm_settings_set_trace`); its phase is
/// read by `cadmm_solver_get_trace_phase`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct cadmm_trace_point {
    /// Iteration number (1-based).
    pub iteration: u64,
    /// Seconds since the start of the solve.
    pub seconds: f64,
    /// Error measure at this iteration.
    pub error: f64,
    /// Primal residual.
    pub primal_residual: f64,
    /// Dual residual.
    pub dual_residual: f64,
    /// Penalty rho used in this iteration.
    pub rho: f64,
}

impl From<&TracePoint> for cadmm_trace_point {
    fn from(t: &TracePoint) -> Self {
        Self {
            iteration: t.iteration as u64,
            seconds: t.seconds,
            error: t.error,
            primal_residual: t.primal_residual,
            dual_residual: t.dual_residual,
            rho: t.rho,
        }
    }
}

/// The phase a trace point belongs to, written by `cadmm_solver_get_trace_phase`: one of
/// the `CADMM_PHASE_*` values. A plain integer like `cadmm_result`.
pub type cadmm_phase = i32;

/// An ADMM iteration.
pub const CADMM_PHASE_ADMM: cadmm_phase = 0;
/// The end of a semismooth Newton phase (its point has NaN residuals).
pub const CADMM_PHASE_NEWTON: cadmm_phase = 1;

/// The C code of a [`Phase`].
pub(crate) fn phase_code(phase: Phase) -> cadmm_phase {
    match phase {
        Phase::Admm => CADMM_PHASE_ADMM,
        Phase::Newton => CADMM_PHASE_NEWTON,
    }
}
