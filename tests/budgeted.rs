//! A solver built with a time limit starts with Gauss-Seidel sweeps (docs/algorithms.md
//! §16): every answer it hands back is measured by the independent measure of `common` at
//! the error it reports; the sweeps meet a loose tolerance alone, hand over to a tight one
//! and still solve it; a budget too short for them hands back their best iterate; updates,
//! refused updates and warm starts reach them; problems they do not suit solve as before;
//! a solver rebuilt for other patterns answers as a new one.
#![cfg(feature = "fclib")]

mod common;

use cadmm::{fclib, CscMatrix, GlobalProblem, NewValues, Problem, Settings, Solver, Status};

fn box_stack() -> GlobalProblem {
    let rel = "global/Box_Stacks-i0122-82-5.hdf5";
    match fclib::read(common::data(rel)).unwrap_or_else(|e| panic!("{rel}: {e}")) {
        Problem::Global(g) => g,
        Problem::Local(_) => panic!("{rel} is global"),
    }
}

fn budget(tolerance: f64, time_limit: f64) -> Settings {
    Settings {
        tolerance,
        time_limit,
        ..Settings::default()
    }
}

/// Solves and checks that the reported error is the independent measure's.
fn solve(solver: &mut Solver, p: &GlobalProblem) -> (Status, f64) {
    let status = solver.solve().unwrap();
    let s = solver.solution();
    let independent = common::global_error(p, &s.r, &s.v, &s.lambda);
    let reported = solver.stats().error;
    assert!(
        (independent - reported).abs() <= 1e-9 + 1e-6 * reported,
        "reported {reported:e}, independent {independent:e}"
    );
    (status, independent)
}

#[test]
fn sweeps_meet_a_loose_tolerance_alone() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-3, 10.0)).unwrap();
    let (status, error) = solve(&mut solver, &p);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-3);
    let stats = solver.stats();
    assert!(stats.gauss_seidel_sweeps > 0);
    assert_eq!(
        stats.iterations, 0,
        "no ADMM iteration: the sweeps solved it"
    );
}

#[test]
fn a_tight_tolerance_hands_over_and_is_met() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-8, 60.0)).unwrap();
    let (status, error) = solve(&mut solver, &p);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-8);
    let stats = solver.stats();
    assert!(stats.gauss_seidel_sweeps >= 8, "{stats:?}");
    assert!(stats.iterations > 0, "ADMM and Newton finished: {stats:?}");
}

#[test]
fn a_short_budget_hands_back_the_best_iterate_it_measured() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-12, 1e-9)).unwrap();
    let (status, error) = solve(&mut solver, &p);
    assert_eq!(status, Status::TimeLimit);
    // The sweeps run at least four times, whatever the budget: far better than no impulse.
    assert!(solver.stats().gauss_seidel_sweeps >= 4);
    assert!(error < 0.5, "error {error:e}");
}

/// Islands that answered a solve (the sweeps handed over to them) keep the next solve of
/// the same problem: it starts with them, from its warm start, without a sweep, and meets
/// the tolerance. A rebuild hands the next solve back to the sweeps.
#[test]
fn islands_that_answered_keep_the_next_solve() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-8, 60.0)).unwrap();
    assert_eq!(solve(&mut solver, &p).0, Status::Solved);
    let stats = solver.stats();
    assert!(
        stats.gauss_seidel_sweeps >= 8 && stats.iterations > 0,
        "{stats:?}"
    );
    // The next step: forces 1% larger, from the answer.
    let mut next = p.clone();
    next.f.iter_mut().for_each(|x| *x *= 1.01);
    let new = NewValues {
        f: Some(&next.f),
        ..NewValues::default()
    };
    let warm = |solver: &mut Solver| {
        let s = solver.solution().clone();
        solver.warm_start(&s.r, Some(&s.v)).unwrap();
    };
    solver.update_values(&new).unwrap();
    warm(&mut solver);
    let (status, error) = solve(&mut solver, &next);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-8);
    let stats = solver.stats();
    assert_eq!(stats.gauss_seidel_sweeps, 0, "{stats:?}");
    assert!(stats.iterations > 0, "{stats:?}");
    solver.rebuild(&Problem::Global(next.clone())).unwrap();
    warm(&mut solver);
    assert_eq!(solve(&mut solver, &next).0, Status::Solved);
    assert!(
        solver.stats().gauss_seidel_sweeps > 0,
        "{:?}",
        solver.stats()
    );
}

