//! The public solver. A scene is split into its contact islands (docs/algorithms.md §12):
//! a small island is solved by Newton on its dense Delassus form ([`SmallIsland`]), any
//! other by its own [`CoupledSolver`] (its own rho, stopping test, factorization and warm
//! start); velocities no contact reaches are solved once, body by body ([`FreeMotion`]).
//! A problem that is one island is solved as it is, with no copy.

use crate::coupled::CoupledSolver;
use crate::free_motion::FreeMotion;
use crate::islands::{
    contact_rows, gather, partition_global, partition_local, positions, Part, Partition,
    ValueBuffers, EVERY_FIELD,
};
use crate::measure::{global_error_with, local_error_with, Floors, MeasureWork, Scales};
use crate::problem::{NewValues, Problem};
use crate::settings::{NewtonUse, Resolved, Settings};
use crate::small_island::{Site, SmallIsland, SmallWork};
use crate::tuning::{ISLAND_ROUNDS, ISLAND_TIGHTENING, NEWTON_FIRST_STEPS, ROUND_OFF_MARGIN};
use crate::types::{Error, Solution, Status};
use crate::types::{Stats, TracePoint};
use std::sync::Mutex;
use std::time::Instant;

/// Solves one frictional contact problem, and its successors with the same pattern.
pub struct Solver {
    settings: Settings,
    /// The settings the parts work to: the tolerance less [`ROUND_OFF_MARGIN`].
    inner: Settings,
    resolved: Resolved,
    layout: Layout,
    stats: Stats,
    island_stats: Vec<Stats>,
}

/// How the problem is held.
enum Layout {
    /// As one coupled problem (islands off, or one island).
    Whole(Box<CoupledSolver>),
    /// As islands.
    Split(Box<Split>),
}

/// A problem split into islands.
struct Split {
    /// The whole problem: new values land here first, and the assembled solution is
    /// measured on it.
    whole: Problem,
    /// The contact islands, then the contact-free part (global form) when there is one.
    parts: Vec<PartSolver>,
    /// Contact islands among `parts` (the first ones).
    n_islands: usize,
    /// Contacts no velocity moves (see [`Partition::bodiless`]).
    bodiless: Vec<usize>,
    measure: MeasureWork,
    /// The whole problem's scales known before solving: `||f||`, `||b||` (local: `||q||`).
    known_scales: Scales,
    /// The solution assembled and measured by the last solve, until an update or a warm
    /// start changes the parts.
    assembled: Option<Solution>,
    /// The part whose trace and residuals the solver reports (the one that needed the
    /// most iterations in the last solve; none without parts).
    slowest: Option<usize>,
    /// Where each velocity (global) or contact row (local) sits in its part.
    row_of: Vec<usize>,
    /// Work space of the small islands, one per thread that solves them.
    work: Vec<SmallWork>,
}

/// What every part's solve reads: the whole problem (a small island that falls back builds
/// its sub-problem from it), the positions of [`positions`], and the clock.
struct SolveContext<'a> {
    whole: &'a Problem,
    row_of: &'a [usize],
    settings: &'a Settings,
    t0: Instant,
    time_limit: f64,
}

/// One part and its solvers: a small island is solved directly by Newton on its Delassus
/// form ([`SmallIsland`]); its coupled solver (ADMM and Newton) is built when that fails,
/// and is the only one of the other parts.
struct PartSolver {
    part: Part,
    /// The contact-free part, when its blocks of M are small.
    free: Option<Box<FreeMotion>>,
    small: Option<SmallIsland>,
    /// Boxed: most parts of a scene of many islands never build one.
    coupled: Option<Box<CoupledSolver>>,
    /// The solution of the last solve is the small path's.
    small_solved: bool,
    floors: Floors,
    /// Boxed and built on the first update of a built coupled solver.
    values: Option<Box<ValueBuffers>>,
    /// Warm-start buffers.
    r: Vec<f64>,
    v: Vec<f64>,
    warm: bool,
    /// The part's share of the whole problem's velocities, contacts and joints (the
    /// square of the factor applied to the whole's scales in its measure floors).
    share: [f64; 3],
    /// Tolerance of the part in the current round, and the outcome of its last solve.
    tolerance: f64,
    outcome: Result<Status, Error>,
    /// Statistics and trace of the current solve, summed over its rounds.
    stats: Stats,
    trace: Vec<TracePoint>,
}

