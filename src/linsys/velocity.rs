//! The v-update system of the global form, behind one interface (docs/algorithms.md §4,
//! §14, §16): `(M + rho H D H^T) v = f + H t` (with joints, the quasi-definite system around
//! it when factorized, the joints' columns beside H's when matrix-free), where `t` is the
//! x-step's contact-space vector and `D` marks the rows in the system.
//! Three backends implement it: the factorized system ([`FactorizedSystem`]), the
//! matrix-free one ([`MatrixFreeSystem`]), and the system shared over processes
//! (`distributed::DistributedGram`). The global splitting drives each the same way.

mod factorized;
mod matrix_free;
mod own_problem;
mod system;

use crate::linsys::{Factor, GramPcg};
use crate::problem::GlobalProblem;
use crate::settings::LinearSolver;
use crate::tuning::{FACTOR_MAX_ENTRIES, MATRIX_FREE_MIN_FILL, PCG_EXPECTED_ITERATIONS};
use crate::types::Error;
use factorized::FactorizedSystem;
use matrix_free::MatrixFreeSystem;
use own_problem::OwnProblem;
#[cfg(feature = "mpi")]
pub(crate) use system::inexact_stop;
pub(crate) use system::{Accuracy, ContactData, ProblemSystem, VelocitySystem};

/// The one-process system `choice` asks for. `Auto` (docs/algorithms.md §14) factorizes
/// unless the system is large and the symbolic analysis predicts a factor whose two
/// triangular solves cost more than the expected conjugate-gradient products, or a factor
/// too large for memory. A non-symmetric M stays direct, and so do joints unless their
/// factor is too large for memory. M alone is factorized first: a clear error when it is
/// not positive definite.
pub(crate) fn problem_system(
    p: &GlobalProblem,
    active: &[f64],
    choice: LinearSolver,
) -> Result<Box<dyn ProblemSystem>, Error> {
    let own = OwnProblem::new(p)?;
    // Checked before anything is assembled: the matrix-free backend never forms the matrix.
    let eligible = GramPcg::fits(MatrixFreeSystem::gram(p, active));
    if eligible && choice == LinearSolver::Iterative {
        return Ok(Box::new(MatrixFreeSystem::new(p, active, own)));
    }
    let direct = FactorizedSystem::new(p, active, own)?;
    if eligible && choice == LinearSolver::Auto && matrix_free_pays(p, &direct.factor) {
        return Ok(Box::new(MatrixFreeSystem::new(p, active, direct.own)));
    }
    Ok(Box::new(direct))
}

/// The cost model of `Auto`: per v-update, two triangular solves read the factor twice;
/// conjugate gradients take about [`PCG_EXPECTED_ITERATIONS`] products with `M`, `H` and
/// `H^T` each (plus the block preconditioner, about as much as M). Below
/// [`MATRIX_FREE_MIN_FILL`] the factor stays: the Newton phase it keeps is worth more.
fn matrix_free_pays(p: &GlobalProblem, factor: &Factor) -> bool {
    let Some(fill) = factor.stored_entries() else {
        return false;
    };
    if p.n_joints() > 0 {
        // Joint rows: the factor keeps the equalities exact and the Newton phase; only a
        // factor too large for memory gives way.
        return fill > FACTOR_MAX_ENTRIES;
    }
    if fill < MATRIX_FREE_MIN_FILL {
        return false;
    }
    let direct = 2.0 * fill as f64;
    let product = 2.0 * p.m.nnz() as f64 + 2.0 * p.h.nnz() as f64;
    let iterative = PCG_EXPECTED_ITERATIONS * product;
    direct > iterative || fill > FACTOR_MAX_ENTRIES
}
