//! Symmetric positive definite matrices made of small dense blocks on the diagonal, each
//! factorized on its own, with no sparse analysis, no assembly and no ordering: an engine's
//! mass matrix (a rigid body's 6 x 6 block, a particle's 3 x 3 or diagonal), the block
//! Jacobi preconditioner of the conjugate gradients (one process's and the distributed
//! one), the free bodies' M, a small island's M. A new solver checks M in microseconds.

use crate::csc::CscMatrix;
use crate::dense::{cholesky, cholesky_solve, is_symmetric, spd_inverse};
use crate::disjoint_sets::DisjointSets;
use crate::tuning::DENSE_MAX;
use crate::types::Error;
use std::ops::Range;

/// Dense blocks on the diagonal of a matrix, of at most [`DENSE_MAX`] unknowns each, and
/// their factors. Block `b` holds the unknowns `index[start[b]..start[b + 1]]`, ascending;
/// its column-major matrix and its factor sit at `offset[b]..offset[b + 1]`.
#[derive(Debug, Clone)]
pub struct BlockDiagonal {
    index: Vec<usize>,
    start: Vec<usize>,
    offset: Vec<usize>,
    /// The block of each unknown, and its position there.
    block_of: Vec<usize>,
    position: Vec<usize>,
    /// The blocks hold the unknowns in order (`index` is `0..n`).
    in_order: bool,
    /// The blocks' matrices, as taken.
    matrix: Vec<f64>,
    /// Their Cholesky factors ([`BlockDiagonal::cholesky`]) or inverses
    /// ([`BlockDiagonal::invert`]).
    factor: Vec<f64>,
    /// One block's `matrix + rho shift`, while it is inverted.
    scratch: Vec<f64>,
    refactorizations: usize,
}

impl BlockDiagonal {
    /// The blocks of `m` (square) when its graph's connected components are ranges of
    /// consecutive indices of at most [`DENSE_MAX`]; `None` otherwise. Nothing is
    /// factorized yet.
    pub fn of(m: &CscMatrix) -> Option<Self> {
        let (blocks, split) = Self::components_of(m, DENSE_MAX);
        (!split && blocks.in_order).then_some(blocks)
    }

    /// The connected components of the graph on `0..n` whose edges are `edges` (a matrix
    /// entry joins its row and its column, whether or not its mirror is stored) as blocks,
    /// in the order of their smallest unknown; a component of more than `max` unknowns
    /// (at most [`DENSE_MAX`]) is split into blocks of one. Also says whether one was.
    pub fn components(
        n: usize,
        max: usize,
        edges: impl IntoIterator<Item = (usize, usize)>,
    ) -> (Self, bool) {
        assert!(max <= DENSE_MAX, "blocks of at most DENSE_MAX unknowns");
        let mut sets = DisjointSets::new(n);
        for (i, j) in edges {
            sets.union(i, j);
        }
        // Each component's members in order, components by their first member.
        let mut component_of_root = vec![usize::MAX; n];
        let mut members: Vec<Vec<usize>> = Vec::new();
        for i in 0..n {
            let root = sets.find(i);
            if component_of_root[root] == usize::MAX {
                component_of_root[root] = members.len();
                members.push(Vec::new());
            }
            members[component_of_root[root]].push(i);
        }
        let mut sizes = Vec::with_capacity(members.len());
        let mut index = Vec::with_capacity(n);
        let mut split = false;
        for component in members {
            if component.len() <= max {
                sizes.push(component.len());
            } else {
                split = true;
                sizes.extend(std::iter::repeat_n(1, component.len()));
            }
            index.extend(component);
        }
        (Self::new(index, &sizes), split)
    }

    /// The components of `m`'s graph as blocks (see [`BlockDiagonal::components`]).
    pub fn components_of(m: &CscMatrix, max: usize) -> (Self, bool) {
        Self::components(m.ncols(), max, entries(m))
    }

