//! Optimal sAA coefficients. For sAA(1), the closed forms of seed 001 Propositions 3 (real
//! spectrum, every sign case) and 4 (complex spectrum), with a numerical minimization over
//! beta where no closed form applies; for sAA(2) and sAA(3), the seed's brute-force grid
//! search (section 3), refined around the best grid point.

use super::poly::max_root_modulus;
use super::saa::{char_poly, factor};
use super::C64;

/// Which case of Propositions 3 and 4 gave the optimum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Saa1Case {
    /// Real spectrum in `[0, 1)`.
    NonNegative,
    /// Real spectrum in `(-1, 0]`.
    NonPositive,
    /// Real spectrum of both signs with `sigma_max = |sigma_min|`: case (a), `beta* = 0`.
    MixedEqual,
    /// Both signs, `sigma_max > |sigma_min|`, the positive end decides: case (b1).
    MixedB1,
    /// Both signs, `sigma_max > |sigma_min|`, both ends balance: case (b2).
    MixedB2,
    /// Both signs, `sigma_max < |sigma_min|`, the negative end decides: case (c1).
    MixedC1,
    /// Both signs, `sigma_max < |sigma_min|`, both ends balance: case (c2).
    MixedC2,
    /// Complex spectrum whose spectral radius is a positive real eigenvalue, where the lower
    /// bound of Proposition 4 is attained.
    ComplexBound,
    /// Complex spectrum where the bound `1 - sqrt(1 - mu+)` of the largest nonnegative real
    /// eigenvalue `mu+` is attained (seed section 3.4.4, Corollary S.1 of its ref. 6).
    ComplexPositiveReal,
    /// Complex spectrum where no closed form holds: numerical minimization over beta.
    ComplexNumeric,
    /// A real eigenvalue outside `(-1, 1)`: the plain iteration does not converge;
    /// numerical minimization over beta.
    Divergent,
}

/// Optimal sAA(1) coefficient and factor for a spectrum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Saa1Optimum {
    /// Optimal `beta*`.
    pub beta: f64,
    /// Optimal asymptotic factor `rho*_sAA(1)`.
    pub rho: f64,
    /// The case that applied.
    pub case: Saa1Case,
    /// Lower bound `1 - sqrt(1 - rho_q)` of Proposition 4 when it applies.
    pub lower_bound: Option<f64>,
}

/// `beta*_mu = (1 - sqrt(1 - mu)) / (1 + sqrt(1 - mu))` (Proposition 2).
pub fn beta_of(mu: f64) -> f64 {
    let s = (1.0 - mu).sqrt();
    (1.0 - s) / (1.0 + s)
}

/// `S_mu(beta)`: largest root modulus of `lambda^2 - (1 + beta) mu lambda + beta mu`.
pub fn s_mu(mu: C64, beta: f64) -> f64 {
    max_root_modulus(&char_poly(mu, &[beta]))
}

/// Proposition 3: optimal sAA(1) for a real spectrum with extreme values `sigma_min <=
/// sigma_max`.
pub fn proposition3(sigma_min: f64, sigma_max: f64) -> Saa1Optimum {
    let (lo, hi) = (sigma_min, sigma_max);
    let real = |x: f64| C64::new(x, 0.0);
    let done = |beta: f64, rho: f64, case| Saa1Optimum {
        beta,
        rho,
        case,
        lower_bound: None,
    };
    if hi >= 1.0 || lo <= -1.0 {
        let (beta, rho) = brute_force_saa1(&[real(lo), real(hi)]);
        return done(beta, rho, Saa1Case::Divergent);
    }
    if lo >= 0.0 {
        return done(beta_of(hi), 1.0 - (1.0 - hi).sqrt(), Saa1Case::NonNegative);
    }
    if hi <= 0.0 {
        return done(beta_of(lo), (1.0 - lo).sqrt() - 1.0, Saa1Case::NonPositive);
    }
    if (hi + lo).abs() <= 1e-14 * hi {
        return done(0.0, hi, Saa1Case::MixedEqual);
    }
    // Both ends at a given beta; at the balanced optimum they are equal.
    let both = |beta: f64| s_mu(real(hi), beta).max(s_mu(real(lo), beta));
    if hi > -lo {
        let bp = beta_of(hi);
        let rho_plus = 1.0 - (1.0 - hi).sqrt();
        if s_mu(real(lo), bp) <= rho_plus {
            return done(bp, rho_plus, Saa1Case::MixedB1);
        }
        let m = (hi - lo) / (-2.0 * hi * lo * (hi + lo)).sqrt();
        let beta = (m - (m * m - 4.0).sqrt()).powi(2) / 4.0;
        done(beta, both(beta), Saa1Case::MixedB2)
    } else {
        let bm = beta_of(lo);
        let rho_minus = (1.0 - lo).sqrt() - 1.0;
        if s_mu(real(hi), bm) <= rho_minus {
            return done(bm, rho_minus, Saa1Case::MixedC1);
        }
        let m = (hi - lo) / (2.0 * hi * lo * (hi + lo)).sqrt();
        let beta = -((m * m + 4.0).sqrt() - m).powi(2) / 4.0;
        done(beta, both(beta), Saa1Case::MixedC2)
    }
}

