//! The factorized v-update system: `M + rho H D H^T` assembled once (new values scattered
//! through the assembly maps), or with joints the quasi-definite
//! `[[M + rho H D H^T, G_E, rho G_B], [G_E^T, -(C + delta I), 0], [rho G_B^T, 0, -rho I]]`
//! over the velocities, the equality rows (`C` their compliances; `delta` corrected by one
//! step of iterative refinement) and the bounded rows, whose unknown is
//! `mu = G_B^T v - t_B / rho`: eliminating it leaves `M + rho (H D H^T + G_B G_B^T)`, the
//! bounded rows' share of the x-step's quadratic (docs/algorithms.md §4.2). Dense or sparse
//! ([`Factor`]).

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
    /// The joint rows with a finite bound (columns of `G`), in the splitting's order.
    bounded: Vec<usize>,
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
            bounded: p.bounded_rows(),
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

/// The constant part of the v-update system, in a fixed order: M, then for each entry of
/// an equality row of `G`, `G` and `G^T`, then the equality rows' compliance and
/// regularization.
fn base_triplets(p: &GlobalProblem) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
    let n = p.n();
    let joints = p.joints.iter().flat_map(move |j| {
        let g = triplets(&j.g)
            .filter(|&(_, k, _)| !j.is_bounded(k))
            .flat_map(move |(i, k, v)| [(i, n + k, v), (n + k, i, v)]);
        let reg = (0..j.g.ncols())
            .filter(|&k| !j.is_bounded(k))
            .map(move |k| (n + k, n + k, -(j.compliance[k] + JOINT_DELTA)));
        g.chain(reg)
    });
    triplets(&p.m).chain(joints)
}

/// The bounded rows' part of the system's slope (the coefficient of rho), in a fixed
/// order: `G_B` and `G_B^T` entry by entry, then `-I` on their diagonal.
fn bounded_triplets(p: &GlobalProblem) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
    let n = p.n();
    p.joints.iter().flat_map(move |j| {
        let g = triplets(&j.g)
            .filter(|&(_, k, _)| j.is_bounded(k))
            .flat_map(move |(i, k, v)| [(i, n + k, v), (n + k, i, v)]);
        let diagonal = (0..j.g.ncols())
            .filter(|&k| j.is_bounded(k))
            .map(move |k| (n + k, n + k, -1.0));
        g.chain(diagonal)
    })
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
    let slope = gram.triplets().chain(bounded_triplets(p));
    let (matrix, assembly) = ParamMatrix::from_triplets(n + np, base_triplets(p), slope, symmetric);
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
            let slope = self.gram.triplets().chain(bounded_triplets(p));
            self.factor
                .reassemble(&self.assembly, base_triplets(p), slope);
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
        let (n, m) = (p.n(), p.w.len());
        let mut rhs = std::mem::take(&mut self.rhs);
        rhs[..n].copy_from_slice(&p.f);
        self.h_times(p, &t[..m], 1.0, &mut rhs[..n]);
        if let Some(j) = &p.joints {
            for (r, b) in rhs[n..].iter_mut().zip(&j.b) {
                *r = -b;
            }
            for (q, &k) in self.bounded.iter().enumerate() {
                rhs[n + k] = t[m + q];
            }
        }
        sol.copy_from_slice(&rhs);
        self.factor.solve_in_place(sol);
        if let Some(j) = &p.joints {
            // One refinement step against the unregularized system (the bounded rows
            // carry no regularization).
            let resid = &mut self.resid;
            self.factor.mul_vec(sol, resid);
            for k in 0..j.b.len() {
                if !j.is_bounded(k) {
                    resid[n + k] += JOINT_DELTA * sol[n + k];
                }
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
        self.h_t_mul(p, &sol[..n], ax);
    }

    fn h_t_mul(&mut self, p: &GlobalProblem, v: &[f64], out: &mut [f64]) {
        let m = p.w.len();
        p.h.mul_t_vec(1.0, v, 0.0, &mut out[..m]);
        if let Some(j) = &p.joints {
            for (q, &k) in self.bounded.iter().enumerate() {
                out[m + q] = j.g.col(k).map(|(i, x)| x * v[i]).sum();
            }
        }
    }

    fn h_norm(&mut self, p: &GlobalProblem, t: &[f64]) -> f64 {
        let m = p.w.len();
        let mut hd = std::mem::take(&mut self.work_n);
        self.h_times(p, &t[..m], 0.0, &mut hd);
        if let Some(j) = &p.joints {
            for (q, &k) in self.bounded.iter().enumerate() {
                for (i, x) in j.g.col(k) {
                    hd[i] += x * t[m + q];
                }
            }
        }
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

    fn sparse_cholesky_cost(&self) -> Option<(f64, usize)> {
        self.factor.sparse_cholesky_cost()
    }
}
