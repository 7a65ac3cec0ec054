//! Least squares with a regularizer on a copy of the variable (seed 001 sections 3.1, 3.4,
//! 3.5): `min s/2 ||A x - b||^2 + g(z)  s.t.  x - z = 0`, with `g` ridge, l1 or the
//! nonnegativity indicator. The x-step is one solve with the Cholesky factor of
//! `s A^T A + rho I`, computed once per rho.

use super::{soft_threshold, InputMemo, Rng, TestProblem};
use cadmm::admm::Splitting;
use cadmm::Error;
use nalgebra::{linalg::Cholesky, DMatrix, DVector, Dyn};

/// The regularizer `g(z)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Regularizer {
    /// `lambda ||z||^2` (ridge regression).
    Ridge {
        /// Weight.
        lambda: f64,
    },
    /// `lambda ||z||_1` (lasso).
    L1 {
        /// Weight.
        lambda: f64,
    },
    /// Indicator of `z >= 0` (nonnegative least squares).
    NonNegative,
}

/// A least-squares test problem (ridge, lasso, NNLS).
pub struct LeastSquares {
    name: String,
    notes: String,
    reg: Regularizer,
    paper_rho: f64,
    gram: DMatrix<f64>, // s A^T A
    atb: DVector<f64>,  // s A^T b
    factor: Option<Cholesky<f64, Dyn>>,
    current_rho: f64,
    rhs: DVector<f64>,
    zeros: Vec<f64>,
    memo: InputMemo,
}

impl LeastSquares {
    /// A problem from data `a`, `b`, the data-term scale `s` (1 for `1/2 ||.||^2`, 2 for
    /// `||.||^2`), a regularizer and the penalty to report as the seed's.
    pub fn new(
        name: &str,
        a: &DMatrix<f64>,
        b: &[f64],
        s: f64,
        reg: Regularizer,
        paper_rho: f64,
    ) -> Self {
        let n = a.ncols();
        let gram = a.tr_mul(a) * s;
        let atb = a.tr_mul(&DVector::from_column_slice(b)) * s;
        Self {
            name: name.to_string(),
            notes: String::new(),
            reg,
            paper_rho,
            gram,
            atb,
            factor: None,
            current_rho: f64::NAN,
            rhs: DVector::zeros(n),
            zeros: vec![0.0; n],
            memo: InputMemo::default(),
        }
    }

    /// Ridge regression (section 3.1): `A` is `m x n` sparse with the given density and
    /// standard normal entries, `b` standard normal, `lambda = 1`, `rho = 10`.
    pub fn ridge(m: usize, n: usize, density: f64, seed: u64) -> Self {
        let mut r = Rng::new(seed);
        let a = r.sparse(m, n, density, Rng::normal);
        let b = r.normal_vec(m);
        Self::new(
            "ridge",
            &a,
            &b,
            1.0,
            Regularizer::Ridge { lambda: 1.0 },
            10.0,
        )
    }

    /// Lasso (section 3.4): `A` is `m x n` sparse with the given density and entries uniform
    /// on `[0, 1)`, `b` standard normal, `lambda = 1`, `rho = 10`. Named `lasso-<density>`.
    pub fn lasso(m: usize, n: usize, density: f64, seed: u64) -> Self {
        let mut r = Rng::new(seed);
        let a = r.sparse(m, n, density, Rng::uniform);
        let b = r.normal_vec(m);
        let name = format!("lasso-{density}");
        Self::new(&name, &a, &b, 1.0, Regularizer::L1 { lambda: 1.0 }, 10.0)
    }

    /// Nonnegative least squares `min ||F x - g||^2, x >= 0` (section 3.5) with `rho = 2`
    /// and `g` standard normal, but `F` is `m x n` dense with entries `N(0, 0.03^2)`:
    ///
    /// * the seed's `F` (150 x 300, density 0.001) makes the problem degenerate: most columns
    ///   are empty, so those variables sit exactly on the kink of the projection with a zero
    ///   multiplier, and more unknowns than equations leave a continuum of solutions, where
    ///   `q'` has the eigenvalue 1 (ADMM then converges at ~0.999; the seed's code divides
    ///   the projection by rho, which solves a different, regularized problem);
    /// * with more rows than columns the problem is strictly convex, and scaling `F` so
    ///   that `rho > lambda_max(2 F^T F)` makes `N = 2 rho (2 F^T F + rho I)^-1 - I`
    ///   positive definite, so that `q' ~ (I + N T) / 2` (T a diagonal reflection) is
    ///   similar to a symmetric matrix: the spectrum is real, the case the seed analyses.
    pub fn nnls(m: usize, n: usize, seed: u64) -> Self {
        let mut r = Rng::new(seed);
        let a = DMatrix::from_fn(m, n, |_, _| 0.03 * r.normal());
        let b = r.normal_vec(m);
        let mut p = Self::new("nnls", &a, &b, 2.0, Regularizer::NonNegative, 2.0);
        p.notes = format!(
            "F is {m}x{n} dense N(0, 0.03^2) instead of 150x300 with density 0.001: the seed's \
             instance has a continuum of solutions (q' has the eigenvalue 1); this one is \
             strictly convex with rho > lambda_max(2 F^T F), hence a real spectrum"
        );
        p
    }

    /// The regularizer.
    pub fn regularizer(&self) -> Regularizer {
        self.reg
    }
}

impl Splitting for LeastSquares {
    fn dim(&self) -> usize {
        self.atb.len()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if rho == self.current_rho && self.factor.is_some() {
            return Ok(());
        }
        let mut m = self.gram.clone();
        for i in 0..m.nrows() {
            m[(i, i)] += rho;
        }
        self.factor = Some(Cholesky::new(m).ok_or(Error::NotPositiveDefinite {
            field: "s A^T A + rho I",
        })?);
        self.current_rho = rho;
        Ok(())
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        self.memo.record(y, zeta);
        for i in 0..self.rhs.len() {
            self.rhs[i] = self.atb[i] + rho * (y[i] - zeta[i]);
        }
        if let Some(f) = &self.factor {
            f.solve_mut(&mut self.rhs);
        }
        ax.copy_from_slice(self.rhs.as_slice());
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        let rho = self.current_rho;
        for i in 0..y.len() {
            let v = ax[i] + zeta[i];
            y[i] = match self.reg {
                Regularizer::Ridge { lambda } => rho * v / (2.0 * lambda + rho),
                Regularizer::L1 { lambda } => soft_threshold(v, lambda / rho),
                Regularizer::NonNegative => v.max(0.0),
            };
        }
    }

    fn c(&self) -> &[f64] {
        &self.zeros
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        cadmm::admm::norm2(d)
    }

    fn error(&mut self, _ax: &[f64], y: &[f64], zeta: &[f64], _rho: f64) -> f64 {
        self.memo.residual(y, zeta)
    }
}

impl TestProblem for LeastSquares {
    fn splitting(&mut self) -> &mut dyn Splitting {
        self
    }

    fn name(&self) -> &str {
        &self.name
    }

    fn rho(&self) -> f64 {
        self.paper_rho
    }

    fn notes(&self) -> &str {
        &self.notes
    }
}
