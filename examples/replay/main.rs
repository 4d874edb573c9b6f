//! Replays a vehicle's log through the crate's estimators and scores them
//! against the log's onboard reference.
//!
//! ```text
//! cargo run --release --features replay --example replay -- \
//!     ../shared/data/ardupilot-log171 --from 75 --to 225 --estimator all --json out.json
//! cargo run --release --features replay --example replay -- \
//!     ../shared/data/ardupilot-log171/log171.bin --from 75 --to 225 --json out.json
//! ```
//!
//! Writes per-sample estimates (`--out`), a JSON summary per estimator
//! (`--json`: final delay, delay over time, RMS roll/pitch/yaw/velocity
//! differences from the reference, refused samples, skipped rows by kind),
//! and SVG plots (`--plots DIR`). See `docs/replay.md`.
//!
//! A front end: the replay is the library's `delaynav::replay::session`
//! (options, defaults from the log, the estimators, the JSON and the console
//! text); this file maps the flags to `ReplayOptions`, draws the progress
//! bars, prints, and plots (`plots.rs`).

mod plots;

use clap::Parser;
use delaynav::Estimate;
use delaynav::replay::config_file::config_to_toml;
use delaynav::replay::session::{
    EstimatorReport, ReplayObserver, ReplayOptions, ReplaySetup, select_estimators, table_header,
    write_delay_windows,
};
use delaynav::replay::{EstimateWriter, LogFormat, ReplayError};
use indicatif::{ProgressBar, ProgressStyle};
use std::error::Error;
use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

type Failure = Box<dyn Error>;

/// Replay a log through the estimators.
#[derive(Parser, Debug)]
#[command(name = "replay")]
struct Args {
    /// Log: an ArduPilot `.bin` or PX4 `.ulg` file (recognised by its first
    /// bytes), or a directory or files of CSVs. None: replay a simulated run
    /// (needs the `sim` feature).
    inputs: Vec<PathBuf>,
    /// Log layout: auto, csv (the crate's), ardupilot, px4, bin, ulg.
    #[arg(long, default_value = "auto")]
    format: String,
    /// Estimator to run: one of the registered names, or `all`.
    #[arg(long, default_value = "all")]
    estimator: String,
    /// Seconds added to every GPS receive time (the added-delay experiment).
    #[arg(long, default_value_t = 0.0)]
    add_gps_delay: f64,
    /// Add the delay only to the fixes received from this time on, seconds
    /// on the log's clock (default: from the start). Each estimator is then
    /// also replayed without the added delay, and the JSON reports how its
    /// delay estimate followed the step (`delay_step`): the time until it
    /// stays within 10 ms of its final value without the added delay plus
    /// the added delay.
    #[arg(long)]
    add_delay_from: Option<f64>,
    /// Start of the scored window, seconds on the log's clock (default: the
    /// take-off found in the log).
    #[arg(long)]
    from: Option<f64>,
    /// End of the replayed and scored window, seconds (default: the landing
    /// found in the log, cut 2 s before an impact).
    #[arg(long)]
    to: Option<f64>,
    /// Seconds replayed before `--from` so the estimators initialize and
    /// converge; not scored.
    #[arg(long, default_value_t = 30.0)]
    warmup: f64,
    /// Per-sample estimates CSV.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Summary JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// CSV of every delay-loop update (one correlation window): the fused
    /// estimate, its status and each axis' peak, for estimators with a loop.
    #[arg(long)]
    delay_windows: Option<PathBuf>,
    /// Directory for SVG plots.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Magnetic declination, degrees east (default: ArduPilot `COMPASS_DEC`
    /// when `COMPASS_AUTODEC = 0`, else the World Magnetic Model at the first
    /// fix and the log's date).
    #[arg(long)]
    declination_deg: Option<f64>,
    /// Magnetic inclination, degrees down (default: measured over the
    /// stationary segment, else the World Magnetic Model).
    #[arg(long)]
    inclination_deg: Option<f64>,
    /// Mounting trim roll, radians (default: ArduPilot `AHRS_TRIM_X` from params.csv, else 0).
    #[arg(long)]
    trim_roll_rad: Option<f64>,
    /// Mounting trim pitch, radians (default: ArduPilot `AHRS_TRIM_Y`, else 0).
    #[arg(long)]
    trim_pitch_rad: Option<f64>,
    /// ArduPilot: read the second IMU (`imu2.csv`); the same as `--imu-instance 1`.
    #[arg(long)]
    imu2: bool,
    /// Which IMU to read, 0 first: DataFlash `IMU` instance, ULog
    /// `sensor_combined` multi-id, ArduPilot CSV `imu.csv` (0) or `imu2.csv` (1).
    #[arg(long, default_value_t = 0)]
    imu_instance: u8,
    /// Accelerometer noise density of the filters, m/s^2/sqrt(Hz) (default:
    /// measured on the log, never below the filters' default; see
    /// `docs/replay.md`).
    #[arg(long)]
    accel_noise_density: Option<f64>,
    /// Gyro noise density of the filters, rad/s/sqrt(Hz) (default: as above).
    #[arg(long)]
    gyro_noise_density: Option<f64>,
    /// Accelerometer bias random walk, m/s^2/sqrt(s) (default: the filters').
    #[arg(long)]
    accel_bias_random_walk: Option<f64>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Navigator configuration (TOML, may be partial), merged over the one
    /// derived from the log; its `ekf` table configures every estimator.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Write the resolved configuration as TOML to stdout and exit.
    #[arg(long)]
    print_config: bool,
    /// Drop the log's magnetometer records: heading from the GPS velocity
    /// and the IMU alone (the navigator's yaw estimator).
    #[arg(long)]
    no_mag: bool,
}

