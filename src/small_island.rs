//! Small contact islands solved directly: semismooth Newton on the island's Delassus form
//! `u = W r + q` (docs/algorithms.md §12). A global island's `W = H^T M^-1 H` and
//! `q = H^T M^-1 f + w` are formed densely from a Cholesky factor of M, and every iterate
//! is judged by the island's own global measure at `v = M^-1 (H r + f)`. An island of a box
//! on the ground (6 velocities, 4 contacts) costs a few microseconds this way, where
//! building its ADMM form and its global Newton system costs tens. When Newton does not
//! reach the tolerance, the island's coupled solver (ADMM and Newton) takes over.

use crate::csc::CscMatrix;
use crate::error::{Error, Status};
use crate::linsys::dense::{cholesky, cholesky_solve};
use crate::linsys::DENSE_MAX;
use crate::measure::{global_error_with, local_error_with, Floors, MeasureWork};
use crate::newton::LocalNewton;
use crate::problem::{GlobalProblem, LocalProblem, NewValues, Problem};
use crate::solver::Solution;
use crate::stats::{Phase, Stats, TracePoint};
use std::time::{Duration, Instant};

/// An island of at most this many contact rows and velocities may be solved directly.
pub(crate) const SMALL_ISLAND_MAX: usize = DENSE_MAX;

/// True when `p` is an island the direct Newton path takes: some friction (an all
/// frictionless island is a QP, which the coupled solver solves with one row per contact),
/// no joints, a symmetric M (the Cholesky factor of the reduction; the coupled solver
/// takes the others by LU), and small enough for dense factors.
pub(crate) fn is_small_island(p: &Problem) -> bool {
    let small = 3 * p.n_contacts() <= SMALL_ISLAND_MAX && p.n_velocities() <= SMALL_ISLAND_MAX;
    let reducible = match p {
        Problem::Global(g) => g.joints.is_none() && g.m.is_symmetric(),
        Problem::Local(_) => true,
    };
    small && reducible && p.mu().iter().any(|&mu| mu > 0.0)
}

/// A global island reduced to its Delassus form.
struct Reduction {
    problem: GlobalProblem,
    /// Column-major Cholesky factor of M (`n x n`).
    chol: Vec<f64>,
    /// `M^-1 H`, column-major `n x 3nc`.
    minv_h: Vec<f64>,
    /// `M^-1 f`.
    minv_f: Vec<f64>,
    /// `W`, column-major, before it is copied into the local problem.
    w: Vec<f64>,
}

impl Reduction {
    /// Forms `W` and `q` of `local` from the problem's current values (no allocation).
    fn reduce(&mut self, local: &mut LocalProblem) -> Result<(), Error> {
        let p = &self.problem;
        let (n, m) = (p.n(), p.w.len());
        // The symmetric part of M: positive definite exactly when M is (as the coupled
        // solver checks it). An M that an update made asymmetric gets a wrong W here, which
        // the island's measure (on M itself) rejects, and the coupled solver takes over.
        self.chol.fill(0.0);
        for j in 0..n {
            for (i, x) in p.m.col(j) {
                self.chol[i + j * n] += 0.5 * x;
                self.chol[j + i * n] += 0.5 * x;
            }
        }
        if !cholesky(&mut self.chol, n) {
            return Err(Error::NotPositiveDefinite { field: "M" });
        }
        self.minv_h.fill(0.0);
        for c in 0..m {
            let col = &mut self.minv_h[c * n..(c + 1) * n];
            for (i, x) in p.h.col(c) {
                col[i] = x;
            }
            cholesky_solve(&self.chol, n, col);
        }
        self.minv_f.copy_from_slice(&p.f);
        cholesky_solve(&self.chol, n, &mut self.minv_f);
        for j in 0..m {
            let minv_hj = &self.minv_h[j * n..(j + 1) * n];
            for i in 0..m {
                self.w[i + j * m] = p.h.col(i).map(|(k, x)| x * minv_hj[k]).sum();
            }
        }
        local.w.set_values("W", &self.w)?;
        local.q.copy_from_slice(&p.w);
        p.h.mul_t_vec(1.0, &self.minv_f, 1.0, &mut local.q);
        local.mu.copy_from_slice(&p.mu);
        Ok(())
    }

