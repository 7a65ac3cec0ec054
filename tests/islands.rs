//! Contact islands: a scene of uncoupled piles is solved island by island, each exactly as
//! it would be alone; the assembled solution meets the whole problem's tolerance by the
//! independent measure of `common`; threads do not change a bit; contact-free bodies,
//! separating contacts and contacts that touch no body are short cuts with honest statuses.
#![cfg(feature = "fclib")]

mod common;

use cadmm::{
    fclib, CscMatrix, GlobalProblem, LocalProblem, NewValues, Phase, Problem, Settings, Solution,
    Solver, Status, VariantChoice,
};

const TOL: f64 = 1e-8;

fn read(rel: &str) -> Problem {
    fclib::read(common::data(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn solve(p: &Problem, settings: Settings) -> (Solver, Status) {
    let mut solver = Solver::new(p.clone(), settings).unwrap();
    let status = solver.solve().unwrap();
    (solver, status)
}

fn independent_error(p: &Problem, s: &Solution) -> f64 {
    common::error(p, &s.r, &s.v, &s.lambda)
}

/// Global and local problems whose copies make the test scenes (small, so that the dense
/// independent measure stays cheap).
const PILES: [&str; 4] = [
    "global/GFC3D_Example1.hdf5",
    "global/Box_Stacks-i0122-82-5.hdf5",
    "local/Capsules-i101-404.hdf5",
    "local/Rover1039.hdf5",
];

/// Each island of K copies is solved as in a scene of two copies: same iterations, same
/// impulses (to round-off: the whole measure sums more terms, so an island that ends right
/// at the tolerance may get one more refinement round in one of the two); the whole
/// solution meets the tolerance by the independent measure. (A pile that is one island
/// alone is solved as one coupled problem, by another Newton system, hence the pair as the
/// reference.)
#[test]
fn copies_solve_as_the_pile_alone() {
    for rel in PILES {
        let pile = read(rel);
        let pair = Problem::block_diagonal(&[pile.clone(), pile.clone()]).unwrap();
        let (alone, status) = solve(&pile, Settings::default());
        assert_eq!(status, Status::Solved, "{rel} alone");
        assert!(
            independent_error(&pile, alone.solution()) <= TOL,
            "{rel} alone"
        );
        let (alone, status) = solve(&pair, Settings::default());
        assert_eq!(status, Status::Solved, "{rel} x2");
        let one = alone.solution().clone();
        let one = Solution {
            r: one.r[..one.r.len() / 2].to_vec(),
            ..one
        };
        let k = 5;
        let scene = Problem::block_diagonal(&vec![pile.clone(); k]).unwrap();
        let (solver, status) = solve(&scene, Settings::default());
        assert_eq!(status, Status::Solved, "{rel} x{k}");
        let stats = solver.stats();
        // A pile may itself hold several islands (boxes apart from the stack).
        assert_eq!(2 * stats.islands, k * alone.stats().islands, "{rel}");
        assert_eq!(solver.island_stats().len(), stats.islands);
        assert_eq!(stats.iterations, alone.stats().iterations, "{rel}");
        let s = solver.solution();
        let m = one.r.len();
        let scale = one.r.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for c in 0..k {
            let copy = &s.r[c * m..(c + 1) * m];
            let d = copy
                .iter()
                .zip(&one.r)
                .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
            assert!(d <= 1e-7 * scale, "{rel}: copy {c} differs by {d:e}");
        }
        let e = independent_error(&scene, s);
        assert!(e <= TOL, "{rel} x{k}: independent error {e:e}");
        // Relative agreement, down to the measure's round-off (sums of O(1) terms).
        assert!(
            (e - stats.error).abs() <= 1e-3 * e + 1e-13,
            "{rel}: reported {:e}, independent {e:e}",
            stats.error
        );
        // Islands off: one coupled problem, solved too (another path to the same answer).
        let off = Settings {
            islands: false,
            ..Settings::default()
        };
        let (whole, status) = solve(&scene, off);
        assert_eq!(status, Status::Solved, "{rel} x{k}, islands off");
        assert_eq!(whole.stats().islands, 1);
        assert!(independent_error(&scene, whole.solution()) <= TOL);
    }
}

/// Different piles side by side, on 1, 2 and 8 threads: bitwise identical solutions.
#[test]
fn threads_do_not_change_a_bit() {
    for rels in [&PILES[..2], &PILES[2..]] {
        let parts: Vec<Problem> = rels.iter().chain(rels).map(|r| read(r)).collect();
        let scene = Problem::block_diagonal(&parts).unwrap();
        let mut reference = None;
        for threads in [1, 2, 8] {
            let settings = Settings {
                threads,
                ..Settings::default()
            };
            let (solver, status) = solve(&scene, settings);
            assert_eq!(status, Status::Solved);
            let s = solver.solution();
            let bits: Vec<u64> = s.r.iter().chain(&s.v).map(|x| x.to_bits()).collect();
            match &reference {
                None => reference = Some(bits),
                Some(b) => assert_eq!(&bits, b, "{threads} threads"),
            }
        }
    }
}

/// Small islands (a few boxes on the ground) are solved by Newton on their Delassus form
/// alone: every island of the pile takes Newton steps only, the assembled solution meets
/// the tolerance by the independent measure and agrees with ADMM on the same islands (a
/// named variant); the iteration limit holds for the Newton steps too.
#[test]
fn small_islands_are_solved_by_newton_directly() {
    let scene =
        Problem::block_diagonal(&vec![read("global/Box_Stacks-i0122-82-5.hdf5"); 3]).unwrap();
    let (newton, status) = solve(&scene, Settings::default());
    assert_eq!(status, Status::Solved);
    let islands = newton.island_stats();
    assert!(islands.len() > 3);
    for (k, s) in islands.iter().enumerate() {
        assert_eq!(s.status, Status::Solved, "island {k}");
        assert_eq!(
            s.newton_iterations, s.iterations,
            "island {k}: not Newton alone"
        );
        assert_eq!(s.newton_fallbacks, 0, "island {k}");
    }
    let direct = newton.solution();
    assert!(independent_error(&scene, direct) <= TOL);
    let admm = Settings {
        variant: VariantChoice::from_name("vp-RR-He").unwrap(),
        ..Settings::default()
    };
    let (admm, status) = solve(&scene, admm);
    assert_eq!(status, Status::Solved);
    assert!(admm.island_stats().iter().all(|s| s.newton_iterations == 0));
    let other = admm.solution();
    assert!(independent_error(&scene, other) <= TOL);
    // Boxes on four corners have many impulses for one motion: compare the velocities.
    let scale = other.v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let d = direct
        .v
        .iter()
        .zip(&other.v)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    eprintln!("velocities: largest {scale:e}, largest difference {d:e}");
    assert!(
        d <= 1e-6 * scale,
        "Newton and ADMM velocities differ by {d:e}"
    );
    for cap in 1..=3 {
        let capped = Settings {
            max_iterations: cap,
            ..Settings::default()
        };
        let (solver, _) = solve(&scene, capped);
        assert!(solver.stats().iterations <= cap, "cap {cap}");
        assert!(solver.island_stats().iter().all(|s| s.iterations <= cap));
    }
}

/// One island that cannot finish within the iteration limit among easy ones: the status
/// says so, and names the island.
#[test]
fn a_failing_island_makes_the_status() {
    let easy = read("global/GFC3D_Example1.hdf5");
    let hard = read("global/Box_Stacks-i1000-547-14.hdf5");
    let scene = Problem::block_diagonal(&[easy.clone(), hard, easy]).unwrap();
    let settings = Settings {
        max_iterations: 100,
        ..Settings::default()
    };
    let (solver, status) = solve(&scene, settings);
    assert_eq!(status, Status::MaxIterations);
    let stats = solver.stats();
    assert_eq!(stats.failed_island, Some(1));
    let islands = solver.island_stats();
    assert_eq!(islands[0].status, Status::Solved);
    assert_eq!(islands[1].status, Status::MaxIterations);
    let e = independent_error(&scene, solver.solution());
    assert!(e > TOL && e.is_finite(), "independent error {e:e}");
}

/// Unit masses: body 0 rests on the ground (one contact), body 1 floats free, body 2
/// hovers above the ground moving up (its contact separates). `M = I` (9 x 9).
fn free_and_separating_scene(w_separating: f64) -> GlobalProblem {
    let h = CscMatrix::from_triplets(
        "H",
        9,
        6,
        &[
            (0, 0, 1.0),
            (1, 1, 1.0),
            (2, 2, 1.0),
            (6, 3, 1.0),
            (7, 4, 1.0),
            (8, 5, 1.0),
        ],
    )
    .unwrap();
    let f = vec![-9.81, 0.5, 0.0, 1.0, 2.0, 3.0, 4.0, 0.0, 0.0];
    GlobalProblem::new(
        CscMatrix::identity(9),
        h,
        f,
        vec![0.0, 0.0, 0.0, w_separating, 0.0, 0.0],
        vec![0.3, 0.3],
    )
    .unwrap()
}

#[test]
fn free_bodies_and_separating_contacts_cost_nothing() {
    let p = Problem::Global(free_and_separating_scene(0.0));
    let (solver, status) = solve(&p, Settings::default());
    assert_eq!(status, Status::Solved);
    let s = solver.solution();
    // Body 0 sticks: r = (9.81, -0.5, 0), v = 0.
    for (a, b) in s.r[..3].iter().zip([9.81, -0.5, 0.0]) {
        assert!((a - b).abs() <= 1e-7, "r {:?}", &s.r[..3]);
    }
    // Body 1 is free: v = M^-1 f. Body 2's contact separates: r = 0, v = f.
    assert_eq!(s.v[3..6], [1.0, 2.0, 3.0]);
    assert_eq!(s.r[3..], [0.0, 0.0, 0.0]);
    assert_eq!(s.v[6..], [4.0, 0.0, 0.0]);
    assert_eq!(solver.stats().islands, 2);
    assert_eq!(solver.island_stats()[1].iterations, 0, "separating island");
    assert!(independent_error(&p, s) <= TOL);
}

#[test]
fn a_scene_whose_contacts_all_separate_takes_no_iteration() {
    let mut g = free_and_separating_scene(0.0);
    g.f[0] = 9.81; // body 0 now moves up as well
    let p = Problem::Global(g);
    for islands in [true, false] {
        let settings = Settings {
            islands,
            ..Settings::default()
        };
        let (solver, status) = solve(&p, settings);
        assert_eq!(status, Status::Solved);
        assert_eq!(solver.stats().iterations, 0);
        let s = solver.solution();
        assert!(s.r.iter().all(|&x| x == 0.0));
        assert!(independent_error(&p, s) <= TOL);
    }
    // Local form: q_N >= 0 at every contact.
    let l = LocalProblem::new(
        CscMatrix::identity(6),
        vec![0.1, 5.0, 0.0, 0.0, -2.0, 1.0],
        vec![0.5, 0.5],
    )
    .unwrap();
    let p = Problem::Local(l);
    let (solver, status) = solve(&p, Settings::default());
    assert_eq!(status, Status::Solved);
    assert_eq!(solver.stats().iterations, 0);
    assert!(independent_error(&p, solver.solution()) <= TOL);
}

/// A contact whose columns of H are empty: nothing moves it, so `u = w` whatever `r`.
/// Approaching (`w_N < 0`) it cannot be satisfied: `Infeasible`, never `Solved`.
#[test]
fn a_contact_that_touches_no_body() {
    let h = CscMatrix::from_triplets("H", 3, 6, &[(0, 0, 1.0), (1, 1, 1.0), (2, 2, 1.0)]).unwrap();
    for (w_n, expected) in [(-8.0, Status::Infeasible), (0.5, Status::Solved)] {
        let g = GlobalProblem::new(
            CscMatrix::identity(3),
            h.clone(),
            vec![-1.0, 0.0, 0.0],
            vec![0.0, 0.0, 0.0, w_n, 0.0, 0.0],
            vec![0.3, 0.3],
        )
        .unwrap();
        let p = Problem::Global(g);
        let (solver, status) = solve(&p, Settings::default());
        assert_eq!(status, expected, "w_N = {w_n}");
        let s = solver.solution();
        assert_eq!(s.r[3..], [0.0; 3]);
        let e = independent_error(&p, s);
        assert_eq!(e <= TOL, expected == Status::Solved, "w_N = {w_n}: {e:e}");
    }
}

/// New values through the islands (caller-order arrays scattered into each island) give
/// the same solve as `update` with the new problem, bit for bit, and a solution of the
/// new problem by the independent measure.
#[test]
fn update_values_reaches_every_island() {
    let pile = read("global/GFC3D_Example1.hdf5");
    let scene = Problem::block_diagonal(&[pile.clone(), pile.clone(), pile]).unwrap();
    let Problem::Global(g) = &scene else {
        unreachable!()
    };
    let mut next = g.clone();
    for (k, x) in next.f.iter_mut().enumerate() {
        *x *= 1.0 + 0.01 * (k % 7) as f64;
    }
    let h_values: Vec<f64> = g.h.values().iter().map(|x| 1.05 * x).collect();
    next.h = CscMatrix::new(
        "H",
        g.h.nrows(),
        g.h.ncols(),
        g.h.colptr().to_vec(),
        g.h.rowind().to_vec(),
        h_values.clone(),
    )
    .unwrap();
    let next = Problem::Global(next);
    let (mut kept, _) = solve(&scene, Settings::default());
    let Problem::Global(n) = &next else {
        unreachable!()
    };
    kept.update_values(&NewValues {
        f: Some(&n.f),
        h: Some(&h_values),
        ..NewValues::default()
    })
    .unwrap();
    assert_eq!(kept.solve().unwrap(), Status::Solved);
    assert!(independent_error(&next, kept.solution()) <= TOL);
    let (mut other, _) = solve(&scene, Settings::default());
    other.update(next.clone()).unwrap();
    assert_eq!(other.solve().unwrap(), Status::Solved);
    let cold = other.stats().iterations;
    assert_eq!(kept.solution(), other.solution());
    // A warm start from the answer finishes at once.
    let s = other.solution();
    kept.warm_start(&s.r, Some(&s.v)).unwrap();
    assert_eq!(kept.solve().unwrap(), Status::Solved);
    let warm = kept.stats().iterations;
    assert!(3 * warm < cold, "warm {warm}, cold {cold}");
}

/// A rebuild for a scene where one pile changed and the others took new values (the
/// piles that kept their patterns keep their islands' solvers): it answers as a new
/// solver of the new scene, bit for bit, and as the same scene updated for the piles that
/// kept their patterns; the whole answer meets the tolerance by the independent measure.
#[test]
fn a_rebuild_where_one_pile_changed_answers_as_an_update_for_the_others() {
    let pile = read("global/LMGC_GFC3D_CubeH8.hdf5"); // one island, solved by ADMM
    let small = read("global/GFC3D_Example1.hdf5");
    let other = read("global/Box_Stacks-i0207-114-3.hdf5");
    let pressed = |p: &Problem| {
        let Problem::Global(g) = p else {
            unreachable!()
        };
        let mut g = g.clone();
        for (k, x) in g.f.iter_mut().enumerate() {
            *x *= 1.0 + 0.02 * (k % 5) as f64;
        }
        Problem::Global(g)
    };
    let scene = Problem::block_diagonal(&[pile.clone(), pile.clone(), small.clone()]).unwrap();
    let next = Problem::block_diagonal(&[pressed(&pile), pressed(&pile), other]).unwrap();
    let updated = Problem::block_diagonal(&[pressed(&pile), pressed(&pile), small]).unwrap();
    let (mut rebuilt, _) = solve(&scene, Settings::default());
    rebuilt.rebuild(&next).unwrap();
    assert_eq!(rebuilt.solve().unwrap(), Status::Solved);
    assert!(independent_error(&next, rebuilt.solution()) <= TOL);
    let (fresh, _) = solve(&next, Settings::default());
    assert_eq!(rebuilt.solution(), fresh.solution());
    assert_eq!(rebuilt.stats().iterations, fresh.stats().iterations);
    let (mut reference, _) = solve(&scene, Settings::default());
    reference.update(updated).unwrap();
    assert_eq!(reference.solve().unwrap(), Status::Solved);
    // The two piles' contacts come first in both scenes.
    let m = 2 * 3 * pile.n_contacts();
    assert_eq!(rebuilt.solution().r[..m], reference.solution().r[..m]);
}

/// A pile with its friction coefficients set to `mu`.
fn with_mu(p: &Problem, value: f64) -> Problem {
    let mut p = p.clone();
    let mu = match &mut p {
        Problem::Global(g) => &mut g.mu,
        Problem::Local(l) => &mut l.mu,
    };
    mu.fill(value);
    p
}

/// A scene of a frictionless pile beside a frictional one: the frictionless islands carry
/// one row per contact in their systems, and the answer is that of the three-row form (a
/// friction coefficient of 1e-12 there, which keeps every row) to the tolerance: each
/// answer solves the other form, by the independent measure.
#[test]
fn frictionless_contacts_carry_one_row() {
    for rel in [
        "global/Box_Stacks-i0122-82-5.hdf5",
        "local/BoxesStack1-i100000-32.hdf5",
        "local/Rover1039.hdf5",
    ] {
        let pile = read(rel);
        let nc = pile.n_contacts();
        let one_row = Problem::block_diagonal(&[with_mu(&pile, 0.0), pile.clone()]).unwrap();
        let three_rows = Problem::block_diagonal(&[with_mu(&pile, 1e-12), pile.clone()]).unwrap();
        let (a, status) = solve(&one_row, Settings::default());
        assert_eq!(status, Status::Solved, "{rel}");
        assert_eq!(a.stats().rows, 3 * nc + nc, "{rel}");
        let (b, status) = solve(&three_rows, Settings::default());
        assert_eq!(status, Status::Solved, "{rel}");
        assert_eq!(b.stats().rows, 6 * nc, "{rel}");
        let (sa, sb) = (a.solution(), b.solution());
        // The frictionless impulses are normal.
        for c in 0..nc {
            assert_eq!(sa.r[3 * c + 1..3 * c + 3], [0.0, 0.0], "{rel}: contact {c}");
        }
        let errors = [
            independent_error(&one_row, sa),
            independent_error(&three_rows, sb),
            independent_error(&three_rows, sa),
            independent_error(&one_row, sb),
        ];
        assert!(errors.iter().all(|&e| e <= TOL), "{rel}: {errors:?}");
    }
}

/// A contact whose normal velocity no impulse can change (its normal column of H, or its
/// normal row of W, is zero) and which approaches has no solution: `Infeasible`, never
/// `Solved`, with islands on or off; the same contact moving apart is solved.
#[test]
fn a_contact_whose_normal_cannot_move() {
    // One unit mass; the contact's tangential columns touch it, its normal column does not.
    let h = CscMatrix::from_triplets("H", 3, 3, &[(1, 1, 1.0), (2, 2, 1.0)]).unwrap();
    for (w_n, expected) in [(-8.0, Status::Infeasible), (8.0, Status::Solved)] {
        let g = GlobalProblem::new(
            CscMatrix::identity(3),
            h.clone(),
            vec![-1.0, 0.5, 0.0],
            vec![w_n, 0.0, 0.0],
            vec![0.3],
        )
        .unwrap();
        let p = Problem::Global(g);
        for islands in [true, false] {
            let settings = Settings {
                islands,
                ..Settings::default()
            };
            let (solver, status) = solve(&p, settings);
            assert_eq!(status, expected, "w_N = {w_n}, islands {islands}");
            let e = independent_error(&p, solver.solution());
            assert!(e.is_finite());
            assert_eq!(e <= TOL, expected == Status::Solved, "w_N = {w_n}: {e:e}");
        }
    }
    // Local form: W's normal row of the first contact is zero (a stored zero included).
    let w = CscMatrix::from_triplets(
        "W",
        6,
        6,
        &[
            (0, 3, 0.0),
            (1, 1, 1.0),
            (2, 2, 1.0),
            (3, 3, 2.0),
            (4, 4, 1.0),
            (5, 5, 1.0),
        ],
    )
    .unwrap();
    for (q_n, expected) in [(-1.0, Status::Infeasible), (1.0, Status::Solved)] {
        let l = LocalProblem::new(
            w.clone(),
            vec![q_n, 0.2, 0.0, -1.0, 0.0, 0.0],
            vec![0.5, 0.5],
        )
        .unwrap();
        let p = Problem::Local(l);
        let (solver, status) = solve(&p, Settings::default());
        assert_eq!(status, expected, "q_N = {q_n}");
        let e = independent_error(&p, solver.solution());
        assert_eq!(e <= TOL, expected == Status::Solved, "q_N = {q_n}: {e:e}");
    }
}

/// A scene of islands refuses what one coupled solver refuses, with the same errors: a
/// warm start that is not finite, an update of other sizes.
#[test]
fn islands_refuse_bad_warm_starts_and_updates_by_name() {
    let pile = read("global/Box_Stacks-i0122-82-5.hdf5");
    let scene = Problem::block_diagonal(&[pile.clone(), pile.clone()]).unwrap();
    let mut solver = Solver::new(scene.clone(), Settings::default()).unwrap();
    assert!(solver.stats().islands > 1);
    let mut r = vec![0.0; 3 * scene.n_contacts()];
    r[7] = f64::NAN;
    match solver.warm_start(&r, None) {
        Err(cadmm::Error::InvalidValue {
            field: "r",
            index: 7,
            ..
        }) => {}
        other => panic!("warm start with a NaN: {other:?}"),
    }
    match solver.update(pile) {
        Err(cadmm::Error::Dimension { field: "n", .. }) => {}
        other => panic!("update with half the velocities: {other:?}"),
    }
    assert_eq!(solver.solve().unwrap(), Status::Solved);
}

/// Free bodies whose M stores an entry without its mirror (a stored zero: the values are
/// symmetric, the pattern is not) form one block: the entry joins its row and its column
/// whichever is stored (fuzzing found the one-sided case splitting the block and a panic).
#[test]
fn free_bodies_coupled_by_a_one_sided_entry_of_m() {
    let mut m: Vec<(usize, usize, f64)> = (0..9).map(|i| (i, i, 2.0)).collect();
    m.push((3, 4, 0.0));
    m.push((5, 3, 0.0));
    let h = CscMatrix::from_triplets("H", 9, 3, &[(0, 0, 1.0), (1, 1, 1.0), (2, 2, 1.0)]).unwrap();
    let f: Vec<f64> = (0..9).map(|i| i as f64 - 4.0).collect();
    let p = GlobalProblem::new(
        CscMatrix::from_triplets("M", 9, 9, &m).unwrap(),
        h,
        f.clone(),
        vec![0.0; 3],
        vec![0.5],
    )
    .unwrap();
    let scene = Problem::Global(p);
    let (solver, status) = solve(&scene, Settings::default());
    assert_eq!(status, Status::Solved);
    let s = solver.solution();
    for (i, (v, f)) in s.v.iter().zip(&f).enumerate().skip(3) {
        assert!((v - f / 2.0).abs() <= 1e-12, "v[{i}] = {v}");
    }
    assert!(independent_error(&scene, s) <= TOL);
}

/// A small island is solved by Newton on its dense Delassus form first; when that fails,
/// ADMM takes over, and Newton runs again only once ADMM hands over, not straight away from
/// the start it just failed from (it used to run a second, global Newton phase first). The
/// island here has no solution (`tests/hybrid.rs`: the fuzzed one-velocity problem), so the
/// dense Newton phase cannot end it; a separate body resting on the ground makes a second
/// island.
#[test]
fn a_small_island_whose_newton_fails_goes_on_with_admm() {
    let one_velocity = GlobalProblem::new(
        CscMatrix::new("M", 1, 1, vec![0, 1], vec![0], vec![10.666666666666666]).unwrap(),
        CscMatrix::new(
            "H",
            1,
            3,
            vec![0, 1, 2, 3],
            vec![0, 0, 0],
            vec![1.0, -2.6666666666666665, -1.0],
        )
        .unwrap(),
        vec![-8.0],
        vec![-8.0; 3],
        vec![1.3],
    )
    .unwrap();
    let resting = GlobalProblem::new(
        CscMatrix::identity(3),
        CscMatrix::identity(3),
        vec![-9.81, 0.0, 0.0],
        vec![0.0; 3],
        vec![0.5],
    )
    .unwrap();
    let scene = Problem::block_diagonal(&[Problem::Global(one_velocity), Problem::Global(resting)])
        .unwrap();
    let settings = Settings {
        max_iterations: 2_000,
        trace: true,
        ..Settings::default()
    };
    let mut solver = Solver::new(scene, settings).unwrap();
    let status = solver.solve().unwrap();
    assert_ne!(status, Status::Solved);
    assert_eq!(solver.island_stats().len(), 2);
    let failed = &solver.island_stats()[0];
    assert!(failed.newton_fallbacks >= 1, "{failed:?}");
    // The trace is the failed island's (it took the most iterations): the dense Newton
    // phase, then ADMM iterations.
    let trace = solver.trace();
    assert!(trace.len() >= 2, "{trace:?}");
    assert_eq!(trace[0].phase, Phase::Newton, "{:?}", &trace[..2]);
    assert_eq!(trace[1].phase, Phase::Admm, "{:?}", &trace[..2]);
}
