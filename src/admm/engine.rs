//! The ADMM loop: one implementation for every problem, rule and acceleration
//! (docs/algorithms.md §4.1, §5-§8). The loop reads as the algorithm; its parts are the
//! accelerator (next input), the handover monitor, the best iterate, the s schedule and
//! the stopping test.

use super::accelerator::{Accelerator, Screen};
use super::best_iterate::BestIterate;
use super::handover::{Handover, HandoverMonitor};
use super::rho_rule::{IterationView, RhoAdapter};
use super::{EngineState, SUpdate, Splitting, Variant};
use crate::csc::dot;
use crate::types::{Error, Stats, Status};
use crate::types::{Phase, TracePoint};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Settings the loop needs.
#[derive(Debug, Clone)]
pub struct EngineSettings {
    /// Target of the problem's error measure.
    pub tolerance: f64,
    /// Iteration limit.
    pub max_iterations: usize,
    /// Wall-clock limit in seconds (infinite for none).
    pub time_limit: f64,
    /// Penalty rule and relaxation.
    pub variant: Variant,
    /// Anderson memory (0 = off). When on, it replaces the Nesterov relaxation.
    pub anderson: usize,
    /// An Anderson step is tried every this many iterations (at least 1).
    pub anderson_interval: usize,
    /// When the s parameter is updated.
    pub s_update: SUpdate,
    /// Absolute tolerance of the residual test (docs/algorithms.md §8).
    pub eps_abs: f64,
    /// Relative tolerance of the residual test (docs/algorithms.md §8).
    pub eps_rel: f64,
    /// The error measure is evaluated every this many iterations (and whenever the
    /// residual test passes).
    pub check_every: usize,
    /// Record a trace point per iteration.
    pub trace: bool,
    /// Bounds on rho relative to its initial value.
    pub rho_range: f64,
    /// When to stop and hand the iterate over to a finishing phase (none: run to the end).
    pub handover: Option<Handover>,
}

/// What the loop reports.
#[derive(Debug, Clone, Default)]
pub struct EngineOutcome {
    /// Outcome (None while running).
    pub status: Option<Status>,
    /// Iterations done.
    pub iterations: usize,
    /// Last error measure.
    pub error: f64,
    /// Last primal residual.
    pub primal: f64,
    /// Last dual residual.
    pub dual: f64,
    /// Anderson steps accepted.
    pub aa_accepted: usize,
    /// Anderson steps rejected.
    pub aa_rejected: usize,
    /// Per-iteration trace (empty unless asked for).
    pub trace: Vec<TracePoint>,
    /// The loop stopped to hand over (status `None`): see [`Handover`].
    pub handed_over: bool,
    /// At a handover, the steps the Newton phase may take (`None`: no limit), see
    /// [`Handover`].
    pub newton_budget: Option<usize>,
}

impl EngineOutcome {
    /// Adds this run to a solve's statistics: its iterations and Anderson counts add up,
    /// its final residuals replace the last run's.
    pub fn add_to(&self, stats: &mut Stats) {
        stats.iterations += self.iterations;
        stats.primal_residual = self.primal;
        stats.dual_residual = self.dual;
        stats.anderson_accepted += self.aa_accepted;
        stats.anderson_rejected += self.aa_rejected;
    }
}

/// External s update's first inner tolerance: loose, for a guessed shift (docs/algorithms.md §5).
const INNER_TOL_START: f64 = 1e-3;
/// Each external s update tightens the inner tolerance tenfold (docs/algorithms.md §5).
const INNER_TOL_SHRINK: f64 = 0.1;
/// Inner solves go no further than a decade below the outer tolerance (docs/algorithms.md §5).
const INNER_TOL_FLOOR: f64 = 0.1;
/// Floor of the external update's scales: its relative test stays defined at a zero iterate.
const TINY_SCALE: f64 = 1e-300;

/// Runs ADMM from `state` until the problem's error measure reaches the tolerance or a
/// limit is hit. `state` holds, on return, the solved iterate, or the best measured one of a
/// run a limit or a non-finite iterate ended (the last finite one when none was measured).
pub fn run(
    sp: &mut dyn Splitting,
    state: &mut EngineState,
    set: &EngineSettings,
    start: Instant,
) -> Result<EngineOutcome, Error> {
    run_until(sp, state, set, start, &AtomicBool::new(false))
}

