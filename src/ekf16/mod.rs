//! The paper's 16-state extended Kalman filter (section 2.1), without delay
//! handling: GPS fixes are fused as if they described the current instant.
//!
//! | part | where | paper |
//! |---|---|---|
//! | state `x = [q r v b_f b_w]` | [`state`] | eq. (1) |
//! | process model, `F`, `A`, `Q` | [`internals::process`](crate::internals::process) | eqs. (2)-(5) |
//! | GPS and magnetometer models | [`internals::measurement`](crate::internals::measurement) | eqs. (6)-(8) |
//! | gain, Joseph update, gating | [`internals::kalman`](crate::internals::kalman) | eqs. (9)-(10) |
//! | configuration | [`Ekf16Config`] | Table 3 defaults |
//!
//! # Where this departs from the paper's print
//! - eq. (3): the (3,1) entry of `R(q)` is `2(q1 q3 - q0 q2)` (printed with `+`);
//! - eq. (4): the attitude is integrated with the exact rotation over the
//!   step, not an Euler step (see [`internals::process`](crate::internals::process));
//! - eq. (5): `P = A P A^T + Q` (the transpose is missing);
//! - eq. (6): `C_psi(3,3) = 1` (printed 0), and `m_n = [cos I cos D, cos I sin D, sin I]`
//!   with `I` measured down from horizontal;
//! - eqs. (7)-(8): the magnetometer model holds roll and pitch at the
//!   estimate, and its Jacobian carries the tilt error the heading inherits
//!   from them (`tan(I)` per radian; a yaw-only Jacobian diverges with a fast
//!   magnetometer); once the tilt is known (`mag_tilt_alignment_std_rad`)
//!   the update corrects heading only, as the text intends: its correction
//!   is a rotation about the NED vertical and it leaves the accelerometer
//!   biases alone ([`measurement::heading_only_restriction`]);
//! - eq. (9): `K = P H^T (H P H^T + R)^-1` (printed `H^T P H^T`);
//! - additions: Joseph-form update, chi-square gating, the GPS lever arm,
//!   and the quaternion's covariance kept in the tangent space of the unit
//!   sphere (see `docs/math.md`).
//!
//! # One cycle
//! - **IMU sample** ([`Navigator::push_imu`]): the step length is the
//!   difference of consecutive IMU timestamps (any rate, 50 Hz to 1 kHz and
//!   irregular); the first sample only sets the clock. The rate and specific
//!   force over a step are the mean of the samples at its two ends. The state
//!   goes through [`process::propagate`], the covariance through
//!   `P = A P A^T + Q`.
//! - **GPS fix** ([`Navigator::push_gps`]): position then velocity, two
//!   3-D blocks, each gated on its NIS and recorded; the velocity block is
//!   linearized after the position update (sequential fusion). Each block
//!   is reset to the fix on its own (shifted by its innovation, its rows and
//!   columns of `P` cleared, its variances set to the fix's `R`; ArduPilot
//!   and PX4 recover the same way) when it has been rejected in every fix
//!   for `gps_reset_timeout_us` (default 5 s, one timer per block), or when
//!   the mean NIS of its last `gps_nis_window` accepted fusions exceeds
//!   `gps_nis_bound` (divergence). Counted per block and recorded
//!   ([`Ekf16::last_gps_reset`]). Geodetic and NED fixes cannot be mixed.
//! - **Magnetometer sample** ([`Navigator::push_mag`]): refused as disturbed
//!   when its field norm or inclination is too far from the learned field,
//!   gated on its heading innovation (1 DOF), then the heading
//!   pseudo-measurement is fused and recorded (see `docs/math.md`,
//!   "Magnetometer gating").
//!
//! # Initialization
//! Before the first GPS fix the filter only listens: it averages the
//! accelerometer (running mean over up to `align_window` samples, then an
//! exponential mean of the same length) and the direction of the
//! magnetometer field the same way. The first fix once that mean covers
//! `align_min_duration_us` (default 50 ms: a vibration line above 40 Hz
//! averaged over two periods, where one sample would keep all of it) sets
//!
//! - roll and pitch from the mean specific force
//!   ([`roll_pitch_from_accel`](crate::geo::roll_pitch_from_accel); valid when
//!   the vehicle did not accelerate meanwhile);
//! - yaw from the tilt-compensated heading of the mean field direction (at
//!   rest, averaging beats the latest sample; the paper's Table 3 noise is
//!   17 deg of heading per sample), or 0 with the
//!   variance `initial_yaw_std_no_mag_rad²` without a magnetometer;
//! - position and velocity from the fix (minus the lever-arm terms), biases 0;
//! - `P` diagonal from the configured standard deviations, the attitude block
//!   through [`state::attitude_covariance`].
//!
//! [`Ekf16::from_state`] starts from a known state instead.
//!
//! # Bad input
//! Non-finite or implausible samples ([`Error::NonFinite`],
//! [`Error::OutOfRange`]), duplicates ([`Error::DuplicateTimestamp`]) and
//! samples going back in time ([`Error::TimeWentBackwards`]) are refused
//! and leave the filter unchanged; [`Ekf16::refusals`] counts them. An IMU
//! gap longer than `max_imu_step_us` returns [`Error::StepTooLong`]: the
//! clock moves to the sample, the position is carried by the velocity over
//! the gap, and `P` grows by `Q` of the gap and by the motion nobody measured
//! (an unknown acceleration and rotation rate, `docs/integrity.md`), over at
//! most [`MAX_GAP_NOISE_US`] (the state is then unknown anyway; the GPS block
//! resets bring it back).

