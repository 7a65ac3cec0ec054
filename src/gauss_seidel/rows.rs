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
    /// Group `g` holds columns `ROWS * source[g]..ROWS * (source[g] + 1)` of A.
    source: Vec<usize>,
    /// Work space of the interleaving: each column group's rank, and how many groups
    /// have each rank.
    rank: Vec<usize>,
    count: Vec<usize>,
}

impl<const ROWS: usize> Default for RowGroups<ROWS> {
    /// No group.
    fn default() -> Self {
        Self {
            start: vec![0],
            reach: Vec::new(),
            a_t: Vec::new(),
            minv_a: Vec::new(),
            source: Vec::new(),
            rank: Vec::new(),
            count: Vec::new(),
        }
    }
}

impl<const ROWS: usize> RowGroups<ROWS> {
    /// The groups of `ROWS` consecutive columns of `a` (`n x ROWS groups`), over the blocks
    /// of `mass`, in the columns' order or interleaved ([`RowGroups::refit`]). Values are
    /// taken by [`RowGroups::take_values`].
    pub fn new(a: &CscMatrix, mass: &BlockDiagonal, interleave: bool) -> Self {
        let mut groups = Self::default();
        groups.refit(a, mass, interleave);
        groups
    }

    /// Becomes [`RowGroups::new`] in the memory it holds. `interleave` stores first each
    /// pair of bodies' first group, then their second, and so on: consecutive groups of a
    /// sweep then rarely share a body, so that one need not wait for the velocities the one
    /// before it has just written (an engine lists a manifold's points one after the
    /// other, each on the same two bodies).
    pub fn refit(&mut self, a: &CscMatrix, mass: &BlockDiagonal, interleave: bool) {
        let rows = ROWS;
        let groups = a.ncols() / rows;
        // The first and last block of a group's first column: which bodies it couples (the
        // interleaving's key only; the reach below reads every column).
        let bodies = |g: usize| {
            let mut column = a.col(rows * g).map(|(i, _)| mass.block_containing(i));
            let first = column.next();
            (first, column.last().or(first))
        };
        self.source.clear();
        if interleave {
            // A group's rank: its place in a run of consecutive groups on the same bodies
            // (a manifold's points); then the groups by rank, each rank in the columns'
            // order (a counting sort).
            let (rank, count) = (&mut self.rank, &mut self.count);
            rank.clear();
            count.clear();
            let mut previous = None;
            for g in 0..groups {
                let pair = bodies(g);
                let r = match previous == Some(pair) {
                    true => rank[g - 1] + 1,
                    false => 0,
                };
                previous = Some(pair);
                rank.push(r);
                if count.len() <= r {
                    count.resize(r + 1, 0);
                }
                count[r] += 1;
            }
            let mut next = 0;
            for c in count.iter_mut() {
                (*c, next) = (next, next + *c);
            }
            self.source.resize(groups, 0);
            for (g, &r) in rank.iter().enumerate() {
                self.source[count[r]] = g;
                count[r] += 1;
            }
        } else {
            self.source.extend(0..groups);
        }
        let (start, reach) = (&mut self.start, &mut self.reach);
        start.clear();
        start.push(0);
        reach.clear();
        // A group touches one or two bodies: a linear search beats sorting its entries.
        let mut touched: Vec<usize> = Vec::new();
        for &g in &self.source {
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
        // Sized, not cleared: `take_values` writes every value (zeroing them here cost a
        // tenth of rebuilding the sweeps of a 900-contact wall step).
        let len = rows * reach.len();
        for x in [&mut self.a_t, &mut self.minv_a] {
            x.resize(len, 0.0);
        }
    }

    /// The group of A's columns stored as group `g`.
    #[inline]
    pub fn source(&self, g: usize) -> usize {
        self.source[g]
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
                for (i, x) in a.col(rows * self.source[g] + d) {
                    a_t[d * len + position[i]] = x;
                }
            }
            for (b, k) in blocks(&self.reach[from..to], mass) {
                let size = mass.block(b).len();
                for d in 0..rows {
                    let at = d * len + k..d * len + k + size;
                    mass.mul_block_inverse(b, &a_t[at.clone()], &mut minv_a[at]);
                }
            }
        }
    }

    /// The velocities group `g` reaches (whole blocks of M, ascending).
    pub fn reach(&self, g: usize) -> &[usize] {
        &self.reach[self.start[g]..self.start[g + 1]]
    }

    /// All groups' rows of `A^T` and `(M^-1 A)^T`, one after the other: group `g`'s `d`-th
    /// row over its reach starts at `ROWS * offset(g) + d * reach length`.
    pub fn values(&self) -> (&[f64], &[f64]) {
        (&self.a_t, &self.minv_a)
    }

    /// Where group `g`'s values start in [`RowGroups::values`], over `ROWS`.
    pub fn offset(&self, g: usize) -> usize {
        self.start[g]
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
        let (reach, a_t) = (&self.reach[from..to], &self.a_t[ROWS * from..ROWS * to]);
        // A group between two rigid bodies reaches 12 velocities, one between a body and a
        // fixed one 6: at those lengths the loops unroll and each velocity is read once for
        // all rows (with the sums split in two, a third more sweeps a second on Bullet's
        // scenes).
        match reach.len() {
            12 => apply_fixed::<ROWS, 12, 2>(a_t, reach, v),
            6 => apply_fixed::<ROWS, 6, 2>(a_t, reach, v),
            len => std::array::from_fn(|d| {
                let row = &a_t[d * len..(d + 1) * len];
                row.iter().zip(reach).map(|(a, &i)| a * v[i]).sum()
            }),
        }
    }

    /// `v += M^-1 A_g x`.
    #[inline]
    pub fn add(&self, g: usize, x: [f64; ROWS], v: &mut [f64]) {
        let (from, to) = (self.start[g], self.start[g + 1]);
        let (reach, minv_a) = (&self.reach[from..to], &self.minv_a[ROWS * from..ROWS * to]);
        match reach.len() {
            12 => add_fixed::<ROWS, 12>(minv_a, reach, x, v),
            6 => add_fixed::<ROWS, 6>(minv_a, reach, x, v),
            len => {
                // One pass over the reach: each velocity is read and written once (a pass
                // per row cost the sweeps 40%).
                for (k, &i) in reach.iter().enumerate() {
                    let mut sum = 0.0;
                    for (d, &xd) in x.iter().enumerate() {
                        sum += minv_a[d * len + k] * xd;
                    }
                    v[i] += sum;
                }
            }
        }
    }
}

