//! The v-update system of the global form, behind one interface (docs/algorithms.md §4,
//! §14, §16): `(M + rho H D H^T) v = f + H t` (with joints, the quasi-definite system around
//! it), where `t` is the x-step's contact-space vector and `D` marks the rows in the system.
//! Three backends implement it: the factorized system ([`FactorizedSystem`]), the
//! matrix-free one ([`MatrixFreeSystem`]), and the system shared over processes
//! (`distributed::DistributedGram`). The global splitting drives each the same way.

mod factorized;
mod matrix_free;

pub(crate) use factorized::FactorizedSystem;
pub(crate) use matrix_free::MatrixFreeSystem;

use super::param_matrix::{triplets, Assembly};
use super::{BlockDiagonal, Factor, FactorKind, GramPcg, ParamMatrix, PcgStop};
use crate::measure::{global_error_with, Floors, MeasureWork};
use crate::problem::GlobalProblem;
use crate::settings::LinearSolver;
use crate::tuning::{
    FACTOR_MAX_ENTRIES, MATRIX_FREE_MIN_FILL, PCG_ERROR_SHARE, PCG_EXPECTED_ITERATIONS,
    PCG_FIRST_RELATIVE, PCG_MAX_ITERATIONS, PCG_REDUCTION, PCG_RELATIVE_FLOOR,
};
use crate::types::Error;
use std::time::Instant;

/// The contact data the global splitting reads beside its system: the free velocities'
/// right-hand side is the system's business, the contacts' `w` and `mu` are the
/// splitting's (one process: the whole problem's; many: this process's contacts').
pub(crate) trait ContactData {
    /// `w`, 3 per contact.
    fn w(&self) -> &[f64];
    /// Friction coefficients, 1 per contact.
    fn mu(&self) -> &[f64];
}

impl ContactData for GlobalProblem {
    fn w(&self) -> &[f64] {
        &self.w
    }

    fn mu(&self) -> &[f64] {
        &self.mu
    }
}

/// How exactly an x-step solves when the backend is inexact: from the last error measured
/// (infinite before the first) and within the solve's wall-clock limit.
#[derive(Clone, Copy)]
pub(crate) struct Accuracy {
    pub last_error: f64,
    pub deadline: Option<Instant>,
}

/// One v-update system, as the global splitting uses it. `p` is what the system was built
/// from ([`VelocitySystem::Data`]), held by the splitting and handed back at each call.
pub(crate) trait VelocitySystem {
    /// The problem (one process) or the process's part (many) the system is built from.
    type Data: ContactData;

    /// Makes `rho` the current penalty; when `changed`, first takes the values now in `p`
    /// and the rows `active` marks (new values, screened contacts).
    fn set_rho(
        &mut self,
        p: &Self::Data,
        rho: f64,
        active: &[f64],
        changed: bool,
    ) -> Result<(), Error>;

    /// The x-step: `sol` (velocities, then `-lambda` with joints) from `f + H t` and the
    /// joints' `-b`, and `ax = H^T v`. `sol` holds the last iterate, which an inexact
    /// backend starts from.
    fn x_step(
        &mut self,
        p: &Self::Data,
        t: &[f64],
        sol: &mut [f64],
        ax: &mut [f64],
        accuracy: Accuracy,
    );

    /// `u = H^T v + w` over the contacts.
    fn contact_velocity(&mut self, p: &Self::Data, v: &[f64], u: &mut [f64]);

    /// `out = H^T v`.
    fn h_t_mul(&mut self, p: &Self::Data, v: &[f64], out: &mut [f64]);

    /// `||H t||` (over every process).
    fn h_norm(&mut self, p: &Self::Data, t: &[f64]) -> f64;

    /// The error measure (docs/algorithms.md §3) at impulses `r` and the iterate `sol`
    /// (over every process; infinite when some vector is not finite).
    fn measure(&mut self, p: &Self::Data, r: &[f64], sol: &[f64]) -> f64;

    /// Adds each entry of `partial` up over the processes (one process: nothing to add).
    fn sum_across(&self, _partial: &mut [f64]) {}

    /// Numeric factorizations so far.
    fn refactorizations(&self) -> usize;

