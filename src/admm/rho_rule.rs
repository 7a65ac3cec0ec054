//! Penalty (rho) rules (docs/algorithms.md §6.2): constant, He, Wohlberg, Spectral.

use crate::csc::dot;

/// A rule that changes rho during the iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RhoRule {
    /// rho never changes.
    Constant,
    /// Residual balancing (eq. 38): multiply or divide rho by `tau` when one residual
    /// exceeds `phi` times the other.
    He {
        /// Multiplier (> 1).
        tau: f64,
        /// Imbalance threshold (> 1).
        phi: f64,
    },
    /// Scaled residual balancing with adaptive multiplier (eqs. 39-41).
    Wohlberg {
        /// Target ratio of the relative residuals.
        xi: f64,
        /// Imbalance threshold (> 1).
        phi: f64,
        /// Largest multiplier.
        tau_max: f64,
    },
    /// Spectral (Barzilai-Borwein) penalty of Xu et al. (eqs. 42-49), every `period`
    /// iterations, safeguarded by the correlation threshold `eps_cor`.
    Spectral {
        /// Correlation threshold.
        eps_cor: f64,
        /// Update period `T_f`.
        period: usize,
    },
}

impl RhoRule {
    /// He with the parameters of docs/algorithms.md §6.2 (tau = 2, phi = 10).
    pub fn he() -> Self {
        RhoRule::He {
            tau: 2.0,
            phi: 10.0,
        }
    }
    /// Wohlberg with the parameters of docs/algorithms.md §6.2 (xi = 1, phi = 10, tau_max = 100).
    pub fn wohlberg() -> Self {
        RhoRule::Wohlberg {
            xi: 1.0,
            phi: 10.0,
            tau_max: 100.0,
        }
    }
    /// Spectral with the parameters of docs/algorithms.md §6.2 (eps_cor = 0.2, T_f = 2).
    pub fn spectral() -> Self {
        RhoRule::Spectral {
            eps_cor: 0.2,
            period: 2,
        }
    }
}

/// What the rules look at after an iteration.
pub struct IterationView<'a> {
    /// Iteration number (0-based).
    pub k: usize,
    /// Current rho.
    pub rho: f64,
    /// `||A x - y - c||`.
    pub primal: f64,
    /// `rho ||A^T (y - y_in)||`.
    pub dual: f64,
    /// `max(||A x||, ||y||, ||c||)`.
    pub primal_scale: f64,
    /// `||A^T zeta||` (scaled dual), computed only for the rules that need it.
    pub dual_scale: f64,
    /// `A x` of this iteration.
    pub ax: &'a [f64],
    /// New `y`.
    pub y: &'a [f64],
    /// New scaled dual.
    pub zeta: &'a [f64],
    /// Scaled dual fed into this iteration.
    pub zeta_in: &'a [f64],
    /// `y` fed into this iteration.
    pub y_in: &'a [f64],
    /// The constraint constant.
    pub c: &'a [f64],
    /// Adds up partial sums across the processes sharing the problem
    /// ([`super::Splitting::sum_across`]).
    pub sum: &'a dyn Fn(&mut [f64]),
}

/// State of a rule across iterations.
pub struct RhoAdapter {
    rule: RhoRule,
    spectral: Option<SpectralMemory>,
}

struct SpectralMemory {
    ax0: Vec<f64>,
    y0: Vec<f64>,
    lambda_hat0: Vec<f64>,
    lambda0: Vec<f64>,
    d_lambda_hat: Vec<f64>,
    d_lambda: Vec<f64>,
    filled: bool,
}

impl RhoAdapter {
    /// A rule for a constraint space of dimension `dim`.
    pub fn new(rule: RhoRule, dim: usize) -> Self {
        let spectral = matches!(rule, RhoRule::Spectral { .. }).then(|| SpectralMemory {
            ax0: vec![0.0; dim],
            y0: vec![0.0; dim],
            lambda_hat0: vec![0.0; dim],
            lambda0: vec![0.0; dim],
            d_lambda_hat: vec![0.0; dim],
            d_lambda: vec![0.0; dim],
            filled: false,
        });
        Self { rule, spectral }
    }

    /// True when the rule needs `||A^T zeta||`.
    pub fn needs_dual_scale(&self) -> bool {
        matches!(self.rule, RhoRule::Wohlberg { .. })
    }

