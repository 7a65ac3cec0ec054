//! The error measure every test and benchmark uses (it matches Siconos numerics):
//!
//! global: `||-M v + H r + f|| / max(||f||, ||M v||, ||H r||)
//!          + ||r - P_K(r - (u + Phi(u)))|| / max(||u||, ||r||)`, `u = H^T v + w`;
//! local:  `||r - P_K(r - (u + Phi(u)))|| / ||q||`, `u = W r + q`.
//!
//! Each denominator is skipped when it is below 1.5e-8. A non-finite input gives `inf`.

use crate::cone::{de_saxce, get3, project_cone};
use crate::csc::norm2;
use crate::problem::{GlobalProblem, LocalProblem, Problem};

const TINY: f64 = 1.5e-8;

fn relative(num: f64, den: f64) -> f64 {
    if den > TINY {
        num / den
    } else {
        num
    }
}

/// Norm of the natural-map residual `r - P_K(r - (u + Phi(u)))` over all contacts.
pub fn complementarity_residual(r: &[f64], u: &[f64], mu: &[f64]) -> f64 {
    let mut sum = 0.0;
    for (i, &m) in mu.iter().enumerate() {
        let ri = get3(r, i);
        let ut = de_saxce(get3(u, i), m);
        let p = project_cone([ri[0] - ut[0], ri[1] - ut[1], ri[2] - ut[2]], m);
        sum += (ri[0] - p[0]).powi(2) + (ri[1] - p[1]).powi(2) + (ri[2] - p[2]).powi(2);
    }
    sum.sqrt()
}

fn all_finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// Error of a global solution `(r, v)`; `u` is recomputed as `H^T v + w`.
///
/// With joints, `lambda` (their multipliers) joins the equation residual
/// `-M v + H r + G lambda + f`, and the joint residual `||G^T v + b||` (relative to
/// `max(||G^T v||, ||b||)`) is added. Without joints `lambda` is ignored.
pub fn global_error(p: &GlobalProblem, r: &[f64], v: &[f64], lambda: &[f64]) -> f64 {
    if !all_finite(r) || !all_finite(v) || !all_finite(lambda) {
        return f64::INFINITY;
    }
    let n = p.n();
    let mut mv = vec![0.0; n];
    p.m.mul_vec(1.0, v, 0.0, &mut mv);
    let mut hr = vec![0.0; n];
    p.h.mul_vec(1.0, r, 0.0, &mut hr);
    let mut joint_error = 0.0;
    if let Some(j) = &p.joints {
        if lambda.len() == j.b.len() {
            j.g.mul_vec(1.0, lambda, 1.0, &mut hr);
        }
        let mut gv = vec![0.0; j.b.len()];
        j.g.mul_t_vec(1.0, v, 0.0, &mut gv);
        let scale = norm2(&gv).max(norm2(&j.b));
        let res: Vec<f64> = gv.iter().zip(&j.b).map(|(a, b)| a + b).collect();
        joint_error = relative(norm2(&res), scale);
    }
    let eq: Vec<f64> = (0..n).map(|i| -mv[i] + hr[i] + p.f[i]).collect();
    let e1 = relative(norm2(&eq), norm2(&p.f).max(norm2(&mv)).max(norm2(&hr)));
    let mut u = p.w.clone();
    p.h.mul_t_vec(1.0, v, 1.0, &mut u);
    let e2 = relative(
        complementarity_residual(r, &u, &p.mu),
        norm2(&u).max(norm2(r)),
    );
    e1 + e2 + joint_error
}

/// Error of a local solution `r`; `u` is recomputed as `W r + q`.
pub fn local_error(p: &LocalProblem, r: &[f64]) -> f64 {
    if !all_finite(r) {
        return f64::INFINITY;
    }
    let mut u = p.q.clone();
    p.w.mul_vec(1.0, r, 1.0, &mut u);
    relative(complementarity_residual(r, &u, &p.mu), norm2(&p.q))
}

/// Error of a solution of either form (`v` is ignored for a local problem).
pub fn problem_error(p: &Problem, r: &[f64], v: &[f64], lambda: &[f64]) -> f64 {
    match p {
        Problem::Global(g) => global_error(g, r, v, lambda),
        Problem::Local(l) => local_error(l, r),
    }
}