/// [`RowGroups::apply`] over a reach of `N` velocities (`N` a multiple of `LANES`).
#[inline(always)]
fn apply_fixed<const ROWS: usize, const N: usize, const LANES: usize>(
    a_t: &[f64],
    reach: &[usize],
    v: &[f64],
) -> [f64; ROWS] {
    let reach: &[usize; N] = reach.try_into().expect("a reach of N velocities");
    // Gathered by a loop: `reach.map` was not inlined (a call and a copy per row group).
    let mut x = [0.0; N];
    for (x, &i) in x.iter_mut().zip(reach) {
        *x = v[i];
    }
    // Each row summed in LANES interleaved parts: a sweep waits on these sums, and one
    // chain of N dependent additions was its longest wait.
    let mut sums = [[0.0; LANES]; ROWS];
    for k in (0..N).step_by(LANES) {
        for (d, sum) in sums.iter_mut().enumerate() {
            for (j, s) in sum.iter_mut().enumerate() {
                *s += a_t[d * N + k + j] * x[k + j];
            }
        }
    }
    sums.map(|parts| parts.iter().sum())
}

/// [`RowGroups::add`] over a reach of `N` velocities: the same sums in the same order,
/// unrolled (a fifth more sweeps a second on a Bullet wall's step than the loop).
#[inline(always)]
fn add_fixed<const ROWS: usize, const N: usize>(
    minv_a: &[f64],
    reach: &[usize],
    x: [f64; ROWS],
    v: &mut [f64],
) {
    let reach: &[usize; N] = reach.try_into().expect("a reach of N velocities");
    let minv_a: &[f64] = &minv_a[..ROWS * N];
    for (k, &i) in reach.iter().enumerate() {
        let mut sum = 0.0;
        for (d, &xd) in x.iter().enumerate() {
            sum += minv_a[d * N + k] * xd;
        }
        v[i] += sum;
    }
}

