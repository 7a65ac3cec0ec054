//! The extreme suite of `examples/extreme/scenes.rs` (stiff mass ratios, extreme and mixed
//! friction, unit scalings, redundant contacts, near-singular inertia, 1000 contacts on one
//! body, an impact, separating and empty contact sets, a granular pile of 325 contacts):
//! every case in both forms with `auto`, the small ones with every named variant. Each
//! outcome must be honest: finite outputs, and either `solved` with the error re-measured
//! independently at or below 1e-8, or another status with a finite error.

mod common;
#[path = "../examples/extreme/scenes.rs"]
mod scenes;

use cadmm::admm::VARIANT_NAMES;
use cadmm::LocalProblem;
use scenes::{Case, Outcome};

const TOL: f64 = 1e-8;
/// The pile of the test: 5 x 5 x 5 spheres, 325 contacts (the example runs 1e5).
const PILE: (usize, usize, usize) = (5, 5, 5);
/// Named variants run on the cases with at most this many `n * 3nc` (the small ones).
const NAMED_MAX: usize = 50_000;

fn check(o: &Outcome, failures: &mut Vec<String>) {
    let tag = format!("{} {} {}", o.case, o.form, o.variant);
    let honest_status = matches!(
        o.status.as_str(),
        "max_iterations" | "time_limit" | "numerical_error" | "stalled"
    );
    if !o.finite {
        failures.push(format!("{tag}: non-finite output ({})", o.status));
    } else if o.status == "solved" {
        if o.error.is_nan() || o.error > TOL {
            failures.push(format!(
                "{tag}: solved, but re-measured error {:e}",
                o.error
            ));
        }
    } else if !honest_status || !o.error.is_finite() {
        // A diverged run (`numerical_error`: named variants at mu = 1e3 or mixed mu) hands
        // back the best iterate it measured, whose error is finite, not its last finite
        // iterate (entries near 1e154, whose measure overflowed).
        failures.push(format!("{tag}: {} with error {:e}", o.status, o.error));
    }
}

fn forms(case: &Case) -> Vec<&'static str> {
    if case.local.is_some() {
        vec!["global", "local"]
    } else {
        vec!["global"]
    }
}

