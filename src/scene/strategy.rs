//! How one part of a scene is solved, chosen once when the solver is built
//! (docs/algorithms.md §12): velocities no contact reaches by free motion, a small island
//! by Newton on its dense Delassus form with ADMM behind it, any other island by its own
//! coupled solver (ADMM finished by Newton). The fallback order of each part is fixed by
//! its [`Strategy`]; no part runs Newton twice from the same start.

use crate::coupled::{CoupledSolver, NewtonFirst};
use crate::measure::{Floors, Scales};
use crate::problem::{NewValues, Problem};
use crate::scene::free_motion::FreeMotion;
use crate::scene::islands::{contact_rows, Part, ValueBuffers};
use crate::scene::offered::{Offer, Offered};
use crate::scene::small_island::{Site, SmallIsland, SmallWork};
use crate::settings::Settings;
use crate::tuning::NEWTON_FIRST_STEPS;
use crate::types::{Error, Solution, Stats, Status, TracePoint};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

/// What every part's solve reads: the whole problem (a small island that falls back builds
/// its sub-problem from it), the positions of [`crate::scene::islands::positions`], and the clock.
pub(crate) struct SolveContext<'a> {
    pub(crate) whole: &'a Problem,
    pub(crate) row_of: &'a [usize],
    pub(crate) settings: &'a Settings,
    pub(crate) t0: Instant,
}

/// How a part is to be solved: the strategy built, or an offered coupled solver.
pub(crate) struct Plan(Planned);

enum Planned {
    Strategy(Strategy),
    /// The index of an offered coupled solver that took the part's sub-problem.
    Offered(usize),
}

/// How a part is solved.
enum Strategy {
    /// Velocities no contact reaches, whose blocks of M are small: `v = M^-1 f`, body by
    /// body.
    FreeMotion(Box<FreeMotion>),
    /// A small frictional island: Newton on its dense Delassus form first; when that
    /// fails, ADMM finished by Newton (built then, and not starting with Newton again).
    DenseNewton {
        newton: SmallIsland,
        /// Boxed and built on the first failure: most small islands never need one.
        fallback: Option<Box<CoupledSolver>>,
        /// The last solve's solution is Newton's.
        solved_by_newton: bool,
    },
    /// Any other part: ADMM finished by Newton.
    Coupled(Box<CoupledSolver>),
}

/// One part of a scene and the state of its solves.
pub(crate) struct PartSolver {
    pub(crate) part: Part,
    strategy: Strategy,
    floors: Floors,
    /// Boxed and built on the first update of a built coupled solver.
    values: Option<Box<ValueBuffers>>,
    /// Warm-start buffers.
    pub(crate) r: Vec<f64>,
    pub(crate) v: Vec<f64>,
    warm: bool,
    /// The part's share of the whole problem's velocities, contacts and joints (the
    /// square of the factor applied to the whole's scales in its measure floors).
    share: [f64; 3],
    /// Tolerance of the part in the current round, and the outcome of its last solve.
    pub(crate) tolerance: f64,
    pub(crate) outcome: Result<Status, Error>,
    /// Statistics and trace of the current solve, summed over its rounds.
    pub(crate) stats: Stats,
    pub(crate) trace: Vec<TracePoint>,
    /// Handed to the part's coupled solver, now or when it is built.
    interrupt: Arc<AtomicBool>,
}

impl PartSolver {
    /// Chooses the part's strategy and builds it, or takes an offered coupled solver that
    /// fits its sub-problem (`offered`). Small islands go to Newton directly when the
    /// settings polish with Newton (`newton_polish`). The part's entry maps are filled.
    pub(crate) fn plan(
        part: &mut Part,
        whole: &Problem,
        row_of: &[usize],
        settings: &Settings,
        newton_polish: bool,
        work: &mut SmallWork,
        offered: &mut Offered,
    ) -> Result<Plan, Error> {
        let free = match whole {
            Problem::Global(g) => FreeMotion::new(g, part, row_of)?,
            Problem::Local(_) => None,
        };
        let site = Site {
            whole,
            part,
            row_of,
        };
        let small = match (&free, newton_polish) {
            (None, true) => SmallIsland::new(site, settings.trace, work)?,
            _ => None,
        };
        Ok(Plan(match (free, small) {
            (Some(free), _) => Planned::Strategy(Strategy::FreeMotion(Box::new(free))),
            (None, Some(newton)) => Planned::Strategy(Strategy::DenseNewton {
                newton,
                fallback: None,
                solved_by_newton: false,
            }),
            (None, None) => match offered.take(part.sub_problem(whole, row_of)?)? {
                Offer::Taken(k) => Planned::Offered(k),
                Offer::NoneFits(sub) => Planned::Strategy(Strategy::Coupled(Box::new(
                    CoupledSolver::new(sub, settings.clone(), NewtonFirst::IfSmall)?,
                ))),
            },
        }))
    }

