//! A splitting wrapper whose error measure is seed 001's `e_k`: the distance of the engine's
//! iterate `(y, zeta)` to a reference fixed point, relative to the reference's norm. With
//! the engine's per-iteration trace this records the error history of any run (plain ADMM
//! or AA(m)) without touching the loop.

use cadmm::admm::Splitting;
use cadmm::Error;

/// `inner` with the error measure `||(y, zeta) - (y*, zeta*)|| / ||(y*, zeta*)||`.
pub struct Tracked<'a> {
    inner: &'a mut dyn Splitting,
    reference: &'a [f64],
    scale: f64,
}

impl<'a> Tracked<'a> {
    /// Wraps `inner`; `reference` is the stacked fixed point `(y*, zeta*)`.
    pub fn new(inner: &'a mut dyn Splitting, reference: &'a [f64]) -> Self {
        assert_eq!(reference.len(), 2 * inner.dim());
        let scale = cadmm::admm::norm2(reference).max(f64::MIN_POSITIVE);
        Self {
            inner,
            reference,
            scale,
        }
    }

    /// The error measure of a stacked state.
    pub fn distance(&self, state: &[f64]) -> f64 {
        let d: f64 = state
            .iter()
            .zip(self.reference)
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        d.sqrt() / self.scale
    }
}

impl Splitting for Tracked<'_> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        self.inner.set_rho(rho)
    }

    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]) {
        self.inner.x_step(y, zeta, rho, ax)
    }

    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]) {
        self.inner.y_step(ax, zeta, y)
    }

    fn c(&self) -> &[f64] {
        self.inner.c()
    }

    fn norm_at(&mut self, d: &[f64]) -> f64 {
        self.inner.norm_at(d)
    }

    fn update_s(&mut self, ax: &[f64], y: &[f64]) {
        self.inner.update_s(ax, y)
    }

    fn error(&mut self, _ax: &[f64], y: &[f64], zeta: &[f64], _rho: f64) -> f64 {
        let l = y.len();
        let d: f64 = y
            .iter()
            .zip(&self.reference[..l])
            .chain(zeta.iter().zip(&self.reference[l..]))
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        d.sqrt() / self.scale
    }
}