    /// `v = M^-1 (H r + f)`.
    fn velocities(&self, r: &[f64], v: &mut [f64]) {
        let n = v.len();
        v.copy_from_slice(&self.minv_f);
        for (c, &rc) in r.iter().enumerate() {
            if rc != 0.0 {
                for (vi, x) in v.iter_mut().zip(&self.minv_h[c * n..(c + 1) * n]) {
                    *vi += rc * x;
                }
            }
        }
    }
}

/// Solves one small island by Newton on its Delassus form.
pub(crate) struct SmallIsland {
    /// The Delassus form (a local island's own problem).
    local: LocalProblem,
    /// A global island and its reduction to `local`.
    reduction: Option<Box<Reduction>>,
    newton: LocalNewton,
    measure: MeasureWork,
    tolerance: f64,
    time_limit: f64,
    max_steps: usize,
    trace: bool,
    /// The iterate: impulses, and the velocities they give (global form).
    r: Vec<f64>,
    v: Vec<f64>,
    warm: bool,
    /// The error of the last values taken, when they cannot be solved (M not positive
    /// definite); solves fail with it until an update succeeds.
    broken: Option<Error>,
    stats: Stats,
    last_trace: Option<TracePoint>,
}

impl SmallIsland {
    /// Forms the Delassus form of `problem` (an island [`is_small_island`] accepts) and
    /// the Newton solver on it.
    pub(crate) fn new(problem: Problem, trace: bool) -> Result<Self, Error> {
        let t0 = Instant::now();
        let (local, reduction) = match problem {
            Problem::Local(l) => (l, None),
            Problem::Global(g) => {
                let (n, m) = (g.n(), g.w.len());
                // Full dense pattern, so that new values never change it.
                let colptr = (0..=m).map(|j| j * m).collect();
                let rowind = (0..m * m).map(|k| k % m).collect();
                let w = CscMatrix::new("W", m, m, colptr, rowind, vec![0.0; m * m])?;
                let mut local = LocalProblem::new(w, vec![0.0; m], g.mu.clone())?;
                let mut reduction = Reduction {
                    chol: vec![0.0; n * n],
                    minv_h: vec![0.0; n * m],
                    minv_f: vec![0.0; n],
                    w: vec![0.0; m * m],
                    problem: g,
                };
                reduction.reduce(&mut local)?;
                (local, Some(Box::new(reduction)))
            }
        };
        let newton = LocalNewton::new(&local)?;
        let measure = match &reduction {
            Some(red) => MeasureWork::global(&red.problem),
            None => MeasureWork::local(&local),
        };
        let n = reduction.as_ref().map_or(0, |red| red.problem.n());
        let m = local.q.len();
        Ok(Self {
            newton,
            measure,
            tolerance: 0.0,
            time_limit: f64::INFINITY,
            max_steps: 0,
            trace,
            r: vec![0.0; m],
            v: vec![0.0; n],
            warm: false,
            broken: None,
            stats: Stats {
                setup_seconds: t0.elapsed().as_secs_f64(),
                rows: m,
                ..Stats::default()
            },
            last_trace: None,
            local,
            reduction,
        })
    }

    /// The island's problem, for building its coupled solver.
    pub(crate) fn problem(&self) -> Problem {
        match &self.reduction {
            Some(red) => Problem::Global(red.problem.clone()),
            None => Problem::Local(self.local.clone()),
        }
    }

    /// Sets the tolerance, the time limit and the Newton steps of the next solves.
    pub(crate) fn set_limits(&mut self, tolerance: f64, time_limit: f64, max_steps: usize) {
        self.tolerance = tolerance;
        self.time_limit = time_limit;
        self.max_steps = max_steps;
    }

