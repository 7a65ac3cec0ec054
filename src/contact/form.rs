//! What the solver asks of a contact problem form ([`ContactForm`]), and the pieces of the
//! De Saxce shift and of the system's rows that both forms share.

use crate::admm::{EngineState, Splitting};
use crate::cone::{de_saxce_term, get3, set3};
use crate::measure::Floors;
use crate::newton::NewtonOutcome;
use crate::problem::{NewValues, Problem, ProblemRef};
use crate::types::Error;
use crate::types::Solution;
use std::time::Instant;

/// A contact problem form as the solver drives it: the engine's [`Splitting`] plus what
/// the solver needs around a solve.
pub(crate) trait ContactForm: Splitting + Send {
    /// Takes new values on the same sizes and patterns (numeric refactorization only);
    /// a problem of the other form or other sizes is an error.
    fn update(&mut self, p: Problem) -> Result<(), Error>;
    /// Takes new values in place (same patterns): scattered into the kept system matrix,
    /// no sorting, no allocation; the caller then calls [`ContactForm::ready_for`].
    fn update_values(&mut self, v: &NewValues) -> Result<(), Error>;
    /// After new values: refactorizes for `rho` where the factorization can fail and the
    /// update must say so; a form may defer what cannot fail to the solve's first
    /// [`Splitting::set_rho`].
    fn ready_for(&mut self, rho: f64) -> Result<(), Error> {
        self.set_rho(rho)
    }
    /// The problem as the form holds it now.
    fn problem(&self) -> ProblemRef<'_>;
    /// Cold start: zero iterate, initial De Saxce shift.
    fn cold_start(&mut self, state: &mut EngineState);
    /// The short cut of a problem whose contacts all separate under the free motion: when
    /// the free velocity (`r = 0`) has a non-negative normal component at every contact,
    /// `r = 0` solves the problem exactly; this makes it the iterate and returns true (no
    /// contact, in particular). Otherwise returns false and leaves the engine state alone.
    /// A form that cannot afford the free velocity says false.
    fn separating(&mut self, state: &mut EngineState) -> bool;
    /// Warm start from impulses `r` (finite, checked) and, global form only, velocities
    /// `v` (checked here).
    fn warm_start(
        &mut self,
        r: &[f64],
        v: Option<&[f64]>,
        state: &mut EngineState,
    ) -> Result<(), Error>;
    /// Re-derives the form's own iterate (velocity, multipliers) from the engine state,
    /// after a step that went non-finite left it behind.
    fn recover(&mut self, state: &EngineState) -> Result<(), Error>;
    /// Writes the solution at the engine state into `out`, reusing its vectors.
    fn write_solution(&self, state: &EngineState, out: &mut Solution);
    /// Floors of the error measure's denominators (an island's share of a scene's measure,
    /// docs/algorithms.md §12), for ADMM and the Newton phase alike.
    fn set_measure_floors(&mut self, floors: Floors);
    /// Rows of the contact space in the linear systems (`3 nc`, less two per frictionless
    /// contact).
    fn rows(&self) -> usize;
    /// Length of the constraint space the engine iterates over: the contacts' rows, then
    /// the joint rows the v-update system leaves to the splitting.
    fn space(&self) -> usize;
    /// A contact whose normal relative velocity no impulse can change (its normal column
    /// of H, or its normal row of W, is zero) and which approaches there (`w_N < 0`, or
    /// `q_N < 0`): Coulomb's law needs `u_N >= 0`, so the problem has no solution.
    fn blocked_contact(&self) -> Option<usize>;
    /// True when the impulses at the engine state certify that the problem has no
    /// solution ([`crate::certificate`]): they grew along a null direction of the
    /// operator against approaching velocities.
    fn certifies_infeasibility(&self, state: &EngineState) -> bool;
    /// Numeric factorizations so far.
    fn refactorizations(&self) -> usize;
    /// True when the v-update is solved matrix-free: the Newton phase, whose systems are
    /// factorized, is then left out.
    fn matrix_free(&self) -> bool {
        false
    }
    /// Threads the form's linear algebra may use (the matrix-free products of a problem
    /// solved whole); the results do not depend on it.
    fn set_threads(&mut self, _threads: usize) {}
    /// Conjugate-gradient iterations of the matrix-free backend so far.
    fn linear_iterations(&self) -> usize {
        0
    }
    /// The Newton phase from the iterate in `state`: when it ends below the error of its
    /// start, its best iterate becomes the form's iterate and a warm start in `state` that
    /// ADMM can resume from. The Newton solver is built on first use.
    fn polish(
        &mut self,
        state: &mut EngineState,
        tol: f64,
        max_steps: usize,
        deadline: Option<Instant>,
    ) -> Result<NewtonOutcome, Error>;
}

