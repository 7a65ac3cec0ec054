//! The solve of one problem shared out among processes: every process builds a
//! [`DistributedSolver`] from its part and calls the same methods in the same order; each
//! gets back its own contacts' impulses and velocities and its own bodies' velocities,
//! and every process the same status, iterations and error.

use super::halo::agree_on;
use super::problem::{RankError, RankProblem};
use super::splitting::DistributedSplitting;
use crate::admm::{run, EngineSettings, EngineState, Splitting};
use crate::problem::check_len;
use crate::settings::{InitialRho, LinearSolver, NewtonUse, Settings};
use crate::types::{ErrorKind, Stats, Status, TracePoint};
use mpi::topology::{Communicator, SimpleCommunicator};
use std::time::Instant;

/// ADMM on a global contact problem whose bodies and contacts are shared out among MPI
/// processes (docs/algorithms.md §16): the matrix-free v-update of one process's
/// iterative backend, across processes.
///
/// Every process of the communicator must make the same calls with the same settings:
/// each call that communicates returns on all of them, with the same outcome. An error
/// one process meets (a part that names an unknown body, a non-finite value) is every
/// process's [`RankError`], naming that process.
pub struct DistributedSolver {
    split: DistributedSplitting,
    settings: Settings,
    engine: EngineSettings,
    state: EngineState,
    rho0: f64,
    warm: bool,
    rank: usize,
    stats: Stats,
    /// Seconds the last solve spent in exchanges with the other processes.
    exchange_seconds: f64,
    trace: Vec<TracePoint>,
    r: Vec<f64>,
    u: Vec<f64>,
}

impl DistributedSolver {
    /// Builds the solver of this process's `part` of a problem shared over `comm` (a
    /// collective call: every process of `comm` makes it with its own part). The solver
    /// talks on its own duplicate of `comm`, so the host's messages never mix with its.
    ///
    /// Settings: the penalty rules, Anderson acceleration and limits apply as for one
    /// process; the v-update is always the matrix-free one (`linear_solver` `auto` or
    /// `iterative`), the first penalty is Acary's, normal or given, and no Newton phase
    /// runs (a Newton polish asked for is left out, as one process's matrix-free backend
    /// does). Other choices are an [`crate::Error::Unsupported`] or
    /// [`crate::Error::InvalidSetting`] error, on every process.
    pub fn new(
        comm: &SimpleCommunicator,
        part: RankProblem,
        settings: Settings,
    ) -> Result<Self, RankError> {
        let t0 = Instant::now();
        let rank = comm.rank() as usize;
        agree_on(comm, supported(&settings))?;
        let mut split = DistributedSplitting::new(comm, part)?;
        let resolved = settings.resolved();
        let rho0 = match resolved.initial_rho {
            InitialRho::Normal => 1.0,
            InitialRho::Given(rho) => rho,
            _ => split.acary_rho(),
        };
        let rho0 = if rho0.is_finite() && rho0 > 0.0 {
            rho0
        } else {
            1.0 // H = 0: any penalty will do
        };
        let engine = settings.engine_settings(&resolved, false);
        let engine = EngineSettings {
            handover: None,
            ..engine
        };
        split.set_rho(rho0).map_err(|_| failure(&mut split))?;
        let l = split.dim();
        let stats = Stats {
            setup_seconds: t0.elapsed().as_secs_f64(),
            rho: rho0,
            rows: l,
            ..Default::default()
        };
        Ok(Self {
            split,
            settings,
            engine,
            state: EngineState {
                y: vec![0.0; l],
                zeta: vec![0.0; l],
                ax: vec![0.0; l],
                rho: rho0,
            },
            rho0,
            warm: false,
            rank,
            stats,
            exchange_seconds: 0.0,
            trace: Vec::new(),
            r: Vec::new(),
            u: Vec::new(),
        })
    }

