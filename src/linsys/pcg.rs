//! The iterative backend of the global v-update: preconditioned conjugate gradients on
//! `A(rho) = M + rho H D H^T` (D: the active contact rows), applied as products with M and
//! H and never formed. A factor of a large pile's system fills in far beyond `H` (and its
//! memory grows with it), while a product costs `nnz(M) + 2 nnz(H)`.
//!
//! The preconditioner is block Jacobi per body: the blocks are the connected components of
//! M's graph (a rigid body's 6 velocities), each block `M_BB + rho (H D H^T)_BB` factorized
//! densely at each new rho. Components larger than [`BLOCK_MAX`] (a finite-element mesh's
//! M) fall back to their diagonal.

use super::block_diagonal::BlockDiagonal;
use super::contact_columns::ContactColumns;
use super::workers::Workers;
use crate::csc::{dot, CscMatrix, RowMajor};
use crate::tuning::{BLOCK_MAX, PARALLEL_MIN_ENTRIES, PCG_TRUE_RESIDUAL_EVERY};
use crate::types::Error;
use std::time::Instant;

/// The operator's data: `M`, `H` and the active contact rows `D` (1 or 0 each).
#[derive(Clone, Copy)]
pub struct Gram<'a> {
    /// The mass matrix (symmetric).
    pub m: &'a CscMatrix,
    /// The contact Jacobian.
    pub h: &'a CscMatrix,
    /// Which contact rows take part.
    pub active: &'a [f64],
}

/// When a solve stops: at `||b - A x|| <= max(floor, tol, reduction * r0)`, `r0` the
/// residual of the starting point, or after `max_iterations`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgStop {
    /// Residual that is good enough whatever the start.
    pub tol: f64,
    /// Factor by which the starting residual must shrink (1 for none).
    pub reduction: f64,
    /// Residual below which no solve is asked to go (round-off).
    pub floor: f64,
    /// Iteration limit.
    pub max_iterations: usize,
    /// Wall-clock limit: the solve stops there, inexact (a time limit the caller checks
    /// again after the step, so that a long solve does not overrun it).
    pub deadline: Option<Instant>,
}

/// How one solve ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgOutcome {
    /// Conjugate-gradient iterations done.
    pub iterations: usize,
    /// `||b - A x||` at the end.
    pub residual: f64,
    /// The residual reached the asked tolerance.
    pub converged: bool,
}

/// Preconditioned conjugate gradients on `M + rho H D H^T`, with its block-Jacobi
/// preconditioner and work vectors (a solve does not allocate).
pub struct GramPcg {
    /// The blocks `(M_BB + M_BB^T) / 2` and the inverses of `M_BB + rho (H D H^T)_BB` (an
    /// inverse, because applying it is one small product where a factor takes two
    /// triangular solves, at every iteration).
    blocks: BlockDiagonal,
    /// The blocks `(H D H^T)_BB`, laid out as those of M.
    gram: Vec<f64>,
    rho: f64,
    work: CgWork,
    /// The last solve's right-hand side and answer: while the operator stays, the next
    /// solve's starting residual is `r + b_next - b` (the recurrence's residual), which
    /// saves a product.
    last_b: Vec<f64>,
    last_x: Vec<f64>,
    /// Solves left that may start from the recurrence's residual (0: compute it): reset by
    /// a new operator, and every [`PCG_TRUE_RESIDUAL_EVERY`] solves so that round-off does
    /// not pile up in it.
    recurrences_left: usize,
    /// H contact by contact and M by rows, for the products `M p + rho H D H^T p`.
    h: ContactColumns,
    m_rows: RowMajor,
    /// Threads the products run on (their results do not depend on them).
    workers: Workers,
    /// Conjugate-gradient iterations over every solve.
    iterations: usize,
}

impl GramPcg {
    /// Finds the blocks in M's pattern and takes the values of `M`, `H` and `active`.
    pub fn new(a: Gram) -> Self {
        let n = a.m.ncols();
        let (blocks, _) = BlockDiagonal::components_of(a.m, BLOCK_MAX);
        let mut pcg = Self {
            gram: vec![0.0; blocks.entries()],
            blocks,
            rho: f64::NAN,
            work: CgWork::new(n),
            last_b: vec![0.0; n],
            last_x: vec![0.0; n],
            recurrences_left: 0,
            h: ContactColumns::new(a.h),
            m_rows: RowMajor::new(a.m),
            workers: Workers::serial(),
            iterations: 0,
        };
        pcg.take_values(a);
        pcg
    }

