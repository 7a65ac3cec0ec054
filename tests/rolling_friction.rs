//! Rolling and spinning friction: joint rows on a contact's relative angular velocity,
//! bounded by `e r_n` (docs/algorithms.md §1.4), on scenes with closed forms. A ball of
//! radius `R` (`I = 2/5 m R^2`) touches a plane whose frame has x down the slope, y along
//! the normal and z across; its contact carries Coulomb friction and three rows: rolling
//! about x and z, spinning about y. Every step's answer is judged by the tests' own copy of
//! the measure (`common::global_error`), and each check comes with a negative control that
//! breaks the law the check states, which the check must reject.

mod common;

use cadmm::{CscMatrix, GlobalProblem, NewValues, Problem, Settings, Solver, Status};

const G: f64 = 9.81;
const TOL: f64 = 1e-10;
const INF: f64 = f64::INFINITY;
const H: f64 = 0.01;

/// A ball on a plane tilted by `slope` (radians), with Coulomb friction `mu` and the
/// rolling and spinning coefficients `rolling` and `spinning` (lengths; `None` leaves the
/// rows out).
#[derive(Clone, Copy)]
struct Ball {
    mass: f64,
    radius: f64,
    slope: f64,
    mu: f64,
    rolling: Option<f64>,
    spinning: Option<f64>,
    /// The rows' own bounds `[-cap, cap]` (a torque impulse), besides `e r_n`.
    cap: f64,
}

impl Ball {
    fn inertia(&self) -> f64 {
        0.4 * self.mass * self.radius * self.radius
    }

    /// The step's problem from the velocities `v_prev` (`[v; w]`): `M v = f + H r + G lambda`
    /// with `f = M v_prev + h m g`, the contact at `(0, -R, 0)` (its velocity `(v_y, v_x +
    /// R w_z, v_z - R w_x)`, normal first), and the rows on `w_x`, `w_z` (rolling) and `w_y`
    /// (spinning).
    fn problem(&self, v_prev: &[f64]) -> GlobalProblem {
        let (m, i, r) = (self.mass, self.inertia(), self.radius);
        let diag = [m, m, m, i, i, i];
        let mass = CscMatrix::from_triplets(
            "M",
            6,
            6,
            &(0..6).map(|k| (k, k, diag[k])).collect::<Vec<_>>(),
        )
        .unwrap();
        let gravity = [G * self.slope.sin(), -G * self.slope.cos(), 0.0];
        let f: Vec<f64> = (0..6)
            .map(|k| diag[k] * v_prev[k] + if k < 3 { H * m * gravity[k] } else { 0.0 })
            .collect();
        let h = CscMatrix::from_triplets(
            "H",
            6,
            3,
            &[(1, 0, 1.0), (0, 1, 1.0), (5, 1, r), (2, 2, 1.0), (3, 2, -r)],
        )
        .unwrap();
        let mut axes = Vec::new();
        if let Some(e) = self.rolling {
            axes.extend([(3, e), (5, e)]);
        }
        if let Some(e) = self.spinning {
            axes.push((4, e));
        }
        let p = GlobalProblem::new(mass, h, f, vec![0.0; 3], vec![self.mu]).unwrap();
        if axes.is_empty() {
            return p;
        }
        let triplets: Vec<_> = axes
            .iter()
            .enumerate()
            .map(|(k, &(a, _))| (a, k, 1.0))
            .collect();
        let g = CscMatrix::from_triplets("G", 6, axes.len(), &triplets).unwrap();
        p.with_joints(g, vec![0.0; axes.len()])
            .unwrap()
            .with_joint_bounds(vec![-self.cap; axes.len()], vec![self.cap; axes.len()])
            .unwrap()
            .with_joint_friction(
                vec![Some(0); axes.len()],
                axes.iter().map(|&(_, e)| e).collect(),
            )
            .unwrap()
    }
}

/// The 2 kg ball of radius 0.1 m on a 20 degree slope, mu 1 (it rolls without slipping),
/// rolling friction 0.01 m and spinning friction 0.005 m.
fn ball_on_slope() -> Ball {
    Ball {
        mass: 2.0,
        radius: 0.1,
        slope: 20f64.to_radians(),
        mu: 1.0,
        rolling: Some(0.01),
        spinning: Some(0.005),
        cap: INF,
    }
}

/// What a run gives back: the velocities after each step and the last step's multipliers.
struct Run {
    velocities: Vec<Vec<f64>>,
    lambda: Vec<f64>,
    r: Vec<f64>,
}

/// `steps` steps of `ball` from the velocities `v0`, one solver for the whole run (the
/// problem's values change through `update_values`), every answer checked to `TOL`.
fn roll(ball: Ball, v0: [f64; 6], steps: usize) -> Result<Run, String> {
    roll_with(ball, v0, steps, cadmm::LinearSolver::Auto)
}

