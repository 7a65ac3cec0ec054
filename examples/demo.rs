//! cadmm demo: a brick pyramid settles in an open box and holds a stone block dropped on
//! it, while two bricks slide to a stop on the floor. Moreau-Jean time stepping (velocity
//! level, semi-implicit Euler); every step's frictional contact problem is solved by cadmm
//! in the global form `M v = H r + f`, `u = H^T v + w`, warm started from the previous
//! step. While the contact pattern stays the same, one solver is kept and takes each
//! step's values through `Solver::update_values`; the summary compares that per-step setup
//! with building a new solver for the same step. The checks at the end compare the outcome with statics and with the Coulomb
//! stopping distance.
//!
//! Run: `cargo run --release --example demo`. Exits with status 1 when a solve or a
//! physical sanity check fails (CI runs it). `-- --tilted` drops the block tilted from
//! 1 m: it lands on an edge and rocks, a known hard case where steps can stall short of
//! the tolerance; it is judged by what physics sets (rest, energy, overlap, equilibrium,
//! sliding distances) and by the solver's honesty on its unsolved steps (CI runs it too). `-- --tol X` solves every step to `X`
//! instead of 1e-8. `-- --dump DIR` (with `--features fclib`)
//! writes every step that does not reach the tolerance as `DIR/step-NNN.hdf5` (FCLib) and
//! its warm start as `DIR/step-NNN-warm.hdf5`, for `cadmm solve FILE --warm WARM`;
//! `-- --dump-all DIR` writes every step (to time two builds on the same problems: the
//! trajectory itself follows round-off).

#[path = "demo/scene.rs"]
mod scene;

use cadmm::measure::global_error;
use cadmm::{CscMatrix, GlobalProblem, NewValues, Problem, Settings, Solver, Status};
use nalgebra::UnitQuaternion;
use scene::{container, detect, Body, Contact, Partner, Plane, V3};
use std::collections::HashMap;
use std::process::ExitCode;
use std::time::Instant;

/// Time step (s) and number of steps.
const H: f64 = 1.0 / 60.0;
const STEPS: usize = 300;
const GRAVITY: V3 = V3::new(0.0, 0.0, -9.81);
/// Coulomb friction coefficient of every contact.
const MU: f64 = 0.5;
/// Fraction of a penetration pushed out per step (a velocity bias, no restitution).
const BAUMGARTE: f64 = 0.2;
/// Contacts are kept up to this gap plus the distance the bodies may close in one step.
const MARGIN: f64 = 0.01;
/// A previous impulse warm starts a new contact of the same pair within this distance.
const WARM_RADIUS: f64 = 0.02;
/// Half width of the container (m).
const HALF_WIDTH: f64 = 2.0;
/// Solver tolerance (stats.error, docs/algorithms.md §3) and iteration cap.
const TOLERANCE: f64 = 1e-8;
const MAX_ITERATIONS: usize = 20_000;

/// Half extents of the bricks (m), their density and the rows of the pyramid.
const BRICK: V3 = V3::new(0.2, 0.15, 0.1);
const BRICK_DENSITY: f64 = 600.0;
const ROWS: usize = 7;
/// Step at which the block is dropped.
const DROP_STEP: usize = 60;
/// Launch speeds (m/s) of the two bricks sliding on the floor, the second turned by 30
/// degrees about z (friction must not depend on the contact frame).
const SLIDE_SPEEDS: [f64; 2] = [2.5, 3.5];
const SLIDE_YAW: [f64; 2] = [0.0, std::f64::consts::FRAC_PI_6];

/// Limits of the final sanity checks.
const REST_SPEED: f64 = 1e-3;
const MAX_OVERLAP_RUN: f64 = 1e-3;
const MAX_OVERLAP_END: f64 = 1e-4;
const EQUILIBRIUM_TOL: f64 = 1e-3;
const ENERGY_GAIN_TOL: f64 = 1e-2;
const PYRAMID_SHIFT: f64 = 1e-3;
const SLIDE_TOL: f64 = 1e-3;

/// A pyramid of bricks in running bond, 1 cm apart, each row 5 mm above the one below.
/// Gap between neighbouring bricks of a pyramid row (m): twice [`MARGIN`], so that side
/// faces become contact candidates only when bricks close in. At exactly the margin their
/// open contacts came and went with the round-off of velocities at rest, and the problem
/// with them.
const SIDE_GAP: f64 = 0.02;

