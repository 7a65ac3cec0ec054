//! Semismooth Newton for the local problem `u = W r + q`, unknown `r`, on the
//! Alart-Curnier equation `F(r, W r + q) = 0`.
//!
//! Each step solves `(A (W + alpha D) + B) dr = -F`, with `A`, `B` the block-diagonal
//! Jacobian pieces of [`super::ac_contact`] and `D = diag(1 / rho_i)` (so that `alpha` is
//! dimensionless: on a sticking contact the added block is `alpha I`).
//!
//! Why this regularization: `A W + B` is singular whenever the sticking contacts are
//! redundant (a box on four coplanar corners: `W` has rank 6 for 12 unknowns). Adding
//! `alpha A` is one Newton step on the proximal problem `u = W r + q + alpha D (r - r_k)`
//! centred at the current iterate, whose function value at `r_k` is unchanged: the fixed
//! points are the same, and the step is an inexact Newton step with a residual of order
//! `alpha`. `alpha` follows the residual relative to the impulse scale,
//! `alpha = min(3 ||F|| / max(||r||, ||rho q||), 1e-2)`, which keeps the convergence
//! superlinear near the solution, and grows tenfold whenever no step length passes the line
//! search (Levenberg-Marquardt style), back down after full steps. Every part of `F` is an
//! impulse, so `alpha` and the iterates do not depend on the units; the error measure,
//! which adds velocities to impulses, would make them depend (it decides only when to stop
//! and which iterate is the best).
//!
//! Line search: backtracking on `||F||` with the test `||F(r + t d)|| <= (1 - 1e-4 t) R`
//! (for an inexact Newton step this is the Armijo test of `0.5 ||F||^2`), where `R` is the
//! largest `||F||` of the last 8 accepted points (non-monotone: a monotone search stalled
//! on kinks of `||F||` from cold starts on stacks of boxes). The best iterate by the common
//! error measure `crate::measure::local_error` is kept and returned, whatever happens.
//!
//! `rho_N = rho_T = 1 / ||W_ii||_F` per contact: it makes the method invariant to the units
//! of `r` (with `rho = 1`, scaling every mass by 1e4 made all 40 random 3-box stacks of the
//! tests fail from a cold start; with this choice they all converge, as at unit scale).

use super::sparse::{Pattern, SparseLu};
use super::{
    backtrack, impulse_scale, iterate, rho_from_block, AcPoint, Mat3, NewtonOutcome, NewtonSystem,
};
use crate::csc::CscMatrix;
use crate::measure::{local_error_with, MeasureWork};
use crate::problem::LocalProblem;
use crate::tuning::SMALL_ALPHA_CAP;
use crate::types::Error;
use std::time::Instant;

/// Newton solver of a local problem; built once per sparsity pattern of `W`.
pub struct LocalNewton {
    nc: usize,
    w_colptr: Vec<usize>,
    w_rowind: Vec<usize>,
    /// Per contact `rho_N = rho_T`.
    rho: Vec<f64>,
    /// Per W entry: position of row `3 i` (its contact's first row) in the Jacobian column.
    w_dest: Vec<usize>,
    /// Per column `c`: position of row `3 (c / 3)` (diagonal block) in column `c`.
    diag_dest: Vec<usize>,
    lu: SparseLu,
    /// The Alart-Curnier function at the current point and at the trial point.
    point: AcPoint,
    trial_point: AcPoint,
    d: Vec<f64>,
    wd: Vec<f64>,
    r_trial: Vec<f64>,
    best: Vec<f64>,
    measure: MeasureWork,
}

