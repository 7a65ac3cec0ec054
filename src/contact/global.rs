//! Global form: `x = v`, `y = u~`, `A = H^T`, `c = -w - Phi(s)`, g = indicator of `K*`.
//!
//! v-update: `(M + rho H H^T) v = f + rho H (u~ + c - zeta)`; with joints the
//! quasi-definite system `[[M + rho H H^T, G], [G^T, -delta I]] [v; -lambda] = [.; -b]`
//! (delta tiny, corrected by one step of iterative refinement).

use super::{
    active_rows, check_vector, count_rows, de_saxce_shift, initial_shift, prox_input, rows_missing,
    ContactForm, NewValues,
};
use crate::admm::{EngineState, Splitting};
use crate::certificate::run_off;
use crate::cone::{get3, project_dual_cone, set3};
use crate::csc::{norm2, CscMatrix, RowMajor};
use crate::linsys::param_matrix::{triplets, Assembly};
use crate::linsys::{
    BlockDiagonal, Factor, FactorKind, Gram, GramPcg, GramProduct, ParamMatrix, PcgStop,
};
use crate::measure::{global_error_with, Floors, MeasureWork};
use crate::newton::{GlobalNewton, NewtonOutcome};
use crate::problem::{GlobalProblem, Problem, ProblemRef};
use crate::settings::LinearSolver;
use crate::tuning::{
    FACTOR_MAX_ENTRIES, JOINT_DELTA, MATRIX_FREE_MIN_FILL, PCG_ERROR_SHARE,
    PCG_EXPECTED_ITERATIONS, PCG_FIRST_RELATIVE, PCG_MAX_ITERATIONS, PCG_REDUCTION,
    PCG_RELATIVE_FLOOR, SCREEN_RATIO,
};
use crate::types::Error;
use crate::types::Solution;
use std::time::Instant;

/// The global contact problem as an ADMM splitting.
pub struct GlobalSplitting {
    p: GlobalProblem,
    /// The symmetric part of M alone, refactorized at each update (see [`MassFactor`]).
    mass: MassFactor,
    /// The v-update system and how it is solved.
    system: VelocitySystem,
    /// Mirror map of M when the system stores its upper triangle only (new values are
    /// checked to be still symmetric).
    m_mirror: Option<Vec<usize>>,
    /// Current velocity (and joint multipliers after it, when there are joints).
    sol: Vec<f64>,
    rhs: Vec<f64>,
    resid: Vec<f64>,
    c: Vec<f64>,
    phi: Vec<f64>,
    work_n: Vec<f64>,
    work_m: Vec<f64>,
    /// 1 for the rows of the contact space in the system's pattern, 0 for the tangential
    /// rows of frictionless contacts ([`super::active_rows`]).
    in_pattern: Vec<f64>,
    /// The rows the system holds now: those of `in_pattern` less the screened contacts'.
    active: Vec<f64>,
    /// Contacts left out of the v-update system for this solve ([`GlobalSplitting::screen`]).
    screened: Vec<bool>,
    /// Impulse and joint multipliers of the current iterate, for the error measure.
    r: Vec<f64>,
    lambda: Vec<f64>,
    measure: MeasureWork,
    /// The last error measured, which sets how exactly the iterative backend solves
    /// (infinite until a first measure; see [`GlobalSplitting::inexact_tolerance`]).
    last_error: f64,
    /// The Newton phase, built on first use and kept across updates.
    newton: Option<GlobalNewton>,
    /// The running solve's wall-clock limit, which also stops a conjugate-gradient solve.
    deadline: Option<Instant>,
    /// New values not yet in the v-update system: the next `set_rho` takes them (through
    /// the assembly maps, no sorting), so that a solve its warm start already ends (an
    /// engine's resting scene), or that a first Newton phase ends, assembles and factorizes
    /// nothing.
    stale: bool,
}

/// The v-update system and its backend.
enum VelocitySystem {
    /// Factorized (dense or sparse): the assembled matrix, where M, G and `H H^T` go in
    /// it (new values without re-sorting), and `H H^T` itself.
    Direct {
        factor: Factor,
        assembly: Assembly,
        gram: GramProduct,
        /// H by rows, for the products `H x` of every iteration (a gather, faster than
        /// the column product's scatter); `None` past 32-bit indices.
        h_rows: Option<RowMajor>,
    },
    /// Matrix-free conjugate gradients on `M + rho H H^T` (symmetric M, no joints).
    Iterative(GramPcg),
}

