//! The C API entry points with fuzzed inputs: arrays of the lengths the header documents,
//! with arbitrary contents (column pointers, indices, NaN...), NULL pointers, arbitrary
//! setting values and names, and a sequence of calls on the solver. Every call must return
//! a result code (never unwind), and the messages must be readable C strings.
//!
//! Now and then one size is a lie ([`Lie`]): `n`, `n_contacts`, a matrix's `nrows` or
//! `ncols`, or its last column pointer is made huge while the arrays stay small. Each lie
//! contradicts another size the call is given (a matrix's shape, `nrows * ncols`), so the
//! library must refuse the call (DIMENSION or INVALID_CSC) before it reads or allocates
//! anything by the lie; the arrays whose length the header ties to the true sizes keep it.
#![no_main]

use cadmm::ffi::*;
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;
use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};

/// Owned arrays behind a `cadmm_csc`.
struct Csc {
    nrows: usize,
    ncols: usize,
    colptr: Vec<i64>,
    rowind: Vec<i64>,
    values: Vec<f64>,
}

impl Csc {
    fn new(u: &mut Unstructured, nrows: usize, ncols: usize) -> Result<Self> {
        let mut colptr = vec![0i64];
        for _ in 0..ncols {
            let step = u.int_in_range(0..=nrows.min(4) as i64)?;
            colptr.push(colptr.last().unwrap() + step);
        }
        if u.ratio(1, 8)? {
            let k = u.choose_index(colptr.len())?;
            colptr[k] = u.int_in_range(-3..=30)?;
        }
        // The arrays have colptr[ncols] entries whenever that is a valid count: the header's
        // contract (the library validates colptr before reading them).
        let nnz = colptr[ncols].clamp(0, 64) as usize;
        let rowind = (0..nnz)
            .map(|_| u.int_in_range(-1..=nrows as i64))
            .collect::<Result<Vec<i64>>>()?;
        let values = (0..nnz).map(|_| float(u)).collect::<Result<Vec<f64>>>()?;
        let mut m = Self {
            nrows,
            ncols,
            colptr,
            rowind,
            values,
        };
        if m.colptr[ncols] > 64 {
            m.colptr[ncols] = -1; // refused before rowind and values are read
        }
        Ok(m)
    }
    fn raw(&self) -> cadmm_csc {
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

/// One size made huge, the arrays left as they are (issue 41: such sizes aborted on an
/// allocation or read past the caller's arrays).
#[derive(Debug, Clone, Copy)]
enum Lie {
    /// `n` passed to `cadmm_problem_new_global` (M and H keep their `n` rows).
    N(usize),
    /// `n_contacts` passed (H or W keep their `3 n_contacts` columns).
    Contacts(usize),
    /// A matrix (0: M or W, 1: H) claims this many rows.
    Rows(usize, usize),
    /// A matrix claims this many columns (its colptr is never read past by the library).
    Cols(usize, usize),
    /// A matrix's last column pointer, beyond `nrows * ncols`, with `rowind` and `values`
    /// as short as before.
    LastPointer(usize, i64),
}

/// A size far beyond any array of the target (at least 2^20), often near the top of the
/// type, where `3 n` or `ncols + 1` overflows.
fn huge(u: &mut Unstructured) -> Result<usize> {
    Ok(match u.int_in_range(0..=2)? {
        0 => 1usize << u.int_in_range(20..=63)?,
        1 => usize::MAX - u.int_in_range(0..=3)?,
        _ => u.int_in_range(1usize << 20..=usize::MAX)?,
    })
}

fn lie(u: &mut Unstructured) -> Result<Option<Lie>> {
    if !u.ratio(1, 6)? {
        return Ok(None);
    }
    let which = u.int_in_range(0..=1)?;
    Ok(Some(match u.int_in_range(0..=4)? {
        0 => Lie::N(huge(u)?),
        1 => Lie::Contacts(huge(u)?),
        2 => Lie::Rows(which, huge(u)?),
        3 => Lie::Cols(which, huge(u)?),
        _ => Lie::LastPointer(which, u.int_in_range(1i64 << 20..=i64::MAX)?),
    }))
}

/// The raw matrix `k` (0: M or W, 1: H) as the lie has it.
fn told(lie: Option<Lie>, k: usize, m: &Csc) -> cadmm_csc {
    let mut raw = m.raw();
    match lie {
        Some(Lie::Rows(w, big)) if w == k => raw.nrows = big,
        Some(Lie::Cols(w, big)) if w == k => raw.ncols = big,
        _ => {}
    }
    raw
}

/// Applies a last-pointer lie to matrix `k` (its arrays keep their length).
fn lie_pointer(lie: Option<Lie>, k: usize, m: &mut Csc) {
    if let Some(Lie::LastPointer(w, big)) = lie {
        if w == k {
            *m.colptr.last_mut().unwrap() = big;
        }
    }
}

fn float(u: &mut Unstructured) -> Result<f64> {
    Ok(if u.ratio(3, 4)? {
        f64::from(u.int_in_range(-8i8..=8)?)
    } else {
        f64::from_bits(u.arbitrary()?)
    })
}

fn floats(u: &mut Unstructured, len: usize) -> Result<Vec<f64>> {
    (0..len).map(|_| float(u)).collect()
}

/// A pointer to `v`, or NULL now and then.
fn ptr(u: &mut Unstructured, v: &[f64]) -> Result<*const f64> {
    Ok(if u.ratio(1, 32)? { null() } else { v.as_ptr() })
}

fn readable(s: *const std::ffi::c_char) {
    assert!(!s.is_null());
    // SAFETY: the library returns NUL-terminated strings.
    let _ = unsafe { CStr::from_ptr(s) }.to_bytes().len();
}

fn new_problem(
    u: &mut Unstructured,
    n: usize,
    nc: usize,
    global: bool,
    lie: Option<Lie>,
) -> Result<*mut cadmm_problem> {
    let n_arg = match lie {
        Some(Lie::N(big)) => big,
        _ => n,
    };
    let nc_arg = match lie {
        Some(Lie::Contacts(big)) => big,
        _ => nc,
    };
    let mut out: *mut cadmm_problem = null_mut();
    let mu: Vec<f64> = (0..nc)
        .map(|_| {
            Ok(if u.ratio(7, 8)? {
                f64::from(u.int_in_range(0u8..=10)?) / 10.0
            } else {
                float(u)?
            })
        })
        .collect::<Result<_>>()?;
    let rc = if global {
        let mut m = Csc::new(u, n, n)?;
        for j in 0..n {
            // Mostly a dominant diagonal, so that solves happen.
            if u.ratio(3, 4)? {
                let (a, b) = (m.colptr[j].max(0) as usize, m.colptr[j + 1].max(0) as usize);
                for k in a..b.min(m.rowind.len()) {
                    if m.rowind[k] == j as i64 {
                        m.values[k] = m.values[k].abs() + 10.0;
                    }
                }
            }
        }
        let mut h = Csc::new(u, n, 3 * nc)?;
        let (f, w) = (floats(u, n)?, floats(u, 3 * nc)?);
        lie_pointer(lie, 0, &mut m);
        lie_pointer(lie, 1, &mut h);
        let (mr, hr) = (told(lie, 0, &m), told(lie, 1, &h));
        // SAFETY: every array has the length the header documents for n and nc; a lie
        // contradicts another size, and the library refuses it before reading by it.
        unsafe {
            cadmm_problem_new_global(
                n_arg,
                nc_arg,
                &mr,
                &hr,
                ptr(u, &f)?,
                ptr(u, &w)?,
                ptr(u, &mu)?,
                &mut out,
            )
        }
    } else {
        let mut w = Csc::new(u, 3 * nc, 3 * nc)?;
        let q = floats(u, 3 * nc)?;
        lie_pointer(lie, 0, &mut w);
        let wr = told(lie, 0, &w);
        // SAFETY: as above.
        unsafe { cadmm_problem_new_local(nc_arg, &wr, ptr(u, &q)?, ptr(u, &mu)?, &mut out) }
    };
    readable(cadmm_result_message(rc));
    // A lie a local problem has no place for (n, H) changes nothing there.
    let told_lie = match lie {
        Some(Lie::N(_)) | Some(Lie::Rows(1, _) | Lie::Cols(1, _) | Lie::LastPointer(1, _)) => {
            global
        }
        Some(_) => true,
        None => false,
    };
    if told_lie {
        // Refused at the lie, or at a bad value of a matrix read before it (M ahead of H).
        assert!(
            [
                CADMM_ERR_DIMENSION,
                CADMM_ERR_INVALID_CSC,
                CADMM_ERR_INVALID_VALUE
            ]
            .contains(&rc),
            "{lie:?} not refused: {rc}"
        );
    }
    if rc != CADMM_OK {
        assert!(out.is_null());
        readable(cadmm_last_error());
    }
    Ok(out)
}

/// Joints on a global problem of `n` velocities: G (`n x p`, any p) and b, sometimes with
/// a huge row count or last column pointer, which must be refused.
fn joints(u: &mut Unstructured, p: *mut cadmm_problem, n: usize) -> Result<()> {
    let cols = u.int_in_range(0..=3)?;
    let mut g = Csc::new(u, n, cols)?;
    let b = floats(u, cols)?;
    let mut raw = g.raw();
    let lied = if u.ratio(1, 3)? {
        if u.arbitrary()? {
            raw.nrows = huge(u)?;
        } else {
            *g.colptr.last_mut().unwrap() = u.int_in_range(1i64 << 20..=i64::MAX)?;
            raw = g.raw();
        }
        true
    } else {
        false
    };
    // SAFETY: G's arrays and b have the documented lengths but for the lie, which the
    // library must refuse before reading by it.
    let rc = unsafe { cadmm_problem_set_joints(p, &raw, ptr(u, &b)?) };
    readable(cadmm_result_message(rc));
    if lied {
        assert!(
            rc == CADMM_ERR_DIMENSION || rc == CADMM_ERR_INVALID_CSC,
            "joints with a huge size not refused: {rc}"
        );
    }
    Ok(())
}

fn c_string(u: &mut Unstructured, names: &[&str]) -> Result<CString> {
    let s: String = if u.ratio(3, 4)? {
        (*u.choose(names)?).into()
    } else {
        u.arbitrary()?
    };
    Ok(CString::new(s.replace('\0', "")).unwrap())
}

fn run(data: &[u8]) -> Result<()> {
    let mut u = Unstructured::new(data);
    let (n, nc, global) = (
        u.int_in_range(0..=6)?,
        u.int_in_range(0..=3)?,
        u.arbitrary()?,
    );
    let size_lie = lie(&mut u)?;
    let p = new_problem(&mut u, n, nc, global, size_lie)?;
    if !p.is_null() && global && u.ratio(1, 4)? {
        joints(&mut u, p, n)?;
    }
    let mut s: *mut cadmm_settings = null_mut();
    // SAFETY: every pointer below is NULL or valid; objects are freed once.
    unsafe {
        assert_eq!(cadmm_settings_new(&mut s), CADMM_OK);
        for _ in 0..u.int_in_range(0..=4)? {
            let rc = match u.int_in_range(0..=6)? {
                0 => cadmm_settings_set_variant(
                    s,
                    c_string(&mut u, &["auto", "newton", "cp-N", "vp-RR-Spectral"])?.as_ptr(),
                ),
                1 => cadmm_settings_set_tolerance(s, float(&mut u)?.abs() * 1e-9),
                2 => cadmm_settings_set_max_iterations(s, u.int_in_range(0..=300)?),
                3 => cadmm_settings_set_anderson(s, u.int_in_range(0..=12)?),
                4 => cadmm_settings_set_initial_rho(
                    s,
                    c_string(
                        &mut u,
                        &["normal", "acary", "ghadimi", "dicairano", "given"],
                    )?
                    .as_ptr(),
                    float(&mut u)?,
                ),
                5 => cadmm_settings_set_s_update(
                    s,
                    c_string(&mut u, &["internal", "external"])?.as_ptr(),
                ),
                _ => cadmm_settings_set_newton(s, u.arbitrary()?),
            };
            readable(cadmm_result_message(rc));
        }
        // Bounded solves whatever the fuzzed settings say.
        cadmm_settings_set_time_limit(s, 0.2);
        if u.ratio(1, 2)? {
            cadmm_settings_set_max_iterations(s, 300);
        }
        let mut sv: *mut cadmm_solver = null_mut();
        if !p.is_null() && cadmm_solver_new(p, s, &mut sv) == CADMM_OK {
            let (mut nn, mut ncc, mut is_global) = (0usize, 0usize, false);
            assert_eq!(
                cadmm_problem_dims(p, &mut nn, &mut ncc, &mut is_global),
                CADMM_OK
            );
            let mut r = vec![0.0; 3 * ncc];
            let mut uu = vec![0.0; 3 * ncc];
            let mut v = vec![0.0; nn];
            for _ in 0..u.int_in_range(1..=3)? {
                match u.int_in_range(0..=3)? {
                    0 => {
                        let q = new_problem(&mut u, n, nc, global, None)?;
                        if !q.is_null() {
                            readable(cadmm_result_message(cadmm_solver_update(sv, q)));
                        }
                        cadmm_problem_free(q);
                    }
                    1 => {
                        let wr = floats(&mut u, 3 * ncc)?;
                        let wv = floats(&mut u, nn)?;
                        let vp = if u.arbitrary()? { null() } else { wv.as_ptr() };
                        readable(cadmm_result_message(cadmm_solver_warm_start(
                            sv,
                            wr.as_ptr(),
                            vp,
                        )));
                    }
                    _ => {
                        let mut status: cadmm_status = -1;
                        if cadmm_solver_solve(sv, &mut status) == CADMM_OK {
                            assert!((0..=5).contains(&status), "status {status}");
                        }
                    }
                }
            }
            assert_eq!(
                cadmm_solver_get_solution(sv, r.as_mut_ptr(), uu.as_mut_ptr(), v.as_mut_ptr()),
                CADMM_OK
            );
            let mut e = 0.0;
            let _ = cadmm_problem_error(p, r.as_ptr(), uu.as_ptr(), v.as_ptr(), &mut e);
            let mut stats: cadmm_stats = std::mem::zeroed();
            stats.struct_size = std::mem::size_of::<cadmm_stats>();
            assert_eq!(cadmm_solver_get_stats(sv, &mut stats), CADMM_OK);
            let len = cadmm_solver_trace_len(sv);
            if len > 0 {
                let mut point: cadmm_trace_point = std::mem::zeroed();
                let i = if u.arbitrary()? { len - 1 } else { len };
                let _ = cadmm_solver_get_trace(sv, i, &mut point);
            }
            readable(cadmm_solver_last_error(sv));
        }
        cadmm_solver_free(sv);
        cadmm_settings_free(s);
        cadmm_problem_free(p);
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(data);
});