    /// The rho for the next iteration.
    pub fn next_rho(&mut self, it: &IterationView) -> f64 {
        match self.rule {
            RhoRule::Constant => it.rho,
            RhoRule::He { tau, phi } => {
                if it.primal > phi * it.dual {
                    it.rho * tau
                } else if it.dual > phi * it.primal {
                    it.rho / tau
                } else {
                    it.rho
                }
            }
            RhoRule::Wohlberg { xi, phi, tau_max } => {
                let r = it.primal / it.primal_scale.max(f64::MIN_POSITIVE);
                // s_rel = ||A^T (y - y_in)|| / ||A^T zeta||, and it.dual = rho ||A^T (y - y_in)||.
                let s = it.dual / (it.rho * it.dual_scale).max(f64::MIN_POSITIVE);
                if r == 0.0 || s == 0.0 {
                    return it.rho;
                }
                let ratio = (r / (xi * s)).sqrt();
                let tau = if (1.0..tau_max).contains(&ratio) {
                    ratio
                } else if ratio > 1.0 / tau_max && ratio < 1.0 {
                    1.0 / ratio
                } else {
                    tau_max
                };
                if r > xi * phi * s {
                    it.rho * tau
                } else if s > xi * phi * r {
                    it.rho / tau
                } else {
                    it.rho
                }
            }
            RhoRule::Spectral { eps_cor, period } => self.spectral(it, eps_cor, period),
        }
    }

    fn spectral(&mut self, it: &IterationView, eps_cor: f64, period: usize) -> f64 {
        let mem = self
            .spectral
            .as_mut()
            .expect("spectral memory exists for the spectral rule");
        let n = it.ax.len();
        // The unscaled duals in Xu et al.'s sign, which is opposite to the scaled dual's
        // (zeta grows with A x - y - c, their lambda with c - A x + y): lambda_hat =
        // -rho (zeta_in + A x - c - y_in) after the x-step (docs/algorithms.md §6.2), lambda =
        // -rho zeta. With the sign printed in the ADMM-for-contact report, <dF, dw> <= 0 for every convex problem, so the
        // correlation safeguard rejects every estimate and rho never moves.
        for i in 0..n {
            let lambda_hat = -it.rho * (it.zeta_in[i] + it.ax[i] - it.c[i] - it.y_in[i]);
            mem.d_lambda_hat[i] = lambda_hat - mem.lambda_hat0[i];
            mem.d_lambda[i] = -it.rho * it.zeta[i] - mem.lambda0[i];
        }
        let mut rho = it.rho;
        if mem.filled && it.k % period == 1 {
            let dlh = &mem.d_lambda_hat;
            let dl = &mem.d_lambda;
            let (mut hh, mut hl, mut gg, mut gl) = (0.0, 0.0, 0.0, 0.0);
            for i in 0..n {
                let dh = it.ax[i] - mem.ax0[i];
                let dg = -(it.y[i] - mem.y0[i]); // B = -I
                hh += dh * dh;
                hl += dh * dlh[i];
                gg += dg * dg;
                gl += dg * dl[i];
            }
            let mut sums = [hh, hl, gg, gl, dot(dlh, dlh), dot(dl, dl)];
            (it.sum)(&mut sums);
            let [hh, hl, gg, gl, ll_hat, ll] = sums;
            let curvature = |ff: f64, fl: f64, lam: f64| -> Option<(f64, f64)> {
                if ff <= 0.0 || lam <= 0.0 || fl <= 0.0 {
                    return None;
                }
                let sd = lam / fl;
                let mg = fl / ff;
                let est = if 2.0 * mg > sd { mg } else { sd - mg / 2.0 };
                Some((est, fl / (ff.sqrt() * lam.sqrt())))
            };
            let a = curvature(hh, hl, ll_hat)
                .filter(|&(_, cor)| cor > eps_cor)
                .map(|(e, _)| e);
            let b = curvature(gg, gl, ll)
                .filter(|&(_, cor)| cor > eps_cor)
                .map(|(e, _)| e);
            rho = match (a, b) {
                (Some(a), Some(b)) => (a * b).sqrt(),
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => it.rho,
            };
            if !(rho.is_finite() && rho > 0.0) {
                rho = it.rho;
            }
        }
        if !mem.filled || it.k % period == 1 {
            mem.ax0.copy_from_slice(it.ax);
            mem.y0.copy_from_slice(it.y);
            for i in 0..n {
                mem.lambda_hat0[i] = -it.rho * (it.zeta_in[i] + it.ax[i] - it.c[i] - it.y_in[i]);
                mem.lambda0[i] = -it.rho * it.zeta[i];
            }
            mem.filled = true;
        }
        rho
    }
}
