//! Seed 002 on the engine: the acceptance figures (spectral penalty on l0 regression, the
//! range of initial penalties that converge, the leading eigenvector) and independent
//! checks of every block update and of the stopping test.

use cadmm_research::nonconvex::{
    abs_prox, correlated_regression, forward_difference, hard_threshold, leading_eigen_matrix,
    phase_measurements, piecewise_signal, solve, Eigenvector, L0Denoising, L0Regression,
    NonconvexProblem, Order, PhaseRetrieval, StopSettings, Strategy, Tridiagonal,
};
use cadmm_research::test_problems::Rng;
use nalgebra::{Complex, DMatrix, DVector, SymmetricEigen};

/// The initial penalties of the sweep: 10^-2 .. 10^4 in half decades.
fn tau0_grid() -> Vec<f64> {
    (0..13).map(|i| 10f64.powf(-2.0 + 0.5 * i as f64)).collect()
}

fn regression() -> L0Regression {
    L0Regression::new(&correlated_regression(2016), 1.0)
}

/// From tau0 = 1 the spectral rule converges in fewer than 200 iterations, the constant
/// penalty not within 2000; the minimizer is at least as good as the generating x*.
#[test]
fn spectral_penalty_converges_on_l0_regression_where_constant_does_not() {
    let data = correlated_regression(2016);
    let mut p = L0Regression::new(&data, 1.0);
    let stop = StopSettings::paper(2000);
    for order in Order::ALL {
        let spectral = solve(&mut p, order, Strategy::Spectral, 1.0, &stop).unwrap();
        assert!(
            spectral.converged && spectral.iterations < 200,
            "{order:?}: spectral {} iterations, converged {}",
            spectral.iterations,
            spectral.converged
        );
        let truth = p.objective(data.x_true.as_slice());
        assert!(
            spectral.quality.objective <= truth,
            "{order:?}: objective {} above that of x*, {truth}",
            spectral.quality.objective
        );
        let constant = solve(&mut p, order, Strategy::Vanilla, 1.0, &stop).unwrap();
        assert!(
            !constant.converged && constant.iterations == 2000,
            "{order:?}: constant penalty stopped after {} iterations",
            constant.iterations
        );
    }
}

fn converged_count(p: &mut dyn NonconvexProblem, strategy: Strategy) -> usize {
    let stop = StopSettings::paper(2000);
    tau0_grid()
        .into_iter()
        .filter(|&t| {
            solve(p, Order::SmoothFirst, strategy, t, &stop)
                .unwrap()
                .converged
        })
        .count()
}

/// Both adaptive rules converge from more initial penalties than the constant one, on l0
/// regression and on 1D l0 denoising.
#[test]
fn adaptive_penalties_converge_over_a_wider_tau0_range() {
    let mut reg = regression();
    let mut den = L0Denoising::new(piecewise_signal(2016), 1.0);
    for p in [&mut reg as &mut dyn NonconvexProblem, &mut den] {
        let vanilla = converged_count(p, Strategy::Vanilla);
        let balancing = converged_count(p, Strategy::ResidualBalancing);
        let spectral = converged_count(p, Strategy::Spectral);
        assert!(
            spectral > vanilla && balancing > vanilla,
            "{}: converged from {vanilla} (constant), {balancing} (balancing), {spectral} \
             (spectral) of 13 initial penalties",
            p.name()
        );
    }
}

/// ADMM with a constant penalty above twice the largest eigenvalue finds the leading
/// eigenvector of D^T D as a dense symmetric eigensolver does; the spectral rule converges
/// to an eigenvector, usually another one (docs/solver-guide.md, the seed-002 table): the iterate is
/// checked to be one, with an eigenvalue of the eigensolver's.
#[test]
fn leading_eigenvector_matches_symmetric_eigen() {
    let d = leading_eigen_matrix(20, 2016);
    let gram = d.tr_mul(&d);
    let eig = SymmetricEigen::new(gram.clone());
    let top = eig.eigenvalues.imax();
    let v = eig.eigenvectors.column(top).clone_owned();
    let stop = StopSettings {
        tolerance: 1e-10,
        max_iterations: 5000,
    };
    let scale = eig.eigenvalues[top];
    for (strategy, tau0) in [(Strategy::Spectral, 1.0), (Strategy::Vanilla, 1000.0)] {
        let mut p = Eigenvector::new(d.clone(), 7);
        let r = solve(&mut p, Order::SmoothFirst, strategy, tau0, &stop).unwrap();
        assert!(r.converged, "{strategy:?}: not converged");
        let n = DVector::from_column_slice(&r.n);
        // An eigenvector: G n = (n^T G n) n, with n^T G n in the spectrum.
        let lambda = n.dot(&(&gram * &n));
        let residual = (&gram * &n - lambda * &n).norm();
        assert!(
            residual < 1e-5 * scale,
            "{strategy:?}: ||G n - lambda n|| = {residual:e}"
        );
        let nearest = eig
            .eigenvalues
            .iter()
            .map(|e| (e - lambda).abs())
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 1e-8 * scale,
            "{strategy:?}: lambda {lambda} not an eigenvalue"
        );
        if strategy == Strategy::Vanilla {
            let err = (&n - &v).norm().min((&n + &v).norm());
            assert!(
                err < 1e-6,
                "{strategy:?}: distance {err:e} to the leading eigenvector"
            );
            assert!((-r.quality.objective - scale).abs() < 1e-8 * scale);
        }
    }
}

