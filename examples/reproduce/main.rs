//! Reproduces the paper's simulation study (section 3.1, Tables 5 and 6,
//! Figures 5 and 6) on the crate's simulator.
//!
//! Runs scenarios x estimators x seeds, prints the RMSE table with the
//! paper's figures and the noise floor beside ours, the bias table, and
//! writes the JSON results and SVG plots.
//!
//! ```text
//! cargo run --release --features sim --example reproduce              # everything
//! cargo run --release --features sim --example reproduce -- --quick --json out.json
//! cargo run --release --features sim --example reproduce -- --quick --csv target/logs   # CSV logs too
//! cargo run --release --features sim --example reproduce -- --seeds 20                  # Monte Carlo
//! cargo run --release --features sim --example reproduce -- --sweep delay --json target/sweep.json
//! cargo run --release --features sim --example reproduce -- --faults --json target/faults.json   # fault suite
//! cargo run --release --features sim --example reproduce -- --delay-suite --json d.json  # issue 11's delay suite
//! cargo run --release --features sim --example reproduce -- --delay-suite --rows delay_ramp,gps_2hz \
//!     --delay-rate-std 1 --delay-rate-time-constant 30 --json d.json      # rows with the drift-rate state
//! cargo run --release --features sim --example reproduce -- --delay-trace cold_start_low --seed 1 \
//!     --csv target/low.csv                                                 # a row's run, per second
//! cargo run --release --features sim --example reproduce -- --check \
//!     --known-failures low.proposed_tilt_vs_bound,high.proposed_tilt_vs_bound   # verdicts enforced
//! ```
//!
//! Rows: `bound` (`sim::trajectory_bound`, the linearized filter about the
//! true trajectory), `bound_filter_heading` (the same taking from the
//! magnetometer only what the estimators take: a tilt-compensated heading),
//! `bound_calibrated` (the bound with the
//! biases' prior of the IMU calibration below), the crate's estimators in
//! `f64` and `f32`, `calibrated` (`proposed` starting from a pre-flight IMU bias calibration,
//! [`imu_calibration`]), and the peer `fusion_nav` (module `fusion_nav`).
//!
//! Every figure is the mean over the seeds of one run's RMSE, counted
//! after `skip_s` seconds (the convergence time), with the 95 % t-interval
//! of that mean (`stats`); seeds run in parallel (`--threads`). Attitude errors are the
//! differences of ZYX Euler angles wrapped to (-180, 180] degrees, and
//! beside them the tilt and heading errors of the attitude error's rotation
//! vector (`sim::tilt_heading_error_rad`, invariant to the vehicle's own
//! attitude); velocity and position errors are the RMS of the 3-D error norm; delay is
//! the RMS of estimate minus true delay; biases are per-axis RMS errors.
//! `us_per_imu_sample` is the time spent inside the estimator's own
//! `push_*` calls divided by the number of IMU samples.
//!
//! Consistency: the NEES of `[position, velocity]` (6 degrees of freedom)
//! against each filter's own 6x6 covariance block at the instant its
//! estimate describes (the horizon for the delay-compensated navigator),
//! sampled every 100 ms and averaged over the seeds, with the 95 %
//! chi-square band of an average over that many seeds; and the NIS of the
//! GPS fixes (position and velocity, 6 degrees of freedom, from the fusion
//! records' innovations and the diagonal of their innovation covariance)
//! averaged over every scored fix, with its band.
//!
//! Estimators are registered in one place, [`estimators`]: adding a row is
//! one line there.

mod check;
pub(crate) mod delay_suite;
mod faults;

