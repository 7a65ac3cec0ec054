//! `cadmm bench-worker` (hidden): one traced cadmm solve, run by `cadmm bench` in a child
//! process so that a hang in the factorization or a crash cannot take the benchmark down.
//!
//! Writes the solution to `--out` and prints one JSON line:
//! `{"status", "iterations", "setup_seconds", "solve_seconds", "trace": [[seconds, error|null], ...]}`
//! where trace seconds count from the start of the solve (setup excluded).

use crate::solve::json_number;
use cadmm::{fclib, Settings, Solver, VariantChoice};
use clap::Args;
use std::fmt::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of the hidden `bench-worker` command.
#[derive(Args)]
pub struct WorkerArgs {
    /// FCLib problem file.
    file: PathBuf,
    /// `auto` or a seed 000 variant name.
    #[arg(long)]
    variant: String,
    /// Anderson memory; default: the variant's.
    #[arg(long)]
    anderson: Option<usize>,
    /// Tolerance (the smallest of the benchmark).
    #[arg(long)]
    tol: f64,
    /// Time limit of the solve, seconds.
    #[arg(long)]
    time_limit: f64,
    /// Iteration limit.
    #[arg(long)]
    max_iter: usize,
    /// Where to write /solution.
    #[arg(long)]
    out: PathBuf,
}

fn work(a: &WorkerArgs) -> Result<String, cadmm::Error> {
    let settings = Settings {
        tolerance: a.tol,
        max_iterations: a.max_iter,
        time_limit: a.time_limit,
        variant: VariantChoice::from_name(&a.variant)?,
        anderson: a.anderson,
        // The trace gives the time to reach every tolerance from one run. Its cost (the
        // error measure at every iteration instead of every 5th) is included in the times.
        trace: true,
        ..Settings::default()
    };
    let problem = fclib::read(&a.file)?;
    let mut solver = Solver::new(problem, settings)?;
    let status = solver.solve()?;
    fclib::write_solution(&a.out, &solver.solution())?;
    let st = solver.stats();
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
        "{{\"status\": \"{}\", \"iterations\": {}, \"setup_seconds\": {}, \"solve_seconds\": {}, \"trace\": [{trace}]}}",
        status.name(),
        st.iterations,
        json_number(st.setup_seconds),
        json_number(st.solve_seconds),
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