fn pyramid() -> Vec<Body> {
    let mut bodies = Vec::new();
    for row in 0..ROWS {
        let count = ROWS - row;
        for k in 0..count {
            let x = (k as f64 - 0.5 * (count - 1) as f64) * (2.0 * BRICK.x + SIDE_GAP);
            let z = BRICK.z + row as f64 * (2.0 * BRICK.z + 0.005) + 0.005;
            bodies.push(Body::new(BRICK, BRICK_DENSITY, V3::new(x, 0.0, z)));
        }
    }
    bodies
}

/// Bricks resting on the floor beside the pyramid, launched along +x.
fn sliders() -> Vec<Body> {
    (0..2)
        .map(|k| {
            let y = if k == 0 { -1.0 } else { 1.0 };
            let mut body = Body::new(BRICK, BRICK_DENSITY, V3::new(-1.7, y, BRICK.z));
            body.rot = UnitQuaternion::from_euler_angles(0.0, 0.0, SLIDE_YAW[k]);
            body.vel = V3::new(SLIDE_SPEEDS[k], 0.0, 0.0);
            body
        })
        .collect()
}

/// Distance a body launched at `speed` slides under Coulomb friction with this time
/// stepping: each step removes mu g h of speed, positions move with the new speed.
fn discrete_slide(speed: f64) -> f64 {
    let decrement = MU * GRAVITY.norm() * H;
    (1..)
        .map(|k| (speed - k as f64 * decrement).max(0.0) * H)
        .take_while(|&d| d > 0.0)
        .sum()
}

/// A 68 kg stone block (five bricks' mass) dropped flat from 30 cm onto the apex, or
/// (`tilted`) from 1 m, turned so that it lands on an edge and rocks.
fn block(tilted: bool) -> Body {
    let top = 2.0 * BRICK.z * ROWS as f64;
    let height = if tilted { 1.0 } else { 0.3 };
    let mut body = Body::new(V3::repeat(0.15), 2500.0, V3::new(0.03, 0.02, top + height));
    if tilted {
        body.rot = UnitQuaternion::from_euler_angles(0.2, 0.1, 0.3);
    }
    body
}

/// The global problem of one step. Velocity unknowns: `(v, omega)` of every body, world
/// frame. `f = M v_prev + h (m g, -omega x I omega)`; H maps a contact's impulse
/// `(r_N, r_T1, r_T2)` to `+` on body A and `-` on body B at the contact point.
fn build_problem(bodies: &[Body], contacts: &[Contact]) -> GlobalProblem {
    let n = 6 * bodies.len();
    let mut m = Vec::new();
    let mut f = vec![0.0; n];
    for (b, body) in bodies.iter().enumerate() {
        let i_world = body.inertia_world();
        let i_omega = i_world * body.omega;
        for k in 0..3 {
            m.push((6 * b + k, 6 * b + k, body.mass));
            for l in 0..3 {
                m.push((6 * b + 3 + k, 6 * b + 3 + l, i_world[(k, l)]));
            }
        }
        // The gyroscopic torque is taken explicitly.
        let linear = body.mass * (body.vel + H * GRAVITY);
        let angular = i_omega - H * body.omega.cross(&i_omega);
        f[6 * b..6 * b + 3].copy_from_slice(linear.as_slice());
        f[6 * b + 3..6 * b + 6].copy_from_slice(angular.as_slice());
    }
    let mut h = Vec::new();
    let mut w = vec![0.0; 3 * contacts.len()];
    for (c, contact) in contacts.iter().enumerate() {
        let mut add = |body: usize, sign: f64| {
            let arm = contact.point - bodies[body].pos;
            for k in 0..3 {
                let dir = contact.frame.column(k).into_owned();
                let moment = arm.cross(&dir);
                for l in 0..3 {
                    h.push((6 * body + l, 3 * c + k, sign * dir[l]));
                    h.push((6 * body + 3 + l, 3 * c + k, sign * moment[l]));
                }
            }
        };
        add(contact.a, 1.0);
        if let Partner::Body(b) = contact.b {
            add(b, -1.0);
        }
        // u_N = (relative normal velocity) + w_N >= 0: an open gap may close within the
        // step (speculative contact), a penetration must open at BAUMGARTE * depth / h.
        let gap = contact.gap;
        w[3 * c] = if gap >= 0.0 { gap } else { BAUMGARTE * gap } / H;
    }
    let m = CscMatrix::from_triplets("M", n, n, &m).expect("M triplets are in range");
    let h =
        CscMatrix::from_triplets("H", n, 3 * contacts.len(), &h).expect("H triplets are in range");
    GlobalProblem::new(m, h, f, w, vec![MU; contacts.len()]).expect("the problem is well formed")
}

