//! cadmm solves 3D frictional contact problems (Coulomb friction, De Saxce formulation,
//! second-order cones) with ADMM, in the global form (mass matrix M and contact Jacobian H)
//! or the local form (Delassus matrix W). Conventions: FCLib orientation, normal first.
//!
//! ```
//! use cadmm::{CscMatrix, GlobalProblem, Problem, Settings, Solver, Status};
//! // One unit mass pressed on the ground by gravity: v = -9.81 before contact.
//! let m = CscMatrix::identity(3);
//! let h = CscMatrix::identity(3);
//! let p = GlobalProblem::new(m, h, vec![-9.81, 0.0, 0.0], vec![0.0; 3], vec![0.5]).unwrap();
//! let mut solver = Solver::new(Problem::Global(p), Settings::default()).unwrap();
//! assert_eq!(solver.solve().unwrap(), Status::Solved);
//! let r = solver.solution().r;
//! assert!((r[0] - 9.81).abs() < 1e-6);
//! ```
#![deny(missing_docs)]
// Numerical kernels index several vectors with one counter; iterator zips would hide that.
#![allow(clippy::needless_range_loop)]
// One problem or solver lives per simulation; its size does not matter, boxing would.
#![allow(clippy::large_enum_variant)]

pub mod admm;
/// Seed 001 analysis: stationary Anderson acceleration, optimal coefficients, spectra of `q'`.
pub mod analysis;
pub mod cone;
pub mod contact;
pub mod csc;
pub mod error;
#[cfg(feature = "fclib")]
pub mod fclib;
/// The C API (`include/cadmm.h`): opaque handles, result codes, panic boundary.
pub mod ffi;
pub mod linsys;
pub mod measure;
pub mod problem;
pub mod settings;
pub mod solver;
pub mod stats;
/// Seed 001 test problems (ridge, logistic, total variation, lasso, NNLS, constrained
/// logistic) as engine plug-ins.
pub mod test_problems;

pub use admm::SUpdate;
pub use contact::InitialRho;
pub use csc::CscMatrix;
pub use error::{Error, Status};
pub use problem::{GlobalProblem, LocalProblem, Problem};
pub use settings::{Settings, VariantChoice};
pub use solver::{Solution, Solver};
pub use stats::{Stats, TracePoint};
