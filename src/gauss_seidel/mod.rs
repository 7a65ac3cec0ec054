//! Projected block Gauss-Seidel over the contacts (and joint rows) of a global problem
//! whose M is block diagonal (an engine's rigid bodies): the first phase of a solve under a
//! time budget (docs/algorithms.md §17). A sweep visits each contact once, solves its own
//! 3 x 3 problem with every other impulse held, then each joint row (or all of them at
//! once, `joint_block.rs`), and moves the velocities by what changed; it costs one pass
//! over H and G and factorizes nothing but M's small blocks (and the joints' when solved
//! together). Its error falls fast at first and slowly after (sublinearly on stacks
//! and walls), so within an engine's milliseconds it answers far better than a few ADMM
//! iterations can, and it hands over to ADMM and Newton once a doubling of its sweeps no
//! longer pays.

mod contact;
mod dense_contacts;
mod joint_block;
mod movement;
mod rows;

use crate::cone::{get3, set3};
use crate::linsys::BlockDiagonal;
use crate::measure::{global_error_with, MeasureWork};
use crate::problem::{GlobalProblem, Joints};
use crate::tuning::{
    DENSE_CONTACTS_FIRST_SWEEPS, DENSE_CONTACTS_NEWTON_STEPS, DENSE_CONTACTS_TIGHTER, DENSE_MAX,
    GAUSS_SEIDEL_FIRST_MEASURE, GAUSS_SEIDEL_JUDGED_LATE, GAUSS_SEIDEL_MATRIX_FREE_SWEEPS,
    GAUSS_SEIDEL_MEASURE_SHARE, GAUSS_SEIDEL_PATIENCE,
};
use crate::types::{Error, Status};
use contact::ContactBlock;
use dense_contacts::{DenseContacts, Swept};
use joint_block::JointBlock;
use movement::{Movement, Stillness};
use rows::RowGroups;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The sweeps' data and iterates (empty by default, until [`GaussSeidel::refit`]).
#[derive(Default)]
pub(crate) struct GaussSeidel {
    /// M's blocks and their inverses.
    mass: BlockDiagonal,
    /// Zeros laid out as M's blocks (what `BlockDiagonal::invert` adds to them).
    no_shift: Vec<f64>,
    /// The contacts' columns of H, and each contact's own problem.
    contacts: RowGroups<3>,
    blocks: Vec<ContactBlock>,
    /// The joints' columns of G (none without joints), and each row's
    /// `1 / (G_j^T M^-1 G_j)` (0 for a row no velocity moves).
    joints: Option<RowGroups<1>>,
    joint_gain: Vec<f64>,
    /// The equality rows solved together, and the rows swept one at a time (all of them
    /// when the block's factor does not hold).
    joint_block: JointBlock,
    single_rows: Vec<usize>,
    /// The joints' pattern the rows' groups and block were fitted to.
    fitted_joints: JointPattern,
    /// Newton on the contacts' dense form when they are few, by their number (each built
    /// on first use).
    dense: Vec<Option<Box<DenseContacts>>>,
    /// The current iterate (`v = M^-1 (f + H r + G lambda)` up to the sweeps' round-off).
    r: Vec<f64>,
    lambda: Vec<f64>,
    v: Vec<f64>,
    /// The best iterate measured, and its error.
    best_r: Vec<f64>,
    best_lambda: Vec<f64>,
    best_v: Vec<f64>,
    best_error: f64,
    /// The last run was solved: its successor's warm start is worth measuring as it is.
    solved_last: bool,
    /// `f + H r + G lambda`, while the velocities are computed from it; positions of the
    /// velocities in a group's reach, while its values are taken.
    forces: Vec<f64>,
    position: Vec<usize>,
}

/// The pattern of a problem's joints: G's column pointers and row indices, and which rows
/// are bounded (empty without joints).
#[derive(Default)]
struct JointPattern {
    colptr: Vec<usize>,
    rowind: Vec<usize>,
    bounded: Vec<bool>,
    /// Whether any joints were taken (a problem without joints fits no pattern).
    joints: bool,
}

impl JointPattern {
    /// Whether `joints` have this pattern.
    fn fits(&self, joints: Option<&Joints>) -> bool {
        joints.is_some_and(|j| {
            self.joints
                && j.g.colptr() == self.colptr
                && j.g.rowind() == self.rowind
                && self
                    .bounded
                    .iter()
                    .enumerate()
                    .all(|(k, &b)| j.is_bounded(k) == b)
        })
    }