    /// The part's solver as `plan` chose it; an offered one is taken from `offered` (the
    /// replaced layout's coupled solvers, by the index `plan` gave).
    pub(crate) fn new(
        part: Part,
        whole: &Problem,
        settings: &Settings,
        plan: Plan,
        offered: &mut [Option<Box<CoupledSolver>>],
    ) -> Self {
        let strategy = match plan.0 {
            Planned::Strategy(s) => s,
            Planned::Offered(k) => {
                let mut solver = offered[k].take().expect("taken once");
                solver.update_settings(settings);
                // As a new island's: the scene's threads go to the islands, not their
                // linear algebra (a problem solved whole had them).
                solver.set_linear_threads(1);
                Strategy::Coupled(solver)
            }
        };
        Self {
            share: shares(&part, whole),
            stats: Stats::default(),
            trace: Vec::new(),
            values: None,
            r: vec![0.0; 3 * part.contacts.len()],
            v: vec![0.0; part.velocities.len()],
            warm: false,
            strategy,
            floors: Floors::default(),
            part,
            tolerance: settings.tolerance,
            outcome: Ok(Status::Unsolved),
            interrupt: Arc::default(),
        }
    }

    /// The part's coupled solver when it is one, for a rebuild to offer.
    pub(crate) fn coupled_to_offer(&mut self) -> Option<&mut CoupledSolver> {
        match &mut self.strategy {
            Strategy::Coupled(c) => Some(c),
            _ => None,
        }
    }

    /// [`PartSolver::coupled_to_offer`], taken.
    pub(crate) fn into_offered(self) -> Option<Box<CoupledSolver>> {
        match self.strategy {
            Strategy::Coupled(c) => Some(c),
            _ => None,
        }
    }

    /// The coupled solver, when the part has one built.
    fn coupled(&mut self) -> Option<&mut CoupledSolver> {
        match &mut self.strategy {
            Strategy::Coupled(c) => Some(c),
            Strategy::DenseNewton { fallback, .. } => fallback.as_deref_mut(),
            Strategy::FreeMotion(_) => None,
        }
    }

    /// Floors of the part's measure: its share of the whole problem's scales.
    pub(crate) fn set_floors(&mut self, whole: Scales) {
        let [velocities, contacts, joints] = self.share.map(f64::sqrt);
        self.floors = Floors {
            equation: whole.equation * velocities,
            contact: whole.contact * contacts,
            joint: whole.joint * joints,
        };
        let floors = self.floors;
        match &mut self.strategy {
            Strategy::FreeMotion(f) => f.set_measure_floors(floors),
            Strategy::DenseNewton { newton, .. } => newton.set_measure_floors(floors),
            Strategy::Coupled(_) => {}
        }
        if let Some(c) = self.coupled() {
            c.set_measure_floors(floors);
        }
    }

    /// Makes `flag` the interrupt of the part's ADMM runs (see `Solver::set_interrupt`).
    pub(crate) fn set_interrupt(&mut self, flag: Arc<AtomicBool>) {
        if let Some(c) = self.coupled() {
            c.set_interrupt(flag.clone());
        }
        self.interrupt = flag;
    }

    /// Takes the settings a solve reads when it starts.
    pub(crate) fn update_settings(&mut self, settings: &Settings) {
        if let Strategy::DenseNewton { newton, .. } = &mut self.strategy {
            newton.set_trace(settings.trace);
        }
        if let Some(c) = self.coupled() {
            c.update_settings(settings);
        }
    }

    /// Starts the next solve from the part's share of a warm start (in `self.r`, `self.v`).
    pub(crate) fn warm_start(&mut self, with_v: bool) -> Result<(), Error> {
        self.warm = true;
        if let Strategy::DenseNewton { newton, .. } = &mut self.strategy {
            newton.warm_start(&self.r);
        }
        let (r, v) = (std::mem::take(&mut self.r), std::mem::take(&mut self.v));
        let done = match self.coupled() {
            Some(c) => c.warm_start(&r, with_v.then_some(v.as_slice())),
            None => Ok(()),
        };
        (self.r, self.v) = (r, v);
        done
    }