impl GlobalSplitting {
    /// Analyses and factorizes `M` (to check it is positive definite) and prepares the
    /// v-update system.
    pub(crate) fn new(p: GlobalProblem, backend: LinearSolver) -> Result<Self, Error> {
        let n = p.n();
        let m = 3 * p.n_contacts();
        // M alone first: a clear error when M is not positive definite.
        let mass = MassFactor::new(&p)?;
        let active = active_rows(&p.mu);
        let (system, kind) = velocity_system(&p, &active, backend)?;
        let dim = n + p.n_joints();
        let m_mirror = (kind != FactorKind::Lu).then(|| p.m.mirror_map());
        let mut phi = vec![0.0; m];
        initial_shift(&p.mu, p.h.norm_fro(), &mut phi);
        let c = p.w.iter().zip(&phi).map(|(w, s)| -w - s).collect();
        let measure = MeasureWork::global(&p);
        Ok(Self {
            mass,
            system,
            m_mirror,
            sol: vec![0.0; dim],
            rhs: vec![0.0; dim],
            resid: vec![0.0; dim],
            c,
            phi,
            work_n: vec![0.0; n],
            work_m: vec![0.0; m],
            r: vec![0.0; m],
            in_pattern: active.clone(),
            active,
            screened: vec![false; p.n_contacts()],
            lambda: vec![0.0; dim - n],
            measure,
            last_error: f64::INFINITY,
            newton: None,
            deadline: None,
            stale: false,
            p,
        })
    }

    /// Joint multipliers of the last x-step into `out` (the system is solved for
    /// `-lambda`, see the module comment).
    fn lambda_into(sol: &[f64], n: usize, out: &mut [f64]) {
        for (o, x) in out.iter_mut().zip(&sol[n..]) {
            *o = -x;
        }
    }

    /// Makes the values now in `self.p` the problem's (same patterns): refactorizes M,
    /// restarts the shift and rescales the Newton phase; the v-update system takes them at
    /// the next [`Splitting::set_rho`] (see `stale`). No sorting, no allocation. M is
    /// refactorized on its own (its symmetric part, much sparser than the system) because
    /// the system can be positive definite while M is not. When M stopped being symmetric, the Cholesky
    /// system gives way to a new LU one.
    fn take_values(&mut self) -> Result<(), Error> {
        let asymmetric = self
            .m_mirror
            .as_ref()
            .is_some_and(|mirror| !self.p.m.is_symmetric_with(mirror));
        if asymmetric || rows_missing(&self.in_pattern, &self.p.mu) {
            let floors = self.measure.floors;
            *self = Self::new(self.p.clone(), self.backend())?;
            self.set_measure_floors(floors);
            return Ok(());
        }
        self.mass.refactorize(&self.p)?;
        self.stale = true;
        self.reset_shift();
        if let Some(newton) = &mut self.newton {
            newton.take_values(&self.p);
        }
        Ok(())
    }

    /// Restarts the De Saxce shift from its initial guess (docs/algorithms.md §5), and the
    /// iterative backend's accuracy with it (a new solve).
    fn reset_shift(&mut self) {
        initial_shift(&self.p.mu, self.p.h.norm_fro(), &mut self.phi);
        self.refresh_c();
        self.last_error = f64::INFINITY;
    }

    /// The backend the system was built with (a rebuild keeps it).
    fn backend(&self) -> LinearSolver {
        match self.system {
            VelocitySystem::Direct { .. } => LinearSolver::Direct,
            VelocitySystem::Iterative(_) => LinearSolver::Iterative,
        }
    }

    /// Sets the De Saxce shift from a velocity (warm start).
    fn shift_from_velocity(&mut self, v: &[f64]) {
        self.work_m.copy_from_slice(&self.p.w);
        self.p.h.mul_t_vec(1.0, v, 1.0, &mut self.work_m);
        de_saxce_shift(&self.work_m, &self.p.mu, &mut self.phi);
        self.refresh_c();
    }

    fn refresh_c(&mut self) {
        for i in 0..self.c.len() {
            self.c[i] = -self.p.w[i] - self.phi[i];
        }
    }

