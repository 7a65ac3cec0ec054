//! The public solver: a problem's form, its settings and the last iterate. Everything that
//! depends on the form lives in the form itself ([`crate::contact::ContactForm`]).

use crate::admm::{self, EngineState};
use crate::contact::{contact_form, initial_rho, ContactForm};
use crate::error::{Error, Status};
use crate::problem::Problem;
use crate::settings::{Resolved, Settings};
use crate::stats::{Stats, TracePoint};
use std::time::Instant;

/// A solution of either form. `v` and `lambda` are empty for a local problem.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Solution {
    /// Contact impulses (`3 nc`).
    pub r: Vec<f64>,
    /// Local relative velocities (`3 nc`).
    pub u: Vec<f64>,
    /// Generalized velocities (`n`, global form only).
    pub v: Vec<f64>,
    /// Joint multipliers (global form with joints only).
    pub lambda: Vec<f64>,
}

/// Solves one frictional contact problem, and its successors with the same pattern.
pub struct Solver {
    settings: Settings,
    resolved: Resolved,
    form: Box<dyn ContactForm>,
    rho0: f64,
    state: EngineState,
    warm: bool,
    stats: Stats,
    trace: Vec<TracePoint>,
}

impl Solver {
    /// Validates the settings, picks the first rho, and factorizes (symbolic analysis and
    /// the first numeric factorization).
    pub fn new(problem: Problem, settings: Settings) -> Result<Self, Error> {
        let t0 = Instant::now();
        settings.validate()?;
        let resolved = settings.resolved();
        let rho0 = initial_rho(resolved.initial_rho, &problem)?;
        let l = 3 * problem.n_contacts();
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
        })
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The variant, initial rho rule and Anderson memory actually used.
    pub fn resolved(&self) -> &Resolved {
        &self.resolved
    }

    /// Replaces the problem by one of the same form, sizes and sparsity patterns (the next
    /// time step of a simulation): numeric refactorization only.
    pub fn update(&mut self, problem: Problem) -> Result<(), Error> {
        self.form.update(problem)?;
        self.form.set_rho(self.rho0)?;
        self.warm = false;
        Ok(())
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
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

    /// Runs ADMM. Without a preceding [`Solver::warm_start`], starts from zero.
    pub fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        if !self.warm {
            self.state.rho = self.rho0;
            self.form.cold_start(&mut self.state);
        }
        self.warm = false;
        let set = self.settings.engine_settings(&self.resolved);
        let out = admm::run(self.form.as_mut(), &mut self.state, &set, t0)?;
        let status = out.status.unwrap_or(Status::MaxIterations);
        let mut error = out.error;
        if status == Status::NumericalError {
            // The form's own iterate comes from the step that blew up: recompute it from
            // the last finite iterate, which the state holds, and measure that.
            self.form.recover(&self.state)?;
            let s = &self.state;
            error = self.form.error(&s.ax, &s.y, &s.zeta, s.rho);
        }
        self.trace = out.trace;
        self.stats = Stats {
            status,
            iterations: out.iterations,
            error,
            primal_residual: out.primal,
            dual_residual: out.dual,
            rho: self.state.rho,
            refactorizations: self.form.refactorizations(),
            anderson_accepted: out.aa_accepted,
            anderson_rejected: out.aa_rejected,
            setup_seconds: self.stats.setup_seconds,
            solve_seconds: t0.elapsed().as_secs_f64(),
        };
        Ok(status)
    }

    /// The current solution (the last finite iterate).
    pub fn solution(&self) -> Solution {
        self.form.solution(&self.state)
    }

    /// Length of `v` (0 for a local problem).
    pub fn n_velocities(&self) -> usize {
        self.form.n_velocities()
    }

    /// Statistics of the last solve.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Per-iteration trace of the last solve (empty unless `Settings::trace`).
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }
}
