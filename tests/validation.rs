//! Every validation error of problems, matrices and settings, asserting its kind and what
//! it names.

use cadmm::{CscMatrix, Error, GlobalProblem, InitialRho, LocalProblem, Problem, Settings, Solver};

fn identity3() -> CscMatrix {
    CscMatrix::identity(3)
}

#[test]
fn csc_structure_errors_name_the_matrix() {
    let e = CscMatrix::new("M", 3, 3, vec![0, 1, 2], vec![0, 1], vec![1.0, 1.0]).unwrap_err();
    assert!(matches!(e, Error::InvalidCsc { field: "M", .. }), "{e}");
    let e = CscMatrix::new("H", 3, 3, vec![0, 2, 1, 3], vec![0, 1, 2], vec![1.0; 3]).unwrap_err();
    assert!(
        matches!(&e, Error::InvalidCsc { field: "H", reason } if reason.contains("decrease")),
        "{e}"
    );
    let e = CscMatrix::new("W", 3, 3, vec![0, 1, 2, 3], vec![0, 5, 2], vec![1.0; 3]).unwrap_err();
    assert!(
        matches!(&e, Error::InvalidCsc { field: "W", reason } if reason.contains("out of range")),
        "{e}"
    );
    let e = CscMatrix::new("W", 3, 3, vec![0, 2, 2, 3], vec![1, 1, 2], vec![1.0; 3]).unwrap_err();
    assert!(
        matches!(&e, Error::InvalidCsc { reason, .. } if reason.contains("duplicate")),
        "{e}"
    );
    let e = CscMatrix::new("W", 3, 3, vec![1, 1, 2, 3], vec![0, 1, 2], vec![1.0; 3]).unwrap_err();
    assert!(matches!(e, Error::InvalidCsc { .. }), "{e}");
    let e = CscMatrix::new(
        "G",
        3,
        3,
        vec![0, 1, 2, 3],
        vec![0, 1, 2],
        vec![1.0, f64::NAN, 1.0],
    )
    .unwrap_err();
    assert_eq!(
        e,
        Error::InvalidValue {
            field: "G",
            index: 1,
            reason: "not finite"
        }
    );
    let e = CscMatrix::from_triplets("H", 2, 2, &[(0, 0, 1.0), (2, 0, 1.0)]).unwrap_err();
    assert!(matches!(e, Error::InvalidCsc { field: "H", .. }), "{e}");
}

#[test]
fn unsorted_rows_are_accepted_and_sorted() {
    let a = CscMatrix::new("W", 3, 1, vec![0, 3], vec![2, 0, 1], vec![3.0, 1.0, 2.0]).unwrap();
    assert_eq!(a.rowind(), &[0, 1, 2]);
    assert_eq!(a.values(), &[1.0, 2.0, 3.0]);
}

#[test]
fn global_problem_errors() {
    let ok = || {
        GlobalProblem::new(
            identity3(),
            identity3(),
            vec![-1.0, 0.0, 0.0],
            vec![0.0; 3],
            vec![0.5],
        )
    };
    assert!(ok().is_ok());
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![-1.0, 0.0],
        vec![0.0; 3],
        vec![0.5],
    )
    .unwrap_err();
    assert_eq!(
        e,
        Error::Dimension {
            field: "f",
            expected: 3,
            found: 2
        }
    );
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0; 3],
        vec![0.0; 6],
        vec![0.5],
    )
    .unwrap_err();
    assert_eq!(
        e,
        Error::Dimension {
            field: "w",
            expected: 3,
            found: 6
        }
    );
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0; 3],
        vec![0.0; 3],
        vec![0.5, 0.5],
    )
    .unwrap_err();
    // Two friction coefficients for H's one contact (issue 41: named mu, not H).
    assert_eq!(
        e,
        Error::Dimension {
            field: "mu",
            expected: 1,
            found: 2
        }
    );
    let h = CscMatrix::identity(4);
    let e = GlobalProblem::new(identity3(), h, vec![0.0; 3], vec![0.0; 3], vec![0.5]).unwrap_err();
    assert!(matches!(e, Error::Dimension { field: "H", .. }), "{e}");
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0, f64::INFINITY, 0.0],
        vec![0.0; 3],
        vec![0.5],
    )
    .unwrap_err();
    assert_eq!(
        e,
        Error::InvalidValue {
            field: "f",
            index: 1,
            reason: "not finite"
        }
    );
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0; 3],
        vec![0.0, 0.0, f64::NAN],
        vec![0.5],
    )
    .unwrap_err();
    assert_eq!(
        e,
        Error::InvalidValue {
            field: "w",
            index: 2,
            reason: "not finite"
        }
    );
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0; 3],
        vec![0.0; 3],
        vec![-0.1],
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            Error::InvalidValue {
                field: "mu",
                index: 0,
                ..
            }
        ),
        "{e}"
    );
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0; 3],
        vec![0.0; 3],
        vec![f64::NAN],
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            Error::InvalidValue {
                field: "mu",
                index: 0,
                ..
            }
        ),
        "{e}"
    );
    let e = ok()
        .unwrap()
        .with_joints(CscMatrix::identity(2), vec![0.0; 2])
        .unwrap_err();
    assert!(matches!(e, Error::Dimension { field: "G", .. }), "{e}");
    let g = CscMatrix::from_dense("G", 3, 1, &[0.0, 1.0, 0.0]).unwrap();
    let e = ok().unwrap().with_joints(g, vec![0.0; 2]).unwrap_err();
    assert_eq!(
        e,
        Error::Dimension {
            field: "b",
            expected: 1,
            found: 2
        }
    );
}

