//! Global form: `x = v`, `y = u~`, `A = H^T`, `c = -w - Phi(s)`, g = indicator of `K*`.
//!
//! v-update: `(M + rho H H^T) v = f + rho H (u~ + c - zeta)`; with joints the
//! quasi-definite system `[[M + rho H H^T, G], [G^T, -delta I]] [v; -lambda] = [.; -b]`
//! (delta tiny, corrected by one step of iterative refinement).

use super::{de_saxce_shift, initial_shift};
use crate::admm::Splitting;
use crate::cone::{get3, project_dual_cone, set3};
use crate::csc::norm2;
use crate::error::Error;
use crate::linsys::param_matrix::{gram_triplets, triplets};
use crate::linsys::{FactorKind, ParamMatrix, SparseFactor};
use crate::measure::complementarity_residual;
use crate::problem::GlobalProblem;

/// Regularization of the joint block of the quasi-definite system.
const JOINT_DELTA: f64 = 1e-9;

/// Relative asymmetry above which M is treated as non-symmetric.
const SYMMETRY_TOL: f64 = 1e-12;

/// The global contact problem as an ADMM splitting.
pub struct GlobalSplitting {
    p: GlobalProblem,
    mass: SparseFactor,
    factor: SparseFactor,
    /// Current velocity (and joint multipliers after it, when there are joints).
    sol: Vec<f64>,
    rhs: Vec<f64>,
    resid: Vec<f64>,
    c: Vec<f64>,
    phi: Vec<f64>,
    work_n: Vec<f64>,
    work_n2: Vec<f64>,
    work_m: Vec<f64>,
    r: Vec<f64>,
}

impl GlobalSplitting {
    /// Analyses and factorizes `M` (to check it is positive definite) and prepares the
    /// v-update system.
    pub fn new(p: GlobalProblem) -> Result<Self, Error> {
        let n = p.n();
        let m = 3 * p.n_contacts();
        // M alone first: a clear error when M is not positive definite.
        let mut mass = SparseFactor::new("M", mass_matrix(&p), FactorKind::Cholesky)?;
        mass.set_rho(0.0)?;
        let (matrix, kind) = system_matrix(&p);
        let dim = matrix.n;
        let factor = SparseFactor::new("M + rho H H^T", matrix, kind)?;
        let mut phi = vec![0.0; m];
        initial_shift(&p.mu, p.h.norm_fro(), &mut phi);
        let c = p.w.iter().zip(&phi).map(|(w, s)| -w - s).collect();
        Ok(Self {
            mass,
            factor,
            sol: vec![0.0; dim],
            rhs: vec![0.0; dim],
            resid: vec![0.0; dim],
            c,
            phi,
            work_n: vec![0.0; n],
            work_n2: vec![0.0; n],
            work_m: vec![0.0; m],
            r: vec![0.0; m],
            p,
        })
    }

    /// Takes new values on the same sizes and patterns: numeric refactorization only.
    pub fn update(&mut self, p: GlobalProblem) -> Result<(), Error> {
        let (matrix, _) = system_matrix(&p);
        self.mass.replace_matrix(mass_matrix(&p))?;
        self.mass.set_rho(0.0)?;
        self.factor.replace_matrix(matrix)?;
        self.p = p;
        self.reset_shift();
        Ok(())
    }

    /// The problem.
    pub fn problem(&self) -> &GlobalProblem {
        &self.p
    }

    /// Velocity of the last x-step.
    pub fn v(&self) -> &[f64] {
        &self.sol[..self.p.n()]
    }

    /// Joint multipliers of the last x-step (empty without joints).
    pub fn lambda(&self) -> Vec<f64> {
        // The system is solved for -lambda (see the module comment).
        self.sol[self.p.n()..].iter().map(|x| -x).collect()
    }

    /// Numeric factorizations so far.
    pub fn refactorizations(&self) -> usize {
        self.factor.refactorizations() + self.mass.refactorizations()
    }

    /// Restarts the De Saxce shift from the initial guess of eq. (61).
    pub fn reset_shift(&mut self) {
        initial_shift(&self.p.mu, self.p.h.norm_fro(), &mut self.phi);
        self.refresh_c();
    }

    /// Sets the De Saxce shift from a velocity (warm start).
    pub fn shift_from_velocity(&mut self, v: &[f64]) {
        let mut u = self.p.w.clone();
        self.p.h.mul_t_vec(1.0, v, 1.0, &mut u);
        de_saxce_shift(&u, &self.p.mu, &mut self.phi);
        self.refresh_c();
    }

    fn refresh_c(&mut self) {
        for i in 0..self.c.len() {
            self.c[i] = -self.p.w[i] - self.phi[i];
        }
    }
}

/// Symmetric part of M (upper triangle): positive definite exactly when `x^T M x > 0`.
fn mass_matrix(p: &GlobalProblem) -> ParamMatrix {
    let half = triplets(&p.m).flat_map(|(i, j, v)| [(i, j, 0.5 * v), (j, i, 0.5 * v)]);
    ParamMatrix::from_triplets(p.n(), half, [], true)
}

