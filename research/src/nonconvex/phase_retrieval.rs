//! Phase retrieval (seed 002 eq. 12): `min 1/2 || |n| - c ||^2  s.t.  D s - n = 0` with
//! complex `D` and `s`. The engine works on real vectors, so a complex vector of length m
//! is stored as 2m reals `(re_0, im_0, re_1, im_1, ...)`: Euclidean norms and inner
//! products (`Re <a, b>`) are then the complex ones, which is what the spectral rule's
//! curvature estimates need. The smooth block has `F = 0`: its solve is the least-squares
//! solve `s = (D^H D)^-1 D^H t`, independent of rho (Cholesky of `D^H D` once).

use super::{NonconvexProblem, PhaseData, Quality};
use crate::test_problems::Rng;
use cadmm::Error;
use nalgebra::{linalg::Cholesky, Complex, DMatrix, DVector, Dyn};

/// `argmin_y 1/2 (|y| - c)^2 + rho/2 |y - z|^2` for complex `z` and `c >= 0`: the phase of
/// `z` (1 when `z = 0`) with magnitude `(rho |z| + c) / (1 + rho)`.
pub fn abs_prox(z: Complex<f64>, c: f64, rho: f64) -> Complex<f64> {
    let r = z.norm();
    let phase = if r > 0.0 {
        z / r
    } else {
        Complex::new(1.0, 0.0)
    };
    phase * ((rho * r + c) / (1.0 + rho))
}

fn to_complex(v: &[f64]) -> DVector<Complex<f64>> {
    DVector::from_fn(v.len() / 2, |i, _| Complex::new(v[2 * i], v[2 * i + 1]))
}

fn to_reals(v: &DVector<Complex<f64>>, out: &mut [f64]) {
    for (i, z) in v.iter().enumerate() {
        out[2 * i] = z.re;
        out[2 * i + 1] = z.im;
    }
}

/// A phase retrieval instance.
pub struct PhaseRetrieval {
    d: DMatrix<Complex<f64>>,
    c: Vec<f64>,
    gram: Cholesky<Complex<f64>, Dyn>,
    start_seed: u64,
}

impl PhaseRetrieval {
    /// `min 1/2 || |D x| - c ||^2`; the start is `D x0` for a complex Gaussian `x0` drawn
    /// with `start_seed`.
    pub fn new(data: PhaseData, start_seed: u64) -> Result<Self, Error> {
        let PhaseData { d, c, .. } = data;
        let gram =
            Cholesky::new(d.ad_mul(&d)).ok_or(Error::NotPositiveDefinite { field: "D^H D" })?;
        Ok(Self {
            d,
            c,
            gram,
            start_seed,
        })
    }

    /// The objective at `x` (complex, as pairs of reals).
    pub fn objective(&self, x: &[f64]) -> f64 {
        self.objective_complex(&to_complex(x))
    }

    /// The objective at a complex `x`.
    pub fn objective_complex(&self, x: &DVector<Complex<f64>>) -> f64 {
        let dx = &self.d * x;
        dx.iter()
            .zip(&self.c)
            .map(|(z, c)| 0.5 * (z.norm() - c) * (z.norm() - c))
            .sum()
    }
}

impl NonconvexProblem for PhaseRetrieval {
    fn name(&self) -> &str {
        "phase-retrieval"
    }

    fn dim(&self) -> usize {
        2 * self.d.nrows()
    }

    fn set_rho(&mut self, _rho: f64) -> Result<(), Error> {
        Ok(())
    }

    fn smooth_step(&self, t: &[f64], _rho: f64, s: &mut Vec<f64>, ks: &mut [f64]) {
        let x = self.gram.solve(&self.d.ad_mul(&to_complex(t)));
        s.resize(2 * x.len(), 0.0);
        to_reals(&x, s);
        to_reals(&(&self.d * x), ks);
    }

    fn nonsmooth_prox(&self, t: &[f64], rho: f64, n: &mut [f64]) {
        for i in 0..self.c.len() {
            let y = abs_prox(Complex::new(t[2 * i], t[2 * i + 1]), self.c[i], rho);
            n[2 * i] = y.re;
            n[2 * i + 1] = y.im;
        }
    }

    fn norm_kt(&self, d: &[f64]) -> f64 {
        self.d.ad_mul(&to_complex(d)).norm()
    }

    fn initial(&self) -> Vec<f64> {
        let mut r = Rng::new(self.start_seed);
        let x0 = DVector::from_fn(self.d.ncols(), |_, _| Complex::new(r.normal(), r.normal()));
        let mut y = vec![0.0; self.dim()];
        to_reals(&(&self.d * x0), &mut y);
        y
    }

    /// The seed updates the magnitude fit first in its Figure 1 (its eqs. 30-32).
    fn prox_is_smooth(&self) -> bool {
        true
    }

    /// The objective at the image `s` (the nonsmooth block is only its measured copy).
    fn quality(&self, s: &[f64], _n: &[f64]) -> Quality {
        Quality {
            objective: self.objective(s),
            psnr: None,
        }
    }
}
