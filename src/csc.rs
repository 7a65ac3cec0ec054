//! Compressed sparse column matrices: validated storage and the products the solver needs.

use crate::types::Error;

/// A sparse matrix in compressed-column form, 0-based, validated on construction.
///
/// Row indices inside a column need not be sorted; they are sorted on construction.
#[derive(Debug, PartialEq)]
pub struct CscMatrix {
    nrows: usize,
    ncols: usize,
    colptr: Vec<usize>,
    rowind: Vec<usize>,
    values: Vec<f64>,
    /// Where each stored entry came from in the arrays the matrix was built from, when
    /// construction had to sort rows (None: stored in input order).
    input_order: Option<Vec<usize>>,
}

impl Clone for CscMatrix {
    fn clone(&self) -> Self {
        Self {
            nrows: self.nrows,
            ncols: self.ncols,
            colptr: self.colptr.clone(),
            rowind: self.rowind.clone(),
            values: self.values.clone(),
            input_order: self.input_order.clone(),
        }
    }

    /// Reuses the arrays' memory (a solver rebuilt for each step's problem).
    fn clone_from(&mut self, source: &Self) {
        let Self {
            nrows,
            ncols,
            colptr,
            rowind,
            values,
            input_order,
        } = self;
        (*nrows, *ncols) = (source.nrows, source.ncols);
        colptr.clone_from(&source.colptr);
        rowind.clone_from(&source.rowind);
        values.clone_from(&source.values);
        input_order.clone_from(&source.input_order);
    }
}

/// Marks an entry without a mirror in [`CscMatrix::mirror_map`].
const NO_MIRROR: usize = usize::MAX;

/// A stored entry while its column is sorted: (row, value, position in the input arrays).
type Entry = (usize, f64, usize);

/// Checks the column pointers against `ncols` and the lengths of the row index and value
/// arrays; returns the number of stored entries.
fn check_pointers(
    field: &'static str,
    ncols: usize,
    colptr: &[usize],
    n_rowind: usize,
    n_values: usize,
) -> Result<usize, Error> {
    let bad = |reason: String| Error::InvalidCsc { field, reason };
    if colptr.len() != ncols + 1 {
        return Err(bad(format!(
            "column pointer array has {} entries, expected ncols + 1 = {}",
            colptr.len(),
            ncols + 1
        )));
    }
    if colptr[0] != 0 {
        return Err(bad(format!("colptr[0] = {}, expected 0", colptr[0])));
    }
    for j in 0..ncols {
        if colptr[j + 1] < colptr[j] {
            return Err(bad(format!("column pointers decrease at column {j}")));
        }
    }
    let nnz = colptr[ncols];
    if n_rowind != nnz || n_values != nnz {
        return Err(bad(format!(
            "colptr[ncols] = {nnz} but {n_rowind} row indices and {n_values} values were given"
        )));
    }
    Ok(nnz)
}

/// Fills `order` with the entries `range` of column `j`, sorted by row, after checking
/// each row index against `nrows` and each value for finiteness (in storage order, so
/// the first bad entry is the one reported).
fn sorted_column(
    field: &'static str,
    nrows: usize,
    j: usize,
    range: std::ops::Range<usize>,
    rowind: &[usize],
    values: &[f64],
    order: &mut Vec<Entry>,
) -> Result<(), Error> {
    order.clear();
    for k in range {
        if rowind[k] >= nrows {
            return Err(Error::InvalidCsc {
                field,
                reason: format!(
                    "row index {} at entry {k} (column {j}) is out of range (nrows = {nrows})",
                    rowind[k]
                ),
            });
        }
        if !values[k].is_finite() {
            return Err(Error::InvalidValue {
                field,
                index: k,
                reason: "not finite",
            });
        }
        order.push((rowind[k], values[k], k));
    }
    order.sort_by_key(|e| e.0);
    Ok(())
}

/// Whether a column needs no sorting and holds nothing to report: rows strictly
/// increasing and in range, values finite (most input; the others take the slow path,
/// which reports the first bad entry).
fn column_in_order(nrows: usize, rows: &[usize], values: &[f64]) -> bool {
    rows.windows(2).all(|w| w[0] < w[1])
        && rows.last().is_none_or(|&i| i < nrows)
        && values.iter().all(|v| v.is_finite())
}

