//! One contact's own problem in a sweep: with every other impulse held, `u = W r + q` for
//! its Delassus block `W`, solved by the separating, sticking or sliding case.

use crate::cone::{de_saxce_term, project_cone, tangential_norm};
use crate::tuning::GAUSS_SEIDEL_INNER;

/// One contact's Delassus block `W_cc = H_c^T M^-1 H_c` (row-major), its inverse when it
/// is well conditioned, and the step of its projected fixed point, `1 / lambda_max`,
/// computed when the contact first slides: most contacts of an engine's step separate or
/// stick, and the eigenvalue (an `acos` and a `cos`) was a tenth of building a budgeted
/// solver on a wall's step.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ContactBlock {
    w: [f64; 9],
    inverse: Option<[f64; 9]>,
    step: Option<f64>,
}

impl ContactBlock {
    pub fn of(w: [f64; 9]) -> Self {
        Self {
            w,
            inverse: inverse(&w),
            step: None,
        }
    }

    /// `1 / lambda_max` (0 for a zero block).
    fn step(&mut self) -> f64 {
        *self.step.get_or_insert_with(|| {
            let lambda_max = largest_eigenvalue(&self.w);
            if lambda_max > 0.0 {
                1.0 / lambda_max
            } else {
                0.0
            }
        })
    }

    #[inline]
    pub fn mul(&self, x: [f64; 3]) -> [f64; 3] {
        let w = &self.w;
        [
            w[0] * x[0] + w[1] * x[1] + w[2] * x[2],
            w[3] * x[0] + w[4] * x[1] + w[5] * x[2],
            w[6] * x[0] + w[7] * x[1] + w[8] * x[2],
        ]
    }

    /// The contact's impulse for `u = W r + q`, the others held: none when `q` separates,
    /// the sticking impulse `-W^-1 q` when it lies in the cone, and otherwise a few steps
    /// of the projected fixed point `r <- P_K(r - step (u + mu ||u_T|| e_N))` from `r`.
    #[inline]
    pub fn solve(&mut self, q: [f64; 3], mu: f64, mut r: [f64; 3]) -> [f64; 3] {
        if q[0] >= 0.0 {
            return [0.0; 3];
        }
        if let Some(inv) = &self.inverse {
            let stick = [
                -(inv[0] * q[0] + inv[1] * q[1] + inv[2] * q[2]),
                -(inv[3] * q[0] + inv[4] * q[1] + inv[5] * q[2]),
                -(inv[6] * q[0] + inv[7] * q[1] + inv[8] * q[2]),
            ];
            if stick[0] >= 0.0 && tangential_norm(stick[1], stick[2]) <= mu * stick[0] {
                return stick;
            }
        }
        let step = self.step();
        for _ in 0..GAUSS_SEIDEL_INNER {
            let wr = self.mul(r);
            let u = [wr[0] + q[0], wr[1] + q[1], wr[2] + q[2]];
            let un = u[0] + de_saxce_term(u, mu);
            r = project_cone(
                [r[0] - step * un, r[1] - step * u[1], r[2] - step * u[2]],
                mu,
            );
        }
        r
    }
}

/// The largest eigenvalue of a symmetric 3 x 3 matrix (row-major), in closed form
/// (the trigonometric solution of its characteristic cubic).
fn largest_eigenvalue(w: &[f64; 9]) -> f64 {
    let off = w[1] * w[1] + w[2] * w[2] + w[5] * w[5];
    let trace = w[0] + w[4] + w[8];
    if off == 0.0 {
        return w[0].max(w[4]).max(w[8]);
    }
    let mean = trace / 3.0;
    let d = [w[0] - mean, w[4] - mean, w[8] - mean];
    let p2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * off;
    let scale = (p2 / 6.0).sqrt();
    // det((W - mean I) / scale) / 2, clamped into [-1, 1] against round-off.
    let b = [
        d[0] / scale,
        w[1] / scale,
        w[2] / scale,
        d[1] / scale,
        w[5] / scale,
        d[2] / scale,
    ];
    let det = b[0] * (b[3] * b[5] - b[4] * b[4]) - b[1] * (b[1] * b[5] - b[4] * b[2])
        + b[2] * (b[1] * b[4] - b[3] * b[2]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    mean + 2.0 * scale * phi.cos()
}

/// The inverse of a symmetric positive definite 3 x 3 matrix (row-major) when its
/// determinant is clear of round-off; `None` for a singular or nearly singular block (a
/// contact whose rows are dependent), which then has no sticking shortcut.
fn inverse(w: &[f64; 9]) -> Option<[f64; 9]> {
    let cof = [
        w[4] * w[8] - w[5] * w[7],
        w[2] * w[7] - w[1] * w[8],
        w[1] * w[5] - w[2] * w[4],
        w[5] * w[6] - w[3] * w[8],
        w[0] * w[8] - w[2] * w[6],
        w[2] * w[3] - w[0] * w[5],
        w[3] * w[7] - w[4] * w[6],
        w[1] * w[6] - w[0] * w[7],
        w[0] * w[4] - w[1] * w[3],
    ];
    let det = w[0] * cof[0] + w[1] * cof[3] + w[2] * cof[6];
    let trace = w[0] + w[4] + w[8];
    // Written to refuse a NaN determinant too.
    (det > 1e-12 * trace * trace * trace).then(|| cof.map(|x| x / det))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, SymmetricEigen};

    fn spd(seed: u64) -> [f64; 9] {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a = Matrix3::from_fn(|_, _| next());
        let w = a * a.transpose() + Matrix3::identity() * 0.01;
        let mut out = [0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                out[3 * i + j] = w[(i, j)];
            }
        }
        out
    }

    #[test]
    fn closed_form_eigenvalue_and_inverse_match_nalgebra() {
        for seed in 0..200 {
            let w = spd(seed);
            let m = Matrix3::from_row_slice(&w);
            let largest = SymmetricEigen::new(m).eigenvalues.max();
            approx::assert_relative_eq!(largest_eigenvalue(&w), largest, max_relative = 1e-10);
            let inv = Matrix3::from_row_slice(&inverse(&w).unwrap());
            approx::assert_relative_eq!(inv * m, Matrix3::identity(), epsilon = 1e-8);
        }
        let diagonal = [2.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 3.0];
        assert_eq!(largest_eigenvalue(&diagonal), 5.0);
        assert!(inverse(&[1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0]).is_none());
    }

    /// Each branch of a contact's own solve meets Coulomb's law for its `u = W r + q`.
    #[test]
    fn a_contact_solve_meets_coulombs_law_on_each_branch() {
        let mut block = ContactBlock::of(spd(7));
        let mu = 0.5;
        for q in [[0.3, 1.0, -2.0], [-1.0, 0.1, 0.05], [-1.0, 3.0, -2.0]] {
            let mut r = [0.0; 3];
            for _ in 0..400 {
                r = block.solve(q, mu, r);
            }
            let wr = block.mul(r);
            let u = [wr[0] + q[0], wr[1] + q[1], wr[2] + q[2]];
            let error = crate::measure::complementarity_residual(&r, &u, &[mu]);
            assert!(error < 1e-9, "q {q:?}: r {r:?}, u {u:?}, residual {error}");
        }
    }
}