mod config;
#[doc(hidden)]
pub mod delta;
pub mod latency;
#[doc(hidden)]
pub mod measurement;
pub(crate) mod nav_core;
#[doc(hidden)]
pub mod process;
pub mod state;

pub use config::{
    DEFAULT_GPS_NIS_BOUND, DEFAULT_GPS_NIS_WINDOW, Ekf16Config, MAG_FIELD_GATE_3_SIGMA,
    MAG_HEADING_GATE_3_SIGMA, MAX_MAGNITUDE, PAPER_IMU_RATE_HZ, STANDARD_GRAVITY,
    TABLE3_ACCEL_VARIANCE_G2, TABLE3_GPS_POSITION_VARIANCE, TABLE3_GPS_VELOCITY_VARIANCE,
    TABLE3_GYRO_VARIANCE, TABLE3_MAG_VARIANCE,
};
pub use state::NavState;

use crate::error::Error;
use crate::estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome, Navigator};
use crate::geo::LocalFrame;
use crate::scalar::{Scalar, us_to_s};
use crate::sensors::{GpsFix, ImuSample, MagSample};
use nalgebra::Vector3;
use nav_core::NavCore;
pub use nav_core::{
    GpsBlock, MAG_ALIGNING_INCLINATION_RATE, MAG_FIELD_MIN_SAMPLES, MAG_GAP_US,
    MAG_INFLIGHT_TILT_STD_RAD, MAG_THREE_AXIS_HOLD_US, MAG_THREE_AXIS_INCLINATION_TOLERANCE_RAD,
    MAX_GAP_NOISE_US, MAX_TIME_JUMP_US, QUATERNION_VARIANCE_CEILING,
};
use state::{NAV_STATES, StateCovariance, StateVector};

/// How a magnetometer sample is fused, chosen sample by sample (see
/// `docs/math.md`, "Magnetometer: mode switching").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MagMode {
    /// Not fused: the field's norm or inclination is off the learned field
    /// (a disturbance), or no sample yet. First, so that a blank filter is
    /// all zero bytes.
    NoFusion,
    /// The tilt-compensated heading only.
    HeadingOnly,
    /// The field direction, all three axes: corrects roll, pitch and heading.
    ThreeAxis,
}

impl MagMode {
    /// Index in [`MagModeHealth::time_us`].
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// The magnetometer's fusion mode and the time spent in each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MagModeHealth {
    /// Mode of the last sample after initialization ([`MagMode::NoFusion`] before one).
    pub mode: MagMode,
    /// Changes of mode between consecutive samples.
    pub switches: u32,
    /// Time spent in each mode, µs, indexed by [`MagMode::index`]: the
    /// interval before each sample counts in that sample's mode; an interval
    /// longer than [`MAG_GAP_US`] (no samples) counts as
    /// [`MagMode::NoFusion`].
    pub time_us: [u64; 3],
}

impl MagModeHealth {
    /// No sample yet.
    pub const START: Self = Self {
        mode: MagMode::NoFusion,
        switches: 0,
        time_us: [0; 3],
    };
}

