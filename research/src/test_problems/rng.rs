//! Deterministic random data for the test problems: the same seed gives the same problem on
//! every platform, without a dependency.

use nalgebra::DMatrix;

/// SplitMix64: a 64-bit state, full period, good enough statistics for test data.
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
    spare_normal: Option<f64>,
}

impl Rng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            state: seed,
            spare_normal: None,
        }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform on `[0, 1)` with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform integer in `0..n` (`n > 0`); the modulo bias is below 2^-40 for our sizes.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Standard normal (Box-Muller, both values used).
    pub fn normal(&mut self) -> f64 {
        if let Some(v) = self.spare_normal.take() {
            return v;
        }
        // 1 - u lies in (0, 1], so the logarithm is finite.
        let r = (-2.0 * (1.0 - self.uniform()).ln()).sqrt();
        let t = 2.0 * std::f64::consts::PI * self.uniform();
        self.spare_normal = Some(r * t.sin());
        r * t.cos()
    }

    /// A vector of `n` standard normals.
    pub fn normal_vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.normal()).collect()
    }

    /// A `rows x cols` matrix with exactly `round(density * rows * cols)` nonzeros at distinct
    /// random positions (the convention of `scipy.sparse.random` used by seed 001), each drawn
    /// by `value`.
    pub fn sparse(
        &mut self,
        rows: usize,
        cols: usize,
        density: f64,
        mut value: impl FnMut(&mut Rng) -> f64,
    ) -> DMatrix<f64> {
        let total = rows * cols;
        let nnz = ((density * total as f64).round() as usize).min(total);
        // Partial Fisher-Yates: the first nnz entries of a shuffled index list.
        let mut idx: Vec<usize> = (0..total).collect();
        for k in 0..nnz {
            let j = k + self.below(total - k);
            idx.swap(k, j);
        }
        let mut a = DMatrix::zeros(rows, cols);
        for &p in &idx[..nnz] {
            a[(p % rows, p / rows)] = value(self);
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_and_sparsity() {
        let mut r = Rng::new(7);
        let n = 20000;
        let v = r.normal_vec(n);
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
        let a = r.sparse(150, 300, 0.001, |r| r.uniform());
        assert_eq!(a.iter().filter(|x| **x != 0.0).count(), 45);
        assert_eq!(Rng::new(3).next_u64(), Rng::new(3).next_u64());
    }
}
