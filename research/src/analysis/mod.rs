//! The analysis side of Anderson acceleration of ADMM (seed 001): stationary AA sAA(m),
//! the optimal sAA(1) coefficient and factor of Propositions 3 and 4 for every spectrum
//! case, brute-force sAA(2)/sAA(3) coefficients, the spectrum of the ADMM map's Jacobian
//! `q'(x*)` by finite differences, and asymptotic factors measured from error histories.
//!
//! It works on any engine [`Splitting`](cadmm::admm::Splitting) (the seed's test problems
//! live in [`crate::test_problems`]): solving always goes through the one engine loop
//! ([`cadmm::admm::run`]); the single map `q` of [`AdmmMap`] is used only where the
//! analysis needs `q` itself (finite differences, the stationary iteration).
//!
//! ```
//! use cadmm_research::analysis::{optimal::proposition3, C64};
//! // Ridge regression of seed 001: spectrum in [0, 0.833] -> beta* = 0.420, rho* = 0.592.
//! let opt = proposition3(0.0, 5.0 / 6.0);
//! assert!((opt.beta - 0.420).abs() < 5e-4 && (opt.rho - 0.592).abs() < 5e-4);
//! # let _ = C64::new(0.0, 0.0);
//! ```

mod admm_map;
pub mod experiment;
pub mod optimal;
mod poly;
pub mod saa;
pub mod spectrum;
mod tracked;

pub use admm_map::{prox_input, AdmmMap};
pub use experiment::{analyze, Analysis, ExperimentSettings, Run};
pub use optimal::{optimal_saa1, proposition3, Saa1Case, Saa1Optimum};
pub use poly::{max_root_modulus, roots};
pub use spectrum::{asymptotic_factor, Spectrum};
pub use tracked::Tracked;

/// Complex numbers of the spectra.
pub type C64 = nalgebra::Complex<f64>;