impl PartSolver {
    fn new(
        mut part: Part,
        whole: &Problem,
        row_of: &[usize],
        settings: &Settings,
        newton_polish: bool,
        work: &mut SmallWork,
    ) -> Result<Self, Error> {
        let free = match whole {
            Problem::Global(g) => FreeMotion::new(g, &part, row_of)?,
            Problem::Local(_) => None,
        };
        let small = match newton_polish && free.is_none() {
            true => {
                let at = Site {
                    whole,
                    part: &part,
                    row_of,
                };
                SmallIsland::new(at, settings.trace, work)?
            }
            false => None,
        };
        let coupled = match (&free, &small) {
            (Some(_), _) | (_, Some(_)) => None,
            (None, None) => Some(Box::new(CoupledSolver::new(
                part.sub_problem(whole, row_of)?,
                settings.clone(),
            )?)),
        };
        let n = part.velocities.len();
        let fraction = |k: usize, total: usize| k as f64 / total.max(1) as f64;
        let share = match whole {
            Problem::Global(g) => [
                fraction(part.velocities.len(), g.n()),
                fraction(part.contacts.len(), g.n_contacts()),
                fraction(part.joints.len(), g.n_joints()),
            ],
            Problem::Local(l) => {
                let c = fraction(part.contacts.len(), l.n_contacts());
                [c, c, 0.0]
            }
        };
        Ok(Self {
            share,
            stats: Stats::default(),
            trace: Vec::new(),
            values: None,
            r: vec![0.0; 3 * part.contacts.len()],
            v: vec![0.0; n],
            warm: false,
            free: free.map(Box::new),
            small,
            coupled,
            small_solved: false,
            floors: Floors::default(),
            part,
            tolerance: settings.tolerance,
            outcome: Ok(Status::MaxIterations),
        })
    }

    /// Floors of the part's measure: its share of the whole problem's scales.
    fn set_floors(&mut self, whole: Scales) {
        let [velocities, contacts, joints] = self.share.map(f64::sqrt);
        self.floors = Floors {
            equation: whole.equation * velocities,
            contact: whole.contact * contacts,
            joint: whole.joint * joints,
        };
        if let Some(f) = &mut self.free {
            f.set_measure_floors(self.floors);
        }
        if let Some(s) = &mut self.small {
            s.set_measure_floors(self.floors);
        }
        if let Some(c) = &mut self.coupled {
            c.set_measure_floors(self.floors);
        }
    }

    /// Starts the next solve from the part's share of a warm start (in `self.r`, `self.v`).
    fn warm_start(&mut self, with_v: bool) -> Result<(), Error> {
        self.warm = true;
        if let Some(s) = &mut self.small {
            s.warm_start(&self.r);
        }
        if let Some(c) = &mut self.coupled {
            c.warm_start(&self.r, with_v.then_some(self.v.as_slice()))?;
        }
        Ok(())
    }

    /// Solves with the part's tolerance and what is left of the time limit, and adds the
    /// solve to the part's statistics and trace: the small path first, the coupled solver
    /// (built now if need be, and starting as the warm start asked) when it fails.
    fn solve(&mut self, at: &SolveContext, work: &mut SmallWork) {
        self.outcome = self.solve_once(at, work);
        if let Ok(status) = self.outcome {
            // A part the time limit left no time for did not run.
            self.stats.status = status;
        }
    }

