//! The global form's ADMM splitting over the processes sharing a problem
//! (docs/algorithms.md §16): the steps of one process's matrix-free global form (§4, §14),
//! each process updating its own contacts (projection, shift, dual) and its own bodies'
//! velocities, the v-update solved by [`DistributedGram`] and every norm added up across
//! the processes in rank order.

use super::halo::agree_on;
use super::problem::{RankError, RankProblem};
use super::system::DistributedGram;
use crate::admm::{EngineState, Splitting};
use crate::cone::{get3, project_dual_cone, set3};
use crate::contact::{de_saxce_shift, inexact_stop, initial_shift_of, prox_input};
use crate::csc::dot;
use crate::measure::{Floors, GlobalSums, GlobalTerms, Scales};
use crate::types::Error;
use mpi::topology::SimpleCommunicator;
use std::time::Instant;

/// A process's part of the global form `x = v`, `y = u~`, `A = H^T`, `c = -w - Phi(s)`:
/// its vectors over the constraint space are its own contacts' rows, its velocities its
/// own bodies'.
pub(crate) struct DistributedSplitting {
    part: RankProblem,
    system: DistributedGram,
    /// Owned bodies: first velocity, velocities, offset of the mass block.
    blocks: Vec<(usize, usize, usize)>,
    /// Owned velocities of the current iterate.
    sol: Vec<f64>,
    rhs: Vec<f64>,
    mv: Vec<f64>,
    hr: Vec<f64>,
    c: Vec<f64>,
    phi: Vec<f64>,
    active: Vec<f64>,
    work_m: Vec<f64>,
    r: Vec<f64>,
    /// `||mu||` and `||H||_F` of the whole problem, which the initial shift is made of.
    norm_mu: f64,
    h_fro: f64,
    /// The denominators of the last error measured, and that error (the inexact stop of
    /// the conjugate gradients reads both).
    scales: Scales,
    last_error: f64,
    deadline: Option<Instant>,
    linear_iterations: usize,
    /// The error a failed [`Splitting::set_rho`] met, which every process met alike.
    failure: Option<RankError>,
}

impl DistributedSplitting {
    /// The splitting of `part`, this process's part of a problem shared over `comm`
    /// (every process calls it with its own part, together).
    pub fn new(comm: &SimpleCommunicator, part: RankProblem) -> Result<Self, RankError> {
        let m = 3 * part.n_contacts();
        // Every row stays in the system (one process leaves the tangential rows of an
        // all-frictionless problem out; here they stay, inert, docs/algorithms.md §16).
        let active = vec![1.0; m];
        let system = DistributedGram::new(comm, &part, active.clone())?;
        let mut norms = [dot(&part.mu, &part.mu), dot(&part.h_values, &part.h_values)];
        system.halo().sum_across(&mut norms);
        let n = part.n_velocities();
        let mut split = Self {
            blocks: system.blocks().to_vec(),
            sol: vec![0.0; n],
            rhs: vec![0.0; n],
            mv: vec![0.0; n],
            hr: vec![0.0; n],
            c: vec![0.0; m],
            phi: vec![0.0; m],
            active,
            work_m: vec![0.0; m],
            r: vec![0.0; m],
            norm_mu: norms[0].sqrt(),
            h_fro: norms[1].sqrt(),
            scales: Scales::default(),
            last_error: f64::INFINITY,
            deadline: None,
            linear_iterations: 0,
            failure: None,
            system,
            part,
        };
        split.reset_shift();
        Ok(split)
    }

    /// Acary's first penalty `||M||_1 / ||H||_1` of the whole problem (docs/algorithms.md
    /// §6.1): the largest column sums are each owned by one process.
    pub fn acary_rho(&self) -> f64 {
        let mut m_norm: f64 = 0.0;
        for &(_, k, at) in &self.blocks {
            for column in self.part.mass[at..at + k * k].chunks_exact(k) {
                m_norm = m_norm.max(column.iter().map(|x| x.abs()).sum());
            }
        }
        let h_norm = (0..3 * self.part.n_contacts())
            .map(|j| {
                let entries = self.part.h_colptr[j]..self.part.h_colptr[j + 1];
                self.part.h_values[entries].iter().map(|x| x.abs()).sum()
            })
            .fold(0.0f64, f64::max);
        let halo = self.system.halo();
        halo.max_across(m_norm) / halo.max_across(h_norm)
    }

    /// The part this process solves.
    pub fn part(&self) -> &RankProblem {
        &self.part
    }

    /// The owned velocities of the current iterate.
    pub fn velocities(&self) -> &[f64] {
        &self.sol
    }

