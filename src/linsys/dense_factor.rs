//! Dense factorization of a small [`ParamMatrix`] (at most [`crate::tuning::DENSE_MAX`]
//! unknowns), with the kernels of [`crate::dense`].

use super::param_matrix::{Assembly, ParamMatrix};
use super::sparse_factor::FactorKind;
use crate::dense::{cholesky, cholesky_solve, lu, lu_solve};
use crate::types::Error;

/// `A(rho)` factorized densely in place: `L L^T` (lower triangle of `factor`) for the
/// positive definite kind, `P A = L U` with partial pivoting for the others (a quasi-definite
/// matrix is nonsingular, so LU needs no regularization there).
pub struct DenseFactor {
    kind: FactorKind,
    name: &'static str,
    matrix: ParamMatrix,
    values: Vec<f64>,
    /// Column-major `n x n` factor.
    factor: Vec<f64>,
    /// Row exchanged with row `k` at step `k` (LU).
    pivots: Vec<usize>,
    /// The rho of the current factor.
    rho: Option<f64>,
    refactorizations: usize,
}

impl DenseFactor {
    /// Storage for the factor; nothing is factorized yet.
    pub fn new(name: &'static str, matrix: ParamMatrix, kind: FactorKind) -> Self {
        let n = matrix.n;
        Self {
            kind,
            name,
            values: vec![0.0; matrix.base.len()],
            matrix,
            factor: vec![0.0; n * n],
            pivots: vec![0; n],
            rho: None,
            refactorizations: 0,
        }
    }

    /// Number of numeric factorizations done so far.
    pub fn refactorizations(&self) -> usize {
        self.refactorizations
    }

    /// Order of the matrix.
    pub fn size(&self) -> usize {
        self.matrix.n
    }

    /// New values on the same pattern; the next [`DenseFactor::set_rho`] refactorizes.
    pub fn reassemble(
        &mut self,
        assembly: &Assembly,
        base: impl IntoIterator<Item = (usize, usize, f64)>,
        slope: impl IntoIterator<Item = (usize, usize, f64)>,
    ) {
        self.matrix.reassemble(assembly, base, slope);
        self.rho = None;
    }

    /// Makes `A(rho)` the current factor (no allocation).
    pub fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        self.matrix.values_at(rho, &mut self.values);
        if self.rho == Some(rho) {
            return Ok(());
        }
        self.rho = None;
        let n = self.matrix.n;
        let symmetric = self.kind != FactorKind::Lu;
        let a = &mut self.factor;
        a.fill(0.0);
        for j in 0..n {
            for k in self.matrix.colptr[j]..self.matrix.colptr[j + 1] {
                let i = self.matrix.rowind[k];
                a[i + j * n] = self.values[k];
                if symmetric {
                    a[j + i * n] = self.values[k];
                }
            }
        }
        let ok = match self.kind {
            FactorKind::Cholesky => cholesky(a, n),
            _ => lu(a, &mut self.pivots, n),
        };
        if !ok {
            return Err(match self.kind {
                FactorKind::Lu => Error::Singular { field: self.name },
                _ => Error::NotPositiveDefinite { field: self.name },
            });
        }
        self.refactorizations += 1;
        self.rho = Some(rho);
        Ok(())
    }

    /// Solves `A(rho) x = rhs` in place with the current factor (no allocation).
    pub fn solve_in_place(&mut self, x: &mut [f64]) {
        let n = self.matrix.n;
        let a = &self.factor;
        match self.kind {
            FactorKind::Cholesky => cholesky_solve(a, n, x),
            _ => lu_solve(a, &self.pivots, n, x),
        }
    }

    /// `y = A(rho) x` for the current rho.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        self.matrix
            .mul_vec(&self.values, self.kind != FactorKind::Lu, x, y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense factors solve what they factorize, for each kind.
    #[test]
    fn solves_each_kind() {
        let n = 4;
        // Symmetric positive definite (upper triangle), and a quasi-definite joint system.
        let spd = [
            (0, 0, 4.0),
            (0, 1, 1.0),
            (1, 1, 3.0),
            (2, 2, 2.0),
            (1, 3, 0.5),
            (3, 3, 5.0),
        ];
        let qd = [
            (0, 0, 4.0),
            (1, 1, 3.0),
            (2, 2, 2.0),
            (0, 3, 1.0),
            (2, 3, 1.0),
            (3, 3, -1e-9),
        ];
        let general = [
            (0, 0, 1e-3),
            (1, 0, 2.0),
            (0, 1, 1.0),
            (1, 1, 0.5),
            (2, 2, 1.0),
            (3, 2, 1.0),
            (2, 3, -1.0),
            (3, 3, 1.0),
        ];
        for (triplets, kind, upper) in [
            (&spd[..], FactorKind::Cholesky, true),
            (&qd[..], FactorKind::QuasiDefinite { n_positive: 3 }, true),
            (&general[..], FactorKind::Lu, false),
        ] {
            let (m, _) = ParamMatrix::from_triplets(n, triplets.iter().copied(), [], upper);
            let mut f = DenseFactor::new("A", m, kind);
            f.set_rho(0.0).unwrap();
            let x = [1.0, -2.0, 0.5, 3.0];
            let mut b = [0.0; 4];
            f.mul_vec(&x, &mut b);
            f.solve_in_place(&mut b);
            for (a, e) in b.iter().zip(x) {
                assert!((a - e).abs() < 1e-6, "{kind:?}: {b:?}");
            }
        }
        let (m, _) = ParamMatrix::from_triplets(2, [(0, 0, 1.0), (1, 1, -1.0)], [], true);
        let mut f = DenseFactor::new("A", m, FactorKind::Cholesky);
        assert!(matches!(
            f.set_rho(0.0),
            Err(Error::NotPositiveDefinite { .. })
        ));
    }
}