/// The engine run with a constant penalty is the seed's ADMM (its eqs. 18-21, unscaled
/// multiplier, dense LU solves) stopped by its eq. (6): same iteration count, same iterate.
#[test]
fn constant_penalty_run_is_the_seeds_admm_with_its_stopping_test() {
    let data = correlated_regression(2016);
    let (d, c, mu, tau, tol) = (&data.d, &data.c, 1.0, 10.0, 1e-5);
    let m = d.ncols();
    let lhs = d.tr_mul(d) + DMatrix::identity(m, m) * tau;
    let lu = lhs.lu();
    let dtc = d.tr_mul(c);
    let (mut v, mut lambda) = (DVector::zeros(m), DVector::zeros(m));
    let mut iterations = 0;
    for k in 1..=2000 {
        let u = lu.solve(&(&v * tau + &lambda + &dtc)).unwrap();
        let v_new = (&u - &lambda / tau).map(|z| hard_threshold(z, mu / tau));
        let r = &v_new - &u; // b - A u - B v with A = I, B = -I, b = 0
        lambda += &r * tau;
        let dual = (&v_new - &v).norm() * tau;
        v = v_new;
        iterations = k;
        if r.norm() <= tol * u.norm().max(v.norm()) && dual <= tol * lambda.norm() {
            break;
        }
    }
    assert!(iterations < 2000, "the reference did not converge");
    let mut p = regression();
    let engine = solve(
        &mut p,
        Order::SmoothFirst,
        Strategy::Vanilla,
        tau,
        &StopSettings::paper(2000),
    )
    .unwrap();
    assert_eq!(engine.iterations, iterations);
    let diff = (DVector::from_column_slice(&engine.n) - &v).norm();
    assert!(diff < 1e-9 * v.norm(), "iterates differ by {diff:e}");
}

/// hard(z, t) keeps |z| > sqrt(2t), zeroes the rest, and is the cheaper of the two
/// candidates of `||x||_0 + (x - z)^2 / (2t)`.
#[test]
fn hard_threshold_keeps_or_zeroes() {
    let t = 0.5; // threshold sqrt(2 t) = 1
    assert_eq!(hard_threshold(1.2, t), 1.2);
    assert_eq!(hard_threshold(-1.5, t), -1.5);
    assert_eq!(hard_threshold(0.9, t), 0.0);
    assert_eq!(hard_threshold(-0.99, t), 0.0);
    for z in [-3.0, -1.01, -0.4, 0.0, 0.3, 0.999, 1.001, 2.5] {
        let cost = |x: f64| f64::from(u8::from(x != 0.0)) + (x - z) * (x - z) / (2.0 * t);
        let h = hard_threshold(z, t);
        assert!(cost(h) <= cost(0.0).min(cost(z)), "z = {z}");
    }
}

/// The tridiagonal LDL^T solve and the denoising block update against dense solves.
#[test]
fn denoising_solve_matches_a_dense_solve() {
    let mut r = Rng::new(11);
    let n = 30;
    let diag: Vec<f64> = (0..n).map(|_| 3.0 + r.uniform()).collect();
    let off: Vec<f64> = (0..n - 1).map(|_| r.uniform() - 0.5).collect();
    let dense = DMatrix::from_fn(n, n, |i, j| {
        if i == j {
            diag[i]
        } else if i == j + 1 {
            off[j]
        } else if j == i + 1 {
            off[i]
        } else {
            0.0
        }
    });
    let b = DVector::from_vec(r.normal_vec(n));
    let mut x = b.as_slice().to_vec();
    Tridiagonal::factor(&diag, &off).unwrap().solve(&mut x);
    let reference = dense.clone().lu().solve(&b).unwrap();
    assert!((DVector::from_vec(x) - &reference).norm() < 1e-12 * reference.norm());

    let signal = piecewise_signal(3);
    let len = signal.noisy.len();
    let grad = DMatrix::from_fn(len - 1, len, |i, j| {
        if j == i + 1 {
            1.0
        } else if j == i {
            -1.0
        } else {
            0.0
        }
    });
    let noisy = DVector::from_column_slice(&signal.noisy);
    let mut p = L0Denoising::new(signal, 1.0);
    let rho = 7.5;
    p.set_rho(rho).unwrap();
    let t = DVector::from_vec(r.normal_vec(len - 1));
    let (mut s, mut ks) = (Vec::new(), vec![0.0; len - 1]);
    p.smooth_step(t.as_slice(), rho, &mut s, &mut ks);
    let lhs = DMatrix::identity(len, len) + grad.tr_mul(&grad) * rho;
    let u = lhs.lu().solve(&(&noisy + grad.tr_mul(&t) * rho)).unwrap();
    assert!((DVector::from_column_slice(&s) - &u).norm() < 1e-10 * u.norm());
    let mut gu = vec![0.0; len - 1];
    forward_difference(u.as_slice(), &mut gu);
    assert!((DVector::from_vec(ks) - DVector::from_vec(gu)).norm() < 1e-10 * u.norm());
}

