//! Sensor models of the simulator, with the paper's Table 3 as defaults.
//!
//! At IMU sample `k` (time `t_k`), with the true motion of
//! [`trajectory`](super::trajectory):
//!
//! ```text
//! gyro_k  = w_b(t_k) + b_g(t_k) + n_g,k + v_g(t_k)        n_g ~ N(0, s_g^2 I)
//! accel_k = f_b(t_k) + b_a(t_k) + n_a,k + v_a(t_k)        n_a ~ N(0, s_a^2 I)
//! mag_m   = S R(t_m)^T m_n + b_hi + n_m,m                 n_m ~ N(0, s_m^2 I)
//! gps_j   = [p(t_j - tau_j) + n_p,  v(t_j - tau_j) + n_v]  n_p ~ N(0, s_p^2 I), n_v ~ N(0, s_v^2 I)
//! ```
//!
//! - The white-noise variances are **per sample** at the sensor's own rate
//!   (Table 3 read literally at 1 kHz): changing the rate keeps the
//!   per-sample variance, so the noise density is `s^2 / rate`.
//! - Biases are constant per run, each axis drawn uniformly in
//!   `[-max, max]` (Table 3: 0.01 rad/s, 0.1 g), plus an optional random
//!   walk `b(t_k+1) = b(t_k) + N(0, q dt)` with density `q` per axis.
//! - `m_n = [cos I cos D, cos I sin D, sin I]` (unit field; Shanghai by
//!   default: declination -6 deg 2', inclination 47 deg 14').
//! - Magnetometer calibration errors: a soft-iron matrix `S` (identity by
//!   default) and a hard-iron offset `b_hi` (body FRD, unit field; zero by
//!   default), both fixed to the body.
//! - Motor vibration: harmonics `A_h sin(2 pi f_h t + phi_h,axis)` added to
//!   gyro and accelerometer, each axis with its own random phase.
//! - `g` in Table 3's units is standard gravity, 9.80665 m/s^2.

use super::trajectory::STANDARD_GRAVITY;
use crate::Scalar;
use crate::ekf16::{
    Ekf16Config, PAPER_IMU_RATE_HZ, TABLE3_ACCEL_VARIANCE_G2, TABLE3_GPS_POSITION_VARIANCE,
    TABLE3_GPS_VELOCITY_VARIANCE, TABLE3_GYRO_VARIANCE, TABLE3_MAG_VARIANCE,
};
use crate::sensors::Geodetic;
use nalgebra::{Matrix3, Vector3};

/// Allowed IMU rates, Hz.
pub const IMU_RATE_RANGE_HZ: core::ops::RangeInclusive<f64> = 50.0..=2000.0;
/// Allowed GPS rates, Hz.
pub const GPS_RATE_RANGE_HZ: core::ops::RangeInclusive<f64> = 1.0..=20.0;

/// How the simulated GPS reports its position.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GpsPositionOutput {
    /// Local NED metres about the origin (`GpsPosition::Ned`).
    Ned,
    /// WGS-84 latitude, longitude, height (`GpsPosition::Geodetic`).
    Geodetic,
}

/// One harmonic of motor vibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VibrationHarmonic {
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Amplitude on every gyro axis, rad/s.
    pub gyro_amplitude_rad_s: f64,
    /// Amplitude on every accelerometer axis, m/s^2.
    pub accel_amplitude_m_s2: f64,
}

