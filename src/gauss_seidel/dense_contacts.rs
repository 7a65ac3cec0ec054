//! Few contacts solved at once: semismooth Newton on the contacts' Delassus form, with
//! the joints' equality rows eliminated exactly (docs/algorithms.md §17). Where contacts
//! change between sticking and sliding, the sweeps plateau while that settles: a chain of
//! 20 links striking a box (8 contacts, 60 joint rows) measured 0.010 after 30 sweeps,
//! 0.0087 after 100, and 2e-7 only after about 340. Newton finds which contacts stick in
//! a few steps. With few contacts the form is small and dense, and forming it costs one
//! joint solve per contact row, so it is tried once per run, after the first sweeps.
//!
//! Through the joints, an impulse `r` on the contacts gives the velocities
//! `v = v_0 + (M^-1 - M^-1 G S^-1 G^T M^-1) H r`, where `v_0` are the free velocities
//! with every joint row met and `S = L L^T` the joints' Delassus matrix (`joint_block.rs`):
//! so the contacts see `u = W r + q`, `q = H^T v_0 + w`, `W = H^T M^-1 H - Y^T Y` with
//! `Y = L^-1 G^T M^-1 H`.

use super::joint_block::JointBlock;
use super::movement::Movement;
use super::rows::RowGroups;
use crate::linsys::BlockDiagonal;
use crate::newton::{LocalNewton, NewtonOutcome};
use crate::problem::{GlobalProblem, Joints, LocalProblem};
use crate::types::Error;
use std::time::Instant;

/// The Newton solver of one number of contacts, its problem and work space (kept for
/// each number: an engine's step changes its contacts, and building one costs a few
/// Newton steps).
pub(super) struct DenseContacts {
    local: LocalProblem,
    newton: LocalNewton,
    /// `W` column-major.
    w: Vec<f64>,
    /// Work space: velocities, and the joints' multipliers.
    v: Vec<f64>,
    lambda: Vec<f64>,
    /// `Y = L^-1 G^T M^-1 H` column-major, and each column's first row not zero.
    y: Vec<f64>,
    y_from: Vec<usize>,
    /// What the last attempt took, in seconds (doubled when the deadline cut it short).
    pub seconds: f64,
}

/// What the sweeps hold of the problem: M's blocks, the contacts' columns of H and, when
/// every joint row is solved together, the joints' columns of G and their factor.
pub(super) struct Swept<'a> {
    pub mass: &'a BlockDiagonal,
    pub contacts: &'a RowGroups<3>,
    pub joints: Option<(&'a RowGroups<1>, &'a Joints, &'a mut JointBlock)>,
}

impl DenseContacts {
    /// The solver of `nc` contacts.
    pub fn new(nc: usize) -> Result<Self, Error> {
        let local = LocalProblem::dense(nc)?;
        let newton = LocalNewton::new(&local)?;
        Ok(Self {
            local,
            newton,
            w: vec![0.0; 9 * nc * nc],
            v: Vec::new(),
            lambda: Vec::new(),
            y: Vec::new(),
            y_from: Vec::new(),
            seconds: 0.0,
        })
    }

    /// Forms the contacts' Delassus form of `p` through the joints and solves it by Newton
    /// from the impulses `r`, for at most `steps` steps, until its own measure meets
    /// `tolerance` or the `deadline`; `r` holds the best iterate. An error when an entry of
    /// W is not finite.
    pub fn solve(
        &mut self,
        swept: Swept,
        p: &GlobalProblem,
        r: &mut [f64],
        (tolerance, steps, deadline): (f64, usize, Option<Instant>),
    ) -> Result<NewtonOutcome, Error> {
        self.form(swept, p)?;
        self.newton.take_values(&self.local);
        self.newton
            .solve(&self.local, r, tolerance, steps, deadline)
    }