    /// Conjugate-gradient iterations so far (0 when factorized).
    fn linear_iterations(&self) -> usize {
        0
    }
}

/// What a one-process system adds: it answers for the whole problem, so it also checks M,
/// gives the free motion and keeps the measure's floors, all through its [`OwnProblem`].
pub(crate) trait ProblemSystem: VelocitySystem<Data = GlobalProblem> + Send {
    /// What the system keeps of the problem beside its matrix.
    fn own(&mut self) -> &mut OwnProblem;

    /// The backend, which a rebuild keeps.
    fn backend(&self) -> LinearSolver;

    /// Threads the products may use (the results do not depend on them).
    fn set_threads(&mut self, _threads: usize) {}
}

/// What a one-process system keeps of the problem beside its matrix: M's own check
/// factor, M's mirror map when the system is symmetric, and the measure's work vectors.
pub(crate) struct OwnProblem {
    mass: MassFactor,
    /// Mirror map of M when the system stores its upper triangle only (new values are
    /// checked to be still symmetric); `None` for an LU system.
    m_mirror: Option<Vec<usize>>,
    measure: MeasureWork,
    lambda: Vec<f64>,
}

impl OwnProblem {
    /// M factorized alone: a clear error when it is not positive definite. The system is
    /// symmetric (Cholesky, LDL^T) exactly when M is.
    fn new(p: &GlobalProblem) -> Result<Self, Error> {
        Ok(Self {
            mass: MassFactor::new(p)?,
            m_mirror: p.m.is_symmetric().then(|| p.m.mirror_map()),
            measure: MeasureWork::global(p),
            lambda: vec![0.0; p.n_joints()],
        })
    }

    /// Refactorizes M alone for new values (an error when it is not positive definite);
    /// the system takes them at its next `set_rho` with `changed`.
    pub fn take_values(&mut self, p: &GlobalProblem) -> Result<(), Error> {
        self.mass.refactorize(p)
    }

    /// The free velocity `M^-1 f` into `v`, when the system is symmetric (M's check
    /// factor is then M's own).
    pub fn free_velocity(&mut self, p: &GlobalProblem, v: &mut [f64]) -> bool {
        if self.m_mirror.is_none() {
            return false;
        }
        v.copy_from_slice(&p.f);
        self.mass.solve_in_place(v);
        true
    }

    /// True when the system was built for a symmetric M that no longer is.
    pub fn lost_symmetry(&self, p: &GlobalProblem) -> bool {
        self.m_mirror
            .as_ref()
            .is_some_and(|mirror| !p.m.is_symmetric_with(mirror))
    }

    /// True for a factorization that can fail on new values (LU), which an update must
    /// then attempt at once.
    pub fn may_fail(&self) -> bool {
        self.m_mirror.is_none()
    }

    /// The measure's floors (docs/algorithms.md §12).
    pub fn floors(&self) -> Floors {
        self.measure.floors
    }

    /// Sets the measure's floors.
    pub fn set_floors(&mut self, floors: Floors) {
        self.measure.floors = floors;
    }

    /// The error measure of `r` and `sol` (velocities, then `-lambda`).
    fn measure(&mut self, p: &GlobalProblem, r: &[f64], sol: &[f64]) -> f64 {
        let n = p.n();
        for (l, x) in self.lambda.iter_mut().zip(&sol[n..]) {
            *l = -x;
        }
        global_error_with(p, r, &sol[..n], &self.lambda, &mut self.measure)
    }

    /// The equation denominator of the last measure.
    fn equation_scale(&self) -> f64 {
        self.measure.scales.equation
    }

    fn refactorizations(&self) -> usize {
        self.mass.refactorizations()
    }
}

impl<T: VelocitySystem + ?Sized> VelocitySystem for Box<T> {
    type Data = T::Data;

    fn set_rho(
        &mut self,
        p: &T::Data,
        rho: f64,
        active: &[f64],
        changed: bool,
    ) -> Result<(), Error> {
        (**self).set_rho(p, rho, active, changed)
    }

    fn x_step(&mut self, p: &T::Data, t: &[f64], sol: &mut [f64], ax: &mut [f64], a: Accuracy) {
        (**self).x_step(p, t, sol, ax, a)
    }

