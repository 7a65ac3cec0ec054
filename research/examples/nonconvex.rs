//! Seed 002 on cadmm's engine: ADMM on four nonconvex problems (l0 regression, 1D l0
//! denoising, phase retrieval, leading eigenvector), both update orders, constant penalty
//! against residual balancing and the spectral rule, over a range of initial penalties.
//!
//! ```text
//! cargo run --release -p cadmm-research --example nonconvex -- [--plots DIR] [--full] [--only NAME]
//! ```
//!
//! Prints one JSON object per run and line, then a table of iterations to stderr; PNG plots
//! (iterations and objective or PSNR against tau0, as the seed's Figures 1 and 2) go to
//! `DIR` (default `target/nonconvex`). `--full` uses the seed's 15000 x 500 phase
//! retrieval instance instead of the 3000 x 100 one (same 30:1 shape, 25 times cheaper).

#[path = "../../cli/src/font.rs"]
mod font;

use cadmm::Status;
use cadmm_research::nonconvex::{
    correlated_regression, leading_eigen_matrix, phase_measurements, piecewise_signal, solve,
    Eigenvector, L0Denoising, L0Regression, NonconvexProblem, Order, PhaseRetrieval, RunResult,
    StopSettings, Strategy,
};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Initial penalties: 10^-2 .. 10^4 in half decades.
fn tau0_grid() -> Vec<f64> {
    (0..13).map(|i| 10f64.powf(-2.0 + 0.5 * i as f64)).collect()
}

struct Case {
    problem: Box<dyn NonconvexProblem>,
    stop: StopSettings,
}

fn cases(full: bool) -> Vec<Case> {
    let (m, n) = if full { (15000, 500) } else { (3000, 100) };
    let phase = phase_measurements(m, n, 2016);
    vec![
        Case {
            problem: Box::new(L0Regression::new(&correlated_regression(2016), 1.0)),
            stop: StopSettings::paper(2000),
        },
        Case {
            problem: Box::new(L0Denoising::new(piecewise_signal(2016), 1.0)),
            stop: StopSettings::paper(2000),
        },
        Case {
            problem: Box::new(PhaseRetrieval::new(phase, 7).expect("D has full column rank")),
            stop: StopSettings::paper(200),
        },
        Case {
            problem: Box::new(Eigenvector::new(leading_eigen_matrix(20, 2016), 7)),
            stop: StopSettings::paper(2000),
        },
    ]
}

struct Row {
    order: Order,
    strategy: Strategy,
    tau0: f64,
    result: RunResult,
}

fn main() {
    let mut out = PathBuf::from("target/nonconvex");
    let mut full = false;
    let mut only: Option<String> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--plots" => out = args.next().map(PathBuf::from).unwrap_or_else(|| usage()),
            "--full" => full = true,
            "--only" => only = Some(args.next().unwrap_or_else(|| usage())),
            _ => usage(),
        }
    }
    let plots = match font::font() {
        Ok(()) => std::fs::create_dir_all(&out)
            .map_err(|e| eprintln!("no plots: cannot create {}: {e}", out.display()))
            .is_ok(),
        Err(e) => {
            eprintln!("no plots: {e}");
            false
        }
    };
    for mut case in cases(full) {
        let name = case.problem.name().to_string();
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let mut rows = Vec::new();
        for order in Order::ALL {
            for strategy in Strategy::ALL {
                for tau0 in tau0_grid() {
                    let result =
                        match solve(case.problem.as_mut(), order, strategy, tau0, &case.stop) {
                            Ok(r) => r,
                            Err(e) => {
                                eprintln!(
                                    "{name} {} {} {tau0}: {e}",
                                    order.name(),
                                    strategy.name()
                                );
                                continue;
                            }
                        };
                    let row = Row {
                        order,
                        strategy,
                        tau0,
                        result,
                    };
                    println!("{}", json(&name, &row));
                    rows.push(row);
                }
            }
        }
        print_table(&name, &rows, &case.stop);
        if plots {
            for order in Order::ALL {
                if let Err(e) = plot(&out, &name, order, &rows) {
                    eprintln!("{name}: plot failed: {e}");
                }
            }
        }
    }
}

fn usage() -> ! {
    eprintln!("usage: nonconvex [--plots DIR] [--full] [--only NAME]");
    std::process::exit(2)
}

fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{v:e}")
    } else {
        "null".into()
    }
}

fn json(problem: &str, r: &Row) -> String {
    let q = &r.result.quality;
    format!(
        "{{\"problem\":\"{problem}\",\"order\":\"{}\",\"strategy\":\"{}\",\"tau0\":{},\
         \"iterations\":{},\"converged\":{},\"status\":\"{:?}\",\"error\":{},\"final_tau\":{},\"objective\":{},\
         \"psnr\":{}}}",
        r.order.name(),
        r.strategy.name(),
        num(r.tau0),
        r.result.iterations,
        r.result.converged,
        r.result.status,
        num(r.result.error),
        num(r.result.final_rho),
        num(q.objective),
        q.psnr.map_or("null".into(), num),
    )
}

