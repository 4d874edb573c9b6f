//! Sweeps: every estimator and the linearized bound against one parameter
//! of the simulation (GPS rate, IMU rate, true delay), each value a full
//! Monte Carlo run of the scenario (same seeds, same options).
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --sweep gps_rate --json target/sweep-gps_rate.json
//! ```
//!
//! Prints per scenario a table of tilt, heading, velocity and position
//! (mean over the seeds) per value and estimator, writes the JSON (one
//! `to_json` run per value) and an SVG plot per scenario (tilt and velocity
//! against the parameter, log scale) under the plot directory
//! (`target/reproduce` unless `--plots`).
//!
//! No row is dropped. A cell is marked `(diverged)` when the estimator's
//! velocity RMSE exceeds [`DIVERGED_FACTOR`] times the bound's on the same
//! runs, and reads `fail` when the estimator gave no estimate after the
//! convergence time (or no finite figure).

use super::Progress;
use super::{
    Metrics, RunOptions, ScenarioResult, Summary, fmt_value, print_tables, run_scenario, to_json,
};
use clap::ValueEnum;
use delaynav::sim::Scenario;
use plotters::prelude::*;
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// Velocity RMSE above this multiple of the bound's marks a cell diverged.
pub const DIVERGED_FACTOR: f64 = 5.0;

/// The parameters a sweep can vary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SweepName {
    /// GPS rate: 1, 2, 5, 10, 20 Hz.
    #[value(name = "gps_rate")]
    GpsRate,
    /// IMU rate: 50, 100, 200, 1000 Hz (the magnetometer at most at the IMU rate).
    #[value(name = "imu_rate")]
    ImuRate,
    /// True GPS delay: 0, 0.1, 0.2, 0.4, 0.6 s.
    #[value(name = "delay")]
    Delay,
}

impl SweepName {
    fn name(self) -> &'static str {
        match self {
            SweepName::GpsRate => "gps_rate",
            SweepName::ImuRate => "imu_rate",
            SweepName::Delay => "delay",
        }
    }

    fn label(self) -> &'static str {
        match self {
            SweepName::GpsRate => "GPS rate (Hz)",
            SweepName::ImuRate => "IMU rate (Hz)",
            SweepName::Delay => "true delay (s)",
        }
    }

    fn values(self) -> &'static [f64] {
        match self {
            SweepName::GpsRate => &[1.0, 2.0, 5.0, 10.0, 20.0],
            SweepName::ImuRate => &[50.0, 100.0, 200.0, 1000.0],
            SweepName::Delay => &[0.0, 0.1, 0.2, 0.4, 0.6],
        }
    }

    fn apply(self, options: &mut RunOptions, value: f64) {
        match self {
            SweepName::GpsRate => options.gps_rate_hz = Some(value),
            SweepName::ImuRate => options.imu_rate_hz = Some(value),
            SweepName::Delay => options.delay_s = Some(value),
        }
    }
}

/// Runs the sweep, prints its tables, writes the JSON and the plots.
pub fn run(
    sweep: SweepName,
    scenarios: &[Scenario],
    seeds: &[u64],
    options: RunOptions,
    json_path: &Path,
    plots: Option<PathBuf>,
) -> Result<(), Box<dyn std::error::Error>> {
    let values = sweep.values();
    let registry = super::estimators();
    let progress = Mutex::new(Progress {
        done: 0,
        total: values.len() * scenarios.len() * seeds.len() * registry.len(),
        started: Instant::now(),
    });
    // points[v][s]: the result of value v in scenario s.
    let mut points: Vec<Vec<ScenarioResult>> = Vec::new();
    for &value in values {
        let mut o = RunOptions {
            keep_trace: false,
            ..options
        };
        sweep.apply(&mut o, value);
        eprintln!("{} = {value}", sweep.name());
        points.push(
            scenarios
                .iter()
                .map(|&s| run_scenario(s, seeds, &o, &registry, &progress))
                .collect(),
        );
    }
    print!(
        "{}",
        sweep_tables(sweep, scenarios, &points, seeds.len(), &options)
    );
    let json = json!({
        "sweep": sweep.name(),
        "parameter": sweep.label(),
        "values": values,
        "seeds": seeds,
        "diverged_factor": DIVERGED_FACTOR,
        "points": values.iter().zip(&points).map(|(v, results)| json!({
            "value": v,
            "run": to_json(results, seeds, options.duration_s, options.skip_s),
        })).collect::<Vec<Value>>(),
    });
    if let Some(parent) = json_path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    std::fs::write(json_path, serde_json::to_string_pretty(&json)? + "\n")?;
    eprintln!("wrote {}", json_path.display());
    let dir = plots.unwrap_or_else(|| PathBuf::from("target/reproduce"));
    std::fs::create_dir_all(&dir)?;
    for (k, scenario) in scenarios.iter().enumerate() {
        let path = dir.join(format!("sweep-{}-{}.svg", sweep.name(), scenario.name()));
        let column: Vec<&ScenarioResult> = points.iter().map(|p| &p[k]).collect();
        plot(&path, sweep, *scenario, &column)?;
        eprintln!("wrote {}", path.display());
    }
    // The full tables of every point, for the record.
    if std::env::var_os("REPRODUCE_SWEEP_FULL").is_some() {
        for results in &points {
            print!(
                "{}",
                print_tables(results, seeds.len(), options.duration_s, options.skip_s)
            );
        }
    }
    Ok(())
}

