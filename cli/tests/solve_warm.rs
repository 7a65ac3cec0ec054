//! `cadmm solve --warm`: a solve started from a solution file (as `--out` writes it, or as
//! the demo's `--dump` writes a step's warm start).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn problem(rel: &str) -> PathBuf {
    let shared = std::env::var_os("CADMM_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"));
    let p = shared.join("data/fclib").join(rel);
    assert!(p.is_file(), "solve_warm: {} is missing", p.display());
    p
}

fn solve(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cadmm"))
        .arg("solve")
        .args(args)
        .output()
        .expect("cadmm runs")
}

/// The value of `"key": value` in the JSON line.
fn field<'a>(json: &'a str, key: &str) -> &'a str {
    let start = json
        .find(&format!("\"{key}\": "))
        .unwrap_or_else(|| panic!("no {key} in {json}"))
        + key.len()
        + 4;
    let rest = &json[start..];
    rest[..rest.find([',', '}']).unwrap()].trim_matches('"')
}

#[test]
fn a_warm_start_from_the_solution_needs_no_iteration() {
    let dir = std::env::temp_dir().join(format!("cadmm-solve-warm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("solution.hdf5");
    for rel in ["global/Box_Stacks-i0122-82-5.hdf5", "local/Rover1039.hdf5"] {
        let file = problem(rel);
        let (file, out_s) = (file.to_str().unwrap(), out.to_str().unwrap());
        let cold = solve(&[file, "--out", out_s]);
        assert!(cold.status.success(), "{rel}: {cold:?}");
        let cold = String::from_utf8(cold.stdout).unwrap();
        assert_eq!(field(&cold, "status"), "solved", "{rel}: {cold}");
        assert_ne!(field(&cold, "iterations"), "0", "{rel}: {cold}");

        // Started from its own solution, the solve is measured and ends at once, with the
        // error of the cold solve.
        let warm = solve(&[file, "--warm", out_s]);
        assert!(warm.status.success(), "{rel}: {warm:?}");
        let warm = String::from_utf8(warm.stdout).unwrap();
        assert_eq!(field(&warm, "status"), "solved", "{rel}: {warm}");
        assert_eq!(field(&warm, "iterations"), "0", "{rel}: {warm}");
        assert_eq!(field(&warm, "error"), field(&cold, "error"), "{rel}");
    }
    // A warm start of another problem's size is refused by name.
    let other = problem("local/FC3D_Example1.hdf5");
    let wrong = solve(&[other.to_str().unwrap(), "--warm", out.to_str().unwrap()]);
    assert_eq!(wrong.status.code(), Some(2));
    let message = String::from_utf8(wrong.stderr).unwrap();
    assert!(
        message.contains("dimension mismatch in r: expected 9"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
