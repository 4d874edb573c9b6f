//! `delaynav replay`: the library's replay (`delaynav::replay::session`)
//! with a progress bar, the console table and `--json`; also the runner
//! `report` and `batch` build on.

use crate::Failure;
use crate::args::{LogArgs, LogSpan, check_against_log, usage};
use clap::Args;
use delaynav::Estimate;
use delaynav::replay::config_file::config_to_toml;
use delaynav::replay::session::{
    EstimatorReport, LogScan, ReplayObserver, ReplayReport, ReplaySetup, select_estimators,
    table_header, write_delay_windows,
};
use delaynav::replay::{EstimateWriter, LogReader, ReplayError, SensorEvent};
use indicatif::{ProgressBar, ProgressStyle};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Flags of `replay`.
#[derive(Debug, Clone, Args)]
pub struct ReplayArgs {
    #[command(flatten)]
    pub log: LogArgs,
    /// Estimator to run: proposed, aekf17, ekf16, or all.
    #[arg(long, default_value = "all")]
    pub estimator: String,
    /// Write the summary as JSON to this file.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write every estimate to this CSV file.
    #[arg(long, value_name = "PATH")]
    pub out: Option<PathBuf>,
    /// Write every delay-loop update (one correlation window) to this CSV.
    #[arg(long, value_name = "PATH")]
    pub delay_windows: Option<PathBuf>,
    /// Print the resolved configuration as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
}

/// The library's errors, those of the command line as usage errors (exit
/// 2): the configuration file (its path, key, value and bound), a bad added
/// delay.
pub fn flagged(e: ReplayError) -> Failure {
    match e {
        ReplayError::ConfigFile { path, source } => {
            usage(format!("--config {}: {source}", path.display()))
        }
        e @ ReplayError::InvalidSeconds { .. } => usage(e.to_string()),
        e => e.into(),
    }
}

/// What the console and the report get while the estimators run.
pub struct Console {
    quiet: bool,
    bar: ProgressBar,
    /// Each estimator's table row printed as it completes.
    pub print_rows: bool,
    estimates: Option<EstimateWriter<BufWriter<File>>>,
    /// `(estimator, [(t s, estimate)])` at 10 Hz when kept.
    pub traces: Vec<(String, Vec<Estimate<f64>>)>,
    keep_traces: bool,
    trace: Vec<Estimate<f64>>,
    next_trace_us: u64,
}

impl Console {
    /// A console; `keep_traces` keeps every estimator's estimates at 10 Hz.
    pub fn new(quiet: bool, keep_traces: bool) -> Self {
        Self {
            quiet,
            bar: ProgressBar::hidden(),
            print_rows: false,
            estimates: None,
            traces: Vec::new(),
            keep_traces,
            trace: Vec::new(),
            next_trace_us: 0,
        }
    }
}

impl ReplayObserver for Console {
    fn started(&mut self, estimator: &str, length_s: Option<u64>) {
        self.trace.clear();
        self.next_trace_us = 0;
        self.bar = if self.quiet {
            ProgressBar::hidden()
        } else if let Some(length) = length_s {
            let bar = ProgressBar::new(length);
            if let Ok(style) =
                ProgressStyle::with_template("{prefix:>9} [{wide_bar}] {pos}/{len} s of log")
            {
                bar.set_style(style);
            }
            bar.with_prefix(estimator.to_string())
        } else {
            ProgressBar::new_spinner().with_prefix(estimator.to_string())
        };
    }

    fn progress(&mut self, replayed_s: u64) {
        self.bar.set_position(replayed_s);
    }

    fn estimate(
        &mut self,
        estimator: &str,
        e: &Estimate<f64>,
    ) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        if let Some(w) = self.estimates.as_mut() {
            w.write(estimator, e)?;
        }
        if self.keep_traces && e.t_us >= self.next_trace_us {
            self.trace.push(*e);
            self.next_trace_us = e.t_us + 100_000;
        }
        Ok(())
    }

    fn finished(&mut self) {
        self.bar.finish_and_clear();
    }

    fn report(&mut self, report: &EstimatorReport) {
        let trace = std::mem::take(&mut self.trace);
        self.traces.push((report.estimator.name.to_string(), trace));
        if self.print_rows {
            println!("{}", report.table_row());
        }
    }
}

