//! Seeded synthetic data of the seed's experiments (section 3 and appendix 7).

use crate::test_problems::Rng;
use nalgebra::{Complex, DMatrix, DVector};

/// A regression instance `c = D x* + e`.
#[derive(Debug, Clone)]
pub struct RegressionData {
    /// Data matrix `D` (samples x features).
    pub d: DMatrix<f64>,
    /// Measurements `c`.
    pub c: DVector<f64>,
    /// The coefficients the measurements were made from.
    pub x_true: DVector<f64>,
}

/// The correlated synthetic regression of the seed's appendix 7 (Zou and Hastie's design):
/// 50 samples, 40 features; features 1-5, 6-10, 11-15 are three shared normal vectors plus
/// independent `N(0, 1)` noise, features 16-40 independent `N(0, 1)`; `x*` is 3 on the
/// first 15 features and 0 elsewhere; `c = D x* + e` with `e ~ N(0, 0.1^2)`.
pub fn correlated_regression(seed: u64) -> RegressionData {
    let (samples, features, grouped) = (50, 40, 15);
    let mut r = Rng::new(seed);
    let shared: Vec<Vec<f64>> = (0..3).map(|_| r.normal_vec(samples)).collect();
    let mut d = DMatrix::zeros(samples, features);
    for j in 0..features {
        for i in 0..samples {
            let base = if j < grouped { shared[j / 5][i] } else { 0.0 };
            d[(i, j)] = base + r.normal();
        }
    }
    let x_true = DVector::from_fn(features, |j, _| if j < grouped { 3.0 } else { 0.0 });
    let c = &d * &x_true + DVector::from_vec(r.normal_vec(samples)) * 0.1;
    RegressionData { d, c, x_true }
}

/// A noisy piecewise-constant signal.
#[derive(Debug, Clone)]
pub struct SignalData {
    /// The clean signal.
    pub truth: Vec<f64>,
    /// The signal with noise.
    pub noisy: Vec<f64>,
}

/// The one-dimensional denoising signal: 100 samples of 1, three times a random segment
/// `[ceil(j/2), j]` multiplied by an integer in 2..=5 (steps of various heights and
/// widths), plus `N(0, 0.5^2)` noise.
pub fn piecewise_signal(seed: u64) -> SignalData {
    let len = 100;
    let mut r = Rng::new(seed);
    let mut truth = vec![1.0; len];
    for _ in 0..3 {
        let end = r.below(len);
        let factor = (2 + r.below(4)) as f64;
        for v in &mut truth[end.div_ceil(2)..=end] {
            *v *= factor;
        }
    }
    let noisy = truth.iter().map(|v| v + 0.5 * r.normal()).collect();
    SignalData { truth, noisy }
}

/// A phase retrieval instance `c = |D x + e|`.
#[derive(Debug, Clone)]
pub struct PhaseData {
    /// Measurement matrix `D`.
    pub d: DMatrix<Complex<f64>>,
    /// Measured magnitudes `c`.
    pub c: Vec<f64>,
    /// The signal the magnitudes were measured from.
    pub x_true: DVector<Complex<f64>>,
}

/// Phase retrieval data (the seed's synthetic instance has `m = 15000`, `n = 500`): a
/// complex Gaussian `D` (`m x n`, real and imaginary parts `N(0, 1)`), a complex Gaussian
/// `x`, and `c = |D x + e|` with `e` complex, `N(0, 0.1^2)` per part.
pub fn phase_measurements(m: usize, n: usize, seed: u64) -> PhaseData {
    let mut r = Rng::new(seed);
    let mut gauss = |s: f64| Complex::new(s * r.normal(), s * r.normal());
    let d = DMatrix::from_fn(m, n, |_, _| gauss(1.0));
    let x = DVector::from_fn(n, |_, _| gauss(1.0));
    let dx = &d * &x;
    let c = dx.iter().map(|v| (v + gauss(0.1)).norm()).collect();
    PhaseData { d, c, x_true: x }
}

/// A `size x size` matrix with `N(0, 1)` entries (the eigenvector problem).
pub fn leading_eigen_matrix(size: usize, seed: u64) -> DMatrix<f64> {
    let mut r = Rng::new(seed);
    DMatrix::from_fn(size, size, |_, _| r.normal())
}
