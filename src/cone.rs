//! The Coulomb friction cone `K_mu = { ||x_T|| <= mu x_N }`, its dual `K*_mu = K_{1/mu}`,
//! their projections and the De Saxce correction. Contact vectors are `[x_N, x_T1, x_T2]`.

/// Squares below this may have lost a term to underflow (2^-969: what vanishes is below
/// 2^-105 of the sum).
const SQUARES_LOW: f64 = 2.004168360008973e-292;

/// `sqrt(a^2 + b^2)`: the plain root while the sum of squares is in range (bitwise as
/// always), `hypot` where a square would overflow or vanish, so that contacts at any
/// scale a double holds are projected alike.
#[inline]
pub fn tangential_norm(a: f64, b: f64) -> f64 {
    let s = a * a + b * b;
    if (SQUARES_LOW..=f64::MAX).contains(&s) || (a == 0.0 && b == 0.0) {
        s.sqrt()
    } else {
        a.hypot(b)
    }
}

/// Projection of `z` onto `K_mu`, exact at `mu = 0` (normal ray) and `||z_T|| = 0`.
#[inline]
pub fn project_cone(z: [f64; 3], mu: f64) -> [f64; 3] {
    let t = tangential_norm(z[1], z[2]);
    // z_N >= 0 matters at mu = 0, where t = 0 <= 0 * z_N holds for a negative z_N too.
    if t <= mu * z[0] && z[0] >= 0.0 {
        return z; // inside K
    }
    if mu * t + z[0] <= 0.0 {
        return [0.0; 3]; // inside the polar cone
    }
    // Onto the boundary ray through z_T; here z_N + mu t > 0, so t > 0 whenever mu > 0.
    let a = (z[0] + mu * t) / (1.0 + mu * mu);
    if t == 0.0 {
        return [a, 0.0, 0.0];
    }
    let s = mu * a / t;
    [a, s * z[1], s * z[2]]
}

/// Projection of `z` onto the dual cone `K*_mu = { mu ||x_T|| <= x_N }`; at `mu = 0` it is
/// the half-space `x_N >= 0`.
#[inline]
pub fn project_dual_cone(z: [f64; 3], mu: f64) -> [f64; 3] {
    let t = tangential_norm(z[1], z[2]);
    if mu * t <= z[0] {
        return z; // inside K*
    }
    if t + mu * z[0] <= 0.0 {
        return [0.0; 3]; // inside polar(K*) = -K
    }
    // Boundary of K*_mu: x_N = mu ||x_T||. Written with mu (not 1/mu) so mu = 0 is exact.
    let c = (mu * z[0] + t) / (1.0 + mu * mu); // new tangential norm
    let s = c / t; // t > 0 here: t = 0 would have returned above
    [mu * c, s * z[1], s * z[2]]
}

/// The De Saxce term of one contact, `mu ||u_T||`: the only place it is computed.
#[inline]
pub fn de_saxce_term(u: [f64; 3], mu: f64) -> f64 {
    mu * tangential_norm(u[1], u[2])
}

/// De Saxce correction of one contact: `u + (mu ||u_T||, 0, 0)`.
#[inline]
pub fn de_saxce(u: [f64; 3], mu: f64) -> [f64; 3] {
    [u[0] + de_saxce_term(u, mu), u[1], u[2]]
}

/// Reads contact `i` of a stacked vector.
#[inline]
pub fn get3(x: &[f64], i: usize) -> [f64; 3] {
    [x[3 * i], x[3 * i + 1], x[3 * i + 2]]
}

/// Writes contact `i` of a stacked vector.
#[inline]
pub fn set3(x: &mut [f64], i: usize, v: [f64; 3]) {
    x[3 * i..3 * i + 3].copy_from_slice(&v);
}
