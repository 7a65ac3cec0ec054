//! Summary statistics of a solve and the optional per-iteration trace.

use super::Status;

/// Summary of the last solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    /// Outcome.
    pub status: Status,
    /// Iterations done: ADMM iterations and semismooth Newton steps (with several islands,
    /// those of the island that needed the most; the residuals and rho are that island's,
    /// the counts of factorizations, Anderson and Newton steps are summed over islands).
    pub iterations: usize,
    /// Final error measure (docs/algorithms.md §3).
    pub error: f64,
    /// Final primal residual `||A x - y - c||`.
    pub primal_residual: f64,
    /// Final dual residual `rho ||A^T (y - y_prev)||`.
    pub dual_residual: f64,
    /// Final penalty.
    pub rho: f64,
    /// Numeric factorizations done (setup and solve).
    pub refactorizations: usize,
    /// Anderson steps accepted.
    pub anderson_accepted: usize,
    /// Anderson steps rejected by the safeguard.
    pub anderson_rejected: usize,
    /// Of `iterations`, the semismooth Newton steps.
    pub newton_iterations: usize,
    /// Numeric factorizations of the Newton phases (not in `refactorizations`).
    pub newton_factorizations: usize,
    /// Newton phases run.
    pub newton_phases: usize,
    /// Newton phases that ended above the tolerance, after which ADMM resumed.
    pub newton_fallbacks: usize,
    /// Seconds spent building the solver (symbolic and first numeric factorization).
    pub setup_seconds: f64,
    /// Rows of the contact space in the linear systems: `3 nc`, less two for each
    /// contact of an island whose contacts are all frictionless (docs/algorithms.md §12).
    pub rows: usize,
    /// Contact islands the problem was solved as (1 when islands are off or the problem
    /// is one coupled island; 0 without contacts).
    pub islands: usize,
    /// The first island (in [`crate::Solver::island_stats`] order) that ended unsolved,
    /// when the solve is not solved because of one.
    pub failed_island: Option<usize>,
    /// Seconds spent in the last solve.
    pub solve_seconds: f64,
    /// Conjugate-gradient iterations of the matrix-free v-updates (0 when the systems are
    /// factorized; see [`crate::LinearSolver`]).
    pub linear_iterations: usize,
    /// Gauss-Seidel sweeps of a solver built with a time limit (docs/algorithms.md §17;
    /// 0 otherwise), not counted in `iterations`.
    pub gauss_seidel_sweeps: usize,
}

impl Default for Stats {
    fn default() -> Self {
        Self {
            status: Status::Unsolved,
            iterations: 0,
            error: f64::INFINITY,
            primal_residual: f64::INFINITY,
            dual_residual: f64::INFINITY,
            rho: f64::NAN,
            refactorizations: 0,
            anderson_accepted: 0,
            anderson_rejected: 0,
            newton_iterations: 0,
            newton_factorizations: 0,
            newton_phases: 0,
            newton_fallbacks: 0,
            setup_seconds: 0.0,
            rows: 0,
            islands: 0,
            failed_island: None,
            solve_seconds: 0.0,
            linear_iterations: 0,
            gauss_seidel_sweeps: 0,
        }
    }
}

impl Stats {
    /// The counts that add up over the parts of a solve (islands, processes):
    /// factorizations, rows, Anderson, Newton and conjugate-gradient counts.
    pub(crate) fn part_counts(&self) -> [usize; 9] {
        [
            self.refactorizations,
            self.rows,
            self.anderson_accepted,
            self.anderson_rejected,
            self.newton_iterations,
            self.newton_factorizations,
            self.newton_phases,
            self.newton_fallbacks,
            self.linear_iterations,
        ]
    }

    /// Sets the counts [`Stats::part_counts`] lists.
    pub(crate) fn set_part_counts(&mut self, counts: [usize; 9]) {
        [
            self.refactorizations,
            self.rows,
            self.anderson_accepted,
            self.anderson_rejected,
            self.newton_iterations,
            self.newton_factorizations,
            self.newton_phases,
            self.newton_fallbacks,
            self.linear_iterations,
        ] = counts;
    }

    /// Adds the counts of a part of the solve (an island) to these.
    pub(crate) fn add_part(&mut self, part: &Stats) {
        let mut counts = self.part_counts();
        for (c, p) in counts.iter_mut().zip(part.part_counts()) {
            *c += p;
        }
        self.set_part_counts(counts);
    }

    /// Adds a later solve of the same part: its iterations, work and time add up; the
    /// counters its solver keeps over its life (factorizations, rows), the setup time and
    /// the final values are the later solve's.
    pub(crate) fn add_solve(&mut self, later: &Stats) {
        let mut next = Stats {
            iterations: self.iterations + later.iterations,
            solve_seconds: self.solve_seconds + later.solve_seconds,
            setup_seconds: self.setup_seconds,
            ..*later
        };
        let [refactorizations, rows, ..] = later.part_counts();
        next.add_part(self);
        next.refactorizations = refactorizations;
        next.rows = rows;
        *self = next;
    }
}

/// Which phase of the solve an iteration belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Phase {
    /// An ADMM iteration.
    #[default]
    Admm,
    /// The end of a semismooth Newton phase (one point per phase).
    Newton,
}

/// One recorded iteration (only when the trace is switched on).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracePoint {
    /// Iteration number (1-based).
    pub iteration: usize,
    /// Seconds since the start of the solve.
    pub seconds: f64,
    /// Error measure at this iteration.
    pub error: f64,
    /// Primal residual.
    pub primal_residual: f64,
    /// Dual residual.
    pub dual_residual: f64,
    /// Penalty used in this iteration.
    pub rho: f64,
    /// Anderson steps accepted so far in this solve.
    pub anderson_accepted: usize,
    /// Anderson steps rejected so far in this solve.
    pub anderson_rejected: usize,
    /// The phase: an ADMM iteration, or the end of a Newton phase (whose `iteration`
    /// counts its steps with the ADMM iterations before it; residuals are NaN there).
    pub phase: Phase,
}
