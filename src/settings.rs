//! Solver settings, validated when a solver is built.

use crate::admm::{EngineSettings, Handover, SUpdate, Variant};
use crate::tuning::{
    ANDERSON_MEMORY_MAX, ERROR_CHECK_INTERVAL, HANDOVER_ERROR, HANDOVER_STALL_CHECKS,
    NEWTON_BUDGET, NEWTON_DENSE_STEP_ITERATIONS, NEWTON_EXPECTED_STEPS, NEWTON_RESCUE_STEPS,
    NEWTON_STEP_ITERATIONS, RESIDUAL_EPS_ABS, RESIDUAL_EPS_ABS_FROM, RHO_RANGE,
};
use crate::types::Error;

/// Which ADMM variant to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VariantChoice {
    /// The measured default (docs/solver-guide.md, "Choosing `auto`").
    Auto,
    /// One of the twelve named variants.
    Named(Variant),
    /// Semismooth Newton alone from the initial guess, no ADMM (for comparison with
    /// Newton-only solvers; docs/algorithms.md §9).
    Newton,
}

impl VariantChoice {
    /// Parses `auto`, `newton` or a variant name (docs/algorithms.md §6.5).
    pub fn from_name(name: &str) -> Result<Self, Error> {
        match name {
            "auto" => Ok(VariantChoice::Auto),
            "newton" => Ok(VariantChoice::Newton),
            _ => Variant::from_name(name).map(VariantChoice::Named),
        }
    }
}

/// How the semismooth Newton phase takes part in a solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NewtonUse {
    /// ADMM alone.
    Off,
    /// ADMM, then Newton from ADMM's iterate once the error is small or stalls; back to
    /// ADMM from Newton's best iterate when Newton fails (docs/algorithms.md §9).
    Polish,
    /// Newton alone from the initial guess.
    Alone,
}

/// How the global form's v-update systems `M + rho H H^T` are solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinearSolver {
    /// Chosen per island by a cost model: the direct factor unless its predicted fill makes
    /// each solve cost more than the iterative backend's products (docs/algorithms.md §14).
    Auto,
    /// Sparse (or dense, for small islands) factorization.
    Direct,
    /// Matrix-free preconditioned conjugate gradients, with no Newton phase (its systems
    /// are factorized); joint rows, equalities included, are then rows of the splitting.
    /// The local form and a non-symmetric M stay direct.
    Iterative,
}

impl LinearSolver {
    /// Parses `auto`, `direct` or `iterative`.
    pub fn from_name(name: &str) -> Result<Self, Error> {
        match name {
            "auto" => Ok(LinearSolver::Auto),
            "direct" => Ok(LinearSolver::Direct),
            "iterative" => Ok(LinearSolver::Iterative),
            _ => Err(Error::InvalidSetting {
                name: "linear_solver",
                reason: format!("expected auto, direct or iterative, got {name}"),
            }),
        }
    }
}

/// Settings of a solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Target of the error measure (docs/algorithms.md §3). Default 1e-8.
    pub tolerance: f64,
    /// Iteration limit. Default 100000.
    pub max_iterations: usize,
    /// Wall-clock limit of one solve, seconds. Default: none (infinity). It bounds the solve
    /// call only, checked between steps: after every ADMM iteration (which ends the run
    /// when the next one, as long as the last, would end past it), conjugate-gradient
    /// iteration and Newton step, and before each island. A step under way is finished,
    /// so a solve can overrun by one step: with the factorized backend, a refactorization
    /// when rho changes or a Newton factorization (tens of milliseconds on a large
    /// problem). Building the solver (analysis, first factorization) and updating it are
    /// outside the limit. An `auto` solver built with a limit (an engine's budget per step) starts
    /// each solve of a global problem whose M is block diagonal with
    /// Gauss-Seidel sweeps, and builds its islands only if the sweeps hand over
    /// (docs/algorithms.md §17); otherwise a limit that is not reached does not change the
    /// solve.
    pub time_limit: f64,
    /// ADMM variant. Default `auto`.
    pub variant: VariantChoice,
    /// First rho. `None`: the variant's default (Acary for `auto`, Normal otherwise... see
    /// [`Settings::resolved`]).
    pub initial_rho: Option<InitialRho>,
    /// s-update mode. Default internal.
    pub s_update: SUpdate,
    /// Anderson memory; `None`: the variant's default (on for `auto`, off for named variants).
    pub anderson: Option<usize>,
    /// Try an Anderson step every this many iterations (1 = every iteration, the default);
    /// the history is recorded at every iteration either way.
    pub anderson_interval: usize,
    /// Record a per-iteration trace. Default off.
    pub trace: bool,
    /// Finish with the semismooth Newton phase (and, under a time limit, solve few
    /// contacts at once by Newton after the first sweeps); `None`: the variant's default
    /// (on for `auto`, off for the named ADMM variants, which then run as published).
    pub newton_polish: Option<bool>,
    /// Split the problem into its contact islands and solve each on its own
    /// (docs/algorithms.md §12). Default on.
    pub islands: bool,
    /// Threads the solver may use: 1 (the default) runs everything on the caller's thread.
    /// With more, a solve of several islands starts up to that many scoped threads that
    /// solve them side by side and joins them before it returns; a problem solved whole
    /// with the matrix-free v-update and at least 200 000 entries in M and H gets a pool of
    /// that many threads for its products when the solver is built (or its settings
    /// updated), kept until the solver is dropped or the count changes. The results do
    /// not depend on it.
    pub threads: usize,
    /// How the v-update systems are solved. Default `Auto`.
    pub linear_solver: LinearSolver,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            tolerance: 1e-8,
            max_iterations: 100_000,
            time_limit: f64::INFINITY,
            variant: VariantChoice::Auto,
            initial_rho: None,
            s_update: SUpdate::Internal,
            anderson: None,
            anderson_interval: 1,
            trace: false,
            newton_polish: None,
            islands: true,
            threads: 1,
            linear_solver: LinearSolver::Auto,
        }
    }
}

