//! When the ADMM loop hands its iterate over to a finishing phase (the Newton polish,
//! docs/algorithms.md §9.3): the error measure is low enough, or the error stalls, and a
//! Newton phase is predicted to cost less than ADMM still needs at its measured rate.

use std::time::Instant;

/// A stall is an error not halved over the window: the hybrid rule of docs/algorithms.md §9.3.
const STALL_RATIO: f64 = 0.5;

/// ADMM's rate is measured over this many evaluations (with Anderson steps the error is not
/// monotone from one evaluation to the next).
const RATE_WINDOW: usize = 4;

/// When the loop hands its iterate over to a finishing phase (the Newton polish): once the
/// error measure is below `error_below`, or when it stalls, i.e. fails to halve over
/// `stall_checks` consecutive evaluations; in both cases only when the predicted cost of a
/// Newton phase is below the predicted cost of finishing with ADMM.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handover {
    /// Hand over at or below this error.
    pub error_below: f64,
    /// Hand over when the error has not halved over this many evaluations (0: never).
    pub stall_checks: usize,
    /// Newton steps a phase is expected to take.
    pub newton_steps: f64,
    /// Cost of one Newton step in seconds, measured on this problem's earlier phases;
    /// `None` before any: then `newton_step_iterations` ADMM iterations.
    pub newton_step_seconds: Option<f64>,
    /// The cost of a Newton step in ADMM iterations when none was measured.
    pub newton_step_iterations: f64,
}

/// Watches the error measure at the loop's evaluations and says when to hand over.
pub(super) struct HandoverMonitor {
    rule: Handover,
    tolerance: f64,
    /// When the loop started: ADMM's cost per iteration is measured from it.
    start: Instant,
    /// Errors of the last `stall_checks` evaluations (a ring, `checks` modulo its length).
    recent: Vec<f64>,
    checks: usize,
    /// Error and iteration count of the first evaluation and of the last `RATE_WINDOW`
    /// ones (a ring, `checks` modulo its length), for the rate.
    first: (f64, usize),
    window: [(f64, usize); RATE_WINDOW],
    /// ADMM's predicted iterations to the tolerance at the last evaluation, and its
    /// measured cost of an iteration.
    admm_iterations_left: f64,
    seconds_per_iteration: f64,
    /// The last evaluation was at or below `error_below`.
    polishing: bool,
}

impl HandoverMonitor {
    /// A monitor for a loop that starts now and stops at `tolerance`.
    pub(super) fn new(rule: Handover, tolerance: f64) -> Self {
        Self {
            rule,
            tolerance,
            start: Instant::now(),
            recent: vec![f64::INFINITY; rule.stall_checks],
            checks: 0,
            first: (f64::INFINITY, 0),
            window: [(f64::INFINITY, 0); RATE_WINDOW],
            admm_iterations_left: f64::INFINITY,
            seconds_per_iteration: 0.0,
            polishing: false,
        }
    }

    /// Records the error measured after `iterations` iterations of this loop; true when
    /// the loop should hand over now.
    pub(super) fn hand_over(&mut self, error: f64, iterations: usize) -> bool {
        self.seconds_per_iteration = self.start.elapsed().as_secs_f64() / iterations.max(1) as f64;
        self.admm_iterations_left = self.iterations_left(error, iterations);
        // The first evaluation gives no rate: ADMM may be about to finish.
        let rated = self.checks > 0;
        if self.checks == 0 {
            self.first = (error, iterations);
        }
        self.window[self.checks % RATE_WINDOW] = (error, iterations);
        let stalled = self.stalled(error);
        let newton_seconds = self.rule.newton_steps
            * self
                .rule
                .newton_step_seconds
                .unwrap_or(self.rule.newton_step_iterations * self.seconds_per_iteration);
        self.polishing = error <= self.rule.error_below;
        rated && (self.polishing || stalled) && newton_seconds < self.admm_seconds_left()
    }

    /// What the Newton phase after a handover may spend before it no longer pays: ADMM's
    /// predicted seconds to the tolerance when it handed over below `error_below`. A
    /// handover on a stall is a rescue, not a polish: no limit then (Newton took 175 steps
    /// from a stalled 4e-4 on Box_Stacks-i1000-444-8, where ADMM's estimate, from a rate
    /// near 1, said little).
    pub(super) fn newton_budget(&self) -> f64 {
        match self.polishing {
            true => self.admm_seconds_left(),
            false => f64::INFINITY,
        }
    }