    /// Whether `a` can be solved so: a symmetric M, H with three columns per contact,
    /// indices that fit the 32-bit storage.
    pub fn fits(a: Gram) -> bool {
        a.m.is_symmetric() && RowMajor::fits(a.m) && ContactColumns::fits(a.h)
    }

    /// `y += H t` (products outside the solve, with its storage of H and its threads).
    pub fn h_mul_add(&mut self, t: &[f64], y: &mut [f64]) {
        self.h.mul_add(t, y, &self.workers);
    }

    /// `out = H^T x`.
    pub fn h_t_mul(&self, x: &[f64], out: &mut [f64]) {
        self.h.mul_t(x, out, &self.workers);
    }

    /// Conjugate-gradient iterations over every solve so far.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Numeric factorizations of the preconditioner so far.
    pub fn factorizations(&self) -> usize {
        self.blocks.refactorizations()
    }

    /// Takes new values of M, H and the active rows on the same patterns (no allocation);
    /// the next [`GramPcg::set_rho`] refactorizes the blocks.
    pub fn take_values(&mut self, Gram { m, h, active }: Gram) {
        self.h.take_values(h);
        self.m_rows.take_values(m);
        self.blocks.take_symmetric_part(m);
        self.gram.fill(0.0);
        for c in 0..h.ncols() {
            if active[c] == 0.0 {
                continue;
            }
            for (i, a) in h.col(c) {
                for (j, b) in h.col(c) {
                    if let Some(at) = self.blocks.slot(i, j) {
                        self.gram[at] += a * b;
                    }
                }
            }
        }
        self.rho = f64::NAN;
        self.recurrences_left = 0;
    }

    /// Factorizes the blocks of `M + rho H D H^T`; a block that is not positive definite is
    /// an error naming the system.
    pub fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        if rho == self.rho {
            return Ok(());
        }
        if self.blocks.invert(rho, &self.gram).is_err() {
            self.rho = f64::NAN;
            return Err(Error::NotPositiveDefinite {
                field: "M + rho H H^T",
            });
        }
        self.rho = rho;
        self.recurrences_left = 0;
        Ok(())
    }

    /// Threads for the products of systems with at least [`PARALLEL_MIN_ENTRIES`] entries in
    /// `M` and `H` (below, handing work to other threads costs more than it saves).
    pub fn set_threads(&mut self, threads: usize) {
        let big = self.h.entries() + self.m_rows.entries() >= PARALLEL_MIN_ENTRIES;
        let threads = if big { threads.max(1) } else { 1 };
        if threads != self.workers.count() {
            self.workers = Workers::new(threads);
        }
    }

    /// `y = (M + rho H D H^T) x` at the rho of the last [`GramPcg::set_rho`]: `M x` by rows
    /// of M beside `rho H D H^T x` in one pass over H. Each entry is summed in one order
    /// whatever the threads.
    pub fn apply(&mut self, Gram { active, .. }: Gram, x: &[f64], y: &mut [f64]) {
        let m_rows = &self.m_rows;
        let mass = |first: usize, part: &mut [f64]| {
            for (k, yi) in part.iter_mut().enumerate() {
                *yi = m_rows.row_dot(first + k, x);
            }
        };
        self.h.gram(x, active, self.rho, y, &self.workers, mass);
    }

    /// `z = P^-1 r`, block by block (on the threads when the blocks are the velocities in
    /// order, so that each thread writes one slice of `z`).
    fn precondition(&self, r: &[f64], z: &mut [f64]) {
        let blocks = &self.blocks;
        let count = blocks.block_count();
        let threads = self.workers.count();
        if !blocks.in_order() || threads == 1 {
            return blocks.mul_inverse(0..count, r, z);
        }
        let per = count.div_ceil(threads);
        let parts = (0..count).step_by(per).scan(z, |rest, first| {
            let range = first..(first + per).min(count);
            let len = blocks.unknowns_before(range.end) - blocks.unknowns_before(range.start);
            let (part, tail) = std::mem::take(rest).split_at_mut(len);
            *rest = tail;
            Some((range, part))
        });
        self.workers
            .run(parts, |(range, part)| blocks.mul_inverse(range, r, part));
    }

    /// Solves `A(rho) x = b` from the `x` given (a warm start) until `stop` says (see
    /// [`conjugate_gradients`]).
    pub fn solve(&mut self, a: Gram, b: &[f64], x: &mut [f64], stop: PcgStop) -> PcgOutcome {
        let mut work = std::mem::take(&mut self.work);
        if self.recurrences_left > 0 && x == self.last_x.as_slice() {
            // b - A x = (b - b_last) + (b_last - A x_last).
            self.recurrences_left -= 1;
            for i in 0..work.r.len() {
                work.r[i] += b[i] - self.last_b[i];
            }
        } else {
            self.recurrences_left = PCG_TRUE_RESIDUAL_EVERY;
            work.start(&mut Bound { pcg: self, a }, b, x);
        }
        let out = conjugate_gradients(&mut Bound { pcg: self, a }, x, &mut work, &stop);
        self.iterations += out.iterations;
        self.last_b.copy_from_slice(b);
        self.last_x.copy_from_slice(x);
        if !out.residual.is_finite() {
            self.recurrences_left = 0;
        }
        self.work = work;
        out
    }
}

