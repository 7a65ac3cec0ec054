//! Semismooth Newton phase (Alart-Curnier) for the local and global contact problems.
//!
//! Meant to finish a solve after ADMM has identified the contact states: from a start near
//! the solution it converges in a few steps. [`alart_curnier`] has the per-contact function
//! and Jacobian, [`local::LocalNewton`] and [`global::GlobalNewton`] the two solvers.

pub mod alart_curnier;
pub mod global;
pub mod local;
mod reduced;
mod sparse;
#[cfg(test)]
mod testing;

pub use alart_curnier::{ac_branch, ac_contact, Branch, Mat3};

#[cfg(doc)]
use crate::tuning::NewtonTuning;
use crate::tuning::NEWTON;
use crate::types::Status;
use std::time::Instant;
// The solvers' entry points, for the solver driver that will call them.
#[allow(unused_imports)]
pub use global::GlobalNewton;
#[allow(unused_imports)]
pub use local::LocalNewton;

/// Why a Newton solve stopped without reaching the tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FailReason {
    /// The iteration limit was reached.
    MaxIterations,
    /// The deadline passed.
    Deadline,
    /// No step decreased the merit function, even with the strongest regularization.
    LineSearch,
    /// The Newton matrix stayed singular (or its solution non-finite) at every
    /// regularization tried.
    Singular,
    /// The residual at the start point is not finite.
    NonFinite,
    /// The error measure did not improve by a tenth over many iterations.
    NoProgress,
}

/// Outcome status of a Newton solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NewtonStatus {
    /// The common error measure reached the tolerance.
    Converged,
    /// Stopped early; the best iterate found is returned anyway.
    Failed(FailReason),
}

/// What a Newton solve did. The best iterate (by the common error measure) is left in the
/// caller's vectors whatever the status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonOutcome {
    /// Converged or why not.
    pub status: NewtonStatus,
    /// Accepted Newton steps.
    pub iterations: usize,
    /// Numeric LU factorizations (one per step, more when a step is retried with a
    /// stronger regularization).
    pub factorizations: usize,
    /// Error measure (`crate::measure`) of the returned iterate.
    pub error: f64,
}

impl NewtonOutcome {
    /// True when the tolerance was reached.
    pub fn converged(&self) -> bool {
        self.status == NewtonStatus::Converged
    }

    /// The status of a solve that this Newton phase ends: `Solved` when its iterate `met`
    /// the tolerance (as the caller measures what it hands back), `TimeLimit` when the
    /// deadline passed, otherwise why Newton stopped. The one mapping of both Newton
    /// paths (a coupled problem's phase, a small island's dense Newton).
    pub fn status_when_final(&self, met: bool, deadline: Option<Instant>) -> Status {
        let timed_out = self.status == NewtonStatus::Failed(FailReason::Deadline)
            || deadline.is_some_and(|d| Instant::now() >= d);
        match self.status {
            _ if met => Status::Solved,
            _ if timed_out => Status::TimeLimit,
            NewtonStatus::Failed(FailReason::MaxIterations) => Status::MaxIterations,
            NewtonStatus::Failed(FailReason::NonFinite) => Status::NumericalError,
            _ => Status::Stalled,
        }
    }
}

