//! Bounded and compliant joint rows on scenes with closed forms: one rigid body (six
//! velocities, `M = diag(m, m, m, I, I, I)`, no contact) held by equality rows (a hinge
//! about z at a pivot, or a slider along y) plus the row under test. Every step's answer
//! is judged by the tests' own copy of the measure (`common::global_error`), and each
//! check comes with a negative control: a scene that breaks the law the check states,
//! which the check must reject with its message.

mod common;

use cadmm::{CscMatrix, GlobalProblem, Problem, Settings, Solver, Status};
use std::f64::consts::PI;

const G: f64 = 9.81;
const TOL: f64 = 1e-10;
const INF: f64 = f64::INFINITY;

/// One joint row: its column of `G` (6 entries), `b`, bounds and compliance.
#[derive(Clone, Copy)]
struct Row {
    col: [f64; 6],
    b: f64,
    lo: f64,
    hi: f64,
    c: f64,
}

impl Row {
    fn equality(col: [f64; 6]) -> Self {
        Row {
            col,
            b: 0.0,
            lo: -INF,
            hi: INF,
            c: 0.0,
        }
    }
}

/// `e_k` in the six velocities.
fn unit(k: usize) -> [f64; 6] {
    let mut e = [0.0; 6];
    e[k] = 1.0;
    e
}

/// The rows of a hinge about z at a pivot `r` from the centre of mass: the pivot's
/// velocity `v + w x r` (its component `a` is `[e_a; r x e_a] . [v; w]`), then `w_x`, `w_y`.
fn hinge(r: [f64; 3]) -> Vec<Row> {
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let mut rows: Vec<Row> = (0..3)
        .map(|a| {
            let mut e = [0.0; 3];
            e[a] = 1.0;
            let rxe = cross(r, e);
            Row::equality([e[0], e[1], e[2], rxe[0], rxe[1], rxe[2]])
        })
        .collect();
    rows.push(Row::equality(unit(3)));
    rows.push(Row::equality(unit(4)));
    rows
}

/// A slider along y: `v_x`, `v_z` and the angular velocity held.
fn slider() -> Vec<Row> {
    [0, 2, 3, 4, 5].map(|k| Row::equality(unit(k))).to_vec()
}

/// One step of the body: `M v = f + G lambda` with `f = M v_prev + h F`, gravity along -y.
struct Body {
    mass: f64,
    inertia: f64,
    h: f64,
}

/// What a step gives back: the velocities and the rows' multipliers.
struct Step {
    v: Vec<f64>,
    lambda: Vec<f64>,
}

impl Body {
    /// The step's problem: `M v = f + G lambda` with `f = M v_prev + h F`.
    fn problem(&self, v_prev: &[f64], rows: &[Row]) -> GlobalProblem {
        let (m, i, h) = (self.mass, self.inertia, self.h);
        let diag = [m, m, m, i, i, i];
        let mass = CscMatrix::from_triplets(
            "M",
            6,
            6,
            &(0..6).map(|k| (k, k, diag[k])).collect::<Vec<_>>(),
        )
        .unwrap();
        let f: Vec<f64> = (0..6)
            .map(|k| diag[k] * v_prev[k] - if k == 1 { h * m * G } else { 0.0 })
            .collect();
        let triplets: Vec<(usize, usize, f64)> = rows
            .iter()
            .enumerate()
            .flat_map(|(k, row)| {
                (0..6)
                    .filter(|&a| row.col[a] != 0.0)
                    .map(move |a| (a, k, row.col[a]))
            })
            .collect();
        let g = CscMatrix::from_triplets("G", 6, rows.len(), &triplets).unwrap();
        let no_contact = CscMatrix::from_triplets("H", 6, 0, &[]).unwrap();
        GlobalProblem::new(mass, no_contact, f, vec![], vec![])
            .unwrap()
            .with_joints(g, rows.iter().map(|r| r.b).collect())
            .unwrap()
            .with_joint_bounds(
                rows.iter().map(|r| r.lo).collect(),
                rows.iter().map(|r| r.hi).collect(),
            )
            .unwrap()
            .with_joint_compliance(rows.iter().map(|r| r.c).collect())
            .unwrap()
    }

    fn step(&self, v_prev: &[f64], rows: &[Row]) -> Result<Step, String> {
        let p = self.problem(v_prev, rows);
        let settings = Settings {
            tolerance: TOL,
            ..Default::default()
        };
        let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
        let status = solver.solve().unwrap();
        let s = solver.solution();
        let error = common::global_error(&p, &s.r, &s.v, &s.lambda);
        if status != Status::Solved || error > TOL {
            return Err(format!("step not solved: {status:?}, error {error:e}"));
        }
        Ok(Step {
            v: s.v.clone(),
            lambda: s.lambda.clone(),
        })
    }
}

