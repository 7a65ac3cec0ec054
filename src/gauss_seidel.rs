//! Projected block Gauss-Seidel over the contacts of a global problem whose M is block
//! diagonal (an engine's rigid bodies): the first phase of a solve under a time budget
//! (docs/algorithms.md §17). A sweep visits each contact once, solves its own 3 x 3
//! problem with every other impulse held, and moves the velocities by what changed; it
//! costs one pass over H and factorizes nothing but M's small blocks. Its error falls
//! fast at first and slowly after (sublinearly on stacks and walls), so within an
//! engine's milliseconds it answers far better than a few ADMM iterations can, and it
//! hands over to ADMM and Newton once a doubling of its sweeps no longer pays.

use crate::cone::{de_saxce_term, get3, project_cone, set3, tangential_norm};
use crate::linsys::BlockDiagonal;
use crate::measure::{global_error_with, MeasureWork};
use crate::problem::GlobalProblem;
use crate::tuning::{
    GAUSS_SEIDEL_FIRST_MEASURE, GAUSS_SEIDEL_HANDOVER_SWEEPS, GAUSS_SEIDEL_INNER,
    GAUSS_SEIDEL_PATIENCE,
};
use crate::types::{Error, Status};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// One contact's Delassus block `W_cc = H_c^T M^-1 H_c` (row-major), its inverse when it
/// is well conditioned, and the step of its projected fixed point, `1 / lambda_max`.
#[derive(Debug, Clone, Copy, Default)]
struct ContactBlock {
    w: [f64; 9],
    inverse: Option<[f64; 9]>,
    step: f64,
}

/// The sweeps' data: M's blocks and, for each contact, the velocities it reaches with its
/// rows of `H^T` and of `(M^-1 H)^T` over them, and its Delassus block.
pub(crate) struct GaussSeidel {
    /// M's blocks and their inverses.
    mass: BlockDiagonal,
    /// Zeros laid out as M's blocks (what `BlockDiagonal::invert` adds to them).
    no_shift: Vec<f64>,
    /// Contact `c` reaches the velocities `reach[start[c]..start[c + 1]]`: the unknowns of
    /// the blocks of M its columns of H touch.
    start: Vec<usize>,
    reach: Vec<usize>,
    /// Contact `c`'s three rows of `H_c^T` over its reach, one after the other from
    /// `3 start[c]`; `minv_h` the same for `(M^-1 H_c)^T`.
    ht: Vec<f64>,
    minv_h: Vec<f64>,
    blocks: Vec<ContactBlock>,
    /// The current iterate (`v = M^-1 (f + H r)` up to the sweeps' round-off).
    r: Vec<f64>,
    v: Vec<f64>,
    /// The best iterate measured, and its error.
    best_r: Vec<f64>,
    best_v: Vec<f64>,
    best_error: f64,
    /// `f + H r`, while the velocities are computed from it.
    forces: Vec<f64>,
}

/// How a run of sweeps ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SweepOutcome {
    /// `Some` when the run ended the solve (solved, or out of time or sweeps); `None` when
    /// it hands over.
    pub status: Option<Status>,
    pub sweeps: usize,
    /// The best error measured (that of [`GaussSeidel::best`]).
    pub error: f64,
}

impl GaussSeidel {
    /// The sweeps for `p` when its M is made of small symmetric blocks on the diagonal
    /// and it has no joints; `None` otherwise. [`GaussSeidel::take_values`] takes the
    /// values before the first run.
    pub(crate) fn new(p: &GlobalProblem) -> Option<Self> {
        if p.joints.is_some() {
            return None;
        }
        let mut mass = BlockDiagonal::of(&p.m)?;
        mass.take_values(&p.m);
        if !mass.is_symmetric() {
            return None;
        }
        let (start, reach) = reach_of(p, &mass);
        let len = 3 * reach.len();
        let (n, m) = (p.n(), p.w.len());
        Some(Self {
            no_shift: vec![0.0; mass.entries()],
            mass,
            start,
            reach,
            ht: vec![0.0; len],
            minv_h: vec![0.0; len],
            blocks: vec![ContactBlock::default(); p.n_contacts()],
            r: vec![0.0; m],
            v: vec![0.0; n],
            best_r: vec![0.0; m],
            best_v: vec![0.0; n],
            forces: vec![0.0; n],
            best_error: f64::INFINITY,
        })
    }