#[test]
fn warm_starts_and_new_values_reach_the_sweeps() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-4, 10.0)).unwrap();
    assert_eq!(solve(&mut solver, &p).0, Status::Solved);
    // From its own answer: measured, met, no sweep.
    let s = solver.solution().clone();
    solver.warm_start(&s.r, Some(&s.v)).unwrap();
    assert_eq!(solve(&mut solver, &p).0, Status::Solved);
    assert_eq!(
        solver.stats().gauss_seidel_sweeps,
        0,
        "{:?}",
        solver.stats()
    );
    // Twice the forces: the answer is that of the new problem.
    let f: Vec<f64> = p.f.iter().map(|x| 2.0 * x).collect();
    let new = NewValues {
        f: Some(&f),
        ..NewValues::default()
    };
    solver.update_values(&new).unwrap();
    let mut doubled = p.clone();
    doubled.f = f.clone();
    let (status, error) = solve(&mut solver, &doubled);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-4);
}

/// After a solved run, a warm start whose own velocities meet the tolerance is handed back
/// as given (as a solver without a budget does), not with velocities recomputed from its
/// impulses; after a run stopped by its limit, it is swept as before.
#[test]
fn a_warm_start_that_meets_the_tolerance_keeps_its_velocities() {
    let p = box_stack();
    let tolerance = 1e-4;
    let given = |solver: &Solver| {
        let s = solver.solution();
        // Velocities off by a little, well within the tolerance.
        let v: Vec<f64> = s.v.iter().map(|x| x * (1.0 + 1e-9)).collect();
        (s.r.clone(), v)
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(tolerance, 10.0)).unwrap();
    assert_eq!(solve(&mut solver, &p).0, Status::Solved);
    let (r, v) = given(&solver);
    assert!(common::global_error(&p, &r, &v, &[]) <= tolerance);
    solver.warm_start(&r, Some(&v)).unwrap();
    assert_eq!(solve(&mut solver, &p).0, Status::Solved);
    assert_eq!(solver.stats().gauss_seidel_sweeps, 0);
    assert_eq!((&solver.solution().r, &solver.solution().v), (&r, &v));

    let mut stopped = Solver::new(Problem::Global(p.clone()), budget(1e-12, 1e-9)).unwrap();
    assert_eq!(solve(&mut stopped, &p).0, Status::TimeLimit);
    stopped.update_settings(budget(tolerance, 10.0)).unwrap();
    stopped.warm_start(&r, Some(&v)).unwrap();
    assert_eq!(solve(&mut stopped, &p).0, Status::Solved);
    assert_eq!(stopped.solution().r, r);
    assert_ne!(
        stopped.solution().v,
        v,
        "velocities recomputed from the impulses"
    );
}

#[test]
fn a_refused_update_changes_nothing() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-4, 10.0)).unwrap();
    let (_, before) = solve(&mut solver, &p);
    // M's first diagonal entry negated: not positive definite.
    let mut m = p.m.values().to_vec();
    let first = p.m.colptr()[0]..p.m.colptr()[1];
    let at = first.clone().find(|&k| p.m.rowind()[k] == 0).unwrap();
    m[at] = -m[at];
    let f: Vec<f64> = p.f.iter().map(|x| 3.0 * x).collect();
    let bad = NewValues {
        m: Some(&m),
        f: Some(&f),
        ..NewValues::default()
    };
    assert!(solver.update_values(&bad).is_err());
    let (_, after) = solve(&mut solver, &p);
    assert_eq!(before, after, "the same problem, the same answer");
}

