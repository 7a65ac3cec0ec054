//! Global form: `x = v`, `y = u~`, `A = H^T`, `c = -w - Phi(s)`, g = indicator of `K*`;
//! bounded joint rows add rows to the constraint space after the contacts'
//! ([`BoundedRows`]).
//!
//! v-update: `(M + rho H H^T) v = f + rho H (u~ + c - zeta)`; with joints the
//! quasi-definite system `[[M + rho H H^T, G], [G^T, -delta I]] [v; -lambda] = [.; -b]`
//! (delta tiny, corrected by one step of iterative refinement). One splitting for every
//! [`VelocitySystem`]: the whole problem on one process (factorized or matrix-free), or a
//! process's part of a problem shared over processes (`distributed/`), whose vectors over
//! the constraint space are then its own contacts' rows and its velocities its own bodies'.

use super::form::{
    active_rows, check_vector, count_rows, de_saxce_shift, initial_shift_of, prox_input,
    rows_missing, ContactForm,
};
use crate::admm::{EngineState, Splitting};
use crate::bounded_rows::BoundedRows;
use crate::certificate::run_off;
use crate::cone::{get3, project_dual_cone, set3};
use crate::linsys::velocity::{
    problem_system, Accuracy, ContactData, ProblemSystem, VelocitySystem,
};
use crate::measure::Floors;
use crate::newton::{GlobalNewton, NewtonOutcome};
use crate::problem::{GlobalProblem, NewValues, Problem, ProblemRef};
use crate::settings::LinearSolver;
use crate::tuning::{NEWTON, NEWTON_MIN_STALL, NEWTON_STALL_ITERATIONS, SCREEN_RATIO};
use crate::types::Error;
use crate::types::Solution;
use std::time::Instant;

/// The global contact problem as an ADMM splitting over the v-update system `S`.
pub(crate) struct GlobalSplitting<S: VelocitySystem> {
    p: S::Data,
    system: S,
    /// Current velocity (and `-lambda` after it, when there are joints).
    sol: Vec<f64>,
    c: Vec<f64>,
    phi: Vec<f64>,
    /// The contact velocity `u` of the last warm start.
    u: Vec<f64>,
    work_m: Vec<f64>,
    /// Impulses of the current iterate, for the error measure.
    r: Vec<f64>,
    /// 1 for the rows of the contact space in the system's pattern, 0 for the tangential
    /// rows of frictionless contacts ([`super::form::active_rows`]).
    in_pattern: Vec<f64>,
    /// The rows the system holds now: those of `in_pattern` less the screened contacts'.
    active: Vec<f64>,
    /// Contacts left out of the v-update system for this solve ([`GlobalSplitting::screen`]).
    screened: Vec<bool>,
    /// `||mu||` and `||H||_F` of the whole problem, which the initial shift is made of.
    norm_mu: f64,
    h_fro: f64,
    /// The last error measured, which sets how exactly an inexact backend solves
    /// (infinite until a first measure; see [`crate::linsys::velocity::inexact_stop`]).
    last_error: f64,
    /// The running solve's wall-clock limit, which also stops a conjugate-gradient solve.
    deadline: Option<Instant>,
    /// The bounded joint rows, the constraint space's rows after the contacts'.
    bounded: BoundedRows,
    /// The current penalty, which the bounded rows' proximal step reads.
    rho: f64,
    /// New values or screened rows not yet in the v-update system: the next `set_rho`
    /// takes them (through the assembly maps, no sorting), so that a solve its warm start
    /// already ends (an engine's resting scene), or that a first Newton phase ends,
    /// assembles and factorizes nothing.
    stale: bool,
    /// The Newton phase of a problem on one process, built on first use and kept across
    /// updates.
    newton: Option<GlobalNewton>,
}

/// The whole problem on one process, factorized or matrix-free.
pub(crate) type ProblemSplitting = GlobalSplitting<Box<dyn ProblemSystem>>;

