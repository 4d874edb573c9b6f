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

mod config_file;
mod plots;

use clap::Parser;
use delaynav::replay::{
    ArduPilotImu, EstimateWriter, LogFiles, LogFormat, LogReader, ReaderOptions,
    ReferenceAlignment, ReferenceReader, RunOptions, RunSummary, SkipCounts, SkipKind, ardupilot,
    dataflash::DataFlashLog, flight_window, inclination_at_rest, replay,
};
use delaynav::{
    Aekf17Config, AugmentedEkf17, DelayCompensatedNav, Ekf16, Ekf16Config, Estimate, NavConfig,
    Navigator,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{Value, json};
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
    /// Start of the scored window, seconds on the log's clock (default: the
    /// take-off found in the log).
    #[arg(long)]
    from: Option<f64>,
    /// End of the replayed and scored window, seconds (default: the landing
    /// found in the log, cut 2 s before an impact).
    #[arg(long)]
    to: Option<f64>,
    /// Set for the simulated run: its window is fixed, not found.
    #[arg(skip)]
    simulated: bool,
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
    /// Directory for SVG plots.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// Magnetic declination, degrees east (default: ArduPilot `COMPASS_DEC`
    /// when `COMPASS_AUTODEC = 0`, else log171's measured +11.8; 0 for other layouts).
    #[arg(long)]
    declination_deg: Option<f64>,
    /// Magnetic inclination, degrees down (default: measured over the log's first 10 s at rest).
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
    /// ArduPilot logs log171's measured in-flight value, others the paper's
    /// Table 3; see `docs/replay.md`).
    #[arg(long)]
    accel_noise_density: Option<f64>,
    /// Gyro noise density of the filters, rad/s/sqrt(Hz) (default: as above).
    #[arg(long)]
    gyro_noise_density: Option<f64>,
    /// Accelerometer bias random walk, m/s^2/sqrt(s) (default: the filters').
    #[arg(long)]
    accel_bias_random_walk: Option<f64>,
    /// Navigator configuration (TOML, may be partial), merged over the one
    /// derived from the log; its `ekf` table configures every estimator.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Write the resolved configuration as TOML to stdout and exit.
    #[arg(long)]
    print_config: bool,
}

/// One estimator the replay can run. Adding one is one entry here.
struct Registered {
    name: &'static str,
    about: &'static str,
    run: fn(&Setup, &mut Outputs) -> Result<RunSummary, Failure>,
}

const ESTIMATORS: &[Registered] = &[
    Registered {
        name: "proposed",
        about: "delay-compensated navigator: delay loop, delayed-horizon EKF, forward reckoning",
        run: |setup, out| {
            run_one(
                setup,
                out,
                "proposed",
                &mut DelayCompensatedNav::<f64>::new(setup.nav)?,
            )
        },
    },
    Registered {
        name: "aekf17",
        about: "17-state augmented EKF with the delay as a state (the paper's baseline)",
        run: |setup, out| {
            let config = Aekf17Config::with_nav(setup.ekf16_config());
            run_one(setup, out, "aekf17", &mut AugmentedEkf17::new(config)?)
        },
    },
    Registered {
        name: "ekf16",
        about: "16-state EKF, GPS fused as if current (no delay handling)",
        run: |setup, out| run_one(setup, out, "ekf16", &mut Ekf16::new(setup.ekf16_config())?),
    },
];

/// The names `--estimator` understands, including those not built yet.
const PLANNED: [&str; 3] = ["proposed", "aekf17", "ekf16"];

/// Everything fixed for one replay, shared by the estimators.
struct Setup {
    files: LogFiles,
    reader: ReaderOptions,
    run: RunOptions,
    declination_rad: f64,
    inclination_rad: f64,
    /// Median IMU rate over the log's first 10 s, Hz.
    imu_rate_hz: f64,
    /// The filters' IMU noise model for this log.
    imu_noise: ImuNoise,
    /// The navigator's configuration: the log's, with `--config` merged over it.
    nav: NavConfig<f64>,
}

