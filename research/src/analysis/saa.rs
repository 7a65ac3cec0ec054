//! Stationary Anderson acceleration sAA(m) (seed 001 eqs. 11, 14, 16) with fixed
//! coefficients `beta_1..beta_m`:
//!
//! ```text
//! x_{k+1} = (1 + sum beta_i) q(x_k) - sum_i beta_i q(x_{k-i})
//! ```
//!
//! Linearized at the fixed point, each eigenvalue `mu` of `q'(x*)` gives the `m + 1`
//! eigenvalues of the sAA(m) iteration matrix `Psi'_m`: the roots of
//! `lambda^(m+1) - (1 + sum beta_i) mu lambda^m + sum_i beta_i mu lambda^(m-i)` (eq. 15 for
//! m = 1). The asymptotic factor of sAA(m) is the largest root modulus over the spectrum.

use super::poly::{max_root_modulus, roots};
use super::C64;

/// Coefficients (constant term first) of the monic sAA(m) characteristic polynomial for
/// the eigenvalue `mu` of `q'`, `m = betas.len()`.
pub fn char_poly(mu: C64, betas: &[f64]) -> Vec<C64> {
    let m = betas.len();
    let mut a = vec![C64::new(0.0, 0.0); m + 1];
    a[m] = -mu * (1.0 + betas.iter().sum::<f64>());
    for (i, b) in betas.iter().enumerate() {
        a[m - 1 - i] = mu * *b;
    }
    a
}

/// Asymptotic convergence factor `rho(Psi'_m)` of sAA(m) with coefficients `betas` for a
/// map whose Jacobian at the fixed point has the eigenvalues `spectrum` (plain iteration
/// for empty `betas`).
pub fn factor(spectrum: &[C64], betas: &[f64]) -> f64 {
    spectrum
        .iter()
        .map(|&mu| max_root_modulus(&char_poly(mu, betas)))
        .fold(0.0, f64::max)
}

/// All eigenvalues of the sAA(m) iteration matrix `Psi'_m` (`m + 1` per eigenvalue of
/// `q'`), for plots.
pub fn iteration_spectrum(spectrum: &[C64], betas: &[f64]) -> Vec<C64> {
    spectrum
        .iter()
        .flat_map(|&mu| roots(&char_poly(mu, betas)))
        .collect()
}

/// Runs sAA(m) on the map `q` from `x0` for at most `iterations` map evaluations and
/// returns `error(q(x_k))` after each; stops once the error is below `tol`. The first `m`
/// steps are plain, until `m` previous images exist.
pub fn run(
    mut q: impl FnMut(&[f64], &mut [f64]),
    x0: &[f64],
    betas: &[f64],
    iterations: usize,
    tol: f64,
    mut error: impl FnMut(&[f64]) -> f64,
) -> Vec<f64> {
    let (n, m) = (x0.len(), betas.len());
    let mut x = x0.to_vec();
    // images[0] = q(x_k), images[i] = q(x_{k-i}).
    let mut images: Vec<Vec<f64>> = vec![vec![0.0; n]; m + 1];
    let mut history = Vec::with_capacity(iterations);
    for k in 0..iterations {
        images.rotate_right(1);
        q(&x, &mut images[0]);
        let e = error(&images[0]);
        history.push(e);
        if !e.is_finite() || e <= tol {
            break;
        }
        if k < m {
            x.copy_from_slice(&images[0]);
            continue;
        }
        let w0 = 1.0 + betas.iter().sum::<f64>();
        for j in 0..n {
            x[j] = w0 * images[0][j] - (0..m).map(|i| betas[i] * images[i + 1][j]).sum::<f64>();
        }
    }
    history
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a diagonal linear map the measured sAA(1) factor is the predicted one.
    #[test]
    fn linear_map_converges_at_the_predicted_factor() {
        let mus = [0.8, 0.5, 0.1];
        let beta = 0.3; // distinct real roots: no polynomial transient
        let pred = factor(&mus.map(|m| C64::new(m, 0.0)), &[beta]);
        let q = |x: &[f64], out: &mut [f64]| {
            for i in 0..3 {
                out[i] = mus[i] * x[i] + 1.0;
            }
        };
        let fix: Vec<f64> = mus.iter().map(|m| 1.0 / (1.0 - m)).collect();
        let h = run(q, &[0.0; 3], &[beta], 200, 1e-13, |y| {
            y.iter()
                .zip(&fix)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        });
        let k = h.len() - 1;
        let measured = (h[k] / h[k - 40]).powf(1.0 / 40.0);
        assert!((measured - pred).abs() < 0.02, "{measured} vs {pred}");
    }
}