/// Notes where the sorted entries of a column starting at `start` came from, when sorting
/// moved any (the permutation is made, as the identity, on the first such column).
fn record_input_order(
    order: &[Entry],
    start: usize,
    nnz: usize,
    input_order: &mut Option<Vec<usize>>,
) {
    if order.iter().enumerate().any(|(k, e)| e.2 != start + k) {
        let perm = input_order.get_or_insert_with(|| (0..nnz).collect());
        for (k, e) in order.iter().enumerate() {
            perm[start + k] = e.2;
        }
    }
}

/// Fails on two entries of the same row in the sorted column `j` starting at `start`.
fn check_duplicates(
    field: &'static str,
    j: usize,
    start: usize,
    order: &[Entry],
) -> Result<(), Error> {
    for (k, w) in order.windows(2).enumerate() {
        if w[0].0 == w[1].0 {
            return Err(Error::InvalidCsc {
                field,
                reason: format!(
                    "duplicate entry at row {} in column {j} (entry {})",
                    w[0].0,
                    start + k + 1
                ),
            });
        }
    }
    Ok(())
}

impl CscMatrix {
    /// Builds and validates a matrix. `field` names it in errors (`"M"`, `"H"`...).
    ///
    /// Checks: `colptr` has `ncols + 1` entries, starts at 0, is non-decreasing and ends at
    /// `rowind.len() == values.len()`; each row index is `< nrows`; no duplicate entry in a
    /// column; every value finite.
    pub fn new(
        field: &'static str,
        nrows: usize,
        ncols: usize,
        colptr: Vec<usize>,
        rowind: Vec<usize>,
        values: Vec<f64>,
    ) -> Result<Self, Error> {
        let nnz = check_pointers(field, ncols, &colptr, rowind.len(), values.len())?;
        let mut rowind = rowind;
        let mut values = values;
        let mut input_order: Option<Vec<usize>> = None;
        let mut order: Vec<Entry> = Vec::new();
        // Column by column: the error reported is the first one met in storage order.
        for j in 0..ncols {
            let (start, end) = (colptr[j], colptr[j + 1]);
            if column_in_order(nrows, &rowind[start..end], &values[start..end]) {
                continue;
            }
            sorted_column(field, nrows, j, start..end, &rowind, &values, &mut order)?;
            record_input_order(&order, start, nnz, &mut input_order);
            check_duplicates(field, j, start, &order)?;
            for (k, (i, v, _)) in order.iter().enumerate() {
                rowind[start + k] = *i;
                values[start + k] = *v;
            }
        }
        Ok(Self {
            nrows,
            ncols,
            colptr,
            rowind,
            values,
            input_order,
        })
    }

    /// Replaces the values, given in the order of the arrays the matrix was built from (the
    /// pattern stays). Checks the length and that every value is finite; on error the
    /// matrix is unchanged. Does not allocate.
    pub fn set_values(&mut self, field: &'static str, values: &[f64]) -> Result<(), Error> {
        self.check_values(field, values)?;
        match &self.input_order {
            None => self.values.copy_from_slice(values),
            Some(perm) => {
                for (v, &k) in self.values.iter_mut().zip(perm) {
                    *v = values[k];
                }
            }
        }
        Ok(())
    }

    /// Entry `(i, i)` (zero when the pattern has none).
    pub fn diagonal_entry(&self, i: usize) -> f64 {
        let r = self.colptr[i]..self.colptr[i + 1];
        match self.rowind[r.clone()].binary_search(&i) {
            Ok(k) => self.values[r.start + k],
            Err(_) => 0.0,
        }
    }

    /// The values in the order of the arrays the matrix was built from (what
    /// [`CscMatrix::set_values`] takes), written into `out` (no allocation once it fits).
    pub(crate) fn values_in_input_order(&self, out: &mut Vec<f64>) {
        out.clear();
        match &self.input_order {
            None => out.extend_from_slice(&self.values),
            Some(perm) => {
                out.resize(self.values.len(), 0.0);
                for (&v, &k) in self.values.iter().zip(perm) {
                    out[k] = v;
                }
            }
        }
    }

