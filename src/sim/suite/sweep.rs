//! Sweeps: every estimator of the tables and the linearized bound against one parameter of the
//! simulation (GPS rate, IMU rate, true delay), each value a full Monte Carlo run of the tables
//! (same seeds, same options).
//!
//! ```text
//! cargo run --release --features sim --example reproduce -- --sweep gps_rate --seeds 5 --json target/sweep-gps_rate.json
//! ```
//!
//! **Scenario.** [`SweepParameter::values`] of the parameter, each set on the tables' options
//! ([`TablesOptions`]) and run with [`tables::run`]'s rows, without traces.
//!
//! **Verdicts.** None is enforced: no row is dropped. A cell is marked `(diverged)` when the
//! estimator's velocity RMSE exceeds [`DIVERGED_FACTOR`] times the bound's on the same runs,
//! and reads `fail` when the estimator gave no estimate after the convergence time (or no
//! finite figure).
//!
//! **JSON** ([`SweepResult::to_json`]): `sweep` (the parameter's name), `parameter` (its label),
//! `values`, `seeds`, `diverged_factor`, and `points`: per value, `value` and `run` (the tables'
//! JSON document at that value, [`TablesResult::to_json`]).
//!
//! **Text** (`Display` of [`SweepResult`]): per scenario a table of tilt, heading, velocity
//! and position (mean over the seeds) per value and estimator, then the delay RMSE of the
//! estimators that estimate it. [`SweepResult::full_tables`] gives every point's tables.

use super::tables::{
    self, Estimator, Metrics, ScenarioResult, Summary, TablesOptions, TablesResult,
};
use super::{Progress, ProgressFn, Steps, SuiteError};
use crate::sim::Scenario;
use core::fmt;
use serde_json::{Value, json};
use tables::fmt_value;

/// Velocity RMSE above this multiple of the bound's marks a cell diverged.
pub const DIVERGED_FACTOR: f64 = 5.0;

/// The parameters a sweep can vary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SweepParameter {
    /// GPS rate: 1, 2, 5, 10, 20 Hz.
    GpsRate,
    /// IMU rate: 50, 100, 200, 1000 Hz (the magnetometer at most at the IMU rate).
    ImuRate,
    /// True GPS delay: 0, 0.1, 0.2, 0.4, 0.6 s.
    Delay,
}

impl SweepParameter {
    /// Every parameter.
    pub const ALL: [SweepParameter; 3] = [Self::GpsRate, Self::ImuRate, Self::Delay];

    /// Its name: `gps_rate`, `imu_rate`, `delay`.
    pub fn name(self) -> &'static str {
        match self {
            SweepParameter::GpsRate => "gps_rate",
            SweepParameter::ImuRate => "imu_rate",
            SweepParameter::Delay => "delay",
        }
    }

    /// The parameter named `name` ([`Self::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Its label with its unit, for tables and plots.
    pub fn label(self) -> &'static str {
        match self {
            SweepParameter::GpsRate => "GPS rate (Hz)",
            SweepParameter::ImuRate => "IMU rate (Hz)",
            SweepParameter::Delay => "true delay (s)",
        }
    }

    /// The values swept.
    pub fn values(self) -> &'static [f64] {
        match self {
            SweepParameter::GpsRate => &[1.0, 2.0, 5.0, 10.0, 20.0],
            SweepParameter::ImuRate => &[50.0, 100.0, 200.0, 1000.0],
            SweepParameter::Delay => &[0.0, 0.1, 0.2, 0.4, 0.6],
        }
    }

    /// Sets the parameter to `value` on the tables' options.
    pub fn apply(self, options: &mut TablesOptions, value: f64) {
        match self {
            SweepParameter::GpsRate => options.gps_rate_hz = Some(value),
            SweepParameter::ImuRate => options.imu_rate_hz = Some(value),
            SweepParameter::Delay => options.delay_s = Some(value),
        }
    }
}

/// The options of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepOptions {
    /// The parameter swept.
    pub parameter: SweepParameter,
    /// The tables' options at every value (traces are never kept).
    pub tables: TablesOptions,
}

/// A sweep: the tables at every value of the parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepResult {
    /// The parameter swept.
    pub parameter: SweepParameter,
    /// The tables at each value, in [`SweepParameter::values`] order.
    pub points: Vec<(f64, TablesResult)>,
}

/// Runs the tables' rows `estimators` at every value of the parameter, reporting a
/// [`Progress::SweepValue`] per value and a [`Progress::Step`] per row and seed.
pub fn run(
    options: &SweepOptions,
    estimators: &[Estimator],
    progress: ProgressFn,
) -> Result<SweepResult, SuiteError> {
    let parameter = options.parameter;
    let values = parameter.values();
    let base = &options.tables;
    let total = values.len() * base.scenarios.len() * base.seeds.len() * estimators.len();
    let steps = Steps::new(total, progress);
    let mut points = Vec::new();
    for &value in values {
        let mut o = TablesOptions {
            keep_trace: false,
            ..base.clone()
        };
        parameter.apply(&mut o, value);
        o.validate()?;
        steps.report(Progress::SweepValue {
            parameter: parameter.name(),
            value,
        });
        let scenarios = o
            .scenarios
            .iter()
            .map(|&s| tables::run_scenario(s, &o, estimators, &steps))
            .collect::<Result<_, _>>()?;
        points.push((
            value,
            TablesResult {
                options: o,
                scenarios,
            },
        ));
    }
    Ok(SweepResult { parameter, points })
}