impl<S: VelocitySystem> GlobalSplitting<S> {
    /// The splitting over `system`, built from `p`, with `sol` of length `dim`, the rows
    /// `in_pattern` marks, and the whole problem's `||mu||` and `||H||_F`.
    pub(crate) fn with_system(
        p: S::Data,
        system: S,
        dim: usize,
        in_pattern: Vec<f64>,
        [norm_mu, h_fro]: [f64; 2],
    ) -> Self {
        let m = in_pattern.len();
        let nc = p.mu().len();
        let bounded = p.bounded();
        let mut split = Self {
            system,
            sol: vec![0.0; dim],
            c: vec![0.0; m],
            phi: vec![0.0; m],
            u: vec![0.0; m],
            work_m: vec![0.0; m],
            r: vec![0.0; m],
            active: in_pattern.clone(),
            screened: vec![false; nc],
            in_pattern,
            norm_mu,
            h_fro,
            last_error: f64::INFINITY,
            deadline: None,
            bounded,
            rho: 1.0,
            stale: false,
            newton: None,
            p,
        };
        split.reset_shift();
        split
    }

    /// The system and what it was built from.
    #[cfg(feature = "mpi")]
    pub(crate) fn system(&self) -> (&S, &S::Data) {
        (&self.system, &self.p)
    }

    /// The system, what it was built from and the current iterate, for the calls that
    /// need all three.
    #[cfg(feature = "mpi")]
    pub(crate) fn parts_mut(&mut self) -> (&mut S, &S::Data, &[f64]) {
        (&mut self.system, &self.p, &self.sol)
    }

    /// The current velocities (and `-lambda` after them with joints).
    #[cfg(feature = "mpi")]
    pub(crate) fn velocities(&self) -> &[f64] {
        &self.sol
    }

    /// Restarts the De Saxce shift from its initial guess (docs/algorithms.md §5), and the
    /// inexact backend's accuracy with it (a new solve).
    fn reset_shift(&mut self) {
        initial_shift_of(self.p.mu(), self.norm_mu, self.h_fro, &mut self.phi);
        self.refresh_c();
        self.last_error = f64::INFINITY;
    }

    fn refresh_c(&mut self) {
        for ((c, w), s) in self.c.iter_mut().zip(self.p.w()).zip(&self.phi) {
            *c = -w - s;
        }
        let m = self.p.w().len();
        for (c, b) in self.c[m..].iter_mut().zip(&self.bounded.bias) {
            *c = -b;
        }
    }

    /// A start from nothing: no impulse, no velocity, the initial shift, no contact
    /// screened.
    pub(crate) fn start_cold(&mut self, state: &mut EngineState) {
        state.y.fill(0.0);
        state.zeta.fill(0.0);
        // No velocity carried over from a previous solve either (the Newton phase alone
        // starts from it).
        self.sol.fill(0.0);
        self.reset_shift();
        self.unscreen_all();
    }

    /// A start from impulses `r` and, when given, velocities `v` (checked by the caller):
    /// `zeta = -r / rho`, and with `v` the shift and `u~ = P_K*(H^T v + w + Phi(u))` taken
    /// from the same `u` (kept in `self.u`).
    pub(crate) fn start_warm(&mut self, r: &[f64], v: Option<&[f64]>, state: &mut EngineState) {
        // r = -rho zeta at a solution; the bounded joint rows start from no impulse.
        for (z, ri) in state.zeta.iter_mut().zip(r) {
            *z = -ri / state.rho;
        }
        state.zeta[r.len()..].fill(0.0);
        state.y.fill(0.0);
        let Some(v) = v else {
            self.reset_shift();
            self.unscreen_all();
            return;
        };
        // The velocity is the iterate a Newton phase would start from.
        self.sol[..v.len()].copy_from_slice(v);
        // One product for both: u = H^T v + w, and H^T v for the projection.
        self.system.h_t_mul(&self.p, v, &mut self.work_m);
        for ((u, a), w) in self.u.iter_mut().zip(&self.work_m).zip(self.p.w()) {
            *u = a + w;
        }
        de_saxce_shift(&self.u, self.p.mu(), &mut self.phi);
        self.refresh_c();
        for (i, &mu) in self.p.mu().iter().enumerate() {
            let (a, c) = (get3(&self.work_m, i), get3(&self.c, i));
            set3(
                &mut state.y,
                i,
                project_dual_cone([a[0] - c[0], a[1] - c[1], a[2] - c[2]], mu),
            );
        }
    }

