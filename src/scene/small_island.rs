//! Small contact islands solved directly: semismooth Newton on the island's Delassus form
//! `u = W r + q` (docs/algorithms.md §12). A global island's `W = H^T M^-1 H` and
//! `q = H^T M^-1 f + w` are formed densely from a Cholesky factor of M, and every iterate
//! is judged by the island's own global measure at `v = M^-1 (H r + f)`. When Newton does
//! not reach the tolerance, the island's coupled solver (ADMM and Newton) takes over.
//!
//! A scene may hold thousands of such islands (a box on the ground: 6 velocities, 4
//! contacts), so an island keeps only its dense data, read straight from the whole
//! problem, in one array; the Newton solver, its problem and the measure's vectors live in
//! a [`SmallWork`] that every island of one size shares (one per thread).

use crate::certificate::local_run_off;
use crate::csc::CscMatrix;
use crate::linsys::{BlockDiagonal, DENSE_MAX};
use crate::measure::{local_error_with, Floors, GlobalTerms, MeasureWork, Scales};
use crate::newton::{LocalNewton, NewtonOutcome};
use crate::problem::{GlobalProblem, LocalProblem, Problem};
use crate::scene::islands::{contact_rows, Part};
use crate::types::Solution;
use crate::types::{Error, Status};
use crate::types::{Phase, Stats, TracePoint};
use std::time::{Duration, Instant};

/// Where each piece of an island's data sits in its one array (`n` velocities, `m = 3 nc`
/// contact rows; a local island has `n = 0`).
#[derive(Debug, Clone, Copy)]
struct DataLayout {
    n: usize,
    m: usize,
}

impl DataLayout {
    fn len(&self) -> usize {
        self.ranges()[4].end
    }
    /// Column-major `W` (`m x m`), then `q`, `mu`, and for a global island `M^-1 H`
    /// (`n x m`) and `M^-1 f`. M, H, f and w stay in the whole problem.
    fn ranges(&self) -> [std::ops::Range<usize>; 5] {
        let (n, m) = (self.n, self.m);
        let sizes = [m * m, m, m / 3, n * m, n];
        let mut at = 0;
        sizes.map(|len| {
            at += len;
            at - len..at
        })
    }
}

/// An island's data, borrowed out of its array, with the whole problem it came from.
struct Data<'a> {
    w: &'a [f64],
    q: &'a [f64],
    mu: &'a [f64],
    minv_h: &'a [f64],
    minv_f: &'a [f64],
    at: Site<'a>,
}

/// Where an island sits in the whole problem: its velocities and contacts, and the
/// positions of [`crate::scene::islands::positions`].
#[derive(Clone, Copy)]
pub(crate) struct Site<'a> {
    pub whole: &'a Problem,
    pub part: &'a Part,
    pub row_of: &'a [usize],
}

impl<'a> Data<'a> {
    fn new(layout: DataLayout, data: &'a [f64], at: Site<'a>) -> Self {
        let [w, q, mu, minv_h, minv_f] = layout.ranges().map(|r| &data[r]);
        Self {
            w,
            q,
            mu,
            minv_h,
            minv_f,
            at,
        }
    }

    /// `v = M^-1 (H r + f)`.
    fn velocities(&self, r: &[f64], v: &mut [f64]) {
        let n = v.len();
        v.copy_from_slice(self.minv_f);
        for (c, &rc) in r.iter().enumerate() {
            if rc != 0.0 {
                for (vi, x) in v.iter_mut().zip(&self.minv_h[c * n..(c + 1) * n]) {
                    *vi += rc * x;
                }
            }
        }
    }

    /// The global island's M, H, f and w, from the whole problem.
    fn global(&self) -> &'a GlobalProblem {
        match self.at.whole {
            Problem::Global(g) => g,
            Problem::Local(_) => unreachable!("a local island has no global data"),
        }
    }

    /// `mv = M v`, `hr = H r` on the island's velocities.
    fn products(&self, r: &[f64], v: &[f64], mv: &mut [f64], hr: &mut [f64]) {
        let (g, part, row_of) = (self.global(), self.at.part, self.at.row_of);
        mv.fill(0.0);
        for (&j, &vj) in part.velocities.iter().zip(v) {
            for (i, x) in g.m.col(j) {
                mv[row_of[i]] += x * vj;
            }
        }
        hr.fill(0.0);
        for (c, &rc) in contact_rows(&part.contacts).zip(r) {
            for (i, x) in g.h.col(c) {
                hr[row_of[i]] += x * rc;
            }
        }
    }

    /// Row `k` of `u = H^T v + w` (global island).
    fn global_u_row(&self, k: usize, v: &[f64]) -> f64 {
        let (g, row_of) = (self.global(), self.at.row_of);
        let c = 3 * self.at.part.contacts[k / 3] + k % 3;
        g.w[c] + g.h.col(c).map(|(i, x)| x * v[row_of[i]]).sum::<f64>()
    }

    /// Row `c` of `u = W r + q` (local island).
    fn local_u_row(&self, c: usize, r: &[f64]) -> f64 {
        let m = r.len();
        let mut u = 0.0;
        for (j, &rj) in r.iter().enumerate() {
            if rj != 0.0 {
                u += self.w[c + j * m] * rj;
            }
        }
        u + self.q[c]
    }
}

