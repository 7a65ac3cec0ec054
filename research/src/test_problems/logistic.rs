//! l2-regularized logistic regression (seed 001 section 3.2) and its box-constrained
//! variant (section 3.6) on Madelon-shaped data. The x-step minimizes the smooth part plus
//! `rho/2 ||x - v||^2` by Newton's method that keeps the Cholesky factor of the Hessian while
//! it still contracts fast (chord steps): near convergence, and in the finite-difference
//! Jacobian, an x-step then costs a few gradients instead of a factorization each.

use super::{madelon_like, InputMemo, TestProblem};
use cadmm::admm::norm2;
use cadmm::admm::Splitting;
use cadmm::Error;
use nalgebra::{linalg::Cholesky, DMatrix, DVector, Dyn};

/// Which of the two seed problems.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LogisticKind {
    /// `min loss(x) + lambda ||z||^2, x - z = 0` (section 3.2), `lambda = 2`.
    Regularized,
    /// `min loss(x) + lambda ||x||^2 + I(||z||_inf <= bound), x - z = 0` (section 3.6).
    Boxed,
}

/// A logistic regression test problem; `x = (bias, weights)`.
pub struct Logistic {
    kind: LogisticKind,
    lambda: f64,
    bound: f64,
    notes: String,
    c: DMatrix<f64>, // rows -y_i (1, a_i)
    grad_scale: f64, // || |C|^T 1 || / m: scale of the loss gradient, for the stop test
    rho: f64,
    factor: Option<Cholesky<f64, Dyn>>,
    stale: bool,
    x: DVector<f64>,
    v: DVector<f64>,
    zeros: Vec<f64>,
    memo: InputMemo,
}

fn sigmoid(t: f64) -> f64 {
    if t >= 0.0 {
        1.0 / (1.0 + (-t).exp())
    } else {
        let e = t.exp();
        e / (1.0 + e)
    }
}

impl Logistic {
    /// A problem from features `a` (`m x n`), labels in `{-1, +1}`, the kind, `lambda` and
    /// the box bound (ignored for [`LogisticKind::Regularized`]).
    pub fn new(
        a: &DMatrix<f64>,
        labels: &[f64],
        kind: LogisticKind,
        lambda: f64,
        bound: f64,
    ) -> Self {
        let (m, n) = a.shape();
        let c = DMatrix::from_fn(m, n + 1, |i, j| {
            -labels[i] * if j == 0 { 1.0 } else { a[(i, j - 1)] }
        });
        let colsum = DVector::from_fn(n + 1, |j, _| c.column(j).abs().sum() / m as f64);
        Self {
            kind,
            lambda,
            bound,
            notes: String::new(),
            grad_scale: colsum.norm(),
            c,
            rho: f64::NAN,
            factor: None,
            stale: true,
            x: DVector::zeros(n + 1),
            v: DVector::zeros(n + 1),
            zeros: vec![0.0; n + 1],
            memo: InputMemo::default(),
        }
    }

    /// The seed's instance on 200 x 250 Madelon-shaped data (the seed uses every 10th sample
    /// and every 2nd feature of Madelon), `lambda = 2`, `rho = 10`. The box of the
    /// constrained variant is `||x||_inf <= 0.01` instead of 1: at `lambda = 2` the weights
    /// are ~0.03 at most, so the unit box would be inactive and the problem would just be
    /// the regularized one (the seed's code scales its projection by 1/rho, which makes it
    /// active but changes the problem).
    pub fn paper(kind: LogisticKind) -> Self {
        let (a, y) = madelon_like(200, 250, 6);
        let mut p = Self::new(&a, &y, kind, 2.0, 0.01);
        p.notes =
            "synthetic Madelon-shaped data (200 x 250, Madelon's recipe) replaces Madelon".into();
        if kind == LogisticKind::Boxed {
            p.notes +=
                "; box ||x||_inf <= 0.01 instead of 1 (the unit box is inactive at lambda = 2)";
        }
        p
    }

    /// Smooth part of the x-step objective at `x`: its gradient into `g`.
    fn gradient(&self, x: &DVector<f64>, g: &mut DVector<f64>, s: &mut DVector<f64>) {
        let m = self.c.nrows() as f64;
        self.c.mul_to(x, s);
        s.apply(|t| *t = sigmoid(*t) / m);
        self.c.tr_mul_to(s, g);
        let kappa = self.kappa();
        for i in 0..g.len() {
            g[i] += 2.0 * kappa * x[i] + self.rho * (x[i] - self.v[i]);
        }
    }

