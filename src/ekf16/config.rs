//! Configuration of the 16-state EKF (and of every filter built on its core).
//!
//! Noise is given as continuous-time densities, independent of the IMU rate:
//!
//! | field | unit | meaning |
//! |---|---|---|
//! | `gyro_noise_density` | rad/s/√Hz | white noise on the rate |
//! | `accel_noise_density` | m/s²/√Hz | white noise on the specific force |
//! | `gyro_bias_random_walk` | rad/s/√s | drift of the gyro bias |
//! | `accel_bias_random_walk` | m/s²/√s | drift of the accelerometer bias |
//!
//! A datasheet or the paper's Table 3 gives a per-sample variance `σ²` at a
//! sample rate `f`; white noise of density `d` sampled at `f` (anti-aliased to
//! `f/2`) has variance `d² f`, so `d² = σ² / f`
//! ([`Ekf16Config::with_per_sample_imu_variances`]).
//!
//! The defaults are the paper's simulation (Table 3, IMU at 1 kHz): gyro
//! 0.0017 (rad/s)², accelerometer 0.01 g² per sample, GPS position 4 m²,
//! velocity 0.1 (m/s)², magnetometer 0.02 (unit field).

use crate::error::{Bound, Error, check};
use crate::integrity::IntegrityConfig;
use crate::kalman::GATE_5_SIGMA_3DOF;
use crate::scalar::{Scalar, zeros_const};
use crate::sensors::Geodetic;
use nalgebra::Vector3;

/// Longest [`Ekf16Config::align_min_duration_us`], µs (60 s).
const ALIGN_MAX_DURATION_US: u64 = 60_000_000;

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// Paper Table 3: gyro white-noise variance per sample, (rad/s)^2.
pub const TABLE3_GYRO_VARIANCE: f64 = 0.0017;
/// Paper Table 3: accelerometer white-noise variance per sample, g^2.
pub const TABLE3_ACCEL_VARIANCE_G2: f64 = 0.01;
/// Paper Table 3: magnetometer white-noise variance (unit field).
pub const TABLE3_MAG_VARIANCE: f64 = 0.02;
/// Paper Table 3: GPS position variance, m^2.
pub const TABLE3_GPS_POSITION_VARIANCE: f64 = 4.0;
/// Paper Table 3: GPS velocity variance, (m/s)^2.
pub const TABLE3_GPS_VELOCITY_VARIANCE: f64 = 0.1;
/// Default gate of the magnetometer's heading innovation: the chi-square
/// quantile of 1 degree of freedom at 3 sigma (`P(NIS > 9) = 0.27 %`). The
/// 3-D pseudo-measurement's innovation and `H` span one direction, so its NIS
/// is that of the scalar heading (see `docs/math.md`).
pub const MAG_HEADING_GATE_3_SIGMA: f64 = 9.0;
/// Default gate of the 3-axis magnetometer update: the chi-square quantile
/// of 2 degrees of freedom at 3 sigma (`P(NIS > 11.83) = 0.27 %`). The
/// innovation of two unit directions has no first-order component along the
/// field: its NIS has two degrees of freedom (see `docs/math.md`).
pub const MAG_FIELD_GATE_3_SIGMA: f64 = 11.83;
/// Default bound on the mean NIS of a GPS block over
/// [`DEFAULT_GPS_NIS_WINDOW`] accepted fusions: 20, innovations 2.6 times
/// the filter's own sigma on average over 20 fixes. It marks gross
/// divergence, not mere inconsistency: a consistent filter's mean is 3 and
/// exceeds 6.6 with probability 2.9e-7 (the chi-square quantile of 60
/// degrees of freedom at a one-sided 5-sigma tail, / 20), but a filter that is
/// only overconfident under strong manoeuvres (the augmented baseline in the
/// simulator's `high` scenario, NEES ~11) crossed 6.6 and 12 there, and each
/// reset threw away its velocity: `high` velocity RMSE 0.18 m/s at 20 (no
/// resets), 0.22 at 12, 0.31 at 6.6 (`reproduce --scenario high --seeds 4`).
pub const DEFAULT_GPS_NIS_BOUND: f64 = 20.0;
/// Default divergence window of a GPS block, accepted fusions.
pub const DEFAULT_GPS_NIS_WINDOW: u32 = 20;
/// The paper's IMU rate, Hz.
pub const PAPER_IMU_RATE_HZ: f64 = 1000.0;
/// The largest noise density, standard deviation or limit a configuration
/// may hold, in its own unit (m, m/s, rad/s, ...): `1e7`. Any physical
/// figure is far below it, and its square stays far from `f32`'s range in
/// the filter's sums (an initial position standard deviation of `1e30` m
/// was accepted, and every fix then failed to initialize in `f32`).
pub const MAX_MAGNITUDE: f64 = 1e7;

