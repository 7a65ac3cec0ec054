//! A process's part of a global contact problem, checked on its own.

use crate::linsys::BLOCK_MAX;
use crate::problem::GlobalProblem;
use crate::types::{Error, ErrorKind};
use std::fmt;

/// This process's part of a global contact problem: the bodies it owns and the contacts
/// it owns (each body and each contact is owned by exactly one process).
#[derive(Debug, Clone, Default)]
pub struct RankProblem {
    /// Global ids of the bodies this process owns.
    pub bodies: Vec<u64>,
    /// Velocities of each owned body (6 for a rigid body; at most 12).
    pub dofs: Vec<usize>,
    /// Each owned body's mass matrix, `dofs x dofs` column-major, body after body.
    pub mass: Vec<f64>,
    /// Free-motion term: one entry per owned velocity, body after body.
    pub f: Vec<f64>,
    /// Start of each column of H in the entries below: three columns per owned contact
    /// (normal first), column `j` is `h_colptr[j]..h_colptr[j + 1]`.
    pub h_colptr: Vec<usize>,
    /// Each entry's body: a global id, of a body this process or another one owns.
    pub h_body: Vec<u64>,
    /// Each entry's velocity within its body (`0..dofs` of that body).
    pub h_dof: Vec<usize>,
    /// Each entry's value.
    pub h_values: Vec<f64>,
    /// Relative velocity offset `w`, three entries per owned contact.
    pub w: Vec<f64>,
    /// Friction coefficient of each owned contact.
    pub mu: Vec<f64>,
}

/// An error one process found, which every process sharing the problem returns alike.
#[derive(Debug, Clone, PartialEq)]
pub struct RankError {
    /// The process (its rank) whose part or work failed; the lowest one when several did.
    pub rank: usize,
    /// What kind of error it met there (the C API's result code).
    pub kind: ErrorKind,
    /// What failed there, with the item it names.
    pub message: String,
}

impl fmt::Display for RankError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "rank {}: {}", self.rank, self.message)
    }
}

impl std::error::Error for RankError {}

impl RankProblem {
    /// Owned contacts.
    pub fn n_contacts(&self) -> usize {
        self.mu.len()
    }

    /// Owned velocities.
    pub fn n_velocities(&self) -> usize {
        self.f.len()
    }

    /// The part of a whole problem that the process `rank` owns, for a host (or a test)
    /// that holds the whole problem on every process: body `b` (id `b`) has the
    /// velocities `dofs[b]`, consecutive and in order, and belongs to `body_rank[b]`;
    /// contact `i` belongs to `contact_rank[i]`. M must be block diagonal over the bodies.
    pub fn split(
        whole: &GlobalProblem,
        dofs: &[usize],
        body_rank: &[usize],
        contact_rank: &[usize],
        rank: usize,
    ) -> Result<Self, Error> {
        check_split(whole, dofs, body_rank, contact_rank)?;
        let (n, bodies) = (whole.n(), dofs.len());
        // Each velocity's body and the body's first velocity.
        let mut body_of = Vec::with_capacity(n);
        let mut first = Vec::with_capacity(bodies);
        for (b, &k) in dofs.iter().enumerate() {
            first.push(body_of.len());
            body_of.extend(std::iter::repeat_n(b, k));
        }
        let mut part = Self {
            h_colptr: vec![0],
            ..Self::default()
        };
        let mut blocks: Vec<Option<Vec<f64>>> = vec![None; bodies];
        for j in 0..n {
            for (i, v) in whole.m.col(j) {
                let b = body_of[j];
                if body_of[i] != b {
                    return Err(Error::InvalidCsc {
                        field: "M",
                        reason: format!(
                            "entry ({i}, {j}) joins two bodies: M is not block diagonal over dofs"
                        ),
                    });
                }
                if body_rank[b] == rank {
                    let k = dofs[b];
                    let block = blocks[b].get_or_insert_with(|| vec![0.0; k * k]);
                    block[(j - first[b]) * k + (i - first[b])] = v;
                }
            }
        }
        for (b, block) in blocks.into_iter().enumerate() {
            if body_rank[b] != rank {
                continue;
            }
            let k = dofs[b];
            part.bodies.push(b as u64);
            part.dofs.push(k);
            part.mass.extend(block.unwrap_or_else(|| vec![0.0; k * k]));
            part.f.extend_from_slice(&whole.f[first[b]..first[b] + k]);
        }
        for (c, _) in contact_rank.iter().enumerate().filter(|&(_, &r)| r == rank) {
            for j in 3 * c..3 * c + 3 {
                for (i, v) in whole.h.col(j) {
                    part.h_body.push(body_of[i] as u64);
                    part.h_dof.push(i - first[body_of[i]]);
                    part.h_values.push(v);
                }
                part.h_colptr.push(part.h_body.len());
            }
            part.w.extend_from_slice(&whole.w[3 * c..3 * c + 3]);
            part.mu.push(whole.mu[c]);
        }
        Ok(part)
    }