#[test]
fn local_problem_errors() {
    // W says two contacts: q and mu, of one, are named (the first, q).
    let e = LocalProblem::new(CscMatrix::identity(6), vec![0.0; 3], vec![0.5]).unwrap_err();
    assert!(matches!(e, Error::Dimension { field: "q", .. }), "{e}");
    let e = LocalProblem::new(CscMatrix::identity(4), vec![0.0; 3], vec![0.5]).unwrap_err();
    assert!(matches!(e, Error::Dimension { field: "W", .. }), "{e}");
    let e = LocalProblem::new(identity3(), vec![0.0; 6], vec![0.5]).unwrap_err();
    assert_eq!(
        e,
        Error::Dimension {
            field: "q",
            expected: 3,
            found: 6
        }
    );
    let e = LocalProblem::new(identity3(), vec![f64::NAN, 0.0, 0.0], vec![0.5]).unwrap_err();
    assert_eq!(
        e,
        Error::InvalidValue {
            field: "q",
            index: 0,
            reason: "not finite"
        }
    );
    let e = LocalProblem::new(identity3(), vec![0.0; 3], vec![-1.0]).unwrap_err();
    assert!(matches!(e, Error::InvalidValue { field: "mu", .. }), "{e}");
}

#[test]
fn mass_matrix_not_positive_definite_is_refused_at_factorization() {
    for diag in [[1.0, -1.0, 1.0], [1.0, 0.0, 1.0]] {
        let m = CscMatrix::from_dense(
            "M",
            3,
            3,
            &[diag[0], 0.0, 0.0, 0.0, diag[1], 0.0, 0.0, 0.0, diag[2]],
        )
        .unwrap();
        let p = GlobalProblem::new(
            m,
            identity3(),
            vec![-1.0, 0.0, 0.0],
            vec![0.0; 3],
            vec![0.5],
        )
        .unwrap();
        let e = Solver::new(Problem::Global(p), Settings::default())
            .err()
            .unwrap();
        assert_eq!(e, Error::NotPositiveDefinite { field: "M" });
    }
    // W + rho I indefinite (symmetric W).
    let w = CscMatrix::from_dense(
        "W",
        3,
        3,
        &[-10.0, 0.0, 0.0, 0.0, -10.0, 0.0, 0.0, 0.0, -10.0],
    )
    .unwrap();
    let p = LocalProblem::new(w, vec![-1.0, 0.0, 0.0], vec![0.5]).unwrap();
    let s = Settings {
        initial_rho: Some(InitialRho::Given(1.0)),
        ..Default::default()
    };
    let e = Solver::new(Problem::Local(p), s).err().unwrap();
    assert_eq!(e, Error::NotPositiveDefinite { field: "W + rho I" });
    // Non-symmetric W with W + rho I singular: LU reports it.
    let w = CscMatrix::new(
        "W",
        3,
        3,
        vec![0, 1, 3, 4],
        vec![0, 0, 1, 2],
        vec![-1.0, 1.0, -1.0, -1.0],
    )
    .unwrap();
    let p = LocalProblem::new(w, vec![1.0, 0.0, 0.0], vec![0.5]).unwrap();
    let s = Settings {
        initial_rho: Some(InitialRho::Given(1.0)),
        ..Default::default()
    };
    let e = Solver::new(Problem::Local(p), s).err().unwrap();
    assert_eq!(e, Error::Singular { field: "W + rho I" });
}