/// [`run`], which also ends, as at its time limit, once `interrupt` is set (from any
/// thread): it is read where the clock is, after each iteration.
pub(crate) fn run_until(
    sp: &mut dyn Splitting,
    state: &mut EngineState,
    set: &EngineSettings,
    start: Instant,
    interrupt: &AtomicBool,
) -> Result<EngineOutcome, Error> {
    let (rho_min, rho_max) = (state.rho / set.rho_range, state.rho * set.rho_range);
    sp.set_deadline(
        Duration::try_from_secs_f64(set.time_limit)
            .ok()
            .and_then(|limit| start.checked_add(limit)),
    );
    sp.set_rho(state.rho)?;
    let mut out = EngineOutcome {
        error: f64::INFINITY,
        ..Default::default()
    };
    // Everything the loop works with is made here: the loop does not allocate.
    let l = sp.dim();
    let mut w = Work::new(state, l);
    let (anderson, interval) = (set.anderson, set.anderson_interval);
    let relaxation = set.variant.relaxation;
    let mut accel = Accelerator::new(anderson, interval, relaxation, &state.y, &state.zeta);
    let mut rule = RhoAdapter::new(set.variant.rule, l);
    let mut shift = ShiftSchedule::new(set);
    let mut stop = StopTest::new(set, start, interrupt, sp);
    let mut best = BestIterate::new(state, sp);
    let mut rho = state.rho;
    // Whether the form's own x iterate (the global form's velocity) came from a rejected
    // step and so does not belong to the state's iterate.
    let mut x_stale = false;

    for k in 0..set.max_iterations {
        // x-step, y-step, dual update.
        sp.x_step(&w.y_in, &w.z_in, rho, &mut w.ax);
        sp.y_step(&w.ax, &w.z_in, &mut w.y);
        let sums = w.dual_update(sp);
        let (primal, dual) = (sums.primal_sq.sqrt(), rho * sp.norm_at(&w.diff));
        (out.iterations, out.primal, out.dual) = (k + 1, primal, dual);
        if !(sums.finite && dual.is_finite()) {
            out.status = Some(Status::NumericalError);
            break; // state still holds the last finite iterate
        }
        // A rejected Anderson point voids the iteration: it restarts from the plain point.
        match accel.screen(sums.primal_sq + sums.diff_sq, &mut w.y_in, &mut w.z_in) {
            Screen::Rejected => {
                out.aa_rejected += 1;
                x_stale = true;
                continue;
            }
            Screen::Accepted => out.aa_accepted += 1,
            Screen::Plain => {}
        }
        x_stale = false;
        w.keep(state, rho); // the state now holds a finite iterate

        // Measure; stop test.
        let r = Residuals {
            primal,
            dual,
            xy_scale: sums.ax_sq.sqrt().max(sums.y_sq.sqrt()),
        };
        if stop.ends(sp, state, k, &r, &mut out, &mut best) {
            break;
        }
        // s update (docs/algorithms.md §5).
        shift.update(sp, &w, rho, &r);
        // Next rho, from this iteration's quantities (and c after the s update).
        let rho_next = next_rho(&mut rule, sp, &w, k, rho, &r).clamp(rho_min, rho_max);
        // Next input.
        let sum = |partial: &mut [f64]| sp.sum_across(partial);
        accel.next_input(k, &w.y, &w.zeta, &mut w.y_in, &mut w.z_in, &sum);
        rho = change_rho(sp, &mut accel, &mut w.z_in, rho, rho_next)?;
    }
    finish(sp, state, &best, x_stale, &mut w.ax, &mut out);
    Ok(out)
}

