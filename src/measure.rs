//! The error measure every test and benchmark uses (docs/algorithms.md §3; it matches
//! Siconos numerics). This is its only implementation: the splittings call it through a
//! [`MeasureWork`] so that it allocates nothing inside the iteration.
//!
//! global: `||-M v + H r + G lambda + f|| / max(||f||, ||M v||, ||H r + G lambda||)
//!          + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||)
//!          + ||rho_J|| / max(||G^T v||, ||b||, || |G|^T |diag(M)^-1 f| ||, ||lambda_B||)`,
//!          `u = H^T v + w` (joint terms only with joints), where a joint row's residual
//!          `rho_J` is its velocity `y = G^T v + b + c lambda` for an equality and the
//!          natural map `lambda - P_[lo,hi](lambda - y)` for a bounded row, and `lambda_B`
//!          the bounded rows' multipliers (none: the equalities' measure as it always was);
//! local:  `||r - P_K(r - (u + Phi(u)))|| / ||q||`, `u = W r + q`.
//!
//! A denominator divides whatever its size: the measure does not change when the data
//! are scaled (docs/algorithms.md §3.4). Only an exactly zero denominator is skipped, and
//! its term is then the residual as it is (zero vectors make a zero residual). Norms are
//! sums of squares kept in range by a power-of-two scale ([`SumSq`]), so that data of any
//! magnitude f64 holds are measured, not overflowed into a false zero. A non-finite input,
//! or a norm past f64's range, gives `inf`.
//! Joint multipliers that are not supplied (an empty `lambda`) are recomputed as the
//! least-squares solution of `G lambda = M v - H r - f`: the best multipliers for the given
//! `(r, v)`, so the measure then says whether `(r, v)` can be completed into a solution.

use crate::cone::{de_saxce, get3, project_cone};
use crate::csc::dot;
use crate::problem::{GlobalProblem, Joints, LocalProblem, Problem};
use crate::types::Solution;

/// `num / den`; `num` itself when `den` is zero (then the vectors of both are zero, and
/// so is `num` but for round-off); infinite when either is not finite, so that a norm
/// out of range never reads as a small error.
fn relative(num: f64, den: f64) -> f64 {
    if !num.is_finite() || !den.is_finite() {
        f64::INFINITY
    } else if den > 0.0 {
        num / den
    } else {
        num
    }
}

/// A sum of squares held as `scale^2 * ssq`. `scale` is a power of two, so rescaling is
/// exact; it is 1 (the plain sum, bitwise) unless the plain sum leaves the range where
/// squares neither overflow nor vanish, and then the largest magnitude's power of two.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SumSq {
    scale: f64,
    ssq: f64,
}

impl Default for SumSq {
    fn default() -> Self {
        Self {
            scale: 1.0,
            ssq: 0.0,
        }
    }
}

/// Below this a plain sum of squares may have lost terms to underflow (2^-900: a square
/// that flushes to zero is then below 2^-174 of the sum).
const SUM_SQ_LOW: f64 = 1.1830521861667747e-271;

impl SumSq {
    /// The sum of squares of `values()`, which is called a second time only when the plain
    /// sum is out of range.
    pub fn of<I: Iterator<Item = f64>>(values: impl Fn() -> I) -> Self {
        if let Some(sum) = Self::from_plain(values().map(|x| x * x).sum()) {
            return sum;
        }
        let largest = values().fold(0.0_f64, |m, x| m.max(x.abs()));
        if largest.is_nan() || !values().all(f64::is_finite) {
            return Self {
                scale: 1.0,
                ssq: f64::INFINITY,
            };
        }
        if largest == 0.0 {
            return Self::default();
        }
        let scale = power_of_two_above(largest);
        let ssq = values().map(|x| (x / scale) * (x / scale)).sum();
        Self { scale, ssq }
    }

    /// The sum of squares of `x`.
    pub fn of_slice(x: &[f64]) -> Self {
        Self::from_plain(dot(x, x)).unwrap_or_else(|| Self::of(|| x.iter().copied()))
    }

    /// A plain sum of squares when it is in range (no square overflowed or vanished).
    fn from_plain(plain: f64) -> Option<Self> {
        (plain.is_finite() && plain >= SUM_SQ_LOW).then_some(Self {
            scale: 1.0,
            ssq: plain,
        })
    }