use clap::{Parser, ValueEnum};
use delaynav::Navigator;
use delaynav::delay::{CalibrationConfig, DefaultCalibrator};
use delaynav::ekf16::state as ekf16_state;
use delaynav::geo::wrap_pi;
use delaynav::nav::{DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
use delaynav::sensors::{Gps, GpsPosition, Imu, Mag};
use delaynav::sim::Trajectory;
use delaynav::sim::{BoundConfig, BoundMagnetometer, BoundRms, trajectory_bound};
use delaynav::sim::{
    DelayProfile, NoiseFloor, STANDARD_GRAVITY, Scenario, SimConfig, SimEvent, Simulation,
    csv::write_run, delay_bound_s, noise_floor, tilt_heading_error_rad,
};
use delaynav::{
    AugmentedEkf17, AugmentedEkf17Config, Ekf16, Ekf16Config, Estimate, GpsOutcome, Scalar,
};
use nalgebra::{Matrix6, Quaternion, SMatrix, UnitQuaternion, Vector3, Vector6};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

mod fusion_nav;
mod plots;
mod stats;
mod sweep;

use fusion_nav::FusionNav;
use plots::{COLORS, Panel, Series, TRUTH_COLOR};

/// Window of GPS fixes over which the delay bound counts information, µs.
const DELAY_BOUND_WINDOW_US: u64 = 5_000_000;
/// Spacing of the points kept for the plots, µs.
const TRACE_STEP_US: u64 = 20_000;
/// Spacing of the instants at which the NEES is sampled, µs.
const NEES_STEP_US: u64 = 100_000;
/// Degrees of freedom of the NEES (position and velocity) and of the GPS NIS.
const CONSISTENCY_DOF: usize = 6;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ScenarioChoice {
    Low,
    High,
    All,
}

/// Reproduce the paper's simulation tables on the crate's simulator.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Which acceleration scenario to run.
    #[arg(long, value_enum, default_value = "all")]
    scenario: ScenarioChoice,
    /// Number of seeds per scenario [default: 5, quick: 2].
    #[arg(long)]
    seeds: Option<u64>,
    /// First seed; the run uses seeds S, S+1, ...
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of each run, seconds [default: 60, quick: 20].
    #[arg(long)]
    duration: Option<f64>,
    /// True GPS delay, seconds (constant) [default: 0.2, Table 3's maximum].
    #[arg(long)]
    delay: Option<f64>,
    /// Convergence time not scored, seconds.
    #[arg(long, default_value_t = 10.0)]
    skip: f64,
    /// Where to write the JSON results.
    #[arg(long, default_value = "target/reproduce/results.json")]
    json: PathBuf,
    /// Where to write the SVG plots [default: target/reproduce, none with --quick].
    #[arg(long)]
    plots: Option<PathBuf>,
    /// A short run for CI and tests (2 seeds of 20 s, no plots unless --plots).
    #[arg(long)]
    quick: bool,
    /// Also write each scenario's first-seed run as a CSV log under
    /// DIR/<scenario>-seed<S>/; with --delay-trace, the trace's CSV file.
    #[arg(long, value_name = "DIR|FILE")]
    csv: Option<PathBuf>,
    /// Start `proposed` and `aekf17` from the fixed 0.1 s instead of an
    /// offline calibration on a separate run (sec. 2.2.2).
    #[arg(long)]
    no_calibration: bool,
    /// Seeds run in parallel [default: the machine's available parallelism].
    #[arg(long)]
    threads: Option<usize>,
    /// Run a sweep instead of the tables: every estimator and the bound
    /// against one parameter (a table and a plot per scenario).
    #[arg(long, value_enum)]
    sweep: Option<sweep::SweepName>,
    /// Run the fault suite of issue 10 instead (`--duration` scales its 60 s runs).
    #[arg(long)]
    faults: bool,
    /// Run the delay suite of issue 11 instead (see `delay_suite.rs`); writes
    /// `delay_scenarios` to the JSON file.
    #[arg(long)]
    delay_suite: bool,
    /// Write a per-second trace of the delay suite's row ROW (seed --seed,
    /// with --delay-rate-std / --delay-rate-time-constant) as CSV to --csv
    /// (a file here) [default: target/delay-trace/ROW-seedS.csv];
    /// `aekf17_hover` traces AEKF17 (--duration sets the hover's length);
    /// `calibrated_low` and `calibrated_high` trace the runs of
    /// `sigma_coverage`.
    #[arg(long, value_name = "ROW")]
    delay_trace: Option<String>,
    /// With --delay-trace aekf17_hover: AEKF17's `delay_random_walk` [default: its own].
    #[arg(long, value_name = "S_PER_SQRT_S")]
    aekf17_delay_random_walk: Option<f64>,
    /// With --delay-trace aekf17_hover: AEKF17's `accel_smoothing_s` (0: the
    /// paper's last sample) [default: its own].
    #[arg(long, value_name = "S")]
    aekf17_accel_smoothing: Option<f64>,
    /// With --delay-trace: two more delay loops beside the navigator's, fed
    /// the oracle navigator's acceleration and the true acceleration plus
    /// the accelerometer's noise (their estimates as two more columns, the
    /// three RMSEs from 20 s printed).
    #[arg(long)]
    compare_accel: bool,
    /// With --delay-suite: only these rows (comma-separated names) [default: all].
    #[arg(long, value_delimiter = ',', value_name = "ROW,...")]
    rows: Option<Vec<String>>,
    /// With --delay-suite or --delay-trace: the drift-rate state of the `proposed` navigator's
    /// delay loop on, `GainFusionConfig::rate_std` in ms/s, in every row
    /// [default: the loop's, off].
    #[arg(long, value_name = "MS_PER_S")]
    delay_rate_std: Option<f64>,
    /// With --delay-suite or --delay-trace: `GainFusionConfig::rate_time_constant_s`, s, in
    /// every row [default: the loop's].
    #[arg(long, value_name = "S")]
    delay_rate_time_constant: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `process_noise_ms2_per_s` (`q`), ms^2/s, in every row [default: the loop's].
    #[arg(long, value_name = "MS2_PER_S")]
    delay_process_noise: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_window_s` (the horizon innovations' observation), s; 0
    /// turns it off [default: the loop's].
    #[arg(long, value_name = "S")]
    delay_innovation_window: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_noise_scale` [default: the loop's].
    #[arg(long, value_name = "FACTOR")]
    delay_innovation_noise_scale: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_reacquire_sigma` (0: off) [default: the loop's].
    #[arg(long, value_name = "SIGMA")]
    delay_innovation_reacquire_sigma: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_before_lock` on (fuse the innovation windows before
    /// lock too, each when it agrees with the previous one).
    #[arg(long)]
    delay_innovation_before_lock: bool,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `acquisition_motion_exponent` (1 to 4) [default: the loop's].
    #[arg(long, value_name = "EXPONENT")]
    delay_acquisition_exponent: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `smoothing_cutoff_hz` (both accelerations' common low-pass), Hz
    /// [default: the loop's; `adapted_to_gps_rate` rows set their own].
    #[arg(long, value_name = "HZ")]
    delay_smoothing_cutoff: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `innovation_acquire_noise_scale` [default: the loop's].
    #[arg(long, value_name = "FACTOR")]
    delay_innovation_acquire_noise_scale: Option<f64>,
    /// With --delay-suite or --delay-trace: the delay loop's
    /// `measurement_noise_ms2` (the correlation peaks'), ms^2, every axis
    /// [default: the loop's].
    #[arg(long, value_name = "MS2")]
    delay_measurement_noise: Option<f64>,
    /// Run only the bound study instead of the tables: the bound with each
    /// difference to the estimators in turn, beside `oracle` and `proposed`.
    #[arg(long)]
    bound_study: bool,
    /// Prediction rate of the navigator's horizon filter, Hz; 0 predicts at
    /// every IMU sample [default: `DelayCompensatedNavConfig`'s].
    #[arg(long)]
    filter_rate_hz: Option<f64>,
    /// With the default run, --faults or --delay-suite: print every verdict
    /// and exit non-zero when one fails or a figure is NaN (`check.rs`).
    #[arg(long)]
    check: bool,
    /// With --check: rows that fail for a known reason, printed as
    /// `FAIL (known)`; naming a row that does not exist or passes fails.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "ROW,...",
        requires = "check"
    )]
    known_failures: Vec<String>,
}

/// `--filter-rate-hz`, set once from the arguments.
static FILTER_RATE_HZ: std::sync::OnceLock<f64> = std::sync::OnceLock::new();

/// One simulated run, shared by every estimator.
struct RunSetup {
    config: SimConfig,
    events: Vec<SimEvent>,
    skip_us: u64,
    keep_trace: bool,
    /// Where `proposed` and `aekf17` start their delay estimate.
    start: DelayStart,
    /// The closed-form truth, for states a filter reports at a past instant.
    trajectory: Trajectory,
}

impl RunSetup {
    /// NEES of a position-velocity estimate against the truth at its instant.
    fn nees(&self, (t_us, p, v, cov): &PosVelCovariance) -> f64 {
        let truth = self.trajectory.kinematics(*t_us as f64 * 1e-6);
        let mut e = Vector6::zeros();
        e.fixed_rows_mut::<3>(0).copy_from(&(p - truth.position_m));
        e.fixed_rows_mut::<3>(3)
            .copy_from(&(v - truth.velocity_m_s));
        cov.cholesky().map_or(f64::NAN, |c| e.dot(&c.solve(&e)))
    }
}

/// The initial delay of the estimators that estimate it.
#[derive(Debug, Clone, Copy)]
struct DelayStart {
    delay_s: f64,
    /// Initial standard deviation, s; `None` keeps each estimator's default.
    std_s: Option<f64>,
}

/// The uncalibrated start: 100 ms below the default true delay.
const UNCALIBRATED_START: DelayStart = DelayStart {
    delay_s: 0.1,
    std_s: None,
};

/// Seed offset of the calibration run of each seed.
const CALIBRATION_SEED_OFFSET: u64 = 10_000;

/// Length of each calibration run, s, whatever the scored run's length (a
/// 20 s record holds too little motion: two of the scenario's strong
/// manoeuvres need 60 s).
const CALIBRATION_DURATION_S: f64 = 60.0;

/// Offline calibration (sec. 2.2.2) on a separate simulated run with the
/// same sensors and true delay: IMU-only attitude, correlation over +-6 s.
/// The initial standard deviation is one correlation grid sample.
fn calibrate(config: &SimConfig) -> DelayStart {
    let cal_config = CalibrationConfig::<f64>::default();
    let mut calibrator =
        Box::new(DefaultCalibrator::<f64>::new(cal_config).expect("valid calibration config"));
    let events: Vec<SimEvent> = Simulation::new(config.clone())
        .expect("valid calibration run")
        .collect();
    let imu = events.iter().filter_map(|e| match e {
        SimEvent::Imu { sample, .. } => Some(*sample),
        _ => None,
    });
    let gps = events.iter().filter_map(|e| match e {
        SimEvent::Gps { fix, .. } => Some(*fix),
        _ => None,
    });
    match calibrator.calibrate(imu, gps) {
        Ok(c) => DelayStart {
            delay_s: c.delay_s.clamp(0.0, 1.0),
            std_s: Some(1.0 / cal_config.correlation_rate_hz),
        },
        Err(_) => UNCALIBRATED_START,
    }
}

/// Time series of one estimator on one run, for the plots.
#[derive(Default, Clone)]
struct Trace {
    t_s: Vec<f64>,
    /// Roll, pitch, yaw error, degrees.
    attitude_err_deg: Vec<[f64; 3]>,
    /// Estimated pitch, degrees.
    pitch_deg: Vec<f64>,
    delay_s: Vec<f64>,
}

/// RMS errors and cost of one estimator: of one run, or one statistic
/// (mean, interval bound) over the seeds of a scenario.
#[derive(Clone)]
struct Metrics {
    roll_deg: f64,
    pitch_deg: f64,
    yaw_deg: f64,
    /// RMS of the rotation-vector tilt error (`sim::tilt_heading_error_rad`), degrees.
    tilt_deg: f64,
    /// RMS of the rotation-vector heading error, degrees.
    heading_deg: f64,
    vel_m_s: f64,
    pos_m: f64,
    delay_s: Option<f64>,
    gyro_bias_rad_s: [f64; 3],
    accel_bias_g: [f64; 3],
    /// Mean NEES of `[position, velocity]` over the scored NEES instants.
    nees: Option<f64>,
    /// Mean NIS of the GPS fixes fused after the skip.
    nis: Option<f64>,
    us_per_imu_sample: f64,
}

/// The scores of one estimator on one run.
struct RunScore {
    metrics: Metrics,
    trace: Trace,
    /// NEES at every NEES instant after the skip (NaN without an estimate).
    nees_series: Vec<f64>,
    /// Sum and count of the GPS NIS after the skip.
    nis: (f64, usize),
}

/// A registered estimator: its JSON name and how to run it on a setup.
struct Estimator {
    name: &'static str,
    run: fn(&RunSetup) -> RunScore,
}

/// Position-velocity covariance of the 16-state EKF.
fn ekf16_covariance<T: Scalar>(f: &Ekf16<T>) -> Option<PosVelCovariance> {
    Some(pos_vel_block(&f.estimate()?, f.covariance()))
}

/// Position-velocity covariance of the augmented EKF.
fn aekf17_covariance<T: Scalar>(f: &AugmentedEkf17<T>) -> Option<PosVelCovariance> {
    Some(pos_vel_block(&f.estimate()?, f.covariance()))
}

/// Position-velocity covariance of the navigator's horizon EKF, at the
/// horizon (its forward-reckoned present carries no covariance of its own).
fn nav_covariance<T: Scalar>(n: &DelayCompensatedNav<T>) -> Option<PosVelCovariance> {
    Some(pos_vel_block(
        &n.horizon_estimate()?,
        n.horizon_filter().covariance(),
    ))
}

fn run_ekf16<T: Scalar>(s: &RunSetup) -> RunScore {
    let filter = Ekf16::new(ekf16_config::<T>(&s.config)).expect("valid Ekf16 config");
    score(filter, s, ekf16_covariance)
}

fn run_aekf17<T: Scalar>(s: &RunSetup) -> RunScore {
    let mut config = AugmentedEkf17Config::with_nav(ekf16_config::<T>(&s.config));
    config.initial_delay_s = T::lit(s.start.delay_s);
    if let Some(std) = s.start.std_s {
        config.initial_delay_std_s = T::lit(std);
    }
    let filter = AugmentedEkf17::new(config).expect("valid Aekf17 config");
    score(filter, s, aekf17_covariance)
}

fn run_proposed<T: Scalar>(s: &RunSetup) -> RunScore {
    let mode = DelayMode::Estimated {
        initial_s: T::lit(s.start.delay_s),
    };
    score(nav::<T>(&s.config, mode, s.start.std_s), s, nav_covariance)
}

/// Standard deviation of the pre-flight accelerometer bias calibration, g
/// (per axis; the simulator draws biases within +-0.1 g).
const IMU_CALIBRATION_ACCEL_STD_G: f64 = 0.01;
/// Standard deviation of the pre-flight gyro bias calibration, deg/s (per
/// axis; the simulator draws biases within +-0.57 deg/s).
const IMU_CALIBRATION_GYRO_STD_DEG_S: f64 = 0.05;
/// Key of the calibration error's random stream (the simulator's use 1-9).
const IMU_CALIBRATION_STREAM: u64 = 100;

/// A pre-flight IMU bias calibration of the run: the simulator's biases at
/// the first IMU sample plus an error drawn per seed, normal with the
/// standard deviations above. `(accel m/s², gyro rad/s)`.
fn imu_calibration(s: &RunSetup) -> (Vector3<f64>, Vector3<f64>) {
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&s.config.seed.to_le_bytes());
    key[8..16].copy_from_slice(&IMU_CALIBRATION_STREAM.to_le_bytes());
    let mut rng = ChaCha8Rng::from_seed(key);
    // Box-Muller: a standard normal deviate from two uniforms.
    let mut normal = || {
        let u: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
        let v: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let accel_std = IMU_CALIBRATION_ACCEL_STD_G * STANDARD_GRAVITY;
    let gyro_std = IMU_CALIBRATION_GYRO_STD_DEG_S.to_radians();
    let accel_error = Vector3::from_fn(|_, _| accel_std * normal());
    let gyro_error = Vector3::from_fn(|_, _| gyro_std * normal());
    let truth = s.events.iter().find_map(|e| match e {
        SimEvent::Imu { truth, .. } => Some(truth),
        _ => None,
    });
    truth.map_or((accel_error, gyro_error), |t| {
        (
            t.accel_bias_m_s2 + accel_error,
            t.gyro_bias_rad_s + gyro_error,
        )
    })
}

/// `proposed` on a calibrated IMU: its EKF starts from [`imu_calibration`]
/// with the calibration's standard deviations as the bias uncertainty.
fn run_calibrated<T: Scalar>(s: &RunSetup) -> RunScore {
    let mode = DelayMode::Estimated {
        initial_s: T::lit(s.start.delay_s),
    };
    let mut config = nav_config::<T>(&s.config, mode, s.start.std_s);
    let (accel, gyro) = imu_calibration(s);
    config.ekf.initial_accel_bias_m_s2 = accel.map(T::lit);
    config.ekf.initial_gyro_bias_rad_s = gyro.map(T::lit);
    config.ekf.initial_accel_bias_std_m_s2 = T::lit(IMU_CALIBRATION_ACCEL_STD_G * STANDARD_GRAVITY);
    config.ekf.initial_gyro_bias_std_rad_s = T::lit(IMU_CALIBRATION_GYRO_STD_DEG_S.to_radians());
    let nav = DelayCompensatedNav::new(config).expect("valid navigator config");
    score(nav, s, nav_covariance)
}

fn run_oracle<T: Scalar>(s: &RunSetup) -> RunScore {
    let mode = DelayMode::Fixed {
        delay_s: T::lit(s.config.delay.initial_s),
    };
    score(nav::<T>(&s.config, mode, None), s, nav_covariance)
}

/// The linearized bound of the run (`sim::trajectory_bound`) in the
/// estimators' figures: the RMS over the scored samples of its per-time
/// standard deviations.
fn run_bound(s: &RunSetup) -> RunScore {
    linearized(s, BoundConfig::for_sensors(&s.config.sensors))
}

/// The bound of a filter starting from the pre-flight IMU calibration
/// (`calibrated`): the biases' prior is the calibration's uncertainty.
fn run_bound_calibrated(s: &RunSetup) -> RunScore {
    let config = BoundConfig {
        accel_bias_std_m_s2: IMU_CALIBRATION_ACCEL_STD_G * STANDARD_GRAVITY,
        gyro_bias_std_rad_s: IMU_CALIBRATION_GYRO_STD_DEG_S.to_radians(),
        ..BoundConfig::for_sensors(&s.config.sensors)
    };
    linearized(s, config)
}

/// The bound of a filter taking from the magnetometer what the estimators
/// take, the heading of the field de-rotated with its estimated tilt, with
/// the optimal gain throughout.
fn run_bound_filter_heading(s: &RunSetup) -> RunScore {
    let config = BoundConfig {
        mag_tilt_alignment_std_rad: 0.0,
        ..BoundConfig::for_filter(&ekf16_config(&s.config))
    };
    linearized(s, config)
}

/// Not a bound: the same linearized filter with the estimators' own gain on
/// that heading (heading-only once the tilt is known,
/// `BoundConfig::for_filter`), the covariance their gain structure reaches
/// about the truth.
fn run_filter_gain(s: &RunSetup) -> RunScore {
    linearized(s, BoundConfig::for_filter(&ekf16_config(&s.config)))
}

/// `--bound-study`: what each difference between `bound` and the
/// estimators is worth, one at a time (docs/RESULTS.md, "The bound gap").
fn bound_study() -> Vec<Estimator> {
    let row = |name, run| Estimator { name, run };
    vec![
        // The bound's prior before it was taken from the filters' config:
        // heading 0.5 rad, position and velocity the GPS noise.
        row("bound_gps_prior", |s| {
            let sensors = &s.config.sensors;
            linearized(
                s,
                BoundConfig {
                    heading_std_rad: 0.5,
                    position_std_m: sensors.gps_position_var_m2.sqrt(),
                    velocity_std_m_s: sensors.gps_velocity_var_m2_s2.sqrt(),
                    ..BoundConfig::for_sensors(sensors)
                },
            )
        }),
        row("bound", run_bound),
        row("bound_filter_walks", |s| {
            with_filter_walks(s, BoundConfig::for_sensors(&s.config.sensors))
        }),
        row("bound_heading_only", |s| {
            linearized(
                s,
                BoundConfig {
                    magnetometer: BoundMagnetometer::Heading,
                    ..BoundConfig::for_sensors(&s.config.sensors)
                },
            )
        }),
        row("bound_filter_heading", run_bound_filter_heading),
        row("filter_gain", run_filter_gain),
        row("filter_gain_walks", |s| {
            with_filter_walks(s, BoundConfig::for_filter(&ekf16_config(&s.config)))
        }),
        row("bound_known_biases", |s| {
            linearized(
                s,
                BoundConfig {
                    accel_bias_std_m_s2: 0.0,
                    gyro_bias_std_rad_s: 0.0,
                    ..BoundConfig::for_sensors(&s.config.sensors)
                },
            )
        }),
        row("oracle", run_oracle::<f64>),
        row("proposed", run_proposed::<f64>),
    ]
}

/// The bound with the bias random walks the filters are configured with
/// (`Ekf16Config`) instead of the simulator's (constant biases).
fn with_filter_walks(s: &RunSetup, config: BoundConfig) -> RunScore {
    let filter = ekf16_config::<f64>(&s.config);
    let mut sim = s.config.clone();
    sim.sensors.gyro_bias_walk_rad_s_sqrt_s = filter.gyro_bias_random_walk;
    sim.sensors.accel_bias_walk_m_s2_sqrt_s = filter.accel_bias_random_walk;
    linearized_with(s, &sim, config)
}

fn linearized(s: &RunSetup, config: BoundConfig) -> RunScore {
    linearized_with(s, &s.config, config)
}

/// [`linearized`] with the noise of `sim` (the run's events, another model).
fn linearized_with(s: &RunSetup, sim: &SimConfig, config: BoundConfig) -> RunScore {
    let started = Instant::now();
    let bound = trajectory_bound(&s.events, sim, &config).expect("valid bound config");
    let busy = started.elapsed();
    let rms = bound.rms_after(s.skip_us);
    let nan = f64::NAN;
    let g = |r: &BoundRms| r.accel_bias_m_s2 / STANDARD_GRAVITY;
    let metrics = Metrics {
        roll_deg: rms.map_or(nan, |r| r.euler_rad.x.to_degrees()),
        pitch_deg: rms.map_or(nan, |r| r.euler_rad.y.to_degrees()),
        yaw_deg: rms.map_or(nan, |r| r.euler_rad.z.to_degrees()),
        tilt_deg: rms.map_or(nan, |r| r.tilt_rad.to_degrees()),
        heading_deg: rms.map_or(nan, |r| r.heading_rad.to_degrees()),
        vel_m_s: rms.map_or(nan, |r| r.velocity_m_s),
        pos_m: rms.map_or(nan, |r| r.position_m),
        delay_s: None,
        gyro_bias_rad_s: rms.map_or([nan; 3], |r| r.gyro_bias_rad_s.into()),
        accel_bias_g: rms.map_or([nan; 3], |r| g(&r).into()),
        nees: None,
        nis: None,
        us_per_imu_sample: busy.as_secs_f64() * 1e6 / bound.samples.len().max(1) as f64,
    };
    RunScore {
        metrics,
        trace: Trace::default(),
        nees_series: Vec::new(),
        nis: (0.0, 0),
    }
}

/// Every estimator of the comparison, in table order. One line each.
fn estimators() -> Vec<Estimator> {
    let row = |name, run| Estimator { name, run };
    vec![
        row("bound", run_bound),
        row("bound_filter_heading", run_bound_filter_heading),
        row("bound_calibrated", run_bound_calibrated),
        row("ekf16", run_ekf16::<f64>),
        row("aekf17", run_aekf17::<f64>),
        row("proposed", run_proposed::<f64>),
        row("calibrated", run_calibrated::<f64>),
        row("oracle", run_oracle::<f64>),
        row("ekf16_f32", run_ekf16::<f32>),
        row("aekf17_f32", run_aekf17::<f32>),
        row("proposed_f32", run_proposed::<f32>),
        row("fusion_nav", |s| {
            score::<f32, _>(FusionNav::new(&s.config), s, |_| None)
        }),
    ]
}

/// The delay-compensated navigator on the same EKF configuration as `ekf16`:
/// `proposed` estimates the delay (initial std `initial_std_s`, else the
/// loop's default), `oracle` is given the true (constant) one.
fn nav<T: Scalar>(
    sim: &SimConfig,
    mode: DelayMode<T>,
    initial_std_s: Option<f64>,
) -> DelayCompensatedNav<T> {
    DelayCompensatedNav::new(nav_config(sim, mode, initial_std_s)).expect("valid navigator config")
}

/// The configuration of [`nav`].
fn nav_config<T: Scalar>(
    sim: &SimConfig,
    mode: DelayMode<T>,
    initial_std_s: Option<f64>,
) -> DelayCompensatedNavConfig<T> {
    let mut config = DelayCompensatedNavConfig {
        ekf: ekf16_config::<T>(sim),
        mode,
        imu_rate_hz: T::lit(sim.sensors.imu_rate_hz),
        ..DelayCompensatedNavConfig::default()
    };
    if let Some(std) = initial_std_s {
        config.delay_loop.fusion.initial_std_s = T::lit(std);
    }
    if let Some(&rate) = FILTER_RATE_HZ.get() {
        config.filter_rate_hz = T::lit(rate);
    }
    // The loop's defaults are those of 10 Hz GPS; at another simulated rate
    // (the gps_rate sweep) it is configured for that rate, as a user would.
    let gps_rate_hz = sim.sensors.gps_rate_hz;
    if gps_rate_hz != 10.0
        && let Ok(adapted) = config.delay_loop.adapted_to_gps_rate(T::lit(gps_rate_hz))
    {
        config.delay_loop = adapted;
    }
    config
}

/// The 16-state EKF configured with the simulator's own noise, field and
/// bias spread (`SensorConfig::ekf16_config`).
fn ekf16_config<T: Scalar>(sim: &SimConfig) -> Ekf16Config<T> {
    sim.sensors.ekf16_config()
}

/// Root mean square accumulator.
#[derive(Default, Clone, Copy)]
struct Rms {
    sum_sq: f64,
    n: usize,
}

impl Rms {
    fn add(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.n += 1;
    }
    fn value(self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
}

/// What a filter reports about its own position and velocity error: the
/// instant its estimate describes, the estimate, and the 6x6 covariance of
/// `[position, velocity]` (NED, m and m/s).
type PosVelCovariance = (u64, Vector3<f64>, Vector3<f64>, Matrix6<f64>);

/// The `[position, velocity]` block of a 16- (or 17-) state covariance in
/// `Ekf16`'s state order (q0..q3, position, velocity, biases[, delay]).
fn pos_vel_block<T: Scalar, const N: usize>(
    estimate: &Estimate<T>,
    p: &SMatrix<T, N, N>,
) -> PosVelCovariance {
    (
        estimate.t_us,
        estimate.position_ned_m.map(T::as_f64),
        estimate.velocity_ned_m_s.map(T::as_f64),
        p.fixed_view::<6, 6>(ekf16_state::POS, ekf16_state::POS)
            .map(T::as_f64),
    )
}

/// The simulator's samples in the estimator's float type.
fn imu_as<T: Scalar>(s: &Imu<f64>) -> Imu<T> {
    Imu {
        t_us: s.t_us,
        gyro_rad_s: s.gyro_rad_s.map(T::lit),
        accel_m_s2: s.accel_m_s2.map(T::lit),
    }
}

fn mag_as<T: Scalar>(m: &Mag<f64>) -> Mag<T> {
    Mag {
        t_us: m.t_us,
        field_body: m.field_body.map(T::lit),
    }
}

fn gps_as<T: Scalar>(g: &Gps<f64>) -> Gps<T> {
    Gps {
        t_us: g.t_us,
        position: match g.position {
            GpsPosition::Ned(p) => GpsPosition::Ned(p.map(T::lit)),
            GpsPosition::Geodetic(p) => GpsPosition::Geodetic(p),
        },
        velocity_ned_m_s: g.velocity_ned_m_s.map(T::lit),
        horizontal_accuracy_m: g.horizontal_accuracy_m.map(T::lit),
        vertical_accuracy_m: g.vertical_accuracy_m.map(T::lit),
        speed_accuracy_m_s: g.speed_accuracy_m_s.map(T::lit),
    }
}

/// Normalized innovation squared of a GPS fusion, position and velocity
/// (6 degrees of freedom), from the records' innovations and the diagonal
/// of their innovation covariance.
fn gps_nis<T: Scalar>(outcome: &GpsOutcome<T>) -> Option<f64> {
    let GpsOutcome::Fused { position, velocity } = outcome else {
        return None;
    };
    let mut nis = 0.0;
    for r in [position, velocity] {
        for i in 0..3 {
            let s = r.innovation_variance[i].as_f64();
            if s.is_nan() || s <= 0.0 {
                return None;
            }
            nis += r.innovation[i].as_f64().powi(2) / s;
        }
    }
    Some(nis)
}

/// The NEES instants: the first IMU sample at or after each `50 ms + k 100 ms`
/// (half-way between two 10 Hz fixes), the same on every seed.
struct NeesClock {
    next_us: u64,
}

impl NeesClock {
    fn new() -> Self {
        Self {
            next_us: NEES_STEP_US / 2,
        }
    }

    /// Whether the sample at `t_us` is an instant (call once per IMU sample).
    fn tick(&mut self, t_us: u64) -> bool {
        if t_us < self.next_us {
            return false;
        }
        while self.next_us <= t_us {
            self.next_us += NEES_STEP_US;
        }
        true
    }
}

/// Feeds a run to a navigator in float type `T`, timing only its own calls,
/// and scores its estimate against the truth at every IMU sample after the
/// skip; `covariance` reads the filter's position-velocity covariance for
/// the NEES.
fn score<T: Scalar, N: Navigator<T>>(
    mut nav: N,
    setup: &RunSetup,
    covariance: impl Fn(&N) -> Option<PosVelCovariance>,
) -> RunScore {
    let mut euler = [Rms::default(); 3];
    let (mut tilt, mut heading) = (Rms::default(), Rms::default());
    let (mut vel, mut pos, mut delay) = (Rms::default(), Rms::default(), Rms::default());
    let mut gyro_bias = [Rms::default(); 3];
    let mut accel_bias = [Rms::default(); 3];
    let mut has_delay = false;
    let mut missing = 0usize;
    let mut busy = std::time::Duration::ZERO;
    let mut imu_samples = 0usize;
    let mut trace = Trace::default();
    let mut nees_series = Vec::new();
    let (mut nis_sum, mut nis_count) = (0.0, 0usize);
    let mut nees_clock = NeesClock::new();
    for event in &setup.events {
        // Conversion to `T` happens outside the timed call.
        let converted = match event {
            SimEvent::Imu { sample, .. } => Sample::Imu(imu_as::<T>(sample)),
            SimEvent::Mag(m) => Sample::Mag(mag_as::<T>(m)),
            SimEvent::Gps { fix, .. } => Sample::Gps(gps_as::<T>(fix)),
        };
        let start = Instant::now();
        // Refusals are the estimator's business (it counts them); scoring
        // goes on with whatever estimate it holds.
        let outcome = match &converted {
            Sample::Imu(s) => {
                let _ = nav.push_imu(s);
                None
            }
            Sample::Mag(m) => {
                let _ = nav.push_mag(m);
                None
            }
            Sample::Gps(g) => nav.push_gps(g).ok(),
        };
        busy += start.elapsed();
        if let Some(nis) = outcome.as_ref().and_then(gps_nis)
            && event.t_us() >= setup.skip_us
        {
            nis_sum += nis;
            nis_count += 1;
        }
        let SimEvent::Imu { truth, .. } = event else {
            continue;
        };
        imu_samples += 1;
        let nees_instant = nees_clock.tick(truth.t_us);
        if truth.t_us < setup.skip_us && !setup.keep_trace {
            continue;
        }
        let Some(est) = nav.estimate() else {
            if truth.t_us >= setup.skip_us {
                missing += 1;
                if nees_instant {
                    nees_series.push(f64::NAN);
                }
            }
            continue;
        };
        let attitude = UnitQuaternion::new_normalize(Quaternion::from(
            est.attitude.quaternion().coords.map(T::as_f64),
        ));
        let e = est.euler_rad().map(T::as_f64);
        let err_deg: [f64; 3] =
            core::array::from_fn(|i| wrap_pi(e[i] - truth.euler_rad[i]).to_degrees());
        let delay_err = est.delay_s.map(|d| d.as_f64() - truth.gps_delay_s);
        if setup.keep_trace && truth.t_us.is_multiple_of(TRACE_STEP_US) {
            trace.t_s.push(truth.t_us as f64 * 1e-6);
            trace.attitude_err_deg.push(err_deg);
            trace.pitch_deg.push(e[1].to_degrees());
            trace.delay_s.push(est.delay_s.map_or(f64::NAN, T::as_f64));
        }
        if truth.t_us < setup.skip_us {
            continue;
        }
        if nees_instant {
            nees_series.push(covariance(&nav).map_or(f64::NAN, |c| setup.nees(&c)));
        }
        let (tilt_rad, heading_rad) = tilt_heading_error_rad(&attitude, &truth.attitude);
        tilt.add(tilt_rad.to_degrees());
        heading.add(heading_rad.to_degrees());
        for i in 0..3 {
            euler[i].add(err_deg[i]);
            gyro_bias[i].add(est.gyro_bias_rad_s[i].as_f64() - truth.gyro_bias_rad_s[i]);
            accel_bias[i].add(
                (est.accel_bias_m_s2[i].as_f64() - truth.accel_bias_m_s2[i]) / STANDARD_GRAVITY,
            );
        }
        vel.add((est.velocity_ned_m_s.map(T::as_f64) - truth.velocity_m_s).norm());
        pos.add((est.position_ned_m.map(T::as_f64) - truth.position_m).norm());
        if let Some(d) = delay_err {
            has_delay = true;
            delay.add(d);
        }
    }
    // An estimator without an estimate after the convergence time fails the run.
    let penalty = if missing > 0 { f64::NAN } else { 0.0 };
    let finite_nees: Vec<f64> = nees_series
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    let metrics = Metrics {
        roll_deg: euler[0].value() + penalty,
        pitch_deg: euler[1].value() + penalty,
        yaw_deg: euler[2].value() + penalty,
        tilt_deg: tilt.value() + penalty,
        heading_deg: heading.value() + penalty,
        vel_m_s: vel.value() + penalty,
        pos_m: pos.value() + penalty,
        delay_s: has_delay.then(|| delay.value() + penalty),
        gyro_bias_rad_s: gyro_bias.map(|r| r.value() + penalty),
        accel_bias_g: accel_bias.map(|r| r.value() + penalty),
        nees: (!finite_nees.is_empty())
            .then(|| finite_nees.iter().sum::<f64>() / finite_nees.len() as f64 + penalty),
        nis: (nis_count > 0).then(|| nis_sum / nis_count as f64 + penalty),
        us_per_imu_sample: busy.as_secs_f64() * 1e6 / imu_samples.max(1) as f64,
    };
    RunScore {
        metrics,
        trace,
        nees_series,
        nis: (nis_sum, nis_count),
    }
}

/// One simulated sample converted to the estimator's float type.
enum Sample<T: Scalar> {
    Imu(Imu<T>),
    Mag(Mag<T>),
    Gps(Gps<T>),
}

/// Median of finite values; NaN when any is not finite (a failed run shows).
fn median(xs: Vec<f64>) -> f64 {
    if xs.iter().any(|x| !x.is_finite()) {
        return f64::NAN;
    }
    median_ordered(xs)
}

/// Median in `f64::total_cmp` order (infinities sort to the ends); NaN for
/// no values.
pub(crate) fn median_ordered(mut xs: Vec<f64>) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// One statistic over the seeds of every figure of an estimator.
fn metrics_over(runs: &[Metrics], stat: &dyn Fn(&[f64]) -> f64) -> Metrics {
    let m = |f: &dyn Fn(&Metrics) -> f64| stat(&runs.iter().map(f).collect::<Vec<_>>());
    let opt = |f: &dyn Fn(&Metrics) -> Option<f64>| {
        f(&runs[0])
            .is_some()
            .then(|| m(&|r| f(r).unwrap_or(f64::NAN)))
    };
    Metrics {
        roll_deg: m(&|r| r.roll_deg),
        pitch_deg: m(&|r| r.pitch_deg),
        yaw_deg: m(&|r| r.yaw_deg),
        tilt_deg: m(&|r| r.tilt_deg),
        heading_deg: m(&|r| r.heading_deg),
        vel_m_s: m(&|r| r.vel_m_s),
        pos_m: m(&|r| r.pos_m),
        delay_s: opt(&|r| r.delay_s),
        gyro_bias_rad_s: core::array::from_fn(|i| m(&|r| r.gyro_bias_rad_s[i])),
        accel_bias_g: core::array::from_fn(|i| m(&|r| r.accel_bias_g[i])),
        nees: opt(&|r| r.nees),
        nis: opt(&|r| r.nis),
        us_per_imu_sample: m(&|r| r.us_per_imu_sample),
    }
}

/// Mean over the seeds of every figure, the bounds of its 95 %
/// t-interval (`stats::mean_ci95`), and its median.
struct Summary {
    mean: Metrics,
    lo: Metrics,
    hi: Metrics,
    median: Metrics,
}

fn summarize(runs: &[Metrics]) -> Summary {
    Summary {
        mean: metrics_over(runs, &|xs| stats::mean_ci95(xs).0),
        lo: metrics_over(runs, &|xs| stats::mean_ci95(xs).1),
        hi: metrics_over(runs, &|xs| stats::mean_ci95(xs).2),
        median: metrics_over(runs, &|xs| median(xs.to_vec())),
    }
}

/// Filter consistency of one estimator over the seeds of a scenario.
struct Consistency {
    /// Time average of the seed-averaged NEES (position and velocity).
    nees_mean: f64,
    /// 95 % band of a seed-averaged NEES at one instant.
    nees_band: (f64, f64),
    /// Share of the NEES instants whose seed average lies in the band.
    nees_in_band: f64,
    /// Mean GPS NIS over every scored fix of every seed.
    nis_mean: f64,
    /// 95 % band of that mean (innovations of a consistent filter are white).
    nis_band: (f64, f64),
}

fn consistency(scores: &[RunScore]) -> Consistency {
    let instants = scores
        .iter()
        .map(|s| s.nees_series.len())
        .min()
        .unwrap_or(0);
    let seeds = scores.len();
    let averaged: Vec<f64> = (0..instants)
        .map(|k| scores.iter().map(|s| s.nees_series[k]).sum::<f64>() / seeds as f64)
        .collect();
    let finite: Vec<f64> = averaged.iter().copied().filter(|x| x.is_finite()).collect();
    let nees_band = stats::chi2_band95(CONSISTENCY_DOF, seeds);
    let nees_mean = if finite.is_empty() || finite.len() < averaged.len() {
        f64::NAN
    } else {
        finite.iter().sum::<f64>() / finite.len() as f64
    };
    let inside = finite
        .iter()
        .filter(|x| (nees_band.0..=nees_band.1).contains(*x))
        .count();
    let (nis_sum, nis_count) = scores
        .iter()
        .fold((0.0, 0), |(s, n), r| (s + r.nis.0, n + r.nis.1));
    Consistency {
        nees_mean,
        nees_band,
        nees_in_band: inside as f64 / averaged.len().max(1) as f64,
        nis_mean: if nis_count > 0 {
            nis_sum / nis_count as f64
        } else {
            f64::NAN
        },
        nis_band: stats::chi2_band95(CONSISTENCY_DOF, nis_count),
    }
}

/// The paper's Table 6 for a scenario: (proposed, AEKF) per row, in the
/// order pitch, roll, yaw, velocity, position, delay.
fn paper_table6(scenario: Scenario) -> [(f64, f64); 6] {
    match scenario {
        Scenario::Low => [
            (0.059, 0.2237),
            (0.0616, 0.2868),
            (0.181, 0.3116),
            (0.0163, 0.0229),
            (0.381, 0.4462),
            (0.000678, 0.00396),
        ],
        Scenario::High => [
            (0.0878, 1.1467),
            (0.1276, 0.8195),
            (0.1644, 1.0829),
            (0.0192, 0.0425),
            (0.0344, 0.4896),
            (0.000492, 0.00506),
        ],
    }
}

/// The paper's Table 5 (scenario not stated): (EKF without delay handling,
/// proposed) for gyro x, y, z (rad/s) and accelerometer x, y, z (g).
const PAPER_TABLE5: [(f64, f64); 6] = [
    (0.000945, 0.000112),
    (0.000675, 0.000075),
    (0.000130, 0.000080),
    (0.055240, 0.009653),
    (0.057460, 0.006093),
    (0.043000, 0.005345),
];

/// Everything measured in one scenario.
struct ScenarioResult {
    scenario: Scenario,
    true_delay_s: f64,
    delay_bound_s: f64,
    floor_hover: NoiseFloor,
    summaries: Vec<(&'static str, Summary)>,
    consistency: Vec<(&'static str, Consistency)>,
    /// Every seed's metrics per estimator, in registry order (paired comparisons).
    per_seed: Vec<(&'static str, Vec<Metrics>)>,
    /// First seed's traces per estimator, and the truth's pitch and delay.
    traces: Vec<(&'static str, Trace)>,
    truth_trace: Vec<(f64, f64, f64)>,
    /// Calibrated delay per seed, s (empty with `--no-calibration`).
    calibrated_delays_s: Vec<f64>,
}

impl ScenarioResult {
    /// RMS error of the calibrated delays, s.
    fn calibration_rms_error_s(&self) -> Option<f64> {
        (!self.calibrated_delays_s.is_empty()).then(|| {
            let n = self.calibrated_delays_s.len() as f64;
            (self
                .calibrated_delays_s
                .iter()
                .map(|d| (d - self.true_delay_s).powi(2))
                .sum::<f64>()
                / n)
                .sqrt()
        })
    }
}

/// The paired comparisons printed and written: `proposed` against each.
const PAIRED_AGAINST: [&str; 4] = ["oracle", "aekf17", "ekf16", "calibrated"];

/// Figures of the paired comparison: the errors of [`FIGURES`] (roll to position).
const PAIRED_FIGURES: &[Figure] = FIGURES.split_at(7).0;

/// A mean over the seeds with its 95 % interval, `(mean, lo, hi)`.
type MeanCi = (f64, f64, f64);

impl ScenarioResult {
    /// Per figure, the mean over the seeds of `proposed - other` on the same
    /// seed and its 95 % t-interval, `(mean, lo, hi)`; `None` when a row is
    /// missing.
    fn paired(&self, other: &str) -> Option<Vec<(&'static str, MeanCi)>> {
        let runs = |name: &str| {
            self.per_seed
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, m)| m)
        };
        let (p, o) = (runs("proposed")?, runs(other)?);
        Some(
            PAIRED_FIGURES
                .iter()
                .map(|(name, get)| {
                    let d: Vec<f64> = p
                        .iter()
                        .zip(o)
                        .map(|(a, b)| get(a).unwrap_or(f64::NAN) - get(b).unwrap_or(f64::NAN))
                        .collect();
                    (*name, stats::mean_ci95(&d))
                })
                .collect(),
        )
    }
}

/// A mean and the half-width of its 95 % interval.
fn fmt_ci(mean: f64, lo: f64, hi: f64) -> String {
    let half = 0.5 * (hi - lo);
    // The bound is the same on every seed: no interval to show.
    if half.abs() <= 1e-9 * mean.abs() {
        return fmt_value(mean);
    }
    if mean.is_finite() && lo.is_finite() && hi.is_finite() {
        format!("{} ±{}", fmt_value(mean), fmt_short(half))
    } else {
        fmt_value(mean)
    }
}

/// Two significant digits.
fn fmt_short(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x.abs() >= 0.01 {
        format!("{x:.3}")
    } else {
        format!("{x:.1e}")
    }
}

fn fmt_value(x: f64) -> String {
    if !x.is_finite() {
        "fail".into()
    } else if x == 0.0 {
        "0".into()
    } else if x.abs() >= 0.01 {
        format!("{x:.4}")
    } else {
        format!("{x:.2e}")
    }
}

/// One row of the RMSE table: label, how to read it, the paper's
/// (proposed, AEKF), and the floor column.
type TableRow<'a> = (
    &'a str,
    &'a dyn Fn(&Metrics) -> Option<f64>,
    Option<(f64, f64)>,
    String,
);

fn print_tables(results: &[ScenarioResult], seeds: usize, duration_s: f64, skip_s: f64) -> String {
    let mut out = String::new();
    for r in results {
        let names: Vec<&str> = r.summaries.iter().map(|(n, _)| *n).collect();
        let _ = writeln!(
            out,
            "\n### `{}`: acceleration limit {} m/s², true delay {} s; mean ±95 % t-interval over {} seeds of the RMSE after {} s of {} s\n",
            r.scenario.name(),
            r.scenario.accel_limit_m_s2(),
            r.true_delay_s,
            seeds,
            skip_s,
            duration_s
        );
        let start = match r.calibration_rms_error_s() {
            Some(rms) => format!(
                "`proposed`, `calibrated` and `aekf17` start from an offline delay calibration on a separate \
                 {CALIBRATION_DURATION_S} s run (seed + {CALIBRATION_SEED_OFFSET}): {} s per seed, \
                 RMS error {:.2} ms",
                r.calibrated_delays_s
                    .iter()
                    .map(|d| format!("{d:.4}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                rms * 1e3
            ),
            None => format!(
                "`proposed` and `aekf17` start from {} s, uncalibrated",
                UNCALIBRATED_START.delay_s
            ),
        };
        let _ = writeln!(out, "{start}\n");
        let _ = writeln!(
            out,
            "| RMSE | {} | paper proposed | paper AEKF | floor |",
            names.join(" | ")
        );
        let _ = writeln!(out, "|---|{}---|---|---|", "---|".repeat(names.len()));
        let paper = paper_table6(r.scenario);
        let f = &r.floor_hover;
        let rows: [TableRow; 8] = [
            (
                "pitch (deg)",
                &|s| Some(s.pitch_deg),
                Some(paper[0]),
                fmt_value(f.tilt_rad.to_degrees()),
            ),
            (
                "roll (deg)",
                &|s| Some(s.roll_deg),
                Some(paper[1]),
                fmt_value(f.tilt_rad.to_degrees()),
            ),
            (
                "yaw (deg)",
                &|s| Some(s.yaw_deg),
                Some(paper[2]),
                format!(
                    "{} (mag only)",
                    fmt_value(f.heading_mag_only_rad.to_degrees())
                ),
            ),
            (
                "tilt (deg)",
                &|s| Some(s.tilt_deg),
                None,
                fmt_value(f.tilt_rad.to_degrees()),
            ),
            (
                "heading (deg)",
                &|s| Some(s.heading_deg),
                None,
                format!(
                    "{} (mag only)",
                    fmt_value(f.heading_mag_only_rad.to_degrees())
                ),
            ),
            (
                "velocity (m/s)",
                &|s| Some(s.vel_m_s),
                Some(paper[3]),
                fmt_value(f.velocity_norm_m_s),
            ),
            (
                "position (m)",
                &|s| Some(s.pos_m),
                Some(paper[4]),
                fmt_value(f.position_norm_m),
            ),
            (
                "delay (s)",
                &|s| s.delay_s,
                Some(paper[5]),
                format!("{} (bound)", fmt_value(r.delay_bound_s)),
            ),
        ];
        for (label, get, paper, floor) in rows {
            let ours: Vec<String> = r
                .summaries
                .iter()
                .map(|(_, s)| {
                    get(&s.mean).map_or("-".into(), |m| {
                        fmt_ci(
                            m,
                            get(&s.lo).unwrap_or(f64::NAN),
                            get(&s.hi).unwrap_or(f64::NAN),
                        )
                    })
                })
                .collect();
            let (p_prop, p_aekf) = paper.map_or(("-".into(), "-".into()), |(p, a)| {
                (fmt_value(p), fmt_value(a))
            });
            let _ = writeln!(
                out,
                "| {label} | {} | {p_prop} | {p_aekf} | {floor} |",
                ours.join(" | "),
            );
        }
        let timing: Vec<String> = r
            .summaries
            .iter()
            .map(|(_, s)| format!("{:.2}", s.mean.us_per_imu_sample))
            .collect();
        let _ = writeln!(out, "| µs per IMU sample | {} | | | |", timing.join(" | "));
        // Issue 11 states the calibrated runs' delay RMSE as medians.
        let delay_medians: Vec<String> = r
            .summaries
            .iter()
            .filter_map(|(name, s)| Some(format!("{name} {:.2}", s.median.delay_s? * 1e3)))
            .collect();
        let _ = writeln!(
            out,
            "\nDelay RMSE, median over the seeds (ms): {}",
            delay_medians.join(", ")
        );

        let _ = writeln!(
            out,
            "\nBias RMSE (`{}`; the paper's Table 5 beside, scenario not stated there)\n",
            r.scenario.name()
        );
        let _ = writeln!(
            out,
            "| bias | {} | paper EKF | paper proposed |",
            names.join(" | ")
        );
        let _ = writeln!(out, "|---|{}---|---|", "---|".repeat(names.len()));
        let labels = [
            "gyro x (rad/s)",
            "gyro y (rad/s)",
            "gyro z (rad/s)",
            "accel x (g)",
            "accel y (g)",
            "accel z (g)",
        ];
        for (i, label) in labels.iter().enumerate() {
            let ours: Vec<String> = r
                .summaries
                .iter()
                .map(|(_, s)| {
                    let get = |m: &Metrics| {
                        if i < 3 {
                            m.gyro_bias_rad_s[i]
                        } else {
                            m.accel_bias_g[i - 3]
                        }
                    };
                    fmt_ci(get(&s.mean), get(&s.lo), get(&s.hi))
                })
                .collect();
            let (p_ekf, p_prop) = PAPER_TABLE5[i];
            let _ = writeln!(
                out,
                "| {label} | {} | {} | {} |",
                ours.join(" | "),
                fmt_value(p_ekf),
                fmt_value(p_prop)
            );
        }
        let _ = writeln!(
            out,
            "\nPaired differences (`{}`): `proposed` minus each row on the same seeds, mean \
             ±95 % t-interval; negative: `proposed` lower\n",
            r.scenario.name()
        );
        let _ = writeln!(
            out,
            "| proposed minus | {} |",
            PAIRED_FIGURES
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(out, "|---|{}", "---|".repeat(PAIRED_FIGURES.len()));
        for other in PAIRED_AGAINST {
            if let Some(diffs) = r.paired(other) {
                let cells: Vec<String> = diffs
                    .iter()
                    .map(|(_, (m, lo, hi))| fmt_ci(*m, *lo, *hi))
                    .collect();
                let _ = writeln!(out, "| {other} | {} |", cells.join(" | "));
            }
        }
        let _ = writeln!(
            out,
            "\nConsistency (`{}`): NEES of [position, velocity] (6 dof, the filter's own covariance \
             at the instant its estimate describes), every 100 ms, averaged over the seeds; GPS NIS \
             (6 dof, diagonal of S) over every scored fix\n",
            r.scenario.name()
        );
        let _ = writeln!(
            out,
            "| estimator | NEES mean | NEES 95 % band | instants in band | NIS mean | NIS 95 % band |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|");
        for (name, c) in &r.consistency {
            if c.nees_mean.is_nan() && c.nis_mean.is_nan() && c.nis_band.0.is_nan() {
                // The bound: no estimate, no innovations.
                continue;
            }
            let _ = writeln!(
                out,
                "| {name} | {} | [{:.2}, {:.2}] | {:.0} % | {} | [{:.2}, {:.2}] |",
                fmt_value(c.nees_mean),
                c.nees_band.0,
                c.nees_band.1,
                100.0 * c.nees_in_band,
                fmt_value(c.nis_mean),
                c.nis_band.0,
                c.nis_band.1
            );
        }
    }
    let _ = writeln!(
        out,
        "\nfloor: steady-state error of an ideal filter with this noise at hover (docs/RESULTS.md); \
         delay bound: RMS over the scored fixes of 1/sqrt(sum |a|²/σv²) over the last 5 s of fixes."
    );
    out
}

fn json_number(x: f64) -> Value {
    if x.is_finite() { json!(x) } else { Value::Null }
}

fn json_pair((lo, hi): (f64, f64)) -> Value {
    json!([json_number(lo), json_number(hi)])
}

/// The scalar figures of an entry: JSON name and how to read it.
type Figure = (&'static str, fn(&Metrics) -> Option<f64>);

const FIGURES: [Figure; 10] = [
    ("roll_deg", |m| Some(m.roll_deg)),
    ("pitch_deg", |m| Some(m.pitch_deg)),
    ("yaw_deg", |m| Some(m.yaw_deg)),
    ("tilt_deg", |m| Some(m.tilt_deg)),
    ("heading_deg", |m| Some(m.heading_deg)),
    ("vel_m_s", |m| Some(m.vel_m_s)),
    ("pos_m", |m| Some(m.pos_m)),
    ("delay_s", |m| m.delay_s),
    ("nis_run_mean", |m| m.nis),
    ("us_per_imu_sample", |m| Some(m.us_per_imu_sample)),
];

/// One estimator's entry: every figure's mean over the seeds and, as
/// `<name>_ci95`, its 95 % t-interval; `delay_s_median`, the delay RMSE's
/// median over the seeds.
fn estimator_json(s: &Summary) -> serde_json::Map<String, Value> {
    let mut entry = serde_json::Map::new();
    for (name, get) in FIGURES {
        entry.insert(name.into(), get(&s.mean).map_or(Value::Null, json_number));
        let ci = match (get(&s.lo), get(&s.hi)) {
            (Some(lo), Some(hi)) => json_pair((lo, hi)),
            _ => Value::Null,
        };
        entry.insert(format!("{name}_ci95"), ci);
    }
    entry.insert(
        "delay_s_median".into(),
        s.median.delay_s.map_or(Value::Null, json_number),
    );
    type Biases = fn(&Metrics) -> [f64; 3];
    let biases: [(&str, Biases); 2] = [
        ("gyro_bias_rad_s", |m| m.gyro_bias_rad_s),
        ("accel_bias_g", |m| m.accel_bias_g),
    ];
    for (name, get) in biases {
        entry.insert(name.into(), json!(get(&s.mean).map(json_number)));
        let (lo, hi) = (get(&s.lo), get(&s.hi));
        let ci: Vec<Value> = (0..3).map(|i| json_pair((lo[i], hi[i]))).collect();
        entry.insert(format!("{name}_ci95"), Value::Array(ci));
    }
    entry
}

fn to_json(results: &[ScenarioResult], seeds: &[u64], duration_s: f64, skip_s: f64) -> Value {
    let scenarios: Vec<Value> = results
        .iter()
        .map(|r| {
            let mut estimators = serde_json::Map::new();
            for ((name, s), (_, c)) in r.summaries.iter().zip(&r.consistency) {
                let mut entry = estimator_json(s);
                entry.insert("nees_mean".into(), json_number(c.nees_mean));
                entry.insert("nees_band95".into(), json_pair(c.nees_band));
                entry.insert("nees_in_band_fraction".into(), json_number(c.nees_in_band));
                entry.insert("nis_mean".into(), json_number(c.nis_mean));
                entry.insert("nis_band95".into(), json_pair(c.nis_band));
                estimators.insert((*name).into(), Value::Object(entry));
            }
            let f = &r.floor_hover;
            let mut paired = serde_json::Map::new();
            for other in PAIRED_AGAINST {
                if let Some(diffs) = r.paired(other) {
                    let entry: serde_json::Map<String, Value> = diffs
                        .iter()
                        .map(|(n, (m, lo, hi))| {
                            (
                                (*n).to_string(),
                                json!({"mean": json_number(*m), "ci95": json_pair((*lo, *hi))}),
                            )
                        })
                        .collect();
                    paired.insert(format!("proposed_minus_{other}"), Value::Object(entry));
                }
            }
            json!({
                "name": r.scenario.name(),
                "paired": paired,
                "accel_limit_m_s2": r.scenario.accel_limit_m_s2(),
                "true_delay_s": r.true_delay_s,
                "delay_bound_s": json_number(r.delay_bound_s),
                "calibrated_delay_s": r.calibrated_delays_s,
                "calibration_rms_error_s": r.calibration_rms_error_s().map_or(Value::Null, json_number),
                "noise_floor": {
                    "tilt_deg": f.tilt_rad.to_degrees(),
                    "vel_m_s": f.velocity_norm_m_s,
                    "pos_m": f.position_norm_m,
                    "heading_mag_only_deg": f.heading_mag_only_rad.to_degrees(),
                },
                "estimators": estimators,
            })
        })
        .collect();
    json!({
        "duration_s": duration_s,
        "skip_s": skip_s,
        "seeds": seeds,
        "scenarios": scenarios,
    })
}

/// Figures 5 and 6: true and estimated pitch, attitude errors, delay estimate.
fn write_plots(dir: &Path, r: &ScenarioResult) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    let truth_t: Vec<f64> = r.truth_trace.iter().map(|p| p.0).collect();
    let mut pitch = Panel {
        title: "pitch (deg): truth and estimates".into(),
        series: vec![Series {
            name: "truth",
            color: TRUTH_COLOR,
            x: &truth_t,
            y: r.truth_trace.iter().map(|p| p.1).collect(),
        }],
    };
    let mut errors: Vec<Panel> = ["roll", "pitch", "yaw"]
        .iter()
        .map(|axis| Panel {
            title: format!("{axis} error (deg)"),
            series: Vec::new(),
        })
        .collect();
    let mut delay = Panel {
        title: "GPS delay (s): truth and estimates".into(),
        series: vec![Series {
            name: "truth",
            color: TRUTH_COLOR,
            x: &truth_t,
            y: r.truth_trace.iter().map(|p| p.2).collect(),
        }],
    };
    let plotted = r.traces.iter().filter(|(_, t)| !t.t_s.is_empty());
    for (k, (name, trace)) in plotted.enumerate() {
        let color = COLORS[k % COLORS.len()];
        pitch.series.push(Series {
            name,
            color,
            x: &trace.t_s,
            y: trace.pitch_deg.clone(),
        });
        for (axis, panel) in errors.iter_mut().enumerate() {
            panel.series.push(Series {
                name,
                color,
                x: &trace.t_s,
                y: trace.attitude_err_deg.iter().map(|e| e[axis]).collect(),
            });
        }
        if trace.delay_s.iter().any(|d| d.is_finite()) {
            delay.series.push(Series {
                name,
                color,
                x: &trace.t_s,
                y: trace.delay_s.clone(),
            });
        }
    }
    let name = r.scenario.name();
    let attitude_path = dir.join(format!("{name}-attitude.svg"));
    let mut panels = vec![pitch];
    panels.extend(errors);
    let title = format!("scenario {name}: attitude (first seed)");
    plots::panels(&attitude_path, &title, &panels)?;
    let delay_path = dir.join(format!("{name}-delay.svg"));
    let title = format!("scenario {name}: GPS delay (first seed)");
    plots::panels(&delay_path, &title, &[delay])?;
    Ok(vec![attitude_path, delay_path])
}

/// The simulation of one scenario and seed with the run's options.
fn sim_config(scenario: Scenario, seed: u64, duration_s: f64, delay_s: Option<f64>) -> SimConfig {
    let mut config = SimConfig {
        duration_s,
        ..SimConfig::for_scenario(scenario, seed)
    };
    if let Some(d) = delay_s {
        config.delay = DelayProfile::constant(d);
    }
    config
}

/// What one seed of a scenario gives.
struct SeedResult {
    delay_bound_s: f64,
    calibrated_delay_s: Option<f64>,
    /// One score per registered estimator, in registry order.
    scores: Vec<RunScore>,
    /// The truth's pitch and delay, for the plots (first seed only).
    truth_trace: Vec<(f64, f64, f64)>,
}

/// Each GPS fix's receive time (us) and the true acceleration at its
/// validity: what [`delay_bound_s`] reads.
fn fix_accelerations(events: &[SimEvent]) -> Vec<(u64, Vector3<f64>)> {
    events
        .iter()
        .filter_map(|e| match e {
            SimEvent::Gps {
                fix,
                truth_at_validity,
                ..
            } => Some((fix.t_us, truth_at_validity.accel_m_s2)),
            _ => None,
        })
        .collect()
}

/// Simulates one seed, calibrates, and runs every estimator on it.
fn run_seed(
    scenario: Scenario,
    seed: u64,
    first: bool,
    options: &RunOptions,
    registry: &[Estimator],
    progress: &Mutex<Progress>,
) -> SeedResult {
    let config = options.sim_config(scenario, seed);
    let simulation = Simulation::new(config.clone()).expect("valid simulation config");
    let trajectory = simulation.trajectory().clone();
    let events: Vec<SimEvent> = simulation.collect();
    let skip_us = (options.skip_s * 1e6).round() as u64;
    let fixes = fix_accelerations(&events);
    let delay_bound_s = delay_bound_s(
        &fixes,
        config.sensors.gps_velocity_var_m2_s2,
        DELAY_BOUND_WINDOW_US,
        skip_us,
    )
    .unwrap_or(f64::NAN);
    let truth_trace = if first {
        events
            .iter()
            .filter_map(|e| match e {
                SimEvent::Imu { truth, .. } if truth.t_us.is_multiple_of(TRACE_STEP_US) => Some((
                    truth.t_us as f64 * 1e-6,
                    truth.euler_rad.y.to_degrees(),
                    truth.gps_delay_s,
                )),
                _ => None,
            })
            .collect()
    } else {
        Vec::new()
    };
    let (start, calibrated_delay_s) = if options.calibrated {
        let mut cal = config.clone();
        cal.seed = seed + CALIBRATION_SEED_OFFSET;
        cal.duration_s = CALIBRATION_DURATION_S;
        let start = calibrate(&cal);
        (start, Some(start.delay_s))
    } else {
        (UNCALIBRATED_START, None)
    };
    let setup = RunSetup {
        config,
        events,
        skip_us,
        keep_trace: first,
        start,
        trajectory,
    };
    let scores = registry
        .iter()
        .map(|estimator| {
            let started = Instant::now();
            let s = (estimator.run)(&setup);
            if let Ok(mut p) = progress.lock() {
                p.step(
                    scenario.name(),
                    seed,
                    estimator.name,
                    started.elapsed().as_secs_f64(),
                );
            }
            s
        })
        .collect();
    SeedResult {
        delay_bound_s,
        calibrated_delay_s,
        scores,
        truth_trace,
    }
}

/// Runs the seeds of a scenario on `options.threads` threads, each taking
/// the next seed not yet started.
fn run_scenario(
    scenario: Scenario,
    seeds: &[u64],
    options: &RunOptions,
    registry: &[Estimator],
    progress: &Mutex<Progress>,
) -> ScenarioResult {
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<Option<SeedResult>>> = Mutex::new(seeds.iter().map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..options.threads.clamp(1, seeds.len()) {
            scope.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&seed) = seeds.get(k) else {
                        break;
                    };
                    let first = k == 0 && options.keep_trace;
                    let result = run_seed(scenario, seed, first, options, registry, progress);
                    if let Ok(mut d) = done.lock() {
                        d[k] = Some(result);
                    }
                }
            });
        }
    });
    let mut per_seed: Vec<SeedResult> = done
        .into_inner()
        .unwrap_or_default()
        .into_iter()
        .map(|r| r.expect("every seed ran"))
        .collect();
    let mut by_estimator: Vec<Vec<RunScore>> = registry.iter().map(|_| Vec::new()).collect();
    let mut bounds = Vec::new();
    let mut calibrated_delays_s = Vec::new();
    let truth_trace = std::mem::take(&mut per_seed[0].truth_trace);
    for seed in per_seed {
        bounds.push(seed.delay_bound_s);
        calibrated_delays_s.extend(seed.calibrated_delay_s);
        for (i, score) in seed.scores.into_iter().enumerate() {
            by_estimator[i].push(score);
        }
    }
    let config = options.sim_config(scenario, seeds[0]);
    let mut traces = Vec::new();
    let mut summaries = Vec::new();
    let mut consistencies = Vec::new();
    let mut per_seed = Vec::new();
    for (estimator, scores) in registry.iter().zip(&mut by_estimator) {
        let metrics: Vec<Metrics> = scores.iter().map(|s| s.metrics.clone()).collect();
        summaries.push((estimator.name, summarize(&metrics)));
        per_seed.push((estimator.name, metrics));
        consistencies.push((estimator.name, consistency(scores)));
        if options.keep_trace {
            traces.push((estimator.name, std::mem::take(&mut scores[0].trace)));
        }
    }
    ScenarioResult {
        scenario,
        true_delay_s: config.delay.initial_s,
        delay_bound_s: median(bounds),
        floor_hover: noise_floor(&config.sensors, STANDARD_GRAVITY),
        summaries,
        consistency: consistencies,
        per_seed,
        traces,
        truth_trace,
        calibrated_delays_s,
    }
}

/// The options shared by every scenario of a run.
struct RunOptions {
    /// True delay, s, when not the scenario's default.
    delay_s: Option<f64>,
    duration_s: f64,
    skip_s: f64,
    keep_trace: bool,
    /// Start the delay estimators from an offline calibration.
    calibrated: bool,
    /// Seeds run at once.
    threads: usize,
    /// GPS rate, Hz, when not the default (sweeps).
    gps_rate_hz: Option<f64>,
    /// IMU rate, Hz, when not the default (sweeps).
    imu_rate_hz: Option<f64>,
}

impl RunOptions {
    /// The simulation of one scenario and seed with these options.
    fn sim_config(&self, scenario: Scenario, seed: u64) -> SimConfig {
        let mut config = sim_config(scenario, seed, self.duration_s, self.delay_s);
        if let Some(r) = self.gps_rate_hz {
            config.sensors.gps_rate_hz = r;
        }
        if let Some(r) = self.imu_rate_hz {
            config.sensors.imu_rate_hz = r;
            // The magnetometer cannot outrun the IMU (100 Hz by default).
            config.sensors.mag_rate_hz = config.sensors.mag_rate_hz.min(r);
        }
        config
    }
}

/// Progress on stderr: one line per estimator run.
struct Progress {
    done: usize,
    total: usize,
    started: Instant,
}

impl Progress {
    fn step(&mut self, scenario: &str, seed: u64, estimator: &str, seconds: f64) {
        self.done += 1;
        eprintln!(
            "[{}/{}] {scenario} seed {seed} {estimator}: {seconds:.1} s (elapsed {:.0} s)",
            self.done,
            self.total,
            self.started.elapsed().as_secs_f64()
        );
    }
}

/// Where `--delay-trace` writes (its directory created).
fn trace_path(args: &Args) -> std::io::Result<PathBuf> {
    let row = args.delay_trace.as_deref().unwrap_or("trace");
    let path = args.csv.clone().unwrap_or_else(|| {
        PathBuf::from(format!("target/delay-trace/{row}-seed{}.csv", args.seed))
    });
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    Ok(path)
}

/// The delay loop's changes that `--delay-rate-std`, `--delay-rate-time-constant`
/// and `--delay-process-noise` ask for.
fn delay_tuning(args: &Args) -> delay_suite::LoopTuning {
    delay_suite::LoopTuning {
        rate_std: args.delay_rate_std.map(|ms_per_s| ms_per_s * 1e-3),
        rate_time_constant_s: args.delay_rate_time_constant,
        process_noise_ms2_per_s: args.delay_process_noise,
        innovation_window_s: args.delay_innovation_window,
        innovation_noise_scale: args.delay_innovation_noise_scale,
        innovation_reacquire_sigma: args.delay_innovation_reacquire_sigma,
        innovation_before_lock: args.delay_innovation_before_lock,
        innovation_acquire_noise_scale: args.delay_innovation_acquire_noise_scale,
        measurement_noise_ms2: args.delay_measurement_noise,
        acquisition_motion_exponent: args.delay_acquisition_exponent,
        smoothing_cutoff_hz: args.delay_smoothing_cutoff,
    }
}

/// The delay suite's options: `seeds_n` seeds from `--seed`, `--rows`, the
/// loop's tuning; an error names a row the suite does not have.
fn suite_options(args: &Args, seeds_n: u64) -> Result<delay_suite::SuiteOptions, String> {
    let mut options = delay_suite::SuiteOptions::full(args.seed, seeds_n);
    if let Some(names) = &args.rows {
        let rows = names.iter().map(|n| {
            delay_suite::row_name(n).ok_or_else(|| {
                format!(
                    "--rows: no row {n:?} (rows: {})",
                    delay_suite::ROW_NAMES.join(", ")
                )
            })
        });
        options.rows = Some(rows.collect::<Result<_, _>>()?);
    }
    options.tuning = delay_tuning(args);
    Ok(options)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    if args.check && (args.sweep.is_some() || args.bound_study || args.delay_trace.is_some()) {
        return Err("--check applies to the default run, --faults and --delay-suite".into());
    }
    if let Some(rate) = args.filter_rate_hz {
        FILTER_RATE_HZ.get_or_init(|| rate);
    }
    if args.faults {
        let scale = args.duration.unwrap_or(60.0) / 60.0;
        let results = faults::run(args.seed, scale);
        if let Some(parent) = args.json.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)?;
        }
        let json = faults::to_json(&results, args.seed, scale);
        std::fs::write(&args.json, serde_json::to_string_pretty(&json)? + "\n")?;
        eprintln!("wrote {}", args.json.display());
        if args.check {
            check::enforce(&faults::verdicts(&results), &args.known_failures)?;
        }
        return Ok(());
    }
    let seeds_n = args.seeds.unwrap_or(if args.quick { 2 } else { 5 });
    let duration_s = args
        .duration
        .unwrap_or(if args.quick { 20.0 } else { 60.0 });
    if seeds_n == 0 {
        return Err("--seeds must be at least 1".into());
    }
    if !(args.skip >= 0.0 && duration_s > args.skip) {
        return Err(format!(
            "--duration ({duration_s} s) must exceed the convergence time ({} s)",
            args.skip
        )
        .into());
    }
    let plots = match (&args.plots, args.quick) {
        (Some(dir), _) => Some(dir.clone()),
        (None, false) => Some(PathBuf::from("target/reproduce")),
        (None, true) => None,
    };
    let scenarios: Vec<Scenario> = match args.scenario {
        ScenarioChoice::Low => vec![Scenario::Low],
        ScenarioChoice::High => vec![Scenario::High],
        ScenarioChoice::All => Scenario::ALL.to_vec(),
    };
    let tuning = delay_tuning(&args);
    if args.delay_trace.as_deref() == Some("aekf17_hover") {
        let setup = delay_suite::HoverSetup {
            duration_s: args.duration,
            delay_random_walk: args.aekf17_delay_random_walk,
            accel_smoothing_s: args.aekf17_accel_smoothing,
        };
        let path = trace_path(&args)?;
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
        let end = delay_suite::write_hover_trace(args.seed, &setup, &mut out)?;
        std::io::Write::flush(&mut out)?;
        eprintln!(
            "aekf17_hover seed {}: final estimate {:.4} s, sigma {:.4} s, ratio {:.4}, {} clamps",
            args.seed, end.estimate_s, end.sigma_s, end.ratio, end.clamps
        );
        eprintln!("wrote {} rows to {}", end.rows, path.display());
        return Ok(());
    }
    if let Some(row) = &args.delay_trace {
        let path = trace_path(&args)?;
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
        let summary =
            delay_suite::write_trace(row, args.seed, tuning, args.compare_accel, &mut out)?;
        let Some(summary) = summary else {
            return Err(format!(
                "--delay-trace: no navigator trace for {row:?} (rows: {}, {})",
                delay_suite::TRACE_ROWS.join(", "),
                delay_suite::EXTRA_TRACES.join(", ")
            )
            .into());
        };
        std::io::Write::flush(&mut out)?;
        for (estimate, rmse_ms) in &summary.rmse_ms {
            eprintln!(
                "{row} seed {}: {estimate} delay RMSE from 20 s {rmse_ms:.4} ms",
                args.seed
            );
        }
        eprintln!(
            "{row} seed {}: information bound (Cramér-Rao from every GPS velocity since the start), RMS from 20 s {:.4} ms",
            args.seed, summary.information_bound_ms
        );
        eprintln!(
            "{row} seed {}: navigator error within its reported 1-sigma from 20 s: {:.3} of the time",
            args.seed, summary.sigma_coverage
        );
        eprintln!("wrote {} rows to {}", summary.rows, path.display());
        return Ok(());
    }
    if args.delay_suite {
        let options = suite_options(&args, seeds_n)?;
        let rows = delay_suite::run(&options);
        if let Some(parent) = args.json.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)?;
        }
        let json = delay_suite::to_json(&rows, &options);
        std::fs::write(&args.json, serde_json::to_string_pretty(&json)? + "\n")?;
        eprintln!("wrote {}", args.json.display());
        if args.check {
            check::enforce(&delay_suite::verdicts(&rows), &args.known_failures)?;
        }
        return Ok(());
    }
    let seeds: Vec<u64> = (args.seed..args.seed + seeds_n).collect();
    let registry = if args.bound_study {
        bound_study()
    } else {
        estimators()
    };
    let progress = Mutex::new(Progress {
        done: 0,
        total: scenarios.len() * seeds.len() * registry.len(),
        started: Instant::now(),
    });
    if let Some(dir) = &args.csv {
        for &scenario in &scenarios {
            let config = sim_config(scenario, seeds[0], duration_s, args.delay);
            let path = dir.join(format!("{}-seed{}", scenario.name(), seeds[0]));
            let n = write_run(&path, Simulation::new(config)?)?;
            eprintln!("wrote {n} events to {}", path.display());
        }
    }
    let options = RunOptions {
        delay_s: args.delay,
        duration_s,
        skip_s: args.skip,
        keep_trace: plots.is_some(),
        calibrated: !args.no_calibration,
        threads: args.threads.unwrap_or_else(|| {
            std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
        }),
        gps_rate_hz: None,
        imu_rate_hz: None,
    };
    if let Some(name) = args.sweep {
        return sweep::run(name, &scenarios, &seeds, options, &args.json, plots);
    }
    let results: Vec<ScenarioResult> = scenarios
        .iter()
        .map(|&s| run_scenario(s, &seeds, &options, &registry, &progress))
        .collect();
    print!(
        "{}",
        print_tables(&results, seeds.len(), duration_s, args.skip)
    );
    if let Some(parent) = args.json.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    let json = to_json(&results, &seeds, duration_s, args.skip);
    std::fs::write(&args.json, serde_json::to_string_pretty(&json)? + "\n")?;
    eprintln!("wrote {}", args.json.display());
    if let Some(dir) = plots {
        for r in &results {
            for path in write_plots(&dir, r)? {
                eprintln!("wrote {}", path.display());
            }
        }
    }
    if args.check {
        check::enforce(&check::tables(&results), &args.known_failures)?;
    }
    Ok(())
}