/// The columns `cols` of `a` into the column-major `out` of `rows` rows, rows renumbered
/// by `row_of`.
fn scatter_columns(
    a: &CscMatrix,
    cols: impl Iterator<Item = usize>,
    row_of: &[usize],
    rows: usize,
    out: &mut [f64],
) {
    out.fill(0.0);
    for (k, j) in cols.enumerate() {
        let col = &mut out[k * rows..(k + 1) * rows];
        for (i, x) in a.col(j) {
            col[row_of[i]] = x;
        }
    }
}

/// The Newton solver and the problem it runs on for islands of one size: each island's
/// values are copied in before its solve.
struct SizedNewton {
    local: LocalProblem,
    newton: LocalNewton,
    measure: MeasureWork,
}

/// Work space of the small islands one thread solves.
#[derive(Default)]
pub(crate) struct SmallWork {
    /// By number of contacts.
    sized: Vec<Option<Box<SizedNewton>>>,
    /// The island's share of f, and the measure's products.
    f: Vec<f64>,
    mv: Vec<f64>,
    hr: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
    /// A global island's M (one dense block) with its factor, and its dense H, while its
    /// Delassus form is formed.
    mass: BlockDiagonal,
    h: Vec<f64>,
}

impl SmallWork {
    /// Sizes the measure's vectors for an island of `n` velocities and `m` contact rows,
    /// and gathers a global island's share of f.
    fn size_for(&mut self, data: &Data, global: bool, n: usize, m: usize) {
        for x in [&mut self.f, &mut self.mv, &mut self.hr, &mut self.v] {
            x.resize(n, 0.0);
        }
        self.u.resize(m, 0.0);
        if global {
            for (fk, &i) in self.f.iter_mut().zip(&data.at.part.velocities) {
                *fk = data.global().f[i];
            }
        }
    }

    /// The solver for islands of `nc` contacts out of `sized`, built on first use (on a
    /// dense pattern, so that any island of that size fits it).
    fn sized(
        sized: &mut Vec<Option<Box<SizedNewton>>>,
        nc: usize,
    ) -> Result<&mut Box<SizedNewton>, Error> {
        if sized.len() <= nc {
            sized.resize_with(nc + 1, || None);
        }
        if sized[nc].is_none() {
            let local = LocalProblem::dense(nc)?;
            let newton = LocalNewton::new(&local)?;
            let measure = MeasureWork::local(&local);
            sized[nc] = Some(Box::new(SizedNewton {
                local,
                newton,
                measure,
            }));
        }
        Ok(sized[nc].as_mut().expect("built above"))
    }
}

/// One small island: its dense data and its iterate.
pub(crate) struct SmallIsland {
    layout: DataLayout,
    global: bool,
    data: Vec<f64>,
    /// The iterate: impulses, and the velocities they give (global form).
    r: Vec<f64>,
    v: Vec<f64>,
    warm: bool,
    /// The error of the last values taken, when they cannot be solved (M not positive
    /// definite); solves fail with it until an update succeeds.
    broken: Option<Error>,
    floors: Floors,
    tolerance: f64,
    time_limit: f64,
    max_steps: usize,
    trace: bool,
    stats: Stats,
    last_trace: Option<TracePoint>,
}

impl SmallIsland {
    /// The island `at.part` when the direct path takes it: some friction (an
    /// all-frictionless island is a QP, which the coupled solver solves with one row per
    /// contact), no joints, a symmetric M, and small enough for dense factors. `None`
    /// otherwise.
    pub(crate) fn new(at: Site, trace: bool, work: &mut SmallWork) -> Result<Option<Self>, Error> {
        let t0 = Instant::now();
        let (whole, part) = (at.whole, at.part);
        let (nc, n) = (part.contacts.len(), part.velocities.len());
        let frictional = part.contacts.iter().any(|&c| whole.mu()[c] > 0.0);
        let small = 3 * nc <= DENSE_MAX && n <= DENSE_MAX;
        if !small || !frictional || !part.joints.is_empty() {
            return Ok(None);
        }
        let global = matches!(whole, Problem::Global(_));
        let layout = DataLayout {
            n: if global { n } else { 0 },
            m: 3 * nc,
        };
        let mut island = Self {
            layout,
            global,
            data: vec![0.0; layout.len()],
            r: vec![0.0; layout.m],
            v: vec![0.0; layout.n],
            warm: false,
            broken: None,
            floors: Floors::default(),
            tolerance: 0.0,
            time_limit: f64::INFINITY,
            max_steps: 0,
            trace,
            stats: Stats {
                rows: layout.m,
                ..Stats::default()
            },
            last_trace: None,
        };
        if !island.load(at, work, true)? {
            return Ok(None);
        }
        island.stats.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(Some(island))
    }