/// How many samples were refused or gated out, by kind.
///
/// Counting is the only trace a refused sample leaves.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct FilterRefusals {
    /// IMU samples with a non-finite value.
    pub imu_non_finite: u32,
    /// IMU samples above the plausible range, or whose step would make the state non-finite
    /// (refused); also the steps integrated with a quaternion variance capped at
    /// [`QUATERNION_VARIANCE_CEILING`] (a rotation per step too large for the covariance's
    /// linearization: samples far apart at high rates).
    pub imu_out_of_range: u32,
    /// IMU samples duplicated or going back in time.
    pub imu_time: u32,
    /// IMU steps longer than `max_imu_step_us` (not integrated).
    pub imu_step_too_long: u32,
    /// IMU samples more than [`MAX_TIME_JUMP_US`] after the previous one, refused until
    /// the next sample confirms the jump (a sample stamped in the future).
    pub imu_ahead: u32,
    /// GPS fixes with a non-finite or invalid value.
    pub gps_invalid: u32,
    /// GPS fixes duplicated or going back in time.
    pub gps_time: u32,
    /// GPS position blocks rejected by the gate.
    pub gps_position_rejected: u32,
    /// GPS velocity blocks rejected by the gate.
    pub gps_velocity_rejected: u32,
    /// Magnetometer samples with a non-finite or zero field.
    pub mag_invalid: u32,
    /// Magnetometer samples duplicated or going back in time.
    pub mag_time: u32,
    /// Magnetometer updates rejected by the heading-innovation gate (`mag_gate`), and samples
    /// refused while the field offset the monitor holds can turn the heading beyond its alert
    /// limit (see `mag_field_offset`).
    pub mag_rejected: u32,
    /// Magnetometer samples refused as disturbed: field norm or inclination
    /// too far from the learned field (`mag_norm_tolerance`,
    /// `mag_inclination_tolerance_rad`).
    pub mag_disturbed: u32,
    /// GPS fixes whose position kind (geodetic or NED) differs from the
    /// first accepted fix's.
    pub gps_mixed_frames: u32,
    /// Fusions refused because the innovation covariance had no Cholesky factor.
    pub not_positive_definite: u32,
    /// Position block reset to a fix (after `gps_reset_timeout_us` of
    /// rejected position blocks, or a divergence).
    pub gps_position_resets: u32,
    /// Velocity block reset to a fix (after `gps_reset_timeout_us` of
    /// rejected velocity blocks, or a divergence).
    pub gps_velocity_resets: u32,
    /// Of the two reset counts above, the resets caused by a divergence: the
    /// block's mean NIS over `gps_nis_window` fixes above `gps_nis_bound`.
    pub gps_divergence_resets: u32,
    /// GPS fixes whose position was beyond its tolerance from the integrated GPS velocity
    /// (the position-against-velocity check: the position levels raised by the offset).
    pub gps_position_inconsistent: u32,
    /// Quaternion variances left negative by an update or a prediction (rounding: a variance
    /// zero in exact arithmetic, or an `f32` covariance spanning too many orders of magnitude),
    /// set to zero with their row and column (the state kept).
    pub covariance_repairs: u32,
    /// Magnetometer samples whose field norm varied with the attitude beyond the noise (the
    /// field-offset monitor: a hard-iron offset or a disturbance seen; the heading and tilt
    /// levels raised by it, no 3-axis update while it lasts).
    pub mag_field_offset: u32,
    /// Field offsets the monitor held and dropped because the field's norm, once back within
    /// its tolerance, had changed by more than an offset fixed to the body allows for the turn
    /// since the offset showed (a disturbance that passed; docs/integrity.md).
    pub mag_field_offset_cleared: u32,
}

impl FilterRefusals {
    /// Nothing counted (the `const` of [`Default::default`]).
    pub const ZERO: Self = Self {
        imu_non_finite: 0,
        imu_out_of_range: 0,
        imu_time: 0,
        imu_step_too_long: 0,
        imu_ahead: 0,
        gps_invalid: 0,
        gps_time: 0,
        gps_position_rejected: 0,
        gps_velocity_rejected: 0,
        mag_invalid: 0,
        mag_time: 0,
        mag_rejected: 0,
        mag_disturbed: 0,
        gps_mixed_frames: 0,
        not_positive_definite: 0,
        gps_position_resets: 0,
        gps_velocity_resets: 0,
        gps_divergence_resets: 0,
        gps_position_inconsistent: 0,
        covariance_repairs: 0,
        mag_field_offset: 0,
        mag_field_offset_cleared: 0,
    };

