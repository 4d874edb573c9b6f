//! `NavCore<T, N>`: the filter machinery shared by the 16-state EKF and the
//! augmented 17-state baseline (crate-internal).
//!
//! # Contract
//! - State: `x` of length `N >= 16`. The first 16 entries are the navigation
//!   states of [`state`](super::state) (indices `QUAT`, `POS`, `VEL`,
//!   `ACCEL_BIAS`, `GYRO_BIAS`); entries `16..N` are extra states, each a
//!   random walk described by an [`ExtraState`] (initial value, initial
//!   variance, intensity in unit²/s). Their process model is `x' = 0`; the
//!   core never reads their values.
//! - Covariance: `P` (`N x N`), symmetric after every operation, its
//!   quaternion rows and columns projected on the tangent space of the unit
//!   sphere (`I - q q^T`) after every prediction and fusion.
//! - Clock: the state describes the instant of the last accepted IMU sample
//!   ([`NavCore::time_us`]). GPS and magnetometer samples are fused at that
//!   instant, whatever their own timestamp (this filter has no delay handling;
//!   timestamps are only checked for order per stream).
//! - [`NavCore::push_imu`]: checks (finite, plausible, increasing time, step
//!   length), then propagates the first 16 states with
//!   [`process::propagate`] and the covariance with `A P A^T + Q`, where
//!   `F`, `A`, `Q` are the 16-state ones padded with zeros and the extra
//!   states' intensities on the diagonal of `Q'`. Before initialization it
//!   only keeps the clock, the last sample and the accelerometer mean (the
//!   magnetometer direction is averaged by [`NavCore::push_mag`]).
//! - [`NavCore::begin_gps`]: checks the fix (finite, increasing time),
//!   converts it to NED (origin: configured, else the initializing fix) and
//!   picks its noise (receiver accuracies or configured). Before
//!   initialization it returns [`GpsStep::Waiting`] or initializes from the
//!   fix ([`GpsStep::Initialized`]); afterwards it returns the
//!   [`GpsMeasurement`] for the filter's own GPS model.
//!   [`NavCore::push_gps`] does the whole cycle with a filter's model: begin,
//!   fuse position then velocity with [`NavCore::fuse_restricted`], store the records
//!   with [`NavCore::record_gps`]. Each block then goes through
//!   `NavCore::gps_block_verdict` (its own rejection timer,
//!   `gps_reset_timeout_us`, and its NIS window, `gps_nis_window` /
//!   `gps_nis_bound`) and, when it must, `NavCore::reset_gps_block` resets
//!   that block alone to the fix (counted per block in [`FilterRefusals`],
//!   recorded as the last [`GpsReset`]). Geodetic and NED fixes cannot be
//!   mixed ([`check_position_kind`], shared with the navigator).
//! - [`NavCore::fuse_restricted`]: any `M`-dim block `(y, H (M x N), R)` through
//!   [`kalman::joseph_update_restricted`] (the gain optionally restricted to
//!   `C K`), then renormalizes the quaternion. A rejected or
//!   failed fusion leaves `x` and `P` unchanged.
//! - [`NavCore::push_mag`]: the magnetometer update of
//!   [`measurement`](crate::internals::measurement) (or keeps the sample for
//!   initialization): refused as disturbed when the field norm or
//!   inclination is off the learned field, gated on the heading innovation,
//!   heading-only once the tilt standard deviation is below
//!   `mag_tilt_alignment_std_rad` (the gain restricted by
//!   [`measurement::heading_only_restriction`](crate::internals::measurement::heading_only_restriction)).
//! - [`NavCore::reset_extra_state`] and [`NavCore::clamp_extra_state`]: the
//!   two ways a filter may change an extra state from outside the Kalman
//!   algebra. A reset sets the value and variance and drops the state's
//!   correlations (`P` stays symmetric PSD: a block-diagonal of PSD blocks);
//!   a clamp moves the value into a range and leaves `P` untouched.
//! - Every refused sample leaves `x`, `P` and the clocks as they were (except
//!   [`Error::StepTooLong`], see its docs) and increments a
//!   [`FilterRefusals`] field.
//! - No allocation: every buffer is a fixed-size nalgebra type.

mod alignment;
mod gps;
mod integrity;
pub(crate) use integrity::{GAP_MOTION_MAX_S, gap_growth};
mod mag;
mod mag_monitor;
mod predict;

use super::config::Ekf16Config;
use super::delta::ImuDeltas;
use super::measurement;
use super::process;
use super::state::{
    ACCEL_BIAS, GYRO_BIAS, NAV_STATES, POS, QUAT, StateVector, VEL, WxyzCoords,
    attitude_covariance, quaternion_of,
};
use super::{FilterRefusals, GpsReset, GpsResetCause, MagModeHealth};
use crate::error::Error;
use crate::estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome};
use crate::geo::{
    LocalFrame, euler_from_quaternion, magnetic_field_ned, quaternion_from_euler,
    roll_pitch_from_accel, rotation_matrix, tilt_compensated_heading, tilt_compensated_heading_sc,
};
use crate::kalman::{self, GainRestriction};
use crate::scalar::{Scalar, all_finite, all_finite_fixed, us_to_s, zeros_const};
use crate::sensors::{
    GpsFix, GpsPosition, Imu, ImuSample, MagSample, check_time, checked_gps, checked_imu,
    checked_mag,
};
use crate::zero_option::ZeroOption;
use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};

