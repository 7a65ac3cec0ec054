//! The first phase of a solver built with a time limit (an engine's per-step budget):
//! Gauss-Seidel sweeps over the whole problem (`gauss_seidel/`), which need no
//! factorization of the coupled system, so that a solver built every step costs its
//! sweeps and little else. It keeps its own copy of the problem: the islands and their
//! factorizations are built only when the sweeps stall with time left
//! (docs/algorithms.md §17).

use crate::gauss_seidel::{GaussSeidel, SweepLimits, SweepOutcome, Yield};
use crate::measure::MeasureWork;
use crate::problem::{check_len, GlobalProblem, KeptValues, NewValues, Problem, ProblemRef};
use crate::settings::{Settings, VariantChoice};
use crate::types::{Error, Solution};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// The problem, its sweeps and the warm start they begin from.
pub(crate) struct BudgetedStart {
    problem: GlobalProblem,
    sweeps: GaussSeidel,
    /// Impulses and velocities of the last warm start, until the next solve takes them.
    warm: Option<(Vec<f64>, Option<Vec<f64>>)>,
    /// The warm start the last run began from, for the coupled solve it may hand over to.
    used_warm: Option<(Vec<f64>, Option<Vec<f64>>)>,
    measure: MeasureWork,
    /// The values an update replaces, until it has succeeded.
    kept: KeptValues,
    /// The problem and sweeps before the last rebuild, whose memory the next one reuses.
    spare: Option<(GlobalProblem, GaussSeidel)>,
    /// When the sweeps give way: by an engine's budget, or before a matrix-free solve.
    yields: Yield,
}

impl BudgetedStart {
    /// The sweeps for `problem` when `settings` ask for `auto` with a time limit and the
    /// problem is global, with M made of small symmetric blocks; `None` otherwise (a named
    /// variant runs as named).
    pub(crate) fn sweeps_for(problem: &Problem, settings: &Settings) -> Option<GaussSeidel> {
        Self::asked_by(settings)
            .then(|| Self::sweeps_of(problem))
            .flatten()
    }

    /// The sweeps for `problem` when it is global, with M made of small symmetric blocks.
    pub(crate) fn sweeps_of(problem: &Problem) -> Option<GaussSeidel> {
        match problem {
            Problem::Global(g) => GaussSeidel::new(g),
            Problem::Local(_) => None,
        }
    }

    /// Whether `settings` ask for the sweeps: `auto` with a time limit.
    pub(crate) fn asked_by(settings: &Settings) -> bool {
        settings.variant == VariantChoice::Auto && settings.time_limit.is_finite()
    }

    /// The first phase of `problem` with its `sweeps` ([`BudgetedStart::sweeps_for`]).
    /// M's blocks are factorized here, so a matrix that is not positive definite is
    /// reported now, as the coupled solver would.
    pub(crate) fn new(
        problem: Problem,
        mut sweeps: GaussSeidel,
        yields: Yield,
    ) -> Result<Self, Error> {
        let Problem::Global(problem) = problem else {
            unreachable!("sweeps_for takes global problems only")
        };
        // Symmetric blocks: `sweeps` were fitted to these values.
        sweeps.take_values(&problem)?;
        Ok(Self {
            measure: MeasureWork::global(&problem),
            problem,
            sweeps,
            warm: None,
            used_warm: None,
            kept: KeptValues::default(),
            spare: None,
            yields,
        })
    }

    /// Becomes the start of `next`, a problem of any sizes and patterns, in the memory of
    /// the problem and sweeps it replaced last time (an engine's contacts change from step
    /// to step; building them anew cost page faults and copies, a fifth of setting up a
    /// step). Ok(false) when the sweeps do not suit `next`, and an error when its M is not
    /// positive definite; either way nothing changes.
    pub(crate) fn rebuild(&mut self, next: &GlobalProblem) -> Result<bool, Error> {
        let (mut problem, mut sweeps) = match self.spare.take() {
            Some((mut problem, mut sweeps)) => {
                problem.clone_from(next);
                if !sweeps.refit(&problem) {
                    return Ok(false);
                }
                (problem, sweeps)
            }
            None => match GaussSeidel::new(next) {
                Some(sweeps) => (next.clone(), sweeps),
                None => return Ok(false),
            },
        };
        if !sweeps.take_values(&problem)? {
            return Ok(false);
        }
        std::mem::swap(&mut self.problem, &mut problem);
        std::mem::swap(&mut self.sweeps, &mut sweeps);
        self.spare = Some((problem, sweeps));
        self.measure.fit_global(&self.problem);
        self.warm = None;
        self.used_warm = None;
        Ok(true)
    }

    /// The problem as it stands (for building the islands' solvers from it).
    pub(crate) fn problem(&self) -> Problem {
        Problem::Global(self.problem.clone())
    }