    /// Field-wise sum (saturating): the counters of a filter that replaced
    /// another added to those of the one it replaced.
    pub fn merged(self, other: Self) -> Self {
        Self {
            imu_non_finite: self.imu_non_finite.saturating_add(other.imu_non_finite),
            imu_out_of_range: self.imu_out_of_range.saturating_add(other.imu_out_of_range),
            imu_time: self.imu_time.saturating_add(other.imu_time),
            imu_step_too_long: self
                .imu_step_too_long
                .saturating_add(other.imu_step_too_long),
            imu_ahead: self.imu_ahead.saturating_add(other.imu_ahead),
            gps_invalid: self.gps_invalid.saturating_add(other.gps_invalid),
            gps_time: self.gps_time.saturating_add(other.gps_time),
            gps_position_rejected: self
                .gps_position_rejected
                .saturating_add(other.gps_position_rejected),
            gps_velocity_rejected: self
                .gps_velocity_rejected
                .saturating_add(other.gps_velocity_rejected),
            mag_invalid: self.mag_invalid.saturating_add(other.mag_invalid),
            mag_time: self.mag_time.saturating_add(other.mag_time),
            mag_rejected: self.mag_rejected.saturating_add(other.mag_rejected),
            mag_disturbed: self.mag_disturbed.saturating_add(other.mag_disturbed),
            gps_mixed_frames: self.gps_mixed_frames.saturating_add(other.gps_mixed_frames),
            not_positive_definite: self
                .not_positive_definite
                .saturating_add(other.not_positive_definite),
            gps_position_resets: self
                .gps_position_resets
                .saturating_add(other.gps_position_resets),
            gps_velocity_resets: self
                .gps_velocity_resets
                .saturating_add(other.gps_velocity_resets),
            gps_divergence_resets: self
                .gps_divergence_resets
                .saturating_add(other.gps_divergence_resets),
            gps_position_inconsistent: self
                .gps_position_inconsistent
                .saturating_add(other.gps_position_inconsistent),
            covariance_repairs: self
                .covariance_repairs
                .saturating_add(other.covariance_repairs),
            mag_field_offset: self.mag_field_offset.saturating_add(other.mag_field_offset),
            mag_field_offset_cleared: self
                .mag_field_offset_cleared
                .saturating_add(other.mag_field_offset_cleared),
        }
    }
}

/// Why a GPS block was reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GpsResetCause {
    /// Every fix's block was rejected for `gps_reset_timeout_us`.
    Rejected,
    /// The block's mean NIS over `gps_nis_window` fixes exceeded
    /// `gps_nis_bound` (accepted fusions inconsistent with the covariance).
    Diverged,
}

/// The last reset of a GPS block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GpsReset {
    /// Time of the fix the block was reset to, µs.
    pub t_us: u64,
    /// The block.
    pub block: GpsBlock,
    /// Why.
    pub cause: GpsResetCause,
}

/// The 16-state EKF of the paper (section 2.1), GPS fused without delay handling.
///
/// ```
/// use delaynav::{Ekf16, Ekf16Config, Gps, GpsOutcome, GpsPosition, Imu, Navigator};
/// use nalgebra::Vector3;
///
/// let mut ekf = Ekf16::<f64>::new(Ekf16Config::default())?;
/// // Level and at rest, 100 Hz.
/// for k in 0..100u64 {
///     let imu = Imu { t_us: k * 10_000, gyro_rad_s: Vector3::zeros(), accel_m_s2: Vector3::new(0.0, 0.0, -9.80665) };
///     ekf.push_imu(&imu)?;
/// }
/// let fix = Gps {
///     t_us: 990_500,
///     position: GpsPosition::Ned(Vector3::new(1.0, 2.0, 3.0)),
///     velocity_ned_m_s: Vector3::zeros(),
///     horizontal_accuracy_m: None,
///     vertical_accuracy_m: None,
///     speed_accuracy_m_s: None,
/// };
/// assert_eq!(ekf.push_gps(&fix)?, GpsOutcome::Initialized);
/// let e = ekf.estimate().unwrap();
/// assert!((e.position_ned_m - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
/// assert!(e.euler_rad().xy().norm() < 1e-12); // level
/// # Ok::<(), delaynav::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Ekf16<T: Scalar> {
    core: NavCore<T, NAV_STATES>,
    /// The motion its levels allow for an unmodelled GPS latency ([`latency`]).
    latency: latency::LatencyMonitor<T>,
}

