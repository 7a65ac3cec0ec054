//! A [`NonconvexProblem`] as an engine [`Splitting`] in either update order, and the run of
//! one (problem, order, strategy, tau0) on [`cadmm::admm::run`].

use super::{NonconvexProblem, Quality};
use cadmm::admm::{
    self, norm2, EngineSettings, EngineState, Relaxation, RhoRule, SUpdate, Splitting, Variant,
};
use cadmm::{Error, Status};
use std::cell::RefCell;
use std::time::Instant;

/// Which term ADMM updates first: the smooth one (the seed's Figure 1) or the nonsmooth
/// one (its Figure 2).
///
/// The engine always does its x-step, then its y-step, on `A x - y = c`. The two orders
/// are two assignments of the problem's blocks to those roles:
///
/// * solve first: `x = s`, `A = K`, `y = n`, `c = 0`. The x-step is the linear solve of
///   the `s` block, the y-step the elementwise prox of the `n` block.
/// * prox first: `x = n`, `A = I`, `y = K s`, `c = 0` (the constraint `n - K s = 0`). The
///   x-step is the prox; the y-step is the prox of `F~(w) = min { F(s) : K s = w }`, which
///   is `K s` for `s = argmin F(s) + rho/2 ||K s - t||^2`, the same linear solve. The
///   residuals, the stopping test and the spectral curvatures are then those of ADMM on
///   the swapped problem `min G(n) + F(s)`.
///
/// The smooth term is the solved block `F` except in phase retrieval, where the seed
/// counts `1/2 || |u| - c ||^2` (differentiable away from 0) as the smooth term and updates
/// it first in its Figure 1 (see [`NonconvexProblem::prox_is_smooth`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Smooth block first.
    SmoothFirst,
    /// Nonsmooth block first.
    NonsmoothFirst,
}

impl Order {
    /// Both orders.
    pub const ALL: [Order; 2] = [Order::SmoothFirst, Order::NonsmoothFirst];

    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Order::SmoothFirst => "smooth-first",
            Order::NonsmoothFirst => "nonsmooth-first",
        }
    }
}

/// The penalty strategies the seed compares, as engine rules (no relaxation, no Anderson).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// Constant penalty ("vanilla ADMM").
    Vanilla,
    /// He et al.'s residual balancing (tau = 2, phi = 10).
    ResidualBalancing,
    /// Xu et al.'s spectral rule (AADMM: eps_cor = 0.2, period 2).
    Spectral,
}

impl Strategy {
    /// The three strategies.
    pub const ALL: [Strategy; 3] = [
        Strategy::Vanilla,
        Strategy::ResidualBalancing,
        Strategy::Spectral,
    ];

    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Vanilla => "vanilla",
            Strategy::ResidualBalancing => "residual-balancing",
            Strategy::Spectral => "spectral",
        }
    }

    /// The engine variant: the rule, no relaxation.
    pub fn variant(self) -> Variant {
        let rule = match self {
            Strategy::Vanilla => RhoRule::Constant,
            Strategy::ResidualBalancing => RhoRule::he(),
            Strategy::Spectral => RhoRule::spectral(),
        };
        Variant {
            rule,
            relaxation: Relaxation::None,
        }
    }
}

/// A problem seen by the engine in one update order.
///
/// Its error measure is the seed's stopping quantity (eq. 6),
/// `max(||r|| / max(||A x||, ||y||, ||c||), ||d|| / ||A^T lambda||)` with `r = A x - y - c`,
/// `d = rho A^T (y - y_prev)` and `lambda = rho zeta`, so that "error <= tol" is eq. (6).
pub struct OrderedSplitting<'a> {
    problem: &'a mut dyn NonconvexProblem,
    prox_first: bool,
    rho: f64,
    zeros: Vec<f64>,
    y_in: Vec<f64>,
    // The smooth block of the last smooth solve (the y-step in the prox-first order,
    // which the engine calls through `&self`).
    s: RefCell<Vec<f64>>,
    t: RefCell<Vec<f64>>,
}

impl<'a> OrderedSplitting<'a> {
    /// `problem` in `order`.
    pub fn new(problem: &'a mut dyn NonconvexProblem, order: Order) -> Self {
        let l = problem.dim();
        let prox_first = (order == Order::NonsmoothFirst) != problem.prox_is_smooth();
        Self {
            problem,
            prox_first,
            rho: f64::NAN,
            zeros: vec![0.0; l],
            y_in: vec![0.0; l],
            s: RefCell::new(Vec::new()),
            t: RefCell::new(vec![0.0; l]),
        }
    }

    /// The smooth block `s` of the last smooth solve.
    pub fn smooth_block(&self) -> Vec<f64> {
        self.s.borrow().clone()
    }

    /// The nonsmooth block `n` of an engine state.
    pub fn nonsmooth_block<'s>(&self, state: &'s EngineState) -> &'s [f64] {
        if self.prox_first {
            &state.ax
        } else {
            &state.y
        }
    }

    fn smooth(&self, t: &[f64], out: &mut [f64]) {
        self.problem
            .smooth_step(t, self.rho, &mut self.s.borrow_mut(), out);
    }
}