#[test]
fn an_m_that_loses_its_symmetry_goes_to_the_coupled_solver() {
    // The stack's M (diagonal) with a stored zero pair coupling velocities 0 and 1, which
    // an update then makes asymmetric.
    let p = box_stack();
    let mut triplets: Vec<(usize, usize, f64)> = (0..p.n())
        .flat_map(|j| p.m.col(j).map(move |(i, x)| (i, j, x)))
        .collect();
    triplets.extend([(0, 1, 0.0), (1, 0, 0.0)]);
    let m = CscMatrix::from_triplets("M", p.n(), p.n(), &triplets).unwrap();
    let coupled = GlobalProblem::new(m, p.h.clone(), p.f.clone(), p.w.clone(), p.mu.clone());
    let coupled = coupled.unwrap();
    let mut solver = Solver::new(Problem::Global(coupled.clone()), budget(1e-6, 10.0)).unwrap();
    assert_eq!(solve(&mut solver, &coupled).0, Status::Solved);
    // Entry (0, 1) in storage order (a matrix built from triplets takes its values so).
    let m = &coupled.m;
    let at = (m.colptr()[1]..m.colptr()[2])
        .find(|&k| m.rowind()[k] == 0)
        .unwrap();
    let mut values = m.values().to_vec();
    values[at] = 1e-3 * p.m.diagonal_entry(0);
    let new = NewValues {
        m: Some(&values),
        ..NewValues::default()
    };
    solver.update_values(&new).unwrap();
    let mut asymmetric = coupled.clone();
    asymmetric.m = CscMatrix::new(
        "M",
        p.n(),
        p.n(),
        m.colptr().to_vec(),
        m.rowind().to_vec(),
        values,
    )
    .unwrap();
    let (status, error) = solve(&mut solver, &asymmetric);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-6);
    assert_eq!(solver.stats().gauss_seidel_sweeps, 0);
}

/// Without a time limit a solver solves as it always did: no sweep.
#[test]
fn no_budget_no_sweeps() {
    let p = box_stack();
    let mut solver = Solver::new(Problem::Global(p.clone()), Settings::default()).unwrap();
    assert_eq!(solve(&mut solver, &p).0, Status::Solved);
    assert_eq!(solver.stats().gauss_seidel_sweeps, 0);
}

/// Joint rows are swept too: alone to a loose tolerance, handing over to a tight one; both
/// answers meet the tolerance by the independent measure, joint residual included.
#[test]
fn joint_rows_are_swept() {
    // Two joint rows: the first velocity held, and the second tied to the third.
    let p = box_stack();
    let g = CscMatrix::from_triplets("G", p.n(), 2, &[(0, 0, 1.0), (1, 1, 1.0), (2, 1, -1.0)]);
    let jointed = p.clone().with_joints(g.unwrap(), vec![0.0, 0.0]).unwrap();
    let mut solver = Solver::new(Problem::Global(jointed.clone()), budget(1e-3, 10.0)).unwrap();
    let (status, error) = solve(&mut solver, &jointed);
    assert_eq!((status, solver.stats().iterations), (Status::Solved, 0));
    assert!(error <= 1e-3 && solver.stats().gauss_seidel_sweeps > 0);
    let s = solver.solution();
    assert!(s.v[0].abs() <= 1e-3 * s.v.iter().fold(0.0f64, |a, x| a.max(x.abs())));
    let mut solver = Solver::new(Problem::Global(jointed.clone()), budget(1e-8, 60.0)).unwrap();
    let (status, error) = solve(&mut solver, &jointed);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-8 && solver.stats().gauss_seidel_sweeps > 0);
}

/// Four unit-mass particles on a line (x, y, z each), each tied to the next by three rows,
/// the first held by three more; the last rests on the floor (one contact).
fn particle_chain() -> GlobalProblem {
    particle_chain_above(0.0)
}

/// [`particle_chain`] with one row bounded (far from its bounds): the sweeps then take the
/// rows one at a time, not together.
fn particle_chain_with_a_bound() -> GlobalProblem {
    let (mut lo, hi) = (vec![f64::NEG_INFINITY; 12], vec![f64::INFINITY; 12]);
    lo[2] = -1e3;
    particle_chain().with_joint_bounds(lo, hi).unwrap()
}