#[cfg(test)]
mod json_contract {
    use super::*;

    /// Issue 14's contract of `reproduce --seeds N --json PATH`, on two
    /// short seeds: each scenario's `estimators` has `bound`, `fusion_nav`
    /// and `proposed_f32`; each entry `tilt_deg`, `heading_deg`, every
    /// figure's `<name>_ci95` and `nees_mean`; the top level the seeds.
    #[test]
    fn the_run_json_has_the_issue_keys() {
        let options = RunOptions {
            delay_s: None,
            duration_s: 12.0,
            skip_s: 10.0,
            keep_trace: false,
            calibrated: false,
            threads: 2,
            gps_rate_hz: None,
            imu_rate_hz: None,
        };
        let names = ["bound", "proposed", "proposed_f32", "fusion_nav"];
        let registry: Vec<Estimator> = estimators()
            .into_iter()
            .filter(|e| names.contains(&e.name))
            .collect();
        assert_eq!(registry.len(), names.len());
        let progress = Mutex::new(Progress {
            done: 0,
            total: 2 * registry.len(),
            started: Instant::now(),
        });
        let seeds = [1, 2];
        let result = run_scenario(Scenario::Low, &seeds, &options, &registry, &progress);
        let json = to_json(&[result], &seeds, options.duration_s, options.skip_s);
        assert_eq!(json["seeds"], json!([1, 2]));
        let estimators = &json["scenarios"][0]["estimators"];
        for name in names {
            let entry = estimators[name].as_object().expect("an entry per row");
            for key in ["tilt_deg", "heading_deg", "vel_m_s", "pos_m"] {
                assert!(
                    entry[key].as_f64().is_some_and(f64::is_finite),
                    "{name}.{key}"
                );
                let ci = entry[&format!("{key}_ci95")].as_array().expect("a pair");
                assert!(
                    ci.len() == 2 && ci.iter().all(Value::is_number),
                    "{name}.{key}_ci95"
                );
            }
            for (figure, _) in FIGURES {
                assert!(
                    entry.contains_key(&format!("{figure}_ci95")),
                    "{name}.{figure}_ci95"
                );
            }
            assert!(entry.contains_key("nees_mean"), "{name}.nees_mean");
        }
        assert!(estimators["proposed_f32"]["nees_mean"].is_number());
    }
}