    fn solve_once(&mut self, at: &SolveContext, work: &mut SmallWork) -> Result<Status, Error> {
        let (t0, time_limit) = (at.t0, at.time_limit);
        let warm = std::mem::replace(&mut self.warm, false);
        let time_left = time_limit - t0.elapsed().as_secs_f64();
        if time_left <= 0.0 {
            return Ok(Status::TimeLimit);
        }
        if let Some(free) = &mut self.free {
            let status = free.solve()?;
            self.stats = Stats {
                setup_seconds: self.stats.setup_seconds,
                ..*free.stats()
            };
            return Ok(status);
        }
        // The iteration limit holds for the whole solve, refinement rounds and the Newton
        // steps of the small path included.
        let left = |stats: &Stats| at.settings.max_iterations.saturating_sub(stats.iterations);
        if let Some(small) = &mut self.small {
            let steps = left(&self.stats).min(NEWTON_FIRST_STEPS);
            if steps == 0 {
                return Ok(Status::MaxIterations);
            }
            let started = t0.elapsed().as_secs_f64();
            small.set_limits(self.tolerance, time_left, steps);
            let site = Site {
                whole: at.whole,
                part: &self.part,
                row_of: at.row_of,
            };
            let status = small.solve(site, work)?;
            let (stats, trace) = (*small.stats(), small.trace());
            add_solve(&mut self.stats, &mut self.trace, &stats, trace, started);
            self.small_solved = status == Status::Solved;
            if self.small_solved || status == Status::TimeLimit {
                return Ok(status);
            }
            if left(&self.stats) == 0 {
                return Ok(Status::MaxIterations);
            }
            self.stats.newton_fallbacks += 1;
        }
        if self.coupled.is_none() {
            let problem = self.part.sub_problem(at.whole, at.row_of)?;
            let mut coupled = CoupledSolver::new(problem, at.settings.clone())?;
            coupled.set_measure_floors(self.floors);
            if warm {
                coupled.warm_start(&self.r, None)?;
            }
            self.coupled = Some(Box::new(coupled));
        }
        let coupled = self.coupled.as_mut().expect("built above");
        let started = t0.elapsed().as_secs_f64();
        let time_left = time_limit - started;
        if time_left <= 0.0 {
            return Ok(Status::TimeLimit);
        }
        coupled.set_limits(self.tolerance, time_left, left(&self.stats));
        let status = coupled.solve()?;
        add_solve(
            &mut self.stats,
            &mut self.trace,
            coupled.stats(),
            coupled.trace(),
            started,
        );
        Ok(status)
    }

    /// The part's solution: that of the solver that solved last.
    fn solution(&self, whole: &Problem, row_of: &[usize]) -> Solution {
        if let Some(f) = &self.free {
            return f.solution();
        }
        let at = Site {
            whole,
            part: &self.part,
            row_of,
        };
        match (&self.small, &self.coupled) {
            (Some(s), _) if self.small_solved => s.solution(at),
            (_, Some(c)) => c.solution(),
            (Some(s), None) => s.solution(at),
            (None, None) => unreachable!("a part has one of its solvers"),
        }
    }

    /// Starts a new solve's statistics.
    fn reset(&mut self) {
        let setup = |s: &Stats| s.setup_seconds;
        self.stats = Stats {
            setup_seconds: self.free.as_ref().map_or(0.0, |f| setup(f.stats()))
                + self.small.as_ref().map_or(0.0, |s| setup(s.stats()))
                + self.coupled.as_ref().map_or(0.0, |c| setup(c.stats())),
            ..Stats::default()
        };
        self.trace.clear();
    }
}

/// Adds one solve's statistics and trace (started `started` seconds into the solve) to a
/// part's totals.
fn add_solve(
    total: &mut Stats,
    trace: &mut Vec<TracePoint>,
    s: &Stats,
    points: &[TracePoint],
    started: f64,
) {
    let offset = total.iterations;
    trace.extend(points.iter().map(|t| TracePoint {
        iteration: t.iteration + offset,
        seconds: t.seconds + started,
        ..*t
    }));
    *total = Stats {
        iterations: total.iterations + s.iterations,
        refactorizations: s.refactorizations,
        anderson_accepted: total.anderson_accepted + s.anderson_accepted,
        anderson_rejected: total.anderson_rejected + s.anderson_rejected,
        newton_iterations: total.newton_iterations + s.newton_iterations,
        newton_factorizations: total.newton_factorizations + s.newton_factorizations,
        newton_phases: total.newton_phases + s.newton_phases,
        newton_fallbacks: total.newton_fallbacks + s.newton_fallbacks,
        solve_seconds: total.solve_seconds + s.solve_seconds,
        setup_seconds: total.setup_seconds,
        ..*s
    };
}

/// What the parts work to: the user's settings with the tolerance less
/// [`ROUND_OFF_MARGIN`] (`Solver::settings` hands back the user's).
fn working_settings(user: &Settings) -> Settings {
    Settings {
        tolerance: user.tolerance * (1.0 - ROUND_OFF_MARGIN),
        ..user.clone()
    }
}

