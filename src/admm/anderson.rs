//! Type-II Anderson acceleration AA(m) of a fixed-point map `x -> g(x)` (docs/algorithms.md §7).
//!
//! With `f = g(x) - x`, the last `m` differences `dF`, `dG` of residuals and images give
//! `gamma = argmin ||f_k - dF gamma||` and the next point `x = g_k - dG gamma`. The small
//! least-squares problem is solved through its Tikhonov-regularized normal equations, whose
//! Gram matrix is updated one column at a time. Nothing is allocated after construction.

use crate::csc::dot;
use crate::dense::gauss_solve;
use crate::tuning::ANDERSON_REGULARIZATION;

/// Anderson acceleration state for vectors of a fixed dimension.
pub struct Anderson {
    memory: usize,
    dim: usize,
    df: Vec<f64>, // memory columns of length dim, ring buffer
    dg: Vec<f64>,
    gram: Vec<f64>, // memory x memory, gram[i*memory + j] = <df_i, df_j>
    len: usize,
    head: usize, // index of the oldest column when full
    f_prev: Vec<f64>,
    g_prev: Vec<f64>,
    has_prev: bool,
    rhs: Vec<f64>,
    sys: Vec<f64>,
    gamma: Vec<f64>,
}

impl Anderson {
    /// AA(`memory`) for vectors of length `dim`.
    pub fn new(memory: usize, dim: usize) -> Self {
        Self {
            memory,
            dim,
            df: vec![0.0; memory * dim],
            dg: vec![0.0; memory * dim],
            gram: vec![0.0; memory * memory],
            len: 0,
            head: 0,
            f_prev: vec![0.0; dim],
            g_prev: vec![0.0; dim],
            has_prev: false,
            rhs: vec![0.0; memory],
            sys: vec![0.0; memory * memory],
            gamma: vec![0.0; memory],
        }
    }

    /// Forgets the history (after a rho change or a rejected step).
    pub fn reset(&mut self) {
        self.len = 0;
        self.head = 0;
        self.has_prev = false;
    }

    /// Records the pair `(x, g = g(x))` and writes the accelerated next point into `out`.
    /// Returns false (and leaves `out` = `g`) when there is no history yet or the
    /// least-squares system is degenerate.
    pub fn step(&mut self, x: &[f64], g: &[f64], out: &mut [f64]) -> bool {
        self.step_across(x, g, out, &|_| {})
    }

    /// [`Anderson::step`] for vectors shared out among processes, each holding its part:
    /// `sum` adds up partial sums across them (in place), so that every process solves
    /// the same least-squares problem.
    pub fn step_across(
        &mut self,
        x: &[f64],
        g: &[f64],
        out: &mut [f64],
        sum: &dyn Fn(&mut [f64]),
    ) -> bool {
        debug_assert_eq!(x.len(), self.dim);
        out.copy_from_slice(g);
        if self.memory == 0 {
            return false;
        }
        if self.has_prev {
            self.push_difference(x, g, sum);
        }
        for i in 0..self.dim {
            self.f_prev[i] = g[i] - x[i];
            self.g_prev[i] = g[i];
        }
        self.has_prev = true;
        if self.len == 0 || !self.solve_for_gamma(sum) {
            return false;
        }
        for a in 0..self.len {
            let ca = (self.head + a) % self.memory;
            let gma = self.gamma[a];
            let dga = &self.dg[ca * self.dim..(ca + 1) * self.dim];
            for (o, d) in out.iter_mut().zip(dga) {
                *o -= gma * d;
            }
        }
        let mut non_finite = [f64::from(u8::from(!out.iter().all(|v| v.is_finite())))];
        sum(&mut non_finite);
        non_finite[0] == 0.0
    }

    /// Adds the column `df = f - f_prev`, `dg = g - g_prev` (over the oldest one when the
    /// memory is full) and its inner products with the live columns to the Gram matrix.
    fn push_difference(&mut self, x: &[f64], g: &[f64], sum: &dyn Fn(&mut [f64])) {
        let m = self.memory;
        let col = if self.len < m {
            self.len += 1;
            (self.head + self.len - 1) % m
        } else {
            let c = self.head;
            self.head = (self.head + 1) % m;
            c
        };
        let (dfc, dgc) = (
            &mut self.df[col * self.dim..(col + 1) * self.dim],
            &mut self.dg[col * self.dim..(col + 1) * self.dim],
        );
        for i in 0..self.dim {
            let f = g[i] - x[i];
            dfc[i] = f - self.f_prev[i];
            dgc[i] = g[i] - self.g_prev[i];
        }
        for j in 0..m {
            self.rhs[j] = if self.is_live(j) {
                dot_cols(&self.df, self.dim, col, j)
            } else {
                0.0
            };
        }
        sum(&mut self.rhs);
        for j in 0..m {
            if self.is_live(j) {
                self.gram[col * m + j] = self.rhs[j];
                self.gram[j * m + col] = self.rhs[j];
            }
        }
    }

    /// `gamma = argmin ||f - dF gamma||` over the live columns, in ring order, through the
    /// regularized normal equations; false when they are degenerate.
    fn solve_for_gamma(&mut self, sum: &dyn Fn(&mut [f64])) -> bool {
        let (k, m) = (self.len, self.memory);
        let mut trace = 0.0;
        for a in 0..k {
            let ca = (self.head + a) % m;
            let dfa = &self.df[ca * self.dim..(ca + 1) * self.dim];
            self.rhs[a] = dot(dfa, &self.f_prev);
            for b in 0..k {
                let cb = (self.head + b) % m;
                self.sys[a * k + b] = self.gram[ca * m + cb];
            }
            trace += self.sys[a * k + a];
        }
        sum(&mut self.rhs[..k]);
        if !(trace > 0.0 && trace.is_finite()) {
            return false;
        }
        let reg = ANDERSON_REGULARIZATION * trace / k as f64;
        for a in 0..k {
            self.sys[a * k + a] += reg;
        }
        gauss_solve(
            &mut self.sys[..k * k],
            &mut self.rhs[..k],
            &mut self.gamma[..k],
        )
    }

    fn is_live(&self, col: usize) -> bool {
        let m = self.memory;
        (col + m - self.head) % m < self.len
    }
}

fn dot_cols(buf: &[f64], dim: usize, a: usize, b: usize) -> f64 {
    dot(&buf[a * dim..(a + 1) * dim], &buf[b * dim..(b + 1) * dim])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a linear contraction `g(x) = A x + b`, AA(m) with m >= dim converges in a few steps.
    #[test]
    fn accelerates_a_linear_map() {
        let a = [[0.9, 0.05], [0.0, 0.8]];
        let b = [1.0, -2.0];
        let g = |x: &[f64]| {
            [
                a[0][0] * x[0] + a[0][1] * x[1] + b[0],
                a[1][0] * x[0] + a[1][1] * x[1] + b[1],
            ]
        };
        // Fixed point solves (I - A) x = b.
        let x2 = b[1] / (1.0 - a[1][1]);
        let x1 = (b[0] + a[0][1] * x2) / (1.0 - a[0][0]);
        let mut aa = Anderson::new(2, 2);
        let mut x = [0.0, 0.0];
        let mut next = [0.0, 0.0];
        for _ in 0..6 {
            let gx = g(&x);
            aa.step(&x, &gx, &mut next);
            x = next;
        }
        assert!(
            (x[0] - x1).abs() < 1e-8 && (x[1] - x2).abs() < 1e-8,
            "{x:?} vs {x1} {x2}"
        );
    }
}
