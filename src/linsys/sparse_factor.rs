//! Sparse factorization of a [`ParamMatrix`] with faer, reused across rho values (the LU
//! kind through [`Lu`]).

use super::lu::{Lu, LuFactors};
use super::param_matrix::{Assembly, ParamMatrix};
use crate::tuning::{FACTOR_CACHE, LDLT_PIVOT_MIN, LDLT_PIVOT_REPLACEMENT};
use crate::types::Error;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::LdltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LdltRef, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// Which factorization a matrix gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FactorKind {
    /// Symmetric positive definite: `L L^T` (upper triangle stored).
    Cholesky,
    /// Symmetric quasi-definite: `L D L^T` with the first `n_positive` pivots positive and
    /// the rest negative (upper triangle stored).
    QuasiDefinite {
        /// Number of leading positive pivots.
        n_positive: usize,
    },
    /// General square: `L U` with partial pivoting (full pattern stored).
    Lu,
}

enum Symbolic {
    Cholesky(SymbolicCholesky<usize>),
    Lu(Lu),
}

enum Numeric {
    Cholesky(Vec<f64>),
    Lu(LuFactors),
}

/// Factorization of `A(rho)`; `set_rho` refactorizes numerically (or reuses a cached factor),
/// `solve_in_place` solves without allocating.
pub struct SparseFactor {
    kind: FactorKind,
    name: &'static str,
    matrix: ParamMatrix,
    values: Vec<f64>,
    symbolic: Symbolic,
    signs: Vec<i8>,
    cache: Vec<(f64, Numeric)>,
    spare: Vec<Numeric>,
    mem: MemBuffer,
    probe: Vec<f64>,
    refactorizations: usize,
}

