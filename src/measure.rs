//! The error measure every test and benchmark uses (docs/algorithms.md §3; it matches
//! Siconos numerics). This is its only implementation: the splittings call it through a
//! [`MeasureWork`] so that it allocates nothing inside the iteration.
//!
//! global: `||-M v + H r + G lambda + f|| / max(||f||, ||M v||, ||H r + G lambda||)
//!          + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||)
//!          + ||G^T v + b|| / max(||G^T v||, ||b||)`, `u = H^T v + w` (joint terms only with
//!          joints);
//! local:  `||r - P_K(r - (u + Phi(u)))|| / ||q||`, `u = W r + q`.
//!
//! Each denominator is skipped when it is below [`TINY`]. A non-finite input gives `inf`.
//! Joint multipliers that are not supplied (an empty `lambda`) are recomputed as the
//! least-squares solution of `G lambda = M v - H r - f`: the best multipliers for the given
//! `(r, v)`, so the measure then says whether `(r, v)` can be completed into a solution.

use crate::cone::{de_saxce, get3, project_cone};
use crate::csc::{dot, norm2};
use crate::problem::{GlobalProblem, LocalProblem, Problem};
use crate::types::Solution;

/// Denominators below this are skipped (the residual is taken as it is).
pub const TINY: f64 = 1.5e-8;

fn relative(num: f64, den: f64) -> f64 {
    if den > TINY {
        num / den
    } else {
        num
    }
}

/// Norm of the natural-map residual `r - P_K(r - (u + Phi(u)))` over all contacts.
pub fn complementarity_residual(r: &[f64], u: &[f64], mu: &[f64]) -> f64 {
    complementarity_sq(r, u, mu).sqrt()
}

/// The square of [`complementarity_residual`], a sum over contacts (which processes
/// sharing a problem add up).
pub(crate) fn complementarity_sq(r: &[f64], u: &[f64], mu: &[f64]) -> f64 {
    let mut sum = 0.0;
    for (i, &m) in mu.iter().enumerate() {
        let ri = get3(r, i);
        let ut = de_saxce(get3(u, i), m);
        let p = project_cone([ri[0] - ut[0], ri[1] - ut[1], ri[2] - ut[2]], m);
        sum += (ri[0] - p[0]).powi(2) + (ri[1] - p[1]).powi(2) + (ri[2] - p[2]).powi(2);
    }
    sum
}

fn all_finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// Lower bounds on the measure's denominators. An island of a scene (docs/algorithms.md
/// §12) is measured with floors taken from the whole problem's scales, so that it is
/// judged by its share of the whole problem's measure instead of by its own, often much
/// smaller, scale. All zero (no floor) for a problem solved as it is.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Floors {
    /// Global: equation term (`max(||f||, ||M v||, ||H r + G lambda||)`); local: `||q||`.
    pub equation: f64,
    /// Global: complementarity term (`max(||u||, ||r||)`).
    pub contact: f64,
    /// Global: joint term (`max(||G^T v||, ||b||)`).
    pub joint: f64,
}

/// The denominators of the global measure at a solution (before any floor).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Scales {
    pub equation: f64,
    pub contact: f64,
    pub joint: f64,
}

/// Work vectors of the measure, sized once for one problem's dimensions.
#[derive(Debug, Clone, Default)]
pub struct MeasureWork {
    mv: Vec<f64>,
    hr: Vec<f64>,
    u: Vec<f64>,
    gv: Vec<f64>,
    pub(crate) floors: Floors,
    /// The denominators of the last global evaluation.
    pub(crate) scales: Scales,
}

impl MeasureWork {
    /// Work space for a problem of either form.
    pub fn new(p: &Problem) -> Self {
        match p {
            Problem::Global(g) => Self::global(g),
            Problem::Local(l) => Self::local(l),
        }
    }

    /// Work vectors sized for a global problem (`n`, `3 nc` and the joint rows).
    pub fn global(p: &GlobalProblem) -> Self {
        let mut work = Self::default();
        work.fit_global(p);
        work
    }

    /// Work vectors sized for a local problem (`3 nc`).
    pub fn local(p: &LocalProblem) -> Self {
        Self {
            u: vec![0.0; p.q.len()],
            ..Self::default()
        }
    }