/// What a Newton system supplies to the one iteration, [`iterate`]. The unknown is a flat
/// vector `x`: `r` for the local form, `(v, lambda, r)` for the global form.
pub(crate) trait NewtonSystem {
    /// The problem the system is built for.
    type Problem;
    /// Evaluates F, A, B at `x`; returns the merit `0.5 ||R||^2`.
    fn evaluate_at(&mut self, p: &Self::Problem, x: &[f64]) -> f64;
    /// The common error measure at `x`.
    fn error(&mut self, p: &Self::Problem, x: &[f64]) -> f64;
    /// Assembles, factorizes and solves for the direction at the last evaluated point;
    /// false when the matrix is singular or the direction not finite.
    fn direction(&mut self, p: &Self::Problem, alpha: f64) -> bool;
    /// Backtracking from `t = 1` against `reference`; the step length, with the trial point
    /// in [`NewtonSystem::trial`].
    fn line_search(&mut self, p: &Self::Problem, x: &[f64], reference: f64) -> Option<f64>;
    /// The trial point of the last successful line search.
    fn trial(&self) -> &[f64];
    /// Sets exactly to zero the impulses of contacts the converged `x` finds open, when the
    /// error stays within `max(error, tol)`; returns the error of `x`.
    fn snap_open(&mut self, p: &Self::Problem, x: &mut [f64], error: f64, tol: f64) -> f64;
    /// Numeric factorizations so far.
    fn factorizations(&self) -> usize;
    /// The impulse scale at `x`, `max(||r||, ||rho u_free||)` with `u_free` the free
    /// velocity: it makes the residual `||R||` relative and unit-free (every part of `R` is
    /// an impulse).
    fn impulse_scale(&self, p: &Self::Problem, x: &[f64]) -> f64;
    /// Cap of the residual-driven part of the regularization ([`NewtonTuning::alpha_cap`] unless a
    /// system knows better).
    fn alpha_cap(&self) -> f64 {
        NEWTON.alpha_cap
    }
    /// Steps without progress after which the iteration gives up ([`NewtonTuning::stall`]
    /// unless a system knows what its steps cost).
    fn stall(&self) -> usize {
        NEWTON.stall
    }
}

/// The Newton iteration both forms share: regularized steps, non-monotone line search,
/// best iterate by the common error measure (left in `x`; `best` is work space of `x`'s
/// length).
pub(crate) fn iterate<S: NewtonSystem>(
    s: &mut S,
    p: &S::Problem,
    x: &mut [f64],
    best: &mut [f64],
    tol: f64,
    max_iter: usize,
    deadline: Option<Instant>,
) -> NewtonOutcome {
    let factorizations0 = s.factorizations();
    let mut merit = s.evaluate_at(p, x);
    let err = s.error(p, x);
    // The regularization follows the residual relative to the impulse scale, not the error
    // measure: the measure adds velocities to impulses, so it changes with the units, and
    // the iterates would too.
    let relative = |merit: f64, scale: f64| {
        NEWTON.alpha_per_residual * (2.0 * merit).sqrt() / scale.max(f64::MIN_POSITIVE)
    };
    let mut rel = relative(merit, s.impulse_scale(p, x));
    best.copy_from_slice(x);
    let mut progress = Progress {
        err,
        rel,
        met_at: None,
        mark: err,
        last_improvement: 0,
        stall: s.stall(),
    };
    let mut reg = Regularization::new(s.alpha_cap());
    let mut window = MeritWindow::new(merit);
    let mut iterations = 0;
    let status = loop {
        if let Some(status) = progress.stop(merit, iterations, tol, max_iter, deadline) {
            break status;
        }
        let t = match regularized_step(s, p, x, &mut reg, rel, window.reference()) {
            Ok(t) => t,
            Err(why) => break NewtonStatus::Failed(why),
        };
        if t == 1.0 {
            reg.relax();
        }
        iterations += 1;
        // Accept the trial point; re-evaluate exactly (the trial residuals were updated
        // linearly and drift by round-off).
        x.copy_from_slice(s.trial());
        merit = s.evaluate_at(p, x);
        rel = relative(merit, s.impulse_scale(p, x));
        window.push(merit);
        let err = s.error(p, x);
        if progress.improves(err, rel, iterations, tol) {
            best.copy_from_slice(x);
        }
    };
    // A step that fails while confirming leaves a best iterate that meets the tolerance.
    let status = if progress.err <= tol {
        NewtonStatus::Converged
    } else {
        status
    };
    x.copy_from_slice(best);
    let mut error = progress.err;
    if status == NewtonStatus::Converged {
        error = s.snap_open(p, x, error, tol);
    }
    NewtonOutcome {
        status,
        iterations,
        factorizations: s.factorizations() - factorizations0,
        error,
    }
}