    /// Leaves out of the v-update system the contacts a warm start predicts open: no
    /// impulse, and a normal velocity `u` (at the warm velocity) above [`SCREEN_RATIO`]
    /// times the largest. Their impulse stays zero, which Coulomb's law accepts as long as
    /// their normal velocity stays non-negative; `readmit`, at each of the loop's own
    /// evaluations, brings back any whose velocity turned negative, and the error always
    /// measures the whole problem (docs/algorithms.md §15).
    fn screen(&mut self, r: &[f64]) {
        let nc = self.screened.len();
        let largest = (0..nc).map(|i| self.u[3 * i].abs()).fold(0.0, f64::max);
        let threshold = SCREEN_RATIO * largest;
        for i in 0..nc {
            let open = r[3 * i..3 * i + 3].iter().all(|&x| x == 0.0) && self.u[3 * i] > threshold;
            self.set_screened(i, open);
        }
    }

    /// Screens contact `i` or brings it back; the system takes the change at the next
    /// `set_rho` (as it takes new values).
    fn set_screened(&mut self, i: usize, screened: bool) {
        if self.screened[i] != screened {
            self.screened[i] = screened;
            for k in 3 * i..3 * i + 3 {
                self.active[k] = if screened { 0.0 } else { self.in_pattern[k] };
            }
            self.stale = true;
        }
    }

    /// Brings every screened contact back.
    fn unscreen_all(&mut self) {
        for i in 0..self.screened.len() {
            self.set_screened(i, false);
        }
    }
}

impl<S: VelocitySystem> Splitting for GlobalSplitting<S> {
    fn dim(&self) -> usize {
        self.c.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        let changed = std::mem::take(&mut self.stale);
        self.rho = rho;
        self.system.set_rho(&self.p, rho, &self.active, changed)
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        for i in 0..self.work_m.len() {
            self.work_m[i] = self.active[i] * rho * (y[i] + self.c[i] - zeta[i]);
        }
        let accuracy = Accuracy {
            last_error: self.last_error,
            deadline: self.deadline,
        };
        self.system
            .x_step(&self.p, &self.work_m, &mut self.sol, ax, accuracy);
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        for (i, &mu) in self.p.mu().iter().enumerate() {
            let input = prox_input(ax, &self.c, zeta, i);
            // A screened contact is not projected: the dual update then leaves zeta, the
            // impulse, at zero.
            let out = match self.screened[i] {
                true => input,
                false => project_dual_cone(input, mu),
            };
            set3(y, i, out);
        }
        let m = self.p.w().len();
        let rho = self.rho;
        for q in 0..self.bounded.len() {
            let a = ax[m + q] - self.c[m + q] + zeta[m + q];
            // The contacts' impulses just projected, `r = -rho zeta+ = rho (y - input)`.
            let normal = |i: usize| rho * (y[3 * i] - prox_input(ax, &self.c, zeta, i)[0]);
            let bounds = self.bounded.bounds(q, normal);
            y[m + q] = self.bounded.prox(q, a, rho, bounds);
        }
    }

    fn c(&self) -> &[f64] {
        &self.c
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        for i in 0..d.len() {
            self.work_m[i] = self.active[i] * d[i];
        }
        self.system.h_norm(&self.p, &self.work_m)
    }

