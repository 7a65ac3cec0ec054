//! The factorized v-update system: `M + rho H D H^T` assembled once (new values scattered
//! through the assembly maps), or with joints the quasi-definite
//! `[[M + rho H D H^T, G], [G^T, -delta I]]`, corrected by one step of iterative
//! refinement; dense or sparse ([`Factor`]).

use super::own_problem::OwnProblem;
use super::system::{Accuracy, ProblemSystem, VelocitySystem};
use crate::csc::{norm2, RowMajor};
use crate::linsys::param_matrix::{triplets, Assembly};
use crate::linsys::{Factor, FactorKind, GramProduct, ParamMatrix};
use crate::problem::GlobalProblem;
use crate::settings::LinearSolver;
use crate::tuning::JOINT_DELTA;
use crate::types::Error;

/// The assembled system, its factor and the product `H H^T` it is made of.
pub(crate) struct FactorizedSystem {
    pub(super) factor: Factor,
    assembly: Assembly,
    gram: GramProduct,
    /// H by rows, for the products `H x` of every iteration (a gather, faster than the
    /// column product's scatter); `None` past 32-bit indices.
    h_rows: Option<RowMajor>,
    pub(super) own: OwnProblem,
    rhs: Vec<f64>,
    resid: Vec<f64>,
    work_n: Vec<f64>,
}

impl FactorizedSystem {
    /// Assembles the system of `p` with the rows `active` marks and analyses its factor.
    pub fn new(p: &GlobalProblem, active: &[f64], own: OwnProblem) -> Result<Self, Error> {
        let (matrix, assembly, gram, kind) = system_matrix(p, active);
        let dim = p.n() + p.n_joints();
        Ok(Self {
            factor: Factor::new("M + rho H H^T", matrix, kind)?,
            assembly,
            gram,
            h_rows: RowMajor::fits(&p.h).then(|| RowMajor::new(&p.h)),
            own,
            rhs: vec![0.0; dim],
            resid: vec![0.0; dim],
            work_n: vec![0.0; p.n()],
        })
    }

    /// `y = H x + beta y` (`beta` 0 or 1), by rows when they are kept.
    fn h_times(&self, p: &GlobalProblem, x: &[f64], beta: f64, y: &mut [f64]) {
        match &self.h_rows {
            Some(rows) => rows.mul_vec(x, beta, y),
            None => p.h.mul_vec(1.0, x, beta, y),
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

impl VelocitySystem for FactorizedSystem {
    type Data = GlobalProblem;

    fn set_rho(
        &mut self,
        p: &GlobalProblem,
        rho: f64,
        active: &[f64],
        changed: bool,
    ) -> Result<(), Error> {
        if changed {
            if let Some(rows) = &mut self.h_rows {
                rows.take_values(&p.h);
            }
            self.gram.recompute(&p.h, active);
            self.factor
                .reassemble(&self.assembly, base_triplets(p), self.gram.triplets());
        }
        self.factor.set_rho(rho)
    }

    fn x_step(
        &mut self,
        p: &GlobalProblem,
        t: &[f64],
        sol: &mut [f64],
        ax: &mut [f64],
        _accuracy: Accuracy,
    ) {
        let n = p.n();
        let mut rhs = std::mem::take(&mut self.rhs);
        rhs[..n].copy_from_slice(&p.f);
        self.h_times(p, t, 1.0, &mut rhs[..n]);
        if let Some(j) = &p.joints {
            for (r, b) in rhs[n..].iter_mut().zip(&j.b) {
                *r = -b;
            }
        }
        sol.copy_from_slice(&rhs);
        self.factor.solve_in_place(sol);
        if p.joints.is_some() {
            // One refinement step against the unregularized system.
            let resid = &mut self.resid;
            self.factor.mul_vec(sol, resid);
            for i in n..resid.len() {
                resid[i] += JOINT_DELTA * sol[i];
            }
            for i in 0..resid.len() {
                resid[i] = rhs[i] - resid[i];
            }
            self.factor.solve_in_place(resid);
            for i in 0..resid.len() {
                sol[i] += resid[i];
            }
        }
        self.rhs = rhs;
        p.h.mul_t_vec(1.0, &sol[..n], 0.0, ax);
    }

    fn h_t_mul(&mut self, p: &GlobalProblem, v: &[f64], out: &mut [f64]) {
        p.h.mul_t_vec(1.0, v, 0.0, out);
    }

    fn h_norm(&mut self, p: &GlobalProblem, t: &[f64]) -> f64 {
        let mut hd = std::mem::take(&mut self.work_n);
        self.h_times(p, t, 0.0, &mut hd);
        let norm = norm2(&hd);
        self.work_n = hd;
        norm
    }

    fn measure(&mut self, p: &GlobalProblem, r: &[f64], sol: &[f64]) -> f64 {
        self.own.measure(p, r, sol)
    }

    fn refactorizations(&self) -> usize {
        self.factor.refactorizations() + self.own.refactorizations()
    }
}

impl ProblemSystem for FactorizedSystem {
    fn own(&mut self) -> &mut OwnProblem {
        &mut self.own
    }

    fn backend(&self) -> LinearSolver {
        LinearSolver::Direct
    }
}
