//! Property tests of the cone projections (docs/algorithms.md §2): idempotence, Moreau
//! decomposition, non-expansiveness, agreement with an independent geometric construction,
//! over mu in {0, 1e-8, 0.3, 1, 1e8}.

mod common;

use cadmm::{project_cone, project_dual_cone};
use common::{ray_projection, Rng};

const MUS: [f64; 5] = [0.0, 1e-8, 0.3, 1.0, 1e8];

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
fn norm(a: [f64; 3]) -> f64 {
    dist(a, [0.0; 3])
}
fn in_cone(x: [f64; 3], mu: f64, tol: f64) -> bool {
    x[1].hypot(x[2]) <= mu * x[0] + tol
}
fn in_dual(x: [f64; 3], mu: f64, tol: f64) -> bool {
    mu * x[1].hypot(x[2]) <= x[0] + tol
}
/// Projection onto the polar of K_mu: `-P_{K*_mu}(-z)`.
fn project_polar(z: [f64; 3], mu: f64) -> [f64; 3] {
    let p = project_dual_cone([-z[0], -z[1], -z[2]], mu);
    [-p[0], -p[1], -p[2]]
}

fn samples(seed: u64) -> Vec<[f64; 3]> {
    let mut rng = Rng::new(seed);
    let mut v: Vec<[f64; 3]> = (0..2000).map(|_| rng.vec3()).collect();
    // Edge cases: apex, axes, tangential-only, exactly on the boundary.
    v.extend([
        [0.0; 3],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -2.0, 3.0],
        [1.0, 0.3, 0.4],
    ]);
    v
}

#[test]
fn projections_are_idempotent_and_land_in_their_cones() {
    for &mu in &MUS {
        for z in samples(1) {
            let tol = 1e-12 * (1.0 + norm(z)) * (1.0 + mu);
            let p = project_cone(z, mu);
            assert!(in_cone(p, mu, tol), "P_K({z:?}) = {p:?} not in K_{mu}");
            assert!(
                dist(project_cone(p, mu), p) <= tol,
                "P_K not idempotent at {z:?}, mu {mu}"
            );
            let d = project_dual_cone(z, mu);
            assert!(in_dual(d, mu, tol), "P_K*({z:?}) = {d:?} not in K*_{mu}");
            assert!(
                dist(project_dual_cone(d, mu), d) <= tol,
                "P_K* not idempotent at {z:?}, mu {mu}"
            );
        }
    }
}

#[test]
fn moreau_decomposition_holds() {
    for &mu in &MUS {
        for z in samples(2) {
            let p = project_cone(z, mu);
            let q = project_polar(z, mu);
            let tol = 1e-11 * (1.0 + norm(z));
            let sum = [p[0] + q[0], p[1] + q[1], p[2] + q[2]];
            assert!(
                dist(sum, z) <= tol,
                "z != P_K z + P_polar z at {z:?}, mu {mu}: {sum:?}"
            );
            let inner = p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
            assert!(
                inner.abs() <= tol * (1.0 + norm(z)),
                "P_K z not orthogonal to P_polar z at {z:?}, mu {mu}"
            );
        }
    }
}

#[test]
fn projections_are_non_expansive() {
    for &mu in &MUS {
        let (a, b) = (samples(3), samples(4));
        for (x, y) in a.iter().zip(&b) {
            let tol = 1e-12 * (1.0 + norm(*x) + norm(*y));
            assert!(dist(project_cone(*x, mu), project_cone(*y, mu)) <= dist(*x, *y) + tol);
            assert!(
                dist(project_dual_cone(*x, mu), project_dual_cone(*y, mu)) <= dist(*x, *y) + tol
            );
        }
    }
}

#[test]
fn projection_agrees_with_the_nearest_ray_construction() {
    for &mu in &[0.0, 0.3, 1.0, 2.5] {
        for z in samples(5) {
            let tol = 1e-10 * (1.0 + norm(z));
            let (a, b) = (project_cone(z, mu), ray_projection(z, mu));
            assert!(
                dist(a, b) <= tol,
                "mu {mu}, z {z:?}: {a:?} vs geometric {b:?}"
            );
        }
    }
}

#[test]
fn limits_at_mu_zero_and_at_the_apex_are_exact() {
    // K_0 is the normal ray, K*_0 the half-space x_N >= 0.
    assert_eq!(project_cone([2.0, 3.0, -4.0], 0.0), [2.0, 0.0, 0.0]);
    assert_eq!(project_cone([-2.0, 3.0, -4.0], 0.0), [0.0, 0.0, 0.0]);
    assert_eq!(project_dual_cone([-2.0, 3.0, -4.0], 0.0), [0.0, 3.0, -4.0]);
    assert_eq!(project_dual_cone([2.0, 3.0, -4.0], 0.0), [2.0, 3.0, -4.0]);
    // t = 0: no division by the tangential norm.
    assert_eq!(project_cone([-1.0, 0.0, 0.0], 0.5), [0.0, 0.0, 0.0]);
    assert_eq!(project_dual_cone([-1.0, 0.0, 0.0], 0.5), [0.0, 0.0, 0.0]);
    assert_eq!(project_cone([1.0, 0.0, 0.0], 0.5), [1.0, 0.0, 0.0]);
    // A point projected onto the boundary: ||(1, 0)|| with mu = 1 -> (0.5, 0.5).
    let p = project_cone([0.0, 1.0, 0.0], 1.0);
    assert!(dist(p, [0.5, 0.5, 0.0]) < 1e-15);
}
