//! The answer of a solve.

/// A solution of either form. `v` and `lambda` are empty for a local problem.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Solution {
    /// Contact impulses (`3 nc`).
    pub r: Vec<f64>,
    /// Local relative velocities (`3 nc`).
    pub u: Vec<f64>,
    /// Generalized velocities (`n`, global form only).
    pub v: Vec<f64>,
    /// Joint multipliers (global form with joints only).
    pub lambda: Vec<f64>,
}

impl Solution {
    /// Zeros of the given lengths (`3 nc` contact rows, `n` velocities, `np` joint
    /// multipliers), reusing the vectors' memory.
    pub(crate) fn zeroed(&mut self, rows: usize, n: usize, np: usize) {
        for (x, len) in [
            (&mut self.r, rows),
            (&mut self.u, rows),
            (&mut self.v, n),
            (&mut self.lambda, np),
        ] {
            x.clear();
            x.resize(len, 0.0);
        }
    }
}
