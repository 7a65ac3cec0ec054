//! What a one-process v-update system keeps of the problem beside its matrix: M's own
//! check factor and the error measure's work.

use crate::linsys::param_matrix::{triplets, Assembly};
use crate::linsys::{BlockDiagonal, Factor, FactorKind, ParamMatrix};
use crate::measure::{global_error_with, Floors, MeasureWork};
use crate::problem::GlobalProblem;
use crate::types::Error;

/// What a one-process system keeps of the problem beside its matrix: M's own check
/// factor, M's mirror map when the system is symmetric, and the measure's work vectors.
pub(crate) struct OwnProblem {
    mass: MassFactor,
    /// Mirror map of M when the system stores its upper triangle only (new values are
    /// checked to be still symmetric); `None` for an LU system.
    m_mirror: Option<Vec<usize>>,
    measure: MeasureWork,
    lambda: Vec<f64>,
    /// The joint rows the splitting holds (with a finite bound, or all of them): their
    /// multipliers come with the impulses.
    bounded: Vec<usize>,
}

impl OwnProblem {
    /// M factorized alone: a clear error when it is not positive definite. The system is
    /// symmetric (Cholesky, LDL^T) exactly when M is.
    pub(super) fn new(p: &GlobalProblem) -> Result<Self, Error> {
        Ok(Self {
            mass: MassFactor::new(p)?,
            m_mirror: p.m.is_symmetric().then(|| p.m.mirror_map()),
            measure: MeasureWork::global(p),
            lambda: vec![0.0; p.n_joints()],
            bounded: p.bounded_rows(),
        })
    }

    /// Every joint row's multiplier comes with the impulses (a system that leaves all the
    /// rows to the splitting).
    pub(super) fn take_all_rows(&mut self, p: &GlobalProblem) {
        self.bounded = (0..p.n_joints()).collect();
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

    /// The error measure of `r` (the impulses, then the bounded joint rows' multipliers)
    /// and `sol` (velocities, then `-lambda` of the equality rows).
    pub(super) fn measure(&mut self, p: &GlobalProblem, r: &[f64], sol: &[f64]) -> f64 {
        let (n, m) = (p.n(), p.w.len());
        for (l, x) in self.lambda.iter_mut().zip(&sol[n..]) {
            *l = -x;
        }
        for (q, &k) in self.bounded.iter().enumerate() {
            self.lambda[k] = r[m + q];
        }
        global_error_with(p, &r[..m], &sol[..n], &self.lambda, &mut self.measure)
    }

    /// The equation denominator of the last measure.
    pub(super) fn equation_scale(&self) -> f64 {
        self.measure.scales.equation
    }

    pub(super) fn refactorizations(&self) -> usize {
        self.mass.refactorizations()
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