/// One step of [`iterate`] from `x`, at the relative residual `rel`: retried with a
/// stronger regularization until the line search against `reference` passes; its length.
fn regularized_step<S: NewtonSystem>(
    s: &mut S,
    p: &S::Problem,
    x: &[f64],
    reg: &mut Regularization,
    rel: f64,
    reference: f64,
) -> Result<f64, FailReason> {
    loop {
        let alpha = reg.alpha(rel);
        let outcome = if s.direction(p, alpha) {
            s.line_search(p, x, reference).ok_or(FailReason::LineSearch)
        } else {
            Err(FailReason::Singular)
        };
        match outcome {
            Ok(t) => return Ok(t),
            Err(why) if !reg.strengthen(rel) => return Err(why),
            Err(_) => {}
        }
    }
}

/// The best iterate of [`iterate`] so far, as its stopping rules read it.
struct Progress {
    /// The best iterate's error measure.
    err: f64,
    /// The best iterate's unit-free relative residual.
    rel: f64,
    /// The iteration at which the measure first met the tolerance.
    met_at: Option<usize>,
    /// The best error at the last improvement by [`NewtonTuning::progress`] ...
    mark: f64,
    /// ... and the iteration that made it.
    last_improvement: usize,
    /// Steps without progress after which the iteration gives up.
    stall: usize,
}

impl Progress {
    /// Why the iteration stops after `iterations` steps, at the merit `merit`; `None` to
    /// take another step.
    fn stop(
        &mut self,
        merit: f64,
        iterations: usize,
        tol: f64,
        max_iter: usize,
        deadline: Option<Instant>,
    ) -> Option<NewtonStatus> {
        if self.err <= tol {
            // The measure adds velocities to impulses, so whether an iterate meets it
            // depends on the units; the iterates do not. Up to `NEWTON.confirm` more steps
            // are taken until the unit-free residual agrees, so that the same iterate is
            // handed back in any units (the measure alone would stop a step earlier or
            // later when the mass unit changes).
            let met = *self.met_at.get_or_insert(iterations);
            if self.rel <= NEWTON.alpha_per_residual * tol || iterations - met >= NEWTON.confirm {
                return Some(NewtonStatus::Converged);
            }
        }
        let why = if !merit.is_finite() {
            FailReason::NonFinite
        } else if iterations >= max_iter {
            FailReason::MaxIterations
        } else if deadline.is_some_and(|d| Instant::now() >= d) {
            FailReason::Deadline
        } else if iterations - self.last_improvement >= self.stall {
            FailReason::NoProgress
        } else {
            return None;
        };
        Some(NewtonStatus::Failed(why))
    }

    /// Whether the iterate after `iterations` steps, of error `err` and relative residual
    /// `rel`, is the new best; it is recorded as such then, and as progress when it cuts
    /// the error of the last progress by [`NewtonTuning::progress`].
    fn improves(&mut self, err: f64, rel: f64, iterations: usize, tol: f64) -> bool {
        // Past the tolerance, the best is the unit-free one among the iterates that meet it.
        let better = if self.err <= tol {
            err <= tol && rel < self.rel
        } else {
            err < self.err
        };
        if better {
            self.err = err;
            self.rel = rel;
        }
        // Progress is an error cut by a share: a phase that creeps (9.3e-6 to 8.7e-6 in 246
        // steps on Box_Stacks-i1000-547-14) stops like one that does not move.
        if err <= NEWTON.progress * self.mark {
            self.mark = err;
            self.last_improvement = iterations;
        }
        better
    }
}

/// `max(||r||, ||rho u_free||)` with `rho` per contact: the impulse scale of
/// [`NewtonSystem::impulse_scale`], for both forms.
pub(crate) fn impulse_scale(r: &[f64], rho: &[f64], u_free: &[f64]) -> f64 {
    let free: f64 = u_free
        .iter()
        .enumerate()
        .map(|(k, u)| (rho[k / 3] * u).powi(2))
        .sum();
    crate::csc::dot(r, r).max(free).sqrt()
}

/// The last [`NewtonTuning::window`] merit values: the line search asks for a decrease relative
/// to their maximum (non-monotone, Grippo-Lampariello-Lucidi), which lets the iteration
/// cross the kinks of `||F||` that stop a monotone search far from the solution.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MeritWindow {
    past: [f64; 8],
    len: usize,
    next: usize,
}

