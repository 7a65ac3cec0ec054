//! The leading eigenvector (seed 002 eq. 14): `min -||D s||^2 + indicator_{||n|| = 1}(n)
//! s.t. s - n = 0`. The smooth solve is `(rho I - 2 D^T D) s = rho t`, an LU solve
//! (the matrix is indefinite when `rho < 2 lambda_max(D^T D)`: the step is then a
//! stationary point of a nonconvex quadratic, as in the seed), factored once per rho.

use super::{NonconvexProblem, Quality};
use crate::test_problems::Rng;
use cadmm::admm::norm2;
use cadmm::Error;
use nalgebra::{linalg::LU, DMatrix, DVector, Dyn};

/// An eigenvector instance.
pub struct Eigenvector {
    d: DMatrix<f64>,
    gram: DMatrix<f64>,
    factor: Option<LU<f64, Dyn, Dyn>>,
    factor_rho: f64,
    start_seed: u64,
}

impl Eigenvector {
    /// `max ||D x||^2  s.t.  ||x|| = 1` (the leading eigenvector of `D^T D`); the start is a
    /// random unit vector drawn with `start_seed`.
    pub fn new(d: DMatrix<f64>, start_seed: u64) -> Self {
        Self {
            gram: d.tr_mul(&d),
            d,
            factor: None,
            factor_rho: f64::NAN,
            start_seed,
        }
    }

    /// `D^T D`.
    pub fn gram(&self) -> &DMatrix<f64> {
        &self.gram
    }

    /// `||D x||^2`.
    pub fn rayleigh(&self, x: &[f64]) -> f64 {
        (&self.d * DVector::from_column_slice(x)).norm_squared()
    }
}

/// `t / ||t||` (the first unit vector when `t = 0`), scaled first so that a huge `t` (a
/// diverging iterate) does not overflow the norm.
fn normalize(t: &[f64], n: &mut [f64]) {
    let big = t.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scaled_norm = t.iter().map(|v| (v / big).powi(2)).sum::<f64>().sqrt();
    for (i, ni) in n.iter_mut().enumerate() {
        *ni = if big > 0.0 && big.is_finite() {
            t[i] / big / scaled_norm
        } else if i == 0 {
            1.0
        } else {
            0.0
        };
    }
}

impl NonconvexProblem for Eigenvector {
    fn name(&self) -> &str {
        "eigenvector"
    }

    fn dim(&self) -> usize {
        self.d.ncols()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if rho == self.factor_rho {
            return Ok(());
        }
        let m = DMatrix::identity(self.dim(), self.dim()) * rho - &self.gram * 2.0;
        let lu = m.lu();
        if !lu.is_invertible() {
            return Err(Error::NotPositiveDefinite {
                field: "rho I - 2 D^T D (singular)",
            });
        }
        self.factor = Some(lu);
        self.factor_rho = rho;
        Ok(())
    }

    fn smooth_step(&self, t: &[f64], rho: f64, s: &mut Vec<f64>, ks: &mut [f64]) {
        let rhs = DVector::from_column_slice(t) * rho;
        let f = self.factor.as_ref().expect("set_rho before smooth_step");
        let x = f.solve(&rhs).expect("factor checked invertible");
        s.clear();
        s.extend_from_slice(x.as_slice());
        ks.copy_from_slice(x.as_slice());
    }

    fn nonsmooth_prox(&self, t: &[f64], _rho: f64, n: &mut [f64]) {
        normalize(t, n);
    }

    fn norm_kt(&self, d: &[f64]) -> f64 {
        norm2(d)
    }

    fn initial(&self) -> Vec<f64> {
        let mut r = Rng::new(self.start_seed);
        let v = r.normal_vec(self.dim());
        let mut n = vec![0.0; v.len()];
        normalize(&v, &mut n);
        n
    }

    /// The objective `-||D n||^2` at the unit vector `n`.
    fn quality(&self, _s: &[f64], n: &[f64]) -> Quality {
        Quality {
            objective: -self.rayleigh(n),
            psnr: None,
        }
    }
}