impl Solver {
    /// Validates the settings, finds the contact islands (unless switched off), picks each
    /// island's first rho and factorizes (symbolic analysis and first numeric
    /// factorization).
    pub fn new(problem: Problem, settings: Settings) -> Result<Self, Error> {
        let t0 = Instant::now();
        settings.validate()?;
        problem.validate()?;
        let user = settings;
        let settings = working_settings(&user);
        let partition = match (&problem, settings.islands) {
            (_, false) => None,
            (Problem::Global(g), true) => Some(partition_global(g)),
            (Problem::Local(l), true) => Some(partition_local(l)),
        };
        let (layout, n_islands) = match partition {
            Some(p) if !p.is_whole() => {
                let split = Split::new(problem, p, &settings)?;
                let n = split.n_islands;
                (Layout::Split(Box::new(split)), n)
            }
            _ => {
                let islands = usize::from(problem.n_contacts() > 0);
                let solver = CoupledSolver::new(problem, settings.clone())?;
                (Layout::Whole(Box::new(solver)), islands)
            }
        };
        let mut solver = Self {
            resolved: user.resolved(),
            settings: user,
            inner: settings,
            layout,
            stats: Stats::default(),
            island_stats: Vec::new(),
        };
        solver.stats.islands = n_islands;
        solver.collect_stats(Status::Unsolved, f64::INFINITY, 0.0);
        solver.stats.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(solver)
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Changes the settings between solves: the tolerance, the iteration and time limits,
    /// the trace and the threads may change; any other change is refused with
    /// [`Error::InvalidSetting`] naming it (it needs a new solver), and nothing changes.
    pub fn update_settings(&mut self, settings: Settings) -> Result<(), Error> {
        self.settings.check_update(&settings)?;
        self.inner = working_settings(&settings);
        self.settings = settings;
        match &mut self.layout {
            Layout::Whole(s) => s.update_settings(&self.inner),
            Layout::Split(split) => {
                for p in &mut split.parts {
                    if let Some(s) = &mut p.small {
                        s.set_trace(self.inner.trace);
                    }
                    if let Some(c) = &mut p.coupled {
                        c.update_settings(&self.inner);
                    }
                }
            }
        }
        Ok(())
    }

    /// The variant, initial rho rule and Anderson memory actually used.
    pub fn resolved(&self) -> &Resolved {
        &self.resolved
    }

    /// Replaces the problem by one of the same form, sizes and sparsity patterns (the next
    /// time step of a simulation): numeric refactorization only, through the same path as
    /// [`Solver::update_values`].
    pub fn update(&mut self, problem: Problem) -> Result<(), Error> {
        problem.validate()?;
        match &mut self.layout {
            Layout::Whole(s) => s.update(problem),
            Layout::Split(split) => split.update(problem),
        }
    }

    /// Takes new values for the problem on the same sizes and sparsity patterns (the next
    /// time step of a scene), without building a problem: they are scattered into the kept
    /// system matrices through maps built once, then one numeric refactorization per
    /// island; no sorting, no allocation (except when a symmetric matrix stops being
    /// symmetric, which rebuilds that system for LU). Every value is checked before any is
    /// taken; M is refactorized on its own to check it is positive definite, and after a
    /// failed factorization the solver keeps failing until an update succeeds. The next
    /// solve starts cold unless [`Solver::warm_start`] is called after this.
    pub fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        match &mut self.layout {
            Layout::Whole(s) => s.update_values(values),
            Layout::Split(split) => split.update_values(values),
        }
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        match &mut self.layout {
            Layout::Whole(s) => s.warm_start(r, v),
            Layout::Split(split) => split.warm_start(r, v),
        }
    }