    /// Weight of `||x||^2` inside f.
    fn kappa(&self) -> f64 {
        match self.kind {
            LogisticKind::Regularized => 0.0,
            LogisticKind::Boxed => self.lambda,
        }
    }

    fn factorize(&mut self, x: &DVector<f64>) {
        let m = self.c.nrows() as f64;
        let t = &self.c * x;
        let w = t.map(|t| {
            let p = sigmoid(t);
            (p * (1.0 - p) / m).sqrt()
        });
        let b = DMatrix::from_fn(self.c.nrows(), self.c.ncols(), |i, j| w[i] * self.c[(i, j)]);
        let mut h = b.tr_mul(&b);
        for i in 0..h.nrows() {
            h[(i, i)] += 2.0 * self.kappa() + self.rho;
        }
        // rho > 0 makes h positive definite.
        self.factor = Cholesky::new(h);
        self.stale = false;
    }

    /// Minimizes `loss(x) + kappa ||x||^2 + rho/2 ||x - v||^2` from the previous x.
    fn solve_x(&mut self) {
        let (mut g, mut gt) = (DVector::zeros(self.x.len()), DVector::zeros(self.x.len()));
        let mut s = DVector::zeros(self.c.nrows());
        let mut x = self.x.clone();
        self.gradient(&x, &mut g, &mut s);
        // A few ulps of the gradient's terms: below that its value is round-off.
        let tol = 2.0 * f64::EPSILON * (self.grad_scale + self.rho * (x.norm() + self.v.norm()));
        let mut fresh = false;
        for _ in 0..100 {
            let gn = g.norm();
            if gn <= tol {
                break;
            }
            if self.stale || self.factor.is_none() {
                self.factorize(&x);
                fresh = true;
            }
            let Some(f) = &self.factor else { break };
            let dx = f.solve(&(-&g));
            // Backtrack on the gradient norm: a descent direction for it when the factor
            // is current; a stale factor that fails is refreshed.
            let mut t = 1.0;
            let mut accepted = false;
            for _ in 0..40 {
                let xt = &x + &dx * t;
                self.gradient(&xt, &mut gt, &mut s);
                if gt.norm() < gn {
                    x = xt;
                    accepted = true;
                    break;
                }
                t *= 0.5;
            }
            if !accepted {
                if fresh {
                    break; // no progress with the exact Hessian: at round-off level
                }
                self.stale = true;
                continue;
            }
            std::mem::swap(&mut g, &mut gt);
            // A slow contraction means the factor is too old.
            self.stale = g.norm() > 0.25 * gn;
            fresh = false;
        }
        self.x = x;
    }
}

impl Splitting for Logistic {
    fn dim(&self) -> usize {
        self.x.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if rho != self.rho {
            self.rho = rho;
            self.stale = true;
        }
        Ok(())
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], _rho: f64, ax: &mut [f64]) {
        self.memo.record(y, zeta);
        for i in 0..y.len() {
            self.v[i] = y[i] - zeta[i];
        }
        self.solve_x();
        ax.copy_from_slice(self.x.as_slice());
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        for i in 0..y.len() {
            let v = ax[i] + zeta[i];
            y[i] = match self.kind {
                LogisticKind::Regularized => self.rho * v / (2.0 * self.lambda + self.rho),
                LogisticKind::Boxed => v.clamp(-self.bound, self.bound),
            };
        }
    }

    fn c(&self) -> &[f64] {
        &self.zeros
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        norm2(d)
    }

    fn error(&mut self, _ax: &[f64], y: &[f64], zeta: &[f64], _rho: f64) -> f64 {
        self.memo.residual(y, zeta)
    }
}

impl TestProblem for Logistic {
    fn splitting(&mut self) -> &mut dyn Splitting {
        self
    }

    fn name(&self) -> &str {
        match self.kind {
            LogisticKind::Regularized => "logistic",
            LogisticKind::Boxed => "constrained-logistic",
        }
    }

    fn rho(&self) -> f64 {
        10.0
    }

    fn notes(&self) -> &str {
        &self.notes
    }
}