#[cfg(test)]
mod delay_flags {
    use super::*;

    fn parse(flags: &[&str]) -> Args {
        Args::try_parse_from(std::iter::once("reproduce").chain(flags.iter().copied()))
            .expect("the flags parse")
    }

    /// `--rows`, `--delay-rate-std` (ms/s), `--delay-rate-time-constant` and
    /// `--delay-process-noise` reach the suite's options and its JSON; a
    /// row the suite does not have is refused with the list.
    #[test]
    fn suite_flags_reach_the_options() {
        let args = parse(&[
            "--delay-suite",
            "--rows",
            "delay_step,aekf17_hover",
            "--seed",
            "3",
            "--delay-rate-std",
            "2",
            "--delay-rate-time-constant",
            "300",
            "--delay-process-noise",
            "0.5",
        ]);
        let options = suite_options(&args, 2).expect("known rows");
        assert_eq!(options.rows, Some(vec!["delay_step", "aekf17_hover"]));
        assert_eq!(options.seeds, [3, 4]);
        let tuning = options.tuning;
        assert!((tuning.rate_std.expect("set") - 2e-3).abs() < 1e-12);
        assert_eq!(tuning.rate_time_constant_s, Some(300.0));
        assert_eq!(tuning.process_noise_ms2_per_s, Some(0.5));
        let json = delay_suite::to_json(&[], &options);
        assert_eq!(json["loop_tuning"]["rate_time_constant_s"], 300.0);
        let defaults = suite_options(&parse(&["--delay-suite"]), 5).expect("no rows named");
        assert_eq!(defaults.rows, None);
        assert_eq!(defaults.tuning, delay_suite::LoopTuning::default());
        let tried = parse(&[
            "--delay-suite",
            "--delay-acquisition-exponent",
            "3",
            "--delay-smoothing-cutoff",
            "0.7",
        ]);
        let tuning = suite_options(&tried, 1).expect("valid").tuning;
        let mut config = delaynav::delay::DelayLoopConfig::<f64>::clean_input();
        tuning.apply(&mut config);
        assert_eq!(config.acquisition_motion_exponent, 3.0);
        assert_eq!(config.smoothing_cutoff_hz, 0.7);
        let bad = suite_options(&parse(&["--delay-suite", "--rows", "cold_start"]), 1);
        assert!(bad.is_err_and(|e| e.contains("cold_start_low")));
    }

