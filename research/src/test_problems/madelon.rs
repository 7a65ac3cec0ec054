//! A synthetic stand-in for the Madelon data set used by seed 001 (sections 3.2 and 3.6),
//! built with Madelon's recipe: points in clusters on the vertices of a 5-D hypercube (half
//! of the 32 vertices per class), 15 redundant linear combinations of those 5 features,
//! the rest pure-noise probes, every feature shifted to ~480 with a spread like Madelon's
//! (~20 for probes, 40-110 for relevant ones) and rounded to integers, 1% of labels flipped.

use super::Rng;
use nalgebra::DMatrix;

/// `m` samples of `n >= 20` features and their labels in `{-1, +1}`.
pub fn madelon_like(m: usize, n: usize, seed: u64) -> (DMatrix<f64>, Vec<f64>) {
    assert!(
        n >= 20,
        "madelon_like needs at least the 20 relevant features"
    );
    let mut r = Rng::new(seed);
    let informative = 5;
    let vertices = 1usize << informative;
    // Half of the vertices per class, at random.
    let mut class = vec![-1.0; vertices];
    let mut order: Vec<usize> = (0..vertices).collect();
    for k in 0..vertices {
        let j = k + r.below(vertices - k);
        order.swap(k, j);
    }
    for &v in &order[..vertices / 2] {
        class[v] = 1.0;
    }
    let mix = DMatrix::from_fn(informative, 15, |_, _| r.normal());
    let mut raw = DMatrix::zeros(m, n);
    let mut labels = vec![0.0; m];
    for i in 0..m {
        let v = r.below(vertices);
        labels[i] = if r.uniform() < 0.01 {
            -class[v]
        } else {
            class[v]
        };
        for f in 0..informative {
            let corner = if (v >> f) & 1 == 1 { 1.0 } else { -1.0 };
            raw[(i, f)] = corner + 0.5 * r.normal();
        }
        for f in 0..15 {
            raw[(i, informative + f)] = (0..informative).map(|k| raw[(i, k)] * mix[(k, f)]).sum();
        }
        for f in 20..n {
            raw[(i, f)] = r.normal();
        }
    }
    // Madelon-like scale: standardize, then spread, shift and quantize; shuffle the columns.
    let mut perm: Vec<usize> = (0..n).collect();
    for k in 0..n {
        let j = k + r.below(n - k);
        perm.swap(k, j);
    }
    let mut a = DMatrix::zeros(m, n);
    for f in 0..n {
        let col = raw.column(f);
        let mean = col.mean();
        let sd = col.variance().sqrt().max(1e-12);
        let spread = if f < 20 {
            40.0 + 70.0 * r.uniform()
        } else {
            15.0 + 10.0 * r.uniform()
        };
        let shift = 480.0 + 15.0 * r.normal();
        for i in 0..m {
            a[(i, perm[f])] = (shift + spread * (raw[(i, f)] - mean) / sd).round();
        }
    }
    (a, labels)
}
