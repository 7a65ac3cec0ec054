//! The engine's iterate, apart from the loop so that the parts of the loop that keep an
//! iterate (the best iterate) need not import the loop.

/// The iterate the loop works on; the caller initializes it (warm start) and reads it back.
#[derive(Debug, Clone)]
pub struct EngineState {
    /// `y` (u~ for the global form, z for the local form).
    pub y: Vec<f64>,
    /// Scaled dual.
    pub zeta: Vec<f64>,
    /// `A x` of the last x-step.
    pub ax: Vec<f64>,
    /// Penalty.
    pub rho: f64,
}
