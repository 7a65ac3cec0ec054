//! The frictional contact problems as ADMM splittings (docs/algorithms.md §4), and the
//! initial penalty rules. Each form owns everything that depends on it: its warm start, its
//! solution and its recovery after a failed step, behind [`ContactForm`], so the solver
//! never branches on the form.

mod form;
mod global;
mod initial_rho;
mod local;

pub(crate) use form::ContactForm;
#[cfg(feature = "mpi")]
pub(crate) use global::GlobalSplitting;
use global::ProblemSplitting;
pub(crate) use initial_rho::initial_rho;
#[cfg(feature = "mpi")]
pub(crate) use initial_rho::shared_initial_rho;
pub(crate) use local::LocalSplitting;

use crate::problem::Problem;
use crate::settings::LinearSolver;
use crate::types::Error;

/// Builds the form of `problem`.
pub(crate) fn contact_form(
    problem: Problem,
    backend: LinearSolver,
) -> Result<Box<dyn ContactForm>, Error> {
    Ok(match problem {
        Problem::Global(g) => Box::new(ProblemSplitting::new(g, backend)?),
        Problem::Local(l) => Box::new(LocalSplitting::new(l)?),
    })
}
