//! How far a sweep moved the impulses, and when a sweep stood still enough to be measured:
//! engines stop their own sweeps once one moves nothing, and a measure the checkpoints
//! would skip as too dear may find the tolerance met.

use crate::tuning::GAUSS_SEIDEL_STILL;

/// How far a sweep moved the impulses (contacts' and joint rows'): the sums of squares of
/// their changes and of their new values (sums, not largest entries: a sweep runs through
/// its contacts waiting on each one's velocities, and these add beside that wait, where
/// comparisons for the largest took 7% of the sweeps' rate).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Movement {
    step_sq: f64,
    impulse_sq: f64,
}

impl Movement {
    /// Counts the changes `step` of impulses whose new values are `new`.
    #[inline(always)]
    pub(super) fn add<const K: usize>(&mut self, step: &[f64; K], new: &[f64; K]) {
        // One addition a call on each running sum: the squares are summed apart from it.
        self.step_sq += step.iter().map(|x| x * x).sum::<f64>();
        self.impulse_sq += new.iter().map(|x| x * x).sum::<f64>();
    }

    /// The sweep stood still to `share`: the impulses moved by at most `share` times their
    /// norm (not at all, when all are zero).
    fn still(&self, share: f64) -> bool {
        self.step_sq <= share * share * self.impulse_sq
    }

    /// How far the impulses moved, as a share of their norm (0 when none moved).
    fn share(&self) -> f64 {
        match self.step_sq {
            0.0 => 0.0,
            step_sq => (step_sq / self.impulse_sq).sqrt(),
        }
    }
}

/// Asks for a measure when a sweep stands still: at first at [`GAUSS_SEIDEL_STILL`] times
/// the tolerance, then only at a sweep that many times stiller than the last one asked.
pub(super) struct Stillness {
    share: f64,
}

impl Stillness {
    /// For a run to `tolerance`.
    pub(super) fn new(tolerance: f64) -> Self {
        Self {
            share: GAUSS_SEIDEL_STILL * tolerance,
        }
    }

    /// Whether the sweep that `moved` so should be measured.
    pub(super) fn asks(&mut self, moved: Movement) -> bool {
        let asks = moved.still(self.share);
        if asks {
            self.share = GAUSS_SEIDEL_STILL * moved.share();
        }
        asks
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first measure at a tenth of the tolerance, the next at a sweep ten times
    /// stiller than the one that asked; a sweep that moved nothing always asks, and then
    /// only another that moves nothing.
    #[test]
    fn stillness_asks_once_a_decade() {
        let moved = |step: f64| {
            let mut m = Movement::default();
            m.add(&[step, 0.0, 0.0], &[1.0, 0.0, 0.0]);
            m
        };
        let mut s = Stillness::new(1e-4);
        assert!(!s.asks(moved(2e-5)));
        assert!(s.asks(moved(8e-6)));
        assert!(!s.asks(moved(1e-6)));
        assert!(s.asks(moved(7e-7)));
        assert!(s.asks(moved(0.0)));
        assert!(!s.asks(moved(1e-100)));
        assert!(s.asks(Movement::default()));
    }
}