/// Everything the 16-state EKF needs to know that is not a sensor sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct Ekf16Config<T: Scalar> {
    /// Gravity magnitude, m/s^2 (NED: `[0, 0, +g]`).
    pub gravity_m_s2: T,
    /// Gyro white-noise density, rad/s/√Hz (positive, at most 1).
    pub gyro_noise_density: T,
    /// Accelerometer white-noise density, m/s^2/√Hz (positive, at most 10).
    pub accel_noise_density: T,
    /// Gyro bias random walk, rad/s/√s (in [0, 1]).
    pub gyro_bias_random_walk: T,
    /// Accelerometer bias random walk, m/s^2/√s (in [0, 1]).
    pub accel_bias_random_walk: T,

    /// GPS horizontal position noise (1 sigma, north and east), m.
    pub gps_horizontal_std_m: T,
    /// GPS vertical position noise (1 sigma), m.
    pub gps_vertical_std_m: T,
    /// GPS velocity noise (1 sigma per axis), m/s.
    pub gps_velocity_std_m_s: T,
    /// Use the receiver's reported accuracies instead of the three values
    /// above when a fix carries them.
    pub use_receiver_accuracy: bool,
    /// GPS antenna position relative to the IMU, body FRD, m.
    pub lever_arm_m: Vector3<T>,
    /// Origin of the local NED frame; `None`: the fix that initializes the filter.
    pub origin: Option<Geodetic>,

    /// Magnetic inclination, radians, positive down from horizontal.
    pub mag_inclination_rad: T,
    /// Magnetic declination, radians, east of true north.
    pub mag_declination_rad: T,
    /// Variance of each component of the unit-field pseudo-measurement.
    pub mag_noise_variance: T,
    /// Whether a magnetometer sample may correct roll and pitch.
    ///
    /// The heading is computed from the field de-rotated with the
    /// *estimated* roll and pitch, so with an inclined field it is wrong by
    /// about `tan(I)` times the tilt error; the measurement Jacobian carries
    /// that term in both modes (see
    /// [`mag_model_tilt_coupled`](crate::internals::measurement::mag_model_tilt_coupled)).
    /// `false` (default): a "consider" update restricted to heading (the
    /// paper's stated intent for eq. 7, see
    /// [`heading_only_restriction`](crate::internals::measurement::heading_only_restriction)
    /// and [`joseph_update_restricted`](crate::internals::kalman::joseph_update_restricted)):
    /// the correction's rotation is about the NED vertical only, the
    /// accelerometer biases and the roll/pitch-rate gyro biases are not
    /// moved; the tilt's uncertainty is still accounted for. `true`: the
    /// plain Kalman update, which also corrects roll and pitch through that
    /// term (and lets a magnetic disturbance tilt the filter).
    pub mag_corrects_tilt: bool,
    /// With `mag_corrects_tilt = false`: while the tilt is less certain
    /// than this (the larger of the north and east standard deviations of
    /// the attitude error, rad, from `P`), the magnetometer still corrects
    /// roll and pitch (the plain update): an alignment in flight, where the
    /// accelerometer gave a poor tilt and the heading's `tan(I)` share of
    /// the tilt error is real information. Below it the update is heading
    /// only. Default 0.035 rad (2 deg); +inf: heading only from the start.
    pub mag_tilt_alignment_std_rad: T,
    /// Largest relative difference between a magnetometer sample's field
    /// norm and the learned norm, `|m| / m0 - 1`; beyond, the sample is
    /// refused as disturbed (counted in `mag_disturbed`). Default 0.5: wide
    /// enough for Table 3 noise (0.14 of the field per axis).
    pub mag_norm_tolerance: T,
    /// Largest difference, rad, between a sample's inclination (seen with
    /// the estimated attitude) and the learned inclination; beyond, refused
    /// as disturbed. Default 0.5 rad (29 deg; Table 3 noise gives about
    /// 8 deg per sample).
    pub mag_inclination_tolerance_rad: T,
    /// Whether the magnetometer may be fused as a 3-axis field direction
    /// (which observes roll and pitch as well as heading) while the field
    /// is consistent: `true` (default) switches sample by sample between
    /// 3-axis, heading-only and no fusion (see
    /// [`MagMode`](crate::ekf16::MagMode)); `false`: heading-only (or none)
    /// always, as before.
    pub mag_three_axis: bool,
    /// Chi-square gate on the NIS of the 3-axis update (2 DOF; default
    /// [`MAG_FIELD_GATE_3_SIGMA`]).
    pub mag_three_axis_gate: T,
    /// Hard-iron offset, sensor units, body FRD: subtracted from every
    /// magnetometer sample before anything else (a calibration; default 0).
    pub mag_hard_iron: Vector3<T>,
    /// Weight of one accepted sample in the learned field norm and
    /// inclination (an exponential mean; learned first from the samples
    /// averaged at initialization). Default 1e-3 (10 s at 100 Hz).
    pub mag_field_learning_rate: T,

    /// Chi-square gate on the NIS of the GPS position block (3 DOF).
    pub gps_position_gate: T,
    /// Chi-square gate on the NIS of the GPS velocity block (3 DOF).
    pub gps_velocity_gate: T,
    /// Chi-square gate on the NIS of the magnetometer block, which is the
    /// NIS of the heading innovation (1 DOF; default
    /// [`MAG_HEADING_GATE_3_SIGMA`]).
    pub mag_gate: T,
    /// Longest time, microseconds, with a GPS block (position or velocity)
    /// rejected in every fix before that block is reset to a fix; each
    /// block has its own timer; 0: never. Without it a filter that has
    /// drifted past a gate never accepts that block again (a bad first fix,
    /// a position step with good velocity).
    pub gps_reset_timeout_us: u64,
    /// Divergence window of a GPS block, accepted fusions (0: no divergence
    /// detection). The NIS of the block's accepted fusions is averaged over
    /// consecutive windows of this many.
    pub gps_nis_window: u32,
    /// Bound on a block's mean NIS over a window; above it the block is
    /// reset to the fix (counted in `gps_divergence_resets`).
    pub gps_nis_bound: T,

    /// Longest IMU step integrated, microseconds, in `[1, MAX_TIME_JUMP_US]`
    /// (1 s); longer gaps are refused
    /// with [`Error::StepTooLong`] (the position carried by the velocity, the covariance grown for the
    /// unknown motion: `docs/integrity.md`).
    pub max_imu_step_us: u64,
    /// Largest plausible rate magnitude per axis, rad/s; larger samples are refused.
    pub max_gyro_rad_s: T,
    /// Largest plausible specific force per axis, m/s^2; larger samples are refused.
    pub max_accel_m_s2: T,

    /// IMU samples averaged for the initial roll and pitch (running mean
    /// up to this count, then exponential with weight `1 / align_window`).
    pub align_window: u32,
    /// Time the accelerometer mean must cover before a GPS fix may
    /// initialize the filter, µs (from the first IMU sample to the newest;
    /// at most 60 s). Default 50 ms: a vibration line above 40 Hz is then
    /// averaged over at least two periods, which leaves at most
    /// `1 / (pi f T)` (a sixth) of its amplitude in the mean, where one
    /// sample keeps all of it (2 m/s^2 across gravity tilts the level by 12 deg).
    /// `0` initializes on the first fix after one sample.
    pub align_min_duration_us: u32,
    /// Initial roll and pitch standard deviation, rad (in (0, pi]).
    pub initial_tilt_std_rad: T,
    /// Initial yaw standard deviation with a magnetometer heading, rad (in (0, pi]).
    pub initial_yaw_std_rad: T,
    /// Initial yaw standard deviation without magnetometer (yaw set to 0), rad (in (0, pi]).
    pub initial_yaw_std_no_mag_rad: T,
    /// Initial position standard deviation per axis, m.
    pub initial_position_std_m: T,
    /// Initial velocity standard deviation per axis, m/s.
    pub initial_velocity_std_m_s: T,
    /// Initial accelerometer-bias estimate, body FRD, m/s^2 (a calibrated
    /// IMU; default zero). Subtracted from the accelerometer mean the
    /// initial roll and pitch come from.
    pub initial_accel_bias_m_s2: Vector3<T>,
    /// Initial accelerometer-bias standard deviation per axis, m/s^2: the
    /// uncertainty of [`initial_accel_bias_m_s2`](Self::initial_accel_bias_m_s2).
    pub initial_accel_bias_std_m_s2: T,
    /// Initial gyro-bias estimate, body FRD, rad/s (default zero).
    pub initial_gyro_bias_rad_s: Vector3<T>,
    /// Initial gyro-bias standard deviation per axis, rad/s: the uncertainty
    /// of [`initial_gyro_bias_rad_s`](Self::initial_gyro_bias_rad_s).
    pub initial_gyro_bias_std_rad_s: T,
    /// The integrity risk and the alert limits of the protection levels
    /// ([`crate::integrity`]).
    pub integrity: IntegrityConfig<T>,
}

