//! The x-update linear systems: `A(rho) = base + rho * slope` with a fixed sparsity
//! pattern (`M + rho H H^T`, `W + rho I`, or the quasi-definite joint system). Large ones
//! are factorized with faer: the symbolic analysis (AMD ordering) is done once; a change of
//! rho only refactorizes numerically, and the last few numeric factors are kept so that a
//! rho rule that oscillates between two values does not refactorize back and forth. Small
//! ones (an island of a few contacts) are factorized densely.
//!
//! Beside them, the other factorizations of the solver: [`BlockDiagonal`], symmetric
//! positive definite matrices made of small dense blocks (a mass matrix, the block Jacobi
//! preconditioner of the iterative backend, a small island's M), and [`Lu`], LU with
//! partial pivoting on a fixed pattern (the Newton systems). Their dense kernels are in
//! [`crate::dense`].

mod block_diagonal;
mod contact_columns;
mod dense_factor;
mod gram_product;
mod lu;
pub mod param_matrix;
mod pcg;
mod sparse_factor;
pub(crate) mod velocity;
mod workers;

pub use crate::tuning::DENSE_MAX;
pub use block_diagonal::BlockDiagonal;
pub(crate) use contact_columns::ContactRows;
use dense_factor::DenseFactor;
pub use gram_product::GramProduct;
pub(crate) use lu::{Lu, LuFactors, PatternRef};
pub use param_matrix::ParamMatrix;
pub use pcg::{Gram, GramPcg, PcgStop};
pub use sparse_factor::{FactorKind, SparseFactor};
// What the distributed v-update system shares with one process's iterative backend.
#[cfg(feature = "mpi")]
pub(crate) use crate::tuning::BLOCK_MAX;
#[cfg(feature = "mpi")]
pub(crate) use contact_columns::ContactColumns;
#[cfg(feature = "mpi")]
pub(crate) use pcg::{conjugate_gradients, CgSystem, CgWork, PcgOutcome};
#[cfg(feature = "mpi")]
pub(crate) use workers::Workers;

use crate::types::Error;
use param_matrix::Assembly;

/// The factorization of one system: dense up to [`DENSE_MAX`] unknowns, sparse above.
pub enum Factor {
    /// Dense, in place.
    Dense(DenseFactor),
    /// Sparse, with faer.
    Sparse(SparseFactor),
}

impl Factor {
    /// Prepares the factorization of `matrix` (`name` labels it in errors); the first
    /// numeric factorization happens at the first [`Factor::set_rho`].
    pub fn new(name: &'static str, matrix: ParamMatrix, kind: FactorKind) -> Result<Self, Error> {
        Ok(if matrix.n <= DENSE_MAX {
            Factor::Dense(DenseFactor::new(name, matrix, kind))
        } else {
            Factor::Sparse(SparseFactor::new(name, matrix, kind)?)
        })
    }

    /// Number of numeric factorizations done so far.
    pub fn refactorizations(&self) -> usize {
        match self {
            Factor::Dense(f) => f.refactorizations(),
            Factor::Sparse(f) => f.refactorizations(),
        }
    }

    /// Entries the factor stores (its fill), when the analysis predicts them: a dense
    /// factor's `n^2`, a sparse Cholesky's from its symbolic analysis; `None` for LU, whose
    /// fill depends on the pivots.
    pub fn stored_entries(&self) -> Option<usize> {
        match self {
            Factor::Dense(f) => Some(f.size() * f.size()),
            Factor::Sparse(f) => f.stored_entries(),
        }
    }

    /// Multiply-adds of one numeric factorization and the entries of the factor, for a
    /// sparse Cholesky (from its analysis); `None` for a dense factor or LU.
    pub fn sparse_cholesky_cost(&self) -> Option<(f64, usize)> {
        match self {
            Factor::Dense(_) => None,
            Factor::Sparse(f) => f.factorization_flops().zip(f.stored_entries()),
        }
    }

    /// New values on the same pattern; the next [`Factor::set_rho`] refactorizes.
    pub fn reassemble(
        &mut self,
        assembly: &Assembly,
        base: impl IntoIterator<Item = (usize, usize, f64)>,
        slope: impl IntoIterator<Item = (usize, usize, f64)>,
    ) {
        match self {
            Factor::Dense(f) => f.reassemble(assembly, base, slope),
            Factor::Sparse(f) => f.reassemble(assembly, base, slope),
        }
    }

    /// Makes `A(rho)` the current factor.
    pub fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        match self {
            Factor::Dense(f) => f.set_rho(rho),
            Factor::Sparse(f) => f.set_rho(rho),
        }
    }

    /// Solves `A(rho) x = rhs` in place (no allocation).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        match self {
            Factor::Dense(f) => f.solve_in_place(rhs),
            Factor::Sparse(f) => f.solve_in_place(rhs),
        }
    }

    /// `y = A(rho) x` for the current rho.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        match self {
            Factor::Dense(f) => f.mul_vec(x, y),
            Factor::Sparse(f) => f.mul_vec(x, y),
        }
    }
}
