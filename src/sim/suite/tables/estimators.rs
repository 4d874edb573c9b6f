//! The rows of the tables: the crate's estimators and the linearized bounds, registered in one
//! place ([`estimators`], [`bound_study`]); a caller adds its own [`Estimator`]s to the list.

use super::RunSetup;
use super::score::{
    Metrics, RunScore, Trace, aekf17_covariance, ekf16_covariance, nav_covariance, score,
};
use crate::nav::{DelayCompensatedNav, DelayMode};
use crate::sim::suite::setup::{ekf16_config, nav, nav_config};
use crate::sim::{
    BoundConfig, BoundMagnetometer, BoundRms, STANDARD_GRAVITY, SimConfig, SimEvent,
    trajectory_bound,
};
use crate::{AugmentedEkf17, AugmentedEkf17Config, Ekf16, Error, Scalar};
use nalgebra::Vector3;
use std::time::Instant;

/// A row of the tables: its name in the JSON and the text, and how to run it on a setup.
///
/// `run` builds the estimator for the run (`setup.config`, `setup.start`) and scores it with
/// [`score`]; an `Err` (the estimator refuses its configuration) fails the suite's run.
#[derive(Debug, Clone, Copy)]
pub struct Estimator {
    /// The row's name.
    pub name: &'static str,
    /// Runs and scores the estimator on one run.
    pub run: fn(&RunSetup) -> Result<RunScore, Error>,
}

impl Estimator {
    /// A row named `name`.
    pub const fn new(name: &'static str, run: fn(&RunSetup) -> Result<RunScore, Error>) -> Self {
        Self { name, run }
    }
}

/// Standard deviation of the pre-flight accelerometer bias calibration, g
/// (per axis; the simulator draws biases within +-0.1 g).
pub const IMU_CALIBRATION_ACCEL_STD_G: f64 = 0.01;
/// Standard deviation of the pre-flight gyro bias calibration, deg/s (per
/// axis; the simulator draws biases within +-0.57 deg/s).
pub const IMU_CALIBRATION_GYRO_STD_DEG_S: f64 = 0.05;
/// Key of the calibration error's random stream (the simulator's use 1-9).
const IMU_CALIBRATION_STREAM: u64 = 100;

/// Every estimator of the comparison, in table order (the `reproduce` example adds the peer
/// `fusion_nav` at the end):
///
/// - `bound` (`sim::trajectory_bound`, the linearized filter about the true trajectory),
///   `bound_filter_heading` (the same taking from the magnetometer only what the estimators
///   take: a tilt-compensated heading), `bound_calibrated` (the bound with the biases' prior of
///   the IMU calibration of `calibrated`);
/// - `ekf16` (no delay handling), `aekf17` (the delay as a state), `proposed` (the
///   delay-compensated navigator), `calibrated` (`proposed` starting from a pre-flight IMU bias
///   calibration, [`imu_calibration`]), `oracle` (the navigator given the true delay);
/// - `ekf16_f32`, `aekf17_f32`, `proposed_f32`: the same in `f32`.
pub fn estimators() -> Vec<Estimator> {
    vec![
        Estimator::new("bound", run_bound),
        Estimator::new("bound_filter_heading", run_bound_filter_heading),
        Estimator::new("bound_calibrated", run_bound_calibrated),
        Estimator::new("ekf16", run_ekf16::<f64>),
        Estimator::new("aekf17", run_aekf17::<f64>),
        Estimator::new("proposed", run_proposed::<f64>),
        Estimator::new("calibrated", run_calibrated::<f64>),
        Estimator::new("oracle", run_oracle::<f64>),
        Estimator::new("ekf16_f32", run_ekf16::<f32>),
        Estimator::new("aekf17_f32", run_aekf17::<f32>),
        Estimator::new("proposed_f32", run_proposed::<f32>),
    ]
}

