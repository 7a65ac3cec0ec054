//! The solver of one coupled problem (one island of a scene, or a whole scene when islands
//! are off): a problem's form, its settings and the last iterate. Everything that depends
//! on the form lives in the form itself ([`crate::contact::ContactForm`]).

use crate::admm::{self, EngineSettings, EngineState, SUpdate};
use crate::contact::{contact_form, initial_rho, ContactForm};
use crate::measure::Floors;
use crate::problem::{KeptValues, NewValues, Problem, ProblemRef};
use crate::settings::{NewtonUse, Resolved, Settings};
use crate::tuning::{DENSE_MAX, HANDOVER_RETRY_FACTOR, NEWTON_FIRST_STEPS, NEWTON_MAX_STEPS};
use crate::types::Solution;
use crate::types::{Error, Status};
use crate::types::{Phase, Stats, TracePoint};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Whether a small problem's solves start with a Newton phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum NewtonFirst {
    /// When its Newton system is dense (see [`DENSE_MAX`]) and the settings polish with
    /// Newton.
    IfSmall,
    /// Never: Newton already failed on this problem from the same start (a small island's
    /// dense Newton, which this solver backs up).
    Never,
}

/// The state of one solve's alternating ADMM and Newton phases.
struct Run {
    /// The engine's settings; a failed Newton phase moves the next handover.
    set: EngineSettings,
    t0: Instant,
    deadline: Option<Instant>,
    stats: Stats,
    /// The best error measured so far.
    error: f64,
    /// The next phase is the first Newton phase of a small problem.
    newton_first: bool,
    /// The form's conjugate-gradient count when the solve started.
    linear_iterations: usize,
    /// Steps the next Newton phase may take (`None`: no limit), set by ADMM's last
    /// handover.
    newton_budget: Option<usize>,
}

/// Solves one coupled frictional contact problem, and its successors with the same pattern.
pub(crate) struct CoupledSolver {
    settings: Settings,
    resolved: Resolved,
    form: Box<dyn ContactForm>,
    rho0: f64,
    state: EngineState,
    warm: bool,
    stats: Stats,
    trace: Vec<TracePoint>,
    /// A small problem with the Newton phase on: each solve starts with Newton.
    newton_first: bool,
    /// Its Newton steps factorize a dense system.
    dense_newton: bool,
    /// The values an update replaces, until it has succeeded.
    kept: KeptValues,
    /// Once set, ADMM runs end as at the time limit (see `Solver::set_interrupt`).
    interrupt: Arc<AtomicBool>,
}

impl CoupledSolver {
    /// Validates the settings, picks the first rho, and factorizes (symbolic analysis and
    /// the first numeric factorization).
    pub(crate) fn new(
        problem: Problem,
        settings: Settings,
        first: NewtonFirst,
    ) -> Result<Self, Error> {
        let t0 = Instant::now();
        settings.validate()?;
        let mut resolved = settings.resolved();
        let rho0 = initial_rho(resolved.initial_rho, &problem)?;
        let joints = match &problem {
            Problem::Global(g) => g.n_joints(),
            Problem::Local(_) => 0,
        };
        let n = problem.n_velocities();
        // The global Newton step is solved on the velocities and joints (reduced), the
        // local one on the contact rows.
        let dense_newton = match &problem {
            Problem::Global(_) => n + joints <= DENSE_MAX,
            Problem::Local(_) => 3 * problem.n_contacts() <= DENSE_MAX,
        };
        // Newton's step has no term for a bound that moves with a contact's normal impulse.
        let contact_bounds = match &problem {
            Problem::Global(g) => g.has_contact_bounds(),
            Problem::Local(_) => false,
        };
        if contact_bounds && resolved.newton == NewtonUse::Alone {
            return Err(Error::Unsupported(
                "the Newton variant: rows bounded by a contact's normal impulse (rolling or \
                 spinning friction) are solved by ADMM"
                    .into(),
            ));
        }
        let mut form = contact_form(problem, settings.linear_solver)?;
        // The constraint space: the contacts' rows, then the joint rows of the splitting.
        let l = form.space();
        let small = n + l + joints <= DENSE_MAX;
        if (form.matrix_free() || contact_bounds) && resolved.newton == NewtonUse::Polish {
            // A Newton phase would factorize what the matrix-free backend avoids.
            resolved.newton = NewtonUse::Off;
        }
        let newton_first =
            first == NewtonFirst::IfSmall && resolved.newton == NewtonUse::Polish && l > 0 && small;
        form.set_rho(rho0)?;
        let state = EngineState {
            y: vec![0.0; l],
            zeta: vec![0.0; l],
            ax: vec![0.0; l],
            rho: rho0,
        };
        let stats = Stats {
            setup_seconds: t0.elapsed().as_secs_f64(),
            rho: rho0,
            refactorizations: form.refactorizations(),
            rows: form.rows(),
            ..Default::default()
        };
        Ok(Self {
            settings,
            resolved,
            form,
            rho0,
            state,
            warm: false,
            stats,
            trace: Vec::new(),
            newton_first,
            dense_newton,
            kept: KeptValues::default(),
            interrupt: Arc::default(),
        })
    }

