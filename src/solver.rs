//! The public solver, a facade over the scene's structure: a problem that is one island
//! (or whose islands are off) is solved as it is, by one [`CoupledSolver`], with no copy;
//! any other is split into its islands ([`Scene`]), each solved by the strategy chosen for
//! it when the solver is built (docs/algorithms.md §12). A solver built with a time limit
//! starts each solve with Gauss-Seidel sweeps when the problem suits them, and builds its
//! islands only when the sweeps hand over (docs/algorithms.md §17).

use crate::budgeted::BudgetedStart;
use crate::coupled::{CoupledSolver, NewtonFirst};
use crate::gauss_seidel::{SweepOutcome, Yield};
use crate::problem::{NewValues, Problem};
use crate::scene::islands::{partition_global, partition_local};
use crate::scene::offered::{Offer, Offered};
use crate::scene::{Scene, ScenePlan};
use crate::settings::{LinearSolver, Resolved, Settings, VariantChoice};
use crate::tuning::{
    BUDGET_JOINTED_AFTER, FIRST_STEP_HANDOVER_SWEEPS, GAUSS_SEIDEL_HANDOVER_SWEEPS,
    ROUND_OFF_MARGIN,
};
use crate::types::{Error, Solution, Stats, Status, TracePoint};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

/// Solves one frictional contact problem, and its successors with the same pattern.
pub struct Solver {
    settings: Settings,
    /// The settings the parts work to: the tolerance less [`ROUND_OFF_MARGIN`].
    inner: Settings,
    resolved: Resolved,
    /// The islands and their solvers; `None` while a budgeted start has not needed them.
    layout: Option<Layout>,
    /// A budgeted solver's islands from before its last rebuild: the islands it builds
    /// next may take their solvers (`scene::offered`).
    spare: Option<Layout>,
    /// The Gauss-Seidel phase of a solver built with a time limit, when the problem suits it.
    budgeted: Option<Box<BudgetedStart>>,
    /// The flag of [`Solver::set_interrupt`], handed to the islands when they are built.
    interrupt: Option<Arc<AtomicBool>>,
    /// Solves done: a budgeted solver kept across steps may go straight to its islands.
    solves: usize,
    /// No solve yet since the solver was built, with a time limit or without (a rebuild
    /// does not count as built).
    first_solve: bool,
    /// A budgeted solver's islands solved the last solve: the next solve on the same
    /// problem starts with them, from its warm start.
    islands_first: bool,
    stats: Stats,
    island_stats: Vec<Stats>,
    /// The solution the last solve handed back (zeros before the first solve), kept so
    /// that reading it copies nothing.
    solution: Solution,
}

/// A layout planned, before the offered solvers it takes are handed over.
enum Planned {
    Split(ScenePlan),
    /// An offered solver's index, or a new solver; and the number of islands.
    Whole(Result<usize, Box<CoupledSolver>>, usize),
}

/// How the problem is held.
enum Layout {
    /// As one coupled problem (islands off, or one island).
    Whole(Box<CoupledSolver>),
    /// As islands.
    Split(Box<Scene>),
}