/// The rod of the pendulum scenes: 2 kg, 1 m, hinged at one end, its centre of mass at
/// angle `theta` from the x axis; `I` about the centre `m L^2 / 12`.
const ROD_MASS: f64 = 2.0;
const ROD_LENGTH: f64 = 1.0;

fn rod() -> Body {
    Body {
        mass: ROD_MASS,
        inertia: ROD_MASS * ROD_LENGTH * ROD_LENGTH / 12.0,
        h: 0.01,
    }
}

/// The pivot seen from the centre of mass at angle `theta`.
fn pivot_at(theta: f64) -> [f64; 3] {
    let half = ROD_LENGTH / 2.0;
    [-half * theta.cos(), -half * theta.sin(), 0.0]
}

/// Gravity's torque about the pivot at angle `theta`, `m g L/2 cos(theta)` (clockwise).
fn load_torque(theta: f64) -> f64 {
    ROD_MASS * G * ROD_LENGTH / 2.0 * theta.cos()
}

/// The pendulum released at 60 degrees and falling onto a limit `theta >= 0` (the limit row
/// `w_z + theta / h >= 0`, multiplier in `[0, inf)`) when `limit`, for 1.5 s: the angles
/// and, at the end, the limit's multiplier.
fn pendulum_onto_limit(limit: bool) -> Result<(Vec<f64>, f64), String> {
    let body = rod();
    let (mut theta, mut v) = (PI / 3.0, vec![0.0; 6]);
    let mut angles = vec![theta];
    let mut last_lambda = 0.0;
    for _ in 0..150 {
        let mut rows = hinge(pivot_at(theta));
        if limit {
            rows.push(Row {
                col: unit(5),
                b: theta / body.h,
                lo: 0.0,
                hi: INF,
                c: 0.0,
            });
        }
        let step = body.step(&v, &rows)?;
        theta += body.h * step.v[5];
        angles.push(theta);
        last_lambda = step.lambda.get(5).copied().unwrap_or(0.0);
        v = step.v;
    }
    Ok((angles, last_lambda))
}

/// The limit's law: the angle never goes below the limit, the pendulum ends on it, and the
/// limit then carries the load's torque, `lambda = h m g L/2`.
fn check_limit(angles: &[f64], lambda: f64, h: f64) -> Result<(), String> {
    let lowest = angles.iter().copied().fold(INF, f64::min);
    if lowest < -1e-9 {
        return Err(format!(
            "went through its limit: lowest angle {lowest:e} rad"
        ));
    }
    let last = *angles.last().unwrap();
    if last.abs() > 1e-9 {
        return Err(format!("does not rest on its limit: ends at {last:e} rad"));
    }
    let expected = h * load_torque(0.0);
    if (lambda - expected).abs() > 1e-7 * expected {
        return Err(format!("limit impulse {lambda}, expected {expected}"));
    }
    Ok(())
}

#[test]
fn hinge_pendulum_falls_onto_its_limit_and_rests_there_with_the_load_torque() {
    let (angles, lambda) = pendulum_onto_limit(true).unwrap();
    check_limit(&angles, lambda, rod().h).unwrap();
    // Negative control: without the limit row the rod swings through.
    let (free, lambda) = pendulum_onto_limit(false).unwrap();
    let message = check_limit(&free, lambda, rod().h).unwrap_err();
    assert!(message.contains("went through its limit"), "{message}");
}

/// A load of 3 kg on a slider along y, lifted by a motor (the row `v_y - target`, its
/// multiplier in `[-F h, F h]`) from rest for 0.3 s: the velocity at each step and the
/// motor's multiplier.
fn motor_lift(force: f64, bounded: bool) -> Result<Vec<(f64, f64)>, String> {
    let body = Body {
        mass: 3.0,
        inertia: 0.1,
        h: 0.01,
    };
    let target = 0.5;
    let mut rows = slider();
    let limit = if bounded { force * body.h } else { INF };
    rows.push(Row {
        col: unit(1),
        b: -target,
        lo: -limit,
        hi: limit,
        c: 0.0,
    });
    let mut v = vec![0.0; 6];
    let mut out = Vec::new();
    for _ in 0..30 {
        let step = body.step(&v, &rows)?;
        out.push((step.v[1], step.lambda[5]));
        v = step.v;
    }
    Ok(out)
}

/// The motor's law: saturated at `F` the load accelerates at `F/m - g` until it reaches
/// the target velocity, which it then keeps with the impulse `m g h`.
fn check_motor(steps: &[(f64, f64)], force: f64) -> Result<(), String> {
    let (m, h, target) = (3.0, 0.01, 0.5);
    let mut predicted = 0.0_f64;
    for (k, &(v, lambda)) in steps.iter().enumerate() {
        let saturated = predicted + h * (force / m - G);
        let (v_expected, lambda_expected) = if saturated < target {
            (saturated, force * h)
        } else {
            (target, m * (target - predicted) + m * G * h)
        };
        predicted = v_expected;
        if (v - v_expected).abs() > 1e-8 || (lambda - lambda_expected).abs() > 1e-8 {
            return Err(format!(
                "step {k}: v = {v}, lambda = {lambda}; expected {v_expected} and {lambda_expected}"
            ));
        }
    }
    if (predicted - target).abs() > 1e-12 {
        return Err(format!("the load never reached {target} m/s"));
    }
    Ok(())
}

