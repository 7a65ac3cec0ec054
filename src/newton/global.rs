//! Semismooth Newton for the global problem, without forming the Delassus matrix.
//!
//! Unknowns `z = (v, lambda, r)` (velocities, joint multipliers, contact impulses) and
//! residual
//!
//! ```text
//! R_v      = M v - H r - G lambda - f
//! R_lambda = G^T v + b + c lambda        (per joint row; see below for bounded rows)
//! R_r      = F_AC(r, H^T v + w)
//! ```
//!
//! A bounded joint row's residual is the natural map scaled to velocity units,
//! `S_k (lambda - P_[lo,hi](lambda - y / S_k))` with `y = G_k^T v + b_k + c_k lambda`: `y`
//! while the row is inside its bounds (the equality's residual), `S_k (lambda - bound)`
//! once clamped, whose row of the Newton matrix is then `S_k dl_k` alone (its generalized
//! Jacobian: the step lands on the bound).
//!
//! with the Newton matrix
//!
//! ```text
//! [ M       -G            -H             ]
//! [ G^T     alpha S        0             ]
//! [ A H^T    0             B + alpha D A ]
//! ```
//!
//! `D = diag(1 / rho_i)`, `S = diag(G_k^T diag(M)^-1 G_k)` (plus the compliances `C` on
//! the joint rows' diagonal). Eliminating `v` gives the
//! local Newton matrix `A (W + alpha D) + B` exactly (and `G^T M^-1 G + alpha S` for the
//! joints), so the regularization, line search and stopping rules are those of
//! [`super::local`]: the proximal term keeps the matrix invertible when contacts (or
//! joints) are redundant. The error measure is `crate::measure::global_error`.

use super::reduced::{columns, ReducedSystem, StepBlocks};
use super::sparse::{Pattern, SparseLu};
use super::{
    ac_branch, backtrack, impulse_scale, iterate, rho_from_block, AcPoint, Branch, NewtonOutcome,
    NewtonSystem,
};
use crate::csc::CscMatrix;
use crate::measure::{global_error_with, MeasureWork};
use crate::problem::{GlobalProblem, Joints};
use crate::tuning::NEWTON;
use crate::types::Error;
use std::time::Instant;

/// Newton solver of a global problem; built once per sparsity pattern of `(M, H, G)`.
pub struct GlobalNewton {
    n: usize,
    p: usize,
    nc: usize,
    /// Patterns of M, H, G the solver was built for: (colptr, rowind).
    patterns: [(Vec<usize>, Vec<usize>); 3],
    rho: Vec<f64>,
    /// Joint scaling `S_k` (units of a Delassus entry).
    joint_scale: Vec<f64>,
    /// `diag(M)^-1` (scaling work).
    minv: Vec<f64>,
    /// The system reduced to the velocities, solved first at every step.
    reduced: ReducedSystem,
    /// The unreduced system, built at the first step the reduced one refuses.
    unreduced: Option<Unreduced>,
    /// `alpha / rho_i` per contact and `alpha S_k` per joint, at the current step.
    reg: Vec<f64>,
    joint_reg: Vec<f64>,
    /// Right-hand side of the Newton system.
    rhs: Vec<f64>,
    // Residual pieces at the current point and their trial counterparts.
    rv: Vec<f64>,
    rl: Vec<f64>,
    /// `G^T v` at the current point, and which joint rows are clamped at a bound there.
    gv: Vec<f64>,
    clamped: Vec<bool>,
    /// The Alart-Curnier function at the current point and at the trial point.
    point: AcPoint,
    trial_point: AcPoint,
    /// Newton direction `(dv, dlambda, dr)` and its images `J_v d`, `G^T dv`, `H^T dv`.
    d: Vec<f64>,
    jd_v: Vec<f64>,
    gt_dv: Vec<f64>,
    ht_dv: Vec<f64>,
    z_trial: Vec<f64>,
    best: Vec<f64>,
    /// The current point `(v, lambda, r)`, taken out of `self` during a solve.
    z: Vec<f64>,
    measure: MeasureWork,
    /// The free velocity `w + H^T diag(M)^-1 f`, for [`NewtonSystem::impulse_scale`].
    u_free: Vec<f64>,
    /// Steps without progress after which a solve gives up ([`GlobalNewton::set_stall`]).
    stall: usize,
}

fn pattern_of(a: &CscMatrix) -> (Vec<usize>, Vec<usize>) {
    (a.colptr().to_vec(), a.rowind().to_vec())
}

/// (row, column, value) of every stored entry, in storage order.
fn entries(a: &CscMatrix) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
    (0..a.ncols()).flat_map(move |c| a.col(c).map(move |(i, v)| (i, c, v)))
}

/// The blocks of the Newton matrix: `n` velocities, `p` joint multipliers and `m = 3 nc`
/// contact impulses, with M, G (`n x p`) and H (`n x m`).
#[derive(Clone, Copy)]
struct Blocks<'a> {
    n: usize,
    p: usize,
    m: usize,
    mm: &'a CscMatrix,
    g: &'a CscMatrix,
    h: &'a CscMatrix,
}

