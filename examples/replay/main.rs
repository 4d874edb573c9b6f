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
use delaynav::ekf16::GpsReset;
use delaynav::nav::Health;
use delaynav::replay::{
    ArduPilotImu, DelayStep, EstimateWriter, FusionRecords, ImuNoise, LogDefaults, LogFiles,
    LogFormat, LogReader, MagneticModel, NoiseSource, ReaderOptions, ReferenceAlignment,
    ReferenceReader, RunOptions, RunSummary, SkipCounts, SkipKind, ardupilot,
    dataflash::DataFlashLog, flight_window, inclination_at_rest, log_date, magnetic_model, replay,
};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, DelayCompensatedNav, DelayCompensatedNavConfig, Ekf16,
    Ekf16Config, Estimate, FilterRefusals, Navigator,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{Value, json};
use std::error::Error;
use std::fs::File;
use std::io::{BufWriter, Write};
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
}

/// What one estimator's replay gives: its scores and its health at the end.
type Outcome = (RunSummary, HealthSummary);

/// One estimator the replay can run. Adding one is one entry here.
struct Registered {
    name: &'static str,
    about: &'static str,
    run: fn(&Setup, &mut Outputs) -> Result<Outcome, Failure>,
}

const ESTIMATORS: &[Registered] = &[
    Registered {
        name: "proposed",
        about: "delay-compensated navigator: delay loop, delayed-horizon EKF, forward reckoning",
        run: |setup, out| {
            let mut nav = DelayCompensatedNav::<f64>::new(setup.nav)?;
            let summary = run_one(setup, out, "proposed", &mut nav)?;
            Ok((summary, HealthSummary::of_navigator(&nav.health())))
        },
    },
    Registered {
        name: "aekf17",
        about: "17-state augmented EKF with the delay as a state (the paper's baseline)",
        run: |setup, out| {
            let config = AugmentedEkf17Config::with_nav(setup.ekf16_config());
            let mut nav = AugmentedEkf17::new(config)?;
            let summary = run_one(setup, out, "aekf17", &mut nav)?;
            let mut health = HealthSummary::of_filter(nav.refusals(), nav.last_gps_reset());
            health.initialized(nav.estimate().is_some());
            health.delay_status = Some(format!(
                "state estimate {:.3} s +- {:.3} s, clamped to its range {} times, \
                 held on {} fixes without the motion to observe it",
                nav.delay_s(),
                nav.delay_std_s(),
                nav.delay_clamps(),
                nav.delay_unobservable_fixes()
            ));
            Ok((summary, health))
        },
    },
    Registered {
        name: "ekf16",
        about: "16-state EKF, GPS fused as if current (no delay handling)",
        run: |setup, out| {
            let mut nav = Ekf16::new(setup.ekf16_config())?;
            let summary = run_one(setup, out, "ekf16", &mut nav)?;
            let mut health = HealthSummary::of_filter(nav.refusals(), nav.last_gps_reset());
            health.initialized(nav.estimate().is_some());
            Ok((summary, health))
        },
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
    /// IMU rate, Hz (median interval of the log).
    imu_rate_hz: f64,
    /// GPS rate, Hz, when measured within the delay loop's 1-20 Hz.
    gps_rate_hz: Option<f64>,
    /// The filters' IMU noise model for this log.
    imu_noise: ImuNoise,
    /// The navigator's configuration: the log's, with `--config` merged over it.
    nav: DelayCompensatedNavConfig<f64>,
    accel_bias_random_walk: f64,
    /// Median reported GPS accuracies (h m, v m, speed m/s), the filters'
    /// accuracies for fixes that report none.
    gps_accuracy: [Option<f64>; 3],
    /// What was measured and chosen, printed and written to the JSON.
    derived: Value,
    /// No progress bar.
    quiet: bool,
}

impl Setup {
    /// The navigation filter's configuration: every estimator builds on it.
    fn ekf16_config(&self) -> Ekf16Config<f64> {
        self.nav.ekf
    }

    /// The navigator's configuration for this log: defaults with the values
    /// derived from the log (IMU rate and noise, magnetic field, GPS rate and
    /// accuracy).
    fn log_config(&self) -> Result<DelayCompensatedNavConfig<f64>, Failure> {
        let defaults = Ekf16Config::<f64>::default();
        let [h, v, speed] = self.gps_accuracy;
        let mut config = DelayCompensatedNavConfig {
            ekf: Ekf16Config {
                mag_inclination_rad: self.inclination_rad,
                mag_declination_rad: self.declination_rad,
                accel_noise_density: self.imu_noise.accel_noise_density,
                gyro_noise_density: self.imu_noise.gyro_noise_density,
                accel_bias_random_walk: self.accel_bias_random_walk,
                gps_horizontal_std_m: h.unwrap_or(defaults.gps_horizontal_std_m),
                gps_vertical_std_m: v.unwrap_or(defaults.gps_vertical_std_m),
                gps_velocity_std_m_s: speed.unwrap_or(defaults.gps_velocity_std_m_s),
                ..defaults
            },
            imu_rate_hz: self.imu_rate_hz,
            ..DelayCompensatedNavConfig::default()
        };
        if let Some(rate) = self.gps_rate_hz {
            config.delay_loop = config.delay_loop.adapted_to_gps_rate(rate)?;
        }
        Ok(config)
    }

    /// Merges the `--config` file over [`Self::log_config`] and makes the
    /// figures reported beside the results follow it.
    fn with_config_file(mut self, path: Option<&std::path::Path>) -> Result<Self, Failure> {
        self.nav = config_file::resolve(self.log_config()?, path)?;
        let ekf = self.nav.ekf;
        self.imu_rate_hz = self.nav.imu_rate_hz;
        self.declination_rad = ekf.mag_declination_rad;
        self.inclination_rad = ekf.mag_inclination_rad;
        self.run.estimator_declination_rad = ekf.mag_declination_rad;
        self.imu_noise = ImuNoise {
            accel_noise_density: ekf.accel_noise_density,
            gyro_noise_density: ekf.gyro_noise_density,
        };
        self.accel_bias_random_walk = ekf.accel_bias_random_walk;
        Ok(self)
    }
}

/// What an estimator reports about itself at the end of a replay.
#[derive(Debug, Default)]
struct HealthSummary {
    /// Alignment state (the navigator's; the filters: initialized or not).
    alignment: Option<String>,
    /// Samples refused, `sensor_reason` and count (non-zero only).
    refused: Vec<(String, u64)>,
    /// Fusions rejected by a gate.
    gated: Vec<(String, u64)>,
    /// Resets by block and cause.
    resets: Vec<(String, u64)>,
    /// The last reset and its cause.
    last_reset: Option<String>,
    /// The delay loop's status.
    delay_status: Option<String>,
}

/// `(name, value)` of the named fields of a counter struct.
macro_rules! fields {
    ($c:expr; $($f:ident),* $(,)?) => {
        vec![$((stringify!($f).to_string(), u64::from($c.$f))),*]
    };
}

fn non_zero(list: Vec<(String, u64)>) -> Vec<(String, u64)> {
    list.into_iter().filter(|(_, n)| *n > 0).collect()
}

impl HealthSummary {
    /// A filter's counters ([`FilterRefusals`]) and its last GPS reset.
    fn of_filter(c: FilterRefusals, last: Option<GpsReset>) -> Self {
        Self {
            refused: non_zero(fields!(c; imu_non_finite, imu_out_of_range, imu_time,
                imu_step_too_long, gps_invalid, gps_time, gps_mixed_frames, mag_invalid,
                mag_time, not_positive_definite)),
            gated: non_zero(fields!(c; gps_position_rejected, gps_velocity_rejected,
                mag_rejected, mag_disturbed)),
            resets: non_zero(fields!(c; gps_position_resets, gps_velocity_resets,
                gps_divergence_resets)),
            last_reset: last.map(|r| {
                format!(
                    "{:?} block, {:?}, at {:.1} s",
                    r.block,
                    r.cause,
                    r.t_us as f64 * 1e-6
                )
            }),
            ..Self::default()
        }
    }

    /// The alignment of a filter without an alignment state: initialized
    /// (it gives an estimate) or not.
    fn initialized(&mut self, yes: bool) {
        self.alignment = Some(if yes { "Initialized" } else { "NotInitialized" }.to_string());
    }

    /// The navigator's [`Health`]: its own refusals, its horizon filter's
    /// counters, alignment, last reset and delay status.
    fn of_navigator(h: &Health<f64>) -> Self {
        let mut summary = Self::of_filter(h.refusals.horizon, None);
        let n = h.refusals;
        let own = fields!(n; imu_non_finite, imu_out_of_range, imu_time, imu_ahead,
            gps_invalid, gps_time, gps_accuracy, gps_ahead, gps_mixed_frames, mag_invalid,
            mag_time, mag_ahead, mag_averaged, horizon_refused, delay_loop_refused);
        summary.refused = non_zero(own)
            .into_iter()
            .map(|(k, v)| (format!("nav.{k}"), v))
            .chain(
                summary
                    .refused
                    .into_iter()
                    .map(|(k, v)| (format!("horizon.{k}"), v)),
            )
            .collect();
        // An IMU gap is not a refused sample: the history restarts (a reset
        // whose cause `last_reset` names, `ImuGap`), so it is listed with
        // the horizon filter's GPS resets.
        summary.resets = non_zero(vec![(
            "nav.imu_gap_restarts".to_string(),
            u64::from(n.imu_gap),
        )])
        .into_iter()
        .chain(
            summary
                .resets
                .into_iter()
                .map(|(k, v)| (format!("horizon.{k}"), v)),
        )
        .collect();
        summary.alignment = Some(format!("{:?}", h.alignment));
        summary.last_reset = h.last_reset.map(|r| {
            let at = r
                .t_us
                .map_or_else(String::new, |t| format!(" at {:.1} s", t as f64 * 1e-6));
            format!("{:?}{at}", r.cause)
        });
        summary.delay_status = Some(match h.delay.status {
            Some(status) => format!(
                "{status:?}, {:.3} s +- {:.3} s, {} valid updates",
                h.delay.delay_s, h.delay.delay_std_s, h.delay.valid_updates
            ),
            None => format!("fixed at {:.3} s", h.delay.delay_s),
        });
        summary
    }

    fn json(&self) -> Value {
        let map = |list: &[(String, u64)]| {
            list.iter()
                .map(|(k, v)| (k.clone(), json!(v)))
                .collect::<serde_json::Map<_, _>>()
        };
        json!({
            "alignment": self.alignment,
            "refused": map(&self.refused),
            "gated": map(&self.gated),
            "resets": map(&self.resets),
            "last_reset": self.last_reset,
            "delay_status": self.delay_status,
        })
    }

    fn print(&self, name: &str) {
        let list = |l: &[(String, u64)]| {
            if l.is_empty() {
                "none".to_string()
            } else {
                l.iter()
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        println!("{name}");
        let rows = [
            ("alignment", self.alignment.clone()),
            ("refused", Some(list(&self.refused))),
            ("gated", Some(list(&self.gated))),
            ("resets", Some(list(&self.resets))),
            (
                "last reset",
                Some(self.last_reset.clone().unwrap_or_else(|| "none".into())),
            ),
            ("delay", self.delay_status.clone()),
        ];
        for (label, value) in rows {
            if let Some(v) = value {
                println!("  {label:<10} {v}");
            }
        }
    }
}

/// Per-sample outputs shared across estimators.
struct Outputs {
    estimates: Option<EstimateWriter<BufWriter<File>>>,
    /// `(estimator, [(t s, roll deg, pitch deg, yaw deg)])` at 10 Hz, for
    /// plots, aligned like the reference.
    attitude: Vec<(String, Vec<[f64; 4]>)>,
    keep_attitude: bool,
}

fn run_one<N: Navigator<f64> + FusionRecords<f64>>(
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
    if setup.quiet {
        return ProgressBar::hidden();
    }
    // indicatif draws to stderr, and nothing when it is not a terminal.
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
        ardupilot_imu: match imu_instance {
            0 => ArduPilotImu::First,
            _ => ArduPilotImu::Second,
        },
        imu_instance,
        ..ReaderOptions::default()
    }
    .with_added_gps_delay(args.add_gps_delay, args.add_delay_from)?;
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
    let open = || LogReader::<f64>::open(&files, &reader);

    // The flight window: found in the log (the simulated run's is fixed).
    let found = if args.simulated {
        None
    } else {
        let window = flight_window(open()?);
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
    let measured = LogDefaults::measure(open()?, found.as_ref());
    let imu_rate_hz = measured
        .imu_rate_hz
        .unwrap_or(DelayCompensatedNavConfig::<f64>::default().imu_rate_hz);
    let gps_rate_hz = measured.gps_rate_hz.filter(|r| (1.0..=20.0).contains(r));

    // IMU noise: measured (never below the filters' defaults), flags override.
    let defaults = Ekf16Config::<f64>::default();
    let (noise, [accel_source, gyro_source]) = measured.imu_noise(ImuNoise {
        accel_noise_density: defaults.accel_noise_density,
        gyro_noise_density: defaults.gyro_noise_density,
    });
    let imu_noise = ImuNoise {
        accel_noise_density: args
            .accel_noise_density
            .unwrap_or(noise.accel_noise_density),
        gyro_noise_density: args.gyro_noise_density.unwrap_or(noise.gyro_noise_density),
    };
    let source = |flag: Option<f64>, s: NoiseSource| flag.map_or(s.name(), |_| "command line");

    // Declination: the flag, else the autopilot's own manual setting, else
    // the World Magnetic Model at the first fix on the log's date.
    let date = log_date(&files)?;
    let model: Option<MagneticModel> = measured
        .first_fix
        .zip(date)
        .and_then(|(place, date)| magnetic_model(&place, date));
    if let (Some(m), Some(date)) = (model, date)
        && m.date_clamped
    {
        eprintln!(
            "warning: the log is dated {date}, outside the World Magnetic Model's 2020-2029: \
             its field is evaluated at {} (the nearest date it covers); \
             give --declination-deg to set it",
            m.model_date
        );
    }
    let params = match (&files.params, files.format) {
        (Some(path), LogFormat::DataFlash) => Some(DataFlashLog::open(path)?.params()),
        (Some(path), LogFormat::ArduPilot) => {
            Some(ardupilot::read_params(path, &mut SkipCounts::default())?)
        }
        _ => None,
    };
    let model_declination = model.map_or(0.0, |m| m.declination_rad);
    let mut alignment = match &params {
        Some(values) => ardupilot::alignment_from_params(values, model_declination),
        None => ReferenceAlignment {
            declination_rad: model_declination,
            ..ReferenceAlignment::default()
        },
    };
    let manual_declination = params
        .as_ref()
        .is_some_and(|p| p.get("COMPASS_AUTODEC") == Some(&0.0) && p.contains_key("COMPASS_DEC"));
    let declination_source = if args.declination_deg.is_some() {
        "command line"
    } else if manual_declination {
        "log parameter COMPASS_DEC (COMPASS_AUTODEC = 0)"
    } else if model.is_some_and(|m| m.date_clamped) {
        "World Magnetic Model at the nearest date it covers"
    } else if model.is_some() {
        "World Magnetic Model"
    } else {
        eprintln!(
            "warning: no date or no geodetic fix in the log: declination 0 (give --declination-deg)"
        );
        "none (0)"
    };
    if let Some(d) = args.declination_deg {
        alignment.declination_rad = d.to_radians();
    }
    alignment.trim_roll_rad = args.trim_roll_rad.unwrap_or(alignment.trim_roll_rad);
    alignment.trim_pitch_rad = args.trim_pitch_rad.unwrap_or(alignment.trim_pitch_rad);

    // Inclination: the flag, else measured over the stationary segment,
    // else the model, else measured over the log's first 10 s.
    let (inclination_rad, inclination_source) = match (args.inclination_deg, measured.stationary) {
        (Some(i), _) => (i.to_radians(), "command line"),
        (None, Some(still)) => {
            let events = open()?.skip_while(move |e| e.time_us() < still.from_us);
            match inclination_at_rest(events, still.to_us - still.from_us) {
                Some(i) => (i, "stationary segment"),
                None => (
                    model.map_or(0.0, |m| m.inclination_rad),
                    "World Magnetic Model",
                ),
            }
        }
        (None, None) => match model {
            Some(m) => (m.inclination_rad, "World Magnetic Model"),
            None => (
                inclination_at_rest(open()?, 10_000_000).unwrap_or(0.0),
                "the log's first 10 s",
            ),
        },
    };

    if let Some(m) = model
        && (m.inclination_rad - inclination_rad).abs() > 10f64.to_radians()
    {
        eprintln!(
            "warning: the magnetometer's inclination ({:.1} deg, {inclination_source}) is {:.1} deg \
             from the World Magnetic Model's ({:.1} deg): uncalibrated or disturbed magnetometer? \
             The measured value is used (give --inclination-deg to set it)",
            inclination_rad.to_degrees(),
            (inclination_rad - m.inclination_rad).abs().to_degrees(),
            m.inclination_rad.to_degrees()
        );
    }
    let gps_accuracy = [
        measured.gps_horizontal_accuracy_m,
        measured.gps_vertical_accuracy_m,
        measured.gps_speed_accuracy_m_s,
    ];
    let segment = |m: Option<delaynav::replay::defaults::NoiseMeasurement>| {
        m.map(|m| {
            json!({
                "from_s": m.from_us as f64 * 1e-6,
                "to_s": m.to_us as f64 * 1e-6,
                "accel_density_per_axis": m.accel_density,
                "gyro_density_per_axis": m.gyro_density,
            })
        })
    };
    let derived = json!({
        "imu_rate_hz": measured.imu_rate_hz,
        "gps_rate_hz": measured.gps_rate_hz,
        "mag_rate_hz": measured.mag_rate_hz,
        "gps_accuracy_reported_median": {
            "horizontal_m": gps_accuracy[0],
            "vertical_m": gps_accuracy[1],
            "speed_m_s": gps_accuracy[2],
        },
        "stationary_segment": segment(measured.stationary),
        "in_flight": segment(measured.in_flight),
        "accel_noise_density": imu_noise.accel_noise_density,
        "accel_noise_source": source(args.accel_noise_density, accel_source),
        "gyro_noise_density": imu_noise.gyro_noise_density,
        "gyro_noise_source": source(args.gyro_noise_density, gyro_source),
        "log_date": date.map(|d| d.to_string()),
        "first_fix": measured.first_fix.map(|g| [g.lat_deg, g.lon_deg, g.alt_m]),
        "model": model.map(|m| json!({
            "declination_deg": m.declination_rad.to_degrees(),
            "declination_std_deg": m.declination_std_rad.to_degrees(),
            "inclination_deg": m.inclination_rad.to_degrees(),
            "evaluated_at": m.model_date.to_string(),
            "date_clamped": m.date_clamped,
        })),
        "declination_deg": alignment.declination_rad.to_degrees(),
        "declination_source": declination_source,
        "inclination_deg": inclination_rad.to_degrees(),
        "inclination_source": inclination_source,
    });

    let from_s = args.from.or(found.map(|w| w.from_us as f64 * 1e-6));
    let to_s = args.to.or(found.map(|w| w.to_us as f64 * 1e-6));
    let run = RunOptions {
        start_us: from_s.map(|f| seconds_to_us(f - args.warmup)),
        score_from_us: from_s.map(seconds_to_us),
        end_us: to_s.map(seconds_to_us),
        alignment,
        estimator_declination_rad: alignment.declination_rad,
        delay_step: args
            .add_delay_from
            .map(|_| DelayStep::new(reader.gps_delay_added_from_us, args.add_gps_delay)),
        ..RunOptions::default()
    };
    Setup {
        files,
        reader,
        run,
        declination_rad: alignment.declination_rad,
        inclination_rad,
        imu_rate_hz,
        gps_rate_hz,
        imu_noise,
        accel_bias_random_walk: args
            .accel_bias_random_walk
            .unwrap_or(defaults.accel_bias_random_walk),
        gps_accuracy,
        derived,
        quiet: args.quiet,
        nav: DelayCompensatedNavConfig::default(),
    }
    .with_config_file(args.config.as_deref())
}

/// The derived values, one line each, as printed at the start of a replay.
fn print_derived(setup: &Setup) {
    let d = &setup.derived;
    let num = |v: &Value, digits: usize| {
        v.as_f64()
            .map_or_else(|| "-".to_string(), |x| format!("{x:.digits$}"))
    };
    eprintln!("derived from the log (docs/replay.md, \"Defaults from the log\"):");
    eprintln!(
        "  rates: IMU {} Hz, GPS {} Hz, magnetometer {} Hz (median intervals)",
        num(&d["imu_rate_hz"], 1),
        num(&d["gps_rate_hz"], 2),
        num(&d["mag_rate_hz"], 2)
    );
    let acc = &d["gps_accuracy_reported_median"];
    if acc["horizontal_m"].is_null() && acc["speed_m_s"].is_null() {
        eprintln!("  GPS accuracy: not reported by the log: the filters' defaults");
    } else {
        eprintln!(
            "  GPS accuracy: reported per fix, median horizontal {} m, vertical {} m, speed {} m/s",
            num(&acc["horizontal_m"], 2),
            num(&acc["vertical_m"], 2),
            num(&acc["speed_m_s"], 2)
        );
    }
    for (label, key) in [
        ("stationary segment", "stationary_segment"),
        ("in flight", "in_flight"),
    ] {
        let m = &d[key];
        if m.is_null() {
            eprintln!("  {label}: none");
            continue;
        }
        let axes = |k: &str, digits: usize| {
            m[k].as_array()
                .map(|a| {
                    a.iter()
                        .map(|v| num(v, digits))
                        .collect::<Vec<_>>()
                        .join("/")
                })
                .unwrap_or_default()
        };
        eprintln!(
            "  {label} {}-{} s: accel {} m/s^2/sqrt(Hz), gyro {} rad/s/sqrt(Hz) (x/y/z)",
            num(&m["from_s"], 1),
            num(&m["to_s"], 1),
            axes("accel_density_per_axis", 4),
            axes("gyro_density_per_axis", 5)
        );
    }
    eprintln!(
        "  IMU noise used: accel {} ({}), gyro {} ({})",
        num(&d["accel_noise_density"], 4),
        d["accel_noise_source"].as_str().unwrap_or("-"),
        num(&d["gyro_noise_density"], 5),
        d["gyro_noise_source"].as_str().unwrap_or("-")
    );
    eprintln!(
        "  declination {} deg ({}), inclination {} deg ({}); log date {}, first fix {}",
        num(&d["declination_deg"], 2),
        d["declination_source"].as_str().unwrap_or("-"),
        num(&d["inclination_deg"], 2),
        d["inclination_source"].as_str().unwrap_or("-"),
        d["log_date"].as_str().unwrap_or("unknown"),
        d["first_fix"].as_array().map_or_else(
            || "none".to_string(),
            |a| format!("{} {}", num(&a[0], 5), num(&a[1], 5))
        )
    );
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

/// `--delay-windows`: one row per delay-loop update and estimator.
fn write_delay_windows<'a>(
    path: &std::path::Path,
    summaries: impl Iterator<Item = (&'a str, &'a RunSummary)>,
) -> Result<(), Failure> {
    let mut w = BufWriter::new(File::create(path)?);
    write!(w, "estimator,t_s,delay_s,delay_std_s,status")?;
    for axis in ["n", "e", "d"] {
        write!(
            w,
            ",{axis}_valid,{axis}_delay_s,{axis}_peak,{axis}_accel_var,{axis}_interior"
        )?;
    }
    writeln!(w)?;
    for (name, s) in summaries {
        for win in &s.delay_windows {
            // The status's debug form may hold commas (out of range).
            let status = win.status.replace(',', ";");
            write!(
                w,
                "{name},{:.3},{:.5},{:.5},{status}",
                win.t_s, win.delay_s, win.delay_std_s
            )?;
            for a in &win.axes {
                write!(
                    w,
                    ",{},{:.5},{:.4},{:.4},{}",
                    u8::from(a.valid),
                    a.measured_delay_s,
                    a.peak,
                    a.accel_variance,
                    u8::from(a.interior)
                )?;
            }
            writeln!(w)?;
        }
    }
    w.flush()?;
    Ok(())
}

fn summary_json(name: &str, s: &RunSummary, skips: &SkipCounts) -> Value {
    let rms = s.reference_rms;
    json!({
        "estimator": name,
        "final_delay_s": s.final_delay_s,
        "delay_step": s.delay_step.map(|d| json!({
            "from_s": d.from_s,
            "added_s": d.added_s,
            "before_s": d.before_s,
            "final_s": d.final_s,
            "reference_s": d.reference_s,
            "target_s": d.target_s,
            "settled_after_s": d.settled_after_s,
        })),
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
    let mut setup = setup(&args)?;
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
    print_derived(&setup);

    let mut summaries = Vec::new();
    println!(
        "{:<9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>8} {:>8}",
        "estimator", "delay_s", "roll_deg", "pitch_deg", "yaw_deg", "vel_m_s", "refused", "nonfin"
    );
    let step = setup.run.delay_step;
    for r in estimators {
        if let Some(step) = step {
            // The reference of the step: the same replay without the added delay.
            let (reader, run) = (setup.reader, setup.run);
            setup.reader.gps_delay_added_us = 0;
            setup.run.delay_step = None;
            let mut none = Outputs {
                estimates: None,
                attitude: Vec::new(),
                keep_attitude: false,
            };
            let without = (r.run)(&setup, &mut none);
            (setup.reader, setup.run) = (reader, run);
            setup.run.delay_step = Some(DelayStep {
                reference_s: without?.0.final_delay_s,
                ..step
            });
        }
        let (s, health) = (r.run)(&setup, &mut outputs)?;
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
        summaries.push((r, s, health));
    }
    for (r, s, _) in &summaries {
        if let Some(d) = s.delay_step {
            println!(
                "{}: delay step +{:.3} s at {:.1} s: before {} s, final {} s, without the added delay {} s, within 10 ms of the target {} s after {} s",
                r.name,
                d.added_s,
                d.from_s,
                fmt_opt(d.before_s, 4),
                fmt_opt(d.final_s, 4),
                fmt_opt(d.reference_s, 4),
                fmt_opt(d.target_s, 4),
                fmt_opt(d.settled_after_s, 1),
            );
        }
    }
    if let Some(path) = &args.delay_windows {
        write_delay_windows(path, summaries.iter().map(|(r, s, _)| (r.name, s)))?;
    }
    println!();
    println!("health at the end of the replay (docs/replay.md, \"Health summary\"):");
    for (r, _, health) in &summaries {
        health.print(r.name);
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
            "gps_delay_added_from_s": args.add_delay_from,
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
            "accel_bias_random_walk": setup.accel_bias_random_walk,
            "trim_roll_rad": setup.run.alignment.trim_roll_rad,
            "trim_pitch_rad": setup.run.alignment.trim_pitch_rad,
            "derived": setup.derived,
            "estimators": summaries.iter().map(|(r, s, health)| {
                let mut v = summary_json(r.name, s, &skips);
                v["about"] = json!(r.about);
                v["health"] = health.json();
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
            .map(|(r, s, _)| (r.name, s.delay_track.as_slice()))
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
