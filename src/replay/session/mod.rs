//! A replay of a log through the crate's estimators, scored against the
//! log's onboard reference: what `delaynav replay` (and any front end)
//! runs, as library calls.
//!
//! # What a replay does
//! 1. [`ReplaySetup::from_log`] locates and reads the log named by the
//!    [`ReplayOptions`] and derives everything from it ([`DerivedDefaults`],
//!    `docs/replay.md`, "Defaults from the log"): the flight window
//!    ([`flight_window`](super::flight_window)), the sensors' rates and the
//!    receiver's accuracy, the IMU noise, the date and the Earth's field
//!    (declination, inclination), ArduPilot's mounting trim; the navigator's
//!    configuration for the log ([`ReplaySetup::nav`]). What it finds and
//!    warns about is in [`ReplaySetup::notes`].
//! 2. [`ReplaySetup::with_config_file`] merges a TOML file over that
//!    configuration ([`config_file`](super::config_file)).
//! 3. [`ReplaySetup::scan`] counts the log's records and skipped rows once.
//! 4. [`ReplaySetup::run`] replays each chosen estimator
//!    ([`ESTIMATORS`], [`select_estimators`]) from the warm-up before the
//!    scored window to its end ([`replay`](super::replay)), with a step of
//!    the GPS delay replayed first without it, and returns a
//!    [`ReplayReport`]: per estimator a [`RunSummary`](super::RunSummary)
//!    and a [`HealthSummary`]. A [`ReplayObserver`] sees the progress and
//!    every estimate (a progress bar, an estimates file, plots).
//!
//! # Options
//! [`ReplayOptions`]: the log (`inputs`, `format`, `imu_instance`), the
//! window (`from_s`, `to_s`, `warmup_s`, `fixed_window`), the added GPS
//! delay (`add_gps_delay_s`, from `add_delay_from_s` on: a delay step),
//! values that override what the log gives (`declination_deg`,
//! `inclination_deg`, `trim_rad`, `accel_noise_density`,
//! `gyro_noise_density`, `accel_bias_random_walk`) and a configuration file
//! (`config_file`). `ReplayOptions::default()` is `delaynav replay`'s command
//! line without flags.
//!
//! # Outputs
//! - Console text: [`ReplaySetup::log_line`], the [`SkipCounts`]
//!   and [`DerivedDefaults`] (`Display`) at the start; then the table
//!   ([`table_header`], [`EstimatorReport::table_row`]), the delay steps
//!   and the health summary ([`ReplayReport::delay_steps`],
//!   [`ReplayReport::health`]); `Display` of a [`ReplayReport`] is the
//!   table to the end.
//! - JSON ([`ReplayReport::to_json`]): at the top `log`, `format`,
//!   `imu_instance`, `counts` (`imu`, `gps`, `mag`), `gps_delay_added_s`,
//!   `gps_delay_added_from_s`, `replayed_from_s`, `scored_from_s`, `to_s`,
//!   `window_s`, `declination_deg`, `inclination_deg`, `imu_rate_hz`,
//!   `accel_noise_density`, `gyro_noise_density`, `accel_bias_random_walk`,
//!   `trim_roll_rad`, `trim_pitch_rad`, `derived`
//!   ([`DerivedDefaults::to_json`]) and `estimators`, one entry each
//!   ([`EstimatorReport::to_json`]: `estimator`, `about`, `final_delay_s`,
//!   `delay_estimated`, `delay_not_estimated_reason`, `offline_delay`, `delay_step`, `delay_track`, `roll_rms_deg`, `pitch_rms_deg`,
//!   `yaw_rms_deg`, `velocity_rms_m_s`, `reference_samples_scored`,
//!   `reference_samples_unscored`, `samples_refused`, `refused_by_kind`,
//!   `non_finite_estimates`, `samples_pushed`, `gps_position_fused`,
//!   `gps_velocity_fused`, `gps_gated`, `mag_fused`, `mag_gated`,
//!   `rows_skipped`, `health`).
//! - CSV of every delay-loop update ([`write_delay_windows`]).
//!
//! ```no_run
//! use delaynav::replay::session::{ReplayOptions, ReplaySetup, select_estimators};
//!
//! # fn main() -> Result<(), delaynav::replay::ReplayError> {
//! let options = ReplayOptions {
//!     from_s: Some(75.0),
//!     to_s: Some(225.0),
//!     ..ReplayOptions::new(["../shared/data/ardupilot-log171/log171.bin"])
//! };
//! let setup = ReplaySetup::open(&options)?; // from_log, then the config file if any
//! for note in &setup.notes {
//!     eprintln!("{note}");
//! }
//! let scan = setup.scan()?;
//! let report = setup.run(scan, &select_estimators("all")?, &mut ())?;
//! print!("{report}"); // the console table and the health summary
//! let json = report.to_json(); // delaynav replay --json
//! println!("{}", json["estimators"][0]["yaw_rms_deg"]);
//! # Ok(())
//! # }
//! ```