impl Splitting for OrderedSplitting<'_> {
    fn dim(&self) -> usize {
        self.zeros.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        self.rho = rho;
        self.problem.set_rho(rho)
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], _rho: f64, ax: &mut [f64]) {
        self.y_in.copy_from_slice(y);
        let mut t = self.t.borrow_mut();
        for i in 0..t.len() {
            t[i] = y[i] - zeta[i];
        }
        if self.prox_first {
            self.problem.nonsmooth_prox(&t, self.rho, ax);
        } else {
            self.smooth(&t, ax);
        }
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        let mut t = self.t.borrow_mut();
        for i in 0..t.len() {
            t[i] = ax[i] + zeta[i];
        }
        if self.prox_first {
            self.smooth(&t, y);
        } else {
            self.problem.nonsmooth_prox(&t, self.rho, y);
        }
    }

    fn c(&self) -> &[f64] {
        &self.zeros
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        if self.prox_first {
            norm2(d)
        } else {
            self.problem.norm_kt(d)
        }
    }

    fn error(&mut self, ax: &[f64], y: &[f64], zeta: &[f64], _rho: f64) -> f64 {
        let (mut primal, mut dy) = (0.0, vec![0.0; y.len()]);
        for i in 0..y.len() {
            primal += (ax[i] - y[i]) * (ax[i] - y[i]);
            dy[i] = y[i] - self.y_in[i];
        }
        let primal = primal.sqrt() / norm2(ax).max(norm2(y));
        // rho cancels: ||d|| / ||A^T lambda|| = ||A^T (y - y_prev)|| / ||A^T zeta||.
        let dual = self.norm_at(&dy) / self.norm_at(zeta);
        // A diverged iterate (0/0, inf/inf) must not pass for a converged one.
        if primal.is_nan() || dual.is_nan() {
            f64::INFINITY
        } else {
            primal.max(dual)
        }
    }
}

/// When a run stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopSettings {
    /// `eps_tol` of eq. (6).
    pub tolerance: f64,
    /// Iteration limit.
    pub max_iterations: usize,
}

impl StopSettings {
    /// The seed's experiments: eq. (6) at `1e-5` (the seed's text gives no value; this is
    /// the one of the authors' released experiment scripts), at most `max_iterations`
    /// (2000 for regression, denoising and the eigenvector, 200 for phase retrieval: the
    /// limits of the seed's Table 1).
    pub fn paper(max_iterations: usize) -> Self {
        Self {
            tolerance: 1e-5,
            max_iterations,
        }
    }
}

/// The outcome of one run.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// Iterations done.
    pub iterations: usize,
    /// Eq. (6) held within the iteration limit.
    pub converged: bool,
    /// How the run ended (`NumericalError`: the iterates overflowed).
    pub status: Status,
    /// The eq. (6) quantity at the end.
    pub error: f64,
    /// The penalty at the end.
    pub final_rho: f64,
    /// Quality of the final iterate.
    pub quality: Quality,
    /// The smooth block at the end.
    pub s: Vec<f64>,
    /// The nonsmooth block at the end.
    pub n: Vec<f64>,
}

/// Runs ADMM on `problem` in `order` with `strategy` from the initial penalty `tau0` and the
/// problem's starting point (zero dual), on the engine's loop.
pub fn solve(
    problem: &mut dyn NonconvexProblem,
    order: Order,
    strategy: Strategy,
    tau0: f64,
    stop: &StopSettings,
) -> Result<RunResult, Error> {
    let y0 = problem.initial();
    let l = y0.len();
    let mut sp = OrderedSplitting::new(problem, order);
    let mut state = EngineState {
        y: y0,
        zeta: vec![0.0; l],
        ax: vec![0.0; l],
        rho: tau0,
    };
    // The residual test with eps_abs = 0 and eps_rel = tol is eq. (6) itself: the engine
    // evaluates the error measure (the same quantity) exactly when it passes, and only
    // then (check_every beyond the iteration limit), so the stop is eq. (6).
    let set = EngineSettings {
        tolerance: stop.tolerance,
        max_iterations: stop.max_iterations,
        time_limit: f64::INFINITY,
        variant: strategy.variant(),
        anderson: 0,
        anderson_interval: 1,
        s_update: SUpdate::Internal,
        eps_abs: 0.0,
        eps_rel: stop.tolerance,
        check_every: stop.max_iterations + 1,
        trace: false,
        rho_range: 1e8,
        handover: None,
    };
    let out = admm::run(&mut sp, &mut state, &set, Instant::now())?;
    let s = sp.smooth_block();
    let n = sp.nonsmooth_block(&state).to_vec();
    drop(sp);
    let quality = problem.quality(&s, &n);
    Ok(RunResult {
        iterations: out.iterations,
        converged: out.status == Some(Status::Solved),
        status: out.status.unwrap_or(Status::MaxIterations),
        error: out.error,
        final_rho: state.rho,
        quality,
        s,
        n,
    })
}
