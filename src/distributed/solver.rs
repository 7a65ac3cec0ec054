//! The solve of one problem shared out among processes: every process builds a
//! [`DistributedSolver`] from its part and calls the same methods in the same order; each
//! gets back its own contacts' impulses and velocities and its own bodies' velocities,
//! and every process the same status, iterations and error.
//!
//! A process's islands that no other process's contacts reach ([`RankSplit`]) are solved
//! by that process alone, by the one-process [`Solver`] with everything it does for an
//! island (free motion, Newton on small islands, a factorized backend); the rest, the
//! shared problem, by ADMM across the processes. As for one process's islands, the whole
//! problem's measure judges the assembled answer, and when it misses the tolerance both
//! are solved again, warm, to a tighter one.

use super::halo::{agree_on, all_gather_varcount};
use super::islands::{RankSplit, Slot};
use super::problem::{RankError, RankProblem};
use super::splitting::DistributedSplitting;
use crate::admm::{run, EngineSettings, EngineState, Splitting};
use crate::contact::shared_initial_rho;
use crate::measure::{Floors, GlobalTerms, Scales};
use crate::problem::{check_len, GlobalProblem, Problem};
use crate::scene::refine::{most_severe, refine_rounds, severity, status_of, SolveInParts};
use crate::settings::{InitialRho, LinearSolver, NewtonUse, Resolved, Settings};
use crate::solver::Solver;
use crate::tuning::{ISLAND_ROUNDS, ROUND_OFF_MARGIN};
use crate::types::{ErrorKind, Stats, Status, TracePoint};
use mpi::topology::{Communicator, SimpleCommunicator};
use std::time::Instant;

/// ADMM on a global contact problem whose bodies and contacts are shared out among MPI
/// processes (docs/algorithms.md §16): the matrix-free v-update of one process's
/// iterative backend, across processes; islands inside one process solved there.
///
/// Every process of the communicator must make the same calls with the same settings:
/// each call that communicates returns on all of them, with the same outcome. An error
/// one process meets (a part that names an unknown body, a non-finite value) is every
/// process's [`RankError`], naming that process.
pub struct DistributedSolver {
    /// The shared problem's splitting (this process's rows of it, maybe none).
    split: DistributedSplitting,
    /// This process's own islands, and their problem (the solver keeps its own copy,
    /// which it does not hand out; the measure of the whole reads this one).
    own: Option<Solver>,
    own_problem: Option<GlobalProblem>,
    /// Where each of this process's contacts and bodies went.
    contacts: Vec<Slot>,
    bodies: Vec<(Slot, usize)>,
    n_velocities: usize,
    /// Contacts of the shared problem, on all processes together.
    shared_contacts: usize,
    /// Islands solved inside one process, on all processes together.
    own_islands: usize,
    settings: Settings,
    resolved: Resolved,
    state: EngineState,
    rho0: f64,
    warm: bool,
    rank: usize,
    stats: Stats,
    /// Seconds the last solve spent in exchanges with the other processes.
    exchange_seconds: f64,
    trace: Vec<TracePoint>,
    /// The shared problem's impulses and relative velocities (this process's rows).
    shared_r: Vec<f64>,
    shared_u: Vec<f64>,
    r: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
}