    /// Sets the tolerance, the time limit and the iteration limit of the next solves (an
    /// island's share).
    pub(crate) fn set_limits(&mut self, tolerance: f64, time_limit: f64, max_iterations: usize) {
        self.settings.tolerance = tolerance;
        self.settings.time_limit = time_limit;
        self.settings.max_iterations = max_iterations;
    }

    /// Makes `flag` the interrupt its ADMM runs read (see `Solver::set_interrupt`).
    pub(crate) fn set_interrupt(&mut self, flag: Arc<AtomicBool>) {
        self.interrupt = flag;
    }

    /// Takes the settings a solve reads when it starts (see [`Settings::check_update`]).
    pub(crate) fn update_settings(&mut self, settings: &Settings) {
        self.set_limits(
            settings.tolerance,
            settings.time_limit,
            settings.max_iterations,
        );
        self.settings.trace = settings.trace;
        self.settings.threads = settings.threads;
    }

    /// Threads for the linear algebra of this problem (a problem solved whole: the islands
    /// of a split scene take the threads instead).
    pub(crate) fn set_linear_threads(&mut self, threads: usize) {
        self.form.set_threads(threads);
    }

    /// Floors of the error measure (an island's share of a scene's measure).
    pub(crate) fn set_measure_floors(&mut self, floors: Floors) {
        self.form.set_measure_floors(floors);
    }

    /// Replaces the problem by one of the same form, sizes and sparsity patterns (the next
    /// time step of a simulation): numeric refactorization only, through the same path as
    /// [`CoupledSolver::update_values`].
    pub(crate) fn update(&mut self, problem: Problem) -> Result<(), Error> {
        self.kept.keep(self.form.problem(), &NewValues::EVERY_FIELD);
        let taken = self.form.update(problem);
        self.ready_or_undo(taken)
    }

    /// Whether `next` has this solver's problem's form, sizes and sparsity patterns: then
    /// [`CoupledSolver::update`] takes it.
    pub(crate) fn fits(&self, next: &Problem) -> bool {
        match (self.form.problem(), next) {
            (ProblemRef::Global(a), Problem::Global(b)) => a.check_successor(b).is_ok(),
            (ProblemRef::Local(a), Problem::Local(b)) => a.check_successor(b).is_ok(),
            _ => false,
        }
    }

    /// [`CoupledSolver::update`] for a solver taken over by another problem of the same
    /// patterns (an island kept by a rebuild): its first rho is picked again from the new
    /// values and its measure floors go (a scene sets its islands' at every solve), as for
    /// a new solver, so that it answers as one.
    pub(crate) fn take_over(&mut self, problem: Problem) -> Result<(), Error> {
        let rho0 = initial_rho(self.resolved.initial_rho, &problem)?;
        let before = std::mem::replace(&mut self.rho0, rho0);
        match self.update(problem) {
            Ok(()) => {
                self.state.rho = rho0;
                self.set_measure_floors(Floors::default());
                Ok(())
            }
            Err(e) => {
                self.rho0 = before;
                Err(e)
            }
        }
    }

    /// True when the v-update is solved matrix-free (see `ContactForm::matrix_free`).
    pub(crate) fn matrix_free(&self) -> bool {
        self.form.matrix_free()
    }

    /// A copy of the problem as the solver holds it.
    pub(crate) fn problem_owned(&self) -> Problem {
        match self.form.problem() {
            ProblemRef::Global(g) => Problem::Global(g.clone()),
            ProblemRef::Local(l) => Problem::Local(l.clone()),
        }
    }

