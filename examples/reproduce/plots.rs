//! The plots, drawn with plotters as SVG: stacked line plots sharing the time
//! axis (Figures 5 and 6 of the paper, [`scenario`]) and a sweep's figures
//! against its parameter ([`sweep`]).

use delaynav::sim::Scenario;
use delaynav::sim::suite::integrity::{STANFORD_BINS, STANFORD_SPAN_AL, Stanford};
use delaynav::sim::suite::sweep::{SWEEP_FIGURES, SweepFigure, SweepParameter};
use delaynav::sim::suite::tables::ScenarioResult;
use plotters::prelude::*;
use std::error::Error;
use std::path::{Path, PathBuf};

/// One line of a plot. Non-finite values leave a gap.
pub struct Series<'a> {
    pub name: &'a str,
    pub color: RGBColor,
    pub x: &'a [f64],
    pub y: Vec<f64>,
}

/// One panel of a stacked plot.
pub struct Panel<'a> {
    pub title: String,
    pub series: Vec<Series<'a>>,
}

/// The truth's colour, then the estimators' in registry order.
pub const TRUTH_COLOR: RGBColor = BLACK;
pub const COLORS: [RGBColor; 8] = [
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x17, 0xbe, 0xcf),
];

/// The finite range of `values`, padded; `None` when there is none.
fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    Some((lo - pad, hi + pad))
}

/// The runs of consecutive finite points of a series.
fn segments(s: &Series) -> Vec<Vec<(f64, f64)>> {
    let mut out = vec![Vec::new()];
    for (&x, &y) in s.x.iter().zip(&s.y) {
        if y.is_finite() {
            out.last_mut().expect("never empty").push((x, y));
        } else if !out.last().expect("never empty").is_empty() {
            out.push(Vec::new());
        }
    }
    out
}

/// Draws `panels` (those with a finite point) one above the other into `path`.
pub fn panels(path: &Path, title: &str, panels: &[Panel]) -> Result<(), Box<dyn Error>> {
    let drawn: Vec<&Panel> = panels
        .iter()
        .filter(|p| range(p.series.iter().flat_map(|s| s.y.iter().copied())).is_some())
        .collect();
    let height = 40 + 250 * drawn.len().max(1) as u32;
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 18))?;
    for (area, panel) in root.split_evenly((drawn.len().max(1), 1)).iter().zip(drawn) {
        let points = || {
            panel
                .series
                .iter()
                .flat_map(|s| s.x.iter().copied().zip(s.y.iter().copied()))
        };
        let finite = || points().filter(|(_, y)| y.is_finite());
        let (Some(x), Some(y)) = (range(finite().map(|p| p.0)), range(finite().map(|p| p.1)))
        else {
            continue;
        };
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, ("sans-serif", 14))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
        chart.configure_mesh().x_desc("time (s)").draw()?;
        for s in &panel.series {
            let color = s.color;
            let mut first = true;
            for segment in segments(s) {
                let drawn = chart.draw_series(LineSeries::new(segment, &color))?;
                if first {
                    drawn
                        .label(s.name)
                        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color));
                    first = false;
                }
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// Figures 5 and 6 of a scenario's first seed: true and estimated pitch,
/// attitude errors, delay estimate; the paths written.
pub fn scenario(dir: &Path, r: &ScenarioResult) -> Result<Vec<PathBuf>, Box<dyn Error>> {
    std::fs::create_dir_all(dir)?;
    let truth_t: Vec<f64> = r.truth_trace.iter().map(|p| p.0).collect();
    let mut pitch = Panel {
        title: "pitch (deg): truth and estimates".into(),
        series: vec![Series {
            name: "truth",
            color: TRUTH_COLOR,
            x: &truth_t,
            y: r.truth_trace.iter().map(|p| p.1).collect(),
        }],
    };
    let mut errors: Vec<Panel> = ["roll", "pitch", "yaw"]
        .iter()
        .map(|axis| Panel {
            title: format!("{axis} error (deg)"),
            series: Vec::new(),
        })
        .collect();
    let mut delay = Panel {
        title: "GPS delay (s): truth and estimates".into(),
        series: vec![Series {
            name: "truth",
            color: TRUTH_COLOR,
            x: &truth_t,
            y: r.truth_trace.iter().map(|p| p.2).collect(),
        }],
    };
    let plotted = r.traces.iter().filter(|(_, t)| !t.t_s.is_empty());
    for (k, (name, trace)) in plotted.enumerate() {
        let color = COLORS[k % COLORS.len()];
        pitch.series.push(Series {
            name,
            color,
            x: &trace.t_s,
            y: trace.pitch_deg.clone(),
        });
        for (axis, panel) in errors.iter_mut().enumerate() {
            panel.series.push(Series {
                name,
                color,
                x: &trace.t_s,
                y: trace.attitude_err_deg.iter().map(|e| e[axis]).collect(),
            });
        }
        if trace.delay_s.iter().any(|d| d.is_finite()) {
            delay.series.push(Series {
                name,
                color,
                x: &trace.t_s,
                y: trace.delay_s.clone(),
            });
        }
    }
    let name = r.scenario.name();
    let attitude_path = dir.join(format!("{name}-attitude.svg"));
    let mut all = vec![pitch];
    all.extend(errors);
    let title = format!("scenario {name}: attitude (first seed)");
    panels(&attitude_path, &title, &all)?;
    let delay_path = dir.join(format!("{name}-delay.svg"));
    let title = format!("scenario {name}: GPS delay (first seed)");
    panels(&delay_path, &title, &[delay])?;
    Ok(vec![attitude_path, delay_path])
}

