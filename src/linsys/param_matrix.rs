//! A square sparse matrix affine in a parameter: `A(rho) = base + rho * slope`.

use super::lu::PatternRef;
use crate::csc::CscMatrix;

/// Square matrix `base + rho * slope` on one sparsity pattern (compressed columns,
/// sorted rows). Symmetric matrices keep their upper triangle only.
#[derive(Debug, Clone)]
pub struct ParamMatrix {
    /// Dimension.
    pub n: usize,
    /// Column pointers of the pattern.
    pub colptr: Vec<usize>,
    /// Row indices of the pattern.
    pub rowind: Vec<usize>,
    /// Values at `rho = 0`.
    pub base: Vec<f64>,
    /// Coefficients of `rho`.
    pub slope: Vec<f64>,
}

/// Where each input triplet of [`ParamMatrix::from_triplets`] landed in the value arrays,
/// so that new values on the same pattern are scattered without sorting or allocating
/// ([`ParamMatrix::reassemble`]). [`DROPPED`] marks a triplet left out (lower triangle).
#[derive(Debug, Clone)]
pub struct Assembly {
    base: Vec<usize>,
    slope: Vec<usize>,
}

/// Position of a triplet that is not stored.
pub const DROPPED: usize = usize::MAX;

/// The entries ordered by column, then row, equal keys keeping their input order (so
/// duplicates are summed in the same order as a stable sort would sum them): two stable
/// counting passes, by row and then by column, in `O(entries + n)`.
fn sorted_by_column<T: Copy>(
    all: Vec<(usize, usize, f64, f64, T)>,
    n: usize,
) -> Vec<(usize, usize, f64, f64, T)> {
    /// Positions of `order`'s entries stably sorted by `key`.
    fn counting_pass(order: &[usize], key: impl Fn(usize) -> usize, n: usize) -> Vec<usize> {
        let mut start = vec![0usize; n + 1];
        for &e in order {
            start[key(e) + 1] += 1;
        }
        for k in 0..n {
            start[k + 1] += start[k];
        }
        let mut out = vec![0usize; order.len()];
        for &e in order {
            let slot = &mut start[key(e)];
            out[*slot] = e;
            *slot += 1;
        }
        out
    }
    // Most input is a few runs already in order (M's columns, the product's, the
    // diagonal): merged without sorting.
    let runs = run_starts(&all);
    if runs.len() <= MERGED_RUNS_MAX {
        return merged(&all, &runs);
    }
    let identity: Vec<usize> = (0..all.len()).collect();
    let by_row = counting_pass(&identity, |e| all[e].0, n);
    let by_column = counting_pass(&by_row, |e| all[e].1, n);
    by_column.into_iter().map(|e| all[e]).collect()
}

/// Inputs of at most this many ordered runs are merged instead of sorted.
const MERGED_RUNS_MAX: usize = 4;

/// The (column, row) key of an entry.
fn key<T>(e: &(usize, usize, f64, f64, T)) -> (usize, usize) {
    (e.1, e.0)
}

/// Where each maximal run of entries in non-decreasing (column, row) order starts, up to
/// one past [`MERGED_RUNS_MAX`] runs.
fn run_starts<T>(all: &[(usize, usize, f64, f64, T)]) -> Vec<usize> {
    let mut starts = vec![0];
    for (k, w) in all.windows(2).enumerate() {
        if key(&w[1]) < key(&w[0]) {
            starts.push(k + 1);
            if starts.len() > MERGED_RUNS_MAX {
                break;
            }
        }
    }
    starts
}