    /// Resizes for `p` (no allocation when the sizes already fit).
    fn fit_global(&mut self, p: &GlobalProblem) {
        let np = p.n_joints();
        self.mv.resize(p.n(), 0.0);
        self.hr.resize(p.n(), 0.0);
        self.u.resize(p.w.len(), 0.0);
        self.gv.resize(np, 0.0);
    }
}

/// Error of a global solution `(r, v)` with joint multipliers `lambda` (ignored without
/// joints; recomputed by least squares when empty). Allocates its work vectors.
pub fn global_error(p: &GlobalProblem, r: &[f64], v: &[f64], lambda: &[f64]) -> f64 {
    let mut work = MeasureWork::default();
    global_error_with(p, r, v, lambda, &mut work)
}

/// [`global_error`] with caller-owned work vectors: no allocation when `work` fits `p`
/// and `lambda` is supplied (or there are no joints).
pub fn global_error_with(
    p: &GlobalProblem,
    r: &[f64],
    v: &[f64],
    lambda: &[f64],
    work: &mut MeasureWork,
) -> f64 {
    if !all_finite(r) || !all_finite(v) || !all_finite(lambda) {
        return f64::INFINITY;
    }
    work.fit_global(p);
    p.m.mul_vec(1.0, v, 0.0, &mut work.mv);
    p.h.mul_vec(1.0, r, 0.0, &mut work.hr);
    let mut joint_error = 0.0;
    if let Some(j) = &p.joints {
        if lambda.len() == j.b.len() {
            j.g.mul_vec(1.0, lambda, 1.0, &mut work.hr);
        } else {
            let ls = least_squares_multipliers(p, &work.mv, &work.hr);
            j.g.mul_vec(1.0, &ls, 1.0, &mut work.hr);
        }
        j.g.mul_t_vec(1.0, v, 0.0, &mut work.gv);
        let scale = norm2(&work.gv).max(norm2(&j.b));
        let res: f64 = work
            .gv
            .iter()
            .zip(&j.b)
            .map(|(a, b)| (a + b) * (a + b))
            .sum();
        work.scales.joint = scale;
        joint_error = relative(res.sqrt(), scale.max(work.floors.joint));
    }
    work.u.copy_from_slice(&p.w);
    p.h.mul_t_vec(1.0, v, 1.0, &mut work.u);
    let terms = GlobalTerms {
        f: &p.f,
        mv: &work.mv,
        hr: &work.hr,
        u: &work.u,
        r,
        mu: &p.mu,
    };
    finite_or_infinite(terms.error(work.floors, &mut work.scales) + joint_error)
}

/// The products the equation and contact terms of the global measure are made of, at
/// `(r, v)`: `mv = M v`, `hr = H r (+ G lambda)`, `u = H^T v + w`. Whoever computes them
/// (the whole problem's sparse products here, a small island's or a free block's own) gets
/// the one formula.
pub(crate) struct GlobalTerms<'a> {
    pub f: &'a [f64],
    pub mv: &'a [f64],
    pub hr: &'a [f64],
    pub u: &'a [f64],
    pub r: &'a [f64],
    pub mu: &'a [f64],
}

impl GlobalTerms<'_> {
    /// The measure of these products ([`GlobalSums::error`]).
    pub fn error(&self, floors: Floors, scales: &mut Scales) -> f64 {
        self.sums().error(floors, scales)
    }

    /// The squared norms the measure is made of.
    pub fn sums(&self) -> GlobalSums {
        let mut eq = 0.0;
        for ((mv, hr), f) in self.mv.iter().zip(self.hr).zip(self.f) {
            eq += (-mv + hr + f).powi(2);
        }
        GlobalSums {
            equation: eq,
            f: dot(self.f, self.f),
            mv: dot(self.mv, self.mv),
            hr: dot(self.hr, self.hr),
            complementarity: complementarity_sq(self.r, self.u, self.mu),
            u: dot(self.u, self.u),
            r: dot(self.r, self.r),
        }
    }
}

/// The squared norms the equation and contact terms of the global measure are made of:
/// sums over velocities and contacts, which processes sharing a problem add up before
/// [`GlobalSums::error`] makes the measure of them.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GlobalSums {
    /// `||-M v + H r + f||^2`.
    pub equation: f64,
    /// `||f||^2`, `||M v||^2`, `||H r||^2`.
    pub f: f64,
    pub mv: f64,
    pub hr: f64,
    /// `||r - P_K(r - (u + Phi(u)))||^2`.
    pub complementarity: f64,
    /// `||u||^2`, `||r||^2`.
    pub u: f64,
    pub r: f64,
}