    /// Runs the solve: on each island, ADMM finished by the semismooth Newton phase when
    /// the settings ask for it (docs/algorithms.md §9). Without a preceding
    /// [`Solver::warm_start`], starts from zero. With islands, the status is `Solved` only
    /// when the assembled solution meets the tolerance by the whole problem's measure.
    pub fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        let (status, error) = match &mut self.layout {
            Layout::Whole(s) => {
                let status = s.solve()?;
                (status, s.stats().error)
            }
            Layout::Split(split) => split.solve(&self.inner, t0)?,
        };
        self.collect_stats(status, error, t0.elapsed().as_secs_f64());
        Ok(status)
    }

    /// Gathers the statistics of the last solve from the islands.
    fn collect_stats(&mut self, status: Status, error: f64, seconds: f64) {
        let (islands, setup) = (self.stats.islands, self.stats.setup_seconds);
        match &self.layout {
            Layout::Whole(s) => {
                self.stats = *s.stats();
                self.island_stats.clear();
                if islands > 0 {
                    self.island_stats.push(Stats {
                        islands,
                        ..self.stats
                    });
                }
            }
            Layout::Split(split) => {
                self.island_stats.clear();
                self.island_stats
                    .extend(split.parts[..split.n_islands].iter().map(|p| p.stats));
                let parts = split.parts.iter().map(|p| &p.stats);
                let none = Stats::default();
                let slowest = split.slowest.map_or(&none, |k| &split.parts[k].stats);
                let mut stats = Stats {
                    iterations: slowest.iterations,
                    primal_residual: slowest.primal_residual,
                    dual_residual: slowest.dual_residual,
                    rho: slowest.rho,
                    ..Stats::default()
                };
                for p in parts {
                    stats.refactorizations += p.refactorizations;
                    stats.rows += p.rows;
                    stats.anderson_accepted += p.anderson_accepted;
                    stats.anderson_rejected += p.anderson_rejected;
                    stats.newton_iterations += p.newton_iterations;
                    stats.newton_factorizations += p.newton_factorizations;
                    stats.newton_phases += p.newton_phases;
                    stats.newton_fallbacks += p.newton_fallbacks;
                }
                stats.failed_island = (status != Status::Solved)
                    .then(|| {
                        self.island_stats
                            .iter()
                            .position(|s| s.status != Status::Solved)
                    })
                    .flatten();
                self.stats = stats;
            }
        }
        self.stats.status = status;
        self.stats.error = error;
        self.stats.solve_seconds = seconds;
        self.stats.islands = islands;
        self.stats.setup_seconds = setup;
    }

    /// The current solution (the iterate the last solve handed back), assembled from the
    /// islands.
    pub fn solution(&self) -> Solution {
        match &self.layout {
            Layout::Whole(s) => s.solution(),
            Layout::Split(split) => split.solution(),
        }
    }

    /// Length of `v` (0 for a local problem).
    pub fn n_velocities(&self) -> usize {
        match &self.layout {
            Layout::Whole(s) => s.n_velocities(),
            Layout::Split(split) => split.whole.n_velocities(),
        }
    }

    /// Statistics of the last solve.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Statistics of each contact island in the last solve, ordered by the islands' first
    /// contacts (one entry when the problem was solved whole; each island's `error` is by
    /// its own measure).
    pub fn island_stats(&self) -> &[Stats] {
        &self.island_stats
    }

    /// Per-iteration trace of the last solve (empty unless `Settings::trace`); with several
    /// islands, the trace of the island that needed the most iterations.
    pub fn trace(&self) -> &[TracePoint] {
        match &self.layout {
            Layout::Whole(s) => s.trace(),
            Layout::Split(split) => split.slowest.map_or(&[][..], |k| &split.parts[k].trace),
        }
    }
}

impl Split {
    fn new(whole: Problem, partition: Partition, settings: &Settings) -> Result<Self, Error> {
        let Partition {
            islands,
            free,
            bodiless,
        } = partition;
        let n_islands = islands.len();
        let all: Vec<Part> = islands.into_iter().chain(free).collect();
        let row_of = match &whole {
            Problem::Global(g) => positions(&all.iter().collect::<Vec<_>>(), g.n(), true),
            Problem::Local(l) => positions(&all.iter().collect::<Vec<_>>(), l.q.len(), false),
        };
        // Small islands go to Newton directly when the settings polish with Newton.
        let newton_polish = settings.resolved().newton == NewtonUse::Polish;
        let mut work = vec![SmallWork::default()];
        let parts = all
            .into_iter()
            .map(|part| {
                PartSolver::new(part, &whole, &row_of, settings, newton_polish, &mut work[0])
            })
            .collect::<Result<Vec<_>, _>>()?;
        let measure = match &whole {
            Problem::Global(g) => MeasureWork::global(g),
            Problem::Local(l) => MeasureWork::local(l),
        };
        let known_scales = match &whole {
            Problem::Global(g) => Scales {
                equation: crate::csc::norm2(&g.f),
                contact: 0.0,
                joint: g.joints.as_ref().map_or(0.0, |j| crate::csc::norm2(&j.b)),
            },
            Problem::Local(l) => Scales {
                equation: crate::csc::norm2(&l.q),
                ..Scales::default()
            },
        };
        Ok(Self {
            known_scales,
            whole,
            parts,
            n_islands,
            bodiless,
            measure,
            slowest: None,
            assembled: None,
            row_of,
            work,
        })
    }