impl<T: Scalar> Ekf16<T> {
    /// An uninitialized filter; it initializes itself from the first GPS fix
    /// (see the module docs). Fails when the configuration does not validate.
    pub fn new(config: Ekf16Config<T>) -> Result<Self, Error> {
        Ok(Self {
            core: NavCore::new(config, &[])?,
            latency: latency::LatencyMonitor::BLANK,
        })
    }

    /// A filter not configured yet: a `const` value the compiler builds (in
    /// a `static`, no stack at all). It refuses every sample
    /// ([`Error::NotConfigured`]) until [`configure`](Self::configure)
    /// succeeds.
    ///
    /// ```
    /// use delaynav::{Ekf16, Ekf16Config, Error, Imu, Navigator};
    /// use nalgebra::Vector3;
    ///
    /// static BLANK: Ekf16<f32> = Ekf16::BLANK;
    /// let mut ekf = BLANK.clone();
    /// let imu = Imu { t_us: 0, gyro_rad_s: Vector3::zeros(), accel_m_s2: Vector3::new(0.0, 0.0, -9.8) };
    /// assert_eq!(ekf.push_imu(&imu), Err(Error::NotConfigured));
    /// ekf.configure(Ekf16Config::default())?;
    /// assert!(ekf.push_imu(&imu).is_ok());
    /// # Ok::<(), Error>(())
    /// ```
    pub const BLANK: Self = Self {
        core: NavCore::BLANK,
        latency: latency::LatencyMonitor::BLANK,
    };

    /// Validates `config` and (re)starts the filter with it in place, as
    /// [`new`](Self::new) would build it (counters included), without a
    /// copy of the filter on the stack. On error the filter is left not
    /// configured: it refuses every sample.
    pub fn configure(&mut self, config: Ekf16Config<T>) -> Result<(), Error> {
        self.latency = latency::LatencyMonitor::BLANK;
        self.core.configure(config, &[])
    }

    /// True once a [`configure`](Self::configure) (or [`new`](Self::new))
    /// succeeded.
    pub fn is_configured(&self) -> bool {
        self.core.is_configured()
    }

    /// [`from_state_with_covariance`](Self::from_state_with_covariance) in
    /// place (the navigator's alignment, on the push path). The
    /// configuration and the state are checked before anything changes.
    pub(crate) fn configure_from_state(
        &mut self,
        config: Ekf16Config<T>,
        t_us: u64,
        state: &NavState<T>,
        covariance: &StateCovariance<T>,
    ) -> Result<(), Error> {
        self.latency = latency::LatencyMonitor::BLANK;
        self.core
            .configure_from_state(config, &[], t_us, &state.to_vector(), covariance)
    }

    /// A filter initialized at time `t_us` (microseconds, IMU clock) with a
    /// known state and a diagonal covariance (in state order, see
    /// [`state`]). For an attitude uncertainty given as roll/pitch/yaw
    /// standard deviations use [`Ekf16::from_state_with_covariance`] with
    /// [`state::attitude_covariance`].
    ///
    /// The next IMU sample must be later than `t_us`. GPS fixes in geodetic
    /// coordinates need `config.origin` to match the state's position.
    pub fn from_state(
        config: Ekf16Config<T>,
        t_us: u64,
        state: &NavState<T>,
        covariance_diagonal: &StateVector<T>,
    ) -> Result<Self, Error> {
        Self::from_state_with_covariance(
            config,
            t_us,
            state,
            &StateCovariance::from_diagonal(covariance_diagonal),
        )
    }

    /// As [`Ekf16::from_state`] with a full covariance (symmetrized).
    pub fn from_state_with_covariance(
        config: Ekf16Config<T>,
        t_us: u64,
        state: &NavState<T>,
        covariance: &StateCovariance<T>,
    ) -> Result<Self, Error> {
        Ok(Self {
            core: NavCore::from_state(config, &[], t_us, &state.to_vector(), covariance)?,
            latency: latency::LatencyMonitor::BLANK,
        })
    }