/// The longest stretch of an IMU gap whose process noise and unknown motion
/// are added to `P`, µs (a gap longer than `max_imu_step_us` is not
/// integrated: the position is carried by the velocity and `P` grows over
/// `min(gap, MAX_GAP_NOISE_US)`).
pub const MAX_GAP_NOISE_US: u64 = 60_000_000;

/// Time of clean magnetometer samples (never two in a row disturbed or
/// gated out) before the 3-axis update is used, µs.
pub const MAG_THREE_AXIS_HOLD_US: u32 = 1_000_000;
/// Largest difference between the inclination learned at initialization
/// and the configured one for the 3-axis update, rad (8.6 deg): the 3-axis
/// update pulls the tilt toward the configured field, so it is used only
/// when the two agree.
pub const MAG_THREE_AXIS_INCLINATION_TOLERANCE_RAD: f64 = 0.15;
/// Tilt standard deviation above which the filter is aligning in motion, rad
/// (8.6 deg: above the default `initial_tilt_std_rad` of a start at rest,
/// 0.1 rad, below the 0.35 rad the navigator sets for a start in motion):
/// the magnetometer is then fused as the 3-axis field whatever its clean
/// time and learned inclination, and the inclination is learned at
/// [`MAG_ALIGNING_INCLINATION_RATE`] at least.
pub const MAG_INFLIGHT_TILT_STD_RAD: f64 = 0.15;
/// Least weight of one accepted sample in the learned inclination while the
/// filter aligns in motion (tilt standard deviation above
/// [`MAG_INFLIGHT_TILT_STD_RAD`]): 20 samples, 0.2 s at 100 Hz.
pub const MAG_ALIGNING_INCLINATION_RATE: f64 = 0.05;
/// Samples the learned magnetometer field must be the mean of before it
/// refuses a sample as disturbed (its norm known to `1 / sqrt(20)` of one
/// sample's noise; 0.2 s at 100 Hz).
pub const MAG_FIELD_MIN_SAMPLES: u32 = 20;
/// Interval between magnetometer samples beyond which the time counts as
/// [`MagMode::NoFusion`](super::MagMode::NoFusion), µs.
pub const MAG_GAP_US: u64 = 1_000_000;
/// Largest forward jump of the IMU clock accepted at once, µs (the navigator's default
/// `max_time_jump_us`): a sample further ahead is refused
/// ([`Error::OutOfRange`] `imu.time`, counted in `FilterRefusals::imu_ahead`) and kept as a
/// candidate; the next sample within this bound after it confirms the jump (a real gap), one
/// within this bound after the clock drops it (a sample stamped in the future).
pub const MAX_TIME_JUMP_US: u64 = 1_000_000;

/// One state appended after the 16 navigation states: a random walk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ExtraState<T: Scalar> {
    /// Value at initialization.
    pub initial: T,
    /// Variance at initialization.
    pub initial_variance: T,
    /// Random-walk intensity (variance growth per second).
    pub random_walk_intensity: T,
}

impl<T: Scalar> ExtraState<T> {
    /// No state: zero value, variance and intensity.
    const ZERO: Self = Self {
        initial: T::ZERO,
        initial_variance: T::ZERO,
        random_walk_intensity: T::ZERO,
    };
}

/// Most states a core carries after the 16 navigation states (the augmented EKF's delay):
/// their initial values, variances and intensities are kept in a fixed array of this length,
/// 12 B in `f32`, where three `N`-long vectors zero over the navigation states took 192 B in
/// the 16-state filter.
pub(crate) const MAX_EXTRA_STATES: usize = 1;

/// Mean of the last samples of a vector: a running mean up to `window`
/// samples, then an exponential mean of weight `1 / window`. No storage
/// beyond the mean.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BoundedMean<T: Scalar, const D: usize = 3> {
    mean: SVector<T, D>,
    count: u32,
}

impl<T: Scalar, const D: usize> BoundedMean<T, D> {
    const EMPTY: Self = Self {
        mean: zeros_const(),
        count: 0,
    };

    fn push(&mut self, v: &SVector<T, D>, window: u32) {
        if self.count < window {
            self.count += 1;
        }
        self.mean += (v - self.mean) / T::lit(f64::from(self.count));
    }
}