impl Args {
    /// The library's options for these flags.
    fn options(&self) -> ReplayOptions {
        ReplayOptions {
            inputs: self.inputs.clone(),
            format: None,
            imu_instance: if self.imu2 { 1 } else { self.imu_instance },
            add_gps_delay_s: self.add_gps_delay,
            add_delay_from_s: self.add_delay_from,
            from_s: self.from,
            to_s: self.to,
            warmup_s: Some(self.warmup),
            fixed_window: false,
            declination_deg: self.declination_deg,
            inclination_deg: self.inclination_deg,
            trim_rad: [self.trim_roll_rad, self.trim_pitch_rad],
            accel_noise_density: self.accel_noise_density,
            gyro_noise_density: self.gyro_noise_density,
            accel_bias_random_walk: self.accel_bias_random_walk,
            config_file: self.config.clone(),
            no_mag: self.no_mag,
        }
    }
}

/// What the console and the files get while the estimators run: a progress
/// bar per pass, each estimate to `--out`, the attitude for `--plots`, each
/// estimator's table row.
struct Console<'a> {
    setup: &'a ReplaySetup,
    quiet: bool,
    bar: ProgressBar,
    estimates: Option<EstimateWriter<BufWriter<File>>>,
    /// `(estimator, [(t s, roll deg, pitch deg, yaw deg)])` at 10 Hz, for
    /// plots, aligned like the reference.
    attitude: Vec<(String, Vec<[f64; 4]>)>,
    keep_attitude: bool,
    /// The attitude of the pass under way.
    trace: Vec<[f64; 4]>,
    next_trace_us: u64,
}