    /// Seconds spent in exchanges with the other processes since the splitting was built.
    pub fn exchange_seconds(&self) -> f64 {
        self.system.halo().exchange_seconds()
    }

    /// Conjugate-gradient iterations since the splitting was built.
    pub fn linear_iterations(&self) -> usize {
        self.linear_iterations
    }

    /// Takes the error a failed `set_rho` left (every process has the same).
    pub fn take_failure(&mut self) -> Option<RankError> {
        self.failure.take()
    }

    /// The communicator of the processes sharing the problem.
    pub fn comm(&self) -> &SimpleCommunicator {
        self.system.halo().comm()
    }

    /// Every process learns whether one failed (see [`agree_on`]).
    pub fn agree_on(&self, outcome: Result<(), Error>) -> Result<(), RankError> {
        agree_on(self.system.halo().comm(), outcome)
    }

    /// A start from nothing: no impulse, no velocity, the initial shift.
    pub fn cold_start(&mut self, state: &mut EngineState) {
        state.y.fill(0.0);
        state.zeta.fill(0.0);
        self.sol.fill(0.0);
        self.reset_shift();
    }

    /// A start from impulses `r` of the owned contacts and, when given, velocities `v` of
    /// the owned bodies (checked by the caller): as one process's global form does.
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>, state: &mut EngineState) {
        for (z, ri) in state.zeta.iter_mut().zip(r) {
            *z = -ri / state.rho;
        }
        state.y.fill(0.0);
        let Some(v) = v else {
            self.reset_shift();
            return;
        };
        self.sol.copy_from_slice(v);
        // u~ = P_K*(H^T v + w + Phi(u)), the shift taken from the same u.
        self.system.h_t_mul(v, &mut self.work_m);
        let mut u = std::mem::take(&mut self.r);
        for ((u, a), w) in u.iter_mut().zip(&self.work_m).zip(&self.part.w) {
            *u = a + w;
        }
        de_saxce_shift(&u, &self.part.mu, &mut self.phi);
        self.r = u;
        self.refresh_c();
        for (i, &mu) in self.part.mu.iter().enumerate() {
            let (a, c) = (get3(&self.work_m, i), get3(&self.c, i));
            set3(
                &mut state.y,
                i,
                project_dual_cone([a[0] - c[0], a[1] - c[1], a[2] - c[2]], mu),
            );
        }
    }

    /// The impulses and relative velocities of the owned contacts at `state`, and the
    /// owned velocities in [`DistributedSplitting::velocities`].
    pub fn write_solution(&mut self, state: &EngineState, r: &mut Vec<f64>, u: &mut Vec<f64>) {
        r.clear();
        r.extend(state.zeta.iter().map(|z| -state.rho * z));
        u.resize(self.part.w.len(), 0.0);
        self.system.h_t_mul(&self.sol, u);
        for (u, w) in u.iter_mut().zip(&self.part.w) {
            *u += w;
        }
    }

    /// Restarts the De Saxce shift from its initial guess (docs/algorithms.md §5) with the
    /// whole problem's norms, and the conjugate gradients' accuracy with it.
    fn reset_shift(&mut self) {
        initial_shift_of(&self.part.mu, self.norm_mu, self.h_fro, &mut self.phi);
        self.refresh_c();
        self.last_error = f64::INFINITY;
    }

    fn refresh_c(&mut self) {
        for ((c, w), s) in self.c.iter_mut().zip(&self.part.w).zip(&self.phi) {
            *c = -w - s;
        }
    }

    /// `out = M x` over the owned bodies.
    /// This process's share of the measure's sums at the impulses `-rho zeta` and the
    /// current velocities, not yet added across processes (a collective call: `H r` is
    /// handed back to the owners), and whether those vectors are all finite.
    pub fn own_sums(&mut self, zeta: &[f64], rho: f64) -> (GlobalSums, bool) {
        for (r, z) in self.r.iter_mut().zip(zeta) {
            *r = -rho * z;
        }
        let (mut hr, mut mv) = (std::mem::take(&mut self.hr), std::mem::take(&mut self.mv));
        self.system.h_mul(&self.r, &mut hr);
        self.mass_mul(&self.sol, &mut mv);
        // u = H^T v + w, in the work vector over the contact rows.
        let mut u = std::mem::take(&mut self.work_m);
        self.system.h_t_mul(&self.sol, &mut u);
        for (u, w) in u.iter_mut().zip(&self.part.w) {
            *u += w;
        }
        let finite = [&self.r, &self.sol, &u]
            .iter()
            .all(|x| x.iter().all(|v| v.is_finite()));
        let sums = GlobalTerms {
            f: &self.part.f,
            mv: &mv,
            hr: &hr,
            u: &u,
            r: &self.r,
            mu: &self.part.mu,
        }
        .sums();
        (self.hr, self.mv, self.work_m) = (hr, mv, u);
        (sums, finite)
    }

    fn mass_mul(&self, x: &[f64], out: &mut [f64]) {
        for &(first, k, at) in &self.blocks {
            let block = &self.part.mass[at..at + k * k];
            for i in 0..k {
                out[first + i] = (0..k).map(|j| block[j * k + i] * x[first + j]).sum();
            }
        }
    }

    /// Every process's measure sums added up, or `None` when some process's vectors are
    /// not all finite (a collective call).
    pub fn whole_sums(&self, sums: GlobalSums, finite: bool) -> Option<GlobalSums> {
        let halo = self.system.halo();
        let mut failed = false;
        let whole = sums.add_across(
            |scales| {
                // The flag travels with the scales: one exchange for both.
                let mut all = [0.0; 8];
                all[..7].copy_from_slice(scales);
                all[7] = f64::from(u8::from(!finite));
                halo.max_across_each(&mut all);
                scales.copy_from_slice(&all[..7]);
                failed = all[7] > 0.0;
            },
            |ssq| halo.sum_across(ssq),
        );
        (!failed).then_some(whole)
    }

    /// The largest of every process's `x`.
    pub fn max_across(&self, x: f64) -> f64 {
        self.system.halo().max_across(x)
    }

    /// The 2-norm of a vector split over the processes.
    fn norm_across(&self, x: &[f64]) -> f64 {
        let mut sq = [dot(x, x)];
        self.sum_across(&mut sq);
        sq[0].sqrt()
    }
}

