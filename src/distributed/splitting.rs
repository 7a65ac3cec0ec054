//! The global form's ADMM splitting over the processes sharing a problem
//! (docs/algorithms.md §16): one process's global splitting ([`GlobalSplitting`]) over the
//! [`DistributedSystem`], each process updating its own contacts (projection, shift, dual)
//! and its own bodies' velocities, the v-update solved by [`DistributedGram`] and every
//! norm added up across the processes in rank order.

use super::halo::agree_on;
use super::problem::{RankError, RankProblem};
use super::system::DistributedGram;
use crate::admm::EngineState;
use crate::contact::GlobalSplitting;
use crate::csc::dot;
use crate::linsys::velocity::{inexact_stop, Accuracy, ContactData, VelocitySystem};
use crate::measure::{Floors, GlobalSums, GlobalTerms, Scales};
use crate::types::Error;
use mpi::topology::SimpleCommunicator;

impl ContactData for RankProblem {
    fn w(&self) -> &[f64] {
        &self.w
    }

    fn mu(&self) -> &[f64] {
        &self.mu
    }
}

/// A process's part of the global form: its vectors over the constraint space are its own
/// contacts' rows, its velocities its own bodies'.
pub(crate) type DistributedSplitting = GlobalSplitting<DistributedSystem>;

/// The v-update system over the processes, with what the splitting asks of it beside the
/// solve: the measure's sums added up across processes, and the error a failed
/// factorization met.
pub(crate) struct DistributedSystem {
    gram: DistributedGram,
    /// Owned bodies: first velocity, velocities, offset of the mass block.
    blocks: Vec<(usize, usize, usize)>,
    rhs: Vec<f64>,
    mv: Vec<f64>,
    hr: Vec<f64>,
    u: Vec<f64>,
    /// The denominators of the last error measured (the inexact stop reads the equation's).
    scales: Scales,
    linear_iterations: usize,
    /// The error a failed [`VelocitySystem::set_rho`] met, which every process met alike.
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
        let gram = DistributedGram::new(comm, &part, active.clone())?;
        let mut norms = [dot(&part.mu, &part.mu), dot(&part.h_values, &part.h_values)];
        gram.halo().sum_across(&mut norms);
        let n = part.n_velocities();
        let system = DistributedSystem {
            blocks: gram.blocks().to_vec(),
            rhs: vec![0.0; n],
            mv: vec![0.0; n],
            hr: vec![0.0; n],
            u: vec![0.0; m],
            scales: Scales::default(),
            linear_iterations: 0,
            failure: None,
            gram,
        };
        let norms = norms.map(f64::sqrt);
        Ok(Self::with_system(part, system, n, active, norms))
    }

    /// Acary's first penalty `||M||_1 / ||H||_1` of the whole problem (docs/algorithms.md
    /// §6.1): the largest column sums are each owned by one process.
    pub fn acary_rho(&self) -> f64 {
        let (system, part) = self.system();
        let mut m_norm: f64 = 0.0;
        for &(_, k, at) in &system.blocks {
            for column in part.mass[at..at + k * k].chunks_exact(k) {
                m_norm = m_norm.max(column.iter().map(|x| x.abs()).sum());
            }
        }
        let h_norm = (0..3 * part.n_contacts())
            .map(|j| {
                let entries = part.h_colptr[j]..part.h_colptr[j + 1];
                part.h_values[entries].iter().map(|x| x.abs()).sum()
            })
            .fold(0.0f64, f64::max);
        self.max_across(m_norm) / self.max_across(h_norm)
    }

    /// The part this process solves.
    pub fn part(&self) -> &RankProblem {
        self.system().1
    }

    /// Seconds spent in exchanges with the other processes since the splitting was built.
    pub fn exchange_seconds(&self) -> f64 {
        self.system().0.gram.halo().exchange_seconds()
    }

    /// Conjugate-gradient iterations since the splitting was built.
    pub fn linear_iterations(&self) -> usize {
        self.system().0.linear_iterations
    }

    /// Takes the error a failed `set_rho` left (every process has the same).
    pub fn take_failure(&mut self) -> Option<RankError> {
        self.parts_mut().0.failure.take()
    }

    /// The communicator of the processes sharing the problem.
    pub fn comm(&self) -> &SimpleCommunicator {
        self.system().0.gram.halo().comm()
    }

    /// Every process learns whether one failed (see [`agree_on`]).
    pub fn agree_on(&self, outcome: Result<(), Error>) -> Result<(), RankError> {
        agree_on(self.comm(), outcome)
    }

    /// The impulses and relative velocities of the owned contacts at `state`, and the
    /// owned velocities in [`GlobalSplitting::velocities`].
    pub fn write_solution(&mut self, state: &EngineState, r: &mut Vec<f64>, u: &mut Vec<f64>) {
        r.clear();
        r.extend(state.zeta.iter().map(|z| -state.rho * z));
        u.resize(self.part().w.len(), 0.0);
        let (system, part, sol) = self.parts_mut();
        system.contact_velocity(part, sol, u);
    }

    /// This process's share of the measure's sums at the impulses `-rho zeta` and the
    /// current velocities, not yet added across processes (a collective call: `H r` is
    /// handed back to the owners), and whether those vectors are all finite.
    pub fn own_sums(&mut self, zeta: &[f64], rho: f64) -> (GlobalSums, bool) {
        let r: Vec<f64> = zeta.iter().map(|z| -rho * z).collect();
        let (system, part, sol) = self.parts_mut();
        system.own_sums(part, &r, sol)
    }

    /// Every process's measure sums added up, or `None` when some process's vectors are
    /// not all finite (a collective call).
    pub fn whole_sums(&self, sums: GlobalSums, finite: bool) -> Option<GlobalSums> {
        self.system().0.whole_sums(sums, finite)
    }

    /// The largest of every process's `x`.
    pub fn max_across(&self, x: f64) -> f64 {
        self.system().0.gram.halo().max_across(x)
    }
}