/// [`particle_chain`] with the floor's contact opening at normal velocity `gap` when no
/// impulse acts on it.
fn particle_chain_above(gap: f64) -> GlobalProblem {
    let n = 12;
    let mut g = Vec::new();
    for axis in 0..3 {
        g.push((axis, axis, 1.0));
        for link in 0..3 {
            let k = 3 + 3 * link + axis;
            g.push((3 * link + axis, k, 1.0));
            g.push((3 * (link + 1) + axis, k, -1.0));
        }
    }
    let g = CscMatrix::from_triplets("G", n, 12, &g).unwrap();
    let h = CscMatrix::from_triplets("H", n, 3, &[(11, 0, 1.0), (9, 1, 1.0), (10, 2, 1.0)]);
    let mut f = vec![0.0; n];
    for body in 0..4 {
        f[3 * body + 2] = -0.1;
    }
    GlobalProblem::new(
        CscMatrix::identity(n),
        h.unwrap(),
        f,
        vec![gap, 0.0, 0.0],
        vec![0.5],
    )
    .unwrap()
    .with_joints(g, vec![0.0; 12])
    .unwrap()
}

/// The sweeps solve the joints' equality rows together: a chain hanging free (its contact
/// opening) is answered exactly within the sweeps a budget of 4 allows (its second sweep
/// stands still and is measured), where rows swept one at a time carry a correction one
/// link a sweep. Measured independently.
#[test]
fn a_chain_of_equality_rows_is_solved_by_its_first_sweeps() {
    solved_to_1e_12_within_4_sweeps(&particle_chain_above(1.0));
}

/// A budget of 4 sweeps (the least a budgeted solve runs) at 1e-12: solved, measured
/// independently, within those sweeps.
fn solved_to_1e_12_within_4_sweeps(p: &GlobalProblem) {
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-12, 1e-9)).unwrap();
    let (status, error) = solve(&mut solver, p);
    assert!(
        solver.stats().gauss_seidel_sweeps <= 4,
        "{:?}",
        solver.stats()
    );
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-12, "{error}");
}

/// A hanging chain of 121 unit particles (x, y, z each; the first held by three rows, each
/// tied to the next by three), its 363 rows handed in a scrambled order of links, as an
/// engine that sorts its constraints unstably hands them; its contact, under the last
/// particle, opens.
fn scrambled_particle_chain() -> GlobalProblem {
    let (links, n) = (120, 363);
    // Link k goes to position (37 k) mod 120: every neighbour far from the last.
    let position = |link: usize| (37 * link) % links;
    let mut g = Vec::new();
    for axis in 0..3 {
        g.push((axis, axis, 1.0));
        for link in 0..links {
            let k = 3 + 3 * position(link) + axis;
            g.push((3 * link + axis, k, 1.0));
            g.push((3 * (link + 1) + axis, k, -1.0));
        }
    }
    let g = CscMatrix::from_triplets("G", n, n, &g).unwrap();
    let h = CscMatrix::from_triplets(
        "H",
        n,
        3,
        &[(n - 1, 0, 1.0), (n - 3, 1, 1.0), (n - 2, 2, 1.0)],
    );
    let f: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 2 { -0.1 } else { 0.0 })
        .collect();
    GlobalProblem::new(
        CscMatrix::identity(n),
        h.unwrap(),
        f,
        vec![1.0, 0.0, 0.0],
        vec![0.5],
    )
    .unwrap()
    .with_joints(g, vec![0.0; n])
    .unwrap()
}

/// The sweeps solve a long chain's rows together whatever order they come in: reordered,
/// their factor stays narrow (handed in this order, its profile would cost 8e6
/// multiply-adds, past what the sweeps factorize, and one row at a time a correction
/// travels one link a sweep, 120 sweeps down the chain). Measured independently.
#[test]
fn a_scrambled_chain_is_solved_by_its_first_sweeps() {
    solved_to_1e_12_within_4_sweeps(&scrambled_particle_chain());
}

/// Redundant equality rows (a link's row given again, scaled, as a closed loop of joints
/// gives them) make the rows' Delassus matrix singular, which the sweeps do not solve
/// with: the solve still meets the tolerance, measured independently.
#[test]
fn redundant_joint_rows_are_swept_one_at_a_time() {
    let p = particle_chain_above(1.0);
    let joints = p.joints.as_ref().unwrap();
    let (g, mut b) = (&joints.g, joints.b.clone());
    let mut triplets: Vec<(usize, usize, f64)> = (0..g.ncols())
        .flat_map(|k| g.col(k).map(move |(i, x)| (i, k, x)))
        .collect();
    triplets.extend(g.col(3).map(|(i, x)| (i, g.ncols(), x / 3.0)));
    b.push(b[3] / 3.0);
    let g = CscMatrix::from_triplets("G", g.nrows(), g.ncols() + 1, &triplets).unwrap();
    let p = GlobalProblem { joints: None, ..p }
        .with_joints(g, b)
        .unwrap();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-8, 10.0)).unwrap();
    let (status, error) = solve(&mut solver, &p);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-8, "{error}");
}

