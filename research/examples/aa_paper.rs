//! Seed 001 reproduced on cadmm's engine: for each test problem, the spectrum of the ADMM
//! map's Jacobian at the solution, the optimal stationary AA coefficients and factors it
//! predicts (Propositions 3 and 4, brute force for m = 2, 3), and the factors measured for
//! plain ADMM, AA(1..3) (the engine's Anderson acceleration) and sAA(1..3).
//!
//! ```text
//! cargo run --release --example aa_paper -- [--json] [--out DIR] [--only NAME]
//! ```
//!
//! `--json` prints one JSON object per problem and line; PNG plots (error against iteration,
//! spectra) go to `DIR` (default `target/aa_paper`). Text in the plots needs a TrueType
//! font (`$CADMM_FONT` or a common system path); without one the plots are skipped.

#[path = "../../cli/src/font.rs"]
mod font;

use cadmm_research::analysis::{analyze, saa, Analysis, ExperimentSettings, Run, Saa1Case, C64};
use cadmm_research::test_problems::{paper_problems, TestProblem};
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn main() {
    let mut json = false;
    let mut out = PathBuf::from("target/aa_paper");
    let mut only: Option<String> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--json" => json = true,
            "--out" => out = args.next().map(PathBuf::from).unwrap_or_else(|| usage()),
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
    let set = ExperimentSettings::default();
    for mut p in paper_problems() {
        if only.as_deref().is_some_and(|o| o != p.name()) {
            continue;
        }
        let rho = p.rho();
        let a = match analyze(p.splitting(), rho, &set) {
            Ok(a) => a,
            Err(e) => {
                eprintln!("{}: {e}", p.name());
                std::process::exit(1);
            }
        };
        if json {
            println!("{}", to_json(p.as_ref(), &a));
        } else {
            print_summary(p.as_ref(), &a);
        }
        if plots {
            for r in [
                plot_errors(&out, p.as_ref(), &a),
                plot_spectrum(&out, p.as_ref(), &a),
            ] {
                if let Err(e) = r {
                    eprintln!("{}: plot failed: {e}", p.name());
                }
            }
        }
    }
}

fn usage() -> ! {
    eprintln!("usage: aa_paper [--json] [--out DIR] [--only NAME]");
    std::process::exit(2)
}

fn num(x: Option<f64>) -> String {
    match x {
        Some(v) if v.is_finite() => format!("{v:.6}"),
        _ => "null".into(),
    }
}

fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.4}")).collect();
    format!("[{}]", items.join(", "))
}

fn case_name(c: Saa1Case) -> &'static str {
    match c {
        Saa1Case::NonNegative => "real [0,1)",
        Saa1Case::NonPositive => "real (-1,0]",
        Saa1Case::MixedEqual => "mixed (a)",
        Saa1Case::MixedB1 => "mixed (b1)",
        Saa1Case::MixedB2 => "mixed (b2)",
        Saa1Case::MixedC1 => "mixed (c1)",
        Saa1Case::MixedC2 => "mixed (c2)",
        Saa1Case::ComplexBound => "complex, Prop. 4 bound attained",
        Saa1Case::ComplexPositiveReal => "complex, mu+ bound attained",
        Saa1Case::ComplexNumeric => "complex, numerical",
        Saa1Case::Divergent => "divergent",
    }
}

fn last_iteration(r: &Run) -> usize {
    r.iterations.last().copied().unwrap_or(0)
}

fn to_json(p: &dyn TestProblem, a: &Analysis) -> String {
    let mut s = String::new();
    let aa = |f: &dyn Fn(&Run) -> String| -> String {
        let items: Vec<String> =
            a.aa.iter()
                .map(|r| format!("\"{}\": {}", &r.label[3..r.label.len() - 1], f(r)))
                .collect();
        format!("{{{}}}", items.join(", "))
    };
    let saa_meas: Vec<String> = a
        .saa
        .iter()
        .map(|r| format!("\"{}\": {}", &r.label[4..r.label.len() - 1], num(r.factor)))
        .collect();
    let _ = write!(
        s,
        "{{\"problem\": \"{}\", \"dim\": {}, \"rho_penalty\": {}, \"rho_q\": {}, \
         \"spectrum_real\": {}, \"spectrum_max_imag\": {:.3e}, \"saa1_case\": \"{}\", \
         \"beta_saa1\": {}, \"rho_saa1_pred\": {}, \"rho_saa1_bound\": {}, \"rho_admm\": {}, \
         \"rho_aa\": {}, \"aa_rejected\": {}, \"rho_saa_meas\": {{{}}}",
        p.name(),
        p.dim(),
        a.rho,
        num(Some(a.spectrum.radius())),
        a.real,
        a.spectrum.max_imag(),
        case_name(a.saa1.case),
        num(Some(a.saa1.beta)),
        num(Some(a.saa1.rho)),
        num(a.saa1.lower_bound),
        num(a.admm.factor),
        aa(&|r| num(r.factor)),
        aa(&|r| r.rejected.to_string()),
        saa_meas.join(", "),
    );
    for (m, sr) in a.saa_search.iter().enumerate() {
        let m = m + 2;
        let _ = write!(
            s,
            ", \"beta_saa{m}\": {}, \"rho_saa{m}_pred\": {}",
            list(&sr.betas),
            num(Some(sr.rho))
        );
    }
    let _ = write!(
        s,
        ", \"iterations\": {{\"admm\": {}, \"aa\": {}}}, \"reference_residual\": {:.1e}, \
         \"seconds\": {:.2}, \"notes\": \"{}\"}}",
        last_iteration(&a.admm),
        aa(&|r| last_iteration(r).to_string()),
        a.reference_residual,
        a.seconds,
        p.notes().replace('"', "'"),
    );
    s
}

