//! The coupled solvers of a layout being replaced (`Solver::rebuild`), offered to the
//! islands of the new one: an island whose sub-problem has the sizes and sparsity patterns
//! of an offered solver's problem takes that solver with its new values (numeric
//! refactorization only, its first rho picked again as a new solver's), and keeps its
//! analysis and its memory. A scene
//! whose contacts change in one place (a box falling beside resting stacks, handed over
//! as one problem) then rebuilds the islands that changed, not the whole scene.

use crate::coupled::CoupledSolver;
use crate::problem::Problem;
use crate::types::Error;

/// What [`Offered::take`] did with a sub-problem.
pub(crate) enum Offer {
    /// The offered solver of this index took it.
    Taken(usize),
    /// No offered solver fits it: it is handed back, for a new solver.
    NoneFits(Problem),
}

/// The replaced layout's coupled solvers, borrowed until the new layout is built: those
/// taken hold the new values, and go back to their old ones if the build fails.
pub(crate) struct Offered<'a> {
    solvers: Vec<Option<&'a mut CoupledSolver>>,
    /// The solvers taken, with their index and the problem each held before.
    taken: Vec<(usize, &'a mut CoupledSolver, Problem)>,
}

impl<'a> Offered<'a> {
    /// Offers `solvers` (in the order the indices of [`Offer::Taken`] refer to).
    pub(crate) fn new(solvers: Vec<&'a mut CoupledSolver>) -> Self {
        Self {
            solvers: solvers.into_iter().map(Some).collect(),
            taken: Vec::new(),
        }
    }

    /// Nothing offered (a solver built for the first time).
    pub(crate) fn none() -> Self {
        Self::new(Vec::new())
    }

    /// Gives `sub` to the first offered solver it fits, or hands it back when none fits.
    /// An error is the fitting solver's refusal of the values (which leaves it on its old
    /// ones).
    pub(crate) fn take(&mut self, sub: Problem) -> Result<Offer, Error> {
        let found = self
            .solvers
            .iter()
            .position(|s| s.as_ref().is_some_and(|s| s.fits(&sub)));
        let Some(k) = found else {
            return Ok(Offer::NoneFits(sub));
        };
        let solver = self.solvers[k].take().expect("offered");
        let before = solver.problem_owned();
        let taken = solver.take_over(sub);
        self.taken.push((k, solver, before));
        taken.map(|()| Offer::Taken(k))
    }

    /// Whether any solver was taken.
    pub(crate) fn took_any(&self) -> bool {
        !self.taken.is_empty()
    }

    /// Gives every solver taken its old problem back (the new layout was refused).
    pub(crate) fn give_back(self) {
        for (_, solver, before) in self.taken {
            // It held these values before, so it takes them again.
            let _ = solver.take_over(before);
        }
    }
}