/// The ordered runs starting at `starts` merged into one, equal keys in input order (the
/// earlier run first), as the stable sort would order them.
fn merged<T: Copy>(
    all: &[(usize, usize, f64, f64, T)],
    starts: &[usize],
) -> Vec<(usize, usize, f64, f64, T)> {
    let ends: Vec<usize> = starts[1..].iter().copied().chain([all.len()]).collect();
    let mut next = starts.to_vec();
    let mut out = Vec::with_capacity(all.len());
    loop {
        // The run whose next entry has the smallest key; ties go to the earliest run.
        let mut best: Option<usize> = None;
        for r in 0..next.len() {
            if next[r] < ends[r] && best.is_none_or(|b| key(&all[next[r]]) < key(&all[next[b]])) {
                best = Some(r);
            }
        }
        let Some(r) = best else {
            return out;
        };
        out.push(all[next[r]]);
        next[r] += 1;
    }
}

impl ParamMatrix {
    /// The sparsity pattern, borrowed.
    pub fn pattern(&self) -> PatternRef<'_> {
        PatternRef {
            n: self.n,
            colptr: &self.colptr,
            rowind: &self.rowind,
        }
    }

    /// Builds the pattern union of two triplet lists; with `upper_only`, entries below the
    /// diagonal are dropped (the caller passes both triangles of a symmetric matrix).
    /// Duplicates are summed. Also returns where each triplet went.
    pub fn from_triplets(
        n: usize,
        base: impl IntoIterator<Item = (usize, usize, f64)>,
        slope: impl IntoIterator<Item = (usize, usize, f64)>,
        upper_only: bool,
    ) -> (Self, Assembly) {
        // (row, col, base value, slope value, source): source t < n_base is base triplet t,
        // n_base + t is slope triplet t, and DROPPED the diagonal entries added below.
        let (base, slope) = (base.into_iter(), slope.into_iter());
        let mut all: Vec<(usize, usize, f64, f64, usize)> =
            Vec::with_capacity(base.size_hint().0 + slope.size_hint().0 + n);
        all.extend(
            base.map(|(i, j, v)| (i, j, v, 0.0))
                .enumerate()
                .map(|(t, (i, j, b, s))| (i, j, b, s, t)),
        );
        let n_base = all.len();
        all.extend(
            slope
                .into_iter()
                .enumerate()
                .map(|(t, (i, j, v))| (i, j, 0.0, v, n_base + t)),
        );
        let n_slope = all.len() - n_base;
        let mut assembly = Assembly {
            base: vec![DROPPED; n_base],
            slope: vec![DROPPED; n_slope],
        };
        all.retain(|e| !upper_only || e.0 <= e.1);
        // Every diagonal entry is in the pattern, so refactorizations never lose it.
        all.extend((0..n).map(|i| (i, i, 0.0, 0.0, DROPPED)));
        let all = sorted_by_column(all, n);
        let mut colptr = vec![0usize; n + 1];
        let stored = all.len();
        let (mut rowind, mut b, mut s) = (
            Vec::with_capacity(stored),
            Vec::with_capacity(stored),
            Vec::<f64>::with_capacity(stored),
        );
        let mut last = None;
        for (i, j, vb, vs, source) in all {
            if last != Some((i, j)) {
                last = Some((i, j));
                rowind.push(i);
                b.push(0.0);
                s.push(0.0);
                colptr[j + 1] += 1;
            }
            let pos = rowind.len() - 1;
            b[pos] += vb;
            s[pos] += vs;
            match source {
                DROPPED => {}
                t if t < n_base => assembly.base[t] = pos,
                t => assembly.slope[t - n_base] = pos,
            }
        }
        for j in 0..n {
            colptr[j + 1] += colptr[j];
        }
        let matrix = Self {
            n,
            colptr,
            rowind,
            base: b,
            slope: s,
        };
        (matrix, assembly)
    }

    /// New values on the pattern built by [`ParamMatrix::from_triplets`]: the triplets must
    /// come in the same order and number as then (only the values are read). No sorting,
    /// no allocation.
    pub fn reassemble(
        &mut self,
        assembly: &Assembly,
        base: impl IntoIterator<Item = (usize, usize, f64)>,
        slope: impl IntoIterator<Item = (usize, usize, f64)>,
    ) {
        fn scatter(
            out: &mut [f64],
            dest: &[usize],
            values: impl IntoIterator<Item = (usize, usize, f64)>,
        ) {
            out.fill(0.0);
            let mut count = 0;
            for (&d, (_, _, v)) in dest.iter().zip(values) {
                count += 1;
                if d != DROPPED {
                    out[d] += v;
                }
            }
            debug_assert_eq!(count, dest.len(), "triplets differ from the assembled ones");
        }
        scatter(&mut self.base, &assembly.base, base);
        scatter(&mut self.slope, &assembly.slope, slope);
    }

    /// `y = A x` for the values `values` on this pattern; `symmetric`: only the upper
    /// triangle is stored, the product is the full matrix's.
    pub fn mul_vec(&self, values: &[f64], symmetric: bool, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for j in 0..self.n {
            for k in self.colptr[j]..self.colptr[j + 1] {
                let i = self.rowind[k];
                let v = values[k];
                y[i] += v * x[j];
                if symmetric && i != j {
                    y[j] += v * x[i];
                }
            }
        }
    }

    /// Values of `A(rho)` into `out`.
    pub fn values_at(&self, rho: f64, out: &mut [f64]) {
        for ((o, b), s) in out.iter_mut().zip(&self.base).zip(&self.slope) {
            *o = b + rho * s;
        }
    }
}

