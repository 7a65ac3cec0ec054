//! When the ADMM loop hands its iterate over to a finishing phase (the Newton polish,
//! docs/algorithms.md §9.3): the error measure is low enough, or the error stalls, and a
//! Newton phase is predicted to cost less than what ADMM still needs at its measured rate.
//! Costs are counted in ADMM iterations, not seconds, so that the decision, and the solve,
//! do not depend on the machine's load.

use crate::tuning::HANDOVER_ERROR;

/// A stall is an error not halved over the window: the hybrid rule of docs/algorithms.md §9.3.
const STALL_RATIO: f64 = 0.5;

/// A Newton rescue from a stall more than this many times above the tolerance has no step
/// limit; nearer, it is bounded (see `HandoverMonitor::newton_budget`).
const RESCUE_FAR: f64 = 10.0;

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
    /// Newton steps a phase is expected to take from below `error_below` (a polish).
    pub newton_steps: f64,
    /// Newton steps a phase is expected to take from a stall above `error_below` (a rescue,
    /// from farther away).
    pub rescue_steps: f64,
    /// The cost of a Newton step, in ADMM iterations.
    pub newton_step_iterations: f64,
    /// A polishing phase may take the steps that cost this many times ADMM's predicted
    /// remaining iterations.
    pub budget: f64,
}

/// Watches the error measure at the loop's evaluations and says when to hand over.
pub(super) struct HandoverMonitor {
    rule: Handover,
    tolerance: f64,
    /// Errors of the last `stall_checks` evaluations (a ring, `checks` modulo its length).
    recent: Vec<f64>,
    checks: usize,
    /// Error and iteration count of the first evaluation and of the last `RATE_WINDOW`
    /// ones (a ring, `checks` modulo its length), for the rate.
    first: (f64, usize),
    window: [(f64, usize); RATE_WINDOW],
    /// ADMM's predicted iterations to the tolerance at the last evaluation.
    admm_iterations_left: f64,
    /// The last evaluation was at or below `error_below`.
    polishing: bool,
    /// The lowest error measured so far.
    best: f64,
}

impl HandoverMonitor {
    /// A monitor for a loop that stops at `tolerance`.
    pub(super) fn new(rule: Handover, tolerance: f64) -> Self {
        Self {
            rule,
            tolerance,
            recent: vec![f64::INFINITY; rule.stall_checks],
            checks: 0,
            first: (f64::INFINITY, 0),
            window: [(f64::INFINITY, 0); RATE_WINDOW],
            admm_iterations_left: f64::INFINITY,
            polishing: false,
            best: f64::INFINITY,
        }
    }

    /// Records the error measured after `iterations` iterations of this loop; true when
    /// the loop should hand over now.
    pub(super) fn hand_over(&mut self, error: f64, iterations: usize) -> bool {
        self.admm_iterations_left = self.iterations_left(error, iterations);
        // The first evaluation gives no rate: ADMM may be about to finish.
        let rated = self.checks > 0;
        if self.checks == 0 {
            self.first = (error, iterations);
        }
        self.window[self.checks % RATE_WINDOW] = (error, iterations);
        self.best = self.best.min(error);
        let stalled = self.stalled(error);
        self.polishing = error <= self.rule.error_below;
        let steps = match self.polishing {
            true => self.rule.newton_steps,
            false => self.rule.rescue_steps,
        };
        let newton = steps * self.rule.newton_step_iterations;
        // An error that has not fallen below its first measure gives no rate, hence no
        // prediction (a warm start's error may rise over the first iterations, from which
        // ADMM still finishes in a few): then only a stall hands over.
        let pays = match self.admm_iterations_left.is_finite() {
            true => newton < self.admm_iterations_left,
            false => stalled,
        };
        // A stall within RESCUE_FAR of the tolerance, above the handover error, is no
        // rescue: ADMM is within a decade of the end there (see `newton_budget`).
        let near = error <= RESCUE_FAR * self.tolerance && error > HANDOVER_ERROR;
        rated && (self.polishing || (stalled && !near)) && pays
    }

