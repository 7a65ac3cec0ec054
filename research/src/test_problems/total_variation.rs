//! 1-D total variation denoising (seed 001 section 3.3):
//! `min 1/2 ||y - x||^2 + alpha ||z||_1  s.t.  D x - z = 0`, `D` the forward difference.
//! The x-step solves the tridiagonal system `(I + rho D^T D) x = y + rho D^T (z - u)` with a
//! factorization computed once per rho.

use super::{soft_threshold, InputMemo, Rng, TestProblem};
use cadmm::admm::Splitting;
use cadmm::Error;

/// A total variation test problem.
pub struct TotalVariation {
    data: Vec<f64>,
    alpha: f64,
    rho: f64,
    // LDL^T of the tridiagonal matrix: pivots and sub-diagonal multipliers.
    pivot: Vec<f64>,
    mult: Vec<f64>,
    x: Vec<f64>,
    scratch: Vec<f64>,
    zeros: Vec<f64>,
    memo: InputMemo,
}

/// `out = D^T v` for the forward difference `D` (`v` has one entry fewer than `out`).
fn apply_dt(v: &[f64], out: &mut [f64]) {
    let n = out.len();
    out[0] = -v[0];
    for j in 1..n - 1 {
        out[j] = v[j - 1] - v[j];
    }
    out[n - 1] = v[n - 2];
}

impl TotalVariation {
    /// Signal `data` (length >= 2) and weight `alpha`.
    pub fn new(data: Vec<f64>, alpha: f64) -> Self {
        let n = data.len();
        assert!(n >= 2, "total variation needs at least two samples");
        Self {
            data,
            alpha,
            rho: f64::NAN,
            pivot: vec![0.0; n],
            mult: vec![0.0; n],
            x: vec![0.0; n],
            scratch: vec![0.0; n],
            zeros: vec![0.0; n - 1],
            memo: InputMemo::default(),
        }
    }

    /// The seed's instance: `n` standard normal samples (`n = 1000` in the seed),
    /// `alpha = 0.001 ||y||_inf`, `rho = 10`.
    pub fn random(n: usize, seed: u64) -> Self {
        let data = Rng::new(seed).normal_vec(n);
        let alpha = 0.001 * data.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        Self::new(data, alpha)
    }

    /// [`TotalVariation::random`] at the seed's size.
    pub fn paper() -> Self {
        Self::random(1000, 5)
    }
}

impl Splitting for TotalVariation {
    fn dim(&self) -> usize {
        self.data.len() - 1
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        // I + rho D^T D: diagonal 1 + rho (1, 2, ..., 2, 1), off-diagonal -rho.
        let n = self.data.len();
        for i in 0..n {
            let deg = if i == 0 || i == n - 1 { 1.0 } else { 2.0 };
            let diag = 1.0 + rho * deg;
            if i == 0 {
                self.pivot[0] = diag;
            } else {
                self.mult[i] = -rho / self.pivot[i - 1];
                self.pivot[i] = diag + rho * self.mult[i];
            }
        }
        self.rho = rho;
        Ok(())
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        self.memo.record(y, zeta);
        let n = self.data.len();
        for i in 0..n - 1 {
            ax[i] = y[i] - zeta[i]; // scratch: z - u
        }
        apply_dt(ax, &mut self.x);
        for i in 0..n {
            self.x[i] = self.data[i] + rho * self.x[i];
        }
        // Forward then backward substitution with the LDL^T factors.
        for i in 1..n {
            self.x[i] -= self.mult[i] * self.x[i - 1];
        }
        self.x[n - 1] /= self.pivot[n - 1];
        for i in (0..n - 1).rev() {
            self.x[i] = self.x[i] / self.pivot[i] - self.mult[i + 1] * self.x[i + 1];
        }
        for i in 0..n - 1 {
            ax[i] = self.x[i + 1] - self.x[i];
        }
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        let t = self.alpha / self.rho;
        for i in 0..y.len() {
            y[i] = soft_threshold(ax[i] + zeta[i], t);
        }
    }

    fn c(&self) -> &[f64] {
        &self.zeros
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        apply_dt(d, &mut self.scratch);
        cadmm::admm::norm2(&self.scratch)
    }

    fn error(&mut self, _ax: &[f64], y: &[f64], zeta: &[f64], _rho: f64) -> f64 {
        self.memo.residual(y, zeta)
    }
}

impl TestProblem for TotalVariation {
    fn splitting(&mut self) -> &mut dyn Splitting {
        self
    }

    fn name(&self) -> &str {
        "total-variation"
    }

    fn rho(&self) -> f64 {
        10.0
    }
}