    /// The configuration (every field zero on a filter not configured: see
    /// [`is_configured`](Self::is_configured)).
    pub fn config(&self) -> &Ekf16Config<T> {
        self.core.config()
    }

    /// Multiplies the white-noise intensities of the next predictions by `scale` (at least
    /// 1): what the navigator's horizon reads at a period other than the configured one.
    pub(crate) fn set_imu_noise_scale(&mut self, scale: T) {
        self.core.set_imu_noise_scale(scale);
    }

    /// The state vector (eq. 1; meaningful once initialized).
    pub fn state_vector(&self) -> &StateVector<T> {
        self.core.state()
    }

    /// The named navigation state, `None` until initialized.
    pub fn nav_state(&self) -> Option<NavState<T>> {
        self.is_initialized()
            .then(|| NavState::from_vector(self.core.state()))
    }

    /// The covariance (16x16).
    pub fn covariance(&self) -> &StateCovariance<T> {
        self.core.covariance()
    }

    /// One prediction over a filter step from its delta angle and delta
    /// velocity ([`delta::DeltaAccumulator`], coning and sculling
    /// corrected), instead of one [`push_imu`](Navigator::push_imu) per
    /// sample: the multi-rate filter of the navigator. The step must start
    /// at the filter's time; otherwise (and before initialization) its last
    /// sample is pushed as an IMU sample. Refusals as for `push_imu`.
    pub fn push_imu_deltas(&mut self, deltas: &delta::ImuDeltas<T>) -> Result<(), Error> {
        let before = self.core.time_us();
        self.core.push_deltas(deltas)?;
        self.observe_motion(before);
        Ok(())
    }

    /// Feeds the latency monitor the step just integrated (from `before`, the filter's time
    /// before it, to now): the last sample's specific force through the estimate.
    fn observe_motion(&mut self, before: Option<u64>) {
        let (Some(before), Some(now), Some(imu)) =
            (before, self.core.time_us(), self.core.last_imu())
        else {
            return;
        };
        if !self.core.is_initialized() || now <= before {
            return;
        }
        let state = NavState::from_vector(self.core.state());
        let dt = us_to_s::<T>(now - before);
        let config = self.core.config();
        self.latency.update(
            &state.attitude,
            &imu.accel_m_s2,
            &state.accel_bias_m_s2,
            config.gravity_m_s2,
            dt,
            config.integrity.gps_latency_allowance_s,
        );
    }

    /// [`push_gps`](Navigator::push_gps) for a fix whose time of validity
    /// is uncertain by `timing_variance_s2` (s^2): a timing error `d`
    /// moves the fix by `-v d` in position and `-a d` in velocity (`v` the
    /// filter's NED velocity, `accel_ned_m_s2` its NED acceleration), so
    /// the position noise gains `timing_variance_s2 v v'` and the velocity
    /// noise `timing_variance_s2 a a'` (the cross term between the blocks,
    /// fused one after the other, is left out). The navigator's delay
    /// uncertainty, `docs/nav.md`. With `gain_restriction` the gain is
    /// `C K` (a consider update, [`crate::kalman::joseph_update_restricted`]).
    pub(crate) fn push_gps_with_timing_noise<G: GpsFix<T> + ?Sized>(
        &mut self,
        gps: &G,
        timing_variance_s2: T,
        accel_ned_m_s2: &Vector3<T>,
        gain_restriction: Option<crate::kalman::GainRestriction<'_, T, NAV_STATES>>,
    ) -> Result<GpsOutcome<T>, Error> {
        self.core.push_gps(
            gps,
            |core, block, m| {
                let lever = &core.config().lever_arm_m;
                let state = core.nav_state();
                match block {
                    GpsBlock::Position => {
                        let (h, jac) = measurement::gps_position(&state, lever);
                        let v = state.fixed_rows::<3>(state::VEL);
                        (
                            h,
                            jac,
                            m.position_noise + v * v.transpose() * timing_variance_s2,
                        )
                    }
                    GpsBlock::Velocity => {
                        let gyro = core
                            .last_imu()
                            .map_or_else(Vector3::zeros, |s| s.gyro_rad_s);
                        let (h, jac) = measurement::gps_velocity(&state, &gyro, lever);
                        let a = accel_ned_m_s2;
                        (
                            h,
                            jac,
                            m.velocity_noise + a * a.transpose() * timing_variance_s2,
                        )
                    }
                }
            },
            gain_restriction,
            |_| {},
        )
    }