    /// Blocks of consecutive unknowns of the sizes given, each 1 to [`DENSE_MAX`] (a
    /// distributed part's bodies).
    #[cfg(any(feature = "mpi", test))]
    pub fn consecutive(sizes: &[usize]) -> Self {
        assert!(
            sizes.iter().all(|&k| (1..=DENSE_MAX).contains(&k)),
            "blocks of 1 to DENSE_MAX unknowns"
        );
        Self::new((0..sizes.iter().sum()).collect(), sizes)
    }

    /// Makes this one block of `n <= DENSE_MAX` unknowns (none for `n = 0`), keeping the
    /// storage (a small island's M, on the storage its thread shares with other islands).
    pub fn reshape_one(&mut self, n: usize) {
        assert!(n <= DENSE_MAX, "blocks of at most DENSE_MAX unknowns");
        let sizes: &[usize] = if n == 0 { &[] } else { &[n] };
        self.index.clear();
        self.index.extend(0..n);
        self.set_sizes(sizes);
    }

    /// The blocks of `sizes` over `index` (the unknowns block after block).
    fn new(index: Vec<usize>, sizes: &[usize]) -> Self {
        let mut blocks = Self {
            index,
            start: Vec::with_capacity(sizes.len() + 1),
            offset: Vec::with_capacity(sizes.len() + 1),
            block_of: Vec::new(),
            position: Vec::new(),
            in_order: true,
            matrix: Vec::new(),
            factor: Vec::new(),
            scratch: Vec::new(),
            refactorizations: 0,
        };
        blocks.set_sizes(sizes);
        blocks
    }

    /// Starts, offsets, the maps and the storage of blocks of `sizes` over `self.index`.
    fn set_sizes(&mut self, sizes: &[usize]) {
        let n = self.index.len();
        self.start.clear();
        self.start.push(0);
        self.offset.clear();
        self.offset.push(0);
        self.block_of.resize(n, 0);
        self.position.resize(n, 0);
        for (b, &k) in sizes.iter().enumerate() {
            let first = self.start[b];
            for (pos, &i) in self.index[first..first + k].iter().enumerate() {
                self.block_of[i] = b;
                self.position[i] = pos;
            }
            self.start.push(first + k);
            self.offset.push(self.offset[b] + k * k);
        }
        self.in_order = self.index.iter().enumerate().all(|(k, &i)| k == i);
        let size = self.offset[sizes.len()];
        self.matrix.resize(size, 0.0);
        self.factor.resize(size, 0.0);
        // The inversions do not allocate.
        let largest = sizes.iter().max().map_or(0, |k| k * k);
        self.scratch.reserve(largest);
    }

    /// Whether `other` has the same blocks: the same unknowns in each, in the same order.
    pub fn same_blocks(&self, other: &BlockDiagonal) -> bool {
        self.start == other.start && self.index == other.index
    }

    /// Number of blocks.
    pub fn block_count(&self) -> usize {
        self.start.len() - 1
    }

    /// The unknowns of block `b`, ascending.
    pub fn block(&self, b: usize) -> &[usize] {
        &self.index[self.start[b]..self.start[b + 1]]
    }

    /// The block that holds unknown `i`.
    pub fn block_containing(&self, i: usize) -> usize {
        self.block_of[i]
    }

    /// How many unknowns the blocks before `b` hold.
    pub fn unknowns_before(&self, b: usize) -> usize {
        self.start[b]
    }

    /// Whether the blocks hold the unknowns in order, so that a run of blocks is a range
    /// of unknowns.
    pub fn in_order(&self) -> bool {
        self.in_order
    }

    /// Where entry `(i, j)` sits in the blocks' storage (that of [`BlockDiagonal::matrix_mut`]
    /// and of arrays laid out alike), if both are in one block.
    pub fn slot(&self, i: usize, j: usize) -> Option<usize> {
        let b = self.block_of[i];
        if self.block_of[j] != b {
            return None;
        }
        let k = self.start[b + 1] - self.start[b];
        Some(self.offset[b] + self.position[j] * k + self.position[i])
    }

