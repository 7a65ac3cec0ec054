//! `summary.md` of `cadmm bench`: where and how the run was made, then per tolerance the
//! fraction of problems each solver solves, how often it is fastest, its median time ratio
//! to the best cadmm configuration, and the per-problem times.

use crate::bench::{tol_name, Bench};
use crate::profile;
use std::fmt::Write;
use std::time::{SystemTime, UNIX_EPOCH};

/// `YYYY-MM-DD HH:MM UTC` from the system clock (civil-from-days, proleptic Gregorian).
fn utc_now() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        rem / 3600,
        rem % 3600 / 60
    )
}

fn machine() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "unknown host".into());
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.into());
    let n = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("`{host}`, {cpu}, {n} logical CPUs")
}

fn command_line() -> String {
    let mut args = std::env::args();
    let _exe = args.next();
    let rest: Vec<String> = args
        .map(|a| {
            if a.contains(char::is_whitespace) {
                format!("'{a}'")
            } else {
                a
            }
        })
        .collect();
    format!("cadmm {}", rest.join(" "))
}

fn pct(x: f64, n: usize) -> String {
    if x.is_nan() {
        "n/a".into()
    } else {
        format!(
            "{}/{n} ({:.0}%)",
            (x * n as f64).round() as usize,
            100.0 * x
        )
    }
}

fn ratio(x: f64) -> String {
    if x.is_nan() {
        "n/a".into()
    } else if x.is_infinite() {
        "inf".into()
    } else {
        format!("{x:.2}")
    }
}

fn seconds(x: f64) -> String {
    format!("{x:.3e}")
}

/// The whole `summary.md`.
pub fn markdown(b: &Bench) -> String {
    let mut s = String::new();
    let np = b.problems.len();
    let n_global = b.problems.iter().filter(|p| p.form == "global").count();
    let labels: Vec<String> = b.solvers.iter().map(|x| x.label()).collect();
    let is_cadmm: Vec<bool> = b.solvers.iter().map(|x| x.is_cadmm()).collect();
    let _ = writeln!(s, "# cadmm bench\n");
    let _ = writeln!(s, "- Date: {}", utc_now());
    let _ = writeln!(s, "- Machine: {}", machine());
    let _ = writeln!(s, "- Command: `{}`", command_line());
    let _ = writeln!(s, "- cadmm {}", env!("CARGO_PKG_VERSION"));
    if let Some(p) = &b.siconos {
        let _ = writeln!(s, "- Siconos: {p}");
    }
    let _ = writeln!(
        s,
        "- {np} problems ({n_global} global, {} local), solvers: {}; time limit {} s per \
         solve, iteration limit {}, {} repeat(s).",
        np - n_global,
        labels.join(", "),
        b.limits.time_limit,
        b.limits.max_iter,
        b.repeat
    );
    let _ = writeln!(
        s,
        "\nTimes are wall seconds of the solve, the median over repeats; reading the file is \
         not counted. cadmm: setup (factorization) plus the solve, as a user runs it (no \
         trace), one new solver per tolerance; a separate traced run only draws the line of \
         the work-precision plots, its solve clock scaled to the untraced solve's (the trace \
         itself costs time), while the dots are the untraced solves. Siconos: the driver call (its own setup included) in a child \
         process; it has no trace, so its time to a tolerance is the time of a whole run {} \
         when its final error is at most that tolerance. Every error is re-measured with \
         cadmm's `problem_error` (docs/algorithms.md §3) on the solution the solver \
         returned; a crash, a timeout or an error above the tolerance is a failure \
         (infinite time).",
        if b.peer_per_tol {
            "asked for that tolerance"
        } else {
            "asked for the smallest tolerance"
        }
    );
    if !b.notes.is_empty() {
        let _ = writeln!(s, "\nNotes:");
        for n in &b.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    if np == 0 {
        let _ = writeln!(s, "\nNo problem could be read.");
        return s;
    }
    for (k, &tol) in b.limits.tols.iter().enumerate() {
        let t = b.times(k);
        let r = profile::ratios(&t);
        let name = tol_name(tol);
        let _ = writeln!(s, "\n## tol = {name}\n");
        let _ = writeln!(s, "![performance profile](profile-{name}.png)\n");
        let _ = writeln!(
            s,
            "| solver | solved | fastest | median time ratio to the best cadmm |"
        );
        let _ = writeln!(s, "|---|---|---|---|");
        let mut n_ref = 0;
        for (j, label) in labels.iter().enumerate() {
            let (m, n) = profile::median_ratio_to_best_cadmm(&t, &is_cadmm, j);
            n_ref = n;
            let _ = writeln!(
                s,
                "| {label} | {} | {} | {} |",
                pct(profile::solved_fraction(&t, j), np),
                pct(profile::fastest_fraction(&r, j), np),
                ratio(m)
            );
        }
        let _ = writeln!(
            s,
            "\nFastest: ties count for each tied solver. Time ratio: over the {n_ref} \
             problem(s) that some cadmm configuration solves, the solver's time divided by the \
             best cadmm time on that problem (a failure counts as infinite).\n"
        );
        let _ = writeln!(s, "| problem | form | {} |", labels.join(" | "));
        let _ = writeln!(s, "|---|---|{}", "---|".repeat(labels.len()));
        for (p, pr) in b.problems.iter().enumerate() {
            let cells: Vec<String> = (0..labels.len())
                .map(|j| {
                    if t[p][j].is_finite() {
                        seconds(t[p][j])
                    } else {
                        let status = b.first(p, j).map_or("?", |r| r.status.as_str());
                        format!("fail ({status})")
                    }
                })
                .collect();
            let _ = writeln!(s, "| {} | {} | {} |", pr.name, pr.form, cells.join(" | "));
        }
    }
    let _ = writeln!(
        s,
        "\nWork-precision plots (error against wall time, first repeat): `work-precision/`. \
         All runs: `results.csv`."
    );
    s
}