/// The blocks of M a reach (whole blocks, ascending) covers, each with its place in it.
pub(super) fn blocks<'a>(
    reach: &'a [usize],
    mass: &'a BlockDiagonal,
) -> impl Iterator<Item = (usize, usize)> + 'a {
    let mut at = 0;
    std::iter::from_fn(move || {
        let b = mass.block_containing(*reach.get(at)?);
        let place = at;
        at += mass.block(b).len();
        Some((b, place))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rigid bodies of 6 velocities each, M's blocks dense: a contact on two bodies reaches
    /// 12 velocities, one on a single body 6 (the unrolled paths), and `apply` and `add`
    /// give `A_g^T v` and `M^-1 A_g x` as dense products with nalgebra's inverse of M do.
    #[test]
    fn unrolled_reaches_match_dense_products() {
        use nalgebra::{DMatrix, DVector};
        let (bodies, n) = (3, 18);
        let mut seed = 11u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut m = DMatrix::<f64>::zeros(n, n);
        for b in 0..bodies {
            let a = DMatrix::<f64>::from_fn(6, 6, |_, _| next());
            let block = &a * a.transpose() + DMatrix::<f64>::identity(6, 6);
            m.view_mut((6 * b, 6 * b), (6, 6)).copy_from(&block);
        }
        // Contacts on bodies (0, 1), (2) and (1, 2): every entry of their columns nonzero.
        let touched: [&[usize]; 3] = [&[0, 1], &[2], &[1, 2]];
        let mut h = DMatrix::<f64>::zeros(n, 9);
        for (c, on) in touched.iter().enumerate() {
            for &b in *on {
                for i in 6 * b..6 * b + 6 {
                    for d in 0..3 {
                        h[(i, 3 * c + d)] = next();
                    }
                }
            }
        }
        let dense = |x: &DMatrix<f64>| {
            let rows: Vec<f64> = x.transpose().iter().copied().collect();
            CscMatrix::from_dense("test", x.nrows(), x.ncols(), &rows).unwrap()
        };
        let (mass_csc, h_csc) = (dense(&m), dense(&h));
        let mut mass = BlockDiagonal::of(&mass_csc).unwrap();
        mass.take_values(&mass_csc);
        mass.invert(0.0, &[0.0; 3 * 36]).unwrap();
        let mut groups = RowGroups::<3>::new(&h_csc, &mass, false);
        groups.take_values(&h_csc, &mass, &mut [0; 18]);
        let m_inv = m.clone().try_inverse().unwrap();
        let v = DVector::<f64>::from_fn(n, |_, _| next());
        let hv = h.transpose() * &v;
        for (c, on) in touched.iter().enumerate() {
            assert_eq!(groups.reach(c).len(), 6 * on.len());
            let applied = groups.apply(c, v.as_slice());
            for d in 0..3 {
                approx::assert_relative_eq!(applied[d], hv[3 * c + d], max_relative = 1e-12);
            }
            let x = [next(), next(), next()];
            let mut added = v.clone();
            groups.add(c, x, added.as_mut_slice());
            let expected = &v + &m_inv * h.columns(3 * c, 3) * DVector::from_row_slice(&x);
            for i in 0..n {
                approx::assert_relative_eq!(added[i], expected[i], epsilon = 1e-12);
            }
        }
    }

    /// Three bodies of one velocity each (M = I); contacts as an engine lists them, a
    /// manifold's points one after the other: three on bodies (0, 1), two on (1, 2), one
    /// on body 2 alone. Interleaved, each pair's first point comes first, then the
    /// seconds, then the third; every group keeps its own column's values.
    #[test]
    fn interleaving_spreads_a_manifolds_points() {
        let bodies: [&[usize]; 6] = [&[0, 1], &[0, 1], &[0, 1], &[1, 2], &[1, 2], &[2]];
        let (mut colptr, mut rowind, mut values) = (vec![0], Vec::new(), Vec::new());
        for (g, touched) in bodies.iter().enumerate() {
            for d in 0..3 {
                for &i in *touched {
                    rowind.push(i);
                    values.push((10 * g + d) as f64 + 0.1 * i as f64);
                }
                colptr.push(rowind.len());
            }
        }
        let h = CscMatrix::new("H", 3, 18, colptr, rowind, values).unwrap();
        let mut mass = BlockDiagonal::of(&CscMatrix::identity(3)).unwrap();
        mass.take_values(&CscMatrix::identity(3));
        mass.invert(0.0, &[0.0; 3]).unwrap();
        for interleave in [false, true] {
            let mut groups = RowGroups::<3>::new(&h, &mass, interleave);
            let order: Vec<usize> = (0..6).map(|g| groups.source(g)).collect();
            let expected = match interleave {
                true => vec![0, 3, 5, 1, 4, 2],
                false => (0..6).collect(),
            };
            assert_eq!(order, expected);
            groups.take_values(&h, &mass, &mut [0; 3]);
            let v = [1.0, 10.0, 100.0];
            for (g, &c) in order.iter().enumerate() {
                let expected: [f64; 3] = std::array::from_fn(|d| {
                    let value = |i: usize| (10 * c + d) as f64 + 0.1 * i as f64;
                    bodies[c].iter().map(|&i| value(i) * v[i]).sum()
                });
                assert_eq!(groups.apply(g, &v), expected, "group {g}, contact {c}");
            }
        }
    }
}