/// What `auto` runs.
pub const AUTO_VARIANT: &str = "vp-N-He";

/// Anderson memory `auto` uses.
pub const AUTO_ANDERSON: usize = 5;
/// Initial rho rule `auto` uses.
pub const AUTO_INITIAL_RHO: InitialRho = InitialRho::Acary;

/// Most island threads one solve may start.
pub const MAX_THREADS: usize = 256;

/// Absolute tolerance of the residual test at error tolerance `tol`: 1e-6 at `tol = 1e-3`,
/// scaled with `tol` below that (the relative part is `tol` itself).
fn residual_eps_abs(tol: f64) -> f64 {
    RESIDUAL_EPS_ABS * tol.min(RESIDUAL_EPS_ABS_FROM) / RESIDUAL_EPS_ABS_FROM
}

/// Settings with every default resolved.
#[derive(Debug, Clone, PartialEq)]
pub struct Resolved {
    /// Concrete variant.
    pub variant: Variant,
    /// Concrete initial rho rule.
    pub initial_rho: InitialRho,
    /// Concrete Anderson memory.
    pub anderson: usize,
    /// The Newton phase.
    pub newton: NewtonUse,
}

impl Settings {
    /// Checks every value; the error names the setting.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |name, reason: String| Err(Error::InvalidSetting { name, reason });
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return bad(
                "tolerance",
                format!("must be positive and finite, got {}", self.tolerance),
            );
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1".into());
        }
        if self.time_limit.is_nan() || self.time_limit <= 0.0 {
            return bad(
                "time_limit",
                format!(
                    "must be positive (infinity for none), got {}",
                    self.time_limit
                ),
            );
        }
        if let Some(InitialRho::Given(r)) = self.initial_rho {
            if !(r.is_finite() && r > 0.0) {
                return bad(
                    "initial_rho",
                    format!("a given rho must be positive and finite, got {r}"),
                );
            }
        }
        if self.threads == 0 || self.threads > MAX_THREADS {
            return bad(
                "threads",
                format!("must be between 1 and {MAX_THREADS}, got {}", self.threads),
            );
        }
        if self.anderson_interval == 0 {
            return bad("anderson_interval", "must be at least 1".into());
        }
        if let Some(m) = self.anderson {
            if m > ANDERSON_MEMORY_MAX {
                return bad(
                    "anderson",
                    format!("memory must be at most {ANDERSON_MEMORY_MAX}, got {m}"),
                );
            }
        }
        Ok(())
    }

    /// Checks that `next` may replace these settings in a built solver: it is valid, and
    /// changes only what a solve reads when it starts (tolerance, iteration and time
    /// limits, trace, threads). The others chose the structure, the penalty or the Newton
    /// path the solver was built with; changing them needs a new solver.
    pub fn check_update(&self, next: &Settings) -> Result<(), Error> {
        next.validate()?;
        let fixed: [(&'static str, bool); 8] = [
            ("variant", self.variant == next.variant),
            ("initial_rho", self.initial_rho == next.initial_rho),
            ("s_update", self.s_update == next.s_update),
            ("anderson", self.anderson == next.anderson),
            (
                "anderson_interval",
                self.anderson_interval == next.anderson_interval,
            ),
            ("newton_polish", self.newton_polish == next.newton_polish),
            ("islands", self.islands == next.islands),
            ("linear_solver", self.linear_solver == next.linear_solver),
        ];
        match fixed.iter().find(|(_, same)| !same) {
            Some(&(name, _)) => Err(Error::InvalidSetting {
                name,
                reason: "cannot change in a built solver (it chose the structure, the penalty \
                         or the Newton path): build a new solver"
                    .into(),
            }),
            None => Ok(()),
        }
    }

    /// What the engine loop runs with, for a problem whose Newton step factorizes a dense
    /// system or not (the step's cost in the handover's model).
    pub(crate) fn engine_settings(
        &self,
        resolved: &Resolved,
        dense_newton: bool,
    ) -> EngineSettings {
        EngineSettings {
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            time_limit: self.time_limit,
            variant: resolved.variant,
            anderson: resolved.anderson,
            anderson_interval: self.anderson_interval,
            s_update: self.s_update,
            eps_abs: residual_eps_abs(self.tolerance),
            eps_rel: self.tolerance,
            check_every: ERROR_CHECK_INTERVAL,
            trace: self.trace,
            rho_range: RHO_RANGE,
            handover: (resolved.newton == NewtonUse::Polish).then_some(Handover {
                error_below: HANDOVER_ERROR,
                stall_checks: HANDOVER_STALL_CHECKS,
                newton_steps: NEWTON_EXPECTED_STEPS,
                rescue_steps: NEWTON_RESCUE_STEPS,
                newton_step_iterations: match dense_newton {
                    true => NEWTON_DENSE_STEP_ITERATIONS,
                    false => NEWTON_STEP_ITERATIONS,
                },
                budget: NEWTON_BUDGET,
            }),
        }
    }

    /// Resolves `auto` and the per-variant defaults.
    pub fn resolved(&self) -> Resolved {
        match self.variant {
            VariantChoice::Auto | VariantChoice::Newton => Resolved {
                variant: Variant::from_name(AUTO_VARIANT).expect("AUTO_VARIANT is a valid name"),
                initial_rho: self.initial_rho.unwrap_or(AUTO_INITIAL_RHO),
                anderson: self.anderson.unwrap_or(AUTO_ANDERSON),
                newton: match (self.variant, self.newton_polish) {
                    (VariantChoice::Newton, _) => NewtonUse::Alone,
                    (_, Some(false)) => NewtonUse::Off,
                    _ => NewtonUse::Polish,
                },
            },
            VariantChoice::Named(v) => Resolved {
                variant: v,
                initial_rho: self.initial_rho.unwrap_or(InitialRho::Normal),
                anderson: self.anderson.unwrap_or(0),
                newton: if self.newton_polish == Some(true) {
                    NewtonUse::Polish
                } else {
                    NewtonUse::Off
                },
            },
        }
    }
}

