//! When the ADMM loop hands its iterate over to a finishing phase (the Newton polish,
//! docs/algorithms.md §9.3): the error measure is low enough and ADMM is not about to
//! finish on its own, or the error stalls.

/// A stall is an error not halved over the window: the hybrid rule of docs/algorithms.md §9.3.
const STALL_RATIO: f64 = 0.5;

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

/// Watches the error measure at the loop's evaluations and says when to hand over.
pub(super) struct HandoverMonitor {
    rule: Handover,
    tolerance: f64,
    check_every: usize,
    /// Errors of the last `stall_checks` evaluations (a ring, `checks` modulo its length).
    recent: Vec<f64>,
    checks: usize,
    /// Error of the previous evaluation, for the rate.
    last_error: f64,
}

impl HandoverMonitor {
    /// A monitor for a loop stopping at `tolerance` and evaluating the error every
    /// `check_every` iterations.
    pub(super) fn new(rule: Handover, tolerance: f64, check_every: usize) -> Self {
        Self {
            rule,
            tolerance,
            check_every,
            recent: vec![f64::INFINITY; rule.stall_checks],
            checks: 0,
            last_error: f64::INFINITY,
        }
    }

    /// Records the error of one evaluation; true when the loop should hand over now.
    pub(super) fn hand_over(&mut self, error: f64) -> bool {
        let stalled = self.stalled(error);
        let finishing = self.finishing(error);
        self.last_error = error;
        (error <= self.rule.error_below && !finishing) || stalled
    }

    /// Records `error` in the window; true when it is not below `STALL_RATIO` times the
    /// error `stall_checks` evaluations ago.
    fn stalled(&mut self, error: f64) -> bool {
        let n = self.recent.len();
        n > 0 && {
            let oldest = self.recent[self.checks % n];
            self.recent[self.checks % n] = error;
            self.checks += 1;
            self.checks > n && error > STALL_RATIO * oldest
        }
    }

    /// ADMM about to finish on its own (at the rate of the last two evaluations) is
    /// cheaper than a Newton phase: no handover below `error_below` then.
    fn finishing(&self, error: f64) -> bool {
        let rate = error / self.last_error;
        rate < 1.0
            && (self.tolerance / error).ln() / rate.ln() * self.check_every as f64
                <= self.rule.finish_within as f64
    }
}