#[test]
fn motor_lifts_its_load_saturated_then_at_the_target_velocity() {
    let force = 45.0;
    check_motor(&motor_lift(force, true).unwrap(), force).unwrap();
    // Negative control: a motor without its force limit reaches the target at once.
    let message = check_motor(&motor_lift(force, false).unwrap(), force).unwrap_err();
    assert!(message.starts_with("step 0:"), "{message}");
}

/// The rod held horizontal by dry joint friction (the row `w_z`, its multiplier in
/// `[-F h, F h]` with `F` a share of the load's torque) from rest for 0.2 s: the angular
/// velocities and the friction's multipliers.
fn dry_friction(share: f64) -> Result<Vec<(f64, f64)>, String> {
    let body = rod();
    let limit = share * load_torque(0.0) * body.h;
    let (mut theta, mut v) = (0.0, vec![0.0; 6]);
    let mut out = Vec::new();
    for _ in 0..20 {
        let mut rows = hinge(pivot_at(theta));
        rows.push(Row {
            col: unit(5),
            b: 0.0,
            lo: -limit,
            hi: limit,
            c: 0.0,
        });
        let step = body.step(&v, &rows)?;
        theta += body.h * step.v[5];
        out.push((step.v[5], step.lambda[5]));
        v = step.v;
    }
    Ok(out)
}

/// Holding: no rotation, and the friction carries the load's torque, `lambda = h m g L/2`.
fn check_holds(steps: &[(f64, f64)]) -> Result<(), String> {
    let expected = rod().h * load_torque(0.0);
    for (k, &(w, lambda)) in steps.iter().enumerate() {
        if w.abs() > 1e-9 || (lambda - expected).abs() > 1e-7 * expected {
            return Err(format!("slipped at step {k}: w = {w}, lambda = {lambda}"));
        }
    }
    Ok(())
}

/// Slipping from rest: the first step's angular velocity is `-h (tau - F) / I_pivot`, with
/// `I_pivot = I + m (L/2)^2`, and the friction is at its bound.
fn check_slips(steps: &[(f64, f64)], share: f64) -> Result<(), String> {
    let body = rod();
    let tau = load_torque(0.0);
    let i_pivot = body.inertia + ROD_MASS * (ROD_LENGTH / 2.0).powi(2);
    let expected = -body.h * (tau - share * tau) / i_pivot;
    let (w, lambda) = steps[0];
    if (w - expected).abs() > 1e-8 * expected.abs() {
        return Err(format!("first step w = {w}, expected {expected}"));
    }
    if (lambda - share * tau * body.h).abs() > 1e-9 {
        return Err(format!("friction {lambda} is not at its bound"));
    }
    Ok(())
}

#[test]
fn dry_joint_friction_holds_below_its_limit_and_slips_above() {
    let holding = dry_friction(1.25).unwrap();
    let slipping = dry_friction(0.75).unwrap();
    check_holds(&holding).unwrap();
    check_slips(&slipping, 0.75).unwrap();
    // Negative controls: each law rejects the other scene.
    let message = check_holds(&slipping).unwrap_err();
    assert!(message.starts_with("slipped at step 0"), "{message}");
    let message = check_slips(&holding, 1.25).unwrap_err();
    assert!(message.starts_with("first step"), "{message}");
}

/// A 1 kg load on a slider along y held by a spring of stiffness `k` to `y = 0`: the
/// compliant equality row `v_y + y/h + c lambda = 0` with `c = 1 / (h^2 k)` (implicit
/// Euler's spring, `lambda = -h k y_next`). Released at `y = 0.1` without gravity's
/// effect on the period (it shifts the rest position only), for 4.5 s: the periods between
/// upward crossings of the rest position.
fn spring_periods(stiffness: f64) -> Result<Vec<f64>, String> {
    let body = Body {
        mass: 1.0,
        inertia: 0.1,
        h: 1e-3,
    };
    let rest = -body.mass * G / stiffness;
    let (mut y, mut v) = (0.1, vec![0.0; 6]);
    let mut crossings = Vec::new();
    for k in 0..4500 {
        let mut rows = slider();
        rows.push(Row {
            col: unit(1),
            b: y / body.h,
            lo: -INF,
            hi: INF,
            c: 1.0 / (body.h * body.h * stiffness),
        });
        let step = body.step(&v, &rows)?;
        let y_next = y + body.h * step.v[1];
        if y < rest && y_next >= rest {
            // Linear interpolation of the crossing time within the step.
            crossings.push((k as f64 + (rest - y) / (y_next - y)) * body.h);
        }
        y = y_next;
        v = step.v;
    }
    Ok(crossings.windows(2).map(|w| w[1] - w[0]).collect())
}