/// How the first rho is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialRho {
    /// rho = 1 (eq. 37).
    Normal,
    /// `||M||_1 / ||H||_1` (eq. 36); `||W||_1` for the local form.
    Acary,
    /// Ghadimi's optimal rho from the Delassus spectrum (eq. 34).
    Ghadimi,
    /// Di Cairano's optimal rho from the spectrum of M (eq. 35).
    DiCairano,
    /// A given value.
    Given(f64),
}

impl InitialRho {
    /// Parses `normal`, `acary`, `ghadimi`, `dicairano` or `given` (with `value`).
    pub fn from_name(name: &str, value: f64) -> Result<Self, Error> {
        match name {
            "normal" => Ok(InitialRho::Normal),
            "acary" => Ok(InitialRho::Acary),
            "ghadimi" => Ok(InitialRho::Ghadimi),
            "dicairano" => Ok(InitialRho::DiCairano),
            "given" if value.is_finite() && value > 0.0 => Ok(InitialRho::Given(value)),
            "given" => Err(Error::InvalidSetting {
                name: "initial_rho",
                reason: format!("a given rho must be positive and finite, got {value}"),
            }),
            _ => Err(Error::InvalidSetting {
                name: "initial_rho",
                reason: format!(
                    "unknown rule '{name}' (expected normal, acary, ghadimi, dicairano or given)"
                ),
            }),
        }
    }

    /// The rule's name.
    pub fn name(&self) -> &'static str {
        match self {
            InitialRho::Normal => "normal",
            InitialRho::Acary => "acary",
            InitialRho::Ghadimi => "ghadimi",
            InitialRho::DiCairano => "dicairano",
            InitialRho::Given(_) => "given",
        }
    }
}
