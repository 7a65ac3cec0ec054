//! The matrix-free v-update system: preconditioned conjugate gradients on
//! `M + rho H D H^T` (symmetric M), solved as exactly as the last error needs
//! ([`super::system::inexact_stop`]). Joint rows, equalities included, are rows of the
//! splitting here (an exact equality would make the system indefinite): the operator is
//! `M + rho [H G] D [H G]^T`, G's columns after H's (docs/algorithms.md §14).

use super::own_problem::OwnProblem;
use super::system::{inexact_stop, Accuracy, ProblemSystem, VelocitySystem};
use crate::bounded_rows::BoundedRows;
use crate::csc::{norm2, CscMatrix};
use crate::linsys::{Gram, GramPcg};
use crate::problem::GlobalProblem;
use crate::settings::LinearSolver;
use crate::types::Error;

/// The conjugate-gradient solver of the v-update and what it keeps of the problem.
pub(crate) struct MatrixFreeSystem {
    pcg: GramPcg,
    own: OwnProblem,
    /// With joint rows: `[H G 0]`, the joint columns after the contacts' and padded with
    /// empty columns to whole triples (the products go contact by contact); `None` without.
    stacked: Option<CscMatrix>,
    /// The rows in the system as of the last change (the preconditioner's), over the
    /// columns of `[H G 0]` (the padding's 0).
    active: Vec<f64>,
    /// The values of `[H G]`, gathered when H's or G's change (kept: no allocation then).
    stacked_values: Vec<f64>,
    /// The splitting's vectors over `[H G]`, padded as `stacked`.
    t: Vec<f64>,
    ax: Vec<f64>,
    rhs: Vec<f64>,
    work_n: Vec<f64>,
}

impl MatrixFreeSystem {
    /// The solver of `p`'s system with the contact rows `active` marks (entries past the
    /// contacts' are not read: every joint row takes part).
    pub fn new(p: &GlobalProblem, active: &[f64], mut own: OwnProblem) -> Self {
        let stacked = stack_joints(p);
        let columns = stacked.as_ref().map_or(p.h.ncols(), CscMatrix::ncols);
        let m = p.w.len();
        let mut all = vec![0.0; columns];
        all[..m].copy_from_slice(&active[..m]);
        all[m..m + p.n_joints()].fill(1.0);
        own.take_all_rows(p);
        let operator = stacked.as_ref().unwrap_or(&p.h);
        Self {
            pcg: GramPcg::new(Gram {
                m: &p.m,
                h: operator,
                active: &all,
            }),
            own,
            t: vec![0.0; columns],
            ax: vec![0.0; columns],
            active: all,
            stacked_values: stacked
                .as_ref()
                .map_or_else(Vec::new, |s| s.values().to_vec()),
            stacked,
            rhs: vec![0.0; p.n()],
            work_n: vec![0.0; p.n()],
        }
    }

    /// The operator `M + rho H D H^T` of `p` (its contacts only: what decides whether the
    /// backend fits).
    pub fn gram<'a>(p: &'a GlobalProblem, active: &'a [f64]) -> Gram<'a> {
        Gram {
            m: &p.m,
            h: &p.h,
            active,
        }
    }
}

impl MatrixFreeSystem {
    /// `[H G 0]` takes the values now in `p` (the same patterns: H's stored values, then
    /// G's, the padding empty), without allocating: this runs whenever the active rows
    /// change, screening included.
    fn restack(&mut self, p: &GlobalProblem) {
        let (Some(stacked), Some(j)) = (&mut self.stacked, &p.joints) else {
            return;
        };
        self.stacked_values.clear();
        self.stacked_values.extend_from_slice(p.h.values());
        self.stacked_values.extend_from_slice(j.g.values());
        // Built from sorted columns, `[H G 0]` takes its values in storage order; they are
        // the problem's, already checked finite.
        stacked
            .set_values("[H G]", &self.stacked_values)
            .expect("the problem's values on the stacked pattern");
    }
}

/// `[H G 0]` for a problem with joints: G's columns after H's, then empty columns up to a
/// multiple of three.
fn stack_joints(p: &GlobalProblem) -> Option<CscMatrix> {
    let j = p.joints.as_ref()?;
    let (h, g) = (&p.h, &j.g);
    let mut colptr = h.colptr().to_vec();
    let mut rowind = h.rowind().to_vec();
    let mut values = h.values().to_vec();
    for k in 0..g.ncols() {
        for (i, x) in g.col(k) {
            rowind.push(i);
            values.push(x);
        }
        colptr.push(rowind.len());
    }
    let columns = h.ncols() + g.ncols();
    let padded = columns.div_ceil(3) * 3;
    colptr.resize(padded + 1, rowind.len());
    let stacked = CscMatrix::new("[H G]", p.n(), padded, colptr, rowind, values);
    Some(stacked.expect("H and G have n rows and sorted columns"))
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
            self.active[..active.len()].copy_from_slice(active);
            self.restack(p);
            self.pcg.take_values(Gram {
                m: &p.m,
                h: self.stacked.as_ref().unwrap_or(&p.h),
                active: &self.active,
            });
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
        let (n, rows) = (p.n(), t.len());
        self.rhs.copy_from_slice(&p.f);
        self.t[..rows].copy_from_slice(t);
        self.pcg.h_mul_add(&self.t, &mut self.rhs);
        // From the last velocity: a warm start that is close after a few iterations.
        let stop = inexact_stop(accuracy, self.own.equation_scale(), norm2(&self.rhs));
        let operator = Gram {
            m: &p.m,
            h: self.stacked.as_ref().unwrap_or(&p.h),
            active: &self.active,
        };
        self.pcg.solve(operator, &self.rhs, &mut sol[..n], stop);
        self.pcg.h_t_mul(&sol[..n], &mut self.ax);
        ax.copy_from_slice(&self.ax[..rows]);
    }

    fn h_t_mul(&mut self, p: &GlobalProblem, v: &[f64], out: &mut [f64]) {
        p.h.mul_t_vec(1.0, v, 0.0, out);
    }

    fn h_norm(&mut self, _p: &GlobalProblem, t: &[f64]) -> f64 {
        self.work_n.fill(0.0);
        self.t[..t.len()].copy_from_slice(t);
        self.pcg.h_mul_add(&self.t, &mut self.work_n);
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

    fn splitting_rows(&self, p: &GlobalProblem) -> BoundedRows {
        BoundedRows::all(p)
    }
}
