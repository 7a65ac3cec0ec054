//! CI smoke test of `cadmm bench` (benchmarks are not tests: two tiny files, a short limit).
//!
//! Checks that every solver x file has its row in `results.csv`, that the PNGs and
//! `summary.md` are written, and that the CSV's errors are those of the kept solutions,
//! re-measured by `cadmm::measure::problem_error` and, when a Python with h5py/scipy is
//! around, by `../shared/tools/fc_error.py`. With Siconos importable by `/usr/bin/python3`
//! (or `$CADMM_PYTHON`), a second run includes `siconos:ADMM`.

mod common;

use common::{shared, siconos_python};
use std::path::{Path, PathBuf};
use std::process::Command;

const FILES: [&str; 2] = ["global/GFC3D_Example1.hdf5", "local/FC3D_Example1.hdf5"];

fn problem_path(rel: &str) -> PathBuf {
    let p = shared().join("data/fclib").join(rel);
    assert!(p.is_file(), "bench_smoke: {} is missing", p.display());
    p
}

fn stem(rel: &str) -> String {
    Path::new(rel)
        .file_stem()
        .unwrap()
        .to_string_lossy()
        .into_owned()
}

fn file_tag(solver: &str) -> String {
    solver
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Equal up to round-off: relative 1e-6, and an absolute 1e-13 for errors near machine
/// precision (the Newton polish ends there), where two implementations of the measure
/// differ in their leading digits.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs()) + 1e-13
}

/// `(r, v, lambda)` of a solution file.
fn read_solution(path: &Path) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let s = cadmm::fclib::read_solution(path).unwrap_or_else(|e| panic!("{e}"));
    (s.r, s.v, s.lambda)
}

/// A Python that imports what fc_error.py needs, if any.
fn python_with_h5py() -> Option<&'static str> {
    ["python3", "/usr/bin/python3"].into_iter().find(|py| {
        Command::new(py)
            .args(["-c", "import numpy, scipy, h5py"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// The error fc_error.py computes, at full precision (its command line prints 4 digits).
fn fc_error(py: &str, problem: &Path, sol: &Path) -> f64 {
    let tools = shared().join("tools");
    let script = "import sys, numpy as np, h5py\n\
                  sys.path.insert(0, sys.argv[1])\n\
                  import fclib_read, fc_error\n\
                  d = fclib_read.read(sys.argv[2])\n\
                  s = h5py.File(sys.argv[3], 'r')['solution']\n\
                  v = np.array(s['v']) if 'v' in s else None\n\
                  print(repr(float(fc_error.error(d, np.array(s['r']), v))))\n";
    let o = Command::new(py)
        .args(["-c", script])
        .arg(&tools)
        .arg(problem)
        .arg(sol)
        .output()
        .expect("python runs");
    assert!(
        o.status.success(),
        "fc_error.py failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).trim().parse().unwrap()
}

fn smoke(name: &str, solvers: &[&str]) {
    let out = std::env::temp_dir().join(format!("cadmm-bench-smoke-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = Command::new(env!("CARGO_BIN_EXE_cadmm"))
        .arg("bench")
        .args(["--solvers", &solvers.join(",")])
        .args(["--tol", "1e-6,1e-8", "--time-limit", "5", "--repeat", "1"])
        .arg("--keep-solutions")
        .arg("--out")
        .arg(&out)
        .args(FILES.iter().map(|f| problem_path(f)))
        .output()
        .expect("cadmm bench runs");
    let stderr = String::from_utf8_lossy(&o.stderr);
    eprintln!("{stderr}");
    assert!(o.status.success(), "cadmm bench failed: {}", o.status);

    // results.csv: the header, and one row per solver x file.
    let csv = std::fs::read_to_string(out.join("results.csv")).expect("results.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        header,
        [
            "problem",
            "form",
            "solver",
            "repeat",
            "status",
            "iterations",
            "seconds",
            "error",
            "seconds_to_1e-6",
            "seconds_to_1e-8"
        ]
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), FILES.len() * solvers.len(), "{csv}");
    // The independent Python measure is required: .ci/run installs numpy/scipy/h5py.
    let py = python_with_h5py()
        .expect("bench_smoke: no python3 with numpy, scipy and h5py to run fc_error.py");
    for rel in FILES {
        let problem_file = problem_path(rel);
        let problem = cadmm::fclib::read(&problem_file).unwrap();
        for solver in solvers {
            let row = rows
                .iter()
                .find(|r| r[0] == stem(rel) && r[2] == *solver)
                .unwrap_or_else(|| panic!("no row for {rel} {solver}:\n{csv}"));
            if solver.starts_with("cadmm:") {
                assert_eq!(row[4], "solved", "{row:?}");
                let t: f64 = row[9].parse().unwrap();
                assert!(t.is_finite() && t > 0.0, "{row:?}");
            }
            if row[7].is_empty() {
                continue; // no answer (a peer that could not run)
            }
            let csv_error: f64 = row[7].parse().unwrap();
            let sol = out
                .join("solutions")
                .join(format!("{}.{}.h5", stem(rel), file_tag(solver)));
            let (r, v, l) = read_solution(&sol);
            let again = cadmm::measure::problem_error(&problem, &r, &v, &l);
            assert!(
                close(csv_error, again),
                "{row:?}: CSV {csv_error}, re-measured {again}"
            );
            let theirs = fc_error(py, &problem_file, &sol);
            assert!(
                close(csv_error, theirs),
                "{row:?}: CSV {csv_error}, fc_error.py {theirs}"
            );
            if row[4] == "solved" {
                // "solved" is a claim about the common measure at the tolerance of the run.
                assert!(
                    theirs <= 1e-8,
                    "{row:?}: solved, but fc_error.py says {theirs}"
                );
            }
        }
    }

    // The plots and the summary.
    let mut pngs = vec![out.join("profile-1e-6.png"), out.join("profile-1e-8.png")];
    pngs.extend(
        FILES
            .iter()
            .map(|f| out.join("work-precision").join(format!("{}.png", stem(f)))),
    );
    for p in pngs {
        let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(
            bytes.starts_with(b"\x89PNG"),
            "{} is not a PNG",
            p.display()
        );
    }
    let md = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(md.contains("## tol = 1e-8"), "{md}");
    for solver in solvers {
        assert!(md.contains(solver), "summary.md does not name {solver}");
    }
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bench_smoke_cadmm() {
    smoke("cadmm", &["cadmm:auto", "cadmm:cp-N"]);
}

#[test]
fn bench_smoke_with_siconos() {
    // Required in CI (.ci/run installs python3-siconos); elsewhere a missing Siconos says so.
    if siconos_python().is_none() {
        assert!(
            std::env::var_os("CI").is_none(),
            "bench_smoke: Siconos is not importable by /usr/bin/python3 ($CADMM_PYTHON) in CI"
        );
        println!(
            "bench_smoke: Siconos is not importable by /usr/bin/python3 ($CADMM_PYTHON); skipped"
        );
        return;
    }
    smoke("siconos", &["cadmm:auto", "siconos:ADMM"]);
}
