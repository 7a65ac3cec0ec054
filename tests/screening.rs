//! Contacts a warm start predicts open are left out of the v-update system
//! (docs/algorithms.md §15): the answer must still be the whole problem's, also when a
//! contact predicted open has to push.

mod common;

use cadmm::{CscMatrix, GlobalProblem, Problem, Settings, Solver, Status};

/// Two unit point masses on the ground, one contact each (normal along z, tangents along
/// x and y): the first is pressed down and pushed sideways (it must stick: v = 0,
/// r = (1, -0.2, 0)); the second is lifted off a gap (v = (0, 0, 0.5), r = 0).
fn two_masses() -> GlobalProblem {
    let mut h = Vec::new();
    for body in 0..2 {
        for (k, axis) in [2, 0, 1].into_iter().enumerate() {
            h.push((3 * body + axis, 3 * body + k, 1.0));
        }
    }
    GlobalProblem::new(
        CscMatrix::identity(6),
        CscMatrix::from_triplets("H", 6, 6, &h).unwrap(),
        vec![0.2, 0.0, -1.0, 0.0, 0.0, 0.5],
        vec![0.0, 0.0, 0.0, 0.1, 0.0, 0.0],
        vec![0.5, 0.5],
    )
    .unwrap()
}

#[test]
fn a_contact_predicted_open_that_must_push_comes_back() {
    let p = two_masses();
    let tol = 1e-10;
    let settings = Settings {
        tolerance: tol,
        newton_polish: Some(false),
        ..Settings::default()
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
    // Both contacts look open from this warm start (no impulse, both masses rising).
    solver
        .warm_start(&[0.0; 6], Some(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]))
        .unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let s = solver.solution();
    let (v, r) = (&s.v, &s.r);
    let expected_v = [0.0, 0.0, 0.0, 0.0, 0.0, 0.5];
    let expected_r = [1.0, -0.2, 0.0, 0.0, 0.0, 0.0];
    for k in 0..6 {
        assert!((v[k] - expected_v[k]).abs() < 1e-7, "v[{k}] = {}", v[k]);
        assert!((r[k] - expected_r[k]).abs() < 1e-7, "r[{k}] = {}", r[k]);
    }
    // The contact that stays open keeps an impulse of exactly zero.
    assert_eq!(&r[3..], &[0.0; 3]);
    let error = common::global_error(&p, r, v, &[]);
    assert!(error <= 2.0 * tol, "independent measure {error:e}");
}

/// The trace measures every iteration, but only the loop's own evaluations decide: a
/// contact predicted open comes back at the same iteration with and without it. One mass
/// on two ground contacts: the first carries the warm start's impulse, the second, with
/// none and the mass rising, is predicted open but must share the load.
#[test]
fn the_trace_does_not_change_a_screened_solve() {
    let mut h = Vec::new();
    for contact in 0..2 {
        for (k, axis) in [2, 0, 1].into_iter().enumerate() {
            h.push((axis, 3 * contact + k, 1.0));
        }
    }
    let p = GlobalProblem::new(
        CscMatrix::identity(3),
        CscMatrix::from_triplets("H", 3, 6, &h).unwrap(),
        vec![0.2, 0.0, -1.0],
        vec![0.0; 6],
        vec![0.5, 0.5],
    )
    .unwrap();
    let solve = |trace: bool| {
        let settings = Settings {
            tolerance: 1e-10,
            newton_polish: Some(false),
            trace,
            ..Settings::default()
        };
        let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
        solver
            .warm_start(&[0.3, 0.0, 0.0, 0.0, 0.0, 0.0], Some(&[0.0, 0.0, 1.0]))
            .unwrap();
        let status = solver.solve().unwrap();
        (status, solver.stats().iterations, solver.solution().clone())
    };
    let (quiet, traced) = (solve(false), solve(true));
    assert_eq!(quiet.0, Status::Solved);
    assert_eq!((quiet.0, quiet.1), (traced.0, traced.1));
    assert_eq!(quiet.2.r, traced.2.r);
    assert_eq!(quiet.2.v, traced.2.v);
}
