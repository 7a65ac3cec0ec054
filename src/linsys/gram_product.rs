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
use crate::linsys::contact_columns::{ContactRows, LEFT_OUT};
use crate::linsys::param_matrix::Triplets;

/// The pattern and values of `sum_{k active} H(:, k) H(:, k)^T` (the upper triangle only
/// when asked), compressed by columns with sorted rows, for `H` of three columns per
/// contact.
#[derive(Debug, Clone)]
pub struct GramProduct {
    upper_only: bool,
    /// Each contact's rows (those of its active columns), ascending, and each entry of H's
    /// slot in the contacts' `rows x 3` blocks (see [`ContactRows`]).
    start: Vec<usize>,
    rows: Vec<usize>,
    slot: Vec<usize>,
    /// The contact's columns each of its rows is stored in (bit `d` for column `3 c + d`):
    /// two rows pair, and their entry is stored, only where a column holds both.
    columns_of: Vec<u8>,
    /// Position in `values` of each pair (a, b) of a contact's rows (`a <= b` when
    /// `upper_only`), by `b` then `a`, from `pairs_at[c]`. A contact with the rows and
    /// columns of the one before (the next contact between the same two bodies) shares
    /// its positions.
    pairs_at: Vec<usize>,
    shares_previous: Vec<bool>,
    positions: Vec<usize>,
    colptr: Vec<usize>,
    rowind: Vec<usize>,
    values: Vec<f64>,
    /// One contact's block of H, `rows x 3` row-major, then the same weighted by column.
    block: Vec<f64>,
}

impl GramProduct {
    /// The product for `h` (`n x 3 contacts`) over the columns `k` with `active[k] != 0`.
    pub fn new(h: &CscMatrix, active: &[f64], upper_only: bool) -> Self {
        let (n, contacts) = (h.nrows(), h.ncols() / 3);
        debug_assert_eq!(h.ncols(), 3 * contacts, "three columns per contact");
        let ContactRows { start, rows, slot } = ContactRows::of(h, |k| active[k] != 0.0);
        let mut columns_of = vec![0u8; rows.len()];
        for &s in slot.iter().filter(|&&s| s != LEFT_OUT) {
            columns_of[s / 3] |= 1 << (s % 3);
        }
        let mut product = Self {
            upper_only,
            start,
            rows,
            slot,
            columns_of,
            pairs_at: Vec::with_capacity(contacts),
            shares_previous: Vec::with_capacity(contacts),
            positions: Vec::new(),
            colptr: Vec::with_capacity(n + 1),
            rowind: Vec::new(),
            values: Vec::new(),
            block: Vec::new(),
        };
        product.share_pairs();
        product.pattern(n);
        product.values = vec![0.0; product.rowind.len()];
        product.recompute(h, active);
        product
    }

    /// Where each contact's pair positions start: a contact with the rows and columns of
    /// the one before shares its positions.
    fn share_pairs(&mut self) {
        let (mut widest, mut total) = (0, 0);
        for c in 0..self.start.len() - 1 {
            let (from, to) = (self.start[c], self.start[c + 1]);
            let r = to - from;
            widest = widest.max(r);
            let same = c > 0 && r > 0 && {
                let before = self.start[c - 1];
                self.rows[before..from] == self.rows[from..to]
                    && self.columns_of[before..from] == self.columns_of[from..to]
            };
            self.shares_previous.push(same);
            if same {
                self.pairs_at.push(self.pairs_at[c - 1]);
            } else {
                self.pairs_at.push(total);
                total += if self.upper_only {
                    r * (r + 1) / 2
                } else {
                    r * r
                };
            }
        }
        self.block = vec![0.0; 6 * widest];
        self.positions = vec![0; total];
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
                let base = self.start[c];
                let own = &self.rows[base..self.start[c + 1]];
                let shared = |a: usize| self.columns_of[base + a] & self.columns_of[base + b] != 0;
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
                let base = self.start[c];
                let own = &self.rows[base..self.start[c + 1]];
                let r = own.len();
                let first = self.pairs_at[c]
                    + if self.upper_only {
                        b * (b + 1) / 2
                    } else {
                        b * r
                    };
                for a in partners(self.upper_only, b, r) {
                    let shared = self.columns_of[base + a] & self.columns_of[base + b] != 0;
                    self.positions[first + a] = if shared { place[own[a]] } else { UNPAIRED };
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
            let first = 3 * self.start[c];
            for k in h.colptr()[3 * c]..h.colptr()[3 * c + 3] {
                if self.slot[k] != LEFT_OUT {
                    block[self.slot[k] - first] = hv[k];
                }
            }
            for (x, (w, &v)) in weighted
                .iter_mut()
                .zip(block.iter().zip(weight[3 * c..3 * c + 3].iter().cycle()))
            {
                *x = v * w;
            }
            let columns_of = &self.columns_of[self.start[c]..self.start[c + 1]];
            let mut pair = self.pairs_at[c];
            for b in 0..r {
                let wb = &weighted[3 * b..3 * b + 3];
                for a in partners(self.upper_only, b, r) {
                    let (at, shared) = (self.positions[pair], columns_of[a] & columns_of[b]);
                    pair += 1;
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
