//! Test scenes shared by the local and global Newton tests: a rigid box on four coplanar
//! corner contacts, a point mass with duplicated contacts, and the local form of any
//! global problem with a diagonal mass matrix.

use crate::csc::CscMatrix;
use crate::problem::{GlobalProblem, LocalProblem};

/// Gravity.
pub const G: f64 = 9.81;
/// Time step: the data are impulses over one step from rest.
pub const DT: f64 = 0.01;

/// A rigid box (half extents 0.5, 0.3, 0.2, mass 2) resting on the ground (normal +z) on its
/// four bottom corners, pushed along x by `push` (a force), gravity along -z.
/// Unknowns `v = (v_x, v_y, v_z, w_x, w_y, w_z)` at the centre of mass.
/// `lift` adds an upward force (in units of the weight) to make the contacts separate.
pub fn box_problem(mu: f64, push: f64, lift: f64) -> GlobalProblem {
    let (a, b, c) = (0.5, 0.3, 0.2);
    let mass = 2.0;
    let inertia = [
        mass / 3.0 * (b * b + c * c),
        mass / 3.0 * (a * a + c * c),
        mass / 3.0 * (a * a + b * b),
    ];
    let diag = [mass, mass, mass, inertia[0], inertia[1], inertia[2]];
    let m = CscMatrix::from_triplets(
        "M",
        6,
        6,
        &(0..6).map(|i| (i, i, diag[i])).collect::<Vec<_>>(),
    )
    .unwrap();
    let corners = [[a, b, -c], [-a, b, -c], [-a, -b, -c], [a, -b, -c]];
    // Contact frame: normal e_z, tangents e_x, e_y (normal first).
    let frame = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut t = Vec::new();
    for (i, p) in corners.iter().enumerate() {
        for (d, e) in frame.iter().enumerate() {
            // Velocity of the corner along e: e . (v + w x p) = e . v + (p x e) . w.
            let pxe = [
                p[1] * e[2] - p[2] * e[1],
                p[2] * e[0] - p[0] * e[2],
                p[0] * e[1] - p[1] * e[0],
            ];
            for k in 0..3 {
                t.push((k, 3 * i + d, e[k]));
                t.push((3 + k, 3 * i + d, pxe[k]));
            }
        }
    }
    let t: Vec<_> = t.into_iter().filter(|x| x.2 != 0.0).collect();
    let h = CscMatrix::from_triplets("H", 6, 12, &t).unwrap();
    let f = vec![push * DT, 0.0, (lift - 1.0) * mass * G * DT, 0.0, 0.0, 0.0];
    GlobalProblem::new(m, h, f, vec![0.0; 12], vec![mu; 4]).unwrap()
}

/// A point mass `mass` on the ground with `copies` identical contacts, pushed along x by
/// `push` (force) and along -z by `load` (force).
pub fn point_mass_problem(
    mu: f64,
    mass: f64,
    push: f64,
    load: f64,
    copies: usize,
) -> GlobalProblem {
    let m =
        CscMatrix::from_triplets("M", 3, 3, &[(0, 0, mass), (1, 1, mass), (2, 2, mass)]).unwrap();
    // Local frame (normal e_z, tangents e_x, e_y) for every copy.
    let mut t = Vec::new();
    for c in 0..copies {
        t.push((2, 3 * c, 1.0));
        t.push((0, 3 * c + 1, 1.0));
        t.push((1, 3 * c + 2, 1.0));
    }
    let h = CscMatrix::from_triplets("H", 3, 3 * copies, &t).unwrap();
    let f = vec![push * DT, 0.0, -load * DT];
    GlobalProblem::new(m, h, f, vec![0.0; 3 * copies], vec![mu; copies]).unwrap()
}

/// Local form `W = H^T M^-1 H`, `q = H^T M^-1 f + w` of a global problem with diagonal M.
pub fn to_local(p: &GlobalProblem) -> LocalProblem {
    let n = p.n();
    let mut minv = vec![0.0; n];
    for j in 0..n {
        for (i, v) in p.m.col(j) {
            assert_eq!(i, j, "to_local needs a diagonal M");
            minv[j] = 1.0 / v;
        }
    }
    let m = p.h.ncols();
    let hd: Vec<Vec<f64>> = (0..m)
        .map(|c| {
            let mut col = vec![0.0; n];
            for (i, v) in p.h.col(c) {
                col[i] = v;
            }
            col
        })
        .collect();
    let mut t = Vec::new();
    for i in 0..m {
        for j in 0..m {
            let w: f64 = (0..n).map(|k| hd[i][k] * minv[k] * hd[j][k]).sum();
            if w.abs() > 1e-15 {
                t.push((i, j, w));
            }
        }
    }
    let w = CscMatrix::from_triplets("W", m, m, &t).unwrap();
    let q: Vec<f64> = (0..m)
        .map(|c| (0..n).map(|k| hd[c][k] * minv[k] * p.f[k]).sum::<f64>() + p.w[c])
        .collect();
    LocalProblem::new(w, q, p.mu.clone()).unwrap()
}

/// `v = M^-1 (H r + f)` for a diagonal M.
pub fn velocity(p: &GlobalProblem, r: &[f64]) -> Vec<f64> {
    let mut v = p.f.clone();
    p.h.mul_vec(1.0, r, 1.0, &mut v);
    for j in 0..p.n() {
        let d = p.m.col(j).next().unwrap().1;
        v[j] /= d;
    }
    v
}