    /// Takes the part's share of the whole problem's new values for the fields `given`
    /// names. The next solve starts cold.
    pub(crate) fn take_values(
        &mut self,
        whole: &Problem,
        row_of: &[usize],
        given: &NewValues,
        work: &mut SmallWork,
    ) -> Result<(), Error> {
        self.warm = false;
        let at = Site {
            whole,
            part: &self.part,
            row_of,
        };
        let (part, values) = (&self.part, &mut self.values);
        let mut share = |c: &mut CoupledSolver| {
            let values = values.get_or_insert_with(Default::default);
            let share = match whole {
                Problem::Global(g) => values.global(part, g, given),
                Problem::Local(l) => values.local(part, l, given),
            };
            c.update_values(&share)
        };
        match &mut self.strategy {
            Strategy::FreeMotion(f) => match whole {
                Problem::Global(g) => f.take_values(g, part, row_of),
                Problem::Local(_) => Ok(()),
            },
            // A small island reads its values from the whole problem; its fallback, when
            // built, takes its share as the other parts do.
            Strategy::DenseNewton {
                newton, fallback, ..
            } => {
                let newton = newton.take_values(at, work);
                let fallback = fallback.as_deref_mut().map_or(Ok(()), &mut share);
                newton.and(fallback)
            }
            Strategy::Coupled(c) => share(c),
        }
    }

    /// Solves with the part's tolerance and what is left of the time limit, and adds the
    /// solve to the part's statistics and trace.
    pub(crate) fn solve(&mut self, at: &SolveContext, work: &mut SmallWork) {
        self.outcome = self.solve_once(at, work);
        if let Ok(status) = self.outcome {
            // A part the time limit left no time for did not run.
            self.stats.status = status;
        }
    }

    /// The iterations the settings leave this solve (refinement rounds and the Newton
    /// steps of a small island count).
    fn iterations_left(&self, at: &SolveContext) -> usize {
        at.settings
            .max_iterations
            .saturating_sub(self.stats.iterations)
    }

    fn time_left(at: &SolveContext) -> f64 {
        at.settings.time_limit - at.t0.elapsed().as_secs_f64()
    }

    fn solve_once(&mut self, at: &SolveContext, work: &mut SmallWork) -> Result<Status, Error> {
        let warm = std::mem::replace(&mut self.warm, false);
        if Self::time_left(at) <= 0.0 {
            return Ok(Status::TimeLimit);
        }
        if let Strategy::FreeMotion(free) = &mut self.strategy {
            let status = free.solve()?;
            self.stats = Stats {
                setup_seconds: self.stats.setup_seconds,
                ..*free.stats()
            };
            return Ok(status);
        }
        if matches!(self.strategy, Strategy::DenseNewton { .. }) {
            if let Some(status) = self.solve_by_newton(at, work)? {
                return Ok(status);
            }
            self.build_fallback(at, warm)?;
        }
        self.solve_coupled(at)
    }

    /// The dense Newton solve of a small island: its status when it ends the part's solve
    /// (solved, or a limit reached), `None` when ADMM is to take over.
    fn solve_by_newton(
        &mut self,
        at: &SolveContext,
        work: &mut SmallWork,
    ) -> Result<Option<Status>, Error> {
        let steps = self.iterations_left(at).min(NEWTON_FIRST_STEPS);
        let Strategy::DenseNewton {
            newton,
            solved_by_newton,
            ..
        } = &mut self.strategy
        else {
            return Ok(None);
        };
        if steps == 0 {
            return Ok(Some(Status::MaxIterations));
        }
        let started = at.t0.elapsed().as_secs_f64();
        newton.set_limits(self.tolerance, Self::time_left(at), steps);
        let site = Site {
            whole: at.whole,
            part: &self.part,
            row_of: at.row_of,
        };
        let status = newton.solve(site, work)?;
        *solved_by_newton = status == Status::Solved;
        add_solve(
            &mut self.stats,
            &mut self.trace,
            newton.stats(),
            newton.trace(),
            started,
        );
        if status == Status::Solved || status == Status::TimeLimit {
            return Ok(Some(status));
        }
        if self.iterations_left(at) == 0 {
            return Ok(Some(Status::MaxIterations));
        }
        self.stats.newton_fallbacks += 1;
        Ok(None)
    }

