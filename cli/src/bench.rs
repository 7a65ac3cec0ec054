//! `cadmm bench`: time cadmm configurations and Siconos solvers on FCLib files, with the same
//! error measure for all, and write `results.csv`, performance profiles, work-precision plots
//! and `summary.md` (see `../shared/design/BENCHMARKING.md`).
//!
//! Runs are sequential (timings on a shared machine are noisy enough) and interleaved:
//! problem, then repeat, then solver, so that a slow phase of the machine hits every solver.

use crate::plot::{self, Curve};
use crate::profile;
use crate::run::{self, Limits, Run};
use crate::siconos::{self, Peer};
use crate::spec::SolverSpec;
use crate::summary;
use clap::Args;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Flags of `cadmm bench`.
#[derive(Args)]
pub struct BenchArgs {
    /// Comma-separated solvers: cadmm:auto, cadmm:newton, cadmm:<variant>[+aa<M>][+newton|+nonewton] (e.g. cadmm:cp-N+aa5, cadmm:auto+nonewton),
    /// siconos:<ADMM|NSGS|NSGS_WR|IPM|NSN_AC|PROX>.
    #[arg(long, value_delimiter = ',', required = true)]
    solvers: Vec<String>,
    /// Comma-separated tolerances on the error measure; a cadmm configuration runs once per tolerance.
    #[arg(long, value_delimiter = ',', default_value = "1e-4,1e-6,1e-8")]
    tol: Vec<f64>,
    /// Time limit of one solve, seconds.
    #[arg(long, default_value_t = 20.0)]
    time_limit: f64,
    /// Runs of every solver on every problem (times are medians over them).
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    /// Iteration limit of one solve (the same for every solver).
    #[arg(long, default_value_t = 100_000)]
    max_iter: usize,
    /// Output directory (created).
    #[arg(long)]
    out: PathBuf,
    /// Keep the first repeat's solutions as DIR/solutions/<problem>.<solver>.h5.
    #[arg(long)]
    keep_solutions: bool,
    /// Run each Siconos solver once per tolerance (default: once at the smallest; its time to
    /// a looser tolerance is then the time of that run).
    #[arg(long)]
    peer_per_tol: bool,
    /// Python with python3-siconos [default: $CADMM_PYTHON, else /usr/bin/python3].
    #[arg(long)]
    python: Option<PathBuf>,
    /// The Siconos peer script [default: $CADMM_SICONOS_SCRIPT, else bench/siconos_solve.py of
    /// this crate].
    #[arg(long)]
    siconos_script: Option<PathBuf>,
    /// FCLib problem files.
    #[arg(required = true)]
    files: Vec<PathBuf>,
}

/// A problem of the benchmark.
pub struct ProblemInfo {
    /// File stem: the problem's name in every output.
    pub name: String,
    /// `global` or `local`.
    pub form: &'static str,
}

/// One row of `results.csv`.
pub struct Row {
    /// Index into `Bench::problems`.
    pub problem: usize,
    /// Index into `Bench::solvers`.
    pub solver: usize,
    /// Repeat number, from 0.
    pub repeat: usize,
    /// What the run gave.
    pub run: Run,
}

/// Everything a finished benchmark produced, for the summary.
pub struct Bench {
    /// Problems that could be read.
    pub problems: Vec<ProblemInfo>,
    /// Solvers that ran.
    pub solvers: Vec<SolverSpec>,
    /// Shared limits.
    pub limits: Limits,
    /// Repeats.
    pub repeat: usize,
    /// All runs.
    pub rows: Vec<Row>,
    /// Things the reader must know (Siconos missing, unreadable files, ...).
    pub notes: Vec<String>,
    /// Whether Siconos ran once per tolerance.
    pub peer_per_tol: bool,
    /// How Siconos was run, when it was.
    pub siconos: Option<String>,
}

impl Bench {
    /// `t[p][s]`: median over repeats of the seconds to reach tolerance number `k`.
    pub fn times(&self, k: usize) -> Vec<Vec<f64>> {
        let mut samples = vec![vec![Vec::new(); self.solvers.len()]; self.problems.len()];
        for r in &self.rows {
            samples[r.problem][r.solver].push(r.run.to_tol[k]);
        }
        samples
            .iter()
            .map(|row| row.iter().map(|x| profile::median(x)).collect())
            .collect()
    }

    /// The first repeat's run of solver `s` on problem `p`.
    pub fn first(&self, p: usize, s: usize) -> Option<&Run> {
        self.rows
            .iter()
            .find(|r| r.problem == p && r.solver == s && r.repeat == 0)
            .map(|r| &r.run)
    }
}

/// `1e-6` style: the shortest text that reads back as the same number.
pub fn tol_name(t: f64) -> String {
    format!("{t:e}")
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        "inf".into()
    }
}