    /// `--delay-trace ROW --compare-accel`: one CSV row a second with the
    /// two comparison columns, and the navigator's RMSE the suite's row
    /// measures on that seed with the same tuning.
    #[test]
    fn trace_agrees_with_the_suite() {
        let args = parse(&[
            "--delay-trace",
            "cold_start_high",
            "--compare-accel",
            "--seed",
            "2",
            "--delay-rate-std",
            "1",
        ]);
        let tuning = delay_tuning(&args);
        let row = args.delay_trace.as_deref().expect("a row");
        let mut csv = Vec::new();
        let summary =
            delay_suite::write_trace(row, args.seed, tuning, args.compare_accel, &mut csv)
                .expect("writes to memory")
                .expect("a navigator row");
        let text = String::from_utf8(csv).expect("UTF-8");
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(summary.rows, 61);
        assert_eq!(lines.len(), 62);
        let columns = lines[0].split(',').count();
        // 8 + the GFA's sigma and the innovation window (3), 5 per axis, 2 compared.
        assert_eq!(columns, 11 + 3 * 5 + 2);
        assert!(lines.iter().all(|l| l.split(',').count() == columns));
        assert!(lines[0].ends_with("oracle_accel_estimate_s,true_accel_estimate_s"));
        let names: Vec<&str> = summary.rmse_ms.iter().map(|(n, _)| *n).collect();
        assert_eq!(names, ["navigator", "oracle_accel", "true_accel"]);
        assert!(
            summary
                .rmse_ms
                .iter()
                .all(|(_, x)| x.is_finite() && *x > 0.0)
        );
        // The Cramer-Rao bound from every GPS velocity so far: below what each
        // of the three loops reaches on this seed (a bound on the mean square
        // over the noise; one lucky seed may score below it).
        let bound = summary.information_bound_ms;
        assert!(bound > 1.0 && summary.rmse_ms.iter().all(|(_, x)| *x > bound));
        // The sigma's coverage (10 ms spacing) agrees with the CSV's rows
        // (1 s spacing) from 20 s: columns sigma_s and error_ms.
        let (mut inside, mut n) = (0.0, 0.0);
        for line in lines[1..].iter().map(|l| l.split(',').collect::<Vec<_>>()) {
            let value = |i: usize| line[i].parse::<f64>().expect("a number");
            if value(0) >= 20.0 {
                inside += f64::from(u8::from(value(4).abs() * 1e-3 <= value(3)));
                n += 1.0;
            }
        }
        assert!((0.0..=1.0).contains(&summary.sigma_coverage));
        assert!((summary.sigma_coverage - inside / n).abs() < 0.05);
        let options = delay_suite::SuiteOptions {
            seeds: vec![2],
            coverage_seeds: vec![2],
            rows: Some(vec!["cold_start_high"]),
            tuning,
        };
        let suite = delay_suite::run(&options)[0].measured.expect("measured");
        assert_eq!(summary.rmse_ms[0].1, suite);
        let none = delay_suite::write_trace("sigma_coverage", 1, tuning, false, &mut Vec::new());
        assert!(none.expect("nothing written").is_none());
    }