/// Makes `rho_next` the penalty of the next input, whose scaled dual is `z_in`, or the
/// current penalty current again when the system changed; the penalty now in force.
fn change_rho(
    sp: &mut dyn Splitting,
    accel: &mut Accelerator,
    z_in: &mut [f64],
    rho: f64,
    rho_next: f64,
) -> Result<f64, Error> {
    if rho_next != rho {
        // Scaled form: the unscaled dual rho * zeta is what must stay put.
        let s = rho / rho_next;
        z_in.iter_mut().for_each(|v| *v *= s);
        accel.rho_changed(s);
        sp.set_rho(rho_next)?;
        Ok(rho_next)
    } else {
        if sp.system_changed() {
            accel.rho_changed(1.0);
            sp.set_rho(rho)?;
        }
        Ok(rho)
    }
}

/// Ends a run: the status of a loop that ran out of iterations, and the iterate handed back
/// (the best one when a limit ended the run) with its error measured at it.
fn finish(
    sp: &mut dyn Splitting,
    state: &mut EngineState,
    best: &BestIterate,
    x_stale: bool,
    ax: &mut [f64],
    out: &mut EngineOutcome,
) {
    if out.status.is_none() && !out.handed_over {
        out.status = Some(Status::MaxIterations);
    }
    if x_stale && out.status != Some(Status::NumericalError) {
        // The limit struck on a rejected Anderson step: the form's x iterate is that of
        // the rejected point. Take it from the kept iterate (the plain step the rejection
        // restarts from), so that what is measured and handed back is one iterate.
        sp.x_step(&state.y, &state.zeta, state.rho, ax);
    }
    if out.status != Some(Status::Solved) {
        out.error = sp.error(&state.ax, &state.y, &state.zeta, state.rho);
    }
    let limited = matches!(
        out.status,
        Some(Status::MaxIterations | Status::TimeLimit | Status::NumericalError)
    );
    // The last finite iterate of a diverged run may measure NaN: any finite best beats it.
    let better = best.error() < out.error || out.error.is_nan();
    if limited && best.error().is_finite() && better {
        // ADMM's error is not monotone: a limit hands back the best iterate of the run,
        // measured again; so does a run that diverged, rather than its last finite iterate,
        // whose entries can be near overflow.
        best.restore(state, sp);
        out.error = sp.error(&state.ax, &state.y, &state.zeta, state.rho);
    }
}

/// The loop's vectors: the input of an iteration (the hat variables, which relaxation and
/// Anderson produce), its output, and `y+ - y_in`.
struct Work {
    y_in: Vec<f64>,
    z_in: Vec<f64>,
    y: Vec<f64>,
    zeta: Vec<f64>,
    ax: Vec<f64>,
    diff: Vec<f64>,
}

impl Work {
    /// The first input is the state; the other vectors have the dimension `l`.
    fn new(state: &EngineState, l: usize) -> Self {
        Self {
            y_in: state.y.clone(),
            z_in: state.zeta.clone(),
            y: vec![0.0; l],
            zeta: vec![0.0; l],
            ax: vec![0.0; l],
            diff: vec![0.0; l],
        }
    }

    /// `zeta+ = zeta_in + A x+ - c - y+` and `y+ - y_in`; returns the iteration's sums,
    /// added up across the processes sharing the problem.
    fn dual_update(&mut self, sp: &dyn Splitting) -> IterationSums {
        let c = sp.c();
        let mut primal_sq = 0.0;
        for i in 0..self.y.len() {
            let r = self.ax[i] - c[i] - self.y[i];
            self.zeta[i] = self.z_in[i] + r;
            primal_sq += r * r;
            self.diff[i] = self.y[i] - self.y_in[i];
        }
        let finite = finite(&self.ax) && finite(&self.y) && finite(&self.zeta);
        let mut sums = [
            primal_sq,
            dot(&self.diff, &self.diff),
            dot(&self.ax, &self.ax),
            dot(&self.y, &self.y),
            if finite { 0.0 } else { 1.0 },
        ];
        sp.sum_across(&mut sums);
        IterationSums {
            primal_sq: sums[0],
            diff_sq: sums[1],
            ax_sq: sums[2],
            y_sq: sums[3],
            finite: sums[4] == 0.0,
        }
    }

