//! l0 regularized linear regression (seed 002 eq. 8): `min 1/2 ||D s - c||^2 + mu ||n||_0
//! s.t. s - n = 0`. The smooth solve uses the Cholesky factor of `D^T D + rho I`, computed
//! once per rho; the nonsmooth prox is hard thresholding.

use super::data::RegressionData;
use super::{hard_threshold, NonconvexProblem, Quality};
use cadmm::admm::norm2;
use cadmm::Error;
use nalgebra::{linalg::Cholesky, DMatrix, DVector, Dyn};

/// An l0 regression instance.
pub struct L0Regression {
    d: DMatrix<f64>,
    c: DVector<f64>,
    mu: f64,
    gram: DMatrix<f64>,
    dtc: DVector<f64>,
    factor: Option<Cholesky<f64, Dyn>>,
    factor_rho: f64,
}

impl L0Regression {
    /// `min 1/2 ||D x - c||^2 + mu ||x||_0` on `data` (the seed uses `mu = 1`).
    pub fn new(data: &RegressionData, mu: f64) -> Self {
        Self {
            gram: data.d.tr_mul(&data.d),
            dtc: data.d.tr_mul(&data.c),
            d: data.d.clone(),
            c: data.c.clone(),
            mu,
            factor: None,
            factor_rho: f64::NAN,
        }
    }

    /// The objective at `x`.
    pub fn objective(&self, x: &[f64]) -> f64 {
        let r = &self.d * DVector::from_column_slice(x) - &self.c;
        0.5 * r.norm_squared() + self.mu * x.iter().filter(|v| **v != 0.0).count() as f64
    }
}

impl NonconvexProblem for L0Regression {
    fn name(&self) -> &str {
        "l0-regression"
    }

    fn dim(&self) -> usize {
        self.d.ncols()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if rho == self.factor_rho {
            return Ok(());
        }
        let m = &self.gram + DMatrix::identity(self.dim(), self.dim()) * rho;
        self.factor = Some(Cholesky::new(m).ok_or(Error::NotPositiveDefinite {
            field: "D^T D + rho I",
        })?);
        self.factor_rho = rho;
        Ok(())
    }

    fn smooth_step(&self, t: &[f64], rho: f64, s: &mut Vec<f64>, ks: &mut [f64]) {
        let rhs = &self.dtc + DVector::from_column_slice(t) * rho;
        let f = self.factor.as_ref().expect("set_rho before smooth_step");
        let x = f.solve(&rhs);
        s.clear();
        s.extend_from_slice(x.as_slice());
        ks.copy_from_slice(x.as_slice());
    }

    fn nonsmooth_prox(&self, t: &[f64], rho: f64, n: &mut [f64]) {
        for (ni, ti) in n.iter_mut().zip(t) {
            *ni = hard_threshold(*ti, self.mu / rho);
        }
    }

    fn norm_kt(&self, d: &[f64]) -> f64 {
        norm2(d)
    }

    fn initial(&self) -> Vec<f64> {
        vec![0.0; self.dim()]
    }

    /// The objective at the sparse block `n` (the smooth block is never exactly sparse).
    fn quality(&self, _s: &[f64], n: &[f64]) -> Quality {
        Quality {
            objective: self.objective(n),
            psnr: None,
        }
    }
}
