//! The joints' equality rows solved together in each sweep. One row at a time, a sweep
//! carries a correction along a chain of joints one link further; solved together, with
//! the factor of their Delassus matrix `S = G_E^T M^-1 G_E + C_E`, every sweep ends with
//! the velocities meeting every equality row exactly, the contacts' impulses held.
//!
//! `S` couples two rows only through a body they share, so engines' joints, listed body
//! after body along their chains, give it a narrow profile: it is factorized within that
//! profile (an envelope Cholesky), and so cheaply on chains, trees and ragdolls.

use super::movement::Movement;
use super::rows::{blocks, RowGroups};
use crate::linsys::BlockDiagonal;
use crate::problem::Joints;
use crate::tuning::{JOINT_BLOCK_FLOPS, JOINT_BLOCK_REORDERED_FLOPS};

/// The equality rows' factorized Delassus matrix (empty when not used).
#[derive(Default)]
pub(super) struct JointBlock {
    /// The rows solved together (unbounded, moved by some velocity), in the order of the
    /// factor ([`JointBlock::order_rows`]).
    rows: Vec<usize>,
    /// Whether each row of the joints is among `rows`.
    member: Vec<bool>,
    /// Row `i`'s first column within the profile of `S`'s lower triangle, and where its
    /// entries (columns `first[i]..=i`) start in `factor`.
    first: Vec<usize>,
    start: Vec<usize>,
    /// The rows on each block of M: for block `b` (of `block_size[b]` unknowns),
    /// `on_block[on_start[b]..on_start[b + 1]]` holds `(i, at)`, row `i` (ascending) whose
    /// values on the block start at `at` in `RowGroups::values`.
    on_start: Vec<usize>,
    on_block: Vec<(usize, usize)>,
    block_size: Vec<usize>,
    /// Work space: where each block's next row goes.
    fill: Vec<usize>,
    /// `S`, then its lower Cholesky factor, row by row within the profile.
    factor: Vec<f64>,
    /// Work space: the rows' velocities, then their step.
    step: Vec<f64>,
    /// Whether the factor holds (otherwise the rows are swept one at a time).
    ready: bool,
}

impl JointBlock {
    /// Which rows of `j` are solved together, and the profile of their `S`: every row
    /// moved by some velocity, when all are equalities; none (all left to the
    /// one-at-a-time sweep) when a row is bounded, when fewer than two, or when
    /// factorizing within the profile would cost more than [`JOINT_BLOCK_FLOPS`].
    pub fn refit(&mut self, j: &Joints, groups: &RowGroups<1>, mass: &BlockDiagonal) {
        self.rows.clear();
        // Beside bounded rows, equalities solved together answered worse (JOINT_BLOCK_FLOPS).
        if (0..groups.len()).all(|k| !j.is_bounded(k)) {
            self.rows
                .extend((0..groups.len()).filter(|&k| !groups.reach(k).is_empty()));
        }
        self.index_blocks(groups, mass);
        let mut flops = self.profile(groups, mass);
        if flops > JOINT_BLOCK_REORDERED_FLOPS {
            self.order_rows(groups, mass);
            self.index_blocks(groups, mass);
            flops = self.profile(groups, mass);
        }
        self.ready = false;
        if self.rows.len() < 2 || flops > JOINT_BLOCK_FLOPS {
            self.rows.clear();
            self.first.clear();
        }
        self.member.clear();
        self.member.resize(groups.len(), false);
        for &k in &self.rows {
            self.member[k] = true;
        }
        self.start.clear();
        self.start.push(0);
        for (i, &f) in self.first.iter().enumerate() {
            self.start.push(self.start[i] + i + 1 - f);
        }
        self.factor.clear();
        self.factor.resize(self.start[self.first.len()], 0.0);
        self.step.clear();
        self.step.resize(self.rows.len(), 0.0);
    }