mod derive;
mod estimators;
mod health;
mod offline;
mod report;

pub use derive::{DeclinationSource, DerivedDefaults, InclinationSource, NoiseChoice, SetupNote};
pub use estimators::{ESTIMATORS, RegisteredEstimator, ReplayObserver, select_estimators};
pub use health::HealthSummary;
pub use offline::{OFFLINE_MAX_SHIFT_S, OFFLINE_MIN_PEAK, OFFLINE_RANGE_MARGIN_S, OfflineDelay};
pub use report::{EstimatorReport, ReplayReport, table_header, write_delay_windows};

use super::config_file::read_config_file;
use super::{
    FlightWindow, ImuNoise, LogFiles, LogFormat, LogReader, ReaderOptions, ReferenceReader,
    ReplayError, RunOptions, SkipCounts, StreamCounts,
};
use crate::estimate::Estimate;
use crate::{DelayCompensatedNavConfig, Ekf16Config};
use std::path::{Path, PathBuf};

/// What to replay and how: `delaynav replay`'s command line as a struct;
/// `ReplayOptions::default()` is the command line without flags. `None`
/// takes the value from the log (see [`DerivedDefaults`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayOptions {
    /// The log: an ArduPilot `.bin` or PX4 `.ulg` file (recognised by its
    /// first bytes), or directories or files of CSVs
    /// ([`LogFiles::locate`]).
    pub inputs: Vec<PathBuf>,
    /// The layout (`None`: detected).
    pub format: Option<LogFormat>,
    /// Which IMU to read, 0 first: DataFlash `IMU` instance, ULog
    /// `sensor_combined` multi-id, ArduPilot CSV `imu.csv` (0) or
    /// `imu2.csv` (1).
    pub imu_instance: u8,
    /// Start of the scored window, seconds on the log's clock (`None`: the
    /// take-off found in the log).
    pub from_s: Option<f64>,
    /// End of the replayed and scored window, seconds (`None`: the landing
    /// found in the log, cut 2 s before an impact).
    pub to_s: Option<f64>,
    /// Seconds replayed before `from_s` so the estimators initialize and
    /// converge; not scored (`None`: [`DEFAULT_WARMUP_S`]).
    pub warmup_s: Option<f64>,
    /// The window is `from_s` to `to_s` (or the whole log), not searched
    /// in the log (the simulated run's).
    pub fixed_window: bool,
    /// Seconds added to every GPS receive time (the added-delay
    /// experiment); negative or non-finite is
    /// [`ReplayError::InvalidSeconds`].
    pub add_gps_delay_s: f64,
    /// Add the delay only to the fixes received from this time on, seconds
    /// on the log's clock: a delay step. Each estimator is then also
    /// replayed without the added delay, and its summary reports how its
    /// delay estimate followed the step ([`RunSummary::delay_step`](super::RunSummary::delay_step)).
    pub add_delay_from_s: Option<f64>,
    /// Magnetic declination, degrees east.
    pub declination_deg: Option<f64>,
    /// Magnetic inclination, degrees down.
    pub inclination_deg: Option<f64>,
    /// Mounting trim (roll, pitch), radians (default: ArduPilot's
    /// `AHRS_TRIM_X`, `AHRS_TRIM_Y`, else 0).
    pub trim_rad: [Option<f64>; 2],
    /// Accelerometer noise density of the filters, m/s^2/sqrt(Hz).
    pub accel_noise_density: Option<f64>,
    /// Gyro noise density of the filters, rad/s/sqrt(Hz).
    pub gyro_noise_density: Option<f64>,
    /// Accelerometer bias random walk, m/s^2/sqrt(s) (`None`: the filters'
    /// default).
    pub accel_bias_random_walk: Option<f64>,
    /// Navigator configuration (TOML, may be partial) merged over the one
    /// derived from the log ([`ReplaySetup::with_config_file`]).
    pub config_file: Option<PathBuf>,
    /// Drop the log's magnetometer records
    /// ([`ReaderOptions::drop_mag`](super::ReaderOptions::drop_mag)): yaw
    /// without a compass, on any log.
    pub no_mag: bool,
}