/// The filters' IMU noise model (continuous-time densities, see `Ekf16Config`).
#[derive(Debug, Clone, Copy)]
struct ImuNoise {
    accel_noise_density: f64,
    gyro_noise_density: f64,
    accel_bias_random_walk: f64,
}

impl Setup {
    /// The navigation filter's configuration: every estimator builds on it.
    fn ekf16_config(&self) -> Ekf16Config<f64> {
        self.nav.ekf
    }

    /// The navigator's configuration for this log: defaults with the log's
    /// IMU rate, IMU noise and magnetic field.
    fn log_config(&self) -> NavConfig<f64> {
        NavConfig {
            ekf: Ekf16Config {
                mag_inclination_rad: self.inclination_rad,
                mag_declination_rad: self.declination_rad,
                accel_noise_density: self.imu_noise.accel_noise_density,
                gyro_noise_density: self.imu_noise.gyro_noise_density,
                accel_bias_random_walk: self.imu_noise.accel_bias_random_walk,
                ..Ekf16Config::default()
            },
            imu_rate_hz: self.imu_rate_hz,
            ..NavConfig::default()
        }
    }

    /// Merges the `--config` file over [`Self::log_config`] and makes the
    /// figures reported beside the results follow it.
    fn with_config_file(mut self, path: Option<&std::path::Path>) -> Result<Self, Failure> {
        self.nav = config_file::resolve(self.log_config(), path)?;
        let ekf = self.nav.ekf;
        self.imu_rate_hz = self.nav.imu_rate_hz;
        self.declination_rad = ekf.mag_declination_rad;
        self.inclination_rad = ekf.mag_inclination_rad;
        self.run.estimator_declination_rad = ekf.mag_declination_rad;
        self.imu_noise = ImuNoise {
            accel_noise_density: ekf.accel_noise_density,
            gyro_noise_density: ekf.gyro_noise_density,
            accel_bias_random_walk: ekf.accel_bias_random_walk,
        };
        Ok(self)
    }
}

/// Median IMU rate, Hz, over the first `window_us` of a log.
fn imu_rate_hz(events: LogReader<f64>, window_us: u64) -> Option<f64> {
    let times: Vec<u64> = events
        .filter(|e| matches!(e, delaynav::replay::SensorEvent::Imu(_)))
        .map(|e| e.time_us())
        .take_while({
            let mut first = None;
            move |&t| t <= *first.get_or_insert(t) + window_us
        })
        .collect();
    let mut steps: Vec<u64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_unstable();
    steps.get(steps.len() / 2).map(|&dt| 1e6 / dt as f64)
}

/// Per-sample outputs shared across estimators.
struct Outputs {
    estimates: Option<EstimateWriter<BufWriter<File>>>,
    /// `(estimator, [(t s, roll deg, pitch deg, yaw deg)])` at 10 Hz, for
    /// plots, aligned like the reference.
    attitude: Vec<(String, Vec<[f64; 4]>)>,
    keep_attitude: bool,
}

fn run_one<N: Navigator<f64>>(
    setup: &Setup,
    out: &mut Outputs,
    name: &str,
    nav: &mut N,
) -> Result<RunSummary, Failure> {
    let events = LogReader::<f64>::open(&setup.files, &setup.reader)?;
    let reference = ReferenceReader::open(&setup.files)?;
    let start_us = setup.run.start_us.unwrap_or(0);
    let progress = progress_bar(name, setup);
    let mut trace = Vec::new();
    let mut next_trace_us = 0;
    let mut write_error = None;
    let summary = replay(nav, events, reference, &setup.run, |e: &Estimate<f64>| {
        progress.set_position(e.t_us.saturating_sub(start_us) / 1_000_000);
        if let Some(w) = out.estimates.as_mut()
            && let Err(err) = w.write(name, e)
        {
            write_error.get_or_insert(err);
        }
        if out.keep_attitude && e.t_us >= next_trace_us {
            // Plotted as the reference reports attitude (trim and declination applied).
            let aligned = setup
                .run
                .alignment
                .align_estimate(&e.attitude, setup.run.estimator_declination_rad);
            let euler =
                delaynav::geo::euler_from_quaternion(aligned.quaternion()).map(f64::to_degrees);
            trace.push([e.t_us as f64 * 1e-6, euler.x, euler.y, euler.z]);
            next_trace_us = e.t_us + 100_000;
        }
    });
    progress.finish_and_clear();
    if let Some(err) = write_error {
        return Err(err.into());
    }
    out.attitude.push((name.to_string(), trace));
    Ok(summary)
}