    /// Row i's first row sharing a body with it, the profile of S's lower triangle, into
    /// `first` ([`JointBlock::index_blocks`] of the rows' order); the multiply-adds of
    /// factorizing within it.
    fn profile(&mut self, groups: &RowGroups<1>, mass: &BlockDiagonal) -> f64 {
        self.first.clear();
        for (i, &k) in self.rows.iter().enumerate() {
            let first = blocks(groups.reach(k), mass)
                .map(|(b, _)| self.on_block[self.on_start[b]].0)
                .fold(i, usize::min);
            self.first.push(first);
        }
        self.first
            .iter()
            .enumerate()
            .map(|(i, &f)| ((i - f) as f64).powi(2))
            .sum()
    }

    /// The rows on each block, in the order of `rows` (a counting sort by block).
    fn index_blocks(&mut self, groups: &RowGroups<1>, mass: &BlockDiagonal) {
        let nb = mass.block_count();
        self.on_start.clear();
        self.on_start.resize(nb + 1, 0);
        for &k in &self.rows {
            for (b, _) in blocks(groups.reach(k), mass) {
                self.on_start[b + 1] += 1;
            }
        }
        for b in 0..nb {
            self.on_start[b + 1] += self.on_start[b];
        }
        self.on_block.clear();
        self.on_block.resize(self.on_start[nb], (0, 0));
        self.fill.clone_from(&self.on_start);
        for (i, &k) in self.rows.iter().enumerate() {
            for (b, at) in blocks(groups.reach(k), mass) {
                self.on_block[self.fill[b]] = (i, groups.offset(k) + at);
                self.fill[b] += 1;
            }
        }
        self.block_size.clear();
        self.block_size.extend((0..nb).map(|b| mass.block(b).len()));
    }

    /// Puts `rows` in reverse Cuthill-McKee order of the graph in which two rows touch
    /// when they move a body together ([`JointBlock::index_blocks`] of the order given),
    /// which keeps the envelope of `S` narrow whatever order the engine hands its joints
    /// in (Bullet sorts its constraints by island, unstably: a 20-link chain's 60 rows came
    /// with 9 000 products in their envelope, about 1 000 in this order). Only for a profile
    /// above [`JOINT_BLOCK_REORDERED_FLOPS`]: below it, ordering cost about what it saved.
    fn order_rows(&mut self, groups: &RowGroups<1>, mass: &BlockDiagonal) {
        let p = self.rows.len();
        let (on_start, on_block) = (&self.on_start, &self.on_block);
        let row_blocks = |i: usize| blocks(groups.reach(self.rows[i]), mass).map(|(b, _)| b);
        let on = |b: usize| {
            on_block[on_start[b]..on_start[b + 1]]
                .iter()
                .map(|&(l, _)| l)
        };
        let degree: Vec<usize> = (0..p)
            .map(|i| {
                row_blocks(i)
                    .map(|b| on_start[b + 1] - on_start[b] - 1)
                    .sum()
            })
            .collect();
        // Breadth first from a row of least degree (an end of a chain), each row's unplaced
        // neighbours by increasing degree; then reversed.
        let mut starts: Vec<usize> = (0..p).collect();
        starts.sort_by_key(|&i| (degree[i], i));
        let (mut placed, mut order) = (vec![false; p], Vec::with_capacity(p));
        for start in starts {
            if placed[start] {
                continue;
            }
            placed[start] = true;
            let mut head = order.len();
            order.push(start);
            while let Some(&i) = order.get(head) {
                head += 1;
                let from = order.len();
                for l in row_blocks(i).flat_map(on) {
                    if !placed[l] {
                        placed[l] = true;
                        order.push(l);
                    }
                }
                order[from..].sort_by_key(|&l| (degree[l], l));
            }
        }
        let permuted: Vec<usize> = order.iter().rev().map(|&i| self.rows[i]).collect();
        self.rows = permuted;
    }

    /// Whether the factor holds: the rows are solved here, and the one-at-a-time sweep
    /// skips them.
    pub fn ready(&self) -> bool {
        self.ready
    }

