//! Single-contact problems with a closed-form Coulomb answer, in global form (M = m I,
//! H = I, w = 0, so u = v = v_free + r / m with v_free = f / m) and local form (W = I / m,
//! q = v_free), for every variant. With `v_free = (n, t)`:
//! - open (n > 0): r = 0;
//! - stick (n < 0, |t| <= mu |n|): u = 0, r = -m v_free;
//! - slide (n < 0, |t| > mu |n|): u_N = 0, r_N = -m n, r_T = -mu r_N t / |t|;
//! - frictionless (mu = 0, n < 0): r = (-m n, 0, 0).

use cadmm::admm::VARIANT_NAMES;
use cadmm::{
    CscMatrix, GlobalProblem, LocalProblem, Problem, Settings, Solver, Status, VariantChoice,
};

fn exact(mass: f64, vf: [f64; 3], mu: f64) -> [f64; 3] {
    let t = vf[1].hypot(vf[2]);
    if vf[0] >= 0.0 {
        [0.0; 3]
    } else if t <= mu * -vf[0] {
        [-mass * vf[0], -mass * vf[1], -mass * vf[2]]
    } else {
        let rn = -mass * vf[0];
        [rn, -mu * rn * vf[1] / t, -mu * rn * vf[2] / t]
    }
}

fn cases() -> Vec<(&'static str, [f64; 3], f64)> {
    vec![
        ("open", [0.5, 0.3, -0.2], 0.5),
        ("stick", [-9.81, 1.0, -2.0], 0.5),
        ("slide", [-1.0, 3.0, 4.0], 0.3),
        ("frictionless", [-2.0, 1.0, 1.0], 0.0),
    ]
}

fn check(problem: Problem, variant: &str, expected: [f64; 3], what: &str) {
    let settings = Settings {
        tolerance: 1e-10,
        variant: VariantChoice::from_name(variant).unwrap(),
        ..Default::default()
    };
    let mut solver = Solver::new(problem, settings).unwrap();
    let status = solver.solve().unwrap();
    assert_eq!(
        status,
        Status::Solved,
        "{what} with {variant}: {:?}",
        solver.stats()
    );
    let r = &solver.solution().r;
    let scale = 1.0 + expected.iter().map(|x| x.abs()).fold(0.0, f64::max);
    for k in 0..3 {
        assert!(
            (r[k] - expected[k]).abs() <= 1e-6 * scale,
            "{what} with {variant}: r = {r:?}, expected {expected:?}"
        );
    }
}

#[test]
fn single_contact_global_form_every_variant() {
    let mass = 2.0;
    for (what, vf, mu) in cases() {
        let expected = exact(mass, vf, mu);
        for variant in VARIANT_NAMES.iter().copied().chain(["auto"]) {
            let m =
                CscMatrix::from_dense("M", 3, 3, &[mass, 0.0, 0.0, 0.0, mass, 0.0, 0.0, 0.0, mass])
                    .unwrap();
            let f = vf.iter().map(|x| mass * x).collect();
            let p =
                GlobalProblem::new(m, CscMatrix::identity(3), f, vec![0.0; 3], vec![mu]).unwrap();
            check(Problem::Global(p), variant, expected, what);
        }
    }
}

#[test]
fn single_contact_local_form_every_variant() {
    let mass = 0.25;
    for (what, vf, mu) in cases() {
        let expected = exact(mass, vf, mu);
        for variant in VARIANT_NAMES.iter().copied().chain(["auto"]) {
            let w =
                CscMatrix::from_dense("W", 3, 3, &[4.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 4.0])
                    .unwrap();
            let p = LocalProblem::new(w, vf.to_vec(), vec![mu]).unwrap();
            check(Problem::Local(p), variant, expected, what);
        }
    }
}

/// A finite warm start far off the answer (impulses and velocities of 1e300, whose
/// products overflow) is a hint the solve drops: it ends solved at the exact answer, in
/// both forms and with every variant, instead of `numerical_error` at the warm start.
#[test]
fn an_enormous_warm_start_is_dropped() {
    let mass = 2.0;
    let (what, vf, mu) = cases()[2];
    let expected = exact(mass, vf, mu);
    let m = CscMatrix::from_dense("M", 3, 3, &[mass, 0.0, 0.0, 0.0, mass, 0.0, 0.0, 0.0, mass])
        .unwrap();
    let f = vf.iter().map(|x| mass * x).collect();
    let global = GlobalProblem::new(m, CscMatrix::identity(3), f, vec![0.0; 3], vec![mu]).unwrap();
    let w = CscMatrix::from_dense(
        "W",
        3,
        3,
        &[
            1.0 / mass,
            0.0,
            0.0,
            0.0,
            1.0 / mass,
            0.0,
            0.0,
            0.0,
            1.0 / mass,
        ],
    )
    .unwrap();
    let local = LocalProblem::new(w, vf.to_vec(), vec![mu]).unwrap();
    let starts: [([f64; 3], Option<[f64; 3]>); 3] = [
        ([1e300, 1e300, 0.0], Some([1e300, 0.0, 0.0])),
        ([-1e300, 0.0, 0.0], None),
        ([1e300, -1e300, 1e300], Some([-1e300, 1e300, 1e300])),
    ];
    for problem in [Problem::Global(global), Problem::Local(local)] {
        for variant in VARIANT_NAMES.iter().copied().chain(["auto"]) {
            for (r, v) in &starts {
                let settings = Settings {
                    tolerance: 1e-10,
                    variant: VariantChoice::from_name(variant).unwrap(),
                    ..Default::default()
                };
                let mut solver = Solver::new(problem.clone(), settings).unwrap();
                solver.warm_start(r, v.as_ref().map(|v| &v[..])).unwrap();
                let status = solver.solve().unwrap();
                let tag = format!("{what} with {variant}, warm start {r:?} {v:?}");
                assert_eq!(status, Status::Solved, "{tag}: {:?}", solver.stats());
                let got = &solver.solution().r;
                for k in 0..3 {
                    assert!(
                        (got[k] - expected[k]).abs() <= 1e-6 * (1.0 + expected[k].abs()),
                        "{tag}: r = {got:?}, expected {expected:?}"
                    );
                }
            }
        }
    }
}