fn velocities(bodies: &[Body]) -> Vec<f64> {
    bodies
        .iter()
        .flat_map(|b| b.vel.iter().chain(b.omega.iter()).copied())
        .collect()
}

fn energy(bodies: &[Body]) -> f64 {
    bodies
        .iter()
        .map(|b| b.kinetic_energy() - b.mass * GRAVITY.dot(&b.pos))
        .sum()
}

/// World-frame impulses of the last step's contacts, by body pair.
type Impulses = HashMap<(usize, Partner), Vec<(V3, V3)>>;

/// Local-frame warm start of each contact: the previous impulse of the nearest contact
/// of the same pair (within WARM_RADIUS), turned into the new frame.
fn warm_impulses(contacts: &[Contact], previous: &Impulses) -> Vec<f64> {
    let mut r = Vec::with_capacity(3 * contacts.len());
    for c in contacts {
        let nearest = previous
            .get(&(c.a, c.b))
            .into_iter()
            .flatten()
            .map(|(p, imp)| ((p - c.point).norm(), imp))
            .filter(|(d, _)| *d < WARM_RADIUS)
            .min_by(|x, y| x.0.total_cmp(&y.0));
        let local = nearest.map_or(V3::zeros(), |(_, imp)| c.frame.transpose() * imp);
        r.extend_from_slice(local.as_slice());
    }
    r
}

/// Per-step record for the summary.
struct StepLog {
    contacts: usize,
    status: Status,
    iterations: usize,
    error: f64,
    check: f64,
    solve_ms: f64,
}

/// End-of-run quantities the checks look at.
struct Outcome {
    deepest_run: f64,
    max_energy_gain: f64,
    static_impulse: V3,
    momentum_change: V3,
    /// Pyramid brick positions when the block is dropped (after settling).
    settled: Vec<V3>,
    wall_seconds: f64,
    /// Per step whose contact pattern did not change: seconds to take the new values into
    /// the kept solver, and seconds a new solver for the same problem takes.
    update_seconds: Vec<(f64, f64)>,
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let tilted = args.iter().any(|a| a == "--tilted");
    let dump_all = args.iter().any(|a| a == "--dump-all");
    let dump_dir = args
        .iter()
        .position(|a| a == "--dump" || a == "--dump-all")
        .and_then(|i| args.get(i + 1).cloned());
    let tolerance = match args.iter().position(|a| a == "--tol") {
        None => TOLERANCE,
        Some(i) => match args.get(i + 1).map(|t| t.parse::<f64>()) {
            Some(Ok(t)) if t > 0.0 && t.is_finite() => t,
            _ => {
                eprintln!("demo: --tol expects a positive number");
                return ExitCode::FAILURE;
            }
        },
    };
    let planes = container(HALF_WIDTH);
    let mut bodies = pyramid();
    let bricks = bodies.len();
    bodies.extend(sliders());
    let slider_start: Vec<V3> = bodies[bricks..].iter().map(|b| b.pos).collect();
    let settings = Settings {
        tolerance,
        max_iterations: MAX_ITERATIONS,
        ..Settings::default()
    };
    let mut previous = Impulses::new();
    let mut logs = Vec::with_capacity(STEPS);
    let mut outcome = Outcome {
        deepest_run: 0.0,
        max_energy_gain: 0.0,
        static_impulse: V3::zeros(),
        momentum_change: V3::zeros(),
        settled: Vec::new(),
        wall_seconds: 0.0,
        update_seconds: Vec::new(),
    };
    // One solver kept while the contact pattern stays, with the problem it last took.
    let mut kept: Option<(Solver, GlobalProblem)> = None;
    let started = Instant::now();