/// Seconds replayed before the scored window by default.
pub const DEFAULT_WARMUP_S: f64 = 30.0;

impl ReplayOptions {
    /// The defaults, replaying the log at `inputs`.
    pub fn new<P: Into<PathBuf>>(inputs: impl IntoIterator<Item = P>) -> Self {
        Self {
            inputs: inputs.into_iter().map(Into::into).collect(),
            ..Self::default()
        }
    }

    /// Writes a simulated run (the paper's low-acceleration scenario, 60 s,
    /// seed 1) in the crate's CSV format into `dir` and points these options
    /// at it, with the simulator's magnetic field (unless given) and, unless
    /// `from_s` is given, scoring from 10 s after a 10 s warm-up; the window
    /// is not searched. Returns the number of samples written.
    #[cfg(feature = "sim")]
    pub fn simulated_log(&mut self, dir: &Path) -> Result<usize, ReplayError> {
        use crate::sim::{Scenario, SimConfig, Simulation};
        let simulation = Simulation::new(SimConfig::for_scenario(Scenario::Low, 1))?;
        let field = simulation.field_ned();
        let write_error = |source| ReplayError::Write {
            path: dir.to_path_buf(),
            source,
        };
        std::fs::create_dir_all(dir).map_err(write_error)?;
        let written = crate::sim::csv::write_run(dir, simulation).map_err(write_error)?;
        self.inputs = vec![dir.to_path_buf()];
        self.fixed_window = true;
        self.declination_deg
            .get_or_insert(field.y.atan2(field.x).to_degrees());
        self.inclination_deg
            .get_or_insert(field.z.atan2(field.x.hypot(field.y)).to_degrees());
        if self.from_s.is_none() {
            self.from_s = Some(10.0);
            self.warmup_s = Some(10.0);
        }
        Ok(written)
    }
}

/// Seconds to microseconds for the window's bounds: negative times clamp to
/// the log's start (a warm-up longer than the time before `from_s`).
fn seconds_to_us_clamped(s: f64) -> u64 {
    (s.max(0.0) * 1e6).round() as u64
}