    /// Forms the island's Delassus form from the whole problem's values: a local island's
    /// block of W and q; a global island's `W = H^T M^-1 H`, `q = H^T M^-1 f + w`, `M^-1 H`,
    /// `M^-1 f` from a Cholesky factor of M's symmetric part (positive definite exactly
    /// when M is, as the coupled solver checks it). With `need_symmetric`, false (nothing
    /// formed) when M is not symmetric; otherwise an M that an update made asymmetric gets
    /// a wrong W, which the island's measure (on M itself) rejects, and the coupled solver
    /// takes over.
    fn load(
        &mut self,
        at: Site,
        work: &mut SmallWork,
        need_symmetric: bool,
    ) -> Result<bool, Error> {
        let DataLayout { n, m } = self.layout;
        let [w, q, mu, minv_h, minv_f] = self.layout.ranges();
        let (part, row_of) = (at.part, at.row_of);
        let d = &mut self.data;
        for (dst, c) in d[mu].iter_mut().zip(&part.contacts) {
            *dst = at.whole.mu()[*c];
        }
        let g = match at.whole {
            Problem::Local(l) => {
                scatter_columns(&l.w, contact_rows(&part.contacts), row_of, m, &mut d[w]);
                for (dst, i) in d[q].iter_mut().zip(contact_rows(&part.contacts)) {
                    *dst = l.q[i];
                }
                return Ok(true);
            }
            Problem::Global(g) => g,
        };
        let mass = &mut work.mass;
        mass.reshape_one(n);
        work.h.resize(n * m, 0.0);
        let velocities = part.velocities.iter().copied();
        scatter_columns(&g.m, velocities, row_of, n, mass.matrix_mut());
        if need_symmetric && !mass.is_symmetric() {
            return Ok(false);
        }
        mass.symmetrize();
        mass.cholesky("M")?;
        scatter_columns(&g.h, contact_rows(&part.contacts), row_of, n, &mut work.h);
        d[minv_h.clone()].copy_from_slice(&work.h);
        for col in d[minv_h.clone()].chunks_exact_mut(n.max(1)) {
            mass.solve_in_place(col);
        }
        for (dst, &i) in d[minv_f.clone()].iter_mut().zip(&part.velocities) {
            *dst = g.f[i];
        }
        mass.solve_in_place(&mut d[minv_f.clone()]);
        // W = H^T (M^-1 H), q = H^T (M^-1 f) + w.
        for j in 0..m {
            for i in 0..m {
                let (hi, mj) = (&work.h[i * n..][..n], &d[minv_h.start + j * n..][..n]);
                d[w.start + i + j * m] = hi.iter().zip(mj).map(|(a, b)| a * b).sum();
            }
        }
        for (i, c) in contact_rows(&part.contacts).enumerate() {
            let (hi, mf) = (&work.h[i * n..][..n], &d[minv_f.clone()]);
            d[q.start + i] = g.w[c] + hi.iter().zip(mf).map(|(a, b)| a * b).sum::<f64>();
        }
        Ok(true)
    }

    /// Takes the whole problem's current values (after an update on the same pattern). The
    /// next solve starts cold unless a warm start follows.
    pub(crate) fn take_values(&mut self, at: Site, work: &mut SmallWork) -> Result<(), Error> {
        self.warm = false;
        let done = self.load(at, work, false).map(|_| ());
        self.broken = done.as_ref().err().cloned();
        done
    }

    /// Records the Newton phase as a trace point, or not.
    pub(crate) fn set_trace(&mut self, trace: bool) {
        self.trace = trace;
    }

    /// Sets the tolerance, the time limit and the Newton steps of the next solves.
    pub(crate) fn set_limits(&mut self, tolerance: f64, time_limit: f64, max_steps: usize) {
        self.tolerance = tolerance;
        self.time_limit = time_limit;
        self.max_steps = max_steps;
    }

    /// Floors of the error measure (the island's share of a scene's measure).
    pub(crate) fn set_measure_floors(&mut self, floors: Floors) {
        self.floors = floors;
    }

    /// Starts the next solve from impulses `r` (velocities follow from them).
    pub(crate) fn warm_start(&mut self, r: &[f64]) {
        self.r.copy_from_slice(r);
        self.warm = true;
    }