/// [`roll`] with the v-update backend `linear_solver`.
fn roll_with(
    ball: Ball,
    v0: [f64; 6],
    steps: usize,
    linear_solver: cadmm::LinearSolver,
) -> Result<Run, String> {
    let settings = Settings {
        tolerance: TOL,
        linear_solver,
        ..Default::default()
    };
    let mut v = v0.to_vec();
    let mut p = ball.problem(&v);
    let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
    let mut run = Run {
        velocities: Vec::new(),
        lambda: Vec::new(),
        r: Vec::new(),
    };
    for step in 0..steps {
        if step > 0 {
            p = ball.problem(&v);
            let values = NewValues {
                f: Some(&p.f),
                ..Default::default()
            };
            solver.update_values(&values).unwrap();
        }
        let status = solver.solve().unwrap();
        let s = solver.solution();
        let error = common::global_error(&p, &s.r, &s.v, &s.lambda);
        if status != Status::Solved || error > TOL {
            return Err(format!(
                "step {step} not solved: {status:?}, error {error:e}"
            ));
        }
        v.clone_from(&s.v);
        run.velocities.push(s.v.clone());
        run.lambda.clone_from(&s.lambda);
        run.r.clone_from(&s.r);
    }
    Ok(run)
}

/// Rolling without slipping against the rolling resistance: `a = 5/7 g (sin(theta) - e/R
/// cos(theta))` down the slope, each step exactly `h a` more (the discrete law is the
/// continuous one), `w_z = -v_x / R`.
fn check_rolling(ball: &Ball, run: &Run) -> Result<(), String> {
    let e = ball.rolling.unwrap_or(0.0);
    let a = 5.0 / 7.0 * G * (ball.slope.sin() - e / ball.radius * ball.slope.cos());
    for (k, v) in run.velocities.iter().enumerate() {
        let expected = (k + 1) as f64 * H * a;
        if (v[0] - expected).abs() > 1e-7 * expected.abs().max(1.0) {
            return Err(format!(
                "step {k}: speed {} m/s, expected {expected} (a = {a} m/s^2)",
                v[0]
            ));
        }
        if (v[0] + ball.radius * v[5]).abs() > 1e-8 {
            return Err(format!(
                "step {k}: the ball slips, v_x + R w_z = {}",
                v[0] + ball.radius * v[5]
            ));
        }
    }
    Ok(())
}

#[test]
fn ball_rolls_down_a_slope_at_the_predicted_deceleration() {
    let ball = ball_on_slope();
    let run = roll(ball, [0.0; 6], 100).unwrap();
    check_rolling(&ball, &run).unwrap();
    // The rolling row about z is saturated at e r_n, the others carry nothing.
    let rn = run.r[0];
    assert!((rn - H * ball.mass * G * ball.slope.cos()).abs() < 1e-9 * rn);
    assert!(
        (run.lambda[1] - 0.01 * rn).abs() < 1e-9 * rn,
        "{:?}",
        run.lambda
    );
    assert!(run.lambda[0].abs() < 1e-9 * rn && run.lambda[2].abs() < 1e-9 * rn);

    // Negative control: the same ball without rolling resistance accelerates at 5/7 g
    // sin(theta), which the check must reject.
    let free = Ball {
        rolling: None,
        spinning: None,
        ..ball
    };
    let run = roll(free, [0.0; 6], 100).unwrap();
    let err = check_rolling(&ball, &run).unwrap_err();
    assert!(err.contains("expected"), "{err}");
}

/// The matrix-free backend (every joint row in the splitting) rolls the ball at the same
/// rate and spins the sphere down at the same time.
#[test]
fn matrix_free_backend_rolls_and_spins_the_same() {
    let ball = ball_on_slope();
    let iterative = cadmm::LinearSolver::Iterative;
    check_rolling(&ball, &roll_with(ball, [0.0; 6], 100, iterative).unwrap()).unwrap();
    let floor = Ball { slope: 0.0, ..ball };
    let run = roll_with(floor, [0.0, 0.0, 0.0, 0.0, 10.0, 0.0], 120, iterative).unwrap();
    check_spin_down(&floor, 10.0, &run).unwrap();
}