    /// `--delay-trace aekf17_hover`: the flags reach the hover's setup, and
    /// the default trace ends on the suite row's figure for that seed.
    #[test]
    fn hover_trace_agrees_with_the_suite() {
        let args = parse(&[
            "--delay-trace",
            "aekf17_hover",
            "--duration",
            "30",
            "--aekf17-delay-random-walk",
            "0",
            "--aekf17-accel-smoothing",
            "0",
        ]);
        assert_eq!(args.duration, Some(30.0));
        assert_eq!(args.aekf17_delay_random_walk, Some(0.0));
        assert_eq!(args.aekf17_accel_smoothing, Some(0.0));
        let setup = delay_suite::HoverSetup::default();
        let mut csv = Vec::new();
        let end = delay_suite::write_hover_trace(1, &setup, &mut csv).expect("writes to memory");
        let text = String::from_utf8(csv).expect("UTF-8");
        assert_eq!(end.rows, 61);
        assert_eq!(text.lines().count(), 62);
        assert!(end.ratio.is_finite() && end.sigma_s > 0.0);
        let options = delay_suite::SuiteOptions {
            seeds: vec![1],
            coverage_seeds: vec![1],
            rows: Some(vec!["aekf17_hover"]),
            tuning: delay_suite::LoopTuning::default(),
        };
        let suite = delay_suite::run(&options)[0].measured.expect("measured");
        assert_eq!(end.ratio, suite);
    }
}