    println!(
        "cadmm demo: a {ROWS}-row pyramid of {bricks} bricks ({:.1} kg each) settles in a {:.0} m wide open box",
        bodies[0].mass,
        2.0 * HALF_WIDTH
    );
    println!(
        "while two bricks slide to a stop on the floor; at t = {:.2} s a {:.0} kg block is dropped {} on the apex.",
        DROP_STEP as f64 * H,
        block(tilted).mass,
        if tilted { "tilted, from 1 m," } else { "flat, from 30 cm," }
    );
    println!(
        "Moreau-Jean steps of 1/{:.0} s, mu = {MU}, global form, tolerance {tolerance:e}.",
        1.0 / H
    );
    println!(
        "{:>5} {:>6} {:>6} {:>8} {:>7} {:>6} {:>9} {:>9} {:>8}",
        "step", "t[s]", "bodies", "contacts", "status", "iters", "error", "check", "solve ms"
    );
    for step in 1..=STEPS {
        if step == DROP_STEP {
            outcome.settled = bodies[..bricks].iter().map(|b| b.pos).collect();
            bodies.push(block(tilted));
        }
        let energy_before = energy(&bodies);
        let margin = |a: usize, b: Option<usize>| {
            let closing =
                bodies[a].max_point_speed() + b.map_or(0.0, |b| bodies[b].max_point_speed());
            MARGIN + H * closing
        };
        let contacts = detect(&bodies, &planes, margin);
        outcome.deepest_run = contacts
            .iter()
            .map(|c| -c.gap)
            .fold(outcome.deepest_run, f64::max);

        let v_prev = velocities(&bodies);
        let record = if contacts.is_empty() {
            // Free flight: M v = f.
            for body in &mut bodies {
                body.vel += H * GRAVITY;
            }
            StepLog {
                contacts: 0,
                status: Status::Solved,
                iterations: 0,
                error: 0.0,
                check: 0.0,
                solve_ms: 0.0,
            }
        } else {
            let problem = build_problem(&bodies, &contacts);
            let setup = Instant::now();
            // The step's own setup: the values update, or the new solver.
            let setup_seconds = match &mut kept {
                // The per-step path: new values into the kept system, one refactorization.
                Some((solver, last)) if last.same_pattern(&problem) => {
                    solver
                        .update_values(&NewValues {
                            m: Some(problem.m.values()),
                            h: Some(problem.h.values()),
                            f: Some(&problem.f),
                            w: Some(&problem.w),
                            mu: Some(&problem.mu),
                            ..Default::default()
                        })
                        .expect("M is positive definite");
                    let update = setup.elapsed().as_secs_f64();
                    // What a new solver for the same step would have cost (not the step's).
                    let fresh = Instant::now();
                    let other = Solver::new(Problem::Global(problem.clone()), settings.clone());
                    let fresh = fresh.elapsed().as_secs_f64();
                    drop(other);
                    outcome.update_seconds.push((update, fresh));
                    *last = problem;
                    update
                }
                // Contacts appeared or vanished: the pattern of H changed, a new solver.
                _ => {
                    let solver = Solver::new(Problem::Global(problem.clone()), settings.clone())
                        .expect("M is positive definite");
                    kept = Some((solver, problem));
                    setup.elapsed().as_secs_f64()
                }
            };
            let (solver, check_problem) = kept.as_mut().expect("kept above");
            let check_problem = &*check_problem;
            let r0 = warm_impulses(&contacts, &previous);
            solver
                .warm_start(&r0, Some(&v_prev))
                .expect("warm start sizes match");
            let status = solver.solve().expect("the solve runs");
            let stats = *solver.stats();
            let solution = solver.solution();
            let check = global_error(check_problem, &solution.r, &solution.v, &[]);
            if let (Some(dir), false) = (&dump_dir, status == Status::Solved && !dump_all) {
                if let Err(e) = dump(dir, step, check_problem, &r0, &v_prev) {
                    eprintln!("--dump: {e}");
                    return ExitCode::FAILURE;
                }
            }
            previous.clear();
            outcome.static_impulse = V3::zeros();
            for (c, contact) in contacts.iter().enumerate() {
                let impulse = contact.frame * V3::from_column_slice(&solution.r[3 * c..3 * c + 3]);
                previous
                    .entry((contact.a, contact.b))
                    .or_default()
                    .push((contact.point, impulse));
                if let Partner::Plane(_) = contact.b {
                    outcome.static_impulse += impulse;
                }
            }
            for (b, body) in bodies.iter_mut().enumerate() {
                body.vel = V3::from_column_slice(&solution.v[6 * b..6 * b + 3]);
                body.omega = V3::from_column_slice(&solution.v[6 * b + 3..6 * b + 6]);
            }
            StepLog {
                contacts: contacts.len(),
                status,
                iterations: stats.iterations,
                error: stats.error,
                check,
                solve_ms: 1e3 * (setup_seconds + stats.solve_seconds),
            }
        };
        outcome.momentum_change = bodies
            .iter()
            .enumerate()
            .fold(V3::zeros(), |acc, (b, body)| {
                acc + body.mass * (body.vel - V3::from_column_slice(&v_prev[6 * b..6 * b + 3]))
            });
        // Semi-implicit Euler: positions move with the new velocities.
        for body in &mut bodies {
            body.pos += H * body.vel;
            body.rot = UnitQuaternion::from_scaled_axis(H * body.omega) * body.rot;
        }
        // Contacts are perfectly inelastic and free flight loses energy under semi-implicit
        // Euler: any gain comes from the penetration bias or a wrong impulse.
        outcome.max_energy_gain = outcome.max_energy_gain.max(energy(&bodies) - energy_before);
        println!(
            "{step:>5} {:>6.3} {:>6} {:>8} {:>7} {:>6} {:>9.2e} {:>9.2e} {:>8.2}",
            step as f64 * H,
            bodies.len(),
            record.contacts,
            short_status(record.status),
            record.iterations,
            record.error,
            record.check,
            record.solve_ms
        );
        logs.push(record);
    }
    outcome.wall_seconds = started.elapsed().as_secs_f64();
    summary(
        &bodies,
        &slider_start,
        &planes,
        &logs,
        &outcome,
        tolerance,
        tilted,
    )
}