/// De Saxce shift of each contact's normal component: `mu ||u_T||`, written into `phi`
/// (normal slots only).
pub(crate) fn de_saxce_shift(u: &[f64], mu: &[f64], phi: &mut [f64]) {
    for (i, &m) in mu.iter().enumerate() {
        set3(phi, i, [de_saxce_term(get3(u, i), m), 0.0, 0.0]);
    }
}

/// Which rows of the contact space take part in the linear systems, as factors 1 or 0.
/// When every contact is frictionless (`mu = 0`), each keeps its normal row only: its
/// impulse is normal (`K_0` is the normal half-line) and its tangential velocity is free
/// (`K*_0` is the half-space `u_N >= 0`), so the tangential rows constrain nothing; leaving
/// them out of `M + rho H H^T` (`W + rho I`) is exactly ADMM on the quadratic program
/// without them, while the rows stay in the engine's vectors, where they remain inert
/// (docs/algorithms.md §12). With frictional contacts beside them, all rows stay: without
/// the frictionless rows' proximal term the internal De Saxce update diverged on a scene
/// mixing mu = 0 and mu = 1e3 (extreme suite, `mixed-mu`), with every variant.
pub(super) fn active_rows(mu: &[f64]) -> Vec<f64> {
    let tangential = if mu.iter().all(|&m| m == 0.0) {
        0.0
    } else {
        1.0
    };
    mu.iter()
        .flat_map(|_| [1.0, tangential, tangential])
        .collect()
}

/// True when a contact whose tangential rows were left out is no longer frictionless:
/// the systems must be built again with its rows.
pub(super) fn rows_missing(active: &[f64], mu: &[f64]) -> bool {
    mu.iter()
        .enumerate()
        .any(|(i, &m)| m > 0.0 && active[3 * i + 1] == 0.0)
}

/// Number of rows taking part in the systems.
pub(super) fn count_rows(active: &[f64]) -> usize {
    active.iter().filter(|&&a| a != 0.0).count()
}

/// Initial shift (docs/algorithms.md §5): `Phi(1) / (||Phi(1)|| ||A||_F)`, where `A` is `H`
/// (global) or `W` (local).
pub(super) fn initial_shift(mu: &[f64], frobenius: f64, phi: &mut [f64]) {
    let norm_mu = mu.iter().map(|m| m * m).sum::<f64>().sqrt();
    initial_shift_of(mu, norm_mu, frobenius, phi);
}

/// [`initial_shift`] with `||mu||` given (a distributed problem's, summed across
/// processes).
pub(crate) fn initial_shift_of(mu: &[f64], norm_mu: f64, frobenius: f64, phi: &mut [f64]) {
    phi.fill(0.0);
    if norm_mu == 0.0 || frobenius == 0.0 {
        return;
    }
    for (i, &m) in mu.iter().enumerate() {
        phi[3 * i] = m / (norm_mu * frobenius);
    }
}

/// Contact `i`'s point the global form's y-step projects: `(A x - c + zeta)_i`.
pub(crate) fn prox_input(ax: &[f64], c: &[f64], zeta: &[f64], i: usize) -> [f64; 3] {
    let (a, c, z) = (get3(ax, i), get3(c, i), get3(zeta, i));
    [a[0] - c[0] + z[0], a[1] - c[1] + z[1], a[2] - c[2] + z[2]]
}

/// Rejects a vector of the wrong length or with a non-finite entry.
pub(crate) use crate::problem::check_len as check_vector;
