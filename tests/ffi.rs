//! The C API exercised from Rust through `cadmm::ffi`: solves, every class of bad input,
//! the stats versioning and the error measure.

use cadmm::ffi::*;
use std::ffi::{c_char, CStr};
use std::mem::{offset_of, size_of};
use std::ptr::{null, null_mut, NonNull};

/// A matrix owned on the Rust side, lent to C as a `cadmm_csc`.
struct Csc {
    nrows: usize,
    ncols: usize,
    colptr: Vec<i64>,
    rowind: Vec<i64>,
    values: Vec<f64>,
}

impl Csc {
    fn new(nrows: usize, ncols: usize, colptr: &[i64], rowind: &[i64], values: &[f64]) -> Self {
        Self {
            nrows,
            ncols,
            colptr: colptr.to_vec(),
            rowind: rowind.to_vec(),
            values: values.to_vec(),
        }
    }
    fn diag(d: &[f64]) -> Self {
        let n = d.len() as i64;
        Self::new(
            d.len(),
            d.len(),
            &(0..=n).collect::<Vec<_>>(),
            &(0..n).collect::<Vec<_>>(),
            d,
        )
    }
    fn eye(n: usize) -> Self {
        Self::diag(&vec![1.0; n])
    }
    fn c(&self) -> cadmm_csc {
        cadmm_csc {
            nrows: self.nrows,
            ncols: self.ncols,
            colptr: self.colptr.as_ptr(),
            rowind: if self.rowind.is_empty() {
                null()
            } else {
                self.rowind.as_ptr()
            },
            values: if self.values.is_empty() {
                null()
            } else {
                self.values.as_ptr()
            },
        }
    }
}

const F: [f64; 3] = [-9.81, 0.0, 0.0];
const W0: [f64; 3] = [0.0; 3];
const MU: [f64; 1] = [0.5];

/// A pointer that no call may write: any failed `_new` must leave it as it is.
fn sentinel<T>() -> *mut T {
    NonNull::<T>::dangling().as_ptr()
}

fn msg(code: cadmm_result) -> String {
    unsafe { CStr::from_ptr(cadmm_result_message(code)) }
        .to_str()
        .unwrap()
        .to_owned()
}

fn last_error(sv: *const cadmm_solver) -> String {
    unsafe { CStr::from_ptr(cadmm_solver_last_error(sv)) }
        .to_str()
        .unwrap()
        .to_owned()
}

fn cstr(s: &CStr) -> *const c_char {
    s.as_ptr()
}

/// The single-contact global problem: unit mass pressed on the ground by gravity.
fn global_problem() -> *mut cadmm_problem {
    let (m, h) = (Csc::eye(3), Csc::eye(3));
    let mut p = null_mut();
    let rc = unsafe {
        cadmm_problem_new_global(
            3,
            1,
            &m.c(),
            &h.c(),
            F.as_ptr(),
            W0.as_ptr(),
            MU.as_ptr(),
            &mut p,
        )
    };
    assert_eq!(rc, CADMM_OK);
    assert!(!p.is_null());
    p
}

/// `u = W r + q` with `W = I`, `q = (-1, 0.2, 0)`.
fn local_problem() -> *mut cadmm_problem {
    let w = Csc::eye(3);
    let q = [-1.0, 0.2, 0.0];
    let mut p = null_mut();
    let rc = unsafe { cadmm_problem_new_local(1, &w.c(), q.as_ptr(), MU.as_ptr(), &mut p) };
    assert_eq!(rc, CADMM_OK);
    p
}

fn settings() -> *mut cadmm_settings {
    let mut s = null_mut();
    assert_eq!(unsafe { cadmm_settings_new(&mut s) }, CADMM_OK);
    s
}

fn solver(p: *const cadmm_problem, s: *const cadmm_settings) -> *mut cadmm_solver {
    let mut sv = null_mut();
    assert_eq!(unsafe { cadmm_solver_new(p, s, &mut sv) }, CADMM_OK);
    sv
}

fn full_stats(sv: *const cadmm_solver) -> cadmm_stats {
    let mut st = cadmm_stats {
        struct_size: size_of::<cadmm_stats>(),
        ..Default::default()
    };
    assert_eq!(unsafe { cadmm_solver_get_stats(sv, &mut st) }, CADMM_OK);
    st
}

