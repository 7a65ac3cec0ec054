//! The frictional contact problems as ADMM splittings (ALGORITHMS.md sections 3 and 4),
//! and the initial penalty rules (seed 000 section 4.1).

mod global;
mod initial_rho;
mod local;

pub use global::GlobalSplitting;
pub use initial_rho::{initial_rho, InitialRho};
pub use local::LocalSplitting;

use crate::cone::{get3, set3};

/// De Saxce shift of each contact's normal component: `mu ||u_T||`, written into `phi`
/// (normal slots only). Returns the relative change of the shift.
fn de_saxce_shift(u: &[f64], mu: &[f64], phi: &mut [f64]) -> f64 {
    let (mut change, mut size) = (0.0f64, 0.0f64);
    for (i, &m) in mu.iter().enumerate() {
        let ui = get3(u, i);
        let s = m * (ui[1] * ui[1] + ui[2] * ui[2]).sqrt();
        change += (s - phi[3 * i]).powi(2);
        size += s * s;
        set3(phi, i, [s, 0.0, 0.0]);
    }
    change.sqrt() / size.sqrt().max(f64::MIN_POSITIVE)
}

/// Initial shift of seed 000 eq. (61): `Phi(1) / (||Phi(1)|| ||A||_F)`, where `A` is `H`
/// (global) or `W` (local).
fn initial_shift(mu: &[f64], frobenius: f64, phi: &mut [f64]) {
    phi.fill(0.0);
    let norm_mu = mu.iter().map(|m| m * m).sum::<f64>().sqrt();
    if norm_mu == 0.0 || frobenius == 0.0 {
        return;
    }
    for (i, &m) in mu.iter().enumerate() {
        phi[3 * i] = m / (norm_mu * frobenius);
    }
}