    /// Makes the iteration's output, at penalty `rho`, the state's iterate.
    fn keep(&self, state: &mut EngineState, rho: f64) {
        state.y.copy_from_slice(&self.y);
        state.zeta.copy_from_slice(&self.zeta);
        state.ax.copy_from_slice(&self.ax);
        state.rho = rho;
    }
}

fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// An iteration's squared norms and whether its output is finite (everywhere, when the
/// problem is shared by several processes).
struct IterationSums {
    /// `||A x+ - c - y+||^2`.
    pub primal_sq: f64,
    /// `||y+ - y_in||^2`.
    pub diff_sq: f64,
    /// `||A x+||^2`.
    pub ax_sq: f64,
    /// `||y+||^2`.
    pub y_sq: f64,
    /// `A x+`, `y+` and `zeta+` are finite.
    pub finite: bool,
}

/// An iteration's residuals (docs/algorithms.md §4.1) and the scale they are judged by.
struct Residuals {
    primal: f64,
    dual: f64,
    /// `max(||A x+||, ||y+||)`: the c-independent part of the primal scale, which the
    /// residual test, the external s update and the penalty rule each complete with `||c||`.
    xy_scale: f64,
}

/// The stopping test (docs/algorithms.md §8): the residual test is a cheap trigger; the
/// decision is the problem's own error measure, also evaluated periodically. Then the
/// handover, then the wall clock.
struct StopTest<'a> {
    set: &'a EngineSettings,
    start: Instant,
    /// When the last iteration was measured (the loop's start before the first).
    last_seen: Instant,
    interrupt: &'a AtomicBool,
    monitor: Option<HandoverMonitor>,
    /// The constraint space's dimension (of every process's part together).
    dim: f64,
}

impl<'a> StopTest<'a> {
    fn new(
        set: &'a EngineSettings,
        start: Instant,
        interrupt: &'a AtomicBool,
        sp: &dyn Splitting,
    ) -> Self {
        let monitor = set.handover.map(|h| HandoverMonitor::new(h, set.tolerance));
        let mut dim = [sp.dim() as f64];
        sp.sum_across(&mut dim);
        Self {
            set,
            start,
            last_seen: Instant::now(),
            interrupt,
            monitor,
            dim: dim[0],
        }
    }

    /// Measures the `k`-th (0-based) iteration, whose iterate `state` holds; true, with the
    /// ending set in `out`, when the loop ends there.
    fn ends(
        &mut self,
        sp: &mut dyn Splitting,
        state: &EngineState,
        k: usize,
        r: &Residuals,
        out: &mut EngineOutcome,
        best: &mut BestIterate,
    ) -> bool {
        let set = self.set;
        // The trace measures every iteration, but only the iterations measured without it
        // decide (stop, hand over): tracing must not change the solve.
        let check = self.residual_test(sp, state, r)
            || (k + 1) % set.check_every == 0
            || k + 1 == set.max_iterations;
        if check {
            sp.readmit(&state.ax);
        }
        if check || set.trace {
            let error = sp.error(&state.ax, &state.y, &state.zeta, state.rho);
            if set.trace {
                let seconds = self.start.elapsed().as_secs_f64();
                out.record(k, seconds, error, state.rho);
            }
            if check {
                out.error = error;
                best.offer(error, state, sp);
            }
        }
        if check && out.error <= set.tolerance {
            out.status = Some(Status::Solved);
        } else if let Some(left) = self
            .monitor
            .as_mut()
            .filter(|_| check)
            .and_then(|m| m.hand_over(out.error, k + 1).then(|| m.newton_budget()))
        {
            out.handed_over = true;
            out.newton_budget = left;
        } else if self.out_of_time(sp) {
            out.status = Some(Status::TimeLimit);
        }
        out.status.is_some() || out.handed_over
    }

    /// Whether the next iteration, judged by the one just done, would end past the time
    /// limit, or the run is interrupted (on any of the processes sharing the problem: they
    /// all stop together). Judged after the iteration that crosses it, a run overran its
    /// limit by most of an iteration: an engine's budget of a few iterations by a third.
    fn out_of_time(&mut self, sp: &dyn Splitting) -> bool {
        let now = Instant::now();
        let took = now.duration_since(std::mem::replace(&mut self.last_seen, now));
        let next_ends = (now + took).duration_since(self.start).as_secs_f64();
        let late = next_ends > self.set.time_limit || self.interrupt.load(Ordering::Relaxed);
        let mut late = [f64::from(u8::from(late))];
        sp.sum_across(&mut late);
        late[0] > 0.0
    }

