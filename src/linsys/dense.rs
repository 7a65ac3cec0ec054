//! Dense factorization of a small [`ParamMatrix`]: below a few dozen unknowns a dense
//! Cholesky or LU costs less than a sparse one's analysis, bookkeeping and allocations
//! (an island of a box on the ground has 6 velocities and 12 contact rows).

use super::param_matrix::Assembly;
use super::{FactorKind, ParamMatrix};
use crate::types::Error;

pub use crate::tuning::DENSE_MAX;

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

/// True when the column-major `n x n` matrix `a` is symmetric to the tolerance sparse
/// matrices are held to (`max |A - A^T| <= SYMMETRY_TOL max |A|`).
pub(crate) fn is_symmetric(a: &[f64], n: usize) -> bool {
    let scale = a.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    let tol = crate::csc::SYMMETRY_TOL * scale;
    (0..n).all(|j| (0..j).all(|i| (a[i + j * n] - a[j + i * n]).abs() <= tol))
}

/// The inverse of a symmetric positive definite column-major `n x n` matrix into
/// `inverse`, through its Cholesky factor (which overwrites `a`); false when `a` is not
/// positive definite. (Applying an inverse is one small product where a factor takes two
/// triangular solves: the preconditioners apply theirs at every iteration.)
pub(crate) fn spd_inverse(a: &mut [f64], n: usize, inverse: &mut [f64]) -> bool {
    if !cholesky(a, n) {
        return false;
    }
    for (j, column) in inverse.chunks_exact_mut(n).enumerate() {
        column.fill(0.0);
        column[j] = 1.0;
        cholesky_solve(a, n, column);
    }
    true
}

/// Solves with the factor of [`cholesky`], in place.
pub(crate) fn cholesky_solve(a: &[f64], n: usize, x: &mut [f64]) {
    // Column slices, so that the inner loops run without index checks (small islands
    // make many of these solves).
    for j in 0..n {
        let col = &a[j * n..(j + 1) * n];
        let (head, tail) = x.split_at_mut(j + 1);
        head[j] /= col[j];
        let xj = head[j];
        for (xi, aij) in tail[..n - j - 1].iter_mut().zip(&col[j + 1..]) {
            *xi -= aij * xj;
        }
    }
    for j in (0..n).rev() {
        let col = &a[j * n..(j + 1) * n];
        let (head, tail) = x.split_at_mut(j + 1);
        let mut xj = head[j];
        for (aij, xi) in col[j + 1..].iter().zip(&tail[..n - j - 1]) {
            xj -= aij * xi;
        }
        head[j] = xj / col[j];
    }
}

/// In-place lower Cholesky of a column-major symmetric matrix; false when a pivot is not
/// positive (or not finite).
pub(crate) fn cholesky(a: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j + j * n];
        for k in 0..j {
            d -= a[j + k * n] * a[j + k * n];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j + j * n] = d;
        for i in j + 1..n {
            let mut s = a[i + j * n];
            for k in 0..j {
                s -= a[i + k * n] * a[j + k * n];
            }
            a[i + j * n] = s / d;
        }
    }
    true
}

/// Solves with the factors of [`lu`], in place.
pub(crate) fn lu_solve(a: &[f64], pivots: &[usize], n: usize, x: &mut [f64]) {
    for (k, &p) in pivots.iter().enumerate() {
        x.swap(k, p);
    }
    for j in 0..n {
        let col = &a[j * n..(j + 1) * n];
        let (head, tail) = x.split_at_mut(j + 1);
        let xj = head[j];
        for (xi, aij) in tail[..n - j - 1].iter_mut().zip(&col[j + 1..]) {
            *xi -= aij * xj;
        }
    }
    for j in (0..n).rev() {
        let col = &a[j * n..(j + 1) * n];
        x[j] /= col[j];
        let xj = x[j];
        for (xi, aij) in x[..j].iter_mut().zip(&col[..j]) {
            *xi -= aij * xj;
        }
    }
}

/// In-place LU with partial pivoting of a column-major matrix; false on a zero or
/// non-finite pivot.
pub(crate) fn lu(a: &mut [f64], pivots: &mut [usize], n: usize) -> bool {
    for k in 0..n {
        let mut p = k;
        for i in k + 1..n {
            if a[i + k * n].abs() > a[p + k * n].abs() {
                p = i;
            }
        }
        pivots[k] = p;
        let pivot = a[p + k * n];
        if pivot == 0.0 || !pivot.is_finite() {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k + j * n, p + j * n);
            }
        }
        for i in k + 1..n {
            a[i + k * n] /= pivot;
        }
        let (left, right) = a.split_at_mut((k + 1) * n);
        let pivot_col = &left[k * n + k + 1..(k + 1) * n];
        for col in right[..(n - k - 1) * n].chunks_exact_mut(n) {
            let f = col[k];
            if f != 0.0 {
                for (x, l) in col[k + 1..].iter_mut().zip(pivot_col) {
                    *x -= l * f;
                }
            }
        }
    }
    true
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