impl Layout {
    /// Finds the contact islands (unless switched off), picks each island's first rho and
    /// factorizes; also returns the number of islands. An island whose sub-problem fits a
    /// coupled solver of `replaced` (the layout of the problem before, in a rebuild) takes
    /// that solver with its values instead (`scene::offered`). `replaced` is used up, or
    /// left as it was when the problem is refused.
    fn new(
        problem: Problem,
        settings: &Settings,
        replaced: &mut Option<Layout>,
    ) -> Result<(Self, usize), Error> {
        let partition = match (&problem, settings.islands) {
            (_, false) => None,
            (Problem::Global(g), true) => Some(partition_global(g)),
            (Problem::Local(l), true) => Some(partition_local(l)),
        };
        let split = partition.filter(|p| !p.is_whole());
        let mut offered = match replaced.as_mut() {
            Some(layout) => Offered::new(layout.coupled_to_offer()),
            None => Offered::none(),
        };
        let planned = match split {
            Some(p) => Scene::plan(problem, p, settings, &mut offered).map(Planned::Split),
            None => {
                let islands = usize::from(problem.n_contacts() > 0);
                Self::whole(problem, settings, &mut offered).map(|s| Planned::Whole(s, islands))
            }
        };
        let planned = match planned {
            Ok(planned) => planned,
            Err(e) => {
                offered.give_back();
                return Err(e);
            }
        };
        let reused = offered.took_any();
        drop(offered);
        // The replaced layout goes: its solvers that were taken into the new one.
        let mut solvers = match (reused, replaced.take()) {
            (true, Some(layout)) => layout.into_offered(),
            _ => Vec::new(),
        };
        Ok(match planned {
            Planned::Split(plan) => {
                let split = Scene::new(plan, settings, &mut solvers);
                let n = split.n_islands;
                (Layout::Split(Box::new(split)), n)
            }
            Planned::Whole(Ok(k), islands) => {
                let mut solver = solvers[k].take().expect("taken once");
                solver.update_settings(settings);
                solver.set_linear_threads(settings.threads);
                (Layout::Whole(solver), islands)
            }
            Planned::Whole(Err(solver), islands) => (Layout::Whole(solver), islands),
        })
    }

    /// The solver of a problem solved whole: an offered one it fits (its index), or a new
    /// one.
    fn whole(
        problem: Problem,
        settings: &Settings,
        offered: &mut Offered,
    ) -> Result<Result<usize, Box<CoupledSolver>>, Error> {
        let problem = match offered.take(problem)? {
            Offer::Taken(k) => return Ok(Ok(k)),
            Offer::NoneFits(problem) => problem,
        };
        let mut solver = CoupledSolver::new(problem, settings.clone(), NewtonFirst::IfSmall)?;
        solver.set_linear_threads(settings.threads);
        Ok(Err(Box::new(solver)))
    }

    /// Its coupled solvers, for a rebuild to offer (in the order of
    /// [`Layout::into_offered`]).
    fn coupled_to_offer(&mut self) -> Vec<&mut CoupledSolver> {
        match self {
            Layout::Whole(s) => vec![s],
            Layout::Split(split) => split.coupled_to_offer(),
        }
    }

    /// [`Layout::coupled_to_offer`], taken.
    fn into_offered(self) -> Vec<Option<Box<CoupledSolver>>> {
        match self {
            Layout::Whole(s) => vec![Some(s)],
            Layout::Split(split) => split.into_offered(),
        }
    }

    fn set_interrupt(&mut self, flag: &Arc<AtomicBool>) {
        match self {
            Layout::Whole(s) => s.set_interrupt(flag.clone()),
            Layout::Split(split) => split.set_interrupt(flag),
        }
    }

    fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        match self {
            Layout::Whole(s) => s.warm_start(r, v),
            Layout::Split(split) => split.warm_start(r, v),
        }
    }

    fn update_settings(&mut self, settings: &Settings) {
        match self {
            Layout::Whole(s) => {
                s.update_settings(settings);
                s.set_linear_threads(settings.threads);
            }
            Layout::Split(split) => split.update_settings(settings),
        }
    }

    /// Solves; the status and the whole problem's error, the solution left in `out`.
    fn solve(
        &mut self,
        settings: &Settings,
        t0: Instant,
        out: &mut Solution,
    ) -> Result<(Status, f64), Error> {
        match self {
            Layout::Whole(s) => {
                let status = s.solve()?;
                s.write_solution(out);
                Ok((status, s.stats().error))
            }
            Layout::Split(split) => split.solve(settings, t0, out),
        }
    }
}