impl MeritWindow {
    /// A window holding the merit of the start point.
    pub fn new(first: f64) -> Self {
        let mut w = Self {
            past: [0.0; 8],
            len: 0,
            next: 0,
        };
        w.push(first);
        w
    }
    /// Records the merit of an accepted point (dropping the oldest).
    pub fn push(&mut self, merit: f64) {
        let cap = NEWTON.window.clamp(1, 8);
        self.past[self.next] = merit;
        self.next = (self.next + 1) % cap;
        self.len = (self.len + 1).min(cap);
    }
    /// The merit a trial point must decrease from.
    pub fn reference(&self) -> f64 {
        self.past[..self.len]
            .iter()
            .fold(0.0, |a: f64, &b| a.max(b))
    }
}

/// Regularization state: `alpha = clamp(min(rel, cap) * boost)`, where `rel` is the scaled
/// relative residual of [`iterate`], and `boost` grows by 10 when a step fails and shrinks
/// back by 10 after a full step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Regularization {
    cap: f64,
    boost: f64,
}

impl Regularization {
    /// No boost; `cap` bounds the residual-driven part.
    pub fn new(cap: f64) -> Self {
        Self { cap, boost: 1.0 }
    }
    /// The relative regularization to use at the relative residual `rel`. The floor comes
    /// before the boost, so that every boost raises alpha: at `rel = 0` (an underflowed
    /// residual) or an infinite impulse scale, a failing step still reaches `alpha_max` and
    /// gives up.
    pub fn alpha(&self, rel: f64) -> f64 {
        let t = NEWTON;
        let base = if rel.is_nan() {
            self.cap
        } else {
            rel.clamp(t.alpha_min, self.cap)
        };
        (base * self.boost).min(t.alpha_max)
    }
    /// Strengthens after a failed step; false when it is already at its maximum.
    pub fn strengthen(&mut self, rel: f64) -> bool {
        if self.alpha(rel) >= NEWTON.alpha_max {
            return false;
        }
        self.boost *= 10.0;
        true
    }
    /// Relaxes after a full step.
    pub fn relax(&mut self) {
        self.boost = (self.boost / 10.0).max(1.0);
    }
}

/// Per-contact rho from a 3x3 Delassus block: `1 / ||W_ii||_F`, 1 when the block is 0.
pub(crate) fn rho_from_block(block: &Mat3) -> f64 {
    let norm = block.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
    if norm.is_finite() && norm > 0.0 {
        1.0 / norm
    } else {
        1.0
    }
}

/// The Alart-Curnier function at one point, per contact: the local velocities `u`, the
/// residual `F` and the blocks `A`, `B` of its generalized Jacobian. Both Newton forms keep
/// one for the current point and one for the line search's trial point.
pub(crate) struct AcPoint {
    pub u: Vec<f64>,
    pub f: Vec<f64>,
    pub a: Vec<Mat3>,
    pub b: Vec<Mat3>,
}

impl AcPoint {
    /// Zeros for `nc` contacts.
    pub fn new(nc: usize) -> Self {
        Self {
            u: vec![0.0; 3 * nc],
            f: vec![0.0; 3 * nc],
            a: vec![[[0.0; 3]; 3]; nc],
            b: vec![[[0.0; 3]; 3]; nc],
        }
    }

    /// `F`, `A`, `B` at impulses `r` and the velocities in `u`; returns `0.5 ||F||^2`.
    pub fn evaluate(&mut self, r: &[f64], mu: &[f64], rho: &[f64]) -> f64 {
        eval_all(r, &self.u, mu, rho, &mut self.f, &mut self.a, &mut self.b)
    }
}

/// The backtracking line search of both forms: halves the step from `t = 1` until the
/// merit of the trial point at `t` (computed by `trial_merit`) shows a sufficient decrease
/// of `||F||` (Armijo, constant [`NewtonTuning::sigma`]); `None` below
/// [`NewtonTuning::min_step`].
pub(crate) fn backtrack(merit: f64, mut trial_merit: impl FnMut(f64) -> f64) -> Option<f64> {
    let mut t = 1.0;
    while t >= NEWTON.min_step {
        let trial = trial_merit(t);
        let decrease = 1.0 - NEWTON.sigma * t;
        if trial <= decrease * decrease * merit {
            return Some(t);
        }
        t *= 0.5;
    }
    None
}

