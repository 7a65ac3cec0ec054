//! The per-step values path: `Solver::update_values` must give the very solve that
//! `Solver::update` with a whole new problem gives, take matrix values in the caller's
//! array order (also when construction sorted the rows), and allocate nothing.

mod common;

use cadmm::{CscMatrix, GlobalProblem, LocalProblem, NewValues, Problem, Settings, Solver, Status};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts the allocations of the thread that asked for it (`COUNTING`): the other tests of
/// this binary run on other threads at the same time.
struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    static COUNTING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn count() {
    if COUNTING.with(|c| c.get()) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: forwarded.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Arrays of a CSC matrix as a caller holds them: rows of each column in *descending*
/// order, so the library must map the caller's order onto its sorted storage.
struct CallerCsc {
    n: usize,
    colptr: Vec<usize>,
    rowind: Vec<usize>,
    values: Vec<f64>,
}

impl CallerCsc {
    fn from_dense(nrows: usize, ncols: usize, a: impl Fn(usize, usize) -> f64) -> Self {
        let (mut colptr, mut rowind, mut values) = (vec![0], Vec::new(), Vec::new());
        for j in 0..ncols {
            for i in (0..nrows).rev() {
                let v = a(i, j);
                if v != 0.0 {
                    rowind.push(i);
                    values.push(v);
                }
            }
            colptr.push(rowind.len());
        }
        Self {
            n: nrows,
            colptr,
            rowind,
            values,
        }
    }
    fn matrix(&self, name: &'static str) -> CscMatrix {
        let ncols = self.colptr.len() - 1;
        CscMatrix::new(
            name,
            self.n,
            ncols,
            self.colptr.clone(),
            self.rowind.clone(),
            self.values.clone(),
        )
        .unwrap()
    }
}

/// A column of `k` point masses (3 velocities each) resting on each other and on the
/// ground, each with a coupled (non-diagonal) 3x3 mass block, pushed sideways: step `t`
/// changes every value (masses, contact frames, forces, friction).
fn stack(k: usize, t: f64) -> (CallerCsc, CallerCsc, Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = 3 * k;
    let m = CallerCsc::from_dense(n, n, |i, j| {
        let (b, a, c) = (i / 3, i % 3, j % 3);
        if b != j / 3 {
            return 0.0;
        }
        let mass = 1.0 + b as f64 + 0.1 * t;
        if a == c {
            mass
        } else {
            0.05 * mass
        }
    });
    // Contact c between mass c (above) and mass c - 1 (below, ground for c = 0); a
    // slightly tilted normal so that every value of H moves with t.
    let tilt = 0.01 * (1.0 + t);
    let h = CallerCsc::from_dense(n, 3 * k, |i, j| {
        let (c, comp) = (j / 3, j % 3);
        let frame = [[tilt, 0.0, 1.0], [1.0, 0.0, -tilt], [0.0, 1.0, 0.0]];
        let sign = if i / 3 == c {
            1.0
        } else if c > 0 && i / 3 == c - 1 {
            -1.0
        } else {
            return 0.0;
        };
        sign * frame[comp][i % 3]
    });
    let f: Vec<f64> = (0..n)
        .map(|i| match i % 3 {
            2 => -9.81 * (1.0 + (i / 3) as f64) * 0.01,
            0 => 0.02 * (1.0 + t) * ((i / 3) as f64 - 1.0),
            _ => 0.0,
        })
        .collect();
    let w: Vec<f64> = (0..3 * k)
        .map(|i| if i % 3 == 0 { -1e-3 * t } else { 0.0 })
        .collect();
    let mu: Vec<f64> = (0..k).map(|c| 0.3 + 0.1 * c as f64 + 0.05 * t).collect();
    (m, h, f, w, mu)
}

fn global(step: &(CallerCsc, CallerCsc, Vec<f64>, Vec<f64>, Vec<f64>)) -> GlobalProblem {
    let (m, h, f, w, mu) = step;
    GlobalProblem::new(
        m.matrix("M"),
        h.matrix("H"),
        f.clone(),
        w.clone(),
        mu.clone(),
    )
    .unwrap()
}

fn settings() -> Settings {
    Settings {
        tolerance: 1e-10,
        ..Settings::default()
    }
}

#[test]
fn global_values_path_solves_like_a_whole_update() {
    let k = 5;
    let first = stack(k, 0.0);
    let mut by_values = Solver::new(Problem::Global(global(&first)), settings()).unwrap();
    let mut by_problem = Solver::new(Problem::Global(global(&first)), settings()).unwrap();
    for t in 1..4 {
        let next = stack(k, t as f64);
        let (m, h, f, w, mu) = &next;
        by_values
            .update_values(&NewValues {
                m: Some(&m.values),
                h: Some(&h.values),
                f: Some(f),
                w: Some(w),
                mu: Some(mu),
                ..Default::default()
            })
            .unwrap();
        let problem = global(&next);
        by_problem.update(Problem::Global(problem.clone())).unwrap();
        let (a, b) = (by_values.solve().unwrap(), by_problem.solve().unwrap());
        assert_eq!(a, b);
        let (sa, sb) = (by_values.solution(), by_problem.solution());
        assert_eq!(
            sa, sb,
            "step {t}: the two update paths give different solves"
        );
        let error = common::global_error(&problem, &sa.r, &sa.v, &sa.lambda);
        assert!(error <= 1e-10, "step {t}: error {error:e}");
        // The problem really changed: the first step's solution does not solve this one.
        let stale = global(&first);
        let e0 = common::global_error(&problem, &solve_once(stale).r, &sa.v, &sa.lambda);
        assert!(e0 > 1e-6, "step {t}: data did not change ({e0:e})");
    }
}

/// Two joints on a 10-mass stack (large enough that ADMM runs, with its quasi-definite
/// system): the x velocity of the bottom mass and the y velocity of the top one, with
/// values that move with `t`.
fn joints(k: usize, t: f64) -> (CallerCsc, Vec<f64>) {
    let n = 3 * k;
    let g = CallerCsc::from_dense(n, 2, |i, j| match (i, j) {
        (0, 0) => 1.0 + 0.1 * t,
        (i, 1) if i == n - 2 => 1.0,
        _ => 0.0,
    });
    (g, vec![1e-3 * t, 0.0])
}

/// The values path with joints, whose system takes the new values at the solve's first
/// step: each step's solve meets the tolerance by the independent measure (joint residual
/// included) and agrees with a new solver built on the same step's problem. ADMM runs
/// alone, so that only the v-update system carries the new values (a Newton phase builds
/// its own).
#[test]
fn values_path_with_joints_solves_like_a_new_solver() {
    let settings = || Settings {
        newton_polish: Some(false),
        ..settings()
    };
    let k = 10;
    let with_joints = |step: &_, t: f64| {
        let (g, b) = joints(k, t);
        global(step).with_joints(g.matrix("G"), b).unwrap()
    };
    let first = stack(k, 0.0);
    let mut by_values = Solver::new(Problem::Global(with_joints(&first, 0.0)), settings()).unwrap();
    assert_eq!(by_values.solve().unwrap(), Status::Solved);
    for t in 1..4 {
        let t = t as f64;
        let next = stack(k, t);
        let (m, h, f, w, mu) = &next;
        let (g, b) = joints(k, t);
        by_values
            .update_values(&NewValues {
                m: Some(&m.values),
                h: Some(&h.values),
                g: Some(&g.values),
                f: Some(f),
                w: Some(w),
                b: Some(&b),
                mu: Some(mu),
                ..Default::default()
            })
            .unwrap();
        let problem = with_joints(&next, t);
        let mut fresh = Solver::new(Problem::Global(problem.clone()), settings()).unwrap();
        assert_eq!(by_values.solve().unwrap(), Status::Solved, "step {t}");
        assert_eq!(fresh.solve().unwrap(), Status::Solved, "step {t}");
        let (sa, sb) = (by_values.solution(), fresh.solution());
        let error = common::global_error(&problem, &sa.r, &sa.v, &sa.lambda);
        assert!(error <= 1e-10, "step {t}: error {error:e}");
        let scale = sb.v.iter().fold(1e-3f64, |a, x| a.max(x.abs()));
        for (x, y) in sa.v.iter().zip(&sb.v) {
            assert!((x - y).abs() <= 1e-6 * scale, "step {t}: v {x} against {y}");
        }
        // The joints hold, and the step's data changed (the first step's solution fails).
        let stale = common::global_error(&problem, &sa.r, &sa.v, &[0.0, 0.0]);
        assert!(stale > error, "step {t}: the joint impulses do nothing");
    }
}

fn solve_once(p: GlobalProblem) -> cadmm::Solution {
    let mut s = Solver::new(Problem::Global(p), settings()).unwrap();
    s.solve().unwrap();
    s.solution().clone()
}

#[test]
fn local_values_path_solves_like_a_whole_update() {
    // Delassus matrix of the stack, dense, with the rows of each column in caller order.
    let local = |t: f64| {
        let p = global(&stack(3, t));
        let (m, h) = (p.m.to_dense(), p.h.to_dense());
        let (n, l) = (p.n(), p.w.len());
        let mm = nalgebra::DMatrix::from_column_slice(n, n, &m);
        let hh = nalgebra::DMatrix::from_column_slice(n, l, &h);
        let minv = mm.try_inverse().unwrap();
        let w = hh.transpose() * &minv * &hh;
        let q = nalgebra::DVector::from_column_slice(&p.w)
            + hh.transpose() * minv * nalgebra::DVector::from_column_slice(&p.f);
        (
            CallerCsc::from_dense(l, l, |i, j| w[(i, j)]),
            q.as_slice().to_vec(),
            p.mu.clone(),
        )
    };
    let build = |(w, q, mu): &(CallerCsc, Vec<f64>, Vec<f64>)| {
        LocalProblem::new(w.matrix("W"), q.clone(), mu.clone()).unwrap()
    };
    let first = local(0.0);
    let mut by_values = Solver::new(Problem::Local(build(&first)), settings()).unwrap();
    let mut by_problem = Solver::new(Problem::Local(build(&first)), settings()).unwrap();
    for t in 1..3 {
        let next = local(t as f64);
        by_values
            .update_values(&NewValues {
                delassus: Some(&next.0.values),
                q: Some(&next.1),
                mu: Some(&next.2),
                ..Default::default()
            })
            .unwrap();
        let problem = build(&next);
        by_problem.update(Problem::Local(problem.clone())).unwrap();
        by_values.solve().unwrap();
        by_problem.solve().unwrap();
        let sa = by_values.solution();
        assert_eq!(sa, by_problem.solution());
        let error = common::local_error(&problem, &sa.r);
        assert!(error <= 1e-10, "step {t}: error {error:e}");
    }
}

#[test]
fn values_path_allocates_nothing_and_refuses_bad_values() {
    let k = 20;
    let mut solver = Solver::new(Problem::Global(global(&stack(k, 0.0))), settings()).unwrap();
    solver.solve().unwrap();
    let next = stack(k, 1.0);
    let (m, h, f, w, mu) = &next;
    let values = NewValues {
        m: Some(&m.values),
        h: Some(&h.values),
        f: Some(f),
        w: Some(w),
        mu: Some(mu),
        ..Default::default()
    };
    // The first update may size nothing either, but measure the steady state.
    solver.update_values(&values).unwrap();
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.with(|c| c.set(true));
    solver.update_values(&values).unwrap();
    COUNTING.with(|c| c.set(false));
    let during = ALLOCATIONS.load(Ordering::Relaxed) - before;
    assert_eq!(during, 0, "update_values allocated {during} times");

    // The same through islands: each island's share is gathered into buffers sized by the
    // first update and kept.
    let pile = Problem::Global(global(&stack(5, 0.0)));
    let scene = Problem::block_diagonal(&[pile.clone(), pile.clone(), pile]).unwrap();
    let Problem::Global(g) = &scene else {
        unreachable!()
    };
    let heavier: Vec<f64> = g.m.values().iter().map(|x| 1.1 * x).collect();
    let scene_values = NewValues {
        m: Some(&heavier),
        f: Some(&g.f),
        w: Some(&g.w),
        ..Default::default()
    };
    let mut islands = Solver::new(scene.clone(), settings()).unwrap();
    islands.solve().unwrap();
    assert_eq!(islands.stats().islands, 3);
    islands.update_values(&scene_values).unwrap();
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.with(|c| c.set(true));
    islands.update_values(&scene_values).unwrap();
    COUNTING.with(|c| c.set(false));
    let during = ALLOCATIONS.load(Ordering::Relaxed) - before;
    assert_eq!(
        during, 0,
        "update_values on islands allocated {during} times"
    );

    // Bad values are named and change nothing: the solver still solves the last good data.
    let mut bad_mu = mu.clone();
    bad_mu[3] = -1.0;
    let err = solver
        .update_values(&NewValues {
            mu: Some(&bad_mu),
            ..Default::default()
        })
        .unwrap_err();
    assert!(err.to_string().contains("mu[3]"), "{err}");
    let short = &m.values[1..];
    let err = solver
        .update_values(&NewValues {
            m: Some(short),
            ..Default::default()
        })
        .unwrap_err();
    assert!(err.to_string().contains('M'), "{err}");
    let err = solver
        .update_values(&NewValues {
            q: Some(f),
            ..Default::default()
        })
        .unwrap_err();
    assert!(err.to_string().contains("local"), "{err}");
    solver.solve().unwrap();
    let s = solver.solution();
    let error = common::global_error(&global(&next), &s.r, &s.v, &s.lambda);
    assert!(error <= 1e-10, "error {error:e}");
}

/// A refused update changes nothing, whatever it was refused for, also when it is refused
/// only once its values were taken (an indefinite M fails its factorization): the solver
/// solves the data it held before, bitwise as before, and a later update that sends only
/// a new `f` (M kept) succeeds and solves the old M with the new f.
#[test]
fn a_refused_update_changes_nothing() {
    let one = global(&stack(5, 0.0));
    let three = Problem::block_diagonal(&[
        Problem::Global(one.clone()),
        Problem::Global(one.clone()),
        Problem::Global(one.clone()),
    ])
    .unwrap();
    let Problem::Global(three) = three else {
        unreachable!()
    };
    for (label, p) in [("one island", one), ("three islands", three)] {
        let mut solver = Solver::new(Problem::Global(p.clone()), settings()).unwrap();
        solver.solve().unwrap();
        let before = solver.solution().clone();
        // An indefinite M: the first diagonal entry negated.
        let diag = (p.m.colptr()[0]..p.m.colptr()[1])
            .find(|&k| p.m.rowind()[k] == 0)
            .unwrap();
        let mut indefinite = p.m.values().to_vec();
        indefinite[diag] = -indefinite[diag];
        let mut nan_f = p.f.clone();
        nan_f[1] = f64::NAN;
        let short_h = &p.h.values()[1..];
        let negative_mu = vec![-0.5; p.mu.len()];
        let refusals: [(&str, NewValues); 5] = [
            (
                "indefinite M",
                NewValues {
                    m: Some(&indefinite),
                    ..Default::default()
                },
            ),
            (
                "indefinite M with a new f",
                NewValues {
                    m: Some(&indefinite),
                    f: Some(&p.f),
                    ..Default::default()
                },
            ),
            (
                "NaN in f",
                NewValues {
                    f: Some(&nan_f),
                    ..Default::default()
                },
            ),
            (
                "short H",
                NewValues {
                    h: Some(short_h),
                    ..Default::default()
                },
            ),
            (
                "negative mu",
                NewValues {
                    mu: Some(&negative_mu),
                    ..Default::default()
                },
            ),
        ];
        for (what, values) in refusals {
            assert!(solver.update_values(&values).is_err(), "{label}: {what}");
            assert_eq!(solver.solve().unwrap(), Status::Solved, "{label}: {what}");
            assert_eq!(
                solver.solution(),
                &before,
                "{label}: after a refused update ({what}) the solve changed"
            );
        }
        // The same for a whole problem refused: M indefinite.
        let mut bad = p.clone();
        bad.m.set_values("M", &indefinite).unwrap();
        assert!(solver.update(Problem::Global(bad)).is_err(), "{label}");
        solver.solve().unwrap();
        assert_eq!(
            solver.solution(),
            &before,
            "{label}: after a refused update"
        );

        // Only a new f, M kept (not sent): taken, and solved with the M held before.
        let f2: Vec<f64> = p.f.iter().map(|x| 1.5 * x).collect();
        solver
            .update_values(&NewValues {
                f: Some(&f2),
                ..Default::default()
            })
            .unwrap_or_else(|e| panic!("{label}: an update of f alone was refused: {e}"));
        assert_eq!(solver.solve().unwrap(), Status::Solved, "{label}");
        let s = solver.solution();
        let mut expected = p.clone();
        expected.f = f2;
        let error = common::global_error(&expected, &s.r, &s.v, &s.lambda);
        assert!(error <= 1e-10, "{label}: error {error:e}");
    }
}