    /// Entries the blocks store: the length of an array laid out as their matrices.
    pub fn entries(&self) -> usize {
        self.matrix.len()
    }

    /// The blocks' matrices, column-major, block after block (for a caller that fills them).
    pub fn matrix_mut(&mut self) -> &mut [f64] {
        &mut self.matrix
    }

    /// Takes `m`'s entries in the blocks as they are (entries outside the blocks are left
    /// out), for [`BlockDiagonal::is_symmetric`] to judge.
    pub fn take_values(&mut self, m: &CscMatrix) {
        self.matrix.fill(0.0);
        for j in 0..m.ncols() {
            for (i, v) in m.col(j) {
                if let Some(at) = self.slot(i, j) {
                    self.matrix[at] = v;
                }
            }
        }
    }

    /// Takes the symmetric part `(M + M^T) / 2` of `m`'s blocks (both triangles add half of
    /// each entry); entries outside the blocks are left out.
    pub fn take_symmetric_part(&mut self, m: &CscMatrix) {
        self.matrix.fill(0.0);
        for j in 0..m.ncols() {
            for (i, v) in m.col(j) {
                if let Some(at) = self.slot(i, j) {
                    self.matrix[at] += 0.5 * v;
                    let mirror = self.slot(j, i).expect("same block");
                    self.matrix[mirror] += 0.5 * v;
                }
            }
        }
    }

    /// Replaces each pair of mirror entries of the matrices taken by their mean.
    pub fn symmetrize(&mut self) {
        for b in 0..self.block_count() {
            let k = self.start[b + 1] - self.start[b];
            let m = &mut self.matrix[self.offset[b]..self.offset[b + 1]];
            for j in 0..k {
                for i in 0..j {
                    let s = 0.5 * (m[j * k + i] + m[i * k + j]);
                    (m[j * k + i], m[i * k + j]) = (s, s);
                }
            }
        }
    }

    /// Whether every block's matrix is symmetric (see [`is_symmetric`]).
    pub fn is_symmetric(&self) -> bool {
        (0..self.block_count()).all(|b| {
            let k = self.start[b + 1] - self.start[b];
            is_symmetric(&self.matrix[self.offset[b]..self.offset[b + 1]], k)
        })
    }

    /// Takes the symmetric part of `m` (the matrix the blocks came from, or one with its
    /// pattern) and factorizes it; fails when a block is not positive definite (`name`
    /// labels the error).
    pub fn factorize(&mut self, name: &'static str, m: &CscMatrix) -> Result<(), Error> {
        self.take_symmetric_part(m);
        self.cholesky(name)
    }

    /// The Cholesky factor of each block's matrix (its lower triangle is read); fails when
    /// a block is not positive definite (`name` labels the error).
    pub fn cholesky(&mut self, name: &'static str) -> Result<(), Error> {
        self.factor.copy_from_slice(&self.matrix);
        for b in 0..self.block_count() {
            let k = self.start[b + 1] - self.start[b];
            if !cholesky(&mut self.factor[self.offset[b]..self.offset[b + 1]], k) {
                return Err(Error::NotPositiveDefinite { field: name });
            }
        }
        self.refactorizations += 1;
        Ok(())
    }

    /// The inverse of each block's `matrix + rho shift` (`shift` laid out as the
    /// matrices); the first block that is not positive definite when one is.
    pub fn invert(&mut self, rho: f64, shift: &[f64]) -> Result<(), usize> {
        for b in 0..self.block_count() {
            let k = self.start[b + 1] - self.start[b];
            let blocks = self.offset[b]..self.offset[b + 1];
            self.scratch.clear();
            self.scratch.extend(
                self.matrix[blocks.clone()]
                    .iter()
                    .zip(&shift[blocks.clone()])
                    .map(|(m, s)| m + rho * s),
            );
            if !spd_inverse(&mut self.scratch, k, &mut self.factor[blocks]) {
                return Err(b);
            }
        }
        self.refactorizations += 1;
        Ok(())
    }

