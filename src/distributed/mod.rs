//! One contact problem shared out among MPI processes (feature `mpi`).
//!
//! Each process hands cadmm its part ([`RankProblem`]): the bodies it owns, named by
//! global ids, with their mass blocks, and the contacts it owns, whose columns of H may
//! reference bodies another process owns. Every process then holds the velocities of its
//! own bodies followed by copies of the other bodies its contacts touch ([`halo`]): the
//! products with `M` and `H` need nothing else, and the sums of dot products and norms are
//! the only other exchanges. Sums add the processes' partial sums in rank order, so that
//! a result is bitwise the same from run to run for a given number of processes.
//!
//! A problem one process finds wrong (a non-finite value, a contact that names a body no
//! process owns) makes every process return the same [`RankError`], which names that
//! process and the item: no process is left waiting on the others.
//!
//! [`DistributedSolver`] runs the engine's ADMM on the process's part
//! ([`splitting`]): the matrix-free v-update by conjugate gradients across the processes
//! ([`system`]), projections and dual updates per owned contact, the stopping test and the
//! error measure of the whole problem on sums across processes.

mod halo;
mod islands;
#[doc(hidden)]
pub mod mpirun;
mod problem;
mod solver;
mod splitting;
mod system;

pub(crate) use halo::agree_code;
pub use problem::{RankError, RankProblem};
pub use solver::DistributedSolver;