/// Optimal sAA(1) for any spectrum: Proposition 3 when `real`, otherwise Proposition 4 (and
/// the largest-nonnegative-eigenvalue variant), checked against the factor that the chosen
/// beta really gives, with a numerical minimization when neither bound is attained.
pub fn optimal_saa1(spectrum: &[C64], real: bool) -> Saa1Optimum {
    if spectrum.is_empty() {
        return Saa1Optimum {
            beta: 0.0,
            rho: 0.0,
            case: Saa1Case::NonNegative,
            lower_bound: None,
        };
    }
    if real {
        let lo = spectrum.iter().map(|z| z.re).fold(f64::INFINITY, f64::min);
        let hi = spectrum
            .iter()
            .map(|z| z.re)
            .fold(f64::NEG_INFINITY, f64::max);
        return proposition3(lo, hi);
    }
    let dominant = spectrum
        .iter()
        .copied()
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
        .unwrap_or_default();
    let rho_q = dominant.norm();
    // A double root (what the optimal beta makes) is computed to ~sqrt(eps) only.
    let attained = |bound: f64, rho: f64| rho <= bound * (1.0 + 1e-6);
    let mut lower_bound = None;
    if rho_q < 1.0 && dominant.re > 0.0 && dominant.im.abs() <= 1e-6 * rho_q {
        let bound = 1.0 - (1.0 - rho_q).sqrt();
        lower_bound = Some(bound);
        let beta = beta_of(rho_q);
        let rho = factor(spectrum, &[beta]);
        if attained(bound, rho) {
            return Saa1Optimum {
                beta,
                rho,
                case: Saa1Case::ComplexBound,
                lower_bound,
            };
        }
    }
    let mu_plus = spectrum
        .iter()
        .filter(|z| z.im.abs() <= 1e-6 * rho_q && z.re >= 0.0)
        .map(|z| z.re)
        .fold(f64::NAN, f64::max);
    if mu_plus.is_finite() && mu_plus < 1.0 {
        let beta = beta_of(mu_plus);
        let rho = factor(spectrum, &[beta]);
        if attained(1.0 - (1.0 - mu_plus).sqrt(), rho) {
            return Saa1Optimum {
                beta,
                rho,
                case: Saa1Case::ComplexPositiveReal,
                lower_bound,
            };
        }
    }
    let (beta, rho) = brute_force_saa1(spectrum);
    Saa1Optimum {
        beta,
        rho,
        case: Saa1Case::ComplexNumeric,
        lower_bound,
    }
}