/// `M + rho H H^T`, or the joint system around it: `[[M + rho H H^T, G], [G^T, -delta I]]`.
/// Cholesky / quasi-definite LDL^T on the upper triangle when M is symmetric (up to
/// round-off), LU on the full pattern otherwise (some FEM files carry a non-symmetric M).
fn system_matrix(p: &GlobalProblem) -> (ParamMatrix, FactorKind) {
    let n = p.n();
    let gram = gram_triplets(&p.h);
    let symmetric = p.m.is_symmetric(SYMMETRY_TOL);
    match &p.joints {
        None if symmetric => (
            ParamMatrix::from_triplets(n, triplets(&p.m), gram, true),
            FactorKind::Cholesky,
        ),
        None => (
            ParamMatrix::from_triplets(n, triplets(&p.m), gram, false),
            FactorKind::Lu,
        ),
        Some(j) => {
            let np = j.g.ncols();
            let g = triplets(&j.g).flat_map(|(i, k, v)| [(i, n + k, v), (n + k, i, v)]);
            let reg = (0..np).map(|k| (n + k, n + k, -JOINT_DELTA));
            let base: Vec<_> = triplets(&p.m).chain(g).chain(reg).collect();
            if symmetric {
                (
                    ParamMatrix::from_triplets(n + np, base, gram, true),
                    FactorKind::QuasiDefinite { n_positive: n },
                )
            } else {
                (
                    ParamMatrix::from_triplets(n + np, base, gram, false),
                    FactorKind::Lu,
                )
            }
        }
    }
}

impl Splitting for GlobalSplitting {
    fn dim(&self) -> usize {
        self.c.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        self.factor.set_rho(rho)
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        let n = self.p.n();
        for i in 0..self.work_m.len() {
            self.work_m[i] = rho * (y[i] + self.c[i] - zeta[i]);
        }
        self.rhs[..n].copy_from_slice(&self.p.f);
        self.p.h.mul_vec(1.0, &self.work_m, 1.0, &mut self.rhs[..n]);
        if let Some(j) = &self.p.joints {
            for (t, b) in self.rhs[n..].iter_mut().zip(&j.b) {
                *t = -b;
            }
        }
        self.sol.copy_from_slice(&self.rhs);
        self.factor.solve_in_place(&mut self.sol);
        if self.p.joints.is_some() {
            // One refinement step against the unregularized system.
            self.factor.mul_vec(&self.sol, &mut self.resid);
            for i in n..self.resid.len() {
                self.resid[i] += JOINT_DELTA * self.sol[i];
            }
            for i in 0..self.resid.len() {
                self.resid[i] = self.rhs[i] - self.resid[i];
            }
            self.factor.solve_in_place(&mut self.resid);
            for i in 0..self.resid.len() {
                self.sol[i] += self.resid[i];
            }
        }
        self.p.h.mul_t_vec(1.0, &self.sol[..n], 0.0, ax);
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        for (i, &mu) in self.p.mu.iter().enumerate() {
            let a = get3(ax, i);
            let c = get3(&self.c, i);
            let z = get3(zeta, i);
            set3(
                y,
                i,
                project_dual_cone(
                    [a[0] - c[0] + z[0], a[1] - c[1] + z[1], a[2] - c[2] + z[2]],
                    mu,
                ),
            );
        }
    }

    fn c(&self) -> &[f64] {
        &self.c
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        self.p.h.mul_vec(1.0, d, 0.0, &mut self.work_n);
        norm2(&self.work_n)
    }

    fn update_s(&mut self, ax: &[f64], _y: &[f64]) -> f64 {
        // u = H^T v + w
        for i in 0..ax.len() {
            self.work_m[i] = ax[i] + self.p.w[i];
        }
        let change = de_saxce_shift(&self.work_m, &self.p.mu, &mut self.phi);
        self.refresh_c();
        change
    }

    fn error(&mut self, ax: &[f64], _y: &[f64], zeta: &[f64], rho: f64) -> f64 {
        let n = self.p.n();
        for i in 0..zeta.len() {
            self.r[i] = -rho * zeta[i];
        }
        let v = &self.sol[..n];
        if !v.iter().chain(self.r.iter()).all(|x| x.is_finite()) {
            return f64::INFINITY;
        }
        // Equation residual -M v + H r + G lambda + f.
        self.p.m.mul_vec(1.0, v, 0.0, &mut self.work_n);
        self.p.h.mul_vec(1.0, &self.r, 0.0, &mut self.work_n2);
        let mut joint_error = 0.0;
        if let Some(j) = &self.p.joints {
            let minus_lambda = &self.sol[n..];
            j.g.mul_vec(-1.0, minus_lambda, 1.0, &mut self.work_n2);
            let mut res = 0.0f64;
            let mut gv_sq = 0.0f64;
            for (k, b) in j.b.iter().enumerate() {
                let gv: f64 = j.g.col(k).map(|(i, g)| g * v[i]).sum();
                res += (gv + b).powi(2);
                gv_sq += gv * gv;
            }
            let scale = gv_sq.sqrt().max(norm2(&j.b));
            joint_error = if scale > 1.5e-8 {
                res.sqrt() / scale
            } else {
                res.sqrt()
            };
        }
        let (mv, hr) = (norm2(&self.work_n), norm2(&self.work_n2));
        let mut eq = 0.0;
        for i in 0..n {
            eq += (-self.work_n[i] + self.work_n2[i] + self.p.f[i]).powi(2);
        }
        let scale = norm2(&self.p.f).max(mv).max(hr);
        let e1 = if scale > 1.5e-8 {
            eq.sqrt() / scale
        } else {
            eq.sqrt()
        };
        for i in 0..ax.len() {
            self.work_m[i] = ax[i] + self.p.w[i];
        }
        let comp = complementarity_residual(&self.r, &self.work_m, &self.p.mu);
        let scale = norm2(&self.work_m).max(norm2(&self.r));
        let e2 = if scale > 1.5e-8 { comp / scale } else { comp };
        e1 + e2 + joint_error
    }
}