/// Whether an estimator broke down: no finite figure, or velocity above
/// [`DIVERGED_FACTOR`] times the bound's.
fn diverged(s: &Metrics, bound: &Metrics) -> bool {
    !(s.vel_m_s.is_finite() && s.vel_m_s <= DIVERGED_FACTOR * bound.vel_m_s)
}

/// The table rows of one figure: label and how to read it.
type SweepFigure = (&'static str, fn(&Metrics) -> f64);

const SWEEP_FIGURES: [SweepFigure; 4] = [
    ("tilt (deg)", |m| m.tilt_deg),
    ("heading (deg)", |m| m.heading_deg),
    ("velocity (m/s)", |m| m.vel_m_s),
    ("position (m)", |m| m.pos_m),
];

fn bound_of(r: &ScenarioResult) -> Option<&Summary> {
    r.summaries
        .iter()
        .find(|(n, _)| *n == "bound")
        .map(|(_, s)| s)
}

fn sweep_tables(
    sweep: SweepName,
    scenarios: &[Scenario],
    points: &[Vec<ScenarioResult>],
    seeds: usize,
    options: &RunOptions,
) -> String {
    let mut out = String::new();
    for (k, scenario) in scenarios.iter().enumerate() {
        let names: Vec<&str> = points[0][k].summaries.iter().map(|(n, _)| *n).collect();
        let _ = writeln!(
            out,
            "\n### Sweep `{}`, scenario `{}`: mean over {seeds} seeds of the RMSE after {} s of {} s\n",
            sweep.name(),
            scenario.name(),
            options.skip_s,
            options.duration_s
        );
        for (label, get) in SWEEP_FIGURES {
            let _ = writeln!(out, "\n{label}\n");
            let _ = writeln!(out, "| {} | {} |", sweep.label(), names.join(" | "));
            let _ = writeln!(out, "|---|{}", "---|".repeat(names.len()));
            for (value, results) in sweep.values().iter().zip(points) {
                let r = &results[k];
                let bound = bound_of(r).map(|b| &b.mean);
                let cells: Vec<String> = r
                    .summaries
                    .iter()
                    .map(|(_, s)| {
                        let x = fmt_value(get(&s.mean));
                        match bound {
                            Some(b) if diverged(&s.mean, b) && x != "fail" => {
                                format!("{x} (diverged)")
                            }
                            _ => x,
                        }
                    })
                    .collect();
                let _ = writeln!(out, "| {value} | {} |", cells.join(" | "));
            }
        }
        let _ = writeln!(out, "\ndelay RMSE (s) of the estimators that estimate it\n");
        // `oracle` is given the delay: its error is zero by construction.
        let with_delay: Vec<usize> = points[0][k]
            .summaries
            .iter()
            .enumerate()
            .filter(|(_, (n, s))| s.mean.delay_s.is_some() && *n != "oracle")
            .map(|(i, _)| i)
            .collect();
        let _ = writeln!(
            out,
            "| {} | {} |",
            sweep.label(),
            with_delay
                .iter()
                .map(|&i| points[0][k].summaries[i].0)
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(out, "|---|{}", "---|".repeat(with_delay.len()));
        for (value, results) in sweep.values().iter().zip(points) {
            let cells: Vec<String> = with_delay
                .iter()
                .map(|&i| fmt_value(results[k].summaries[i].1.mean.delay_s.unwrap_or(f64::NAN)))
                .collect();
            let _ = writeln!(out, "| {value} | {} |", cells.join(" | "));
        }
    }
    let _ = writeln!(
        out,
        "\n(diverged): velocity RMSE above {DIVERGED_FACTOR}x the bound's on the same runs; \
         fail: no estimate after the convergence time, or no finite figure."
    );
    out
}

/// Tilt and velocity against the parameter, one line per estimator, log
/// scale on both figures (a diverged estimator stays on the plot).
fn plot(
    path: &Path,
    sweep: SweepName,
    scenario: Scenario,
    column: &[&ScenarioResult],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (900, 800)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((2, 1));
    let values = sweep.values();
    let (x_min, x_max) = (values[0], values[values.len() - 1]);
    let names: Vec<&str> = column[0].summaries.iter().map(|(n, _)| *n).collect();
    let figures: [SweepFigure; 2] = [SWEEP_FIGURES[0], SWEEP_FIGURES[2]];
    for (panel, (label, get)) in panels.iter().zip(figures) {
        let ys: Vec<f64> = column
            .iter()
            .flat_map(|r| r.summaries.iter().map(|(_, s)| get(&s.mean)))
            .filter(|y| y.is_finite() && *y > 0.0)
            .collect();
        let y_min = ys.iter().copied().fold(f64::INFINITY, f64::min).max(1e-6) * 0.8;
        let y_max = ys.iter().copied().fold(0.0, f64::max).max(y_min * 10.0) * 1.25;
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!(
                    "{} against {}, scenario {}",
                    label,
                    sweep.label(),
                    scenario.name()
                ),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(60)
            .build_cartesian_2d(x_min..x_max, (y_min..y_max).log_scale())?;
        chart
            .configure_mesh()
            .x_desc(sweep.label())
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