/// Brute-force minimization of the sAA(1) factor over `beta in [-1, 1]`: a grid of step
/// 0.002, then golden-section search in the best cell. Returns `(beta*, rho*)`.
pub fn brute_force_saa1(spectrum: &[C64]) -> (f64, f64) {
    let mut spec = reduce(spectrum);
    let spec_all = spec.clone();
    let f = |b: f64| factor(&spec_all, &[b]);
    let h = 0.002;
    let (mut best_b, mut best) = (0.0, f64::INFINITY);
    for k in 0..=1000 {
        let b = -1.0 + h * k as f64;
        let v = pruned_factor(&mut spec, &[b], best);
        if v < best {
            (best_b, best) = (b, v);
        }
    }
    let (mut a, mut c) = (best_b - h, best_b + h);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (c - g * (c - a), a + g * (c - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..60 {
        if f1 <= f2 {
            (c, x2, f2) = (x2, x1, f1);
            x1 = c - g * (c - a);
            f1 = f(x1);
        } else {
            (a, x1, f1) = (x1, x2, f2);
            x2 = a + g * (c - a);
            f2 = f(x2);
        }
    }
    let (b, v) = if f1 <= f2 { (x1, f1) } else { (x2, f2) };
    if v < best {
        (b, v)
    } else {
        (best_b, best)
    }
}

/// Brute-force search of the sAA(m) coefficients (seed 001 section 3): every `beta_i` on
/// the grid `[-1, 1]` with step 0.05, then a pattern search (all `3^m - 1` directions of
/// `{-1, 0, 1}^m`, step halved from 0.025 to 1e-4) from each of the best grid points:
/// the factor is a max of root moduli, whose valleys are narrow and oblique, so refining
/// only the single best grid point can miss the optimum. Above 160 distinct eigenvalues
/// (one per conjugate pair) the grid and the first searches use the 80 largest and an even
/// sample of the rest, and the three best results are polished on the whole spectrum.
/// `starts` are extra starting points
/// (e.g. the sAA(m-1) optimum with a zero appended, which makes the result no worse than
/// it). Returns `(betas, rho*_sAA(m))`.
pub fn search_saa(spectrum: &[C64], m: usize, starts: &[Vec<f64>]) -> (Vec<f64>, f64) {
    let mut full = reduce(spectrum);
    // Large spectra: search on the largest eigenvalues plus an even sample of the rest,
    // then polish the few best on the whole spectrum.
    let mut spec = if full.len() > 160 {
        let stride = (full.len() - 80).div_ceil(80);
        full[..80]
            .iter()
            .chain(full[80..].iter().step_by(stride))
            .copied()
            .collect()
    } else {
        full.clone()
    };
    let grid: Vec<f64> = (0..=40).map(|k| -1.0 + 0.05 * k as f64).collect();
    let mut top = Top::new(16);
    scan(&mut spec, &vec![grid; m], &mut top);
    let extra: Vec<(f64, Vec<f64>)> = starts
        .iter()
        .filter(|b| b.len() == m)
        .map(|b| (factor(&spec, b), b.clone()))
        .collect();
    let mut found = Top::new(3);
    for (v, b) in top.items.into_iter().chain(extra) {
        let (b, v) = pattern_search(&mut spec, b, v, 0.025);
        found.offer(v, &b);
    }
    // On the whole spectrum (a no-op when nothing was left out).
    let mut best = (vec![0.0; m], f64::INFINITY);
    for (_, b) in found.items.into_iter().chain(
        starts
            .iter()
            .filter(|b| b.len() == m)
            .map(|b| (0.0, b.clone())),
    ) {
        let v = factor(&full, &b);
        let (b, v) = if spec.len() < full.len() {
            pattern_search(&mut full, b, v, 0.005)
        } else {
            (b, v)
        };
        if v < best.1 {
            best = (b, v);
        }
    }
    best
}

/// The `k` best points seen, kept sorted.
struct Top {
    k: usize,
    items: Vec<(f64, Vec<f64>)>,
}

impl Top {
    fn new(k: usize) -> Self {
        Self {
            k,
            items: Vec::new(),
        }
    }

    /// Values at or above this cannot enter.
    fn cutoff(&self) -> f64 {
        if self.items.len() < self.k {
            f64::INFINITY
        } else {
            self.items[self.k - 1].0
        }
    }

    fn offer(&mut self, v: f64, b: &[f64]) {
        if v < self.cutoff() {
            let at = self.items.partition_point(|(w, _)| *w <= v);
            self.items.insert(at, (v, b.to_vec()));
            self.items.truncate(self.k);
        }
    }
}

/// Evaluates every point of the tensor grid `axes`, keeping the best in `top`.
fn scan(spec: &mut [C64], axes: &[Vec<f64>], top: &mut Top) {
    let m = axes.len();
    let mut idx = vec![0usize; m];
    let mut b = vec![0.0; m];
    loop {
        for i in 0..m {
            b[i] = axes[i][idx[i]];
        }
        top.offer(pruned_factor(spec, &b, top.cutoff()), &b);
        // Odometer increment.
        let mut i = 0;
        loop {
            if i == m {
                return;
            }
            idx[i] += 1;
            if idx[i] < axes[i].len() {
                break;
            }
            idx[i] = 0;
            i += 1;
        }
    }
}

/// Pattern search from `b` (factor `v`) over the directions `{-1, 0, 1}^m \ {0}`, from
/// step `step` down to 1e-4.
fn pattern_search(spec: &mut [C64], mut b: Vec<f64>, mut v: f64, step: f64) -> (Vec<f64>, f64) {
    let m = b.len();
    let dirs: Vec<Vec<f64>> = (0..3usize.pow(m as u32))
        .map(|code| {
            (0..m)
                .map(|i| (code / 3usize.pow(i as u32) % 3) as f64 - 1.0)
                .collect()
        })
        .filter(|d: &Vec<f64>| d.iter().any(|x| *x != 0.0))
        .collect();
    let mut step = step;
    let mut trial = vec![0.0; m];
    while step > 1e-4 {
        let mut moved = false;
        for d in &dirs {
            for i in 0..m {
                trial[i] = b[i] + step * d[i];
            }
            let t = pruned_factor(spec, &trial, v);
            if t < v {
                b.copy_from_slice(&trial);
                v = t;
                moved = true;
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    (b, v)
}

/// The sAA factor over `spec`, stopping as soon as it reaches `cutoff` (then the value is
/// only a lower bound, enough to reject the point). The eigenvalue that caused the stop
/// moves to the front: nearby points are usually rejected by the same one, at once.
fn pruned_factor(spec: &mut [C64], betas: &[f64], cutoff: f64) -> f64 {
    let mut r = 0.0f64;
    for i in 0..spec.len() {
        r = r.max(max_root_modulus(&char_poly(spec[i], betas)));
        if r >= cutoff {
            spec[..=i].rotate_right(1);
            break;
        }
    }
    r
}

/// The eigenvalues that matter for a factor: one of each conjugate pair, without
/// duplicates, largest modulus first (the likeliest to decide, so pruning stops early).
fn reduce(spectrum: &[C64]) -> Vec<C64> {
    let mut v: Vec<C64> = spectrum
        .iter()
        .map(|z| C64::new(z.re, z.im.abs()))
        .collect();
    v.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
    v.dedup_by(|a, b| (*a - *b).norm() <= 1e-9 * b.norm().max(1.0));
    v.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
    v
}