    /// Inverts M's blocks (an error when one is not positive definite, or M is not
    /// symmetric) and computes each contact's rows and Delassus block, for `p` (the
    /// pattern the sweeps were built for).
    pub(crate) fn take_values(&mut self, p: &GlobalProblem) -> Result<(), Error> {
        self.mass.take_values(&p.m);
        if !self.mass.is_symmetric() {
            return Err(Error::Unsupported(
                "Gauss-Seidel sweeps: M is no longer symmetric".into(),
            ));
        }
        if self.mass.invert(0.0, &self.no_shift).is_err() {
            return Err(Error::NotPositiveDefinite { field: "M" });
        }
        let mut position = vec![usize::MAX; p.n()];
        for c in 0..self.blocks.len() {
            let (from, to) = (self.start[c], self.start[c + 1]);
            let len = to - from;
            for (k, &i) in self.reach[from..to].iter().enumerate() {
                position[i] = k;
            }
            let rows = 3 * from..3 * to;
            let (ht, minv_h) = (&mut self.ht[rows.clone()], &mut self.minv_h[rows]);
            ht.fill(0.0);
            for d in 0..3 {
                for (i, x) in p.h.col(3 * c + d) {
                    ht[d * len + position[i]] = x;
                }
            }
            // M^-1 H_c block by block: the reach is whole blocks, one after the other.
            let mut k = 0;
            while k < len {
                let b = self.mass.block_containing(self.reach[from + k]);
                let (inverse, size) = (self.mass.inverse_block(b), self.mass.block(b).len());
                for d in 0..3 {
                    let at = d * len + k..d * len + k + size;
                    mul_symmetric(inverse, &ht[at.clone()], &mut minv_h[at]);
                }
                k += size;
            }
            let mut w = [0.0; 9];
            for a in 0..3 {
                for b in 0..3 {
                    let (x, y) = (&ht[a * len..(a + 1) * len], &minv_h[b * len..(b + 1) * len]);
                    w[3 * a + b] = x.iter().zip(y).map(|(x, y)| x * y).sum();
                }
            }
            self.blocks[c] = ContactBlock::of(w);
        }
        Ok(())
    }

    /// Sweeps from the impulses `r0` (zero when `None`) until the measure meets
    /// `tolerance`, `max_sweeps` are done, the next sweep and measure would end past
    /// `deadline` (judged by the last ones; never before [`GAUSS_SEIDEL_FIRST_MEASURE`]
    /// sweeps), or the sweeps hand over ([`hand_over`]). The
    /// error is measured before the first sweep, after [`GAUSS_SEIDEL_FIRST_MEASURE`]
    /// sweeps and each doubling of them, and at the end; the best iterate
    /// measured is kept ([`GaussSeidel::best`]).
    pub(crate) fn run(
        &mut self,
        p: &GlobalProblem,
        r0: Option<&[f64]>,
        limits: SweepLimits,
        work: &mut MeasureWork,
    ) -> SweepOutcome {
        let t0 = Instant::now();
        match r0 {
            Some(r) => self.r.copy_from_slice(r),
            None => self.r.fill(0.0),
        }
        self.best_error = f64::INFINITY;
        let mut previous = self.measure(p, work);
        let mut outcome = SweepOutcome {
            status: None,
            sweeps: 0,
            error: previous,
        };
        let (mut sweep_time, mut measure_time) = (0.0, t0.elapsed().as_secs_f64());
        let (mut checkpoint, mut measured) = (GAUSS_SEIDEL_FIRST_MEASURE, true);
        outcome.status = measured_status(previous, limits);
        while outcome.status.is_none() {
            let left = limits.deadline.map_or(f64::INFINITY, seconds_until);
            // Fewer sweeps than the first measure's answer worse than an engine's own solver
            // does: the budget yields to them.
            let interrupted = limits.interrupt.is_some_and(|i| i.load(Ordering::Relaxed));
            let out_of_time = interrupted
                || (left < sweep_time + measure_time
                    && outcome.sweeps >= GAUSS_SEIDEL_FIRST_MEASURE);
            if out_of_time || outcome.sweeps >= limits.max_sweeps {
                if !measured {
                    self.measure(p, work);
                }
                outcome.status = Some(match out_of_time {
                    true => Status::TimeLimit,
                    false => Status::MaxIterations,
                });
            } else {
                let at = Instant::now();
                self.sweep(p);
                sweep_time = at.elapsed().as_secs_f64();
                outcome.sweeps += 1;
                measured = outcome.sweeps == checkpoint;
                if measured {
                    let at = Instant::now();
                    let error = self.measure(p, work);
                    measure_time = at.elapsed().as_secs_f64();
                    checkpoint *= 2;
                    let progress = Progress {
                        sweeps: outcome.sweeps,
                        seconds: t0.elapsed().as_secs_f64(),
                        halved_from: previous,
                        error,
                    };
                    if progress.sweeps >= 8 && hand_over(progress, limits) {
                        outcome.error = self.best_error;
                        break;
                    }
                    previous = error;
                }
            }
            outcome.error = self.best_error;
            outcome.status = outcome.status.or(measured_status(outcome.error, limits));
        }
        outcome
    }

