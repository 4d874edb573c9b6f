//! `delaynav simulate` and `delaynav suite`: the simulator's runs and the
//! suites that define what the crate promises, all in the library
//! (`delaynav::sim::suite`); this maps the flags to their options, shows
//! their progress, prints their text, writes their JSON and judges their
//! verdicts (`--check`).

use crate::Failure;
use crate::args::{duration_s, rate_hz, sim_delay_s};
use crate::replay::write_json;
use clap::{Args, ValueEnum};
use delaynav::sim::Scenario;
use delaynav::sim::suite::check::{Verdict, judge};
use delaynav::sim::suite::delay::{self, DelayOptions, ROW_NAMES};
use delaynav::sim::suite::faults::{self, FaultsOptions};
use delaynav::sim::suite::sweep::{self, SweepOptions, SweepParameter};
use delaynav::sim::suite::tables::{self, TablesOptions};
use delaynav::sim::suite::{Progress, ProgressFn};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

/// The acceleration scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScenarioChoice {
    /// The paper's low-acceleration scenario.
    Low,
    /// The high-acceleration scenario.
    High,
    /// Both.
    All,
}

/// Flags of `simulate`: the paper's simulated experiments (Tables 5 and 6).
#[derive(Debug, Clone, Args)]
pub struct SimulateArgs {
    /// Which acceleration scenario to run.
    #[arg(long, value_enum, default_value = "all")]
    pub scenario: ScenarioChoice,
    /// Seeds per scenario, 1 to 1000.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub seeds: u64,
    /// First seed; the run uses seeds S, S+1, ...
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Length of each run, seconds (above 0; must exceed --skip).
    #[arg(long, value_name = "S", default_value_t = 60.0, value_parser = duration_s)]
    pub duration: f64,
    /// True GPS delay, seconds, 0 to 2 (default: 0.2, Table 3's maximum).
    #[arg(long, value_name = "S", value_parser = sim_delay_s)]
    pub delay: Option<f64>,
    /// Convergence time not scored, seconds.
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = crate::args::warmup_s)]
    pub skip: f64,
    /// Start the delay loops from a fixed 0.1 s instead of an offline
    /// calibration on a separate run.
    #[arg(long)]
    pub no_calibration: bool,
    /// Prediction rate of the navigator's horizon filter, Hz (0: every IMU
    /// sample).
    #[arg(long, value_name = "HZ", value_parser = rate_hz)]
    pub filter_rate_hz: Option<f64>,
    /// Write the results as JSON to this file.
    #[arg(
        long,
        value_name = "PATH",
        default_value = "target/simulate/results.json"
    )]
    pub json: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The suites.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SuiteName {
    /// The paper's tables with their verdicts (what `simulate` runs).
    Tables,
    /// Every injected fault, how it is handled (docs/faults.md).
    Faults,
    /// The delay loop's scenarios (docs/delay.md).
    Delay,
    /// GPS rate sweep.
    SweepGpsRate,
    /// IMU rate sweep.
    SweepImuRate,
    /// True delay sweep.
    SweepDelay,
}

/// Flags of `suite`.
#[derive(Debug, Clone, Args)]
pub struct SuiteArgs {
    /// Which suite.
    #[arg(value_enum)]
    pub name: SuiteName,
    /// Seeds (tables, sweeps, delay suite), 1 to 1000.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub seeds: u64,
    /// First seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The delay suite: only these rows (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "ROW,...")]
    pub rows: Option<Vec<String>>,
    /// The fault suite: length of its runs, seconds (they are 60 s).
    #[arg(long, value_name = "S", default_value_t = 60.0, value_parser = duration_s)]
    pub duration: f64,
    /// Print every verdict and exit 1 when one fails or a figure is NaN.
    #[arg(long)]
    pub check: bool,
    /// With --check: rows that fail for a known reason.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ROW,...",
        requires = "check"
    )]
    pub known_failures: Vec<String>,
    /// Write the suite's JSON document to this file.
    #[arg(long, value_name = "PATH", default_value = "target/suite/results.json")]
    pub json: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// The suites' progress on stderr, a bar below the lines on a terminal.
struct Reporter {
    bar: ProgressBar,
}

impl Reporter {
    fn new(quiet: bool) -> Self {
        let bar = if quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(0)
        };
        if let Ok(style) = ProgressStyle::with_template("[{wide_bar}] {pos}/{len} ({eta} left)") {
            bar.set_style(style);
        }
        Self { bar }
    }

    fn report(&self, progress: Progress) {
        if let Progress::Step { done, total, .. } = &progress {
            self.bar.set_length(*total as u64);
            self.bar.set_position(*done as u64);
        }
        if !self.bar.is_hidden() {
            self.bar.suspend(|| eprintln!("{progress}"));
        }
    }
}