/// The log read once: its records and skipped rows, and the span of its
/// IMU samples.
pub fn scan(setup: &ReplaySetup) -> Result<(LogScan, Option<LogSpan>), ReplayError> {
    let mut reader = LogReader::<f64>::open(&setup.files, &setup.reader)?;
    let mut span: Option<LogSpan> = None;
    for event in reader.by_ref() {
        if let SensorEvent::Imu(imu) = event {
            let t = imu.t_us as f64 * 1e-6;
            let s = span.get_or_insert(LogSpan {
                first_s: t,
                last_s: t,
            });
            s.last_s = t;
        }
    }
    Ok((
        LogScan {
            skips: reader.skip_counts().clone(),
            counts: reader.stream_counts(),
        },
        span,
    ))
}

/// A log opened and checked: the setup (configuration file merged), its
/// scan, and the window's checks against the log done.
pub struct Opened {
    /// The replay's setup.
    pub setup: ReplaySetup,
    /// The log's records and skipped rows.
    pub scan: LogScan,
}

/// Opens the log of `args`, derives the setup, merges `--config`, and
/// checks the times given against the log.
pub fn open(args: &LogArgs, print_notes: bool) -> Result<Opened, Failure> {
    let options = args.options()?;
    let setup = ReplaySetup::from_log(&options).map_err(flagged)?;
    if print_notes {
        for note in &setup.notes {
            eprintln!("{note}");
        }
    }
    let setup = setup
        .with_config_file(options.config_file.as_deref())
        .map_err(flagged)?;
    let (scan, span) = scan(&setup)?;
    if let Some(span) = span {
        let s = |t: Option<u64>| t.map(|t| t as f64 * 1e-6);
        check_against_log(
            args,
            span,
            (s(setup.run.score_from_us), s(setup.run.end_us)),
        )?;
    }
    Ok(Opened { setup, scan })
}

/// Runs `estimators` on an opened log.
pub fn run(
    opened: Opened,
    estimator: &str,
    console: &mut Console,
) -> Result<ReplayReport, Failure> {
    let estimators = select_estimators(estimator).map_err(|e| usage(e.to_string()))?;
    Ok(opened.setup.run(opened.scan, &estimators, console)?)
}

/// Writes `json` pretty-printed to `path`, its folder created.
pub fn write_json(path: &Path, json: &serde_json::Value) -> Result<(), Failure> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    std::fs::write(path, serde_json::to_string_pretty(json)? + "\n")?;
    Ok(())
}

/// `delaynav replay`.
pub fn main(args: &ReplayArgs) -> Result<(), Failure> {
    let opened = open(&args.log, true)?;
    if args.print_config {
        print!("{}", config_to_toml(&opened.setup.nav)?);
        return Ok(());
    }
    eprintln!("{}", opened.setup.log_line(&opened.scan));
    eprint!("{}", opened.scan.skips);
    eprint!("{}", opened.setup.derived);
    let mut console = Console::new(args.log.quiet, false);
    console.print_rows = true;
    if let Some(p) = &args.out {
        console.estimates = Some(EstimateWriter::new(BufWriter::new(File::create(p)?))?);
    }
    println!("{}", table_header());
    let report = run(opened, &args.estimator, &mut console)?;
    print!("{}", report.delay_steps());
    print!("{}{}", report.health(), report.integrity());
    if let Some(w) = console.estimates.as_mut() {
        w.flush()?;
    }
    if let Some(path) = &args.delay_windows {
        write_delay_windows(File::create(path)?, &report.estimators)?;
    }
    if let Some(path) = &args.json {
        write_json(path, &report.to_json())?;
        eprintln!("summary written to {}", path.display());
    }
    Ok(())
}