/// The spring's law: every period within 0.2% of `2 pi sqrt(m / k)`.
fn check_period(periods: &[f64], expected: f64) -> Result<(), String> {
    if periods.is_empty() {
        return Err("no whole period seen".into());
    }
    for &t in periods {
        if (t - expected).abs() > 2e-3 * expected {
            return Err(format!("period {t} s, expected {expected} s"));
        }
    }
    Ok(())
}

#[test]
fn soft_constraint_oscillates_at_its_spring_frequency() {
    let k = 4.0 * PI * PI; // a period of 1 s for 1 kg
    check_period(&spring_periods(k).unwrap(), 1.0).unwrap();
    // Negative control: a quarter of the stiffness doubles the period.
    let message = check_period(&spring_periods(k / 4.0).unwrap(), 1.0).unwrap_err();
    assert!(message.starts_with("period"), "{message}");
}

#[test]
fn bad_bounds_and_compliance_are_named() {
    let m = CscMatrix::from_triplets("M", 1, 1, &[(0, 0, 1.0)]).unwrap();
    let h = CscMatrix::from_triplets("H", 1, 0, &[]).unwrap();
    let g = CscMatrix::from_triplets("G", 1, 2, &[(0, 0, 1.0), (0, 1, 1.0)]).unwrap();
    let p = GlobalProblem::new(m, h, vec![1.0], vec![], vec![])
        .unwrap()
        .with_joints(g, vec![0.0, 0.0])
        .unwrap();
    let err = |r: Result<GlobalProblem, cadmm::Error>| r.unwrap_err().to_string();
    let above = err(p.clone().with_joint_bounds(vec![0.0, 2.0], vec![1.0, 1.0]));
    assert!(
        above.contains("hi") && above.contains("lower bound above upper bound"),
        "{above}"
    );
    let nan = err(p
        .clone()
        .with_joint_bounds(vec![f64::NAN, 0.0], vec![1.0, 1.0]));
    assert!(nan.contains("lo") && nan.contains("NaN"), "{nan}");
    let short = err(p.clone().with_joint_bounds(vec![0.0], vec![1.0]));
    assert!(short.contains("lo"), "{short}");
    let negative = err(p.clone().with_joint_compliance(vec![0.0, -1.0]));
    assert!(
        negative.contains("compliance") && negative.contains("negative"),
        "{negative}"
    );
    // Bounds set in the public field after construction are checked by the solver.
    let mut q = p
        .with_joint_bounds(vec![0.0, -1.0], vec![INF, 1.0])
        .unwrap();
    q.joints.as_mut().unwrap().hi[1] = -INF;
    let message = Solver::new(Problem::Global(q), Settings::default())
        .err()
        .expect("refused")
        .to_string();
    assert!(message.contains("upper bound is -inf"), "{message}");
}