    /// Becomes the pattern of `joints`.
    fn take(&mut self, joints: Option<&Joints>) {
        self.joints = joints.is_some();
        self.colptr.clear();
        self.rowind.clear();
        self.bounded.clear();
        if let Some(j) = joints {
            self.colptr.extend_from_slice(j.g.colptr());
            self.rowind.extend_from_slice(j.g.rowind());
            self.bounded.extend((0..j.b.len()).map(|k| j.is_bounded(k)));
        }
    }
}

/// How a run of sweeps ended.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct SweepOutcome {
    /// `Some` when the run ended the solve (solved, or out of time or sweeps); `None` when
    /// it hands over.
    pub status: Option<Status>,
    pub sweeps: usize,
    /// The best error measured (that of [`GaussSeidel::best`]).
    pub error: f64,
    /// Newton's steps and factorizations on the contacts' dense form (`dense_contacts.rs`).
    pub newton_steps: usize,
    pub newton_factorizations: usize,
}

impl GaussSeidel {
    /// The sweeps for `p` when its M is made of small symmetric blocks on the diagonal;
    /// `None` otherwise. [`GaussSeidel::take_values`] takes the values before the first
    /// run.
    pub(crate) fn new(p: &GlobalProblem) -> Option<Self> {
        let mut sweeps = Self::default();
        sweeps.refit(p).then_some(sweeps)
    }

    /// Becomes [`GaussSeidel::new`]`(p)` in the memory it holds (a solver rebuilt for a
    /// step whose contacts changed: its arrays over the contacts and velocities are reused;
    /// M's block structure is built anew); false, and left to be refitted or dropped, when
    /// `p` does not suit the sweeps.
    pub(crate) fn refit(&mut self, p: &GlobalProblem) -> bool {
        let Some(mut mass) = BlockDiagonal::of(&p.m) else {
            return false;
        };
        mass.take_values(&p.m);
        if !mass.is_symmetric() {
            return false;
        }
        self.contacts.refit(&p.h, &mass, true);
        // A rebuild for new contacts (an engine's step) keeps the joints' structure, its
        // rows' order included, when their pattern and M's blocks are those it was fitted to.
        let kept = self.mass.same_blocks(&mass) && self.fitted_joints.fits(p.joints.as_ref());
        if !kept {
            match (&mut self.joints, &p.joints) {
                (Some(rows), Some(j)) => rows.refit(&j.g, &mass, false),
                (rows, j) => *rows = j.as_ref().map(|j| RowGroups::new(&j.g, &mass, false)),
            }
            match (&self.joints, &p.joints) {
                (Some(rows), Some(j)) => self.joint_block.refit(j, rows, &mass),
                _ => self.joint_block = JointBlock::default(),
            }
            self.fitted_joints.take(p.joints.as_ref());
        }
        let (n, m, np) = (p.n(), p.w.len(), p.n_joints());
        self.blocks.clear();
        self.blocks.resize(p.n_contacts(), ContactBlock::default());
        for (x, len) in [
            (&mut self.no_shift, mass.entries()),
            (&mut self.joint_gain, np),
            (&mut self.r, m),
            (&mut self.lambda, np),
            (&mut self.v, n),
            (&mut self.best_r, m),
            (&mut self.best_lambda, np),
            (&mut self.best_v, n),
            (&mut self.forces, n),
        ] {
            x.clear();
            x.resize(len, 0.0);
        }
        self.position.clear();
        self.position.resize(n, 0);
        self.best_error = f64::INFINITY;
        self.mass = mass;
        true
    }

