//! The bounded joint rows of the global splitting (`contact::global`) (docs/algorithms.md §4.2): each is one
//! more row of the constraint space, after the contacts', with `A = G_k^T`, `c = -b_k` and
//! `g` the function whose proximal step clamps the multiplier into `[lo_k, hi_k]`. The
//! equality rows stay in the v-update system, exactly. A row bounded by a contact's normal
//! impulse (rolling or spinning friction) is clamped into `[-e r_n, e r_n]` as well, with the `r_n`
//! the same y-step has just projected (docs/algorithms.md §1.4).

use crate::problem::{contact_bounds, GlobalProblem};

/// The joint rows with a finite bound, as the splitting reads them: which column of `G`
/// each is, its bounds, its compliance and its `b`.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct BoundedRows {
    /// Columns of `G`, in order.
    pub(crate) rows: Vec<usize>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    compliance: Vec<f64>,
    /// The contact and coefficient of each row bounded by a contact.
    friction: Vec<Option<(usize, f64)>>,
    /// `b_k` of each row (the splitting's `c` is its negative).
    pub(crate) bias: Vec<f64>,
}

impl BoundedRows {
    /// The bounded rows of `p` (none without joints): the rows a factorized v-update
    /// system leaves to the splitting, its equalities staying exact in the system.
    pub(crate) fn of(p: &GlobalProblem) -> Self {
        Self::with_rows(p, p.bounded_rows())
    }

    /// Every joint row of `p`, equalities included (as rows with infinite bounds, whose
    /// proximal step is the compliance's alone): what the matrix-free v-update system,
    /// which has no place for an exact equality, leaves to the splitting.
    pub(crate) fn all(p: &GlobalProblem) -> Self {
        Self::with_rows(p, (0..p.n_joints()).collect())
    }

    /// The joint rows `rows` of `p`, in order.
    fn with_rows(p: &GlobalProblem, rows: Vec<usize>) -> Self {
        let Some(j) = &p.joints else {
            return Self::default();
        };
        let pick = |x: &[f64]| rows.iter().map(|&k| x[k]).collect();
        Self {
            lo: pick(&j.lo),
            hi: pick(&j.hi),
            compliance: pick(&j.compliance),
            bias: pick(&j.b),
            friction: rows
                .iter()
                .map(|&k| j.friction_contact[k].map(|i| (i, j.friction[k])))
                .collect(),
            rows,
        }
    }

    /// Number of bounded rows.
    pub(crate) fn len(&self) -> usize {
        self.rows.len()
    }

    /// Row `q`'s bounds, `normal(i)` giving contact `i`'s normal impulse for a row bounded
    /// by a contact (a negative one counts as zero, as in [`crate::Joints::bounds`]).
    #[inline]
    pub(crate) fn bounds(&self, q: usize, normal: impl Fn(usize) -> f64) -> (f64, f64) {
        let (lo, hi) = (self.lo[q], self.hi[q]);
        match self.friction[q] {
            Some((i, e)) => contact_bounds(lo, hi, e, normal(i)),
            None => (lo, hi),
        }
    }

    /// Row `q`'s multiplier from its dual variable, `-rho zeta` clamped into its bounds:
    /// the proximal step leaves it there, but an accelerated or relaxed iterate can carry
    /// it past a bound by round-off, and an engine must never be handed that.
    pub(crate) fn multiplier(&self, zeta: f64, rho: f64, (lo, hi): (f64, f64)) -> f64 {
        (-rho * zeta).clamp(lo, hi)
    }