    /// Takes new values for the problem on the same sizes and sparsity patterns (the next
    /// time step of a scene), without building a problem: they are scattered into the kept
    /// system matrix through maps built once, then one numeric refactorization (deferred to
    /// the solve's first step where it cannot fail once M passed its check); no sorting,
    /// no allocation (except when a symmetric matrix stops being symmetric, which rebuilds
    /// the system for LU). Every value is checked before any is taken; M is refactorized on
    /// its own to check it is positive definite; a refused update changes nothing
    /// ([`CoupledSolver::ready_or_undo`]). The next solve starts cold unless
    /// [`CoupledSolver::warm_start`] is called after this.
    pub(crate) fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        self.kept.keep(self.form.problem(), values);
        let taken = self.form.update_values(values);
        self.ready_or_undo(taken)
    }

    /// Refactorizes after new values were `taken`; when either fails, puts back the
    /// values kept before the update (which factorized), so that a refused update changes
    /// nothing, the warm start included.
    fn ready_or_undo(&mut self, taken: Result<(), Error>) -> Result<(), Error> {
        let Err(e) = taken.and_then(|()| self.form.ready_for(self.rho0)) else {
            self.warm = false;
            return Ok(());
        };
        let kept = std::mem::take(&mut self.kept);
        // Should the old values fail too (a solver already failing), the solver goes on
        // failing as it did.
        let _ = self
            .form
            .update_values(&kept.values())
            .and_then(|()| self.form.ready_for(self.rho0));
        self.kept = kept;
        Err(e)
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    pub(crate) fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        // The contacts' impulses: the bounded joint rows after them start from zero.
        let l = 3 * match self.form.problem() {
            ProblemRef::Global(g) => g.n_contacts(),
            ProblemRef::Local(p) => p.n_contacts(),
        };
        if r.len() != l {
            return Err(Error::Dimension {
                field: "r",
                expected: l,
                found: r.len(),
            });
        }
        if let Some(index) = r.iter().position(|x| !x.is_finite()) {
            return Err(Error::InvalidValue {
                field: "r",
                index,
                reason: "not finite",
            });
        }
        self.state.rho = self.rho0;
        self.form.warm_start(r, v, &mut self.state)?;
        self.warm = true;
        Ok(())
    }

    /// Runs the solve: ADMM, finished by the semismooth Newton phase when the settings ask
    /// for it (docs/algorithms.md §9). Without a preceding [`CoupledSolver::warm_start`], starts
    /// from zero.
    pub(crate) fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        if let Some((status, error)) = self.short_cut() {
            return Ok(self.end_without_iterating(status, error, t0));
        }
        let warm = std::mem::replace(&mut self.warm, false);
        if !warm {
            self.state.rho = self.rho0;
            self.form.cold_start(&mut self.state);
        }
        self.trace.clear();
        let set = self
            .settings
            .engine_settings(&self.resolved, self.dense_newton);
        let mut run = Run {
            deadline: t0
                .checked_add(Duration::try_from_secs_f64(set.time_limit).unwrap_or(Duration::MAX)),
            set,
            t0,
            stats: Stats {
                setup_seconds: self.stats.setup_seconds,
                ..Default::default()
            },
            error: f64::INFINITY,
            newton_first: self.newton_first,
            linear_iterations: self.form.linear_iterations(),
            newton_budget: None,
        };
        let mut status = self.phases(&mut run)?;
        // A run whose iterates overflowed starts again from the cold start, within what is
        // left of the limits, when something else may succeed: without the warm start (a
        // hint, not an order: impulses of 1e300 on a contact that needs 10), then with the
        // external s update (docs/algorithms.md §5: updated every iteration, the De Saxce
        // shift amplifies a change of u_T by mu, and a pile at mu >= 30 diverges).
        let (mut warm, mut s_update) = (warm, run.set.s_update);
        while status == Status::NumericalError {
            if warm {
                warm = false;
            } else if s_update == SUpdate::Internal {
                s_update = SUpdate::External;
            } else {
                break;
            }
            // The engine as at the start (handover thresholds a failed Newton phase moved
            // included), the counts and the clock as they are.
            run.set = self
                .settings
                .engine_settings(&self.resolved, self.dense_newton);
            run.set.s_update = s_update;
            self.state.rho = self.rho0;
            self.form.cold_start(&mut self.state);
            run.error = f64::INFINITY;
            run.newton_first = self.newton_first;
            run.newton_budget = None;
            status = self.phases(&mut run)?;
        }
        Ok(self.finish(status, run))
    }

    /// ADMM and Newton phases alternate until one meets the tolerance or a limit is hit;
    /// the iteration limit counts the steps of both. A small problem starts with Newton.
    fn phases(&mut self, run: &mut Run) -> Result<Status, Error> {
        let mut status = None;
        while status.is_none() {
            if self.resolved.newton != NewtonUse::Alone && !run.newton_first {
                let (ended, handed_over) = self.admm_phase(run)?;
                status = ended;
                if !handed_over {
                    break;
                }
            }
            if self.iterations_left(&run.stats) == 0 {
                status = Some(Status::MaxIterations);
                break;
            }
            status = self.newton_phase(run)?;
        }
        Ok(status.unwrap_or(Status::MaxIterations))
    }

    /// A solve that needs no iteration: no solution (a contact no impulse can satisfy), a
    /// warm start that already meets the tolerance (an engine's resting scene), or
    /// contacts that all separate; each measured before it is taken.
    fn short_cut(&mut self) -> Option<(Status, f64)> {
        if self.form.blocked_contact().is_some() {
            // Say so from the cold-start iterate, measured, rather than let the impulses
            // grow until the relative measure fades.
            self.state.rho = self.rho0;
            self.form.cold_start(&mut self.state);
            return Some((Status::Infeasible, self.iterate_error()));
        }
        if self.warm {
            let error = self.iterate_error();
            if error <= self.settings.tolerance {
                return Some((Status::Solved, error));
            }
        }
        if self.form.separating(&mut self.state) {
            let error = self.iterate_error();
            if error <= self.settings.tolerance {
                return Some((Status::Solved, error));
            }
            // Round-off kept r = 0 above the tolerance (and the warm start is gone): solve
            // from the start.
            self.warm = false;
        }
        None
    }

    fn iterations_left(&self, stats: &Stats) -> usize {
        self.settings
            .max_iterations
            .saturating_sub(stats.iterations)
    }

    /// One ADMM run: its status if it ended the solve, and whether it handed over to
    /// Newton.
    fn admm_phase(&mut self, run: &mut Run) -> Result<(Option<Status>, bool), Error> {
        run.set.max_iterations = self.iterations_left(&run.stats);
        let form = self.form.as_mut();
        let out = admm::run_until(form, &mut self.state, &run.set, run.t0, &self.interrupt)?;
        out.add_to(&mut run.stats);
        let offset = run.stats.iterations - out.iterations;
        self.trace.extend(out.trace.into_iter().map(|mut t| {
            t.iteration += offset;
            t
        }));
        run.error = out.error;
        run.newton_budget = out.newton_budget;
        if out.status == Some(Status::NumericalError) && !out.error.is_finite() {
            // No finite iterate was measured (the engine hands back its best measured one
            // otherwise): the form's own iterate comes from the step that blew up, so
            // recompute it from the last finite iterate, which the state holds, and
            // measure that.
            self.form.recover(&self.state)?;
            run.error = self.iterate_error();
        }
        Ok((out.status, out.handed_over))
    }

    /// One Newton phase from the engine state: the solve's status if it ended the solve,
    /// `None` when ADMM resumes from Newton's best iterate.
    fn newton_phase(&mut self, run: &mut Run) -> Result<Option<Status>, Error> {
        let left = self.iterations_left(&run.stats);
        // Newton alone may use every iteration left; as a polish, a bounded phase.
        let steps = match self.resolved.newton {
            NewtonUse::Alone => left,
            _ if run.newton_first => left.min(NEWTON_FIRST_STEPS),
            _ => left.min(NEWTON_MAX_STEPS),
        };
        let tolerance = self.settings.tolerance;
        // A polishing phase may take the steps ADMM's predicted remaining iterations pay
        // for (docs/algorithms.md §9.3); past them it ends as a failed phase.
        let steps = run.newton_budget.map_or(steps, |budget| steps.min(budget));
        let newton = self
            .form
            .polish(&mut self.state, tolerance, steps, run.deadline)?;
        run.stats.iterations += newton.iterations;
        run.stats.newton_iterations += newton.iterations;
        run.stats.newton_factorizations += newton.factorizations;
        run.stats.newton_phases += 1;
        // Newton measured its own iterate; what the solver hands back is the engine state
        // Newton wrote, recomputed from it: measure that (at huge impulses the two can
        // differ beyond the tolerance).
        let handed = match newton.converged() {
            true => self.iterate_error(),
            false => newton.error,
        };
        run.error = run.error.min(handed);
        self.trace_newton(run, handed);
        let status =
            newton.status_when_final(newton.converged() && handed <= tolerance, run.deadline);
        let ends = matches!(status, Status::Solved | Status::TimeLimit);
        if ends || self.resolved.newton == NewtonUse::Alone {
            // Newton alone has nothing to fall back on.
            return Ok(Some(status));
        }
        // Back to ADMM from Newton's best iterate, handing over again only once the error
        // is well below where this Newton phase failed, or after a stall twice as long:
        // Newton then costs a bounded share of the solve.
        run.stats.newton_fallbacks += 1;
        if run.newton_first {
            // The first phase of a small problem: ADMM runs with the usual handover.
            run.newton_first = false;
        } else if let Some(h) = run.set.handover.as_mut() {
            h.error_below = HANDOVER_RETRY_FACTOR * h.error_below.min(run.error);
            h.stall_checks *= 2;
        }
        Ok(None)
    }

    /// Records the end of a Newton phase in the trace, when tracing.
    fn trace_newton(&mut self, run: &Run, error: f64) {
        if self.settings.trace {
            self.trace.push(TracePoint {
                iteration: run.stats.iterations,
                seconds: run.t0.elapsed().as_secs_f64(),
                error,
                primal_residual: f64::NAN,
                dual_residual: f64::NAN,
                rho: self.state.rho,
                anderson_accepted: run.stats.anderson_accepted,
                anderson_rejected: run.stats.anderson_rejected,
                phase: Phase::Newton,
            });
        }
    }

    /// The solve's statistics, and its status once the infeasibility certificate has
    /// questioned a `Solved`.
    fn finish(&mut self, mut status: Status, run: Run) -> Status {
        if status == Status::Solved && self.form.certifies_infeasibility(&self.state) {
            // The impulses ran off along a direction that shows there is no solution: the
            // relative error faded with them (docs/algorithms.md §13). Only a `Solved`
            // is questioned: on badly conditioned problems (mass ratio 1e6, local form) an
            // unconverged iterate can pass the test too, and its status is honest already.
            status = Status::Infeasible;
        }
        self.stats = Stats {
            status,
            error: run.error,
            rho: self.state.rho,
            refactorizations: self.form.refactorizations(),
            rows: self.form.rows(),
            solve_seconds: run.t0.elapsed().as_secs_f64(),
            linear_iterations: self.form.linear_iterations() - run.linear_iterations,
            ..run.stats
        };
        status
    }

    /// The error measure of the iterate in the engine state.
    fn iterate_error(&mut self) -> f64 {
        let s = &self.state;
        self.form.error(&s.ax, &s.y, &s.zeta, s.rho)
    }

    /// Ends a solve that took no iteration (a short cut, or no solution) with the iterate
    /// in the engine state.
    fn end_without_iterating(&mut self, status: Status, error: f64, t0: Instant) -> Status {
        self.warm = false;
        self.trace.clear();
        self.stats = Stats {
            status,
            iterations: 0,
            error,
            primal_residual: 0.0,
            dual_residual: 0.0,
            rho: self.state.rho,
            refactorizations: self.form.refactorizations(),
            rows: self.form.rows(),
            setup_seconds: self.stats.setup_seconds,
            solve_seconds: t0.elapsed().as_secs_f64(),
            ..Default::default()
        };
        status
    }

    /// The current solution (the iterate the last solve handed back).
    pub(crate) fn solution(&self) -> Solution {
        let mut out = Solution::default();
        self.write_solution(&mut out);
        out
    }

    /// Writes the current solution into `out`, reusing its vectors.
    pub(crate) fn write_solution(&self, out: &mut Solution) {
        self.form.write_solution(&self.state, out);
    }

    /// Statistics of the last solve.
    pub(crate) fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Per-iteration trace of the last solve (empty unless `Settings::trace`).
    pub(crate) fn trace(&self) -> &[TracePoint] {
        &self.trace
    }
}
