//! The ADMM loop: one implementation for every problem, rule and acceleration.

use super::anderson::Anderson;
use super::rho_rule::{IterationView, RhoAdapter};
use super::{Relaxation, SUpdate, Splitting, Variant};
use crate::csc::norm2;
use crate::types::{Error, Status};
use crate::types::{Phase, TracePoint};
use std::time::Instant;

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

/// When the loop hands its iterate over to a finishing phase (the Newton polish): once the
/// error measure is below `error_below`, or when it stalls, i.e. fails to halve over
/// `stall_checks` consecutive evaluations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handover {
    /// Hand over at or below this error.
    pub error_below: f64,
    /// Hand over when the error has not halved over this many evaluations (0: never).
    pub stall_checks: usize,
    /// ... but not below `error_below` while the current rate would reach the tolerance
    /// within this many iterations.
    pub finish_within: usize,
}

/// The iterate the loop works on; the caller initializes it (warm start) and reads it back.
#[derive(Debug, Clone)]
pub struct EngineState {
    /// `y` (u~ for the global form, z for the local form).
    pub y: Vec<f64>,
    /// Scaled dual.
    pub zeta: Vec<f64>,
    /// `A x` of the last x-step.
    pub ax: Vec<f64>,
    /// Penalty.
    pub rho: f64,
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
}

fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// Runs ADMM from `state` until the problem's error measure reaches the tolerance or a
/// limit is hit. `state` holds the last finite iterate on return.
pub fn run(
    sp: &mut dyn Splitting,
    state: &mut EngineState,
    set: &EngineSettings,
    start: Instant,
) -> Result<EngineOutcome, Error> {
    let l = sp.dim();
    let rho0 = state.rho;
    let (rho_min, rho_max) = (rho0 / set.rho_range, rho0 * set.rho_range);
    sp.set_rho(state.rho)?;
    let mut out = EngineOutcome {
        error: f64::INFINITY,
        ..Default::default()
    };

    // Inputs of the next iteration (hat variables), its outputs, and work vectors.
    let mut y_in = state.y.clone();
    let mut z_in = state.zeta.clone();
    let mut y = vec![0.0; l];
    let mut zeta = vec![0.0; l];
    let mut ax = vec![0.0; l];
    let mut diff = vec![0.0; l];
    // Nesterov memory: previous outputs.
    let mut y_prev = y_in.clone();
    let mut z_prev = z_in.clone();
    let (mut alpha, mut e_prev) = (1.0f64, f64::INFINITY);
    let eta = 0.999;
    let relaxation = if set.anderson > 0 {
        Relaxation::None
    } else {
        set.variant.relaxation
    };
    // Anderson on the stacked state (y, zeta).
    let mut aa = Anderson::new(set.anderson, 2 * l);
    let mut aa_x = vec![0.0; if set.anderson > 0 { 2 * l } else { 0 }];
    let mut aa_g = aa_x.clone();
    let mut aa_next = aa_x.clone();
    let mut plain = aa_x.clone(); // fallback when an accelerated point is rejected
    let mut last_was_aa = false;
    // Whether the form's own x iterate (the global form's velocity) came from a rejected
    // step and so does not belong to the state's iterate.
    let mut x_stale = false;
    let mut res_prev = f64::INFINITY;

    let mut rule = RhoAdapter::new(set.variant.rule, l);
    let mut rho = state.rho;
    // Errors of the last evaluations, for the stall test of the handover.
    let stall_checks = set.handover.map_or(0, |h| h.stall_checks);
    let mut recent = vec![f64::INFINITY; stall_checks];
    let mut checks = 0usize;
    let mut last_check_error = f64::INFINITY;
    // The iterate with the smallest measured error, handed back when a limit ends the run
    // (its buffers allocated here: the loop does not allocate).
    let mut best = BestIterate::new(state, sp);
    let mut inner_tol = if set.s_update == SUpdate::External {
        1e-3f64.max(set.tolerance)
    } else {
        0.0
    };

    for k in 0..set.max_iterations {
        sp.x_step(&y_in, &z_in, rho, &mut ax);
        sp.y_step(&ax, &z_in, &mut y);
        let c = sp.c();
        let mut primal_sq = 0.0;
        for i in 0..l {
            let r = ax[i] - c[i] - y[i];
            zeta[i] = z_in[i] + r;
            primal_sq += r * r;
            diff[i] = y[i] - y_in[i];
        }
        let primal = primal_sq.sqrt();
        let dual = rho * sp.norm_at(&diff);
        out.iterations = k + 1;
        out.primal = primal;
        out.dual = dual;
        if !(finite(&ax) && finite(&y) && finite(&zeta) && dual.is_finite()) {
            out.status = Some(Status::NumericalError);
            break; // state still holds the last finite iterate
        }

        // Anderson safeguard: an accelerated input whose fixed-point residual grew is
        // rejected; the iteration restarts from the plain point it replaced.
        if set.anderson > 0 {
            let res = (primal_sq + norm2(&diff).powi(2)).sqrt();
            if last_was_aa && res > res_prev {
                out.aa_rejected += 1;
                x_stale = true;
                aa.reset();
                last_was_aa = false;
                y_in.copy_from_slice(&plain[..l]);
                z_in.copy_from_slice(&plain[l..]);
                continue;
            }
            if last_was_aa {
                out.aa_accepted += 1;
            }
            res_prev = res;
        }

        // The state now holds a finite iterate.
        x_stale = false;
        state.y.copy_from_slice(&y);
        state.zeta.copy_from_slice(&zeta);
        state.ax.copy_from_slice(&ax);
        state.rho = rho;

        // Stopping: the residual test (docs/algorithms.md §8) is a cheap trigger; the decision is the
        // problem's own error measure, also evaluated periodically.
        // max(||A x||, ||y||): the c-independent part of the primal scale, used three times.
        let xy_scale = norm2(&ax).max(norm2(&y));
        let eps_pri = (l as f64).sqrt() * set.eps_abs + set.eps_rel * xy_scale.max(norm2(sp.c()));
        let residual_test = primal <= eps_pri && {
            let eps_dual = (l as f64).sqrt() * set.eps_abs + set.eps_rel * rho * sp.norm_at(&zeta);
            dual <= eps_dual
        };
        // The trace measures every iteration, but only the iterations measured without it
        // decide (stop, hand over): tracing must not change the solve.
        let check = residual_test || (k + 1) % set.check_every == 0 || k + 1 == set.max_iterations;
        if check || set.trace {
            let error = sp.error(&ax, &y, &zeta, rho);
            if set.trace {
                out.trace.push(TracePoint {
                    iteration: k + 1,
                    seconds: start.elapsed().as_secs_f64(),
                    error,
                    primal_residual: primal,
                    dual_residual: dual,
                    rho,
                    anderson_accepted: out.aa_accepted,
                    anderson_rejected: out.aa_rejected,
                    phase: Phase::Admm,
                });
            }
            if check {
                out.error = error;
                best.offer(error, state, sp);
            }
        }
        if check {
            if out.error <= set.tolerance {
                out.status = Some(Status::Solved);
                break;
            }
            if let Some(h) = set.handover {
                let stalled = stall_checks > 0 && {
                    let oldest = recent[checks % stall_checks];
                    recent[checks % stall_checks] = out.error;
                    checks += 1;
                    checks > stall_checks && out.error > 0.5 * oldest
                };
                // ADMM about to finish on its own (at the rate of the last evaluations) is
                // cheaper than a Newton phase: no handover then.
                let rate = out.error / last_check_error;
                let finishing = rate < 1.0
                    && (set.tolerance / out.error).ln() / rate.ln() * set.check_every as f64
                        <= h.finish_within as f64;
                last_check_error = out.error;
                if (out.error <= h.error_below && !finishing) || stalled {
                    out.handed_over = true;
                    break;
                }
            }
        }
        if start.elapsed().as_secs_f64() > set.time_limit {
            out.status = Some(Status::TimeLimit);
            break;
        }

        // s update.
        match set.s_update {
            SUpdate::Internal => {
                sp.update_s(&ax, &y);
            }
            SUpdate::External => {
                let scale = xy_scale.max(norm2(sp.c())).max(1e-300);
                if primal <= inner_tol * scale
                    && dual <= inner_tol * rho * sp.norm_at(&zeta).max(1e-300)
                {
                    sp.update_s(&ax, &y);
                    inner_tol = (inner_tol * 0.1).max(0.1 * set.tolerance);
                }
            }
        }

        // Next penalty, from this iteration's quantities.
        let dual_scale = if rule.needs_dual_scale() {
            sp.norm_at(&zeta)
        } else {
            0.0
        };
        let view = IterationView {
            k,
            rho,
            primal,
            dual,
            primal_scale: xy_scale.max(norm2(sp.c())),
            dual_scale,
            ax: &ax,
            y: &y,
            zeta: &zeta,
            zeta_in: &z_in,
            y_in: &y_in,
            c: sp.c(),
        };
        let rho_next = rule.next_rho(&view).clamp(rho_min, rho_max);

        // Next input: Anderson, Nesterov relaxation (with restart), or the plain output.
        if set.anderson > 0 {
            aa_x[..l].copy_from_slice(&y_in);
            aa_x[l..].copy_from_slice(&z_in);
            aa_g[..l].copy_from_slice(&y);
            aa_g[l..].copy_from_slice(&zeta);
            // The history grows every iteration; the extrapolated point is used only on
            // the iterations that try it.
            let extrapolated = aa.step(&aa_x, &aa_g, &mut aa_next);
            last_was_aa = extrapolated && (k + 1) % set.anderson_interval.max(1) == 0;
            plain.copy_from_slice(&aa_g);
            let next = if last_was_aa { &aa_next } else { &aa_g };
            y_in.copy_from_slice(&next[..l]);
            z_in.copy_from_slice(&next[l..]);
        } else {
            let mut relax = relaxation != Relaxation::None;
            if relaxation == Relaxation::NesterovRestart {
                let e = norm_diff_sq(&zeta, &z_in) + norm_diff_sq(&y, &y_in);
                if e < eta * e_prev {
                    e_prev = e;
                } else {
                    relax = false;
                    alpha = 1.0;
                    e_prev /= eta;
                }
            }
            if relax {
                let alpha_next = 0.5 * (1.0 + (1.0 + 4.0 * alpha * alpha).sqrt());
                let beta = (alpha - 1.0) / alpha_next;
                for i in 0..l {
                    y_in[i] = y[i] + beta * (y[i] - y_prev[i]);
                    z_in[i] = zeta[i] + beta * (zeta[i] - z_prev[i]);
                }
                alpha = alpha_next;
            } else {
                y_in.copy_from_slice(&y);
                z_in.copy_from_slice(&zeta);
            }
            y_prev.copy_from_slice(&y);
            z_prev.copy_from_slice(&zeta);
        }

        if rho_next != rho {
            // Scaled form: the unscaled dual rho * zeta is what must stay put.
            let s = rho / rho_next;
            for v in z_in
                .iter_mut()
                .chain(z_prev.iter_mut())
                .chain(plain.iter_mut().skip(l))
            {
                *v *= s;
            }
            rho = rho_next;
            sp.set_rho(rho)?;
            // Momentum and Anderson history mix iterates of the maps of two penalties:
            // both restart. (Nesterov momentum carried across the spectral rule's frequent
            // changes kept vp-R-Spectral from converging on GFC3D_Example1.)
            alpha = 1.0;
            aa.reset();
            last_was_aa = false;
            res_prev = f64::INFINITY;
        }
    }
    if out.status.is_none() && !out.handed_over {
        out.status = Some(Status::MaxIterations);
    }
    if x_stale && out.status != Some(Status::NumericalError) {
        // The limit struck on a rejected Anderson step: the form's x iterate is that of
        // the rejected point. Take it from the kept iterate (the plain step the rejection
        // restarts from), so that what is measured and handed back is one iterate.
        sp.x_step(&state.y, &state.zeta, state.rho, &mut ax);
    }
    if out.status != Some(Status::Solved) {
        out.error = sp.error(&state.ax, &state.y, &state.zeta, state.rho);
    }
    if matches!(out.status, Some(Status::MaxIterations | Status::TimeLimit))
        && best.error < out.error
    {
        // ADMM's error is not monotone: a limit hands back the best iterate of the run,
        // measured again.
        best.restore(state, sp);
        out.error = sp.error(&state.ax, &state.y, &state.zeta, state.rho);
    }
    Ok(out)
}