    /// Builds a small island's coupled solver on its first fallback: ADMM with the usual
    /// handover to Newton, not a second Newton phase from the start Newton just failed
    /// from.
    fn build_fallback(&mut self, at: &SolveContext, warm: bool) -> Result<(), Error> {
        let Strategy::DenseNewton { fallback, .. } = &mut self.strategy else {
            return Ok(());
        };
        if fallback.is_none() {
            let problem = self.part.sub_problem(at.whole, at.row_of)?;
            let mut coupled = CoupledSolver::new(problem, at.settings.clone(), NewtonFirst::Never)?;
            coupled.set_measure_floors(self.floors);
            coupled.set_interrupt(self.interrupt.clone());
            if warm {
                coupled.warm_start(&self.r, None)?;
            }
            *fallback = Some(Box::new(coupled));
        }
        Ok(())
    }

    /// ADMM finished by Newton on the part's coupled solver.
    fn solve_coupled(&mut self, at: &SolveContext) -> Result<Status, Error> {
        let (tolerance, left) = (self.tolerance, self.iterations_left(at));
        let started = at.t0.elapsed().as_secs_f64();
        let time_left = at.settings.time_limit - started;
        let coupled = match &mut self.strategy {
            Strategy::Coupled(c) => c,
            Strategy::DenseNewton {
                fallback: Some(c), ..
            } => c,
            _ => return Err(Error::Unsupported("a part without a coupled solver".into())),
        };
        if time_left <= 0.0 {
            return Ok(Status::TimeLimit);
        }
        coupled.set_limits(tolerance, time_left, left);
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
    pub(crate) fn solution(&self, whole: &Problem, row_of: &[usize]) -> Solution {
        let at = Site {
            whole,
            part: &self.part,
            row_of,
        };
        match &self.strategy {
            Strategy::FreeMotion(f) => f.solution(),
            Strategy::Coupled(c) => c.solution(),
            Strategy::DenseNewton {
                newton,
                fallback,
                solved_by_newton,
            } => match fallback {
                Some(c) if !solved_by_newton => c.solution(),
                _ => newton.solution(at),
            },
        }
    }

    /// Writes the part's solution into the whole problem's at the part's places.
    pub(crate) fn write_solution(&self, whole: &Problem, row_of: &[usize], out: &mut Solution) {
        if let Strategy::DenseNewton {
            newton,
            fallback,
            solved_by_newton,
        } = &self.strategy
        {
            if *solved_by_newton || fallback.is_none() {
                let at = Site {
                    whole,
                    part: &self.part,
                    row_of,
                };
                newton.write_solution(at, out);
                return;
            }
        }
        let s = self.solution(whole, row_of);
        for (k, i) in contact_rows(&self.part.contacts).enumerate() {
            out.r[i] = s.r[k];
            out.u[i] = s.u[k];
        }
        for (k, &i) in self.part.velocities.iter().enumerate() {
            out.v[i] = s.v[k];
        }
        for (k, &i) in self.part.joints.iter().enumerate() {
            out.lambda[i] = s.lambda[k];
        }
    }

    /// Starts a new solve's statistics.
    pub(crate) fn reset(&mut self) {
        let setup = match &self.strategy {
            Strategy::FreeMotion(f) => f.stats().setup_seconds,
            Strategy::Coupled(c) => c.stats().setup_seconds,
            Strategy::DenseNewton {
                newton, fallback, ..
            } => {
                newton.stats().setup_seconds
                    + fallback.as_ref().map_or(0.0, |c| c.stats().setup_seconds)
            }
        };
        self.stats = Stats {
            setup_seconds: setup,
            ..Stats::default()
        };
        self.trace.clear();
    }
}

/// A part's share of the whole problem's velocities, contacts and joints.
fn shares(part: &Part, whole: &Problem) -> [f64; 3] {
    let fraction = |k: usize, total: usize| k as f64 / total.max(1) as f64;
    match whole {
        Problem::Global(g) => [
            fraction(part.velocities.len(), g.n()),
            fraction(part.contacts.len(), g.n_contacts()),
            fraction(part.joints.len(), g.n_joints()),
        ],
        Problem::Local(l) => {
            let c = fraction(part.contacts.len(), l.n_contacts());
            [c, c, 0.0]
        }
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
    total.add_solve(s);
}
