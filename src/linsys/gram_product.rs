//! `H_a H_a^T` as a sparse matrix, for the v-update system `M + rho H H^T`: its pattern
//! computed once, its values again after new values of `H` on the same pattern.
//!
//! Contact by contact: a contact's three columns touch a dozen velocities (two bodies),
//! and its term `H_c W_c H_c^T` couples each pair of them. The product has far fewer
//! entries than the pairs it sums (an engine's scene of 300 contacts: about 4 000 entries
//! from 23 000 pairs), so the system is assembled from the product, not from the pairs, and
//! each pair keeps the position of its entry: a rebuild costs the multiply-adds alone.
//! Each entry sums its terms in increasing column order, as the column-by-column product
//! `sum_k H(:, k) H(:, k)^T` does.

use crate::csc::CscMatrix;
use crate::linsys::param_matrix::Triplets;

/// One stored entry of H in an active column: row `rows[start[c] + local]` of the
/// contact's rows, its column within the contact (0, 1, 2), its position in H's values.
#[derive(Debug, Clone, Copy)]
struct Entry {
    local: usize,
    column: usize,
    at: usize,
}

/// The pattern and values of `sum_{k active} H(:, k) H(:, k)^T` (the upper triangle only
/// when asked), compressed by columns with sorted rows, for `H` of three columns per
/// contact.
#[derive(Debug, Clone)]
pub struct GramProduct {
    upper_only: bool,
    /// Contact `c`'s rows (those of its active columns), ascending:
    /// `rows[start[c]..start[c + 1]]`.
    start: Vec<usize>,
    rows: Vec<usize>,
    /// Contact `c`'s stored entries: `entries[entry_start[c]..entry_start[c + 1]]`.
    entry_start: Vec<usize>,
    entries: Vec<Entry>,
    /// The contact's columns each of its rows is stored in (bit `d` for column `3 c + d`):
    /// two rows pair, and their entry is stored, only where a column holds both.
    columns_of: Vec<u8>,
    /// Position in `values` of each pair (a, b) of a contact's rows (`a <= b` when
    /// `upper_only`), by `b` then `a`, from `pairs_at[c]`. A contact with the rows and
    /// columns of the one before (the next contact between the same two bodies) shares
    /// its positions.
    pairs_at: Vec<usize>,
    shares_previous: Vec<bool>,
    slots: Vec<usize>,
    colptr: Vec<usize>,
    rowind: Vec<usize>,
    values: Vec<f64>,
    /// One contact's block of H, `rows x 3` row-major.
    block: Vec<f64>,
}

impl GramProduct {
    /// The product for `h` (`n x 3 contacts`) over the columns `k` with `active[k] != 0`.
    pub fn new(h: &CscMatrix, active: &[f64], upper_only: bool) -> Self {
        let (n, contacts) = (h.nrows(), h.ncols() / 3);
        debug_assert_eq!(h.ncols(), 3 * contacts, "three columns per contact");
        let mut product = Self {
            upper_only,
            start: Vec::with_capacity(contacts + 1),
            rows: Vec::with_capacity(h.nnz()),
            entry_start: Vec::with_capacity(contacts + 1),
            entries: Vec::with_capacity(h.nnz()),
            columns_of: Vec::with_capacity(h.nnz()),
            pairs_at: Vec::with_capacity(contacts),
            shares_previous: Vec::with_capacity(contacts),
            slots: Vec::new(),
            colptr: Vec::with_capacity(n + 1),
            rowind: Vec::new(),
            values: Vec::new(),
            block: Vec::new(),
        };
        product.contacts(h, active);
        product.pattern(n);
        product.values = vec![0.0; product.rowind.len()];
        product.recompute(h, active);
        product
    }

