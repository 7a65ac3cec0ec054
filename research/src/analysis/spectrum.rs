//! The spectrum of the fixed-point map's Jacobian `q'(x*)`, by central finite differences at
//! a converged point and a dense eigenvalue solver, and the asymptotic linear factor of a
//! run estimated from its error history.

use super::C64;
use cadmm::Error;
use faer::Mat;

/// Jacobian of `q` at `x` by central differences with step `h`, column-major `n x n`
/// (entry `(i, j)` at `j * n + i`). Exact for a piecewise-linear map when no kink lies
/// within `h` of `x`; `O(h^2)` otherwise.
pub fn jacobian_fd(mut q: impl FnMut(&[f64], &mut [f64]), x: &[f64], h: f64) -> Vec<f64> {
    let n = x.len();
    let mut jac = vec![0.0; n * n];
    let (mut xp, mut fp, mut fm) = (x.to_vec(), vec![0.0; n], vec![0.0; n]);
    for j in 0..n {
        xp[j] = x[j] + h;
        q(&xp, &mut fp);
        xp[j] = x[j] - h;
        q(&xp, &mut fm);
        xp[j] = x[j];
        for i in 0..n {
            jac[j * n + i] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    jac
}

/// Eigenvalues of the column-major `n x n` matrix `a`.
pub fn eigenvalues(a: &[f64], n: usize) -> Result<Vec<C64>, Error> {
    assert_eq!(a.len(), n * n);
    let m = Mat::from_fn(n, n, |i, j| a[j * n + i]);
    m.eigenvalues()
        .map(|v| v.into_iter().map(|z| C64::new(z.re, z.im)).collect())
        .map_err(|e| Error::Unsupported(format!("eigenvalues of the Jacobian: {e:?}")))
}

/// The eigenvalues of `q'(x*)` with the quantities the analysis reads from them.
#[derive(Debug, Clone)]
pub struct Spectrum {
    /// The eigenvalues.
    pub eigenvalues: Vec<C64>,
}

impl Spectrum {
    /// Spectral radius `rho(q'(x*))`.
    pub fn radius(&self) -> f64 {
        self.eigenvalues.iter().fold(0.0, |m, z| m.max(z.norm()))
    }

    /// Largest imaginary part in absolute value.
    pub fn max_imag(&self) -> f64 {
        self.eigenvalues.iter().fold(0.0, |m, z| m.max(z.im.abs()))
    }

    /// True when every imaginary part is below `tol` times the spectral radius (finite
    /// differences leave ~1e-10 imaginary noise on a real spectrum).
    pub fn is_real(&self, tol: f64) -> bool {
        self.max_imag() <= tol * self.radius().max(f64::MIN_POSITIVE)
    }

    /// Smallest and largest real part.
    pub fn real_range(&self) -> (f64, f64) {
        self.eigenvalues
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| {
                (lo.min(z.re), hi.max(z.re))
            })
    }
}

/// Asymptotic linear factor of a run from its error history (`errors[k]` after
/// `iterations[k]` map evaluations): the least-squares slope of `log(error)` over the last
/// half of the stretch where the error is below 1e-2 of its start and above 1e-10 of it or
/// ten times its smallest value (past the transient, before round-off). `None` when that
/// stretch has fewer than four points.
pub fn asymptotic_factor(iterations: &[usize], errors: &[f64]) -> Option<f64> {
    let n = errors.len().min(iterations.len());
    let first = errors.iter().copied().find(|e| e.is_finite() && *e > 0.0)?;
    let floor = errors[..n]
        .iter()
        .copied()
        .filter(|e| *e > 0.0)
        .fold(f64::INFINITY, f64::min);
    let (hi, lo) = (1e-2 * first, (1e-10 * first).max(10.0 * floor));
    let start = (0..n).find(|&k| errors[k] <= hi)?;
    let end = (start..n).rev().find(|&k| errors[k] >= lo)?;
    if end < start + 3 {
        return None;
    }
    let from = start + (end - start) / 2;
    let pts: Vec<(f64, f64)> = (from..=end)
        .filter(|&k| errors[k] > 0.0)
        .map(|k| (iterations[k] as f64, errors[k].ln()))
        .collect();
    if pts.len() < 4 {
        return None;
    }
    let np = pts.len() as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / np, b + y / np));
    let (sxy, sxx) = pts.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    Some((sxy / sxx).exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_and_eigenvalues_of_a_rotation() {
        // q(x) = 0.9 R(theta) x: eigenvalues 0.9 e^{+-i theta}.
        let (c, s) = (0.9 * 0.3f64.cos(), 0.9 * 0.3f64.sin());
        let q = |x: &[f64], y: &mut [f64]| {
            y[0] = c * x[0] - s * x[1];
            y[1] = s * x[0] + c * x[1];
        };
        let j = jacobian_fd(q, &[1.0, 2.0], 1e-6);
        let sp = Spectrum {
            eigenvalues: eigenvalues(&j, 2).unwrap(),
        };
        assert!((sp.radius() - 0.9).abs() < 1e-9);
        assert!((sp.max_imag() - s).abs() < 1e-9 && !sp.is_real(1e-6));
    }

    #[test]
    fn factor_of_a_geometric_history() {
        let it: Vec<usize> = (1..=200).collect();
        let e: Vec<f64> = it
            .iter()
            .map(|&k| 0.7f64.powi(k as i32) * (1.0 + 0.3 * 0.2f64.powi(k as i32)))
            .map(|v| v.max(1e-16))
            .collect();
        let f = asymptotic_factor(&it, &e).unwrap();
        assert!((f - 0.7).abs() < 1e-6, "{f}");
    }
}