fn csv_row(b: &Bench, row: &Row) -> String {
    let r = &row.run;
    let mut f = vec![
        csv_field(&b.problems[row.problem].name),
        b.problems[row.problem].form.to_string(),
        csv_field(&b.solvers[row.solver].label()),
        row.repeat.to_string(),
        r.status.clone(),
        r.iterations.map_or(String::new(), |k| k.to_string()),
        r.seconds.map_or(String::new(), num),
        r.error.map_or(String::new(), num),
    ];
    f.extend(r.to_tol.iter().map(|&x| num(x)));
    f.join(",")
}

fn validate(a: &BenchArgs) -> Result<(Vec<SolverSpec>, Vec<f64>), String> {
    let mut specs: Vec<SolverSpec> = Vec::new();
    for s in &a.solvers {
        let spec = SolverSpec::parse(s)?;
        if specs.iter().any(|x| x.label() == spec.label()) {
            return Err(format!("solver {} is listed twice", spec.label()));
        }
        specs.push(spec);
    }
    let mut tols: Vec<f64> = Vec::new();
    for &t in &a.tol {
        if !(t.is_finite() && t > 0.0) {
            return Err(format!("tolerance {t} must be positive and finite"));
        }
        if !tols.contains(&t) {
            tols.push(t);
        }
    }
    if tols.is_empty() {
        return Err("no tolerance".into());
    }
    if !(a.time_limit.is_finite() && a.time_limit > 0.0) {
        return Err(format!(
            "--time-limit must be positive and finite, got {}",
            a.time_limit
        ));
    }
    if a.repeat == 0 || a.max_iter == 0 {
        return Err("--repeat and --max-iter must be at least 1".into());
    }
    let mut stems: Vec<String> = Vec::new();
    for f in &a.files {
        let stem = stem(f);
        if stems.contains(&stem) {
            return Err(format!(
                "two files are named {stem}: outputs are named by file stem"
            ));
        }
        stems.push(stem);
    }
    Ok((specs, tols))
}

fn stem(f: &Path) -> String {
    f.file_stem().map_or_else(
        || f.display().to_string(),
        |s| s.to_string_lossy().into_owned(),
    )
}

fn progress(b: &Bench, row: &Row, done: usize, total: usize) {
    let r = &row.run;
    let mut line = format!(
        "[{done}/{total}] {} {} #{}: {}",
        b.problems[row.problem].name,
        b.solvers[row.solver].label(),
        row.repeat,
        r.status
    );
    if let Some(s) = r.seconds {
        line += &format!(", {s:.3e} s");
    }
    if let Some(e) = r.error {
        line += &format!(", error {e:.2e}");
    }
    if let Some(n) = &r.note {
        line += &format!(" ({n})");
    }
    eprintln!("{line}");
}