impl<T: Scalar> Ekf16Config<T> {
    /// Every field zero (never valid): the configuration of a blank filter.
    pub(crate) const ZEROED: Self = Self {
        gravity_m_s2: T::ZERO,
        gyro_noise_density: T::ZERO,
        accel_noise_density: T::ZERO,
        gyro_bias_random_walk: T::ZERO,
        accel_bias_random_walk: T::ZERO,
        gps_horizontal_std_m: T::ZERO,
        gps_vertical_std_m: T::ZERO,
        gps_velocity_std_m_s: T::ZERO,
        use_receiver_accuracy: false,
        lever_arm_m: zeros_const(),
        origin: None,
        mag_inclination_rad: T::ZERO,
        mag_declination_rad: T::ZERO,
        mag_noise_variance: T::ZERO,
        mag_corrects_tilt: false,
        mag_tilt_alignment_std_rad: T::ZERO,
        mag_norm_tolerance: T::ZERO,
        mag_inclination_tolerance_rad: T::ZERO,
        mag_three_axis: false,
        mag_three_axis_gate: T::ZERO,
        mag_hard_iron: zeros_const(),
        mag_field_learning_rate: T::ZERO,
        gps_position_gate: T::ZERO,
        gps_velocity_gate: T::ZERO,
        mag_gate: T::ZERO,
        gps_reset_timeout_us: 0,
        gps_nis_window: 0,
        gps_nis_bound: T::ZERO,
        max_imu_step_us: 0,
        max_gyro_rad_s: T::ZERO,
        max_accel_m_s2: T::ZERO,
        align_window: 0,
        align_min_duration_us: 0,
        initial_tilt_std_rad: T::ZERO,
        initial_yaw_std_rad: T::ZERO,
        initial_yaw_std_no_mag_rad: T::ZERO,
        initial_position_std_m: T::ZERO,
        initial_velocity_std_m_s: T::ZERO,
        initial_accel_bias_m_s2: zeros_const(),
        initial_accel_bias_std_m_s2: T::ZERO,
        initial_gyro_bias_rad_s: zeros_const(),
        initial_gyro_bias_std_rad_s: T::ZERO,
        integrity: IntegrityConfig::ZEROED,
    };
}