impl LocalNewton {
    /// Builds the Jacobian pattern (3x3 block closure of the pattern of `W` plus the
    /// diagonal blocks), its symbolic LU, and `rho_i = 1 / ||W_ii||_F` per contact.
    pub fn new(p: &LocalProblem) -> Result<Self, Error> {
        let nc = p.n_contacts();
        let m = 3 * nc;
        let w = &p.w;
        if w.nrows() != m || w.ncols() != m {
            return Err(Error::Dimension {
                field: "W",
                expected: m,
                found: w.nrows(),
            });
        }
        // Row i of the Jacobian mixes the rows of W of its contact (A_i W): a W entry in
        // row 3i+b fills rows 3i..3i+3 of its column.
        let pattern = Pattern::from_column_rows(m, |c, col| {
            for (row, _) in w.col(c) {
                let i = row / 3;
                col.extend([3 * i, 3 * i + 1, 3 * i + 2]);
            }
            let j = c / 3;
            col.extend([3 * j, 3 * j + 1, 3 * j + 2]);
        });
        let mut w_dest = Vec::with_capacity(w.nnz());
        for c in 0..m {
            for (row, _) in w.col(c) {
                w_dest.push(pattern.pos(3 * (row / 3), c));
            }
        }
        let diag_dest = (0..m).map(|c| pattern.pos(3 * (c / 3), c)).collect();
        let rho = (0..nc).map(|i| rho_from_block(&diag_block(w, i))).collect();
        let lu = SparseLu::new("Newton matrix A (W + alpha D) + B", pattern)?;
        Ok(Self {
            nc,
            w_colptr: w.colptr().to_vec(),
            w_rowind: w.rowind().to_vec(),
            rho,
            w_dest,
            diag_dest,
            lu,
            point: AcPoint::new(nc),
            trial_point: AcPoint::new(nc),
            d: vec![0.0; m],
            wd: vec![0.0; m],
            r_trial: vec![0.0; m],
            best: vec![0.0; m],
            measure: MeasureWork::local(p),
        })
    }

    /// Recomputes `rho_i = 1 / ||W_ii||_F` from the values of `p` (same pattern as at
    /// construction). No allocation.
    /// Floors of the error measure (an island's share of a scene's measure).
    pub fn set_measure_floors(&mut self, floors: crate::measure::Floors) {
        self.measure.floors = floors;
    }

    pub fn take_values(&mut self, p: &LocalProblem) {
        for (i, rho) in self.rho.iter_mut().enumerate() {
            *rho = rho_from_block(&diag_block(&p.w, i));
        }
    }

    /// Replaces the per-contact `rho` (positive, one per contact): the tests try other
    /// choices than the Delassus blocks'.
    #[cfg(test)]
    pub fn set_rho(&mut self, rho: &[f64]) -> Result<(), Error> {
        check_rho(rho, self.nc)?;
        self.rho.copy_from_slice(rho);
        Ok(())
    }

    /// Solves from the start point `r` until `local_error <= tol`, `max_iter` steps, the
    /// deadline, or a failure; leaves the best iterate (by `local_error`) in `r`.
    ///
    /// `p` must have the sparsity pattern of the problem the solver was built for.
    pub fn solve(
        &mut self,
        p: &LocalProblem,
        r: &mut [f64],
        tol: f64,
        max_iter: usize,
        deadline: Option<Instant>,
    ) -> Result<NewtonOutcome, Error> {
        self.check(p, r)?;
        Ok(self.with_best(|s, best| iterate(s, p, r, best, tol, max_iter, deadline)))
    }

    /// As [`LocalNewton::solve`], but the best iterate and the stop are judged by `measure`
    /// instead of the local measure: a global problem solved through its Delassus form is
    /// judged by its own measure at the velocities `r` gives. Open contacts are not snapped.
    pub(crate) fn solve_measured(
        &mut self,
        p: &LocalProblem,
        r: &mut [f64],
        tol: f64,
        max_iter: usize,
        deadline: Option<Instant>,
        measure: &mut dyn FnMut(&[f64]) -> f64,
    ) -> Result<NewtonOutcome, Error> {
        self.check(p, r)?;
        Ok(self.with_best(|newton, best| {
            let mut judged = Measured { newton, measure };
            iterate(&mut judged, p, r, best, tol, max_iter, deadline)
        }))
    }

    /// Runs `solve` with the best-iterate work space lent out of `self`.
    fn with_best(
        &mut self,
        solve: impl FnOnce(&mut Self, &mut [f64]) -> NewtonOutcome,
    ) -> NewtonOutcome {
        let mut best = std::mem::take(&mut self.best);
        let out = solve(self, &mut best);
        self.best = best;
        out
    }

    /// Checks that `p` has the pattern the solver was built for and `r` its length.
    fn check(&self, p: &LocalProblem, r: &[f64]) -> Result<(), Error> {
        let m = 3 * self.nc;
        if p.n_contacts() != self.nc
            || p.w.colptr() != self.w_colptr
            || p.w.rowind() != self.w_rowind
        {
            return Err(Error::PatternChanged { field: "W" });
        }
        if r.len() != m {
            return Err(Error::Dimension {
                field: "r",
                expected: m,
                found: r.len(),
            });
        }
        Ok(())
    }
}