/// What conjugate gradients need of a symmetric positive definite system: its product,
/// its preconditioner and the dot product of its space (summed over every process that
/// holds a part of the vectors, for a distributed system).
pub(crate) trait CgSystem {
    /// `y = A x`.
    fn apply(&mut self, x: &[f64], y: &mut [f64]);
    /// `z = P^-1 r`.
    fn precondition(&self, r: &[f64], z: &mut [f64]);
    /// `a . b`.
    fn dot(&self, a: &[f64], b: &[f64]) -> f64;
    /// Whether the clock is past `deadline` (for every process sharing the system, when
    /// the system is distributed: they all stop at the same iteration).
    fn past(&self, deadline: Instant) -> bool {
        Instant::now() >= deadline
    }
}

/// The vectors of a conjugate-gradient solve, made once per system (a solve does not
/// allocate); `r` holds `b - A x` of the start.
#[derive(Default)]
pub(crate) struct CgWork {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
}

impl CgWork {
    /// Vectors of length `n`.
    pub fn new(n: usize) -> Self {
        Self {
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            q: vec![0.0; n],
        }
    }

    /// `r = b - A x`, by one product.
    pub fn start(&mut self, system: &mut impl CgSystem, b: &[f64], x: &[f64]) {
        system.apply(x, &mut self.q);
        for i in 0..self.r.len() {
            self.r[i] = b[i] - self.q[i];
        }
    }
}

/// Preconditioned conjugate gradients on `system` from `x`, whose residual `work.r`
/// holds, until `stop` says. A breakdown (a non-positive or non-finite curvature, which
/// round-off alone can cause on a positive definite system) leaves `x` non-finite, so
/// that the caller's finiteness check ends the solve with a status.
pub(crate) fn conjugate_gradients(
    system: &mut impl CgSystem,
    x: &mut [f64],
    work: &mut CgWork,
    stop: &PcgStop,
) -> PcgOutcome {
    let CgWork { r, z, p, q } = work;
    let (r, z, p, q) = (&mut r[..], &mut z[..], &mut p[..], &mut q[..]);
    let mut out = PcgOutcome {
        iterations: 0,
        residual: system.dot(r, r).sqrt(),
        converged: false,
    };
    let tol = stop.tol.max(stop.reduction * out.residual).max(stop.floor);
    if out.residual > tol {
        system.precondition(r, z);
        p.copy_from_slice(z);
        let mut rz = system.dot(r, z);
        while out.iterations < stop.max_iterations {
            system.apply(p, q);
            let curvature = system.dot(p, q);
            if !(curvature > 0.0 && curvature.is_finite()) {
                x.fill(f64::NAN);
                out.residual = f64::NAN;
                break;
            }
            let alpha = rz / curvature;
            for i in 0..x.len() {
                x[i] += alpha * p[i];
                r[i] -= alpha * q[i];
            }
            out.iterations += 1;
            out.residual = system.dot(r, r).sqrt();
            if out.residual <= tol || stop.deadline.is_some_and(|d| system.past(d)) {
                break;
            }
            system.precondition(r, z);
            let rz_next = system.dot(r, z);
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..p.len() {
                p[i] = z[i] + beta * p[i];
            }
        }
    }
    out.converged = out.residual <= tol;
    out
}

