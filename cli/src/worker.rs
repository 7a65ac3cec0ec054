//! `cadmm bench-worker` (hidden): the cadmm solves of one benchmark cell, run by
//! `cadmm bench` in a child process so that a hang in the factorization or a crash cannot
//! take the benchmark down.
//!
//! One untraced solve per tolerance (a new solver each, as a user would run it: these are
//! the timed figures), then one traced solve at the smallest tolerance whose trace only
//! draws the error-against-time curve. Writes the solution of the untraced solve at the
//! smallest tolerance to `--out` and prints one JSON line:
//! `{"runs": [{"tol", "status", "iterations", "error", "setup_seconds", "solve_seconds"}, ...],
//!   "trace_solve_seconds": s, "trace_islands": k, "trace": [[seconds, error|null], ...]}`
//! (runs in the order of `--tols`; trace seconds count from the start of the traced solve,
//! setup excluded; `trace_solve_seconds` is the traced solve's own time, longer than the
//! untraced one by what the trace costs; with `trace_islands` > 1 the trace is that of the
//! island that needed the most iterations, its error that island's).

use crate::solve::json_number;
use cadmm::{fclib, Problem, Settings, Solver, VariantChoice};
use clap::Args;
use std::fmt::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of the hidden `bench-worker` command.
#[derive(Args)]
pub struct WorkerArgs {
    /// FCLib problem file.
    file: PathBuf,
    /// `auto`, `newton` or an ADMM variant name.
    #[arg(long)]
    variant: String,
    /// Anderson memory; default: the variant's.
    #[arg(long)]
    anderson: Option<usize>,
    /// Newton polish on or off; default: the variant's.
    #[arg(long)]
    newton: Option<bool>,
    /// Tolerances, comma separated; the smallest one's solution is written.
    #[arg(long, value_delimiter = ',')]
    tols: Vec<f64>,
    /// Time limit of each solve, seconds.
    #[arg(long)]
    time_limit: f64,
    /// Iteration limit.
    #[arg(long)]
    max_iter: usize,
    /// Where to write /solution.
    #[arg(long)]
    out: PathBuf,
}

fn settings(a: &WorkerArgs, tol: f64, trace: bool) -> Result<Settings, cadmm::Error> {
    Ok(Settings {
        tolerance: tol,
        max_iterations: a.max_iter,
        time_limit: a.time_limit,
        variant: VariantChoice::from_name(&a.variant)?,
        anderson: a.anderson,
        newton_polish: a.newton,
        trace,
        ..Settings::default()
    })
}

fn work(a: &WorkerArgs) -> Result<String, cadmm::Error> {
    let problem: Problem = fclib::read(&a.file)?;
    let tmin = a.tols.iter().copied().fold(f64::INFINITY, f64::min);
    let mut runs = String::new();
    for (k, &tol) in a.tols.iter().enumerate() {
        let mut solver = Solver::new(problem.clone(), settings(a, tol, false)?)?;
        let status = solver.solve()?;
        if tol == tmin {
            fclib::write_solution(&a.out, solver.solution())?;
        }
        let st = solver.stats();
        let sep = if k == 0 { "" } else { ", " };
        let _ = write!(
            runs,
            "{sep}{{\"tol\": {}, \"status\": \"{}\", \"iterations\": {}, \"error\": {}, \"setup_seconds\": {}, \"solve_seconds\": {}}}",
            json_number(tol),
            status.name(),
            st.iterations,
            json_number(st.error),
            json_number(st.setup_seconds),
            json_number(st.solve_seconds),
        );
    }
    let mut solver = Solver::new(problem, settings(a, tmin, true)?)?;
    solver.solve()?;
    let mut trace = String::with_capacity(40 * solver.trace().len());
    for (k, p) in solver.trace().iter().enumerate() {
        let sep = if k == 0 { "" } else { "," };
        let _ = write!(
            trace,
            "{sep}[{},{}]",
            json_number(p.seconds),
            json_number(p.error)
        );
    }
    Ok(format!(
        "{{\"runs\": [{runs}], \"trace_solve_seconds\": {}, \"trace_islands\": {}, \"trace\": [{trace}]}}",
        json_number(solver.stats().solve_seconds),
        solver.stats().islands
    ))
}

/// Runs the worker: exit code 0 with the JSON line, 2 with a message on stderr.
pub fn run(a: WorkerArgs) -> ExitCode {
    match work(&a) {
        Ok(line) => {
            println!("{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("cadmm bench-worker: {e}");
            ExitCode::from(2)
        }
    }
}