    /// The contacts' Delassus form through the joints into `self.local` (module doc).
    fn form(&mut self, swept: Swept, p: &GlobalProblem) -> Result<(), Error> {
        let Swept {
            mass,
            contacts,
            mut joints,
        } = swept;
        let (n, m) = (p.n(), 3 * p.n_contacts());
        self.v.resize(n, 0.0);
        self.lambda.resize(p.n_joints(), 0.0);
        // q: the free velocities with the joints met.
        mass.mul_inverse(0..mass.block_count(), &p.f, &mut self.v);
        if let Some((rows, j, block)) = &mut joints {
            self.lambda.fill(0.0);
            block.solve(
                j,
                rows,
                &mut self.lambda,
                &mut self.v,
                &mut Movement::default(),
            );
        }
        for g in 0..contacts.len() {
            let c = contacts.source(g);
            let u = contacts.apply(g, &self.v);
            for k in 0..3 {
                self.local.q[3 * c + k] = u[k] + p.w[3 * c + k];
            }
        }
        self.local.mu.copy_from_slice(&p.mu);
        // W = H^T M^-1 H - Y^T Y, a column of each per contact row: its unit impulse's
        // velocities, seen by every contact and (Y) by the joints.
        let together = joints.as_ref().map_or(0, |(_, _, block)| block.len());
        self.y.resize(together * m, 0.0);
        self.y_from.resize(m, 0);
        for g in 0..contacts.len() {
            let c = contacts.source(g);
            for a in 0..3 {
                let col = 3 * c + a;
                self.v.fill(0.0);
                let mut unit = [0.0; 3];
                unit[a] = 1.0;
                contacts.add(g, unit, &mut self.v);
                let column = &mut self.w[col * m..(col + 1) * m];
                for h in 0..contacts.len() {
                    let e = contacts.source(h);
                    column[3 * e..3 * e + 3].copy_from_slice(&contacts.apply(h, &self.v));
                }
                if let Some((rows, _, block)) = &joints {
                    let y = &mut self.y[col * together..(col + 1) * together];
                    self.y_from[col] = block.forward(rows, &self.v, y);
                }
            }
        }
        self.subtract_joints(m, together);
        self.local.w.set_values("W", &self.w)
    }

