//! The one ADMM engine, and its extension API: a problem plugs in by implementing
//! [`Splitting`] (the contact forms do, and so do the research problems of the crate
//! `cadmm-research`); the engine owns the loop, the stopping test, the penalty rules,
//! relaxation/restart and Anderson acceleration.
//!
//! Every problem is written as `min f(x) + g(y)  s.t.  A x - y = c` in scaled form, with the
//! iteration state `(y, zeta)` in the constraint space:
//!
//! ```text
//! x+    = argmin f(x) + rho/2 ||A x - y - c + zeta||^2      (Splitting::x_step, gives A x+)
//! y+    = prox_g(A x+ - c + zeta)                           (Splitting::y_step)
//! zeta+ = zeta + A x+ - c - y+
//! ```

mod accelerator;
mod anderson;
mod best_iterate;
mod engine;
mod handover;
mod rho_rule;
mod state;
mod variant;

/// Euclidean norm, for plug-ins computing their residuals and scales.
pub use crate::csc::norm2;
pub use anderson::Anderson;
pub(crate) use engine::run_until;
pub use engine::{run, EngineOutcome, EngineSettings};
pub use handover::Handover;
pub use rho_rule::RhoRule;
pub use state::EngineState;
pub use variant::{Relaxation, Variant, VARIANT_NAMES};

use crate::types::Error;
use std::time::Instant;

/// What a problem supplies to the engine.
pub trait Splitting {
    /// Dimension of the constraint space (length of `y`, `zeta`, `A x`).
    fn dim(&self) -> usize;
    /// Makes `rho` the current penalty (refactorizes when needed).
    fn set_rho(&mut self, rho: f64) -> Result<(), Error>;
    /// x-update from `(y, zeta)`: writes `A x+` into `ax`.
    fn x_step(&mut self, y: &[f64], zeta: &[f64], rho: f64, ax: &mut [f64]);
    /// y-update: `y = prox_g(ax - c + zeta)`.
    fn y_step(&self, ax: &[f64], zeta: &[f64], y: &mut [f64]);
    /// The constant `c` of the constraint `A x - y = c`.
    fn c(&self) -> &[f64];
    /// `||A^T d||` (dual residual and its scale).
    fn norm_at(&mut self, d: &[f64]) -> f64;
    /// Updates the problem parameter `s` from the current iterate (De Saxce shift for
    /// contact problems); nothing by default.
    fn update_s(&mut self, _ax: &[f64], _y: &[f64]) {}
    /// The problem's own error measure at the current iterate (after `x_step`).
    fn error(&mut self, ax: &[f64], y: &[f64], zeta: &[f64], rho: f64) -> f64;
    /// Appends to `into` the splitting's own part of the current iterate, what `error` and
    /// the next steps read beyond the engine state (the global form's velocity, the shift
    /// `s`); nothing by default.
    fn save_iterate(&self, _into: &mut Vec<f64>) {}
    /// Restores what [`Splitting::save_iterate`] saved.
    fn restore_iterate(&mut self, _from: &[f64]) {}
    /// The run's wall-clock limit, for work inside a step that can stop early (the
    /// iterative backend's conjugate gradients); ignored by default.
    fn set_deadline(&mut self, _deadline: Option<Instant>) {}
    /// At each of the loop's own evaluations (not those made only for the trace): takes
    /// back the rows left out of the system whose constraint the iterate `ax` now
    /// violates; nothing by default.
    fn readmit(&mut self, _ax: &[f64]) {}
    /// Whether the system changed since the last [`Splitting::set_rho`] (rows it had left
    /// out came back): the engine then makes the penalty current again and restarts its
    /// acceleration; never by default.
    fn system_changed(&self) -> bool {
        false
    }
    /// Adds up, entry by entry and in place, partial sums that each process sharing a
    /// distributed problem computed over its own part of the constraint space, so that
    /// every process holds the totals: the engine's norms, dot products and agreement
    /// flags (a non-finite iterate, the clock) go through it, and every process takes the
    /// same decisions. One process owns the whole space: nothing, by default.
    fn sum_across(&self, _partial: &mut [f64]) {}
}

/// When the s parameter is updated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SUpdate {
    /// Every iteration, from the current iterate (docs/algorithms.md §5).
    Internal,
    /// After each inner ADMM solve of the convex problem with s fixed (section 8.3).
    External,
}