    /// Inverts M's blocks (an error when one is not positive definite) and computes each
    /// contact's and joint row's data, for `p` (the pattern the sweeps were built for).
    /// Ok(false), nothing else taken, when a block of M is no longer symmetric: the sweeps
    /// no longer suit the problem. (M is block diagonal here, so its blocks' symmetry is
    /// its own, judged without a transpose.)
    pub(crate) fn take_values(&mut self, p: &GlobalProblem) -> Result<bool, Error> {
        self.mass.take_values(&p.m);
        if !self.mass.is_symmetric() {
            return Ok(false);
        }
        if self.mass.invert(0.0, &self.no_shift).is_err() {
            return Err(Error::NotPositiveDefinite { field: "M" });
        }
        self.contacts
            .take_values(&p.h, &self.mass, &mut self.position);
        for (c, block) in self.blocks.iter_mut().enumerate() {
            *block = ContactBlock::of(self.contacts.delassus(c));
        }
        if let (Some(rows), Some(j)) = (&mut self.joints, &p.joints) {
            rows.take_values(&j.g, &self.mass, &mut self.position);
            for (k, gain) in self.joint_gain.iter_mut().enumerate() {
                let d = rows.delassus(k)[0] + j.compliance[k];
                *gain = if d > 0.0 { 1.0 / d } else { 0.0 };
            }
            self.joint_block.take_values(j, rows);
        }
        // The rows not solved together, in order.
        let together = &self.joint_block;
        self.single_rows.clear();
        self.single_rows.extend(
            (0..self.joint_gain.len()).filter(|&k| !(together.ready() && together.solves(k))),
        );
        Ok(true)
    }

    /// Sweeps from the impulses `r0` (zero when `None`; the joint multipliers from zero),
    /// unless the warm start `(r0, v0)` is taken as it is
    /// ([`GaussSeidel::take_warm_start`]), until the measure meets `tolerance`,
    /// `max_sweeps` are done, the next sweep and measure would end past `deadline` (judged
    /// by the last ones; never before [`GAUSS_SEIDEL_FIRST_MEASURE`] sweeps), or the sweeps
    /// hand over ([`hand_over`]). The error is measured before the first sweep, after
    /// [`GAUSS_SEIDEL_FIRST_MEASURE`] sweeps and each doubling of them when worth it
    /// ([`worth_measuring`]), and at the end; the best iterate measured is kept
    /// ([`GaussSeidel::best`]).
    pub(crate) fn run(
        &mut self,
        p: &GlobalProblem,
        r0: Option<&[f64]>,
        v0: Option<&[f64]>,
        limits: SweepLimits,
        work: &mut MeasureWork,
    ) -> SweepOutcome {
        let t0 = Instant::now();
        self.start(r0);
        if let Some(outcome) = self.take_warm_start(p, v0, limits, work) {
            return outcome;
        }
        let first = self.measure(p, work);
        // The errors measured at the last two doublings' checkpoints, the latest first.
        let mut doublings = [first, f64::INFINITY];
        let mut outcome = SweepOutcome {
            error: first,
            ..SweepOutcome::default()
        };
        let (mut sweep_time, mut measure_time) = (0.0, t0.elapsed().as_secs_f64());
        let (mut checkpoint, mut measured) = (GAUSS_SEIDEL_FIRST_MEASURE, true);
        let (mut last_measure, mut stillness) = (0, Stillness::new(limits.tolerance));
        outcome.status = measured_status(first, limits);
        while outcome.status.is_none() {
            let left = limits.deadline.map_or(f64::INFINITY, seconds_until);
            // Fewer sweeps than the first measure's answer worse than an engine's own solver
            // does: the budget yields to them.
            let interrupted = limits.interrupt.is_some_and(|i| i.load(Ordering::Relaxed));
            let out_of_time = interrupted
                || (left < sweep_time + measure_time
                    && outcome.sweeps >= GAUSS_SEIDEL_FIRST_MEASURE);
            if out_of_time || outcome.sweeps >= limits.max_sweeps {
                outcome.status = Some(self.stop(p, work, measured, out_of_time, limits));
            } else {
                let at = Instant::now();
                let moved = self.sweep(p);
                sweep_time = at.elapsed().as_secs_f64();
                outcome.sweeps += 1;
                let doubling = outcome.sweeps == checkpoint && {
                    checkpoint *= 2;
                    let per_sweep = t0.elapsed().as_secs_f64() / outcome.sweeps as f64;
                    let judged = (outcome.sweeps - last_measure) as f64 * sweep_time;
                    worth_measuring(limits, per_sweep, left, measure_time, judged)
                };
                // A sweep that stood still (as engines stop their own) may have met the
                // tolerance: the measure says.
                measured = doubling || stillness.asks(moved);
                let mut error = match measured {
                    true => self.timed_measure(p, work, &mut measure_time),
                    false => f64::NAN,
                };
                if self.solves_contacts_now(outcome.sweeps, error, limits) {
                    let tried =
                        self.solve_contacts_at_once(p, limits, sweep_time, &mut outcome, work);
                    (error, measured) = tried.map_or((error, measured), |e| (e, true));
                }
                if measured {
                    last_measure = outcome.sweeps;
                }
                // Only a doubling's measure judges the sweeps' rate.
                if doubling {
                    let progress = Progress::after(outcome.sweeps, t0, doublings, error);
                    if progress.sweeps >= limits.yields.first_judged()
                        && hand_over(progress, limits)
                    {
                        outcome.error = self.best_error;
                        break;
                    }
                    doublings = [error, doublings[0]];
                }
            }
            outcome.error = self.best_error;
            outcome.status = outcome.status.or(measured_status(outcome.error, limits));
        }
        self.solved_last = outcome.status == Some(Status::Solved);
        outcome
    }