fn execute(a: BenchArgs) -> Result<(), String> {
    let (mut specs, tols) = validate(&a)?;
    let mut notes = Vec::new();
    let peer = Peer::locate(a.python.clone(), a.siconos_script.clone());
    if specs.iter().any(|s| !s.is_cadmm()) {
        if let Err(why) = peer.check() {
            let dropped: Vec<String> = specs
                .iter()
                .filter(|s| !s.is_cadmm())
                .map(|s| s.label())
                .collect();
            let msg = format!(
                "Siconos is not available: {why}. Not run: {}.",
                dropped.join(", ")
            );
            eprintln!("cadmm bench: {msg}");
            notes.push(msg);
            specs.retain(|s| s.is_cadmm());
        }
    }
    if specs.is_empty() {
        return Err("no solver left to run".into());
    }
    let exe = std::env::current_exe().map_err(|e| format!("cannot locate cadmm itself: {e}"))?;
    let out = &a.out;
    let mkdir = |d: &Path| {
        std::fs::create_dir_all(d).map_err(|e| format!("cannot create {}: {e}", d.display()))
    };
    mkdir(out)?;
    mkdir(&out.join("work-precision"))?;
    if a.keep_solutions {
        mkdir(&out.join("solutions"))?;
    }
    let scratch = std::env::temp_dir().join(format!("cadmm-bench-{}", std::process::id()));
    mkdir(&scratch)?;
    let plots = crate::font::font();
    if let Err(why) = &plots {
        let msg = format!("No PNG written: {why}.");
        eprintln!("cadmm bench: {msg}");
        notes.push(msg);
    }

    let mut b = Bench {
        problems: Vec::new(),
        solvers: specs,
        limits: Limits {
            tols,
            time_limit: a.time_limit,
            max_iter: a.max_iter,
        },
        repeat: a.repeat,
        rows: Vec::new(),
        notes,
        peer_per_tol: a.peer_per_tol,
        siconos: None,
    };
    if b.solvers.iter().any(|s| !s.is_cadmm()) {
        b.siconos = Some(format!(
            "python3-siconos {} through `{} {}`",
            siconos::version().unwrap_or_else(|| "(version unknown)".into()),
            peer.python.display(),
            peer.script.display()
        ));
    }

    // results.csv is written row by row: a long run interrupted still leaves its data.
    let csv_path = out.join("results.csv");
    let csv_err = |e: std::io::Error| format!("{}: {e}", csv_path.display());
    let mut csv = BufWriter::new(File::create(&csv_path).map_err(csv_err)?);
    let mut header = "problem,form,solver,repeat,status,iterations,seconds,error".to_string();
    for &t in &b.limits.tols {
        header += &format!(",seconds_to_{}", tol_name(t));
    }
    writeln!(csv, "{header}").map_err(csv_err)?;

    let total = a.files.len() * a.repeat * b.solvers.len();
    let mut done = 0;
    for file in &a.files {
        let name = stem(file);
        let problem = match cadmm::fclib::read(file) {
            Ok(p) => p,
            Err(e) => {
                let msg = format!("{} skipped: {e}", file.display());
                eprintln!("cadmm bench: {msg}");
                b.notes.push(msg);
                done += a.repeat * b.solvers.len();
                continue;
            }
        };
        let global = matches!(problem, cadmm::Problem::Global(_));
        let p = b.problems.len();
        b.problems.push(ProblemInfo {
            name: name.clone(),
            form: if global { "global" } else { "local" },
        });
        for repeat in 0..a.repeat {
            for (s, spec) in b.solvers.iter().enumerate() {
                let sol = scratch.join(format!("{}.h5", spec.file_tag()));
                let _ = std::fs::remove_file(&sol);
                let n = b.limits.tols.len();
                let run = match spec {
                    _ if !spec.supports(global) => Run::failure("unsupported", n, None),
                    SolverSpec::Cadmm { .. } => {
                        run::cadmm(&exe, spec, file, &problem, &b.limits, &sol)
                    }
                    SolverSpec::Siconos { name: sname } => {
                        peer.run(sname, file, &problem, &b.limits, a.peer_per_tol, &sol)
                    }
                };
                if a.keep_solutions && repeat == 0 {
                    let kept = out
                        .join("solutions")
                        .join(format!("{name}.{}.h5", spec.file_tag()));
                    // Never leave a previous benchmark's file behind a run without answer.
                    let _ = std::fs::remove_file(&kept);
                    if sol.is_file() {
                        std::fs::copy(&sol, &kept)
                            .map_err(|e| format!("cannot write {}: {e}", kept.display()))?;
                    }
                }
                let _ = std::fs::remove_file(&sol);
                let row = Row {
                    problem: p,
                    solver: s,
                    repeat,
                    run,
                };
                done += 1;
                progress(&b, &row, done, total);
                writeln!(csv, "{}", csv_row(&b, &row)).map_err(csv_err)?;
                csv.flush().map_err(csv_err)?;
                b.rows.push(row);
            }
        }
        if plots.is_ok() {
            work_precision(
                &b,
                p,
                &out.join("work-precision").join(format!("{name}.png")),
            )?;
        }
    }
    drop(csv);
    let _ = std::fs::remove_dir_all(&scratch);

    if plots.is_ok() {
        let labels: Vec<String> = b.solvers.iter().map(|s| s.label()).collect();
        for (k, &tol) in b.limits.tols.iter().enumerate() {
            let r = profile::ratios(&b.times(k));
            let path = out.join(format!("profile-{}.png", tol_name(tol)));
            plot::profile(&path, tol, &labels, &r)?;
        }
    }
    let md = out.join("summary.md");
    std::fs::write(&md, summary::markdown(&b))
        .map_err(|e| format!("cannot write {}: {e}", md.display()))?;
    eprintln!("cadmm bench: wrote {}", out.display());
    Ok(())
}

fn work_precision(b: &Bench, p: usize, path: &Path) -> Result<(), String> {
    let curves: Vec<Curve> = (0..b.solvers.len())
        .filter_map(|s| {
            let run = b.first(p, s)?;
            let name = b.solvers[s].label();
            let mut label = if b.solvers[s].is_cadmm() {
                format!("{name}, one solve per tol")
            } else {
                name.clone()
            };
            if run.curve.is_empty() {
                label += &format!(" ({})", run.status);
            }
            let trace = (!run.trace.is_empty()).then(|| {
                let whose = if run.trace_islands > 1 {
                    format!(" (slowest of {} islands)", run.trace_islands)
                } else {
                    String::new()
                };
                (
                    format!(
                        "{name} trace{whose}, clock ×{:.2} to untraced",
                        run.trace_scale
                    ),
                    run.trace.clone(),
                )
            });
            Some(Curve {
                label,
                solver: s,
                points: run.curve.clone(),
                trace,
            })
        })
        .collect();
    let pr = &b.problems[p];
    plot::work_precision(
        path,
        &format!("{} ({}): error against time", pr.name, pr.form),
        &curves,
        &b.limits.tols,
    )
}

/// Runs `cadmm bench`: exit code 0 when every run was attempted (failed runs included), 2
/// on bad input or when an output cannot be written.
pub fn run(a: BenchArgs) -> ExitCode {
    match execute(a) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cadmm bench: {e}");
            ExitCode::from(2)
        }
    }
}