/// Triplets of a matrix (both triangles as stored).
pub fn triplets(a: &CscMatrix) -> Triplets<'_> {
    Triplets::new(a.colptr(), a.rowind(), a.values())
}

/// The entries of compressed columns as (row, column, value), by column, their number
/// known ahead (so that what collects them allocates once).
#[derive(Debug, Clone)]
pub struct Triplets<'a> {
    colptr: &'a [usize],
    rowind: &'a [usize],
    values: &'a [f64],
    column: usize,
    next: usize,
}

impl<'a> Triplets<'a> {
    /// The entries of the compressed columns `colptr`, `rowind`, `values`.
    pub fn new(colptr: &'a [usize], rowind: &'a [usize], values: &'a [f64]) -> Self {
        Self {
            colptr,
            rowind,
            values,
            column: 0,
            next: 0,
        }
    }
}

impl Iterator for Triplets<'_> {
    type Item = (usize, usize, f64);

    fn next(&mut self) -> Option<Self::Item> {
        if self.next >= self.values.len() {
            return None;
        }
        while self.colptr[self.column + 1] <= self.next {
            self.column += 1;
        }
        let k = self.next;
        self.next += 1;
        Some((self.rowind[k], self.column, self.values[k]))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.values.len() - self.next;
        (left, Some(left))
    }
}

impl ExactSizeIterator for Triplets<'_> {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The counting passes, and the merge of ordered runs, order entries exactly as a
    /// stable comparison sort by (column, row) does, duplicates included.
    #[test]
    fn counting_sort_matches_a_stable_sort() {
        let n = 17;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |m: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % m as u64) as usize
        };
        let all: Vec<(usize, usize, f64, f64, usize)> = (0..2000)
            .map(|t| (next(n), next(n), next(100) as f64, 0.0, t))
            .collect();
        let mut expected = all.clone();
        expected.sort_by_key(|e| (e.1, e.0));
        assert_eq!(sorted_by_column(all.clone(), n), expected);
        // A few ordered runs (the merged path), duplicates across and within runs.
        let mut runs = Vec::new();
        for chunk in all.chunks(700) {
            let mut run = chunk.to_vec();
            run.sort_by_key(|e| (e.1, e.0));
            runs.extend(run);
        }
        assert!(run_starts(&runs).len() <= MERGED_RUNS_MAX);
        let mut expected = runs.clone();
        expected.sort_by_key(|e| (e.1, e.0));
        assert_eq!(sorted_by_column(runs, n), expected);
    }
}