/// Everything fixed for one replay, shared by the estimators: the log's
/// files, how they are read, the window, and the values derived from the
/// log with the configuration file merged over them.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplaySetup {
    /// The options the setup was made from.
    pub options: ReplayOptions,
    /// The log's files.
    pub files: LogFiles,
    /// How they are read (IMU instance, added GPS delay).
    pub reader: ReaderOptions,
    /// The replayed and scored window, the reference's alignment, the
    /// delay step.
    pub run: RunOptions,
    /// The flight window found in the log, if it was searched and found.
    pub window: Option<FlightWindow>,
    /// Declination of the estimators' magnetic model, radians.
    pub declination_rad: f64,
    /// Inclination of the estimators' magnetic model, radians.
    pub inclination_rad: f64,
    /// IMU rate, Hz (median interval of the log).
    pub imu_rate_hz: f64,
    /// GPS rate, Hz, when measured within the delay loop's 1-20 Hz.
    pub gps_rate_hz: Option<f64>,
    /// The filters' IMU noise model for this log.
    pub imu_noise: ImuNoise,
    /// The filters' accelerometer bias random walk, m/s^2/sqrt(s).
    pub accel_bias_random_walk: f64,
    /// Median reported GPS accuracies (h m, v m, speed m/s), the filters'
    /// accuracies for fixes that report none.
    pub gps_accuracy: [Option<f64>; 3],
    /// The navigator's configuration: the log's ([`Self::log_config`]),
    /// with the configuration file merged over it. Its `ekf` configures
    /// every estimator.
    pub nav: DelayCompensatedNavConfig<f64>,
    /// What was measured and chosen, before the configuration file.
    pub derived: DerivedDefaults,
    /// What was found and warned about, in order.
    pub notes: Vec<SetupNote>,
}

/// The log's records and skipped rows, counted once for every estimator
/// ([`ReplaySetup::scan`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LogScan {
    /// Rows accepted and skipped, by file and kind.
    pub skips: SkipCounts,
    /// Records per stream.
    pub counts: StreamCounts,
}

impl ReplaySetup {
    /// [`Self::from_log`], then the options' configuration file
    /// ([`Self::with_config_file`]).
    pub fn open(options: &ReplayOptions) -> Result<Self, ReplayError> {
        let config_file = options.config_file.clone();
        Self::from_log(options)?.with_config_file(config_file.as_deref())
    }

    /// Locates and reads the log, and derives the setup from it and the
    /// options (see the module docs); the configuration file is not read.
    pub fn from_log(options: &ReplayOptions) -> Result<Self, ReplayError> {
        derive::derive(options)
    }

    /// The navigation filter's configuration: every estimator builds on it.
    pub fn ekf16_config(&self) -> Ekf16Config<f64> {
        self.nav.ekf
    }