    /// The status of a run stopped by its time or sweep limit, its last iterate measured
    /// if it was not.
    fn stop(
        &mut self,
        p: &GlobalProblem,
        work: &mut MeasureWork,
        measured: bool,
        out_of_time: bool,
        limits: SweepLimits,
    ) -> Status {
        if !measured {
            self.measure(p, work);
        }
        // The last measure may meet the tolerance: then it is solved, not stopped.
        let stopped = match out_of_time {
            true => Status::TimeLimit,
            false => Status::MaxIterations,
        };
        measured_status(self.best_error, limits).unwrap_or(stopped)
    }

    /// Starts a run from the impulses `r0` (zero when `None`) and zero joint multipliers,
    /// with no best iterate yet.
    fn start(&mut self, r0: Option<&[f64]>) {
        match r0 {
            Some(r) => self.r.copy_from_slice(r),
            None => self.r.fill(0.0),
        }
        self.lambda.fill(0.0);
        self.best_error = f64::INFINITY;
    }

    /// A warm start that meets the tolerance with its own velocities `v0` is handed back
    /// as it is, as the coupled solver's short cut does: velocities recomputed from its
    /// impulses would move a resting scene's bodies by what the impulses miss, and the next
    /// step's warm start would measure worse. Measured only after a solved run (a scene at
    /// rest): in motion it would cost a measure a step. `self.r` holds the warm start's
    /// impulses and `self.lambda` zeros.
    fn take_warm_start(
        &mut self,
        p: &GlobalProblem,
        v0: Option<&[f64]>,
        limits: SweepLimits,
        work: &mut MeasureWork,
    ) -> Option<SweepOutcome> {
        let v = v0.filter(|_| self.solved_last)?;
        let error = global_error_with(p, &self.r, v, &self.lambda, work);
        if error > limits.tolerance {
            return None;
        }
        self.best_error = error;
        self.best_r.copy_from_slice(&self.r);
        self.best_v.copy_from_slice(v);
        self.best_lambda.fill(0.0);
        Some(SweepOutcome {
            status: Some(Status::Solved),
            error,
            ..SweepOutcome::default()
        })
    }

    /// One pass over the contacts in order, then over the joint rows; how far it moved
    /// the impulses.
    fn sweep(&mut self, p: &GlobalProblem) -> Movement {
        let mut moved = Movement::default();
        // `g` in the groups' stored order (interleaved, `RowGroups::refit`), `c` the contact.
        for (g, block) in self.blocks.iter_mut().enumerate() {
            let c = self.contacts.source(g);
            let hv = self.contacts.apply(g, &self.v);
            let w = get3(&p.w, c);
            let u = [hv[0] + w[0], hv[1] + w[1], hv[2] + w[2]];
            let r_old = get3(&self.r, c);
            let w_r = block.mul(r_old);
            let q = [u[0] - w_r[0], u[1] - w_r[1], u[2] - w_r[2]];
            let r_new = block.solve(q, p.mu[c], r_old);
            let dr = [
                r_new[0] - r_old[0],
                r_new[1] - r_old[1],
                r_new[2] - r_old[2],
            ];
            moved.add(&dr, &r_new);
            if dr != [0.0; 3] {
                set3(&mut self.r, c, r_new);
                self.contacts.add(g, dr, &mut self.v);
            }
        }
        let (Some(rows), Some(j)) = (&self.joints, &p.joints) else {
            return moved;
        };
        // Each row's multiplier makes its velocity `G_k^T v + b_k + c_k lambda_k` zero, the
        // others held, then is clamped into its bounds (infinite for an equality).
        for &k in &self.single_rows {
            let gain = self.joint_gain[k];
            let lambda = self.lambda[k];
            let y = j.row_velocity(k, rows.apply(k, &self.v)[0], lambda);
            let step = match j.is_bounded(k) {
                true => {
                    let (lo, hi) = j.bounds(k, &self.r);
                    (lambda - gain * y).clamp(lo, hi) - lambda
                }
                false => -gain * y,
            };
            if step != 0.0 {
                self.lambda[k] += step;
                rows.add(k, [step], &mut self.v);
            }
            moved.add(&[step], &[self.lambda[k]]);
        }
        if self.joint_block.ready() {
            self.joint_block
                .solve(j, rows, &mut self.lambda, &mut self.v, &mut moved);
        }
        moved
    }

