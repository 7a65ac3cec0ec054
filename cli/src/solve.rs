//! `cadmm solve`: solve one FCLib file and print a one-line JSON summary.

use cadmm::{fclib, InitialRho, LinearSolver, SUpdate, Settings, Solver, VariantChoice};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `cadmm solve`.
#[derive(Args)]
pub struct SolveArgs {
    /// FCLib HDF5 problem file (fclib_global or fclib_local).
    file: PathBuf,
    /// Variant: auto, newton (semismooth Newton alone), cp-N ... vp-RR-Spectral.
    #[arg(long, default_value = "auto")]
    variant: String,
    /// Tolerance on the error measure.
    #[arg(long, default_value_t = 1e-8)]
    tol: f64,
    /// Iteration limit (the time limit is usually the one that binds).
    #[arg(long, default_value_t = 10_000_000)]
    max_iter: usize,
    /// Time limit in seconds.
    #[arg(long)]
    time_limit: Option<f64>,
    /// Anderson memory (0 = off); default: the variant's.
    #[arg(long)]
    anderson: Option<usize>,
    /// Try an Anderson step every N iterations.
    #[arg(long, default_value_t = 1)]
    anderson_interval: usize,
    /// Initial rho rule: normal, acary, ghadimi, dicairano, or a number (given).
    #[arg(long)]
    initial_rho: Option<String>,
    /// Newton polish: on or off; default: the variant's (on for auto, off for named variants).
    #[arg(long)]
    newton: Option<String>,
    /// s update: internal or external.
    #[arg(long, default_value = "internal")]
    s_update: String,
    /// Contact islands: on (each solved on its own) or off (the problem as one).
    #[arg(long, default_value = "on")]
    islands: String,
    /// Threads that solve islands side by side.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// v-update systems: auto (by a cost model), direct (factorized) or iterative
    /// (matrix-free conjugate gradients, no Newton phase).
    #[arg(long, default_value = "auto")]
    linear_solver: String,
    /// Warm start from /solution/{r, v} of this HDF5 file (as `--out` writes it).
    #[arg(long)]
    warm: Option<PathBuf>,
    /// Write r, u, v into /solution of this HDF5 file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the JSON summary (the default output; kept for scripts that pass it).
    #[arg(long)]
    json: bool,
}

fn settings_from(a: &SolveArgs) -> Result<Settings, cadmm::Error> {
    let initial_rho = match a.initial_rho.as_deref() {
        None => None,
        Some(s) => Some(match s.parse::<f64>() {
            Ok(v) => InitialRho::from_name("given", v)?,
            Err(_) => InitialRho::from_name(s, 0.0)?,
        }),
    };
    let s_update = match a.s_update.as_str() {
        "internal" => SUpdate::Internal,
        "external" => SUpdate::External,
        other => {
            return Err(cadmm::Error::InvalidSetting {
                name: "s_update",
                reason: format!("unknown mode '{other}' (expected internal or external)"),
            })
        }
    };
    let newton_polish = match a.newton.as_deref() {
        None => None,
        Some("on") => Some(true),
        Some("off") => Some(false),
        Some(other) => {
            return Err(cadmm::Error::InvalidSetting {
                name: "newton",
                reason: format!("expected on or off, got '{other}'"),
            })
        }
    };
    let islands = match a.islands.as_str() {
        "on" => true,
        "off" => false,
        other => {
            return Err(cadmm::Error::InvalidSetting {
                name: "islands",
                reason: format!("expected on or off, got '{other}'"),
            })
        }
    };
    let s = Settings {
        tolerance: a.tol,
        max_iterations: a.max_iter,
        time_limit: a.time_limit.unwrap_or(f64::INFINITY),
        variant: VariantChoice::from_name(&a.variant)?,
        initial_rho,
        s_update,
        anderson: a.anderson,
        anderson_interval: a.anderson_interval,
        trace: false,
        newton_polish,
        islands,
        threads: a.threads,
        linear_solver: LinearSolver::from_name(&a.linear_solver)?,
    };
    s.validate()?;
    Ok(s)
}

/// A JSON number, `null` when not finite (JSON has no infinity).
pub fn json_number(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        "null".into()
    }
}

/// Runs `cadmm solve`: exit code 0 with the JSON line on stdout, 2 with a message on stderr.
pub fn run(a: SolveArgs) -> ExitCode {
    let settings = settings_from(&a);
    let SolveArgs {
        file, out, warm, ..
    } = a;
    let run = || -> Result<String, cadmm::Error> {
        let settings = settings?;
        let problem = fclib::read(&file)?;
        let form = match problem {
            cadmm::Problem::Global(_) => "global",
            cadmm::Problem::Local(_) => "local",
        };
        let mut solver = Solver::new(problem, settings)?;
        if let Some(warm) = &warm {
            let guess = fclib::read_solution(warm)?;
            let v = (!guess.v.is_empty()).then_some(guess.v.as_slice());
            solver.warm_start(&guess.r, v)?;
        }
        let status = solver.solve()?;
        let st = *solver.stats();
        if let Some(out) = &out {
            fclib::write_solution(out, solver.solution())?;
        }
        let r = solver.resolved();
        Ok(format!(
            "{{\"file\": \"{}\", \"form\": \"{form}\", \"status\": \"{}\", \"iterations\": {}, \"error\": {}, \"seconds\": {}, \"setup_seconds\": {}, \"solve_seconds\": {}, \"rho\": {}, \"refactorizations\": {}, \"variant\": \"{}\", \"initial_rho\": \"{}\", \"anderson\": {}, \"anderson_accepted\": {}, \"anderson_rejected\": {}, \"newton\": \"{:?}\", \"newton_iterations\": {}, \"newton_factorizations\": {}, \"newton_phases\": {}, \"newton_fallbacks\": {}, \"islands\": {}, \"linear_iterations\": {}, \"gauss_seidel_sweeps\": {}}}",
            file.display().to_string().replace('\\', "\\\\").replace('"', "\\\""),
            status.name(),
            st.iterations,
            json_number(st.error),
            json_number(st.setup_seconds + st.solve_seconds),
            json_number(st.setup_seconds),
            json_number(st.solve_seconds),
            json_number(st.rho),
            st.refactorizations,
            r.variant.name(),
            r.initial_rho.name(),
            r.anderson,
            st.anderson_accepted,
            st.anderson_rejected,
            r.newton,
            st.newton_iterations,
            st.newton_factorizations,
            st.newton_phases,
            st.newton_fallbacks,
            st.islands,
            st.linear_iterations,
            st.gauss_seidel_sweeps,
        ))
    };
    match run() {
        Ok(line) => {
            println!("{line}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("cadmm: {e}");
            ExitCode::from(2)
        }
    }
}
