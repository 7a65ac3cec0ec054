//! Fixed-pattern LU for the Newton systems: the pattern is built once, the analysis is done
//! once ([`Lu`]: dense for small systems, sparse above), and every Newton step only refills
//! the values and refactorizes numerically.

use crate::linsys::{Lu, LuFactors, PatternRef};
use crate::types::Error;

/// A square compressed-column pattern with sorted, unique rows per column.
#[derive(Debug, Clone)]
pub struct Pattern {
    /// Dimension.
    pub n: usize,
    /// Column pointers.
    pub colptr: Vec<usize>,
    /// Row indices, sorted within each column.
    pub rowind: Vec<usize>,
}

impl Pattern {
    /// Builds the pattern from the row lists of each column (unsorted, duplicates allowed).
    pub fn from_columns(n: usize, cols: Vec<Vec<usize>>) -> Self {
        debug_assert_eq!(cols.len(), n);
        Self::from_column_rows(n, |c, out| out.extend_from_slice(&cols[c]))
    }

    /// Builds the pattern one column at a time: `rows(c, out)` pushes the rows of column
    /// `c` (unsorted, duplicates allowed). One scratch column, not a vector per column:
    /// small islands build many of these.
    pub fn from_column_rows(n: usize, mut rows: impl FnMut(usize, &mut Vec<usize>)) -> Self {
        let mut colptr = Vec::with_capacity(n + 1);
        let mut rowind = Vec::new();
        let mut col = Vec::new();
        colptr.push(0);
        for c in 0..n {
            col.clear();
            rows(c, &mut col);
            col.sort_unstable();
            col.dedup();
            rowind.extend_from_slice(&col);
            colptr.push(rowind.len());
        }
        Self { n, colptr, rowind }
    }

    /// Position of entry `(row, col)` in the value array; the entry must be in the pattern
    /// (used at construction only, to precompute where each contribution goes).
    pub fn pos(&self, row: usize, col: usize) -> usize {
        let (s, e) = (self.colptr[col], self.colptr[col + 1]);
        match self.rowind[s..e].binary_search(&row) {
            Ok(k) => s + k,
            Err(_) => panic!("entry ({row}, {col}) is not in the Newton pattern"),
        }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.rowind.len()
    }

    /// The pattern, borrowed.
    fn borrowed(&self) -> PatternRef<'_> {
        PatternRef {
            n: self.n,
            colptr: &self.colptr,
            rowind: &self.rowind,
        }
    }
}

/// LU with partial pivoting on a fixed pattern ([`Lu`]), of values the caller fills.
pub struct SparseLu {
    pattern: Pattern,
    /// Values of the matrix to factorize, in pattern order; filled by the caller.
    pub values: Vec<f64>,
    lu: Lu,
    factors: LuFactors,
    factored: bool,
    factorizations: usize,
}

impl SparseLu {
    /// Symbolic analysis of `pattern`; `name` labels the matrix in errors.
    pub fn new(name: &'static str, pattern: Pattern) -> Result<Self, Error> {
        let lu = Lu::new(name, pattern.borrowed())?;
        Ok(Self {
            values: vec![0.0; pattern.nnz()],
            factors: lu.factors(),
            lu,
            pattern,
            factored: false,
            factorizations: 0,
        })
    }

    /// Number of numeric factorizations done.
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    /// Numeric factorization of the current `values`; false when structurally singular
    /// or when a value is not finite.
    pub fn factor(&mut self) -> bool {
        self.factored = false;
        if !self.values.iter().all(|v| v.is_finite()) {
            return false;
        }
        self.factorizations += 1;
        self.factored = self
            .lu
            .factorize(self.pattern.borrowed(), &self.values, &mut self.factors);
        self.factored
    }

    /// Solves in place with the last factorization; false when the solution is not finite
    /// (partial pivoting reports an exactly singular matrix only this way).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> bool {
        if !self.factored {
            return false;
        }
        self.lu.solve_in_place(&self.factors, rhs);
        rhs.iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lu_solves_small_unsymmetric_system() {
        // [[2, 1, 0], [0, 3, 1], [1, 0, 4]] x = b
        let cols = vec![vec![0, 2], vec![0, 1], vec![1, 2]];
        let p = Pattern::from_columns(3, cols);
        let mut lu = SparseLu::new("test", p).unwrap();
        let dense = [[2.0, 1.0, 0.0], [0.0, 3.0, 1.0], [1.0, 0.0, 4.0]];
        for c in 0..3 {
            for k in lu.pattern.colptr[c]..lu.pattern.colptr[c + 1] {
                let r = lu.pattern.rowind[k];
                lu.values[k] = dense[r][c];
            }
        }
        assert!(lu.factor());
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| dense[i][j] * x[j]).sum())
            .collect();
        assert!(lu.solve_in_place(&mut b));
        for i in 0..3 {
            assert!((b[i] - x[i]).abs() < 1e-14);
        }
        // An exactly singular matrix is reported (by the factorization or the solve).
        lu.values.fill(0.0);
        let mut b = vec![1.0; 3];
        assert!(!(lu.factor() && lu.solve_in_place(&mut b)));
    }
}
