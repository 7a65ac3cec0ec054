//! Solver settings, validated when a solver is built.

use crate::admm::{EngineSettings, Handover, SUpdate, Variant};
use crate::types::Error;

/// Which ADMM variant to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VariantChoice {
    /// The measured default (see README, "Choosing `auto`").
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

/// Settings of a solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Target of the error measure (docs/algorithms.md §3). Default 1e-8.
    pub tolerance: f64,
    /// Iteration limit. Default 100000.
    pub max_iterations: usize,
    /// Wall-clock limit of one solve, seconds. Default: none (infinity).
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
    /// Finish with the semismooth Newton phase; `None`: the variant's default (on for
    /// `auto`, off for the named ADMM variants, which then run as published).
    pub newton_polish: Option<bool>,
    /// Split the problem into its contact islands and solve each on its own
    /// (docs/algorithms.md §12). Default on.
    pub islands: bool,
    /// Threads that solve islands side by side: 1 (the default) solves them one after the
    /// other on the caller's thread; more starts that many scoped threads for each solve
    /// that has several islands (no pool is kept). The results do not depend on it.
    pub threads: usize,
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
        }
    }
}

/// What `auto` runs.
pub const AUTO_VARIANT: &str = "vp-N-He";

/// Anderson memory `auto` uses.
pub const AUTO_ANDERSON: usize = 5;
/// Initial rho rule `auto` uses.
pub const AUTO_INITIAL_RHO: InitialRho = InitialRho::Acary;

/// The error measure is evaluated every this many iterations (and whenever the cheap
/// residual test passes): it costs a few matrix-vector products, an iteration about one solve.
pub const ERROR_CHECK_INTERVAL: usize = 5;

/// ADMM hands over to the Newton phase once the error measure is at or below this: by then
/// it has identified which contacts are open, sticking or sliding, where Newton converges
/// in a few steps.
pub const HANDOVER_ERROR: f64 = 1e-6;

/// ... or when the error has not halved over this many evaluations (ERROR_CHECK_INTERVAL
/// iterations each): ADMM has stalled, and Newton may still finish from there.
pub const HANDOVER_STALL_CHECKS: usize = 20;

/// No handover while ADMM, at the rate of its last error evaluations, would reach the
/// tolerance within this many iterations: on easy files a Newton phase (a factorization
/// and a few steps) costs more than that. (FCLib set at 1e-8, `auto` against ADMM alone:
/// median time ratio 1.28 with no such rule, 1.06 with 200 iterations.)
pub const FINISH_WITHIN: usize = 200;

/// Newton steps allowed per Newton phase with ADMM to fall back on. Newton itself stops a
/// phase that has not improved for 60 steps; on the Box_Stacks files it needs 80 to 110
/// steps from ADMM's handover, so caps of 50 or 100 failed phases that were about to
/// converge (FCLib set at 1e-8: 8.2 s in all with 50, 6.7 s with 200, 5.2 s with 400).
pub const NEWTON_MAX_STEPS: usize = 400;

/// Most island threads one solve may start.
pub const MAX_THREADS: usize = 256;

/// The solver works to `tolerance * (1 - ROUND_OFF_MARGIN)`: the measure of a solution
/// computed elsewhere (another summation order, another program) differs by round-off, and
/// a solution reported solved must meet the tolerance there too. At mass ratio 1e4 the local
/// measure of one solution read 9.99964e-9 in cadmm and 1.0000037e-8 recomputed, a
/// relative difference of 4e-5.
pub const ROUND_OFF_MARGIN: f64 = 1e-3;

/// Rounds in which islands are solved again to a tighter tolerance when their assembled
/// solution misses the whole problem's tolerance (docs/algorithms.md §12).
pub const ISLAND_ROUNDS: usize = 4;

/// A problem whose Newton system has at most this many unknowns (velocities, contact rows
/// and joints; the local form: contact rows) starts with a Newton phase of at most
/// [`NEWTON_FIRST_STEPS`] steps, ADMM taking over only if it fails: its dense Newton step
/// costs about as much as a few ADMM iterations, and Newton needs 4 to 10 of them where
/// ADMM needs about 100 (the small Rover files: 3 to 4x less time, median of 2000 solves).
pub const NEWTON_FIRST_MAX_SIZE: usize = crate::linsys::DENSE_MAX;

/// Steps of the first Newton phase of a small problem.
pub const NEWTON_FIRST_STEPS: usize = 50;

/// rho stays within `[rho0 / RHO_RANGE, rho0 * RHO_RANGE]`: beyond that the factorization of
/// `M + rho H H^T` (or `W + rho I`) loses the other term to round-off.
pub const RHO_RANGE: f64 = 1e8;

/// Absolute tolerance of the residual test at error tolerance `tol`: 1e-6 at `tol = 1e-3`,
/// scaled with `tol` below that (the relative part is `tol` itself).
fn residual_eps_abs(tol: f64) -> f64 {
    1e-6 * tol.min(1e-3) / 1e-3
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
            if m > 64 {
                return bad("anderson", format!("memory must be at most 64, got {m}"));
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
        let fixed: [(&'static str, bool); 7] = [
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

    /// What the engine loop runs with.
    pub(crate) fn engine_settings(&self, resolved: &Resolved) -> EngineSettings {
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
                finish_within: FINISH_WITHIN,
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