    /// The norm, `scale * sqrt(ssq)` (infinite past f64's range).
    pub fn norm(self) -> f64 {
        self.scale * self.ssq.sqrt()
    }

    #[cfg(feature = "mpi")]
    /// The power-of-two scale.
    pub fn scale(self) -> f64 {
        self.scale
    }

    #[cfg(feature = "mpi")]
    /// `ssq` expressed at a scale at least this one's (exact but for terms that vanish
    /// beside the larger scale).
    pub fn ssq_at(self, scale: f64) -> f64 {
        let ratio = self.scale / scale;
        self.ssq * ratio * ratio
    }

    #[cfg(feature = "mpi")]
    /// A sum at `scale` of the sums of squares `ssq` (as [`SumSq::ssq_at`] gives them).
    pub fn at(scale: f64, ssq: f64) -> Self {
        Self { scale, ssq }
    }

    #[cfg(feature = "mpi")]
    /// The sum of both.
    pub fn add(self, other: Self) -> Self {
        let scale = self.scale.max(other.scale);
        Self {
            scale,
            ssq: self.ssq_at(scale) + other.ssq_at(scale),
        }
    }
}

/// The smallest power of two at or above `x` (positive, finite), within f64's normal range.
fn power_of_two_above(x: f64) -> f64 {
    let e = x.log2().ceil().clamp(-1022.0, 1023.0) as i32;
    let mut p = f64::from_bits(((e + 1023) as u64) << 52);
    if p < x && e < 1023 {
        p *= 2.0;
    }
    p
}

/// Norm of the natural-map residual `r - P_K(r - (u + Phi(u)))` over all contacts.
pub fn complementarity_residual(r: &[f64], u: &[f64], mu: &[f64]) -> f64 {
    complementarity_sq(r, u, mu).norm()
}

/// The natural-map residual of contact `i`.
fn natural_map(r: &[f64], u: &[f64], i: usize, mu: f64) -> [f64; 3] {
    let ri = get3(r, i);
    let ut = de_saxce(get3(u, i), mu);
    let p = project_cone([ri[0] - ut[0], ri[1] - ut[1], ri[2] - ut[2]], mu);
    [ri[0] - p[0], ri[1] - p[1], ri[2] - p[2]]
}

