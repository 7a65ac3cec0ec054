//! A limit stops a solve and never changes its path: a solve that ends before its limits
//! returns bitwise the same answer, after the same iterations, whatever the time limit,
//! the iteration limit and the load of the machine.

mod common;
#[path = "../examples/extreme/scenes.rs"]
mod scenes;

use cadmm::{LinearSolver, Problem, Settings, Solver, Status};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A scene of several islands of different sizes: two lattice piles and two irregular
/// ones side by side.
fn scene() -> Problem {
    let parts: Vec<Problem> = [
        scenes::pile(3, 3, 2).global(),
        scenes::pile(4, 2, 3).global(),
        scenes::irregular_pile(3, 2, 2).global(),
        scenes::irregular_pile(4, 3, 2).global(),
    ]
    .into_iter()
    .map(Problem::Global)
    .collect();
    Problem::block_diagonal(&parts).unwrap()
}

fn solve(p: &Problem, settings: Settings) -> (Status, cadmm::Solution, cadmm::Stats) {
    let mut solver = Solver::new(p.clone(), settings).unwrap();
    let status = solver.solve().unwrap();
    (status, solver.solution().clone(), *solver.stats())
}

/// Two threads spinning for as long as the value lives: the machine loaded.
struct Load(Arc<AtomicBool>, Vec<std::thread::JoinHandle<()>>);

impl Load {
    fn start() -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let threads = (0..2)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 1u64;
                    while !stop.load(Ordering::Relaxed) {
                        x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
                    }
                    std::hint::black_box(x);
                })
            })
            .collect();
        Self(stop, threads)
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
        for t in self.1.drain(..) {
            let _ = t.join();
        }
    }
}

fn check_same(p: &Problem, base: Settings, what: &str) {
    let (status, reference, stats) = solve(p, base.clone());
    assert_eq!(status, Status::Solved, "{what}: {stats:?}");
    let e = match p {
        Problem::Global(g) => common::global_error_sparse(g, &reference.r, &reference.v),
        Problem::Local(_) => unreachable!(),
    };
    assert!(e <= base.tolerance, "{what}: error {e:e}");
    let limited = [
        Settings {
            time_limit: 3600.0,
            ..base.clone()
        },
        Settings {
            max_iterations: stats.iterations * 100 + 1000,
            ..base.clone()
        },
        Settings {
            time_limit: 1000.0,
            max_iterations: 50_000_000,
            ..base.clone()
        },
    ];
    for loaded in [false, true] {
        let _load = loaded.then(Load::start);
        for s in &limited {
            let (st, sol, stats2) = solve(p, s.clone());
            let how = format!(
                "{what}, time limit {}, iteration limit {}, loaded {loaded}",
                s.time_limit, s.max_iterations
            );
            assert_eq!(st, status, "{how}");
            assert_eq!(stats2.iterations, stats.iterations, "{how}");
            assert_eq!(stats2.newton_iterations, stats.newton_iterations, "{how}");
            assert!(sol == reference, "{how}: another answer");
        }
    }
}

#[test]
fn limits_that_are_not_reached_do_not_change_the_solve() {
    let p = scene();
    let base = Settings {
        tolerance: 1e-8,
        ..Settings::default()
    };
    check_same(&p, base.clone(), "auto");
    check_same(
        &p,
        Settings {
            linear_solver: LinearSolver::Iterative,
            tolerance: 1e-6,
            ..base
        },
        "iterative",
    );
}

/// A pile of a thousand contacts, matrix-free to 1e-5 (the backend whose conjugate
/// gradients watch the clock), with Newton polishing the factorized one.
#[test]
fn limits_do_not_change_a_pile_solve() {
    let p = Problem::Global(scenes::irregular_pile(8, 8, 4).global());
    for backend in [LinearSolver::Iterative, LinearSolver::Direct] {
        let settings = Settings {
            tolerance: 1e-5,
            linear_solver: backend,
            ..Settings::default()
        };
        check_same(&p, settings, &format!("pile, {backend:?}"));
    }
}

/// A splitting whose x-step takes `step` of wall-clock time and whose iterate never meets
/// the tolerance: only the clock ends its runs.
struct SlowSplitting {
    step: std::time::Duration,
}

impl cadmm::admm::Splitting for SlowSplitting {
    fn dim(&self) -> usize {
        1
    }
    fn set_rho(&mut self, _rho: f64) -> Result<(), cadmm::Error> {
        Ok(())
    }
    fn x_step(&mut self, _y: &[f64], _zeta: &[f64], _rho: f64, ax: &mut [f64]) {
        std::thread::sleep(self.step);
        ax[0] = 1.0;
    }
    fn y_step(&self, _ax: &[f64], _zeta: &[f64], y: &mut [f64]) {
        y[0] = -1.0;
    }
    fn c(&self) -> &[f64] {
        &[0.0]
    }
    fn norm_at(&mut self, d: &[f64]) -> f64 {
        d[0].abs()
    }
    fn error(&mut self, _ax: &[f64], _y: &[f64], _zeta: &[f64], _rho: f64) -> f64 {
        1.0
    }
}

/// A run ends before the iteration that would take it past its time limit, judged by the
/// last one, instead of after it: iterations of 20 ms under a 50 ms limit stop after the
/// second (40 ms), not the third (60 ms). A slower machine only ends the run sooner.
#[test]
fn a_run_stops_before_the_iteration_that_would_pass_its_time_limit() {
    use cadmm::admm::{run, EngineSettings, EngineState, Variant};
    let mut sp = SlowSplitting {
        step: std::time::Duration::from_millis(20),
    };
    let mut state = EngineState {
        y: vec![0.0],
        zeta: vec![0.0],
        ax: vec![0.0],
        rho: 1.0,
    };
    let set = EngineSettings {
        tolerance: 1e-8,
        max_iterations: 100,
        time_limit: 0.05,
        variant: Variant::from_name("cp-N").unwrap(),
        anderson: 0,
        anderson_interval: 1,
        s_update: cadmm::SUpdate::Internal,
        eps_abs: 1e-12,
        eps_rel: 1e-12,
        check_every: 1,
        trace: false,
        rho_range: 1e6,
        handover: None,
    };
    let t0 = std::time::Instant::now();
    let out = run(&mut sp, &mut state, &set, t0).unwrap();
    let seconds = t0.elapsed().as_secs_f64();
    assert_eq!(out.status, Some(Status::TimeLimit));
    assert!(
        (1..=2).contains(&out.iterations),
        "{} iterations of 20 ms under a 50 ms limit ({seconds} s)",
        out.iterations
    );
}