    /// How many steps the Newton phase after a handover may take before it no longer pays:
    /// the steps that cost ADMM's predicted iterations to the tolerance when it handed over
    /// below `error_below` (at least one). A handover on a stall is a rescue, not a polish:
    /// ADMM's estimate, from a rate near 1, says little there, and the phase has no limit.
    /// Rescues come from stalls more than [`RESCUE_FAR`] times above the tolerance, where
    /// ADMM's cost grows with the decades still to go and Newton's hardly does (Newton took
    /// 111 to 175 steps from stalls at 4e-4 on Box_Stacks-i1000-444-8 at 1e-8, where a phase
    /// cut short at ADMM's predicted iterations tripled the solve), or from below
    /// [`HANDOVER_ERROR`], where Newton converges fast. Nearer the tolerance, above that
    /// error, ADMM is within a decade of the end and a stall does not hand over at all: on
    /// 15 steps of Bullet scenes in motion (a wall of 100 bricks hit by a ball, 512 boxes
    /// falling into a bin) at 1e-4, such rescues, each allowed the steps that cost the
    /// iterations run before it, mostly failed, and every solve cost fewer iterations and
    /// Newton steps without them (at 50 iterations a step; a bin step's Newton step cost 57).
    pub(super) fn newton_budget(&self) -> Option<usize> {
        if !self.polishing {
            return None;
        }
        let steps = self.rule.budget * self.admm_iterations_left / self.rule.newton_step_iterations;
        steps.is_finite().then(|| (steps as usize).max(1))
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
    /// fall at all); near the tolerance, at most those from the best error at the whole
    /// loop's average rate to it. Called before the evaluation is recorded.
    fn iterations_left(&self, error: f64, iterations: usize) -> f64 {
        if error <= self.tolerance {
            return 0.0;
        }
        if self.checks == 0 {
            return f64::INFINITY;
        }
        // Geometric decrease per iteration from (e0 after k0 iterations) to `e` now.
        let rate = |e: f64, (e0, k0): (f64, usize)| {
            (e / e0).powf(1.0 / iterations.saturating_sub(k0).max(1) as f64)
        };
        let left = |e: f64, r: f64| match r < 1.0 {
            true => (self.tolerance / e).ln() / r.ln(),
            false => f64::INFINITY,
        };
        let oldest = match self.checks >= RATE_WINDOW {
            true => self.window[self.checks % RATE_WINDOW],
            false => self.first,
        };
        let at_rate = [oldest, self.first]
            .into_iter()
            .map(|from| rate(error, from))
            .find(|r| *r < 1.0)
            .map_or(f64::INFINITY, |r| left(error, r));
        // Anderson's errors are not monotone: near the tolerance a window that ends on an
        // upswing predicts far too many iterations. Once the best error so far is below
        // the handover error, the best at the whole run's average rate to it (the
        // iterations since counted in) is the other prediction, and the lower one holds.
        let best = self.best.min(error);
        match best <= self.rule.error_below {
            true => at_rate.min(left(best, rate(best, self.first))),
            false => at_rate,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(newton_step_iterations: f64) -> Handover {
        Handover {
            error_below: 1e-6,
            stall_checks: 4,
            newton_steps: 4.0,
            rescue_steps: 30.0,
            newton_step_iterations,
            budget: 1.0,
        }
    }

    /// Below `error_below`, the monitor hands over when ADMM's remaining iterations at the
    /// measured rate cost more than the Newton phase, and not when they cost less; the
    /// phase may take the steps those iterations pay for.
    #[test]
    fn hands_over_when_newton_is_cheaper() {
        // Error / 10 every 5 iterations: 1e-7 -> 1e-8 takes 5 more iterations, far
        // fewer than 4 steps x 50 iterations.
        let mut m = HandoverMonitor::new(rule(50.0), 1e-8);
        assert!(!m.hand_over(1e-6, 5));
        assert!(!m.hand_over(1e-7, 10));
        assert_eq!(m.admm_iterations_left, 5.0);
        // Error / 1.01 every 5 iterations: about 2 310 iterations to go, 46 steps' worth.
        let mut m = HandoverMonitor::new(rule(50.0), 1e-8);
        assert!(!m.hand_over(1e-6, 5));
        assert!(m.hand_over(1e-6 / 1.01, 10));
        assert_eq!(m.newton_budget(), Some(46));
        m.rule.budget = 2.0;
        assert_eq!(m.newton_budget(), Some(92));
        // The same, with Newton steps of 1 000 iterations: ADMM is cheaper.
        let mut m = HandoverMonitor::new(rule(1000.0), 1e-8);
        assert!(!m.hand_over(1e-6, 5));
        assert!(!m.hand_over(1e-6 / 1.01, 10));
    }

    /// Below the handover error, a window ending on an upswing (Anderson's errors are not
    /// monotone) predicts too many iterations; the best error at the run's average rate
    /// predicts fewer, and that one holds (a demo step: ADMM alone finished at 80).
    #[test]
    fn an_upswing_near_the_tolerance_is_read_from_the_best_error() {
        let mut m = HandoverMonitor::new(rule(50.0), 1e-8);
        let errors = [
            1.1e-4, 6.14e-6, 5.81e-6, 3.24e-6, 6.36e-7, 2.11e-6, 3.29e-7, 5.41e-7,
        ];
        for (k, e) in errors.iter().enumerate() {
            assert!(!m.hand_over(*e, 5 * (k + 1)));
        }
        // The window (6.36e-7 after 25 iterations to 5.85e-7 after 45) says about 1 000
        // iterations to go; 3.29e-7 reached from 1.1e-4 over 40 iterations says 24.
        assert!(!m.hand_over(5.85e-7, 45));
        let left = m.admm_iterations_left;
        assert!((left / 24.0 - 1.0).abs() < 0.05, "{left}");
    }

    /// A polishing error that rose since the first measure (a warm start's) gives no
    /// rate: no handover until it stalls.
    #[test]
    fn a_rising_error_without_a_rate_waits_for_a_stall() {
        let mut m = HandoverMonitor::new(rule(50.0), 1e-8);
        assert!(!m.hand_over(3.95e-8, 5));
        assert!(!m.hand_over(6.1e-8, 10));
        assert!(m.admm_iterations_left.is_infinite());
        // Not halved over 4 evaluations: a stall, which hands over.
        assert!(!m.hand_over(5e-8, 15));
        assert!(!m.hand_over(4.5e-8, 20));
        assert!(m.hand_over(4.5e-8, 25));
    }

    /// Above `error_below`, only a stall hands over; its Newton phase has no limit far from
    /// the tolerance, and near it may take the steps that cost the iterations ADMM has run.
    /// ADMM's remaining iterations come from the rate over the window, from the whole
    /// loop's when the window's error rose, and are infinite when that rose too.
    #[test]
    fn hands_over_on_a_stall() {
        let mut m = HandoverMonitor::new(rule(50.0), 1e-8);
        let mut handed = Vec::new();
        for (k, e) in [1e-3, 0.9e-3, 0.8e-3, 0.85e-3, 0.9e-3, 0.95e-3]
            .iter()
            .enumerate()
        {
            handed.push(m.hand_over(*e, 5 * (k + 1)));
        }
        assert_eq!(handed, [false, false, false, false, true, true]);
        // 0.95e-3 after 30 iterations, from 1e-3 after 5: about 5 590 iterations to go,
        // more than the 30 x 50 a rescue is expected to cost.
        let left = m.admm_iterations_left;
        assert!((left / 5_590.0 - 1.0).abs() < 0.01, "{left}");
        // 0.95e-3 is far above 1e-8: no limit.
        assert_eq!(m.newton_budget(), None);
        // Within 10 times the tolerance 1e-3 (above the handover error) a stall does not
        // hand over, whatever a step costs; within 10 times 1e-7, below the handover error,
        // Newton is where it converges fast and the phase starts, unbounded (the rising
        // error gives no prediction to bound it by).
        for (tolerance, errors, handed) in [
            (1e-3, [4e-3, 4.4e-3, 4.8e-3, 5.2e-3, 5.6e-3, 6e-3], false),
            (1e-7, [4e-7, 4.4e-7, 4.8e-7, 5.2e-7, 5.6e-7, 6e-7], true),
        ] {
            for step in [50.0, 5.0] {
                let mut near = HandoverMonitor::new(rule(step), tolerance);
                let last = errors
                    .iter()
                    .enumerate()
                    .map(|(k, e)| near.hand_over(*e, 5 * (k + 1)))
                    .last();
                assert_eq!(last, Some(handed), "{tolerance} {step}");
                assert!(near.admm_iterations_left.is_infinite());
                assert_eq!(near.newton_budget(), None);
            }
        }
        // A stall from which ADMM still finishes within 1 500 iterations is left to ADMM:
        // not halved over 4 evaluations, but at that window's rate (0.9e-3 after 10
        // iterations, 0.6e-3 after 25) 1e-8 is about 430 iterations away.
        // With Newton steps of 5 iterations the same stall hands over.
        for (step, handed) in [(50.0, false), (5.0, true)] {
            let mut m = HandoverMonitor::new(rule(step), 1e-8);
            for (k, e) in [1e-3, 0.9e-3, 0.8e-3, 0.7e-3].iter().enumerate() {
                assert!(!m.hand_over(*e, 5 * (k + 1)));
            }
            assert_eq!(m.hand_over(0.6e-3, 25), handed);
            let left = m.admm_iterations_left;
            assert!((left / 431.0 - 1.0).abs() < 0.01, "{left}");
        }
        assert!(m.hand_over(1.1e-3, 35));
        assert!(m.admm_iterations_left.is_infinite());
    }
}