/// Whether an estimator broke down: no finite figure, or velocity above
/// [`DIVERGED_FACTOR`] times the bound's.
pub fn diverged(s: &Metrics, bound: &Metrics) -> bool {
    !(s.vel_m_s.is_finite() && s.vel_m_s <= DIVERGED_FACTOR * bound.vel_m_s)
}

/// A figure of the sweep's tables: its label and how to read it.
pub type SweepFigure = (&'static str, fn(&Metrics) -> f64);

/// The figures of the sweep's tables (tilt and velocity are plotted).
pub const SWEEP_FIGURES: [SweepFigure; 4] = [
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

impl SweepResult {
    /// The scenarios of the sweep, in order.
    pub fn scenarios(&self) -> Vec<Scenario> {
        self.points.first().map_or_else(Vec::new, |(_, r)| {
            r.scenarios.iter().map(|s| s.scenario).collect()
        })
    }

    /// The results of scenario number `k` at every value, in order.
    pub fn column(&self, k: usize) -> Vec<&ScenarioResult> {
        self.points.iter().map(|(_, r)| &r.scenarios[k]).collect()
    }

    /// The sweep's JSON document (see the module's docs).
    pub fn to_json(&self) -> Value {
        let seeds = self
            .points
            .first()
            .map_or(&[][..], |(_, r)| &r.options.seeds[..]);
        json!({
            "sweep": self.parameter.name(),
            "parameter": self.parameter.label(),
            "values": self.points.iter().map(|(v, _)| *v).collect::<Vec<_>>(),
            "seeds": seeds,
            "diverged_factor": DIVERGED_FACTOR,
            "points": self.points.iter().map(|(v, run)| json!({
                "value": v,
                "run": run.to_json(),
            })).collect::<Vec<Value>>(),
        })
    }

    /// Every point's full tables (`Display` of [`TablesResult`]), in order.
    pub fn full_tables(&self) -> String {
        self.points.iter().map(|(_, r)| r.to_string()).collect()
    }
}

impl fmt::Display for SweepResult {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some((_, first)) = self.points.first() else {
            return Ok(());
        };
        let label = self.parameter.label();
        for (k, scenario) in self.scenarios().iter().enumerate() {
            let names: Vec<&str> = first.scenarios[k]
                .summaries
                .iter()
                .map(|(n, _)| *n)
                .collect();
            writeln!(
                f,
                "\n### Sweep `{}`, scenario `{}`: mean over {} seeds of the RMSE after {} s of {} s\n",
                self.parameter.name(),
                scenario.name(),
                first.options.seeds.len(),
                first.options.skip_s,
                first.options.duration_s
            )?;
            for (figure, get) in SWEEP_FIGURES {
                writeln!(f, "\n{figure}\n")?;
                writeln!(f, "| {label} | {} |", names.join(" | "))?;
                writeln!(f, "|---|{}", "---|".repeat(names.len()))?;
                for (value, results) in &self.points {
                    let r = &results.scenarios[k];
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
                    writeln!(f, "| {value} | {} |", cells.join(" | "))?;
                }
            }
            writeln!(f, "\ndelay RMSE (s) of the estimators that estimate it\n")?;
            // `oracle` is given the delay: its error is zero by construction.
            let summaries = &first.scenarios[k].summaries;
            let with_delay: Vec<usize> = summaries
                .iter()
                .enumerate()
                .filter(|(_, (n, s))| s.mean.delay_s.is_some() && *n != "oracle")
                .map(|(i, _)| i)
                .collect();
            let names: Vec<&str> = with_delay.iter().map(|&i| summaries[i].0).collect();
            writeln!(f, "| {label} | {} |", names.join(" | "))?;
            writeln!(f, "|---|{}", "---|".repeat(with_delay.len()))?;
            for (value, results) in &self.points {
                let cells: Vec<String> = with_delay
                    .iter()
                    .map(|&i| {
                        let s = &results.scenarios[k].summaries[i].1;
                        fmt_value(s.mean.delay_s.unwrap_or(f64::NAN))
                    })
                    .collect();
                writeln!(f, "| {value} | {} |", cells.join(" | "))?;
            }
        }
        writeln!(
            f,
            "\n(diverged): velocity RMSE above {DIVERGED_FACTOR}x the bound's on the same runs; \
             fail: no estimate after the convergence time, or no finite figure."
        )
    }
}