/// The library's measure and the tests' own copy agree on problems with contacts, equality
/// rows, bounded rows and compliance, at answers near and far from a solution (each
/// bounded row's multiplier inside, at or beyond a bound).
#[test]
fn the_measure_of_joint_rows_matches_the_independent_copy() {
    let mut rng = common::Rng::new(44);
    for case in 0..40 {
        let n = 6;
        let nc = 2;
        let np = 5;
        let mass = CscMatrix::from_triplets(
            "M",
            n,
            n,
            &(0..n)
                .map(|k| (k, k, 1.5 + 0.5 * rng.uniform()))
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let dense = |rng: &mut common::Rng, rows: usize, cols: usize| {
            let t: Vec<(usize, usize, f64)> = (0..rows)
                .flat_map(|i| (0..cols).map(move |j| (i, j)))
                .map(|(i, j)| (i, j, rng.uniform() - 0.5))
                .collect();
            CscMatrix::from_triplets("A", rows, cols, &t).unwrap()
        };
        let h = dense(&mut rng, n, 3 * nc);
        let g = dense(&mut rng, n, np);
        let vec = |rng: &mut common::Rng, len: usize| {
            (0..len).map(|_| rng.uniform() - 0.5).collect::<Vec<f64>>()
        };
        let (f, w, b) = (vec(&mut rng, n), vec(&mut rng, 3 * nc), vec(&mut rng, np));
        // Rows: an equality, a compliant equality, a limit, a motor, an upper bound only.
        let lo = vec![-INF, -INF, 0.0, -0.3, -INF];
        let hi = vec![INF, INF, INF, 0.3, 0.2];
        let c = vec![0.0, 0.5, 0.0, 0.1 * rng.uniform().abs(), 0.0];
        let p = GlobalProblem::new(mass, h, f, w, vec![0.4, 0.0])
            .unwrap()
            .with_joints(g, b)
            .unwrap()
            .with_joint_bounds(lo, hi)
            .unwrap()
            .with_joint_compliance(c)
            .unwrap();
        let scale = if case % 2 == 0 { 1e-3 } else { 1.0 };
        let r = vec(&mut rng, 3 * nc)
            .iter()
            .map(|x| x * scale)
            .collect::<Vec<_>>();
        let v = vec(&mut rng, n);
        let lambda = vec(&mut rng, np);
        let ours = cadmm::measure::global_error(&p, &r, &v, &lambda);
        let theirs = common::global_error(&p, &r, &v, &lambda);
        assert!(
            (ours - theirs).abs() <= 1e-12 * theirs.max(1.0),
            "case {case}: {ours} against {theirs}"
        );
    }
}

/// A solver built for one motor takes another's bounds and compliance through
/// `update_values` and answers as a solver built for it; which rows are bounded cannot
/// change, and a refused update changes nothing.
#[test]
fn update_values_takes_new_bounds_and_compliance() {
    use cadmm::NewValues;
    let body = Body {
        mass: 3.0,
        inertia: 0.1,
        h: 0.01,
    };
    let problem = |limit: f64, c: f64| {
        let mut rows = slider();
        rows.push(Row {
            col: unit(1),
            b: -0.5,
            lo: -limit,
            hi: limit,
            c,
        });
        body.problem(&[0.0; 6], &rows)
    };
    let settings = Settings {
        tolerance: TOL,
        ..Default::default()
    };
    let answer = |solver: &mut Solver| {
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        solver.solution().clone()
    };
    let mut kept = Solver::new(Problem::Global(problem(0.45, 0.0)), settings.clone()).unwrap();
    answer(&mut kept);
    let (lo, hi, c) = (
        [-INF, -INF, -INF, -INF, -INF, -0.2],
        [INF, INF, INF, INF, INF, 0.2],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.05],
    );
    kept.update_values(&NewValues {
        lo: Some(&lo),
        hi: Some(&hi),
        compliance: Some(&c),
        ..Default::default()
    })
    .unwrap();
    let updated = answer(&mut kept);
    let fresh = answer(&mut Solver::new(Problem::Global(problem(0.2, 0.05)), settings).unwrap());
    assert!(
        (updated.lambda[5] - 0.2).abs() < 1e-9,
        "{:?}",
        updated.lambda
    );
    for (a, b) in updated.v.iter().zip(&fresh.v) {
        assert!(
            (a - b).abs() < 1e-9,
            "{:?} against {:?}",
            updated.v,
            fresh.v
        );
    }
    // An equality made a bounded row is a new pattern; the solver keeps its values.
    let mut widened = lo;
    widened[0] = 0.0;
    let err = kept
        .update_values(&NewValues {
            lo: Some(&widened),
            ..Default::default()
        })
        .unwrap_err();
    assert!(matches!(err, cadmm::Error::PatternChanged { .. }), "{err}");
    let again = answer(&mut kept);
    assert_eq!(again.lambda, updated.lambda);
}

/// Two motors on separate bodies, one scene (no contact: solved as the scene's contact-free
/// part), each with its own bounded row; an update of the whole scene's bounds reaches
/// each row.
#[test]
fn bounded_rows_split_into_islands_and_take_updates() {
    use cadmm::NewValues;
    let body = Body {
        mass: 3.0,
        inertia: 0.1,
        h: 0.01,
    };
    let motor = |limit: f64| {
        let mut rows = slider();
        rows.push(Row {
            col: unit(1),
            b: -0.5,
            lo: -limit,
            hi: limit,
            c: 0.0,
        });
        Problem::Global(body.problem(&[0.0; 6], &rows))
    };
    let scene = Problem::block_diagonal(&[motor(0.45), motor(0.2)]).unwrap();
    let settings = Settings {
        tolerance: TOL,
        ..Default::default()
    };
    let mut solver = Solver::new(scene, settings).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    // Saturated, both: reaching 0.5 m/s from rest takes m (0.5 + g h) = 1.79 N s.
    let lambda = &solver.solution().lambda;
    assert!(
        (lambda[5] - 0.45).abs() < 1e-9 && (lambda[11] - 0.2).abs() < 1e-9,
        "{lambda:?}"
    );
    let mut lo = [f64::NEG_INFINITY; 12];
    let mut hi = [INF; 12];
    (lo[5], hi[5], lo[11], hi[11]) = (-0.1, 0.1, -0.3, 0.3);
    solver
        .update_values(&NewValues {
            lo: Some(&lo),
            hi: Some(&hi),
            ..Default::default()
        })
        .unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let lambda = &solver.solution().lambda;
    assert!(
        (lambda[5] - 0.1).abs() < 1e-9 && (lambda[11] - 0.3).abs() < 1e-9,
        "{lambda:?}"
    );
}