impl<T: Scalar> Default for Ekf16Config<T> {
    fn default() -> Self {
        let g = STANDARD_GRAVITY;
        Self {
            gravity_m_s2: T::lit(g),
            gyro_noise_density: T::lit(TABLE3_GYRO_VARIANCE / PAPER_IMU_RATE_HZ).sqrt(),
            accel_noise_density: T::lit(TABLE3_ACCEL_VARIANCE_G2 * g * g / PAPER_IMU_RATE_HZ)
                .sqrt(),
            gyro_bias_random_walk: T::lit(1e-4),
            accel_bias_random_walk: T::lit(1e-3),
            gps_horizontal_std_m: T::lit(TABLE3_GPS_POSITION_VARIANCE).sqrt(),
            gps_vertical_std_m: T::lit(TABLE3_GPS_POSITION_VARIANCE).sqrt(),
            gps_velocity_std_m_s: T::lit(TABLE3_GPS_VELOCITY_VARIANCE).sqrt(),
            use_receiver_accuracy: true,
            lever_arm_m: Vector3::zeros(),
            origin: None,
            mag_inclination_rad: T::zero(),
            mag_declination_rad: T::zero(),
            mag_noise_variance: T::lit(TABLE3_MAG_VARIANCE),
            mag_corrects_tilt: false,
            mag_tilt_alignment_std_rad: T::lit(0.035),
            mag_norm_tolerance: T::lit(0.5),
            mag_inclination_tolerance_rad: T::lit(0.5),
            mag_three_axis: true,
            mag_three_axis_gate: T::lit(MAG_FIELD_GATE_3_SIGMA),
            mag_hard_iron: Vector3::zeros(),
            mag_field_learning_rate: T::lit(1e-3),
            gps_position_gate: T::lit(GATE_5_SIGMA_3DOF),
            gps_velocity_gate: T::lit(GATE_5_SIGMA_3DOF),
            mag_gate: T::lit(MAG_HEADING_GATE_3_SIGMA),
            gps_reset_timeout_us: 5_000_000,
            gps_nis_window: DEFAULT_GPS_NIS_WINDOW,
            gps_nis_bound: T::lit(DEFAULT_GPS_NIS_BOUND),
            max_imu_step_us: 250_000,
            max_gyro_rad_s: T::lit(35.0),
            max_accel_m_s2: T::lit(400.0),
            align_window: 200,
            align_min_duration_us: 50_000,
            initial_tilt_std_rad: T::lit(0.1),
            initial_yaw_std_rad: T::lit(0.3),
            initial_yaw_std_no_mag_rad: T::lit(0.5),
            initial_position_std_m: T::lit(5.0),
            initial_velocity_std_m_s: T::lit(1.0),
            initial_accel_bias_m_s2: Vector3::zeros(),
            initial_accel_bias_std_m_s2: T::lit(0.1 * g),
            initial_gyro_bias_rad_s: Vector3::zeros(),
            initial_gyro_bias_std_rad_s: T::lit(0.01),
            integrity: IntegrityConfig::default(),
        }
    }
}