    /// Solves `A x = rhs` in place with the Cholesky factors (`rhs` over all unknowns).
    pub fn solve_in_place(&self, rhs: &mut [f64]) {
        let mut gathered = [0.0; DENSE_MAX];
        for b in 0..self.block_count() {
            let (idx, factor) = (
                self.block(b),
                &self.factor[self.offset[b]..self.offset[b + 1]],
            );
            let k = idx.len();
            if self.in_order {
                cholesky_solve(factor, k, &mut rhs[idx[0]..idx[0] + k]);
                continue;
            }
            for (g, &i) in gathered.iter_mut().zip(idx) {
                *g = rhs[i];
            }
            cholesky_solve(factor, k, &mut gathered[..k]);
            for (g, &i) in gathered.iter().zip(idx) {
                rhs[i] = *g;
            }
        }
    }

    /// `y = A_b^-1 x` with block `b`'s inverse from [`BlockDiagonal::invert`], `x` and `y`
    /// over the block's own unknowns.
    pub fn mul_block_inverse(&self, b: usize, x: &[f64], y: &mut [f64]) {
        dense_product(&self.factor[self.offset[b]..self.offset[b + 1]], x, y);
    }

    /// `y = A x` with the matrices taken (`x` and `y` over all unknowns).
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        self.product(&self.matrix, 0..self.block_count(), x, y);
    }

    /// `z = A^-1 r` with the inverses of [`BlockDiagonal::invert`] over the blocks
    /// `blocks`: `r` over all unknowns, `z` over all of them too, or, when the blocks are
    /// in order, over the unknowns of `blocks` only.
    pub fn mul_inverse(&self, blocks: Range<usize>, r: &[f64], z: &mut [f64]) {
        self.product(&self.factor, blocks, r, z);
    }

    /// Refactorizations so far.
    pub fn refactorizations(&self) -> usize {
        self.refactorizations
    }

    /// `y = A x` with `A` the blocks of `of` (the matrices or the inverses) over `blocks`;
    /// when the blocks are in order, `y` starts at the first unknown of `blocks`.
    fn product(&self, of: &[f64], blocks: Range<usize>, x: &[f64], y: &mut [f64]) {
        let shift = if self.in_order {
            self.start[blocks.start]
        } else {
            0
        };
        for b in blocks {
            let (idx, a) = (self.block(b), &of[self.offset[b]..self.offset[b + 1]]);
            let (first, k) = (idx[0], idx.len());
            if idx[k - 1] == first + k - 1 {
                // Consecutive unknowns (a body's): a product over slices.
                let at = first - shift;
                dense_product(a, &x[first..first + k], &mut y[at..at + k]);
                continue;
            }
            for &i in idx {
                y[i - shift] = 0.0;
            }
            for (column, &j) in a.chunks_exact(k).zip(idx) {
                let xj = x[j];
                for (aij, &i) in column.iter().zip(idx) {
                    y[i - shift] += aij * xj;
                }
            }
        }
    }
}

impl Default for BlockDiagonal {
    /// No block.
    fn default() -> Self {
        Self::new(Vec::new(), &[])
    }
}

/// The stored entries of `m`, as (row, column).
fn entries(m: &CscMatrix) -> impl Iterator<Item = (usize, usize)> + '_ {
    (0..m.ncols()).flat_map(move |j| m.col(j).map(move |(i, _)| (i, j)))
}

/// `y = A x` for a dense column-major square block `A`, at fixed sizes for a rigid body's
/// blocks: its six velocities together, or a mass (1 x 1, three times) and an inertia
/// (3 x 3) when M's pattern separates them.
fn dense_product(a: &[f64], x: &[f64], y: &mut [f64]) {
    match x.len() {
        1 => y[0] = a[0] * x[0],
        3 => block_product::<3>(a, x, y),
        6 => block_product::<6>(a, x, y),
        k => {
            y.fill(0.0);
            for (column, &xj) in a.chunks_exact(k).zip(x) {
                for (yi, aij) in y.iter_mut().zip(column) {
                    *yi += aij * xj;
                }
            }
        }
    }
}