    /// Takes a successor problem (same sizes and patterns); refused, nothing changes.
    /// Returns false when the sweeps no longer fit it (M lost its symmetry).
    pub(crate) fn update(&mut self, problem: Problem) -> Result<bool, Error> {
        let Problem::Global(next) = problem else {
            return Err(Error::Unsupported(
                "update: the new problem is local, the solver was built for a global one".into(),
            ));
        };
        self.problem.check_successor(&next)?;
        let before = std::mem::replace(&mut self.problem, next);
        let taken = self.take_values();
        if taken.is_err() {
            self.problem = before;
            let _ = self.sweeps.take_values(&self.problem);
        }
        taken
    }

    /// Takes new values (same patterns); refused, nothing changes. Returns false when the
    /// sweeps no longer fit the problem (M lost its symmetry).
    pub(crate) fn update_values(&mut self, values: &NewValues) -> Result<bool, Error> {
        self.kept.keep(ProblemRef::Global(&self.problem), values);
        self.problem.set_values(values)?;
        let taken = self.take_values();
        if taken.is_err() {
            // Back to the values before, which factorized.
            let _ = self.problem.set_values(&self.kept.values());
            let _ = self.sweeps.take_values(&self.problem);
        }
        taken
    }

    /// Takes the problem's current values into the sweeps; false when M lost its symmetry.
    fn take_values(&mut self) -> Result<bool, Error> {
        self.warm = None;
        self.sweeps.take_values(&self.problem)
    }

    /// Starts the next run of sweeps from the impulses `r` (the sweeps' velocities follow
    /// from them, `v = M^-1 (f + H r)`; `v` is kept for the coupled solve, and for taking
    /// the warm start as it is, [`GaussSeidel::take_warm_start`]).
    pub(crate) fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        check_len("r", r, self.problem.w.len())?;
        if let Some(v) = v {
            check_len("v", v, self.problem.n())?;
        }
        self.warm = Some((r.to_vec(), v.map(<[f64]>::to_vec)));
        Ok(())
    }

    /// Whether a warm start was given since the last run.
    pub(crate) fn warm_given(&self) -> bool {
        self.warm.is_some()
    }

    /// Sweeps to `tolerance` within `deadline` and `max_sweeps`, or until `interrupt` is
    /// set, from the warm start when one was given since the last run; `newton` lets a
    /// problem of few contacts be solved by Newton after the first sweeps.
    pub(crate) fn run(
        &mut self,
        tolerance: f64,
        deadline: Option<Instant>,
        max_sweeps: usize,
        interrupt: Option<&AtomicBool>,
        handover_sweeps: f64,
        newton: bool,
    ) -> SweepOutcome {
        self.used_warm = self.warm.take();
        let limits = SweepLimits {
            tolerance,
            deadline,
            max_sweeps,
            interrupt,
            handover_sweeps,
            yields: self.yields,
            newton,
        };
        let r0 = self.used_warm.as_ref().map(|(r, _)| r.as_slice());
        let v0 = self.used_warm.as_ref().and_then(|(_, v)| v.as_deref());
        self.sweeps
            .run(&self.problem, r0, v0, limits, &mut self.measure)
    }

    /// When the sweeps give way to the coupled solve.
    pub(crate) fn yields(&self) -> Yield {
        self.yields
    }

    /// Takes the warm start given since the last run, if any, as a run would, for a solve
    /// that goes straight to the islands (which were handed the same warm start).
    pub(crate) fn skip_run(&mut self) {
        self.used_warm = self.warm.take();
    }

    /// Whether the problem's joint rows outnumber its contact rows, and the sweeps take
    /// them one at a time (they carry a correction one link a sweep; rows they solve
    /// together are met at every sweep).
    pub(crate) fn jointed(&self) -> bool {
        self.problem.n_joints() > 3 * self.problem.n_contacts() && !self.sweeps.joints_together()
    }

    /// The warm start the last run began from (impulses, and velocities when given).
    pub(crate) fn used_warm(&self) -> Option<(&[f64], Option<&[f64]>)> {
        let (r, v) = self.used_warm.as_ref()?;
        Some((r, v.as_deref()))
    }

    /// Writes the best iterate of the last run into `out`.
    pub(crate) fn write_solution(&self, out: &mut Solution) {
        let (r, v, lambda) = self.sweeps.best();
        out.zeroed(r.len(), v.len(), lambda.len());
        out.r.copy_from_slice(r);
        out.v.copy_from_slice(v);
        out.lambda.copy_from_slice(lambda);
        out.u.copy_from_slice(&self.problem.w);
        self.problem.h.mul_t_vec(1.0, v, 1.0, &mut out.u);
    }
}