    /// Leaves out of the v-update system the contacts a warm start predicts open: no
    /// impulse, and a normal velocity `u` (at the warm velocity) above [`SCREEN_RATIO`]
    /// times the largest. Their impulse stays zero, which Coulomb's law accepts as long as
    /// their normal velocity stays non-negative; `readmit`, at each of the loop's own
    /// evaluations, brings back any whose velocity turned negative, and the error always
    /// measures the whole problem (docs/algorithms.md §15).
    fn screen(&mut self, r: &[f64], u: &[f64]) {
        let nc = self.p.n_contacts();
        let largest = (0..nc).map(|i| u[3 * i].abs()).fold(0.0, f64::max);
        let threshold = SCREEN_RATIO * largest;
        for i in 0..nc {
            let open = r[3 * i..3 * i + 3].iter().all(|&x| x == 0.0) && u[3 * i] > threshold;
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

/// Symmetric part of M as triplets: M is positive definite exactly when it is.
fn mass_triplets(p: &GlobalProblem) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
    triplets(&p.m).flat_map(|(i, j, v)| [(i, j, 0.5 * v), (j, i, 0.5 * v)])
}

/// Cholesky factor of the symmetric part of M, kept so that every update checks M on its
/// own: `M + rho H H^T` can be positive definite while M is not. Block by block when M is
/// made of small diagonal blocks (rigid bodies), sparse (upper triangle) otherwise.
enum MassFactor {
    Blocks(BlockDiagonal),
    Sparse(Factor, Assembly),
}

impl MassFactor {
    /// Factorizes M's symmetric part (an error when it is not positive definite).
    fn new(p: &GlobalProblem) -> Result<Self, Error> {
        let mut mass = match BlockDiagonal::of(&p.m) {
            Some(blocks) => Self::Blocks(blocks),
            None => {
                let (matrix, assembly) =
                    ParamMatrix::from_triplets(p.n(), mass_triplets(p), [], true);
                Self::Sparse(Factor::new("M", matrix, FactorKind::Cholesky)?, assembly)
            }
        };
        mass.refactorize(p)?;
        Ok(mass)
    }

    /// Factorizes the values now in `p.m` (the pattern it was made from).
    fn refactorize(&mut self, p: &GlobalProblem) -> Result<(), Error> {
        match self {
            Self::Blocks(blocks) => blocks.factorize("M", &p.m),
            Self::Sparse(factor, assembly) => {
                factor.reassemble(assembly, mass_triplets(p), []);
                factor.set_rho(0.0)
            }
        }
    }

    fn solve_in_place(&mut self, x: &mut [f64]) {
        match self {
            Self::Blocks(blocks) => blocks.solve_in_place(x),
            Self::Sparse(factor, _) => factor.solve_in_place(x),
        }
    }

    fn refactorizations(&self) -> usize {
        match self {
            Self::Blocks(blocks) => blocks.refactorizations(),
            Self::Sparse(factor, _) => factor.refactorizations(),
        }
    }
}

/// The constant part of the v-update system, in a fixed order: M, then for each joint
/// entry `G` and `G^T`, then the joint regularization.
fn base_triplets(p: &GlobalProblem) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
    let n = p.n();
    let joints = p.joints.iter().flat_map(move |j| {
        let g = triplets(&j.g).flat_map(move |(i, k, v)| [(i, n + k, v), (n + k, i, v)]);
        let reg = (0..j.g.ncols()).map(move |k| (n + k, n + k, -JOINT_DELTA));
        g.chain(reg)
    });
    triplets(&p.m).chain(joints)
}

/// `M + rho H H^T`, or the joint system around it: `[[M + rho H H^T, G], [G^T, -delta I]]`.
/// Cholesky / quasi-definite LDL^T on the upper triangle when M is symmetric (up to
/// round-off), LU on the full pattern otherwise (some FEM files carry a non-symmetric M).
fn system_matrix(
    p: &GlobalProblem,
    active: &[f64],
) -> (ParamMatrix, Assembly, GramProduct, FactorKind) {
    let n = p.n();
    let np = p.n_joints();
    let symmetric = p.m.is_symmetric();
    let gram = GramProduct::new(&p.h, active, symmetric);
    let (matrix, assembly) =
        ParamMatrix::from_triplets(n + np, base_triplets(p), gram.triplets(), symmetric);
    let kind = match (symmetric, np) {
        (true, 0) => FactorKind::Cholesky,
        (true, _) => FactorKind::QuasiDefinite { n_positive: n },
        (false, _) => FactorKind::Lu,
    };
    (matrix, assembly, gram, kind)
}

/// When the iterative backend stops (docs/algorithms.md §14): once the residual
/// `||b - A v||` of its warm start has shrunk by [`PCG_REDUCTION`], so that the error of
/// each inexact step is a fraction of the step itself (which goes to zero as ADMM
/// converges: the errors stay summable, as inexact ADMM needs); or once it is below a
/// tenth of the last measured error (`equation_scale`: the measure's equation
/// denominator), which that residual adds to: then it no longer matters for the
/// tolerance. The error measured at the end is of the inexact iterate, so it stays honest
/// either way.
pub(crate) fn inexact_stop(
    last_error: f64,
    equation_scale: f64,
    rhs_norm: f64,
    deadline: Option<Instant>,
) -> PcgStop {
    let tol = if last_error.is_finite() {
        PCG_ERROR_SHARE * last_error * equation_scale
    } else {
        PCG_FIRST_RELATIVE * rhs_norm
    };
    PcgStop {
        tol,
        reduction: PCG_REDUCTION,
        floor: PCG_RELATIVE_FLOOR * rhs_norm,
        max_iterations: PCG_MAX_ITERATIONS,
        deadline,
    }
}

/// The iterative backend's operator `M + rho H D H^T`.
fn gram<'a>(p: &'a GlobalProblem, active: &'a [f64]) -> Gram<'a> {
    Gram {
        m: &p.m,
        h: &p.h,
        active,
    }
}

/// The v-update system with the backend `choice` asks for. `Auto` (docs/algorithms.md §14)
/// factorizes unless the system is large and the symbolic analysis predicts a factor whose
/// two triangular solves cost more than the expected conjugate-gradient products, or a
/// factor too large for memory. Joints and a non-symmetric M stay direct.
fn velocity_system(
    p: &GlobalProblem,
    active: &[f64],
    choice: LinearSolver,
) -> Result<(VelocitySystem, FactorKind), Error> {
    let iterative = || VelocitySystem::Iterative(GramPcg::new(gram(p, active)));
    // Checked before anything is assembled: the matrix-free backend never forms the matrix.
    let eligible = p.n_joints() == 0 && GramPcg::fits(gram(p, active));
    if eligible && choice == LinearSolver::Iterative {
        return Ok((iterative(), FactorKind::Cholesky));
    }
    let (matrix, assembly, gram, kind) = system_matrix(p, active);
    let factor = Factor::new("M + rho H H^T", matrix, kind)?;
    if eligible && choice == LinearSolver::Auto && matrix_free_pays(p, &factor) {
        return Ok((iterative(), kind));
    }
    Ok((
        VelocitySystem::Direct {
            factor,
            assembly,
            gram,
            h_rows: RowMajor::fits(&p.h).then(|| RowMajor::new(&p.h)),
        },
        kind,
    ))
}

/// `y = H x + beta y` (`beta` 0 or 1) through the storage of H the system keeps.
fn h_times(system: &mut VelocitySystem, h: &CscMatrix, x: &[f64], beta: f64, y: &mut [f64]) {
    match system {
        VelocitySystem::Direct {
            h_rows: Some(rows), ..
        } => rows.mul_vec(x, beta, y),
        VelocitySystem::Direct { h_rows: None, .. } => h.mul_vec(1.0, x, beta, y),
        VelocitySystem::Iterative(pcg) => {
            if beta == 0.0 {
                y.fill(0.0);
            }
            pcg.h_mul_add(x, y);
        }
    }
}

/// The cost model of `Auto`: per v-update, two triangular solves read the factor twice;
/// conjugate gradients take about [`PCG_EXPECTED_ITERATIONS`] products with `M`, `H` and
/// `H^T` each (plus the block preconditioner, about as much as M). Below
/// [`MATRIX_FREE_MIN_FILL`] the factor stays: the Newton phase it keeps is worth more.
fn matrix_free_pays(p: &GlobalProblem, factor: &Factor) -> bool {
    let Some(fill) = factor.stored_entries() else {
        return false;
    };
    if fill < MATRIX_FREE_MIN_FILL {
        return false;
    }
    let direct = 2.0 * fill as f64;
    let product = 2.0 * p.m.nnz() as f64 + 2.0 * p.h.nnz() as f64;
    let iterative = PCG_EXPECTED_ITERATIONS * product;
    direct > iterative || fill > FACTOR_MAX_ENTRIES
}

impl Splitting for GlobalSplitting {
    fn dim(&self) -> usize {
        self.c.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if std::mem::take(&mut self.stale) {
            match &mut self.system {
                VelocitySystem::Direct {
                    factor,
                    assembly,
                    gram,
                    h_rows,
                } => {
                    if let Some(rows) = h_rows {
                        rows.take_values(&self.p.h);
                    }
                    gram.recompute(&self.p.h, &self.active);
                    factor.reassemble(assembly, base_triplets(&self.p), gram.triplets())
                }
                VelocitySystem::Iterative(pcg) => pcg.take_values(gram(&self.p, &self.active)),
            }
        }
        match &mut self.system {
            VelocitySystem::Direct { factor, .. } => factor.set_rho(rho),
            VelocitySystem::Iterative(pcg) => pcg.set_rho(rho),
        }
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        let n = self.p.n();
        for i in 0..self.work_m.len() {
            self.work_m[i] = self.active[i] * rho * (y[i] + self.c[i] - zeta[i]);
        }
        self.rhs[..n].copy_from_slice(&self.p.f);
        h_times(
            &mut self.system,
            &self.p.h,
            &self.work_m,
            1.0,
            &mut self.rhs[..n],
        );
        if let Some(j) = &self.p.joints {
            for (t, b) in self.rhs[n..].iter_mut().zip(&j.b) {
                *t = -b;
            }
        }
        let factor = match &mut self.system {
            VelocitySystem::Direct { factor, .. } => factor,
            VelocitySystem::Iterative(pcg) => {
                // From the last velocity: a warm start that is close after a few iterations.
                let scale = self.measure.scales.equation;
                let stop = inexact_stop(self.last_error, scale, norm2(&self.rhs), self.deadline);
                pcg.solve(gram(&self.p, &self.active), &self.rhs, &mut self.sol, stop);
                pcg.h_t_mul(&self.sol, ax);
                return;
            }
        };
        self.sol.copy_from_slice(&self.rhs);
        factor.solve_in_place(&mut self.sol);
        if self.p.joints.is_some() {
            // One refinement step against the unregularized system.
            factor.mul_vec(&self.sol, &mut self.resid);
            for i in n..self.resid.len() {
                self.resid[i] += JOINT_DELTA * self.sol[i];
            }
            for i in 0..self.resid.len() {
                self.resid[i] = self.rhs[i] - self.resid[i];
            }
            factor.solve_in_place(&mut self.resid);
            for i in 0..self.resid.len() {
                self.sol[i] += self.resid[i];
            }
        }
        self.p.h.mul_t_vec(1.0, &self.sol[..n], 0.0, ax);
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        for (i, &mu) in self.p.mu.iter().enumerate() {
            let input = prox_input(ax, &self.c, zeta, i);
            // A screened contact is not projected: the dual update then leaves zeta, the
            // impulse, at zero.
            let out = match self.screened[i] {
                true => input,
                false => project_dual_cone(input, mu),
            };
            set3(y, i, out);
        }
    }