/// A row's own bounds cap the contact's (Bullet caps its rolling friction so): below
/// `e r_n` the ball rolls at `a = 5/7 (g sin(theta) - cap / (h m R))`.
#[test]
fn own_bounds_cap_the_rolling_resistance() {
    let ball = Ball {
        spinning: None,
        ..ball_on_slope()
    };
    let rn = H * ball.mass * G * ball.slope.cos();
    let capped = Ball {
        cap: 0.4 * 0.01 * rn,
        ..ball
    };
    let run = roll(capped, [0.0; 6], 60).unwrap();
    // The cap is the bound of a coefficient 0.4 e.
    let effective = Ball {
        rolling: Some(0.4 * 0.01),
        ..ball
    };
    check_rolling(&effective, &run).unwrap();
    // Negative control: the uncapped law.
    let err = check_rolling(&ball, &run).unwrap_err();
    assert!(err.contains("expected"), "{err}");
}

/// Below `tan(theta) = e / R` the rolling resistance holds the ball: it stays at rest, the
/// row carrying the torque of the friction force, `h m g sin(theta) R`, inside its bound.
#[test]
fn rolling_resistance_holds_a_ball_on_a_gentle_slope() {
    let ball = Ball {
        mass: 1.5,
        radius: 0.2,
        slope: 3f64.to_radians(),
        mu: 0.8,
        rolling: Some(0.02),
        spinning: None,
        cap: INF,
    };
    let check = |run: &Run| -> Result<(), String> {
        let speed = run
            .velocities
            .iter()
            .map(|v| v[0].abs())
            .fold(0.0, f64::max);
        if speed > 1e-9 {
            return Err(format!("the ball moves, at up to {speed} m/s"));
        }
        let torque = H * ball.mass * G * ball.slope.sin() * ball.radius;
        if (run.lambda[1] - torque).abs() > 1e-8 * torque {
            return Err(format!(
                "holding torque {}, expected {torque}",
                run.lambda[1]
            ));
        }
        Ok(())
    };
    check(&roll(ball, [0.0; 6], 50).unwrap()).unwrap();
    // Negative control: a coefficient below R tan(theta) cannot hold it.
    let weak = Ball {
        rolling: Some(0.5 * ball.radius * ball.slope.tan()),
        ..ball
    };
    let err = check(&roll(weak, [0.0; 6], 50).unwrap()).unwrap_err();
    assert!(err.contains("moves"), "{err}");
}

/// A sphere spinning about the normal on a level floor: spinning friction `e m g` brakes
/// it at a constant rate `e m g / I` and it stops at `T = I w0 / (e m g)`, then stays
/// still (no reversal).
fn check_spin_down(ball: &Ball, w0: f64, run: &Run) -> Result<f64, String> {
    let e = ball.spinning.unwrap_or(0.0);
    let rate = e * ball.mass * G / ball.inertia();
    let mut stopped_at = None;
    for (k, v) in run.velocities.iter().enumerate() {
        let expected = (w0 - (k + 1) as f64 * H * rate).max(0.0);
        if (v[4] - expected).abs() > 1e-8 * w0 {
            return Err(format!(
                "step {k}: spin {} rad/s, expected {expected}",
                v[4]
            ));
        }
        if v[4].abs() <= 1e-8 * w0 && stopped_at.is_none() {
            stopped_at = Some((k + 1) as f64 * H);
        }
    }
    stopped_at.ok_or_else(|| "the sphere never stops".to_string())
}

#[test]
fn sphere_spinning_on_the_floor_stops_at_the_predicted_time() {
    let ball = Ball {
        mass: 1.0,
        radius: 0.1,
        slope: 0.0,
        mu: 0.5,
        rolling: Some(0.01),
        spinning: Some(0.005),
        cap: INF,
    };
    let w0 = 10.0;
    let run = roll(ball, [0.0, 0.0, 0.0, 0.0, w0, 0.0], 120).unwrap();
    let stop = check_spin_down(&ball, w0, &run).unwrap();
    let predicted = ball.inertia() * w0 / (0.005 * ball.mass * G);
    assert!(
        (stop - predicted).abs() <= H,
        "stopped at {stop} s, predicted {predicted} s"
    );

    // Negative control: without spinning friction the sphere spins on.
    let free = Ball {
        spinning: None,
        ..ball
    };
    let run = roll(free, [0.0, 0.0, 0.0, 0.0, w0, 0.0], 120).unwrap();
    let err = check_spin_down(&ball, w0, &run).unwrap_err();
    assert!(err.contains("expected"), "{err}");
}

/// The library's measure and the tests' copy agree on rows bounded by contacts, at
/// answers and at arbitrary points (saturated, inside, past the bounds, negative `r_n`).
#[test]
fn measure_agrees_with_an_independent_copy() {
    let ball = Ball {
        mass: 2.0,
        radius: 0.1,
        slope: 0.3,
        mu: 0.6,
        rolling: Some(0.01),
        spinning: Some(0.004),
        cap: INF,
    };
    let p = ball.problem(&[0.2, 0.0, -0.1, 0.5, 1.0, -2.0]);
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    for _ in 0..40 {
        let r: Vec<f64> = (0..3).map(|_| 0.2 * next()).collect();
        let v: Vec<f64> = (0..6).map(|_| next()).collect();
        let lambda: Vec<f64> = (0..3).map(|_| 0.003 * next()).collect();
        let ours = cadmm::measure::global_error(&p, &r, &v, &lambda);
        let theirs = common::global_error(&p, &r, &v, &lambda);
        assert!(
            (ours - theirs).abs() <= 1e-12 * theirs.max(1.0),
            "{ours} vs {theirs}"
        );
    }
}