impl Drop for Reporter {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// `--check`: every verdict printed; an error when the run fails.
fn enforce(verdicts: &[Verdict], known: &[String]) -> Result<(), Failure> {
    let judgement = judge(verdicts, known);
    eprint!("{judgement}");
    judgement
        .failure()
        .map_or(Ok(()), |reason| Err(reason.into()))
}

fn tables_options(
    scenario: ScenarioChoice,
    seed: u64,
    seeds: u64,
    duration_s: f64,
    skip_s: f64,
) -> Result<TablesOptions, Failure> {
    if duration_s <= skip_s {
        return Err(crate::args::usage(format!(
            "invalid value '{duration_s}' for '--duration <S>': must exceed --skip ({skip_s} s)"
        )));
    }
    Ok(TablesOptions {
        scenarios: match scenario {
            ScenarioChoice::Low => vec![Scenario::Low],
            ScenarioChoice::High => vec![Scenario::High],
            ScenarioChoice::All => Scenario::ALL.to_vec(),
        },
        seeds: (seed..seed + seeds).collect(),
        duration_s,
        skip_s,
        ..TablesOptions::default()
    })
}

/// `delaynav simulate`.
pub fn simulate(args: &SimulateArgs) -> Result<(), Failure> {
    let mut options = tables_options(
        args.scenario,
        args.seed,
        args.seeds,
        args.duration,
        args.skip,
    )?;
    options.delay_s = args.delay;
    options.calibrated = !args.no_calibration;
    options.filter_rate_hz = args.filter_rate_hz;
    let reporter = Reporter::new(args.quiet);
    let progress = |p: Progress| reporter.report(p);
    let result = tables::run(&options, &tables::estimators(), &progress)?;
    drop(reporter);
    print!("{result}");
    write_json(&args.json, &result.to_json())?;
    eprintln!("wrote {}", args.json.display());
    Ok(())
}

/// `delaynav suite`.
pub fn suite(args: &SuiteArgs) -> Result<(), Failure> {
    let reporter = Reporter::new(args.quiet);
    let progress = |p: Progress| reporter.report(p);
    let progress: ProgressFn = &progress;
    let (json, verdicts) = match args.name {
        SuiteName::Tables => {
            let options = tables_options(ScenarioChoice::All, args.seed, args.seeds, 60.0, 10.0)?;
            let result = tables::run(&options, &tables::estimators(), progress)?;
            print!("{result}");
            (result.to_json(), result.verdicts())
        }
        SuiteName::Faults => {
            let options = FaultsOptions {
                seed: args.seed,
                scale: args.duration / 60.0,
                ..FaultsOptions::default()
            };
            let result = faults::run(&options, progress)?;
            print!("{result}");
            (result.to_json(), result.verdicts())
        }
        SuiteName::Delay => {
            let mut options = DelayOptions::full(args.seed, args.seeds);
            if let Some(names) = &args.rows {
                if let Some(n) = names.iter().find(|n| delay::row_name(n).is_none()) {
                    return Err(crate::args::usage(format!(
                        "invalid value '{n}' for '--rows <ROW,...>': rows are {}",
                        ROW_NAMES.join(", ")
                    )));
                }
                options.rows = Some(names.clone());
            }
            let result = delay::run(&options, progress)?;
            for row in &result.rows {
                println!("{row}");
            }
            (result.to_json(), result.verdicts())
        }
        SuiteName::SweepGpsRate | SuiteName::SweepImuRate | SuiteName::SweepDelay => {
            let parameter = match args.name {
                SuiteName::SweepGpsRate => SweepParameter::GpsRate,
                SuiteName::SweepImuRate => SweepParameter::ImuRate,
                _ => SweepParameter::Delay,
            };
            let options = SweepOptions {
                parameter,
                tables: tables_options(ScenarioChoice::All, args.seed, args.seeds, 60.0, 10.0)?,
            };
            let result = sweep::run(&options, &tables::estimators(), progress)?;
            print!("{result}");
            (result.to_json(), Vec::new())
        }
    };
    drop(reporter);
    write_json(&args.json, &json)?;
    eprintln!("wrote {}", args.json.display());
    if args.check {
        enforce(&verdicts, &args.known_failures)?;
    }
    Ok(())
}