    /// [`GaussSeidel::measure`], its time into `seconds`.
    fn timed_measure(
        &mut self,
        p: &GlobalProblem,
        work: &mut MeasureWork,
        seconds: &mut f64,
    ) -> f64 {
        let at = Instant::now();
        let error = self.measure(p, work);
        *seconds = at.elapsed().as_secs_f64();
        error
    }

    /// Recomputes `v = M^-1 (f + H r + G lambda)` exactly (the sweeps' increments drift),
    /// measures the iterate and keeps it when it is the best so far; returns its error.
    fn measure(&mut self, p: &GlobalProblem, work: &mut MeasureWork) -> f64 {
        self.forces.copy_from_slice(&p.f);
        p.h.mul_vec(1.0, &self.r, 1.0, &mut self.forces);
        if let Some(j) = &p.joints {
            j.g.mul_vec(1.0, &self.lambda, 1.0, &mut self.forces);
        }
        self.mass
            .mul_inverse(0..self.mass.block_count(), &self.forces, &mut self.v);
        let error = global_error_with(p, &self.r, &self.v, &self.lambda, work);
        if error < self.best_error || !self.best_error.is_finite() {
            self.best_error = error;
            self.best_r.copy_from_slice(&self.r);
            self.best_lambda.copy_from_slice(&self.lambda);
            self.best_v.copy_from_slice(&self.v);
        }
        error
    }

    /// Whether Newton solves the contacts at once after `sweeps` sweeps that measured
    /// `error` (NaN when not measured): after the first sweeps, still unsolved, when
    /// `limits` allow it, the contacts are few enough for their dense form ([`DENSE_MAX`]
    /// rows, `dense_contacts.rs`) and the joints, if any, all solved together (their
    /// elimination is then exact).
    fn solves_contacts_now(&self, sweeps: usize, error: f64, limits: SweepLimits) -> bool {
        let m = self.r.len();
        sweeps == GAUSS_SEIDEL_FIRST_MEASURE
            && measured_status(error, limits) != Some(Status::Solved)
            && limits.newton
            && m > 0
            && m <= DENSE_MAX
            && self.single_rows.is_empty()
    }