/// Counts one refusal (saturating: a counter never panics).
fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// Keeps the quaternion's covariance in the tangent space of the unit
/// sphere at `q` (unit): `P <- T P T^T` with `T = blockdiag(I - q q^T, I)`.
///
/// The quaternion has four components and three degrees of freedom. Left
/// alone, `P` gains variance along `q` itself (after each renormalization
/// the old tangent space is slightly off), and since `R(q) u` scales with
/// `|q|²`, the filter would then "explain" velocity errors by a change of
/// the quaternion's norm that renormalization throws away, and drift.
///
/// True when a quaternion variance came out negative and was repaired (its
/// row and column zeroed): the caller counts it.
fn project_quaternion_covariance<T: Scalar, const N: usize>(
    p: &mut SMatrix<T, N, N>,
    x: &SVector<T, N>,
) -> bool {
    let q = x.fixed_rows::<4>(QUAT).into_owned();
    let q = &q.data.0[0];
    let columns = &mut p.data.0;
    // Rows q of T P, column by column: P[q, j] - q (q . P[q, j]).
    for column in columns.iter_mut() {
        let d = (0..4).fold(T::zero(), |acc, r| acc + q[r] * column[QUAT + r]);
        for r in 0..4 {
            column[QUAT + r] -= q[r] * d;
        }
    }
    // Columns q: outside rows q the mirror of the rows just computed (one
    // column read, another written: indices, not an iterator); the
    // 4x4 block is (T P)[q, q] T^T = B - (B q) q^T, its lower triangle
    // mirrored, so P stays exactly symmetric.
    #[allow(clippy::needless_range_loop)]
    for j in 0..N {
        if !(QUAT..QUAT + 4).contains(&j) {
            for r in 0..4 {
                columns[QUAT + r][j] = columns[j][QUAT + r];
            }
        }
    }
    let mut b = [[T::zero(); 4]; 4];
    for (c, b_col) in b.iter_mut().enumerate() {
        for (r, b_rc) in b_col.iter_mut().enumerate() {
            *b_rc = columns[QUAT + c][QUAT + r];
        }
    }
    let bq: [T; 4] =
        core::array::from_fn(|r| (0..4).fold(T::zero(), |acc, c| acc + b[c][r] * q[c]));
    for c in 0..4 {
        for r in c..4 {
            let v = b[c][r] - bq[r] * q[c];
            columns[QUAT + c][QUAT + r] = v;
            columns[QUAT + r][QUAT + c] = v;
        }
    }
    // A quaternion variance left negative: the rounding of a variance zero in exact arithmetic
    // (pitched 90 degrees, q = (c, 0, s, 0): q1 and q3 carry none of the error left, -1e-12
    // in `f32`), or a block the update left slightly indefinite (an `f32` covariance spanning
    // too many orders of magnitude). The only row and column a zero variance allows in a
    // covariance are zero: they are set so (a principal submatrix padded with zeros), and the
    // caller counts each (`FilterRefusals::covariance_repairs`).
    let mut repaired = false;
    for r in 0..4 {
        if columns[QUAT + r][QUAT + r] < T::zero() {
            for column in columns.iter_mut() {
                column[QUAT + r] = T::zero();
            }
            for v in columns[QUAT + r].iter_mut() {
                *v = T::zero();
            }
            repaired = true;
        }
    }
    repaired
}

/// Largest variance of a quaternion component, a dimensionless ceiling.
///
/// A unit quaternion's components lie in `[-1, 1]`, and an attitude error
/// of standard deviation `σ` (rad, at most pi: the initial attitude standard
/// deviations are bounded so) gives its components a variance near
/// `(σ/2)² <= pi²/4 ≈ 2.47`: 4 is above every meaningful figure. The
/// second-order transition of the attitude covariance,
/// `I + Ω dt/2 + (Ω dt/2)²/2`, grows it by `sqrt(1 + θ⁴/64)` per step of
/// rotation `θ = |w| dt`: negligible at an IMU rate (`θ` of milliradians),
/// but samples a quarter second apart at 30 rad/s grew the quaternion's
/// variances to 1e11 within a dozen steps, and a GPS fix then left a
/// negative variance in `f32`. The ceiling keeps `P` where the updates
/// stay sound; each step that needs it is counted in
/// `FilterRefusals::imu_out_of_range` (`cap_quaternion_variance`).
pub const QUATERNION_VARIANCE_CEILING: f64 = 4.0;

/// Caps the quaternion's variances at [`QUATERNION_VARIANCE_CEILING`]:
/// row and column `i` of a variance `P_ii` above it are scaled by
/// `sqrt(ceiling / P_ii)`, so `P_ii` becomes the ceiling and the
/// correlations are kept (`P <- D P D` with `D` diagonal and positive: `P`
/// stays symmetric positive semi-definite). True when a variance was
/// capped (the caller counts it).
fn cap_quaternion_variance<T: Scalar, const N: usize>(p: &mut SMatrix<T, N, N>) -> bool {
    let ceiling = T::lit(QUATERNION_VARIANCE_CEILING);
    let columns = &mut p.data.0;
    let mut capped = false;
    // Indices below the arrays' lengths (N >= 16): no failing bounds check.
    #[allow(clippy::needless_range_loop)]
    for i in QUAT..QUAT + 4 {
        let v = columns[i][i];
        if v > ceiling {
            let scale = (ceiling / v).sqrt();
            for j in 0..N {
                columns[j][i] *= scale;
                columns[i][j] *= scale;
            }
            // Exactly the ceiling (the diagonal was scaled twice).
            columns[i][i] = ceiling;
            capped = true;
        }
    }
    capped
}

/// Every variance of `p` is zero or positive (not negative, not NaN).
fn variances_not_negative<T: Scalar, const N: usize>(p: &SMatrix<T, N, N>) -> bool {
    (0..N)
        .zip(p.data.0.iter())
        .all(|(j, column)| column.get(j).is_none_or(|v| *v >= T::zero()))
}

/// Whether a fix's position is geodetic, checked against the kind of the
/// first accepted fix (`first`: `Some(true)` geodetic, `Some(false)` NED):
/// one run cannot mix them (a geodetic fix after NED ones would silently
/// become the origin of the frame). The one check of every estimator.
pub(crate) fn check_position_kind<T: Scalar>(
    first: Option<bool>,
    position: &GpsPosition<T>,
) -> Result<bool, Error> {
    let geodetic = matches!(position, GpsPosition::Geodetic(_));
    if first.is_some_and(|g| g != geodetic) {
        return Err(Error::OutOfRange {
            field: "gps.position",
            reason: "geodetic and NED fixes cannot be mixed in one run",
        });
    }
    Ok(geodetic)
}

