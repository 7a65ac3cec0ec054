//! The matrix-free v-update system: preconditioned conjugate gradients on
//! `M + rho H D H^T` (symmetric M, no joints), solved as exactly as the last error needs
//! ([`super::system::inexact_stop`]).

use super::own_problem::OwnProblem;
use super::system::{inexact_stop, Accuracy, ProblemSystem, VelocitySystem};
use crate::csc::norm2;
use crate::linsys::{Gram, GramPcg};
use crate::problem::GlobalProblem;
use crate::settings::LinearSolver;
use crate::types::Error;

/// The conjugate-gradient solver of the v-update and what it keeps of the problem.
pub(crate) struct MatrixFreeSystem {
    pcg: GramPcg,
    own: OwnProblem,
    /// The rows in the system as of the last change (the preconditioner's).
    active: Vec<f64>,
    rhs: Vec<f64>,
    work_n: Vec<f64>,
}

impl MatrixFreeSystem {
    /// The solver of `p`'s system with the rows `active` marks.
    pub fn new(p: &GlobalProblem, active: &[f64], own: OwnProblem) -> Self {
        Self {
            pcg: GramPcg::new(Self::gram(p, active)),
            own,
            active: active.to_vec(),
            rhs: vec![0.0; p.n()],
            work_n: vec![0.0; p.n()],
        }
    }

    /// The operator `M + rho H D H^T` of `p`.
    pub fn gram<'a>(p: &'a GlobalProblem, active: &'a [f64]) -> Gram<'a> {
        Gram {
            m: &p.m,
            h: &p.h,
            active,
        }
    }
}

impl VelocitySystem for MatrixFreeSystem {
    type Data = GlobalProblem;

    fn set_rho(
        &mut self,
        p: &GlobalProblem,
        rho: f64,
        active: &[f64],
        changed: bool,
    ) -> Result<(), Error> {
        if changed {
            self.active.copy_from_slice(active);
            self.pcg.take_values(Self::gram(p, active));
        }
        self.pcg.set_rho(rho)
    }

    fn x_step(
        &mut self,
        p: &GlobalProblem,
        t: &[f64],
        sol: &mut [f64],
        ax: &mut [f64],
        accuracy: Accuracy,
    ) {
        self.rhs.copy_from_slice(&p.f);
        self.pcg.h_mul_add(t, &mut self.rhs);
        // From the last velocity: a warm start that is close after a few iterations.
        let stop = inexact_stop(accuracy, self.own.equation_scale(), norm2(&self.rhs));
        self.pcg
            .solve(Self::gram(p, &self.active), &self.rhs, sol, stop);
        self.pcg.h_t_mul(sol, ax);
    }

    fn h_t_mul(&mut self, p: &GlobalProblem, v: &[f64], out: &mut [f64]) {
        p.h.mul_t_vec(1.0, v, 0.0, out);
    }

    fn h_norm(&mut self, _p: &GlobalProblem, t: &[f64]) -> f64 {
        self.work_n.fill(0.0);
        self.pcg.h_mul_add(t, &mut self.work_n);
        norm2(&self.work_n)
    }

    fn measure(&mut self, p: &GlobalProblem, r: &[f64], sol: &[f64]) -> f64 {
        self.own.measure(p, r, sol)
    }

    fn refactorizations(&self) -> usize {
        self.pcg.factorizations() + self.own.refactorizations()
    }

    fn linear_iterations(&self) -> usize {
        self.pcg.iterations()
    }
}

impl ProblemSystem for MatrixFreeSystem {
    fn own(&mut self) -> &mut OwnProblem {
        &mut self.own
    }

    fn backend(&self) -> LinearSolver {
        LinearSolver::Iterative
    }

    fn set_threads(&mut self, threads: usize) {
        self.pcg.set_threads(threads);
    }
}