impl DistributedSystem {
    /// `out = M x` over the owned bodies.
    fn mass_mul(&self, part: &RankProblem, x: &[f64], out: &mut [f64]) {
        for &(first, k, at) in &self.blocks {
            let block = &part.mass[at..at + k * k];
            for i in 0..k {
                out[first + i] = (0..k).map(|j| block[j * k + i] * x[first + j]).sum();
            }
        }
    }

    /// This process's share of the measure's sums at impulses `r` and velocities `v`, and
    /// whether those vectors are all finite (a collective call).
    fn own_sums(&mut self, part: &RankProblem, r: &[f64], v: &[f64]) -> (GlobalSums, bool) {
        let (mut hr, mut mv, mut u) = (
            std::mem::take(&mut self.hr),
            std::mem::take(&mut self.mv),
            std::mem::take(&mut self.u),
        );
        self.gram.h_mul(r, &mut hr);
        self.mass_mul(part, v, &mut mv);
        self.contact_velocity(part, v, &mut u);
        let finite = [r, v, &u].iter().all(|x| x.iter().all(|v| v.is_finite()));
        let sums = GlobalTerms {
            f: &part.f,
            mv: &mv,
            hr: &hr,
            u: &u,
            r,
            mu: &part.mu,
        }
        .sums();
        (self.hr, self.mv, self.u) = (hr, mv, u);
        (sums, finite)
    }

    /// Every process's measure sums added up, or `None` when some process's vectors are
    /// not all finite (a collective call).
    fn whole_sums(&self, sums: GlobalSums, finite: bool) -> Option<GlobalSums> {
        let halo = self.gram.halo();
        sums.add_across(finite, |x| halo.max_across_each(x), |x| halo.sum_across(x))
    }

    /// The 2-norm of a vector split over the processes.
    fn norm_across(&self, x: &[f64]) -> f64 {
        let mut sq = [dot(x, x)];
        self.sum_across(&mut sq);
        sq[0].sqrt()
    }
}

impl VelocitySystem for DistributedSystem {
    type Data = RankProblem;

    fn set_rho(&mut self, _: &RankProblem, rho: f64, _: &[f64], _: bool) -> Result<(), Error> {
        self.gram.set_rho(rho).map_err(|e| {
            self.failure = Some(e);
            Error::NotPositiveDefinite {
                field: "M + rho H H^T",
            }
        })
    }

    fn x_step(
        &mut self,
        part: &RankProblem,
        t: &[f64],
        sol: &mut [f64],
        ax: &mut [f64],
        accuracy: Accuracy,
    ) {
        self.gram.h_mul(t, &mut self.rhs);
        for (b, f) in self.rhs.iter_mut().zip(&part.f) {
            *b += f;
        }
        let rhs_norm = self.norm_across(&self.rhs);
        let stop = inexact_stop(accuracy, self.scales.equation, rhs_norm);
        let out = self.gram.solve(&self.rhs, sol, &stop);
        self.linear_iterations += out.iterations;
        self.gram.h_t_mul(sol, ax);
    }

    fn h_t_mul(&mut self, _: &RankProblem, v: &[f64], out: &mut [f64]) {
        self.gram.h_t_mul(v, out);
    }

    fn h_norm(&mut self, _: &RankProblem, t: &[f64]) -> f64 {
        let mut ht = std::mem::take(&mut self.hr);
        self.gram.h_mul(t, &mut ht);
        let norm = self.norm_across(&ht);
        self.hr = ht;
        norm
    }

    fn measure(&mut self, part: &RankProblem, r: &[f64], sol: &[f64]) -> f64 {
        let (sums, finite) = self.own_sums(part, r, sol);
        match self.whole_sums(sums, finite) {
            Some(sums) => sums.error(Floors::default(), &mut self.scales),
            None => f64::INFINITY,
        }
    }

    fn sum_across(&self, partial: &mut [f64]) {
        self.gram.halo().sum_across(partial);
    }

    fn refactorizations(&self) -> usize {
        0
    }

    fn linear_iterations(&self) -> usize {
        self.linear_iterations
    }
}