    /// One pass over the contacts in order.
    fn sweep(&mut self, p: &GlobalProblem) {
        for c in 0..self.blocks.len() {
            let (from, to) = (self.start[c], self.start[c + 1]);
            let len = to - from;
            let reach = &self.reach[from..to];
            let ht = &self.ht[3 * from..3 * to];
            let mut u = get3(&p.w, c);
            for (d, u) in u.iter_mut().enumerate() {
                let row = &ht[d * len..(d + 1) * len];
                *u += row
                    .iter()
                    .zip(reach)
                    .map(|(h, &i)| h * self.v[i])
                    .sum::<f64>();
            }
            let block = &self.blocks[c];
            let r_old = get3(&self.r, c);
            let w_r = block.mul(r_old);
            let q = [u[0] - w_r[0], u[1] - w_r[1], u[2] - w_r[2]];
            let r_new = block.solve(q, p.mu[c], r_old);
            let dr = [
                r_new[0] - r_old[0],
                r_new[1] - r_old[1],
                r_new[2] - r_old[2],
            ];
            if dr == [0.0; 3] {
                continue;
            }
            set3(&mut self.r, c, r_new);
            let minv_h = &self.minv_h[3 * from..3 * to];
            for (k, &i) in reach.iter().enumerate() {
                self.v[i] +=
                    minv_h[k] * dr[0] + minv_h[len + k] * dr[1] + minv_h[2 * len + k] * dr[2];
            }
        }
    }

    /// Recomputes `v = M^-1 (f + H r)` exactly (the sweeps' increments drift), measures
    /// the iterate and keeps it when it is the best so far; returns its error.
    fn measure(&mut self, p: &GlobalProblem, work: &mut MeasureWork) -> f64 {
        self.forces.copy_from_slice(&p.f);
        p.h.mul_vec(1.0, &self.r, 1.0, &mut self.forces);
        self.mass
            .mul_inverse(0..self.mass.block_count(), &self.forces, &mut self.v);
        let error = global_error_with(p, &self.r, &self.v, &[], work);
        if error < self.best_error || !self.best_error.is_finite() {
            self.best_error = error;
            self.best_r.copy_from_slice(&self.r);
            self.best_v.copy_from_slice(&self.v);
        }
        error
    }

    /// The best iterate measured in the last run: impulses and velocities.
    pub(crate) fn best(&self) -> (&[f64], &[f64]) {
        (&self.best_r, &self.best_v)
    }
}

/// The sweeps' progress at a checkpoint: the error after `sweeps` sweeps, and after half
/// as many.
#[derive(Debug, Clone, Copy)]
struct Progress {
    sweeps: usize,
    seconds: f64,
    halved_from: f64,
    error: f64,
}

/// Whether the sweeps should hand over to ADMM and Newton: when, at the rate of the
/// last doubling of the sweeps, they would need more than [`GAUSS_SEIDEL_PATIENCE`]
/// times the time spent so far to meet the tolerance, or more than the time left; and
/// only when the time left could pay for the coupled solve (at least
/// [`GAUSS_SEIDEL_HANDOVER_SWEEPS`] sweeps' worth). Otherwise the sweeps are the best
/// use of the time left.
fn hand_over(at: Progress, limits: SweepLimits) -> bool {
    let per_sweep = at.seconds / at.sweeps as f64;
    let left = limits.deadline.map_or(f64::INFINITY, seconds_until);
    if left < GAUSS_SEIDEL_HANDOVER_SWEEPS * per_sweep {
        return false;
    }
    let rate = at.error / at.halved_from;
    let needed = match rate < 1.0 && at.error > 0.0 {
        // Doublings of the sweeps still needed, at this rate.
        true => (limits.tolerance / at.error).ln() / rate.ln(),
        false => f64::INFINITY,
    };
    let to_go = at.seconds * (needed.exp2() - 1.0);
    to_go > (GAUSS_SEIDEL_PATIENCE * at.seconds).min(left)
}

