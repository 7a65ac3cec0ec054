//! Local form: `x` and `y = z` both impulses, `A = I`, `c = 0`, g = indicator of `K`.
//!
//! x-update: `(W + rho I) x = -(q + Phi(s)) + rho (z - zeta)`, by Cholesky when W is
//! symmetric (up to round-off), by LU otherwise.

use super::form::{
    active_rows, count_rows, de_saxce_shift, initial_shift, rows_missing, ContactForm,
};
use crate::admm::{EngineState, Splitting};
use crate::certificate::local_run_off;
use crate::cone::{de_saxce, get3, project_cone, set3};
use crate::csc::{norm2, CscMatrix};
use crate::linsys::param_matrix::{triplets, Assembly};
use crate::linsys::{Factor, FactorKind, ParamMatrix};
use crate::measure::{local_error_with, Floors, MeasureWork};
use crate::newton::{LocalNewton, NewtonOutcome};
use crate::problem::{LocalProblem, NewValues, Problem, ProblemRef};
use crate::types::Error;
use crate::types::Solution;
use std::time::Instant;

/// The local contact problem as an ADMM splitting.
pub struct LocalSplitting {
    p: LocalProblem,
    factor: Factor,
    /// Where W and `I` go in the system matrix (new values without re-sorting).
    assembly: Assembly,
    /// Mirror map of W when the system stores its upper triangle only.
    w_mirror: Option<Vec<usize>>,
    q_shift: Vec<f64>,
    phi: Vec<f64>,
    zero: Vec<f64>,
    /// 1 for the rows in the system, 0 for the tangential rows of frictionless contacts.
    active: Vec<f64>,
    /// Stored entries of W in each contact's normal row.
    normal_rows: Vec<Vec<usize>>,
    u: Vec<f64>,
    measure: MeasureWork,
    /// The Newton phase, built on first use and kept across updates.
    newton: Option<LocalNewton>,
}

impl LocalSplitting {
    /// Chooses Cholesky or LU from the symmetry of W and analyses the pattern.
    pub(crate) fn new(p: LocalProblem) -> Result<Self, Error> {
        let m = p.q.len();
        let active = active_rows(&p.mu);
        let mut normal_rows = vec![Vec::new(); p.n_contacts()];
        for (k, &i) in p.w.rowind().iter().enumerate() {
            if i % 3 == 0 {
                normal_rows[i / 3].push(k);
            }
        }
        let (matrix, assembly, kind) = system_matrix(&p, &active);
        let w_mirror = (kind == FactorKind::Cholesky).then(|| p.w.mirror_map());
        let factor = Factor::new("W + rho I", matrix, kind)?;
        let mut phi = vec![0.0; m];
        initial_shift(&p.mu, p.w.norm_fro(), &mut phi);
        let q_shift = p.q.iter().zip(&phi).map(|(q, s)| q + s).collect();
        Ok(Self {
            factor,
            assembly,
            w_mirror,
            q_shift,
            phi,
            zero: vec![0.0; m],
            active,
            normal_rows,
            u: vec![0.0; m],
            measure: MeasureWork::local(&p),
            newton: None,
            p,
        })
    }

    /// Makes the values now in `self.p` the system's (same pattern): scattered through the
    /// assembly map, shift restarted, Newton phase rescaled; the caller sets rho, which
    /// refactorizes. No sorting, no allocation, except when W stopped being symmetric: the
    /// Cholesky system then gives way to a new LU one.
    fn take_values(&mut self) -> Result<(), Error> {
        let asymmetric = self
            .w_mirror
            .as_ref()
            .is_some_and(|mirror| !self.p.w.is_symmetric_with(mirror));
        if asymmetric || rows_missing(&self.active, &self.p.mu) {
            let floors = self.measure.floors;
            *self = Self::new(self.p.clone())?;
            self.set_measure_floors(floors);
            return Ok(());
        }
        self.factor.reassemble(
            &self.assembly,
            active_triplets(&self.p.w, &self.active),
            identity(self.p.q.len()),
        );
        self.reset_shift();
        if let Some(newton) = &mut self.newton {
            newton.take_values(&self.p);
        }
        Ok(())
    }

    /// Restarts the De Saxce shift from its initial guess (docs/algorithms.md §5).
    fn reset_shift(&mut self) {
        initial_shift(&self.p.mu, self.p.w.norm_fro(), &mut self.phi);
        self.refresh();
    }

    fn refresh(&mut self) {
        for i in 0..self.q_shift.len() {
            self.q_shift[i] = self.p.q[i] + self.phi[i];
        }
    }

    /// Local velocity `u = W r + q` of an impulse.
    fn velocity(&self, r: &[f64], u: &mut [f64]) {
        u.copy_from_slice(&self.p.q);
        self.p.w.mul_vec(1.0, r, 1.0, u);
    }
}

fn identity(m: usize) -> impl Iterator<Item = (usize, usize, f64)> {
    (0..m).map(|i| (i, i, 1.0))
}

/// The entries of W between rows in the system (see [`super::form::active_rows`]): a left-out
/// row keeps only `rho` on its diagonal, and a zero right-hand side there gives `r_T = 0`.
fn active_triplets<'a>(
    w: &'a CscMatrix,
    active: &'a [f64],
) -> impl Iterator<Item = (usize, usize, f64)> + 'a {
    triplets(w).filter(|&(i, j, _)| active[i] != 0.0 && active[j] != 0.0)
}

