//! The seed-001 experiment on one problem: a reference fixed point, the spectrum of `q'`
//! there, the optimal sAA coefficients it predicts, and measured error histories of plain
//! ADMM and AA(m) (through the engine) and of sAA(m) (through the map), all from the zero
//! initial guess at the problem's fixed penalty.

use super::admm_map::{prox_input, AdmmMap};
use super::optimal::{optimal_saa1, search_saa, Saa1Optimum};
use super::spectrum::{asymptotic_factor, eigenvalues, jacobian_fd, Spectrum};
use super::{saa, Tracked};
use cadmm::admm::norm2;
use cadmm::admm::{
    self, EngineSettings, EngineState, Relaxation, RhoRule, SUpdate, Splitting, Variant,
};
use cadmm::Error;
use std::time::Instant;

/// What to measure.
#[derive(Debug, Clone)]
pub struct ExperimentSettings {
    /// Runs stop when the relative distance to the reference is below this.
    pub tolerance: f64,
    /// Iteration limit of every run.
    pub max_iterations: usize,
    /// Anderson memories to measure through the engine.
    pub memories: Vec<usize>,
    /// Largest m of the sAA(m) coefficient search (1 to 3; 3 is the expensive one).
    pub search_m: usize,
    /// Finite-difference step relative to `max(1, ||w*||_inf)`.
    pub fd_step: f64,
}

impl Default for ExperimentSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-11,
            max_iterations: 20_000,
            memories: vec![1, 2, 3],
            search_m: 3,
            fd_step: 1e-6,
        }
    }
}

/// One measured run.
#[derive(Debug, Clone)]
pub struct Run {
    /// `ADMM`, `AA(m)`, `sAA(m)`.
    pub label: String,
    /// Map evaluations done at each recorded error (0 for the initial guess).
    pub iterations: Vec<usize>,
    /// Relative distance to the reference after those evaluations.
    pub errors: Vec<f64>,
    /// Asymptotic factor estimated from the history.
    pub factor: Option<f64>,
    /// Anderson steps accepted by the engine's safeguard.
    pub accepted: usize,
    /// Anderson steps rejected by the engine's safeguard.
    pub rejected: usize,
}

/// Optimal stationary coefficients found by search, with their factor.
#[derive(Debug, Clone)]
pub struct SaaSearch {
    /// `beta_1..beta_m`.
    pub betas: Vec<f64>,
    /// `rho(Psi'_m)` at those coefficients.
    pub rho: f64,
}

/// Everything the experiment found on one problem.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// Penalty used throughout.
    pub rho: f64,
    /// Relative fixed-point residual of the reference point.
    pub reference_residual: f64,
    /// Spectrum of `q'` at the reference (nonzero part, from the reduced map).
    pub spectrum: Spectrum,
    /// Whether that spectrum is real (imaginary parts below 1e-6 of the radius).
    pub real: bool,
    /// Optimal sAA(1) (Propositions 3 and 4).
    pub saa1: Saa1Optimum,
    /// Searched sAA(m) optima for m = 2, 3 (as far as `search_m`).
    pub saa_search: Vec<SaaSearch>,
    /// Plain ADMM through the engine.
    pub admm: Run,
    /// AA(m) through the engine, in the order of `memories`.
    pub aa: Vec<Run>,
    /// sAA(1) with `beta*`, then sAA(m) with the searched coefficients.
    pub saa: Vec<Run>,
    /// Wall time of the whole experiment.
    pub seconds: f64,
}

fn engine_settings(anderson: usize, tolerance: f64, max_iterations: usize) -> EngineSettings {
    EngineSettings {
        tolerance,
        max_iterations,
        time_limit: f64::INFINITY,
        variant: Variant {
            rule: RhoRule::Constant,
            relaxation: Relaxation::None,
        },
        anderson,
        anderson_interval: 1,
        s_update: SUpdate::Internal,
        // The residual test never fires; the error measure decides alone.
        eps_abs: 0.0,
        eps_rel: 0.0,
        check_every: 1,
        trace: true,
        rho_range: 1.0,
        handover: None,
    }
}

fn zero_state(l: usize, rho: f64) -> EngineState {
    EngineState {
        y: vec![0.0; l],
        zeta: vec![0.0; l],
        ax: vec![0.0; l],
        rho,
    }
}

/// A fixed point of `sp`'s ADMM map at `rho`, as the stacked `(y*, zeta*)`, and its
/// relative fixed-point residual: the engine with AA(5) from zero (at most 500 iterations:
/// a map evaluated with an inner solver may never reach 1e-15), then plain iterations of
/// the map while they still reduce the residual (they settle at round-off where
/// accelerated steps stall).
pub fn reference_point(sp: &mut dyn Splitting, rho: f64) -> Result<(Vec<f64>, f64), Error> {
    let l = sp.dim();
    let mut state = zero_state(l, rho);
    admm::run(
        sp,
        &mut state,
        &engine_settings(5, 1e-15, 500),
        Instant::now(),
    )?;
    let mut s = [state.y, state.zeta].concat();
    let mut map = AdmmMap::new(sp, rho)?;
    let mut next = vec![0.0; 2 * l];
    let mut best = (f64::INFINITY, s.clone());
    let mut since_best = 0;
    for _ in 0..20_000 {
        map.apply(&s, &mut next);
        let d: f64 = next.iter().zip(&s).map(|(a, b)| (a - b) * (a - b)).sum();
        let res = d.sqrt() / norm2(&next).max(f64::MIN_POSITIVE);
        if res < best.0 {
            best = (res, next.clone());
            since_best = 0;
        } else {
            since_best += 1;
            if since_best > 50 {
                break;
            }
        }
        std::mem::swap(&mut s, &mut next);
    }
    Ok((best.1, best.0))
}

