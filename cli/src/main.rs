//! `cadmm`: solve FCLib problem files from the command line (`solve`), and compare solvers
//! on them (`bench`).

mod bench;
mod font;
mod plot;
mod profile;
mod run;
mod runner;
mod siconos;
mod solve;
mod spec;
mod summary;
mod worker;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "cadmm",
    version,
    about = "ADMM solver for 3D frictional contact problems (FCLib files)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Solve one FCLib file and print a one-line JSON summary.
    Solve(solve::SolveArgs),
    /// Time solvers (cadmm configurations, Siconos) on FCLib files with one error measure:
    /// results.csv, performance profiles, work-precision plots and summary.md.
    Bench(bench::BenchArgs),
    /// One traced solve for `bench`, run in a child process (internal).
    #[command(hide = true)]
    BenchWorker(worker::WorkerArgs),
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Solve(a) => solve::run(a),
        Command::Bench(a) => bench::run(a),
        Command::BenchWorker(a) => worker::run(a),
    }
}