    /// `W -= Y^T Y` over the `together` rows of each column of `Y` from its first not zero.
    fn subtract_joints(&mut self, m: usize, together: usize) {
        if together == 0 {
            return;
        }
        for a in 0..m {
            let y_a = &self.y[a * together..(a + 1) * together];
            for b in 0..=a {
                let from = self.y_from[a].max(self.y_from[b]);
                let y_b = &self.y[b * together..(b + 1) * together];
                let dot: f64 = y_a[from..]
                    .iter()
                    .zip(&y_b[from..])
                    .map(|(x, y)| x * y)
                    .sum();
                self.w[a + b * m] -= dot;
                if a != b {
                    self.w[b + a * m] -= dot;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::GaussSeidel;
    use super::*;
    use crate::csc::CscMatrix;
    use nalgebra::{DMatrix, DVector};

    /// Four bodies of three velocities each (full symmetric blocks of M), three compliant
    /// joint rows along them, and three contacts: between bodies 0 and 1, and of bodies 2
    /// and 3 with the ground.
    fn jointed() -> GlobalProblem {
        let n = 12;
        let mut m = vec![0.0; n * n];
        for b in 0..4 {
            let d = 1.0 + b as f64;
            for (i, j, x) in [
                (0, 0, 2.0 * d),
                (1, 1, d),
                (2, 2, 3.0 * d),
                (0, 1, 0.3),
                (1, 2, -0.2),
            ] {
                m[(3 * b + i) * n + 3 * b + j] = x;
                m[(3 * b + j) * n + 3 * b + i] = x;
            }
        }
        let mut h = vec![0.0; n * 9];
        for (i, c, x) in [
            (2, 0, 1.0),
            (5, 0, -1.0),
            (0, 1, 1.0),
            (3, 1, -0.8),
            (1, 2, 1.0),
            (4, 2, -1.1),
            (8, 3, 1.0),
            (6, 4, 1.0),
            (7, 5, 1.0),
            (11, 6, 0.9),
            (9, 7, 1.0),
            (10, 8, 1.0),
            (2, 3, 0.1),
        ] {
            h[i * 9 + c] = x;
        }
        let mut g = vec![0.0; n * 3];
        for (i, k, x) in [
            (0, 0, 1.0),
            (3, 0, -1.0),
            (4, 1, 1.0),
            (7, 1, -1.0),
            (8, 2, 1.0),
            (11, 2, -0.5),
        ] {
            g[i * 3 + k] = x;
        }
        let f: Vec<f64> = (0..n).map(|i| (0.7 * i as f64).sin()).collect();
        let w: Vec<f64> = (0..9).map(|c| 0.1 * (1.3 * c as f64).cos()).collect();
        GlobalProblem::new(
            CscMatrix::from_dense("M", n, n, &m).unwrap(),
            CscMatrix::from_dense("H", n, 9, &h).unwrap(),
            f,
            w,
            vec![0.5, 0.3, 0.8],
        )
        .unwrap()
        .with_joints(
            CscMatrix::from_dense("G", n, 3, &g).unwrap(),
            vec![0.05, -0.02, 0.01],
        )
        .unwrap()
        .with_joint_compliance(vec![1e-3, 0.0, 2e-2])
        .unwrap()
    }

    /// The form through the joints is the dense Schur complement computed by nalgebra:
    /// `W = H^T (M^-1 - M^-1 G S^-1 G^T M^-1) H`, `S = G^T M^-1 G + C`, and `q = H^T v_0
    /// + w` with `v_0 = M^-1 (f + G lambda_0)`, `S lambda_0 = -(G^T M^-1 f + b)`.
    #[test]
    fn the_form_through_the_joints_is_the_schur_complement() {
        let p = jointed();
        let mut sweeps = GaussSeidel::new(&p).unwrap();
        assert!(sweeps.take_values(&p).unwrap());
        assert!(sweeps.joint_block.ready() && sweeps.single_rows.is_empty());
        let mut dense = DenseContacts::new(3).unwrap();
        let j = p.joints.as_ref().unwrap();
        let swept = Swept {
            mass: &sweeps.mass,
            contacts: &sweeps.contacts,
            joints: Some((sweeps.joints.as_ref().unwrap(), j, &mut sweeps.joint_block)),
        };
        dense.form(swept, &p).unwrap();

        let dm = |a: &CscMatrix| DMatrix::from_column_slice(a.nrows(), a.ncols(), &a.to_dense());
        let (m, h, g) = (dm(&p.m), dm(&p.h), dm(&j.g));
        let m_inv = m.try_inverse().unwrap();
        let s = g.transpose() * &m_inv * &g
            + DMatrix::from_diagonal(&DVector::from_vec(j.compliance.clone()));
        let s_inv = s.try_inverse().unwrap();
        let through = &m_inv - &m_inv * &g * &s_inv * g.transpose() * &m_inv;
        let w = h.transpose() * &through * &h;
        let f = DVector::from_vec(p.f.clone());
        let lambda0 = -&s_inv * (g.transpose() * &m_inv * &f + DVector::from_vec(j.b.clone()));
        let q = h.transpose() * (&m_inv * (f + &g * lambda0)) + DVector::from_vec(p.w.clone());

        let formed = DMatrix::from_column_slice(9, 9, &dense.local.w.to_dense());
        let scale = w.amax();
        assert!(
            (&formed - &w).amax() <= 1e-13 * scale,
            "{formed} against {w}"
        );
        let formed_q = DVector::from_vec(dense.local.q.clone());
        assert!(
            (&formed_q - &q).amax() <= 1e-13 * q.amax(),
            "{formed_q} against {q}"
        );
        assert_eq!(dense.local.mu, p.mu);
    }
}