#[test]
fn every_case_with_auto() {
    let mut failures = Vec::new();
    let mut solved = 0;
    let cases = scenes::cases(PILE);
    for case in &cases {
        for form in forms(case) {
            let o = scenes::run(case, form, "auto", 5.0, 20_000);
            check(&o, &mut failures);
            solved += usize::from(o.status == "solved");
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    // Every case but the two whose local form sits at the round-off floor (see
    // `local_form_of_mass_ratio_1e8_is_below_round_off`) reaches 1e-8.
    let runs: usize = cases.iter().map(|c| forms(c).len()).sum();
    assert!(solved >= runs - 2, "{solved} of {runs} solved");
}

#[test]
fn small_cases_with_every_named_variant() {
    let mut failures = Vec::new();
    for case in scenes::cases(PILE) {
        if case.global.n() * case.global.w.len() > NAMED_MAX {
            continue;
        }
        for form in forms(&case) {
            for variant in VARIANT_NAMES {
                check(
                    &scenes::run(&case, form, variant, 0.5, 5_000),
                    &mut failures,
                );
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The zero-contact problem is accepted and solved: `v = M^-1 f`, `r` empty.
#[test]
fn zero_contacts_give_the_free_velocity() {
    let cases = scenes::cases((1, 1, 1));
    let case = cases.iter().find(|c| c.name == "zero-contacts").unwrap();
    let o = scenes::run(case, "global", "auto", 5.0, 1000);
    assert_eq!(o.status, "solved");
    assert!(o.solution.r.is_empty());
    let p = &case.global;
    for (j, v) in o.solution.v.iter().enumerate() {
        let m = p.m.col(j).next().unwrap().1;
        assert!((v - p.f[j] / m).abs() <= 1e-12 * (p.f[j] / m).abs().max(1.0));
    }
}

/// A solution in the units of `scenes::scale_units(_, a, b, c)`: `r' = (a b / c) r`,
/// `v' = (a / c) T^-1 v` (`T` scales the rotational velocities by `a`).
fn in_units(s: &cadmm::Solution, a: f64, b: f64, c: f64) -> (Vec<f64>, Vec<f64>) {
    let r = s.r.iter().map(|x| a * b / c * x).collect();
    let v = (s.v.iter().enumerate())
        .map(|(i, x)| a / c * x / if i % 6 >= 3 { a } else { 1.0 })
        .collect();
    (r, v)
}

/// The transformation of `scale_units` maps solutions to solutions: `r' = (a b / c) r`,
/// `v' = (a / c) T^-1 v`, checked on the unscaled solution with the independent measure.
#[test]
fn unit_scaling_maps_solutions() {
    let cases = scenes::cases((1, 1, 1));
    let base = cases.iter().find(|c| c.name == "units-base").unwrap();
    let o = scenes::run(base, "global", "auto", 5.0, 20_000);
    assert_eq!(o.status, "solved");
    for (a, b, c) in [
        (1e3, 1.0, 1.0),
        (1.0, 1e-3, 1.0),
        (1.0, 1.0, 1e6),
        (1e-2, 1e2, 1e-3),
    ] {
        let p = scenes::scale_units(&base.global, a, b, c);
        let (r, v) = in_units(&o.solution, a, b, c);
        let e = common::global_error(&p, &r, &v, &[]);
        // The measure is not unit-invariant (its natural map subtracts a velocity from an
        // impulse), so only a loose bound holds here; the solve itself is checked elsewhere.
        assert!(e < 1e-6, "scaled by ({a}, {b}, {c}): {e:e}");
    }
}

/// `auto` (Newton on these small scenes) is unit-invariant: after the same number of steps,
/// the iterate of a problem in other units is the base iterate mapped by the change of
/// units, `r' = (a b / c) r`, `v' = (a / c) T^-1 v`. Only the choices made by the error
/// measure can differ (when to stop, which iterate is the best so far), because the measure
/// adds velocities to impulses: the local measure changes with the mass unit and picks
/// another best iterate there, so the local form is checked in length and time units.
#[test]
fn auto_iterates_follow_the_units() {
    let cases = scenes::cases((1, 1, 1));
    let base = cases.iter().find(|c| c.name == "units-base").unwrap();
    let close = |x: &[f64], y: &[f64], what: &str| {
        let scale = y.iter().map(|v| v * v).sum::<f64>().sqrt();
        let diff = x
            .iter()
            .zip(y)
            .map(|(p, q)| (p - q) * (p - q))
            .sum::<f64>()
            .sqrt();
        assert!(
            diff <= 1e-9 * scale,
            "{what}: off by {:e} relative",
            diff / scale
        );
    };
    for form in ["global", "local"] {
        for steps in 1..=3 {
            let o = scenes::run(base, form, "auto", 5.0, steps);
            assert_eq!(
                o.iterations, steps,
                "{form}: the base is not solved in {steps}"
            );
            for (a, b, c) in [
                (1e3, 1.0, 1.0),
                (1e-6, 1.0, 1.0),
                (1.0, 1e6, 1.0),
                (1.0, 1e-3, 1.0),
                (1.0, 1.0, 1e6),
                (1e-2, 1e2, 1e-3),
            ] {
                if form == "local" && b != 1.0 {
                    continue;
                }
                let global = scenes::scale_units(&base.global, a, b, c);
                let case = Case {
                    name: format!("units-{a:e}-{b:e}-{c:e}"),
                    family: "units",
                    local: Some(scenes::local_form(&global)),
                    global,
                };
                let s = scenes::run(&case, form, "auto", 5.0, steps);
                let what = format!("{form}, {steps} steps, units ({a:e}, {b:e}, {c:e})");
                assert_eq!(s.iterations, steps, "{what}");
                let (r, v) = in_units(&o.solution, a, b, c);
                close(&s.solution.r, &r, &format!("{what}, r"));
                if form == "global" {
                    close(&s.solution.v, &v, &format!("{what}, v"));
                }
            }
        }
    }
}

/// With its iterates independent of the units (above), `auto` stops after the same number
/// of steps at every scaling of the units family. The error measure alone would not: the
/// global measure changes with the mass unit (it adds velocities to impulses) and met 1e-8
/// one step earlier at masses x1e3 and x1e6; Newton confirms with its unit-free residual.
#[test]
fn auto_iteration_counts_follow_the_units() {
    let cases = scenes::cases((1, 1, 1));
    let family: Vec<&Case> = cases.iter().filter(|c| c.family == "units").collect();
    let base = family.iter().find(|c| c.name == "units-base").unwrap();
    for form in ["global", "local"] {
        let reference = scenes::run(base, form, "auto", 5.0, 20_000);
        assert_eq!(reference.status, "solved");
        for case in &family {
            let o = scenes::run(case, form, "auto", 5.0, 20_000);
            assert_eq!(o.status, "solved", "{} {form}", case.name);
            assert!(o.error <= TOL, "{} {form}: {:e}", case.name, o.error);
            assert!(
                o.iterations == reference.iterations,
                "{} {form}: {} iterations against {}",
                case.name,
                o.iterations,
                reference.iterations
            );
        }
    }
}

/// Frictionless, the algorithms are invariant under time scaling (a homogeneous scaling of
/// the data), and so is the local form under length scaling (it only scales `q`): the
/// iteration counts stay within 10% of the unscaled case. With friction they do not: the
/// first De Saxce shift (docs/algorithms.md §3, seed eq. 61) is a fixed velocity, not scaled
/// with the data (docs/limits.md gives the figures).
#[test]
fn frictionless_unit_scaling_keeps_iteration_counts() {
    let cases = scenes::cases((1, 1, 1));
    let mut base = cases
        .iter()
        .find(|c| c.name == "units-base")
        .unwrap()
        .global
        .clone();
    base.mu.fill(0.0);
    let iterations = |a: f64, c: f64, form: &'static str| {
        let global = scenes::scale_units(&base, a, 1.0, c);
        let case = Case {
            name: format!("frictionless-units-{a:e}-{c:e}"),
            family: "units",
            local: Some(scenes::local_form(&global)),
            global,
        };
        let o = scenes::run(&case, form, "auto", 5.0, 20_000);
        assert_eq!(o.status, "solved", "{}", case.name);
        assert!(o.error <= TOL, "{}: {:e}", case.name, o.error);
        o.iterations as f64
    };
    for form in ["global", "local"] {
        let reference = iterations(1.0, 1.0, form);
        for x in scenes::UNIT_FACTORS {
            let mut scalings = vec![(1.0, x)];
            if form == "local" {
                scalings.push((x, 1.0));
            }
            for (a, c) in scalings {
                let k = iterations(a, c, form);
                assert!(
                    (k - reference).abs() <= 0.1 * reference,
                    "{form}, length x {a:e}, time x {c:e}: {k} iterations against {reference}"
                );
            }
        }
    }
}

/// A heavy box (1e8) on a light one (1), local form: `W` has entries of order 1 and the
/// impulses are 1e8 times the free velocity `q`, so computing `u = W r + q` cancels about
/// eight digits and the measure (relative to `||q||`) cannot go much below
/// `eps ||W|| ||r|| / ||q||`. The solver must stop with an honest status there.
#[test]
fn local_form_of_mass_ratio_1e8_is_below_round_off() {
    let cases = scenes::cases((1, 1, 1));
    let case = cases
        .iter()
        .find(|c| c.name == "heavy-on-light-1e8")
        .unwrap();
    let global = scenes::run(case, "global", "auto", 5.0, 20_000);
    assert_eq!(global.status, "solved");
    let l: &LocalProblem = case.local.as_ref().unwrap();
    // The round-off floor at the global form's exact impulses.
    let r = &global.solution.r;
    let w_norm = l.w.norm_fro();
    let r_norm = r.iter().map(|x| x * x).sum::<f64>().sqrt();
    let q_norm = l.q.iter().map(|x| x * x).sum::<f64>().sqrt();
    let floor = f64::EPSILON * w_norm * r_norm / q_norm;
    eprintln!("round-off floor of the local measure: {floor:e}");
    assert!(floor > 1e-9, "floor {floor:e}");
    let o = scenes::run(case, "local", "auto", 2.0, 20_000);
    let mut failures = Vec::new();
    check(&o, &mut failures);
    assert!(failures.is_empty(), "{failures:?}");
}

/// `solved` holds against a measure computed elsewhere. A named variant on the local form
/// at mass ratio 1e4 creeps up to the tolerance over 478 000 iterations; its measure and
/// an independent one (dense, another summation order) differ by round-off, 4e-5 of the
/// tolerance, and the solver once stopped at 9.99964e-9 by its own measure where the
/// independent one (and `fc_error.py`) read 1.0000037e-8. It now works to the tolerance
/// less a margin (`ROUND_OFF_MARGIN`).
#[test]
fn solved_holds_against_an_independent_measure() {
    let cases = scenes::cases((1, 1, 1));
    let case = cases
        .iter()
        .find(|c| c.name == "heavy-on-light-1e4")
        .unwrap();
    let o = scenes::run(case, "local", "cp-N", 60.0, 1_000_000);
    assert_eq!(o.status, "solved");
    assert!(o.error <= TOL, "re-measured {:e}", o.error);
}

/// The 27-sphere pile at mu = 30 to 300 with `auto`: its first run, with the De Saxce
/// shift updated every iteration, diverges (a change of u_T moves the shift by mu times
/// as much), and the solve runs again with the external s update (docs/algorithms.md §5),
/// which solves it. Before, every such solve ended `numerical_error` at an error of ~1.1.
#[test]
fn a_pile_with_large_friction_coefficients_solves() {
    for mu in [30.0, 100.0, 300.0] {
        let mut p = scenes::pile(3, 3, 3).global();
        p.mu.iter_mut().for_each(|m| *m = mu);
        let settings = cadmm::Settings {
            tolerance: TOL,
            ..cadmm::Settings::default()
        };
        let mut solver = cadmm::Solver::new(cadmm::Problem::Global(p.clone()), settings).unwrap();
        let status = solver.solve().unwrap();
        let s = solver.solution();
        let e = common::global_error_sparse(&p, &s.r, &s.v);
        assert_eq!(
            status,
            cadmm::Status::Solved,
            "mu {mu}: {:?}",
            solver.stats()
        );
        assert!(e <= TOL, "mu {mu}: independent error {e:e}");
    }
}
