//! Helpers shared by the integration tests: a deterministic random generator and an
//! error measure written independently of the library (geometric projection, dense
//! products).

#![allow(dead_code)]
// Dense reference code indexes rows and columns by number on purpose.
#![allow(clippy::needless_range_loop)]

use cadmm::{CscMatrix, GlobalProblem, LocalProblem, Problem};

/// xorshift64*: deterministic, good enough for test data.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [-1, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    /// A vector with components of very different magnitudes.
    pub fn vec3(&mut self) -> [f64; 3] {
        let scale = 10f64.powf(3.0 * self.uniform());
        [
            scale * self.uniform(),
            scale * self.uniform(),
            scale * self.uniform(),
        ]
    }
}

/// Projection onto `{ ||x_T|| <= mu x_N }` written from geometry rather than from the
/// library's case formulas: the nearest point among the cone itself (z inside), the apex
/// and the generating ray through z's tangential direction, `argmin ||z - p||`.
pub fn ray_projection(z: [f64; 3], mu: f64) -> [f64; 3] {
    let t = z[1].hypot(z[2]);
    if z[0] >= 0.0 && t <= mu * z[0] {
        return z;
    }
    let (w1, w2) = if t > 0.0 {
        (z[1] / t, z[2] / t)
    } else {
        (1.0, 0.0)
    };
    // Unit generator of the boundary ray in the plane of z and the normal axis.
    let s = (1.0 + mu * mu).sqrt();
    let d = [1.0 / s, mu * w1 / s, mu * w2 / s];
    let along = (z[0] * d[0] + z[1] * d[1] + z[2] * d[2]).max(0.0);
    [along * d[0], along * d[1], along * d[2]]
}

fn dense(a: &CscMatrix) -> Vec<Vec<f64>> {
    let mut d = vec![vec![0.0; a.ncols()]; a.nrows()];
    for j in 0..a.ncols() {
        for (i, v) in a.col(j) {
            d[i][j] += v;
        }
    }
    d
}

fn matvec(a: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    a.iter()
        .map(|row| row.iter().zip(x).map(|(p, q)| p * q).sum())
        .collect()
}

fn matvec_t(a: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    let ncols = a.first().map_or(0, |r| r.len());
    (0..ncols)
        .map(|j| a.iter().zip(x).map(|(row, xi)| row[j] * xi).sum())
        .collect()
}

/// The 2-norm, of the entries divided by the largest magnitude (no square overflows or
/// vanishes, whatever the data's scale).
fn norm(x: &[f64]) -> f64 {
    let big = x.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if big == 0.0 || !big.is_finite() {
        return big;
    }
    big * x.iter().map(|v| (v / big) * (v / big)).sum::<f64>().sqrt()
}

fn natural_map(r: &[f64], u: &[f64], mu: &[f64]) -> f64 {
    let mut residual = Vec::with_capacity(r.len());
    for (i, &m) in mu.iter().enumerate() {
        let (ri, ui) = (&r[3 * i..3 * i + 3], &u[3 * i..3 * i + 3]);
        let ut = [ui[0] + m * ui[1].hypot(ui[2]), ui[1], ui[2]];
        let p = ray_projection([ri[0] - ut[0], ri[1] - ut[1], ri[2] - ut[2]], m);
        residual.extend((0..3).map(|k| ri[k] - p[k]));
    }
    norm(&residual)
}

/// `num / den`, or `num` when `den` is zero (docs/algorithms.md §3: no floor); a norm out
/// of range counts as an infinite error.
fn rel(num: f64, den: f64) -> f64 {
    if !num.is_finite() || !den.is_finite() {
        f64::INFINITY
    } else if den > 0.0 {
        num / den
    } else {
        num
    }
}