/// Where the entries of each block land in the values of the unreduced Newton matrix.
struct Destinations {
    m: Vec<usize>,
    g: Vec<usize>,
    gt: Vec<usize>,
    h: Vec<usize>,
    /// Per H entry (row j, column c): position of row `n + p + 3 (c / 3)` in column j.
    ah: Vec<usize>,
    /// Per contact column c: position of the first row of its diagonal block.
    diag: Vec<usize>,
    lam: Vec<usize>,
}

/// The unreduced Newton matrix (module documentation) and its LU.
struct Unreduced {
    dest: Destinations,
    lu: SparseLu,
}

impl Blocks<'_> {
    /// Pattern of the Newton matrix (module documentation), with the rows of `A H^T` and
    /// of `B + alpha D A` as whole 3 x 3 contact blocks since A and B are dense per contact.
    fn pattern(&self) -> Pattern {
        let Self { n, p, m, mm, g, h } = *self;
        let (ov, or) = (n + p, n + p); // offsets of the contact rows / columns
        let gt = g.transpose();
        let mut cols: Vec<Vec<usize>> = vec![Vec::new(); n + p + m];
        for (i, j, _) in entries(mm) {
            cols[j].push(i);
        }
        for (k, j, _) in entries(&gt) {
            // G^T in the joint rows of the v columns, -G in the v rows of the lambda columns.
            cols[j].push(n + k);
            cols[n + k].push(j);
        }
        for k in 0..p {
            cols[n + k].push(n + k);
        }
        for (j, c, _) in entries(h) {
            let i = c / 3;
            cols[or + c].push(j);
            cols[j].extend([ov + 3 * i, ov + 3 * i + 1, ov + 3 * i + 2]);
        }
        for c in 0..m {
            let i = c / 3;
            cols[or + c].extend([ov + 3 * i, ov + 3 * i + 1, ov + 3 * i + 2]);
        }
        Pattern::from_columns(n + p + m, cols)
    }

    /// Positions in `pat` of every block entry, so that each Newton step fills the matrix
    /// without a search.
    fn destinations(&self, pat: &Pattern) -> Destinations {
        let Self { n, p, m, mm, g, h } = *self;
        let (ov, or) = (n + p, n + p); // offsets of the contact rows / columns
        Destinations {
            m: entries(mm).map(|(i, j, _)| pat.pos(i, j)).collect(),
            g: entries(g).map(|(j, k, _)| pat.pos(j, n + k)).collect(),
            gt: entries(g).map(|(j, k, _)| pat.pos(n + k, j)).collect(),
            h: entries(h).map(|(j, c, _)| pat.pos(j, or + c)).collect(),
            ah: entries(h)
                .map(|(j, c, _)| pat.pos(ov + 3 * (c / 3), j))
                .collect(),
            diag: (0..m).map(|c| pat.pos(ov + 3 * (c / 3), or + c)).collect(),
            lam: (0..p).map(|k| pat.pos(n + k, n + k)).collect(),
        }
    }
}

impl GlobalNewton {
    /// Builds the reduced Newton system and its symbolic LU; `rho_i = 1 / ||W_ii||_F`
    /// with `W_ii` approximated by `H_i^T diag(M)^-1 H_i` (exact for a diagonal M, and W
    /// is never formed).
    pub fn new(prob: &GlobalProblem) -> Result<Self, Error> {
        if prob.has_contact_bounds() {
            return Err(Error::Unsupported(
                "Newton: rows bounded by a contact's normal impulse (rolling or spinning \
                 friction) are solved by ADMM alone"
                    .into(),
            ));
        }
        let n = prob.n();
        let nc = prob.n_contacts();
        let empty = CscMatrix::from_triplets("G", n, 0, &[])?;
        let g = prob.joints.as_ref().map_or(&empty, |j| &j.g);
        let p = g.ncols();
        let reduced = ReducedSystem::new(&prob.m, &prob.h, g)?;
        let nz = n + p + 3 * nc;
        let mut newton = Self {
            n,
            p,
            nc,
            patterns: [pattern_of(&prob.m), pattern_of(&prob.h), pattern_of(g)],
            rho: vec![0.0; nc],
            joint_scale: vec![0.0; p],
            minv: vec![0.0; n],
            reduced,
            unreduced: None,
            reg: vec![0.0; nc],
            joint_reg: vec![0.0; p],
            rhs: vec![0.0; nz],
            rv: vec![0.0; n],
            rl: vec![0.0; p],
            gv: vec![0.0; p],
            clamped: vec![false; p],
            point: AcPoint::new(nc),
            trial_point: AcPoint::new(nc),
            d: vec![0.0; nz],
            jd_v: vec![0.0; n],
            gt_dv: vec![0.0; p],
            ht_dv: vec![0.0; 3 * nc],
            z_trial: vec![0.0; nz],
            best: vec![0.0; nz],
            z: vec![0.0; nz],
            measure: MeasureWork::global(prob),
            stall: NEWTON.stall,
            u_free: vec![0.0; 3 * nc],
        };
        newton.take_values(prob);
        Ok(newton)
    }