/// The local Newton system judged by another measure (see [`LocalNewton::solve_measured`]).
struct Measured<'a> {
    newton: &'a mut LocalNewton,
    measure: &'a mut dyn FnMut(&[f64]) -> f64,
}

impl NewtonSystem for Measured<'_> {
    type Problem = LocalProblem;

    fn evaluate_at(&mut self, p: &LocalProblem, r: &[f64]) -> f64 {
        self.newton.evaluate_at(p, r)
    }
    fn error(&mut self, _: &LocalProblem, r: &[f64]) -> f64 {
        (self.measure)(r)
    }
    fn direction(&mut self, p: &LocalProblem, alpha: f64) -> bool {
        self.newton.direction(p, alpha)
    }
    fn line_search(&mut self, p: &LocalProblem, r: &[f64], reference: f64) -> Option<f64> {
        self.newton.line_search(p, r, reference)
    }
    fn trial(&self) -> &[f64] {
        self.newton.trial()
    }
    fn snap_open(&mut self, _: &LocalProblem, _: &mut [f64], error: f64, _: f64) -> f64 {
        error
    }
    fn factorizations(&self) -> usize {
        self.newton.factorizations()
    }
    fn impulse_scale(&self, p: &LocalProblem, r: &[f64]) -> f64 {
        self.newton.impulse_scale(p, r)
    }
    fn alpha_cap(&self) -> f64 {
        SMALL_ALPHA_CAP
    }
}

impl NewtonSystem for LocalNewton {
    type Problem = LocalProblem;

    fn error(&mut self, p: &LocalProblem, r: &[f64]) -> f64 {
        local_error_with(p, r, &mut self.measure)
    }

    fn trial(&self) -> &[f64] {
        &self.r_trial
    }

    fn factorizations(&self) -> usize {
        self.lu.factorizations()
    }

    /// The free velocity of the local form is `q`.
    fn impulse_scale(&self, p: &LocalProblem, r: &[f64]) -> f64 {
        impulse_scale(r, &self.rho, &p.q)
    }

    /// `u = W r + q` and F, A, B at `r`; returns the merit `0.5 ||F||^2`.
    fn evaluate_at(&mut self, p: &LocalProblem, r: &[f64]) -> f64 {
        self.point.u.copy_from_slice(&p.q);
        p.w.mul_vec(1.0, r, 1.0, &mut self.point.u);
        self.point.evaluate(r, &p.mu, &self.rho)
    }

    /// Assembles `A (W + alpha D) + B`, factorizes, and solves for `d = -J^-1 F` (into
    /// `self.d`, with `self.wd = W d`); false when singular or not finite.
    fn direction(&mut self, p: &LocalProblem, alpha: f64) -> bool {
        let vals = &mut self.lu.values;
        vals.fill(0.0);
        let (colptr, wv) = (p.w.colptr(), p.w.values());
        for c in 0..colptr.len() - 1 {
            for k in colptr[c]..colptr[c + 1] {
                let row = self.w_rowind[k];
                let (ai, bcol, base) = (&self.point.a[row / 3], row % 3, self.w_dest[k]);
                for r in 0..3 {
                    vals[base + r] += ai[r][bcol] * wv[k];
                }
            }
            let j = c / 3;
            let (aj, bj, bcol, base) =
                (&self.point.a[j], &self.point.b[j], c % 3, self.diag_dest[c]);
            let reg = alpha / self.rho[j];
            for r in 0..3 {
                vals[base + r] += bj[r][bcol] + reg * aj[r][bcol];
            }
        }
        if !self.lu.factor() {
            return false;
        }
        for (d, f) in self.d.iter_mut().zip(&self.point.f) {
            *d = -f;
        }
        if !self.lu.solve_in_place(&mut self.d) {
            return false;
        }
        p.w.mul_vec(1.0, &self.d, 0.0, &mut self.wd);
        true
    }

    /// Backtracking from `t = 1`; on success the trial point is in `r_trial` and the step
    /// length is returned.
    fn line_search(&mut self, p: &LocalProblem, r: &[f64], merit: f64) -> Option<f64> {
        let Self {
            r_trial,
            point,
            trial_point,
            d,
            wd,
            rho,
            ..
        } = self;
        backtrack(merit, |t| {
            for k in 0..r.len() {
                r_trial[k] = r[k] + t * d[k];
                trial_point.u[k] = point.u[k] + t * wd[k];
            }
            trial_point.evaluate(r_trial, &p.mu, rho)
        })
    }

