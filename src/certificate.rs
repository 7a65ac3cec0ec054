//! Infeasibility certificate of a finished solve (docs/algorithms.md §13).
//!
//! When a problem has no solution, ADMM's impulses grow without bound along a direction
//! `y = r / ||r||` of the friction cone that pushes no body (`H y = 0`, or `W y = 0`) and
//! meets approaching velocities (`y . u~ < 0`, `u~ = u + mu ||u_T|| e_N`). The relative
//! error measure then fades with `||r||` and can fall below the tolerance, so a
//! "solution" that lets contacts penetrate at their free speed would pass. Coulomb's law
//! needs `u~ . r = 0`; at such an iterate the product is of the order of `||r|| ||u~||`,
//! which no solved problem shows: the solve is reported `Infeasible` instead.
//!
//! Both tests are relative, so the certificate does not depend on the units: the
//! impulses must be `NULL_SPACE` close to the null space of the operator, and the
//! Signorini defect at least `DEFECT` of the velocity scale.

use crate::cone::{de_saxce_term, get3};
use crate::csc::{norm2, CscMatrix};
use crate::problem::LocalProblem;

use crate::tuning::{DEFECT, NULL_SPACE};

/// [`certifies_infeasibility`] on the global form, with the image `H r` computed here.
pub(crate) fn run_off(op: &CscMatrix, r: &[f64], u: &[f64], u_free: &[f64], mu: &[f64]) -> bool {
    let mut image = vec![0.0; op.nrows()];
    op.mul_vec(1.0, r, 0.0, &mut image);
    certifies_infeasibility(r, &image, op.norm_fro(), u, u_free, mu)
}

/// [`certifies_infeasibility`] on the local form at `r`: one product `W r`, which is both
/// the image and, with `q`, the velocity.
pub(crate) fn local_run_off(p: &LocalProblem, r: &[f64]) -> bool {
    let mut image = vec![0.0; p.q.len()];
    p.w.mul_vec(1.0, r, 0.0, &mut image);
    let u: Vec<f64> = image.iter().zip(&p.q).map(|(wr, q)| wr + q).collect();
    certifies_infeasibility(r, &image, p.w.norm_fro(), &u, &p.q, &p.mu)
}

/// True when `r` certifies that the problem has no solution: `image` is `H r` (global
/// form) or `W r` (local form), `operator_norm` the Frobenius norm of that operator, `u`
/// the local velocity at the iterate, `u_free` the free velocity (`w` or `q`).
pub(crate) fn certifies_infeasibility(
    r: &[f64],
    image: &[f64],
    operator_norm: f64,
    u: &[f64],
    u_free: &[f64],
    mu: &[f64],
) -> bool {
    let r_norm = norm2(r);
    if !(r_norm > 0.0 && r_norm.is_finite()) {
        return false;
    }
    if norm2(image) > NULL_SPACE * operator_norm * r_norm {
        return false;
    }
    // r . u~ and ||u~||, with u~ = u + Phi(u) taken contact by contact.
    let (mut r_dot, mut u_sq) = (0.0, 0.0);
    for (i, &m) in mu.iter().enumerate() {
        let mut ui = get3(u, i);
        ui[0] += de_saxce_term(ui, m);
        let ri = get3(r, i);
        r_dot += ri[0] * ui[0] + ri[1] * ui[1] + ri[2] * ui[2];
        u_sq += ui[0] * ui[0] + ui[1] * ui[1] + ui[2] * ui[2];
    }
    let scale = u_sq.sqrt().max(norm2(u_free));
    -r_dot >= DEFECT * r_norm * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One contact, `mu = 1`: `y = (1, 1, 0)` lies on the cone.
    const MU: [f64; 1] = [1.0];

    #[test]
    fn impulses_in_the_null_space_against_approach_certify() {
        let r = [1e10, 1e10, 0.0];
        let u = [-5.0, 0.0, 0.0];
        assert!(certifies_infeasibility(&r, &[1.0], 1.0, &u, &u, &MU));
    }

    #[test]
    fn impulses_that_push_a_body_do_not_certify() {
        let r = [1e10, 1e10, 0.0];
        let u = [-5.0, 0.0, 0.0];
        assert!(!certifies_infeasibility(&r, &[1e8], 1.0, &u, &u, &MU));
    }

    #[test]
    fn complementary_impulses_do_not_certify() {
        // A loaded sticking contact (u = 0), or a loaded contact that separates slowly
        // relative to a large free velocity: the Signorini defect is small.
        let r = [1e10, 1e10, 0.0];
        assert!(!certifies_infeasibility(
            &r,
            &[0.0],
            1.0,
            &[0.0; 3],
            &[-5.0, 0.0, 0.0],
            &MU
        ));
        let u = [-1e-3, 0.0, 0.0];
        assert!(!certifies_infeasibility(
            &r,
            &[0.0],
            1.0,
            &u,
            &[-5.0, 0.0, 0.0],
            &MU
        ));
    }

    #[test]
    fn zero_or_non_finite_impulses_do_not_certify() {
        let u = [-5.0, 0.0, 0.0];
        assert!(!certifies_infeasibility(
            &[0.0; 3],
            &[0.0],
            1.0,
            &u,
            &u,
            &MU
        ));
        let r = [f64::INFINITY, 0.0, 0.0];
        assert!(!certifies_infeasibility(&r, &[0.0], 1.0, &u, &u, &MU));
    }

    #[test]
    fn the_certificate_does_not_depend_on_the_units() {
        let (r, u) = ([1e10, 1e10, 0.0], [-5.0, 0.0, 0.0]);
        for (a, b) in [(1e-6, 1e3), (1e6, 1e-3), (1.0, 1e8)] {
            let rs = r.map(|x| a * x);
            let us = u.map(|x| b * x);
            assert!(certifies_infeasibility(&rs, &[a * 1.0], 1.0, &us, &us, &MU));
            assert!(!certifies_infeasibility(
                &rs,
                &[a * 1e8],
                1.0,
                &us,
                &us,
                &MU
            ));
        }
    }
}
