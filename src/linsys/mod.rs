//! The x-update linear systems: `A(rho) = base + rho * slope` with a fixed sparsity
//! pattern (`M + rho H H^T`, `W + rho I`, or the quasi-definite joint system), factorized
//! with faer. The symbolic analysis (AMD ordering) is done once; a change of rho only
//! refactorizes numerically, and the last few numeric factors are kept so that a rho rule
//! that oscillates between two values does not refactorize back and forth.

pub mod param_matrix;
mod sparse_factor;

pub use param_matrix::ParamMatrix;
pub use sparse_factor::{FactorKind, SparseFactor};