/// A record of nothing (all zero bytes): what a record slot holds before
/// its first fusion.
const fn zero_record<T: Scalar, const M: usize>() -> FusionRecord<T, M> {
    FusionRecord {
        t_us: 0,
        innovation: zeros_const(),
        innovation_variance: zeros_const(),
        test_ratio: T::ZERO,
        fused: false,
    }
}

/// Inclination (rad, down from horizontal) of a body field `m_b` seen
/// through the body-to-NED rotation `rot`: `asin((R m_b)_down / |m_b|)`.
fn field_inclination<T: Scalar>(rot: &Matrix3<T>, field_body: &Vector3<T>) -> T {
    let down = (rot * field_body)[2] / field_body.norm();
    down.max(-T::one()).min(T::one()).asin()
}

/// A checked GPS fix in the filter's NED frame, ready for a GPS model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GpsMeasurement<T: Scalar> {
    /// Receive time, microseconds.
    pub t_us: u64,
    /// Antenna position, NED, m.
    pub position_ned_m: Vector3<T>,
    /// Antenna velocity, NED, m/s.
    pub velocity_ned_m_s: Vector3<T>,
    /// Position noise covariance `R_r`, m².
    pub position_noise: Matrix3<T>,
    /// Velocity noise covariance `R_v`, (m/s)².
    pub velocity_noise: Matrix3<T>,
}

/// What [`NavCore::begin_gps`] did with a fix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum GpsStep<T: Scalar> {
    /// Not enough IMU data to initialize; the fix is dropped.
    Waiting,
    /// The fix initialized the filter.
    Initialized,
    /// Fuse this measurement with the filter's GPS model.
    Measure(GpsMeasurement<T>),
}

/// The accessors every filter on a `NavCore` (field `core`) shares, spelled
/// once: initialization, clock, frame, fusion records, refusal counters.
macro_rules! core_accessors {
    () => {
        /// True once initialized (from a GPS fix or a given state).
        pub fn is_initialized(&self) -> bool {
            self.core.is_initialized()
        }

        /// Time of the state (last accepted IMU sample), microseconds.
        pub fn time_us(&self) -> Option<u64> {
            self.core.time_us()
        }

        /// The local NED frame of geodetic GPS fixes, once known.
        pub fn frame(&self) -> Option<&LocalFrame> {
            self.core.frame()
        }

        /// Records of the last GPS fusion: (position, velocity).
        pub fn last_gps_fusion(&self) -> Option<(FusionRecord<T, 3>, FusionRecord<T, 3>)> {
            self.core.last_gps_fusion()
        }

        /// Record of the last magnetometer fusion.
        pub fn last_mag_fusion(&self) -> Option<FusionRecord<T, 3>> {
            self.core.last_mag_fusion()
        }

        /// Time of the newest GPS fix with a block (position or velocity)
        /// fused, µs: rejected fixes after it leave it as it is.
        pub fn last_gps_fused_us(&self) -> Option<u64> {
            self.core.last_gps_fused_us()
        }

        /// Time of the newest GPS fix with this block fused (or reset to the fix, or
        /// initializing the filter), µs: what the validity of that block's quantity rests on.
        pub fn last_gps_block_fused_us(&self, block: $crate::ekf16::GpsBlock) -> Option<u64> {
            self.core.last_gps_block_fused_us(block)
        }

        /// Time of the newest fused magnetometer sample, µs.
        pub fn last_mag_fused_us(&self) -> Option<u64> {
            self.core.last_mag_fused_us()
        }

        /// The magnetometer's fusion mode and the time spent in each.
        pub fn mag_modes(&self) -> $crate::ekf16::MagModeHealth {
            self.core.mag_modes()
        }

        /// Counters of refused and gated-out samples.
        pub fn refusals(&self) -> FilterRefusals {
            self.core.refusals()
        }

        /// Standard deviation of the tilt, rad: the larger of the north and
        /// east components of the attitude error (NED), from the covariance.
        /// Below `mag_tilt_alignment_std_rad` the magnetometer corrects
        /// heading only.
        pub fn tilt_std(&self) -> T {
            self.core.tilt_std()
        }

        /// The last reset of a GPS block (which block, why, when).
        pub fn last_gps_reset(&self) -> Option<$crate::ekf16::GpsReset> {
            self.core.last_gps_reset()
        }
    };
}
pub(crate) use core_accessors;

/// The two halves of a GPS fix, fused one after the other.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GpsBlock {
    /// Antenna position, NED.
    Position,
    /// Antenna velocity, NED.
    Velocity,
}

/// A filter's GPS model for one block at the core's current state:
/// `(h(x), H (3 x N), R)`.
pub(crate) type GpsBlockModel<T, const N: usize> = (Vector3<T>, SMatrix<T, 3, N>, Matrix3<T>);