/// Sensor rates, noise, biases and the magnetic field. `Default` is the
/// paper's Table 3 at IMU 1000 Hz, GPS 10 Hz, magnetometer 100 Hz (the
/// paper's MPU-9250 carries an AK8963 magnetometer, whose fastest
/// continuous mode is 100 Hz; the paper states no magnetometer rate).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorConfig {
    /// IMU rate, Hz (50-2000).
    pub imu_rate_hz: f64,
    /// GPS rate, Hz (1-20).
    pub gps_rate_hz: f64,
    /// Magnetometer rate, Hz (at most the IMU rate; 0: no magnetometer at
    /// all, the run carries no magnetometer sample).
    pub mag_rate_hz: f64,
    /// Gyro white-noise variance per sample, (rad/s)^2. Table 3: 0.0017.
    pub gyro_noise_var_rad2_s2: f64,
    /// Accelerometer white-noise variance per sample, g^2. Table 3: 0.01.
    pub accel_noise_var_g2: f64,
    /// Magnetometer white-noise variance per sample, unit field squared. Table 3: 0.02.
    pub mag_noise_var: f64,
    /// Largest absolute gyro bias per axis, rad/s. Table 3: 0.01.
    pub gyro_bias_max_rad_s: f64,
    /// Largest absolute accelerometer bias per axis, g. Table 3: 0.1.
    pub accel_bias_max_g: f64,
    /// Gyro bias random-walk density, rad/s/sqrt(s) (0: constant bias).
    pub gyro_bias_walk_rad_s_sqrt_s: f64,
    /// Accelerometer bias random-walk density, m/s^2/sqrt(s) (0: constant bias).
    pub accel_bias_walk_m_s2_sqrt_s: f64,
    /// GPS position white-noise variance per axis, m^2. Table 3: 4.
    pub gps_position_var_m2: f64,
    /// GPS velocity white-noise variance per axis, (m/s)^2. Table 3: 0.1.
    pub gps_velocity_var_m2_s2: f64,
    /// Whether fixes carry NED or geodetic positions.
    pub gps_position_output: GpsPositionOutput,
    /// Origin of the local NED frame (Shanghai by default).
    pub origin: Geodetic,
    /// Magnetic declination, radians east of true north.
    pub declination_rad: f64,
    /// Magnetic inclination, radians down from horizontal.
    pub inclination_rad: f64,
    /// Motor vibration harmonics (none by default).
    pub vibration: Vec<VibrationHarmonic>,
    /// Magnetometer hard-iron offset `b_hi`, body FRD, unit field (zero by default).
    pub mag_hard_iron: Vector3<f64>,
    /// Magnetometer soft-iron matrix `S` (identity by default).
    pub mag_soft_iron: Matrix3<f64>,
}

/// Degrees and arc minutes to radians.
fn deg_min(deg: f64, min: f64) -> f64 {
    (deg.abs() + min / 60.0).copysign(deg).to_radians()
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            imu_rate_hz: PAPER_IMU_RATE_HZ,
            gps_rate_hz: 10.0,
            mag_rate_hz: 100.0,
            gyro_noise_var_rad2_s2: TABLE3_GYRO_VARIANCE,
            accel_noise_var_g2: TABLE3_ACCEL_VARIANCE_G2,
            mag_noise_var: TABLE3_MAG_VARIANCE,
            gyro_bias_max_rad_s: 0.01,
            accel_bias_max_g: 0.1,
            gyro_bias_walk_rad_s_sqrt_s: 0.0,
            accel_bias_walk_m_s2_sqrt_s: 0.0,
            gps_position_var_m2: TABLE3_GPS_POSITION_VARIANCE,
            gps_velocity_var_m2_s2: TABLE3_GPS_VELOCITY_VARIANCE,
            gps_position_output: GpsPositionOutput::Ned,
            origin: Geodetic {
                lat_deg: 31.2304,
                lon_deg: 121.4737,
                alt_m: 10.0,
            },
            declination_rad: deg_min(-6.0, 2.0),
            inclination_rad: deg_min(47.0, 14.0),
            vibration: Vec::new(),
            mag_hard_iron: Vector3::zeros(),
            mag_soft_iron: Matrix3::identity(),
        }
    }
}

impl SensorConfig {
    /// Every noise and bias set to zero: the sensors read the truth exactly.
    pub fn noise_free() -> Self {
        Self {
            gyro_noise_var_rad2_s2: 0.0,
            accel_noise_var_g2: 0.0,
            mag_noise_var: 0.0,
            gyro_bias_max_rad_s: 0.0,
            accel_bias_max_g: 0.0,
            gps_position_var_m2: 0.0,
            gps_velocity_var_m2_s2: 0.0,
            ..Self::default()
        }
    }

    /// Accelerometer white-noise standard deviation per sample, m/s^2.
    pub fn accel_noise_std_m_s2(&self) -> f64 {
        self.accel_noise_var_g2.sqrt() * STANDARD_GRAVITY
    }

    /// Largest absolute accelerometer bias, m/s^2.
    pub fn accel_bias_max_m_s2(&self) -> f64 {
        self.accel_bias_max_g * STANDARD_GRAVITY
    }