/// A kept solver whose joint rows outnumber its contact rows, and which its sweeps take one
/// at a time, goes straight to its islands, which solve the joint rows exactly, once they
/// have: its sweeps hand over to them on the first solve (at 1e-8, with time for it), and
/// the islands keep it after that (they would be built after the third solve otherwise);
/// one whose sweeps solve the rows together stays on its sweeps. Every answer is measured
/// independently.
#[test]
fn kept_jointed_solvers_go_to_their_islands() {
    for (p, islands) in [
        (particle_chain_with_a_bound(), true),
        (particle_chain(), false),
    ] {
        let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-8, 10.0)).unwrap();
        for solve_number in 1..=5 {
            let (status, error) = solve(&mut solver, &p);
            assert_eq!(status, Status::Solved, "solve {solve_number}");
            assert!(error <= 1e-8, "solve {solve_number}: {error}");
            let swept = solver.stats().gauss_seidel_sweeps > 0;
            let expected = solve_number == 1 || !islands;
            assert_eq!(swept, expected, "solve {solve_number}, islands {islands}");
            solver.update_values(&NewValues::default()).unwrap();
        }
    }
}

/// The solve after which a jointed solver builds its islands is answered by its sweeps:
/// under a budget that leaves time for their first four sweeps only, it hands back what
/// the solves before it did (each from zero), not the islands' start.
#[test]
fn the_solve_that_builds_the_islands_is_swept() {
    let p = particle_chain_with_a_bound();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-12, 1e-9)).unwrap();
    let (status, first) = solve(&mut solver, &p);
    assert_eq!(status, Status::TimeLimit);
    assert_eq!(solver.stats().gauss_seidel_sweeps, 4);
    assert!(first < 0.5, "four sweeps: {first}");
    for solve_number in 2..=3 {
        solver.update_values(&NewValues::default()).unwrap();
        let (status, error) = solve(&mut solver, &p);
        assert_eq!(status, Status::TimeLimit, "solve {solve_number}");
        assert_eq!(error, first, "solve {solve_number}");
    }
}

fn global(rel: &str) -> GlobalProblem {
    match fclib::read(common::data(rel)).unwrap_or_else(|e| panic!("{rel}: {e}")) {
        Problem::Global(g) => g,
        Problem::Local(_) => panic!("{rel} is global"),
    }
}

/// A solver rebuilt for problems of other sizes and patterns, in turn (its sweeps built in
/// the memory of those it replaced), hands back what a new solver for each hands back, digit
/// for digit, with and without a budget, swept alone or handed over to the islands.
#[test]
fn a_rebuilt_solver_answers_as_a_new_one() {
    let small = box_stack();
    let large = global("global/Box_Stacks-i0207-114-3.hdf5");
    let sequence = [&small, &large, &small, &large, &large];
    for settings in [budget(1e-3, 10.0), budget(1e-8, 60.0), Settings::default()] {
        let mut kept: Option<Solver> = None;
        for (step, p) in sequence.iter().enumerate() {
            let problem = Problem::Global((*p).clone());
            let mut fresh = Solver::new(problem.clone(), settings.clone()).unwrap();
            let rebuilt = match &mut kept {
                Some(s) => {
                    s.rebuild(&problem).unwrap();
                    s
                }
                None => kept.insert(Solver::new(problem, settings.clone()).unwrap()),
            };
            if step % 2 == 1 {
                // The warm start reaches a rebuilt solver's sweeps too.
                let r = vec![0.01; 3 * p.mu.len()];
                fresh.warm_start(&r, None).unwrap();
                rebuilt.warm_start(&r, None).unwrap();
            }
            let (status, error) = solve(rebuilt, p);
            assert_eq!(status, solve(&mut fresh, p).0, "step {step}");
            assert!(error <= settings.tolerance, "step {step}: {error:e}");
            assert_eq!(rebuilt.solution().r, fresh.solution().r, "step {step}");
            assert_eq!(rebuilt.solution().v, fresh.solution().v, "step {step}");
            let (a, b) = (rebuilt.stats(), fresh.stats());
            assert_eq!(
                (a.gauss_seidel_sweeps, a.iterations, a.islands),
                (b.gauss_seidel_sweeps, b.iterations, b.islands),
                "step {step}"
            );
        }
    }
}