/// The shared filter machinery; see the module docs for the contract.
#[derive(Debug, Clone)]
pub(crate) struct NavCore<T: Scalar, const N: usize> {
    config: Ekf16Config<T>,
    /// The unit Earth field in NED of the configured inclination and
    /// declination (computed once: four trigonometric calls per
    /// magnetometer sample saved).
    field_ned: Vector3<T>,
    /// The relative field offset beyond which the magnetometer is not fused,
    /// `sin(AL_h) cos I` (`mag.rs`, `mag_offset_beyond_alert`), from the configuration
    /// (infinite when the heading alert limit is 90 deg or more).
    mag_offset_refusal: T,
    x: SVector<T, N>,
    p: SMatrix<T, N, N>,
    /// Extra states (indices >= 16): initial values, variances, intensities.
    extras: [ExtraState<T>; MAX_EXTRA_STATES],
    /// What the white-noise intensities of the next predictions are multiplied by, read as
    /// at least 1 (0 in `BLANK`): set by the navigator from its horizon's read period
    /// ([`set_imu_noise_scale`](Self::set_imu_noise_scale)).
    imu_noise_scale: T,
    initialized: bool,
    imu_clock_us: Option<u64>,
    /// An IMU time refused as too far ahead, waiting for confirmation.
    imu_candidate_us: Option<u64>,
    last_imu: Option<Imu<T>>,
    gps_clock_us: Option<u64>,
    mag_clock_us: Option<u64>,
    accel_mean: BoundedMean<T>,
    /// Time from the first sample of `accel_mean` to the newest, µs
    /// (saturating): what `align_min_duration_us` is compared with.
    accel_mean_span_us: u32,
    mag_mean: BoundedMean<T>,
    frame: Option<LocalFrame>,
    /// The last GPS fusion records (position, velocity), if `gps_recorded`.
    /// A flag beside the records, not an `Option`: `None` would be stored in
    /// the niche of `fused` (not zero bytes, see `BLANK`) and a
    /// `ZeroOption` costs a copy of the records per fix.
    last_gps: (FusionRecord<T, 3>, FusionRecord<T, 3>),
    gps_recorded: bool,
    /// The last magnetometer fusion record, if `mag_recorded` (as `last_gps`).
    last_mag: FusionRecord<T, 3>,
    mag_recorded: bool,
    /// Time of the newest GPS fix with a block fused, µs: what the
    /// validity of velocity and position rests on (a rejected fix after it
    /// does not make it older).
    gps_fused_us: Option<u64>,
    /// Time of the newest fused magnetometer sample, µs (as `gps_fused_us`).
    mag_fused_us: Option<u64>,
    /// The heading's standard deviation from tilt errors the magnetometer updates fused into
    /// it, rad (`mag.rs`, `remember_heading_tilt_coupling`).
    heading_tilt_std: T,
    /// Per GPS block (position, velocity): time of the last fix that
    /// initialized the filter, had the block fused or reset it (or of the
    /// first rejected fix of a filter started from a state).
    gps_accepted_us: [Option<u64>; 2],
    /// Per GPS block: sum and count of the NIS of the accepted fusions of
    /// the current divergence window.
    gps_nis: [(T, u32); 2],
    /// Per GPS block: exponential mean (weight `NIS_MEAN_WEIGHT`) of the NIS of every fix,
    /// each at most the block's gate (the integrity monitor, `integrity.rs`).
    gps_nis_mean: [T; 2],
    /// Exponential mean (weight `NIS_MEAN_WEIGHT`) of the fused GPS velocity innovations,
    /// NED m/s: the velocity error the fixes keep showing (`integrity.rs`).
    gps_velocity_innovation_mean: Vector3<T>,
    /// The GPS position-against-velocity consistency check (`integrity.rs`).
    pv: integrity::PvMonitor<T>,
    /// The magnetometer's innovation and field-offset monitor (`mag_monitor.rs`).
    mag_monitor: mag_monitor::MagMonitor<T>,
    last_gps_reset: ZeroOption<GpsReset>,
    /// Whether the fixes are geodetic (`Some(true)`) or NED, from the first.
    geodetic_fixes: ZeroOption<bool>,
    /// Mean field norm of the magnetometer samples before initialization.
    mag_norm_mean: BoundedMean<T, 1>,
    /// The learned field: norm (sensor units) and inclination (rad, down
    /// from horizontal), set at initialization or by the first sample after
    /// it, then followed slowly by the accepted samples.
    mag_field: Option<(T, T)>,
    /// The magnetometer's mode, switches and time per mode.
    mag_modes: MagModeHealth,
    /// Time of the current run of clean samples, µs (saturating).
    mag_clean_us: u32,
    /// Consecutive samples not fused (disturbed or gated out).
    mag_rejected_run: u8,
    refusals: FilterRefusals,
    /// False in [`BLANK`](Self::BLANK) and after a failed
    /// [`configure`](Self::configure): every sample is refused.
    configured: bool,
}

impl<T: Scalar, const N: usize> NavCore<T, N> {
    /// An uninitialized core; `extras` describes states `16..N` (exactly `N - 16` of them).
    pub(crate) fn new(config: Ekf16Config<T>, extras: &[ExtraState<T>]) -> Result<Self, Error> {
        let mut core = Self::BLANK;
        core.configure(config, extras)?;
        Ok(core)
    }