    /// The proximal step of bounded row `q` at `a = G_k^T v + b_k + zeta`, penalty `rho` and
    /// bounds `[lo, hi]`: the multiplier `lambda = P_[lo,hi](-rho a / (1 + rho c))`, which minimises
    /// `(c/2) lambda^2 + (1/(2 rho)) (lambda + rho a)^2` over the bounds, and the row's
    /// `y = a + lambda / rho` (so that `zeta+ = a - y = -lambda / rho`, and
    /// `lambda = -rho zeta` as for the contacts' impulses).
    #[inline]
    pub(crate) fn prox(&self, q: usize, a: f64, rho: f64, (lo, hi): (f64, f64)) -> f64 {
        let lambda = (-rho * a / (1.0 + rho * self.compliance[q])).clamp(lo, hi);
        a + lambda / rho
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::csc::CscMatrix;

    /// One velocity, one row of each kind: an equality, a limit `[0, inf)` and a motor
    /// `[-2, 2]` with compliance 0.5.
    fn rows() -> BoundedRows {
        let m = CscMatrix::new("M", 1, 1, vec![0, 1], vec![0], vec![1.0]).unwrap();
        let h = CscMatrix::new("H", 1, 0, vec![0], vec![], vec![]).unwrap();
        let g = CscMatrix::new("G", 1, 3, vec![0, 1, 2, 3], vec![0; 3], vec![1.0; 3]).unwrap();
        let p = GlobalProblem::new(m, h, vec![0.0], vec![], vec![])
            .unwrap()
            .with_joints(g, vec![0.1, 0.2, 0.3])
            .unwrap()
            .with_joint_bounds(
                vec![f64::NEG_INFINITY, 0.0, -2.0],
                vec![f64::INFINITY, f64::INFINITY, 2.0],
            )
            .unwrap()
            .with_joint_compliance(vec![0.0, 0.0, 0.5])
            .unwrap();
        BoundedRows::of(&p)
    }

    #[test]
    fn only_rows_with_a_finite_bound_are_taken() {
        let b = rows();
        assert_eq!(b.rows, vec![1, 2]);
        assert_eq!(b.bias, vec![0.2, 0.3]);
    }

    /// A row bounded by a contact's normal impulse: `[-e r_n, e r_n]`, zero when the
    /// contact pushes nothing (or an iterate's `r_n` is negative).
    #[test]
    fn a_row_bounded_by_a_contact_follows_its_normal_impulse() {
        let m = CscMatrix::new("M", 1, 1, vec![0, 1], vec![0], vec![1.0]).unwrap();
        let h = CscMatrix::new("H", 1, 3, vec![0, 1, 1, 1], vec![0], vec![1.0]).unwrap();
        let g = CscMatrix::new("G", 1, 1, vec![0, 1], vec![0], vec![1.0]).unwrap();
        let p = GlobalProblem::new(m, h, vec![0.0], vec![0.0; 3], vec![0.5])
            .unwrap()
            .with_joints(g, vec![0.0])
            .unwrap()
            .with_joint_friction(vec![Some(0)], vec![0.1])
            .unwrap();
        let b = BoundedRows::of(&p);
        assert_eq!(b.rows, vec![0]);
        assert_eq!(b.bounds(0, |i| [3.0][i]), (-0.1 * 3.0, 0.1 * 3.0));
        assert_eq!(b.bounds(0, |_| -1.0), (-0.0, 0.0));
        // Saturated: lambda = -e r_n, y = a + lambda / rho.
        let (rho, bounds) = (2.0, b.bounds(0, |_| 3.0));
        assert!((b.prox(0, 1.0, rho, bounds) - (1.0 - 0.3 / 2.0)).abs() < 1e-15);
    }

    /// The prox's multiplier solves the row's law: inside the bounds the row's velocity
    /// `y + c lambda` is zero, at a bound it pushes the right way; checked by hand here.
    #[test]
    fn prox_clamps_the_multiplier_into_the_bounds() {
        let b = rows();
        let rho = 4.0;
        let (limit, motor) = (b.bounds(0, |_| 0.0), b.bounds(1, |_| 0.0));
        assert_eq!((limit, motor), ((0.0, f64::INFINITY), (-2.0, 2.0)));
        // Limit, separating (a > 0): lambda = 0, y = a.
        assert_eq!(b.prox(0, 0.5, rho, limit), 0.5);
        // Limit, pushed (a < 0): lambda = -rho a = 2, y = 0.
        assert_eq!(b.prox(0, -0.5, rho, limit), 0.0);
        // Motor inside its bounds: lambda = -4 * -0.3 / (1 + 2) = 0.4, y = -0.3 + 0.1.
        assert!((b.prox(1, -0.3, rho, motor) - (-0.2)).abs() < 1e-15);
        // Motor saturated: lambda = 2, y = -3 + 0.5.
        assert_eq!(b.prox(1, -3.0, rho, motor), -2.5);
    }
}
