//! Dense linear algebra on small column-major matrices, in place and without allocation:
//! Cholesky, LU with partial pivoting, and the small least-squares systems of Anderson
//! acceleration. Below a few dozen unknowns these cost less than a sparse factorization's
//! analysis, bookkeeping and allocations (an island of a box on the ground has 6 velocities
//! and 12 contact rows); the factorizations, the block stores and the accelerator all use
//! them. Symmetric eigenvalues and rank-revealing least squares are nalgebra's.

use crate::csc::SYMMETRY_TOL;

/// True when the column-major `n x n` matrix `a` is symmetric to the tolerance sparse
/// matrices are held to (`max |A - A^T| <= SYMMETRY_TOL max |A|`).
pub(crate) fn is_symmetric(a: &[f64], n: usize) -> bool {
    let scale = a.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    let tol = SYMMETRY_TOL * scale;
    (0..n).all(|j| (0..j).all(|i| (a[i + j * n] - a[j + i * n]).abs() <= tol))
}

/// In-place lower Cholesky of a column-major symmetric matrix (its lower triangle is read);
/// false when a pivot is not positive (or not finite).
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

/// Solves `L y = x` in place with the factor of [`cholesky`].
pub(crate) fn forward_substitution(a: &[f64], n: usize, x: &mut [f64]) {
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
}

/// Solves `L^T y = x` in place with the factor of [`cholesky`].
fn backward_substitution(a: &[f64], n: usize, x: &mut [f64]) {
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

/// Solves `L L^T y = x` in place with the factor of [`cholesky`].
pub(crate) fn cholesky_solve(a: &[f64], n: usize, x: &mut [f64]) {
    forward_substitution(a, n, x);
    backward_substitution(a, n, x);
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

/// Solves the `k x k` row-major system `a x = b` (`k = b.len()`) by Gaussian elimination
/// with partial pivoting, overwriting `a` and `b`; false when a pivot is below `1e-300` in
/// magnitude or the solution is not finite. Anderson acceleration's normal equations are
/// solved so; unlike [`lu`] with [`lu_solve`], a tie between pivots goes to the last row
/// and the back substitution runs by rows, the roundings its iterates are made of.
pub(crate) fn gauss_solve(a: &mut [f64], b: &mut [f64], x: &mut [f64]) -> bool {
    let k = b.len();
    for col in 0..k {
        let piv = (col..k)
            .max_by(|&i, &j| a[i * k + col].abs().total_cmp(&a[j * k + col].abs()))
            .unwrap_or(col);
        if a[piv * k + col].abs() < 1e-300 {
            return false;
        }
        if piv != col {
            for j in 0..k {
                a.swap(piv * k + j, col * k + j);
            }
            b.swap(piv, col);
        }
        for i in col + 1..k {
            let f = a[i * k + col] / a[col * k + col];
            for j in col..k {
                a[i * k + j] -= f * a[col * k + j];
            }
            b[i] -= f * b[col];
        }
    }
    for i in (0..k).rev() {
        let s: f64 = (i + 1..k).map(|j| a[i * k + j] * x[j]).sum();
        x[i] = (b[i] - s) / a[i * k + i];
    }
    x.iter().all(|v| v.is_finite())
}