/// The one-process operator `M + rho H D H^T` with its data.
struct Bound<'a, 'b> {
    pcg: &'a mut GramPcg,
    a: Gram<'b>,
}

impl CgSystem for Bound<'_, '_> {
    fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        self.pcg.apply(self.a, x, y);
    }
    fn precondition(&self, r: &[f64], z: &mut [f64]) {
        self.pcg.precondition(r, z);
    }
    fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        dot(a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// Two 2x2 bodies and a 1x1 one, three contact rows (one inactive).
    fn system() -> (CscMatrix, CscMatrix, Vec<f64>) {
        #[rustfmt::skip]
        let m = CscMatrix::from_dense("M", 5, 5, &[
            2.0, 0.3, 0.0, 0.0, 0.0,
            0.3, 1.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 4.0, -1.0, 0.0,
            0.0, 0.0, -1.0, 3.0, 0.0,
            0.0, 0.0, 0.0, 0.0, 0.5,
        ]).unwrap();
        #[rustfmt::skip]
        let h = CscMatrix::from_dense("H", 5, 3, &[
            1.0, 0.0, 0.2,
            0.5, 1.0, 0.0,
            -1.0, 0.0, 0.7,
            0.0, 0.4, 0.0,
            0.0, -0.3, 1.0,
        ]).unwrap();
        (m, h, vec![1.0, 0.0, 1.0])
    }

    #[test]
    fn blocks_are_the_components_of_m() {
        let (m, _, _) = system();
        let (blocks, split) = BlockDiagonal::components_of(&m, BLOCK_MAX);
        assert!(!split && blocks.in_order());
        let sizes: Vec<usize> = (0..blocks.block_count())
            .map(|b| blocks.block(b).len())
            .collect();
        assert_eq!(sizes, [2, 2, 1]);
    }

    /// The solve against a dense LU solve of the formed matrix.
    #[test]
    fn solves_the_formed_system() {
        let (m, h, active) = system();
        let rho = 3.0;
        let md = DMatrix::from_column_slice(5, 5, &m.to_dense());
        let hd = DMatrix::from_column_slice(5, 3, &h.to_dense());
        let d = DMatrix::from_diagonal(&DVector::from_column_slice(&active));
        let a = md + rho * &hd * d * hd.transpose();
        let b = [1.0, -2.0, 0.5, 3.0, -1.0];
        let reference = a.lu().solve(&DVector::from_column_slice(&b)).unwrap();
        let gram = Gram {
            m: &m,
            h: &h,
            active: &active,
        };
        let mut pcg = GramPcg::new(gram);
        pcg.set_rho(rho).unwrap();
        let mut x = vec![0.0; 5];
        let stop = PcgStop {
            tol: 1e-12,
            reduction: 0.0,
            floor: 0.0,
            max_iterations: 50,
            deadline: None,
        };
        let out = pcg.solve(gram, &b, &mut x, stop);
        assert!(out.converged, "{out:?}");
        assert!(
            out.iterations <= 5,
            "CG in exact arithmetic: at most n steps"
        );
        for (a, b) in x.iter().zip(reference.iter()) {
            assert!((a - b).abs() <= 1e-10 * b.abs().max(1.0), "{a} vs {b}");
        }
        // Warm started at the answer: no iteration.
        let again = pcg.solve(gram, &b, &mut x, PcgStop { tol: 1e-10, ..stop });
        assert_eq!(again.iterations, 0);
        // A passed deadline stops the solve after one iteration, unconverged.
        let mut x = vec![0.0; 5];
        let past = Some(Instant::now());
        let cut = pcg.solve(
            gram,
            &b,
            &mut x,
            PcgStop {
                deadline: past,
                ..stop
            },
        );
        assert_eq!((cut.iterations, cut.converged), (1, false), "{cut:?}");
    }

    #[test]
    fn indefinite_block_is_an_error() {
        let (_, h, active) = system();
        let m = CscMatrix::from_dense("M", 5, 5, &{
            let mut d = [0.0; 25];
            for i in 0..5 {
                d[i * 6] = if i == 4 { -1.0 } else { 1.0 };
            }
            d
        })
        .unwrap();
        let mut pcg = GramPcg::new(Gram {
            m: &m,
            h: &h,
            active: &active,
        });
        assert!(matches!(
            pcg.set_rho(1.0),
            Err(Error::NotPositiveDefinite { .. })
        ));
    }
}
