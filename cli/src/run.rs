//! One benchmark run of one solver on one problem, and the cadmm side of it (the hidden
//! `bench-worker` command in a child process). Every answer is re-measured here with
//! `cadmm::measure::problem_error` on the solution file the run wrote.

use crate::runner::{self, ChildEnd};
use crate::spec::SolverSpec;
use cadmm::Problem;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// The limits and tolerances every run of a benchmark shares.
pub struct Limits {
    /// Tolerances, in the order of the CSV columns.
    pub tols: Vec<f64>,
    /// Wall-clock limit of one solve, seconds.
    pub time_limit: f64,
    /// Iteration limit.
    pub max_iter: usize,
}

impl Limits {
    /// The tolerance runs stop at.
    pub fn tmin(&self) -> f64 {
        self.tols.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// When to kill a child: the solve limit plus a generous allowance for starting,
    /// reading the problem and the setup (factorization), which the solver's own limit
    /// does not cover.
    pub fn deadline(&self) -> Duration {
        self.deadline_for(1)
    }

    /// The same for a child that runs `solves` solves, each within the time limit.
    pub fn deadline_for(&self, solves: usize) -> Duration {
        Duration::from_secs_f64(solves as f64 * self.time_limit + self.time_limit.max(60.0) + 30.0)
    }
}

/// What one run gave.
#[derive(Debug, Clone)]
pub struct Run {
    /// `solved` (error <= smallest tol within the time limit), the solver's own stop reason
    /// (`time_limit`, `max_iterations`, `numerical_error`), `failed` (the solver stopped but
    /// the common error is above tol), `crash`, `timeout` (killed), `unsupported`, `error`.
    pub status: String,
    /// Iterations, when known.
    pub iterations: Option<usize>,
    /// Wall seconds of the solve, when it returned.
    pub seconds: Option<f64>,
    /// Final error by `problem_error`, when there is a solution.
    pub error: Option<f64>,
    /// Seconds to reach each tolerance (same order as `Limits::tols`); infinite on failure.
    pub to_tol: Vec<f64>,
    /// `(seconds, error)` of each untraced run, as a user runs it (cadmm: one per tolerance;
    /// a peer: one per run), for the work-precision plot.
    pub curve: Vec<(f64, f64)>,
    /// cadmm: the traced run's `(seconds, error)`, its solve clock multiplied by
    /// `trace_scale`; empty for a peer.
    pub trace: Vec<(f64, f64)>,
    /// Untraced solve seconds over traced solve seconds at the smallest tolerance: the trace
    /// itself costs time, and the plot must not show that cost as the solver's.
    pub trace_scale: f64,
    /// Contact islands of the traced run: above 1, the trace is its slowest island's.
    pub trace_islands: usize,
    /// A message worth printing (stderr of a failed child).
    pub note: Option<String>,
}

impl Run {
    /// A run without any answer.
    pub fn failure(status: &str, n_tols: usize, note: Option<String>) -> Self {
        Run {
            status: status.into(),
            iterations: None,
            seconds: None,
            error: None,
            to_tol: vec![f64::INFINITY; n_tols],
            curve: Vec::new(),
            trace: Vec::new(),
            trace_scale: 1.0,
            trace_islands: 1,
            note,
        }
    }
}

/// The common error of a solution file; infinite when its sizes do not fit the problem.
pub fn measure(problem: &Problem, file: &Path) -> Result<f64, String> {
    let s = cadmm::fclib::read_solution(file).map_err(|e| e.to_string())?;
    let fits = s.r.len() == 3 * problem.n_contacts()
        && match problem {
            Problem::Global(g) => s.v.len() == g.n(),
            Problem::Local(_) => true,
        };
    Ok(if fits {
        cadmm::measure::problem_error(problem, &s.r, &s.v, &s.lambda)
    } else {
        f64::INFINITY
    })
}

/// Final status from the solver's own report and the re-measured error: only the common
/// measure decides "solved".
pub fn verdict(reported: &str, error: f64, seconds: f64, lim: &Limits) -> String {
    if error <= lim.tmin() && seconds <= lim.time_limit {
        "solved".into()
    } else if seconds > lim.time_limit {
        "time_limit".into()
    } else if reported == "solved" {
        "failed".into()
    } else {
        reported.into()
    }
}

/// At most this many points of a trace go to a plot.
const MAX_CURVE_POINTS: usize = 4000;

fn thin(points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    if points.len() <= MAX_CURVE_POINTS {
        return points;
    }
    let stride = points.len().div_ceil(MAX_CURVE_POINTS);
    let last = points.len() - 1;
    points
        .into_iter()
        .enumerate()
        .filter(|(k, _)| k % stride == 0 || *k == last)
        .map(|(_, p)| p)
        .collect()
}

/// A short last line of a child's stderr for messages.
pub fn last_line(stderr: &str) -> Option<String> {
    stderr
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .map(|l| l.trim().chars().take(300).collect())
}

fn number(v: &serde_json::Value) -> f64 {
    // JSON null stands for a non-finite number.
    v.as_f64().unwrap_or(f64::INFINITY)
}

/// Runs a cadmm configuration through `exe bench-worker` and writes its solution to `sol`.
pub fn cadmm(
    exe: &Path,
    spec: &SolverSpec,
    file: &Path,
    problem: &Problem,
    lim: &Limits,
    sol: &Path,
) -> Run {
    let n = lim.tols.len();
    let SolverSpec::Cadmm {
        variant,
        anderson,
        newton,
    } = spec
    else {
        unreachable!("run::cadmm is only called for cadmm solvers")
    };
    let _ = std::fs::remove_file(sol);
    let tols: Vec<String> = lim.tols.iter().map(|t| format!("{t:e}")).collect();
    let mut cmd = Command::new(exe);
    cmd.arg("bench-worker")
        .arg(file)
        .args(["--variant", variant])
        .args(["--tols", &tols.join(",")])
        .args(["--time-limit", &format!("{:e}", lim.time_limit)])
        .args(["--max-iter", &lim.max_iter.to_string()])
        .arg("--out")
        .arg(sol);
    if let Some(m) = anderson {
        cmd.args(["--anderson", &m.to_string()]);
    }
    if let Some(on) = newton {
        cmd.args(["--newton", &on.to_string()]);
    }
    // One untraced solve per tolerance and the traced one.
    let (stdout, stderr) = match runner::run(cmd, lim.deadline_for(n + 1)) {
        Err(e) => return Run::failure("error", n, Some(e)),
        Ok(ChildEnd::Killed) => return Run::failure("timeout", n, None),
        Ok(ChildEnd::Exited {
            code: Some(0),
            stdout,
            stderr,
        }) => (stdout, stderr),
        Ok(ChildEnd::Exited { code, stderr, .. }) => {
            // Exit code 2 is an error the worker reported (e.g. a singular matrix); anything
            // else (a signal, a panic) is a crash.
            let status = if code == Some(2) { "error" } else { "crash" };
            return Run::failure(status, n, last_line(&stderr));
        }
    };
    let parsed: Result<serde_json::Value, _> = serde_json::from_str(stdout.trim());
    let Ok(j) = parsed else {
        return Run::failure("crash", n, last_line(&stderr).or(Some(stdout)));
    };
    // The timed figures: one untraced solve per tolerance.
    let runs = j["runs"].as_array().cloned().unwrap_or_default();
    let total = |r: &serde_json::Value| number(&r["setup_seconds"]) + number(&r["solve_seconds"]);
    let Some(last) = runs
        .iter()
        .find(|r| r["tol"].as_f64() == Some(lim.tmin()))
        .cloned()
    else {
        return Run::failure("crash", n, Some("no run at the smallest tolerance".into()));
    };
    let seconds = total(&last);
    let reported = last["status"].as_str().unwrap_or("failed").to_string();
    let error = match measure(problem, sol) {
        Ok(e) => e,
        Err(e) => return Run::failure("error", n, Some(e)),
    };
    let status = verdict(&reported, error, seconds, lim);
    // Seconds to each tolerance: its own run's, when it solved (the smallest one's also
    // re-measured above).
    let to_tol = lim
        .tols
        .iter()
        .map(|&tol| {
            let run = runs.iter().find(|r| r["tol"].as_f64() == Some(tol));
            let solved = run.is_some_and(|r| r["status"] == "solved")
                && (tol > lim.tmin() || status == "solved");
            match run {
                Some(r) if solved && total(r) <= lim.time_limit => total(r),
                _ => f64::INFINITY,
            }
        })
        .collect();
    // The untraced runs as points: seconds to return and the error they returned (the
    // smallest tolerance's re-measured above).
    let mut curve: Vec<(f64, f64)> = runs
        .iter()
        .map(|r| {
            let e = if r["tol"].as_f64() == Some(lim.tmin()) {
                error
            } else {
                number(&r["error"])
            };
            (total(r), e)
        })
        .collect();
    curve.sort_by(|a, b| a.0.total_cmp(&b.0));
    // The traced run's curve, its solve clock scaled to the untraced solve's and shifted by
    // the untraced setup: the shape of the error over the run, at the time a user sees.
    let setup = number(&last["setup_seconds"]);
    let traced = number(&j["trace_solve_seconds"]);
    let untraced = number(&last["solve_seconds"]);
    let trace_scale = if traced.is_finite() && traced > 0.0 && untraced.is_finite() {
        untraced / traced
    } else {
        1.0
    };
    let trace: Vec<(f64, f64)> = j["trace"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|p| (setup + trace_scale * number(&p[0]), number(&p[1])))
                .collect()
        })
        .unwrap_or_default();
    Run {
        status,
        iterations: last["iterations"].as_u64().map(|k| k as usize),
        seconds: Some(seconds),
        error: Some(error),
        to_tol,
        curve,
        trace: thin(trace),
        trace_scale,
        trace_islands: j["trace_islands"].as_u64().map_or(1, |k| k as usize),
        note: None,
    }
}
