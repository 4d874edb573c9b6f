//! The flags of `reproduce`, mapped to the suites' options by `main.rs` and
//! `delay_suite.rs`.

use super::delay_suite::DelayFlags;
use clap::{Parser, ValueEnum};
use delaynav::sim::suite::sweep::SweepParameter;
use std::path::PathBuf;

/// The sweeps (`sim::suite::sweep::SweepParameter`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SweepChoice {
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

impl From<SweepChoice> for SweepParameter {
    fn from(choice: SweepChoice) -> Self {
        match choice {
            SweepChoice::GpsRate => SweepParameter::GpsRate,
            SweepChoice::ImuRate => SweepParameter::ImuRate,
            SweepChoice::Delay => SweepParameter::Delay,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScenarioChoice {
    Low,
    High,
    All,
}

/// Reproduce the paper's simulation tables on the crate's simulator.
#[derive(Debug, Parser)]
#[command(version, about)]
pub struct Args {
    /// Which acceleration scenario to run.
    #[arg(long, value_enum, default_value = "all")]
    pub scenario: ScenarioChoice,
    /// Number of seeds per scenario [default: 5, quick: 2]. With --faults: the suite on
    /// seeds S..S+N, a row passing on more than half of them [default: seed S alone].
    #[arg(long)]
    pub seeds: Option<u64>,
    /// First seed; the run uses seeds S, S+1, ...
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Length of each run, seconds [default: 60, quick: 20].
    #[arg(long)]
    pub duration: Option<f64>,
    /// True GPS delay, seconds (constant) [default: 0.2, Table 3's maximum].
    #[arg(long)]
    pub delay: Option<f64>,
    /// Convergence time not scored, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub skip: f64,
    /// Where to write the JSON results.
    #[arg(long, default_value = "target/reproduce/results.json")]
    pub json: PathBuf,
    /// Where to write the SVG plots [default: target/reproduce, none with --quick].
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// A short run for CI and tests (2 seeds of 20 s, no plots unless --plots).
    #[arg(long)]
    pub quick: bool,
    /// Also write each scenario's first-seed run as a CSV log under
    /// DIR/<scenario>-seed<S>/; with --delay-trace, the trace's CSV file.
    #[arg(long, value_name = "DIR|FILE")]
    pub csv: Option<PathBuf>,
    /// Start `proposed` and `aekf17` from the fixed 0.1 s instead of an
    /// offline calibration on a separate run (sec. 2.2.2).
    #[arg(long)]
    pub no_calibration: bool,
    /// Seeds run in parallel [default: the machine's available parallelism].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Run a sweep instead of the tables: every estimator and the bound
    /// against one parameter (a table and a plot per scenario).
    #[arg(long, value_enum)]
    pub sweep: Option<SweepChoice>,
    /// Run the fault suite of issue 10 instead (`--duration` scales its 60 s runs).
    #[arg(long)]
    pub faults: bool,
    /// Run the integrity suite instead (`delaynav::sim::suite::integrity`): protection levels
    /// against the errors under faults and on clean runs (`--seeds`, default 3, from
    /// `--seed`; `--duration` scales its 60 s runs); writes `integrity` to the JSON file.
    #[arg(long)]
    pub integrity: bool,
    /// Write every 50 ms of one integrity-suite run as CSV to --csv [default:
    /// target/integrity-trace/RUN.csv]: the run named as the suite's progress names it, e.g.
    /// "high seed 5 proposed reset_inflight", with `--seed`/`--seeds` as in the suite run it
    /// comes from (the delay's start is calibrated on the first seed).
    #[arg(long, value_name = "RUN")]
    pub integrity_trace: Option<String>,
    /// Run the delay suite of issue 11 instead (`delaynav::sim::suite::delay`); writes
    /// `delay_scenarios` to the JSON file.
    #[arg(long)]
    pub delay_suite: bool,
    /// The delay suite's and the traces' flags.
    #[command(flatten)]
    pub delay_flags: DelayFlags,
    /// Run only the bound study instead of the tables: the bound with each
    /// difference to the estimators in turn, beside `oracle` and `proposed`.
    #[arg(long)]
    pub bound_study: bool,
    /// Prediction rate of the navigator's horizon filter, Hz; 0 predicts at
    /// every IMU sample [default: `DelayCompensatedNavConfig`'s].
    #[arg(long)]
    pub filter_rate_hz: Option<f64>,
    /// With the default run, --faults, --integrity or --delay-suite: print every verdict
    /// and exit non-zero when one fails or a figure is NaN (`delaynav::sim::suite::check`).
    #[arg(long)]
    pub check: bool,
    /// With --check: rows that fail for a known reason, printed as
    /// `FAIL (known)`; naming a row that does not exist or passes fails.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ROW,...",
        requires = "check"
    )]
    pub known_failures: Vec<String>,
}
