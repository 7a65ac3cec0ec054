//! A square sparse matrix affine in a parameter: `A(rho) = base + rho * slope`.

use crate::csc::CscMatrix;

/// Square matrix `base + rho * slope` on one sparsity pattern (compressed columns,
/// sorted rows). Symmetric matrices keep their upper triangle only.
#[derive(Debug, Clone)]
pub struct ParamMatrix {
    /// Dimension.
    pub n: usize,
    /// Column pointers of the pattern.
    pub colptr: Vec<usize>,
    /// Row indices of the pattern.
    pub rowind: Vec<usize>,
    /// Values at `rho = 0`.
    pub base: Vec<f64>,
    /// Coefficients of `rho`.
    pub slope: Vec<f64>,
}

impl ParamMatrix {
    /// Builds the pattern union of two triplet lists; with `upper_only`, entries below the
    /// diagonal are dropped (the caller passes both triangles of a symmetric matrix).
    pub fn from_triplets(
        n: usize,
        base: impl IntoIterator<Item = (usize, usize, f64)>,
        slope: impl IntoIterator<Item = (usize, usize, f64)>,
        upper_only: bool,
    ) -> Self {
        let mut all: Vec<(usize, usize, f64, f64)> = base
            .into_iter()
            .map(|(i, j, v)| (i, j, v, 0.0))
            .chain(slope.into_iter().map(|(i, j, v)| (i, j, 0.0, v)))
            .filter(|e| !upper_only || e.0 <= e.1)
            .collect();
        // Every diagonal entry is in the pattern, so refactorizations never lose it.
        all.extend((0..n).map(|i| (i, i, 0.0, 0.0)));
        all.sort_by_key(|e| (e.1, e.0));
        let mut colptr = vec![0usize; n + 1];
        let (mut rowind, mut b, mut s) = (Vec::new(), Vec::new(), Vec::<f64>::new());
        let mut last = None;
        for (i, j, vb, vs) in all {
            if last == Some((i, j)) {
                *b.last_mut().expect("entry exists") += vb;
                *s.last_mut().expect("entry exists") += vs;
                continue;
            }
            last = Some((i, j));
            rowind.push(i);
            b.push(vb);
            s.push(vs);
            colptr[j + 1] += 1;
        }
        for j in 0..n {
            colptr[j + 1] += colptr[j];
        }
        Self {
            n,
            colptr,
            rowind,
            base: b,
            slope: s,
        }
    }

    /// Values of `A(rho)` into `out`.
    pub fn values_at(&self, rho: f64, out: &mut [f64]) {
        for ((o, b), s) in out.iter_mut().zip(&self.base).zip(&self.slope) {
            *o = b + rho * s;
        }
    }
}

/// Triplets of a matrix (both triangles as stored).
pub fn triplets(a: &CscMatrix) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
    (0..a.ncols()).flat_map(move |j| a.col(j).map(move |(i, v)| (i, j, v)))
}

/// Triplets of `H H^T` (`H` is `n x m`), accumulated column by column of `H`.
pub fn gram_triplets(h: &CscMatrix) -> Vec<(usize, usize, f64)> {
    let mut t = Vec::new();
    for k in 0..h.ncols() {
        for (i, vi) in h.col(k) {
            for (j, vj) in h.col(k) {
                t.push((i, j, vi * vj));
            }
        }
    }
    t
}