/// The status an error ends the sweeps with: solved at the tolerance, a numerical error
/// when not finite, none otherwise.
fn measured_status(error: f64, limits: SweepLimits) -> Option<Status> {
    match error {
        e if e <= limits.tolerance => Some(Status::Solved),
        e if !e.is_finite() => Some(Status::NumericalError),
        _ => None,
    }
}

/// Seconds from now until `deadline` (0 once past).
fn seconds_until(deadline: Instant) -> f64 {
    deadline
        .saturating_duration_since(Instant::now())
        .as_secs_f64()
}

/// What bounds a run of sweeps; a set `interrupt` ends it as the deadline does.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SweepLimits<'a> {
    pub tolerance: f64,
    pub deadline: Option<Instant>,
    pub max_sweeps: usize,
    pub interrupt: Option<&'a AtomicBool>,
}

impl ContactBlock {
    fn of(w: [f64; 9]) -> Self {
        let lambda_max = largest_eigenvalue(&w);
        Self {
            w,
            inverse: inverse(&w),
            step: if lambda_max > 0.0 {
                1.0 / lambda_max
            } else {
                0.0
            },
        }
    }

    fn mul(&self, x: [f64; 3]) -> [f64; 3] {
        let w = &self.w;
        [
            w[0] * x[0] + w[1] * x[1] + w[2] * x[2],
            w[3] * x[0] + w[4] * x[1] + w[5] * x[2],
            w[6] * x[0] + w[7] * x[1] + w[8] * x[2],
        ]
    }

    /// The contact's impulse for `u = W r + q`, the others held: none when `q` separates,
    /// the sticking impulse `-W^-1 q` when it lies in the cone, and otherwise a few steps
    /// of the projected fixed point `r <- P_K(r - step (u + mu ||u_T|| e_N))` from `r`.
    fn solve(&self, q: [f64; 3], mu: f64, mut r: [f64; 3]) -> [f64; 3] {
        if q[0] >= 0.0 {
            return [0.0; 3];
        }
        if let Some(inv) = &self.inverse {
            let stick = [
                -(inv[0] * q[0] + inv[1] * q[1] + inv[2] * q[2]),
                -(inv[3] * q[0] + inv[4] * q[1] + inv[5] * q[2]),
                -(inv[6] * q[0] + inv[7] * q[1] + inv[8] * q[2]),
            ];
            if stick[0] >= 0.0 && tangential_norm(stick[1], stick[2]) <= mu * stick[0] {
                return stick;
            }
        }
        for _ in 0..GAUSS_SEIDEL_INNER {
            let wr = self.mul(r);
            let u = [wr[0] + q[0], wr[1] + q[1], wr[2] + q[2]];
            let un = u[0] + de_saxce_term(u, mu);
            r = project_cone(
                [
                    r[0] - self.step * un,
                    r[1] - self.step * u[1],
                    r[2] - self.step * u[2],
                ],
                mu,
            );
        }
        r
    }
}