#[test]
fn version_and_messages() {
    let v = unsafe { CStr::from_ptr(cadmm_version()) };
    assert_eq!(v.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
    assert_eq!(msg(CADMM_OK), "ok");
    let codes = [
        CADMM_ERR_NULL_POINTER,
        CADMM_ERR_DIMENSION,
        CADMM_ERR_INVALID_CSC,
        CADMM_ERR_INVALID_VALUE,
        CADMM_ERR_NOT_POSITIVE_DEFINITE,
        CADMM_ERR_SINGULAR,
        CADMM_ERR_INVALID_SETTING,
        CADMM_ERR_IO,
        CADMM_ERR_UNSUPPORTED,
        CADMM_ERR_PANIC,
        CADMM_ERR_PATTERN_CHANGED,
        CADMM_ERR_OUT_OF_MEMORY,
    ];
    for (k, &c) in codes.iter().enumerate() {
        assert_eq!(c, k as i32 + 1);
        let m = msg(c);
        assert!(!m.is_empty() && m != "unknown result code", "{c}: {m}");
    }
    for bad in [-1, 13, 99, i32::MIN, i32::MAX] {
        assert_eq!(msg(bad), "unknown result code");
    }
}

#[test]
fn single_contact_global_solves() {
    let p = global_problem();
    let s = settings();
    let sv = solver(p, s);
    let mut status = -1;
    assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
    assert_eq!(status, CADMM_STATUS_SOLVED);
    let (mut r, mut u, mut v) = ([f64::NAN; 3], [f64::NAN; 3], [f64::NAN; 3]);
    let rc =
        unsafe { cadmm_solver_get_solution(sv, r.as_mut_ptr(), u.as_mut_ptr(), v.as_mut_ptr()) };
    assert_eq!(rc, CADMM_OK);
    assert!(
        (r[0] - 9.81).abs() < 1e-6 && r[1].abs() < 1e-6 && r[2].abs() < 1e-6,
        "{r:?}"
    );
    assert!(v.iter().all(|x| x.abs() < 1e-6), "{v:?}");
    assert!(u.iter().all(|x| x.abs() < 1e-6), "{u:?}");

    // Any output may be skipped.
    let mut r2 = [0.0; 3];
    let rc = unsafe { cadmm_solver_get_solution(sv, r2.as_mut_ptr(), null_mut(), null_mut()) };
    assert_eq!(rc, CADMM_OK);
    assert_eq!(r, r2);
    assert_eq!(
        unsafe { cadmm_solver_get_solution(sv, null_mut(), null_mut(), null_mut()) },
        CADMM_OK
    );

    let st = full_stats(sv);
    assert_eq!(st.struct_size, size_of::<cadmm_stats>());
    assert_eq!(st.status, CADMM_STATUS_SOLVED);
    assert!(st.iterations > 0);
    assert!(st.error <= 1e-8, "{}", st.error);
    assert!(st.rho > 0.0 && st.refactorizations >= 1);
    assert!(st.setup_seconds >= 0.0 && st.solve_seconds >= 0.0);

    let mut e = f64::NAN;
    let rc = unsafe { cadmm_problem_error(p, r.as_ptr(), u.as_ptr(), v.as_ptr(), &mut e) };
    assert_eq!(rc, CADMM_OK);
    assert!(e <= 1e-8, "{e}");

    let (mut n, mut nc, mut global) = (9, 9, false);
    assert_eq!(
        unsafe { cadmm_problem_dims(p, &mut n, &mut nc, &mut global) },
        CADMM_OK
    );
    assert_eq!((n, nc, global), (3, 1, true));
    assert_eq!(last_error(sv), "");
    assert_eq!(unsafe { cadmm_solver_trace_len(sv) }, 0);

    unsafe {
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn single_contact_local_solves() {
    // W = I, q = (-1, 0.2, 0), mu = 0.5: sticking, r = (1, -0.2, 0), u = 0.
    let p = local_problem();
    let (mut n, mut nc, mut global) = (9, 9, true);
    assert_eq!(
        unsafe { cadmm_problem_dims(p, &mut n, &mut nc, &mut global) },
        CADMM_OK
    );
    assert_eq!((n, nc, global), (0, 1, false));
    let s = settings();
    let sv = solver(p, s);
    let mut status = -1;
    assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
    assert_eq!(status, CADMM_STATUS_SOLVED);
    let (mut r, mut u) = ([0.0; 3], [0.0; 3]);
    // v is ignored for a local problem, even when given.
    let mut v = [7.0; 2];
    let rc =
        unsafe { cadmm_solver_get_solution(sv, r.as_mut_ptr(), u.as_mut_ptr(), v.as_mut_ptr()) };
    assert_eq!(rc, CADMM_OK);
    assert_eq!(v, [7.0; 2]);
    assert!(
        (r[0] - 1.0).abs() < 1e-6 && (r[1] + 0.2).abs() < 1e-6,
        "{r:?}"
    );
    let mut e = f64::NAN;
    let rc = unsafe { cadmm_problem_error(p, r.as_ptr(), null(), null(), &mut e) };
    assert_eq!(rc, CADMM_OK);
    assert!(e <= 1e-8, "{e}");
    unsafe {
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn free_null_is_a_no_op() {
    unsafe {
        cadmm_problem_free(null_mut());
        cadmm_settings_free(null_mut());
        cadmm_solver_free(null_mut());
        assert_eq!(cadmm_solver_trace_len(null()), 0);
        assert!(!cadmm_solver_last_error(null()).is_null());
    }
    assert!(!last_error(null()).is_empty());
}

#[test]
fn null_pointers_are_refused_and_out_is_untouched() {
    let (m, h) = (Csc::eye(3), Csc::eye(3));
    let (mc, hc) = (m.c(), h.c());
    let new_global = |m: *const cadmm_csc,
                      h: *const cadmm_csc,
                      f: *const f64,
                      w: *const f64,
                      mu: *const f64,
                      out: *mut *mut cadmm_problem| unsafe {
        cadmm_problem_new_global(3, 1, m, h, f, w, mu, out)
    };
    let cases: [(
        &str,
        *const cadmm_csc,
        *const cadmm_csc,
        *const f64,
        *const f64,
        *const f64,
    ); 5] = [
        ("M", null(), &hc, F.as_ptr(), W0.as_ptr(), MU.as_ptr()),
        ("H", &mc, null(), F.as_ptr(), W0.as_ptr(), MU.as_ptr()),
        ("f", &mc, &hc, null(), W0.as_ptr(), MU.as_ptr()),
        ("w", &mc, &hc, F.as_ptr(), null(), MU.as_ptr()),
        ("mu", &mc, &hc, F.as_ptr(), W0.as_ptr(), null()),
    ];
    for (what, m, h, f, w, mu) in cases {
        let mut out = sentinel();
        assert_eq!(
            new_global(m, h, f, w, mu, &mut out),
            CADMM_ERR_NULL_POINTER,
            "{what}"
        );
        assert_eq!(out, sentinel(), "{what}");
    }
    assert_eq!(
        new_global(&mc, &hc, F.as_ptr(), W0.as_ptr(), MU.as_ptr(), null_mut()),
        CADMM_ERR_NULL_POINTER
    );
    // colptr is always required, rowind/values when there are entries.
    for k in 0..3 {
        let mut bad = m.c();
        match k {
            0 => bad.colptr = null(),
            1 => bad.rowind = null(),
            _ => bad.values = null(),
        }
        let mut out = sentinel();
        let rc = new_global(&bad, &hc, F.as_ptr(), W0.as_ptr(), MU.as_ptr(), &mut out);
        assert_eq!(rc, CADMM_ERR_NULL_POINTER, "case {k}");
        assert_eq!(out, sentinel());
    }
    // Zero-length arrays may be NULL: no contact, an empty H (3 x 0).
    let h0 = Csc::new(3, 0, &[0], &[], &[]);
    let mut p0 = null_mut();
    let rc = unsafe {
        cadmm_problem_new_global(3, 0, &mc, &h0.c(), F.as_ptr(), null(), null(), &mut p0)
    };
    assert_eq!(rc, CADMM_OK);
    unsafe { cadmm_problem_free(p0) };

    // Local.
    let w = Csc::eye(3);
    let q = [-1.0, 0.0, 0.0];
    unsafe {
        let mut out = sentinel();
        assert_eq!(
            cadmm_problem_new_local(1, null(), q.as_ptr(), MU.as_ptr(), &mut out),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_new_local(1, &w.c(), null(), MU.as_ptr(), &mut out),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_new_local(1, &w.c(), q.as_ptr(), null(), &mut out),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_new_local(1, &w.c(), q.as_ptr(), MU.as_ptr(), null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(out, sentinel());
    }

    // Problem functions.
    let p = global_problem();
    let mut e = 0.0;
    let r = [0.0; 3];
    let (mut n, mut nc, mut g) = (0, 0, false);
    unsafe {
        assert_eq!(
            cadmm_problem_set_joints(null_mut(), &mc, F.as_ptr()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_set_joints(p, null(), F.as_ptr()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_set_joints(p, &mc, null()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_error(null(), r.as_ptr(), null(), r.as_ptr(), &mut e),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_error(p, null(), null(), r.as_ptr(), &mut e),
            CADMM_ERR_NULL_POINTER
        );
        // v is required for a global problem.
        assert_eq!(
            cadmm_problem_error(p, r.as_ptr(), null(), null(), &mut e),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_error(p, r.as_ptr(), null(), r.as_ptr(), null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_dims(null(), &mut n, &mut nc, &mut g),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_dims(p, null_mut(), &mut nc, &mut g),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_dims(p, &mut n, null_mut(), &mut g),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_dims(p, &mut n, &mut nc, null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!((n, nc, g), (0, 0, false));
        let mut out = sentinel();
        assert_eq!(
            cadmm_problem_read_fclib(null(), &mut out),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_problem_read_fclib(cstr(c"x.hdf5"), null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(out, sentinel());
        assert_eq!(
            cadmm_problem_write_fclib(null(), cstr(c"x.hdf5")),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(cadmm_problem_write_fclib(p, null()), CADMM_ERR_NULL_POINTER);
    }

    // Settings functions.
    let s = settings();
    unsafe {
        assert_eq!(cadmm_settings_new(null_mut()), CADMM_ERR_NULL_POINTER);
        let ns = null_mut();
        assert_eq!(
            cadmm_settings_set_variant(ns, cstr(c"auto")),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_variant(s, null()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_initial_rho(ns, cstr(c"normal"), 0.0),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_initial_rho(s, null(), 1.0),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_tolerance(ns, 1e-6),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_max_iterations(ns, 10),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_time_limit(ns, 1.0),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(cadmm_settings_set_anderson(ns, 3), CADMM_ERR_NULL_POINTER);
        assert_eq!(
            cadmm_settings_set_s_update(ns, cstr(c"internal")),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_settings_set_s_update(s, null()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(cadmm_settings_set_trace(ns, true), CADMM_ERR_NULL_POINTER);
    }

    // Solver functions.
    unsafe {
        let mut out = sentinel();
        assert_eq!(
            cadmm_solver_new(null(), s, &mut out),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_solver_new(p, null(), &mut out),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(cadmm_solver_new(p, s, null_mut()), CADMM_ERR_NULL_POINTER);
        assert_eq!(out, sentinel());
        let sv = solver(p, s);
        let mut status = 0;
        let mut st = cadmm_stats {
            struct_size: size_of::<cadmm_stats>(),
            ..Default::default()
        };
        let mut tp = cadmm_trace_point::default();
        let nsv = null_mut();
        assert_eq!(cadmm_solver_update(nsv, p), CADMM_ERR_NULL_POINTER);
        assert_eq!(cadmm_solver_update(sv, null()), CADMM_ERR_NULL_POINTER);
        assert_eq!(
            cadmm_solver_warm_start(nsv, r.as_ptr(), null()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_solver_warm_start(sv, null(), null()),
            CADMM_ERR_NULL_POINTER
        );
        assert!(last_error(sv).contains("r is NULL"), "{}", last_error(sv));
        assert_eq!(cadmm_solver_solve(nsv, &mut status), CADMM_ERR_NULL_POINTER);
        assert_eq!(cadmm_solver_solve(sv, null_mut()), CADMM_ERR_NULL_POINTER);
        assert!(last_error(sv).contains("status"));
        assert_eq!(
            cadmm_solver_get_solution(null(), null_mut(), null_mut(), null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_solver_get_stats(null(), &mut st),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_solver_get_stats(sv, null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_solver_get_trace(null(), 0, &mut tp),
            CADMM_ERR_NULL_POINTER
        );
        assert_eq!(
            cadmm_solver_get_trace(sv, 0, null_mut()),
            CADMM_ERR_NULL_POINTER
        );
        // The solver still works after all that.
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

/// Builds the single-contact global problem with replaced pieces; returns the code and
/// checks `*out` was left untouched on failure.
fn try_global(n: usize, nc: usize, m: &Csc, h: &Csc, f: &[f64], w: &[f64], mu: &[f64]) -> i32 {
    let mut out = sentinel();
    let rc = unsafe {
        cadmm_problem_new_global(
            n,
            nc,
            &m.c(),
            &h.c(),
            f.as_ptr(),
            w.as_ptr(),
            mu.as_ptr(),
            &mut out,
        )
    };
    if rc == CADMM_OK {
        unsafe { cadmm_problem_free(out) };
    } else {
        assert_eq!(out, sentinel());
    }
    rc
}

#[test]
fn wrong_dimensions() {
    let (m, h) = (Csc::eye(3), Csc::eye(3));
    let f4 = [0.0; 4];
    let w6 = [0.0; 6];
    // n disagrees with M.
    assert_eq!(try_global(4, 1, &m, &h, &f4, &W0, &MU), CADMM_ERR_DIMENSION);
    // H has 3 columns, 2 contacts need 6.
    assert_eq!(
        try_global(3, 2, &m, &h, &F, &w6, &[0.5, 0.5]),
        CADMM_ERR_DIMENSION
    );
    // M not square.
    let m32 = Csc::new(3, 2, &[0, 1, 2], &[0, 1], &[1.0, 1.0]);
    assert_eq!(
        try_global(3, 1, &m32, &h, &F, &W0, &MU),
        CADMM_ERR_DIMENSION
    );
    // H with the wrong number of rows.
    let h23 = Csc::new(2, 3, &[0, 1, 2, 2], &[0, 1], &[1.0, 1.0]);
    assert_eq!(
        try_global(3, 1, &m, &h23, &F, &W0, &MU),
        CADMM_ERR_DIMENSION
    );
    // n_contacts so large that 3 n_contacts overflows.
    assert_eq!(
        try_global(3, usize::MAX / 2, &m, &h, &F, &W0, &MU),
        CADMM_ERR_DIMENSION
    );
    // Local: W is 3 x 3 but two contacts need 6 x 6.
    let mut out = sentinel();
    let rc = unsafe {
        cadmm_problem_new_local(
            2,
            &Csc::eye(3).c(),
            w6.as_ptr(),
            [0.5, 0.5].as_ptr(),
            &mut out,
        )
    };
    assert_eq!(rc, CADMM_ERR_DIMENSION);
    assert_eq!(out, sentinel());
    // Joints: G must have n rows.
    let p = global_problem();
    let g = Csc::new(2, 1, &[0, 1], &[0], &[1.0]);
    assert_eq!(
        unsafe { cadmm_problem_set_joints(p, &g.c(), [0.0].as_ptr()) },
        CADMM_ERR_DIMENSION
    );
    unsafe { cadmm_problem_free(p) };
}

#[test]
fn corrupt_csc() {
    let h = Csc::eye(3);
    let cases = [
        (
            "decreasing colptr",
            Csc::new(3, 3, &[0, 2, 1, 3], &[0, 1, 2], &[1.0; 3]),
        ),
        (
            "colptr[0] != 0",
            Csc::new(3, 3, &[1, 1, 2, 3], &[0, 1, 2], &[1.0; 3]),
        ),
        (
            "negative colptr",
            Csc::new(3, 3, &[0, -1, 2, 3], &[0, 1, 2], &[1.0; 3]),
        ),
        (
            "row out of range",
            Csc::new(3, 3, &[0, 1, 2, 3], &[0, 3, 2], &[1.0; 3]),
        ),
        (
            "negative row",
            Csc::new(3, 3, &[0, 1, 2, 3], &[0, -1, 2], &[1.0; 3]),
        ),
        (
            "duplicate",
            Csc::new(3, 3, &[0, 1, 3, 4], &[0, 1, 1, 2], &[1.0; 4]),
        ),
    ];
    for (what, m) in &cases {
        assert_eq!(
            try_global(3, 1, m, &h, &F, &W0, &MU),
            CADMM_ERR_INVALID_CSC,
            "{what}"
        );
    }
    // The same checks guard W and G.
    let mut out = sentinel();
    let rc =
        unsafe { cadmm_problem_new_local(1, &cases[0].1.c(), F.as_ptr(), MU.as_ptr(), &mut out) };
    assert_eq!(rc, CADMM_ERR_INVALID_CSC);
    assert_eq!(out, sentinel());
    let p = global_problem();
    let g = Csc::new(3, 1, &[0, 2], &[1, 1], &[1.0, 1.0]);
    assert_eq!(
        unsafe { cadmm_problem_set_joints(p, &g.c(), [0.0].as_ptr()) },
        CADMM_ERR_INVALID_CSC
    );
    unsafe { cadmm_problem_free(p) };
}

#[test]
fn invalid_values() {
    let (m, h) = (Csc::eye(3), Csc::eye(3));
    assert_eq!(
        try_global(3, 1, &m, &h, &[f64::NAN, 0.0, 0.0], &W0, &MU),
        CADMM_ERR_INVALID_VALUE
    );
    assert_eq!(
        try_global(3, 1, &m, &h, &F, &[0.0, f64::INFINITY, 0.0], &MU),
        CADMM_ERR_INVALID_VALUE
    );
    assert_eq!(
        try_global(3, 1, &m, &h, &F, &W0, &[-0.5]),
        CADMM_ERR_INVALID_VALUE
    );
    assert_eq!(
        try_global(3, 1, &m, &h, &F, &W0, &[f64::NAN]),
        CADMM_ERR_INVALID_VALUE
    );
    let m_nan = Csc::diag(&[1.0, f64::NAN, 1.0]);
    assert_eq!(
        try_global(3, 1, &m_nan, &h, &F, &W0, &MU),
        CADMM_ERR_INVALID_VALUE
    );
    let mut out = sentinel();
    let rc = unsafe {
        cadmm_problem_new_local(1, &Csc::eye(3).c(), F.as_ptr(), [-1.0].as_ptr(), &mut out)
    };
    assert_eq!(rc, CADMM_ERR_INVALID_VALUE);
    assert_eq!(out, sentinel());
}

#[test]
fn indefinite_mass_matrix_fails_at_solver_new() {
    let (m, h) = (Csc::diag(&[1.0, -1.0, 1.0]), Csc::eye(3));
    let mut p = null_mut();
    let rc = unsafe {
        cadmm_problem_new_global(
            3,
            1,
            &m.c(),
            &h.c(),
            F.as_ptr(),
            W0.as_ptr(),
            MU.as_ptr(),
            &mut p,
        )
    };
    assert_eq!(rc, CADMM_OK);
    let s = settings();
    let mut out = sentinel();
    assert_eq!(
        unsafe { cadmm_solver_new(p, s, &mut out) },
        CADMM_ERR_NOT_POSITIVE_DEFINITE
    );
    assert_eq!(out, sentinel());
    unsafe {
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn settings_are_validated_on_set() {
    let s = settings();
    let get = || unsafe { (*s).settings().clone() };
    let defaults = get();
    unsafe {
        assert_eq!(cadmm_settings_set_variant(s, cstr(c"auto")), CADMM_OK);
        for name in [
            "cp-N",
            "cp-R",
            "cp-RR",
            "vp-N-He",
            "vp-R-He",
            "vp-RR-He",
            "vp-N-Wohlberg",
            "vp-R-Wohlberg",
            "vp-RR-Wohlberg",
            "vp-N-Spectral",
            "vp-R-Spectral",
            "vp-RR-Spectral",
        ] {
            let c = std::ffi::CString::new(name).unwrap();
            assert_eq!(
                cadmm_settings_set_variant(s, c.as_ptr()),
                CADMM_OK,
                "{name}"
            );
        }
        let before = get();
        for bad in [c"", c"Auto", c"cp-X", c"vp-N", c"vp-N-He-x"] {
            assert_eq!(
                cadmm_settings_set_variant(s, bad.as_ptr()),
                CADMM_ERR_INVALID_SETTING,
                "{bad:?}"
            );
        }
        let not_utf8 = [0xffu8 as c_char, 0];
        assert_eq!(
            cadmm_settings_set_variant(s, not_utf8.as_ptr()),
            CADMM_ERR_INVALID_SETTING
        );
        assert_eq!(get(), before);

        assert_eq!(cadmm_settings_set_tolerance(s, 1e-6), CADMM_OK);
        for bad in [0.0, -1e-6, f64::NAN, f64::INFINITY] {
            assert_eq!(
                cadmm_settings_set_tolerance(s, bad),
                CADMM_ERR_INVALID_SETTING,
                "{bad}"
            );
            assert_eq!(get().tolerance, 1e-6);
        }

        assert_eq!(cadmm_settings_set_max_iterations(s, 7), CADMM_OK);
        assert_eq!(
            cadmm_settings_set_max_iterations(s, 0),
            CADMM_ERR_INVALID_SETTING
        );
        assert_eq!(get().max_iterations, 7);

        assert_eq!(cadmm_settings_set_time_limit(s, f64::INFINITY), CADMM_OK);
        assert_eq!(cadmm_settings_set_time_limit(s, 2.5), CADMM_OK);
        for bad in [0.0, -1.0, f64::NAN] {
            assert_eq!(
                cadmm_settings_set_time_limit(s, bad),
                CADMM_ERR_INVALID_SETTING
            );
        }
        assert_eq!(get().time_limit, 2.5);

        assert_eq!(cadmm_settings_set_anderson(s, 0), CADMM_OK);
        assert_eq!(get().anderson, Some(0));
        assert_eq!(cadmm_settings_set_anderson(s, 64), CADMM_OK);
        assert_eq!(
            cadmm_settings_set_anderson(s, 65),
            CADMM_ERR_INVALID_SETTING
        );
        assert_eq!(
            cadmm_settings_set_anderson(s, u32::MAX),
            CADMM_ERR_INVALID_SETTING
        );
        assert_eq!(get().anderson, Some(64));

        for rule in [c"normal", c"acary", c"ghadimi", c"dicairano"] {
            assert_eq!(
                cadmm_settings_set_initial_rho(s, rule.as_ptr(), 0.0),
                CADMM_OK
            );
        }
        assert_eq!(
            cadmm_settings_set_initial_rho(s, cstr(c"given"), 3.0),
            CADMM_OK
        );
        let before = get();
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert_eq!(
                cadmm_settings_set_initial_rho(s, cstr(c"given"), bad),
                CADMM_ERR_INVALID_SETTING
            );
        }
        assert_eq!(
            cadmm_settings_set_initial_rho(s, cstr(c"best"), 1.0),
            CADMM_ERR_INVALID_SETTING
        );
        assert_eq!(get(), before);

        assert_eq!(cadmm_settings_set_s_update(s, cstr(c"external")), CADMM_OK);
        assert_eq!(get().s_update, cadmm::SUpdate::External);
        assert_eq!(cadmm_settings_set_s_update(s, cstr(c"internal")), CADMM_OK);
        assert_eq!(
            cadmm_settings_set_s_update(s, cstr(c"sometimes")),
            CADMM_ERR_INVALID_SETTING
        );
        assert_eq!(get().s_update, cadmm::SUpdate::Internal);

        assert_eq!(cadmm_settings_set_trace(s, true), CADMM_OK);
        assert!(get().trace);
        assert_ne!(get(), defaults);
        cadmm_settings_free(s);
    }
}

#[test]
fn iteration_limit_is_a_status_not_an_error() {
    let p = global_problem();
    let s = settings();
    unsafe {
        assert_eq!(cadmm_settings_set_max_iterations(s, 1), CADMM_OK);
        assert_eq!(cadmm_settings_set_tolerance(s, 1e-14), CADMM_OK);
        // A rejected value leaves the limit of 1 in place.
        assert_eq!(
            cadmm_settings_set_max_iterations(s, 0),
            CADMM_ERR_INVALID_SETTING
        );
    }
    let sv = solver(p, s);
    let mut status = -1;
    assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
    assert_eq!(status, CADMM_STATUS_MAX_ITERATIONS);
    let st = full_stats(sv);
    assert_eq!(st.status, CADMM_STATUS_MAX_ITERATIONS);
    assert_eq!(st.iterations, 1);
    unsafe {
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn fclib_files() {
    let mut out = sentinel();
    let rc = unsafe { cadmm_problem_read_fclib(cstr(c"/nonexistent/dir/missing.hdf5"), &mut out) };
    assert_eq!(out, sentinel());
    if cfg!(feature = "fclib") {
        assert_eq!(rc, CADMM_ERR_IO);
    } else {
        assert_eq!(rc, CADMM_ERR_UNSUPPORTED);
    }
    let p = global_problem();
    let dir = std::env::temp_dir().join(format!("cadmm-ffi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("one_contact.hdf5");
    let cfile = std::ffi::CString::new(file.to_str().unwrap()).unwrap();
    let rc = unsafe { cadmm_problem_write_fclib(p, cfile.as_ptr()) };
    if cfg!(feature = "fclib") {
        assert_eq!(rc, CADMM_OK);
        let mut back = null_mut();
        assert_eq!(
            unsafe { cadmm_problem_read_fclib(cfile.as_ptr(), &mut back) },
            CADMM_OK
        );
        assert_eq!(unsafe { (*back).problem() }, unsafe { (*p).problem() });
        unsafe { cadmm_problem_free(back) };
        let bad = dir.join("no/such/dir/x.hdf5");
        let cbad = std::ffi::CString::new(bad.to_str().unwrap()).unwrap();
        assert_eq!(
            unsafe { cadmm_problem_write_fclib(p, cbad.as_ptr()) },
            CADMM_ERR_IO
        );
    } else {
        assert_eq!(rc, CADMM_ERR_UNSUPPORTED);
    }
    let _ = std::fs::remove_dir_all(&dir);
    unsafe { cadmm_problem_free(p) };
}

#[test]
fn stats_struct_size() {
    let p = global_problem();
    let s = settings();
    let sv = solver(p, s);
    let mut status = 0;
    assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
    let full = full_stats(sv);
    let min = offset_of!(cadmm_stats, anderson_accepted);

    // Too small: refused, nothing written.
    for size in [0, 1, size_of::<usize>(), min - 1] {
        let mut st = cadmm_stats {
            struct_size: size,
            iterations: 12345,
            ..Default::default()
        };
        assert_eq!(
            unsafe { cadmm_solver_get_stats(sv, &mut st) },
            CADMM_ERR_INVALID_VALUE,
            "{size}"
        );
        assert_eq!((st.struct_size, st.iterations), (size, 12345));
    }
    assert!(last_error(sv).contains("struct_size"));

    // An older, shorter struct: the fields past its end are not written.
    let mut st = cadmm_stats {
        struct_size: min,
        anderson_accepted: 777,
        anderson_rejected: 888,
        ..Default::default()
    };
    assert_eq!(unsafe { cadmm_solver_get_stats(sv, &mut st) }, CADMM_OK);
    assert_eq!((st.anderson_accepted, st.anderson_rejected), (777, 888));
    assert_eq!(st.struct_size, min);
    assert_eq!(st.status, full.status);
    assert_eq!(st.iterations, full.iterations);
    assert_eq!(st.error, full.error);
    assert_eq!(st.solve_seconds, full.solve_seconds);

    // Half a field fits: it is not written.
    let mut st = cadmm_stats {
        struct_size: min + 4,
        anderson_accepted: 777,
        ..Default::default()
    };
    assert_eq!(unsafe { cadmm_solver_get_stats(sv, &mut st) }, CADMM_OK);
    assert_eq!(st.anderson_accepted, 777);

    // A newer, longer struct: the bytes past ours are not touched.
    #[repr(C)]
    struct Newer {
        stats: cadmm_stats,
        extra: [u64; 2],
    }
    let mut newer = Newer {
        stats: cadmm_stats {
            struct_size: size_of::<Newer>(),
            ..Default::default()
        },
        extra: [0xdead, 0xbeef],
    };
    assert_eq!(
        unsafe { cadmm_solver_get_stats(sv, &mut newer.stats) },
        CADMM_OK
    );
    assert_eq!(newer.extra, [0xdead, 0xbeef]);
    assert_eq!(newer.stats.struct_size, size_of::<Newer>());
    assert_eq!(newer.stats.iterations, full.iterations);
    assert_eq!(newer.stats.anderson_rejected, full.anderson_rejected);

    unsafe {
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn problem_error_agrees_with_the_measure() {
    use cadmm::measure::problem_error;
    // Global, two contacts, non-trivial M and H, and candidate solutions that are off.
    let m = Csc::new(
        3,
        3,
        &[0, 2, 4, 5],
        &[0, 1, 0, 1, 2],
        &[2.0, 0.5, 0.5, 1.5, 1.0],
    );
    let h = Csc::new(
        3,
        6,
        &[0, 1, 2, 3, 5, 6, 7],
        &[0, 1, 2, 0, 1, 1, 2],
        &[1.0, 1.0, 1.0, 0.5, 1.0, 1.0, 1.0],
    );
    let f = [-9.81, 0.3, -0.2];
    let w = [0.0, 0.1, 0.0, -0.05, 0.0, 0.2];
    let mu = [0.3, 0.8];
    let mut p = null_mut();
    let rc = unsafe {
        cadmm_problem_new_global(
            3,
            2,
            &m.c(),
            &h.c(),
            f.as_ptr(),
            w.as_ptr(),
            mu.as_ptr(),
            &mut p,
        )
    };
    assert_eq!(rc, CADMM_OK);
    let candidates = [
        ([1.0, 0.2, -0.1, 2.0, 0.0, 0.3], [0.1, -0.2, 0.05]),
        ([0.0; 6], [0.0; 3]),
        ([5.0, 1.0, 1.0, 4.0, -2.0, 0.5], [-1.0, 2.0, 0.5]),
    ];
    for (r, v) in &candidates {
        let mut e = f64::NAN;
        let rc = unsafe { cadmm_problem_error(p, r.as_ptr(), null(), v.as_ptr(), &mut e) };
        assert_eq!(rc, CADMM_OK);
        let expected = problem_error(unsafe { (*p).problem() }, r, v, &[]);
        assert_eq!(e, expected);
        assert!(e.is_finite() && e > 0.0);
    }
    // A non-finite candidate is measured, not refused.
    let mut e = 0.0;
    let r = [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0];
    let rc = unsafe { cadmm_problem_error(p, r.as_ptr(), null(), [0.0; 3].as_ptr(), &mut e) };
    assert_eq!(rc, CADMM_OK);
    assert_eq!(e, f64::INFINITY);

    // The solver's solution measured both ways.
    let s = settings();
    let sv = solver(p, s);
    let mut status = -1;
    assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
    assert_eq!(status, CADMM_STATUS_SOLVED);
    let (mut r, mut u, mut v) = ([0.0; 6], [0.0; 6], [0.0; 3]);
    unsafe { cadmm_solver_get_solution(sv, r.as_mut_ptr(), u.as_mut_ptr(), v.as_mut_ptr()) };
    let mut e = f64::NAN;
    let rc = unsafe { cadmm_problem_error(p, r.as_ptr(), u.as_ptr(), v.as_ptr(), &mut e) };
    assert_eq!(rc, CADMM_OK);
    assert_eq!(e, problem_error(unsafe { (*p).problem() }, &r, &v, &[]));
    assert!(e <= 1e-8, "{e}");
    unsafe {
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }

    // Local.
    let p = local_problem();
    for r in [[0.5, 0.1, 0.0], [1.0, -0.2, 0.0], [0.0; 3]] {
        let mut e = f64::NAN;
        let rc = unsafe { cadmm_problem_error(p, r.as_ptr(), null(), null(), &mut e) };
        assert_eq!(rc, CADMM_OK);
        assert_eq!(e, problem_error(unsafe { (*p).problem() }, &r, &[], &[]));
    }
    unsafe { cadmm_problem_free(p) };
}

#[test]
fn trace_points() {
    let p = global_problem();
    let s = settings();
    assert_eq!(unsafe { cadmm_settings_set_trace(s, true) }, CADMM_OK);
    // ADMM alone: one trace point per iteration from the first (a small problem would
    // otherwise start with a Newton phase, one point for all its steps).
    assert_eq!(unsafe { cadmm_settings_set_newton(s, false) }, CADMM_OK);
    let sv = solver(p, s);
    let mut status = -1;
    assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
    let len = unsafe { cadmm_solver_trace_len(sv) };
    assert!(len > 0);
    let mut tp = cadmm_trace_point::default();
    assert_eq!(unsafe { cadmm_solver_get_trace(sv, 0, &mut tp) }, CADMM_OK);
    assert_eq!(tp.iteration, 1);
    assert!(tp.rho > 0.0 && tp.seconds >= 0.0);
    assert_eq!(
        unsafe { cadmm_solver_get_trace(sv, len - 1, &mut tp) },
        CADMM_OK
    );
    assert_eq!(tp.iteration, full_stats(sv).iterations);
    let before = tp;
    assert_eq!(
        unsafe { cadmm_solver_get_trace(sv, len, &mut tp) },
        CADMM_ERR_INVALID_VALUE
    );
    assert_eq!(tp.iteration, before.iteration);
    assert!(
        last_error(sv).contains("out of range"),
        "{}",
        last_error(sv)
    );
    unsafe {
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

/// The same global problem with another f and M scaled by `mass`.
fn global_problem_with(mass: [f64; 3], f: [f64; 3]) -> *mut cadmm_problem {
    let (m, h) = (Csc::diag(&mass), Csc::eye(3));
    let mut p = null_mut();
    let rc = unsafe {
        cadmm_problem_new_global(
            3,
            1,
            &m.c(),
            &h.c(),
            f.as_ptr(),
            W0.as_ptr(),
            MU.as_ptr(),
            &mut p,
        )
    };
    assert_eq!(rc, CADMM_OK);
    p
}

#[test]
fn update_and_warm_start() {
    let p = global_problem();
    let s = settings();
    let sv = solver(p, s);
    let mut status = -1;
    unsafe {
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);

        // Next step: same pattern, new values. Exact answer: the mass rests and sticks
        // (|f_T| = 1 <= mu |f_N|), v = 0 and r = -f.
        let p2 = global_problem_with([2.0, 2.0, 2.0], [-9.0, 1.0, 0.0]);
        assert_eq!(cadmm_solver_update(sv, p2), CADMM_OK);
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);
        let cold = full_stats(sv).iterations;
        let (mut r, mut v) = ([0.0; 3], [0.0; 3]);
        cadmm_solver_get_solution(sv, r.as_mut_ptr(), null_mut(), v.as_mut_ptr());
        for (i, exact) in [9.0, -1.0, 0.0].into_iter().enumerate() {
            assert!((r[i] - exact).abs() < 1e-6, "r = {r:?}");
            assert!(v[i].abs() < 1e-7, "v = {v:?}");
        }
        let mut e = f64::NAN;
        assert_eq!(
            cadmm_problem_error(p2, r.as_ptr(), null(), v.as_ptr(), &mut e),
            CADMM_OK
        );
        assert!(e <= 1e-8, "{e}");

        // Warm start from the solution of the same problem: fewer iterations than the
        // cold solve of that problem.
        assert_eq!(
            cadmm_solver_warm_start(sv, r.as_ptr(), v.as_ptr()),
            CADMM_OK
        );
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);
        let warm = full_stats(sv).iterations;
        assert!(warm < cold, "warm {warm} iterations, cold {cold}");
        // v may be NULL.
        assert_eq!(cadmm_solver_warm_start(sv, r.as_ptr(), null()), CADMM_OK);
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        // Non-finite warm starts are refused.
        let bad = [f64::NAN, 0.0, 0.0];
        assert_eq!(
            cadmm_solver_warm_start(sv, bad.as_ptr(), null()),
            CADMM_ERR_INVALID_VALUE
        );
        assert_eq!(
            cadmm_solver_warm_start(sv, r.as_ptr(), bad.as_ptr()),
            CADMM_ERR_INVALID_VALUE
        );
        assert!(last_error(sv).contains('v'), "{}", last_error(sv));

        // A problem of the other form: refused, the solver still works.
        let local = local_problem();
        assert_eq!(cadmm_solver_update(sv, local), CADMM_ERR_UNSUPPORTED);
        // Other sizes.
        let (m4, h4) = (
            Csc::eye(4),
            Csc::new(4, 3, &[0, 1, 2, 3], &[0, 1, 2], &[1.0; 3]),
        );
        let mut p4 = null_mut();
        let rc = cadmm_problem_new_global(
            4,
            1,
            &m4.c(),
            &h4.c(),
            [0.0; 4].as_ptr(),
            W0.as_ptr(),
            MU.as_ptr(),
            &mut p4,
        );
        assert_eq!(rc, CADMM_OK);
        assert_eq!(cadmm_solver_update(sv, p4), CADMM_ERR_DIMENSION);
        assert_eq!(cadmm_solver_update(sv, p), CADMM_OK);
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);

        // An indefinite M with the same pattern: the update is refused and changes nothing:
        // the solver solves the problem it held, and an update of f alone (M kept) is taken.
        let bad_m = global_problem_with([1.0, -1.0, 1.0], F);
        assert_eq!(
            cadmm_solver_update(sv, bad_m),
            CADMM_ERR_NOT_POSITIVE_DEFINITE
        );
        assert!(last_error(sv).contains("positive definite"));
        status = 42;
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);
        let mut r2 = [0.0; 3];
        assert_eq!(
            cadmm_solver_get_solution(sv, r2.as_mut_ptr(), null_mut(), null_mut()),
            CADMM_OK
        );
        assert!((r2[0] - 9.81).abs() < 1e-6);
        assert_eq!(cadmm_solver_warm_start(sv, r.as_ptr(), null()), CADMM_OK);
        let f2 = [2.0 * F[0], F[1], F[2]];
        assert_eq!(
            cadmm_solver_update_values(
                sv,
                null(),
                null(),
                null(),
                f2.as_ptr(),
                null(),
                null(),
                null()
            ),
            CADMM_OK,
            "{}",
            last_error(sv)
        );
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);
        assert_eq!(
            cadmm_solver_get_solution(sv, r2.as_mut_ptr(), null_mut(), null_mut()),
            CADMM_OK
        );
        assert!((r2[0] - 2.0 * 9.81).abs() < 1e-6, "{r2:?}");
        assert_eq!(cadmm_solver_update(sv, p), CADMM_OK);
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED);

        for q in [p2, local, p4, bad_m] {
            cadmm_problem_free(q);
        }
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn joints() {
    unsafe {
        // A local problem has no joints.
        let local = local_problem();
        let g = Csc::new(3, 1, &[0, 1], &[1], &[1.0]);
        assert_eq!(
            cadmm_problem_set_joints(local, &g.c(), [0.0].as_ptr()),
            CADMM_ERR_UNSUPPORTED
        );
        cadmm_problem_free(local);

        // Pushed sideways with the tangential velocity held at 0.1 by a joint:
        // G = e_1, b = -0.1, so v_1 = 0.1 and the contact slides.
        let p = global_problem_with([1.0; 3], [-9.81, 1.0, 0.0]);
        assert_eq!(
            cadmm_problem_set_joints(p, &g.c(), [f64::NAN].as_ptr()),
            CADMM_ERR_INVALID_VALUE
        );
        let same = global_problem_with([1.0; 3], [-9.81, 1.0, 0.0]);
        assert!(
            (*p).problem() == (*same).problem(),
            "unchanged after a failure"
        );
        cadmm_problem_free(same);
        assert_eq!(
            cadmm_problem_set_joints(p, &g.c(), [-0.1].as_ptr()),
            CADMM_OK
        );
        // Exact answer: v = (0, 0.1, 0), sliding along T1, so friction sits on the cone's
        // edge against the motion, r = (9.81, -0.5 * 9.81, 0), and the joint carries the rest
        // of the tangential balance 0.1 = r_1 + lambda + f_1: lambda = 0.1 + 4.905 - 1.
        let (r_exact, v_exact, lambda_exact) = ([9.81, -4.905, 0.0], [0.0, 0.1, 0.0], 4.005);
        let s = settings();
        let sv = solver(p, s);
        let mut status = -1;
        assert_eq!(cadmm_solver_solve(sv, &mut status), CADMM_OK);
        assert_eq!(status, CADMM_STATUS_SOLVED, "{:?}", full_stats(sv));
        let (mut r, mut v, mut lambda, mut np) = ([0.0; 3], [0.0; 3], [0.0; 1], 0usize);
        cadmm_solver_get_solution(sv, r.as_mut_ptr(), null_mut(), v.as_mut_ptr());
        assert_eq!(
            cadmm_solver_get_joint_multipliers(sv, lambda.as_mut_ptr(), &mut np),
            CADMM_OK
        );
        assert_eq!(np, 1);
        for i in 0..3 {
            assert!((v[i] - v_exact[i]).abs() < 1e-7, "v = {v:?}");
            assert!((r[i] - r_exact[i]).abs() < 1e-6, "r = {r:?}");
        }
        assert!(
            (lambda[0] - lambda_exact).abs() < 1e-6,
            "lambda = {lambda:?}"
        );
        // The C API's measure (multipliers recomputed by least squares) accepts the answer
        // and the exact one, and rejects a perturbed one.
        let error = |r: &[f64; 3], v: &[f64; 3]| {
            let mut e = -1.0;
            assert_eq!(
                cadmm_problem_error(p, r.as_ptr(), null(), v.as_ptr(), &mut e),
                CADMM_OK
            );
            e
        };
        assert!(error(&r, &v) <= 1e-8, "{}", error(&r, &v));
        assert!(error(&r_exact, &v_exact) <= 1e-12);
        assert!(error(&r_exact, &[0.0, 0.2, 0.0]) > 1e-3);
        assert!(error(&[9.81, -4.0, 0.0], &v_exact) > 1e-3);
        cadmm_solver_free(sv);
        cadmm_settings_free(s);

        // A G with no column removes the joints.
        let g0 = Csc::new(3, 0, &[0], &[], &[]);
        assert_eq!(cadmm_problem_set_joints(p, &g0.c(), null()), CADMM_OK);
        match (*p).problem() {
            cadmm::Problem::Global(g) => assert!(g.joints.is_none()),
            _ => unreachable!(),
        }
        cadmm_problem_free(p);
    }
}

#[test]
fn solvers_in_threads_share_a_problem_read_only() {
    let p = global_problem();
    let s = settings();
    // Raw pointers are not Send; the thread rule of the header makes this sharing valid.
    let (pa, sa) = (p as usize, s as usize);
    let handles: Vec<_> = (0..4)
        .map(|_| {
            std::thread::spawn(move || {
                let (p, s) = (pa as *const cadmm_problem, sa as *const cadmm_settings);
                let sv = solver(p, s);
                let mut status = -1;
                assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
                let mut r = [0.0; 3];
                unsafe {
                    cadmm_solver_get_solution(sv, r.as_mut_ptr(), null_mut(), null_mut());
                    cadmm_solver_free(sv);
                }
                (status, r[0])
            })
        })
        .collect();
    for h in handles {
        let (status, r0) = h.join().unwrap();
        assert_eq!(status, CADMM_STATUS_SOLVED);
        assert!((r0 - 9.81).abs() < 1e-6);
    }
    unsafe {
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
}

#[test]
fn misaligned_arrays_are_refused() {
    let (m, h) = (Csc::eye(3), Csc::eye(3));
    let buf = [0.0f64; 4];
    let misaligned = unsafe { buf.as_ptr().cast::<u8>().add(1).cast::<f64>() };
    let mut out = sentinel();
    let rc = unsafe {
        cadmm_problem_new_global(
            3,
            1,
            &m.c(),
            &h.c(),
            misaligned,
            W0.as_ptr(),
            MU.as_ptr(),
            &mut out,
        )
    };
    assert_eq!(rc, CADMM_ERR_INVALID_VALUE);
    assert_eq!(out, sentinel());
}

/// No contacts: every initial-rho rule is defined (the spectral ones have no spectrum to
/// read) and the solve returns at once with an empty solution, for both forms.
#[test]
fn zero_contacts_solve_with_every_initial_rule() {
    let w = Csc::new(0, 0, &[0], &[], &[]);
    let (m, h) = (Csc::eye(2), Csc::new(2, 0, &[0], &[], &[]));
    let f = [1.0, -2.0];
    let (mut local, mut global) = (null_mut(), null_mut());
    unsafe {
        let rc = cadmm_problem_new_local(0, &w.c(), null(), null(), &mut local);
        assert_eq!(rc, CADMM_OK);
        let rc = cadmm_problem_new_global(
            2,
            0,
            &m.c(),
            &h.c(),
            f.as_ptr(),
            null(),
            null(),
            &mut global,
        );
        assert_eq!(rc, CADMM_OK);
    }
    let s = settings();
    for rule in [c"normal", c"acary", c"ghadimi", c"dicairano"] {
        assert_eq!(
            unsafe { cadmm_settings_set_initial_rho(s, rule.as_ptr(), 0.0) },
            CADMM_OK
        );
        for p in [local, global] {
            let sv = solver(p, s);
            let mut status = -1;
            assert_eq!(unsafe { cadmm_solver_solve(sv, &mut status) }, CADMM_OK);
            assert_eq!(status, CADMM_STATUS_SOLVED, "{rule:?}");
            if p == global {
                // v = M^-1 f exactly.
                let mut v = [0.0; 2];
                unsafe { cadmm_solver_get_solution(sv, null_mut(), null_mut(), v.as_mut_ptr()) };
                assert_eq!(v, f, "{rule:?}");
            }
            unsafe { cadmm_solver_free(sv) };
        }
    }
    unsafe {
        cadmm_settings_free(s);
        cadmm_problem_free(local);
        cadmm_problem_free(global);
    }
}

/// This thread's `cadmm_last_error`, owned.
fn thread_error() -> String {
    unsafe { CStr::from_ptr(cadmm_last_error()) }
        .to_str()
        .unwrap()
        .to_owned()
}

/// A matrix that claims `nrows x ncols` over the small arrays of `a` (a lie the library must
/// catch before it reads or allocates by the claim).
fn claiming(a: &Csc, nrows: usize, ncols: usize) -> cadmm_csc {
    cadmm_csc {
        nrows,
        ncols,
        ..a.c()
    }
}

/// Issue 41: sizes that disagree are refused before anything proportional to them is
/// allocated or read (the probe's `n_contacts = 1e12` aborted on copying `w`), and sizes
/// that agree but cannot be allocated give OUT_OF_MEMORY, never an abort.
#[test]
fn huge_claimed_sizes_are_refused_without_aborting() {
    let (m, h) = (Csc::eye(3), Csc::eye(3));
    let nc = 1_000_000_000_000usize;
    let global = |n: usize, nc: usize, m: &cadmm_csc, h: &cadmm_csc| {
        let mut out = sentinel();
        let rc = unsafe {
            cadmm_problem_new_global(n, nc, m, h, F.as_ptr(), W0.as_ptr(), MU.as_ptr(), &mut out)
        };
        assert_eq!(out, sentinel());
        (rc, thread_error())
    };
    let (rc, e) = global(3, nc, &m.c(), &h.c());
    assert_eq!(rc, CADMM_ERR_DIMENSION, "{e}");
    assert!(e.contains("H is 3 x 3"), "{e}");
    let mut out = sentinel();
    let rc =
        unsafe { cadmm_problem_new_local(nc, &Csc::eye(3).c(), F.as_ptr(), MU.as_ptr(), &mut out) };
    assert_eq!(rc, CADMM_ERR_DIMENSION, "{}", thread_error());
    assert!(thread_error().contains("W is 3 x 3"), "{}", thread_error());
    assert_eq!(out, sentinel());
    // A column count of 2^40 against n = 3, in M and in H.
    let wide = 1usize << 40;
    let (rc, e) = global(3, 1, &claiming(&m, 3, wide), &h.c());
    assert_eq!(rc, CADMM_ERR_DIMENSION, "{e}");
    assert!(e.contains("M is 3 x 1099511627776"), "{e}");
    let (rc, e) = global(3, 1, &m.c(), &claiming(&h, 3, wide));
    assert_eq!(rc, CADMM_ERR_DIMENSION, "{e}");
    assert!(e.starts_with("H "), "{e}");
    let (rc, e) = global(3, 1, &m.c(), &claiming(&h, wide, 3));
    assert_eq!(rc, CADMM_ERR_DIMENSION, "{e}");
    // G: n rows, any number of columns.
    let p = global_problem();
    let g = Csc::new(3, 1, &[0, 1], &[0], &[1.0]);
    let rc = unsafe { cadmm_problem_set_joints(p, &claiming(&g, wide, 1), [0.0].as_ptr()) };
    assert_eq!(rc, CADMM_ERR_DIMENSION);
    assert!(thread_error().starts_with("G "), "{}", thread_error());
    unsafe { cadmm_problem_free(p) };
    // Sizes that agree with each other but not with any memory: n = 1e12 with M and H
    // claiming it, 1e12 contacts with H claiming 3e12 columns. The first array the claim
    // sizes (M.colptr, H.colptr) cannot be allocated.
    let n = 1_000_000_000_000usize;
    let (rc, e) = global(n, 1, &claiming(&m, n, n), &claiming(&h, n, 3));
    assert_eq!(rc, CADMM_ERR_OUT_OF_MEMORY, "{e}");
    assert!(e.contains("M.colptr"), "{e}");
    let (rc, e) = global(3, nc, &m.c(), &claiming(&h, 3, 3 * nc));
    assert_eq!(rc, CADMM_ERR_OUT_OF_MEMORY, "{e}");
    assert!(e.contains("H.colptr"), "{e}");
    let rc = unsafe {
        cadmm_problem_new_local(
            nc,
            &claiming(&m, 3 * nc, 3 * nc),
            F.as_ptr(),
            MU.as_ptr(),
            &mut out,
        )
    };
    assert_eq!(rc, CADMM_ERR_OUT_OF_MEMORY, "{}", thread_error());
    // Too large to address at all: a dimension error.
    let huge = usize::MAX / 4;
    let (rc, e) = global(huge, 1, &claiming(&m, huge, huge), &claiming(&h, huge, 3));
    assert_eq!(rc, CADMM_ERR_DIMENSION, "{e}");
}

/// Issue 41: a last column pointer past the entries the arrays hold (3 allocated) was read
/// as a length for `rowind` and `values` (a heap overflow, or a segfault at 1e18). A column
/// holds at most `nrows` entries (duplicates are refused), so such pointers are refused
/// before `rowind` and `values` are read.
#[test]
fn column_pointers_past_the_arrays_are_refused_before_reading_them() {
    let h = Csc::eye(3);
    for (last, what) in [
        (40, "colptr[3] = 40"),
        (1_000_000_000_000_000_000, "colptr[3] = 1e18"),
    ] {
        let m = Csc::new(3, 3, &[0, 1, 2, last], &[0, 1, 2], &[1.0; 3]);
        assert_eq!(
            try_global(3, 1, &m, &h, &F, &W0, &MU),
            CADMM_ERR_INVALID_CSC,
            "{what}"
        );
        let e = thread_error();
        assert!(e.contains("M") && e.contains("at most 9"), "{what}: {e}");
    }
    // Within nrows * ncols in all, but one column with more entries than rows.
    let m = Csc::new(3, 3, &[0, 4, 4, 4], &[0, 1, 2], &[1.0; 3]);
    assert_eq!(
        try_global(3, 1, &m, &h, &F, &W0, &MU),
        CADMM_ERR_INVALID_CSC
    );
    let e = thread_error();
    assert!(e.contains("column 0 holds 4 entries"), "{e}");
}