/// The regression block update makes the gradient of its subproblem vanish.
#[test]
fn regression_solve_is_stationary() {
    let data = correlated_regression(5);
    let mut p = L0Regression::new(&data, 1.0);
    let rho = 3.0;
    p.set_rho(rho).unwrap();
    let t = DVector::from_vec(Rng::new(1).normal_vec(40));
    let (mut s, mut ks) = (Vec::new(), vec![0.0; 40]);
    p.smooth_step(t.as_slice(), rho, &mut s, &mut ks);
    let s = DVector::from_vec(s);
    let grad = data.d.tr_mul(&(&data.d * &s - &data.c)) + (&s - &t) * rho;
    assert!(
        grad.norm() < 1e-10 * data.d.tr_mul(&data.c).norm(),
        "{}",
        grad.norm()
    );
}

/// The magnitude prox is no worse than any point of a fine polar grid around it.
#[test]
fn abs_prox_minimizes_its_subproblem() {
    for (z, c, rho) in [
        (Complex::new(0.3, -1.2), 2.0, 0.5),
        (Complex::new(-2.0, 0.1), 0.5, 3.0),
        (Complex::new(0.0, 0.0), 1.0, 1.0),
    ] {
        let f = |y: Complex<f64>| 0.5 * (y.norm() - c).powi(2) + 0.5 * rho * (y - z).norm_sqr();
        let p = abs_prox(z, c, rho);
        let mut best = f64::INFINITY;
        for i in 0..=400 {
            for j in 0..720 {
                let r = 4.0 * i as f64 / 400.0;
                let a = std::f64::consts::PI * j as f64 / 360.0;
                best = best.min(f(Complex::from_polar(r, a)));
            }
        }
        assert!(f(p) <= best + 1e-12, "z = {z}: {} vs grid {best}", f(p));
        assert!(
            best - f(p) < 1e-3,
            "z = {z}: grid finds {best}, prox {}",
            f(p)
        );
    }
}

/// The phase retrieval block update solves the least-squares problem (normal equations),
/// and ADMM reaches an objective no worse than that of the true signal.
#[test]
fn phase_retrieval_solve_and_run() {
    let data = phase_measurements(600, 20, 4);
    let (d, x_true) = (data.d.clone(), data.x_true.clone());
    let mut p = PhaseRetrieval::new(data, 9).unwrap();
    let t: Vec<f64> = Rng::new(2).normal_vec(1200);
    let (mut s, mut ks) = (Vec::new(), vec![0.0; 1200]);
    p.smooth_step(&t, 1.0, &mut s, &mut ks);
    let tc = DVector::from_fn(600, |i, _| Complex::new(t[2 * i], t[2 * i + 1]));
    let sc = DVector::from_fn(20, |i, _| Complex::new(s[2 * i], s[2 * i + 1]));
    let normal = d.ad_mul(&(&d * &sc - &tc));
    assert!(normal.norm() < 1e-9 * d.ad_mul(&tc).norm());

    let truth = p.objective_complex(&x_true);
    for strategy in [Strategy::ResidualBalancing, Strategy::Spectral] {
        let r = solve(
            &mut p,
            Order::SmoothFirst,
            strategy,
            1.0,
            &StopSettings::paper(200),
        )
        .unwrap();
        assert!(
            r.converged && r.quality.objective <= truth,
            "{strategy:?}: {} iterations, objective {} vs {truth} at the true signal",
            r.iterations,
            r.quality.objective
        );
    }
}

/// The eigenvector block updates: the linear solve's residual, and the projection onto
/// the sphere beats other unit vectors.
#[test]
fn eigenvector_updates() {
    let d = leading_eigen_matrix(8, 3);
    let mut p = Eigenvector::new(d, 1);
    let rho = 500.0;
    p.set_rho(rho).unwrap();
    let mut r = Rng::new(8);
    let t = DVector::from_vec(r.normal_vec(8));
    let (mut s, mut ks) = (Vec::new(), vec![0.0; 8]);
    p.smooth_step(t.as_slice(), rho, &mut s, &mut ks);
    let s = DVector::from_vec(s);
    let residual = (&s * rho - p.gram() * &s * 2.0) - &t * rho;
    assert!(residual.norm() < 1e-10 * rho * t.norm());

    let mut n = vec![0.0; 8];
    p.nonsmooth_prox(t.as_slice(), rho, &mut n);
    let n = DVector::from_vec(n);
    assert!((n.norm() - 1.0).abs() < 1e-14);
    for _ in 0..100 {
        let w = DVector::from_vec(r.normal_vec(8)).normalize();
        assert!((&n - &t).norm() <= (&w - &t).norm());
    }
}