    /// A core not configured: zero configuration, state and covariance; it
    /// refuses every sample ([`Error::NotConfigured`]). A `const` value:
    /// in a `static` it costs no stack.
    pub(crate) const BLANK: Self = {
        const {
            assert!(
                N >= NAV_STATES && N - NAV_STATES <= MAX_EXTRA_STATES,
                "a navigation core has the 16 navigation states and at most MAX_EXTRA_STATES more"
            )
        };
        Self {
            config: Ekf16Config::ZEROED,
            field_ned: zeros_const(),
            mag_offset_refusal: T::ZERO,
            x: zeros_const(),
            p: zeros_const(),
            extras: [ExtraState::ZERO; MAX_EXTRA_STATES],
            imu_noise_scale: T::ZERO,
            initialized: false,
            imu_clock_us: None,
            imu_candidate_us: None,
            last_imu: None,
            gps_clock_us: None,
            mag_clock_us: None,
            accel_mean: BoundedMean::EMPTY,
            accel_mean_span_us: 0,
            mag_mean: BoundedMean::EMPTY,
            frame: None,
            last_gps: (zero_record(), zero_record()),
            gps_recorded: false,
            last_mag: zero_record(),
            mag_recorded: false,
            gps_fused_us: None,
            mag_fused_us: None,
            heading_tilt_std: T::ZERO,
            gps_accepted_us: [None; 2],
            gps_nis: [(T::ZERO, 0); 2],
            gps_nis_mean: [T::ZERO; 2],
            gps_velocity_innovation_mean: zeros_const(),
            pv: integrity::PvMonitor::EMPTY,
            mag_monitor: mag_monitor::MagMonitor::EMPTY,
            last_gps_reset: ZeroOption::None,
            geodetic_fixes: ZeroOption::None,
            mag_norm_mean: BoundedMean::EMPTY,
            mag_field: None,
            mag_modes: MagModeHealth::START,
            mag_clean_us: 0,
            mag_rejected_run: 0,
            refusals: FilterRefusals::ZERO,
            configured: false,
        }
    };

    /// True once a [`configure`](Self::configure) succeeded.
    pub(crate) fn is_configured(&self) -> bool {
        self.configured
    }

    /// Refuses every sample from now on, until a [`configure`](Self::configure).
    pub(crate) fn unconfigure(&mut self) {
        self.configured = false;
    }

    /// [`new`](Self::new) in place: validates `config` and `extras`, then
    /// resets every member through `&mut` (the counters too). On error the
    /// core is left not configured, refusing every sample.
    pub(crate) fn configure(
        &mut self,
        config: Ekf16Config<T>,
        extras: &[ExtraState<T>],
    ) -> Result<(), Error> {
        self.configured = false;
        config.validate()?;
        if extras.len() != N - NAV_STATES {
            return Err(Error::InvalidConfig {
                field: "extra_states".into(),
                value: None,
                bound: crate::error::Bound::Rule(
                    "one description per state beyond the 16 navigation states",
                ),
            });
        }
        let valid = |e: &ExtraState<T>| {
            e.initial.is_finite()
                && e.initial_variance.is_finite()
                && e.random_walk_intensity.is_finite()
                && e.initial_variance >= T::zero()
                && e.random_walk_intensity >= T::zero()
        };
        if !extras.iter().all(valid) {
            return Err(Error::InvalidConfig {
                field: "extra_states".into(),
                value: None,
                bound: crate::error::Bound::Rule(
                    "values must be finite, variances and intensities not negative",
                ),
            });
        }
        self.config = config;
        self.field_ned = magnetic_field_ned(config.mag_inclination_rad, config.mag_declination_rad);
        let alert_rad =
            config.integrity.heading_alert_limit_deg * T::lit(core::f64::consts::PI / 180.0);
        self.mag_offset_refusal = if alert_rad < T::lit(core::f64::consts::FRAC_PI_2) {
            alert_rad.sin() * config.mag_inclination_rad.cos()
        } else {
            T::lit(f64::INFINITY)
        };
        self.x.fill(T::zero());
        self.p.fill(T::zero());
        self.extras = [ExtraState::ZERO; MAX_EXTRA_STATES];
        for (slot, e) in self.extras.iter_mut().zip(extras) {
            *slot = *e;
        }
        self.initialized = false;
        self.imu_clock_us = None;
        self.imu_candidate_us = None;
        self.last_imu = None;
        self.gps_clock_us = None;
        self.mag_clock_us = None;
        self.accel_mean = BoundedMean::EMPTY;
        self.accel_mean_span_us = 0;
        self.mag_mean = BoundedMean::EMPTY;
        self.frame = config.origin.map(LocalFrame::new);
        self.gps_recorded = false;
        self.mag_recorded = false;
        self.gps_fused_us = None;
        self.mag_fused_us = None;
        self.heading_tilt_std = T::zero();
        self.gps_accepted_us = [None; 2];
        self.gps_nis = [(T::zero(), 0); 2];
        self.gps_nis_mean = [T::lit(3.0); 2];
        self.gps_velocity_innovation_mean = Vector3::zeros();
        self.pv = integrity::PvMonitor::EMPTY;
        self.mag_monitor = mag_monitor::MagMonitor::EMPTY;
        self.last_gps_reset = ZeroOption::None;
        self.geodetic_fixes = ZeroOption::None;
        self.mag_norm_mean = BoundedMean::EMPTY;
        self.mag_field = None;
        self.mag_modes = MagModeHealth::START;
        self.mag_clean_us = 0;
        self.mag_rejected_run = 0;
        self.refusals = FilterRefusals::default();
        self.configured = true;
        Ok(())
    }

    /// [`from_state`](Self::from_state) in place. The configuration and
    /// the state are checked before anything changes.
    pub(crate) fn configure_from_state(
        &mut self,
        config: Ekf16Config<T>,
        extras: &[ExtraState<T>],
        t_us: u64,
        x: &SVector<T, N>,
        p: &SMatrix<T, N, N>,
    ) -> Result<(), Error> {
        config.validate()?;
        if !all_finite(x) {
            return Err(Error::NonFinite {
                field: "initial state",
            });
        }
        if !all_finite(p) || (0..N).any(|i| p[(i, i)] < T::zero()) {
            return Err(Error::InvalidConfig {
                field: "initial covariance".into(),
                value: None,
                bound: crate::error::Bound::Rule("must be finite with a non-negative diagonal"),
            });
        }
        let norm = quaternion_of(x).norm();
        if norm <= T::lit(1e-3) {
            return Err(Error::OutOfRange {
                field: "initial attitude",
                reason: "quaternion must not be zero",
            });
        }
        self.configure(config, extras)?;
        self.x.copy_from(x);
        self.x.fixed_rows_mut::<4>(QUAT).unscale_mut(norm);
        self.p.copy_from(p);
        if project_quaternion_covariance(&mut self.p, &self.x) {
            bump(&mut self.refusals.covariance_repairs);
        }
        self.imu_clock_us = Some(t_us);
        self.initialized = true;
        Ok(())
    }

