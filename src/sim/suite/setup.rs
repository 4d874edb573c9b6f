//! What every suite shares: the navigator as the suites configure it, and where its delay
//! estimate starts.
//!
//! The filters take the simulator's own noise, field and bias spread
//! ([`SensorConfig::ekf16_config`](crate::sim::SensorConfig::ekf16_config)). The delay estimators
//! start either from 0.1 s, uncalibrated ([`UNCALIBRATED_START`]), or from the offline
//! calibration (sec. 2.2.2 of the paper) of a separate 60 s run of the same sensors
//! ([`calibrated_start`]: seed + [`CALIBRATION_SEED_OFFSET`]).

use crate::delay::{CalibrationConfig, DefaultCalibrator};
use crate::nav::{DelayCompensatedNav, DelayCompensatedNavConfig, DelayMode};
use crate::sim::{SimConfig, SimEvent, Simulation};
use crate::{Ekf16Config, Error, Scalar};
use nalgebra::Vector3;

/// The initial delay of the estimators that estimate it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DelayStart {
    /// Initial delay, s.
    pub delay_s: f64,
    /// Initial standard deviation, s; `None` keeps each estimator's default.
    pub std_s: Option<f64>,
}

/// The uncalibrated start: 100 ms below the default true delay.
pub const UNCALIBRATED_START: DelayStart = DelayStart {
    delay_s: 0.1,
    std_s: None,
};

/// Seed offset of the calibration run of each seed.
pub const CALIBRATION_SEED_OFFSET: u64 = 10_000;

/// Length of each calibration run, s, whatever the scored run's length (a
/// 20 s record holds too little motion: two of the scenario's strong
/// manoeuvres need 60 s).
pub const CALIBRATION_DURATION_S: f64 = 60.0;

/// Offline calibration (sec. 2.2.2) on the simulated run `config`: IMU-only attitude,
/// correlation over +-6 s. The initial standard deviation is one correlation grid sample; a
/// run too still to calibrate gives [`UNCALIBRATED_START`]. An error when `config` is not a
/// valid simulation.
pub fn calibrate(config: &SimConfig) -> Result<DelayStart, Error> {
    let cal_config = CalibrationConfig::<f64>::default();
    let mut calibrator = Box::new(DefaultCalibrator::<f64>::new(cal_config)?);
    let events: Vec<SimEvent> = Simulation::new(config.clone())?.collect();
    let imu = events.iter().filter_map(SimEvent::imu_sample);
    let gps = events.iter().filter_map(SimEvent::gps_fix);
    Ok(match calibrator.calibrate(imu, gps) {
        Ok(c) => DelayStart {
            delay_s: c.delay_s.clamp(0.0, 1.0),
            std_s: Some(1.0 / cal_config.correlation_rate_hz),
        },
        Err(_) => UNCALIBRATED_START,
    })
}

/// [`calibrate`] on the calibration run of `config`: the same sensors and delay, seed +
/// [`CALIBRATION_SEED_OFFSET`], [`CALIBRATION_DURATION_S`] long.
pub fn calibrated_start(config: &SimConfig) -> Result<DelayStart, Error> {
    let mut cal = config.clone();
    cal.seed = config.seed + CALIBRATION_SEED_OFFSET;
    cal.duration_s = CALIBRATION_DURATION_S;
    calibrate(&cal)
}

/// The 16-state EKF configured with the simulator's own noise, field and
/// bias spread (`SensorConfig::ekf16_config`).
pub fn ekf16_config<T: Scalar>(sim: &SimConfig) -> Ekf16Config<T> {
    sim.sensors.ekf16_config()
}

/// The configuration of the delay-compensated navigator on the same EKF configuration as
/// `ekf16`: `mode` estimates the delay (`proposed`, initial std `initial_std_s`, else the
/// loop's default) or is given it (`oracle`); `filter_rate_hz` sets the horizon filter's
/// prediction rate (`None`: the default). At a GPS rate other than 10 Hz the delay loop is
/// adapted to that rate, as a user would configure it.
pub fn nav_config<T: Scalar>(
    sim: &SimConfig,
    mode: DelayMode<T>,
    initial_std_s: Option<f64>,
    filter_rate_hz: Option<f64>,
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
    if let Some(rate) = filter_rate_hz {
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

/// The navigator of [`nav_config`]; an error when it refuses the configuration.
pub fn nav<T: Scalar>(
    sim: &SimConfig,
    mode: DelayMode<T>,
    initial_std_s: Option<f64>,
    filter_rate_hz: Option<f64>,
) -> Result<DelayCompensatedNav<T>, Error> {
    DelayCompensatedNav::new(nav_config(sim, mode, initial_std_s, filter_rate_hz))
}

/// `proposed`: the navigator estimating the delay from `start`.
pub fn proposed(
    sim: &SimConfig,
    start: DelayStart,
    filter_rate_hz: Option<f64>,
) -> Result<DelayCompensatedNav<f64>, Error> {
    let mode = DelayMode::Estimated {
        initial_s: start.delay_s,
    };
    nav(sim, mode, start.std_s, filter_rate_hz)
}

/// Each GPS fix's receive time (us) and the true acceleration at its
/// validity: what [`delay_bound_s`](crate::sim::delay_bound_s) reads.
pub fn fix_accelerations(events: &[SimEvent]) -> Vec<(u64, Vector3<f64>)> {
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