    /// Sets exactly to zero the impulses of the contacts that the converged point finds
    /// open (they are zero up to round-off), when the error stays within `max(error, tol)`.
    fn snap_open(&mut self, p: &LocalProblem, r: &mut [f64], error: f64, tol: f64) -> f64 {
        self.evaluate_at(p, r);
        self.r_trial.copy_from_slice(r);
        let mut changed = false;
        for i in 0..self.nc {
            let (ri, ui) = (
                &mut self.r_trial[3 * i..3 * i + 3],
                &self.point.u[3 * i..3 * i + 3],
            );
            let open = super::ac_branch(
                [ri[0], ri[1], ri[2]],
                [ui[0], ui[1], ui[2]],
                p.mu[i],
                self.rho[i],
                self.rho[i],
            ) == super::Branch::Open;
            if open && ri.iter().any(|&x| x != 0.0) {
                ri.fill(0.0);
                changed = true;
            }
        }
        if !changed {
            return error;
        }
        let trial = std::mem::take(&mut self.r_trial);
        let snapped = self.error(p, &trial);
        self.r_trial = trial;
        if snapped <= error.max(tol) {
            r.copy_from_slice(&self.r_trial);
            snapped
        } else {
            error
        }
    }
}

/// The 3x3 diagonal block of contact `i` of `w`.
pub(crate) fn diag_block(w: &CscMatrix, i: usize) -> Mat3 {
    let mut blk = [[0.0; 3]; 3];
    for b in 0..3 {
        for (row, v) in w.col(3 * i + b) {
            if row / 3 == i {
                blk[row % 3][b] = v;
            }
        }
    }
    blk
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::local_error;
    use crate::newton::testing::{
        box_problem, duplicated, perturb, point_mass_problem, to_local, velocity, DT, G,
    };
    use crate::newton::{FailReason, NewtonStatus};

    fn solve(p: &LocalProblem, r: &mut [f64], tol: f64) -> NewtonOutcome {
        let mut s = LocalNewton::new(p).unwrap();
        let out = s.solve(p, r, tol, 100, None).unwrap();
        // The reported error is the common measure of the returned point.
        assert_eq!(out.error, local_error(p, r));
        out
    }

    fn report(name: &str, out: &NewtonOutcome) {
        eprintln!(
            "local {name}: {:?}, {} iterations, {} factorizations, error {:.2e}",
            out.status, out.iterations, out.factorizations, out.error
        );
    }

    #[test]
    fn single_contact_slides_with_mu_10_under_light_load() {
        // W = diag(2, 1/2, 1/2): r_N = -q_N / 2 = 5e-4, mu r_N = 5e-3 < ||q_T|| = 0.5, so it
        // slides with r_T = -mu r_N q_T / ||q_T|| and u_T = r_T / 2 + q_T parallel to q_T.
        let w = CscMatrix::from_dense("W", 3, 3, &[2.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.5])
            .unwrap();
        let p = LocalProblem::new(w, vec![-1e-3, 0.3, -0.4], vec![10.0]).unwrap();
        let mut r = vec![0.0; 3];
        let out = solve(&p, &mut r, 1e-14);
        report("one contact mu=10 slide", &out);
        assert!(out.converged());
        let exact = [5e-4, -5e-3 * 0.6, 5e-3 * 0.8];
        for k in 0..3 {
            assert!((r[k] - exact[k]).abs() < 1e-10, "{r:?}");
        }
    }

    #[test]
    fn box_on_four_corners_rank_deficient() {
        let g = box_problem(0.5, 0.0, 0.0);
        let p = to_local(&g);
        let mut r = vec![0.0; 12];
        let out = solve(&p, &mut r, 1e-8);
        report("box at rest (cold)", &out);
        assert!(out.converged());
        // Independent checks: the supports carry the weight, the box does not move.
        let total: f64 = (0..4).map(|i| r[3 * i]).sum();
        assert!((total - 2.0 * G * DT).abs() < 1e-8 * 2.0 * G * DT);
        assert!(velocity(&g, &r).iter().all(|v| v.abs() < 1e-8));
    }

    #[test]
    fn box_pushed_sideways_with_mu_1e3_sticks() {
        let g = box_problem(1e3, 5.0, 0.0);
        let p = to_local(&g);
        let mut r = vec![0.0; 12];
        let out = solve(&p, &mut r, 1e-8);
        report("box pushed, mu=1e3 (cold)", &out);
        assert!(out.converged());
        assert!(velocity(&g, &r).iter().all(|v| v.abs() < 1e-8));
        let tangential: f64 = (0..4).map(|i| r[3 * i + 1]).sum();
        assert!((tangential + 5.0 * DT).abs() < 1e-8);
    }

    #[test]
    fn box_pushed_sideways_slides() {
        // mu = 0: no friction, v_x = push dt / m. mu = 0.3: v_x = dt (push - mu m g) / m.
        for &(mu, push) in &[(0.0, 5.0), (0.3, 10.0)] {
            let g = box_problem(mu, push, 0.0);
            let p = to_local(&g);
            let mut r = vec![0.0; 12];
            let out = solve(&p, &mut r, 1e-10);
            report(&format!("box sliding mu={mu} (cold)"), &out);
            assert!(out.converged());
            let v = velocity(&g, &r);
            let vx = DT * (push - mu * 2.0 * G) / 2.0;
            assert!((v[0] - vx).abs() < 1e-9 * vx, "{v:?} vs {vx}");
            assert!(v[1..].iter().all(|x| x.abs() < 1e-9), "{v:?}");
            if mu == 0.0 {
                assert!(
                    (0..4).all(|i| r[3 * i + 1] == 0.0 && r[3 * i + 2] == 0.0),
                    "{r:?}"
                );
            }
        }
    }

    #[test]
    fn separating_contacts_give_exactly_zero() {
        let p = to_local(&box_problem(0.5, 3.0, 2.0));
        for start in [0.0, 0.01] {
            let mut r = vec![start; 12];
            let out = solve(&p, &mut r, 1e-8);
            report(&format!("box lifted (start {start})"), &out);
            assert!(out.converged());
            assert!(r.iter().all(|&x| x == 0.0), "{r:?}");
        }
    }

    #[test]
    fn duplicated_contacts() {
        // A point mass on two identical contacts, sticking then sliding; the box with every
        // corner listed twice.
        for &(mu, push) in &[(0.5, 2.0), (0.5, 20.0)] {
            let g = point_mass_problem(mu, 1.0, push, G, 2);
            let p = to_local(&g);
            let mut r = vec![0.0; 6];
            let out = solve(&p, &mut r, 1e-10);
            report(&format!("point mass x2 push {push}"), &out);
            assert!(out.converged());
            let v = velocity(&g, &r);
            let vx = if push > mu * G {
                DT * (push - mu * G)
            } else {
                0.0
            };
            assert!((v[0] - vx).abs() < 1e-9 && v[2].abs() < 1e-9, "{v:?}");
        }
        let g = duplicated(&box_problem(0.5, 3.0, 0.0));
        let p = to_local(&g);
        let mut r = vec![0.0; 24];
        let out = solve(&p, &mut r, 1e-8);
        report("box with duplicated corners (cold)", &out);
        assert!(out.converged());
        assert!(velocity(&g, &r).iter().all(|v| v.abs() < 1e-8));
    }

    #[test]
    fn limits_and_misuse() {
        let p = to_local(&box_problem(0.5, 0.0, 0.0));
        let mut s = LocalNewton::new(&p).unwrap();
        // A passed deadline or a zero iteration limit: no step, the start point returned.
        let mut r = vec![0.1; 12];
        let out = s
            .solve(&p, &mut r, 1e-8, 100, Some(Instant::now()))
            .unwrap();
        assert_eq!(out.status, NewtonStatus::Failed(FailReason::Deadline));
        assert_eq!((out.iterations, r[0]), (0, 0.1));
        let out = s.solve(&p, &mut r, 1e-8, 0, None).unwrap();
        assert_eq!(out.status, NewtonStatus::Failed(FailReason::MaxIterations));
        assert_eq!(out.error, local_error(&p, &r));
        // A non-finite start is reported, wrong sizes and patterns are errors.
        let mut bad = vec![f64::NAN; 12];
        let out = s.solve(&p, &mut bad, 1e-8, 10, None).unwrap();
        assert_eq!(out.status, NewtonStatus::Failed(FailReason::NonFinite));
        assert!(s.solve(&p, &mut [0.0; 3], 1e-8, 10, None).is_err());
        let other = to_local(&point_mass_problem(0.5, 1.0, 0.0, G, 4));
        assert!(s.solve(&other, &mut [0.0; 12], 1e-8, 10, None).is_err());
        assert!(s.set_rho(&[1.0, 0.0, 1.0, 1.0]).is_err());
    }

    #[test]
    fn warm_start_near_the_solution() {
        let scenes: Vec<(&str, crate::problem::GlobalProblem)> = vec![
            ("box at rest", box_problem(0.5, 0.0, 0.0)),
            ("box mu=1e3", box_problem(1e3, 5.0, 0.0)),
            ("box mu=0", box_problem(0.0, 5.0, 0.0)),
            ("box slide", box_problem(0.3, 10.0, 0.0)),
            ("box lifted", box_problem(0.5, 3.0, 2.0)),
            ("box duplicated", duplicated(&box_problem(0.5, 3.0, 0.0))),
        ];
        for (name, g) in scenes {
            let p = to_local(&g);
            let mut r = vec![0.0; p.q.len()];
            assert!(solve(&p, &mut r, 1e-14).error < 1e-13, "{name}");
            let scale = (crate::csc::norm2(&r) / (r.len() as f64).sqrt()).max(1e-2);
            for (eps, seed) in [(1e-2, 1), (1e-4, 2), (1e-6, 3)] {
                let mut rw = r.clone();
                perturb(&mut rw, eps, scale, seed);
                let out = solve(&p, &mut rw, 1e-10);
                report(&format!("{name} warm eps={eps:.0e}"), &out);
                assert!(out.converged(), "{name} eps {eps}");
            }
        }
    }
}

