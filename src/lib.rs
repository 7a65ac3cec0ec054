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
//! let r = &solver.solution().r;
//! assert!((r[0] - 9.81).abs() < 1e-6);
//! ```
#![deny(missing_docs)]
// Numerical kernels index several vectors with one counter; iterator zips would hide that.
#![allow(clippy::needless_range_loop)]
// One problem or solver lives per simulation; its size does not matter, boxing would.
#![allow(clippy::large_enum_variant)]

// Stable Rust API: the re-exports below, the engine extension API in [`admm`], the error
// measure in [`measure`], FCLib I/O in [`fclib`] and the C API in [`ffi`]. Everything else is
// internal and may change between versions.
pub mod admm;
mod bounded_rows;
mod budgeted;
mod certificate;
mod cone;
mod contact;
mod coupled;
mod csc;
mod dense;
mod disjoint_sets;
#[cfg(feature = "mpi")]
pub mod distributed;
#[cfg(feature = "fclib")]
pub mod fclib;
/// The C API (`include/cadmm.h`): opaque handles, result codes, panic boundary. From Rust,
/// use the types re-exported at the crate root instead.
pub mod ffi;
mod gauss_seidel;
mod linsys;
pub mod measure;
/// Semismooth Newton (Alart-Curnier) phase.
mod newton;
mod problem;
mod scene;
mod settings;
mod solver;
mod tuning;
mod types;

pub use admm::SUpdate;
pub use cone::{de_saxce, project_cone, project_dual_cone};
pub use csc::CscMatrix;
pub use problem::{GlobalProblem, Joints, LocalProblem, NewValues, Problem};
pub use settings::InitialRho;
pub use settings::{LinearSolver, NewtonUse, Resolved, Settings, VariantChoice};
pub use solver::Solver;
pub use types::{Error, ErrorKind, Phase, Solution, Stats, Status, TracePoint};
