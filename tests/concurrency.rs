//! Solvers on threads: eight solvers at once, on eight different problems and on one
//! problem, must give results bitwise identical to serial solves (no shared mutable state,
//! no dependence on scheduling).

mod common;
#[path = "../examples/extreme/scenes.rs"]
mod scenes;

use cadmm::{Problem, Settings, Solver, Status};

/// The bits of `r`, `u`, `v`, the status and the iteration count of one solve.
fn solve(p: &Problem) -> (Vec<u64>, Status, usize) {
    let mut s = Solver::new(p.clone(), Settings::default()).unwrap();
    let status = s.solve().unwrap();
    let sol = s.solution();
    let bits = sol
        .r
        .iter()
        .chain(&sol.u)
        .chain(&sol.v)
        .map(|x| x.to_bits())
        .collect();
    (bits, status, s.stats().iterations)
}

fn problems() -> Vec<Problem> {
    let names = [
        "chain-8-1e4",
        "mixed-mu",
        "one-body-1000-contacts",
        "granular-pile-325",
        "box-mu-1e3",
        "units-base",
        "thin-long-plank",
        "light-load-slide-mu-10",
    ];
    let cases = scenes::cases((5, 5, 5));
    names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let c = cases.iter().find(|c| c.name == *name).unwrap();
            // Half in the global form, half in the local form where there is one.
            match (&c.local, k % 2) {
                (Some(l), 1) => Problem::Local(l.clone()),
                _ => Problem::Global(c.global.clone()),
            }
        })
        .collect()
}

fn parallel(problems: &[Problem]) -> Vec<(Vec<u64>, Status, usize)> {
    std::thread::scope(|scope| {
        let handles: Vec<_> = problems
            .iter()
            .map(|p| scope.spawn(move || solve(p)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

#[test]
fn eight_threads_on_different_problems_match_serial_runs() {
    let problems = problems();
    let serial: Vec<_> = problems.iter().map(solve).collect();
    assert!(serial.iter().all(|s| s.1 == Status::Solved));
    assert_eq!(parallel(&problems), serial);
}

#[test]
fn eight_threads_on_one_problem_match_a_serial_run() {
    let p = problems().swap_remove(3); // the granular pile, 325 contacts
    let serial = solve(&p);
    assert_eq!(serial.1, Status::Solved);
    let copies = vec![p; 8];
    for result in parallel(&copies) {
        assert_eq!(result, serial);
    }
}