/// The bound study (`reproduce --bound-study`): what each difference between `bound` and the
/// estimators is worth, one at a time, beside `oracle` and `proposed` (docs/RESULTS.md, "The
/// bound gap"). Rows: `bound_gps_prior` (the bound's prior before it was taken from the
/// filters' configuration: heading 0.5 rad, position and velocity the GPS noise), `bound`,
/// `bound_filter_walks` (the filters' bias random walks), `bound_heading_only` (a heading-only
/// magnetometer), `bound_filter_heading`, `filter_gain` (not a bound: the estimators' own gain
/// on that heading), `filter_gain_walks`, `bound_known_biases`, `oracle`, `proposed`.
pub fn bound_study() -> Vec<Estimator> {
    vec![
        Estimator::new("bound_gps_prior", |s| {
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
        Estimator::new("bound", run_bound),
        Estimator::new("bound_filter_walks", |s| {
            with_filter_walks(s, BoundConfig::for_sensors(&s.config.sensors))
        }),
        Estimator::new("bound_heading_only", |s| {
            linearized(
                s,
                BoundConfig {
                    magnetometer: BoundMagnetometer::Heading,
                    ..BoundConfig::for_sensors(&s.config.sensors)
                },
            )
        }),
        Estimator::new("bound_filter_heading", run_bound_filter_heading),
        Estimator::new("filter_gain", run_filter_gain),
        Estimator::new("filter_gain_walks", |s| {
            with_filter_walks(s, BoundConfig::for_filter(&ekf16_config(&s.config)))
        }),
        Estimator::new("bound_known_biases", |s| {
            linearized(
                s,
                BoundConfig {
                    accel_bias_std_m_s2: 0.0,
                    gyro_bias_std_rad_s: 0.0,
                    ..BoundConfig::for_sensors(&s.config.sensors)
                },
            )
        }),
        Estimator::new("oracle", run_oracle::<f64>),
        Estimator::new("proposed", run_proposed::<f64>),
    ]
}

fn run_ekf16<T: Scalar>(s: &RunSetup) -> Result<RunScore, Error> {
    let filter = Ekf16::new(ekf16_config::<T>(&s.config))?;
    Ok(score(filter, s, ekf16_covariance))
}

fn run_aekf17<T: Scalar>(s: &RunSetup) -> Result<RunScore, Error> {
    let mut config = AugmentedEkf17Config::with_nav(ekf16_config::<T>(&s.config));
    config.initial_delay_s = T::lit(s.start.delay_s);
    if let Some(std) = s.start.std_s {
        config.initial_delay_std_s = T::lit(std);
    }
    let filter = AugmentedEkf17::new(config)?;
    Ok(score(filter, s, aekf17_covariance))
}

fn run_proposed<T: Scalar>(s: &RunSetup) -> Result<RunScore, Error> {
    let mode = DelayMode::Estimated {
        initial_s: T::lit(s.start.delay_s),
    };
    let nav = nav::<T>(&s.config, mode, s.start.std_s, s.filter_rate_hz)?;
    Ok(score(nav, s, nav_covariance))
}

/// A pre-flight IMU bias calibration of the run: the simulator's biases at
/// the first IMU sample plus an error drawn per seed, normal with standard deviations
/// [`IMU_CALIBRATION_ACCEL_STD_G`] and [`IMU_CALIBRATION_GYRO_STD_DEG_S`].
/// `(accel m/s², gyro rad/s)`.
pub fn imu_calibration(s: &RunSetup) -> (Vector3<f64>, Vector3<f64>) {
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
fn run_calibrated<T: Scalar>(s: &RunSetup) -> Result<RunScore, Error> {
    let mode = DelayMode::Estimated {
        initial_s: T::lit(s.start.delay_s),
    };
    let mut config = nav_config::<T>(&s.config, mode, s.start.std_s, s.filter_rate_hz);
    let (accel, gyro) = imu_calibration(s);
    config.ekf.initial_accel_bias_m_s2 = accel.map(T::lit);
    config.ekf.initial_gyro_bias_rad_s = gyro.map(T::lit);
    config.ekf.initial_accel_bias_std_m_s2 = T::lit(IMU_CALIBRATION_ACCEL_STD_G * STANDARD_GRAVITY);
    config.ekf.initial_gyro_bias_std_rad_s = T::lit(IMU_CALIBRATION_GYRO_STD_DEG_S.to_radians());
    let nav = DelayCompensatedNav::new(config)?;
    Ok(score(nav, s, nav_covariance))
}

fn run_oracle<T: Scalar>(s: &RunSetup) -> Result<RunScore, Error> {
    let mode = DelayMode::Fixed {
        delay_s: T::lit(s.config.delay.initial_s),
    };
    let nav = nav::<T>(&s.config, mode, None, s.filter_rate_hz)?;
    Ok(score(nav, s, nav_covariance))
}

/// The linearized bound of the run (`sim::trajectory_bound`) in the
/// estimators' figures: the RMS over the scored samples of its per-time
/// standard deviations.
fn run_bound(s: &RunSetup) -> Result<RunScore, Error> {
    linearized(s, BoundConfig::for_sensors(&s.config.sensors))
}

/// The bound of a filter starting from the pre-flight IMU calibration
/// (`calibrated`): the biases' prior is the calibration's uncertainty.
fn run_bound_calibrated(s: &RunSetup) -> Result<RunScore, Error> {
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
fn run_bound_filter_heading(s: &RunSetup) -> Result<RunScore, Error> {
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
fn run_filter_gain(s: &RunSetup) -> Result<RunScore, Error> {
    linearized(s, BoundConfig::for_filter(&ekf16_config(&s.config)))
}

/// The bound with the bias random walks the filters are configured with
/// (`Ekf16Config`) instead of the simulator's (constant biases).
fn with_filter_walks(s: &RunSetup, config: BoundConfig) -> Result<RunScore, Error> {
    let filter = ekf16_config::<f64>(&s.config);
    let mut sim = s.config.clone();
    sim.sensors.gyro_bias_walk_rad_s_sqrt_s = filter.gyro_bias_random_walk;
    sim.sensors.accel_bias_walk_m_s2_sqrt_s = filter.accel_bias_random_walk;
    linearized_with(s, &sim, config)
}

fn linearized(s: &RunSetup, config: BoundConfig) -> Result<RunScore, Error> {
    linearized_with(s, &s.config, config)
}

/// [`linearized`] with the noise of `sim` (the run's events, another model).
fn linearized_with(s: &RunSetup, sim: &SimConfig, config: BoundConfig) -> Result<RunScore, Error> {
    let started = Instant::now();
    let bound = trajectory_bound(&s.events, sim, &config)?;
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
    Ok(RunScore {
        metrics,
        trace: Trace::default(),
        nees_series: Vec::new(),
        nis: (0.0, 0),
    })
}