/// `z = A r` for a dense column-major `K x K` block `A`.
fn block_product<const K: usize>(a: &[f64], r: &[f64], z: &mut [f64]) {
    let (a, r, z): (&[f64], &[f64; K], &mut [f64; K]) = (
        &a[..K * K],
        r.try_into().expect("K entries"),
        z.try_into().expect("K entries"),
    );
    *z = [0.0; K];
    for j in 0..K {
        for i in 0..K {
            z[i] += a[j * K + i] * r[j];
        }
    }
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

    /// A rigid body's M as an engine writes it (masses 1 x 1, the inertia 3 x 3) beside a
    /// body's whole 6 x 6 block: the inverse applied whole and block by block (the
    /// fixed-size paths) against nalgebra's inverse of the dense matrix.
    #[test]
    fn rigid_body_blocks_apply_their_inverses() {
        let n = 12;
        let mut t = vec![(0, 0, 2.0), (1, 1, 2.0), (2, 2, 2.0)];
        #[rustfmt::skip]
        let inertia = [[0.9, 0.1, -0.05], [0.1, 0.7, 0.02], [-0.05, 0.02, 0.5]];
        for (i, row) in inertia.iter().enumerate() {
            for (j, &x) in row.iter().enumerate() {
                t.push((3 + i, 3 + j, x));
            }
        }
        for i in 0..6 {
            for j in 0..6 {
                let x = if i == j {
                    3.0 + i as f64
                } else {
                    0.2 / (1 + i + j) as f64
                };
                t.push((6 + i, 6 + j, x));
            }
        }
        let m = CscMatrix::from_triplets("M", n, n, &t).unwrap();
        let mut blocks = BlockDiagonal::of(&m).expect("blocks");
        assert_eq!(blocks.start, [0, 1, 2, 3, 6, 12]);
        blocks.take_values(&m);
        blocks.invert(0.0, &vec![0.0; blocks.entries()]).unwrap();
        let dense = nalgebra::DMatrix::from_column_slice(n, n, &m.to_dense());
        let inverse = dense.try_inverse().expect("M is invertible");
        let x: Vec<f64> = (0..n).map(|i| 1.0 - 0.3 * i as f64).collect();
        let want = &inverse * nalgebra::DVector::from_column_slice(&x);
        let mut whole = vec![0.0; n];
        blocks.mul_inverse(0..blocks.block_count(), &x, &mut whole);
        for b in 0..blocks.block_count() {
            let idx = blocks.block(b).to_vec();
            let xb: Vec<f64> = idx.iter().map(|&i| x[i]).collect();
            let mut yb = vec![0.0; idx.len()];
            blocks.mul_block_inverse(b, &xb, &mut yb);
            for (k, &i) in idx.iter().enumerate() {
                assert!(
                    (yb[k] - want[i]).abs() <= 1e-14,
                    "block {b}: {} against {}",
                    yb[k],
                    want[i]
                );
                assert!(
                    (whole[i] - want[i]).abs() <= 1e-14,
                    "whole: {} against {}",
                    whole[i],
                    want[i]
                );
            }
        }
    }

    /// `y = A x` of a dense column-major `n x n` matrix.
    fn dense_mul(a: &[f64], n: usize, x: &[f64]) -> Vec<f64> {
        (0..n)
            .map(|i| (0..n).map(|j| a[i + j * n] * x[j]).sum())
            .collect()
    }

    /// Blocks that interleave (`{0, 3}` and `{1, 2}`): products, solves and inverses
    /// against the dense matrix; the inverse applied a run of blocks at a time matches it
    /// applied whole when the blocks are in order.
    #[test]
    fn interleaved_blocks_solve_multiply_and_invert() {
        let n = 4;
        #[rustfmt::skip]
        let a = [
            4.0, 0.0, 0.0, 1.0,
            0.0, 3.0, -1.0, 0.0,
            0.0, -1.0, 2.0, 0.0,
            1.0, 0.0, 0.0, 5.0,
        ];
        let (mut blocks, split) = BlockDiagonal::components(n, 2, [(3, 0), (1, 2)]);
        assert!(!split && !blocks.in_order());
        assert_eq!(
            (blocks.block(0), blocks.block(1)),
            (&[0, 3][..], &[1, 2][..])
        );
        blocks.matrix_mut().fill(0.0);
        for j in 0..n {
            for i in 0..n {
                if let Some(at) = blocks.slot(i, j) {
                    blocks.matrix_mut()[at] = a[i + j * n];
                }
            }
        }
        assert!(blocks.is_symmetric());
        let x = [1.0, -2.0, 0.5, 3.0];
        let mut y = [0.0; 4];
        blocks.mul(&x, &mut y);
        assert_eq!(y.to_vec(), dense_mul(&a, n, &x));
        blocks.cholesky("A").unwrap();
        blocks.solve_in_place(&mut y);
        for (got, want) in y.iter().zip(x) {
            assert!((got - want).abs() <= 1e-14, "{got} against {want}");
        }
        // (A + 2 I)^-1, through the shift I.
        let mut identity = vec![0.0; blocks.entries()];
        for i in 0..n {
            identity[blocks.slot(i, i).unwrap()] = 1.0;
        }
        blocks.invert(2.0, &identity).unwrap();
        let mut b = dense_mul(&a, n, &x);
        for (bi, xi) in b.iter_mut().zip(x) {
            *bi += 2.0 * xi;
        }
        let mut z = [0.0; 4];
        blocks.mul_inverse(0..2, &b, &mut z);
        for (got, want) in z.iter().zip(x) {
            assert!((got - want).abs() <= 1e-14, "{got} against {want}");
        }
        assert_eq!(blocks.refactorizations(), 2);
        // Blocks in order, the inverse applied block by block into slices.
        let mut blocks = BlockDiagonal::consecutive(&[1, 2]);
        blocks
            .matrix_mut()
            .copy_from_slice(&[2.0, 4.0, 1.0, 1.0, 3.0]);
        blocks.invert(0.0, &[0.0; 5]).unwrap();
        let r = [1.0, 2.0, 3.0];
        let mut whole = [0.0; 3];
        blocks.mul_inverse(0..2, &r, &mut whole);
        let mut parts = [0.0; 3];
        let (first, second) = parts.split_at_mut(blocks.unknowns_before(1));
        blocks.mul_inverse(0..1, &r, first);
        blocks.mul_inverse(1..2, &r, second);
        assert_eq!(whole, parts);
        // An indefinite block is named by its number.
        blocks.matrix_mut()[0] = -1.0;
        assert_eq!(blocks.invert(0.0, &[0.0; 5]), Err(0));
    }

    /// One block reshaped for islands of several sizes; the symmetric part is taken in
    /// place.
    #[test]
    fn one_block_is_reshaped_and_symmetrized() {
        let mut blocks = BlockDiagonal::default();
        assert_eq!(blocks.block_count(), 0);
        blocks.reshape_one(2);
        blocks.matrix_mut().copy_from_slice(&[2.0, 1.0, 0.0, 3.0]);
        assert!(!blocks.is_symmetric());
        blocks.symmetrize();
        let mut x = [2.5, 3.5];
        blocks.cholesky("M").unwrap();
        blocks.solve_in_place(&mut x);
        for (got, want) in x.iter().zip([1.0, 1.0]) {
            assert!((got - want).abs() <= 1e-14, "{got} against {want}");
        }
        blocks.reshape_one(0);
        assert_eq!((blocks.block_count(), blocks.entries()), (0, 0));
        blocks.cholesky("M").unwrap();
        blocks.reshape_one(3);
        assert_eq!((blocks.block(0), blocks.entries()), (&[0, 1, 2][..], 9));
    }
}