    /// Solves the contacts' dense form by Newton from the current impulses, until a share
    /// of `limits`' tolerance by its own measure or their deadline, then completes its
    /// answer with the joints' multipliers and the velocities and measures it. The sweeps
    /// go on from the better of it and the best iterate so far, whose error this returns.
    /// `None`, nothing tried, when the time left is shorter than Newton is expected to
    /// take: what its last attempt at this number of contacts took, or before one
    /// [`DENSE_CONTACTS_FIRST_SWEEPS`] sweeps of `sweep_time`.
    fn solve_contacts_at_once(
        &mut self,
        p: &GlobalProblem,
        limits: SweepLimits,
        sweep_time: f64,
        outcome: &mut SweepOutcome,
        work: &mut MeasureWork,
    ) -> Option<f64> {
        let nc = p.n_contacts();
        if self.dense.len() <= nc {
            self.dense.resize_with(nc + 1, || None);
        }
        let expected = match &self.dense[nc] {
            Some(d) => d.seconds,
            None => DENSE_CONTACTS_FIRST_SWEEPS * sweep_time,
        };
        if limits.deadline.map_or(f64::INFINITY, seconds_until) < expected {
            return None;
        }
        // Sizes within DENSE_MAX always build: no Newton is no loss.
        let mut dense = match self.dense[nc].take() {
            Some(d) => d,
            None => Box::new(DenseContacts::new(nc).ok()?),
        };
        let at = Instant::now();
        let joints = match (&self.joints, &p.joints) {
            (Some(rows), Some(j)) if self.joint_block.ready() => {
                Some((rows, j, &mut self.joint_block))
            }
            _ => None,
        };
        let swept = Swept {
            mass: &self.mass,
            contacts: &self.contacts,
            joints,
        };
        let bounds = (
            limits.tolerance * DENSE_CONTACTS_TIGHTER,
            DENSE_CONTACTS_NEWTON_STEPS,
            limits.deadline,
        );
        let solved = dense.solve(swept, p, &mut self.r, bounds);
        // Cut short by the deadline, it would have taken longer.
        let cut = solved
            .as_ref()
            .is_ok_and(|out| out.status_when_final(false, limits.deadline) == Status::TimeLimit);
        dense.seconds = at.elapsed().as_secs_f64() * if cut { 2.0 } else { 1.0 };
        self.dense[nc] = Some(dense);
        // An error is a W out of range: the sweeps go on without Newton.
        let error = match solved {
            Ok(newton) => {
                outcome.newton_steps += newton.iterations;
                outcome.newton_factorizations += newton.factorizations;
                self.complete(p);
                self.measure(p, work)
            }
            Err(_) => f64::INFINITY,
        };
        if error.is_nan() || error > self.best_error {
            // Worse than an earlier iterate (or not a number): the sweeps go on from that one.
            self.r.copy_from_slice(&self.best_r);
            self.lambda.copy_from_slice(&self.best_lambda);
            self.v.copy_from_slice(&self.best_v);
        }
        Some(error.min(self.best_error))
    }

    /// The joints' multipliers and the velocities of the impulses `self.r`: `v = M^-1 (f +
    /// H r)`, then the joint rows solved together from zero multipliers.
    fn complete(&mut self, p: &GlobalProblem) {
        self.forces.copy_from_slice(&p.f);
        p.h.mul_vec(1.0, &self.r, 1.0, &mut self.forces);
        self.mass
            .mul_inverse(0..self.mass.block_count(), &self.forces, &mut self.v);
        self.lambda.fill(0.0);
        if let (Some(rows), Some(j)) = (&self.joints, &p.joints) {
            if self.joint_block.ready() {
                let mut moved = Movement::default();
                self.joint_block
                    .solve(j, rows, &mut self.lambda, &mut self.v, &mut moved);
            }
        }
    }

    /// Whether the sweeps solve the joint rows together ([`JointBlock`]).
    pub(crate) fn joints_together(&self) -> bool {
        self.joint_block.ready()
    }

    /// The best iterate measured in the last run: impulses, velocities and joint
    /// multipliers.
    pub(crate) fn best(&self) -> (&[f64], &[f64], &[f64]) {
        (&self.best_r, &self.best_v, &self.best_lambda)
    }
}

/// The sweeps' progress at a checkpoint: the error after `sweeps` sweeps, and after half
/// as many.
#[derive(Debug, Clone, Copy)]
struct Progress {
    sweeps: usize,
    seconds: f64,
    halved_from: f64,
    /// The error after a quarter of the sweeps (infinite when not measured).
    quartered_from: f64,
    error: f64,
}

impl Progress {
    /// At a doubling's checkpoint: `error` after `sweeps` sweeps since `t0`, the errors of
    /// the last two checkpoints before it in `doublings` (the latest first).
    fn after(sweeps: usize, t0: Instant, doublings: [f64; 2], error: f64) -> Self {
        Self {
            sweeps,
            seconds: t0.elapsed().as_secs_f64(),
            halved_from: doublings[0],
            quartered_from: doublings[1],
            error,
        }
    }
}

