//! Roots of the small complex polynomials that give the spectrum of stationary AA
//! (degree m + 1 for sAA(m)): closed form up to degree 2, Aberth-Ehrlich iteration above.

use super::C64;

/// Roots of the monic polynomial `z^d + a[d-1] z^(d-1) + ... + a[0]` (`a` lists the
/// coefficients from the constant term up; `d = a.len()`).
pub fn roots(a: &[C64]) -> Vec<C64> {
    let d = a.len();
    match d {
        0 => Vec::new(),
        1 => vec![-a[0]],
        2 => {
            // z^2 + p z + q; the cancellation-free pair of quadratic formulas.
            let (p, q) = (a[1], a[0]);
            let disc = (p * p - q * 4.0).sqrt();
            let s = if (p.conj() * disc).re >= 0.0 {
                -p - disc
            } else {
                -p + disc
            };
            if s.norm() == 0.0 {
                return vec![C64::new(0.0, 0.0); 2];
            }
            let r1 = s * 0.5;
            vec![r1, q / r1]
        }
        _ => aberth(a),
    }
}

/// Largest root modulus of the monic polynomial of [`roots`].
pub fn max_root_modulus(a: &[C64]) -> f64 {
    roots(a).iter().fold(0.0f64, |m, z| m.max(z.norm()))
}

fn eval(a: &[C64], z: C64) -> (C64, C64) {
    // Horner for p and p'.
    let d = a.len();
    let (mut p, mut dp) = (C64::new(1.0, 0.0), C64::new(0.0, 0.0));
    for k in (0..d).rev() {
        dp = dp * z + p;
        p = p * z + a[k];
    }
    (p, dp)
}

fn aberth(a: &[C64]) -> Vec<C64> {
    let d = a.len();
    if a.iter().all(|c| c.norm() == 0.0) {
        return vec![C64::new(0.0, 0.0); d];
    }
    // Start on a circle of the Fujiwara-type radius, off the real axis.
    let radius = (0..d)
        .map(|k| a[k].norm().powf(1.0 / (d - k) as f64))
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let mut z: Vec<C64> = (0..d)
        .map(|k| {
            C64::from_polar(
                radius,
                0.4 + 2.0 * std::f64::consts::PI * k as f64 / d as f64,
            )
        })
        .collect();
    for _ in 0..200 {
        let mut moved = 0.0f64;
        for i in 0..d {
            let (p, dp) = eval(a, z[i]);
            if p.norm() == 0.0 {
                continue;
            }
            let ratio = p / dp;
            let mut sum = C64::new(0.0, 0.0);
            for j in 0..d {
                if j != i {
                    sum += (z[i] - z[j]).inv();
                }
            }
            let step = ratio / (C64::new(1.0, 0.0) - ratio * sum);
            if step.re.is_finite() && step.im.is_finite() {
                z[i] -= step;
                moved = moved.max(step.norm() / radius);
            }
        }
        if moved < 1e-15 {
            break;
        }
    }
    z
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64) -> C64 {
        C64::new(re, 0.0)
    }

    #[test]
    fn roots_of_products() {
        // (z - 0.5)(z + 0.25)(z - i)(z + i) = (z^2 - 0.25 z - 0.125)(z^2 + 1)
        let a = [c(-0.125), c(-0.25), c(0.875), c(-0.25)];
        let mut r: Vec<f64> = roots(&a).iter().map(|z| z.norm()).collect();
        r.sort_by(f64::total_cmp);
        let expect = [0.25, 0.5, 1.0, 1.0];
        for (x, e) in r.iter().zip(expect) {
            assert!((x - e).abs() < 1e-10, "{r:?}");
        }
        // Double root: z^2 - 2 z + 1.
        assert!((max_root_modulus(&[c(1.0), c(-2.0)]) - 1.0).abs() < 1e-12);
        // Triple root at 0.3: tolerance of a triple root is ~eps^(1/3).
        let a3 = [c(-0.027), c(0.27), c(-0.9)];
        assert!((max_root_modulus(&a3) - 0.3).abs() < 1e-4);
    }
}