    /// An initialized core at time `t_us` with state `x` and covariance `p`
    /// (symmetrized; the quaternion is normalized).
    pub(crate) fn from_state(
        config: Ekf16Config<T>,
        extras: &[ExtraState<T>],
        t_us: u64,
        x: &SVector<T, N>,
        p: &SMatrix<T, N, N>,
    ) -> Result<Self, Error> {
        let mut core = Self::BLANK;
        core.configure_from_state(config, extras, t_us, x, p)?;
        Ok(core)
    }

    /// The configuration.
    pub(crate) fn config(&self) -> &Ekf16Config<T> {
        &self.config
    }

    /// Multiplies the gyro and accelerometer white-noise intensities of the next predictions
    /// by `scale` (read as at least 1; a non-finite value as 1): the densities of the
    /// configuration hold at the configured IMU rate, and a stream read every `h` s keeps
    /// its per-sample variance `d^2 f0`, so its density is `d^2 f0 h` (`src/nav/horizon.rs`).
    pub(crate) fn set_imu_noise_scale(&mut self, scale: T) {
        self.imu_noise_scale = if scale.is_finite() { scale } else { T::one() };
    }

    /// True once initialized (and configured: a failed `configure` leaves
    /// no state to use).
    pub(crate) fn is_initialized(&self) -> bool {
        self.initialized && self.configured
    }

    /// Time of the state (the last accepted IMU sample), microseconds.
    pub(crate) fn time_us(&self) -> Option<u64> {
        self.imu_clock_us
    }

    /// The full state vector.
    pub(crate) fn state(&self) -> &SVector<T, N> {
        &self.x
    }

    /// The first 16 (navigation) states.
    pub(crate) fn nav_state(&self) -> StateVector<T> {
        self.x.fixed_rows::<NAV_STATES>(0).into_owned()
    }

    /// The covariance.
    pub(crate) fn covariance(&self) -> &SMatrix<T, N, N> {
        &self.p
    }

    /// The last accepted IMU sample.
    pub(crate) fn last_imu(&self) -> Option<&Imu<T>> {
        self.last_imu.as_ref()
    }

    /// The local NED frame, once known.
    pub(crate) fn frame(&self) -> Option<&LocalFrame> {
        self.frame.as_ref()
    }

    /// Refusal counters.
    pub(crate) fn refusals(&self) -> FilterRefusals {
        self.refusals
    }

    /// The last reset of a GPS block.
    pub(crate) fn last_gps_reset(&self) -> Option<GpsReset> {
        self.last_gps_reset.get()
    }

    /// The last GPS fusion records (position, velocity).
    pub(crate) fn last_gps_fusion(&self) -> Option<(FusionRecord<T, 3>, FusionRecord<T, 3>)> {
        self.gps_recorded.then_some(self.last_gps)
    }

    /// The last magnetometer fusion record.
    pub(crate) fn last_mag_fusion(&self) -> Option<FusionRecord<T, 3>> {
        self.mag_recorded.then_some(self.last_mag)
    }

    /// Time of the newest fix with a GPS block fused, µs.
    pub(crate) fn last_gps_fused_us(&self) -> Option<u64> {
        self.gps_fused_us
    }

    /// Time of the newest fix with `block` fused, reset to it or initializing the filter, µs.
    pub(crate) fn last_gps_block_fused_us(&self, block: GpsBlock) -> Option<u64> {
        self.gps_accepted_us[block as usize].filter(|_| self.gps_fused_us.is_some())
    }

    /// Time of the newest fused magnetometer sample, µs.
    pub(crate) fn last_mag_fused_us(&self) -> Option<u64> {
        self.mag_fused_us
    }

    pub(crate) fn mag_modes(&self) -> MagModeHealth {
        self.mag_modes
    }

    /// Value and variance of extra state `index` (`16..N`): the initial
    /// ones before initialization.
    pub(crate) fn extra_state(&self, index: usize) -> (T, T) {
        debug_assert!((NAV_STATES..N).contains(&index));
        if self.initialized {
            (self.x[index], self.p[(index, index)])
        } else {
            let e = &self.extras[index - NAV_STATES];
            (e.initial, e.initial_variance)
        }
    }

    /// One of the extra states' figures as an `N`-vector, zero over the navigation states
    /// (`figure` picks it from an [`ExtraState`]).
    pub(super) fn extras_vector(&self, figure: impl Fn(&ExtraState<T>) -> T) -> SVector<T, N> {
        let mut v = SVector::<T, N>::zeros();
        for (i, e) in self.extras.iter().enumerate().take(N - NAV_STATES) {
            v[NAV_STATES + i] = figure(e);
        }
        v
    }

    /// The extra states' random-walk intensities as an `N`-vector (zero over the navigation
    /// states), as the process noise takes them.
    pub(super) fn extra_intensity(&self) -> SVector<T, N> {
        self.extras_vector(|e| e.random_walk_intensity)
    }

