//! The interface of a v-update system ([`VelocitySystem`]), and what a one-process system
//! adds to it ([`ProblemSystem`]).

use super::own_problem::OwnProblem;
use crate::bounded_rows::BoundedRows;
use crate::linsys::PcgStop;
use crate::problem::GlobalProblem;
use crate::settings::LinearSolver;
use crate::tuning::{
    PCG_ERROR_SHARE, PCG_FIRST_RELATIVE, PCG_MAX_ITERATIONS, PCG_REDUCTION, PCG_RELATIVE_FLOOR,
};
use crate::types::Error;
use std::time::Instant;

/// The contact data the global splitting reads beside its system: the free velocities'
/// right-hand side is the system's business, the contacts' `w` and `mu` are the
/// splitting's (one process: the whole problem's; many: this process's contacts').
pub(crate) trait ContactData {
    /// `w`, 3 per contact.
    fn w(&self) -> &[f64];
    /// Friction coefficients, 1 per contact.
    fn mu(&self) -> &[f64];
    /// The joint rows with a finite bound, which the splitting holds after the contacts'
    /// rows (none by default: the system then has none either).
    fn bounded(&self) -> BoundedRows {
        BoundedRows::default()
    }
}

impl ContactData for GlobalProblem {
    fn w(&self) -> &[f64] {
        &self.w
    }

    fn mu(&self) -> &[f64] {
        &self.mu
    }

    fn bounded(&self) -> BoundedRows {
        BoundedRows::of(self)
    }
}

/// How exactly an x-step solves when the backend is inexact: from the last error measured
/// (infinite before the first) and within the solve's wall-clock limit.
#[derive(Clone, Copy)]
pub(crate) struct Accuracy {
    pub last_error: f64,
    pub deadline: Option<Instant>,
}

/// One v-update system, as the global splitting uses it. `p` is what the system was built
/// from ([`VelocitySystem::Data`]), held by the splitting and handed back at each call.
pub(crate) trait VelocitySystem {
    /// The problem (one process) or the process's part (many) the system is built from.
    type Data: ContactData;

    /// Makes `rho` the current penalty; when `changed`, first takes the values now in `p`
    /// and the rows `active` marks (new values, screened contacts).
    fn set_rho(
        &mut self,
        p: &Self::Data,
        rho: f64,
        active: &[f64],
        changed: bool,
    ) -> Result<(), Error>;

    /// The x-step: `sol` (velocities, then one entry per joint row) from `f + H t` and the
    /// joints' `-b`, and `ax = H^T v`; with bounded joint rows, `t` and `ax` go on past the
    /// contacts' rows with those rows' (`G_k^T v` in `ax`). `sol` holds the last iterate, which an inexact
    /// backend starts from.
    fn x_step(
        &mut self,
        p: &Self::Data,
        t: &[f64],
        sol: &mut [f64],
        ax: &mut [f64],
        accuracy: Accuracy,
    );

    /// `u = H^T v + w` over the contacts.
    fn contact_velocity(&mut self, p: &Self::Data, v: &[f64], u: &mut [f64]) {
        self.h_t_mul(p, v, u);
        for (u, w) in u.iter_mut().zip(p.w()) {
            *u += w;
        }
    }

    /// `out = H^T v`.
    fn h_t_mul(&mut self, p: &Self::Data, v: &[f64], out: &mut [f64]);

    /// `||H t||` (over every process).
    fn h_norm(&mut self, p: &Self::Data, t: &[f64]) -> f64;

    /// The error measure (docs/algorithms.md §3) at impulses `r` (then the bounded joint
    /// rows' multipliers) and the iterate `sol`
    /// (over every process; infinite when some vector is not finite).
    fn measure(&mut self, p: &Self::Data, r: &[f64], sol: &[f64]) -> f64;

    /// Adds each entry of `partial` up over the processes (one process: nothing to add).
    fn sum_across(&self, _partial: &mut [f64]) {}

