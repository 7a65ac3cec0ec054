//! Extreme cases: every scene of `examples/extreme/scenes.rs` (stiff mass ratios, extreme
//! friction, unit scalings, redundant contacts, near-singular inertia, 1000 contacts on one
//! body, an impact, separating and empty contact sets, a granular pile of 1e5 contacts),
//! solved in the global form and in its local (Delassus) form, with `auto` and every named
//! variant, each answer re-measured by the independent measure of `tests/common`.
//!
//! ```sh
//! cargo run --release --example extreme -- --json [--variants all|auto] [--dump DIR]
//!     [--time-limit SECONDS] [--pile NX,NY,NZ] [--only SUBSTRING]
//! ```
//!
//! One line per case, form and variant (a JSON object with `--json`). `peak_bytes` is the
//! peak of live heap bytes during the solve (setup included) above those live before it,
//! counted by this program's global allocator. `--dump DIR` writes every case as an FCLib
//! file (needs `--features fclib`).

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "extreme/scenes.rs"]
mod scenes;

use cadmm::admm::VARIANT_NAMES;
use std::alloc::{GlobalAlloc, Layout, System};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The system allocator, counting live bytes and their peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Relaxed) + layout.size();
            PEAK.fetch_max(live, Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        System.dealloc(p, layout);
        LIVE.fetch_sub(layout.size(), Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = System.realloc(p, layout, size);
        if !q.is_null() {
            if size >= layout.size() {
                let live = LIVE.fetch_add(size - layout.size(), Relaxed) + size - layout.size();
                PEAK.fetch_max(live, Relaxed);
            } else {
                LIVE.fetch_sub(layout.size() - size, Relaxed);
            }
        }
        q
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

struct Args {
    json: bool,
    all_variants: bool,
    dump: Option<String>,
    time_limit: f64,
    pile: (usize, usize, usize),
    only: Option<String>,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        json: false,
        all_variants: true,
        dump: None,
        time_limit: 10.0,
        pile: (20, 20, 87),
        only: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--json" => a.json = true,
            "--variants" => match value()?.as_str() {
                "all" => a.all_variants = true,
                "auto" => a.all_variants = false,
                v => return Err(format!("--variants: expected all or auto, got {v}")),
            },
            "--dump" => a.dump = Some(value()?),
            "--time-limit" => {
                a.time_limit = value()?.parse().map_err(|e| format!("--time-limit: {e}"))?
            }
            "--pile" => {
                let v = value()?;
                let d: Vec<usize> = v
                    .split(',')
                    .map(|x| x.parse().map_err(|e| format!("--pile {v}: {e}")))
                    .collect::<Result<_, _>>()?;
                if d.len() != 3 || d.contains(&0) {
                    return Err(format!("--pile {v}: expected NX,NY,NZ, all positive"));
                }
                a.pile = (d[0], d[1], d[2]);
            }
            "--only" => a.only = Some(value()?),
            _ => return Err(format!("unknown argument {flag}")),
        }
    }
    Ok(a)
}

/// A JSON number, `null` when not finite.
fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        "null".into()
    }
}

#[cfg(feature = "fclib")]
fn dump(dir: &str, case: &scenes::Case) -> Result<(), String> {
    use cadmm::Problem;
    std::fs::create_dir_all(dir).map_err(|e| format!("{dir}: {e}"))?;
    let global = Problem::Global(case.global.clone());
    let path = format!("{dir}/{}-global.hdf5", case.name);
    cadmm::fclib::write_problem(&path, &global).map_err(|e| format!("{path}: {e}"))?;
    if let Some(l) = &case.local {
        let path = format!("{dir}/{}-local.hdf5", case.name);
        cadmm::fclib::write_problem(&path, &Problem::Local(l.clone()))
            .map_err(|e| format!("{path}: {e}"))?;
    }
    Ok(())
}

#[cfg(not(feature = "fclib"))]
fn dump(_: &str, _: &scenes::Case) -> Result<(), String> {
    Err(
        "--dump needs the fclib feature: cargo run --release --features fclib --example extreme"
            .into(),
    )
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("extreme: {e}");
            return ExitCode::from(2);
        }
    };
    let mut variants = vec!["auto"];
    if args.all_variants {
        variants.extend(VARIANT_NAMES);
    }
    let mut failures = 0;
    for case in scenes::cases(args.pile) {
        if args
            .only
            .as_ref()
            .is_some_and(|s| !case.name.contains(s.as_str()))
        {
            continue;
        }
        if let Some(dir) = &args.dump {
            if let Err(e) = dump(dir, &case) {
                eprintln!("extreme: dump of {}: {e}", case.name);
                failures += 1;
            }
        }
        let forms: &[&'static str] = if case.local.is_some() {
            &["global", "local"]
        } else {
            &["global"]
        };
        for &form in forms {
            for &variant in &variants {
                let before = LIVE.load(Relaxed);
                PEAK.store(before, Relaxed);
                let o = scenes::run(&case, form, variant, args.time_limit, 1_000_000);
                let peak = PEAK.load(Relaxed) - before;
                // Honest outcomes only: finite outputs, and "solved" confirmed independently.
                if !o.finite || (o.status == "solved" && (o.error.is_nan() || o.error > 1e-8)) {
                    failures += 1;
                }
                if args.json {
                    println!(
                        "{{\"case\": \"{}\", \"form\": \"{}\", \"variant\": \"{}\", \"status\": \"{}\", \"error\": {}, \"reported_error\": {}, \"iterations\": {}, \"seconds\": {}, \"peak_bytes\": {}, \"finite\": {}}}",
                        o.case, o.form, o.variant, o.status.replace('"', "'"), num(o.error),
                        num(o.reported_error), o.iterations, num(o.seconds), peak, o.finite
                    );
                } else {
                    println!(
                        "{:34} {:6} {:15} {:15} {:>10.3e} {:>8} {:>9.4} s {:>12} B",
                        o.case, o.form, o.variant, o.status, o.error, o.iterations, o.seconds, peak
                    );
                }
            }
        }
    }
    if failures > 0 {
        eprintln!("extreme: {failures} dishonest outcomes or failed dumps (above)");
        return ExitCode::FAILURE;
    }
    ExitCode::SUCCESS
}