fn progress_bar(name: &str, setup: &Setup) -> ProgressBar {
    let (start, end) = (setup.run.start_us.unwrap_or(0), setup.run.end_us);
    let Some(end) = end else {
        return ProgressBar::new_spinner().with_prefix(name.to_string());
    };
    let bar = ProgressBar::new(end.saturating_sub(start) / 1_000_000);
    if let Ok(style) = ProgressStyle::with_template("{prefix:>9} [{wide_bar}] {pos}/{len} s of log")
    {
        bar.set_style(style);
    }
    bar.with_prefix(name.to_string())
}

fn seconds_to_us(s: f64) -> u64 {
    (s.max(0.0) * 1e6).round() as u64
}

fn setup(args: &Args) -> Result<Setup, Failure> {
    let imu_instance = if args.imu2 { 1 } else { args.imu_instance };
    let reader = ReaderOptions {
        gps_delay_added_us: seconds_to_us(args.add_gps_delay),
        ardupilot_imu: match imu_instance {
            0 => ArduPilotImu::First,
            _ => ArduPilotImu::Second,
        },
        imu_instance,
        ..ReaderOptions::default()
    };
    let files = LogFiles::locate(
        &args.inputs,
        LogFormat::parse_choice(&args.format)?,
        &reader,
    )?;

    if files.format == LogFormat::ArduPilot && imu_instance > 1 {
        return Err(format!(
            "IMU instance {imu_instance}: the ArduPilot CSV layout has imu.csv (0) and imu2.csv (1)"
        )
        .into());
    }
    let ardupilot_layout = matches!(files.format, LogFormat::ArduPilot | LogFormat::DataFlash);
    let mut alignment = ReferenceAlignment::default();
    let params = match (&files.params, files.format) {
        (Some(path), LogFormat::DataFlash) => Some(DataFlashLog::open(path)?.params()),
        (Some(path), LogFormat::ArduPilot) => {
            Some(ardupilot::read_params(path, &mut SkipCounts::default())?)
        }
        _ => None,
    };
    if let Some(values) = &params {
        alignment =
            ardupilot::alignment_from_params(values, ardupilot::LOG171_ALIGNMENT.declination_rad);
    }
    if let Some(d) = args.declination_deg {
        alignment.declination_rad = d.to_radians();
    }
    alignment.trim_roll_rad = args.trim_roll_rad.unwrap_or(alignment.trim_roll_rad);
    alignment.trim_pitch_rad = args.trim_pitch_rad.unwrap_or(alignment.trim_pitch_rad);

    let inclination_rad = match args.inclination_deg {
        Some(i) => i.to_radians(),
        None => {
            inclination_at_rest(LogReader::<f64>::open(&files, &reader)?, 10_000_000).unwrap_or(0.0)
        }
    };
    let imu_rate_hz = imu_rate_hz(LogReader::open(&files, &reader)?, 10_000_000).unwrap_or(1000.0);
    // Per log: ArduPilot's 50 Hz logged IMU has log171's measured in-flight
    // noise (docs/replay.md); other layouts keep the paper's Table 3.
    let defaults = if ardupilot_layout {
        ardupilot::with_log171_imu_noise(Ekf16Config::<f64>::default())
    } else {
        Ekf16Config::default()
    };
    let imu_noise = ImuNoise {
        accel_noise_density: args
            .accel_noise_density
            .unwrap_or(defaults.accel_noise_density),
        gyro_noise_density: args
            .gyro_noise_density
            .unwrap_or(defaults.gyro_noise_density),
        accel_bias_random_walk: args
            .accel_bias_random_walk
            .unwrap_or(defaults.accel_bias_random_walk),
    };
    // The flight window from the log, unless both ends are given.
    let found = if args.simulated || (args.from.is_some() && args.to.is_some()) {
        None
    } else {
        let window = flight_window(LogReader::<f64>::open(&files, &reader)?);
        match window {
            Some(w) => eprintln!(
                "flight window from the log: {:.1}-{:.1} s (take-off {:.1} s, landing {:.1} s, {}){}",
                w.from_us as f64 * 1e-6,
                w.to_us as f64 * 1e-6,
                w.from_us as f64 * 1e-6,
                w.landing_us as f64 * 1e-6,
                w.impact_us.map_or_else(
                    || "no impact".to_string(),
                    |t| format!("impact at {:.1} s, cut 2 s before", t as f64 * 1e-6)
                ),
                if args.from.is_some() || args.to.is_some() {
                    "; --from/--to override it"
                } else {
                    ""
                },
            ),
            None => {
                eprintln!("no flight found in the log (no GPS fix moving): scoring the whole log")
            }
        }
        window
    };
    let from_s = args.from.or(found.map(|w| w.from_us as f64 * 1e-6));
    let to_s = args.to.or(found.map(|w| w.to_us as f64 * 1e-6));
    let score_from_us = from_s.map(seconds_to_us);
    let run = RunOptions {
        start_us: from_s.map(|f| seconds_to_us(f - args.warmup)),
        score_from_us,
        end_us: to_s.map(seconds_to_us),
        alignment,
        estimator_declination_rad: alignment.declination_rad,
        ..RunOptions::default()
    };
    Setup {
        files,
        reader,
        run,
        declination_rad: alignment.declination_rad,
        inclination_rad,
        imu_rate_hz,
        imu_noise,
        nav: NavConfig::default(),
    }
    .with_config_file(args.config.as_deref())
}

