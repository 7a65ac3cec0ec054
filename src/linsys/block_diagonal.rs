//! The Cholesky factor of the symmetric part of a matrix made of small consecutive
//! diagonal blocks: an engine's mass matrix (a rigid body's 6 x 6 block, a particle's
//! 3 x 3 or diagonal). Each block is factorized densely on its own, with no sparse
//! analysis, no assembly and no ordering: a new solver checks M in microseconds.

use super::DENSE_MAX;
use crate::csc::CscMatrix;
use crate::dense::{cholesky, cholesky_solve};
use crate::disjoint_sets::DisjointSets;
use crate::types::Error;

/// `(M + M^T) / 2 = L L^T` block by block. Block `b` spans the rows and columns
/// `start[b]..start[b + 1]`; its column-major factor sits at `factors[at[b]..]`.
#[derive(Debug, Clone)]
pub struct BlockDiagonal {
    start: Vec<usize>,
    at: Vec<usize>,
    factors: Vec<f64>,
    refactorizations: usize,
}

impl BlockDiagonal {
    /// The blocks of `m` (square) when its graph's connected components are ranges of
    /// consecutive indices of at most [`DENSE_MAX`]; `None` otherwise. Nothing is
    /// factorized yet.
    pub fn of(m: &CscMatrix) -> Option<Self> {
        let (index, start, split) = components(m, DENSE_MAX);
        if split || index.iter().enumerate().any(|(k, &i)| k != i) {
            return None;
        }
        let mut at = vec![0];
        for w in start.windows(2) {
            at.push(at[at.len() - 1] + (w[1] - w[0]) * (w[1] - w[0]));
        }
        Some(Self {
            factors: vec![0.0; at[at.len() - 1]],
            start,
            at,
            refactorizations: 0,
        })
    }

    /// Factorizes the symmetric part of `m` (the matrix the blocks came from, or one with
    /// its pattern); fails when a block is not positive definite (`name` labels the error).
    pub fn factorize(&mut self, name: &'static str, m: &CscMatrix) -> Result<(), Error> {
        self.factors.fill(0.0);
        for b in 0..self.start.len() - 1 {
            let (first, size) = (self.start[b], self.start[b + 1] - self.start[b]);
            let block = &mut self.factors[self.at[b]..self.at[b + 1]];
            for j in first..first + size {
                for (i, v) in m.col(j) {
                    let (r, c) = (i - first, j - first);
                    block[r + c * size] += 0.5 * v;
                    block[c + r * size] += 0.5 * v;
                }
            }
            if !cholesky(block, size) {
                return Err(Error::NotPositiveDefinite { field: name });
            }
        }
        self.refactorizations += 1;
        Ok(())
    }

    /// Solves `(M + M^T) / 2 x = rhs` in place.
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        for b in 0..self.start.len() - 1 {
            let (first, end) = (self.start[b], self.start[b + 1]);
            cholesky_solve(
                &self.factors[self.at[b]..self.at[b + 1]],
                end - first,
                &mut rhs[first..end],
            );
        }
    }

    /// Numeric factorizations done so far.
    pub fn refactorizations(&self) -> usize {
        self.refactorizations
    }
}

/// The connected components of M's graph (an entry joins its row and its column, whether
/// or not its mirror is stored) as blocks, indices ascending within each, components
/// above `max` split into single indices. Returns the indices block after block, each
/// block's start, and whether a component was split.
pub(crate) fn components(m: &CscMatrix, max: usize) -> (Vec<usize>, Vec<usize>, bool) {
    let n = m.ncols();
    let mut sets = DisjointSets::new(n);
    for j in 0..n {
        for (i, _) in m.col(j) {
            sets.union(i, j);
        }
    }
    // Members of each component, in index order.
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n];
    for i in 0..n {
        members[sets.find(i)].push(i);
    }
    let mut index = Vec::with_capacity(n);
    let mut start = vec![0];
    let mut split = false;
    for component in members.into_iter().filter(|c| !c.is_empty()) {
        if component.len() <= max {
            index.extend_from_slice(&component);
            start.push(index.len());
        } else {
            split = true;
            for i in component {
                index.push(i);
                start.push(index.len());
            }
        }
    }
    (index, start, split)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Blocks found where they are, refused where they are not ranges of indices or one is
    /// too large; the solve matches the dense symmetric part's, and an indefinite block
    /// is named.
    #[test]
    fn blocks_factorize_and_solve() {
        // Blocks {0, 1}, {2}, {3, 4, 5}; M not symmetric (its symmetric part is used).
        let t = [
            (0, 0, 4.0),
            (1, 0, 1.0),
            (0, 1, 2.0),
            (1, 1, 3.0),
            (2, 2, 5.0),
            (3, 3, 6.0),
            (5, 3, 1.0),
            (3, 5, 1.0),
            (4, 4, 2.0),
            (5, 5, 7.0),
            (4, 5, 0.5),
        ];
        let m = CscMatrix::from_triplets("M", 6, 6, &t).unwrap();
        let mut blocks = BlockDiagonal::of(&m).expect("three blocks");
        assert_eq!(blocks.start, [0, 2, 3, 6]);
        blocks.factorize("M", &m).unwrap();
        let mut sym = [[0.0; 6]; 6];
        for &(i, j, v) in &t {
            sym[i][j] += 0.5 * v;
            sym[j][i] += 0.5 * v;
        }
        let x = [1.0, -2.0, 0.5, 3.0, -1.0, 2.0];
        let mut b: Vec<f64> = (0..6)
            .map(|i| (0..6).map(|j| sym[i][j] * x[j]).sum())
            .collect();
        blocks.solve_in_place(&mut b);
        for (got, want) in b.iter().zip(x) {
            assert!((got - want).abs() <= 1e-12, "{got} against {want}");
        }
        // An entry joining the first two blocks, stored below or above the diagonal only:
        // one block of three.
        for entry in [(2, 1, 0.1), (1, 2, 0.1)] {
            let mut joined = t.to_vec();
            joined.push(entry);
            let m = CscMatrix::from_triplets("M", 6, 6, &joined).unwrap();
            assert_eq!(BlockDiagonal::of(&m).unwrap().start, [0, 3, 6]);
        }
        // An entry joining the first block to the last: {0, 1, 3, 4, 5} is not a range,
        // refused (the sparse factor takes such a matrix).
        let mut joined = t.to_vec();
        joined.push((0, 5, 0.1));
        let m = CscMatrix::from_triplets("M", 6, 6, &joined).unwrap();
        assert!(BlockDiagonal::of(&m).is_none());
        // One block larger than DENSE_MAX.
        let n = DENSE_MAX + 1;
        let chain: Vec<_> = (0..n)
            .flat_map(|i| [(i, i, 2.0), (i, (i + 1) % n, -0.5)])
            .collect();
        let m = CscMatrix::from_triplets("M", n, n, &chain).unwrap();
        assert!(BlockDiagonal::of(&m).is_none());
        // An indefinite block.
        let m = CscMatrix::from_triplets("M", 2, 2, &[(0, 0, 1.0), (1, 1, -1.0)]).unwrap();
        let mut blocks = BlockDiagonal::of(&m).unwrap();
        assert!(matches!(
            blocks.factorize("M", &m),
            Err(Error::NotPositiveDefinite { field: "M" })
        ));
    }
}