/// `W_a + rho I`: Cholesky on the upper triangle when W is symmetric, LU otherwise.
fn system_matrix(p: &LocalProblem, active: &[f64]) -> (ParamMatrix, Assembly, FactorKind) {
    let m = p.q.len();
    let symmetric = p.w.is_symmetric();
    let (matrix, assembly) =
        ParamMatrix::from_triplets(m, active_triplets(&p.w, active), identity(m), symmetric);
    let kind = if symmetric {
        FactorKind::Cholesky
    } else {
        FactorKind::Lu
    };
    (matrix, assembly, kind)
}

impl Splitting for LocalSplitting {
    fn dim(&self) -> usize {
        self.p.q.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        self.factor.set_rho(rho)
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        for i in 0..ax.len() {
            ax[i] = self.active[i] * (-self.q_shift[i] + rho * (y[i] - zeta[i]));
        }
        self.factor.solve_in_place(ax);
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        for (i, &mu) in self.p.mu.iter().enumerate() {
            let a = get3(ax, i);
            let z = get3(zeta, i);
            set3(
                y,
                i,
                project_cone([a[0] + z[0], a[1] + z[1], a[2] + z[2]], mu),
            );
        }
    }

    fn c(&self) -> &[f64] {
        &self.zero
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        norm2(d)
    }

    fn update_s(&mut self, ax: &[f64], _y: &[f64]) {
        // u = W x + q at the impulse x of the linear solve, not at its projection z: the
        // shift then follows the same iterate the linear system produced, which converges
        // far better on singular Delassus matrices (BoxesStack, Capsules).
        let mut u = std::mem::take(&mut self.u);
        self.velocity(ax, &mut u);
        de_saxce_shift(&u, &self.p.mu, &mut self.phi);
        self.u = u;
        self.refresh();
    }

    fn save_iterate(&self, into: &mut Vec<f64>) {
        into.extend_from_slice(&self.phi);
    }

    fn restore_iterate(&mut self, from: &[f64]) {
        self.phi.copy_from_slice(from);
        self.refresh();
    }

    fn error(&mut self, _ax: &[f64], y: &[f64], _zeta: &[f64], _rho: f64) -> f64 {
        local_error_with(&self.p, y, &mut self.measure)
    }
}

impl ContactForm for LocalSplitting {
    fn update(&mut self, p: Problem) -> Result<(), Error> {
        let Problem::Local(p) = p else {
            return Err(Error::Unsupported(
                "update: the new problem is global, the solver was built for a local one".into(),
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

    fn problem(&self) -> ProblemRef<'_> {
        ProblemRef::Local(&self.p)
    }

    fn cold_start(&mut self, state: &mut EngineState) {
        state.y.fill(0.0);
        state.zeta.fill(0.0);
        self.reset_shift();
    }

    fn separating(&mut self, state: &mut EngineState) -> bool {
        if !(0..self.p.n_contacts()).all(|i| self.p.q[3 * i] >= 0.0) {
            return false;
        }
        state.zeta.fill(0.0);
        state.y.fill(0.0);
        true
    }

    fn warm_start(
        &mut self,
        r: &[f64],
        _v: Option<&[f64]>,
        state: &mut EngineState,
    ) -> Result<(), Error> {
        self.update_s(r, r);
        // At a solution u~ = W r + q + Phi = -rho zeta.
        let mut u = std::mem::take(&mut self.u);
        self.velocity(r, &mut u);
        for (i, &mu) in self.p.mu.iter().enumerate() {
            let ut = de_saxce(get3(&u, i), mu);
            let rho = state.rho;
            set3(
                &mut state.zeta,
                i,
                [-ut[0] / rho, -ut[1] / rho, -ut[2] / rho],
            );
        }
        self.u = u;
        state.y.copy_from_slice(r);
        Ok(())
    }

    fn recover(&mut self, _state: &EngineState) -> Result<(), Error> {
        // The local solution is read from the engine state alone.
        Ok(())
    }

    fn write_solution(&self, state: &EngineState, out: &mut Solution) {
        out.r.clone_from(&state.y);
        out.u.clear();
        out.u.resize(out.r.len(), 0.0);
        self.velocity(&out.r, &mut out.u);
        out.v.clear();
        out.lambda.clear();
    }

    fn set_measure_floors(&mut self, floors: Floors) {
        self.measure.floors = floors;
        if let Some(newton) = &mut self.newton {
            newton.set_measure_floors(floors);
        }
    }

    fn rows(&self) -> usize {
        count_rows(&self.active)
    }

    fn space(&self) -> usize {
        self.active.len()
    }

    fn blocked_contact(&self) -> Option<usize> {
        self.normal_rows
            .iter()
            .enumerate()
            .find(|&(i, entries)| {
                self.p.q[3 * i] < 0.0 && entries.iter().all(|&k| self.p.w.values()[k] == 0.0)
            })
            .map(|(i, _)| i)
    }

    fn certifies_infeasibility(&self, state: &EngineState) -> bool {
        local_run_off(&self.p, &state.y)
    }

    fn refactorizations(&self) -> usize {
        self.factor.refactorizations()
    }

    fn polish(
        &mut self,
        state: &mut EngineState,
        tol: f64,
        max_steps: usize,
        deadline: Option<Instant>,
    ) -> Result<NewtonOutcome, Error> {
        let mut r = state.y.clone();
        let start = local_error_with(&self.p, &r, &mut self.measure);
        if self.newton.is_none() {
            let mut newton = LocalNewton::new(&self.p)?;
            newton.set_measure_floors(self.measure.floors);
            self.newton = Some(newton);
        }
        let newton = self.newton.as_mut().expect("built above");
        let out = newton.solve(&self.p, &mut r, tol, max_steps, deadline)?;
        if out.error < start {
            self.warm_start(&r, None, state)?;
        }
        Ok(out)
    }
}
