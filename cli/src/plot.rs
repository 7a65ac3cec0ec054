//! PNG plots of `cadmm bench`: performance profiles and work-precision (error against time).
//! Text needs the font of [`crate::font`].

use crate::font::font;
use crate::profile::{max_finite_ratio, profile_steps};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// Tableau 10: distinguishable, and readable on white.
const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The color of solver number `s` (the same in every plot of a run).
pub fn color(s: usize) -> RGBColor {
    COLORS[s % COLORS.len()]
}

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

const SIZE: (u32, u32) = (960, 640);

/// `profile-<tol>.png`: `rho_s(tau)` against `log2 tau`, one step curve per solver.
pub fn profile(path: &Path, tol: f64, solvers: &[String], r: &[Vec<f64>]) -> Result<(), String> {
    font()?;
    let x_end = (max_finite_ratio(r).log2() * 1.05).max(1.0);
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("Performance profile, tol = {tol:e} ({} problems)", r.len()),
            ("sans-serif", 26),
        )
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..x_end, 0f64..1.05f64)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("log2(τ)   (τ: time / best time on the problem)")
        .y_desc("ρ(τ): fraction of problems")
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()
        .map_err(err)?;
    for (s, name) in solvers.iter().enumerate() {
        let c = color(s);
        chart
            .draw_series(LineSeries::new(
                profile_steps(r, s, x_end),
                c.stroke_width(3),
            ))
            .map_err(err)?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font(("sans-serif", 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

/// One solver's data on a work-precision plot.
pub struct Curve {
    /// Legend text of the points.
    pub label: String,
    /// Index of the solver (for its color).
    pub solver: usize,
    /// `(seconds, error)` of untraced runs, drawn as markers; empty when no run gave a
    /// solution.
    pub points: Vec<(f64, f64)>,
    /// A traced run's `(seconds, error)`, drawn as a line, and its legend text.
    pub trace: Option<(String, Vec<(f64, f64)>)>,
}

/// A trace as steps: the error a run has measured holds until its next measurement, so a
/// long step (a Newton polish between two ADMM iterations) shows as a drop at its end, not as
/// a slope across its duration.
fn staircase(pts: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(2 * pts.len());
    for (k, &(x, y)) in pts.iter().enumerate() {
        if k > 0 {
            out.push((x, pts[k - 1].1));
        }
        out.push((x, y));
    }
    out
}

/// Errors below this are drawn at this value (log axis).
const ERROR_FLOOR: f64 = 1e-17;

/// `work-precision/<problem>.png`: error against wall time, log-log, with the tolerances as
/// dashed lines.
pub fn work_precision(
    path: &Path,
    title: &str,
    curves: &[Curve],
    tols: &[f64],
) -> Result<(), String> {
    font()?;
    let pts = || {
        curves
            .iter()
            .flat_map(|c| {
                let trace = c.trace.iter().flat_map(|(_, t)| t.iter().copied());
                c.points.iter().copied().chain(trace)
            })
            .filter(|&(x, y)| x > 0.0 && x.is_finite() && y.is_finite())
    };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0f64, f64::INFINITY, 0f64);
    for (x, y) in pts() {
        let y = y.max(ERROR_FLOOR);
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    for &t in tols {
        (y0, y1) = (y0.min(t), y1.max(t));
    }
    if !x0.is_finite() {
        (x0, x1) = (1e-4, 10.0);
    }
    let (x0, x1) = (x0 / 1.5, x1 * 1.5);
    let (y0, y1) = (y0 / 3.0, y1 * 3.0);
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 24))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("wall time (s)")
        .y_desc("error (docs/algorithms.md §3)")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()
        .map_err(err)?;
    let tol_color = RGBColor(80, 80, 80);
    for &t in tols {
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, t), (x1, t)],
                10,
                6,
                tol_color.stroke_width(2),
            ))
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(Text::new(
                format!("tol {t:e}"),
                (x0 * 1.05, t),
                ("sans-serif", 15)
                    .into_font()
                    .color(&tol_color)
                    .pos(Pos::new(HPos::Left, VPos::Bottom)),
            )))
            .map_err(err)?;
    }
    let drawable = |pts: &[(f64, f64)]| -> Vec<(f64, f64)> {
        pts.iter()
            .filter(|&&(x, y)| x > 0.0 && x.is_finite() && y.is_finite())
            .map(|&(x, y)| (x, y.max(ERROR_FLOOR)))
            .collect()
    };
    for c in curves {
        let col = color(c.solver);
        let data = drawable(&c.points);
        if let Some((label, trace)) = &c.trace {
            chart
                .draw_series(LineSeries::new(
                    staircase(&drawable(trace)),
                    col.stroke_width(2),
                ))
                .map_err(err)?
                .label(label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], col.stroke_width(2))
                });
        } else if data.len() > 1 {
            // Runs of a solver without a trace, joined to be told apart from other solvers.
            chart
                .draw_series(LineSeries::new(data.clone(), col.stroke_width(1)))
                .map_err(err)?;
        }
        chart
            .draw_series(data.iter().map(|&p| Circle::new(p, 6, col.filled())))
            .map_err(err)?
            .label(c.label.as_str())
            .legend(move |(x, y)| Circle::new((x + 12, y), 5, col.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::staircase;

    #[test]
    fn trace_holds_each_error_until_the_next_measurement() {
        let pts = [(1.0, 1e-2), (2.0, 1e-4), (10.0, 1e-12)];
        assert_eq!(
            staircase(&pts),
            vec![
                (1.0, 1e-2),
                (2.0, 1e-2),
                (2.0, 1e-4),
                (10.0, 1e-4),
                (10.0, 1e-12)
            ]
        );
        assert!(staircase(&[]).is_empty());
    }
}