/// The square of [`complementarity_residual`], a sum over contacts (which processes
/// sharing a problem add up).
pub(crate) fn complementarity_sq(r: &[f64], u: &[f64], mu: &[f64]) -> SumSq {
    let mut plain = 0.0;
    for (i, &m) in mu.iter().enumerate() {
        let [a, b, c] = natural_map(r, u, i, m);
        plain += a * a + b * b + c * c;
    }
    SumSq::from_plain(plain).unwrap_or_else(|| {
        SumSq::of(|| {
            mu.iter()
                .enumerate()
                .flat_map(|(i, &m)| natural_map(r, u, i, m))
        })
    })
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
    /// Least-squares joint multipliers, when none are supplied.
    ls: Vec<f64>,
    /// The free velocities `diag(M)^-1 f` (the joint term's scale).
    free: Vec<f64>,
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
    pub(crate) fn fit_global(&mut self, p: &GlobalProblem) {
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
            work.ls = least_squares_multipliers(p, &work.mv, &work.hr);
            j.g.mul_vec(1.0, &work.ls, 1.0, &mut work.hr);
        }
        j.g.mul_t_vec(1.0, v, 0.0, &mut work.gv);
        let lambda = match lambda.len() == j.b.len() {
            true => lambda,
            false => &work.ls,
        };
        let scale = SumSq::of_slice(&work.gv)
            .norm()
            .max(SumSq::of_slice(&j.b).norm())
            .max(free_joint_velocity(p, &j.g, &mut work.free))
            .max(bounded_multipliers(j, lambda));
        let gv = &work.gv;
        let res =
            SumSq::of(|| (0..gv.len()).map(|k| joint_row_residual(j, k, gv[k], lambda[k], r)))
                .norm();
        work.scales.joint = scale;
        joint_error = relative(res, scale.max(work.floors.joint));
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

/// Row `k`'s residual at `gv = G_k^T v` and its multiplier `lambda`: the row's velocity
/// `y = gv + b + c lambda` for an equality, the natural map `lambda - P_[lo,hi](lambda - y)`
/// for a bounded row (zero exactly when `lambda` is inside its bounds with `y = 0`, or at
/// `lo` with `y >= 0`, or at `hi` with `y <= 0`), the bounds of a row bounded by a contact
/// taken at the impulses `r`.
fn joint_row_residual(j: &Joints, k: usize, gv: f64, lambda: f64, r: &[f64]) -> f64 {
    let y = j.row_velocity(k, gv, lambda);
    match j.is_bounded(k) {
        false => y,
        true => {
            let (lo, hi) = j.bounds(k, r);
            lambda - (lambda - y).clamp(lo, hi)
        }
    }
}

/// `||lambda||` over the bounded rows: the impulse scale of their natural-map residuals
/// (as `||r||` is the contacts'); zero for a problem of equalities only, whose measure is
/// then the joint velocities' alone.
fn bounded_multipliers(j: &Joints, lambda: &[f64]) -> f64 {
    SumSq::of(|| {
        (0..lambda.len())
            .filter(|&k| j.is_bounded(k))
            .map(|k| lambda[k])
    })
    .norm()
}

/// The velocities the joint rows see under free motion, `|| |G|^T |diag(M)^-1 f| ||`: the
/// joint term's scale from the data, for an answer at rest (a chain hanging still has
/// `G^T v = 0` and `b = 0`, and only this says how small its residual must be).
fn free_joint_velocity(p: &GlobalProblem, g: &crate::csc::CscMatrix, free: &mut Vec<f64>) -> f64 {
    free_velocity(p, free);
    free_row_velocity(g, free, |_| 0.0)
}

/// The contact velocities under free motion in the same sense, `|| |H|^T |diag(M)^-1 f| +
/// |w| ||`: the contact term's scale from the data, for the islands' floors before any
/// answer is known (docs/algorithms.md §12). An island of bodies that touch and move
/// together (a wall's row in free fall) has `u = 0` and `r = 0` at its answer, so its own
/// contact denominator is round-off, and only a floor from the data ends its solve.
pub(crate) fn free_contact_velocity(p: &GlobalProblem) -> f64 {
    let mut free = Vec::new();
    free_velocity(p, &mut free);
    free_row_velocity(&p.h, &free, |k| p.w[k].abs())
}

/// `diag(M)^-1 f` into `free`, one diagonal look-up per velocity (not one per entry of
/// the rows that read it). A diagonal that is not positive (M is then not positive
/// definite either, which the solver refuses) gives no free velocity.
fn free_velocity(p: &GlobalProblem, free: &mut Vec<f64>) {
    free.clear();
    free.extend((0..p.n()).map(|i| match p.m.diagonal_entry(i) {
        d if d > 0.0 => p.f[i] / d,
        _ => 0.0,
    }));
}

/// `|| |J|^T |free| + extra ||` over the columns of `j`.
fn free_row_velocity(j: &crate::csc::CscMatrix, free: &[f64], extra: impl Fn(usize) -> f64) -> f64 {
    let row = |k: usize| j.col(k).map(|(i, jik)| (jik * free[i]).abs()).sum::<f64>() + extra(k);
    SumSq::of(|| (0..j.ncols()).map(row)).norm()
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
        let (mv, hr, f) = (self.mv, self.hr, self.f);
        GlobalSums {
            equation: SumSq::of(|| mv.iter().zip(hr).zip(f).map(|((mv, hr), f)| -mv + hr + f)),
            f: SumSq::of_slice(self.f),
            mv: SumSq::of_slice(self.mv),
            hr: SumSq::of_slice(self.hr),
            complementarity: complementarity_sq(self.r, self.u, self.mu),
            u: SumSq::of_slice(self.u),
            r: SumSq::of_slice(self.r),
        }
    }
}

/// The squared norms the equation and contact terms of the global measure are made of:
/// sums over velocities and contacts, which islands and processes sharing a problem add up
/// before [`GlobalSums::error`] makes the measure of them.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GlobalSums {
    /// `||-M v + H r + f||^2`.
    pub equation: SumSq,
    /// `||f||^2`, `||M v||^2`, `||H r||^2`.
    pub f: SumSq,
    pub mv: SumSq,
    pub hr: SumSq,
    /// `||r - P_K(r - (u + Phi(u)))||^2`.
    pub complementarity: SumSq,
    /// `||u||^2`, `||r||^2`.
    pub u: SumSq,
    pub r: SumSq,
}