/// What the parts work to: the user's settings with the tolerance less
/// [`ROUND_OFF_MARGIN`] (`Solver::settings` hands back the user's).
fn working_settings(user: &Settings) -> Settings {
    Settings {
        tolerance: user.tolerance * (1.0 - ROUND_OFF_MARGIN),
        ..user.clone()
    }
}

/// Gauss-Seidel sweeps before a problem solved whole on the matrix-free backend `auto`
/// picked, with the variant `auto` and no time limit (a backend or variant named runs as
/// named): there an ADMM iteration costs tens of products with `M` and
/// `H`, ten sweeps' time or more, and at an engine's tolerances the sweeps often finish
/// first (docs/algorithms.md §14, the sweeps §17). They start from the layout's copy of
/// the problem; the layout is kept for their handover.
fn sweeps_before_matrix_free(
    layout: &Layout,
    settings: &Settings,
) -> Result<Option<Box<BudgetedStart>>, Error> {
    let Layout::Whole(coupled) = layout else {
        return Ok(None);
    };
    let picked =
        settings.variant == VariantChoice::Auto && settings.linear_solver == LinearSolver::Auto;
    if !picked || !coupled.matrix_free() {
        return Ok(None);
    }
    let problem = coupled.problem_owned();
    match BudgetedStart::sweeps_of(&problem) {
        Some(sweeps) => {
            let start = BudgetedStart::new(problem, sweeps, Yield::CoupledCost)?;
            Ok(Some(Box::new(start)))
        }
        None => Ok(None),
    }
}

impl Solver {
    /// Validates the settings, finds the contact islands (unless switched off), picks each
    /// island's first rho and factorizes (symbolic analysis and first numeric
    /// factorization).
    pub fn new(problem: Problem, settings: Settings) -> Result<Self, Error> {
        Self::replacing(problem, settings, &mut None)
    }