/// For each contact, the unknowns of the blocks of M its columns of H touch, block after
/// block in the order of the blocks: `(start, reach)` as in [`GaussSeidel`].
fn reach_of(p: &GlobalProblem, mass: &BlockDiagonal) -> (Vec<usize>, Vec<usize>) {
    let mut start = Vec::with_capacity(p.n_contacts() + 1);
    start.push(0);
    // A contact touches one or two bodies: a linear search beats sorting its entries.
    let mut reach = Vec::with_capacity(2 * p.h.nnz() / 3);
    let mut touched: Vec<usize> = Vec::new();
    for c in 0..p.n_contacts() {
        touched.clear();
        for d in 0..3 {
            for (i, _) in p.h.col(3 * c + d) {
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
    (start, reach)
}

/// `y = A x` for a symmetric column-major `A` (its columns are its rows), unrolled for a
/// rigid body's 6 x 6 block.
fn mul_symmetric(a: &[f64], x: &[f64], y: &mut [f64]) {
    if let (Ok(x), true) = (<&[f64; 6]>::try_from(x), a.len() == 36) {
        for (y, row) in y.iter_mut().zip(a.chunks_exact(6)) {
            *y = row[0] * x[0]
                + row[1] * x[1]
                + row[2] * x[2]
                + row[3] * x[3]
                + row[4] * x[4]
                + row[5] * x[5];
        }
        return;
    }
    for (y, row) in y.iter_mut().zip(a.chunks_exact(x.len())) {
        *y = row.iter().zip(x).map(|(a, x)| a * x).sum();
    }
}

/// The largest eigenvalue of a symmetric 3 x 3 matrix (row-major), in closed form
/// (the trigonometric solution of its characteristic cubic).
fn largest_eigenvalue(w: &[f64; 9]) -> f64 {
    let off = w[1] * w[1] + w[2] * w[2] + w[5] * w[5];
    let trace = w[0] + w[4] + w[8];
    if off == 0.0 {
        return w[0].max(w[4]).max(w[8]);
    }
    let mean = trace / 3.0;
    let d = [w[0] - mean, w[4] - mean, w[8] - mean];
    let p2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * off;
    let scale = (p2 / 6.0).sqrt();
    // det((W - mean I) / scale) / 2, clamped into [-1, 1] against round-off.
    let b = [
        d[0] / scale,
        w[1] / scale,
        w[2] / scale,
        d[1] / scale,
        w[5] / scale,
        d[2] / scale,
    ];
    let det = b[0] * (b[3] * b[5] - b[4] * b[4]) - b[1] * (b[1] * b[5] - b[4] * b[2])
        + b[2] * (b[1] * b[4] - b[3] * b[2]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    mean + 2.0 * scale * phi.cos()
}

/// The inverse of a symmetric positive definite 3 x 3 matrix (row-major) when its
/// determinant is clear of round-off; `None` for a singular or nearly singular block (a
/// contact whose rows are dependent), which then has no sticking shortcut.
fn inverse(w: &[f64; 9]) -> Option<[f64; 9]> {
    let cof = [
        w[4] * w[8] - w[5] * w[7],
        w[2] * w[7] - w[1] * w[8],
        w[1] * w[5] - w[2] * w[4],
        w[5] * w[6] - w[3] * w[8],
        w[0] * w[8] - w[2] * w[6],
        w[2] * w[3] - w[0] * w[5],
        w[3] * w[7] - w[4] * w[6],
        w[1] * w[6] - w[0] * w[7],
        w[0] * w[4] - w[1] * w[3],
    ];
    let det = w[0] * cof[0] + w[1] * cof[3] + w[2] * cof[6];
    let trace = w[0] + w[4] + w[8];
    // Written to refuse a NaN determinant too.
    (det > 1e-12 * trace * trace * trace).then(|| cof.map(|x| x / det))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, SymmetricEigen};

    fn spd(seed: u64) -> [f64; 9] {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a = Matrix3::from_fn(|_, _| next());
        let w = a * a.transpose() + Matrix3::identity() * 0.01;
        let mut out = [0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                out[3 * i + j] = w[(i, j)];
            }
        }
        out
    }

    #[test]
    fn closed_form_eigenvalue_and_inverse_match_nalgebra() {
        for seed in 0..200 {
            let w = spd(seed);
            let m = Matrix3::from_row_slice(&w);
            let largest = SymmetricEigen::new(m).eigenvalues.max();
            approx::assert_relative_eq!(largest_eigenvalue(&w), largest, max_relative = 1e-10);
            let inv = Matrix3::from_row_slice(&inverse(&w).unwrap());
            approx::assert_relative_eq!(inv * m, Matrix3::identity(), epsilon = 1e-8);
        }
        let diagonal = [2.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 3.0];
        assert_eq!(largest_eigenvalue(&diagonal), 5.0);
        assert!(inverse(&[1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0]).is_none());
    }

    /// Each branch of a contact's own solve meets Coulomb's law for its `u = W r + q`.
    #[test]
    fn a_contact_solve_meets_coulombs_law_on_each_branch() {
        let block = ContactBlock::of(spd(7));
        let mu = 0.5;
        for q in [[0.3, 1.0, -2.0], [-1.0, 0.1, 0.05], [-1.0, 3.0, -2.0]] {
            let mut r = [0.0; 3];
            for _ in 0..400 {
                r = block.solve(q, mu, r);
            }
            let wr = block.mul(r);
            let u = [wr[0] + q[0], wr[1] + q[1], wr[2] + q[2]];
            let error = crate::measure::complementarity_residual(&r, &u, &[mu]);
            assert!(error < 1e-9, "q {q:?}: r {r:?}, u {u:?}, residual {error}");
        }
    }
}