    /// Floors of the error measure (the island's share of a scene's measure).
    pub(crate) fn set_measure_floors(&mut self, floors: Floors) {
        self.measure.floors = floors;
    }

    /// Takes new values on the same pattern and forms the Delassus form again (no
    /// allocation). The next solve starts cold unless a warm start follows.
    pub(crate) fn update_values(&mut self, values: &NewValues) -> Result<(), Error> {
        self.warm = false;
        let done = match &mut self.reduction {
            Some(red) => red
                .problem
                .set_values(values)
                .and_then(|()| red.reduce(&mut self.local)),
            None => self.local.set_values(values),
        };
        self.broken = done.as_ref().err().cloned();
        self.newton.take_values(&self.local);
        done
    }

    /// Starts the next solve from impulses `r` (velocities follow from them).
    pub(crate) fn warm_start(&mut self, r: &[f64]) {
        self.r.copy_from_slice(r);
        self.warm = true;
    }

    /// Newton from the warm start or from zero; `Solved` when the island's measure meets
    /// the tolerance, otherwise the status Newton stopped with (the best iterate is kept).
    pub(crate) fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        if let Some(e) = &self.broken {
            return Err(e.clone());
        }
        if !self.warm {
            self.r.fill(0.0);
        }
        self.warm = false;
        let deadline =
            t0.checked_add(Duration::try_from_secs_f64(self.time_limit).unwrap_or(Duration::MAX));
        let Self {
            local,
            reduction,
            measure,
            newton,
            r,
            v,
            ..
        } = self;
        let (local, reduction) = (&*local, &*reduction);
        let mut judge = |r: &[f64]| match reduction {
            Some(red) => {
                red.velocities(r, v);
                global_error_with(&red.problem, r, v, &[], measure)
            }
            None => local_error_with(local, r, measure),
        };
        let out = newton.solve_measured(
            local,
            r,
            self.tolerance,
            self.max_steps,
            deadline,
            &mut judge,
        )?;
        if let Some(red) = &self.reduction {
            red.velocities(&self.r, &mut self.v);
        }
        let status = if out.converged() {
            Status::Solved
        } else if deadline.is_some_and(|d| Instant::now() >= d) {
            Status::TimeLimit
        } else {
            Status::Stalled
        };
        let seconds = t0.elapsed().as_secs_f64();
        self.stats = Stats {
            status,
            iterations: out.iterations,
            error: out.error,
            newton_iterations: out.iterations,
            newton_factorizations: out.factorizations,
            newton_phases: 1,
            solve_seconds: seconds,
            ..self.stats
        };
        self.last_trace = self.trace.then_some(TracePoint {
            iteration: out.iterations,
            seconds,
            error: out.error,
            primal_residual: f64::NAN,
            dual_residual: f64::NAN,
            rho: f64::NAN,
            anderson_accepted: 0,
            anderson_rejected: 0,
            phase: Phase::Newton,
        });
        Ok(status)
    }

    /// The last iterate.
    pub(crate) fn solution(&self) -> Solution {
        let mut u = self.local.q.clone();
        self.local.w.mul_vec(1.0, &self.r, 1.0, &mut u);
        if let Some(red) = &self.reduction {
            // The global form's u from its own data, as its measure computes it.
            u.copy_from_slice(&red.problem.w);
            red.problem.h.mul_t_vec(1.0, &self.v, 1.0, &mut u);
        }
        Solution {
            r: self.r.clone(),
            u,
            v: self.v.clone(),
            lambda: Vec::new(),
        }
    }

    /// Statistics of the last solve.
    pub(crate) fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The trace of the last solve: its one Newton phase, when tracing.
    pub(crate) fn trace(&self) -> &[TracePoint] {
        self.last_trace.as_slice()
    }
}
