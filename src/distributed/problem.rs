//! A process's part of a global contact problem, checked on its own.

use crate::linsys::BLOCK_MAX;
use crate::types::Error;
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
