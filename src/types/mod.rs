//! The types every other module speaks: what a solve returns ([`Solution`], [`Status`],
//! [`Stats`]) and why a call fails ([`Error`]). Leaves: they import nothing of the crate
//! but each other.

mod error;
mod solution;
mod stats;
mod status;

pub use error::{Error, ErrorKind};
pub use solution::Solution;
pub use stats::{Phase, Stats, TracePoint};
pub use status::Status;
