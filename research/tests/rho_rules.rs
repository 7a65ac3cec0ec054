//! The penalty rules of the engine on a research plug-in: the same rule code that serves
//! the contact solver, checked on ridge regression from a poor initial penalty.

use cadmm::admm::{
    run, EngineSettings, EngineState, Relaxation, RhoRule, SUpdate, Splitting, Variant,
};
use cadmm_research::test_problems::LeastSquares;
use std::time::Instant;

/// Iterations to a 1e-10 fixed-point residual and the final rho, on ridge regression
/// started from a penalty 1000 times too small.
fn solve_ridge(rule: RhoRule) -> (usize, f64) {
    let mut p = LeastSquares::ridge(60, 30, 0.3, 7);
    let rho0 = 1e-2;
    p.set_rho(rho0).unwrap();
    let l = p.dim();
    let mut state = EngineState {
        y: vec![0.0; l],
        zeta: vec![0.0; l],
        ax: vec![0.0; l],
        rho: rho0,
    };
    let set = EngineSettings {
        tolerance: 1e-10,
        max_iterations: 20_000,
        time_limit: f64::INFINITY,
        variant: Variant {
            rule,
            relaxation: Relaxation::None,
        },
        anderson: 0,
        anderson_interval: 1,
        s_update: SUpdate::Internal,
        eps_abs: 0.0,
        eps_rel: 0.0,
        check_every: 1,
        trace: false,
        rho_range: 1e8,
        handover: None,
    };
    let out = run(&mut p, &mut state, &set, Instant::now()).unwrap();
    assert!(out.error <= 1e-10, "{rule:?}: error {}", out.error);
    (out.iterations, state.rho)
}

/// The spectral rule moves a poor penalty and converges faster than keeping it (with
/// the seed's dual sign it never moved).
#[test]
fn spectral_rule_adapts_the_penalty() {
    let (constant, _) = solve_ridge(RhoRule::Constant);
    let (spectral, rho) = solve_ridge(RhoRule::spectral());
    assert!(rho > 0.1, "spectral rule left rho at {rho}");
    assert!(
        2 * spectral < constant,
        "spectral {spectral} iterations vs constant {constant}"
    );
}
