//! The outcome of a solve.

/// Outcome of a solve that ran (a solve that could not run returns an [`Error`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub enum Status {
    /// The error measure reached the tolerance.
    Solved = 0,
    /// The iteration limit was reached first; the best iterate the last ADMM run measured
    /// is kept.
    MaxIterations = 1,
    /// The time limit was reached first; as for `MaxIterations`, the best measured iterate
    /// is kept.
    TimeLimit = 2,
    /// An iterate became non-finite; the best iterate the run measured is kept (the last
    /// finite one when none was measured).
    NumericalError = 3,
    /// The method stopped making progress before the tolerance (only the `newton` variant,
    /// which has no ADMM to fall back on); its best iterate is kept.
    Stalled = 4,
    /// The problem has no solution: some contact's normal relative velocity cannot change
    /// (its normal column of H, or its normal row of W, is zero; or, with islands, all its
    /// columns of H are empty) and it approaches (docs/algorithms.md §12), or the impulses
    /// grew along a direction that pushes no body against approaching velocities, which
    /// certifies it (§13). The solution returned is not one; its error is measured.
    Infeasible = 5,
    /// No solve has run yet (the statistics of a new solver).
    Unsolved = 6,
}

impl Status {
    /// Lower-case name used by the command line tool and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Status::Solved => "solved",
            Status::MaxIterations => "max_iterations",
            Status::TimeLimit => "time_limit",
            Status::NumericalError => "numerical_error",
            Status::Stalled => "stalled",
            Status::Infeasible => "infeasible",
            Status::Unsolved => "unsolved",
        }
    }
}