#[cfg(test)]
mod statistics {
    //! The tables' statistics over seeds on made-up figures.

    use super::*;

    /// Every figure of one run equal to `x` (delay, NEES and NIS present).
    fn metrics(x: f64) -> Metrics {
        Metrics {
            roll_deg: x,
            pitch_deg: x,
            yaw_deg: x,
            tilt_deg: x,
            heading_deg: x,
            vel_m_s: x,
            pos_m: x,
            delay_s: Some(x),
            gyro_bias_rad_s: [x; 3],
            accel_bias_g: [x; 3],
            nees: Some(x),
            nis: Some(x),
            us_per_imu_sample: x,
        }
    }

    fn run(nees_series: Vec<f64>, nis: (f64, usize)) -> RunScore {
        RunScore {
            metrics: metrics(1.0),
            trace: Trace::default(),
            nees_series,
            nis,
        }
    }

    #[test]
    fn medians_keep_failed_runs_visible() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(vec![1.0, f64::NAN, 2.0]).is_nan());
        assert!(median(vec![1.0, f64::INFINITY, 2.0]).is_nan());
        assert!(median(Vec::new()).is_nan());
        assert_eq!(median_ordered(vec![f64::INFINITY, 1.0, 2.0]), 2.0);
        assert_eq!(
            median_ordered(vec![f64::INFINITY, 1.0, f64::INFINITY]),
            f64::INFINITY
        );
        let mut rms = Rms::default();
        assert!(rms.value().is_nan());
        rms.add(3.0);
        rms.add(-4.0);
        assert!((rms.value() - 12.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn every_figure_is_summarized_over_the_seeds() {
        let runs = [metrics(1.0), metrics(2.0), metrics(6.0)];
        let summary = summarize(&runs);
        assert_eq!(summary.mean.pos_m, 3.0);
        assert_eq!(summary.median.vel_m_s, 2.0);
        assert_eq!(summary.mean.accel_bias_g, [3.0; 3]);
        assert_eq!(summary.mean.delay_s, Some(3.0));
        assert!(summary.lo.tilt_deg < 3.0 && summary.hi.tilt_deg > 3.0);
        assert!(
            (summary.mean.tilt_deg - summary.lo.tilt_deg - (summary.hi.tilt_deg - 3.0)).abs()
                < 1e-12
        );
        // A figure the estimator does not have stays absent; one seed without it fails it.
        let mut without = runs.clone();
        for r in &mut without {
            r.delay_s = None;
        }
        assert_eq!(summarize(&without).mean.delay_s, None);
        without[0].delay_s = Some(1.0);
        assert!(summarize(&without).mean.delay_s.is_some_and(f64::is_nan));
        // A failed seed shows in the mean and the median.
        let mut failed = runs.clone();
        failed[1].pos_m = f64::NAN;
        let summary = summarize(&failed);
        assert!(summary.mean.pos_m.is_nan() && summary.median.pos_m.is_nan());
    }

    #[test]
    fn consistency_averages_over_seeds_then_over_time() {
        // Two seeds: seed-averaged NEES 6, 6, 100 (the last outside the 95 % band).
        let scores = [
            run(vec![5.0, 7.0, 100.0], (12.0, 2)),
            run(vec![7.0, 5.0, 100.0], (0.0, 0)),
        ];
        let c = consistency(&scores);
        assert!((c.nees_mean - 112.0 / 3.0).abs() < 1e-12);
        assert_eq!(c.nees_band, stats::chi2_band95(CONSISTENCY_DOF, 2));
        assert!((c.nees_in_band - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(c.nis_mean, 6.0);
        assert_eq!(c.nis_band, stats::chi2_band95(CONSISTENCY_DOF, 2));
        // An instant without an estimate makes the mean NaN, and is not in the band.
        let lost = [
            run(vec![5.0, f64::NAN, 6.0], (0.0, 0)),
            run(vec![7.0, 5.0, 6.0], (0.0, 0)),
        ];
        let c = consistency(&lost);
        assert!(c.nees_mean.is_nan() && c.nis_mean.is_nan());
        assert!((c.nees_in_band - 2.0 / 3.0).abs() < 1e-12);
        // Seeds of different lengths: the common instants only.
        let c = consistency(&[run(vec![6.0, 6.0], (0.0, 0)), run(vec![6.0], (0.0, 0))]);
        assert_eq!((c.nees_mean, c.nees_in_band), (6.0, 1.0));
    }
}
