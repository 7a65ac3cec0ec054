//! The next input point of the ADMM loop from an iteration's input and output: the plain
//! output, Nesterov's relaxation with or without restart (docs/algorithms.md §6.4), or an
//! Anderson point under its safeguard (§7; the extrapolation itself is in `anderson.rs`).

use super::anderson::Anderson;
use super::Relaxation;

/// Restart's eta: momentum needs this residual decrease (Goldstein et al., docs/algorithms.md §6.4).
const RESTART_ETA: f64 = 0.999;

/// Nesterov's sequence starts, and restarts, at alpha = 1: then beta = 0, a plain step.
const ALPHA_START: f64 = 1.0;

/// What the Anderson safeguard made of an iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Screen {
    /// Its input was not an Anderson point.
    Plain,
    /// Its input was an Anderson point, kept.
    Accepted,
    /// Its input was an Anderson point whose fixed-point residual grew: the iteration is
    /// void, and the next input is the plain point the Anderson point replaced.
    Rejected,
}

/// Produces the next input `(y_in, zeta_in)` of the loop.
pub(super) enum Accelerator {
    /// The iteration's output.
    Plain,
    /// Nesterov's relaxation (docs/algorithms.md §6.4).
    Nesterov(Nesterov),
    /// Anderson acceleration with its safeguard (docs/algorithms.md §7).
    Anderson(Safeguarded),
}

impl Accelerator {
    /// Anderson acceleration of memory `anderson`, tried every `interval` iterations, when
    /// on (it replaces the relaxation then), else `relaxation`, for a loop starting from
    /// `(y0, zeta0)`.
    pub(super) fn new(
        anderson: usize,
        interval: usize,
        relaxation: Relaxation,
        y0: &[f64],
        zeta0: &[f64],
    ) -> Self {
        if anderson > 0 {
            return Self::Anderson(Safeguarded::new(anderson, interval, y0.len()));
        }
        match relaxation {
            Relaxation::None => Self::Plain,
            Relaxation::Nesterov => Self::Nesterov(Nesterov::new(false, y0, zeta0)),
            Relaxation::NesterovRestart => Self::Nesterov(Nesterov::new(true, y0, zeta0)),
        }
    }

    /// The safeguard, from the iteration's squared fixed-point residual `res_sq`, its squared
    /// primal residual plus `||y+ - y_in||^2`. On a rejection the next input is written into
    /// `y_in`, `z_in`.
    pub(super) fn screen(&mut self, res_sq: f64, y_in: &mut [f64], z_in: &mut [f64]) -> Screen {
        match self {
            Self::Anderson(a) => a.screen(res_sq, y_in, z_in),
            _ => Screen::Plain,
        }
    }

    /// Overwrites the iteration's input `(y_in, z_in)` with the next input, from the
    /// output `(y, zeta)` of the `k`-th (0-based) iteration; `sum` adds up partial sums
    /// across the processes sharing the problem.
    pub(super) fn next_input(
        &mut self,
        k: usize,
        y: &[f64],
        zeta: &[f64],
        y_in: &mut [f64],
        z_in: &mut [f64],
        sum: &dyn Fn(&mut [f64]),
    ) {
        match self {
            Self::Plain => {
                y_in.copy_from_slice(y);
                z_in.copy_from_slice(zeta);
            }
            Self::Nesterov(n) => n.next_input(y, zeta, y_in, z_in, sum),
            Self::Anderson(a) => a.next_input(k, y, zeta, y_in, z_in, sum),
        }
    }

    /// The penalty changed: the scaled duals kept are multiplied by `s = rho_old / rho_new`
    /// (docs/algorithms.md §6.3), and momentum and Anderson history, which would mix
    /// iterates of two maps, restart. (Nesterov momentum carried across the spectral rule's
    /// frequent changes kept vp-R-Spectral from converging on GFC3D_Example1.)
    pub(super) fn rho_changed(&mut self, s: f64) {
        match self {
            Self::Plain => {}
            Self::Nesterov(n) => {
                n.z_prev.iter_mut().for_each(|v| *v *= s);
                n.alpha = ALPHA_START;
            }
            Self::Anderson(a) => {
                let l = a.plain.len() / 2;
                a.plain[l..].iter_mut().for_each(|v| *v *= s);
                a.restart();
            }
        }
    }
}

/// Nesterov's relaxation: the next input extrapolates from the previous output.
pub(super) struct Nesterov {
    /// Apply the restart rule.
    restart: bool,
    alpha: f64,
    /// The restart rule's reference residual.
    e_prev: f64,
    /// The previous output.
    y_prev: Vec<f64>,
    z_prev: Vec<f64>,
}

impl Nesterov {
    fn new(restart: bool, y0: &[f64], zeta0: &[f64]) -> Self {
        Self {
            restart,
            alpha: ALPHA_START,
            e_prev: f64::INFINITY,
            y_prev: y0.to_vec(),
            z_prev: zeta0.to_vec(),
        }
    }

