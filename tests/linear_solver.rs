//! The v-update backends (`LinearSolver`): the matrix-free one solves what the direct one
//! solves, each answer checked by the independent error measure of `common`; `auto`
//! factorizes small systems and goes matrix-free where the factor fills in; the backend
//! survives value updates; bad names and changes in a built solver are refused.

mod common;

#[path = "../examples/extreme/scenes.rs"]
mod scenes;

use cadmm::{Error, GlobalProblem, LinearSolver, Problem, Settings, Solver, Stats, Status};

/// Solves `p` with `backend` and returns the stats and the independent error.
fn solve(p: &GlobalProblem, backend: LinearSolver, tolerance: f64) -> (Stats, f64) {
    let settings = Settings {
        tolerance,
        linear_solver: backend,
        ..Settings::default()
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
    solver.solve().unwrap();
    let s = solver.solution();
    let error = common::global_error_sparse(p, &s.r, &s.v);
    (*solver.stats(), error)
}

/// A sphere lattice of 6 x 6 x 4 (144 bodies, 384 contacts), one coupled island.
fn small_pile() -> GlobalProblem {
    scenes::pile(6, 6, 4).global()
}

#[test]
fn iterative_solves_the_pile_like_direct() {
    let p = small_pile();
    for tol in [1e-4, 1e-8] {
        let (direct, e_direct) = solve(&p, LinearSolver::Direct, tol);
        let (iterative, e_iterative) = solve(&p, LinearSolver::Iterative, tol);
        assert_eq!(direct.status, Status::Solved, "direct at {tol:e}");
        assert_eq!(iterative.status, Status::Solved, "iterative at {tol:e}");
        assert!(e_direct <= tol, "direct at {tol:e}: error {e_direct:e}");
        assert!(
            e_iterative <= tol,
            "iterative at {tol:e}: error {e_iterative:e}"
        );
        // The backends really differ: conjugate gradients ran, and no Newton phase.
        assert_eq!(direct.linear_iterations, 0);
        assert!(iterative.linear_iterations > 0);
        assert_eq!(iterative.newton_iterations, 0);
        // The reported error is the measured one.
        assert!((iterative.error - e_iterative).abs() <= 1e-6 * e_iterative.max(tol));
    }
}

#[test]
fn auto_factorizes_small_systems_and_goes_matrix_free_on_fill() {
    let (small, _) = solve(&small_pile(), LinearSolver::Auto, 1e-6);
    assert_eq!(small.linear_iterations, 0, "a small pile is factorized");
    // 2 800 contacts: the Cholesky factor of M + rho H H^T holds far more than the
    // conjugate-gradient products cost.
    // (At 1e-6: at 1e-4 the sweeps before it solve the pile alone, below.)
    let large = scenes::pile(10, 10, 10).global();
    let (stats, error) = solve(&large, LinearSolver::Auto, 1e-6);
    assert_eq!(stats.status, Status::Solved);
    assert!(error <= 1e-6, "error {error:e}");
    assert!(
        stats.linear_iterations > 0,
        "auto chose the matrix-free backend: {stats:?}"
    );
}

/// Where `auto` goes matrix-free (without a time limit), Gauss-Seidel sweeps come first:
/// at 1e-4 they solve the 2 800-contact pile alone; at 1e-6 they give way to ADMM, which
/// solves it, and for good; the direct backend, asked for, has no sweeps. Measured
/// independently.
#[test]
fn sweeps_come_before_a_matrix_free_solve() {
    let large = scenes::pile(10, 10, 10).global();
    let (swept, error) = solve(&large, LinearSolver::Auto, 1e-4);
    assert_eq!(swept.status, Status::Solved);
    assert!(error <= 1e-4, "error {error:e}");
    assert!(swept.gauss_seidel_sweeps > 0, "{swept:?}");
    assert_eq!(swept.iterations, 0, "the sweeps alone: {swept:?}");
    let (handed, error) = solve(&large, LinearSolver::Auto, 1e-6);
    assert!(error <= 1e-6, "error {error:e}");
    assert!(
        handed.gauss_seidel_sweeps > 0 && handed.iterations > 0,
        "{handed:?}"
    );
    // Sweeps that gave way give way for good: the same solver's next solve is ADMM's.
    let settings = Settings {
        tolerance: 1e-6,
        ..Settings::default()
    };
    let mut solver = Solver::new(Problem::Global(large.clone()), settings).unwrap();
    solver.solve().unwrap();
    assert!(solver.stats().gauss_seidel_sweeps > 0);
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    assert_eq!(
        solver.stats().gauss_seidel_sweeps,
        0,
        "{:?}",
        solver.stats()
    );
    let s = solver.solution();
    assert!(common::global_error_sparse(&large, &s.r, &s.v) <= 1e-6);
    let (direct, error) = solve(&large, LinearSolver::Direct, 1e-4);
    assert!(error <= 1e-4, "error {error:e}");
    assert_eq!(direct.gauss_seidel_sweeps, 0, "{direct:?}");
}

/// New values (heavier bodies, other forces) through the update path: the answer is
/// measured on the new problem.
#[test]
fn iterative_backend_takes_updates() {
    let p = small_pile();
    let mut q = p.clone();
    for (i, f) in q.f.iter_mut().enumerate() {
        *f *= 1.0 + 0.3 * ((i % 7) as f64 / 7.0);
    }
    let heavier: Vec<f64> = q.m.values().iter().map(|v| 1.5 * v).collect();
    q.m.set_values("M", &heavier).unwrap();
    let settings = Settings {
        linear_solver: LinearSolver::Iterative,
        ..Settings::default()
    };
    let mut solver = Solver::new(Problem::Global(p), settings.clone()).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    solver.update(Problem::Global(q.clone())).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let s = solver.solution();
    let error = common::global_error_sparse(&q, &s.r, &s.v);
    assert!(error <= 1e-8, "after the update: error {error:e}");
    assert!(solver.stats().linear_iterations > 0);
}

#[test]
fn bad_names_and_changes_are_refused() {
    let err = LinearSolver::from_name("cholesky").unwrap_err();
    assert!(
        matches!(
            err,
            Error::InvalidSetting {
                name: "linear_solver",
                ..
            }
        ),
        "{err}"
    );
    let mut solver = Solver::new(Problem::Global(small_pile()), Settings::default()).unwrap();
    let next = Settings {
        linear_solver: LinearSolver::Iterative,
        ..Settings::default()
    };
    let err = solver.update_settings(next).unwrap_err();
    assert!(
        matches!(
            err,
            Error::InvalidSetting {
                name: "linear_solver",
                ..
            }
        ),
        "{err}"
    );
}

/// The matrix-free products on 1, 2 and 3 threads: bitwise the same iterates (each entry of
/// a product is summed in one order whatever the threads). A lattice of 18 560 contacts, whose
/// M and H hold enough entries for the products to use the threads, for 60 iterations.
#[test]
fn threads_leave_the_iterative_iterates_bitwise_unchanged() {
    let p = Problem::Global(scenes::pile(20, 20, 16).global());
    let answer = |threads| {
        let settings = Settings {
            max_iterations: 60,
            linear_solver: LinearSolver::Iterative,
            threads,
            ..Settings::default()
        };
        let mut solver = Solver::new(p.clone(), settings).unwrap();
        solver.solve().unwrap();
        assert!(solver.stats().linear_iterations > 0);
        let s = solver.solution();
        let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        (bits(&s.r), bits(&s.v), solver.stats().iterations)
    };
    let one = answer(1);
    for threads in [2, 3] {
        assert!(answer(threads) == one, "{threads} threads differ from 1");
    }
}

/// The time limit reaches into the conjugate gradients: with a limit already passed when
/// the solve starts, each v-update stops after one conjugate-gradient iteration (where it
/// would otherwise run to its tolerance) and the solve ends at its first check with the
/// status `time_limit`, the error of the iterate it returns measured honestly.
#[test]
fn the_time_limit_stops_the_conjugate_gradients() {
    let p = small_pile();
    let (free, _) = solve(&p, LinearSolver::Iterative, 1e-8);
    assert!(
        free.linear_iterations > 2 * free.iterations,
        "{} CG iterations in {} ADMM iterations: too few to show a cut",
        free.linear_iterations,
        free.iterations
    );
    let settings = Settings {
        linear_solver: LinearSolver::Iterative,
        time_limit: 1e-12,
        ..Settings::default()
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::TimeLimit);
    let stats = *solver.stats();
    assert!(
        stats.linear_iterations <= stats.iterations,
        "{} CG iterations in {} ADMM iterations past the deadline",
        stats.linear_iterations,
        stats.iterations
    );
    let s = solver.solution();
    let error = common::global_error_sparse(&p, &s.r, &s.v);
    assert!(error > 1e-8, "a time-limited solve reported {error:e}");
    assert!((stats.error - error).abs() <= 1e-6 * error);
}
