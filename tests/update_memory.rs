//! The update path does not grow memory: 1e5 solves of a small problem through
//! `Solver::update` and 1e5 through `cadmm_solver_update`, new values each time, with the
//! live heap bytes (counted by this test binary's global allocator) equal after a warm-up
//! and at the end.

use cadmm::ffi::*;
use cadmm::{CscMatrix, GlobalProblem, Problem, Settings, Solver, Status};
use std::alloc::{GlobalAlloc, Layout, System};
use std::ptr::null_mut;
use std::sync::atomic::{AtomicIsize, Ordering::Relaxed};

/// The system allocator, counting live bytes.
struct Counting;

static LIVE: AtomicIsize = AtomicIsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            LIVE.fetch_add(layout.size() as isize, Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        System.dealloc(p, layout);
        LIVE.fetch_sub(layout.size() as isize, Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = System.realloc(p, layout, size);
        if !q.is_null() {
            LIVE.fetch_add(size as isize - layout.size() as isize, Relaxed);
        }
        q
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const SOLVES: usize = 100_000;
const WARM_UP: usize = 1_000;

/// A unit mass on two contacts (a wedge), pushed with a force that changes every step.
fn data(k: usize) -> (Vec<f64>, Vec<f64>) {
    let t = k as f64 * 1e-3;
    let m = vec![
        1.0 + 0.5 * t.sin(),
        1.0 + 0.5 * t.sin(),
        1.0 + 0.5 * t.sin(),
    ];
    let f = vec![0.3 * t.cos(), -1.0 - 0.5 * t.sin(), 0.2];
    (m, f)
}

fn h() -> CscMatrix {
    // Contact frames (normal first) of two contacts on planes tilted by +-45 degrees.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    CscMatrix::from_dense(
        "H",
        3,
        6,
        &[
            s, -s, 0.0, s, s, 0.0, //
            s, s, 0.0, s, -s, 0.0, //
            0.0, 0.0, 1.0, 0.0, 0.0, 1.0,
        ],
    )
    .unwrap()
}

fn problem(k: usize) -> Problem {
    let (m, f) = data(k);
    let m = CscMatrix::new("M", 3, 3, vec![0, 1, 2, 3], vec![0, 1, 2], m).unwrap();
    Problem::Global(GlobalProblem::new(m, h(), f, vec![0.0; 6], vec![0.3, 0.3]).unwrap())
}

fn rust_api() {
    let mut solver = Solver::new(problem(0), Settings::default()).unwrap();
    let (mut live, mut half) = (0, 0);
    for k in 0..SOLVES {
        if k == WARM_UP {
            live = LIVE.load(Relaxed);
        }
        if k == SOLVES / 2 {
            half = LIVE.load(Relaxed);
        }
        solver.update(problem(k)).unwrap();
        if k % 2 == 1 {
            let r = solver.solution().r.clone();
            solver.warm_start(&r, None).unwrap();
        }
        assert_eq!(solver.solve().unwrap(), Status::Solved, "step {k}");
    }
    // The Newton phase is built on its first use and then kept across updates, which may
    // come after the warm-up: one bounded step, then nothing more over 5e4 solves.
    let end = LIVE.load(Relaxed);
    assert_eq!(
        end, half,
        "Solver::update: live bytes grew over the second half"
    );
    assert!(
        end.saturating_sub(live) < 16 << 10,
        "Solver::update: live bytes grew by {} after the warm-up",
        end - live
    );
}

fn c_api() {
    let h = h();
    let colptr: Vec<i64> = h.colptr().iter().map(|&x| x as i64).collect();
    let rowind: Vec<i64> = h.rowind().iter().map(|&x| x as i64).collect();
    let hc = cadmm_csc {
        nrows: 3,
        ncols: 6,
        colptr: colptr.as_ptr(),
        rowind: rowind.as_ptr(),
        values: h.values().as_ptr(),
    };
    let (mp, mi) = ([0i64, 1, 2, 3], [0i64, 1, 2]);
    let (w, mu) = ([0.0; 6], [0.3, 0.3]);
    let new_problem = |k: usize| {
        let (m, f) = data(k);
        let mc = cadmm_csc {
            nrows: 3,
            ncols: 3,
            colptr: mp.as_ptr(),
            rowind: mi.as_ptr(),
            values: m.as_ptr(),
        };
        let mut p = null_mut();
        // SAFETY: every array has the documented length.
        let rc = unsafe {
            cadmm_problem_new_global(3, 2, &mc, &hc, f.as_ptr(), w.as_ptr(), mu.as_ptr(), &mut p)
        };
        assert_eq!(rc, CADMM_OK);
        p
    };
    // SAFETY: valid handles, each freed once.
    unsafe {
        let (mut s, mut sv) = (null_mut(), null_mut());
        assert_eq!(cadmm_settings_new(&mut s), CADMM_OK);
        let p = new_problem(0);
        assert_eq!(cadmm_solver_new(p, s, &mut sv), CADMM_OK);
        cadmm_problem_free(p);
        let mut r = [0.0; 6];
        let (mut live, mut half) = (0, 0);
        for k in 0..SOLVES {
            if k == WARM_UP {
                live = LIVE.load(Relaxed);
            }
            if k == SOLVES / 2 {
                half = LIVE.load(Relaxed);
            }
            let p = new_problem(k);
            assert_eq!(cadmm_solver_update(sv, p), CADMM_OK);
            cadmm_problem_free(p);
            if k % 2 == 1 {
                assert_eq!(
                    cadmm_solver_warm_start(sv, r.as_ptr(), null_mut()),
                    CADMM_OK
                );
            }
            let mut status = -1;
            assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
            assert_eq!(status, CADMM_STATUS_SOLVED, "step {k}");
            let rc = cadmm_solver_get_solution(sv, r.as_mut_ptr(), null_mut(), null_mut());
            assert_eq!(rc, CADMM_OK);
        }
        // As above: the Newton phase may be built once after the warm-up.
        let end = LIVE.load(Relaxed);
        assert_eq!(
            end, half,
            "cadmm_solver_update: live bytes grew over the second half"
        );
        assert!(
            end.saturating_sub(live) < 16 << 10,
            "cadmm_solver_update: live bytes grew by {} after the warm-up",
            end - live
        );
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
    }
}

/// One test function: the allocator counts every thread, so the two runs must not overlap.
#[test]
fn update_path_keeps_memory_flat() {
    rust_api();
    c_api();
}