/// The same problem with every contact listed twice (`H' = [H H]`).
pub fn duplicated(p: &GlobalProblem) -> GlobalProblem {
    let m = p.h.ncols();
    let mut t = Vec::new();
    for c in 0..m {
        for (i, v) in p.h.col(c) {
            t.push((i, c, v));
            t.push((i, c + m, v));
        }
    }
    let h = CscMatrix::from_triplets("H", p.n(), 2 * m, &t).unwrap();
    let w = [p.w.clone(), p.w.clone()].concat();
    let mu = [p.mu.clone(), p.mu.clone()].concat();
    GlobalProblem::new(p.m.clone(), h, p.f.clone(), w, mu).unwrap()
}

/// Deterministic relative perturbation `x_k (1 + eps s_k)` plus `eps * scale * s'_k`,
/// with `s` in [-1, 1).
pub fn perturb(x: &mut [f64], eps: f64, scale: f64, seed: u64) {
    let mut rng = super::alart_curnier::tests::Rng(seed);
    for v in x.iter_mut() {
        *v = *v * (1.0 + eps * rng.uniform(-1.0, 1.0)) + eps * scale * rng.uniform(-1.0, 1.0);
    }
}

/// A stack of `nb` identical boxes (half extents 0.5, 0.3, 0.2, mass 2) on the ground, each
/// resting on the one below on its four bottom corners (`4 nb` contacts, normal +z),
/// box `k` pushed by `push[k] = (F_x, F_y)`; all with friction `mu`.
pub fn stack_problem(mu: f64, push: &[(f64, f64)]) -> GlobalProblem {
    let nb = push.len();
    let (a, b, c) = (0.5, 0.3, 0.2);
    let mass = 2.0;
    let inertia = [
        mass / 3.0 * (b * b + c * c),
        mass / 3.0 * (a * a + c * c),
        mass / 3.0 * (a * a + b * b),
    ];
    let mut mt = Vec::new();
    let mut f = Vec::new();
    for (k, &(fx, fy)) in push.iter().enumerate() {
        let d = [mass, mass, mass, inertia[0], inertia[1], inertia[2]];
        for i in 0..6 {
            mt.push((6 * k + i, 6 * k + i, d[i]));
        }
        f.extend([fx * DT, fy * DT, -mass * G * DT, 0.0, 0.0, 0.0]);
    }
    let m = CscMatrix::from_triplets("M", 6 * nb, 6 * nb, &mt).unwrap();
    let frame = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let corners = [[a, b], [-a, b], [-a, -b], [a, -b]];
    let mut t = Vec::new();
    let cross = |p: [f64; 3], e: [f64; 3]| {
        [
            p[1] * e[2] - p[2] * e[1],
            p[2] * e[0] - p[0] * e[2],
            p[0] * e[1] - p[1] * e[0],
        ]
    };
    for k in 0..nb {
        for (q, xy) in corners.iter().enumerate() {
            let contact = 4 * k + q;
            for (dir, e) in frame.iter().enumerate() {
                let col = 3 * contact + dir;
                // Upper body k: the corner is at its bottom (z = -c).
                let pxe = cross([xy[0], xy[1], -c], *e);
                for i in 0..3 {
                    t.push((6 * k + i, col, e[i]));
                    t.push((6 * k + 3 + i, col, pxe[i]));
                }
                // Lower body k - 1 (none for the ground): the point is at its top (z = +c).
                if k > 0 {
                    let pxe = cross([xy[0], xy[1], c], *e);
                    for i in 0..3 {
                        t.push((6 * (k - 1) + i, col, -e[i]));
                        t.push((6 * (k - 1) + 3 + i, col, -pxe[i]));
                    }
                }
            }
        }
    }
    let t: Vec<_> = t.into_iter().filter(|x| x.2 != 0.0).collect();
    let h = CscMatrix::from_triplets("H", 6 * nb, 12 * nb, &t).unwrap();
    GlobalProblem::new(m, h, f, vec![0.0; 12 * nb], vec![mu; 4 * nb]).unwrap()
}

/// Random stacks: `count` scenes of `boxes` boxes with pushes up to `max_push` (N), `mu`
/// drawn from a few values, deterministic.
pub fn random_stacks(count: usize, boxes: usize, max_push: f64, seed: u64) -> Vec<GlobalProblem> {
    let mut rng = super::alart_curnier::tests::Rng(seed);
    (0..count)
        .map(|_| {
            let mu = [0.0, 0.1, 0.3, 1.0][(rng.uniform(0.0, 4.0) as usize).min(3)];
            let push: Vec<(f64, f64)> = (0..boxes)
                .map(|_| {
                    (
                        rng.uniform(-max_push, max_push),
                        rng.uniform(-max_push, max_push),
                    )
                })
                .collect();
            stack_problem(mu, &push)
        })
        .collect()
}

/// The same scene with masses (and so impulses) multiplied by `s`: velocities unchanged,
/// `r` scaled by `s`, `W` by `1 / s`.
pub fn scaled_mass(p: &GlobalProblem, s: f64) -> GlobalProblem {
    let t: Vec<_> = (0..p.n())
        .flat_map(|j| p.m.col(j).map(move |(i, v)| (i, j, v * s)))
        .collect();
    let m = CscMatrix::from_triplets("M", p.n(), p.n(), &t).unwrap();
    let f = p.f.iter().map(|x| x * s).collect();
    GlobalProblem::new(m, p.h.clone(), f, p.w.clone(), p.mu.clone()).unwrap()
}