    fn c(&self) -> &[f64] {
        &self.c
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        for i in 0..d.len() {
            self.work_m[i] = self.active[i] * d[i];
        }
        h_times(
            &mut self.system,
            &self.p.h,
            &self.work_m,
            0.0,
            &mut self.work_n,
        );
        norm2(&self.work_n)
    }

    fn update_s(&mut self, ax: &[f64], _y: &[f64]) {
        // u = H^T v + w
        for i in 0..ax.len() {
            self.work_m[i] = ax[i] + self.p.w[i];
        }
        de_saxce_shift(&self.work_m, &self.p.mu, &mut self.phi);
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
            if self.screened[i] && ax[3 * i] + self.p.w[3 * i] < 0.0 {
                self.set_screened(i, false);
            }
        }
    }

    fn error(&mut self, _ax: &[f64], _y: &[f64], zeta: &[f64], rho: f64) -> f64 {
        for i in 0..zeta.len() {
            self.r[i] = -rho * zeta[i];
        }
        let n = self.p.n();
        Self::lambda_into(&self.sol, n, &mut self.lambda);
        let error = global_error_with(
            &self.p,
            &self.r,
            &self.sol[..n],
            &self.lambda,
            &mut self.measure,
        );
        self.last_error = error;
        error
    }
}