impl GlobalSums {
    #[cfg(feature = "mpi")]
    fn parts(&self) -> [SumSq; 7] {
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

    #[cfg(feature = "mpi")]
    fn from_parts(parts: [SumSq; 7]) -> Self {
        let [equation, f, mv, hr, complementarity, u, r] = parts;
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

    #[cfg(feature = "mpi")]
    /// The sums of both, entry by entry (an island's sums added to the rest's).
    pub fn add(self, other: Self) -> Self {
        let (a, b) = (self.parts(), other.parts());
        Self::from_parts(std::array::from_fn(|k| a[k].add(b[k])))
    }

    /// Every process's sums added up: `max_across` takes the largest of each scale over
    /// the processes, then `sum_across` adds the sums of squares expressed at those scales.
    /// `None` when some process's vectors were not all `finite`: that flag travels with the
    /// scales, one exchange for both.
    #[cfg(feature = "mpi")]
    pub fn add_across(
        self,
        finite: bool,
        max_across: impl FnOnce(&mut [f64]),
        sum_across: impl FnOnce(&mut [f64]),
    ) -> Option<Self> {
        let parts = self.parts();
        let mut scales = [0.0; 8];
        for (s, part) in scales.iter_mut().zip(&parts) {
            *s = part.scale();
        }
        scales[7] = f64::from(u8::from(!finite));
        max_across(&mut scales);
        if scales[7] > 0.0 {
            return None;
        }
        let mut ssq: [f64; 7] = std::array::from_fn(|k| parts[k].ssq_at(scales[k]));
        sum_across(&mut ssq);
        Some(Self::from_parts(std::array::from_fn(|k| {
            SumSq::at(scales[k], ssq[k])
        })))
    }

    /// `||-M v + H r + f|| / max(||f||, ||M v||, ||H r||) + ||r - P_K(r - (u + Phi(u)))|| /
    /// max(||u||, ||r||)`, denominators floored by `floors`; records the denominators in
    /// `scales`.
    pub fn error(&self, floors: Floors, scales: &mut Scales) -> f64 {
        let scale = self.f.norm().max(self.mv.norm()).max(self.hr.norm());
        scales.equation = scale;
        let e1 = relative(self.equation.norm(), scale.max(floors.equation));
        let scale = self.u.norm().max(self.r.norm());
        scales.contact = scale;
        let e2 = relative(self.complementarity.norm(), scale.max(floors.contact));
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
    if n == 0 || np == 0 {
        // G has no entry: no multiplier moves the equation (and nalgebra's SVD of an
        // empty matrix panics).
        return vec![0.0; np];
    }
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
        SumSq::of_slice(&p.q).norm().max(work.floors.equation),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csc::CscMatrix;

    fn empty(nrows: usize, ncols: usize) -> CscMatrix {
        CscMatrix::from_triplets("M", nrows, ncols, &[]).unwrap()
    }

    /// No velocity and two joint rows: the multipliers are recomputed from an empty G
    /// (whose SVD panicked), and the error is that of the joint residual `||b||`.
    #[test]
    fn joints_without_velocities_are_measured() {
        let p = GlobalProblem::new(empty(0, 0), empty(0, 0), vec![], vec![], vec![])
            .unwrap()
            .with_joints(empty(0, 2), vec![0.0, 0.0])
            .unwrap();
        assert_eq!(global_error(&p, &[], &[], &[]), 0.0);
        let q = p.clone().with_joints(empty(0, 2), vec![1.0, 0.0]).unwrap();
        assert_eq!(global_error(&q, &[], &[], &[]), 1.0);
    }

    /// Sums of squares in and out of the plain range: the same norm as an exact scaling.
    #[test]
    fn sums_of_squares_stay_in_range() {
        for scale in [1.0, 1e-200, 1e-310, 1e200, 1e300] {
            let x = [3.0 * scale, -4.0 * scale];
            let n = SumSq::of_slice(&x).norm();
            assert!(
                (n - 5.0 * scale).abs() <= 1e-15 * 5.0 * scale,
                "{scale:e}: {n:e}"
            );
        }
        assert_eq!(SumSq::of_slice(&[0.0, 0.0]).norm(), 0.0);
        assert_eq!(SumSq::of_slice(&[f64::MAX, f64::MAX]).norm(), f64::INFINITY);
        assert!(SumSq::of_slice(&[f64::NAN]).norm().is_infinite());
    }
}