    /// The unreduced system for `prob`'s patterns (built once, at the first refusal of
    /// the reduced one).
    fn unreduced(prob: &GlobalProblem) -> Result<Unreduced, Error> {
        let n = prob.n();
        let empty = CscMatrix::from_triplets("G", n, 0, &[])?;
        let g = prob.joints.as_ref().map_or(&empty, |j| &j.g);
        let blocks = Blocks {
            n,
            p: g.ncols(),
            m: 3 * prob.n_contacts(),
            mm: &prob.m,
            g,
            h: &prob.h,
        };
        let pat = blocks.pattern();
        let dest = blocks.destinations(&pat);
        let lu = SparseLu::new("global Newton matrix", pat)?;
        Ok(Unreduced { dest, lu })
    }

    /// Steps without progress after which a solve gives up, when a step's cost is known
    /// (`NEWTON.stall` otherwise): a phase should not go on without progress past what
    /// ADMM would have done in that time (`ProblemSplitting::newton_stall`).
    pub fn set_stall(&mut self, steps: usize) {
        self.stall = steps.max(1);
    }

    /// Floors of the error measure (an island's share of a scene's measure).
    pub fn set_measure_floors(&mut self, floors: crate::measure::Floors) {
        self.measure.floors = floors;
    }

    /// Recomputes the scalings from the values of `prob` (same patterns as at
    /// construction): `rho_i = 1 / ||W_ii||_F` with `W_ii` approximated by
    /// `H_i^T diag(M)^-1 H_i`, and the joint scalings. No allocation.
    pub fn take_values(&mut self, prob: &GlobalProblem) {
        // diag(M)^-1 (a non-positive diagonal entry is left out).
        self.minv.fill(0.0);
        for (i, j, v) in entries(&prob.m) {
            if i == j && v > 0.0 {
                self.minv[i] = 1.0 / v;
            }
        }
        let h = &prob.h;
        for (i, rho) in self.rho.iter_mut().enumerate() {
            let mut blk = [[0.0; 3]; 3];
            for a in 0..3 {
                for b in 0..3 {
                    blk[a][b] = weighted_dot(h, 3 * i + a, 3 * i + b, &self.minv);
                }
            }
            *rho = rho_from_block(&blk);
        }
        // u_free through diag(M)^-1: exact for a diagonal M, a scale either way.
        for (c, (u, w)) in self.u_free.iter_mut().zip(&prob.w).enumerate() {
            *u = w + h
                .col(c)
                .map(|(j, x)| x * self.minv[j] * prob.f[j])
                .sum::<f64>();
        }
        if let Some(j) = &prob.joints {
            for (k, scale) in self.joint_scale.iter_mut().enumerate() {
                let s = weighted_dot(&j.g, k, k, &self.minv);
                *scale = if s > 0.0 && s.is_finite() { s } else { 1.0 };
            }
        }
    }

    /// Factorizes the reduced Newton matrix and solves for `rhs` into `d`; false when the
    /// reduced solve is refused (docs/algorithms.md §9.2).
    fn reduced_direction(&mut self, prob: &GlobalProblem) -> bool {
        let blocks = StepBlocks {
            m: &prob.m,
            h: &prob.h,
            g: prob.joints.as_ref().map(|j| &j.g),
            a: &self.point.a,
            b: &self.point.b,
            reg: &self.reg,
            joint_reg: &self.joint_reg,
            clamped: &self.clamped,
        };
        self.reduced.factor(&blocks) && self.reduced.solve(&blocks, &self.rhs, &mut self.d)
    }

    /// Assembles, factorizes and solves the unreduced Newton matrix for `rhs` into `d`.
    fn unreduced_direction(&mut self, prob: &GlobalProblem) -> bool {
        if self.unreduced.is_none() {
            match Self::unreduced(prob) {
                Ok(u) => self.unreduced = Some(u),
                Err(_) => return false,
            }
        }
        let Some(Unreduced { dest, lu }) = &mut self.unreduced else {
            return false;
        };
        let vals = &mut lu.values;
        vals.fill(0.0);
        for (k, &v) in prob.m.values().iter().enumerate() {
            vals[dest.m[k]] = v;
        }
        if let Some(j) = &prob.joints {
            let clamped = &self.clamped;
            for ((k, &v), col) in j.g.values().iter().enumerate().zip(columns(&j.g)) {
                vals[dest.g[k]] = -v;
                vals[dest.gt[k]] = if clamped[col] { 0.0 } else { v };
            }
        }
        for (&k, &reg) in dest.lam.iter().zip(&self.joint_reg) {
            vals[k] = reg;
        }
        for (k, (_, c, v)) in entries(&prob.h).enumerate() {
            vals[dest.h[k]] = -v;
            // A H^T: entry H[j, c] feeds rows 3i..3i+3 of column j through column c % 3 of A_i.
            let (ai, b, base) = (&self.point.a[c / 3], c % 3, dest.ah[k]);
            for row in 0..3 {
                vals[base + row] += ai[row][b] * v;
            }
        }
        for c in 0..3 * self.nc {
            let i = c / 3;
            let (ai, bi, col, base) = (&self.point.a[i], &self.point.b[i], c % 3, dest.diag[c]);
            for row in 0..3 {
                vals[base + row] += bi[row][col] + self.reg[i] * ai[row][col];
            }
        }
        if !lu.factor() {
            return false;
        }
        self.d.copy_from_slice(&self.rhs);
        lu.solve_in_place(&mut self.d)
    }