    fn update_s(&mut self, ax: &[f64], _y: &[f64]) {
        // u = H^T v + w
        for ((u, a), w) in self.work_m.iter_mut().zip(ax).zip(self.p.w()) {
            *u = a + w;
        }
        de_saxce_shift(&self.work_m, self.p.mu(), &mut self.phi);
        self.refresh_c();
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

    fn system_changed(&self) -> bool {
        self.stale
    }

    fn readmit(&mut self, ax: &[f64]) {
        for i in 0..self.screened.len() {
            if self.screened[i] && ax[3 * i] + self.p.w()[3 * i] < 0.0 {
                self.set_screened(i, false);
            }
        }
    }

    fn error(&mut self, _ax: &[f64], _y: &[f64], zeta: &[f64], rho: f64) -> f64 {
        for (r, z) in self.r.iter_mut().zip(zeta) {
            *r = -rho * z;
        }
        let error = self.system.measure(&self.p, &self.r, &self.sol);
        self.last_error = error;
        error
    }

    fn sum_across(&self, partial: &mut [f64]) {
        self.system.sum_across(partial);
    }
}

impl ProblemSplitting {
    /// Analyses and factorizes `M` (to check it is positive definite) and prepares the
    /// v-update system.
    pub(crate) fn new(p: GlobalProblem, backend: LinearSolver) -> Result<Self, Error> {
        let mut active = active_rows(&p.mu);
        active.resize(p.w.len() + p.bounded_rows().len(), 1.0);
        let system = problem_system(&p, &active, backend)?;
        // The joint rows the system leaves to the splitting follow the contacts' rows.
        let bounded = system.splitting_rows(&p);
        active.resize(p.w.len() + bounded.len(), 1.0);
        let dim = p.n() + p.n_joints();
        let norms = shift_norms(&p);
        let mut split = Self::with_system(p, system, dim, active, norms);
        split.bounded = bounded;
        Ok(split)
    }

    /// Makes the values now in `self.p` the problem's (same patterns): refactorizes M,
    /// restarts the shift and rescales the Newton phase; the v-update system takes them at
    /// the next [`Splitting::set_rho`] (see `stale`). No sorting, no allocation. M is
    /// refactorized on its own (its symmetric part, much sparser than the system) because
    /// the system can be positive definite while M is not. When M stopped being symmetric,
    /// the Cholesky system gives way to a new LU one.
    fn take_values(&mut self) -> Result<(), Error> {
        let asymmetric = self.system.own().lost_symmetry(&self.p);
        if asymmetric || rows_missing(&self.in_pattern, &self.p.mu) {
            let floors = self.system.own().floors();
            *self = Self::new(self.p.clone(), self.system.backend())?;
            self.set_measure_floors(floors);
            return Ok(());
        }
        self.system.own().take_values(&self.p)?;
        self.stale = true;
        self.bounded = self.system.splitting_rows(&self.p);
        [self.norm_mu, self.h_fro] = shift_norms(&self.p);
        self.reset_shift();
        if let Some(newton) = &mut self.newton {
            newton.take_values(&self.p);
        }
        Ok(())
    }
}

/// `||mu||` and `||H||_F` of a problem, which the initial shift is made of.
fn shift_norms(p: &GlobalProblem) -> [f64; 2] {
    let norm_mu = p.mu.iter().map(|m| m * m).sum::<f64>().sqrt();
    [norm_mu, p.h.norm_fro()]
}

impl ProblemSplitting {
    /// Steps without progress a Newton phase may take, from what a step is predicted to
    /// cost in ADMM iterations: `NEWTON_STALL_ITERATIONS` worth of them, between
    /// `NEWTON_MIN_STALL` and `NEWTON.stall`. A step factorizes the system reduced to the
    /// velocities, whose pattern is that of `M + rho H H^T`: about the multiply-adds of its
    /// Cholesky factorization, against an iteration's two triangular solves and products
    /// with `H` (its factor's entries and `H`'s). `None` where that factor is not a sparse
    /// Cholesky (dense, LU, matrix-free): the window stays `NEWTON.stall`.
    fn newton_stall(&self) -> Option<usize> {
        let (flops, entries) = self.system.sparse_cholesky_cost()?;
        let step_iterations = flops / (entries + self.p.h.nnz()) as f64;
        let steps = (NEWTON_STALL_ITERATIONS / step_iterations).round();
        Some((steps as usize).clamp(NEWTON_MIN_STALL, NEWTON.stall))
    }
}

impl ContactForm for ProblemSplitting {
    fn update(&mut self, p: Problem) -> Result<(), Error> {
        let Problem::Global(p) = p else {
            return Err(Error::Unsupported(
                "update: the new problem is local, the solver was built for a global one".into(),
            ));
        };
        self.p.check_successor(&p)?;
        self.p = p;
        self.take_values()
    }