/// Two blocks on the ground, each pushed by a motor against friction (the C test's scene:
/// unit mass, `f = (-9.81, 0, 0)`, `mu = 0.5`, the motor the row `v_1 - 0.3`): two contact
/// islands, each carrying its bounded row. The strong motor (limit 6) slides its block at
/// the target with `lambda = 0.3 + 4.905`; the weak one (limit 3) saturates while friction
/// holds its block.
#[test]
fn islands_carry_their_bounded_rows() {
    let block = |limit: f64| {
        let eye =
            CscMatrix::from_triplets("I", 3, 3, &[(0, 0, 1.0), (1, 1, 1.0), (2, 2, 1.0)]).unwrap();
        let g = CscMatrix::from_triplets("G", 3, 1, &[(1, 0, 1.0)]).unwrap();
        let p = GlobalProblem::new(
            eye.clone(),
            eye,
            vec![-9.81, 0.0, 0.0],
            vec![0.0; 3],
            vec![0.5],
        )
        .unwrap()
        .with_joints(g, vec![-0.3])
        .unwrap()
        .with_joint_bounds(vec![-limit], vec![limit])
        .unwrap();
        Problem::Global(p)
    };
    let scene = Problem::block_diagonal(&[block(6.0), block(3.0)]).unwrap();
    let settings = Settings {
        tolerance: TOL,
        ..Default::default()
    };
    let mut solver = Solver::new(scene.clone(), settings).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    assert_eq!(solver.island_stats().len(), 2, "one island per block");
    let s = solver.solution();
    let Problem::Global(p) = &scene else {
        unreachable!()
    };
    assert!(common::global_error(p, &s.r, &s.v, &s.lambda) <= TOL);
    assert!(
        (s.lambda[0] - 5.205).abs() < 1e-7 && (s.v[1] - 0.3).abs() < 1e-7,
        "{s:?}"
    );
    assert!(
        (s.lambda[1] - 3.0).abs() < 1e-7 && s.v[4].abs() < 1e-7,
        "{s:?}"
    );
}

/// A block pushed by a motor (an equality row) beside a block with no joint row: two
/// islands, the second a problem without joints. An update of the whole scene's joint
/// values reaches the first and leaves the second alone (it was refused once an island's
/// coupled solver took its share: an engine's chain hitting a box, its step refused).
#[test]
fn an_island_without_joint_rows_takes_the_scene_s_updates() {
    use cadmm::NewValues;
    let eye =
        CscMatrix::from_triplets("I", 3, 3, &[(0, 0, 1.0), (1, 1, 1.0), (2, 2, 1.0)]).unwrap();
    let block = || {
        GlobalProblem::new(
            eye.clone(),
            eye.clone(),
            vec![-9.81, 0.0, 0.0],
            vec![0.0; 3],
            vec![0.5],
        )
        .unwrap()
    };
    let g = CscMatrix::from_triplets("G", 3, 1, &[(1, 0, 1.0)]).unwrap();
    let driven = Problem::Global(block().with_joints(g, vec![-0.3]).unwrap());
    let scene = Problem::block_diagonal(&[driven, Problem::Global(block())]).unwrap();
    let Problem::Global(whole) = &scene else {
        unreachable!()
    };
    for newton_polish in [false, true] {
        let settings = Settings {
            tolerance: TOL,
            newton_polish: Some(newton_polish),
            ..Default::default()
        };
        let mut solver = Solver::new(scene.clone(), settings).unwrap();
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        assert_eq!(solver.island_stats().len(), 2, "one island per block");
        // The motor's target from 0.3 to 0.4 m/s; G given again as it was.
        let joints = whole.joints.as_ref().unwrap();
        let mut next = whole.clone();
        next.joints.as_mut().unwrap().b = vec![-0.4];
        solver
            .update_values(&NewValues {
                g: Some(joints.g.values()),
                b: Some(&[-0.4]),
                f: Some(&whole.f),
                ..Default::default()
            })
            .unwrap_or_else(|e| panic!("newton_polish {newton_polish}: {e}"));
        assert_eq!(solver.solve().unwrap(), Status::Solved);
        let s = solver.solution();
        assert!(common::global_error(&next, &s.r, &s.v, &s.lambda) <= TOL);
        // Sliding at the target against friction mu m g: lambda = 0.4 + 4.905; the other
        // block rests.
        assert!(
            (s.lambda[0] - 5.305).abs() < 1e-7 && (s.v[1] - 0.4).abs() < 1e-7,
            "{s:?}"
        );
        assert!(s.v[3..].iter().all(|v| v.abs() < 1e-7), "{s:?}");
    }
}