/// Whether a checkpoint's measure is worth its time under `limits`, `per_sweep` being the
/// run's time per sweep so far (its measures included) and `left` the time to the
/// deadline: always while the sweeps could still hand over (the measure decides it), and
/// otherwise, when it only keeps the best iterate and sees the tolerance met, once it
/// costs at most [`GAUSS_SEIDEL_MEASURE_SHARE`] of the time `judged` the sweeps took since
/// the last one.
fn worth_measuring(
    limits: SweepLimits,
    per_sweep: f64,
    left: f64,
    measure_time: f64,
    judged: f64,
) -> bool {
    can_hand_over(per_sweep, left, limits.handover_sweeps)
        || measure_time <= GAUSS_SEIDEL_MEASURE_SHARE * judged
}

/// Whether `left` seconds could pay for the coupled solve after the sweeps: at least
/// `handover_sweeps` sweeps' worth ([`SweepLimits::handover_sweeps`]). Time left only
/// shrinks: once false, it stays false for the run.
fn can_hand_over(per_sweep: f64, left: f64, handover_sweeps: f64) -> bool {
    left >= handover_sweeps * per_sweep
}

/// Whether the sweeps should hand over to ADMM and Newton: when, at the rate of the
/// last doubling of the sweeps, they would need more than [`GAUSS_SEIDEL_PATIENCE`]
/// times the time spent so far to meet the tolerance, or more than the time left; and
/// only when the time left could pay for the coupled solve ([`can_hand_over`]).
/// Otherwise the sweeps are the best use of the time left.
fn hand_over(at: Progress, limits: SweepLimits) -> bool {
    let per_sweep = at.seconds / at.sweeps as f64;
    let left = limits.deadline.map_or(f64::INFINITY, seconds_until);
    if !can_hand_over(per_sweep, left, limits.handover_sweeps) {
        return false;
    }
    // Per doubling: over the last one, or before a matrix-free solve over the last two
    // (a single doubling's rate wanders, from 0.45 to 0.77 on piles of 25 000 spheres).
    let rate = match limits.yields {
        Yield::CoupledCost if at.quartered_from.is_finite() => {
            (at.error / at.quartered_from).sqrt()
        }
        _ => at.error / at.halved_from,
    };
    let needed = match rate < 1.0 && at.error > 0.0 {
        // Doublings of the sweeps still needed, at this rate.
        true => (limits.tolerance / at.error).ln() / rate.ln(),
        false => f64::INFINITY,
    };
    let to_go = at.seconds * (needed.exp2() - 1.0);
    let bar = match limits.yields {
        Yield::Patience => GAUSS_SEIDEL_PATIENCE * at.seconds,
        Yield::CoupledCost => GAUSS_SEIDEL_MATRIX_FREE_SWEEPS * per_sweep,
    };
    to_go > bar.min(left)
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
    /// The sweeps hand over only with this many sweeps' time left
    /// ([`crate::tuning::GAUSS_SEIDEL_HANDOVER_SWEEPS`]; on an engine's first step,
    /// [`crate::tuning::FIRST_STEP_HANDOVER_SWEEPS`]).
    pub handover_sweeps: f64,
    /// When the sweeps give way to the coupled solve.
    pub yields: Yield,
    /// Whether Newton may solve few contacts at once (off when the settings turn Newton
    /// off).
    pub newton: bool,
}

/// When the sweeps give way to the coupled solve (ADMM and Newton), judged at each
/// doubling of the sweeps by the time they would still need at the rate of their last
/// doubling (of the last two, before a matrix-free solve).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Yield {
    /// Under an engine's budget: from the 8th sweep, once that time exceeds
    /// [`GAUSS_SEIDEL_PATIENCE`] times the time they took.
    Patience,
    /// Before a matrix-free coupled solve, whose iterations cost ten sweeps' time or more:
    /// from the [`GAUSS_SEIDEL_JUDGED_LATE`]th sweep (the first doublings' rates say little
    /// of the later ones: on piles of 25 000 spheres the error fell by 0.65 to 0.7 a
    /// doubling up to 64 sweeps, and by 0.45 to 0.6 after), once it exceeds
    /// [`GAUSS_SEIDEL_MATRIX_FREE_SWEEPS`] sweeps' time, the least such a solve costs.
    CoupledCost,
}

