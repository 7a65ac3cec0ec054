//! One ADMM iteration of a [`Splitting`] as a fixed-point map, for the analysis (finite
//! differences, stationary AA). The engine's loop stays the one way to *solve*; this is
//! the single step `q` it iterates, at a fixed rho:
//!
//! ```text
//! w     = A x(y, zeta) - c + zeta       (x-step)
//! y+    = prox_g(w)                     (y-step)
//! zeta+ = w - y+
//! ```
//!
//! `q(y, zeta) = L(X(y, zeta))` with `X(y, zeta) = w` and `L(w) = (prox_g(w), w -
//! prox_g(w))`, so the stacked Jacobian `q' = L' X'` (size 2l) and the reduced one
//! `X' L'` of `w -> X(L(w))` (size l) have the same nonzero eigenvalues: the reduced map
//! gives the spectrum at an eighth of the eigenvalue cost.

use cadmm::admm::Splitting;
use cadmm::Error;

/// The ADMM fixed-point map of a splitting at a fixed penalty.
pub struct AdmmMap<'a> {
    sp: &'a mut dyn Splitting,
    rho: f64,
    ax: Vec<f64>,
    w: Vec<f64>,
    zeros: Vec<f64>,
    state: Vec<f64>,
}

impl<'a> AdmmMap<'a> {
    /// The map of `sp` at penalty `rho` (sets it on the splitting).
    pub fn new(sp: &'a mut dyn Splitting, rho: f64) -> Result<Self, Error> {
        sp.set_rho(rho)?;
        let l = sp.dim();
        Ok(Self {
            sp,
            rho,
            ax: vec![0.0; l],
            w: vec![0.0; l],
            zeros: vec![0.0; l],
            state: vec![0.0; 2 * l],
        })
    }

    /// Dimension `l` of the constraint space (the stacked state has `2 l` entries).
    pub fn dim(&self) -> usize {
        self.ax.len()
    }

    /// Stacked map: `state = (y, zeta)` to `out = (y+, zeta+)`.
    pub fn apply(&mut self, state: &[f64], out: &mut [f64]) {
        let l = self.dim();
        let (y, zeta) = state.split_at(l);
        self.sp.x_step(y, zeta, self.rho, &mut self.ax);
        let c = self.sp.c();
        for i in 0..l {
            self.w[i] = self.ax[i] - c[i] + zeta[i];
        }
        let (y1, z1) = out.split_at_mut(l);
        self.sp.y_step(&self.ax, zeta, y1);
        for i in 0..l {
            z1[i] = self.w[i] - y1[i];
        }
    }

    /// Reduced map on the prox input: `w` to `A x(L(w)) - c + (w - prox_g(w))`.
    pub fn apply_reduced(&mut self, w: &[f64], out: &mut [f64]) {
        let l = self.dim();
        let mut state = std::mem::take(&mut self.state);
        self.split(w, &mut state);
        let (y, zeta) = state.split_at(l);
        self.sp.x_step(y, zeta, self.rho, &mut self.ax);
        let c = self.sp.c();
        for i in 0..l {
            out[i] = self.ax[i] - c[i] + zeta[i];
        }
        self.state = state;
    }

    /// `L(w) = (prox_g(w), w - prox_g(w))`: the state whose prox input is `w`.
    pub fn split(&mut self, w: &[f64], state: &mut [f64]) {
        let l = self.dim();
        let c = self.sp.c();
        // y_step evaluates prox_g(ax - c + zeta): pass ax = w + c, zeta = 0.
        for i in 0..l {
            self.w[i] = w[i] + c[i];
        }
        let (y, zeta) = state.split_at_mut(l);
        self.sp.y_step(&self.w, &self.zeros, y);
        for i in 0..l {
            zeta[i] = w[i] - y[i];
        }
    }
}

/// The prox input `w = y + zeta` of a state that is an output of the map.
pub fn prox_input(state: &[f64]) -> Vec<f64> {
    let l = state.len() / 2;
    (0..l).map(|i| state[i] + state[l + i]).collect()
}