    fn update_values(&mut self, v: &NewValues) -> Result<(), Error> {
        self.p.set_values(v)?;
        self.take_values()
    }

    fn ready_for(&mut self, rho: f64) -> Result<(), Error> {
        // M + rho H H^T is positive definite once M is, which `take_values` checked, and
        // with joints the system [[M + rho H H^T, G], [G^T, -delta I]] is then
        // quasi-definite, which has an LDL^T in any order: the factorization can wait for
        // the solve. An LU (a non-symmetric M) can meet a singular matrix, and the update
        // reports that.
        match self.system.own().may_fail() {
            true => self.set_rho(rho),
            false => Ok(()),
        }
    }

    fn problem(&self) -> ProblemRef<'_> {
        ProblemRef::Global(&self.p)
    }

    fn cold_start(&mut self, state: &mut EngineState) {
        self.start_cold(state);
    }

    fn separating(&mut self, state: &mut EngineState) -> bool {
        // The free velocity M^-1 f costs one solve with the factor of M kept for the
        // update check, which is M itself when M is symmetric; joints would need the
        // constrained system.
        if self.p.joints.is_some() {
            return false;
        }
        // In work space: when the contacts do not all separate, the velocity of a warm
        // start (what a Newton phase starts from) must stay.
        let mut v = vec![0.0; self.p.n()];
        if !self.system.own().free_velocity(&self.p, &mut v) {
            return false;
        }
        self.system.contact_velocity(&self.p, &v, &mut self.work_m);
        if !(0..self.p.n_contacts()).all(|i| self.work_m[3 * i] >= 0.0) {
            return false;
        }
        let n = self.p.n();
        self.sol[..n].copy_from_slice(&v);
        state.zeta.fill(0.0);
        state.y.fill(0.0);
        true
    }

    fn warm_start(
        &mut self,
        r: &[f64],
        v: Option<&[f64]>,
        state: &mut EngineState,
    ) -> Result<(), Error> {
        if let Some(v) = v {
            check_vector("v", v, self.p.n())?;
        }
        self.start_warm(r, v, state);
        if v.is_some() {
            self.screen(r);
        }
        Ok(())
    }

    fn recover(&mut self, state: &EngineState) -> Result<(), Error> {
        let mut ax = vec![0.0; state.ax.len()];
        self.set_rho(state.rho)?;
        self.x_step(&state.y, &state.zeta, state.rho, &mut ax);
        if !self.sol.iter().all(|x| x.is_finite()) {
            // Even the kept iterate's velocity overflows (the data's own scale does): hand
            // back v = 0 and lambda = 0 rather than non-finite values; the error says the rest.
            self.sol.fill(0.0);
        }
        Ok(())
    }