/// docs/algorithms.md §3, global form, dense and independent of the library. With joints,
/// `lambda` (their multipliers, required) enters the equation residual and the joint
/// rows' residual is added: `G^T v + b + c lambda` for an equality, the natural map
/// `lambda - clamp(lambda - y, lo, hi)` for a bounded row (intersected with `-+ e r_n`
/// for one bounded by a contact's normal impulse), whose multipliers also join the denominator.
pub fn global_error(p: &GlobalProblem, r: &[f64], v: &[f64], lambda: &[f64]) -> f64 {
    let (m, h) = (dense(&p.m), dense(&p.h));
    let mv = matvec(&m, v);
    let mut hr = matvec(&h, r);
    let mut joint = 0.0;
    if let Some(j) = &p.joints {
        assert_eq!(lambda.len(), j.b.len(), "joint multipliers are required");
        let g = dense(&j.g);
        for (a, b) in hr.iter_mut().zip(matvec(&g, lambda)) {
            *a += b;
        }
        let gv = matvec_t(&g, v);
        // A row bounded by contact `i` has its bounds intersected with `-+ e r_n(i)`.
        let bounds = |k: usize| match j.friction_contact[k] {
            Some(i) => {
                let t = j.friction[k] * r[3 * i].max(0.0);
                (j.lo[k].max(-t), j.hi[k].min(t))
            }
            None => (j.lo[k], j.hi[k]),
        };
        let is_bounded = |k: usize| {
            j.lo[k].is_finite() || j.hi[k].is_finite() || j.friction_contact[k].is_some()
        };
        let res: Vec<f64> = (0..j.b.len())
            .map(|k| {
                let y = gv[k] + j.b[k] + j.compliance[k] * lambda[k];
                let (lo, hi) = bounds(k);
                match is_bounded(k) {
                    true => lambda[k] - (lambda[k] - y).max(lo).min(hi),
                    false => y,
                }
            })
            .collect();
        let bounded: Vec<f64> = (0..j.b.len())
            .filter(|&k| is_bounded(k))
            .map(|k| lambda[k])
            .collect();
        // The velocities the joint rows see under free motion: |G|^T |diag(M)^-1 f|.
        let free: Vec<f64> = (0..j.b.len())
            .map(|k| (0..p.n()).map(|i| (g[i][k] * p.f[i] / m[i][i]).abs()).sum())
            .collect();
        let scale = norm(&gv)
            .max(norm(&j.b))
            .max(norm(&free))
            .max(norm(&bounded));
        joint = rel(norm(&res), scale);
    }
    let eq: Vec<f64> = (0..mv.len()).map(|i| -mv[i] + hr[i] + p.f[i]).collect();
    let e1 = joint + rel(norm(&eq), norm(&p.f).max(norm(&mv)).max(norm(&hr)));
    let u: Vec<f64> = matvec_t(&h, v)
        .iter()
        .zip(&p.w)
        .map(|(a, b)| a + b)
        .collect();
    e1 + rel(natural_map(r, &u, &p.mu), norm(&u).max(norm(r)))
}

/// docs/algorithms.md §3, local form, dense and independent of the library.
pub fn local_error(p: &LocalProblem, r: &[f64]) -> f64 {
    let w = dense(&p.w);
    let u: Vec<f64> = matvec(&w, r).iter().zip(&p.q).map(|(a, b)| a + b).collect();
    rel(natural_map(r, &u, &p.mu), norm(&p.q))
}

/// Error of a solution of either form (`lambda`: joint multipliers, if any).
pub fn error(p: &Problem, r: &[f64], v: &[f64], lambda: &[f64]) -> f64 {
    if !r.iter().chain(v).chain(lambda).all(|x| x.is_finite()) {
        return f64::INFINITY;
    }
    match p {
        Problem::Global(g) => global_error(g, r, v, lambda),
        Problem::Local(l) => local_error(l, r),
    }
}

/// `../shared/data/fclib/<rel>` from the crate root.
pub fn data(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/fclib")
        .join(rel)
}

/// The global measure of [`global_error`] (no joints) with sparse products, for problems
/// too large for the dense version; the same formula, still independent of the library.
pub fn global_error_sparse(p: &GlobalProblem, r: &[f64], v: &[f64]) -> f64 {
    if !r.iter().chain(v).all(|x| x.is_finite()) {
        return f64::INFINITY;
    }
    let n = p.n();
    let (mut mv, mut hr) = (vec![0.0; n], vec![0.0; n]);
    for j in 0..n {
        for (i, x) in p.m.col(j) {
            mv[i] += x * v[j];
        }
    }
    let mut u = p.w.clone();
    for j in 0..p.h.ncols() {
        for (i, x) in p.h.col(j) {
            hr[i] += x * r[j];
            u[j] += x * v[i];
        }
    }
    let eq: Vec<f64> = (0..n).map(|i| -mv[i] + hr[i] + p.f[i]).collect();
    let e1 = rel(norm(&eq), norm(&p.f).max(norm(&mv)).max(norm(&hr)));
    e1 + rel(natural_map(r, &u, &p.mu), norm(&u).max(norm(r)))
}