    fn check(
        &self,
        prob: &GlobalProblem,
        v: &[f64],
        r: &[f64],
        lambda: &[f64],
    ) -> Result<(), Error> {
        // Compared in place (no copies): a solve allocates nothing per step.
        let same_as = |k: usize, a: &CscMatrix| {
            self.patterns[k].0 == a.colptr() && self.patterns[k].1 == a.rowind()
        };
        let same = prob.n() == self.n
            && prob.n_contacts() == self.nc
            && same_as(0, &prob.m)
            && same_as(1, &prob.h)
            && match &prob.joints {
                Some(j) => same_as(2, &j.g),
                None => self.p == 0,
            };
        if !same {
            return Err(Error::PatternChanged { field: "M, H or G" });
        }
        for (field, x, len) in [
            ("v", v, self.n),
            ("r", r, 3 * self.nc),
            ("lambda", lambda, self.p),
        ] {
            if x.len() != len {
                return Err(Error::Dimension {
                    field,
                    expected: len,
                    found: x.len(),
                });
            }
        }
        Ok(())
    }

    /// Solves from `(v, r, lambda)` until `global_error <= tol`, `max_iter` steps, the
    /// deadline, or a failure; leaves the best iterate (by `global_error`) in
    /// `(v, r, lambda)`. `lambda` is empty without joints.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        prob: &GlobalProblem,
        v: &mut [f64],
        r: &mut [f64],
        lambda: &mut [f64],
        tol: f64,
        max_iter: usize,
        deadline: Option<Instant>,
    ) -> Result<NewtonOutcome, Error> {
        self.check(prob, v, r, lambda)?;
        let (n, p) = (self.n, self.p);
        let mut z = std::mem::take(&mut self.z);
        z[..n].copy_from_slice(v);
        z[n..n + p].copy_from_slice(lambda);
        z[n + p..].copy_from_slice(r);
        let mut best = std::mem::take(&mut self.best);
        let out = iterate(self, prob, &mut z, &mut best, tol, max_iter, deadline);
        self.best = best;
        v.copy_from_slice(&z[..n]);
        lambda.copy_from_slice(&z[n..n + p]);
        r.copy_from_slice(&z[n + p..]);
        self.z = z;
        Ok(out)
    }
}

impl NewtonSystem for GlobalNewton {
    type Problem = GlobalProblem;

    fn error(&mut self, prob: &GlobalProblem, z: &[f64]) -> f64 {
        let (n, p) = (self.n, self.p);
        global_error_with(prob, &z[n + p..], &z[..n], &z[n..n + p], &mut self.measure)
    }

    fn trial(&self) -> &[f64] {
        &self.z_trial
    }

    fn stall(&self) -> usize {
        self.stall
    }

    fn factorizations(&self) -> usize {
        self.reduced.factorizations() + self.unreduced.as_ref().map_or(0, |u| u.lu.factorizations())
    }

    fn impulse_scale(&self, _: &GlobalProblem, z: &[f64]) -> f64 {
        impulse_scale(&z[self.n + self.p..], &self.rho, &self.u_free)
    }

    /// Residuals, F, A, B at `z`; returns the merit `0.5 ||R||^2`.
    fn evaluate_at(&mut self, prob: &GlobalProblem, z: &[f64]) -> f64 {
        let (n, p) = (self.n, self.p);
        let (v, lambda, r) = (&z[..n], &z[n..n + p], &z[n + p..]);
        // R_v = M v - H r - G lambda - f
        prob.m.mul_vec(1.0, v, 0.0, &mut self.rv);
        prob.h.mul_vec(-1.0, r, 1.0, &mut self.rv);
        for (x, f) in self.rv.iter_mut().zip(&prob.f) {
            *x -= f;
        }
        if let Some(j) = &prob.joints {
            j.g.mul_vec(-1.0, lambda, 1.0, &mut self.rv);
            j.g.mul_t_vec(1.0, v, 0.0, &mut self.gv);
            for k in 0..p {
                let s = self.joint_scale[k];
                (self.rl[k], self.clamped[k]) = row_residual(j, k, self.gv[k], lambda[k], s);
            }
        }
        let merit = crate::csc::dot(&self.rv, &self.rv) + crate::csc::dot(&self.rl, &self.rl);
        self.point.u.copy_from_slice(&prob.w);
        prob.h.mul_t_vec(1.0, v, 1.0, &mut self.point.u);
        0.5 * merit + self.point.evaluate(r, &prob.mu, &self.rho)
    }