    /// The checks of [`CscMatrix::set_values`] alone.
    pub fn check_values(&self, field: &'static str, values: &[f64]) -> Result<(), Error> {
        if values.len() != self.values.len() {
            return Err(Error::Dimension {
                field,
                expected: self.values.len(),
                found: values.len(),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidValue {
                field,
                index,
                reason: "not finite",
            });
        }
        Ok(())
    }

    /// For each stored entry `(i, j)`, the position of `(j, i)` (pattern only), so that
    /// [`CscMatrix::is_symmetric_with`] checks new values without allocating. Square
    /// matrices only.
    pub fn mirror_map(&self) -> Vec<usize> {
        let mut mirror = vec![NO_MIRROR; self.nnz()];
        for j in 0..self.ncols {
            for k in self.colptr[j]..self.colptr[j + 1] {
                let i = self.rowind[k];
                let (s, e) = (self.colptr[i], self.colptr[i + 1]);
                if let Ok(t) = self.rowind[s..e].binary_search(&j) {
                    mirror[k] = s + t;
                }
            }
        }
        mirror
    }

    /// [`CscMatrix::is_symmetric`] with a map from [`CscMatrix::mirror_map`] of this
    /// pattern, without allocating.
    pub fn is_symmetric_with(&self, mirror: &[usize]) -> bool {
        let scale = self.values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let asymmetry = self
            .values
            .iter()
            .zip(mirror)
            .map(|(&v, &t)| (v - if t == NO_MIRROR { 0.0 } else { self.values[t] }).abs())
            .fold(0.0f64, f64::max);
        asymmetry <= SYMMETRY_TOL * scale
    }

    /// Builds a matrix from (row, column, value) triplets; duplicates are summed.
    pub fn from_triplets(
        field: &'static str,
        nrows: usize,
        ncols: usize,
        triplets: &[(usize, usize, f64)],
    ) -> Result<Self, Error> {
        for (k, &(i, j, _)) in triplets.iter().enumerate() {
            if i >= nrows || j >= ncols {
                return Err(Error::InvalidCsc {
                    field,
                    reason: format!("triplet {k} at ({i}, {j}) is outside {nrows} x {ncols}"),
                });
            }
        }
        let mut sorted: Vec<(usize, usize, f64)> = triplets.to_vec();
        sorted.sort_by_key(|&(i, j, _)| (j, i));
        let mut colptr = vec![0usize; ncols + 1];
        let mut rowind = Vec::with_capacity(sorted.len());
        let mut values: Vec<f64> = Vec::with_capacity(sorted.len());
        let mut last: Option<(usize, usize)> = None;
        for &(i, j, v) in &sorted {
            if last == Some((i, j)) {
                *values.last_mut().expect("an entry was pushed") += v;
                continue;
            }
            rowind.push(i);
            values.push(v);
            colptr[j + 1] += 1;
            last = Some((i, j));
        }
        for j in 0..ncols {
            colptr[j + 1] += colptr[j];
        }
        Self::new(field, nrows, ncols, colptr, rowind, values)
    }

    /// A dense row-major matrix, for tests and small examples (zeros are dropped).
    pub fn from_dense(
        field: &'static str,
        nrows: usize,
        ncols: usize,
        rows: &[f64],
    ) -> Result<Self, Error> {
        if rows.len() != nrows * ncols {
            return Err(Error::Dimension {
                field,
                expected: nrows * ncols,
                found: rows.len(),
            });
        }
        let mut t = Vec::new();
        for i in 0..nrows {
            for j in 0..ncols {
                let v = rows[i * ncols + j];
                if v != 0.0 {
                    t.push((i, j, v));
                }
            }
        }
        Self::from_triplets(field, nrows, ncols, &t)
    }

    /// Identity matrix of size `n`.
    pub fn identity(n: usize) -> Self {
        Self {
            nrows: n,
            ncols: n,
            colptr: (0..=n).collect(),
            rowind: (0..n).collect(),
            values: vec![1.0; n],
            input_order: None,
        }
    }

    /// Number of rows.
    pub fn nrows(&self) -> usize {
        self.nrows
    }
    /// Number of columns.
    pub fn ncols(&self) -> usize {
        self.ncols
    }
    /// Column pointers (`ncols + 1` entries).
    pub fn colptr(&self) -> &[usize] {
        &self.colptr
    }
    /// Row indices, sorted within each column.
    pub fn rowind(&self) -> &[usize] {
        &self.rowind
    }
    /// Values, in the order of `rowind`.
    pub fn values(&self) -> &[f64] {
        &self.values
    }
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.values.len()
    }

    /// Entries of column `j` as (row, value).
    pub fn col(&self, j: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.colptr[j]..self.colptr[j + 1];
        self.rowind[r.clone()]
            .iter()
            .copied()
            .zip(self.values[r].iter().copied())
    }

