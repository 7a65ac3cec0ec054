//! The Siconos side of `cadmm bench`: `bench/siconos_solve.py` run by a Python that has
//! `python3-siconos` (Debian's `/usr/bin/python3` by default), in a child process.
//!
//! Siconos has no trace: its time to reach a tolerance is its total time when its final
//! error (re-measured here) is below that tolerance. With `--peer-per-tol` it is run once per
//! tolerance instead, which does not charge it the time of the smallest one.

use crate::run::{last_line, measure, verdict, Limits, Run};
use crate::runner::{self, ChildEnd};
use cadmm::Problem;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// Where the interpreter and the script are.
pub struct Peer {
    /// Python interpreter.
    pub python: PathBuf,
    /// `siconos_solve.py`.
    pub script: PathBuf,
}

impl Peer {
    /// `--python`, else `$CADMM_PYTHON`, else `/usr/bin/python3`; `--siconos-script`, else
    /// `$CADMM_SICONOS_SCRIPT`, else `bench/siconos_solve.py` of the crate this binary was
    /// built from.
    pub fn locate(python: Option<PathBuf>, script: Option<PathBuf>) -> Self {
        let env = |k: &str| std::env::var_os(k).map(PathBuf::from);
        Peer {
            python: python
                .or_else(|| env("CADMM_PYTHON"))
                .unwrap_or_else(|| "/usr/bin/python3".into()),
            script: script
                .or_else(|| env("CADMM_SICONOS_SCRIPT"))
                .unwrap_or_else(|| {
                    Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/siconos_solve.py")
                }),
        }
    }

    /// `Ok(())` when the script exists and the interpreter imports `siconos.numerics`;
    /// otherwise why not.
    pub fn check(&self) -> Result<(), String> {
        if !self.script.is_file() {
            return Err(format!(
                "the peer script {} is missing (use --siconos-script or CADMM_SICONOS_SCRIPT)",
                self.script.display()
            ));
        }
        let mut cmd = Command::new(&self.python);
        cmd.args(["-c", "import siconos.numerics, h5py, scipy"]);
        match runner::run(cmd, Duration::from_secs(120)) {
            Ok(ChildEnd::Exited { code: Some(0), .. }) => Ok(()),
            Ok(ChildEnd::Exited { stderr, .. }) => Err(format!(
                "{} cannot import siconos.numerics/h5py/scipy ({}); install python3-siconos \
                 python3-h5py python3-scipy, or point --python/CADMM_PYTHON at a Python that has them",
                self.python.display(),
                last_line(&stderr).unwrap_or_default()
            )),
            Ok(ChildEnd::Killed) => Err(format!("{} hangs", self.python.display())),
            Err(e) => Err(e),
        }
    }

    /// One call of the script, stopping at `tol`; `to_tol` is left infinite (the caller
    /// fills it in).
    fn once(
        &self,
        name: &str,
        file: &Path,
        problem: &Problem,
        tol: f64,
        lim: &Limits,
        sol: &Path,
    ) -> Run {
        let n = lim.tols.len();
        let _ = std::fs::remove_file(sol);
        let mut cmd = Command::new(&self.python);
        cmd.arg(&self.script)
            .arg(file)
            .args(["--solver", name])
            .args(["--tol", &format!("{tol:e}")])
            .args(["--time-limit", &format!("{:e}", lim.time_limit)])
            .args(["--max-iter", &lim.max_iter.to_string()])
            .arg("--out")
            .arg(sol);
        let (stdout, stderr) = match runner::run(cmd, lim.deadline()) {
            Err(e) => return Run::failure("error", n, Some(e)),
            Ok(ChildEnd::Killed) => return Run::failure("timeout", n, None),
            Ok(ChildEnd::Exited {
                code: Some(0),
                stdout,
                stderr,
            }) => (stdout, stderr),
            Ok(ChildEnd::Exited { stderr, .. }) => {
                return Run::failure("error", n, last_line(&stderr))
            }
        };
        // The JSON line is the last line of stdout.
        let line = stdout
            .lines()
            .rev()
            .find(|l| l.trim_start().starts_with('{'));
        let Some(j) = line.and_then(|l| serde_json::from_str::<serde_json::Value>(l).ok()) else {
            return Run::failure("error", n, last_line(&stderr).or(Some(stdout)));
        };
        let reported = j["status"].as_str().unwrap_or("failed").to_string();
        let seconds = j["seconds"].as_f64();
        let iterations = j["iterations"].as_u64().map(|k| k as usize);
        if !sol.is_file() {
            // time_limit or crash: no solution came back.
            let mut r = Run::failure(&reported, n, last_line(&stderr));
            r.seconds = seconds;
            r.iterations = iterations;
            return r;
        }
        let error = match measure(problem, sol) {
            Ok(e) => e,
            Err(e) => return Run::failure("error", n, Some(e)),
        };
        let secs = seconds.unwrap_or(f64::INFINITY);
        Run {
            status: verdict(&reported, error, secs, lim),
            iterations,
            seconds,
            error: Some(error),
            to_tol: vec![f64::INFINITY; n],
            curve: vec![(secs, error)],
            trace: Vec::new(),
            trace_scale: 1.0,
            trace_islands: 1,
            note: None,
        }
    }

    /// Runs Siconos solver `name` (stopping at the smallest tolerance), writing its solution
    /// to `sol` when it returns one.
    pub fn run(
        &self,
        name: &str,
        file: &Path,
        problem: &Problem,
        lim: &Limits,
        per_tol: bool,
        sol: &Path,
    ) -> Run {
        let tmin = lim.tmin();
        let mut main = self.once(name, file, problem, tmin, lim, sol);
        let reached = |r: &Run, tol: f64| match (r.seconds, r.error) {
            (Some(s), Some(e)) if e <= tol && s <= lim.time_limit => s,
            _ => f64::INFINITY,
        };
        let mut extra = Vec::new();
        for (k, &tol) in lim.tols.iter().enumerate() {
            main.to_tol[k] = if per_tol && tol > tmin {
                let other = sol.with_extension(format!("tol{k}.h5"));
                let r = self.once(name, file, problem, tol, lim, &other);
                let _ = std::fs::remove_file(&other);
                extra.extend(r.curve.iter().copied());
                reached(&r, tol)
            } else {
                reached(&main, tol)
            };
        }
        main.curve.extend(extra);
        main.curve.sort_by(|a, b| a.0.total_cmp(&b.0));
        main
    }
}

/// The installed Debian package's version, when there is one (for the summary).
pub fn version() -> Option<String> {
    let mut cmd = Command::new("dpkg-query");
    cmd.args(["-W", "-f=${Version}", "python3-siconos"]);
    match runner::run(cmd, Duration::from_secs(20)) {
        Ok(ChildEnd::Exited {
            code: Some(0),
            stdout,
            ..
        }) if !stdout.trim().is_empty() => Some(stdout.trim().to_string()),
        _ => None,
    }
}