    fn write_solution(&self, state: &EngineState, out: &mut Solution) {
        let (n, m) = (self.p.n(), self.p.w.len());
        out.r.clear();
        out.r.extend(state.zeta[..m].iter().map(|z| -state.rho * z));
        out.v.clear();
        out.v.extend_from_slice(&self.sol[..n]);
        out.u.clone_from(&self.p.w);
        self.p.h.mul_t_vec(1.0, &out.v, 1.0, &mut out.u);
        out.lambda.clear();
        out.lambda.extend(self.sol[n..].iter().map(|x| -x));
        for (q, &k) in self.bounded.rows.iter().enumerate() {
            let bounds = self.bounded.bounds(q, |i| out.r[3 * i]);
            out.lambda[k] = self
                .bounded
                .multiplier(state.zeta[m + q], state.rho, bounds);
        }
    }

    fn set_measure_floors(&mut self, floors: Floors) {
        self.system.own().set_floors(floors);
        if let Some(newton) = &mut self.newton {
            newton.set_measure_floors(floors);
        }
    }

    fn rows(&self) -> usize {
        count_rows(&self.in_pattern)
    }

    fn space(&self) -> usize {
        self.in_pattern.len()
    }

    fn blocked_contact(&self) -> Option<usize> {
        (0..self.p.n_contacts())
            .find(|&i| self.p.w[3 * i] < 0.0 && self.p.h.col(3 * i).all(|(_, x)| x == 0.0))
    }

    fn certifies_infeasibility(&self, state: &EngineState) -> bool {
        let mut s = Solution::default();
        self.write_solution(state, &mut s);
        run_off(&self.p.h, &s.r, &s.u, &self.p.w, &self.p.mu)
    }

    fn matrix_free(&self) -> bool {
        self.system.backend() == LinearSolver::Iterative
    }

    fn set_threads(&mut self, threads: usize) {
        self.system.set_threads(threads);
    }

    fn linear_iterations(&self) -> usize {
        self.system.linear_iterations()
    }

    fn refactorizations(&self) -> usize {
        self.system.refactorizations()
    }