    crate::ekf16::nav_core::core_accessors!();

    /// The integrity monitor's inflation factors `(position, velocity)`, at least 1
    /// (`src/ekf16/nav_core/integrity.rs`).
    pub(crate) fn nis_inflation(&self) -> (T, T) {
        self.core.nis_inflation()
    }

    /// The position-against-velocity check's offset `(horizontal, vertical)`, m, what the
    /// position levels are raised by (`src/ekf16/nav_core/integrity.rs`).
    pub(crate) fn position_velocity_bias(&self) -> (T, T) {
        self.core.position_velocity_bias()
    }

    /// The norm of the GPS velocity innovations' mean, m/s, what the velocity level is raised
    /// by (`src/ekf16/nav_core/integrity.rs`).
    pub(crate) fn velocity_innovation_bias(&self) -> T {
        self.core.velocity_innovation_bias()
    }

    /// The heading's standard deviation from the tilt once a magnetometer update was fused,
    /// rad, else 0: the tilt's share of the heading level
    /// (`ProtectionLevels::with_heading_tilt_coupling`).
    pub(crate) fn heading_tilt_coupling(&self) -> T {
        self.core.heading_tilt_coupling()
    }

    /// The magnetometer monitor's share of the levels: the heading factor and the field
    /// offset's heading and tilt shares, rad (`src/ekf16/nav_core/mag_monitor.rs`).
    pub(crate) fn mag_integrity(&self) -> (T, T, T) {
        self.core.mag_integrity()
    }
}

