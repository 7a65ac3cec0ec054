//! The Alart-Curnier function of one contact and an element of its generalized Jacobian.
//!
//! With `zeta_N = r_N - rho_N u_N`, `zeta_T = r_T - rho_T u_T` and the disk radius
//! `R = mu max(zeta_N, 0)`:
//!
//! ```text
//! F_N = r_N - max(zeta_N, 0)
//! F_T = r_T - P_disk(R)(zeta_T)
//! ```
//!
//! `F(r, u) = 0` is exactly Coulomb's law (Signorini in the normal direction, the maximum
//! dissipation law in the tangent plane), with `u` the plain local velocity (no De Saxce
//! term). The three smooth pieces are *open* (`zeta_N <= 0`), *stick*
//! (`||zeta_T|| <= R`) and *slide*.

/// A 3x3 matrix, row-major (`m[row][col]`).
pub type Mat3 = [[f64; 3]; 3];

const ZERO3: Mat3 = [[0.0; 3]; 3];
const EYE3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Which smooth piece of the Alart-Curnier function a point lies in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// `zeta_N <= 0`: the contact separates, `F = r`.
    Open,
    /// `||zeta_T|| <= R`: sticking, `F = (rho_N u_N, rho_T u_T)`.
    Stick,
    /// Sliding, `F_T = r_T - R zeta_T / ||zeta_T||` (also every closed contact at `mu = 0`).
    Slide,
}

/// Branch of the point `(r, u)`, by the same tests as [`ac_contact`].
pub fn ac_branch(r: [f64; 3], u: [f64; 3], mu: f64, rho_n: f64, rho_t: f64) -> Branch {
    let zn = r[0] - rho_n * u[0];
    if zn <= 0.0 {
        return Branch::Open;
    }
    let radius = mu * zn;
    let s = (r[1] - rho_t * u[1]).hypot(r[2] - rho_t * u[2]);
    if s <= radius && radius > 0.0 {
        Branch::Stick
    } else {
        Branch::Slide
    }
}