    /// `y = alpha * A x + beta * y`.
    pub fn mul_vec(&self, alpha: f64, x: &[f64], beta: f64, y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.ncols);
        debug_assert_eq!(y.len(), self.nrows);
        if beta == 0.0 {
            y.fill(0.0);
        } else if beta != 1.0 {
            y.iter_mut().for_each(|v| *v *= beta);
        }
        for (j, &xj) in x.iter().enumerate() {
            if xj == 0.0 {
                continue;
            }
            let axj = alpha * xj;
            for k in self.colptr[j]..self.colptr[j + 1] {
                y[self.rowind[k]] += self.values[k] * axj;
            }
        }
    }

    /// `y = alpha * A^T x + beta * y`.
    pub fn mul_t_vec(&self, alpha: f64, x: &[f64], beta: f64, y: &mut [f64]) {
        debug_assert_eq!(x.len(), self.nrows);
        debug_assert_eq!(y.len(), self.ncols);
        for (j, yj) in y.iter_mut().enumerate() {
            let r = self.colptr[j]..self.colptr[j + 1];
            let s = gather_dot(&self.values[r.clone()], &self.rowind[r], x);
            *yj = alpha * s + if beta == 0.0 { 0.0 } else { beta * *yj };
        }
    }

    /// Transpose.
    pub fn transpose(&self) -> Self {
        let (colptr, entries) = entries_by_row(self, |_| true);
        Self {
            nrows: self.ncols,
            ncols: self.nrows,
            colptr,
            rowind: entries.iter().map(|&(j, _)| j).collect(),
            values: entries.iter().map(|&(_, k)| self.values[k]).collect(),
            input_order: None,
        }
    }

    /// Max absolute column sum (the matrix 1-norm).
    pub fn norm_1(&self) -> f64 {
        (0..self.ncols)
            .map(|j| self.col(j).map(|(_, v)| v.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    }

    /// Frobenius norm.
    pub fn norm_fro(&self) -> f64 {
        self.values.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// Largest `|A - A^T|` entry (0 for a symmetric matrix); `None` when not square.
    pub fn asymmetry(&self) -> Option<f64> {
        if self.nrows != self.ncols {
            return None;
        }
        let t = self.transpose();
        let mut worst: f64 = 0.0;
        let mut dense_col = vec![0.0; self.nrows];
        for j in 0..self.ncols {
            for (i, v) in self.col(j) {
                dense_col[i] += v;
            }
            for (i, v) in t.col(j) {
                dense_col[i] -= v;
            }
            for (i, _) in self.col(j).chain(t.col(j)) {
                worst = worst.max(dense_col[i].abs());
                dense_col[i] = 0.0;
            }
        }
        Some(worst)
    }

    /// True when the matrix is square and symmetric up to round-off:
    /// `max |A - A^T| <= SYMMETRY_TOL * max |A|`. Decides Cholesky against LU.
    pub fn is_symmetric(&self) -> bool {
        let scale = self.values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        self.asymmetry().is_some_and(|a| a <= SYMMETRY_TOL * scale)
    }

    /// Dense column-major copy (small matrices only).
    pub fn to_dense(&self) -> Vec<f64> {
        let mut d = vec![0.0; self.nrows * self.ncols];
        for j in 0..self.ncols {
            for (i, v) in self.col(j) {
                d[i + j * self.nrows] = v;
            }
        }
        d
    }
}

/// Relative asymmetry up to which a matrix counts as symmetric (round-off of assembled
/// mass and Delassus matrices, not the real asymmetry some FCLib files carry).
pub const SYMMETRY_TOL: f64 = 1e-12;

/// Euclidean norm.
pub fn norm2(x: &[f64]) -> f64 {
    dot(x, x).sqrt()
}

/// Dot product, summed in eight lanes: a single running sum waits on each addition (the
/// compiler may not reorder floating-point sums), eight independent ones vectorize. The
/// order is fixed, so the result is the same on every run.
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    debug_assert_eq!(x.len(), y.len());
    const LANES: usize = 8;
    let (xc, yc) = (x.chunks_exact(LANES), y.chunks_exact(LANES));
    let tail: f64 = xc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| a * b)
        .sum();
    let mut acc = [0.0; LANES];
    for (a, b) in xc.zip(yc) {
        for k in 0..LANES {
            acc[k] += a[k] * b[k];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// A matrix stored by rows beside its compressed-column original: `y = A x` then reads
/// `x` and writes each `y_i` once (a gather, where the column product scatters into `y`),
/// which is the faster product when it runs at every iteration. New values of the
/// original are copied in through the entry map, without allocation. Column indices are
/// 32-bit: the products are memory-bound, and an index is read with every value (a
/// 25 000-contact pile's H and its rows then fit the cache together).
#[derive(Debug, Clone)]
pub(crate) struct RowMajor {
    /// Entries of row `i`: `start[i]..start[i + 1]`.
    start: Vec<usize>,
    col: Vec<u32>,
    /// Where each entry sits in the original's values.
    source: Vec<usize>,
    values: Vec<f64>,
}

impl RowMajor {
    /// The rows of `a`.
    pub fn new(a: &CscMatrix) -> Self {
        let (start, entries) = entries_by_row(a, |_| true);
        let mut rows = Self {
            start,
            col: entries.iter().map(|&(j, _)| index32(j)).collect(),
            source: entries.iter().map(|&(_, k)| k).collect(),
            values: vec![0.0; a.nnz()],
        };
        rows.take_values(a);
        rows
    }

    /// Whether every index of `a` fits the 32-bit storage.
    pub fn fits(a: &CscMatrix) -> bool {
        a.nrows.max(a.ncols) <= u32::MAX as usize
    }

    /// Takes the values of `a` (the matrix it was made from, or one with its pattern).
    pub fn take_values(&mut self, a: &CscMatrix) {
        for (v, &k) in self.values.iter_mut().zip(&self.source) {
            *v = a.values[k];
        }
    }

    /// Stored entries.
    pub fn entries(&self) -> usize {
        self.values.len()
    }

    /// `y = A x + beta y`, one row at a time.
    pub fn mul_vec(&self, x: &[f64], beta: f64, y: &mut [f64]) {
        debug_assert_eq!(y.len() + 1, self.start.len());
        for (i, yi) in y.iter_mut().enumerate() {
            let base = if beta == 0.0 { 0.0 } else { beta * *yi };
            *yi = base + self.row_dot(i, x);
        }
    }

    /// Row `i` of the matrix times `x`.
    pub fn row_dot(&self, i: usize, x: &[f64]) -> f64 {
        let r = self.start[i]..self.start[i + 1];
        gather_dot(&self.values[r.clone()], &self.col[r], x)
    }
}

/// A stored row or column index (the compressed formats' `usize`, [`RowMajor`]'s `u32`).
trait StoredIndex: Copy {
    fn at(self) -> usize;
}

impl StoredIndex for usize {
    fn at(self) -> usize {
        self
    }
}

impl StoredIndex for u32 {
    fn at(self) -> usize {
        self as usize
    }
}

/// `sum_k values[k] x[index[k]]` in four running sums: one sum would wait on each
/// addition (rows of a few dozen entries are then latency-bound); the order is fixed.
fn gather_dot<I: StoredIndex>(values: &[f64], index: &[I], x: &[f64]) -> f64 {
    const LANES: usize = 4;
    let at = |j: I| j.at();
    let (vc, ic) = (values.chunks_exact(LANES), index.chunks_exact(LANES));
    let tail: f64 = vc
        .remainder()
        .iter()
        .zip(ic.remainder())
        .map(|(v, &j)| v * x[at(j)])
        .sum();
    let mut acc = [0.0; LANES];
    for (v, j) in vc.zip(ic) {
        for k in 0..LANES {
            acc[k] += v[k] * x[at(j[k])];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The entries of `a` row by row, over the columns `keep` accepts, each row by increasing
/// column (a counting sort): row `i`'s entries are `start[i]..start[i + 1]` of the list,
/// each as (column, position in `a`'s values).
pub(crate) fn entries_by_row(
    a: &CscMatrix,
    keep: impl Fn(usize) -> bool,
) -> (Vec<usize>, Vec<(usize, usize)>) {
    let kept = || (0..a.ncols).filter(|&j| keep(j));
    let mut start = vec![0usize; a.nrows + 1];
    for j in kept() {
        for &i in &a.rowind[a.colptr[j]..a.colptr[j + 1]] {
            start[i + 1] += 1;
        }
    }
    for i in 0..a.nrows {
        start[i + 1] += start[i];
    }
    let mut next = start.clone();
    let mut entries = vec![(0, 0); start[a.nrows]];
    for j in kept() {
        for k in a.colptr[j]..a.colptr[j + 1] {
            let at = &mut next[a.rowind[k]];
            entries[*at] = (j, k);
            *at += 1;
        }
    }
    (start, entries)
}

/// An index in the 32-bit storage of [`RowMajor`] (checked by [`RowMajor::fits`]).
fn index32(i: usize) -> u32 {
    u32::try_from(i).expect("RowMajor::fits was checked")
}