/// A random scene of point masses on the ground (one contact each, friction 0.3 to 0.8),
/// pushed sideways, and joint rows between neighbours of every kind: equalities, limits
/// `[0, inf)`, boxes `[-F, F]`, with and without compliance. Seeds vary the data.
fn random_scene(seed: u64, bodies: usize) -> GlobalProblem {
    let mut rng = common::Rng::new(seed);
    let n = 3 * bodies;
    let mass: Vec<(usize, usize, f64)> =
        (0..n).map(|i| (i, i, 1.0 + 0.9 * rng.uniform())).collect();
    let m = CscMatrix::from_triplets("M", n, n, &mass).unwrap();
    let h = CscMatrix::from_triplets("H", n, n, &(0..n).map(|i| (i, i, 1.0)).collect::<Vec<_>>())
        .unwrap();
    let f: Vec<f64> = (0..bodies)
        .flat_map(|_| {
            [
                -9.81 + rng.uniform(),
                3.0 * rng.uniform(),
                3.0 * rng.uniform(),
            ]
        })
        .collect();
    let mu: Vec<f64> = (0..bodies).map(|_| 0.55 + 0.25 * rng.uniform()).collect();
    // Rows between body a and a + 1 along a random tangential axis: v_a - v_{a+1} + b.
    let (mut g, mut b, mut lo, mut hi, mut c) = (vec![], vec![], vec![], vec![], vec![]);
    for a in 0..bodies - 1 {
        let k = b.len();
        let axis = 1 + (a % 2);
        g.push((3 * a + axis, k, 1.0));
        g.push((3 * (a + 1) + axis, k, -1.0));
        b.push(0.5 * rng.uniform());
        let (l, u) = match a % 3 {
            0 => (f64::NEG_INFINITY, INF),
            1 => (0.0, INF),
            _ => (-1.0 - rng.uniform().abs(), 1.0 + rng.uniform().abs()),
        };
        lo.push(l);
        hi.push(u);
        c.push(if a % 4 == 3 {
            0.05 * rng.uniform().abs()
        } else {
            0.0
        });
    }
    let g = CscMatrix::from_triplets("G", n, b.len(), &g).unwrap();
    GlobalProblem::new(m, h, f, vec![0.0; n], mu)
        .unwrap()
        .with_joints(g, b)
        .unwrap()
        .with_joint_bounds(lo, hi)
        .unwrap()
        .with_joint_compliance(c)
        .unwrap()
}

/// Newton alone, `auto` (ADMM finished by Newton) and ADMM alone all solve the random
/// scenes with bounded rows, each answer re-measured by the independent copy; Newton alone
/// takes few steps (its mid-function for the bounded rows converges like the cones').
#[test]
fn newton_solves_bounded_rows_with_contacts() {
    use cadmm::VariantChoice;
    for seed in 1..=6 {
        let p = random_scene(seed, 12);
        for (name, variant, newton_polish) in [
            ("newton", "newton", None),
            ("auto", "auto", None),
            ("admm", "auto", Some(false)),
        ] {
            let settings = Settings {
                tolerance: TOL,
                variant: VariantChoice::from_name(variant).unwrap(),
                newton_polish,
                ..Default::default()
            };
            let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
            let status = solver.solve().unwrap();
            let (s, stats) = (solver.solution(), solver.stats());
            let error = common::global_error(&p, &s.r, &s.v, &s.lambda);
            assert_eq!(status, Status::Solved, "seed {seed} {name}: {stats:?}");
            assert!(
                error <= TOL,
                "seed {seed} {name}: independent error {error:e}"
            );
            if name == "newton" {
                assert!(stats.newton_iterations <= 30, "seed {seed}: {stats:?}");
            }
            let clamped = (0..s.lambda.len())
                .filter(|&k| {
                    let j = p.joints.as_ref().unwrap();
                    j.is_bounded(k) && (s.lambda[k] == j.lo[k] || s.lambda[k] == j.hi[k])
                })
                .count();
            println!(
                "seed {seed} {name}: {} iterations, {} Newton steps, {clamped} rows at a bound",
                stats.iterations, stats.newton_iterations
            );
        }
    }
}

