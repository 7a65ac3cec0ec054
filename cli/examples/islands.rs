//! Islands benchmark: K copies of a real FCLib problem side by side in one block-diagonal
//! problem, and one hard problem among K - 1 easy copies, solved with contact islands on
//! and off. Prints a table (median of `--repeat` runs: time to build the solver and solve,
//! peak heap bytes, status, iterations, error) and plots time against K.
//!
//! `cargo run --release -p cadmm-cli --example islands -- [--k 1,10,100] [--repeat 3]
//!  [--easy FILE] [--hard FILE] [--time-limit S] [--plot PNG] [--dump DIR]`
//!
//! `--dump DIR` writes each scene (`<scene>-k<K>.hdf5`) and its islands-on solution
//! (`<scene>-k<K>.solution.hdf5`), for `../shared/tools/fc_error.py`.

#[path = "../src/font.rs"]
mod font;

use cadmm::{fclib, Problem, Settings, Solver, Status};
use plotters::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Counts live heap bytes and their peak.
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(live, Ordering::Relaxed);
        // SAFETY: the caller's layout, forwarded.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's pointer and layout, forwarded.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

struct Args {
    ks: Vec<usize>,
    repeat: usize,
    easy: PathBuf,
    hard: PathBuf,
    time_limit: f64,
    plot: Option<PathBuf>,
    dump: Option<PathBuf>,
}

fn args() -> Result<Args, String> {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/fclib");
    let mut a = Args {
        ks: vec![1, 10, 100],
        repeat: 3,
        easy: data.join("global/Box_Stacks-i0122-82-5.hdf5"),
        hard: data.join("global/Box_Stacks-i1000-482-10.hdf5"),
        time_limit: 60.0,
        plot: None,
        dump: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--k" => {
                a.ks = value()?
                    .split(',')
                    .map(|k| k.parse().map_err(|e| format!("--k {k}: {e}")))
                    .collect::<Result<_, _>>()?
            }
            "--repeat" => a.repeat = value()?.parse().map_err(|e| format!("--repeat: {e}"))?,
            "--easy" => a.easy = value()?.into(),
            "--hard" => a.hard = value()?.into(),
            "--time-limit" => {
                a.time_limit = value()?.parse().map_err(|e| format!("--time-limit: {e}"))?
            }
            "--plot" => a.plot = Some(value()?.into()),
            "--dump" => a.dump = Some(value()?.into()),
            other => return Err(format!("unknown flag {other}")),
        }
    }
    Ok(a)
}

/// One measured configuration.
struct Run {
    seconds: f64,
    peak_bytes: usize,
    status: Status,
    iterations: usize,
    error: f64,
    islands: usize,
}

/// Builds a solver and solves, `repeat` times; the median time, the largest peak.
fn measure(p: &Problem, islands: bool, a: &Args) -> Result<(Run, cadmm::Solution), String> {
    let mut times = Vec::new();
    let mut last = None;
    let mut peak = 0;
    for _ in 0..a.repeat {
        let settings = Settings {
            islands,
            time_limit: a.time_limit,
            ..Settings::default()
        };
        let problem = p.clone();
        let base = LIVE.load(Ordering::Relaxed);
        PEAK.store(base, Ordering::Relaxed);
        let t0 = Instant::now();
        let mut solver = Solver::new(problem, settings).map_err(|e| e.to_string())?;
        let status = solver.solve().map_err(|e| e.to_string())?;
        times.push(t0.elapsed().as_secs_f64());
        peak = peak.max(PEAK.load(Ordering::Relaxed) - base);
        let st = solver.stats();
        last = Some((
            Run {
                seconds: 0.0,
                peak_bytes: 0,
                status,
                iterations: st.iterations,
                error: st.error,
                islands: st.islands,
            },
            solver.solution().clone(),
        ));
    }
    times.sort_by(f64::total_cmp);
    let (mut run, solution) = last.ok_or("--repeat must be at least 1")?;
    run.seconds = times[times.len() / 2];
    run.peak_bytes = peak;
    Ok((run, solution))
}