    /// Each contact's rows, entries and pair positions' offsets.
    fn contacts(&mut self, h: &CscMatrix, active: &[f64]) {
        self.start.push(0);
        self.entry_start.push(0);
        let (mut widest, mut pairs_total) = (0, 0);
        let (colptr, rowind) = (h.colptr(), h.rowind());
        for c in 0..h.ncols() / 3 {
            let from = self.rows.len();
            // The union of the active columns' rows (each sorted), merged: each entry
            // learns its place in it on the way.
            let mut next: [usize; 3] = std::array::from_fn(|d| colptr[3 * c + d]);
            let end: [usize; 3] = std::array::from_fn(|d| {
                let k = 3 * c + d;
                if active[k] != 0.0 {
                    colptr[k + 1]
                } else {
                    colptr[k]
                }
            });
            while let Some(low) = (0..3)
                .filter(|&d| next[d] < end[d])
                .map(|d| rowind[next[d]])
                .min()
            {
                let local = self.rows.len() - from;
                let mut columns = 0u8;
                for d in 0..3 {
                    if next[d] < end[d] && rowind[next[d]] == low {
                        self.entries.push(Entry {
                            local,
                            column: d,
                            at: next[d],
                        });
                        columns |= 1 << d;
                        next[d] += 1;
                    }
                }
                self.rows.push(low);
                self.columns_of.push(columns);
            }
            let own = &self.rows[from..];
            let r = own.len();
            widest = widest.max(r);
            let same = c > 0 && r > 0 && {
                let before = self.start[c - 1];
                self.rows[before..from] == self.rows[from..]
                    && self.columns_of[before..from] == self.columns_of[from..]
            };
            self.start.push(self.rows.len());
            self.entry_start.push(self.entries.len());
            self.shares_previous.push(same);
            if same {
                self.pairs_at.push(self.pairs_at[c - 1]);
            } else {
                self.pairs_at.push(pairs_total);
                pairs_total += if self.upper_only {
                    r * (r + 1) / 2
                } else {
                    r * r
                };
            }
        }
        self.block = vec![0.0; 6 * widest];
        self.slots = vec![0; pairs_total];
    }

    /// The product's pattern (column `j` holds the rows every contact touching `j` pairs
    /// with it) and each pair's position in it.
    fn pattern(&mut self, n: usize) {
        let contacts = self.start.len() - 1;
        // The contacts touching each velocity, as (contact, local row), by velocity.
        let mut touch_start = vec![0usize; n + 1];
        for c in (0..contacts).filter(|&c| !self.shares_previous[c]) {
            for &i in &self.rows[self.start[c]..self.start[c + 1]] {
                touch_start[i + 1] += 1;
            }
        }
        for j in 0..n {
            touch_start[j + 1] += touch_start[j];
        }
        let mut next = touch_start.clone();
        let mut touching = vec![(0, 0); touch_start[n]];
        for c in (0..contacts).filter(|&c| !self.shares_previous[c]) {
            for (b, &j) in self.rows[self.start[c]..self.start[c + 1]]
                .iter()
                .enumerate()
            {
                touching[next[j]] = (c, b);
                next[j] += 1;
            }
        }
        // `seen[i] == j` once row i is in column j; `place[i]` its position there.
        let (mut seen, mut place) = (vec![usize::MAX; n], vec![0usize; n]);
        self.colptr.push(0);
        for j in 0..n {
            let from = self.rowind.len();
            let here = &touching[touch_start[j]..touch_start[j + 1]];
            for &(c, b) in here {
                let from = self.start[c];
                let own = &self.rows[from..self.start[c + 1]];
                let shared = |a: usize| self.columns_of[from + a] & self.columns_of[from + b] != 0;
                for a in partners(self.upper_only, b, own.len()).filter(|&a| shared(a)) {
                    if seen[own[a]] != j {
                        seen[own[a]] = j;
                        self.rowind.push(own[a]);
                    }
                }
            }
            self.rowind[from..].sort_unstable();
            for q in from..self.rowind.len() {
                place[self.rowind[q]] = q;
            }
            for &(c, b) in here {
                let from = self.start[c];
                let own = &self.rows[from..self.start[c + 1]];
                let r = own.len();
                let first = self.pairs_at[c]
                    + if self.upper_only {
                        b * (b + 1) / 2
                    } else {
                        b * r
                    };
                for a in partners(self.upper_only, b, r) {
                    let shared = self.columns_of[from + a] & self.columns_of[from + b] != 0;
                    self.slots[first + a] = if shared { place[own[a]] } else { UNPAIRED };
                }
            }
            self.colptr.push(self.rowind.len());
        }
    }