/// Writes an unsolved step as an FCLib problem and its warm start as a solution file.
#[cfg(feature = "fclib")]
fn dump(dir: &str, step: usize, p: &GlobalProblem, r0: &[f64], v0: &[f64]) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{dir}: {e}"))?;
    let path = format!("{dir}/step-{step:03}.hdf5");
    cadmm::fclib::write_problem(&path, &Problem::Global(p.clone()))
        .map_err(|e| format!("{path}: {e}"))?;
    let warm = cadmm::Solution {
        r: r0.to_vec(),
        u: Vec::new(),
        v: v0.to_vec(),
        lambda: Vec::new(),
    };
    let path = format!("{dir}/step-{step:03}-warm.hdf5");
    cadmm::fclib::write_solution(&path, &warm).map_err(|e| format!("{path}: {e}"))
}

#[cfg(not(feature = "fclib"))]
fn dump(_: &str, _: usize, _: &GlobalProblem, _: &[f64], _: &[f64]) -> Result<(), String> {
    Err(
        "--dump needs the fclib feature: cargo run --release --features fclib --example demo"
            .into(),
    )
}

fn short_status(s: Status) -> &'static str {
    match s {
        Status::Solved => "solved",
        Status::MaxIterations => "maxit",
        Status::TimeLimit => "time",
        Status::NumericalError => "nan",
        Status::Stalled => "stall",
        Status::Infeasible => "infeasible",
        Status::Unsolved => "unsolved",
    }
}