    fn polish(
        &mut self,
        state: &mut EngineState,
        tol: f64,
        max_steps: usize,
        deadline: Option<Instant>,
    ) -> Result<NewtonOutcome, Error> {
        let mut s = Solution::default();
        self.write_solution(state, &mut s);
        let Solution {
            mut r,
            mut v,
            mut lambda,
            ..
        } = s;
        // The measure reads the bounded rows' multipliers after the impulses.
        let m = r.len();
        r.extend(self.bounded.rows.iter().map(|&k| lambda[k]));
        let start = self.system.measure(&self.p, &r, &self.sol);
        r.truncate(m);
        if self.newton.is_none() {
            let mut newton = GlobalNewton::new(&self.p)?;
            newton.set_measure_floors(self.system.own().floors());
            if let Some(steps) = self.newton_stall() {
                newton.set_stall(steps);
            }
            self.newton = Some(newton);
        }
        let newton = self.newton.as_mut().expect("built above");
        let out = newton.solve(
            &self.p,
            &mut v,
            &mut r,
            &mut lambda,
            tol,
            max_steps,
            deadline,
        )?;
        if out.error < start {
            self.warm_start(&r, Some(&v), state)?;
            let n = self.p.n();
            self.sol[..n].copy_from_slice(&v);
            for (s, l) in self.sol[n..].iter_mut().zip(&lambda) {
                *s = -l;
            }
            // A bounded row's multiplier is its dual variable's (`lambda = -rho zeta`).
            for (q, &k) in self.bounded.rows.iter().enumerate() {
                state.zeta[m + q] = -lambda[k] / state.rho;
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csc::CscMatrix;
    use nalgebra::{DMatrix, DVector};

    /// Three bodies' worth of velocities (n = 4), two contacts, one joint row with b != 0.
    fn joint_problem() -> GlobalProblem {
        #[rustfmt::skip]
        let m = CscMatrix::from_dense("M", 4, 4, &[
            2.0, 0.0, 0.0, 0.0,
            0.0, 3.0, 0.5, 0.0,
            0.0, 0.5, 4.0, 0.0,
            0.0, 0.0, 0.0, 5.0,
        ]).unwrap();
        #[rustfmt::skip]
        let h = CscMatrix::from_dense("H", 4, 6, &[
            1.0, 0.0, 0.1, 0.0, 0.0, 1.0,
            0.2, 1.0, 0.0, 0.0, 0.5, 0.0,
            0.0, 0.3, 1.0, 0.4, 0.0, 0.0,
            0.0, 0.0, 0.0, 1.0, 1.0, 0.7,
        ]).unwrap();
        let g = CscMatrix::from_dense("G", 4, 1, &[1.0, -1.0, 0.5, 0.0]).unwrap();
        GlobalProblem::new(
            m,
            h,
            vec![-1.0, 0.5, -2.0, 0.3],
            vec![0.1, 0.0, 0.2, -0.1, 0.3, 0.0],
            vec![0.3, 0.8],
        )
        .unwrap()
        .with_joints(g, vec![0.7])
        .unwrap()
    }

    /// A warm start screens the contacts with no impulse that it sees separating; a
    /// velocity that closes one brings it back and says the system changed.
    #[test]
    fn screening_follows_the_normal_velocity() {
        let mut h = Vec::new();
        for body in 0..2 {
            for (k, axis) in [2, 0, 1].into_iter().enumerate() {
                h.push((3 * body + axis, 3 * body + k, 1.0));
            }
        }
        let p = GlobalProblem::new(
            CscMatrix::identity(6),
            CscMatrix::from_triplets("H", 6, 6, &h).unwrap(),
            vec![0.0; 6],
            vec![0.0; 6],
            vec![0.5, 0.5],
        )
        .unwrap();
        let mut s = ProblemSplitting::new(p, LinearSolver::Direct).unwrap();
        let mut state = EngineState {
            y: vec![0.0; 6],
            zeta: vec![0.0; 6],
            ax: vec![0.0; 6],
            rho: 1.0,
        };
        // Contact 0 rises, contact 1 has an impulse: only contact 0 is screened.
        let r = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0];
        s.warm_start(&r, Some(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]), &mut state)
            .unwrap();
        assert_eq!(s.screened, [true, false]);
        assert_eq!(&s.active[..3], &[0.0; 3]);
        s.set_rho(1.0).unwrap();
        assert!(!s.system_changed());
        // Its normal velocity turns negative: back in the system.
        let ax = [-0.5, 0.0, 0.0, 0.0, 0.0, 0.0];
        s.readmit(&ax);
        assert_eq!(s.screened, [false, false]);
        assert!(s.system_changed());
        assert_eq!(s.active, s.in_pattern);
        // A cold start screens nothing.
        s.warm_start(&r, Some(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]), &mut state)
            .unwrap();
        s.cold_start(&mut state);
        assert_eq!(s.screened, [false, false]);
    }

    /// Unit-mass points on a `nx x ny x nz` grid (3 velocities each), a contact between each
    /// pair of neighbours (normal along the axis they share).
    fn grid_problem(nx: usize, ny: usize, nz: usize) -> GlobalProblem {
        let at = |x: usize, y: usize, z: usize| (z * ny + y) * nx + x;
        let mut pairs = Vec::new();
        for (x, y, z) in
            (0..nz).flat_map(|z| (0..ny).flat_map(move |y| (0..nx).map(move |x| (x, y, z))))
        {
            let me = at(x, y, z);
            for (axis, next) in [(0, x + 1 < nx), (1, y + 1 < ny), (2, z + 1 < nz)] {
                if next {
                    let other = at(
                        x + (axis == 0) as usize,
                        y + (axis == 1) as usize,
                        z + (axis == 2) as usize,
                    );
                    pairs.push((me, other, axis));
                }
            }
        }
        let mut h = Vec::new();
        for (c, &(a, b, axis)) in pairs.iter().enumerate() {
            for k in 0..3 {
                let d = (axis + k) % 3;
                h.push((3 * b + d, 3 * c + k, 1.0));
                h.push((3 * a + d, 3 * c + k, -1.0));
            }
        }
        let (n, m) = (3 * nx * ny * nz, 3 * pairs.len());
        GlobalProblem::new(
            CscMatrix::identity(n),
            CscMatrix::from_triplets("H", n, m, &h).unwrap(),
            vec![0.0; n],
            vec![0.0; m],
            vec![0.5; pairs.len()],
        )
        .unwrap()
    }

