//! What the simulated noise allows: steady-state Kalman error of an
//! idealized filter, a floor under every estimator's RMSE.
//!
//! # Model
//! One horizontal axis, small errors, delay known, biases known:
//!
//! ```text
//! state x = [dp, dv, dth]   (position, velocity, tilt error about the other horizontal axis)
//! per IMU step dt:
//!   dp  += dv dt + f dth dt^2/2 + n_a dt^2/2 + f n_g dt^3/6
//!   dv  += f dth dt + n_a dt + f n_g dt^2/2
//!   dth += n_g dt
//! n_a ~ N(0, s_a^2), n_g ~ N(0, s_g^2) per sample (Table 3 read literally),
//! every imu_rate / gps_rate steps: z = [dp, dv] + N(0, diag(s_p^2, s_v^2))
//! ```
//!
//! `f` is the specific-force magnitude: a tilt error `dth` makes the
//! navigation-frame specific force wrong by `f dth`, which GPS velocity
//! sees. At hover `f = g`; hard manoeuvres raise `f` and with it the tilt
//! observability. The vertical axis is the same model with `f = 0` (no
//! tilt coupling). Heading uses the magnetometer alone:
//! `psi += n_g dt` per IMU step, observed at the magnetometer rate with the
//! variance `s_m^2 / cos^2 I` (noise across the horizontal field of length
//! `cos I`).
//!
//! The discrete Riccati recursion is run to its periodic steady state and
//! the covariance averaged over one GPS cycle at IMU rate (what an RMSE at
//! IMU rate measures). Everything omitted (bias estimation, unknown delay,
//! linearization, attitude-position coupling in 3-D) can only make a real
//! filter worse, so for tilt, velocity and position these are floors. The
//! heading figure is not a floor in manoeuvring flight, where horizontal
//! accelerations also reveal heading through GPS; it is the magnetometer's
//! share alone.

use super::sensors::SensorConfig;
use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector3};

/// Cycles of the Riccati recursion at most.
const MAX_CYCLES: usize = 200_000;
/// Relative change of the averaged covariance that counts as converged.
const CONVERGED: f64 = 1e-12;

/// Index of position in the per-axis error state.
const POS: usize = 0;
/// Index of velocity in the per-axis error state.
const VEL: usize = 1;
/// Index of tilt in the per-axis error state.
const TILT: usize = 2;

/// Steady-state RMS errors of the idealized filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseFloor {
    /// Specific-force magnitude the figures hold for, m/s^2.
    pub specific_force_m_s2: f64,
    /// Tilt (roll or pitch), radians.
    pub tilt_rad: f64,
    /// Velocity per horizontal axis, m/s.
    pub horizontal_velocity_m_s: f64,
    /// Vertical velocity, m/s.
    pub vertical_velocity_m_s: f64,
    /// Position per horizontal axis, metres.
    pub horizontal_position_m: f64,
    /// Vertical position, metres.
    pub vertical_position_m: f64,
    /// RMS of the 3-D velocity error norm, m/s.
    pub velocity_norm_m_s: f64,
    /// RMS of the 3-D position error norm, metres.
    pub position_norm_m: f64,
    /// Heading from the magnetometer alone, radians (not a floor, see the
    /// module docs).
    pub heading_mag_only_rad: f64,
}