fn print_table(problem: &str, rows: &[Row], stop: &StopSettings) {
    let grid = tau0_grid();
    eprintln!(
        "\n{problem}: iterations to eq. (6) at {:e} ('{}+': not converged, 'Nx': overflowed \
         at iteration N)",
        stop.tolerance, stop.max_iterations
    );
    eprint!("{:<36}", "order / strategy \\ tau0");
    for t in &grid {
        eprint!("{:>7}", format!("{t:.0e}"));
    }
    eprintln!();
    for order in Order::ALL {
        for strategy in Strategy::ALL {
            eprint!("{:<36}", format!("{} / {}", order.name(), strategy.name()));
            for t in &grid {
                let cell = rows
                    .iter()
                    .find(|r| r.order == order && r.strategy == strategy && r.tau0 == *t)
                    .map_or("-".to_string(), |r| match r.result.status {
                        Status::Solved => r.result.iterations.to_string(),
                        Status::NumericalError => format!("{}x", r.result.iterations),
                        _ => format!("{}+", r.result.iterations),
                    });
                eprint!("{cell:>7}");
            }
            eprintln!();
        }
    }
}

const COLORS: [RGBColor; 3] = [
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
];

type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// Two panels as the seed's figures: iterations (top) and quality (bottom) against tau0.
fn plot(dir: &Path, problem: &str, order: Order, rows: &[Row]) -> PlotResult {
    let path = dir.join(format!("{problem}_{}.png", order.name()));
    let rows: Vec<&Row> = rows.iter().filter(|r| r.order == order).collect();
    let psnr = rows.iter().all(|r| r.result.quality.psnr.is_some());
    let positive = rows.iter().all(|r| r.result.quality.objective > 0.0);
    let quality = |r: &Row| match r.result.quality.psnr {
        Some(p) if psnr => p,
        _ if positive => r.result.quality.objective.log10(),
        _ => r.result.quality.objective,
    };
    let label = if psnr {
        "PSNR (dB)"
    } else if positive {
        "log10 objective"
    } else {
        "objective"
    };
    let grid = tau0_grid();
    let (xmin, xmax) = (grid[0].log10() - 0.1, grid[grid.len() - 1].log10() + 0.1);
    let ymax_it = rows.iter().map(|r| r.result.iterations).max().unwrap_or(1) as f64 * 1.05;
    let qs: Vec<f64> = rows
        .iter()
        .map(|r| quality(r))
        .filter(|q| q.is_finite())
        .collect();
    let (qmin, qmax) = qs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| {
            (a.min(*q), b.max(*q))
        });
    let pad = ((qmax - qmin) * 0.05).max(1e-3);

    let root = BitMapBackend::new(&path, (900, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(450);
    let mut it = ChartBuilder::on(&top)
        .caption(
            format!("{problem}, {}: iterations", order.name()),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xmin..xmax, 0.0..ymax_it)?;
    it.configure_mesh()
        .x_desc("log10 tau0")
        .y_desc("iterations")
        .label_style(("sans-serif", 14))
        .draw()?;
    let mut q = ChartBuilder::on(&bottom)
        .caption(
            format!("{problem}, {}: {label}", order.name()),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xmin..xmax, (qmin - pad)..(qmax + pad))?;
    q.configure_mesh()
        .x_desc("log10 tau0")
        .y_desc(label)
        .label_style(("sans-serif", 14))
        .draw()?;
    for (i, strategy) in Strategy::ALL.into_iter().enumerate() {
        let c = COLORS[i];
        let mine: Vec<&&Row> = rows.iter().filter(|r| r.strategy == strategy).collect();
        let its: Vec<(f64, f64)> = mine
            .iter()
            .map(|r| (r.tau0.log10(), r.result.iterations as f64))
            .collect();
        it.draw_series(LineSeries::new(its.clone(), c.stroke_width(2)))?
            .label(strategy.name())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        it.draw_series(its.iter().map(|p| Circle::new(*p, 3, c.filled())))?;
        let qp: Vec<(f64, f64)> = mine
            .iter()
            .map(|r| (r.tau0.log10(), quality(r)))
            .filter(|p| p.1.is_finite())
            .collect();
        q.draw_series(LineSeries::new(qp.clone(), c.stroke_width(2)))?;
        q.draw_series(qp.iter().map(|p| Circle::new(*p, 3, c.filled())))?;
    }
    it.configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}