    /// Whether joint row `k` is solved here (when [`JointBlock::ready`]).
    pub fn solves(&self, k: usize) -> bool {
        self.member[k]
    }

    /// Forms and factorizes `S` from the rows' values (`groups` holding them); the rows go
    /// back to the one-at-a-time sweep when `S` is not positive definite to working
    /// precision (redundant rows: a closed loop of joints).
    pub fn take_values(&mut self, j: &Joints, groups: &RowGroups<1>) {
        self.ready = false;
        if self.rows.is_empty() {
            return;
        }
        // S_il = G_k^T M^-1 G_l sums over the blocks rows k and l share.
        let (s, first, start) = (&mut self.factor, &self.first, &self.start);
        s.fill(0.0);
        let (a_t, minv_a) = groups.values();
        for (b, &size) in self.block_size.iter().enumerate() {
            let on = &self.on_block[self.on_start[b]..self.on_start[b + 1]];
            for (x, &(i, at_i)) in on.iter().enumerate() {
                let a_i = &a_t[at_i..at_i + size];
                // Entry (i, l) of the profile sits at `row + l`.
                let row = start[i] - first[i];
                for &(l, at_l) in &on[..=x] {
                    let minv_l = &minv_a[at_l..at_l + size];
                    s[row + l] += a_i.iter().zip(minv_l).map(|(a, m)| a * m).sum::<f64>();
                }
            }
        }
        for (i, &k) in self.rows.iter().enumerate() {
            s[start[i + 1] - 1] += j.compliance[k];
        }
        self.ready = envelope_cholesky(s, first, start);
    }

    /// Solves the rows together from the velocities `v` and multipliers `lambda`: each
    /// row's velocity `G_k^T v + b_k + c_k lambda_k` becomes zero.
    pub fn solve(
        &mut self,
        j: &Joints,
        groups: &RowGroups<1>,
        lambda: &mut [f64],
        v: &mut [f64],
        moved: &mut Movement,
    ) {
        for (y, &k) in self.step.iter_mut().zip(&self.rows) {
            *y = -j.row_velocity(k, groups.apply(k, v)[0], lambda[k]);
        }
        envelope_solve(&self.factor, &self.first, &self.start, &mut self.step);
        for (&dl, &k) in self.step.iter().zip(&self.rows) {
            if dl != 0.0 {
                lambda[k] += dl;
                groups.add(k, [dl], v);
            }
            moved.add(&[dl], &[lambda[k]]);
        }
    }

    /// Number of rows solved together (0 when none).
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// `y = L^-1 G_E^T x`, `L` the factor of `S`, for velocities `x`: the contacts'
    /// Delassus matrix through the joints is `H^T M^-1 H - Y^T Y` for `Y` of `x = M^-1 H`
    /// (`dense_contacts.rs`). Returns the first row where `y` is not zero: a contact's
    /// velocities reach a few rows, and the forward solve starts at the first of them.
    pub fn forward(&self, groups: &RowGroups<1>, x: &[f64], y: &mut [f64]) -> usize {
        for (yi, &k) in y.iter_mut().zip(&self.rows) {
            *yi = groups.apply(k, x)[0];
        }
        let from = y.iter().position(|&yi| yi != 0.0).unwrap_or(y.len());
        envelope_forward(&self.factor, &self.first, &self.start, y, from);
        from
    }
}

/// A pivot below this share of its row's diagonal means `S` is singular to working
/// precision.
const PIVOT_SHARE: f64 = 1e-10;

