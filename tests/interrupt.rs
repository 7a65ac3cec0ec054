//! `Solver::set_interrupt`: a set flag ends a solve as its time limit would, and a flag
//! that is never set changes nothing.

use cadmm::{CscMatrix, LocalProblem, Problem, Settings, Solver, Status, VariantChoice};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Two coupled contacts pressed down, which plain ADMM needs a few dozen iterations for.
fn problem() -> Problem {
    let w = [
        2.0, 0.3, 0.1, 0.5, 0.0, 0.2, //
        0.3, 1.5, 0.0, 0.1, 0.2, 0.0, //
        0.1, 0.0, 1.2, 0.0, 0.1, 0.3, //
        0.5, 0.1, 0.0, 2.5, 0.2, 0.1, //
        0.0, 0.2, 0.1, 0.2, 1.1, 0.0, //
        0.2, 0.0, 0.3, 0.1, 0.0, 1.4,
    ];
    let w = CscMatrix::from_dense("W", 6, 6, &w).unwrap();
    let q = vec![-1.0, 0.4, -0.3, -0.5, 0.2, 0.6];
    Problem::Local(LocalProblem::new(w, q, vec![0.4, 0.6]).unwrap())
}

fn settings() -> Settings {
    Settings {
        variant: VariantChoice::from_name("cp-N").unwrap(),
        ..Settings::default()
    }
}

#[test]
fn a_set_flag_stops_after_one_iteration_and_a_cleared_one_changes_nothing() {
    let flag = Arc::new(AtomicBool::new(true));
    let mut solver = Solver::new(problem(), settings()).unwrap();
    solver.set_interrupt(flag.clone());
    assert_eq!(solver.solve().unwrap(), Status::TimeLimit);
    assert_eq!(solver.stats().iterations, 1);
    assert!(solver.stats().error.is_finite());

    flag.store(false, Ordering::Relaxed);
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let mut plain = Solver::new(problem(), settings()).unwrap();
    assert_eq!(plain.solve().unwrap(), Status::Solved);
    assert_eq!(solver.solution(), plain.solution());
    assert_eq!(solver.stats().iterations, plain.stats().iterations);
    assert!(solver.stats().iterations > 1);
}

#[test]
fn every_island_reads_the_flag() {
    let two = Problem::block_diagonal(&[problem(), problem()]).unwrap();
    let flag = Arc::new(AtomicBool::new(true));
    let mut solver = Solver::new(two, settings()).unwrap();
    assert_eq!(solver.stats().islands, 2);
    solver.set_interrupt(flag);
    assert_eq!(solver.solve().unwrap(), Status::TimeLimit);
    assert!(solver.island_stats().iter().all(|s| s.iterations == 1));
}