    /// New values of `H` (the pattern it was built with), or new weights: the product
    /// `sum_k weight_k H(:, k) H(:, k)^T` again, with the terms of each entry summed in
    /// increasing `k` (a weight of zero leaves a column out, its pattern kept).
    pub fn recompute(&mut self, h: &CscMatrix, weight: &[f64]) {
        let hv = h.values();
        self.values.fill(0.0);
        for c in 0..self.start.len() - 1 {
            let r = self.start[c + 1] - self.start[c];
            // The contact's block of H, then the same weighted by column: `w_k H_jk`.
            let (block, weighted) = self.block[..6 * r].split_at_mut(3 * r);
            block.fill(0.0);
            for e in &self.entries[self.entry_start[c]..self.entry_start[c + 1]] {
                block[3 * e.local + e.column] = hv[e.at];
            }
            for (x, (w, &v)) in weighted
                .iter_mut()
                .zip(block.iter().zip(weight[3 * c..3 * c + 3].iter().cycle()))
            {
                *x = v * w;
            }
            let columns_of = &self.columns_of[self.start[c]..self.start[c + 1]];
            let mut slot = self.pairs_at[c];
            for b in 0..r {
                let wb = &weighted[3 * b..3 * b + 3];
                for a in partners(self.upper_only, b, r) {
                    let (at, shared) = (self.slots[slot], columns_of[a] & columns_of[b]);
                    slot += 1;
                    let ha = &block[3 * a..3 * a + 3];
                    if shared == 0b111 {
                        let value = &mut self.values[at];
                        *value += wb[0] * ha[0];
                        *value += wb[1] * ha[1];
                        *value += wb[2] * ha[2];
                    } else if at != UNPAIRED {
                        for d in (0..3).filter(|&d| shared & (1 << d) != 0) {
                            self.values[at] += wb[d] * ha[d];
                        }
                    }
                }
            }
        }
    }

    /// The entries as (row, column, value), by column.
    pub fn triplets(&self) -> Triplets<'_> {
        Triplets::new(&self.colptr, &self.rowind, &self.values)
    }
}

/// The slot of a pair of rows no column of their contact holds both of.
const UNPAIRED: usize = usize::MAX;

/// The rows `a` paired with row `b` of a contact of `r` rows.
fn partners(upper_only: bool, b: usize, r: usize) -> std::ops::Range<usize> {
    if upper_only {
        0..b + 1
    } else {
        0..r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every entry equals the dense `sum_k active_k H_ik H_jk`, in both modes, before and
    /// after new values; the pattern holds exactly the pairs some active column couples.
    #[test]
    fn matches_the_dense_product() {
        let (n, m) = (9, 15);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut dense = vec![0.0; n * m];
        for v in dense.iter_mut() {
            if next() % 3 == 0 {
                *v = (next() % 1000) as f64 / 100.0 - 5.0;
            }
        }
        // Contact 1 on the rows and columns of contact 0 (the next contact between the
        // same bodies), with other values: it shares contact 0's positions.
        for d in 0..3 {
            for i in 0..n {
                let v = dense[i * m + d];
                dense[i * m + 3 + d] = if v != 0.0 { v + 10.0 } else { 0.0 };
            }
        }
        let mut h = CscMatrix::from_dense("H", n, m, &dense).unwrap();
        // Some columns left out, the same in contacts 0 and 1.
        let out = [1, 4, 11];
        let active: Vec<f64> = (0..m)
            .map(|k| if out.contains(&k) { 0.0 } else { 1.0 })
            .collect();
        for upper_only in [false, true] {
            let mut product = GramProduct::new(&h, &active, upper_only);
            assert!(product.shares_previous[1]);
            for round in 0..2 {
                let hd = h.to_dense();
                let mut expected = vec![0.0; n * n];
                let mut coupled = vec![false; n * n];
                for k in (0..m).filter(|&k| active[k] != 0.0) {
                    for i in 0..n {
                        for j in 0..n {
                            let (a, b) = (hd[i + k * n], hd[j + k * n]);
                            expected[i * n + j] += a * b;
                            coupled[i * n + j] |= a != 0.0 && b != 0.0;
                        }
                    }
                }
                let mut got = vec![0.0; n * n];
                let mut stored = vec![false; n * n];
                for (i, j, v) in product.triplets() {
                    assert!(!stored[i * n + j], "({i}, {j}) stored twice");
                    stored[i * n + j] = true;
                    got[i * n + j] = v;
                }
                for i in 0..n {
                    for j in 0..n {
                        let wanted = coupled[i * n + j] && (!upper_only || i <= j);
                        assert_eq!(stored[i * n + j], wanted, "pattern at ({i}, {j})");
                        if wanted {
                            let e = expected[i * n + j];
                            assert!((got[i * n + j] - e).abs() <= 1e-12 * (1.0 + e.abs()));
                        }
                    }
                }
                if round == 0 {
                    let scaled: Vec<f64> = h.values().iter().map(|v| 1.5 * v - 0.25).collect();
                    h.set_values("H", &scaled).unwrap();
                    product.recompute(&h, &active);
                }
            }
        }
    }
}
