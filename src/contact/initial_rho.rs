//! Initial penalty rules (docs/algorithms.md §6.1).
//!
//! For the global form the QP matrix is `M` and the constraint matrix `H^T`; for the local
//! form they are `W` and `I`, so Ghadimi's `1 / sqrt(l_min l_max (A Q^-1 A^T))` and
//! Di Cairano's `sqrt(l_min l_max (Q))` both become `sqrt(l_min l_max (W))` there (smallest
//! non-zero eigenvalue of the symmetric part of W, which is usually singular).

use crate::dense::{cholesky, forward_substitution};
use crate::problem::{GlobalProblem, LocalProblem, Problem};
use crate::settings::InitialRho;
use crate::types::Error;
use nalgebra::{DMatrix, SymmetricEigen};

/// Smallest eigenvalue above `1e-10 * largest`, and the largest, of a symmetric matrix
/// (nalgebra's symmetric eigensolver: cadmm's dense kernels solve, they do not find
/// spectra).
fn spectrum_bounds(a: DMatrix<f64>) -> (f64, f64) {
    if a.is_empty() {
        return (f64::NAN, f64::NAN); // no spectrum: the caller falls back to rho = 1
    }
    let eig = SymmetricEigen::new(a).eigenvalues;
    let max = eig.iter().cloned().fold(0.0f64, f64::max);
    let min = eig
        .iter()
        .cloned()
        .filter(|&l| l > 1e-10 * max)
        .fold(f64::INFINITY, f64::min);
    (min, max)
}

fn dense(a: &crate::csc::CscMatrix) -> DMatrix<f64> {
    DMatrix::from_column_slice(a.nrows(), a.ncols(), &a.to_dense())
}

fn positive(rho: f64) -> f64 {
    if rho.is_finite() && rho > 0.0 {
        rho
    } else {
        1.0
    }
}

/// The first rho under `rule` of a problem shared over processes, where Acary's ratio
/// (`acary`, computed across them) stands in for the spectral rules (1 when it
/// degenerates, e.g. H = 0).
#[cfg(feature = "mpi")]
pub(crate) fn shared_initial_rho(rule: InitialRho, acary: impl FnOnce() -> f64) -> f64 {
    positive(match rule {
        InitialRho::Normal => 1.0,
        InitialRho::Given(rho) => rho,
        _ => acary(),
    })
}

/// The first rho of a problem under a rule (1 when the rule degenerates, e.g. H = 0).
pub fn initial_rho(rule: InitialRho, p: &Problem) -> Result<f64, Error> {
    Ok(positive(match (rule, p) {
        (InitialRho::Normal, _) => 1.0,
        (InitialRho::Given(r), _) => r,
        (InitialRho::Acary, Problem::Global(g)) => g.m.norm_1() / g.h.norm_1(),
        (InitialRho::Acary, Problem::Local(l)) => l.w.norm_1(),
        (InitialRho::Ghadimi, Problem::Global(g)) => ghadimi_global(g)?,
        (InitialRho::DiCairano, Problem::Global(g)) => {
            let (min, max) = spectrum_bounds(dense(&g.m));
            (min * max).sqrt()
        }
        (InitialRho::Ghadimi | InitialRho::DiCairano, Problem::Local(l)) => local_spectral(l),
    }))
}

/// `1 / sqrt(l_min l_max)` of the Delassus `H^T M^-1 H`, through its non-zero spectrum
/// `L^-1 H H^T L^-T` (n x n, with `M = L L^T`).
fn ghadimi_global(g: &GlobalProblem) -> Result<f64, Error> {
    let n = g.n();
    if n == 0 || g.n_contacts() == 0 {
        return Ok(1.0);
    }
    let mut l = g.m.to_dense();
    if !cholesky(&mut l, n) {
        return Err(Error::NotPositiveDefinite { field: "M" });
    }
    // X = L^-1 H, column by column.
    let mut x = g.h.to_dense();
    for column in x.chunks_exact_mut(n) {
        forward_substitution(&l, n, column);
    }
    let x = DMatrix::from_column_slice(n, g.h.ncols(), &x);
    let (min, max) = spectrum_bounds(&x * x.transpose());
    Ok(1.0 / (min * max).sqrt())
}

fn local_spectral(l: &LocalProblem) -> f64 {
    let w = dense(&l.w);
    let sym = (&w + w.transpose()) * 0.5;
    let (min, max) = spectrum_bounds(sym);
    (min * max).sqrt()
}