    /// Checks what this part can check alone: sizes, the structure of H's columns, and
    /// that every value is finite and every friction coefficient non-negative. (Whether
    /// each entry's body exists is known once the processes have exchanged their ids.)
    pub(crate) fn validate(&self) -> Result<(), Error> {
        let dimension = |field, expected, got| -> Result<(), Error> {
            if expected == got {
                Ok(())
            } else {
                Err(Error::Dimension {
                    field,
                    expected,
                    found: got,
                })
            }
        };
        let nc = self.mu.len();
        dimension("dofs", self.bodies.len(), self.dofs.len())?;
        if let Some(b) = self.dofs.iter().position(|&k| k == 0 || k > BLOCK_MAX) {
            return Err(Error::InvalidValue {
                field: "dofs",
                index: b,
                reason: "a body has 1 to 12 velocities",
            });
        }
        dimension(
            "mass",
            self.dofs.iter().map(|k| k * k).sum(),
            self.mass.len(),
        )?;
        dimension("f", self.dofs.iter().sum(), self.f.len())?;
        dimension("w", 3 * nc, self.w.len())?;
        dimension("h_colptr", 3 * nc + 1, self.h_colptr.len())?;
        let entries = *self.h_colptr.last().unwrap_or(&0);
        if self.h_colptr[0] != 0 || self.h_colptr.windows(2).any(|p| p[0] > p[1]) {
            return Err(Error::InvalidCsc {
                field: "H",
                reason: "h_colptr must start at 0 and never decrease".into(),
            });
        }
        dimension("h_body", entries, self.h_body.len())?;
        dimension("h_dof", entries, self.h_dof.len())?;
        dimension("h_values", entries, self.h_values.len())?;
        for (field, values) in [
            ("mass", &self.mass),
            ("f", &self.f),
            ("h_values", &self.h_values),
            ("w", &self.w),
        ] {
            if let Some(index) = values.iter().position(|v| !v.is_finite()) {
                return Err(Error::InvalidValue {
                    field,
                    index,
                    reason: "not finite",
                });
            }
        }
        if let Some(index) = self.mu.iter().position(|m| !(m.is_finite() && *m >= 0.0)) {
            return Err(Error::InvalidValue {
                field: "mu",
                index,
                reason: "a friction coefficient is finite and non-negative",
            });
        }
        Ok(())
    }
}

/// Checks the sizes [`RankProblem::split`] is given against the whole problem, which must
/// have no joints.
fn check_split(
    whole: &GlobalProblem,
    dofs: &[usize],
    body_rank: &[usize],
    contact_rank: &[usize],
) -> Result<(), Error> {
    let n = whole.n();
    if dofs.iter().sum::<usize>() != n {
        return Err(Error::Dimension {
            field: "dofs",
            expected: n,
            found: dofs.iter().sum(),
        });
    }
    let bodies = dofs.len();
    let dimension = |field, expected, found| Error::Dimension {
        field,
        expected,
        found,
    };
    if body_rank.len() != bodies {
        return Err(dimension("body_rank", bodies, body_rank.len()));
    }
    if contact_rank.len() != whole.n_contacts() {
        return Err(dimension(
            "contact_rank",
            whole.n_contacts(),
            contact_rank.len(),
        ));
    }
    if whole.n_joints() > 0 {
        return Err(Error::Unsupported(
            "a problem with joints cannot be shared out among processes".into(),
        ));
    }
    Ok(())
}