impl Yield {
    /// The first checkpoint that may hand over.
    fn first_judged(self) -> usize {
        match self {
            Yield::Patience => 8,
            Yield::CoupledCost => GAUSS_SEIDEL_JUDGED_LATE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tuning::GAUSS_SEIDEL_HANDOVER_SWEEPS;

    /// Slow sweeps with 500 sweeps' time left hand over when the bar is 200 sweeps' time
    /// (an engine's first step), and keep sweeping when it is 2 000.
    #[test]
    fn the_handover_bar_is_the_limits_own() {
        let at = Progress {
            sweeps: 8,
            seconds: 8e-4,
            halved_from: 1.0,
            quartered_from: f64::INFINITY,
            error: 0.9,
        };
        for (bar, hands_over) in [(200.0, true), (GAUSS_SEIDEL_HANDOVER_SWEEPS, false)] {
            let limits = SweepLimits {
                tolerance: 1e-8,
                deadline: Instant::now().checked_add(std::time::Duration::from_millis(50)),
                max_sweeps: usize::MAX,
                interrupt: None,
                handover_sweeps: bar,
                yields: Yield::Patience,
                newton: true,
            };
            assert_eq!(hand_over(at, limits), hands_over, "bar {bar}");
        }
    }

    /// With time for a handover every checkpoint is measured; without, a measure waits
    /// until it costs at most a tenth of the sweeps it judges.
    #[test]
    fn checkpoints_are_measured_when_worth_it() {
        let (sweep, measure) = (1e-4, 2.5e-4);
        let limits = SweepLimits {
            tolerance: 1e-8,
            deadline: None,
            max_sweeps: usize::MAX,
            interrupt: None,
            handover_sweeps: GAUSS_SEIDEL_HANDOVER_SWEEPS,
            yields: Yield::Patience,
            newton: true,
        };
        let plenty = 2.0 * GAUSS_SEIDEL_HANDOVER_SWEEPS * sweep;
        assert!(worth_measuring(limits, sweep, plenty, measure, 4.0 * sweep));
        let tight = 40.0 * sweep;
        for sweeps in [4.0, 8.0, 16.0] {
            assert!(!worth_measuring(
                limits,
                sweep,
                tight,
                measure,
                sweeps * sweep
            ));
        }
        assert!(worth_measuring(limits, sweep, tight, measure, 32.0 * sweep));
    }

    /// A sweep that stands still is measured, where a measure dearer than the sweeps it
    /// judges would otherwise wait: with no time to hand over, two particles resting on a
    /// floor end within a few dozen sweeps (24), not at the checkpoint whose sweeps pay for
    /// the measure (1 024 of them).
    #[test]
    fn a_sweep_that_stands_still_is_measured() {
        use crate::csc::CscMatrix;
        // Particle 0 on the floor, particle 1 on particle 0; unit masses, gravity h g = 0.1.
        let h = CscMatrix::from_triplets(
            "H",
            6,
            6,
            &[
                (2, 0, 1.0),
                (0, 1, 1.0),
                (1, 2, 1.0),
                (5, 3, 1.0),
                (2, 3, -1.0),
                (3, 4, 1.0),
                (0, 4, -1.0),
                (4, 5, 1.0),
                (1, 5, -1.0),
            ],
        )
        .unwrap();
        let f = vec![0.0, 0.0, -0.1, 0.0, 0.0, -0.1];
        let p =
            GlobalProblem::new(CscMatrix::identity(6), h, f, vec![0.0; 6], vec![0.5, 0.5]).unwrap();
        let mut sweeps = GaussSeidel::new(&p).unwrap();
        sweeps.take_values(&p).unwrap();
        let limits = SweepLimits {
            tolerance: 1e-6,
            deadline: Instant::now().checked_add(std::time::Duration::from_secs(600)),
            max_sweeps: 100_000,
            interrupt: None,
            // No handover can follow: checkpoints are measured only when cheap enough.
            handover_sweeps: f64::INFINITY,
            yields: Yield::Patience,
            newton: true,
        };
        let mut work = MeasureWork::global(&p);
        let out = sweeps.run(&p, None, None, limits, &mut work);
        assert_eq!(out.status, Some(Status::Solved), "{out:?}");
        assert!(out.sweeps <= 64, "{out:?}");
        let (r, v, lambda) = sweeps.best();
        let error = crate::measure::global_error(&p, r, v, lambda);
        assert!(error <= 1e-6, "{error:e}");
        // The stack's weight on the floor: both particles' gravity.
        assert!(
            (r[0] - 0.2).abs() <= 1e-6 && (r[3] - 0.1).abs() <= 1e-6,
            "{r:?}"
        );
    }
}