impl DistributedSolver {
    /// Builds the solver of this process's `part` of a problem shared over `comm` (a
    /// collective call: every process of `comm` makes it with its own part). The solver
    /// talks on its own duplicate of `comm`, so the host's messages never mix with its.
    ///
    /// Settings: the penalty rules, Anderson acceleration and limits apply as for one
    /// process. The shared problem's v-update is always the matrix-free one
    /// (`linear_solver` `auto` or `iterative`), its first penalty is Acary's, normal or
    /// given, and no Newton phase runs on it (as one process's matrix-free backend); a
    /// process's own islands are solved with the settings as given. Other choices are an
    /// [`crate::Error::Unsupported`] or [`crate::Error::InvalidSetting`] error, on every
    /// process. Every process must pass the same settings but for `threads`; any other
    /// that differs is every process's [`ErrorKind::InvalidSetting`], naming it and the
    /// ranks. With `islands` off, the whole problem is shared.
    pub fn new(
        comm: &SimpleCommunicator,
        part: RankProblem,
        settings: Settings,
    ) -> Result<Self, RankError> {
        let t0 = Instant::now();
        let rank = comm.rank() as usize;
        agree_on(comm, supported(&settings))?;
        same_settings(comm, &settings)?;
        let n_velocities = part.n_velocities();
        let cut = RankSplit::new(comm, part, settings.islands)?;
        let mut split = DistributedSplitting::new(comm, cut.shared)?;
        let own_problem = cut.own;
        let own = own_problem
            .as_ref()
            .map(|p| Solver::new(Problem::Global(p.clone()), settings.clone()));
        let built = own
            .as_ref()
            .map_or(Ok(()), |o| o.as_ref().map(|_| ()).map_err(Clone::clone));
        split.agree_on(built)?;
        let own = own.map(|o| o.expect("agreed"));
        let mut counts = [
            split.part().n_contacts() as f64,
            own.as_ref().map_or(0.0, |o| o.stats().islands as f64),
        ];
        split.sum_across(&mut counts);
        let resolved = settings.resolved();
        let rho0 = shared_initial_rho(resolved.initial_rho, || split.acary_rho());
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
            own,
            own_problem,
            contacts: cut.contacts,
            bodies: cut.bodies,
            n_velocities,
            shared_contacts: counts[0] as usize,
            own_islands: counts[1] as usize,
            settings,
            resolved,
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
            shared_r: Vec::new(),
            shared_u: Vec::new(),
            r: Vec::new(),
            u: Vec::new(),
            v: Vec::new(),
        })
    }

    /// Starts the next solve from impulses `r` of this process's contacts (3 per contact)
    /// and, when given, velocities `v` of its bodies (a collective call). Without it a
    /// solve starts from zero.
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), RankError> {
        let checked = check_len("r", r, 3 * self.contacts.len())
            .and_then(|()| v.map_or(Ok(()), |v| check_len("v", v, self.n_velocities)));
        self.split.agree_on(checked)?;
        // Each part's share of r and v.
        let mut shared_r = vec![0.0; self.state.zeta.len()];
        let own_size = self
            .own_problem
            .as_ref()
            .map_or((0, 0), |p| (p.n_contacts(), p.n()));
        let mut own_r = vec![0.0; 3 * own_size.0];
        for (c, &slot) in self.contacts.iter().enumerate() {
            let (to, k) = match slot {
                Slot::Shared(k) => (&mut shared_r, k),
                Slot::Own(k) => (&mut own_r, k),
            };
            to[3 * k..3 * k + 3].copy_from_slice(&r[3 * c..3 * c + 3]);
        }
        let parts_v = v.map(|v| {
            let mut shared_v = vec![0.0; self.split.part().n_velocities()];
            let mut own_v = vec![0.0; own_size.1];
            let mut first = 0;
            for &(slot, k) in &self.bodies {
                let (to, at) = match slot {
                    Slot::Shared(at) => (&mut shared_v, at),
                    Slot::Own(at) => (&mut own_v, at),
                };
                to[at..at + k].copy_from_slice(&v[first..first + k]);
                first += k;
            }
            (shared_v, own_v)
        });
        self.state.rho = self.rho0;
        self.split
            .set_rho(self.rho0)
            .map_err(|_| failure(&mut self.split))?;
        let shared_v = parts_v.as_ref().map(|(s, _)| &s[..]);
        self.split.start_warm(&shared_r, shared_v, &mut self.state);
        let own = match &mut self.own {
            Some(o) => o.warm_start(&own_r, parts_v.as_ref().map(|(_, v)| &v[..])),
            None => Ok(()),
        };
        self.split.agree_on(own)?;
        self.warm = true;
        Ok(())
    }

    /// Solves (a collective call); the status is every process's. A solve that stops
    /// short of the tolerance says so in its status, with the best iterate measured.
    pub fn solve(&mut self) -> Result<Status, RankError> {
        let t0 = Instant::now();
        if !std::mem::replace(&mut self.warm, false) {
            self.state.rho = self.rho0;
            self.split.start_cold(&mut self.state);
        }
        let before = self.split.linear_iterations();
        let exchanged = self.split.exchange_seconds();
        let tol = self.settings.tolerance;
        let mut rounds = RankRounds {
            solver: self,
            tolerance: tol,
            t0,
            shared: Stats::default(),
        };
        let (status, error) = refine_rounds(&mut rounds, tol, ISLAND_ROUNDS)?;
        let shared = rounds.shared;
        self.assemble();
        self.collect_stats(status, error, shared, before, t0);
        self.exchange_seconds = self.split.exchange_seconds() - exchanged;
        Ok(status)
    }

    /// ADMM on the shared problem to `tol` (less the round-off margin), when the problem
    /// has one; its iterations and Anderson counts added to `stats`.
    fn solve_shared(
        &mut self,
        tol: f64,
        t0: Instant,
        stats: &mut Stats,
    ) -> Result<Option<Status>, RankError> {
        if self.shared_contacts == 0 {
            return Ok(None);
        }
        let settings = Settings {
            tolerance: tol * (1.0 - ROUND_OFF_MARGIN),
            ..self.settings.clone()
        };
        let engine = EngineSettings {
            handover: None,
            ..settings.engine_settings(&self.resolved, false)
        };
        let out = run(&mut self.split, &mut self.state, &engine, t0)
            .map_err(|_| failure(&mut self.split))?;
        self.split
            .write_solution(&self.state, &mut self.shared_r, &mut self.shared_u);
        out.add_to(stats);
        self.trace = out.trace;
        Ok(Some(out.status.unwrap_or(Status::MaxIterations)))
    }

    /// This process's own islands to `tol`, within what is left of the time limit (every
    /// process learns of an error one met).
    fn solve_own(&mut self, tol: f64, t0: Instant) -> Result<Option<Status>, RankError> {
        let outcome = match &mut self.own {
            Some(own) => {
                let left = self.settings.time_limit - t0.elapsed().as_secs_f64();
                let settings = Settings {
                    tolerance: tol,
                    time_limit: left.max(f64::MIN_POSITIVE),
                    ..self.settings.clone()
                };
                own.update_settings(settings)
                    .and_then(|()| own.solve())
                    .map(Some)
            }
            None => Ok(None),
        };
        let status = outcome.as_ref().map(|_| ()).map_err(Clone::clone);
        self.split.agree_on(status)?;
        Ok(outcome.expect("agreed"))
    }

    /// The whole problem's measure at the parts' solutions (a collective call): the sums
    /// it is made of, the shared problem's and the own islands', added across processes.
    fn whole_error(&mut self) -> f64 {
        let (mut sums, mut finite) = self.split.own_sums(&self.state.zeta, self.state.rho);
        if let (Some(own), Some(p)) = (&self.own, &self.own_problem) {
            let s = own.solution();
            let (mut mv, mut hr) = (vec![0.0; s.v.len()], vec![0.0; s.v.len()]);
            p.m.mul_vec(1.0, &s.v, 0.0, &mut mv);
            p.h.mul_vec(1.0, &s.r, 0.0, &mut hr);
            let terms = GlobalTerms {
                f: &p.f,
                mv: &mv,
                hr: &hr,
                u: &s.u,
                r: &s.r,
                mu: &p.mu,
            };
            sums = sums.add(terms.sums());
            finite &= [&s.r, &s.u, &s.v]
                .iter()
                .all(|x| x.iter().all(|v| v.is_finite()));
        }
        match self.split.whole_sums(sums, finite) {
            Some(sums) => sums.error(Floors::default(), &mut Scales::default()),
            None => f64::INFINITY,
        }
    }

    /// Warm starts both parts from their last solutions, for the next round.
    fn restart_from_solutions(&mut self) -> Result<(), RankError> {
        let v = self.split.velocities().to_vec();
        let r = std::mem::take(&mut self.shared_r);
        self.split.start_warm(&r, Some(&v), &mut self.state);
        self.shared_r = r;
        let own = match &mut self.own {
            Some(own) => {
                let s = own.solution().clone();
                own.warm_start(&s.r, Some(&s.v))
            }
            None => Ok(()),
        };
        self.split.agree_on(own)
    }

    /// This process's r, u and v from the parts' solutions.
    fn assemble(&mut self) {
        let empty = crate::Solution::default();
        let own = self.own.as_ref().map_or(&empty, Solver::solution);
        let (r, u) = (&mut self.r, &mut self.u);
        r.resize(3 * self.contacts.len(), 0.0);
        u.resize(3 * self.contacts.len(), 0.0);
        for (c, &slot) in self.contacts.iter().enumerate() {
            let (from_r, from_u, k) = match slot {
                Slot::Shared(k) => (&self.shared_r, &self.shared_u, k),
                Slot::Own(k) => (&own.r, &own.u, k),
            };
            r[3 * c..3 * c + 3].copy_from_slice(&from_r[3 * k..3 * k + 3]);
            u[3 * c..3 * c + 3].copy_from_slice(&from_u[3 * k..3 * k + 3]);
        }
        self.v.resize(self.n_velocities, 0.0);
        let mut first = 0;
        for &(slot, k) in &self.bodies {
            let (from, at) = match slot {
                Slot::Shared(at) => (self.split.velocities(), at),
                Slot::Own(at) => (&own.v[..], at),
            };
            self.v[first..first + k].copy_from_slice(&from[at..at + k]);
            first += k;
        }
    }

    /// The whole solve's statistics, the same on every process but for the timings:
    /// iterations are the most any process's parts took, counts are totals.
    fn collect_stats(
        &mut self,
        status: Status,
        error: f64,
        shared: Stats,
        linear_before: usize,
        t0: Instant,
    ) {
        let none = Stats::default();
        let own = self.own.as_ref().map_or(&none, Solver::stats);
        let iterations = self
            .split
            .max_across(shared.iterations.max(own.iterations) as f64);
        // This process's own islands and its rows of the shared part, added up over the
        // processes; the shared part's ADMM counts and CG iterations are every process's.
        let mine = Stats {
            rows: own.rows + self.state.y.len(),
            ..*own
        };
        let mut totals = mine.part_counts().map(|k| k as f64);
        self.split.sum_across(&mut totals);
        let mut stats = Stats {
            status,
            iterations: iterations as usize,
            error,
            primal_residual: shared.primal_residual,
            dual_residual: shared.dual_residual,
            rho: self.state.rho,
            setup_seconds: self.stats.setup_seconds,
            islands: self.own_islands + usize::from(self.shared_contacts > 0),
            solve_seconds: t0.elapsed().as_secs_f64(),
            ..Default::default()
        };
        stats.set_part_counts(totals.map(|k| k as usize));
        stats.anderson_accepted += shared.anderson_accepted;
        stats.anderson_rejected += shared.anderson_rejected;
        stats.linear_iterations += self.split.linear_iterations() - linear_before;
        self.stats = stats;
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
        &self.v
    }

    /// The last solve's statistics (the same on every process, but for the timings).
    /// `islands` counts the islands solved inside one process and the shared problem as
    /// one.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Seconds of the last solve spent in exchanges with the other processes, waiting for
    /// them included (the rest of `stats().solve_seconds` is this process's own work).
    pub fn exchange_seconds(&self) -> f64 {
        self.exchange_seconds
    }

    /// The last solve's trace of the shared problem, when the settings ask for one.
    pub fn trace(&self) -> &[TracePoint] {
        &self.trace
    }

    /// The settings the solver was built with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Contacts this process owns.
    pub fn n_contacts(&self) -> usize {
        self.contacts.len()
    }

    /// Velocities this process owns.
    pub fn n_velocities(&self) -> usize {
        self.n_velocities
    }

    /// Contacts of this process in the shared problem (the others are in its own
    /// islands).
    pub fn n_shared_contacts(&self) -> usize {
        self.split.part().n_contacts()
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

/// Every process must solve with the same settings (all but `threads`, each process's own
/// pool): the shared solve takes its decisions (stop, penalty, Anderson steps, rounds)
/// together, and a process that decided otherwise would wait forever for the others. Each
/// setting is compared as text across processes, and the first that differs is every
/// process's [`ErrorKind::InvalidSetting`], naming it, the two ranks and their values.
fn same_settings(comm: &SimpleCommunicator, s: &Settings) -> Result<(), RankError> {
    let fields = [
        ("tolerance", format!("{:?}", s.tolerance)),
        ("max_iterations", format!("{:?}", s.max_iterations)),
        ("time_limit", format!("{:?}", s.time_limit)),
        ("variant", format!("{:?}", s.variant)),
        ("initial_rho", format!("{:?}", s.initial_rho)),
        ("s_update", format!("{:?}", s.s_update)),
        ("anderson", format!("{:?}", s.anderson)),
        ("anderson_interval", format!("{:?}", s.anderson_interval)),
        ("trace", format!("{:?}", s.trace)),
        ("newton_polish", format!("{:?}", s.newton_polish)),
        ("islands", format!("{:?}", s.islands)),
        ("linear_solver", format!("{:?}", s.linear_solver)),
    ];
    let mine: Vec<u64> = fields
        .iter()
        .map(|(_, value)| value.as_str())
        .collect::<Vec<_>>()
        .join("\n")
        .bytes()
        .map(u64::from)
        .collect();
    let all = all_gather_varcount(comm, &mine);
    let text = |rank: usize| {
        String::from_utf8_lossy(&all[rank].iter().map(|&b| b as u8).collect::<Vec<_>>())
            .into_owned()
    };
    let first = text(0);
    for rank in 1..all.len() {
        let other = text(rank);
        let differing = fields
            .iter()
            .zip(first.split('\n').zip(other.split('\n')))
            .find(|(_, (a, b))| a != b);
        if let Some(((name, _), (a, b))) = differing {
            return Err(RankError {
                rank,
                kind: ErrorKind::InvalidSetting,
                message: format!(
                    "invalid setting {name}: rank 0 has {a}, rank {rank} has {b}; every process \
                     must solve with the same settings (all but threads)"
                ),
            });
        }
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

/// One solve of the shared part and the processes' own islands, as the refine rounds drive
/// it (a collective call, every process in step).
struct RankRounds<'a> {
    solver: &'a mut DistributedSolver,
    /// The parts' tolerance this round.
    tolerance: f64,
    t0: Instant,
    /// The shared part's statistics over the rounds.
    shared: Stats,
}

impl SolveInParts for RankRounds<'_> {
    type Error = RankError;

    fn solve_parts(&mut self) -> Result<Option<Status>, RankError> {
        let (tol, t0) = (self.tolerance, self.t0);
        let shared = self.solver.solve_shared(tol, t0, &mut self.shared)?;
        let own = self.solver.solve_own(tol, t0)?;
        // Every process learns the most severe status of any.
        let code = self
            .solver
            .split
            .max_across(f64::from(severity(most_severe(shared, own))));
        Ok(status_of(code as u8))
    }

    fn whole_error(&mut self) -> Result<f64, RankError> {
        Ok(self.solver.whole_error())
    }

    fn tighten(&mut self, factor: f64) -> Result<(), RankError> {
        self.tolerance *= factor;
        self.solver.restart_from_solutions()
    }
}