/// The matrix-free backend holds every joint row in the splitting (equalities as rows with
/// infinite bounds): it solves the random scenes of every kind of row to the tolerance by
/// the independent copy, through conjugate gradients, to the factorized backend's answer;
/// and it takes new bounds and compliances through an update.
#[test]
fn matrix_free_backend_solves_every_kind_of_row() {
    use cadmm::{LinearSolver, NewValues};
    for seed in 1..=6 {
        let p = random_scene(seed, 12);
        let solve = |linear_solver| {
            let settings = Settings {
                tolerance: TOL,
                linear_solver,
                ..Default::default()
            };
            let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
            let status = solver.solve().unwrap();
            let (s, stats) = (solver.solution().clone(), *solver.stats());
            let error = common::global_error(&p, &s.r, &s.v, &s.lambda);
            assert_eq!(
                status,
                Status::Solved,
                "seed {seed} {linear_solver:?}: {stats:?}"
            );
            assert!(
                error <= TOL,
                "seed {seed} {linear_solver:?}: error {error:e}"
            );
            (s, stats, solver)
        };
        let (iterative, stats, mut solver) = solve(LinearSolver::Iterative);
        assert!(
            stats.linear_iterations > 0,
            "seed {seed}: no conjugate gradients: {stats:?}"
        );
        let (direct, ..) = solve(LinearSolver::Direct);
        let apart = iterative
            .v
            .iter()
            .zip(&direct.v)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(apart < 1e-6, "seed {seed}: velocities {apart:e} apart");
        println!(
            "seed {seed}: matrix-free {} iterations, {} CG iterations; {apart:.1e} from the \
             factorized answer",
            stats.iterations, stats.linear_iterations
        );
        // New bounds (the same rows bounded) and compliances, through the update.
        let j = p.joints.as_ref().unwrap();
        let lo: Vec<f64> =
            j.lo.iter()
                .map(|&l| if l.is_finite() { 0.5 * l } else { l })
                .collect();
        let hi: Vec<f64> =
            j.hi.iter()
                .map(|&h| if h.is_finite() { 0.5 * h } else { h })
                .collect();
        let c: Vec<f64> = j.compliance.iter().map(|&c| 2.0 * c).collect();
        let values = NewValues {
            lo: Some(&lo),
            hi: Some(&hi),
            compliance: Some(&c),
            ..Default::default()
        };
        solver.update_values(&values).unwrap();
        assert_eq!(
            solver.solve().unwrap(),
            Status::Solved,
            "seed {seed} updated"
        );
        let q = p
            .clone()
            .with_joint_bounds(lo.clone(), hi.clone())
            .unwrap()
            .with_joint_compliance(c.clone())
            .unwrap();
        let s = solver.solution();
        let error = common::global_error(&q, &s.r, &s.v, &s.lambda);
        assert!(error <= TOL, "seed {seed} updated: error {error:e}");
        // New values of G (the same pattern), which the stacked operator `[H G]` takes.
        let g = &q.joints.as_ref().unwrap().g;
        let doubled: Vec<f64> = g.values().iter().map(|x| 2.0 * x).collect();
        let values = NewValues {
            g: Some(&doubled),
            ..Default::default()
        };
        solver.update_values(&values).unwrap();
        assert_eq!(solver.solve().unwrap(), Status::Solved, "seed {seed} new G");
        let mut r = q.clone();
        r.joints
            .as_mut()
            .unwrap()
            .g
            .set_values("G", &doubled)
            .unwrap();
        let s = solver.solution();
        let error = common::global_error(&r, &s.r, &s.v, &s.lambda);
        assert!(error <= TOL, "seed {seed} new G: error {error:e}");
    }
}

/// With a time limit, `auto` starts with Gauss-Seidel sweeps, which clamp a bounded row's
/// multiplier after its own step; the answer it hands back, swept or handed over, meets
/// the tolerance by the independent copy.
#[test]
fn gauss_seidel_sweeps_clamp_bounded_rows() {
    for seed in 1..=4 {
        let p = random_scene(seed, 12);
        for tolerance in [1e-3, TOL] {
            let settings = Settings {
                tolerance,
                time_limit: 10.0,
                ..Default::default()
            };
            let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
            assert_eq!(solver.solve().unwrap(), Status::Solved, "seed {seed}");
            let (s, stats) = (solver.solution(), solver.stats());
            let error = common::global_error(&p, &s.r, &s.v, &s.lambda);
            assert!(error <= tolerance, "seed {seed}: {error:e}, {stats:?}");
            assert!(stats.gauss_seidel_sweeps >= 4, "seed {seed}: {stats:?}");
            let j = p.joints.as_ref().unwrap();
            for k in 0..s.lambda.len() {
                assert!(
                    j.lo[k] <= s.lambda[k] && s.lambda[k] <= j.hi[k],
                    "seed {seed} row {k}: {} in [{}, {}] at {tolerance}, {stats:?}",
                    s.lambda[k],
                    j.lo[k],
                    j.hi[k]
                );
            }
        }
    }
}

/// A warm start takes the contacts' impulses (3 per contact) and the velocities, the
/// bounded rows starting from zero, and lands on the same answer.
#[test]
fn warm_start_of_a_problem_with_bounded_rows() {
    let p = random_scene(3, 12);
    let settings = Settings {
        tolerance: TOL,
        ..Default::default()
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let first = solver.solution().clone();
    solver.warm_start(&first.r, Some(&first.v)).unwrap();
    assert_eq!(solver.solve().unwrap(), Status::Solved);
    let again = solver.solution();
    assert!(common::global_error(&p, &again.r, &again.v, &again.lambda) <= TOL);
    for (a, b) in again.lambda.iter().zip(&first.lambda) {
        assert!((a - b).abs() < 1e-6, "{a} against {b}");
    }
}