    /// Numeric factorizations so far.
    fn refactorizations(&self) -> usize;

    /// Conjugate-gradient iterations so far (0 when factorized).
    fn linear_iterations(&self) -> usize {
        0
    }
}

/// What a one-process system adds: it answers for the whole problem, so it also checks M,
/// gives the free motion and keeps the measure's floors, all through its [`OwnProblem`].
pub(crate) trait ProblemSystem: VelocitySystem<Data = GlobalProblem> + Send {
    /// What the system keeps of the problem beside its matrix.
    fn own(&mut self) -> &mut OwnProblem;

    /// The backend, which a rebuild keeps.
    fn backend(&self) -> LinearSolver;

    /// Multiply-adds of one factorization of the system and the entries of its factor,
    /// when it is a sparse Cholesky (`None` otherwise: dense, LU, or not factorized).
    fn sparse_cholesky_cost(&self) -> Option<(f64, usize)> {
        None
    }

    /// Threads the products may use (the results do not depend on them).
    fn set_threads(&mut self, _threads: usize) {}

    /// The joint rows the splitting holds beside the contacts' (after them, in this
    /// order): the bounded ones, the system keeping the equalities exact.
    fn splitting_rows(&self, p: &GlobalProblem) -> BoundedRows {
        BoundedRows::of(p)
    }
}

impl<T: VelocitySystem + ?Sized> VelocitySystem for Box<T> {
    type Data = T::Data;

    fn set_rho(
        &mut self,
        p: &T::Data,
        rho: f64,
        active: &[f64],
        changed: bool,
    ) -> Result<(), Error> {
        (**self).set_rho(p, rho, active, changed)
    }

    fn x_step(&mut self, p: &T::Data, t: &[f64], sol: &mut [f64], ax: &mut [f64], a: Accuracy) {
        (**self).x_step(p, t, sol, ax, a)
    }

    fn contact_velocity(&mut self, p: &T::Data, v: &[f64], u: &mut [f64]) {
        (**self).contact_velocity(p, v, u)
    }

    fn h_t_mul(&mut self, p: &T::Data, v: &[f64], out: &mut [f64]) {
        (**self).h_t_mul(p, v, out)
    }

    fn h_norm(&mut self, p: &T::Data, t: &[f64]) -> f64 {
        (**self).h_norm(p, t)
    }

    fn measure(&mut self, p: &T::Data, r: &[f64], sol: &[f64]) -> f64 {
        (**self).measure(p, r, sol)
    }

    fn sum_across(&self, partial: &mut [f64]) {
        (**self).sum_across(partial)
    }

    fn refactorizations(&self) -> usize {
        (**self).refactorizations()
    }

    fn linear_iterations(&self) -> usize {
        (**self).linear_iterations()
    }
}

/// When an inexact backend stops (docs/algorithms.md §14): once the residual
/// `||b - A v||` of its warm start has shrunk by [`PCG_REDUCTION`], so that the error of
/// each inexact step is a fraction of the step itself (which goes to zero as ADMM
/// converges: the errors stay summable, as inexact ADMM needs); or once it is below a
/// tenth of the last measured error (`equation_scale`: the measure's equation
/// denominator), which that residual adds to: then it no longer matters for the
/// tolerance. The error measured at the end is of the inexact iterate, so it stays honest
/// either way.
pub(crate) fn inexact_stop(accuracy: Accuracy, equation_scale: f64, rhs_norm: f64) -> PcgStop {
    let tol = if accuracy.last_error.is_finite() {
        PCG_ERROR_SHARE * accuracy.last_error * equation_scale
    } else {
        PCG_FIRST_RELATIVE * rhs_norm
    };
    PcgStop {
        tol,
        reduction: PCG_REDUCTION,
        floor: PCG_RELATIVE_FLOOR * rhs_norm,
        max_iterations: PCG_MAX_ITERATIONS,
        deadline: accuracy.deadline,
    }
}