    /// ADMM's predicted seconds to the tolerance at the last evaluation (infinite when
    /// its error was not falling).
    fn admm_seconds_left(&self) -> f64 {
        match self.admm_iterations_left {
            0.0 => 0.0,
            left => left * self.seconds_per_iteration,
        }
    }

    /// Records `error` in the stall window (and counts the evaluation); true when it is
    /// not below `STALL_RATIO` times the error `stall_checks` evaluations ago.
    fn stalled(&mut self, error: f64) -> bool {
        let n = self.recent.len();
        self.checks += 1;
        n > 0 && {
            let at = (self.checks - 1) % n;
            let oldest = self.recent[at];
            self.recent[at] = error;
            self.checks > n && error > STALL_RATIO * oldest
        }
    }

    /// Iterations ADMM still needs at its rate over the last `RATE_WINDOW` evaluations, or
    /// over the whole loop when the error did not fall over those (infinite when it did not
    /// fall at all). Called before the evaluation is recorded.
    fn iterations_left(&self, error: f64, iterations: usize) -> f64 {
        if error <= self.tolerance {
            return 0.0;
        }
        if self.checks == 0 {
            return f64::INFINITY;
        }
        let oldest = match self.checks >= RATE_WINDOW {
            true => self.window[self.checks % RATE_WINDOW],
            false => self.first,
        };
        let rate_since = |(e0, k0): (f64, usize)| {
            (error / e0).powf(1.0 / iterations.saturating_sub(k0).max(1) as f64)
        };
        let rate = [oldest, self.first]
            .into_iter()
            .map(rate_since)
            .find(|r| *r < 1.0);
        rate.map_or(f64::INFINITY, |r| (self.tolerance / error).ln() / r.ln())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(newton_step_seconds: Option<f64>) -> Handover {
        Handover {
            error_below: 1e-6,
            stall_checks: 4,
            newton_steps: 4.0,
            newton_step_seconds,
            newton_step_iterations: 50.0,
        }
    }

    /// Below `error_below`, the monitor hands over when ADMM's remaining iterations at the
    /// measured rate cost more than the Newton phase, and not when they cost less.
    #[test]
    fn hands_over_when_newton_is_cheaper() {
        // Error / 10 every 5 iterations: 1e-7 -> 1e-8 takes 5 more iterations, far
        // fewer than 4 steps x 50 iterations.
        let mut m = HandoverMonitor::new(rule(None), 1e-8);
        assert!(!m.hand_over(1e-6, 5));
        assert!(!m.hand_over(1e-7, 10));
        assert!(m.admm_seconds_left().is_finite());
        assert_eq!(m.newton_budget(), m.admm_seconds_left());
        // Error / 1.01 every 5 iterations: about 1 150 iterations to go.
        let mut m = HandoverMonitor::new(rule(None), 1e-8);
        assert!(!m.hand_over(1e-6, 5));
        assert!(m.hand_over(1e-6 / 1.01, 10));
        // The same, with a measured Newton step far dearer than ADMM's remaining time.
        let mut m = HandoverMonitor::new(rule(Some(1e3)), 1e-8);
        assert!(!m.hand_over(1e-6, 5));
        assert!(!m.hand_over(1e-6 / 1.01, 10));
    }

    /// Above `error_below`, only a stall hands over. ADMM's remaining time comes from the
    /// rate over the window, from the whole loop's when the window's error rose, and is
    /// infinite when that rose too.
    #[test]
    fn hands_over_on_a_stall() {
        let mut m = HandoverMonitor::new(rule(None), 1e-8);
        let mut handed = Vec::new();
        for (k, e) in [1e-3, 0.9e-3, 0.8e-3, 0.85e-3, 0.9e-3, 0.95e-3]
            .iter()
            .enumerate()
        {
            handed.push(m.hand_over(*e, 5 * (k + 1)));
        }
        assert_eq!(handed, [false, false, false, false, true, true]);
        // 0.95e-3 after 30 iterations, from 1e-3 after 5: about 5 590 iterations to go.
        let left = m.admm_iterations_left;
        assert!((left / 5_590.0 - 1.0).abs() < 0.01, "{left}");
        // A stall's Newton phase has no budget.
        assert!(m.newton_budget().is_infinite());
        assert!(m.hand_over(1.1e-3, 35));
        assert!(m.admm_seconds_left().is_infinite());
    }
}
