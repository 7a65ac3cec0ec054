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
use crate::tuning::JOINT_BLOCK_FLOPS;

/// The equality rows' factorized Delassus matrix (empty when not used).
#[derive(Default)]
pub(super) struct JointBlock {
    /// The rows solved together (unbounded, moved by some velocity), ascending.
    rows: Vec<usize>,
    /// Row `i`'s first column within the profile of `S`'s lower triangle.
    first: Vec<usize>,
    /// The rows on each block of M: for block `b` (of `block_size[b]` unknowns),
    /// `on_block[on_start[b]..on_start[b + 1]]` holds `(i, at)`, row `i` (ascending) whose
    /// values on the block start at `at` in `RowGroups::values`.
    on_start: Vec<usize>,
    on_block: Vec<(usize, usize)>,
    block_size: Vec<usize>,
    /// Work space: where each block's next row goes.
    fill: Vec<usize>,
    /// `S`, then its lower Cholesky factor, column-major `p x p` (only the profile is read).
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
        let p = self.rows.len();
        // The rows on each block (a counting sort by block), and row i's first row sharing
        // a body with it: the profile of S's lower triangle.
        self.on_start.clear();
        self.on_start.resize(mass.block_count() + 1, 0);
        for &k in &self.rows {
            for (b, _) in blocks(groups.reach(k), mass) {
                self.on_start[b + 1] += 1;
            }
        }
        for b in 0..mass.block_count() {
            self.on_start[b + 1] += self.on_start[b];
        }
        self.on_block.clear();
        self.on_block
            .resize(self.on_start[mass.block_count()], (0, 0));
        self.fill.clone_from(&self.on_start);
        self.block_size.clear();
        self.block_size
            .extend((0..mass.block_count()).map(|b| mass.block(b).len()));
        self.first.clear();
        for (i, &k) in self.rows.iter().enumerate() {
            let mut first = i;
            for (b, at) in blocks(groups.reach(k), mass) {
                let fill = &mut self.fill[b];
                if *fill > self.on_start[b] {
                    first = first.min(self.on_block[self.on_start[b]].0);
                }
                self.on_block[*fill] = (i, groups.offset(k) + at);
                *fill += 1;
            }
            self.first.push(first);
        }
        let flops: f64 = self
            .first
            .iter()
            .enumerate()
            .map(|(i, &f)| ((i - f) as f64).powi(2))
            .sum();
        self.ready = false;
        if p < 2 || flops > JOINT_BLOCK_FLOPS {
            self.rows.clear();
        }
        let p = self.rows.len();
        self.factor.clear();
        self.factor.resize(p * p, 0.0);
        self.step.clear();
        self.step.resize(p, 0.0);
    }

    /// Whether the factor holds: the rows are solved here, and the one-at-a-time sweep
    /// skips them.
    pub fn ready(&self) -> bool {
        self.ready
    }

    /// The rows solved together.
    pub fn rows(&self) -> &[usize] {
        &self.rows
    }

    /// Forms and factorizes `S` from the rows' values (`groups` holding them); the rows go
    /// back to the one-at-a-time sweep when `S` is not positive definite to working
    /// precision (redundant rows: a closed loop of joints).
    pub fn take_values(&mut self, j: &Joints, groups: &RowGroups<1>) {
        let p = self.rows.len();
        self.ready = false;
        if p == 0 {
            return;
        }
        // S_il = G_k^T M^-1 G_l sums over the blocks rows k and l share.
        let s = &mut self.factor;
        for (i, &f) in self.first.iter().enumerate() {
            (f..=i).for_each(|l| s[i + l * p] = 0.0); // row i's profile: all that is read
        }
        let (a_t, minv_a) = groups.values();
        for (b, &size) in self.block_size.iter().enumerate() {
            let on = &self.on_block[self.on_start[b]..self.on_start[b + 1]];
            for (x, &(i, at_i)) in on.iter().enumerate() {
                let a_i = &a_t[at_i..at_i + size];
                for &(l, at_l) in &on[..=x] {
                    let minv_l = &minv_a[at_l..at_l + size];
                    s[i + l * p] += a_i.iter().zip(minv_l).map(|(a, m)| a * m).sum::<f64>();
                }
            }
        }
        for (i, &k) in self.rows.iter().enumerate() {
            s[i + i * p] += j.compliance[k];
        }
        self.ready = envelope_cholesky(s, &self.first, p);
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
        let p = self.rows.len();
        for (y, &k) in self.step.iter_mut().zip(&self.rows) {
            *y = -j.row_velocity(k, groups.apply(k, v)[0], lambda[k]);
        }
        envelope_solve(&self.factor, &self.first, p, &mut self.step);
        for (&dl, &k) in self.step.iter().zip(&self.rows) {
            if dl != 0.0 {
                lambda[k] += dl;
                groups.add(k, [dl], v);
            }
            moved.add(&[dl], &[lambda[k]]);
        }
    }
}

/// A pivot below this share of its row's diagonal means `S` is singular to working
/// precision.
const PIVOT_SHARE: f64 = 1e-10;

/// In-place lower Cholesky of the column-major `p x p` matrix `s` within its profile
/// (`first[i]`: row i's first entry of the lower triangle); false when a pivot is not
/// positive to working precision.
fn envelope_cholesky(s: &mut [f64], first: &[usize], p: usize) -> bool {
    for i in 0..p {
        // Row i of L: l_ik = (s_ik - sum_m l_im l_km) / l_kk, for k from first[i].
        for k in first[i]..i {
            let from = first[i].max(first[k]);
            let mut x = s[i + k * p];
            for m in from..k {
                x -= s[i + m * p] * s[k + m * p];
            }
            s[i + k * p] = x / s[k + k * p];
        }
        let diagonal = s[i + i * p];
        let mut d = diagonal;
        for m in first[i]..i {
            d -= s[i + m * p] * s[i + m * p];
        }
        if !(d > PIVOT_SHARE * diagonal && d.is_finite()) {
            return false;
        }
        s[i + i * p] = d.sqrt();
    }
    true
}

/// Solves `L L^T x = y` in place with the factor of [`envelope_cholesky`].
fn envelope_solve(l: &[f64], first: &[usize], p: usize, y: &mut [f64]) {
    for i in 0..p {
        let mut x = y[i];
        for m in first[i]..i {
            x -= l[i + m * p] * y[m];
        }
        y[i] = x / l[i + i * p];
    }
    for i in (0..p).rev() {
        let x = y[i] / l[i + i * p];
        y[i] = x;
        for m in first[i]..i {
            y[m] -= l[i + m * p] * x;
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
        let (mut envelope, mut x) = (s.clone(), y.clone());
        assert!(envelope_cholesky(&mut envelope, &first, p));
        envelope_solve(&envelope, &first, p, &mut x);
        for (a, b) in x.iter().zip(&x_dense) {
            assert!((a - b).abs() <= 1e-14 * b.abs().max(1.0), "{a} against {b}");
        }
        // Rows 0 and 1 the same: singular.
        let mut twice = vec![1.0, 1.0, 1.0, 1.0];
        assert!(!envelope_cholesky(&mut twice, &[0, 0], 2));
    }
}