#[cfg(test)]
mod stack_tests {
    use super::*;
    use crate::newton::testing::{perturb, random_stacks, scaled_mass, to_local};

    /// Cold and warm starts on random 3-box stacks (12 coupled contacts, mixed stick/slide
    /// states, rank-deficient W), for two choices of rho.
    #[test]
    fn random_stacks_cold_and_warm() {
        for (mass_scale, unit_rho) in [(1.0, false), (1.0, true), (1e4, false), (1e4, true)] {
            let scenes: Vec<_> = random_stacks(40, 3, 30.0, 7)
                .iter()
                .map(|g| scaled_mass(g, mass_scale))
                .collect();
            let (mut cold_ok, mut cold_iters, mut warm_ok, mut warm_iters) = (0, 0, 0, 0);
            for g in &scenes {
                let p = to_local(g);
                let mut s = LocalNewton::new(&p).unwrap();
                if unit_rho {
                    s.set_rho(&vec![1.0; p.mu.len()]).unwrap();
                }
                let mut r = vec![0.0; p.q.len()];
                let out = s.solve(&p, &mut r, 1e-10, 200, None).unwrap();
                if out.converged() {
                    cold_ok += 1;
                    cold_iters += out.iterations;
                    // Warm start: perturb the solution by 1e-3 (relative, plus absolute).
                    let scale = (crate::csc::norm2(&r) / (r.len() as f64).sqrt()).max(1e-3);
                    perturb(&mut r, 1e-3, scale, 99);
                    let out = s.solve(&p, &mut r, 1e-10, 50, None).unwrap();
                    if out.converged() {
                        warm_ok += 1;
                        warm_iters += out.iterations;
                    }
                } else if !unit_rho {
                    eprintln!(
                        "local stack (x{mass_scale:.0e}) mu={} cold failed: {out:?}",
                        p.mu[0]
                    );
                }
            }
            eprintln!(
                "local stacks, masses x{mass_scale:.0e}, rho = {}: cold {cold_ok}/{} (mean {:.1} it), warm {warm_ok}/{cold_ok} (mean {:.1} it)",
                if unit_rho { "1" } else { "1/||W_ii||" },
                scenes.len(),
                cold_iters as f64 / cold_ok.max(1) as f64,
                warm_iters as f64 / warm_ok.max(1) as f64
            );
            if !unit_rho {
                assert_eq!(warm_ok, cold_ok);
                assert!(cold_ok >= scenes.len() * 9 / 10);
            }
        }
    }
}

/// Checks per-contact `rho` values (positive, finite, one per contact).
#[cfg(test)]
fn check_rho(rho: &[f64], nc: usize) -> Result<(), Error> {
    if rho.len() != nc {
        return Err(Error::Dimension {
            field: "rho",
            expected: nc,
            found: rho.len(),
        });
    }
    match rho.iter().position(|&x| !(x > 0.0 && x.is_finite())) {
        Some(index) => Err(Error::InvalidValue {
            field: "rho",
            index,
            reason: "must be positive and finite",
        }),
        None => Ok(()),
    }
}
