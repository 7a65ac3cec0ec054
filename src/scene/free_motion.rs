//! The contact-free part of a scene (docs/algorithms.md §12): velocities no contact
//! reaches, without joints, move freely, `v = M^-1 f`. Their M splits into the blocks of
//! the bodies it couples (a rigid body's 6 x 6 block, a diagonal entry), each factorized
//! densely on its own, so a scene with thousands of free bodies pays for them in
//! proportion, not for a sparse analysis of all of them together.

use crate::linsys::{BlockDiagonal, DENSE_MAX};
use crate::measure::{Floors, GlobalTerms, Scales};
use crate::problem::GlobalProblem;
use crate::scene::islands::Part;
use crate::types::Solution;
use crate::types::Stats;
use crate::types::{Error, Status};
use std::time::Instant;

/// `v = M^-1 f` on the free velocities, block by block.
pub(crate) struct FreeMotion {
    /// The blocks of M as given (over the velocities' positions in the part), and their
    /// factors.
    mass: BlockDiagonal,
    f: Vec<f64>,
    v: Vec<f64>,
    /// Work vectors of the measure.
    mv: Vec<f64>,
    zeros: Vec<f64>,
    broken: Option<Error>,
    floors: Floors,
    stats: Stats,
}

impl FreeMotion {
    /// The free part `part` of `whole` (`row_of`: the velocities' positions in their
    /// parts) when every block of its M is small and symmetric and it has no joints;
    /// `None` otherwise (the coupled solver takes it).
    pub(crate) fn new(
        whole: &GlobalProblem,
        part: &Part,
        row_of: &[usize],
    ) -> Result<Option<Self>, Error> {
        let t0 = Instant::now();
        if !part.joints.is_empty() || !part.contacts.is_empty() {
            return Ok(None);
        }
        let n = part.velocities.len();
        // Blocks: connected components of M's pattern among the part's velocities.
        let entries = part.velocities.iter().enumerate();
        let entries = entries.flat_map(|(k, &j)| whole.m.col(j).map(move |(i, _)| (k, row_of[i])));
        let (mass, split) = BlockDiagonal::components(n, DENSE_MAX, entries);
        if split {
            return Ok(None);
        }
        let mut free = Self {
            mass,
            f: vec![0.0; n],
            v: vec![0.0; n],
            mv: vec![0.0; n],
            zeros: vec![0.0; n],
            broken: None,
            floors: Floors::default(),
            stats: Stats::default(),
        };
        free.read(whole, part, row_of);
        if !free.mass.is_symmetric() {
            return Ok(None);
        }
        free.mass.cholesky("M")?;
        free.stats.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(Some(free))
    }

    /// Copies the blocks of M and f out of the whole problem.
    fn read(&mut self, whole: &GlobalProblem, part: &Part, row_of: &[usize]) {
        self.mass.matrix_mut().fill(0.0);
        for (k, &j) in part.velocities.iter().enumerate() {
            for (i, x) in whole.m.col(j) {
                let at = self.mass.slot(row_of[i], k);
                self.mass.matrix_mut()[at.expect("a block holds the rows of its columns")] = x;
            }
        }
        for (f, &i) in self.f.iter_mut().zip(&part.velocities) {
            *f = whole.f[i];
        }
    }

    /// Takes the whole problem's current values (same pattern).
    pub(crate) fn take_values(
        &mut self,
        whole: &GlobalProblem,
        part: &Part,
        row_of: &[usize],
    ) -> Result<(), Error> {
        self.read(whole, part, row_of);
        let done = self.mass.cholesky("M");
        self.broken = done.as_ref().err().cloned();
        done
    }

    /// Floors of the error measure (the part's share of a scene's measure).
    pub(crate) fn set_measure_floors(&mut self, floors: Floors) {
        self.floors = floors;
    }

    /// `v = M^-1 f`, measured by the equation term of the measure.
    pub(crate) fn solve(&mut self) -> Result<Status, Error> {
        let t0 = Instant::now();
        if let Some(e) = &self.broken {
            return Err(e.clone());
        }
        self.v.copy_from_slice(&self.f);
        self.mass.solve_in_place(&mut self.v);
        self.mass.mul(&self.v, &mut self.mv);
        let terms = GlobalTerms {
            f: &self.f,
            mv: &self.mv,
            hr: &self.zeros,
            u: &[],
            r: &[],
            mu: &[],
        };
        let error = terms.error(self.floors, &mut Scales::default());
        self.stats = Stats {
            status: Status::Solved,
            error,
            solve_seconds: t0.elapsed().as_secs_f64(),
            ..self.stats
        };
        Ok(Status::Solved)
    }

    /// The velocities of the last solve.
    pub(crate) fn solution(&self) -> Solution {
        Solution {
            v: self.v.clone(),
            ..Solution::default()
        }
    }

    /// Statistics of the last solve.
    pub(crate) fn stats(&self) -> &Stats {
        &self.stats
    }
}