#[test]
fn settings_errors_name_the_setting() {
    let p =
        || Problem::Local(LocalProblem::new(identity3(), vec![-1.0, 0.0, 0.0], vec![0.5]).unwrap());
    let bad = [
        Settings {
            tolerance: 0.0,
            ..Default::default()
        },
        Settings {
            tolerance: f64::NAN,
            ..Default::default()
        },
        Settings {
            tolerance: -1.0,
            ..Default::default()
        },
        Settings {
            max_iterations: 0,
            ..Default::default()
        },
        Settings {
            time_limit: 0.0,
            ..Default::default()
        },
        Settings {
            time_limit: f64::NAN,
            ..Default::default()
        },
        Settings {
            initial_rho: Some(InitialRho::Given(-2.0)),
            ..Default::default()
        },
        Settings {
            anderson: Some(1000),
            ..Default::default()
        },
        Settings {
            anderson_interval: 0,
            ..Default::default()
        },
    ];
    let names = [
        "tolerance",
        "tolerance",
        "tolerance",
        "max_iterations",
        "time_limit",
        "time_limit",
        "initial_rho",
        "anderson",
        "anderson_interval",
    ];
    for (s, name) in bad.into_iter().zip(names) {
        let e = Solver::new(p(), s).err().unwrap();
        assert!(
            matches!(e, Error::InvalidSetting { name: n, .. } if n == name),
            "{e}"
        );
    }
    let e = cadmm::VariantChoice::from_name("vp-X-He").unwrap_err();
    assert!(
        matches!(
            e,
            Error::InvalidSetting {
                name: "variant",
                ..
            }
        ),
        "{e}"
    );
    let e = InitialRho::from_name("largest", 0.0).unwrap_err();
    assert!(
        matches!(
            e,
            Error::InvalidSetting {
                name: "initial_rho",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn warm_start_checks_its_input() {
    let p =
        Problem::Local(LocalProblem::new(identity3(), vec![-1.0, 0.0, 0.0], vec![0.5]).unwrap());
    let mut s = Solver::new(p, Settings::default()).unwrap();
    assert_eq!(
        s.warm_start(&[0.0; 2], None).unwrap_err(),
        Error::Dimension {
            field: "r",
            expected: 3,
            found: 2
        }
    );
    assert!(matches!(
        s.warm_start(&[0.0, f64::NAN, 0.0], None).unwrap_err(),
        Error::InvalidValue { field: "r", .. }
    ));
}

#[test]
fn a_non_finite_iterate_stops_with_a_status_and_keeps_finite_values() {
    // Finite data whose solution overflows: v = M^-1 f with M = 1e-300 I and f = 1e300.
    let m = CscMatrix::from_dense(
        "M",
        3,
        3,
        &[1e-300, 0.0, 0.0, 0.0, 1e-300, 0.0, 0.0, 0.0, 1e-300],
    )
    .unwrap();
    let p = GlobalProblem::new(
        m,
        identity3(),
        vec![1e300, 1e300, 0.0],
        vec![0.0; 3],
        vec![0.5],
    )
    .unwrap();
    let s = Settings {
        initial_rho: Some(InitialRho::Given(1.0)),
        ..Default::default()
    };
    let mut solver = Solver::new(Problem::Global(p.clone()), s).unwrap();
    assert_eq!(solver.solve().unwrap(), cadmm::Status::NumericalError);
    let sol = solver.solution();
    for (name, x) in [("r", &sol.r), ("u", &sol.u), ("v", &sol.v)] {
        assert!(x.iter().all(|x| x.is_finite()), "{name} = {x:?}");
    }
    // The reported error is the measure of the solution handed back, and it is honest: the
    // iterate kept is not a solution.
    let stats = solver.stats();
    let again = cadmm::measure::global_error(&p, &sol.r, &sol.v, &sol.lambda);
    assert_eq!(
        stats.error.to_bits(),
        again.to_bits(),
        "{stats:?} vs {again}"
    );
    assert!(stats.error > 1e-8, "{stats:?}");
}

/// The problems' fields are public: a problem changed after its constructor checked it is
/// checked again by the solver, and gets the constructor's error, not a panic or a status.
#[test]
fn a_problem_changed_after_construction_is_refused_by_the_solver() {
    let valid = || {
        let h = CscMatrix::identity(6);
        GlobalProblem::new(
            CscMatrix::identity(6),
            h,
            vec![-1.0; 6],
            vec![0.0; 6],
            vec![0.5; 2],
        )
        .unwrap()
    };
    let mut p = valid();
    p.mu = vec![0.5, 0.5, 0.5];
    let e = Solver::new(Problem::Global(p), Settings::default()).err();
    assert!(matches!(e, Some(Error::Dimension { .. })), "{e:?}");

    let mut p = valid();
    p.f[3] = f64::NAN;
    let e = Solver::new(Problem::Global(p), Settings::default()).err();
    assert_eq!(
        e,
        Some(Error::InvalidValue {
            field: "f",
            index: 3,
            reason: "not finite"
        })
    );

    let mut p = valid();
    p.mu[1] = -0.1;
    let e = Solver::new(Problem::Global(p), Settings::default()).err();
    assert!(
        matches!(
            e,
            Some(Error::InvalidValue {
                field: "mu",
                index: 1,
                ..
            })
        ),
        "{e:?}"
    );

    let mut l = LocalProblem::new(CscMatrix::identity(3), vec![-1.0, 0.0, 0.0], vec![0.3]).unwrap();
    l.q.push(0.0);
    let e = Solver::new(Problem::Local(l), Settings::default()).err();
    assert!(
        matches!(e, Some(Error::Dimension { field: "q", .. })),
        "{e:?}"
    );

    // The same checks guard an update.
    let mut solver = Solver::new(Problem::Global(valid()), Settings::default()).unwrap();
    let mut p = valid();
    p.w[0] = f64::INFINITY;
    let e = solver.update(Problem::Global(p)).unwrap_err();
    assert!(
        matches!(
            e,
            Error::InvalidValue {
                field: "w",
                index: 0,
                ..
            }
        ),
        "{e}"
    );
}

/// An update with the solver's sizes but other non-zero positions names the matrix.
#[test]
fn an_update_with_another_pattern_names_the_matrix() {
    let m = CscMatrix::identity(3);
    let h = CscMatrix::identity(3);
    let p = GlobalProblem::new(m.clone(), h, vec![-1.0, 0.0, 0.0], vec![0.0; 3], vec![0.5]);
    let mut solver = Solver::new(Problem::Global(p.unwrap()), Settings::default()).unwrap();
    let h2 = CscMatrix::new("H", 3, 3, vec![0, 2, 3, 3], vec![0, 1, 1], vec![1.0; 3]).unwrap();
    let p2 = GlobalProblem::new(m, h2, vec![-1.0, 0.0, 0.0], vec![0.0; 3], vec![0.5]).unwrap();
    let e = solver.update(Problem::Global(p2)).unwrap_err();
    assert_eq!(e, Error::PatternChanged { field: "H" });
    assert!(e.to_string().contains("sparsity pattern of H"), "{e}");
}

/// Before its first solve, a solver's statistics say so.
#[test]
fn a_new_solver_is_unsolved() {
    let p = LocalProblem::new(CscMatrix::identity(3), vec![-1.0, 0.0, 0.0], vec![0.3]).unwrap();
    let mut solver = Solver::new(Problem::Local(p), Settings::default()).unwrap();
    assert_eq!(solver.stats().status, cadmm::Status::Unsolved);
    assert_eq!(solver.solve().unwrap(), cadmm::Status::Solved);
    assert_eq!(solver.stats().status, cadmm::Status::Solved);
}

/// Issue 41: the contact count is H's (or W's) columns over 3; a `mu` of another length is
/// `mu`'s error, not the matrix's.
#[test]
fn a_mu_of_the_wrong_length_is_named() {
    let e = GlobalProblem::new(
        identity3(),
        identity3(),
        vec![0.0; 3],
        vec![0.0; 3],
        vec![0.5, 0.5],
    )
    .unwrap_err();
    assert_eq!(
        e,
        Error::Dimension {
            field: "mu",
            expected: 1,
            found: 2
        }
    );
    let e = LocalProblem::new(identity3(), vec![0.0; 3], vec![0.5, 0.5]).unwrap_err();
    assert_eq!(
        e,
        Error::Dimension {
            field: "mu",
            expected: 1,
            found: 2
        }
    );
    let e = LocalProblem::new(identity3(), vec![0.0; 3], vec![]).unwrap_err();
    assert!(matches!(e, Error::Dimension { field: "mu", .. }), "{e}");
    // A column count that is not a multiple of 3 is the matrix's error.
    let h = CscMatrix::from_dense("H", 3, 4, &[0.0; 12]).unwrap();
    let e = GlobalProblem::new(identity3(), h, vec![0.0; 3], vec![0.0; 3], vec![0.5]).unwrap_err();
    assert!(matches!(e, Error::Dimension { field: "H", .. }), "{e}");
}