/// A rebuild refused (an M that is not positive definite) leaves the solver with its
/// problem: it answers as before.
#[test]
fn a_refused_rebuild_changes_nothing() {
    let p = box_stack();
    let other = global("global/Box_Stacks-i0207-114-3.hdf5");
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-4, 10.0)).unwrap();
    solver.rebuild(&Problem::Global(other.clone())).unwrap();
    solver.rebuild(&Problem::Global(p.clone())).unwrap();
    let (_, before) = solve(&mut solver, &p);
    let mut bad = other;
    let mut m = bad.m.values().to_vec();
    let at = (bad.m.colptr()[0]..bad.m.colptr()[1])
        .find(|&k| bad.m.rowind()[k] == 0)
        .unwrap();
    m[at] = -m[at];
    bad.m.set_values("M", &m).unwrap();
    let refused = solver.rebuild(&Problem::Global(bad));
    assert!(refused.is_err(), "{refused:?}");
    let (_, after) = solve(&mut solver, &p);
    assert_eq!(before, after, "the same problem, the same answer");
    assert_eq!(solver.n_velocities(), p.n());
}

/// Sweeps stopped by their limit whose last measure meets the tolerance report it solved.
#[test]
fn a_last_measure_that_meets_the_tolerance_is_solved() {
    let p = box_stack();
    let limited = |tolerance| Settings {
        max_iterations: 3,
        ..budget(tolerance, 10.0)
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), limited(1e-14)).unwrap();
    let (status, after_three) = solve(&mut solver, &p);
    assert_eq!(status, Status::MaxIterations);
    assert_eq!(solver.stats().gauss_seidel_sweeps, 3);
    let mut solver = Solver::new(Problem::Global(p.clone()), limited(2.0 * after_three)).unwrap();
    let (status, error) = solve(&mut solver, &p);
    assert_eq!((status, error), (Status::Solved, after_three));
}

/// A budgeted solver rebuilt for a local problem (which the sweeps do not suit) solves it
/// as a new solver with its settings would, and back again for a global one.
#[test]
fn a_rebuild_may_change_the_form() {
    let global = box_stack();
    let rel = "local/Capsules-i100-889.hdf5";
    let Problem::Local(local) = fclib::read(common::data(rel)).unwrap() else {
        panic!("{rel} is local")
    };
    let settings = budget(1e-6, 60.0);
    let mut solver = Solver::new(Problem::Global(global.clone()), settings.clone()).unwrap();
    solve(&mut solver, &global);
    solver.rebuild(&Problem::Local(local.clone())).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let r = solver.solution().r.clone();
    assert!(common::local_error(&local, &r) <= 1e-6);
    let mut fresh = Solver::new(Problem::Local(local.clone()), settings).unwrap();
    fresh.solve().unwrap();
    assert_eq!(r, fresh.solution().r);
    solver.rebuild(&Problem::Global(global.clone())).unwrap();
    let (status, error) = solve(&mut solver, &global);
    assert_eq!(status, Status::Solved);
    assert!(error <= 1e-6);
    assert!(
        solver.stats().gauss_seidel_sweeps > 0,
        "the sweeps are back"
    );
}

/// Eight particles on a floor (x, y, z each; masses alternating 1 and 20), their x
/// velocities tied link by link (seven equality rows), pushed along x at the first and
/// along y at the third: together they slide along x, and where each contact sticks or
/// slides sideways depends on the others. Gravity 0.1 a unit mass, friction 0.3.
fn rope_on_a_floor() -> GlobalProblem {
    rope_with_contacts(8)
}