    /// Sets extra state `index` (`16..N`) to `value` with variance
    /// `variance` and no correlation with the other states. Before
    /// initialization this replaces the state's initial value and variance.
    /// The caller checks that both are finite and the variance not negative.
    pub(crate) fn reset_extra_state(&mut self, index: usize, value: T, variance: T) {
        debug_assert!((NAV_STATES..N).contains(&index));
        if !self.initialized {
            let e = &mut self.extras[index - NAV_STATES];
            e.initial = value;
            e.initial_variance = variance;
            return;
        }
        self.x[index] = value;
        self.p.row_mut(index).fill(T::zero());
        self.p.column_mut(index).fill(T::zero());
        self.p[(index, index)] = variance;
    }

    /// Moves the value of extra state `index` (`16..N`) into `[lo, hi]`,
    /// leaving `P` as it is; true when it moved. No-op before initialization.
    pub(crate) fn clamp_extra_state(&mut self, index: usize, lo: T, hi: T) -> bool {
        debug_assert!((NAV_STATES..N).contains(&index) && lo <= hi);
        let v = self.x[index];
        let clamped = if v < lo {
            lo
        } else if v > hi {
            hi
        } else {
            v
        };
        if !self.initialized || clamped == v {
            return false;
        }
        self.x[index] = clamped;
        true
    }

    /// The current solution, `None` until initialized.
    pub(crate) fn estimate(&self) -> Option<Estimate<T>> {
        if !self.is_initialized() {
            return None;
        }
        let x = &self.x;
        Some(Estimate {
            t_us: self.imu_clock_us.unwrap_or(0),
            attitude: UnitQuaternion::new_normalize(quaternion_of(x)),
            position_ned_m: x.fixed_rows::<3>(POS).into_owned(),
            velocity_ned_m_s: x.fixed_rows::<3>(VEL).into_owned(),
            accel_bias_m_s2: x.fixed_rows::<3>(ACCEL_BIAS).into_owned(),
            gyro_bias_rad_s: x.fixed_rows::<3>(GYRO_BIAS).into_owned(),
            covariance_diagonal: self.p.diagonal().fixed_rows::<NAV_STATES>(0).into_owned(),
            delay_s: None,
            delay_std_s: None,
        })
    }
}

#[cfg(test)]
mod tests {
    //! The core with an extra state, as the augmented baseline uses it.
    use super::*;
    use crate::sensors::{Gps, Imu};

    const EXTRA: ExtraState<f64> = ExtraState {
        initial: 0.2,
        initial_variance: 0.01,
        random_walk_intensity: 1e-4,
    };

    fn feed<const N: usize>(core: &mut NavCore<f64, N>) {
        for k in 0..20u64 {
            let imu = Imu {
                t_us: k * 10_000,
                gyro_rad_s: Vector3::new(0.01, -0.02, 0.05),
                accel_m_s2: Vector3::new(0.3, 0.1, -9.7),
            };
            core.push_imu(&imu).unwrap();
            if k == 5 || k == 15 {
                let gps = Gps {
                    t_us: k * 10_000,
                    position: GpsPosition::Ned(Vector3::new(1.0, 2.0, 3.0)),
                    velocity_ned_m_s: Vector3::new(0.5, 0.0, 0.0),
                    horizontal_accuracy_m: None,
                    vertical_accuracy_m: None,
                    speed_accuracy_m_s: None,
                };
                if let GpsStep::Measure(m) = core.begin_gps(&gps).unwrap() {
                    let x16 = core.nav_state();
                    let (h, jac) = measurement::gps_position(&x16, &Vector3::zeros());
                    let gate = core.config().gps_position_gate;
                    let rec = core
                        .fuse_restricted(
                            m.t_us,
                            &(m.position_ned_m - h),
                            &NavCore::<f64, N>::widen(&jac),
                            &m.position_noise,
                            gate,
                            "gps.position",
                            None,
                        )
                        .unwrap();
                    assert!(rec.fused);
                }
            }
        }
    }

    #[test]
    fn an_extra_random_walk_state_rides_along_without_touching_the_navigation_states() {
        let config = Ekf16Config::<f64>::default();
        assert!(NavCore::<f64, 17>::new(config, &[]).is_err());
        let mut plain = NavCore::<f64, 16>::new(config, &[]).unwrap();
        let mut augmented = NavCore::<f64, 17>::new(config, &[EXTRA]).unwrap();
        feed(&mut plain);
        feed(&mut augmented);
        // The extra state is uncorrelated and unobserved: the navigation
        // states and their covariance are those of the plain filter...
        assert_eq!(augmented.nav_state(), plain.nav_state());
        let p16 = augmented
            .covariance()
            .fixed_view::<16, 16>(0, 0)
            .into_owned();
        assert!((p16 - plain.covariance()).amax() < 1e-15);
        // ...and the extra state kept its value while its variance grew by
        // the random-walk intensity over the 0.14 s since initialization.
        assert_eq!(augmented.state()[16], EXTRA.initial);
        let grown = EXTRA.initial_variance + EXTRA.random_walk_intensity * 0.14;
        assert!((augmented.covariance()[(16, 16)] - grown).abs() < 1e-15);
        assert_eq!(augmented.covariance().row(16).columns(0, 16).amax(), 0.0);
        assert_eq!(
            augmented.estimate().unwrap().covariance_diagonal,
            plain.estimate().unwrap().covariance_diagonal
        );
    }
}