    /// The filters' configuration matched to these sensors: their own noise
    /// (Table 3 read per sample at the IMU rate), magnetic field and bias
    /// spread (the standard deviation of a uniform draw in `[-max, max]` is
    /// `max / sqrt(3)`, floored at 1 mm/s^2 and 1e-4 rad/s).
    pub fn ekf16_config<T: Scalar>(&self) -> Ekf16Config<T> {
        Ekf16Config {
            mag_inclination_rad: T::lit(self.inclination_rad),
            mag_declination_rad: T::lit(self.declination_rad),
            mag_noise_variance: T::lit(self.mag_noise_var),
            gps_horizontal_std_m: T::lit(self.gps_position_var_m2.sqrt()),
            gps_vertical_std_m: T::lit(self.gps_position_var_m2.sqrt()),
            gps_velocity_std_m_s: T::lit(self.gps_velocity_var_m2_s2.sqrt()),
            initial_accel_bias_std_m_s2: T::lit(
                (self.accel_bias_max_m_s2() / 3f64.sqrt()).max(1e-3),
            ),
            initial_gyro_bias_std_rad_s: T::lit((self.gyro_bias_max_rad_s / 3f64.sqrt()).max(1e-4)),
            ..Ekf16Config::with_per_sample_imu_variances(
                T::lit(self.gyro_noise_var_rad2_s2),
                T::lit(self.accel_noise_var_g2 * STANDARD_GRAVITY * STANDARD_GRAVITY),
                T::lit(self.imu_rate_hz),
            )
        }
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), crate::Error> {
        use crate::Error::InvalidConfig;
        if !IMU_RATE_RANGE_HZ.contains(&self.imu_rate_hz) {
            return Err(InvalidConfig {
                field: "imu_rate_hz".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be in 50-2000 Hz"),
            });
        }
        if !GPS_RATE_RANGE_HZ.contains(&self.gps_rate_hz) {
            return Err(InvalidConfig {
                field: "gps_rate_hz".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be in 1-20 Hz"),
            });
        }
        if !(self.mag_rate_hz >= 0.0 && self.mag_rate_hz <= self.imu_rate_hz) {
            return Err(InvalidConfig {
                field: "mag_rate_hz".into(),
                value: None,
                bound: crate::error::Bound::Rule(
                    "must be 0 (no magnetometer) or positive and at most the IMU rate",
                ),
            });
        }
        let non_negative = [
            (self.gyro_noise_var_rad2_s2, "gyro_noise_var_rad2_s2"),
            (self.accel_noise_var_g2, "accel_noise_var_g2"),
            (self.mag_noise_var, "mag_noise_var"),
            (self.gyro_bias_max_rad_s, "gyro_bias_max_rad_s"),
            (self.accel_bias_max_g, "accel_bias_max_g"),
            (
                self.gyro_bias_walk_rad_s_sqrt_s,
                "gyro_bias_walk_rad_s_sqrt_s",
            ),
            (
                self.accel_bias_walk_m_s2_sqrt_s,
                "accel_bias_walk_m_s2_sqrt_s",
            ),
            (self.gps_position_var_m2, "gps_position_var_m2"),
            (self.gps_velocity_var_m2_s2, "gps_velocity_var_m2_s2"),
        ];
        for (value, field) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(InvalidConfig {
                    field: field.into(),
                    value: Some(value),
                    bound: crate::error::Bound::NotNegative,
                });
            }
        }
        if !self.origin.is_valid() {
            return Err(InvalidConfig {
                field: "origin".into(),
                value: None,
                bound: crate::error::Bound::Rule("not a valid geodetic position"),
            });
        }
        if !self.declination_rad.is_finite() || !self.inclination_rad.is_finite() {
            return Err(InvalidConfig {
                field: "inclination_rad".into(),
                value: None,
                bound: crate::error::Bound::Rule("field angles must be finite"),
            });
        }
        if !(self.mag_hard_iron.iter().all(|v| v.is_finite())
            && self.mag_soft_iron.iter().all(|v| v.is_finite()))
        {
            return Err(InvalidConfig {
                field: "mag_soft_iron".into(),
                value: None,
                bound: crate::error::Bound::Rule("hard- and soft-iron terms must be finite"),
            });
        }
        if self.vibration.iter().any(|h| {
            !(h.frequency_hz.is_finite()
                && h.frequency_hz >= 0.0
                && h.gyro_amplitude_rad_s.is_finite()
                && h.accel_amplitude_m_s2.is_finite())
        }) {
            return Err(InvalidConfig {
                field: "vibration".into(),
                value: None,
                bound: crate::error::Bound::Rule(
                    "frequencies and amplitudes must be finite, frequencies non-negative",
                ),
            });
        }
        Ok(())
    }
}
