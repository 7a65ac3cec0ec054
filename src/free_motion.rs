//! The contact-free part of a scene (docs/algorithms.md §12): velocities no contact
//! reaches, without joints, move freely, `v = M^-1 f`. Their M splits into the blocks of
//! the bodies it couples (a rigid body's 6 x 6 block, a diagonal entry), each factorized
//! densely on its own, so a scene with thousands of free bodies pays for them in
//! proportion, not for a sparse analysis of all of them together.

use crate::dense::{cholesky, cholesky_solve, is_symmetric};
use crate::disjoint_sets::DisjointSets;
use crate::islands::Part;
use crate::linsys::DENSE_MAX;
use crate::measure::{Floors, GlobalTerms, Scales};
use crate::problem::GlobalProblem;
use crate::types::Solution;
use crate::types::Stats;
use crate::types::{Error, Status};
use std::time::Instant;

/// One block of M: its velocities are `order[start..start + size]` (positions in the
/// part), its column-major dense block at `factors[at..at + size * size]`.
#[derive(Debug, Clone, Copy)]
struct Block {
    start: usize,
    size: usize,
    at: usize,
}

/// `v = M^-1 f` on the free velocities, block by block.
pub(crate) struct FreeMotion {
    blocks: Vec<Block>,
    order: Vec<usize>,
    /// The blocks of M as given, then (after [`FreeMotion::take_values`]) their factors.
    m: Vec<f64>,
    factors: Vec<f64>,
    f: Vec<f64>,
    v: Vec<f64>,
    /// Work vectors of the measure and the block solves.
    mv: Vec<f64>,
    zeros: Vec<f64>,
    x: Vec<f64>,
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
        // Blocks: connected components of M's pattern among the part's velocities (an
        // entry joins its row and its column, whether or not its mirror is stored).
        let mut sets = DisjointSets::new(n);
        for (k, &j) in part.velocities.iter().enumerate() {
            for (i, _) in whole.m.col(j) {
                sets.union(k, row_of[i]);
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        let roots: Vec<usize> = (0..n).map(|k| sets.find(k)).collect();
        // Grouped by block (blocks in the order of their smallest velocity), increasing
        // within a block.
        let mut first = vec![usize::MAX; n];
        for k in 0..n {
            first[roots[k]] = first[roots[k]].min(k);
        }
        order.sort_by_key(|&k| (first[roots[k]], k));
        let mut blocks = Vec::new();
        let mut at = 0;
        let mut start = 0;
        while start < n {
            let root = roots[order[start]];
            let size = order[start..]
                .iter()
                .take_while(|&&k| roots[k] == root)
                .count();
            if size > DENSE_MAX {
                return Ok(None);
            }
            blocks.push(Block { start, size, at });
            at += size * size;
            start += size;
        }
        let mut free = Self {
            blocks,
            order,
            m: vec![0.0; at],
            factors: vec![0.0; at],
            f: vec![0.0; n],
            v: vec![0.0; n],
            mv: vec![0.0; n],
            zeros: vec![0.0; n],
            x: Vec::with_capacity(DENSE_MAX),
            broken: None,
            floors: Floors::default(),
            stats: Stats::default(),
        };
        free.read(whole, part, row_of);
        if !free.symmetric() {
            return Ok(None);
        }
        free.factorize()?;
        free.stats.setup_seconds = t0.elapsed().as_secs_f64();
        Ok(Some(free))
    }

    /// Copies the blocks of M and f out of the whole problem.
    fn read(&mut self, whole: &GlobalProblem, part: &Part, row_of: &[usize]) {
        for b in &self.blocks {
            let velocities = &self.order[b.start..b.start + b.size];
            let block = &mut self.m[b.at..b.at + b.size * b.size];
            block.fill(0.0);
            for (col, &k) in velocities.iter().enumerate() {
                for (i, x) in whole.m.col(part.velocities[k]) {
                    let row = velocities
                        .binary_search(&row_of[i])
                        .expect("a block holds the rows of its columns");
                    block[row + col * b.size] = x;
                }
            }
        }
        for (f, &i) in self.f.iter_mut().zip(&part.velocities) {
            *f = whole.f[i];
        }
    }

    fn symmetric(&self) -> bool {
        self.blocks
            .iter()
            .all(|b| is_symmetric(&self.m[b.at..b.at + b.size * b.size], b.size))
    }

    fn factorize(&mut self) -> Result<(), Error> {
        self.factors.copy_from_slice(&self.m);
        for b in &self.blocks {
            if !cholesky(&mut self.factors[b.at..b.at + b.size * b.size], b.size) {
                return Err(Error::NotPositiveDefinite { field: "M" });
            }
        }
        Ok(())
    }

    /// Takes the whole problem's current values (same pattern).
    pub(crate) fn take_values(
        &mut self,
        whole: &GlobalProblem,
        part: &Part,
        row_of: &[usize],
    ) -> Result<(), Error> {
        self.read(whole, part, row_of);
        let done = self.factorize();
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
        let (mv, x) = (&mut self.mv, &mut self.x);
        mv.fill(0.0);
        for b in &self.blocks {
            let velocities = &self.order[b.start..b.start + b.size];
            x.clear();
            x.extend(velocities.iter().map(|&k| self.f[k]));
            cholesky_solve(&self.factors[b.at..b.at + b.size * b.size], b.size, x);
            let block = &self.m[b.at..b.at + b.size * b.size];
            for (col, &k) in velocities.iter().enumerate() {
                self.v[k] = x[col];
                for (row, &l) in velocities.iter().enumerate() {
                    mv[l] += block[row + col * b.size] * x[col];
                }
            }
        }
        let terms = GlobalTerms {
            f: &self.f,
            mv,
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