fn main() {
    if let Err(e) = run() {
        eprintln!("islands: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), String> {
    let a = args()?;
    let read = |f: &PathBuf| fclib::read(f).map_err(|e| format!("{}: {e}", f.display()));
    let (easy, hard) = (read(&a.easy)?, read(&a.hard)?);
    if let Some(dir) = &a.dump {
        std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    }
    println!(
        "| scene | K | islands | on: seconds | on: peak MB | on: status, iterations, error | off: seconds | off: peak MB | off: status, iterations, error | off / on |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut curves: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let (hard_alone, _) = measure(&hard, true, &a)?;
    println!(
        "hard problem alone: {:.4} s, {} iterations, status {}",
        hard_alone.seconds,
        hard_alone.iterations,
        hard_alone.status.name()
    );
    for scene in ["copies", "hard-among-easy"] {
        let mut on_curve = Vec::new();
        let mut off_curve = Vec::new();
        for &k in &a.ks {
            let parts: Vec<Problem> = match scene {
                "copies" => vec![easy.clone(); k],
                _ => std::iter::once(hard.clone())
                    .chain(std::iter::repeat_n(easy.clone(), k.saturating_sub(1)))
                    .collect(),
            };
            let p = Problem::block_diagonal(&parts).map_err(|e| e.to_string())?;
            let (on, solution) = measure(&p, true, &a)?;
            let (off, _) = measure(&p, false, &a)?;
            if let Some(dir) = &a.dump {
                let stem = dir.join(format!("{scene}-k{k}"));
                fclib::write_problem(stem.with_extension("hdf5"), &p).map_err(|e| e.to_string())?;
                fclib::write_solution(stem.with_extension("solution.hdf5"), &solution)
                    .map_err(|e| e.to_string())?;
            }
            let mb = |b: usize| b as f64 / 1e6;
            println!(
                "| {scene} | {k} | {} | {:.4} | {:.1} | {}, {}, {:.1e} | {:.4} | {:.1} | {}, {}, {:.1e} | {:.1} |",
                on.islands,
                on.seconds,
                mb(on.peak_bytes),
                on.status.name(),
                on.iterations,
                on.error,
                off.seconds,
                mb(off.peak_bytes),
                off.status.name(),
                off.iterations,
                off.error,
                off.seconds / on.seconds
            );
            on_curve.push((k as f64, on.seconds));
            off_curve.push((k as f64, off.seconds));
        }
        curves.push((format!("{scene}, islands on"), on_curve));
        curves.push((format!("{scene}, islands off"), off_curve));
    }
    if let Some(path) = &a.plot {
        plot(path, &curves)?;
        println!("plot: {}", path.display());
    }
    Ok(())
}

/// Time against K, log-log, one line per scene and setting.
fn plot(path: &PathBuf, curves: &[(String, Vec<(f64, f64)>)]) -> Result<(), String> {
    font::font()?;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let points = curves.iter().flat_map(|c| c.1.iter());
    let (mut x1, mut y0, mut y1) = (1.0f64, f64::INFINITY, 0.0f64);
    for &(x, y) in points {
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let root = BitMapBackend::new(path, (960, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "build + solve time against the number of piles K",
            ("sans-serif", 22),
        )
        .margin(20)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (0.8..x1 * 1.25).log_scale(),
            (y0 * 0.5..y1 * 2.0).log_scale(),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("K")
        .y_desc("seconds (median)")
        .draw()
        .map_err(|e| err(&e))?;
    let colors = [BLUE, RED, GREEN, MAGENTA];
    for (k, (name, pts)) in curves.iter().enumerate() {
        let color = colors[k % colors.len()];
        let style = if name.ends_with("off") {
            ShapeStyle::from(&color).stroke_width(2)
        } else {
            ShapeStyle::from(&color).stroke_width(3)
        };
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), style))
            .map_err(|e| err(&e))?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))
            .map_err(|e| err(&e))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}