    /// A Newton phase may go the fewer steps without progress the more a step costs against
    /// an ADMM iteration: the whole default window along a chain, whose factor does not
    /// fill, and a shorter one, not below the floor, in a block of points whose factor's
    /// dense separators make a step cost far more than an iteration's solves. Without a
    /// sparse Cholesky (the matrix-free backend), the default.
    #[test]
    fn a_newton_phase_stalls_sooner_where_its_steps_cost_more() {
        let window =
            |p: GlobalProblem, backend| ProblemSplitting::new(p, backend).unwrap().newton_stall();
        assert_eq!(
            window(grid_problem(400, 1, 1), LinearSolver::Direct),
            Some(NEWTON.stall)
        );
        let block = window(grid_problem(12, 12, 12), LinearSolver::Direct).unwrap();
        assert!(
            (NEWTON_MIN_STALL..NEWTON.stall / 2).contains(&block),
            "{block}"
        );
        assert_eq!(
            window(grid_problem(12, 12, 12), LinearSolver::Iterative),
            None
        );
    }

    /// `v` of the x-step at `rho` by a dense solve of the unregularized joint system
    /// `[[M + rho H H^T, G], [G^T, 0]] [v; -lambda] = [f + rho H (y + c - zeta); -b]`.
    fn dense_x_step(s: &ProblemSplitting, y: &[f64], zeta: &[f64], rho: f64) -> Vec<f64> {
        let p = &s.p;
        let (n, m) = (p.n(), p.w.len());
        let j = p.joints.as_ref().unwrap();
        let dense = |a: &CscMatrix| DMatrix::from_column_slice(a.nrows(), a.ncols(), &a.to_dense());
        let (mm, h, g) = (dense(&p.m), dense(&p.h), dense(&j.g));
        let mut k = DMatrix::zeros(n + 1, n + 1);
        k.view_mut((0, 0), (n, n))
            .copy_from(&(mm + rho * &h * h.transpose()));
        k.view_mut((0, n), (n, 1)).copy_from(&g);
        k.view_mut((n, 0), (1, n)).copy_from(&g.transpose());
        let t = DVector::from_iterator(m, (0..m).map(|i| rho * (y[i] + s.c[i] - zeta[i])));
        let top = DVector::from_column_slice(&p.f) + h * t;
        let mut rhs = DVector::zeros(n + 1);
        rhs.rows_mut(0, n).copy_from(&top);
        rhs[n] = -j.b[0];
        let x = k.lu().solve(&rhs).unwrap();
        x.rows(0, n).iter().copied().collect()
    }

    /// When a rho rule returns to a penalty whose factor is cached, the joint system's
    /// refinement step must multiply by the matrix of that penalty, not of the last one
    /// factorized.
    #[test]
    fn x_step_with_joints_after_returning_to_a_cached_rho() {
        let mut s = ProblemSplitting::new(joint_problem(), LinearSolver::Auto).unwrap();
        let y = [0.3, 0.1, -0.2, 0.5, 0.0, 0.1];
        let zeta = [-0.2, 0.05, 0.1, -0.4, 0.2, 0.0];
        let mut ax = [0.0; 6];
        for rho in [1.0, 10.0, 1.0] {
            s.set_rho(rho).unwrap();
            s.x_step(&y, &zeta, rho, &mut ax);
            let reference = dense_x_step(&s, &y, &zeta, rho);
            for (a, b) in s.sol[..4].iter().zip(&reference) {
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                    "rho {rho}: v {a} vs dense {b}"
                );
            }
        }
    }
}