fn chosen(name: &str) -> Result<Vec<&'static Registered>, Failure> {
    if name == "all" {
        return Ok(ESTIMATORS.iter().collect());
    }
    if let Some(r) = ESTIMATORS.iter().find(|r| r.name == name) {
        return Ok(vec![r]);
    }
    let available: Vec<_> = ESTIMATORS.iter().map(|r| r.name).chain(["all"]).collect();
    let why = if PLANNED.contains(&name) {
        "is not built into this version"
    } else {
        "is unknown"
    };
    Err(format!(
        "estimator `{name}` {why}; available: {}",
        available.join(", ")
    )
    .into())
}

fn skips_json(skips: &SkipCounts) -> Value {
    let by_kind: serde_json::Map<String, Value> = SkipKind::ALL
        .iter()
        .map(|&k| (k.name().to_string(), json!(skips.count(k))))
        .collect();
    let by_file: serde_json::Map<String, Value> = skips
        .files()
        .map(|(file, c)| {
            let mut entry = serde_json::Map::new();
            entry.insert("accepted".into(), json!(c.accepted));
            for k in SkipKind::ALL.iter().filter(|&&k| c.skipped(k) > 0) {
                entry.insert(k.name().into(), json!(c.skipped(*k)));
            }
            (file.to_string(), Value::Object(entry))
        })
        .collect();
    json!({ "total": skips.total(), "by_kind": by_kind, "by_file": by_file })
}

