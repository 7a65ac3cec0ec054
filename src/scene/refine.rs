//! The refine rounds of a problem solved in parts and measured whole (docs/algorithms.md
//! §12, §16): one process's islands, or the processes' shared part and their own islands.
//! Each part meets its own tolerance, yet the assembled solution can miss the whole
//! problem's; the parts are then solved again, warm, to a tolerance tightened in proportion
//! to the miss. One loop and one rule for the final status, for both.

use crate::tuning::ISLAND_TIGHTENING;
use crate::types::Status;

/// A solve in parts, as the rounds drive it.
pub(crate) trait SolveInParts {
    /// What a failed round returns.
    type Error;

    /// Solves the parts still pending at their tolerances; the most severe status among
    /// them, `None` when they all solved ([`most_severe`]).
    fn solve_parts(&mut self) -> Result<Option<Status>, Self::Error>;

    /// The error measure of the assembled solution of the whole problem.
    fn whole_error(&mut self) -> Result<f64, Self::Error>;

    /// Multiplies the parts' tolerances by `factor` and starts them from the assembled
    /// solution.
    fn tighten(&mut self, factor: f64) -> Result<(), Self::Error>;
}

/// Up to `rounds` rounds: solve the parts, measure the whole, and stop when the whole meets
/// `tol`, when a part did not solve (a tighter tolerance will not help it), or after the
/// last round. Returns the status ([`final_status`]) and the whole error.
pub(crate) fn refine_rounds<P: SolveInParts>(
    parts: &mut P,
    tol: f64,
    rounds: usize,
) -> Result<(Status, f64), P::Error> {
    let (mut worst, mut error) = (None, f64::INFINITY);
    for round in 0..rounds {
        worst = parts.solve_parts()?;
        error = parts.whole_error()?;
        if error <= tol || worst.is_some() || round + 1 == rounds {
            break;
        }
        parts.tighten((tol / error).min(ISLAND_TIGHTENING))?;
    }
    Ok((final_status(worst, error, tol), error))
}

/// The status of a solve in parts: `Infeasible` when a part proved it (the whole has no
/// solution either), `Solved` when the whole measures within `tol`, otherwise the most
/// severe status of a part, or `MaxIterations` when every part solved yet the whole misses.
pub(crate) fn final_status(worst: Option<Status>, error: f64, tol: f64) -> Status {
    match worst {
        Some(Status::Infeasible) => Status::Infeasible,
        _ if error <= tol => Status::Solved,
        Some(status) => status,
        None => Status::MaxIterations,
    }
}

/// The more severe of two parts' outcomes (`None` and `Solved`: nothing to report).
pub(crate) fn most_severe(a: Option<Status>, b: Option<Status>) -> Option<Status> {
    let worse = if severity(b) > severity(a) { b } else { a };
    (severity(worse) > 0).then_some(worse).flatten()
}

/// A part's outcome as a number that grows with its severity, which processes can agree
/// on by taking the largest ([`status_of`] reads it back).
pub(crate) fn severity(status: Option<Status>) -> u8 {
    match status {
        None | Some(Status::Solved) | Some(Status::Unsolved) => 0,
        Some(Status::MaxIterations) => 1,
        Some(Status::TimeLimit) => 2,
        Some(Status::NumericalError) => 3,
        Some(Status::Stalled) => 4,
        Some(Status::Infeasible) => 5,
    }
}

/// The status of a [`severity`] (`None` for 0).
#[cfg(any(feature = "mpi", test))]
pub(crate) fn status_of(code: u8) -> Option<Status> {
    [
        Status::MaxIterations,
        Status::TimeLimit,
        Status::NumericalError,
        Status::Stalled,
        Status::Infeasible,
    ]
    .into_iter()
    .find(|&s| severity(Some(s)) == code)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parts whose whole error falls by a fixed ratio per round.
    struct Shrinking {
        error: f64,
        statuses: Vec<Option<Status>>,
        factors: Vec<f64>,
    }

    impl SolveInParts for Shrinking {
        type Error = ();
        fn solve_parts(&mut self) -> Result<Option<Status>, ()> {
            Ok(self.statuses.remove(0))
        }
        fn whole_error(&mut self) -> Result<f64, ()> {
            self.error /= 10.0;
            Ok(self.error)
        }
        fn tighten(&mut self, factor: f64) -> Result<(), ()> {
            self.factors.push(factor);
            Ok(())
        }
    }

    #[test]
    fn rounds_stop_when_the_whole_meets_the_tolerance() {
        let mut p = Shrinking {
            error: 1e-5,
            statuses: vec![None; 5],
            factors: vec![],
        };
        let (status, error) = refine_rounds(&mut p, 1.5e-7, 5).unwrap();
        assert_eq!(status, Status::Solved);
        assert!((error - 1e-7).abs() < 1e-20);
        // The first round's 1e-6 missed by 1e-6 / 1.5e-7: the tolerance is tightened by that
        // ratio, at most by ISLAND_TIGHTENING; the second round meets it.
        assert_eq!(p.factors.len(), 1);
        assert_eq!(
            p.factors[0],
            (1.5e-7 / p.error / 10.0).min(ISLAND_TIGHTENING)
        );
    }

    #[test]
    fn an_unsolved_part_ends_the_rounds_with_the_most_severe_status() {
        let mut p = Shrinking {
            error: 1.0,
            statuses: vec![most_severe(
                Some(Status::TimeLimit),
                Some(Status::MaxIterations),
            )],
            factors: vec![],
        };
        assert_eq!(refine_rounds(&mut p, 1e-8, 3).unwrap().0, Status::TimeLimit);
        assert!(p.factors.is_empty());
        assert_eq!(
            final_status(Some(Status::Infeasible), 0.0, 1.0),
            Status::Infeasible
        );
        assert_eq!(final_status(None, 1.0, 0.5), Status::MaxIterations);
        assert_eq!(most_severe(Some(Status::Solved), None), None);
        for code in 1..=5 {
            assert_eq!(severity(status_of(code)), code);
        }
    }
}