    /// Newton from the warm start or from zero; `Solved` when the island's measure meets
    /// the tolerance, otherwise the status Newton stopped with (the best iterate is kept).
    pub(crate) fn solve(&mut self, at: Site, work: &mut SmallWork) -> Result<Status, Error> {
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
        let DataLayout { n, m } = self.layout;
        let data = Data::new(self.layout, &self.data, at);
        work.size_for(&data, self.global, n, m);
        let SmallWork {
            sized,
            f,
            mv,
            hr,
            u,
            v,
            ..
        } = work;
        let f: &[f64] = f;
        let s = SmallWork::sized(sized, m / 3)?;
        s.local.w.set_values("W", data.w)?;
        s.local.q.copy_from_slice(data.q);
        s.local.mu.copy_from_slice(data.mu);
        s.newton.take_values(&s.local);
        let SizedNewton {
            local,
            newton,
            measure,
        } = &mut **s;
        let local: &LocalProblem = local;
        let (floors, global) = (self.floors, self.global);
        measure.floors = floors;
        // A global island is judged by its own global measure at v = M^-1 (H r + f).
        let mut judge = |r: &[f64]| {
            if !global {
                return local_error_with(local, r, measure);
            }
            if !r.iter().all(|x| x.is_finite()) {
                return f64::INFINITY;
            }
            data.velocities(r, v);
            data.products(r, v, mv, hr);
            for (k, uk) in u.iter_mut().enumerate() {
                *uk = data.global_u_row(k, v);
            }
            let terms = GlobalTerms {
                f,
                mv,
                hr,
                u,
                r,
                mu: data.mu,
            };
            terms.error(floors, &mut Scales::default())
        };
        let out = newton.solve_measured(
            local,
            &mut self.r,
            self.tolerance,
            self.max_steps,
            deadline,
            &mut judge,
        )?;
        if self.global {
            data.velocities(&self.r, &mut self.v);
        }
        let status = if out.converged() && local_run_off(local, &self.r) {
            // Met only because the impulses ran off (docs/algorithms.md §13).
            Status::Infeasible
        } else {
            out.status_when_final(out.converged(), deadline)
        };
        Ok(self.record(&out, status, t0))
    }

    /// Records a solve's statistics and trace point.
    fn record(&mut self, out: &NewtonOutcome, status: Status, t0: Instant) -> Status {
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
        status
    }

    /// Row `c` of the last iterate's `u` (the global form's from its own data, as its
    /// measure computes it).
    fn u_row(&self, data: &Data, c: usize) -> f64 {
        match self.global {
            true => data.global_u_row(c, &self.v),
            false => data.local_u_row(c, &self.r),
        }
    }

    /// The last iterate.
    pub(crate) fn solution(&self, at: Site) -> Solution {
        let data = Data::new(self.layout, &self.data, at);
        Solution {
            r: self.r.clone(),
            u: (0..self.layout.m).map(|c| self.u_row(&data, c)).collect(),
            v: self.v.clone(),
            lambda: Vec::new(),
        }
    }

    /// Writes the last iterate into a whole problem's solution at the island's places
    /// (without building the island's own).
    pub(crate) fn write_solution(&self, at: Site, out: &mut Solution) {
        let data = Data::new(self.layout, &self.data, at);
        for (k, i) in contact_rows(&at.part.contacts).enumerate() {
            out.r[i] = self.r[k];
            out.u[i] = self.u_row(&data, k);
        }
        for (&i, &v) in at.part.velocities.iter().zip(&self.v) {
            out.v[i] = v;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csc::CscMatrix;

    /// The Delassus form of the fuzzed one-velocity problem with no solution
    /// (`tests/hybrid.rs`): `W = h h^T / m`, `q = w + h f / m`.
    fn no_solution() -> LocalProblem {
        let (m, h, f, w) = (
            10.666666666666666,
            [1.0, -2.6666666666666665, -1.0],
            -8.0,
            -8.0,
        );
        let dense: Vec<f64> = (0..9).map(|k| h[k % 3] * h[k / 3] / m).collect();
        LocalProblem::new(
            CscMatrix::from_dense("W", 3, 3, &dense).unwrap(),
            h.iter().map(|hi| w + hi * f / m).collect(),
            vec![1.3],
        )
        .unwrap()
    }

    #[test]
    fn run_off_impulses_certify_and_a_load_does_not() {
        let p = no_solution();
        // A direction of the cone with h . y = 0 (y_N - 2.67 y_T1 - y_T2 = 0).
        let y = [0.68, -0.019, 0.68 + 2.6666666666666665 * 0.019];
        let r: Vec<f64> = y.iter().map(|x| 1e10 * x).collect();
        assert!(local_run_off(&p, &r));
        // The same size along the normal pushes the body: no certificate.
        assert!(!local_run_off(&p, &[1e10, 0.0, 0.0]));
        assert!(!local_run_off(&p, &[0.0; 3]));
    }
}