fn print_summary(p: &dyn TestProblem, a: &Analysis) {
    println!(
        "{:<21} rho_q {:.4} ({}, max|Im| {:.1e})  sAA(1): beta* {:.4} rho* {:.4}",
        p.name(),
        a.spectrum.radius(),
        case_name(a.saa1.case),
        a.spectrum.max_imag(),
        a.saa1.beta,
        a.saa1.rho
    );
    for r in std::iter::once(&a.admm).chain(&a.aa).chain(&a.saa) {
        println!(
            "    {:<8} factor {:>8}  iterations {:>6}  AA rejected {}",
            r.label,
            num(r.factor),
            last_iteration(r),
            r.rejected
        );
    }
    for (m, s) in a.saa_search.iter().enumerate() {
        println!(
            "    sAA({}) optimum {} -> {:.4}",
            m + 2,
            list(&s.betas),
            s.rho
        );
    }
    if !p.notes().is_empty() {
        println!("    note: {}", p.notes());
    }
}

const COLORS: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

type PlotResult = Result<(), Box<dyn std::error::Error>>;

fn plot_errors(dir: &Path, p: &dyn TestProblem, a: &Analysis) -> PlotResult {
    let path = dir.join(format!("{}_error.png", p.name()));
    let runs: Vec<&Run> = std::iter::once(&a.admm)
        .chain(&a.aa)
        .chain(&a.saa)
        .collect();
    let pts = |r: &Run| -> Vec<(f64, f64)> {
        r.iterations
            .iter()
            .zip(&r.errors)
            .filter(|(_, e)| **e > 0.0 && e.is_finite())
            .map(|(k, e)| (*k as f64, e.log10()))
            .collect()
    };
    let xmax = runs
        .iter()
        .map(|r| last_iteration(r))
        .max()
        .unwrap_or(1)
        .max(1) as f64;
    let ymin = runs
        .iter()
        .flat_map(|r| pts(r))
        .fold(0.0f64, |m, (_, y)| m.min(y))
        .floor();
    let root = BitMapBackend::new(&path, (960, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{}: relative error ||(z,u) - (z*,u*)||", p.name()),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..xmax, ymin..1.0)?;
    chart
        .configure_mesh()
        .x_desc("iteration (map evaluations)")
        .y_desc("log10 error")
        .label_style(("sans-serif", 14))
        .draw()?;
    for (i, r) in runs.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        let style = if r.label.starts_with('s') {
            c.stroke_width(1)
        } else {
            c.stroke_width(2)
        };
        let label = match r.factor {
            Some(f) => format!("{} ({f:.3})", r.label),
            None => r.label.clone(),
        };
        chart
            .draw_series(LineSeries::new(pts(r), style))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    // The predicted sAA(1) slope from the start.
    let pred = a.saa1.rho;
    if pred > 0.0 && pred < 1.0 {
        let k = (ymin / pred.log10()).min(xmax);
        let c = RGBColor(127, 127, 127);
        chart
            .draw_series(DashedLineSeries::new(
                vec![(0.0, 0.0), (k, k * pred.log10())],
                6,
                4,
                c.stroke_width(1),
            ))?
            .label(format!("rho*_sAA(1) = {pred:.3} (predicted)"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

fn plot_spectrum(dir: &Path, p: &dyn TestProblem, a: &Analysis) -> PlotResult {
    let path = dir.join(format!("{}_spectrum.png", p.name()));
    let q = &a.spectrum.eigenvalues;
    let psi1 = saa::iteration_spectrum(q, &[a.saa1.beta]);
    let psi2 = a
        .saa_search
        .first()
        .map(|s| saa::iteration_spectrum(q, &s.betas))
        .unwrap_or_default();
    let root = BitMapBackend::new(&path, (800, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{}: spectra", p.name()), ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-1.05..1.05, -1.05..1.05)?;
    chart
        .configure_mesh()
        .x_desc("Re")
        .y_desc("Im")
        .label_style(("sans-serif", 14))
        .draw()?;
    let unit: Vec<(f64, f64)> = (0..=360)
        .map(|d| {
            let t = (d as f64).to_radians();
            (t.cos(), t.sin())
        })
        .collect();
    chart.draw_series(LineSeries::new(unit, RGBColor(200, 200, 200)))?;
    let sets: [(&[C64], String, RGBColor, u32); 3] = [
        (
            q,
            format!("q' (rho = {:.3})", a.spectrum.radius()),
            COLORS[0],
            3,
        ),
        (
            &psi1,
            format!(
                "Psi' sAA(1), beta = {:.3} (rho = {:.3})",
                a.saa1.beta, a.saa1.rho
            ),
            COLORS[1],
            2,
        ),
        (
            &psi2,
            format!(
                "Psi'_2 sAA(2) (rho = {:.3})",
                a.saa_search.first().map_or(f64::NAN, |s| s.rho)
            ),
            COLORS[3],
            2,
        ),
    ];
    for (pts, label, c, size) in sets {
        if pts.is_empty() {
            continue;
        }
        chart
            .draw_series(
                pts.iter()
                    .map(|z| Circle::new((z.re, z.im), size, c.filled())),
            )?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, c.filled()));
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()?;
    root.present()?;
    Ok(())
}