    /// The navigator's configuration for this log: defaults with the values
    /// derived from the log (IMU rate and noise, magnetic field, GPS rate and
    /// accuracy).
    pub fn log_config(&self) -> Result<DelayCompensatedNavConfig<f64>, ReplayError> {
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

    /// Merges the configuration file at `path` (if any) over
    /// [`Self::log_config`] ([`read_config_file`]) and makes the figures
    /// reported beside the results follow it ([`Self::with_config`]).
    pub fn with_config_file(self, path: Option<&Path>) -> Result<Self, ReplayError> {
        let Some(path) = path else {
            return Ok(self);
        };
        let config = read_config_file(self.log_config()?, path)?;
        Ok(self.with_config(config))
    }

    /// Replays with `config` (its `ekf` for every estimator); the IMU rate,
    /// magnetic field and noise reported beside the results follow it
    /// ([`Self::derived`] stays what the log gave). An invalid configuration
    /// is refused when an estimator is built ([`ReplayError::Config`]).
    pub fn with_config(mut self, config: DelayCompensatedNavConfig<f64>) -> Self {
        self.nav = config;
        let ekf = config.ekf;
        self.imu_rate_hz = config.imu_rate_hz;
        self.declination_rad = ekf.mag_declination_rad;
        self.inclination_rad = ekf.mag_inclination_rad;
        self.run.estimator_declination_rad = ekf.mag_declination_rad;
        self.imu_noise = ImuNoise {
            accel_noise_density: ekf.accel_noise_density,
            gyro_noise_density: ekf.gyro_noise_density,
        };
        self.accel_bias_random_walk = ekf.accel_bias_random_walk;
        self
    }

    /// Reads the whole log once: its records per stream and skipped rows
    /// (the same for every estimator).
    pub fn scan(&self) -> Result<LogScan, ReplayError> {
        let mut scan = LogReader::<f64>::open(&self.files, &self.reader)?;
        scan.by_ref().for_each(drop);
        Ok(LogScan {
            skips: scan.skip_counts().clone(),
            counts: scan.stream_counts(),
        })
    }

    /// The console's first line on the log: its name and format, its
    /// records, IMU rate, magnetic field and trim.
    pub fn log_line(&self, scan: &LogScan) -> String {
        let log_path = &self.files.imu;
        let log_name = if log_path == &self.files.gps {
            log_path.display().to_string()
        } else {
            log_path
                .parent()
                .map_or_else(String::new, |p| p.display().to_string())
        };
        let counts = scan.counts;
        format!(
            "log: {log_name} ({}), {} IMU, {} GPS, {} magnetometer records, IMU {:.0} Hz, declination {:.2} deg, inclination {:.2} deg, trim roll {:.4} rad pitch {:.4} rad",
            self.files.format,
            counts.imu,
            counts.gps,
            counts.mag,
            self.imu_rate_hz,
            self.declination_rad.to_degrees(),
            self.inclination_rad.to_degrees(),
            self.run.alignment.trim_roll_rad,
            self.run.alignment.trim_pitch_rad,
        )
    }

    /// An estimate's roll, pitch and yaw, degrees, aligned like the
    /// reference (trim and declination applied): what plots draw against it.
    pub fn aligned_euler_deg(&self, estimate: &Estimate<f64>) -> [f64; 3] {
        let aligned = self
            .run
            .alignment
            .align_estimate(&estimate.attitude, self.run.estimator_declination_rad);
        let e = crate::geo::euler_from_quaternion(aligned.quaternion()).map(f64::to_degrees);
        [e.x, e.y, e.z]
    }

    /// The reference's `[t s, roll, pitch, yaw deg]` within the replayed
    /// window, `None` when the log has no reference.
    pub fn reference_attitude_deg(&self) -> Result<Option<Vec<[f64; 4]>>, ReplayError> {
        let (start, end) = (self.run.start_us, self.run.end_us);
        Ok(ReferenceReader::open(&self.files)?.map(|refs| {
            refs.filter(|r| start.is_none_or(|s| r.t_us >= s) && end.is_none_or(|e| r.t_us <= e))
                .map(|r| {
                    let e = crate::geo::euler_from_quaternion(r.attitude.quaternion())
                        .map(f64::to_degrees);
                    [r.t_us as f64 * 1e-6, e.x, e.y, e.z]
                })
                .collect()
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_options_are_the_command_line_without_flags() {
        let o = ReplayOptions::new(["log.bin"]);
        assert_eq!(o.inputs, [PathBuf::from("log.bin")]);
        assert_eq!(
            (o.warmup_s, o.fixed_window, o.imu_instance),
            (None, false, 0)
        );
        assert_eq!((o.add_gps_delay_s, o.add_delay_from_s), (0.0, None));
        assert!(o.format.is_none() && o.from_s.is_none() && o.config_file.is_none());
    }

    #[test]
    fn window_bounds_before_the_log_clamp_to_its_start() {
        assert_eq!(seconds_to_us_clamped(-20.0), 0);
        assert_eq!(seconds_to_us_clamped(f64::NAN), 0);
        assert_eq!(seconds_to_us_clamped(45.0000004), 45_000_000);
    }

    #[test]
    fn a_missing_log_or_a_bad_added_delay_is_a_typed_error() {
        let err = ReplaySetup::open(&ReplayOptions::new(["/nonexistent/log"])).unwrap_err();
        assert!(matches!(err, ReplayError::Open { .. }), "{err:?}");
        assert_eq!(
            err.to_string(),
            "cannot open /nonexistent/log: no such file or directory"
        );
        let options = ReplayOptions {
            add_gps_delay_s: -1.0,
            ..ReplayOptions::new(["/nonexistent/log"])
        };
        let err = ReplaySetup::open(&options).unwrap_err();
        assert!(matches!(err, ReplayError::InvalidSeconds { .. }), "{err:?}");
    }
}