impl<T: Scalar> Navigator<T> for Ekf16<T> {
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        let before = self.core.time_us();
        self.core.push_imu(imu)?;
        self.observe_motion(before);
        Ok(())
    }

    /// Fuses position then velocity with the lever-arm models of
    /// [`internals::measurement`](crate::internals::measurement), each block gated on its own.
    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error> {
        self.push_gps_with_timing_noise(gps, T::zero(), &Vector3::zeros(), None)
    }

    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, mag: &M) -> Result<MagOutcome<T>, Error> {
        self.core.push_mag(mag)
    }

    fn estimate(&self) -> Option<Estimate<T>> {
        self.core.estimate()
    }

    /// The protection levels of the covariance, the position and velocity ones raised by the
    /// motion over the configured GPS latency allowance ([`latency`]); no delay estimate (an
    /// infinite delay level).
    fn integrity(&self) -> crate::integrity::Integrity<T> {
        let base = self.core.integrity(None);
        if !self.core.is_initialized() {
            return base;
        }
        let config = &self.core.config().integrity;
        let velocity = NavState::from_vector(self.core.state()).velocity_ned_m_s;
        let levels = self.latency.raise(
            base.levels,
            &velocity,
            config.gps_latency_allowance_s,
            self.core.config().gravity_m_s2,
        );
        crate::integrity::Integrity {
            resets: base.resets,
            ..crate::integrity::Integrity::judged(levels, config, !self.core.imu_jump_pending())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::{Gps, GpsPosition, Imu};
    use nalgebra::UnitQuaternion;

    /// The timing noise adds `sigma^2 v_i^2` to each position innovation
    /// variance and `sigma^2 a_i^2` to each velocity one, and the widened
    /// filter moves less towards the fix. A diagonal covariance and no lever
    /// arm keep the position fusion from changing the velocity block, so
    /// both differences are exact.
    fn timing_noise_widens_the_fix<T: Scalar>() {
        let lit = T::lit;
        let velocity = Vector3::new(lit(4.0), lit(-2.0), lit(0.5));
        let start = NavState {
            attitude: UnitQuaternion::identity(),
            position_ned_m: Vector3::zeros(),
            velocity_ned_m_s: velocity,
            accel_bias_m_s2: Vector3::zeros(),
            gyro_bias_rad_s: Vector3::zeros(),
        };
        let p = StateVector::from_element(lit(0.01));
        let mut plain = Ekf16::from_state(Ekf16Config::default(), 0, &start, &p).unwrap();
        let mut widened = plain.clone();
        let offset = Vector3::new(lit(0.3), lit(-0.2), lit(0.1));
        let fix = Gps {
            t_us: 0,
            position: GpsPosition::Ned(offset),
            velocity_ned_m_s: velocity + offset,
            horizontal_accuracy_m: None,
            vertical_accuracy_m: None,
            speed_accuracy_m_s: None,
        };
        let (variance, accel) = (lit(0.01), Vector3::new(lit(3.0), lit(-1.0), lit(0.0)));
        let records = |outcome| match outcome {
            Ok(GpsOutcome::Fused { position, velocity }) => (position, velocity),
            other => panic!("not fused: {other:?}"),
        };
        let off = records(plain.push_gps(&fix));
        let on = records(widened.push_gps_with_timing_noise(&fix, variance, &accel, None));
        for i in 0..3 {
            let tolerance = 1e3 * T::EPS.as_f64();
            let position = on.0.innovation_variance[i] - off.0.innovation_variance[i];
            let velocity = on.1.innovation_variance[i] - off.1.innovation_variance[i];
            assert!(
                (position - variance * start.velocity_ned_m_s[i].powi(2))
                    .as_f64()
                    .abs()
                    < tolerance
            );
            assert!((velocity - variance * accel[i].powi(2)).as_f64().abs() < tolerance);
        }
        let moved = |ekf: &Ekf16<T>| {
            let x = ekf.nav_state().unwrap();
            (
                (x.position_ned_m - start.position_ned_m).norm().as_f64(),
                (x.velocity_ned_m_s - velocity).norm().as_f64(),
            )
        };
        let (p_off, v_off) = moved(&plain);
        let (p_on, v_on) = moved(&widened);
        assert!(
            p_on < p_off && v_on < v_off,
            "{p_on} {p_off} {v_on} {v_off}"
        );
    }

    /// The standalone filter's position and velocity levels carry the motion over the GPS
    /// latency allowance: moving at 5 m/s horizontally and 1 m/s down while accelerating
    /// 2 m/s² north, the default 0.4 s raises them against an allowance of 0 by
    /// `0.4 * 5 + 0.08 * 2` (horizontal), `0.4 * 1 + 0.08 * 2` (vertical) and `0.4 * 2`
    /// (velocity), within the velocity's change over the second flown; the tilt by the
    /// acceleration's change at the start, decayed.
    fn the_levels_carry_the_latency_allowance<T: Scalar>() {
        let lit = T::lit;
        let start = NavState {
            attitude: UnitQuaternion::identity(),
            position_ned_m: Vector3::zeros(),
            velocity_ned_m_s: Vector3::new(lit(3.0), lit(4.0), lit(1.0)),
            accel_bias_m_s2: Vector3::zeros(),
            gyro_bias_rad_s: Vector3::zeros(),
        };
        let p = StateVector::from_element(lit(1e-4));
        let fly = |allowance: f64| {
            let mut config = Ekf16Config::default();
            config.integrity.gps_latency_allowance_s = lit(allowance);
            let mut ekf = Ekf16::from_state(config, 0, &start, &p).unwrap();
            for k in 1..=1000u64 {
                let imu = Imu {
                    t_us: k * 1000,
                    gyro_rad_s: Vector3::zeros(),
                    accel_m_s2: Vector3::new(lit(2.0), lit(0.0), lit(-9.80665)),
                };
                ekf.push_imu(&imu).unwrap();
            }
            let v = ekf.estimate().unwrap().velocity_ned_m_s;
            (ekf.integrity().levels, v)
        };
        let ((with, v), (without, _)) = (fly(0.4), fly(0.0));
        let horizontal = v.x.hypot(v.y).as_f64();
        let near = |a: T, b: f64| (a.as_f64() - b).abs() < 2e-3;
        assert!((horizontal - 6.4).abs() < 0.1, "{v:?}");
        assert!(near(
            with.horizontal_m - without.horizontal_m,
            0.4 * horizontal + 0.16
        ));
        assert!(near(with.vertical_m - without.vertical_m, 0.4 + 0.16));
        assert!(near(with.velocity_m_s - without.velocity_m_s, 0.8));
        // The acceleration began at the start: its change over the allowance, 2 m/s² at
        // most, held in a peak that decays over 1 s.
        let tilt = (with.tilt_deg - without.tilt_deg).as_f64();
        assert!(
            tilt > 0.5 && tilt < (2.0f64 / 9.80665).atan().to_degrees(),
            "{tilt}"
        );
    }

    tests_in_both_precisions!(
        timing_noise_widens_the_fix,
        the_levels_carry_the_latency_allowance
    );
}