    fn contact_velocity(&mut self, p: &T::Data, v: &[f64], u: &mut [f64]) {
        (**self).contact_velocity(p, v, u)
    }

    fn h_t_mul(&mut self, p: &T::Data, v: &[f64], out: &mut [f64]) {
        (**self).h_t_mul(p, v, out)
    }

    fn h_norm(&mut self, p: &T::Data, t: &[f64]) -> f64 {
        (**self).h_norm(p, t)
    }

    fn measure(&mut self, p: &T::Data, r: &[f64], sol: &[f64]) -> f64 {
        (**self).measure(p, r, sol)
    }

    fn sum_across(&self, partial: &mut [f64]) {
        (**self).sum_across(partial)
    }

    fn refactorizations(&self) -> usize {
        (**self).refactorizations()
    }

    fn linear_iterations(&self) -> usize {
        (**self).linear_iterations()
    }
}

/// The one-process system `choice` asks for. `Auto` (docs/algorithms.md §14) factorizes
/// unless the system is large and the symbolic analysis predicts a factor whose two
/// triangular solves cost more than the expected conjugate-gradient products, or a factor
/// too large for memory. Joints and a non-symmetric M stay direct. M alone is factorized
/// first: a clear error when it is not positive definite.
pub(crate) fn problem_system(
    p: &GlobalProblem,
    active: &[f64],
    choice: LinearSolver,
) -> Result<Box<dyn ProblemSystem>, Error> {
    let own = OwnProblem::new(p)?;
    // Checked before anything is assembled: the matrix-free backend never forms the matrix.
    let eligible = p.n_joints() == 0 && GramPcg::fits(MatrixFreeSystem::gram(p, active));
    if eligible && choice == LinearSolver::Iterative {
        return Ok(Box::new(MatrixFreeSystem::new(p, active, own)));
    }
    let direct = FactorizedSystem::new(p, active, own)?;
    if eligible && choice == LinearSolver::Auto && matrix_free_pays(p, &direct.factor) {
        return Ok(Box::new(MatrixFreeSystem::new(p, active, direct.own)));
    }
    Ok(Box::new(direct))
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

/// When an inexact backend stops (docs/algorithms.md §14): once the residual
/// `||b - A v||` of its warm start has shrunk by [`PCG_REDUCTION`], so that the error of
/// each inexact step is a fraction of the step itself (which goes to zero as ADMM
/// converges: the errors stay summable, as inexact ADMM needs); or once it is below a
/// tenth of the last measured error (`equation_scale`: the measure's equation
/// denominator), which that residual adds to: then it no longer matters for the
/// tolerance. The error measured at the end is of the inexact iterate, so it stays honest
/// either way.
pub(crate) fn inexact_stop(accuracy: Accuracy, equation_scale: f64, rhs_norm: f64) -> PcgStop {
    let tol = if accuracy.last_error.is_finite() {
        PCG_ERROR_SHARE * accuracy.last_error * equation_scale
    } else {
        PCG_FIRST_RELATIVE * rhs_norm
    };
    PcgStop {
        tol,
        reduction: PCG_REDUCTION,
        floor: PCG_RELATIVE_FLOOR * rhs_norm,
        max_iterations: PCG_MAX_ITERATIONS,
        deadline: accuracy.deadline,
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
    pub fn new(p: &GlobalProblem) -> Result<Self, Error> {
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
    pub fn refactorize(&mut self, p: &GlobalProblem) -> Result<(), Error> {
        match self {
            Self::Blocks(blocks) => blocks.factorize("M", &p.m),
            Self::Sparse(factor, assembly) => {
                factor.reassemble(assembly, mass_triplets(p), []);
                factor.set_rho(0.0)
            }
        }
    }

    /// `x = M^-1 x` (M's symmetric part).
    pub fn solve_in_place(&mut self, x: &mut [f64]) {
        match self {
            Self::Blocks(blocks) => blocks.solve_in_place(x),
            Self::Sparse(factor, _) => factor.solve_in_place(x),
        }
    }

    /// Numeric factorizations so far.
    pub fn refactorizations(&self) -> usize {
        match self {
            Self::Blocks(blocks) => blocks.refactorizations(),
            Self::Sparse(factor, _) => factor.refactorizations(),
        }
    }
}