/// Two balls in one problem, far apart: the islands split them, each row going with its
/// contact renumbered, and the answer is the one solved whole.
#[test]
fn islands_carry_the_rows_with_their_contacts() {
    let a = ball_on_slope();
    let b = Ball {
        mass: 0.5,
        radius: 0.05,
        rolling: Some(0.002),
        spinning: None,
        ..a
    };
    let pa = a.problem(&[0.3, 0.0, 0.0, 0.0, 4.0, -3.0]);
    let pb = b.problem(&[0.1, 0.0, 0.0, 0.0, 0.0, -2.0]);
    // Second ball first, so that its contact is 0 and the first ball's rows name 1.
    let whole = Problem::block_diagonal(&[Problem::Global(pb), Problem::Global(pa)]).unwrap();
    let Problem::Global(g) = &whole else {
        unreachable!()
    };
    let j = g.joints.as_ref().unwrap();
    assert_eq!(
        j.friction_contact,
        vec![Some(0), Some(0), Some(1), Some(1), Some(1)]
    );
    let solve = |islands: bool| {
        let settings = Settings {
            tolerance: TOL,
            islands,
            ..Default::default()
        };
        let mut s = Solver::new(whole.clone(), settings).unwrap();
        assert_eq!(s.solve().unwrap(), Status::Solved);
        let out = s.solution().clone();
        assert!(common::global_error(g, &out.r, &out.v, &out.lambda) <= TOL);
        out
    };
    let (split, one) = (solve(true), solve(false));
    for (x, y) in split
        .lambda
        .iter()
        .zip(&one.lambda)
        .chain(split.v.iter().zip(&one.v))
    {
        assert!((x - y).abs() < 1e-7, "{x} vs {y}");
    }
}

#[test]
fn bad_rows_are_refused_by_name() {
    let ball = Ball {
        mass: 1.0,
        radius: 0.1,
        slope: 0.0,
        mu: 0.5,
        rolling: Some(0.01),
        spinning: None,
        cap: INF,
    };
    let p = ball.problem(&[0.0; 6]);
    let j = p.joints.clone().unwrap();
    let refuse = |contact: Vec<Option<usize>>, e: Vec<f64>, field: &str| {
        let err = p
            .clone()
            .with_joint_friction(contact, e)
            .unwrap_err()
            .to_string();
        assert!(err.contains(field), "{err}");
    };
    refuse(vec![Some(1), None], vec![0.01, 0.0], "friction_contact");
    refuse(vec![Some(0), Some(0)], vec![-0.01, 0.0], "negative");
    refuse(vec![Some(0), None], vec![0.01, 0.02], "without a contact");
    refuse(vec![Some(0)], vec![0.01], "friction_contact");
    // Own bounds that exclude zero on a row bounded by a contact.
    let err = GlobalProblem {
        joints: None,
        ..p.clone()
    }
    .with_joints(j.g.clone(), j.b.clone())
    .unwrap()
    .with_joint_bounds(vec![0.1, -INF], vec![INF, INF])
    .unwrap()
    .with_joint_friction(j.friction_contact.clone(), j.friction.clone())
    .unwrap_err()
    .to_string();
    assert!(err.contains("exclude zero"), "{err}");
    // Newton alone cannot take such rows; an update cannot give them bounds that exclude
    // zero, nor a negative coefficient.
    let newton = Settings {
        variant: cadmm::VariantChoice::Newton,
        ..Default::default()
    };
    let err = match Solver::new(Problem::Global(p.clone()), newton) {
        Ok(_) => panic!("Newton alone took rows bounded by a contact"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("rolling or spinning"), "{err}");
    let mut solver = Solver::new(Problem::Global(p.clone()), Settings::default()).unwrap();
    let lo = [0.5, -INF];
    let values = NewValues {
        lo: Some(&lo),
        ..Default::default()
    };
    let err = solver.update_values(&values).unwrap_err().to_string();
    assert!(err.contains("exclude zero"), "{err}");
    let e = [-1.0, 0.0];
    let values = NewValues {
        friction: Some(&e),
        ..Default::default()
    };
    let err = solver.update_values(&values).unwrap_err().to_string();
    assert!(err.contains("negative"), "{err}");
}