    /// Boyd et al.'s residual test; `||A^T zeta+||` is computed only when the primal
    /// residual passes.
    fn residual_test(&self, sp: &mut dyn Splitting, state: &EngineState, r: &Residuals) -> bool {
        let set = self.set;
        let sqrt_l = self.dim.sqrt();
        let eps_pri = sqrt_l * set.eps_abs + set.eps_rel * r.xy_scale.max(norm_c(sp));
        r.primal <= eps_pri && {
            let eps_dual = sqrt_l * set.eps_abs + set.eps_rel * state.rho * sp.norm_at(&state.zeta);
            r.dual <= eps_dual
        }
    }
}

impl EngineOutcome {
    /// Appends the trace point of the `k`-th (0-based) iteration, measured at `error`.
    fn record(&mut self, k: usize, seconds: f64, error: f64, rho: f64) {
        self.trace.push(TracePoint {
            iteration: k + 1,
            seconds,
            error,
            primal_residual: self.primal,
            dual_residual: self.dual,
            rho,
            anderson_accepted: self.aa_accepted,
            anderson_rejected: self.aa_rejected,
            phase: Phase::Admm,
        });
    }
}

/// When the De Saxce shift `s` is updated (docs/algorithms.md §5).
struct ShiftSchedule {
    mode: SUpdate,
    tolerance: f64,
    /// The external update's inner tolerance.
    inner_tol: f64,
}

impl ShiftSchedule {
    fn new(set: &EngineSettings) -> Self {
        let inner_tol = match set.s_update {
            SUpdate::External => INNER_TOL_START.max(set.tolerance),
            SUpdate::Internal => 0.0,
        };
        Self {
            mode: set.s_update,
            tolerance: set.tolerance,
            inner_tol,
        }
    }

    /// After an iteration that did not end the loop: every time (internal), or once the
    /// convex problem with `s` fixed is solved to the inner tolerance (external).
    fn update(&mut self, sp: &mut dyn Splitting, w: &Work, rho: f64, r: &Residuals) {
        match self.mode {
            SUpdate::Internal => sp.update_s(&w.ax, &w.y),
            SUpdate::External => {
                let scale = r.xy_scale.max(norm_c(sp)).max(TINY_SCALE);
                if r.primal <= self.inner_tol * scale
                    && r.dual <= self.inner_tol * rho * sp.norm_at(&w.zeta).max(TINY_SCALE)
                {
                    sp.update_s(&w.ax, &w.y);
                    self.inner_tol =
                        (self.inner_tol * INNER_TOL_SHRINK).max(INNER_TOL_FLOOR * self.tolerance);
                }
            }
        }
    }
}

/// The rule's next penalty (unclamped) from the `k`-th iteration's quantities.
fn next_rho(
    rule: &mut RhoAdapter,
    sp: &mut dyn Splitting,
    w: &Work,
    k: usize,
    rho: f64,
    r: &Residuals,
) -> f64 {
    let dual_scale = if rule.needs_dual_scale() {
        sp.norm_at(&w.zeta)
    } else {
        0.0
    };
    rule.next_rho(&IterationView {
        k,
        rho,
        primal: r.primal,
        dual: r.dual,
        primal_scale: r.xy_scale.max(norm_c(sp)),
        dual_scale,
        ax: &w.ax,
        y: &w.y,
        zeta: &w.zeta,
        zeta_in: &w.z_in,
        y_in: &w.y_in,
        c: sp.c(),
        sum: &|partial| sp.sum_across(partial),
    })
}

/// `||c||` across the processes sharing the problem.
fn norm_c(sp: &dyn Splitting) -> f64 {
    let mut c_sq = [dot(sp.c(), sp.c())];
    sp.sum_across(&mut c_sq);
    c_sq[0].sqrt()
}