/// Spectrum of `q'` at the stacked fixed point `reference`, through the reduced map.
pub fn spectrum_at(
    sp: &mut dyn Splitting,
    rho: f64,
    reference: &[f64],
    fd_step: f64,
) -> Result<Spectrum, Error> {
    let w = prox_input(reference);
    let h = fd_step * w.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    let mut map = AdmmMap::new(sp, rho)?;
    let jac = jacobian_fd(|x, y| map.apply_reduced(x, y), &w, h);
    Ok(Spectrum {
        eigenvalues: eigenvalues(&jac, w.len())?,
    })
}

fn finish(label: String, iterations: Vec<usize>, errors: Vec<f64>) -> Run {
    let factor = asymptotic_factor(&iterations, &errors);
    Run {
        label,
        iterations,
        errors,
        factor,
        accepted: 0,
        rejected: 0,
    }
}

/// Plain ADMM (`anderson = 0`) or AA(m) through the engine from zero, recording the
/// distance to `reference` at every iteration.
pub fn engine_run(
    sp: &mut dyn Splitting,
    rho: f64,
    reference: &[f64],
    anderson: usize,
    set: &ExperimentSettings,
) -> Result<Run, Error> {
    let l = sp.dim();
    let mut tracked = Tracked::new(sp, reference);
    let e0 = tracked.distance(&vec![0.0; 2 * l]);
    let mut state = zero_state(l, rho);
    let es = engine_settings(anderson, set.tolerance, set.max_iterations);
    let out = admm::run(&mut tracked, &mut state, &es, Instant::now())?;
    let iterations = std::iter::once(0)
        .chain(out.trace.iter().map(|t| t.iteration))
        .collect();
    let errors = std::iter::once(e0)
        .chain(out.trace.iter().map(|t| t.error))
        .collect();
    let label = if anderson == 0 {
        "ADMM".to_string()
    } else {
        format!("AA({anderson})")
    };
    let mut run = finish(label, iterations, errors);
    run.accepted = out.aa_accepted;
    run.rejected = out.aa_rejected;
    Ok(run)
}

/// sAA(m) with fixed `betas` on the stacked map from zero.
pub fn saa_run(
    sp: &mut dyn Splitting,
    rho: f64,
    reference: &[f64],
    betas: &[f64],
    set: &ExperimentSettings,
) -> Result<Run, Error> {
    let l = sp.dim();
    let scale = norm2(reference).max(f64::MIN_POSITIVE);
    let dist = |s: &[f64]| {
        let d: f64 = s
            .iter()
            .zip(reference)
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        d.sqrt() / scale
    };
    let x0 = vec![0.0; 2 * l];
    let e0 = dist(&x0);
    let mut map = AdmmMap::new(sp, rho)?;
    let hist = saa::run(
        |x, y| map.apply(x, y),
        &x0,
        betas,
        set.max_iterations,
        set.tolerance,
        dist,
    );
    let iterations = (0..=hist.len()).collect();
    let errors = std::iter::once(e0).chain(hist).collect();
    Ok(finish(format!("sAA({})", betas.len()), iterations, errors))
}

/// The whole experiment on `sp` at penalty `rho`.
pub fn analyze(
    sp: &mut dyn Splitting,
    rho: f64,
    set: &ExperimentSettings,
) -> Result<Analysis, Error> {
    let start = Instant::now();
    let (reference, reference_residual) = reference_point(sp, rho)?;
    // Runs stop above the reference's own accuracy, where the error would only be noise.
    let set = &ExperimentSettings {
        tolerance: set.tolerance.max(1e3 * reference_residual),
        ..set.clone()
    };
    let spectrum = spectrum_at(sp, rho, &reference, set.fd_step)?;
    let real = spectrum.is_real(1e-6);
    let saa1 = optimal_saa1(&spectrum.eigenvalues, real);
    // Each search also starts from the previous optimum with a zero appended (the same
    // iteration), so the factors never increase with m.
    let mut saa_search: Vec<SaaSearch> = Vec::new();
    let mut previous = vec![saa1.beta];
    for m in 2..=set.search_m {
        previous.push(0.0);
        let (betas, rho) = search_saa(&spectrum.eigenvalues, m, &[previous]);
        previous = betas.clone();
        saa_search.push(SaaSearch { betas, rho });
    }
    let admm = engine_run(sp, rho, &reference, 0, set)?;
    let aa = set
        .memories
        .iter()
        .map(|&m| engine_run(sp, rho, &reference, m, set))
        .collect::<Result<Vec<_>, _>>()?;
    let mut saa = vec![saa_run(sp, rho, &reference, &[saa1.beta], set)?];
    for s in &saa_search {
        saa.push(saa_run(sp, rho, &reference, &s.betas, set)?);
    }
    Ok(Analysis {
        rho,
        reference_residual,
        spectrum,
        real,
        saa1,
        saa_search,
        admm,
        aa,
        saa,
        seconds: start.elapsed().as_secs_f64(),
    })
}