/// The iterate with the smallest measured error of a run: the engine state and the
/// splitting's own part ([`Splitting::save_iterate`]). Offers copy into the buffers made
/// by [`BestIterate::new`].
struct BestIterate {
    error: f64,
    state: EngineState,
    own: Vec<f64>,
}

impl BestIterate {
    /// Buffers shaped like `state` and the splitting's own part; no iterate kept yet.
    fn new(state: &EngineState, sp: &dyn Splitting) -> Self {
        let mut own = Vec::new();
        sp.save_iterate(&mut own);
        Self {
            error: f64::INFINITY,
            state: state.clone(),
            own,
        }
    }

    /// Keeps the current iterate when `error` is the smallest so far.
    fn offer(&mut self, error: f64, state: &EngineState, sp: &dyn Splitting) {
        if error >= self.error {
            return;
        }
        self.state.y.copy_from_slice(&state.y);
        self.state.zeta.copy_from_slice(&state.zeta);
        self.state.ax.copy_from_slice(&state.ax);
        self.state.rho = state.rho;
        // Within the capacity `new` gave it.
        self.own.clear();
        sp.save_iterate(&mut self.own);
        self.error = error;
    }

    /// Makes the kept iterate the current one (only after an offer was kept).
    fn restore(&self, state: &mut EngineState, sp: &mut dyn Splitting) {
        state.y.copy_from_slice(&self.state.y);
        state.zeta.copy_from_slice(&self.state.zeta);
        state.ax.copy_from_slice(&self.state.ax);
        state.rho = self.state.rho;
        sp.restore_iterate(&self.own);
    }
}

fn norm_diff_sq(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum()
}