    /// [`Solver::new`], whose islands may take the coupled solvers of `replaced` (see
    /// [`Layout::new`]).
    fn replacing(
        problem: Problem,
        settings: Settings,
        replaced: &mut Option<Layout>,
    ) -> Result<Self, Error> {
        let t0 = Instant::now();
        settings.validate()?;
        problem.validate()?;
        let user = settings;
        let settings = working_settings(&user);
        let mut solution = Solution::default();
        solution.zeroed(
            3 * problem.n_contacts(),
            problem.n_velocities(),
            problem.n_joints(),
        );
        let (layout, budgeted, n_islands) = match BudgetedStart::sweeps_for(&problem, &settings) {
            Some(sweeps) => {
                let islands = usize::from(problem.n_contacts() > 0);
                let start = BudgetedStart::new(problem, sweeps, Yield::Patience)?;
                (None, Some(Box::new(start)), islands)
            }
            None => {
                let (layout, n) = Layout::new(problem, &settings, replaced)?;
                let sweeps = sweeps_before_matrix_free(&layout, &settings)?;
                (Some(layout), sweeps, n)
            }
        };
        let mut solver = Self {
            resolved: user.resolved(),
            settings: user,
            inner: settings,
            layout,
            spare: None,
            budgeted,
            interrupt: None,
            solves: 0,
            first_solve: true,
            islands_first: false,
            stats: Stats::default(),
            island_stats: Vec::new(),
            solution,
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
        if let Some(layout) = &mut self.layout {
            layout.update_settings(&self.inner);
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
        match (&mut self.layout, self.budgeted.is_some()) {
            (Some(Layout::Whole(s)), true) => s.update(problem.clone())?,
            (Some(Layout::Split(split)), true) => split.update(problem.clone())?,
            (Some(Layout::Whole(s)), false) => return s.update(problem),
            (Some(Layout::Split(split)), false) => return split.update(problem),
            (None, _) => {}
        }
        let fits = self.budgeted.as_mut().expect("budgeted").update(problem)?;
        self.keep_budgeted_if(fits)
    }

    /// Replaces the problem by one of any sizes and patterns (the next time step of a scene
    /// whose contacts changed), keeping the settings and the interrupt: the solver becomes
    /// what [`Solver::new`] builds for `problem` with its settings, except that an island
    /// whose sub-problem has the sizes and sparsity patterns of one of the replaced
    /// solver's islands (a resting stack beside the contacts that changed) takes that
    /// island's solver with its new values: numeric refactorization only, as
    /// [`Solver::update`] does, where a new one would analyse and factorize. A budgeted solver
    /// (`auto` with a time limit, started by Gauss-Seidel sweeps) builds the new problem's
    /// sweeps in the memory of those it replaced the time before, so that a solver rebuilt
    /// at every step stops taking (and faulting in) fresh memory for its large arrays once
    /// their sizes have been seen. A refused problem changes nothing. The next solve starts
    /// cold unless [`Solver::warm_start`] is called after this.
    pub fn rebuild(&mut self, problem: &Problem) -> Result<(), Error> {
        let t0 = Instant::now();
        let reused = match (&mut self.budgeted, problem) {
            (Some(b), Problem::Global(g)) if BudgetedStart::asked_by(&self.inner) => {
                problem.validate()?;
                b.rebuild(g)?
            }
            _ => false,
        };
        if !reused {
            // Islands whose sub-problems did not change keep their solvers.
            let mut replaced = self.layout.take().or_else(|| self.spare.take());
            let built = Self::replacing(problem.clone(), self.settings.clone(), &mut replaced);
            let mut fresh = match built {
                Ok(fresh) => fresh,
                Err(e) => {
                    self.layout = replaced;
                    return Err(e);
                }
            };
            if let Some(flag) = &self.interrupt {
                fresh.set_interrupt(flag.clone());
            }
            fresh.first_solve = self.first_solve;
            *self = fresh;
            return Ok(());
        }
        if let Some(layout) = self.layout.take() {
            self.spare = Some(layout);
        }
        self.solves = 0;
        self.islands_first = false;
        let (nc, n, np) = (
            problem.n_contacts(),
            problem.n_velocities(),
            problem.n_joints(),
        );
        self.solution.zeroed(3 * nc, n, np);
        self.island_stats.clear();
        self.stats = Stats {
            islands: usize::from(nc > 0),
            setup_seconds: t0.elapsed().as_secs_f64(),
            ..Stats::default()
        };
        Ok(())
    }

    /// Drops the Gauss-Seidel start when the problem no longer suits it (M lost its
    /// symmetry), building the islands from its problem if they are not yet.
    fn keep_budgeted_if(&mut self, fits: bool) -> Result<(), Error> {
        if fits {
            return Ok(());
        }
        if self.layout.is_none() {
            let problem = self.budgeted.as_ref().expect("budgeted").problem();
            self.layout = Some(self.build(problem)?.0);
        }
        self.budgeted = None;
        Ok(())
    }

    /// Builds the islands of `problem` (a budgeted start's, when the sweeps need them),
    /// with the interrupt if one was set; they may take the spare islands' solvers.
    fn build(&mut self, problem: Problem) -> Result<(Layout, usize), Error> {
        let (mut layout, islands) = Layout::new(problem, &self.inner, &mut self.spare)?;
        if let Some(flag) = &self.interrupt {
            layout.set_interrupt(flag);
        }
        Ok((layout, islands))
    }

    /// Takes new values for the problem on the same sizes and sparsity patterns (the next
    /// time step of a scene), without building a problem: they are scattered into the kept
    /// system matrices through maps built once, then one numeric refactorization per
    /// island; no sorting, no allocation (except when a symmetric matrix stops being
    /// symmetric, which rebuilds that system for LU). Every value is checked before any is
    /// taken; M is refactorized on its own to check it is positive definite. A refused
    /// update changes nothing, whatever it was refused for: values refused after they
    /// were taken (a factorization that fails) are replaced by the ones kept from before,
    /// and the solver goes on solving those. After a successful update the next solve
    /// starts cold unless [`Solver::warm_start`] is called after this.
    pub fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        if let Some(layout) = &mut self.layout {
            match layout {
                Layout::Whole(s) => s.update_values(values)?,
                Layout::Split(split) => split.update_values(values)?,
            }
        }
        match &mut self.budgeted {
            Some(b) => {
                let fits = b.update_values(values)?;
                self.keep_budgeted_if(fits)
            }
            None => Ok(()),
        }
    }

    /// Starts the next solve from impulses `r` (and velocities `v`, global form).
    pub fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        if let Some(b) = &mut self.budgeted {
            b.warm_start(r, v)?;
        }
        match &mut self.layout {
            Some(layout) => layout.warm_start(r, v),
            None => Ok(()),
        }
    }

