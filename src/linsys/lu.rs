//! LU with partial pivoting of a square matrix on a fixed sparsity pattern: the analysis is
//! done once, then each numeric factorization takes new values on the pattern. Dense and in
//! place up to [`DENSE_MAX`] unknowns (a small local problem, an island of a few contacts),
//! faer's sparse LU (COLAMD column ordering) above. The Newton systems and the general
//! (unsymmetric) x-update systems are factorized so.

use crate::dense::{lu, lu_solve};
use crate::tuning::{DENSE_MAX, LU_SUPERNODAL_MIN};
use crate::types::Error;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::lu::{
    factorize_symbolic_lu, LuRef, LuSymbolicParams, NumericLu, SymbolicLu,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};

/// A square pattern in compressed columns, rows sorted and unique within each column,
/// borrowed from the matrix that owns it.
#[derive(Clone, Copy)]
pub struct PatternRef<'a> {
    /// Dimension.
    pub n: usize,
    /// Column pointers.
    pub colptr: &'a [usize],
    /// Row indices.
    pub rowind: &'a [usize],
}

impl<'a> PatternRef<'a> {
    fn faer(self) -> SymbolicSparseColMatRef<'a, usize> {
        SymbolicSparseColMatRef::new_checked(self.n, self.n, self.colptr, None, self.rowind)
    }
}

/// The analysis of a pattern for LU, and the workspace of its factorizations and solves.
pub struct Lu {
    n: usize,
    /// The symbolic factorization and its workspace, when sparse.
    sparse: Option<(SymbolicLu<usize>, MemBuffer)>,
}

/// The factors of one numeric factorization.
pub enum LuFactors {
    /// Column-major dense factors and row exchanges ([`lu`]).
    Dense {
        /// `L` below the diagonal, `U` on and above.
        factor: Vec<f64>,
        /// Row exchanged with row `k` at step `k`.
        pivots: Vec<usize>,
    },
    /// faer's sparse factors.
    Sparse(Box<NumericLu<usize, f64>>),
}