impl ReplayObserver for Console<'_> {
    fn started(&mut self, estimator: &str, length_s: Option<u64>) {
        self.trace.clear();
        self.next_trace_us = 0;
        // indicatif draws to stderr, and nothing when it is not a terminal.
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
    ) -> Result<(), Box<dyn Error + Send + Sync>> {
        if let Some(w) = self.estimates.as_mut() {
            w.write(estimator, e)?;
        }
        if self.keep_attitude && e.t_us >= self.next_trace_us {
            let [roll, pitch, yaw] = self.setup.aligned_euler_deg(e);
            self.trace.push([e.t_us as f64 * 1e-6, roll, pitch, yaw]);
            self.next_trace_us = e.t_us + 100_000;
        }
        Ok(())
    }

    fn finished(&mut self) {
        self.bar.finish_and_clear();
    }

    fn report(&mut self, report: &EstimatorReport) {
        let trace = std::mem::take(&mut self.trace);
        self.attitude
            .push((report.estimator.name.to_string(), trace));
        println!("{}", report.table_row());
    }
}

/// With no log given: a simulated run written to a temporary directory.
#[cfg(feature = "sim")]
fn simulated_log(options: &mut ReplayOptions) -> Result<(), Failure> {
    let dir = std::env::temp_dir().join(format!("delaynav-replay-sim-{}", std::process::id()));
    let written = options.simulated_log(&dir)?;
    eprintln!(
        "no log given: replaying a simulated run ({written} samples) written to {}",
        dir.display()
    );
    Ok(())
}

#[cfg(not(feature = "sim"))]
fn simulated_log(_: &mut ReplayOptions) -> Result<(), Failure> {
    Err("no log given, and this build has no simulator to replay instead (feature `sim`).\n\
         Pass a log directory or files, e.g.\n  \
         cargo run --release --features replay --example replay -- ../shared/data/ardupilot-log171 --from 75 --to 225"
        .into())
}

/// The library's errors, the configuration file named by its flag.
fn flagged(e: ReplayError) -> Failure {
    match e {
        ReplayError::ConfigFile { path, source } => {
            format!("--config {}: {source}", path.display()).into()
        }
        e => e.into(),
    }
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("replay: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Failure> {
    let mut options = args.options();
    if args.inputs.is_empty() {
        simulated_log(&mut options)?;
    }
    let estimators = select_estimators(&args.estimator)?;
    options.format = LogFormat::parse_choice(&args.format)?;
    let setup = ReplaySetup::from_log(&options)?;
    for note in &setup.notes {
        eprintln!("{note}");
    }
    let setup = setup
        .with_config_file(options.config_file.as_deref())
        .map_err(flagged)?;
    if args.print_config {
        print!("{}", config_to_toml(&setup.nav)?);
        return Ok(());
    }
    let mut console = Console {
        setup: &setup,
        quiet: args.quiet,
        bar: ProgressBar::hidden(),
        estimates: match &args.out {
            Some(p) => Some(EstimateWriter::new(BufWriter::new(File::create(p)?))?),
            None => None,
        },
        attitude: Vec::new(),
        keep_attitude: args.plots.is_some(),
        trace: Vec::new(),
        next_trace_us: 0,
    };

    // The rows skipped are the same for every estimator: count them once.
    let scan = setup.scan()?;
    eprintln!("{}", setup.log_line(&scan));
    eprint!("{}", scan.skips);
    eprint!("{}", setup.derived);

    println!("{}", table_header());
    let report = setup.run(scan, &estimators, &mut console)?;
    print!("{}", report.delay_steps());
    if let Some(path) = &args.delay_windows {
        write_delay_windows(File::create(path)?, &report.estimators)?;
    }
    print!("{}", report.health());
    if let Some(w) = console.estimates.as_mut() {
        w.flush()?;
    }

    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&report.to_json())?)?;
        eprintln!("summary written to {}", path.display());
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir)?;
        let tracks: Vec<_> = report
            .estimators
            .iter()
            .map(|e| (e.estimator.name, e.summary.delay_track.as_slice()))
            .collect();
        plots::delay(&dir.join("delay.svg"), &tracks)?;
        let reference = setup.reference_attitude_deg()?;
        plots::attitude(dir, &console.attitude, reference.as_deref())?;
        eprintln!("plots written to {}", dir.display());
    }
    Ok(())
}