    fn update(&mut self, problem: Problem) -> Result<(), Error> {
        self.whole.check_successor(&problem)?;
        self.whole = problem;
        self.assembled = None;
        self.distribute(&EVERY_FIELD)
    }

    fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        self.whole.set_values(values)?;
        self.assembled = None;
        self.distribute(values)
    }

    /// Hands each part its share of the whole problem's values for the fields `given`
    /// names. Every part is updated even when one fails, and the first error is returned.
    fn distribute(&mut self, given: &NewValues) -> Result<(), Error> {
        let mut first_error = Ok(());
        for p in &mut self.parts {
            let PartSolver {
                part,
                values,
                free,
                small,
                coupled,
                warm,
                ..
            } = p;
            *warm = false;
            if let (Some(f), Problem::Global(g)) = (free.as_mut(), &self.whole) {
                let done = f.take_values(g, part, &self.row_of);
                if first_error.is_ok() {
                    first_error = done;
                }
                continue;
            }
            // A small island reads its values from the whole problem; its coupled solver,
            // when it has been built, takes its share as the other parts do.
            let at = Site {
                whole: &self.whole,
                part,
                row_of: &self.row_of,
            };
            let small = small
                .as_mut()
                .map_or(Ok(()), |s| s.take_values(at, &mut self.work[0]));
            let coupled = coupled.as_mut().map_or(Ok(()), |c| {
                let values = values.get_or_insert_with(Default::default);
                let share = match &self.whole {
                    Problem::Global(g) => values.global(part, g, given),
                    Problem::Local(l) => values.local(part, l, given),
                };
                c.update_values(&share)
            });
            let done = small.and(coupled);
            if first_error.is_ok() {
                first_error = done;
            }
        }
        first_error
    }

    fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        crate::problem::check_len("r", r, 3 * self.whole.n_contacts())?;
        if let Some(v) = v {
            crate::problem::check_len("v", v, self.whole.n_velocities())?;
        }
        self.assembled = None;
        for p in &mut self.parts {
            gather(r, contact_rows(&p.part.contacts), &mut p.r);
            if let Some(v) = v {
                gather(v, p.part.velocities.iter().copied(), &mut p.v);
            }
            p.warm_start(v.is_some())?;
        }
        Ok(())
    }

    /// Solves the parts, assembles, measures the whole problem. Each island is measured
    /// with floors at its share of the whole problem's scales (docs/algorithms.md §12):
    /// first those known before solving (`||f||`, `||b||`; local: `||q||`), then, when the
    /// assembled solution misses the tolerance, those of that solution, and the islands
    /// are solved again, warm, to a tolerance tightened in proportion.
    fn solve(&mut self, settings: &Settings, t0: Instant) -> Result<(Status, f64), Error> {
        let tol = settings.tolerance;
        let mut pending: Vec<bool> = vec![true; self.parts.len()];
        for p in &mut self.parts {
            p.tolerance = tol;
            p.reset();
            p.set_floors(self.known_scales);
        }
        let mut error = f64::INFINITY;
        // With a bodiless contact that approaches, no round can meet the tolerance.
        let rounds = if self.bodiless_blocked() {
            1
        } else {
            ISLAND_ROUNDS
        };
        for round in 0..rounds {
            self.solve_parts(&pending, settings, t0);
            if let Some(Err(e)) = self.parts.iter().map(|p| &p.outcome).find(|o| o.is_err()) {
                return Err(e.clone());
            }
            error = self.whole_error();
            let all_solved = self
                .parts
                .iter()
                .all(|p| matches!(p.outcome, Ok(Status::Solved)));
            if error <= tol || !all_solved || round + 1 == rounds {
                break;
            }
            let scales = self.measure.scales;
            let factor = (tol / error).min(ISLAND_TIGHTENING);
            for (p, again) in self.parts.iter_mut().zip(&mut pending) {
                // The contact-free part is solved exactly already.
                *again = !p.part.contacts.is_empty();
                if *again {
                    p.tolerance *= factor;
                    p.set_floors(scales);
                    let s = p.solution(&self.whole, &self.row_of);
                    p.r.copy_from_slice(&s.r);
                    p.v.copy_from_slice(&s.v);
                    p.warm_start(!s.v.is_empty())?;
                }
            }
        }
        self.slowest = (0..self.parts.len()).max_by_key(|&k| self.parts[k].stats.iterations);
        let infeasible = self.bodiless_blocked()
            || self
                .parts
                .iter()
                .any(|p| p.stats.status == Status::Infeasible);
        let status = if infeasible {
            Status::Infeasible
        } else if error <= tol {
            Status::Solved
        } else if let Some(p) = self.parts.iter().find(|p| p.stats.status != Status::Solved) {
            p.stats.status
        } else {
            Status::MaxIterations
        };
        Ok((status, error))
    }

    /// Solves the pending parts, on `threads` scoped threads when several are pending. The
    /// parts are independent, so the results do not depend on the threads.
    fn solve_parts(&mut self, pending: &[bool], settings: &Settings, t0: Instant) {
        let Split {
            parts,
            whole,
            row_of,
            work,
            ..
        } = self;
        let at = SolveContext {
            whole,
            row_of,
            settings,
            t0,
            time_limit: settings.time_limit,
        };
        let mut todo: Vec<&mut PartSolver> = parts
            .iter_mut()
            .zip(pending)
            .filter_map(|(p, &again)| again.then_some(p))
            .collect();
        let threads = settings.threads.min(todo.len()).max(1);
        if work.len() < threads {
            work.resize_with(threads, SmallWork::default);
        }
        if threads == 1 {
            let work = &mut work[0];
            todo.into_iter().for_each(|p| p.solve(&at, work));
            return;
        }
        // Largest parts first, so that the last one taken is a small one.
        todo.sort_by_key(|p| std::cmp::Reverse(p.part.contacts.len() + p.part.velocities.len()));
        let queue = Mutex::new(todo.into_iter());
        std::thread::scope(|scope| {
            for work in work.iter_mut().take(threads) {
                let (queue, at) = (&queue, &at);
                scope.spawn(move || loop {
                    let next = queue.lock().map(|mut q| q.next());
                    match next {
                        Ok(Some(p)) => p.solve(at, work),
                        _ => break,
                    }
                });
            }
        });
    }

    /// True when a bodiless contact approaches (`w_N < 0`): the criterion of the forms'
    /// `blocked_contact`, its normal column of H being empty. One that does not is solved
    /// exactly by `r = 0`.
    fn bodiless_blocked(&self) -> bool {
        match &self.whole {
            Problem::Global(g) => self.bodiless.iter().any(|&c| g.w[3 * c] < 0.0),
            Problem::Local(_) => false,
        }
    }

    /// The solution of the whole problem from the parts' (bodiless contacts: `r = 0`,
    /// `u = w`).
    fn assemble(&self) -> Solution {
        let (n, m) = (self.whole.n_velocities(), 3 * self.whole.n_contacts());
        let np = match &self.whole {
            Problem::Global(g) => g.n_joints(),
            Problem::Local(_) => 0,
        };
        let mut out = Solution {
            r: vec![0.0; m],
            u: vec![0.0; m],
            v: vec![0.0; n],
            lambda: vec![0.0; np],
        };
        if let Problem::Global(g) = &self.whole {
            for &c in &self.bodiless {
                out.u[3 * c..3 * c + 3].copy_from_slice(&g.w[3 * c..3 * c + 3]);
            }
        }
        for p in &self.parts {
            if let (Some(small), true) = (&p.small, p.small_solved) {
                let at = Site {
                    whole: &self.whole,
                    part: &p.part,
                    row_of: &self.row_of,
                };
                small.write_solution(at, &mut out);
                continue;
            }
            let s = p.solution(&self.whole, &self.row_of);
            for (k, i) in contact_rows(&p.part.contacts).enumerate() {
                out.r[i] = s.r[k];
                out.u[i] = s.u[k];
            }
            for (k, &i) in p.part.velocities.iter().enumerate() {
                out.v[i] = s.v[k];
            }
            for (k, &i) in p.part.joints.iter().enumerate() {
                out.lambda[i] = s.lambda[k];
            }
        }
        out
    }

    /// The whole problem's error measure at the assembled solution, which is kept for
    /// [`Solver::solution`].
    fn whole_error(&mut self) -> f64 {
        let s = self.assemble();
        let error = match &self.whole {
            Problem::Global(g) => global_error_with(g, &s.r, &s.v, &s.lambda, &mut self.measure),
            Problem::Local(l) => local_error_with(l, &s.r, &mut self.measure),
        };
        self.assembled = Some(s);
        error
    }

    /// The assembled solution: the last solve's, or assembled now.
    fn solution(&self) -> Solution {
        match &self.assembled {
            Some(s) => s.clone(),
            None => self.assemble(),
        }
    }
}