    fn next_input(
        &mut self,
        y: &[f64],
        zeta: &[f64],
        y_in: &mut [f64],
        z_in: &mut [f64],
        sum: &dyn Fn(&mut [f64]),
    ) {
        let relax = !self.restart || self.keeps_momentum(y, zeta, y_in, z_in, sum);
        if relax {
            // alpha' = (1 + sqrt(1 + 4 alpha^2)) / 2, beta = (alpha - 1) / alpha'.
            let alpha_next = 0.5 * (1.0 + (1.0 + 4.0 * self.alpha * self.alpha).sqrt());
            let beta = (self.alpha - 1.0) / alpha_next;
            for i in 0..y.len() {
                y_in[i] = y[i] + beta * (y[i] - self.y_prev[i]);
                z_in[i] = zeta[i] + beta * (zeta[i] - self.z_prev[i]);
            }
            self.alpha = alpha_next;
        } else {
            y_in.copy_from_slice(y);
            z_in.copy_from_slice(zeta);
        }
        self.y_prev.copy_from_slice(y);
        self.z_prev.copy_from_slice(zeta);
    }

    /// The restart rule: momentum continues while the combined residual of the iteration
    /// falls by `RESTART_ETA`; otherwise it restarts and the reference is relaxed.
    fn keeps_momentum(
        &mut self,
        y: &[f64],
        zeta: &[f64],
        y_in: &[f64],
        z_in: &[f64],
        sum: &dyn Fn(&mut [f64]),
    ) -> bool {
        let mut e = [norm_diff_sq(zeta, z_in) + norm_diff_sq(y, y_in)];
        sum(&mut e);
        let e = e[0];
        if e < RESTART_ETA * self.e_prev {
            self.e_prev = e;
            true
        } else {
            self.alpha = ALPHA_START;
            self.e_prev /= RESTART_ETA;
            false
        }
    }
}

/// Anderson acceleration on the stacked state `(y, zeta)`, with its safeguard.
pub(super) struct Safeguarded {
    aa: Anderson,
    /// An Anderson point is tried every this many iterations.
    interval: usize,
    /// The iteration's stacked input and output, and the extrapolated point.
    x: Vec<f64>,
    g: Vec<f64>,
    next: Vec<f64>,
    /// The plain point an Anderson point replaced: where a rejection restarts.
    plain: Vec<f64>,
    /// The current input is an Anderson point.
    tried: bool,
    /// Fixed-point residual of the last kept iteration.
    res_prev: f64,
}

impl Safeguarded {
    fn new(memory: usize, interval: usize, l: usize) -> Self {
        Self {
            aa: Anderson::new(memory, 2 * l),
            interval: interval.max(1),
            x: vec![0.0; 2 * l],
            g: vec![0.0; 2 * l],
            next: vec![0.0; 2 * l],
            plain: vec![0.0; 2 * l],
            tried: false,
            res_prev: f64::INFINITY,
        }
    }

    /// Forgets the history: the next input is not an Anderson point.
    fn restart(&mut self) {
        self.aa.reset();
        self.tried = false;
        self.res_prev = f64::INFINITY;
    }

    /// Rejects an Anderson point whose fixed-point residual
    /// `sqrt(||A x+ - c - y+||^2 + ||y+ - y_in||^2)` (of `res_sq`) exceeds the last kept one.
    fn screen(&mut self, res_sq: f64, y_in: &mut [f64], z_in: &mut [f64]) -> Screen {
        let res = res_sq.sqrt();
        if self.tried && res > self.res_prev {
            self.aa.reset();
            self.tried = false;
            let l = y_in.len();
            y_in.copy_from_slice(&self.plain[..l]);
            z_in.copy_from_slice(&self.plain[l..]);
            return Screen::Rejected;
        }
        self.res_prev = res;
        if self.tried {
            Screen::Accepted
        } else {
            Screen::Plain
        }
    }

    fn next_input(
        &mut self,
        k: usize,
        y: &[f64],
        zeta: &[f64],
        y_in: &mut [f64],
        z_in: &mut [f64],
        sum: &dyn Fn(&mut [f64]),
    ) {
        let l = y.len();
        self.x[..l].copy_from_slice(y_in);
        self.x[l..].copy_from_slice(z_in);
        self.g[..l].copy_from_slice(y);
        self.g[l..].copy_from_slice(zeta);
        // The history grows every iteration; the extrapolated point is used only on the
        // iterations that try it.
        let extrapolated = self.aa.step_across(&self.x, &self.g, &mut self.next, sum);
        self.tried = extrapolated && (k + 1) % self.interval == 0;
        self.plain.copy_from_slice(&self.g);
        let next = if self.tried { &self.next } else { &self.g };
        y_in.copy_from_slice(&next[..l]);
        z_in.copy_from_slice(&next[l..]);
    }
}

fn norm_diff_sq(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum()
}