    /// Starts the next solve from impulses `r` of this process's contacts (3 per contact)
    /// and, when given, velocities `v` of its bodies (a collective call). Without it a
    /// solve starts from zero.
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), RankError> {
        let part = self.split.part();
        let checked = check_len("r", r, 3 * part.n_contacts())
            .and_then(|()| v.map_or(Ok(()), |v| check_len("v", v, part.n_velocities())));
        self.split.agree_on(checked)?;
        self.state.rho = self.rho0;
        self.split
            .set_rho(self.rho0)
            .map_err(|_| failure(&mut self.split))?;
        self.split.warm_start(r, v, &mut self.state);
        self.warm = true;
        Ok(())
    }

    /// Solves (a collective call); the status is every process's. A solve that stops
    /// short of the tolerance says so in its status, with the best iterate measured.
    pub fn solve(&mut self) -> Result<Status, RankError> {
        let t0 = Instant::now();
        if !std::mem::replace(&mut self.warm, false) {
            self.state.rho = self.rho0;
            self.split.cold_start(&mut self.state);
        }
        let before = self.split.linear_iterations();
        let exchanged = self.split.exchange_seconds();
        let out = run(&mut self.split, &mut self.state, &self.engine, t0)
            .map_err(|_| failure(&mut self.split))?;
        self.split
            .write_solution(&self.state, &mut self.r, &mut self.u);
        let status = out.status.unwrap_or(Status::MaxIterations);
        self.stats = Stats {
            status,
            iterations: out.iterations,
            error: out.error,
            primal_residual: out.primal,
            dual_residual: out.dual,
            rho: self.state.rho,
            anderson_accepted: out.aa_accepted,
            anderson_rejected: out.aa_rejected,
            setup_seconds: self.stats.setup_seconds,
            rows: self.state.y.len(),
            islands: 1,
            solve_seconds: t0.elapsed().as_secs_f64(),
            linear_iterations: self.split.linear_iterations() - before,
            ..Default::default()
        };
        self.trace = out.trace;
        self.exchange_seconds = self.split.exchange_seconds() - exchanged;
        Ok(status)
    }

    /// Impulses of this process's contacts (3 per contact, normal first).
    pub fn r(&self) -> &[f64] {
        &self.r
    }

    /// Relative velocities `u = H^T v + w` of this process's contacts.
    pub fn u(&self) -> &[f64] {
        &self.u
    }

    /// Velocities of this process's bodies.
    pub fn v(&self) -> &[f64] {
        self.split.velocities()
    }

    /// The last solve's statistics (the same on every process, but for the timings).
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Seconds of the last solve spent in exchanges with the other processes, waiting for
    /// them included (the rest of `stats().solve_seconds` is this process's own work).
    pub fn exchange_seconds(&self) -> f64 {
        self.exchange_seconds
    }

    /// The last solve's trace, when the settings ask for one.
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }

    /// The settings the solver was built with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Contacts this process owns.
    pub fn n_contacts(&self) -> usize {
        self.split.part().n_contacts()
    }

    /// Velocities this process owns.
    pub fn n_velocities(&self) -> usize {
        self.split.part().n_velocities()
    }

    /// The solver's communicator (its own duplicate of the host's).
    pub(crate) fn comm(&self) -> &SimpleCommunicator {
        self.split.comm()
    }

    /// This process's rank in the communicator.
    pub fn rank(&self) -> usize {
        self.rank
    }
}

/// Whether the distributed solve does what `settings` ask.
fn supported(settings: &Settings) -> Result<(), crate::Error> {
    settings.validate()?;
    if settings.linear_solver == LinearSolver::Direct {
        return Err(crate::Error::Unsupported(
            "linear_solver: a distributed problem is solved by the iterative backend (auto or \
             iterative)"
                .into(),
        ));
    }
    let resolved = settings.resolved();
    if resolved.newton == NewtonUse::Alone {
        return Err(crate::Error::Unsupported(
            "variant: Newton alone does not run on a distributed problem".into(),
        ));
    }
    if matches!(
        resolved.initial_rho,
        InitialRho::Ghadimi | InitialRho::DiCairano
    ) {
        return Err(crate::Error::Unsupported(
            "initial_rho: the spectral rules need the whole problem's spectrum; a distributed \
             problem takes acary, normal or a given rho"
                .into(),
        ));
    }
    Ok(())
}

/// The error a failed step of the splitting left (the same on every process).
fn failure(split: &mut DistributedSplitting) -> RankError {
    split.take_failure().unwrap_or(RankError {
        rank: 0,
        kind: ErrorKind::NotPositiveDefinite,
        message: "the solve failed".into(),
    })
}
