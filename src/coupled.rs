//! The solver of one coupled problem (one island of a scene, or a whole scene when islands
//! are off): a problem's form, its settings and the last iterate. Everything that depends
//! on the form lives in the form itself ([`crate::contact::ContactForm`]).

use crate::admm::{self, EngineState};
use crate::contact::{contact_form, initial_rho, ContactForm};
use crate::measure::Floors;
use crate::newton::{FailReason, NewtonStatus};
use crate::problem::{NewValues, Problem};
use crate::settings::{NewtonUse, Resolved, Settings};
use crate::tuning::{DENSE_MAX, HANDOVER_RETRY_FACTOR, NEWTON_FIRST_STEPS, NEWTON_MAX_STEPS};
use crate::types::Solution;
use crate::types::{Error, Status};
use crate::types::{Phase, Stats, TracePoint};
use std::time::{Duration, Instant};

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
}

impl CoupledSolver {
    /// Validates the settings, picks the first rho, and factorizes (symbolic analysis and
    /// the first numeric factorization).
    pub(crate) fn new(problem: Problem, settings: Settings) -> Result<Self, Error> {
        let t0 = Instant::now();
        settings.validate()?;
        let resolved = settings.resolved();
        let rho0 = initial_rho(resolved.initial_rho, &problem)?;
        let l = 3 * problem.n_contacts();
        let joints = match &problem {
            Problem::Global(g) => g.n_joints(),
            Problem::Local(_) => 0,
        };
        let newton_first = resolved.newton == NewtonUse::Polish
            && l > 0
            && problem.n_velocities() + l + joints <= DENSE_MAX;
        let mut form = contact_form(problem)?;
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
        })
    }

    /// Sets the tolerance, the time limit and the iteration limit of the next solves (an
    /// island's share).
    pub(crate) fn set_limits(&mut self, tolerance: f64, time_limit: f64, max_iterations: usize) {
        self.settings.tolerance = tolerance;
        self.settings.time_limit = time_limit;
        self.settings.max_iterations = max_iterations;
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

    /// Floors of the error measure (an island's share of a scene's measure).
    pub(crate) fn set_measure_floors(&mut self, floors: Floors) {
        self.form.set_measure_floors(floors);
    }

    /// Replaces the problem by one of the same form, sizes and sparsity patterns (the next
    /// time step of a simulation): numeric refactorization only, through the same path as
    /// [`CoupledSolver::update_values`].
    pub(crate) fn update(&mut self, problem: Problem) -> Result<(), Error> {
        self.form.update(problem)?;
        self.form.set_rho(self.rho0)?;
        self.warm = false;
        Ok(())
    }

    /// Takes new values for the problem on the same sizes and sparsity patterns (the next
    /// time step of a scene), without building a problem: they are scattered into the kept
    /// system matrix through maps built once, then one numeric refactorization; no sorting,
    /// no allocation (except when a symmetric matrix stops being symmetric, which rebuilds
    /// the system for LU). Every value is checked before any is taken; M is refactorized on
    /// its own to check it is positive definite, and after a failed factorization the
    /// solver keeps failing until an update succeeds. The next solve starts
    /// cold unless [`CoupledSolver::warm_start`] is called after this.
    pub(crate) fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        self.form.update_values(values)?;
        self.form.set_rho(self.rho0)?;
        self.warm = false;
        Ok(())
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    pub(crate) fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        let l = self.state.y.len();
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
        if self.form.blocked_contact().is_some() {
            // No impulse can satisfy that contact: say so from the cold-start iterate,
            // measured, rather than let the impulses grow until the relative measure fades.
            self.state.rho = self.rho0;
            self.form.cold_start(&mut self.state);
            let error = self.iterate_error();
            return Ok(self.end_without_iterating(Status::Infeasible, error, t0));
        }
        // Short cuts, each measured before it is taken: a warm start that already meets the
        // tolerance (an engine's resting scene), and contacts that all separate.
        if self.warm {
            let error = self.iterate_error();
            if error <= self.settings.tolerance {
                return Ok(self.end_without_iterating(Status::Solved, error, t0));
            }
        }
        if self.form.separating(&mut self.state) {
            let error = self.iterate_error();
            if error <= self.settings.tolerance {
                return Ok(self.end_without_iterating(Status::Solved, error, t0));
            }
            // Round-off kept r = 0 above the tolerance (and the warm start is gone): solve
            // from the start.
            self.warm = false;
        }
        if !self.warm {
            self.state.rho = self.rho0;
            self.form.cold_start(&mut self.state);
        }
        self.warm = false;
        let mut set = self.settings.engine_settings(&self.resolved);
        let deadline =
            t0.checked_add(Duration::try_from_secs_f64(set.time_limit).unwrap_or(Duration::MAX));
        let mut stats = Stats {
            setup_seconds: self.stats.setup_seconds,
            ..Default::default()
        };
        self.trace.clear();
        let mut status = None;
        let mut error = f64::INFINITY;
        // ADMM and Newton phases alternate until one meets the tolerance or a limit is hit;
        // the iteration limit counts the steps of both. A small problem starts with Newton.
        let mut newton_first = self.newton_first;
        while status.is_none() {
            let left = self
                .settings
                .max_iterations
                .saturating_sub(stats.iterations);
            if self.resolved.newton != NewtonUse::Alone && !newton_first {
                set.max_iterations = left;
                let out = admm::run(self.form.as_mut(), &mut self.state, &set, t0)?;
                stats.iterations += out.iterations;
                stats.primal_residual = out.primal;
                stats.dual_residual = out.dual;
                stats.anderson_accepted += out.aa_accepted;
                stats.anderson_rejected += out.aa_rejected;
                let offset = stats.iterations - out.iterations;
                self.trace.extend(out.trace.into_iter().map(|mut t| {
                    t.iteration += offset;
                    t
                }));
                error = out.error;
                status = out.status;
                if status == Some(Status::NumericalError) {
                    // The form's own iterate comes from the step that blew up: recompute
                    // it from the last finite iterate, which the state holds, and measure
                    // that.
                    self.form.recover(&self.state)?;
                    let s = &self.state;
                    error = self.form.error(&s.ax, &s.y, &s.zeta, s.rho);
                }
                if !out.handed_over {
                    break;
                }
            }
            let left = self
                .settings
                .max_iterations
                .saturating_sub(stats.iterations);
            if left == 0 {
                status = Some(Status::MaxIterations);
                break;
            }
            // Newton alone may use every iteration left; as a polish, a bounded phase.
            let steps = match self.resolved.newton {
                NewtonUse::Alone => left,
                _ if newton_first => left.min(NEWTON_FIRST_STEPS),
                _ => left.min(NEWTON_MAX_STEPS),
            };
            let newton =
                self.form
                    .polish(&mut self.state, self.settings.tolerance, steps, deadline)?;
            stats.iterations += newton.iterations;
            stats.newton_iterations += newton.iterations;
            stats.newton_factorizations += newton.factorizations;
            stats.newton_phases += 1;
            // Newton measured its own iterate; what the solver hands back is the engine
            // state Newton wrote, recomputed from it: measure that (at huge impulses the two
            // can differ beyond the tolerance).
            let handed = if newton.converged() {
                self.iterate_error()
            } else {
                newton.error
            };
            let converged = newton.converged() && handed <= self.settings.tolerance;
            error = error.min(handed);
            if self.settings.trace {
                self.trace.push(TracePoint {
                    iteration: stats.iterations,
                    seconds: t0.elapsed().as_secs_f64(),
                    error: handed,
                    primal_residual: f64::NAN,
                    dual_residual: f64::NAN,
                    rho: self.state.rho,
                    anderson_accepted: stats.anderson_accepted,
                    anderson_rejected: stats.anderson_rejected,
                    phase: Phase::Newton,
                });
            }
            if converged {
                status = Some(Status::Solved);
            } else if newton.status == NewtonStatus::Failed(FailReason::Deadline)
                || t0.elapsed().as_secs_f64() > self.settings.time_limit
            {
                status = Some(Status::TimeLimit);
            } else if self.resolved.newton == NewtonUse::Alone {
                // Newton alone has nothing to fall back on.
                status = Some(match newton.status {
                    NewtonStatus::Failed(FailReason::MaxIterations) => Status::MaxIterations,
                    NewtonStatus::Failed(FailReason::NonFinite) => Status::NumericalError,
                    _ => Status::Stalled,
                });
            } else {
                // Back to ADMM from Newton's best iterate, handing over again only once the
                // error is well below where this Newton phase failed, or after a stall twice
                // as long: Newton then costs a bounded share of the solve.
                stats.newton_fallbacks += 1;
                if newton_first {
                    // The first phase of a small problem: ADMM runs with the usual handover.
                    newton_first = false;
                } else if let Some(h) = set.handover.as_mut() {
                    h.error_below = HANDOVER_RETRY_FACTOR * h.error_below.min(error);
                    h.stall_checks *= 2;
                }
            }
        }
        let mut status = status.unwrap_or(Status::MaxIterations);
        if status == Status::Solved && self.form.certifies_infeasibility(&self.state) {
            // The impulses ran off along a direction that shows there is no solution: the
            // relative error faded with them (docs/algorithms.md §13). Only a `Solved`
            // is questioned: on badly conditioned problems (mass ratio 1e6, local form) an
            // unconverged iterate can pass the test too, and its status is honest already.
            status = Status::Infeasible;
        }
        self.stats = Stats {
            status,
            error,
            rho: self.state.rho,
            refactorizations: self.form.refactorizations(),
            rows: self.form.rows(),
            solve_seconds: t0.elapsed().as_secs_f64(),
            ..stats
        };
        Ok(status)
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

    /// The current solution (the last finite iterate).
    pub(crate) fn solution(&self) -> Solution {
        self.form.solution(&self.state)
    }

    /// Length of `v` (0 for a local problem).
    pub(crate) fn n_velocities(&self) -> usize {
        self.form.n_velocities()
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
