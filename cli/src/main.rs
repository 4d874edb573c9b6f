//! `delaynav`: replay a flight log through the crate's estimators, calibrate
//! its GPS delay, write a flight report, run a folder of logs, run the
//! simulator's suites. A front end: the work is the library's
//! (`delaynav::replay::session`, `delaynav::delay::OfflineCalibrator`,
//! `delaynav::sim::suite`). See `docs/cli.md`.
//!
//! Exit codes: 0 done; 1 the work failed (a log that cannot be read, a
//! suite's verdict with `--check`); 2 a bad command line (a number out of
//! its range, a window outside the log, a bad configuration file).

mod args;
mod batch;
mod calibrate;
mod replay;
mod report;
mod suite;
mod svg;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// An error of a subcommand.
pub type Failure = Box<dyn std::error::Error>;

const REPLAY_EXAMPLES: &str = "\
Examples:
  delaynav replay log171.bin
  delaynav replay log171.bin --from 90 --to 220 --json summary.json
  delaynav replay log171.bin --add-gps-delay 0.2 --add-delay-from 150 --estimator proposed";

const CALIBRATE_EXAMPLES: &str = "\
Examples:
  delaynav calibrate log171.bin
  delaynav calibrate flight42/ --from 100 --to 400 --json calibration.json";

const REPORT_EXAMPLES: &str = "\
Examples:
  delaynav report log171.bin -o target/report.html
  delaynav report flight42/ --from 100 --to 400 -o flight42.html --json flight42.json";

const BATCH_EXAMPLES: &str = "\
Examples:
  delaynav batch ../shared/data --json table.json --csv table.csv
  delaynav batch logs/ --jobs 4 --quiet > table.csv";

const SIMULATE_EXAMPLES: &str = "\
Examples:
  delaynav simulate                        # both scenarios, 5 seeds, every estimator
  delaynav simulate --scenario low --seeds 2 --duration 20 --json target/quick.json";

const SUITE_EXAMPLES: &str = "\
Examples:
  delaynav suite faults --check --json target/faults.json
  delaynav suite delay --rows gps_2hz,delay_step --json target/delay.json
  delaynav suite sweep-gps-rate --seeds 2";

/// GPS/IMU navigation with the GPS delay estimated online: replay a flight
/// log, calibrate its delay, read its flight report, run the simulator's
/// suites.
#[derive(Debug, Parser)]
#[command(name = "delaynav", version, propagate_version = true)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  delaynav report log171.bin -o report.html    # the flight report: open it in a browser
  delaynav replay log171.bin --json summary.json
  delaynav batch logs/ --json table.json --csv table.csv
  delaynav <COMMAND> --help                    # each command's flags and examples"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Replay a log through the estimators and score them against the log's
    /// onboard solution: a table, `--json` for machines.
    #[command(after_help = REPLAY_EXAMPLES, allow_negative_numbers = true)]
    Replay(replay::ReplayArgs),
    /// Replay a log and write its flight report: one self-contained HTML
    /// page (attitude against the onboard solution, delay, innovations,
    /// health, track, defaults, window, warnings).
    #[command(after_help = REPORT_EXAMPLES, allow_negative_numbers = true)]
    Report(report::ReportArgs),
    /// The offline delay calibration of a log: the delay, the peak
    /// correlation, the correlation curve.
    #[command(after_help = CALIBRATE_EXAMPLES, allow_negative_numbers = true)]
    Calibrate(calibrate::CalibrateArgs),
    /// Replay every log under a folder (`.bin`, `.ulg`, CSV folders) in
    /// parallel: one row per log (CSV on stdout, `--csv`, `--json`); a log
    /// that fails to read is a row with its error.
    #[command(after_help = BATCH_EXAMPLES)]
    Batch(batch::BatchArgs),
    /// The paper's simulated experiments: every estimator on both scenarios.
    #[command(after_help = SIMULATE_EXAMPLES)]
    Simulate(suite::SimulateArgs),
    /// A suite of the simulator with its verdicts (`--check` enforces them).
    #[command(after_help = SUITE_EXAMPLES)]
    Suite(suite::SuiteArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match &cli.command {
        Command::Replay(a) => replay::main(a),
        Command::Report(a) => report::main(a),
        Command::Calibrate(a) => calibrate::main(a),
        Command::Batch(a) => batch::main(a),
        Command::Simulate(a) => suite::simulate(a),
        Command::Suite(a) => suite::suite(a),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<args::UsageError>() => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}