    /// Runs the solve: on each island, ADMM finished by the semismooth Newton phase when
    /// the settings ask for it (docs/algorithms.md §9). Without a preceding
    /// [`Solver::warm_start`], starts from zero. With islands, the status is `Solved` only
    /// when the assembled solution meets the tolerance by the whole problem's measure.
    pub fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        self.solves += 1;
        let first_solve = std::mem::replace(&mut self.first_solve, false);
        let Some(budgeted) = &mut self.budgeted else {
            let layout = self.layout.as_mut().expect("built unless budgeted");
            let (status, error) = layout.solve(&self.inner, t0, &mut self.solution)?;
            self.collect_stats(status, error, t0.elapsed().as_secs_f64());
            return Ok(status);
        };
        let limit = std::time::Duration::try_from_secs_f64(self.inner.time_limit).ok();
        let deadline = limit.and_then(|l| t0.checked_add(l));
        // Sweeps carry a correction along a chain of joints one link a sweep; the islands'
        // factorized system solves the joint rows exactly, once a kept solver has paid for
        // building it (docs/algorithms.md §17). The pattern, and so the choice, stays with
        // the solver: its sweeps go, and updates no longer refresh them. They are built
        // after the sweeps have answered this solve: built first, under an engine's budget
        // they left no time to solve in, and handed back the cold start.
        let pass = self.solves > BUDGET_JOINTED_AFTER && budgeted.jointed();
        let status = if self.islands_first && self.layout.is_some() {
            // The islands solved the last solve: a scene at rest, or one whose budget pays
            // for them, where ADMM and Newton from the warm start finish in a few
            // iterations and the sweeps might not reach the tolerance at all (a 5-box
            // tower of masses 1 and 1 000 under 10 ms at 1e-8 drifted 0.4 mm).
            budgeted.skip_run();
            self.islands_solve(f64::INFINITY, t0)?
        } else {
            self.sweeps_solve(deadline, first_solve, t0)?
        };
        if pass {
            let built = Instant::now();
            self.keep_budgeted_if(false)?;
            self.stats.setup_seconds += built.elapsed().as_secs_f64();
        }
        Ok(status)
    }

    /// Sweeps from the warm start within `deadline`, handing over to the islands when they
    /// stall with time left.
    fn sweeps_solve(
        &mut self,
        deadline: Option<Instant>,
        first_solve: bool,
        t0: Instant,
    ) -> Result<Status, Error> {
        let budgeted = self.budgeted.as_mut().expect("budgeted");
        let interrupt = self.interrupt.as_deref();
        // An engine's first step (a new solver's first solve, warm started as an engine's
        // loop does): the scene starts at rest more often than not, and every later step
        // starts from this one's answer (tuning::FIRST_STEP_HANDOVER_SWEEPS).
        let first_step = first_solve && budgeted.warm_given();
        let handover_sweeps = match first_step {
            true => FIRST_STEP_HANDOVER_SWEEPS,
            false => GAUSS_SEIDEL_HANDOVER_SWEEPS,
        };
        let swept = budgeted.run(
            self.inner.tolerance,
            deadline,
            self.inner.max_iterations,
            interrupt,
            handover_sweeps,
            self.settings.newton_polish != Some(false),
        );
        budgeted.write_solution(&mut self.solution);
        match swept.status {
            Some(status) => {
                self.collect_swept(status, swept, t0);
                Ok(status)
            }
            None => self.hand_over(swept, t0),
        }
    }

    /// After sweeps that hand over: the islands (built now if need be, and then started
    /// from the solve's warm start if it had one) solve within the time left, and the
    /// better answer by the measure is handed back.
    fn hand_over(&mut self, swept: SweepOutcome, t0: Instant) -> Result<Status, Error> {
        let for_good = (self.budgeted.as_ref()).is_some_and(|b| b.yields() == Yield::CoupledCost);
        if for_good && self.layout.is_some() {
            // Sweeps before a matrix-free solve (`sweeps_before_matrix_free`) that gave way
            // give way for good: their copy of the problem goes before ADMM takes its
            // memory (with both, a lattice pile of 1e5 contacts peaked 16% higher).
            self.budgeted = None;
        }
        if self.layout.is_none() {
            let built = Instant::now();
            let problem = self.budgeted.as_ref().expect("budgeted").problem();
            let (mut layout, islands) = self.build(problem)?;
            let budgeted = self.budgeted.as_ref().expect("budgeted");
            if let Some((r, v)) = budgeted.used_warm() {
                layout.warm_start(r, v)?;
            }
            self.layout = Some(layout);
            self.stats.islands = islands;
            self.stats.setup_seconds += built.elapsed().as_secs_f64();
        }
        let status = self.islands_solve(swept.error, t0)?;
        self.stats.gauss_seidel_sweeps = swept.sweeps;
        self.stats.newton_iterations += swept.newton_steps;
        self.stats.newton_factorizations += swept.newton_factorizations;
        self.stats.newton_phases += usize::from(swept.newton_factorizations > 0);
        Ok(status)
    }

    /// The islands solve within what is left of the time limit from `t0`; their answer is
    /// handed back when it is better than `swept_error` (the sweeps' answer, already in
    /// `self.solution`) or meets the tolerance. They keep the next solve when they met it.
    fn islands_solve(&mut self, swept_error: f64, t0: Instant) -> Result<Status, Error> {
        let left = Settings {
            time_limit: (self.inner.time_limit - t0.elapsed().as_secs_f64()).max(0.0),
            ..self.inner.clone()
        };
        // Not from the sweeps' iterate: that saved a quarter of the iterations on most FCLib
        // Box_Stacks files but took 4 to 5 times as many on two (docs/algorithms.md §17),
        // so the handover costs the sweeps and nothing else.
        let layout = self.layout.as_mut().expect("built above");
        layout.update_settings(&left);
        let mut out = Solution::default();
        let result = layout.solve(&left, Instant::now(), &mut out);
        layout.update_settings(&self.inner);
        let (status, error) = result?;
        let better = error <= swept_error || status == Status::Solved;
        if better {
            self.solution = out;
            self.collect_stats(status, error, t0.elapsed().as_secs_f64());
        } else {
            // The sweeps' answer stays (already in `self.solution`).
            self.collect_stats(status, swept_error, t0.elapsed().as_secs_f64());
        }
        // Only a solved answer keeps them: one stopped by the time limit is a scene in
        // motion, where from the warm start they answered worse than the sweeps (a bin's
        // falling boxes under Bullet's budget: errors of 0.15 against 0.03).
        self.islands_first = status == Status::Solved;
        Ok(status)
    }

    /// The statistics of a solve the sweeps ended.
    fn collect_swept(&mut self, status: Status, swept: SweepOutcome, t0: Instant) {
        let (islands, setup) = (self.stats.islands, self.stats.setup_seconds);
        self.stats = Stats {
            status,
            error: swept.error,
            gauss_seidel_sweeps: swept.sweeps,
            newton_iterations: swept.newton_steps,
            newton_factorizations: swept.newton_factorizations,
            newton_phases: usize::from(swept.newton_factorizations > 0),
            solve_seconds: t0.elapsed().as_secs_f64(),
            islands,
            setup_seconds: setup,
            ..Stats::default()
        };
        self.island_stats.clear();
    }

    /// Gathers the statistics of the last solve from the islands.
    fn collect_stats(&mut self, status: Status, error: f64, seconds: f64) {
        let (islands, setup) = (self.stats.islands, self.stats.setup_seconds);
        let Some(layout) = &self.layout else {
            self.island_stats.clear();
            return;
        };
        match layout {
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
                    stats.add_part(p);
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

    /// The solution the last solve handed back (its best iterate when it did not solve;
    /// zeros before the first solve). A warm start or an update does not change it.
    pub fn solution(&self) -> &Solution {
        &self.solution
    }

    /// Length of `v` (0 for a local problem).
    pub fn n_velocities(&self) -> usize {
        self.solution.v.len()
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

    /// Makes `flag` the solver's interrupt, for a caller that must be able to stop a solve
    /// under way (a user's Ctrl-C): once `flag` is set, from any thread, each ADMM run
    /// ends after its current iteration as at the time limit, and the solve returns
    /// `Status::TimeLimit` with the best iterate measured. A Newton phase under way finishes
    /// its steps first. The solver stays usable; clear the flag before the next solve. A
    /// flag that is never set does not change the solve.
    pub fn set_interrupt(&mut self, flag: Arc<AtomicBool>) {
        if let Some(layout) = &mut self.layout {
            layout.set_interrupt(&flag);
        }
        self.interrupt = Some(flag);
    }

    /// Per-iteration trace of the last solve (empty unless `Settings::trace`); with several
    /// islands, the trace of the island that needed the most iterations.
    pub fn trace(&self) -> &[TracePoint] {
        match &self.layout {
            Some(Layout::Whole(s)) => s.trace(),
            Some(Layout::Split(split)) => split.slowest.map_or(&[][..], |k| &split.parts[k].trace),
            None => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csc::CscMatrix;
    use crate::problem::GlobalProblem;

    /// A body of 6 velocities and mass matrix `mass I` on `contacts` contacts, pressed into
    /// them by `f`, with H's entries drawn from `seed` (every entry stored: the pattern is
    /// the sizes').
    fn pile(contacts: usize, seed: u64, f: f64, mass: f64) -> Problem {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let triplets: Vec<_> = (0..3 * contacts)
            .flat_map(|j| (0..6).map(move |i| (i, j)))
            .map(|(i, j)| {
                let normal_up = i == 1 && j % 3 == 0;
                (i, j, if normal_up { 1.0 } else { 0.2 * next() })
            })
            .collect();
        let h = CscMatrix::from_triplets("H", 6, 3 * contacts, &triplets).unwrap();
        let mut force = vec![0.0; 6];
        force[1] = f;
        let m =
            CscMatrix::from_triplets("M", 6, 6, &(0..6).map(|i| (i, i, mass)).collect::<Vec<_>>())
                .unwrap();
        let p =
            GlobalProblem::new(m, h, force, vec![0.0; 3 * contacts], vec![0.5; contacts]).unwrap();
        Problem::Global(p)
    }

    fn addresses(solver: &mut Solver) -> Vec<*const CoupledSolver> {
        let layout = solver.layout.as_mut().expect("built");
        let solvers = layout.coupled_to_offer();
        solvers.into_iter().map(|s| s as *const _).collect()
    }

    /// A rebuild for a scene whose first island kept its sub-problem's pattern (new values)
    /// and whose second changed keeps the first island's coupled solver and builds the
    /// second's; both answers meet the tolerance.
    #[test]
    fn a_rebuild_keeps_the_solver_of_an_island_whose_pattern_stayed() {
        let settings = Settings {
            newton_polish: Some(false), // coupled solvers for the small islands too
            ..Settings::default()
        };
        let scene =
            Problem::block_diagonal(&[pile(4, 1, -1.0, 1.0), pile(4, 2, -1.0, 1.0)]).unwrap();
        let mut solver = Solver::new(scene, settings).unwrap();
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        let before = addresses(&mut solver);
        assert_eq!(before.len(), 2);
        let next =
            Problem::block_diagonal(&[pile(4, 1, -1.5, 2.0), pile(5, 3, -1.0, 1.0)]).unwrap();
        solver.rebuild(&next).unwrap();
        let after = addresses(&mut solver);
        assert_eq!(after.len(), 2);
        assert_eq!(after[0], before[0], "the first island kept its solver");
        assert_ne!(after[1], before[1], "the second island's changed");
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        assert!(solver.stats().error <= solver.settings().tolerance);
        let answer = solver.solution().clone();
        // A rebuild the second island refuses (its M is not positive definite), after the
        // first took its solver with new values: the solver is left as it was, and answers
        // as it did.
        let refused =
            Problem::block_diagonal(&[pile(4, 1, -2.0, 3.0), pile(6, 4, -1.0, -1.0)]).unwrap();
        assert!(solver.rebuild(&refused).is_err());
        assert_eq!(addresses(&mut solver), after);
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        assert_eq!(solver.solution().r, answer.r);
        assert_eq!(solver.solution().v, answer.v);
    }

    /// An island's solver taken by a problem solved whole (the other island gone) answers
    /// as a new solver of that problem, bit for bit: the island's measure floors go.
    #[test]
    fn an_island_solver_taken_by_a_whole_problem_answers_as_a_new_one() {
        let settings = Settings {
            newton_polish: Some(false),
            ..Settings::default()
        };
        let a = pile(4, 1, -1.0, 1.0);
        let scene = Problem::block_diagonal(&[a.clone(), pile(4, 2, -30.0, 0.1)]).unwrap();
        let mut solver = Solver::new(scene, settings.clone()).unwrap();
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        let before = addresses(&mut solver);
        solver.rebuild(&a).unwrap();
        assert_eq!(
            addresses(&mut solver)[0],
            before[0],
            "the island's solver kept"
        );
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        let mut fresh = Solver::new(a, settings).unwrap();
        assert_eq!(fresh.solve().unwrap(), Status::Solved);
        assert_eq!(solver.solution(), fresh.solution());
        assert_eq!(solver.stats().iterations, fresh.stats().iterations);
        assert_eq!(
            solver.stats().error,
            fresh.stats().error,
            "measured without floors"
        );
    }

    /// A budgeted solver builds its islands when its sweeps hand over; after a rebuild its
    /// next islands take the solvers of those whose patterns stayed.
    #[test]
    fn a_budgeted_rebuild_keeps_the_islands_for_the_next_handover() {
        let settings = Settings {
            newton_polish: Some(false),
            tolerance: 1e-12,
            time_limit: 60.0,
            ..Settings::default()
        };
        let scene =
            Problem::block_diagonal(&[pile(4, 1, -1.0, 1.0), pile(4, 2, -1.0, 1.0)]).unwrap();
        let mut solver = Solver::new(scene, settings).unwrap();
        assert!(solver.budgeted.is_some());
        solver.solve().unwrap();
        assert!(solver.stats().iterations > 0, "the sweeps handed over");
        let before = addresses(&mut solver);
        let next =
            Problem::block_diagonal(&[pile(4, 1, -1.5, 2.0), pile(5, 3, -1.0, 1.0)]).unwrap();
        solver.rebuild(&next).unwrap();
        assert!(solver.layout.is_none(), "the sweeps start again");
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        assert!(solver.stats().iterations > 0, "the sweeps handed over");
        let after = addresses(&mut solver);
        assert_eq!(after[0], before[0], "the first island kept its solver");
        assert_ne!(after[1], before[1]);
    }
}