impl ContactForm for GlobalSplitting {
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
        match self.m_mirror.is_some() {
            true => Ok(()),
            false => self.set_rho(rho),
        }
    }

    fn n_velocities(&self) -> usize {
        self.p.n()
    }

    fn problem(&self) -> ProblemRef<'_> {
        ProblemRef::Global(&self.p)
    }

    fn cold_start(&mut self, state: &mut EngineState) {
        state.y.fill(0.0);
        state.zeta.fill(0.0);
        // No velocity carried over from a previous solve either (the Newton phase alone
        // starts from it).
        self.sol.fill(0.0);
        self.reset_shift();
        self.unscreen_all();
    }

    fn separating(&mut self, state: &mut EngineState) -> bool {
        // The free velocity M^-1 f costs one solve with the factor of M kept for the
        // update check, which is M itself when M is symmetric; joints would need the
        // constrained system.
        if self.p.joints.is_some() || self.m_mirror.is_none() {
            return false;
        }
        // In work space: when the contacts do not all separate, the velocity of a warm
        // start (what a Newton phase starts from) must stay.
        let v = &mut self.work_n;
        v.copy_from_slice(&self.p.f);
        self.mass.solve_in_place(v);
        self.work_m.copy_from_slice(&self.p.w);
        self.p.h.mul_t_vec(1.0, v, 1.0, &mut self.work_m);
        if !(0..self.p.n_contacts()).all(|i| self.work_m[3 * i] >= 0.0) {
            return false;
        }
        let n = self.p.n();
        self.sol[..n].copy_from_slice(&self.work_n);
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
        // r = -rho zeta at a solution.
        for (z, ri) in state.zeta.iter_mut().zip(r) {
            *z = -ri / state.rho;
        }
        state.y.fill(0.0);
        let Some(v) = v else {
            self.reset_shift();
            self.unscreen_all();
            return Ok(());
        };
        // The velocity is the iterate a Newton phase would start from.
        self.sol[..self.p.n()].copy_from_slice(v);
        // u~ = P_K*(H^T v + w + Phi(u)), the shift taken from the same u.
        self.shift_from_velocity(v);
        let u = std::mem::take(&mut self.work_m);
        self.screen(r, &u);
        self.work_m = u;
        self.p.h.mul_t_vec(1.0, v, 0.0, &mut self.work_m);
        for (i, &mu) in self.p.mu.iter().enumerate() {
            let a = get3(&self.work_m, i);
            let c = get3(&self.c, i);
            set3(
                &mut state.y,
                i,
                project_dual_cone([a[0] - c[0], a[1] - c[1], a[2] - c[2]], mu),
            );
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
        let n = self.p.n();
        out.r.clear();
        out.r.extend(state.zeta.iter().map(|z| -state.rho * z));
        out.v.clear();
        out.v.extend_from_slice(&self.sol[..n]);
        out.u.clone_from(&self.p.w);
        self.p.h.mul_t_vec(1.0, &out.v, 1.0, &mut out.u);
        out.lambda.clear();
        out.lambda.resize(self.sol.len() - n, 0.0);
        Self::lambda_into(&self.sol, n, &mut out.lambda);
    }

    fn set_measure_floors(&mut self, floors: Floors) {
        self.measure.floors = floors;
        if let Some(newton) = &mut self.newton {
            newton.set_measure_floors(floors);
        }
    }

    fn rows(&self) -> usize {
        count_rows(&self.in_pattern)
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
        matches!(self.system, VelocitySystem::Iterative(_))
    }

    fn set_threads(&mut self, threads: usize) {
        if let VelocitySystem::Iterative(pcg) = &mut self.system {
            pcg.set_threads(threads);
        }
    }

    fn linear_iterations(&self) -> usize {
        match &self.system {
            VelocitySystem::Iterative(pcg) => pcg.iterations(),
            VelocitySystem::Direct { .. } => 0,
        }
    }

    fn refactorizations(&self) -> usize {
        let system = match &self.system {
            VelocitySystem::Direct { factor, .. } => factor.refactorizations(),
            VelocitySystem::Iterative(pcg) => pcg.factorizations(),
        };
        system + self.mass.refactorizations()
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
        let start = global_error_with(&self.p, &r, &v, &lambda, &mut self.measure);
        if self.newton.is_none() {
            let mut newton = GlobalNewton::new(&self.p)?;
            newton.set_measure_floors(self.measure.floors);
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
        let mut s = GlobalSplitting::new(p, LinearSolver::Direct).unwrap();
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

    /// `v` of the x-step at `rho` by a dense solve of the unregularized joint system
    /// `[[M + rho H H^T, G], [G^T, 0]] [v; -lambda] = [f + rho H (y + c - zeta); -b]`.
    fn dense_x_step(s: &GlobalSplitting, y: &[f64], zeta: &[f64], rho: f64) -> Vec<f64> {
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
        let mut s = GlobalSplitting::new(joint_problem(), LinearSolver::Auto).unwrap();
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