/// Evaluates the Alart-Curnier function of every contact: fills `f` (length `3 nc`) and
/// the blocks `a`, `b`; returns `0.5 ||f||^2`.
pub(crate) fn eval_all(
    r: &[f64],
    u: &[f64],
    mu: &[f64],
    rho: &[f64],
    f: &mut [f64],
    a: &mut [Mat3],
    b: &mut [Mat3],
) -> f64 {
    let mut merit = 0.0;
    for i in 0..mu.len() {
        let ri = [r[3 * i], r[3 * i + 1], r[3 * i + 2]];
        let ui = [u[3 * i], u[3 * i + 1], u[3 * i + 2]];
        let (fi, ai, bi) = ac_contact(ri, ui, mu[i], rho[i], rho[i]);
        f[3 * i..3 * i + 3].copy_from_slice(&fi);
        a[i] = ai;
        b[i] = bi;
        merit += fi[0] * fi[0] + fi[1] * fi[1] + fi[2] * fi[2];
    }
    0.5 * merit
}

#[cfg(test)]
mod regularization_tests {
    use super::*;

    /// Strengthening ends for any residual: a residual of 0 (underflow) once kept alpha at
    /// its floor however large the boost, and the step retried forever.
    #[test]
    fn strengthening_always_reaches_the_maximum() {
        for rel in [0.0, 1e-300, 1e-14, 1e-8, 1.0, f64::INFINITY, f64::NAN] {
            let mut reg = Regularization::new(NEWTON.alpha_cap);
            let mut alpha = reg.alpha(rel);
            assert!(
                (NEWTON.alpha_min..=NEWTON.alpha_cap).contains(&alpha),
                "{rel}: {alpha}"
            );
            let mut tries = 0;
            while reg.strengthen(rel) {
                let stronger = reg.alpha(rel);
                assert!(stronger > alpha, "{rel}: {stronger} after {alpha}");
                alpha = stronger;
                tries += 1;
                assert!(tries < 40, "{rel}: still strengthening");
            }
            assert_eq!(reg.alpha(rel), NEWTON.alpha_max, "{rel}");
        }
    }
}

#[cfg(test)]
mod progress_tests {
    use super::*;

    fn progress(err: f64) -> Progress {
        progress_within(err, NEWTON.stall)
    }

    fn progress_within(err: f64, stall: usize) -> Progress {
        Progress {
            err,
            rel: 1.0,
            met_at: None,
            mark: err,
            last_improvement: 0,
            stall,
        }
    }

    /// Steps that each improve the best error a little, but never by a tenth together
    /// within the window, end the phase as no progress, at the window's end: the default
    /// window and the shorter ones of systems whose steps cost more.
    #[test]
    fn a_creeping_phase_stops_after_the_window() {
        for stall in [NEWTON.stall, 8, crate::tuning::NEWTON_MIN_STALL] {
            let mut p = progress_within(1e-5, stall);
            let mut stopped = None;
            for k in 1..=3 * NEWTON.stall {
                let err = 1e-5 * (1.0 - 1e-3 * k as f64);
                assert!(p.improves(err, 1.0, k, 1e-8), "step {k} is a new best");
                if let Some(status) = p.stop(1.0, k, 1e-8, usize::MAX, None) {
                    stopped = Some((k, status));
                    break;
                }
            }
            assert_eq!(
                stopped,
                Some((stall, NewtonStatus::Failed(FailReason::NoProgress))),
                "window {stall}"
            );
        }
    }

    /// A tenth off the error within the window starts a new window.
    #[test]
    fn a_tenth_off_the_error_keeps_the_phase_going() {
        let mut p = progress(1e-5);
        let mut err = 1e-5;
        for k in 1..=3 * NEWTON.stall {
            if k % (NEWTON.stall - 1) == 0 {
                err *= NEWTON.progress;
            }
            p.improves(err, 1.0, k, 1e-8);
            assert_eq!(p.stop(1.0, k, 1e-8, usize::MAX, None), None, "step {k}");
        }
        assert_eq!(p.err, err);
    }
}