    /// Solves the Newton system for the direction, reduced to the velocities when that
    /// solve is accurate and unreduced otherwise; false when singular or not finite.
    fn direction(&mut self, prob: &GlobalProblem, alpha: f64) -> bool {
        let (n, p) = (self.n, self.p);
        for (reg, rho) in self.reg.iter_mut().zip(&self.rho) {
            *reg = alpha / rho;
        }
        if let Some(j) = &prob.joints {
            for k in 0..p {
                let s = self.joint_scale[k];
                self.joint_reg[k] = match self.clamped[k] {
                    true => s,
                    false if j.compliance[k] == 0.0 => alpha * s,
                    false => alpha * s + j.compliance[k],
                };
            }
        }
        for (x, r) in self.rhs.iter_mut().zip(self.rv.iter().chain(&self.rl)) {
            *x = -r;
        }
        for (x, f) in self.rhs[n + p..].iter_mut().zip(&self.point.f) {
            *x = -f;
        }
        if !(self.reduced_direction(prob) || self.unreduced_direction(prob)) {
            return false;
        }
        // Images of the direction for the linear updates of the line search.
        let d = &self.d;
        let (dv, dl, dr) = (&d[..n], &d[n..n + p], &d[n + p..]);
        prob.m.mul_vec(1.0, dv, 0.0, &mut self.jd_v);
        prob.h.mul_vec(-1.0, dr, 1.0, &mut self.jd_v);
        if let Some(j) = &prob.joints {
            j.g.mul_vec(-1.0, dl, 1.0, &mut self.jd_v);
            j.g.mul_t_vec(1.0, dv, 0.0, &mut self.gt_dv);
        }
        prob.h.mul_t_vec(1.0, dv, 0.0, &mut self.ht_dv);
        true
    }

    /// Backtracking on `||R||`; on success the trial point is in `z_trial`.
    fn line_search(&mut self, prob: &GlobalProblem, z: &[f64], merit: f64) -> Option<f64> {
        let (n, p) = (self.n, self.p);
        let Self {
            z_trial,
            d,
            rv,
            jd_v,
            rl,
            gv,
            joint_scale,
            gt_dv,
            point,
            trial_point,
            ht_dv,
            rho,
            ..
        } = self;
        backtrack(merit, |t| {
            for k in 0..z.len() {
                z_trial[k] = z[k] + t * d[k];
            }
            let mut lin = 0.0;
            for k in 0..n {
                let x = rv[k] + t * jd_v[k];
                lin += x * x;
            }
            for k in 0..p {
                // An equality's residual is linear along the step; a bounded or compliant
                // row's is evaluated at the trial point.
                let x = match &prob.joints {
                    Some(j) if j.is_bounded(k) || j.compliance[k] != 0.0 => {
                        let (lambda, s) = (z_trial[n + k], joint_scale[k]);
                        row_residual(j, k, gv[k] + t * gt_dv[k], lambda, s).0
                    }
                    _ => rl[k] + t * gt_dv[k],
                };
                lin += x * x;
            }
            for k in 0..point.u.len() {
                trial_point.u[k] = point.u[k] + t * ht_dv[k];
            }
            0.5 * lin + trial_point.evaluate(&z_trial[n + p..], &prob.mu, rho)
        })
    }

    /// Zeroes the impulses of the contacts found open at the converged point (round-off
    /// otherwise) when the error stays within `max(error, tol)`.
    fn snap_open(&mut self, prob: &GlobalProblem, z: &mut [f64], error: f64, tol: f64) -> f64 {
        let off = self.n + self.p;
        self.evaluate_at(prob, z);
        self.z_trial.copy_from_slice(z);
        let mut changed = false;
        for i in 0..self.nc {
            let k = off + 3 * i;
            let ri = [z[k], z[k + 1], z[k + 2]];
            let ui = [
                self.point.u[3 * i],
                self.point.u[3 * i + 1],
                self.point.u[3 * i + 2],
            ];
            if ac_branch(ri, ui, prob.mu[i], self.rho[i], self.rho[i]) == Branch::Open
                && ri.iter().any(|&x| x != 0.0)
            {
                self.z_trial[k..k + 3].fill(0.0);
                changed = true;
            }
        }
        if !changed {
            return error;
        }
        let trial = std::mem::take(&mut self.z_trial);
        let snapped = self.error(prob, &trial);
        self.z_trial = trial;
        if snapped <= error.max(tol) {
            z.copy_from_slice(&self.z_trial);
            snapped
        } else {
            error
        }
    }
}

/// Joint row `k`'s residual at `gv = G_k^T v` and `lambda`, in velocity units, and whether
/// the row is clamped at a bound (module documentation): `y = gv + b + c lambda` for an
/// equality or a bounded row inside its bounds, `s (lambda - bound)` for a clamped one.
fn row_residual(j: &Joints, k: usize, gv: f64, lambda: f64, s: f64) -> (f64, bool) {
    let y = j.row_velocity(k, gv, lambda);
    if !j.is_bounded(k) {
        return (y, false);
    }
    let free = lambda - y / s;
    if free <= j.lo[k] {
        (s * (lambda - j.lo[k]), true)
    } else if free >= j.hi[k] {
        (s * (lambda - j.hi[k]), true)
    } else {
        (y, false)
    }
}

