//! The best iterate of a run: ADMM's error is not monotone, so a run ended by a limit hands
//! back the iterate with the smallest measured error (docs/algorithms.md §8).

use super::{EngineState, Splitting};

/// The iterate with the smallest measured error of a run: the engine state and the
/// splitting's own part ([`Splitting::save_iterate`]). Offers copy into the buffers made
/// by [`BestIterate::new`].
pub(super) struct BestIterate {
    error: f64,
    state: EngineState,
    own: Vec<f64>,
}

impl BestIterate {
    /// Buffers shaped like `state` and the splitting's own part; no iterate kept yet.
    pub(super) fn new(state: &EngineState, sp: &dyn Splitting) -> Self {
        let mut own = Vec::new();
        sp.save_iterate(&mut own);
        Self {
            error: f64::INFINITY,
            state: state.clone(),
            own,
        }
    }

    /// The error of the kept iterate (infinite while none is kept).
    pub(super) fn error(&self) -> f64 {
        self.error
    }

    /// Keeps the current iterate when `error` is the smallest so far.
    pub(super) fn offer(&mut self, error: f64, state: &EngineState, sp: &dyn Splitting) {
        if error >= self.error {
            return;
        }
        self.state.y.copy_from_slice(&state.y);
        self.state.zeta.copy_from_slice(&state.zeta);
        self.state.ax.copy_from_slice(&state.ax);
        self.state.rho = state.rho;
        // Within the capacity `new` gave it.
        self.own.clear();
        sp.save_iterate(&mut self.own);
        self.error = error;
    }

    /// Makes the kept iterate the current one (only after an offer was kept).
    pub(super) fn restore(&self, state: &mut EngineState, sp: &mut dyn Splitting) {
        state.y.copy_from_slice(&self.state.y);
        state.zeta.copy_from_slice(&self.state.zeta);
        state.ax.copy_from_slice(&self.state.ax);
        state.rho = self.state.rho;
        sp.restore_iterate(&self.own);
    }
}