impl Lu {
    /// The analysis of `pattern` (`name` labels the matrix in errors).
    pub fn new(name: &'static str, pattern: PatternRef) -> Result<Self, Error> {
        if pattern.n <= DENSE_MAX {
            return Ok(Self {
                n: pattern.n,
                sparse: None,
            });
        }
        // Supernodal from LU_SUPERNODAL_MIN unknowns on: faer's own choice estimates the
        // fill from the pattern alone, and with partial pivoting large Newton matrices fill
        // far more (see the constant).
        let threshold = match pattern.n >= LU_SUPERNODAL_MIN {
            true => SupernodalThreshold::FORCE_SUPERNODAL,
            false => SupernodalThreshold::AUTO,
        };
        let params = LuSymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..Default::default()
        };
        let symbolic =
            factorize_symbolic_lu(pattern.faer(), params).map_err(|_| Error::OutOfMemory {
                what: format!("the symbolic analysis of {name}"),
            })?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        Ok(Self {
            n: pattern.n,
            sparse: Some((symbolic, MemBuffer::new(req))),
        })
    }

    /// Storage for the factors of one factorization.
    pub fn factors(&self) -> LuFactors {
        match self.sparse {
            None => LuFactors::Dense {
                factor: vec![0.0; self.n * self.n],
                pivots: vec![0; self.n],
            },
            Some(_) => LuFactors::Sparse(Box::new(NumericLu::new())),
        }
    }

    /// Factorizes `values` (on the pattern of the analysis) into `factors`, which must come
    /// from [`Lu::factors`]; false on a zero or non-finite pivot (dense), or a structurally
    /// singular matrix (sparse: partial pivoting reports an exactly singular one only by a
    /// non-finite solution).
    pub fn factorize(
        &mut self,
        pattern: PatternRef,
        values: &[f64],
        factors: &mut LuFactors,
    ) -> bool {
        let n = self.n;
        match (&mut self.sparse, factors) {
            (None, LuFactors::Dense { factor, pivots }) => {
                factor.fill(0.0);
                for j in 0..n {
                    for k in pattern.colptr[j]..pattern.colptr[j + 1] {
                        factor[pattern.rowind[k] + j * n] = values[k];
                    }
                }
                lu(factor, pivots, n)
            }
            (Some((symbolic, mem)), LuFactors::Sparse(numeric)) => {
                let a = SparseColMatRef::new(pattern.faer(), values);
                symbolic
                    .factorize_numeric_lu(
                        numeric,
                        a,
                        Par::Seq,
                        MemStack::new(mem),
                        Default::default(),
                    )
                    .is_ok()
            }
            _ => unreachable!("factors come from the same analysis"),
        }
    }

    /// Solves `A x = rhs` in place with `factors` of [`Lu::factorize`] (no allocation).
    pub fn solve_in_place(&mut self, factors: &LuFactors, rhs: &mut [f64]) {
        let n = self.n;
        match (&mut self.sparse, factors) {
            (None, LuFactors::Dense { factor, pivots }) => lu_solve(factor, pivots, n, rhs),
            (Some((symbolic, mem)), LuFactors::Sparse(numeric)) => {
                LuRef::new_unchecked(symbolic, numeric).solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(rhs, n, 1),
                    Par::Seq,
                    MemStack::new(mem),
                )
            }
            _ => unreachable!("factors come from the same analysis"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::newton::alart_curnier::tests::Rng;
    use nalgebra::{DMatrix, DVector};

    /// A sparse unsymmetric matrix of `n` unknowns whose diagonal is small against its
    /// band, so that partial pivoting exchanges rows: columns in CSC and the dense copy.
    fn banded(n: usize, seed: u64) -> (Vec<usize>, Vec<usize>, Vec<f64>, DMatrix<f64>) {
        let mut rng = Rng(seed);
        let (mut colptr, mut rowind, mut values) = (vec![0], Vec::new(), Vec::new());
        let mut dense = DMatrix::zeros(n, n);
        for j in 0..n {
            // The band, and a far row per column, so that the factors fill in.
            let mut rows: Vec<usize> = (j.saturating_sub(3)..(j + 4).min(n)).collect();
            rows.push((j * 7 + 11) % n);
            rows.sort_unstable();
            rows.dedup();
            for i in rows {
                let v = rng.uniform(-0.5, 0.5) * if i == j { 1e-3 } else { 1.0 };
                rowind.push(i);
                values.push(v);
                dense[(i, j)] = v;
            }
            colptr.push(rowind.len());
        }
        (colptr, rowind, values, dense)
    }

    /// Both sparse paths (faer's choice below LU_SUPERNODAL_MIN unknowns, supernodal from
    /// it) solve as nalgebra's dense LU does, and a second factorization on the same
    /// analysis takes new values.
    #[test]
    fn sparse_factorizations_match_a_dense_solve() {
        for n in [DENSE_MAX + 20, LU_SUPERNODAL_MIN + 44] {
            let (colptr, rowind, values, dense) = banded(n, 7 + n as u64);
            let pattern = PatternRef {
                n,
                colptr: &colptr,
                rowind: &rowind,
            };
            let mut lu = Lu::new("test matrix", pattern).unwrap();
            let mut factors = lu.factors();
            let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            for scale in [1.0, -2.5] {
                let scaled: Vec<f64> = values.iter().map(|v| scale * v).collect();
                assert!(lu.factorize(pattern, &scaled, &mut factors), "n = {n}");
                let mut x = b.clone();
                lu.solve_in_place(&factors, &mut x);
                let reference = (scale * &dense)
                    .lu()
                    .solve(&DVector::from_vec(b.clone()))
                    .unwrap();
                let diff = (DVector::from_vec(x) - &reference).amax();
                assert!(diff <= 1e-9 * reference.amax(), "n = {n}: {diff}");
            }
        }
    }
}