/// [`rope_on_a_floor`] with contacts under its first `contacts` particles only.
fn rope_with_contacts(contacts: usize) -> GlobalProblem {
    let (bodies, n) = (8, 24);
    let mass = |body: usize| if body % 2 == 0 { 1.0 } else { 20.0 };
    let m: Vec<(usize, usize, f64)> = (0..n).map(|i| (i, i, mass(i / 3))).collect();
    let g: Vec<(usize, usize, f64)> = (0..2 * (bodies - 1))
        .flat_map(|k| {
            let (link, axis) = (k / 2, k % 2);
            [(3 * link + axis, k, 1.0), (3 * (link + 1) + axis, k, -1.0)]
        })
        .collect();
    // Contact c: normal z, tangents x and y, on particle c.
    let h: Vec<(usize, usize, f64)> = (0..contacts)
        .flat_map(|c| {
            [
                (3 * c + 2, 3 * c, 1.0),
                (3 * c, 3 * c + 1, 1.0),
                (3 * c + 1, 3 * c + 2, 1.0),
            ]
        })
        .collect();
    let mut f: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 2 { -0.1 * mass(i / 3) } else { 0.0 })
        .collect();
    (f[0], f[7]) = (30.0, 0.2);
    GlobalProblem::new(
        CscMatrix::from_triplets("M", n, n, &m).unwrap(),
        CscMatrix::from_triplets("H", n, 3 * contacts, &h).unwrap(),
        f,
        vec![0.0; 3 * contacts],
        vec![0.3; contacts],
    )
    .unwrap()
    .with_joints(
        CscMatrix::from_triplets("G", n, 2 * (bodies - 1), &g).unwrap(),
        vec![0.0; 2 * (bodies - 1)],
    )
    .unwrap()
}

/// A jointed problem of few contacts whose sticking and sliding depend on each other is
/// solved by Newton on its contacts after the first sweeps (docs/algorithms.md §17), where
/// sweeps alone converge slowly: at 1e-12, within 8 sweeps. Measured independently.
#[test]
fn few_contacts_on_joints_are_solved_at_once() {
    let p = rope_on_a_floor();
    let mut solver = Solver::new(Problem::Global(p.clone()), budget(1e-12, 10.0)).unwrap();
    let (status, error) = solve(&mut solver, &p);
    assert_eq!(status, Status::Solved, "{:?}", solver.stats());
    assert!(error <= 1e-12, "{error}");
    assert!(
        solver.stats().gauss_seidel_sweeps <= 8,
        "{:?}",
        solver.stats()
    );
    assert_eq!(
        solver.stats().iterations,
        0,
        "no ADMM: {:?}",
        solver.stats()
    );
}

/// A jointed solver rebuilt in turn for problems whose joints keep or change their pattern
/// (the same rows with other contacts, a row bounded, other joints) hands back what a new
/// solver for each hands back, digit for digit: the sweeps keep the joints' structure only
/// while it fits.
#[test]
fn a_rebuilt_jointed_solver_answers_as_a_new_one() {
    // A rebuild refits the sweeps of the problem before last (two sets, swapped): each
    // pattern comes twice, so that a set meets both what it was fitted to and other rows.
    let sequence = [
        particle_chain(),
        particle_chain(),
        particle_chain_with_a_bound(),
        particle_chain_with_a_bound(),
        particle_chain(),
        rope_with_contacts(8),
        rope_with_contacts(5),
        rope_with_contacts(8),
        rope_with_contacts(8),
        particle_chain_above(1.0),
    ];
    for settings in [budget(1e-3, 10.0), budget(1e-10, 10.0)] {
        let mut kept: Option<Solver> = None;
        for (step, p) in sequence.iter().enumerate() {
            let problem = Problem::Global(p.clone());
            let mut fresh = Solver::new(problem.clone(), settings.clone()).unwrap();
            let rebuilt = match &mut kept {
                Some(s) => {
                    s.rebuild(&problem).unwrap();
                    s
                }
                None => kept.insert(Solver::new(problem, settings.clone()).unwrap()),
            };
            let (status, error) = solve(rebuilt, p);
            assert_eq!(status, solve(&mut fresh, p).0, "step {step}");
            assert!(error <= settings.tolerance, "step {step}: {error:e}");
            assert_eq!(rebuilt.solution().r, fresh.solution().r, "step {step}");
            assert_eq!(rebuilt.solution().v, fresh.solution().v, "step {step}");
            assert_eq!(
                rebuilt.solution().lambda,
                fresh.solution().lambda,
                "step {step}"
            );
        }
    }
}