impl Splitting for DistributedSplitting {
    fn dim(&self) -> usize {
        self.c.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        self.system.set_rho(rho).map_err(|e| {
            self.failure = Some(e);
            Error::NotPositiveDefinite {
                field: "M + rho H H^T",
            }
        })
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        for i in 0..self.work_m.len() {
            self.work_m[i] = self.active[i] * rho * (y[i] + self.c[i] - zeta[i]);
        }
        self.system.h_mul(&self.work_m, &mut self.rhs);
        for (b, f) in self.rhs.iter_mut().zip(&self.part.f) {
            *b += f;
        }
        let rhs_norm = self.norm_across(&self.rhs);
        let stop = inexact_stop(
            self.last_error,
            self.scales.equation,
            rhs_norm,
            self.deadline,
        );
        let out = self.system.solve(&self.rhs, &mut self.sol, &stop);
        self.linear_iterations += out.iterations;
        self.system.h_t_mul(&self.sol, ax);
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        for (i, &mu) in self.part.mu.iter().enumerate() {
            set3(
                y,
                i,
                project_dual_cone(prox_input(ax, &self.c, zeta, i), mu),
            );
        }
    }

    fn c(&self) -> &[f64] {
        &self.c
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        for i in 0..d.len() {
            self.work_m[i] = self.active[i] * d[i];
        }
        let mut hd = std::mem::take(&mut self.hr);
        self.system.h_mul(&self.work_m, &mut hd);
        let norm = self.norm_across(&hd);
        self.hr = hd;
        norm
    }

    fn update_s(&mut self, ax: &[f64], _y: &[f64]) {
        for ((u, a), w) in self.work_m.iter_mut().zip(ax).zip(&self.part.w) {
            *u = a + w;
        }
        de_saxce_shift(&self.work_m, &self.part.mu, &mut self.phi);
        self.refresh_c();
    }

    fn error(&mut self, _ax: &[f64], _y: &[f64], zeta: &[f64], rho: f64) -> f64 {
        let (sums, finite) = self.own_sums(zeta, rho);
        let error = match self.whole_sums(sums, finite) {
            Some(sums) => sums.error(Floors::default(), &mut self.scales),
            None => f64::INFINITY,
        };
        self.last_error = error;
        error
    }

    fn save_iterate(&self, into: &mut Vec<f64>) {
        into.extend_from_slice(&self.sol);
        into.extend_from_slice(&self.phi);
    }

    fn restore_iterate(&mut self, from: &[f64]) {
        let (sol, phi) = from.split_at(self.sol.len());
        self.sol.copy_from_slice(sol);
        self.phi.copy_from_slice(phi);
        self.refresh_c();
    }

    fn set_deadline(&mut self, deadline: Option<Instant>) {
        self.deadline = deadline;
    }

    fn sum_across(&self, partial: &mut [f64]) {
        self.system.halo().sum_across(partial);
    }
}
