//! The error measure at the far ends of f64's range (docs/algorithms.md §3): data scaled
//! down to a tenth of a milligram or by 1e-9 is judged relative to its own size, not
//! against an absolute floor, and data scaled by 1e155 is measured without its squares
//! overflowing. Each answer is checked against the independent measure of `tests/common`
//! and against an exact or a rescaled reference answer.

mod common;
#[path = "../examples/extreme/scenes.rs"]
mod scenes;

use cadmm::{CscMatrix, GlobalProblem, Problem, Settings, Solver, Status, VariantChoice};

const TOL: f64 = 1e-8;

fn solve(p: &GlobalProblem, variant: &str) -> (Status, Solver) {
    let settings = Settings {
        tolerance: TOL,
        max_iterations: 200_000,
        time_limit: 60.0,
        variant: VariantChoice::from_name(variant).unwrap(),
        ..Settings::default()
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), settings).unwrap();
    let status = solver.solve().unwrap();
    (status, solver)
}

/// Grains of 0.1 mg sliding on the ground at 9 and 6 mm/s, a 1e-4 s step: `||f||` is
/// about 1e-9. Each grain is a point mass with velocities in its contact's frame (normal,
/// then the sliding direction), so the answer is exact: `r_N = m g h`, `r_T = -mu r_N`,
/// the grain slides on at `v_T - mu g h`. Measured against an absolute floor of 1.5e-8,
/// `r = 0, v = 0` looked solved at once: grains stopped dead.
#[test]
fn sliding_grains_of_a_tenth_of_a_milligram() {
    let (m, h, g, mu) = (1e-7, 1e-4, 9.81, 0.5);
    let speeds = [0.009, 0.006];
    let n = 3 * speeds.len();
    let diag: Vec<_> = (0..n).map(|i| (i, i, m)).collect();
    let mass = CscMatrix::from_triplets("M", n, n, &diag).unwrap();
    let ident: Vec<_> = (0..n).map(|i| (i, i, 1.0)).collect();
    let h_mat = CscMatrix::from_triplets("H", n, n, &ident).unwrap();
    let f: Vec<f64> = speeds
        .iter()
        .flat_map(|&s| [-m * g * h, m * s, 0.0])
        .collect();
    let p = GlobalProblem::new(mass, h_mat, f, vec![0.0; n], vec![mu; speeds.len()]).unwrap();
    // cp-N keeps rho = 1, a million times too large here: it is not among them.
    for variant in ["auto", "vp-N-He", "vp-RR-Spectral"] {
        let (status, solver) = solve(&p, variant);
        let s = solver.solution();
        let e = common::global_error(&p, &s.r, &s.v, &[]);
        assert_eq!(status, Status::Solved, "{variant}: {:?}", solver.stats());
        assert!(e <= TOL, "{variant}: independent error {e:e}");
        for (k, &speed) in speeds.iter().enumerate() {
            let rn = m * g * h;
            let (r, v) = (&s.r[3 * k..3 * k + 3], &s.v[3 * k..3 * k + 3]);
            let slide = speed - mu * g * h;
            assert!(
                (r[0] - rn).abs() <= 1e-6 * rn && (r[1] + mu * rn).abs() <= 1e-6 * rn,
                "{variant}: grain {k}: r = {r:?}, expected ({rn:e}, {:e}, 0)",
                -mu * rn
            );
            assert!(
                (v[1] - slide).abs() <= 1e-6 * speed && v[0].abs() <= 1e-6 * speed,
                "{variant}: grain {k} moves at {v:?}, expected (0, {slide}, 0)"
            );
        }
    }
}

/// The 27-sphere pile with `f` scaled by `scale`: the exact answer scales with it (w is
/// zero), so `v / scale` must be the base pile's velocities, within what the tolerance
/// allows. Measured against the absolute floor, the pile scaled by 1e-9 came back solved
/// with impulses 13 times too large; scaled by 1e155, cp-N came back solved at an error
/// of 0 (its squares overflowed) where the answer's error was 0.35.
fn check_scaled_pile(scale: f64, variant: &str) {
    let base = scenes::pile(3, 3, 3).global();
    let mut scaled = base.clone();
    scaled.f.iter_mut().for_each(|x| *x *= scale);
    let (status, solver) = solve(&scaled, variant);
    let s = solver.solution();
    let e = common::global_error(&scaled, &s.r, &s.v, &[]);
    let what = format!("pile scaled by {scale:e}, {variant}");
    if status != Status::Solved {
        // Not solved is honest only when the reported error says so.
        assert!(
            solver.stats().error > TOL,
            "{what}: {status:?} with a reported error of {:e}",
            solver.stats().error
        );
        return;
    }
    assert!(e <= TOL, "{what}: solved, independent error {e:e}");
    let reported = solver.stats().error;
    assert!(
        (reported - e).abs() <= 1e-3 * TOL + 1e-6 * e,
        "{what}: reported {reported:e}, independent {e:e}"
    );
    // The pile is hyperstatic (its impulses are not unique); its velocities are.
    let (_, reference) = solve(&base, "auto");
    let v0 = &reference.solution().v;
    let size = v0.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    let off =
        s.v.iter()
            .zip(v0)
            .fold(0.0_f64, |a, (x, y)| a.max((x / scale - y).abs()));
    assert!(
        off <= 1e-3 * size,
        "{what}: v / scale is off the base answer by {off:e} (largest velocity {size:e})"
    );
}

#[test]
fn pile_scaled_down_by_1e9() {
    for variant in ["auto", "cp-N"] {
        check_scaled_pile(1e-9, variant);
    }
}

#[test]
fn pile_scaled_up_by_1e155() {
    for variant in ["auto", "cp-N"] {
        check_scaled_pile(1e155, variant);
    }
}

/// Data of any scale in f64's range is measured the same: the measure of the scaled
/// pile's scaled reference answer is the base answer's measure.
#[test]
fn the_measure_does_not_change_with_the_data_scale() {
    let base = scenes::pile(3, 3, 3).global();
    let (_, solver) = solve(&base, "auto");
    let s = solver.solution();
    let e0 = cadmm::measure::global_error(&base, &s.r, &s.v, &[]);
    for scale in [1e-290, 1e-160, 1e-9, 1e9, 1e155, 1e290] {
        let mut p = base.clone();
        p.f.iter_mut().for_each(|x| *x *= scale);
        let r: Vec<f64> = s.r.iter().map(|x| x * scale).collect();
        let v: Vec<f64> = s.v.iter().map(|x| x * scale).collect();
        let e = cadmm::measure::global_error(&p, &r, &v, &[]);
        let independent = common::global_error(&p, &r, &v, &[]);
        assert!(
            (e - e0).abs() <= 1e-6 * e0 + 1e-12,
            "scale {scale:e}: {e:e}, unscaled {e0:e}"
        );
        assert!(
            (independent - e0).abs() <= 1e-6 * e0 + 1e-12,
            "scale {scale:e}: independent {independent:e}, unscaled {e0:e}"
        );
    }
}
