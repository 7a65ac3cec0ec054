//! A scene split into its contact islands (docs/algorithms.md §12): the parts found once
//! from the sparsity pattern, each solved by its own [`PartSolver`], and the whole
//! problem, on which new values land first and the assembled solution is measured.

mod free_motion;
pub(crate) mod islands;
pub(crate) mod offered;
pub(crate) mod refine;
mod small_island;
mod strategy;

use crate::coupled::CoupledSolver;
use crate::csc::norm2;
use crate::measure::{free_contact_velocity, solution_error, MeasureWork, Scales};
use crate::problem::{check_len, KeptValues, NewValues, Problem};
use crate::scene::islands::{contact_rows, gather, positions, Part, Partition};
use crate::scene::refine::{most_severe, refine_rounds, SolveInParts};
use crate::scene::small_island::SmallWork;
use crate::scene::strategy::{PartSolver, Plan, SolveContext};
use crate::settings::{NewtonUse, Settings};
use crate::tuning::{FREE_CONTACT_SHARE, ISLAND_ROUNDS};
use crate::types::{Error, Solution, Status};
use offered::Offered;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// A problem split into islands: the structure found once from the sparsity pattern (the
/// parts, where each row sits in its part) and each part's solver.
pub(crate) struct Scene {
    /// The whole problem: new values land here first, and the assembled solution is
    /// measured on it.
    pub(crate) whole: Problem,
    /// The contact islands, then the contact-free part (global form) when there is one.
    pub(crate) parts: Vec<PartSolver>,
    /// Contact islands among `parts` (the first ones).
    pub(crate) n_islands: usize,
    /// Contacts no velocity moves (see [`Partition::bodiless`]).
    bodiless: Vec<usize>,
    measure: MeasureWork,
    /// The part whose trace and residuals the solver reports (the one that needed the
    /// most iterations in the last solve; none without parts).
    pub(crate) slowest: Option<usize>,
    /// Where each velocity (global) or contact row (local) sits in its part.
    row_of: Vec<usize>,
    /// Work space of the small islands, one per thread that solves them.
    work: Vec<SmallWork>,
    /// The values an update replaces, until it has succeeded.
    kept: KeptValues,
}

/// A scene whose parts' solvers are chosen (`Scene::plan`), before the offered solvers
/// they take are handed over (`Scene::new`).
pub(crate) struct ScenePlan {
    whole: Problem,
    parts: Vec<(Part, Plan)>,
    n_islands: usize,
    bodiless: Vec<usize>,
    row_of: Vec<usize>,
    work: Vec<SmallWork>,
}

impl Scene {
    /// Plans the parts of `partition`: each builds its solver, or takes an offered coupled
    /// solver that fits its sub-problem ([`Offered`]).
    pub(crate) fn plan(
        whole: Problem,
        partition: Partition,
        settings: &Settings,
        offered: &mut Offered,
    ) -> Result<ScenePlan, Error> {
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
            .map(|mut part| {
                let plan = PartSolver::plan(
                    &mut part,
                    &whole,
                    &row_of,
                    settings,
                    newton_polish,
                    &mut work[0],
                    offered,
                )?;
                Ok((part, plan))
            })
            .collect::<Result<Vec<_>, Error>>()?;
        Ok(ScenePlan {
            whole,
            parts,
            n_islands,
            bodiless,
            row_of,
            work,
        })
    }

    /// The scene `plan` chose, taking the offered solvers its parts took from `offered`.
    pub(crate) fn new(
        plan: ScenePlan,
        settings: &Settings,
        offered: &mut [Option<Box<CoupledSolver>>],
    ) -> Self {
        let ScenePlan {
            whole,
            parts,
            n_islands,
            bodiless,
            row_of,
            work,
        } = plan;
        let parts = parts
            .into_iter()
            .map(|(part, plan)| PartSolver::new(part, &whole, settings, plan, offered))
            .collect();
        let measure = MeasureWork::new(&whole);
        Self {
            whole,
            parts,
            n_islands,
            bodiless,
            measure,
            slowest: None,
            row_of,
            work,
            kept: KeptValues::default(),
        }
    }

    /// The parts' coupled solvers, for a rebuild to offer (in the order of
    /// [`Scene::into_offered`]).
    pub(crate) fn coupled_to_offer(&mut self) -> Vec<&mut CoupledSolver> {
        self.parts
            .iter_mut()
            .filter_map(PartSolver::coupled_to_offer)
            .collect()
    }

    /// [`Scene::coupled_to_offer`], taken.
    pub(crate) fn into_offered(self) -> Vec<Option<Box<CoupledSolver>>> {
        self.parts
            .into_iter()
            .filter_map(PartSolver::into_offered)
            .map(Some)
            .collect()
    }

    pub(crate) fn update(&mut self, problem: Problem) -> Result<(), Error> {
        self.whole.check_successor(&problem)?;
        let before = std::mem::replace(&mut self.whole, problem);
        let Err(e) = self.distribute(&NewValues::EVERY_FIELD) else {
            return Ok(());
        };
        // A part refused its values: every part goes back to the problem before.
        self.whole = before;
        let _ = self.distribute(&NewValues::EVERY_FIELD);
        Err(e)
    }

