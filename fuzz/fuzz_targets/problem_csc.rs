//! Problem construction from raw compressed-column arrays and vectors (Rust API), then a
//! short solve of whatever is accepted: every input must give an error or a status, never a
//! panic, and a solved status must come with a finite solution at the tolerance.
#![no_main]

use cadmm::{CscMatrix, GlobalProblem, LocalProblem, Problem, Settings, Solver, Status};
use libfuzzer_sys::arbitrary::{Result, Unstructured};
use libfuzzer_sys::fuzz_target;

/// A float from the input: small integers most of the time, raw bits (NaN, infinities,
/// subnormals, huge values) otherwise.
fn float(u: &mut Unstructured) -> Result<f64> {
    Ok(if u.ratio(3, 4)? {
        f64::from(u.int_in_range(-8i8..=8)?) / f64::from(u.int_in_range(1u8..=4)?)
    } else {
        f64::from_bits(u.arbitrary()?)
    })
}

fn floats(u: &mut Unstructured, len: usize) -> Result<Vec<f64>> {
    (0..len).map(|_| float(u)).collect()
}

/// Raw CSC arrays: sizes near the expected ones, indices mostly in range, sometimes not.
fn csc(
    u: &mut Unstructured,
    field: &'static str,
    nrows: usize,
    ncols: usize,
) -> Result<Option<CscMatrix>> {
    let ncols = if u.ratio(1, 16)? {
        u.int_in_range(0..=8)?
    } else {
        ncols
    };
    let mut colptr = vec![0usize];
    for _ in 0..ncols {
        let step = u.int_in_range(0..=nrows.min(6))?;
        colptr.push(colptr.last().unwrap() + step);
    }
    if u.ratio(1, 16)? && !colptr.is_empty() {
        let k = u.choose_index(colptr.len())?;
        colptr[k] = u.int_in_range(0..=40)?;
    }
    if u.ratio(1, 32)? {
        colptr.pop();
    }
    let nnz = colptr.last().copied().unwrap_or(0);
    let len = if u.ratio(1, 16)? {
        u.int_in_range(0..=40)?
    } else {
        nnz
    };
    let mut rowind = Vec::with_capacity(len);
    for _ in 0..len {
        let beyond = usize::from(u.ratio(1, 16)?);
        rowind.push(u.int_in_range(0..=(nrows + beyond).saturating_sub(1))?);
    }
    let mut values: Vec<f64> = floats(u, len)?;
    // Keep the diagonal of square matrices dominant in most inputs, so solves happen.
    if nrows == ncols && u.ratio(3, 4)? {
        for j in 0..ncols.min(colptr.len().saturating_sub(1)) {
            for k in colptr[j]..colptr[j + 1].min(len) {
                if rowind[k] == j {
                    values[k] = values[k].abs() + 10.0;
                }
            }
        }
    }
    Ok(CscMatrix::new(field, nrows, ncols, colptr, rowind, values).ok())
}

fn problem(u: &mut Unstructured) -> Result<Option<Problem>> {
    let nc = u.int_in_range(0..=4)?;
    let mu: Vec<f64> = (0..nc + usize::from(u.ratio(1, 32)?))
        .map(|_| {
            Ok(if u.ratio(7, 8)? {
                f64::from(u.int_in_range(0u8..=20)?) / 10.0
            } else {
                float(u)?
            })
        })
        .collect::<Result<_>>()?;
    if u.arbitrary()? {
        let n = u.int_in_range(0..=8)?;
        let (Some(m), Some(h)) = (csc(u, "M", n, n)?, csc(u, "H", n, 3 * nc)?) else {
            return Ok(None);
        };
        let extra = usize::from(u.ratio(1, 32)?);
        let f = floats(u, n + extra)?;
        let w = floats(u, 3 * nc)?;
        Ok(GlobalProblem::new(m, h, f, w, mu).ok().map(Problem::Global))
    } else {
        let Some(w) = csc(u, "W", 3 * nc, 3 * nc)? else {
            return Ok(None);
        };
        let q = floats(u, 3 * nc)?;
        Ok(LocalProblem::new(w, q, mu).ok().map(Problem::Local))
    }
}

fn run(data: &[u8]) -> Result<()> {
    let mut u = Unstructured::new(data);
    let Some(p) = problem(&mut u)? else {
        return Ok(());
    };
    let variant = *u.choose(&["auto", "newton", "cp-N", "vp-RR-Spectral", "vp-N-He"])?;
    let settings = Settings {
        max_iterations: 300,
        time_limit: 0.2,
        variant: cadmm::VariantChoice::from_name(variant).unwrap(),
        ..Settings::default()
    };
    let Ok(mut solver) = Solver::new(p.clone(), settings) else {
        return Ok(());
    };
    if let Ok(status) = solver.solve() {
        let s = solver.solution();
        if status == Status::Solved {
            assert!(s.r.iter().chain(&s.u).chain(&s.v).all(|x| x.is_finite()));
            let e = cadmm::measure::problem_error(&p, &s.r, &s.v, &s.lambda);
            assert!(e <= 1e-8, "solved with error {e}");
        }
    }
    // The same pattern again through the update path.
    let _ = solver.update(p).and_then(|_| solver.solve());
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let _ = run(data);
});