impl SparseFactor {
    /// Symbolic analysis of the pattern (AMD ordering for the symmetric kinds) and sizing
    /// of the workspace. `name` labels the matrix in errors.
    pub fn new(name: &'static str, matrix: ParamMatrix, kind: FactorKind) -> Result<Self, Error> {
        let n = matrix.n;
        let pattern =
            SymbolicSparseColMatRef::new_checked(n, n, &matrix.colptr, None, &matrix.rowind);
        let oom = |_| Error::OutOfMemory {
            what: format!("the symbolic analysis of {name}"),
        };
        let (symbolic, req) = match kind {
            FactorKind::Cholesky | FactorKind::QuasiDefinite { .. } => {
                let s = factorize_symbolic_cholesky(
                    pattern,
                    Side::Upper,
                    SymmetricOrdering::Amd,
                    CholeskySymbolicParams::default(),
                )
                .map_err(oom)?;
                let req = StackReq::any_of(&[
                    s.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
                    s.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()),
                    s.solve_in_place_scratch::<f64>(1, Par::Seq),
                ]);
                (Symbolic::Cholesky(s), req)
            }
            // The LU keeps its own workspace.
            FactorKind::Lu => (
                Symbolic::Lu(Lu::new(name, matrix.pattern())?),
                StackReq::EMPTY,
            ),
        };
        let signs = match kind {
            FactorKind::QuasiDefinite { n_positive } => (0..n)
                .map(|i| if i < n_positive { 1 } else { -1 })
                .collect(),
            _ => Vec::new(),
        };
        // Factor storage is made by the factorizations that need it (a system whose rho
        // never changes holds one factor, not the cache's worth) and recycled after.
        let spare = Vec::with_capacity(FACTOR_CACHE);
        Ok(Self {
            kind,
            name,
            values: vec![0.0; matrix.base.len()],
            matrix,
            symbolic,
            signs,
            cache: Vec::with_capacity(FACTOR_CACHE),
            spare,
            mem: MemBuffer::new(req),
            probe: vec![0.0; n],
            refactorizations: 0,
        })
    }

    /// Number of numeric factorizations done so far.
    pub fn refactorizations(&self) -> usize {
        self.refactorizations
    }

    /// Entries of a Cholesky factor, from the symbolic analysis; `None` for LU.
    pub fn stored_entries(&self) -> Option<usize> {
        match &self.symbolic {
            Symbolic::Cholesky(s) => Some(s.len_val()),
            Symbolic::Lu(_) => None,
        }
    }

    /// Multiply-adds of one numeric Cholesky factorization, from the symbolic analysis (the
    /// sum of its columns' squared counts); `None` for LU, whose fill depends on the pivots.
    pub fn factorization_flops(&self) -> Option<f64> {
        let Symbolic::Cholesky(s) = &self.symbolic else {
            return None;
        };
        let squared = |count: usize| (count * count) as f64;
        Some(match s.raw() {
            SymbolicCholeskyRaw::Simplicial(c) => {
                c.col_ptr().windows(2).map(|w| squared(w[1] - w[0])).sum()
            }
            SymbolicCholeskyRaw::Supernodal(c) => {
                let below = c.nnz_per_super();
                (0..c.n_supernodes())
                    .map(|k| {
                        let (b, e) = (c.supernode_begin()[k], c.supernode_end()[k]);
                        (b..e).map(|j| squared(e - j + below[k])).sum::<f64>()
                    })
                    .sum()
            }
        })
    }

    /// New values on the same pattern (see [`ParamMatrix::reassemble`]); drops every
    /// cached factor, so the next [`SparseFactor::set_rho`] refactorizes. No allocation.
    pub fn reassemble(
        &mut self,
        assembly: &Assembly,
        base: impl IntoIterator<Item = (usize, usize, f64)>,
        slope: impl IntoIterator<Item = (usize, usize, f64)>,
    ) {
        self.matrix.reassemble(assembly, base, slope);
        self.spare.extend(self.cache.drain(..).map(|(_, n)| n));
    }

    /// Makes `A(rho)` the current factor: a cached one when rho was used recently, a new
    /// numeric factorization otherwise.
    pub fn set_rho(&mut self, rho: f64) -> Result<(), Error> {
        // The values that `mul_vec` reads follow rho whether or not the factor is cached
        // (joint refinement multiplies by them).
        self.matrix.values_at(rho, &mut self.values);
        if self.reuse_cached(rho) {
            return Ok(());
        }
        let recycled = self.recycled_storage();
        let numeric = self.factorize_numeric(recycled)?;
        self.refactorizations += 1;
        self.cache.push((rho, numeric));
        if self.kind == FactorKind::Lu {
            self.reject_singular_lu()?;
        }
        Ok(())
    }

    /// Makes the cached factor of `rho`, if any, the current (most recent) one.
    fn reuse_cached(&mut self, rho: f64) -> bool {
        match self.cache.iter().position(|(r, _)| *r == rho) {
            Some(pos) => {
                let entry = self.cache.remove(pos);
                self.cache.push(entry);
                true
            }
            None => false,
        }
    }

    /// Storage for the next numeric factor.
    fn recycled_storage(&mut self) -> Option<Numeric> {
        // Storage from the pool made at construction, or that of the oldest cached factor:
        // a change of rho inside the iteration does not allocate factor storage.
        match self.spare.pop() {
            Some(n) => Some(n),
            None if self.cache.len() == FACTOR_CACHE => Some(self.cache.remove(0).1),
            None => None,
        }
    }

    /// Numeric factorization of the current values, into `recycled` when it has the
    /// right kind.
    fn factorize_numeric(&mut self, recycled: Option<Numeric>) -> Result<Numeric, Error> {
        let pattern = self.matrix.pattern();
        let (symbolic, name) = (&mut self.symbolic, self.name);
        let s = match symbolic {
            Symbolic::Lu(lu) => {
                let mut factors = match recycled {
                    Some(Numeric::Lu(f)) => f,
                    _ => lu.factors(),
                };
                if !lu.factorize(pattern, &self.values, &mut factors) {
                    return Err(Error::Singular { field: name });
                }
                return Ok(Numeric::Lu(factors));
            }
            Symbolic::Cholesky(s) => s,
        };
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(
                pattern.n,
                pattern.n,
                pattern.colptr,
                None,
                pattern.rowind,
            ),
            &self.values,
        );
        let stack = MemStack::new(&mut self.mem);
        match self.kind {
            FactorKind::Cholesky => factorize_llt(s, a, stack, recycled, name),
            FactorKind::QuasiDefinite { .. } => {
                factorize_ldlt(s, a, stack, recycled, &self.signs, name)
            }
            FactorKind::Lu => unreachable!("symbolic kind matches factor kind by construction"),
        }
    }

    /// Drops the current factor (back to the pool) and fails when it is singular.
    fn reject_singular_lu(&mut self) -> Result<(), Error> {
        // Partial pivoting does not report an exactly singular matrix: a zero pivot
        // shows up as a non-finite solution, so probe once per factorization.
        let mut probe = std::mem::take(&mut self.probe);
        probe.fill(1.0);
        self.solve_in_place(&mut probe);
        let singular = !probe.iter().all(|v| v.is_finite());
        self.probe = probe;
        if singular {
            if let Some((_, n)) = self.cache.pop() {
                self.spare.push(n);
            }
            return Err(Error::Singular { field: self.name });
        }
        Ok(())
    }

    /// Solves `A(rho) x = rhs` in place with the current factor (no heap allocation).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let n = self.matrix.n;
        let (_, numeric) = self
            .cache
            .last()
            .expect("set_rho is called before solve_in_place");
        let stack = MemStack::new(&mut self.mem);
        match (&mut self.symbolic, numeric) {
            (Symbolic::Cholesky(s), Numeric::Cholesky(l)) => {
                let rhs = MatMut::from_column_major_slice_mut(rhs, n, 1);
                match self.kind {
                    FactorKind::Cholesky => {
                        LltRef::new(s, l).solve_in_place_with_conj(Conj::No, rhs, Par::Seq, stack)
                    }
                    _ => {
                        LdltRef::new(s, l).solve_in_place_with_conj(Conj::No, rhs, Par::Seq, stack)
                    }
                }
            }
            (Symbolic::Lu(lu), Numeric::Lu(factors)) => lu.solve_in_place(factors, rhs),
            _ => unreachable!("numeric kind matches symbolic kind by construction"),
        }
    }

    /// `y = A(rho) x` for the current rho (for iterative refinement), full matrix product
    /// even when only the upper triangle is stored.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        self.matrix
            .mul_vec(&self.values, self.kind != FactorKind::Lu, x, y);
    }
}