/// A sweep's tilt and velocity against its parameter, one line per estimator,
/// log scale on both figures (a diverged estimator stays on the plot).
pub fn sweep(
    path: &Path,
    parameter: SweepParameter,
    scenario: Scenario,
    column: &[&ScenarioResult],
) -> Result<(), Box<dyn Error>> {
    let root = SVGBackend::new(path, (900, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let areas = root.split_evenly((2, 1));
    let values = parameter.values();
    let (x_min, x_max) = (values[0], values[values.len() - 1]);
    let names: Vec<&str> = column[0].summaries.iter().map(|(n, _)| *n).collect();
    let figures: [SweepFigure; 2] = [SWEEP_FIGURES[0], SWEEP_FIGURES[2]];
    for (area, (label, get)) in areas.iter().zip(figures) {
        let ys: Vec<f64> = column
            .iter()
            .flat_map(|r| r.summaries.iter().map(|(_, s)| get(&s.mean)))
            .filter(|y| y.is_finite() && *y > 0.0)
            .collect();
        let y_min = ys.iter().copied().fold(f64::INFINITY, f64::min).max(1e-6) * 0.8;
        let y_max = ys.iter().copied().fold(0.0, f64::max).max(y_min * 10.0) * 1.25;
        let caption = format!(
            "{} against {}, scenario {}",
            label,
            parameter.label(),
            scenario.name()
        );
        let mut chart = ChartBuilder::on(area)
            .caption(caption, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(60)
            .build_cartesian_2d(x_min..x_max, (y_min..y_max).log_scale())?;
        chart
            .configure_mesh()
            .x_desc(parameter.label())
            .y_desc(label)
            .draw()?;
        for (i, name) in names.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let points: Vec<(f64, f64)> = values
                .iter()
                .zip(column)
                .map(|(x, r)| (*x, get(&r.summaries[i].1.mean)))
                .filter(|(_, y)| y.is_finite() && *y > 0.0)
                .collect();
            chart
                .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
            chart.draw_series(
                points
                    .iter()
                    .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
            )?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// The colour of a Stanford-diagram bin holding `count` epochs, `max` the fullest bin's, on a
/// log scale through `stops` (from 1 epoch to `max`).
fn stanford_color(count: u64, max: u64, stops: &[RGBColor; 3]) -> RGBColor {
    let f = if max > 1 {
        (count as f64).ln() / (max as f64).ln()
    } else {
        1.0
    };
    let (a, b, t) = if f < 0.5 {
        (stops[0], stops[1], f * 2.0)
    } else {
        (stops[1], stops[2], f * 2.0 - 1.0)
    };
    let mix = |x: u8, y: u8| (x as f64 + (y as f64 - x as f64) * t).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Available epochs: yellow, teal, purple (a viridis-like ramp).
const AVAILABLE_STOPS: [RGBColor; 3] = [
    RGBColor(0xfd, 0xe7, 0x25),
    RGBColor(0x21, 0x91, 0x8c),
    RGBColor(0x44, 0x01, 0x54),
];
/// Epochs not available: light to dark grey.
const UNAVAILABLE_STOPS: [RGBColor; 3] = [
    RGBColor(0xe4, 0xe4, 0xe4),
    RGBColor(0xa8, 0xa8, 0xa8),
    RGBColor(0x50, 0x50, 0x50),
];

/// A Stanford diagram (error against protection level, epochs per bin on a log colour scale,
/// the diagonal and the alert limit drawn, the regions' counts in the caption) into `path`.
pub fn stanford(
    path: &Path,
    quantity: &str,
    unit: &str,
    diagram: &Stanford,
) -> Result<(), Box<dyn Error>> {
    let al = diagram.alert_limit;
    let span = STANFORD_SPAN_AL * al;
    let width = span / STANFORD_BINS as f64;
    let root = SVGBackend::new(path, (760, 820)).into_drawing_area();
    root.fill(&WHITE)?;
    let r = diagram.regions;
    let total = r.nominal + r.misleading + r.hazardous + r.unavailable + r.unavailable_misleading;
    let (top, bottom) = root.split_vertically(700);
    let mut chart = ChartBuilder::on(&top)
        .caption(
            format!("Stanford diagram: {quantity}, navigator, every integrity run"),
            ("sans-serif", 18),
        )
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..span, 0.0..span)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(format!(
            "{quantity} error ({unit}); the last bin holds everything beyond"
        ))
        .y_desc(format!("{quantity} protection level ({unit})"))
        .draw()?;
    let max = diagram
        .counts
        .iter()
        .chain(&diagram.unavailable_counts)
        .copied()
        .max()
        .unwrap_or(0);
    // Where a bin holds both, the available epochs are drawn over the others.
    for (counts, stops) in [
        (&diagram.unavailable_counts, &UNAVAILABLE_STOPS),
        (&diagram.counts, &AVAILABLE_STOPS),
    ] {
        chart.draw_series(
            counts
                .iter()
                .enumerate()
                .filter(|(_, c)| **c > 0)
                .map(|(i, &c)| {
                    let (row, col) = (i / STANFORD_BINS, i % STANFORD_BINS);
                    let (x, y) = (col as f64 * width, row as f64 * width);
                    Rectangle::new(
                        [(x, y), (x + width, y + width)],
                        stanford_color(c, max, stops).filled(),
                    )
                }),
        )?;
    }
    chart.draw_series(LineSeries::new(
        [(0.0, 0.0), (span, span)],
        BLACK.stroke_width(1),
    ))?;
    let limit = RGBColor(0xd6, 0x27, 0x28);
    chart.draw_series(LineSeries::new(
        [(al, 0.0), (al, span)],
        limit.stroke_width(2),
    ))?;
    chart.draw_series(LineSeries::new(
        [(0.0, al), (span, al)],
        limit.stroke_width(2),
    ))?;
    let label = |text: &str, x: f64, y: f64| {
        Text::new(text.to_string(), (x, y), ("sans-serif", 13).into_font())
    };
    chart.draw_series([
        label("MI", 0.6 * al, 0.15 * al),
        label("HMI (error > AL)", 1.5 * al, 0.4 * al),
        label("PL > AL: not available", 1.6 * al, 1.2 * al),
    ])?;
    let share = |n: u64| 100.0 * n as f64 / total.max(1) as f64;
    let lines = [
        "colour: the flag valid (yellow to purple); grey: not valid (PL > AL, or not usable)"
            .to_string(),
        format!(
            "{total} epochs; alert limit (red) {al} {unit}; diagonal: error = PL; epochs per bin (log, max {max})"
        ),
        format!(
            "available: error within PL {} ({:.2} %), MI {} ({:.4} %), HMI (error > AL) {} ({:.4} %)",
            r.nominal,
            share(r.nominal),
            r.misleading,
            share(r.misleading),
            r.hazardous,
            share(r.hazardous),
        ),
        format!(
            "not available: error within PL {} ({:.2} %), error above PL {} ({:.4} %)",
            r.unavailable,
            share(r.unavailable),
            r.unavailable_misleading,
            share(r.unavailable_misleading),
        ),
    ];
    for (k, line) in lines.iter().enumerate() {
        bottom.draw(&Text::new(
            line.clone(),
            (20, 8 + 24 * k as i32),
            ("sans-serif", 14).into_font(),
        ))?;
    }
    root.present()?;
    Ok(())
}