fn summary_json(name: &str, s: &RunSummary, skips: &SkipCounts) -> Value {
    let rms = s.reference_rms;
    json!({
        "estimator": name,
        "final_delay_s": s.final_delay_s,
        "delay_track": s.delay_track,
        "roll_rms_deg": rms.map(|r| r.roll_deg),
        "pitch_rms_deg": rms.map(|r| r.pitch_deg),
        "yaw_rms_deg": rms.map(|r| r.yaw_deg),
        "velocity_rms_m_s": rms.and_then(|r| r.velocity_m_s),
        "reference_samples_scored": rms.map_or(0, |r| r.samples),
        "reference_samples_unscored": s.reference_unscored,
        "samples_refused": s.samples_refused(),
        "refused_by_kind": s.refused,
        "non_finite_estimates": s.non_finite_estimates,
        "samples_pushed": { "imu": s.imu_pushed, "gps": s.gps_pushed, "mag": s.mag_pushed },
        "gps_position_fused": s.gps_position_fused,
        "gps_velocity_fused": s.gps_velocity_fused,
        "gps_gated": s.gps_gated,
        "mag_fused": s.mag_fused,
        "mag_gated": s.mag_gated,
        "rows_skipped": skips_json(skips),
    })
}

/// With no log given: writes a simulated run (the paper's low-acceleration
/// scenario, 60 s) in the crate's format to a temporary directory and points
/// the arguments at it, with the simulator's magnetic field and scoring from 10 s.
#[cfg(feature = "sim")]
fn simulated_log(args: &mut Args) -> Result<(), Failure> {
    use delaynav::sim::{Scenario, SimConfig, Simulation};
    let simulation = Simulation::new(SimConfig::for_scenario(Scenario::Low, 1))?;
    let field = simulation.field_ned();
    let dir = std::env::temp_dir().join(format!("delaynav-replay-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let written = delaynav::sim::csv::write_run(&dir, simulation)?;
    eprintln!(
        "no log given: replaying a simulated run ({written} samples) written to {}",
        dir.display()
    );
    args.inputs = vec![dir];
    args.simulated = true;
    args.declination_deg
        .get_or_insert(field.y.atan2(field.x).to_degrees());
    args.inclination_deg
        .get_or_insert(field.z.atan2(field.x.hypot(field.y)).to_degrees());
    if args.from.is_none() {
        args.from = Some(10.0);
        args.warmup = 10.0;
    }
    Ok(())
}

#[cfg(not(feature = "sim"))]
fn simulated_log(_: &mut Args) -> Result<(), Failure> {
    Err("no log given, and this build has no simulator to replay instead (feature `sim`).\n\
         Pass a log directory or files, e.g.\n  \
         cargo run --release --features replay --example replay -- ../shared/data/ardupilot-log171 --from 75 --to 225"
        .into())
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.digits$}"))
}

fn main() {
    if let Err(e) = run(Args::parse()) {
        eprintln!("replay: {e}");
        std::process::exit(1);
    }
}

fn run(mut args: Args) -> Result<(), Failure> {
    if args.inputs.is_empty() {
        simulated_log(&mut args)?;
    }
    let estimators = chosen(&args.estimator)?;
    let setup = setup(&args)?;
    if args.print_config {
        print!("{}", config_file::to_toml(&setup.nav)?);
        return Ok(());
    }
    let mut outputs = Outputs {
        estimates: match &args.out {
            Some(p) => Some(EstimateWriter::new(BufWriter::new(File::create(p)?))?),
            None => None,
        },
        attitude: Vec::new(),
        keep_attitude: args.plots.is_some(),
    };

    // The rows skipped are the same for every estimator: count them once.
    let mut scan = LogReader::<f64>::open(&setup.files, &setup.reader)?;
    scan.by_ref().for_each(drop);
    let skips = scan.skip_counts().clone();
    let counts = scan.stream_counts();
    let log_path = &setup.files.imu;
    let log_name = if log_path == &setup.files.gps {
        log_path.display().to_string()
    } else {
        log_path
            .parent()
            .map_or_else(String::new, |p| p.display().to_string())
    };
    eprintln!(
        "log: {log_name} ({}), {} IMU, {} GPS, {} magnetometer records, IMU {:.0} Hz, declination {:.2} deg, inclination {:.2} deg, trim roll {:.4} rad pitch {:.4} rad",
        setup.files.format,
        counts.imu,
        counts.gps,
        counts.mag,
        setup.imu_rate_hz,
        setup.declination_rad.to_degrees(),
        setup.inclination_rad.to_degrees(),
        setup.run.alignment.trim_roll_rad,
        setup.run.alignment.trim_pitch_rad,
    );
    eprint!("{skips}");

    let mut summaries = Vec::new();
    println!(
        "{:<9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8} {:>8}",
        "estimator", "delay_s", "roll_deg", "pitch_deg", "yaw_deg", "vel_m_s", "refused", "nonfin"
    );
    for r in estimators {
        let s = (r.run)(&setup, &mut outputs)?;
        let rms = s.reference_rms;
        println!(
            "{:<9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8} {:>8}",
            r.name,
            fmt_opt(s.final_delay_s, 3),
            fmt_opt(rms.map(|r| r.roll_deg), 3),
            fmt_opt(rms.map(|r| r.pitch_deg), 3),
            fmt_opt(rms.map(|r| r.yaw_deg), 3),
            fmt_opt(rms.and_then(|r| r.velocity_m_s), 3),
            s.samples_refused(),
            s.non_finite_estimates,
        );
        summaries.push((r, s));
    }
    if let Some(w) = outputs.estimates.as_mut() {
        w.flush()?;
    }

    if let Some(path) = &args.json {
        let doc = json!({
            "log": args.inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "format": setup.files.format.name(),
            "imu_instance": setup.reader.imu_instance,
            "counts": { "imu": counts.imu, "gps": counts.gps, "mag": counts.mag },
            "gps_delay_added_s": args.add_gps_delay,
            "replayed_from_s": setup.run.start_us.map(|t| t as f64 * 1e-6),
            "scored_from_s": setup.run.score_from_us.map(|t| t as f64 * 1e-6),
            "to_s": setup.run.end_us.map(|t| t as f64 * 1e-6),
            "window_s": [
                setup.run.score_from_us.map(|t| t as f64 / 1e6),
                setup.run.end_us.map(|t| t as f64 / 1e6),
            ],
            "declination_deg": setup.declination_rad.to_degrees(),
            "inclination_deg": setup.inclination_rad.to_degrees(),
            "imu_rate_hz": setup.imu_rate_hz,
            "accel_noise_density": setup.imu_noise.accel_noise_density,
            "gyro_noise_density": setup.imu_noise.gyro_noise_density,
            "accel_bias_random_walk": setup.imu_noise.accel_bias_random_walk,
            "trim_roll_rad": setup.run.alignment.trim_roll_rad,
            "trim_pitch_rad": setup.run.alignment.trim_pitch_rad,
            "estimators": summaries.iter().map(|(r, s)| {
                let mut v = summary_json(r.name, s, &skips);
                v["about"] = json!(r.about);
                v
            }).collect::<Vec<_>>(),
        });
        std::fs::write(path, serde_json::to_string_pretty(&doc)?)?;
        eprintln!("summary written to {}", path.display());
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir)?;
        let tracks: Vec<_> = summaries
            .iter()
            .map(|(r, s)| (r.name, s.delay_track.as_slice()))
            .collect();
        plots::delay(&dir.join("delay.svg"), &tracks)?;
        let reference = ReferenceReader::open(&setup.files)?.map(|refs| {
            refs.filter(|r| {
                setup.run.start_us.is_none_or(|s| r.t_us >= s)
                    && setup.run.end_us.is_none_or(|e| r.t_us <= e)
            })
            .map(|r| {
                let e = delaynav::geo::euler_from_quaternion(r.attitude.quaternion())
                    .map(f64::to_degrees);
                [r.t_us as f64 * 1e-6, e.x, e.y, e.z]
            })
            .collect::<Vec<_>>()
        });
        plots::attitude(dir, &outputs.attitude, reference.as_deref())?;
        eprintln!("plots written to {}", dir.display());
    }
    Ok(())
}