impl GlobalSums {
    /// As an array, for a sum across processes.
    #[cfg(feature = "mpi")]
    pub fn to_array(self) -> [f64; 7] {
        [
            self.equation,
            self.f,
            self.mv,
            self.hr,
            self.complementarity,
            self.u,
            self.r,
        ]
    }

    /// From [`GlobalSums::to_array`]'s order.
    #[cfg(feature = "mpi")]
    pub fn from_array(a: [f64; 7]) -> Self {
        let [equation, f, mv, hr, complementarity, u, r] = a;
        Self {
            equation,
            f,
            mv,
            hr,
            complementarity,
            u,
            r,
        }
    }

    /// `||-M v + H r + f|| / max(||f||, ||M v||, ||H r||) + ||r - P_K(r - (u + Phi(u)))|| /
    /// max(||u||, ||r||)`, denominators floored by `floors`; records the denominators in
    /// `scales`.
    pub fn error(&self, floors: Floors, scales: &mut Scales) -> f64 {
        let scale = self.f.sqrt().max(self.mv.sqrt()).max(self.hr.sqrt());
        scales.equation = scale;
        let e1 = relative(self.equation.sqrt(), scale.max(floors.equation));
        let scale = self.u.sqrt().max(self.r.sqrt());
        scales.contact = scale;
        let e2 = relative(self.complementarity.sqrt(), scale.max(floors.contact));
        finite_or_infinite(e1 + e2)
    }
}

/// Overflowing products make `inf / inf`: such an error is infinite, never NaN.
fn finite_or_infinite(e: f64) -> f64 {
    if e.is_nan() {
        f64::INFINITY
    } else {
        e
    }
}

/// Least-squares joint multipliers: `argmin ||G lambda - (M v - H r - f)||`, by an SVD of
/// `G` (rank-deficient `G` allowed; minimum-norm solution).
fn least_squares_multipliers(p: &GlobalProblem, mv: &[f64], hr: &[f64]) -> Vec<f64> {
    let Some(j) = &p.joints else {
        return Vec::new();
    };
    let (n, np) = (p.n(), j.b.len());
    let mut g = nalgebra::DMatrix::<f64>::zeros(n, np);
    for k in 0..np {
        for (i, x) in j.g.col(k) {
            g[(i, k)] = x;
        }
    }
    let rhs = nalgebra::DVector::from_iterator(n, (0..n).map(|i| mv[i] - hr[i] - p.f[i]));
    let svd = g.svd(true, true);
    let eps = 1e-13 * svd.singular_values.max().max(f64::MIN_POSITIVE);
    svd.solve(&rhs, eps)
        .map(|x| x.iter().copied().collect())
        .unwrap_or_else(|_| vec![0.0; np])
}

/// Error of a local solution `r`; `u` is recomputed as `W r + q`. Allocates its work vector.
pub fn local_error(p: &LocalProblem, r: &[f64]) -> f64 {
    let mut work = MeasureWork::default();
    local_error_with(p, r, &mut work)
}

/// [`local_error`] with caller-owned work vectors (no allocation when `work` fits `p`).
pub fn local_error_with(p: &LocalProblem, r: &[f64], work: &mut MeasureWork) -> f64 {
    if !all_finite(r) {
        return f64::INFINITY;
    }
    work.u.resize(p.q.len(), 0.0);
    work.u.copy_from_slice(&p.q);
    p.w.mul_vec(1.0, r, 1.0, &mut work.u);
    finite_or_infinite(relative(
        complementarity_residual(r, &work.u, &p.mu),
        norm2(&p.q).max(work.floors.equation),
    ))
}

/// Error of a solution of either form (`v` and `lambda` are ignored for a local problem).
pub fn problem_error(p: &Problem, r: &[f64], v: &[f64], lambda: &[f64]) -> f64 {
    match p {
        Problem::Global(g) => global_error(g, r, v, lambda),
        Problem::Local(l) => local_error(l, r),
    }
}

/// The error measure of a solution of either form, with work space.
pub(crate) fn solution_error(p: &Problem, s: &Solution, work: &mut MeasureWork) -> f64 {
    match p {
        Problem::Global(g) => global_error_with(g, &s.r, &s.v, &s.lambda, work),
        Problem::Local(l) => local_error_with(l, &s.r, work),
    }
}