/// Reuses `recycled` as factor storage when it is a Cholesky one, else allocates.
fn cholesky_storage(s: &SymbolicCholesky<usize>, recycled: Option<Numeric>) -> Vec<f64> {
    match recycled {
        Some(Numeric::Cholesky(v)) => v,
        _ => vec![0.0; s.len_val()],
    }
}

/// `L L^T` of a positive definite `a`.
fn factorize_llt(
    s: &SymbolicCholesky<usize>,
    a: SparseColMatRef<'_, usize, f64>,
    stack: &mut MemStack,
    recycled: Option<Numeric>,
    name: &'static str,
) -> Result<Numeric, Error> {
    let mut l = cholesky_storage(s, recycled);
    s.factorize_numeric_llt(
        &mut l,
        a,
        Side::Upper,
        Default::default(),
        Par::Seq,
        stack,
        Default::default(),
    )
    .map_err(|_| Error::NotPositiveDefinite { field: name })?;
    Ok(Numeric::Cholesky(l))
}

/// `L D L^T` of a quasi-definite `a`; `signs` are the expected pivot signs, which the
/// dynamic regularization enforces.
fn factorize_ldlt(
    s: &SymbolicCholesky<usize>,
    a: SparseColMatRef<'_, usize, f64>,
    stack: &mut MemStack,
    recycled: Option<Numeric>,
    signs: &[i8],
    name: &'static str,
) -> Result<Numeric, Error> {
    let mut l = cholesky_storage(s, recycled);
    let reg = LdltRegularization {
        dynamic_regularization_signs: Some(signs),
        dynamic_regularization_delta: LDLT_PIVOT_REPLACEMENT,
        dynamic_regularization_epsilon: LDLT_PIVOT_MIN,
    };
    s.factorize_numeric_ldlt(
        &mut l,
        a,
        Side::Upper,
        reg,
        Par::Seq,
        stack,
        Default::default(),
    )
    .map_err(|_| Error::NotPositiveDefinite { field: name })?;
    Ok(Numeric::Cholesky(l))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric matrix of `n` unknowns with `entry(i, j)` for `i != j` where it returns
    /// a value (both triangles), diagonally dominant.
    fn factor_of(n: usize, entry: impl Fn(usize, usize) -> Option<f64>) -> SparseFactor {
        let triplets: Vec<_> = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .filter_map(|(i, j)| match i == j {
                true => Some((i, i, 2.0 * n as f64)),
                false => entry(i, j).map(|v| (i, j, v)),
            })
            .collect();
        let (matrix, _) = ParamMatrix::from_triplets(n, triplets, [], true);
        SparseFactor::new("test", matrix, FactorKind::Cholesky).unwrap()
    }

    /// The predicted multiply-adds are the factor's squared column counts summed, counted
    /// here by hand: a tridiagonal matrix keeps its pattern (columns of 2, the last of 1)
    /// whatever the ordering, and a full one fills its whole lower triangle (columns of
    /// `n` down to 1). The two take faer's simplicial and supernodal analyses (whose
    /// stored entries count whole diagonal blocks, so only the first one's are checked).
    #[test]
    fn factorization_flops_count_the_factor_columns() {
        let n = 300;
        let tri = factor_of(n, |i, j| (i.abs_diff(j) == 1).then_some(-1.0));
        assert_eq!(tri.stored_entries(), Some(2 * n - 1));
        assert_eq!(tri.factorization_flops(), Some((4 * (n - 1) + 1) as f64));
        let n = 200;
        let full = factor_of(n, |i, j| Some(1.0 / (1 + i + j) as f64));
        let squares: usize = (1..=n).map(|k| k * k).sum();
        assert_eq!(full.factorization_flops(), Some(squares as f64));
        let kinds = [&tri, &full].map(|f| match &f.symbolic {
            Symbolic::Cholesky(s) => matches!(s.raw(), SymbolicCholeskyRaw::Supernodal(_)),
            Symbolic::Lu(_) => unreachable!("Cholesky asked"),
        });
        assert_eq!(kinds, [false, true], "one analysis of each kind");
    }
}