/// Alart-Curnier function of one contact: returns `(F, A = dF/du, B = dF/dr)`, where
/// `(A, B)` is an element of the generalized Jacobian (the derivative of the smooth piece
/// the point lies in; on a kink, the piece chosen by [`ac_branch`]).
pub fn ac_contact(
    r: [f64; 3],
    u: [f64; 3],
    mu: f64,
    rho_n: f64,
    rho_t: f64,
) -> ([f64; 3], Mat3, Mat3) {
    let zn = r[0] - rho_n * u[0];
    if zn <= 0.0 {
        // Open: max(zeta_N, 0) = 0 and the disk has radius 0, so F = r.
        return (r, ZERO3, EYE3);
    }
    let mut a = ZERO3;
    let mut b = ZERO3;
    let mut f = [0.0; 3];
    // F_N = r_N - zeta_N = rho_N u_N, written without the cancellation of r_N - zeta_N.
    f[0] = rho_n * u[0];
    a[0][0] = rho_n;
    let radius = mu * zn;
    let zt = [r[1] - rho_t * u[1], r[2] - rho_t * u[2]];
    let s = zt[0].hypot(zt[1]);
    // At mu = 0 the disk is a point and F_T = r_T is smooth: take the slide formula
    // (which gives B_T = I), never the stick one (rho_T u_T), which is not a derivative.
    if s <= radius && radius > 0.0 {
        // Stick: P_disk(zeta_T) = zeta_T, F_T = r_T - zeta_T = rho_T u_T.
        f[1] = rho_t * u[1];
        f[2] = rho_t * u[2];
        a[1][1] = rho_t;
        a[2][2] = rho_t;
        return (f, a, b);
    }
    // Slide: F_T = r_T - R t with t = zeta_T / s (s > R >= 0, or s = 0 only when mu = 0).
    // d(R t)/d zeta_N = mu t (R = mu zeta_N); d(R t)/d zeta_T = (R / s) (I - t t^T) =: P.
    let (t, ratio) = if s > 0.0 {
        ([zt[0] / s, zt[1] / s], radius / s)
    } else {
        ([0.0, 0.0], 0.0)
    };
    f[1] = r[1] - radius * t[0];
    f[2] = r[2] - radius * t[1];
    for i in 0..2 {
        // zeta_N depends on r_N (+1) and u_N (-rho_N); zeta_T on r_T (+I) and u_T (-rho_T I).
        b[1 + i][0] = -mu * t[i];
        a[1 + i][0] = mu * rho_n * t[i];
        for j in 0..2 {
            let delta = if i == j { 1.0 } else { 0.0 };
            let p = ratio * (delta - t[i] * t[j]);
            b[1 + i][1 + j] = delta - p;
            a[1 + i][1 + j] = rho_t * p;
        }
    }
    (f, a, b)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Small deterministic generator (xorshift64*), uniform in [lo, hi).
    pub(crate) struct Rng(pub u64);
    impl Rng {
        pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let x = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11;
            lo + (hi - lo) * (x as f64 / (1u64 << 53) as f64)
        }
    }

    /// Central finite differences of F w.r.t. u (A) and r (B).
    fn fd_jacobians(r: [f64; 3], u: [f64; 3], mu: f64, rn: f64, rt: f64) -> (Mat3, Mat3) {
        let h = 1e-6;
        let mut a = ZERO3;
        let mut b = ZERO3;
        for j in 0..3 {
            let (mut up, mut um) = (u, u);
            up[j] += h;
            um[j] -= h;
            let (fp, fm) = (
                ac_contact(r, up, mu, rn, rt).0,
                ac_contact(r, um, mu, rn, rt).0,
            );
            let (mut rp, mut rm) = (r, r);
            rp[j] += h;
            rm[j] -= h;
            let (gp, gm) = (
                ac_contact(rp, u, mu, rn, rt).0,
                ac_contact(rm, u, mu, rn, rt).0,
            );
            for i in 0..3 {
                a[i][j] = (fp[i] - fm[i]) / (2.0 * h);
                b[i][j] = (gp[i] - gm[i]) / (2.0 * h);
            }
        }
        (a, b)
    }

    /// Distance of `(r, u)` to the kinks (zeta_N = 0 and ||zeta_T|| = R).
    fn kink_distance(r: [f64; 3], u: [f64; 3], mu: f64, rn: f64, rt: f64) -> f64 {
        let zn = r[0] - rn * u[0];
        let s = (r[1] - rt * u[1]).hypot(r[2] - rt * u[2]);
        let d = zn.abs();
        if zn > 0.0 && mu > 0.0 {
            d.min((s - mu * zn).abs())
        } else {
            d
        }
    }

    #[test]
    fn jacobian_matches_finite_differences_in_every_branch() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for &mu in &[0.0, 0.3, 1.0, 10.0] {
            // At mu = 0 no point sticks (the disk is a point): do not wait for that branch.
            let mut seen = [0usize, if mu == 0.0 { 20 } else { 0 }, 0];
            let mut tries = 0;
            while seen.iter().any(|&c| c < 20) {
                tries += 1;
                assert!(
                    tries < 100_000,
                    "could not sample every branch for mu = {mu}"
                );
                let r = [
                    rng.uniform(-1.0, 2.0),
                    rng.uniform(-2.0, 2.0),
                    rng.uniform(-2.0, 2.0),
                ];
                let u = [
                    rng.uniform(-2.0, 1.0),
                    rng.uniform(-2.0, 2.0),
                    rng.uniform(-2.0, 2.0),
                ];
                let (rn, rt) = (rng.uniform(0.1, 3.0), rng.uniform(0.1, 3.0));
                if kink_distance(r, u, mu, rn, rt) < 1e-3 {
                    continue;
                }
                let k = ac_branch(r, u, mu, rn, rt) as usize;
                if seen[k] >= 20 {
                    continue;
                }
                seen[k] += 1;
                let (_, a, b) = ac_contact(r, u, mu, rn, rt);
                let (fa, fb) = fd_jacobians(r, u, mu, rn, rt);
                for i in 0..3 {
                    for j in 0..3 {
                        let tol = 1e-6 * (1.0 + fa[i][j].abs() + fb[i][j].abs());
                        assert!(
                            (a[i][j] - fa[i][j]).abs() < tol,
                            "A mu={mu} branch {k} ({i},{j}): {} vs {}",
                            a[i][j],
                            fa[i][j]
                        );
                        assert!(
                            (b[i][j] - fb[i][j]).abs() < tol,
                            "B mu={mu} branch {k} ({i},{j}): {} vs {}",
                            b[i][j],
                            fb[i][j]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn zero_at_known_solutions() {
        for &(rn, rt) in &[(1.0, 1.0), (0.3, 5.0)] {
            // Separating: r = 0, u_N > 0, any tangential velocity.
            let (f, _, _) = ac_contact([0.0; 3], [0.7, -3.0, 2.0], 0.5, rn, rt);
            assert_eq!(f, [0.0; 3]);
            // Sticking: r strictly inside the cone, u = 0.
            let (f, _, _) = ac_contact([2.0, 0.3, -0.4], [0.0; 3], 0.5, rn, rt);
            assert_eq!(f, [0.0; 3]);
            // Sliding: ||r_T|| = mu r_N, u_N = 0, u_T = -c r_T with c > 0.
            let mu = 0.5;
            let r = [2.0, 0.6, -0.8];
            let c = 0.7;
            let (f, _, _) = ac_contact(r, [0.0, -c * r[1], -c * r[2]], mu, rn, rt);
            assert!(f.iter().all(|x| x.abs() < 1e-15), "{f:?}");
            // Frictionless sliding: r = (r_N, 0, 0), u_N = 0, any u_T.
            let (f, _, _) = ac_contact([1.5, 0.0, 0.0], [0.0, 0.4, 2.0], 0.0, rn, rt);
            assert_eq!(f, [0.0; 3]);
        }
        // Not a solution: sliding along the force instead of against it.
        let (f, _, _) = ac_contact([2.0, 0.6, -0.8], [0.0, 0.6, -0.8], 0.5, 1.0, 1.0);
        assert!(f[1].abs() > 0.1);
    }
}
