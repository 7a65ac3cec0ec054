//! l0 regularized denoising of a 1D signal (seed 002 eq. 10): `min 1/2 ||s - c||^2 +
//! mu ||n||_0  s.t.  grad s - n = 0`. In 1D, `I + rho grad^T grad` is tridiagonal: the
//! smooth solve is an O(n) LDL^T solve (the seed's FFT solve assumes periodic boundaries;
//! this is the exact non-periodic one), factored once per rho.

use super::data::SignalData;
use super::{hard_threshold, NonconvexProblem, Quality};
use cadmm::admm::norm2;
use cadmm::Error;

/// `out = grad u`, the forward differences `u[i + 1] - u[i]` (`out` has one entry fewer).
pub fn forward_difference(u: &[f64], out: &mut [f64]) {
    for i in 0..out.len() {
        out[i] = u[i + 1] - u[i];
    }
}

/// `out = grad^T d` (`out` has one entry more than `d`).
fn forward_difference_transpose(d: &[f64], out: &mut [f64]) {
    let n = out.len();
    for j in 0..n {
        let left = if j > 0 { d[j - 1] } else { 0.0 };
        let right = if j + 1 < n { d[j] } else { 0.0 };
        out[j] = left - right;
    }
}

/// The LDL^T factor of a symmetric positive definite tridiagonal matrix.
#[derive(Debug, Clone)]
pub struct Tridiagonal {
    d: Vec<f64>,
    l: Vec<f64>,
}

impl Tridiagonal {
    /// Factors the matrix with diagonal `diag` and off-diagonal `off` (one entry fewer).
    pub fn factor(diag: &[f64], off: &[f64]) -> Result<Self, Error> {
        let n = diag.len();
        let (mut d, mut l) = (vec![0.0; n], vec![0.0; n.saturating_sub(1)]);
        for i in 0..n {
            d[i] = diag[i] - if i > 0 { l[i - 1] * off[i - 1] } else { 0.0 };
            if d[i].is_nan() || d[i] <= 0.0 {
                return Err(Error::NotPositiveDefinite {
                    field: "I + rho grad^T grad",
                });
            }
            if i + 1 < n {
                l[i] = off[i] / d[i];
            }
        }
        Ok(Self { d, l })
    }

    /// Solves in place.
    pub fn solve(&self, x: &mut [f64]) {
        let n = x.len();
        for i in 1..n {
            x[i] -= self.l[i - 1] * x[i - 1];
        }
        for i in 0..n {
            x[i] /= self.d[i];
        }
        for i in (0..n.saturating_sub(1)).rev() {
            x[i] -= self.l[i] * x[i + 1];
        }
    }
}

/// A 1D l0 denoising instance.
pub struct L0Denoising {
    signal: SignalData,
    mu: f64,
    factor: Option<Tridiagonal>,
    factor_rho: f64,
}

impl L0Denoising {
    /// `min 1/2 ||x - c||^2 + mu ||grad x||_0` for the noisy signal of `signal` (the seed
    /// uses `mu = 1` for its 1D signal).
    pub fn new(signal: SignalData, mu: f64) -> Self {
        Self {
            signal,
            mu,
            factor: None,
            factor_rho: f64::NAN,
        }
    }

    /// PSNR of `x` against the clean signal, with the clean signal's peak.
    pub fn psnr(&self, x: &[f64]) -> f64 {
        let t = &self.signal.truth;
        let peak = t.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mse = x.iter().zip(t).map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / t.len() as f64;
        10.0 * (peak * peak / mse).log10()
    }

    /// The noisy signal's PSNR.
    pub fn noisy_psnr(&self) -> f64 {
        self.psnr(&self.signal.noisy)
    }
}

impl NonconvexProblem for L0Denoising {
    fn name(&self) -> &str {
        "l0-denoising-1d"
    }

    fn dim(&self) -> usize {
        self.signal.noisy.len() - 1
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if rho == self.factor_rho {
            return Ok(());
        }
        let n = self.signal.noisy.len();
        let diag: Vec<f64> = (0..n)
            .map(|i| 1.0 + rho * if i == 0 || i + 1 == n { 1.0 } else { 2.0 })
            .collect();
        self.factor = Some(Tridiagonal::factor(&diag, &vec![-rho; n - 1])?);
        self.factor_rho = rho;
        Ok(())
    }

    fn smooth_step(&self, t: &[f64], rho: f64, s: &mut Vec<f64>, ks: &mut [f64]) {
        s.resize(self.signal.noisy.len(), 0.0);
        forward_difference_transpose(t, s);
        for (si, ci) in s.iter_mut().zip(&self.signal.noisy) {
            *si = ci + rho * *si;
        }
        self.factor
            .as_ref()
            .expect("set_rho before smooth_step")
            .solve(s);
        forward_difference(s, ks);
    }

    fn nonsmooth_prox(&self, t: &[f64], rho: f64, n: &mut [f64]) {
        for (ni, ti) in n.iter_mut().zip(t) {
            *ni = hard_threshold(*ti, self.mu / rho);
        }
    }

    fn norm_kt(&self, d: &[f64]) -> f64 {
        let mut out = vec![0.0; d.len() + 1];
        forward_difference_transpose(d, &mut out);
        norm2(&out)
    }

    fn initial(&self) -> Vec<f64> {
        vec![0.0; self.dim()]
    }

    /// The objective at the signal `s`, its l0 term counted on the thresholded gradient `n`;
    /// the PSNR of `s`.
    fn quality(&self, s: &[f64], n: &[f64]) -> Quality {
        let fit: f64 = s
            .iter()
            .zip(&self.signal.noisy)
            .map(|(a, b)| 0.5 * (a - b) * (a - b))
            .sum();
        let jumps = n.iter().filter(|v| **v != 0.0).count() as f64;
        Quality {
            objective: fit + self.mu * jumps,
            psnr: Some(self.psnr(s)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The transpose is the adjoint: <grad u, d> = <u, grad^T d>.
    #[test]
    fn transpose_is_adjoint() {
        let u = [1.0, -2.0, 0.5, 4.0];
        let d = [0.3, -1.0, 2.0];
        let (mut gu, mut gtd) = ([0.0; 3], [0.0; 4]);
        forward_difference(&u, &mut gu);
        forward_difference_transpose(&d, &mut gtd);
        let a: f64 = gu.iter().zip(&d).map(|(x, y)| x * y).sum();
        let b: f64 = u.iter().zip(&gtd).map(|(x, y)| x * y).sum();
        assert!((a - b).abs() < 1e-14, "{a} {b}");
    }
}