/// Prints the summary and the checks; failure when any check fails.
fn summary(
    bodies: &[Body],
    slider_start: &[V3],
    planes: &[Plane],
    logs: &[StepLog],
    outcome: &Outcome,
    tolerance: f64,
    tilted: bool,
) -> ExitCode {
    let solved = logs.iter().filter(|l| l.status == Status::Solved).count();
    let mut iterations: Vec<usize> = logs
        .iter()
        .filter(|l| l.contacts > 0)
        .map(|l| l.iterations)
        .collect();
    iterations.sort_unstable();
    let median = iterations.get(iterations.len() / 2).copied().unwrap_or(0);
    let max_iterations = iterations.last().copied().unwrap_or(0);
    let max_error = logs.iter().map(|l| l.error).fold(0.0, f64::max);
    let max_check = logs.iter().map(|l| l.check).fold(0.0, f64::max);
    let total_contacts: usize = logs.iter().map(|l| l.contacts).sum();
    let max_contacts = logs.iter().map(|l| l.contacts).max().unwrap_or(0);
    let solve_total: f64 = logs.iter().map(|l| l.solve_ms).sum::<f64>() / 1e3;
    let solve_max = logs.iter().map(|l| l.solve_ms).fold(0.0, f64::max);
    // Per-step percentiles over the steps that called the solver.
    let mut step_ms: Vec<f64> = logs
        .iter()
        .filter(|l| l.contacts > 0)
        .map(|l| l.solve_ms)
        .collect();
    step_ms.sort_by(f64::total_cmp);
    let percentile = |q: f64| {
        step_ms
            .get(((step_ms.len() as f64 * q) as usize).min(step_ms.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f64::NAN)
    };
    let bricks = outcome.settled.len();
    let pyramid_shift = outcome
        .settled
        .iter()
        .zip(bodies)
        .map(|(p, b)| (p - b.pos).norm())
        .fold(0.0, f64::max);
    let block = bodies.last().expect("the block was dropped");

    println!();
    println!(
        "summary: {} steps ({:.2} s simulated), {} bodies, {total_contacts} contacts in all, at most {max_contacts} per step",
        logs.len(),
        logs.len() as f64 * H,
        bodies.len()
    );
    println!(
        "scene: the block rests at ({:.2}, {:.2}, {:.2}) m; pyramid bricks moved at most {:.2} mm since it was dropped",
        block.pos.x,
        block.pos.y,
        block.pos.z,
        1e3 * pyramid_shift
    );
    println!(
        "solver: {solved}/{} steps solved to {tolerance:e}; iterations median {median}, max {max_iterations}",
        logs.len()
    );
    println!("error: max {max_error:.2e} (stats), max {max_check:.2e} (measure::global_error)");
    println!(
        "time: solver {solve_total:.2} s in all; per step (setup and solve) median {:.2} ms, p90 {:.2} ms, max {solve_max:.1} ms; wall {:.2} s",
        percentile(0.5),
        percentile(0.9),
        outcome.wall_seconds
    );
    let median = |mut x: Vec<f64>| {
        x.sort_by(f64::total_cmp);
        x.get(x.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let ups = &outcome.update_seconds;
    let update_ms = 1e3 * median(ups.iter().map(|u| u.0).collect());
    let fresh_ms = 1e3 * median(ups.iter().map(|u| u.1).collect());
    println!(
        "per-step setup on the {} steps with an unchanged contact pattern: values update \
         {update_ms:.3} ms median, a new solver {fresh_ms:.3} ms ({:.1}x)",
        ups.len(),
        fresh_ms / update_ms
    );

    let mut failures = 0;
    let mut check = |ok: bool, what: String| {
        println!("[{}] {what}", if ok { "pass" } else { "FAIL" });
        failures += usize::from(!ok);
    };
    if tilted {
        // The tilted block rocks on an edge: some steps stall short of the tolerance
        // (docs/limits.md, "A block rocking on an edge"). What the solver owes there is
        // honesty: a step it calls solved is, and an unsolved step reports the error its
        // answer has, re-measured on a copy.
        let dishonest = logs
            .iter()
            .filter(|l| l.contacts > 0)
            .filter(|l| {
                let honest = match l.status {
                    Status::Solved => l.check <= 2.0 * tolerance,
                    _ => (l.error - l.check).abs() <= 1e-6 * l.check && l.check > tolerance,
                };
                !honest
            })
            .count();
        check(
            dishonest == 0,
            format!("solver: {solved} of {} steps solved, each re-measured on a copy of the problem; every unsolved one reports its re-measured error ({dishonest} do not)", logs.len()),
        );
    } else {
        check(
            solved == logs.len() && max_check <= 2.0 * tolerance,
            format!("solver: every step solved, error re-measured on a copy of the problem {max_check:.1e} <= 2 x tolerance"),
        );
    }
    let finite = bodies.iter().all(|b| {
        b.pos
            .iter()
            .chain(b.vel.iter())
            .chain(b.omega.iter())
            .all(|x| x.is_finite())
    });
    let max_speed = bodies.iter().map(Body::max_point_speed).fold(0.0, f64::max);
    let kinetic: f64 = bodies.iter().map(Body::kinetic_energy).sum();
    check(
        finite && max_speed < REST_SPEED,
        format!("at rest: fastest point {max_speed:.1e} m/s (< {REST_SPEED:.0e}), kinetic energy {kinetic:.1e} J"),
    );
    check(
        outcome.max_energy_gain < ENERGY_GAIN_TOL,
        format!(
            "no energy created: largest gain in one step {:.1e} J (< {ENERGY_GAIN_TOL})",
            outcome.max_energy_gain
        ),
    );
    let final_contacts = detect(bodies, planes, |_, _| 0.0);
    let deepest_end = final_contacts.iter().map(|c| -c.gap).fold(0.0, f64::max);
    check(
        outcome.deepest_run < MAX_OVERLAP_RUN && deepest_end < MAX_OVERLAP_END,
        format!(
            "no overlap: deepest {:.3} mm during the run (< {:.0}), {:.4} mm at the end (< {:.1})",
            1e3 * outcome.deepest_run,
            1e3 * MAX_OVERLAP_RUN,
            1e3 * deepest_end,
            1e3 * MAX_OVERLAP_END
        ),
    );
    let escaped: Vec<String> = planes
        .iter()
        .flat_map(|p| {
            bodies
                .iter()
                .enumerate()
                .filter(move |(_, b)| b.support_min(&p.normal) < p.offset - MAX_OVERLAP_END)
                .map(move |(i, _)| format!("body {i} through {}", p.name))
        })
        .collect();
    check(
        escaped.is_empty(),
        if escaped.is_empty() {
            "contained: no body through the floor or a wall".to_string()
        } else {
            format!("contained: {}", escaped.join(", "))
        },
    );
    // At rest the floor and walls carry the whole weight: their impulses over the last step
    // balance h * weight (up to the momentum still changing, which is checked too).
    let weight_impulse = -H * GRAVITY * bodies.iter().map(|b| b.mass).sum::<f64>();
    let imbalance = (outcome.static_impulse - weight_impulse).norm() / weight_impulse.norm();
    let momentum = (outcome.static_impulse - weight_impulse - outcome.momentum_change).norm()
        / weight_impulse.norm();
    check(
        imbalance < EQUILIBRIUM_TOL && momentum < 1e-6,
        format!(
            "equilibrium: floor and walls carry {:.6} x the weight (imbalance {imbalance:.1e} < {EQUILIBRIUM_TOL:.0e}), momentum balance {momentum:.1e}",
            outcome.static_impulse.z / weight_impulse.z
        ),
    );
    if tilted {
        // The tilted block hits the apex from 1 m on an edge: the bricks' shift (25.8 to
        // 28.9 mm at every tolerance) is the impact's, not a bound the solver answers for.
        println!(
            "[info] the impact shifted pyramid bricks by at most {:.3} mm",
            1e3 * pyramid_shift
        );
    } else {
        check(
            pyramid_shift < PYRAMID_SHIFT,
            format!(
                "the pyramid holds the block: largest brick shift {:.3} mm (< {:.0})",
                1e3 * pyramid_shift,
                1e3 * PYRAMID_SHIFT
            ),
        );
    }
    // Sliding bricks: the stopping distance of Coulomb friction under this time stepping,
    // v0^2 / (2 mu g) minus about h v0 / 2, whatever the brick's orientation.
    for (k, start) in slider_start.iter().enumerate() {
        let slider = &bodies[bricks + k];
        let travel = slider.pos - start;
        let expected = discrete_slide(SLIDE_SPEEDS[k]);
        let continuous = SLIDE_SPEEDS[k].powi(2) / (2.0 * MU * GRAVITY.norm());
        let deviation = (travel - V3::new(expected, 0.0, 0.0)).norm();
        check(
            deviation < SLIDE_TOL,
            format!(
                "friction: brick launched at {} m/s slid {:.4} m, Coulomb predicts {expected:.4} m ({continuous:.4} m continuous), off by {:.4} mm (< {:.0})",
                SLIDE_SPEEDS[k],
                travel.x,
                1e3 * deviation,
                1e3 * SLIDE_TOL
            ),
        );
    }
    if failures == 0 {
        println!("RESULT: PASS");
        ExitCode::SUCCESS
    } else {
        println!("RESULT: FAIL ({failures} check(s) failed)");
        ExitCode::FAILURE
    }
}