    pub(crate) fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        let mut kept = std::mem::take(&mut self.kept);
        kept.keep((&self.whole).into(), values);
        let taken = self
            .whole
            .set_values(values)
            .and_then(|()| self.distribute(values));
        if taken.is_err() {
            // A part refused its values (the rest took theirs): every part goes back to
            // the values kept, so that a refused update changes nothing.
            let back = kept.values();
            let _ = self
                .whole
                .set_values(&back)
                .and_then(|()| self.distribute(&back));
        }
        self.kept = kept;
        taken
    }

    /// The whole problem's scales known before solving, from its current values: `||f||`,
    /// a share of the free motion's contact velocities (`measure::free_contact_velocity`,
    /// [`FREE_CONTACT_SHARE`]) and `||b||` (local form: `||q||`), which floor the islands'
    /// first solve.
    fn known_scales(&self) -> Scales {
        match &self.whole {
            Problem::Global(g) => Scales {
                equation: norm2(&g.f),
                contact: FREE_CONTACT_SHARE * free_contact_velocity(g),
                joint: g.joints.as_ref().map_or(0.0, |j| norm2(&j.b)),
            },
            Problem::Local(l) => Scales {
                equation: norm2(&l.q),
                ..Scales::default()
            },
        }
    }

    /// Takes the settings a solve reads when it starts.
    pub(crate) fn update_settings(&mut self, settings: &Settings) {
        for p in &mut self.parts {
            p.update_settings(settings);
        }
    }

    /// Makes `flag` the interrupt of every part's ADMM runs (see `Solver::set_interrupt`).
    pub(crate) fn set_interrupt(&mut self, flag: &Arc<AtomicBool>) {
        for p in &mut self.parts {
            p.set_interrupt(flag.clone());
        }
    }

    /// Hands each part its share of the whole problem's values for the fields `given`
    /// names. Every part is updated even when one fails, and the first error is returned.
    fn distribute(&mut self, given: &NewValues) -> Result<(), Error> {
        let mut first_error = Ok(());
        for p in &mut self.parts {
            let done = p.take_values(&self.whole, &self.row_of, given, &mut self.work[0]);
            if first_error.is_ok() {
                first_error = done;
            }
        }
        first_error
    }

    pub(crate) fn warm_start(&mut self, r: &[f64], v: Option<&[f64]>) -> Result<(), Error> {
        check_len("r", r, 3 * self.whole.n_contacts())?;
        if let Some(v) = v {
            check_len("v", v, self.whole.n_velocities())?;
        }
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
    /// are solved again, warm, to a tolerance tightened in proportion. The assembled
    /// solution is left in `out`.
    pub(crate) fn solve(
        &mut self,
        settings: &Settings,
        t0: Instant,
        out: &mut Solution,
    ) -> Result<(Status, f64), Error> {
        let tol = settings.tolerance;
        let known_scales = self.known_scales();
        for p in &mut self.parts {
            p.tolerance = tol;
            p.reset();
            p.set_floors(known_scales);
        }
        let pending = vec![true; self.parts.len()];
        let mut rounds = SceneRounds {
            scene: self,
            settings,
            t0,
            out,
            pending,
        };
        let (status, error) = refine_rounds(&mut rounds, tol, ISLAND_ROUNDS)?;
        self.slowest = (0..self.parts.len()).max_by_key(|&k| self.parts[k].stats.iterations);
        Ok((status, error))
    }

    /// Multiplies the tolerance of every part with contacts by `factor`, sets its floors at
    /// the last whole measure's scales and starts it warm from the assembled solution;
    /// `pending` marks those parts (the contact-free part is solved exactly already).
    fn tighten(&mut self, factor: f64, pending: &mut [bool]) -> Result<(), Error> {
        let scales = self.measure.scales;
        for (p, again) in self.parts.iter_mut().zip(pending) {
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
        Ok(())
    }

    /// Solves the pending parts, on `threads` scoped threads when several are pending. The
    /// parts are independent, so the results do not depend on the threads.
    fn solve_parts(&mut self, pending: &[bool], settings: &Settings, t0: Instant) {
        let Scene {
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

    /// Writes the solution of the whole problem from the parts' into `out` (bodiless
    /// contacts: `r = 0`, `u = w`), reusing its vectors.
    fn assemble(&self, out: &mut Solution) {
        let (n, m) = (self.whole.n_velocities(), 3 * self.whole.n_contacts());
        out.zeroed(m, n, self.whole.n_joints());
        if let Problem::Global(g) = &self.whole {
            for &c in &self.bodiless {
                out.u[3 * c..3 * c + 3].copy_from_slice(&g.w[3 * c..3 * c + 3]);
            }
        }
        for p in &self.parts {
            p.write_solution(&self.whole, &self.row_of, out);
        }
    }

    /// The whole problem's error measure at the assembled solution, left in `out`.
    fn whole_error(&mut self, out: &mut Solution) -> f64 {
        self.assemble(out);
        solution_error(&self.whole, out, &mut self.measure)
    }
}

/// One solve of a scene's parts, as the refine rounds drive it.
struct SceneRounds<'a> {
    scene: &'a mut Scene,
    settings: &'a Settings,
    t0: Instant,
    out: &'a mut Solution,
    /// The parts the next round solves.
    pending: Vec<bool>,
}

impl SolveInParts for SceneRounds<'_> {
    type Error = Error;

    fn solve_parts(&mut self) -> Result<Option<Status>, Error> {
        let scene = &mut *self.scene;
        scene.solve_parts(&self.pending, self.settings, self.t0);
        if let Some(Err(e)) = scene.parts.iter().map(|p| &p.outcome).find(|o| o.is_err()) {
            return Err(e.clone());
        }
        // With a bodiless contact that approaches, the problem has no solution and no
        // round can meet the tolerance.
        let blocked = scene.bodiless_blocked().then_some(Status::Infeasible);
        let statuses = scene.parts.iter().map(|p| p.outcome.clone().ok());
        Ok(statuses.fold(blocked, most_severe))
    }

    fn whole_error(&mut self) -> Result<f64, Error> {
        Ok(self.scene.whole_error(self.out))
    }

    fn tighten(&mut self, factor: f64) -> Result<(), Error> {
        self.scene.tighten(factor, &mut self.pending)
    }
}