/// Cycle-averaged steady-state covariance of one axis.
fn axis_covariance(sensors: &SensorConfig, f: f64, with_tilt: bool) -> Matrix3<f64> {
    let dt = 1.0 / sensors.imu_rate_hz;
    let steps = (sensors.imu_rate_hz / sensors.gps_rate_hz).round().max(1.0) as usize;
    let var_a = sensors.accel_noise_std_m_s2().powi(2);
    let var_g = if with_tilt {
        sensors.gyro_noise_var_rad2_s2
    } else {
        0.0
    };
    let phi = Matrix3::new(1.0, dt, f * dt * dt / 2.0, 0.0, 1.0, f * dt, 0.0, 0.0, 1.0);
    let gamma_a = Vector3::new(dt * dt / 2.0, dt, 0.0);
    let gamma_g = Vector3::new(f * dt.powi(3) / 6.0, f * dt * dt / 2.0, dt);
    let q = gamma_a * gamma_a.transpose() * var_a + gamma_g * gamma_g.transpose() * var_g;
    let h = Matrix2x3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
    let r = Matrix2::new(
        sensors.gps_position_var_m2,
        0.0,
        0.0,
        sensors.gps_velocity_var_m2_s2,
    );
    let mut p = Matrix3::from_diagonal(&Vector3::new(
        100.0,
        1.0,
        if with_tilt { 0.01 } else { 0.0 },
    ));
    let mut previous = Matrix3::zeros();
    for _ in 0..MAX_CYCLES {
        let mut mean = Matrix3::zeros();
        for _ in 0..steps {
            mean += p;
            p = phi * p * phi.transpose() + q;
        }
        let s = h * p * h.transpose() + r;
        let Some(s_inv) = s.try_inverse() else {
            break;
        };
        let k = p * h.transpose() * s_inv;
        let i_kh = Matrix3::identity() - k * h;
        p = i_kh * p * i_kh.transpose() + k * r * k.transpose();
        mean /= steps as f64;
        let change = (mean - previous).norm();
        previous = mean;
        if change <= CONVERGED * mean.norm() {
            break;
        }
    }
    previous
}

/// Cycle-averaged steady-state heading variance from the magnetometer alone
/// (infinite without a magnetometer).
fn heading_variance(sensors: &SensorConfig) -> f64 {
    if sensors.mag_rate_hz <= 0.0 {
        return f64::INFINITY;
    }
    let dt = 1.0 / sensors.imu_rate_hz;
    let steps = (sensors.imu_rate_hz / sensors.mag_rate_hz).round().max(1.0) as usize;
    let q = sensors.gyro_noise_var_rad2_s2 * dt * dt;
    let r = sensors.mag_noise_var / sensors.inclination_rad.cos().powi(2);
    let mut p = 1.0;
    let mut previous = 0.0;
    for _ in 0..MAX_CYCLES {
        let mut mean = 0.0;
        for _ in 0..steps {
            mean += p;
            p += q;
        }
        p = if p + r > 0.0 { p * r / (p + r) } else { 0.0 };
        mean /= steps as f64;
        let change = (mean - previous).abs();
        previous = mean;
        if change <= CONVERGED * mean {
            break;
        }
    }
    previous
}

/// The idealized filter's steady-state RMS errors for a sensor
/// configuration, at specific-force magnitude `specific_force_m_s2`
/// (use [`STANDARD_GRAVITY`](super::STANDARD_GRAVITY) for hover).
pub fn noise_floor(sensors: &SensorConfig, specific_force_m_s2: f64) -> NoiseFloor {
    let horizontal = axis_covariance(sensors, specific_force_m_s2, true);
    let vertical = axis_covariance(sensors, 0.0, false);
    NoiseFloor {
        specific_force_m_s2,
        tilt_rad: horizontal[(TILT, TILT)].sqrt(),
        horizontal_velocity_m_s: horizontal[(VEL, VEL)].sqrt(),
        vertical_velocity_m_s: vertical[(VEL, VEL)].sqrt(),
        horizontal_position_m: horizontal[(POS, POS)].sqrt(),
        vertical_position_m: vertical[(POS, POS)].sqrt(),
        velocity_norm_m_s: (2.0 * horizontal[(VEL, VEL)] + vertical[(VEL, VEL)]).sqrt(),
        position_norm_m: (2.0 * horizontal[(POS, POS)] + vertical[(POS, POS)]).sqrt(),
        heading_mag_only_rad: heading_variance(sensors).sqrt(),
    }
}