/// `sum_j a[j, c1] a[j, c2] w[j]` for two columns of `a` (sorted rows: merge).
fn weighted_dot(a: &CscMatrix, c1: usize, c2: usize, w: &[f64]) -> f64 {
    let (mut x, mut y) = (a.col(c1).peekable(), a.col(c2).peekable());
    let mut s = 0.0;
    while let (Some(&(i, vi)), Some(&(j, vj))) = (x.peek(), y.peek()) {
        match i.cmp(&j) {
            std::cmp::Ordering::Less => {
                x.next();
            }
            std::cmp::Ordering::Greater => {
                y.next();
            }
            std::cmp::Ordering::Equal => {
                s += vi * vj * w[i];
                x.next();
                y.next();
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::global_error;
    use crate::newton::testing::{
        box_problem, duplicated, perturb, point_mass_problem, random_stacks, DT, G,
    };

    struct Run {
        v: Vec<f64>,
        r: Vec<f64>,
        lambda: Vec<f64>,
        out: NewtonOutcome,
    }

    /// Solves from `(v, r)` (lambda = 0) and checks the reported error independently.
    fn solve_from(p: &GlobalProblem, v: Vec<f64>, r: Vec<f64>, tol: f64) -> Run {
        let mut s = GlobalNewton::new(p).unwrap();
        let (mut v, mut r) = (v, r);
        let mut lambda = vec![0.0; p.n_joints()];
        let out = s
            .solve(p, &mut v, &mut r, &mut lambda, tol, 100, None)
            .unwrap();
        assert_eq!(out.error, global_error(p, &r, &v, &lambda));
        Run { v, r, lambda, out }
    }

    fn cold(p: &GlobalProblem, tol: f64) -> Run {
        solve_from(p, vec![0.0; p.n()], vec![0.0; 3 * p.n_contacts()], tol)
    }

    fn report(name: &str, out: &NewtonOutcome) {
        eprintln!(
            "global {name}: {:?}, {} iterations, {} factorizations, error {:.2e}",
            out.status, out.iterations, out.factorizations, out.error
        );
    }

    #[test]
    fn point_mass_slides_with_mu_10_under_light_load() {
        // Mass 2, normal load 0.05 N, push 30 N: r_N = 0.05 dt, mu r_N = 0.5 dt < 30 dt, so
        // it slides: r_T = (-mu r_N, 0), v_x = (30 dt - mu r_N) / 2, v_z = 0.
        let p = point_mass_problem(10.0, 2.0, 30.0, 0.05, 1);
        let run = cold(&p, 1e-14);
        report("point mass mu=10 slide", &run.out);
        assert!(run.out.converged());
        let rn = 0.05 * DT;
        let exact = [rn, -10.0 * rn, 0.0];
        for k in 0..3 {
            assert!((run.r[k] - exact[k]).abs() < 1e-10, "{:?}", run.r);
        }
        assert!((run.v[0] - (30.0 * DT - 10.0 * rn) / 2.0).abs() < 1e-10);
        assert!(run.v[2].abs() < 1e-10);
    }

    #[test]
    fn box_on_four_corners_rank_deficient() {
        let p = box_problem(0.5, 0.0, 0.0);
        let run = cold(&p, 1e-8);
        report("box at rest (cold)", &run.out);
        assert!(run.out.converged());
        let total: f64 = (0..4).map(|i| run.r[3 * i]).sum();
        assert!((total - 2.0 * G * DT).abs() < 1e-8 * 2.0 * G * DT);
        assert!(run.v.iter().all(|v| v.abs() < 1e-8), "{:?}", run.v);
    }

    #[test]
    fn box_pushed_sideways_with_mu_1e3_sticks() {
        let p = box_problem(1e3, 5.0, 0.0);
        let run = cold(&p, 1e-8);
        report("box pushed, mu=1e3 (cold)", &run.out);
        assert!(run.out.converged());
        assert!(run.v.iter().all(|v| v.abs() < 1e-8), "{:?}", run.v);
    }

    #[test]
    fn box_pushed_sideways_slides() {
        for &(mu, push) in &[(0.0, 5.0), (0.3, 10.0)] {
            let p = box_problem(mu, push, 0.0);
            let run = cold(&p, 1e-10);
            report(&format!("box sliding mu={mu} (cold)"), &run.out);
            assert!(run.out.converged());
            let vx = DT * (push - mu * 2.0 * G) / 2.0;
            assert!((run.v[0] - vx).abs() < 1e-9 * vx, "{:?} vs {vx}", run.v);
            assert!(run.v[1..].iter().all(|x| x.abs() < 1e-9), "{:?}", run.v);
        }
    }

    #[test]
    fn separating_contacts_give_exactly_zero() {
        let p = box_problem(0.5, 3.0, 2.0);
        for start in [0.0, 0.01] {
            let run = solve_from(&p, vec![0.0; 6], vec![start; 12], 1e-8);
            report(&format!("box lifted (start {start})"), &run.out);
            assert!(run.out.converged());
            assert!(run.r.iter().all(|&x| x == 0.0), "{:?}", run.r);
            // v = M^-1 f: up 9.81 dt, along x 1.5 dt.
            assert!((run.v[2] - G * DT).abs() < 1e-12 && (run.v[0] - 1.5 * DT).abs() < 1e-12);
        }
    }

    #[test]
    fn duplicated_contacts() {
        for &(mu, push) in &[(0.5, 2.0), (0.5, 20.0)] {
            let p = point_mass_problem(mu, 1.0, push, G, 2);
            let run = cold(&p, 1e-10);
            report(&format!("point mass x2 push {push}"), &run.out);
            assert!(run.out.converged());
            let vx = if push > mu * G {
                DT * (push - mu * G)
            } else {
                0.0
            };
            assert!(
                (run.v[0] - vx).abs() < 1e-9 && run.v[2].abs() < 1e-9,
                "{:?}",
                run.v
            );
        }
        let p = duplicated(&box_problem(0.5, 3.0, 0.0));
        let run = cold(&p, 1e-8);
        report("box with duplicated corners (cold)", &run.out);
        assert!(run.out.converged());
        assert!(run.v.iter().all(|v| v.abs() < 1e-8));
    }

    /// The reduced solve against the unreduced LU at one point of `p`: same direction.
    /// Returns the contact states met at that point.
    fn directions_agree(p: &GlobalProblem, seed: u64, alpha: f64) -> Vec<String> {
        let mut s = GlobalNewton::new(p).unwrap();
        let (n, np) = (p.n(), p.n() + p.n_joints());
        let mut z = vec![0.0; np + 3 * p.n_contacts()];
        perturb(&mut z[..n], 1.0, 0.05, seed);
        // Impulses of every kind: open (0), sticking and sliding (large tangential).
        perturb(&mut z[np..], 1.0, 0.2, seed + 1);
        for (i, c) in z[np..].chunks_mut(3).enumerate() {
            c[0] = [0.0, 0.3, 0.5][i % 3];
        }
        s.evaluate_at(p, &z);
        // Fills the right-hand side and regularization for the step, then solves again
        // through the reduced system alone, which must accept its own solve.
        assert!(s.direction(p, alpha));
        assert!(s.reduced_direction(p));
        let reduced = s.d.clone();
        assert!(s.unreduced_direction(p));
        let diff = reduced
            .iter()
            .zip(&s.d)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>();
        let size = s.d.iter().map(|x| x * x).sum::<f64>();
        assert!(
            diff.sqrt() <= 1e-8 * size.sqrt(),
            "seed {seed}, alpha {alpha:e}: {:e} apart, |d| {:e}",
            diff.sqrt(),
            size.sqrt()
        );
        (0..p.n_contacts())
            .map(|i| {
                let (r, u) = (&z[np + 3 * i..np + 3 * i + 3], &s.point.u[3 * i..3 * i + 3]);
                let branch = ac_branch(
                    [r[0], r[1], r[2]],
                    [u[0], u[1], u[2]],
                    p.mu[i],
                    s.rho[i],
                    s.rho[i],
                );
                format!("{branch:?}")
            })
            .collect()
    }

    #[test]
    fn reduced_direction_matches_the_unreduced_system() {
        let stacks = random_stacks(4, 12, 20.0, 7);
        let g = CscMatrix::from_triplets("G", 72, 2, &[(1, 0, 1.0), (13, 1, 1.0)]).unwrap();
        let jointed = stacks[0].clone().with_joints(g, vec![-0.02, 0.01]).unwrap();
        let mut branches = std::collections::BTreeSet::new();
        for (k, p) in stacks.iter().chain([&jointed]).enumerate() {
            for alpha in [1e-2, 1e-5, 1e-8] {
                branches.extend(directions_agree(p, 11 * k as u64, alpha));
            }
        }
        // Every kind of contact block was eliminated.
        assert_eq!(branches.len(), 3, "{branches:?}");
    }

    #[test]
    fn joints_including_a_redundant_one() {
        // Box pushed along x with v_y prescribed to 0.02 and w_z = 0, plus the v_y row
        // repeated (G rank deficient): the friction must follow the (x, y) slip.
        let p = box_problem(0.3, 10.0, 0.0);
        let g =
            CscMatrix::from_triplets("G", 6, 3, &[(1, 0, 1.0), (5, 1, 1.0), (1, 2, 1.0)]).unwrap();
        let p = p.with_joints(g, vec![-0.02, 0.0, -0.02]).unwrap();
        let run = cold(&p, 1e-8);
        report("box with joints (cold)", &run.out);
        assert!(run.out.converged());
        assert!((run.v[1] - 0.02).abs() < 1e-9 && run.v[5].abs() < 1e-9);
        // Friction: every contact slides along (v_x, 0.02) and the total friction impulse
        // is -mu m g dt along it, since the box does not rotate.
        let (vx, vy) = (run.v[0], run.v[1]);
        let nrm = vx.hypot(vy);
        let (fx, fy) = (0..4).fold((0.0, 0.0), |(a, b), i| {
            (a + run.r[3 * i + 1], b + run.r[3 * i + 2])
        });
        let limit = 0.3 * 2.0 * G * DT;
        assert!((fx + limit * vx / nrm).abs() < 1e-8 && (fy + limit * vy / nrm).abs() < 1e-8);
        assert_eq!(run.lambda.len(), 3);
    }

    #[test]
    fn warm_start_near_the_solution() {
        let scenes: Vec<(&str, GlobalProblem)> = vec![
            ("box at rest", box_problem(0.5, 0.0, 0.0)),
            ("box mu=1e3", box_problem(1e3, 5.0, 0.0)),
            ("box mu=0", box_problem(0.0, 5.0, 0.0)),
            ("box slide", box_problem(0.3, 10.0, 0.0)),
            ("box lifted", box_problem(0.5, 3.0, 2.0)),
            ("box duplicated", duplicated(&box_problem(0.5, 3.0, 0.0))),
        ];
        for (name, p) in scenes {
            let exact = cold(&p, 1e-14);
            assert!(exact.out.error < 1e-13, "{name}");
            let rs = (crate::csc::norm2(&exact.r) / (exact.r.len() as f64).sqrt()).max(1e-2);
            let vs = (crate::csc::norm2(&exact.v) / (exact.v.len() as f64).sqrt()).max(1e-2);
            for (eps, seed) in [(1e-2, 1), (1e-4, 2), (1e-6, 3)] {
                let (mut v, mut r) = (exact.v.clone(), exact.r.clone());
                perturb(&mut r, eps, rs, seed);
                perturb(&mut v, eps, vs, seed + 10);
                let run = solve_from(&p, v, r, 1e-10);
                report(&format!("{name} warm eps={eps:.0e}"), &run.out);
                assert!(run.out.converged(), "{name} eps {eps}");
            }
        }
    }
}

#[cfg(test)]
mod stack_tests {
    use super::*;
    use crate::newton::testing::{perturb, random_stacks};

    /// Cold and warm starts on random 3-box stacks, global form.
    #[test]
    fn random_stacks_cold_and_warm() {
        let scenes = random_stacks(40, 3, 30.0, 7);
        let (mut cold_ok, mut cold_iters, mut warm_ok, mut warm_iters) = (0, 0, 0, 0);
        for p in &scenes {
            let mut s = GlobalNewton::new(p).unwrap();
            let (mut v, mut r) = (vec![0.0; p.n()], vec![0.0; 3 * p.n_contacts()]);
            let out = s
                .solve(p, &mut v, &mut r, &mut [], 1e-10, 200, None)
                .unwrap();
            if !out.converged() {
                eprintln!("global stack mu={} cold failed: {out:?}", p.mu[0]);
                continue;
            }
            cold_ok += 1;
            cold_iters += out.iterations;
            let rs = (crate::csc::norm2(&r) / (r.len() as f64).sqrt()).max(1e-3);
            let vs = (crate::csc::norm2(&v) / (v.len() as f64).sqrt()).max(1e-3);
            perturb(&mut r, 1e-3, rs, 99);
            perturb(&mut v, 1e-3, vs, 98);
            let out = s
                .solve(p, &mut v, &mut r, &mut [], 1e-10, 50, None)
                .unwrap();
            if out.converged() {
                warm_ok += 1;
                warm_iters += out.iterations;
            }
        }
        eprintln!(
            "global stacks: cold {cold_ok}/{} (mean {:.1} it), warm {warm_ok}/{cold_ok} (mean {:.1} it)",
            scenes.len(),
            cold_iters as f64 / cold_ok.max(1) as f64,
            warm_iters as f64 / warm_ok.max(1) as f64
        );
        assert_eq!(warm_ok, cold_ok);
        assert!(cold_ok >= scenes.len() * 9 / 10);
    }
}

#[cfg(test)]
mod big_stack_tests {
    use super::*;
    use crate::newton::testing::{perturb, random_stacks, to_local};
    use crate::newton::LocalNewton;

    /// 8-box stacks (32 contacts), pushes up to 100 N on 2 kg boxes: the cold start fails
    /// on a few of them (reported), the warm start (the use after ADMM) never does.
    #[test]
    fn eight_box_stacks_warm_start() {
        let scenes = random_stacks(12, 8, 100.0, 11);
        let (mut cold_fail, mut warm_iters, mut warm_max, mut warm_runs) = (0, 0, 0, 0);
        for g in &scenes {
            let mut s = GlobalNewton::new(g).unwrap();
            let (mut v, mut r) = (vec![0.0; g.n()], vec![0.0; 3 * g.n_contacts()]);
            let out = s
                .solve(g, &mut v, &mut r, &mut [], 1e-12, 300, None)
                .unwrap();
            if !out.converged() {
                cold_fail += 1;
                continue;
            }
            let l = to_local(g);
            let mut ls = LocalNewton::new(&l).unwrap();
            for (eps, seed) in [(1e-2, 5), (1e-3, 6), (1e-5, 7)] {
                let (mut vw, mut rw) = (v.clone(), r.clone());
                let rs = (crate::csc::norm2(&r) / (r.len() as f64).sqrt()).max(1e-3);
                let vs = (crate::csc::norm2(&v) / (v.len() as f64).sqrt()).max(1e-3);
                perturb(&mut rw, eps, rs, seed);
                perturb(&mut vw, eps, vs, seed + 1);
                let mut rl = rw.clone();
                let out = s
                    .solve(g, &mut vw, &mut rw, &mut [], 1e-10, 50, None)
                    .unwrap();
                assert!(out.converged(), "global warm eps {eps}: {out:?}");
                let lout = ls.solve(&l, &mut rl, 1e-10, 50, None).unwrap();
                assert!(lout.converged(), "local warm eps {eps}: {lout:?}");
                warm_iters += out.iterations + lout.iterations;
                warm_max = warm_max.max(out.iterations).max(lout.iterations);
                warm_runs += 2;
            }
        }
        eprintln!(
            "8-box stacks: cold global failures {cold_fail}/{}, warm mean {:.1} it (max {warm_max})",
            scenes.len(),
            warm_iters as f64 / warm_runs.max(1) as f64
        );
        assert!(cold_fail <= scenes.len() / 4);
    }
}
