//! Groups of rows of a constraint matrix over the velocities they reach: a contact's three
//! columns of H, a joint's column of G. Each group keeps its rows of `A^T` and of
//! `(M^-1 A)^T` densely over its reach (the unknowns of the blocks of M its columns touch),
//! which is all a sweep reads and writes for it.

use crate::csc::CscMatrix;
use crate::linsys::BlockDiagonal;

/// `ROWS` rows per group: 3 for contacts, 1 for joint rows (a constant, so that a sweep's
/// loops over them unroll).
pub(super) struct RowGroups<const ROWS: usize> {
    /// Group `g` reaches the velocities `reach[start[g]..start[g + 1]]`, whole blocks of M
    /// in the blocks' order.
    start: Vec<usize>,
    reach: Vec<usize>,
    /// Group `g`'s rows of `A^T` over its reach, one after the other from
    /// `ROWS * start[g]`; `minv_a` the same for `(M^-1 A)^T`.
    a_t: Vec<f64>,
    minv_a: Vec<f64>,
}

impl<const ROWS: usize> Default for RowGroups<ROWS> {
    /// No group.
    fn default() -> Self {
        Self {
            start: vec![0],
            reach: Vec::new(),
            a_t: Vec::new(),
            minv_a: Vec::new(),
        }
    }
}

impl<const ROWS: usize> RowGroups<ROWS> {
    /// The groups of `ROWS` consecutive columns of `a` (`n x ROWS groups`), over the blocks
    /// of `mass`. Values are taken by [`RowGroups::take_values`].
    pub fn new(a: &CscMatrix, mass: &BlockDiagonal) -> Self {
        let mut groups = Self::default();
        groups.refit(a, mass);
        groups
    }

    /// Becomes [`RowGroups::new`]`(a, mass)` in the memory it holds.
    pub fn refit(&mut self, a: &CscMatrix, mass: &BlockDiagonal) {
        let rows = ROWS;
        let groups = a.ncols() / rows;
        let (start, reach) = (&mut self.start, &mut self.reach);
        start.clear();
        start.push(0);
        reach.clear();
        // A group touches one or two bodies: a linear search beats sorting its entries.
        let mut touched: Vec<usize> = Vec::new();
        for g in 0..groups {
            touched.clear();
            for d in 0..rows {
                for (i, _) in a.col(rows * g + d) {
                    let b = mass.block_containing(i);
                    if !touched.contains(&b) {
                        touched.push(b);
                    }
                }
            }
            touched.sort_unstable();
            for &b in &touched {
                reach.extend_from_slice(mass.block(b));
            }
            start.push(reach.len());
        }
        let len = rows * reach.len();
        for x in [&mut self.a_t, &mut self.minv_a] {
            x.clear();
            x.resize(len, 0.0);
        }
    }

    /// Number of groups.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// Takes `a`'s values and computes `M^-1 A` with the inverses of `mass`'s blocks
    /// ([`BlockDiagonal::invert`] done); `position` is work space over the velocities.
    pub fn take_values(&mut self, a: &CscMatrix, mass: &BlockDiagonal, position: &mut [usize]) {
        let rows = ROWS;
        for g in 0..self.len() {
            let (from, to) = (self.start[g], self.start[g + 1]);
            let len = to - from;
            for (k, &i) in self.reach[from..to].iter().enumerate() {
                position[i] = k;
            }
            let span = rows * from..rows * to;
            let (a_t, minv_a) = (&mut self.a_t[span.clone()], &mut self.minv_a[span]);
            a_t.fill(0.0);
            for d in 0..rows {
                for (i, x) in a.col(rows * g + d) {
                    a_t[d * len + position[i]] = x;
                }
            }
            let mut k = 0;
            while k < len {
                let b = mass.block_containing(self.reach[from + k]);
                let size = mass.block(b).len();
                for d in 0..rows {
                    let at = d * len + k..d * len + k + size;
                    mass.mul_block_inverse(b, &a_t[at.clone()], &mut minv_a[at]);
                }
                k += size;
            }
        }
    }

    /// `A_g^T M^-1 A_g`, `ROWS x ROWS`, row-major (in the top left of a 3 x 3 array).
    pub fn delassus(&self, g: usize) -> [f64; 9] {
        let (from, to) = (self.start[g], self.start[g + 1]);
        let len = to - from;
        let (a_t, minv_a) = (
            &self.a_t[ROWS * from..ROWS * to],
            &self.minv_a[ROWS * from..ROWS * to],
        );
        let mut w = [0.0; 9];
        for a in 0..ROWS {
            for b in 0..ROWS {
                let (x, y) = (
                    &a_t[a * len..(a + 1) * len],
                    &minv_a[b * len..(b + 1) * len],
                );
                w[3 * a + b] = x.iter().zip(y).map(|(x, y)| x * y).sum();
            }
        }
        w
    }

    /// `A_g^T v`.
    #[inline]
    pub fn apply(&self, g: usize, v: &[f64]) -> [f64; ROWS] {
        let (from, to) = (self.start[g], self.start[g + 1]);
        let (len, reach) = (to - from, &self.reach[from..to]);
        let a_t = &self.a_t[ROWS * from..ROWS * to];
        std::array::from_fn(|d| {
            let row = &a_t[d * len..(d + 1) * len];
            row.iter().zip(reach).map(|(a, &i)| a * v[i]).sum()
        })
    }

    /// `v += M^-1 A_g x`.
    #[inline]
    pub fn add(&self, g: usize, x: [f64; ROWS], v: &mut [f64]) {
        let (from, to) = (self.start[g], self.start[g + 1]);
        let (len, reach) = (to - from, &self.reach[from..to]);
        let minv_a = &self.minv_a[ROWS * from..ROWS * to];
        // One pass over the reach: each velocity is read and written once (a pass per row
        // cost the sweeps 40%).
        for (k, &i) in reach.iter().enumerate() {
            let mut sum = 0.0;
            for (d, &xd) in x.iter().enumerate() {
                sum += minv_a[d * len + k] * xd;
            }
            v[i] += sum;
        }
    }
}