impl<T: Scalar> Ekf16Config<T> {
    /// The defaults with the IMU noise given as per-sample variances at a
    /// sample rate (the paper's Table 3 style): `density² = variance / rate`.
    ///
    /// `gyro_variance` in (rad/s)^2, `accel_variance` in (m/s^2)^2, `imu_rate_hz` in Hz.
    pub fn with_per_sample_imu_variances(
        gyro_variance: T,
        accel_variance: T,
        imu_rate_hz: T,
    ) -> Self {
        Self {
            gyro_noise_density: (gyro_variance / imu_rate_hz).sqrt(),
            accel_noise_density: (accel_variance / imu_rate_hz).sqrt(),
            ..Self::default()
        }
    }

    /// Checks every field; the first offending one is named in the error
    /// with its value and the bound it broke.
    pub fn validate(&self) -> Result<(), Error> {
        // Densities, standard deviations and limits: positive and at most
        // MAX_MAGNITUDE.
        for (field, v) in [
            ("gravity_m_s2", self.gravity_m_s2),
            ("gyro_noise_density", self.gyro_noise_density),
            ("accel_noise_density", self.accel_noise_density),
            ("gps_horizontal_std_m", self.gps_horizontal_std_m),
            ("gps_vertical_std_m", self.gps_vertical_std_m),
            ("gps_velocity_std_m_s", self.gps_velocity_std_m_s),
            ("mag_noise_variance", self.mag_noise_variance),
            ("mag_field_learning_rate", self.mag_field_learning_rate),
            ("max_gyro_rad_s", self.max_gyro_rad_s),
            ("max_accel_m_s2", self.max_accel_m_s2),
            ("initial_position_std_m", self.initial_position_std_m),
            ("initial_velocity_std_m_s", self.initial_velocity_std_m_s),
            (
                "initial_accel_bias_std_m_s2",
                self.initial_accel_bias_std_m_s2,
            ),
            (
                "initial_gyro_bias_std_rad_s",
                self.initial_gyro_bias_std_rad_s,
            ),
        ] {
            check::positive_finite(field, v)?;
            check::at_most(field, v, T::lit(MAX_MAGNITUDE))?;
        }
        // Gates, tolerances and the NIS bound: positive, +inf allowed (no
        // check).
        for (field, v) in [
            ("gps_position_gate", self.gps_position_gate),
            ("gps_velocity_gate", self.gps_velocity_gate),
            ("mag_gate", self.mag_gate),
            ("mag_three_axis_gate", self.mag_three_axis_gate),
            (
                "mag_tilt_alignment_std_rad",
                self.mag_tilt_alignment_std_rad,
            ),
            ("mag_norm_tolerance", self.mag_norm_tolerance),
            (
                "mag_inclination_tolerance_rad",
                self.mag_inclination_tolerance_rad,
            ),
            ("gps_nis_bound", self.gps_nis_bound),
        ] {
            check::positive(field, v)?;
        }
        // The attitude standard deviations: positive and at most pi (an
        // angle's error says nothing beyond it; a larger one made the f32
        // covariance lose its sign after the first fix).
        for (field, v) in [
            ("initial_tilt_std_rad", self.initial_tilt_std_rad),
            ("initial_yaw_std_rad", self.initial_yaw_std_rad),
            (
                "initial_yaw_std_no_mag_rad",
                self.initial_yaw_std_no_mag_rad,
            ),
        ] {
            check::positive(field, v)?;
            check::at_most(field, v, T::pi())?;
        }
        // Noise densities: at most 1 rad/s/√Hz and 10 m/s^2/√Hz, a hundred
        // times the noisiest consumer MEMS part; 1e4 let the covariance of
        // an IMU gap leave f32's range.
        check::at_most("gyro_noise_density", self.gyro_noise_density, T::one())?;
        check::at_most(
            "accel_noise_density",
            self.accel_noise_density,
            T::lit(10.0),
        )?;
        // Bias random walks: in [0, 1] per √s. A bias whose standard
        // deviation grows by one rad/s or m/s^2 in a second is no bias, and
        // 1e30 let the covariance overflow within a second.
        check::within(
            "gyro_bias_random_walk",
            self.gyro_bias_random_walk,
            T::zero(),
            T::one(),
        )?;
        check::within(
            "accel_bias_random_walk",
            self.accel_bias_random_walk,
            T::zero(),
            T::one(),
        )?;
        for (field, v) in [
            ("lever_arm_m.x", self.lever_arm_m.x),
            ("lever_arm_m.y", self.lever_arm_m.y),
            ("lever_arm_m.z", self.lever_arm_m.z),
            ("initial_gyro_bias_rad_s.x", self.initial_gyro_bias_rad_s.x),
            ("initial_gyro_bias_rad_s.y", self.initial_gyro_bias_rad_s.y),
            ("initial_gyro_bias_rad_s.z", self.initial_gyro_bias_rad_s.z),
            ("mag_hard_iron.x", self.mag_hard_iron.x),
            ("mag_hard_iron.y", self.mag_hard_iron.y),
            ("mag_hard_iron.z", self.mag_hard_iron.z),
        ] {
            check::finite(field, v)?;
        }
        // A bias beyond the plausible sample is not a bias.
        for (field, v) in [
            ("initial_accel_bias_m_s2.x", self.initial_accel_bias_m_s2.x),
            ("initial_accel_bias_m_s2.y", self.initial_accel_bias_m_s2.y),
            ("initial_accel_bias_m_s2.z", self.initial_accel_bias_m_s2.z),
        ] {
            check::within(field, v, -self.max_accel_m_s2, self.max_accel_m_s2)?;
        }
        check::within(
            "mag_declination_rad",
            self.mag_declination_rad,
            -T::pi(),
            T::pi(),
        )?;
        // A vertical field has no heading.
        let has_heading = self.mag_inclination_rad.abs() < T::frac_pi_2();
        if !has_heading {
            return Err(check::invalid(
                "mag_inclination_rad",
                self.mag_inclination_rad,
                Bound::Rule("|inclination| must be below pi/2 (a vertical field has no heading)"),
            ));
        }
        check::at_most(
            "mag_field_learning_rate",
            self.mag_field_learning_rate,
            T::one(),
        )?;
        // A step longer than a time jump (`MAX_TIME_JUMP_US`, 1 s) is a gap,
        // not a sample step: integrated, steps of 1,000 s (a configured 1e9
        // µs) took the covariance out of f32's reach.
        check::count_within(
            "max_imu_step_us",
            self.max_imu_step_us,
            1,
            crate::ekf16::MAX_TIME_JUMP_US,
        )?;
        check::count_at_least("align_window", self.align_window.into(), 1)?;
        check::count_within(
            "align_min_duration_us",
            self.align_min_duration_us.into(),
            0,
            ALIGN_MAX_DURATION_US,
        )?;
        if let Some(o) = self.origin {
            check::within("origin.lat_deg", o.lat_deg, -90.0, 90.0)?;
            check::within("origin.lon_deg", o.lon_deg, -360.0, 360.0)?;
            check::finite("origin.alt_m", o.alt_m)?;
        }
        self.integrity.validate()
    }
}