/// In-place lower Cholesky of the symmetric matrix `s` held row by row within its profile
/// (row i's columns `first[i]..=i` at `s[start[i]..start[i + 1]]`); false when a pivot is
/// not positive to working precision.
fn envelope_cholesky(s: &mut [f64], first: &[usize], start: &[usize]) -> bool {
    for (i, &fi) in first.iter().enumerate() {
        // Entry (i, m) of the profile sits at `row_i + m`.
        let row_i = start[i] - fi;
        // l_ik = (s_ik - sum_m l_im l_km) / l_kk over the columns both rows hold.
        for k in fi..i {
            let row_k = start[k] - first[k];
            let mut x = s[row_i + k];
            for m in fi.max(first[k])..k {
                x -= s[row_i + m] * s[row_k + m];
            }
            s[row_i + k] = x / s[row_k + k];
        }
        let diagonal = s[row_i + i];
        let mut d = diagonal;
        for m in fi..i {
            d -= s[row_i + m] * s[row_i + m];
        }
        if !(d > PIVOT_SHARE * diagonal && d.is_finite()) {
            return false;
        }
        s[row_i + i] = d.sqrt();
    }
    true
}

/// Solves `L x = y` in place with the factor of [`envelope_cholesky`], `y` zero before
/// row `from` (so the solve starts there).
fn envelope_forward(l: &[f64], first: &[usize], start: &[usize], y: &mut [f64], from: usize) {
    // Row i's entries left of the diagonal against `y[first[i]..i]`, as slices (indexing
    // each entry cost 12 instructions a multiply-add); those before `from` meet zeros.
    for (i, &fi) in first.iter().enumerate().skip(from) {
        let (row, diagonal) = (&l[start[i]..start[i + 1] - 1], l[start[i + 1] - 1]);
        let (before, at) = y.split_at_mut(i);
        let skip = from.saturating_sub(fi);
        let dot: f64 = row[skip..]
            .iter()
            .zip(&before[fi + skip..])
            .map(|(a, b)| a * b)
            .sum();
        at[0] = (at[0] - dot) / diagonal;
    }
}

/// Solves `L L^T x = y` in place with the factor of [`envelope_cholesky`].
fn envelope_solve(l: &[f64], first: &[usize], start: &[usize], y: &mut [f64]) {
    envelope_forward(l, first, start, y, 0);
    for (i, &fi) in first.iter().enumerate().rev() {
        let (row, diagonal) = (&l[start[i]..start[i + 1] - 1], l[start[i + 1] - 1]);
        let (before, at) = y.split_at_mut(i);
        let x = at[0] / diagonal;
        at[0] = x;
        for (ym, a) in before[fi..].iter_mut().zip(row) {
            *ym -= a * x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within its profile, the envelope factor solves as the dense Cholesky does, and
    /// refuses a singular matrix.
    #[test]
    fn the_envelope_factor_solves_as_the_dense_one() {
        // A chain's S: tridiagonal, plus one row coupled to the first (a tree's root).
        let p = 6;
        let first = [0, 0, 1, 2, 3, 0];
        let mut s = vec![0.0; p * p];
        for i in 0..p {
            s[i + i * p] = 4.0 + i as f64;
            for l in first[i]..i {
                let x = 1.0 / (1.0 + (i + l) as f64);
                s[i + l * p] = x;
                s[l + i * p] = x;
            }
        }
        let y: Vec<f64> = (0..p).map(|i| 1.0 - 0.3 * i as f64).collect();
        let (mut dense, mut x_dense) = (s.clone(), y.clone());
        assert!(crate::dense::cholesky(&mut dense, p));
        crate::dense::cholesky_solve(&dense, p, &mut x_dense);
        // The lower triangle within the profile, row by row.
        let mut start = vec![0];
        let mut envelope = Vec::new();
        for i in 0..p {
            envelope.extend((first[i]..=i).map(|l| s[i + l * p]));
            start.push(envelope.len());
        }
        let mut x = y.clone();
        assert!(envelope_cholesky(&mut envelope, &first, &start));
        envelope_solve(&envelope, &first, &start, &mut x);
        for (a, b) in x.iter().zip(&x_dense) {
            assert!((a - b).abs() <= 1e-14 * b.abs().max(1.0), "{a} against {b}");
        }
        // Rows 0 and 1 the same: singular.
        let mut twice = vec![1.0, 1.0, 1.0];
        assert!(!envelope_cholesky(&mut twice, &[0, 0], &[0, 1, 3]));
    }
}
