//! Research plug-ins of the cadmm engine, kept outside the library that engines link: the
//! analysis of Anderson acceleration of ADMM (seed 001) and its test problems, and the
//! nonconvex problems of the adaptive-penalty study (seed 002), each written as a
//! [`cadmm::admm::Splitting`] so that they run on the very loop the contact solver uses.
#![deny(missing_docs)]
// Numerical kernels index several vectors with one counter; iterator zips would hide that.
#![allow(clippy::needless_range_loop)]

pub mod analysis;
pub mod nonconvex;
pub mod test_problems;
