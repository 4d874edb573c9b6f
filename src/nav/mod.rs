//! `DelayCompensatedNav`: the paper's method (sec. 2.2.2-2.2.4, Figure 1).
//!
//! The 16-state EKF runs at the *delayed horizon*, on IMU data delayed by
//! the GPS delay, so IMU and GPS describe the same instant when a fix is
//! fused; forward reckoning with the newest IMU samples brings the solution
//! to the present; a separate loop estimates the delay by correlating the
//! present acceleration with the GPS one.
//!
//! ```text
//! IMU (t) ─► whitening FIR ─► history ─► Lagrange read at t - tau_a / t - tau_w ─► Ekf16 @ t_h ◄── GPS fix (received t, describes t - tau)
//!   │                                                                                │ x(t_h)
//!   └──────────── raw sample ─────────────► output predictor (forward.rs) ◄──────────┘ correction
//!                                                  │ present q, r, v at t
//!                        a_fwd(t) = R(q)(f - b_f) + [0, 0, g] ─► DelayLoop ◄── GPS velocity ─► tau
//! ```
//!
//! # One IMU sample at time `t`
//! 1. Whitening FIR on the accelerometer and the gyroscope (group delays
//!    `D_f`, `D_w`; pass-through by default).
//! 2. Both whitened streams go into one history (`HIST` samples in 16 bits,
//!    read by cubic Lagrange as a `FractionalDelayLine`).
//! 3. Horizon. The delay of the GPS relative to the raw IMU is
//!    `tau = tau_f + D_f` (the loop estimates `tau_f`, the delay relative to
//!    the whitened accelerometer, because `a_fwd` is built from it; in fixed
//!    mode `tau` is given). The horizon target is `t - tau` (integer µs). The
//!    horizon EKF steps to `t_h` only when `t_h` is later than its own time:
//!    a growing `tau` shortens steps or skips them, never rewinds; a
//!    shrinking `tau` lengthens them, at most `max_horizon_step_ratio` IMU
//!    steps per sample, so the horizon catches up smoothly. The sample it
//!    steps with is read at the delays of eq. (15) measured from `t_h`: the
//!    whitened accelerometer `t - t_h - D_f` behind the newest sample, the
//!    whitened gyroscope `t - t_h - D_w` (with `t - t_h = tau` these are
//!    `tau_f` and `tau_f + D_f - D_w`), stamped `t_h`: the instant the raw
//!    sensors saw. The EKF predicts at `filter_rate_hz` (default 100 Hz):
//!    the samples read at the horizon are accumulated into a delta angle
//!    and a delta velocity with coning and sculling corrections
//!    ([`DeltaAccumulator`]) and the
//!    EKF predicts once over the step when it spans the filter period, on
//!    the timestamps ([`Ekf16::push_imu_deltas`]). At a rate of 0 (or at
//!    or above the IMU rate) it predicts at every sample.
//! 4. Forward reckoning: the present output state is propagated with the raw
//!    sample, then corrected by the horizon EKF (below, and the derivation in
//!    `src/nav/forward.rs` and `docs/nav.md`).
//! 5. The delay loop gets `a_fwd(t) = R(q_present)(f_w - b_f) + [0, 0, g]`,
//!    `f_w` the whitened accelerometer, stamped `t`.
//!
//! # GPS fix received at `t`
//! It describes `t - tau`, which is the horizon: the EKF predicts over the
//! samples accumulated up to it and fuses it at once
//! ([`GpsOutcome::Fused`]). A fix that arrives between IMU
//! samples describes an instant up to one IMU step past the horizon; the
//! horizon first steps there (one more EKF step, read from the history), so
//! the fix is fused at its own instant. The fusion's correction reaches the
//! present through the output predictor. Its velocity goes to the delay
//! loop at a later IMU sample, the first that neither steps the horizon
//! filter nor fuses the magnetometer (at most [`DELAY_UPDATE_MAX_WAIT`]
//! samples later): the loop's peak search and gain fusion do not add to the
//! call that fuses the fix. The loop pairs samples by their grid index, so
//! the wait does not change what it correlates.
//!
//! # Magnetometer
//! Magnetometer samples are real time: the raw field at `t_m` matches the
//! horizon when the horizon reaches `t_m` (eq. 15's `tau_m = tau_f + D_f`
//! behind the present). They wait in a queue of [`MAG_QUEUE`] samples
//! ([`MagOutcome::Queued`]) and are fused by the horizon EKF as soon as its
//! time reaches theirs (at the first filter step at or after them; the
//! fusion runs at the IMU sample after that step, the EKF unmoved, so that
//! no call does a prediction and a fusion together). A full queue averages
//! each pair of neighbours into one sample (the field's mean, at their mean
//! time: it then spans the same time at half the rate), and later samples
//! closer than that spacing to the newest queued one are averaged into it,
//! until the queue drains to a quarter: the magnetometer is then fused at
//! half its rate (a quarter at twice the span...), every sample in it,
//! instead of not at all. Each sample averaged into another is counted in
//! [`NavRefusals::mag_averaged`] (its push answers `Queued`). The EKF's
//! magnetometer noise is not divided by the samples averaged: the
//! configured noise also stands for disturbances, which averaging does not
//! remove.
//!
//! # Forward reckoning in `O(1)`
//! The output predictor of PX4's EKF2, made exact to first order without
//! touching its history: corrections are accumulated and each stored output
//! state is kept in the frame of the corrections applied before it, so the
//! correction still due at `t_h` costs a fixed number of operations
//! whatever the delay. Per IMU sample: two FIR passes, two Lagrange reads
//! (`2 x 4` taps; one when the group delays are equal, as with the default
//! pass-through), one delta accumulation (one EKF step per filter
//! period), one `propagate` for the present, one interpolation between two
//! ring entries, one delay-loop push. See
//! [`NavWork`] and the test that compares the counted work at two delays.
//!
//! # Initialization
//! The horizon EKF initializes as [`Ekf16`] does, from delayed IMU samples
//! and then a GPS fix, with two waits for what it sets: while a
//! magnetometer stream exists but none of its samples has reached the
//! horizon, fixes are answered [`GpsOutcome::Waiting`]; when the aligning
//! fix moves faster than [`MOVING_SPEED_M_S`], the tilt standard deviation
//! is raised to [`MOVING_TILT_STD_RAD`] (the accelerometer is not the
//! vertical in a turn) and GPS velocity resolves it. The output state
//! starts from the horizon state at that moment; the present estimate is
//! `None` until the horizon has reached the first stored output state (one
//! delay later) and corrected it. [`DelayCompensatedNav::alignment`] and
//! [`DelayCompensatedNav::health`] report where it stands.
//!
//! # Timestamps
//! The history is read by time, not with a mean period (`timeline.rs`):
//! rate changes, dropped samples and jitter read the right sample. Clock
//! faults are refused and counted without blocking a stream; a clock that
//! went back needs [`DelayCompensatedNav::reset`].
//!
//! # Fixed mode
//! [`DelayMode::Fixed`] is the same type with the loop off and `tau` given:
//! for receivers whose latency is calibrated, and, run with the simulator's
//! true delay, the `oracle` row of the `reproduce` harness.
//!
//! # Memory
//! `HIST` (default 1100) must hold the largest delay plus the FIR group delay
//! and the Lagrange stencil at the IMU rate ([`DelayCompensatedNav::new`]
//! checks it): at 1 kHz and the default 1 s range, about 1030. Per sample of
//! `HIST`: the history's 6 values in 16 bits with a side word (block
//! floating point, [`HISTORY_BLOCK`] samples a block) and a 16-bit time
//! step, 16 bytes in `f32` and in `f64`, plus one full-precision block. The
//! output predictor's ring ([`OUTPUT_ENTRIES`], one entry per stride), the
//! delay loop and the magnetometer queue ([`MAG_QUEUE`]) do not grow with
//! `HIST`. Measured (`docs/nav.md`): 33,160 bytes in `f32` at 1100, 24,048
//! at 530 (1 kHz, 0.5 s), 19,656 at 256 (200 Hz, 1 s).
//!
//! On a microcontroller, put [`DelayCompensatedNav::BLANK`] (a `const`) in
//! a `static` and [`configure`](DelayCompensatedNav::configure) it there:
//! no stack copy of the navigator at any time (`docs/nav.md`,
//! "Construction in place").

pub mod config;
mod forward;
pub mod health;
mod timeline;

#[cfg(test)]
mod memory;

pub use config::{DelayMode, NavConfig, WHITENING_TAPS, WhiteningFilter};
pub use health::{AlignmentState, DelayHealth, Health, ResetCause, ResetRecord};

use crate::delay::packed::{HeaderCache, PackedRing};
use crate::delay::ring::Ring;
use crate::delay::{
    DefaultDelayLoop, DelayUpdate, HorizonFix, MAX_INPUT_MAGNITUDE, SensorDelays, WhiteningFir,
};
use crate::ekf16::delta::DeltaAccumulator;
use crate::ekf16::nav_core::check_position_kind;
use crate::ekf16::state::{
    ACCEL_BIAS, GYRO_BIAS, POS, QUAT, VEL, attitude_covariance, quaternion_of,
};
use crate::ekf16::{Ekf16, RefusalCounters};
use crate::error::{Bound, ConfigPath, Error, Section};
use crate::estimate::{Estimate, FusionRecord, GpsOutcome, MagOutcome, Navigator};
use crate::geo::rotation_matrix;
use crate::scalar::{Scalar, zeros_const};
use crate::sensors::{
    Gps, GpsFix, Imu, ImuSample, Mag, MagSample, checked_gps, checked_imu, checked_mag,
};
use crate::zero_option::ZeroOption;
use forward::ForwardReckoner;
use health::{GPS_STALE_US, HEADING_STALE_US, MAX_POSITION_STD_M, MAX_VELOCITY_STD_M_S};
use nalgebra::{SVector, UnitQuaternion, Vector3};
use timeline::{ClockRefusal, SampleTimes, StreamClock};

/// Lagrange order of the IMU history reads (cubic).
pub const HISTORY_ORDER: usize = 3;

/// IMU samples that share one offset and scale per channel in the 16-bit
/// history (`src/delay/packed.rs`); the newest incomplete block is kept in
/// full precision.
pub const HISTORY_BLOCK: usize = 24;

/// Magnetometer samples waiting for the horizon: at 100 Hz, a delay up to
/// 0.3 s (with the filter period and one sample: 32 samples) fits; a longer
/// delay or a faster magnetometer fills it, and a full queue is thinned to
/// every other sample (module docs): at 0.5 s the magnetometer is fused at
/// 50 Hz.
pub const MAG_QUEUE: usize = 32;

/// Entries of the output predictor's ring (`src/nav/forward.rs`): one every
/// stride (a time), chosen by [`DelayCompensatedNav::new`] so that the ring
/// spans the largest delay (14 samples at 1 kHz and 0.5 s, 27 at the default
/// 1 s range; 32 entries, 35 samples apart, cost the `high` scenario's roll
/// 3 %: docs/PERFORMANCE.md).
pub const OUTPUT_ENTRIES: usize = 40;

/// Default history, IMU samples: a 1 s delay range at 1 kHz with margin.
pub const DEFAULT_HISTORY: usize = 1100;

/// GPS speed above which an alignment counts as made in motion, m/s. The
/// accelerometer cannot tell: its mean departs from gravity by the
/// kinematic acceleration (6 % in a 20 deg turn) but also by its bias (up
/// to 10 % with Table 3's 0.1 g), so the fix's velocity decides.
pub const MOVING_SPEED_M_S: f64 = 2.0;

/// Tilt standard deviation of an alignment made while accelerating, rad
/// (20 deg: the bank of a brisk turn).
pub const MOVING_TILT_STD_RAD: f64 = 0.35;

/// Relative margin on the IMU rate when checking the history size.
const RATE_MARGIN: f64 = 1.02;

/// IMU samples a fix's velocity waits at most for the delay loop: its
/// correlation update runs at the first IMU sample after the fix that
/// neither steps the horizon filter nor fuses the magnetometer, at the
/// latest at this many samples (a filter at the IMU rate steps at every one).
pub const DELAY_UPDATE_MAX_WAIT: u32 = 3;

/// Samples refused or dropped by the navigator itself (the horizon EKF's own
/// counters are in [`DelayCompensatedNav::ekf_refusals`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NavRefusals {
    /// IMU samples with a non-finite value.
    pub imu_non_finite: u32,
    /// IMU samples above the EKF's plausible range.
    pub imu_out_of_range: u32,
    /// IMU samples duplicated or going back in time.
    pub imu_time: u32,
    /// IMU samples stamped more than `max_time_jump_us` ahead and not
    /// confirmed by the next sample.
    pub imu_ahead: u32,
    /// IMU gaps longer than the EKF's `max_imu_step_us` or than the
    /// history's longest step, `u32::MAX / HIST` µs (history restarted),
    /// and steps of 65,535 µs or more that made the history forget its
    /// oldest samples (a ninth within its span, `docs/nav.md`).
    pub imu_gap: u32,
    /// GPS fixes with a non-finite or implausible value.
    pub gps_invalid: u32,
    /// GPS fixes duplicated or going back in time.
    pub gps_time: u32,
    /// GPS fixes whose reported accuracy is not finite, not positive or
    /// above its bound (also counted in `gps_invalid`).
    pub gps_accuracy: u32,
    /// GPS fixes stamped more than `max_time_jump_us` after the newest IMU sample.
    pub gps_ahead: u32,
    /// GPS fixes whose position kind (geodetic or NED) differs from the first
    /// accepted fix's.
    pub gps_mixed_frames: u32,
    /// Magnetometer samples with a non-finite or zero field.
    pub mag_invalid: u32,
    /// Magnetometer samples duplicated or going back in time.
    pub mag_time: u32,
    /// Magnetometer samples stamped more than `max_time_jump_us` after the newest IMU sample.
    pub mag_ahead: u32,
    /// Magnetometer samples averaged into a neighbour because the queue was
    /// full (module docs): fused, at a lower rate.
    pub mag_averaged: u32,
    /// Horizon steps the EKF refused (e.g. a step longer than its maximum).
    pub horizon_refused: u32,
    /// Samples the delay loop refused.
    pub delay_loop_refused: u32,
}

/// Work done so far, counted (the cost per sample must not grow with the delay).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NavWork {
    /// IMU samples accepted.
    pub imu_samples: u64,
    /// Horizon EKF steps (one per filter period, or per IMU sample at the
    /// IMU rate).
    pub horizon_steps: u64,
    /// `process::propagate` calls of the output predictor.
    pub forward_propagations: u64,
    /// Stored samples combined by the Lagrange reads of the history.
    pub interpolation_taps: u64,
    /// Moves of the output ring's cursor.
    pub ring_cursor_moves: u64,
    /// Products of the delay loop's sliding correlation.
    pub correlation_multiply_adds: u64,
}

/// A magnetometer sample waiting for the horizon: the mean field of
/// `samples` raw samples at their mean time (one sample until a full queue
/// averages neighbours: module docs).
#[derive(Debug, Clone, Copy)]
struct QueuedMag<T: Scalar> {
    t_us: u64,
    field_body: Vector3<T>,
    samples: u16,
}

impl<T: Scalar> QueuedMag<T> {
    fn new(m: Mag<T>) -> Self {
        Self {
            t_us: m.t_us,
            field_body: m.field_body,
            samples: 1,
        }
    }

    /// The mean of `self` and a `newer` one, each weighed by its samples.
    fn averaged_with(self, newer: Self) -> Self {
        // n >= 1 even for blank entries (never averaged), so that no
        // division can fail or give NaN. The offset is at most `dt_us` (in
        // u128 the product cannot overflow), so the sum stays within u64.
        let n = (u32::from(self.samples) + u32::from(newer.samples)).max(1);
        let dt_us = newer.t_us.saturating_sub(self.t_us);
        let share = T::from_f32_exact(f32::from(newer.samples)) / T::from_f32_exact(n as f32);
        let offset_us = u128::from(dt_us) * u128::from(newer.samples) / u128::from(n);
        Self {
            t_us: self.t_us.saturating_add(offset_us as u64),
            field_body: self.field_body + (newer.field_body - self.field_body) * share,
            samples: u16::try_from(n).unwrap_or(u16::MAX),
        }
    }
}

/// Averages the waiting samples of a full queue in pairs, oldest first (the
/// oldest alone when their number is odd, so that the newest is in a pair);
/// returns how many samples were averaged into another.
fn average_pairs<T: Scalar, const N: usize>(ring: &mut Ring<QueuedMag<T>, N>) -> u32 {
    let len = ring.len();
    let mut averaged = 0;
    let mut older = None;
    for k in 0..len {
        let Some(m) = ring.pop_oldest() else {
            break;
        };
        if (len - k).is_multiple_of(2) {
            older = Some(m);
            continue;
        }
        ring.push(match older.take() {
            Some(o) => {
                averaged += 1;
                o.averaged_with(m)
            }
            None => m,
        });
    }
    averaged
}

impl NavRefusals {
    /// Nothing counted (the `const` of [`Default::default`]).
    const ZERO: Self = Self {
        imu_non_finite: 0,
        imu_out_of_range: 0,
        imu_time: 0,
        imu_ahead: 0,
        imu_gap: 0,
        gps_invalid: 0,
        gps_time: 0,
        gps_accuracy: 0,
        gps_ahead: 0,
        gps_mixed_frames: 0,
        mag_invalid: 0,
        mag_time: 0,
        mag_ahead: 0,
        mag_averaged: 0,
        horizon_refused: 0,
        delay_loop_refused: 0,
    };
}

fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// A clock check's outcome with its refusal counted: `ahead` for a
/// timestamp too far ahead, `time` for a duplicate or one going back.
fn counted(
    check: Result<(), (ClockRefusal, Error)>,
    ahead: &mut u32,
    time: &mut u32,
) -> Result<(), Error> {
    check.map_err(|(why, e)| {
        bump(if why == ClockRefusal::Ahead {
            ahead
        } else {
            time
        });
        e
    })
}

/// Either a whitening FIR or nothing.
#[derive(Debug, Clone)]
struct Whitening<T: Scalar> {
    fir: Option<WhiteningFir<T, WHITENING_TAPS>>,
    group_delay_s: T,
}

impl<T: Scalar> Whitening<T> {
    const BLANK: Self = Self {
        fir: None,
        group_delay_s: T::ZERO,
    };

    fn new(filter: WhiteningFilter<T>, rate_hz: T) -> Result<Self, Error> {
        Ok(Self {
            fir: match filter {
                WhiteningFilter::PassThrough => None,
                WhiteningFilter::LowPass { cutoff_hz } => {
                    Some(WhiteningFir::low_pass(cutoff_hz, rate_hz)?)
                }
            },
            group_delay_s: filter.group_delay_s(rate_hz),
        })
    }

    fn filter(&mut self, x: Vector3<T>) -> Vector3<T> {
        match &mut self.fir {
            // The input was checked finite: the filter cannot refuse it.
            Some(fir) => fir.filter(x).unwrap_or(x),
            None => x,
        }
    }

    fn reset(&mut self) {
        if let Some(fir) = &mut self.fir {
            fir.reset();
        }
    }
}

/// The delay-compensated GPS/IMU navigator of the paper (Figure 1); see the
/// module docs. `HIST` is the IMU history in samples.
///
/// ```
/// use delaynav::nav::{DelayCompensatedNav, DelayMode, NavConfig};
/// use delaynav::{Gps, GpsPosition, Imu, Navigator};
/// use nalgebra::Vector3;
///
/// // At rest at 100 Hz; the GPS is 0.1 s late (a calibrated receiver).
/// let mut config = NavConfig::<f64>::default();
/// config.imu_rate_hz = 100.0;
/// config.mode = DelayMode::Fixed { delay_s: 0.1 };
/// let mut nav = DelayCompensatedNav::<f64, 128>::new(config)?;
/// for k in 1..=300u64 {
///     let t_us = k * 10_000;
///     nav.push_imu(&Imu { t_us, gyro_rad_s: Vector3::zeros(), accel_m_s2: Vector3::new(0.0, 0.0, -9.80665) })?;
///     if k % 10 == 0 {
///         let fix = Gps {
///             t_us,
///             position: GpsPosition::Ned(Vector3::new(1.0, 2.0, 0.0)),
///             velocity_ned_m_s: Vector3::zeros(),
///             horizontal_accuracy_m: None,
///             vertical_accuracy_m: None,
///             speed_accuracy_m_s: None,
///         };
///         nav.push_gps(&fix)?;
///     }
/// }
/// let now = nav.estimate().expect("initialized");
/// let horizon = nav.horizon_estimate().expect("initialized");
/// assert_eq!(now.t_us, 3_000_000);
/// assert_eq!(horizon.t_us, 2_900_000);
/// assert!((now.position_ned_m - Vector3::new(1.0, 2.0, 0.0)).norm() < 0.1);
/// # Ok::<(), delaynav::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct DelayCompensatedNav<T: Scalar, const HIST: usize = DEFAULT_HISTORY> {
    config: NavConfig<T>,
    ekf: Ekf16<T>,
    /// Counters of the horizon filters `ekf` replaced.
    replaced_ekf_refusals: RefusalCounters,
    delay_loop: DefaultDelayLoop<T>,
    accel_whitening: Whitening<T>,
    gyro_whitening: Whitening<T>,
    /// Whitened accelerometer (0..3) and gyroscope (3..6).
    /// 16-bit block floating point (`src/delay/packed.rs`).
    history: PackedRing<T, 6, HIST, HISTORY_BLOCK>,
    /// The history's block headers decoded by the last reads.
    history_headers: HeaderCache<T, 6>,
    /// Stored samples combined by the history's reads (a work counter).
    interpolation_taps: u64,
    /// Timestamp of every history sample.
    times: SampleTimes<HIST>,
    forward: ForwardReckoner<T, OUTPUT_ENTRIES>,
    /// Delayed samples read at the horizon since the horizon EKF's time.
    deltas: DeltaAccumulator<T>,
    /// The horizon EKF moved since the magnetometer queue was last drained.
    mags_due: bool,
    /// The horizon EKF's prediction period, µs (0: every IMU sample).
    filter_period_us: u64,
    mags: Ring<QueuedMag<T>, MAG_QUEUE>,
    /// Least time between queued magnetometer samples, µs: 0 until the
    /// queue fills, then the spacing of the averaged queue (module docs).
    mag_spacing_us: u64,
    /// Time of the first raw sample in the newest queued one, µs: samples
    /// closer to it than `mag_spacing_us` are averaged into that one.
    mag_newest_start_us: u64,
    last_imu: Option<Imu<T>>,
    imu_clock: StreamClock,
    gps_clock: StreamClock,
    mag_clock: StreamClock,
    last_reset: ZeroOption<ResetRecord>,
    valid_delay_updates: u32,
    /// IMU biases and their variances (accelerometer, gyroscope) kept
    /// through a reset: sensor properties, not lost with the clock.
    retained_biases: Option<(SVector<T, 6>, SVector<T, 6>)>,
    /// A magnetometer sample has reached the horizon EKF since the start.
    mag_at_horizon: bool,
    /// Whether the accepted fixes are geodetic (`Some(true)`) or NED.
    geodetic_fixes: ZeroOption<bool>,
    last_update: ZeroOption<DelayUpdate<T>>,
    /// A fix's time and velocity waiting for the delay loop, and the IMU
    /// samples it has waited ([`DELAY_UPDATE_MAX_WAIT`]).
    pending_delay_fix: Option<(u64, Vector3<T>, u32)>,
    /// The horizon's time and velocity after the last fused fix: the next
    /// fix's prior velocity minus it is the IMU's velocity change between
    /// them ([`gps_timing_noise`](Self::gps_timing_noise)).
    last_fix_velocity: Option<(u64, Vector3<T>)>,
    present_accel: Vector3<T>,
    refusals: NavRefusals,
    imu_samples: u64,
    horizon_steps: u64,
    /// False in [`BLANK`](Self::BLANK) and after a failed
    /// [`configure`](Self::configure): every sample is refused.
    configured: bool,
}

impl<T: Scalar, const HIST: usize> DelayCompensatedNav<T, HIST> {
    /// A navigator for a validated configuration whose delay range fits the
    /// history `HIST` at `imu_rate_hz` (with a 2 % rate margin).
    ///
    /// The value is built on the stack and returned: on a host that is
    /// what you want. On a microcontroller, where the navigator is tens of
    /// KB, start from [`BLANK`](Self::BLANK) in its final place (a
    /// `static`) and [`configure`](Self::configure) it there.
    pub fn new(config: NavConfig<T>) -> Result<Self, Error> {
        let mut nav = Self::BLANK;
        nav.configure(config)?;
        Ok(nav)
    }

    /// A navigator not configured yet: a `const` value the compiler builds,
    /// every buffer empty, so a `static` holding it is laid out by the
    /// linker and costs no stack at all. It is all zero bytes: a mutable
    /// `static` of it goes to `.bss`, nothing of it in flash
    /// (`tests/blank_bss.rs`). It refuses every sample
    /// ([`Error::NotConfigured`]), its estimates are `None` and its
    /// [`health`](Self::health) says [`AlignmentState::NotConfigured`]
    /// until [`configure`](Self::configure) succeeds.
    ///
    /// ```
    /// use core::cell::RefCell;
    /// use delaynav::nav::{AlignmentState, DelayCompensatedNav, NavConfig};
    /// use delaynav::{Error, Imu, Navigator};
    /// use nalgebra::Vector3;
    ///
    /// // What a firmware does with `critical_section::Mutex<RefCell<..>>`
    /// // or `cortex_m::singleton!`; a thread-local stands in for it here.
    /// std::thread_local! {
    ///     static NAV: RefCell<DelayCompensatedNav<f32, 520>> =
    ///         const { RefCell::new(DelayCompensatedNav::BLANK) };
    /// }
    /// NAV.with_borrow_mut(|nav| {
    ///     let imu = Imu { t_us: 1000, gyro_rad_s: Vector3::zeros(), accel_m_s2: Vector3::new(0.0, 0.0, -9.8) };
    ///     assert_eq!(nav.push_imu(&imu), Err(Error::NotConfigured));
    ///     assert_eq!(nav.health().alignment, AlignmentState::NotConfigured);
    ///     let mut config = NavConfig::default();
    ///     config.delay_loop.fusion.delay_max_s = 0.5;
    ///     nav.configure(config)?; // in place: a small stack
    ///     nav.push_imu(&imu)?;
    ///     assert_eq!(nav.health().alignment, AlignmentState::WaitingForImu);
    ///     Ok::<(), Error>(())
    /// })?;
    /// # Ok::<(), Error>(())
    /// ```
    pub const BLANK: Self = Self {
        config: NavConfig::ZEROED,
        ekf: Ekf16::BLANK,
        replaced_ekf_refusals: RefusalCounters::ZERO,
        delay_loop: DefaultDelayLoop::BLANK,
        accel_whitening: Whitening::BLANK,
        gyro_whitening: Whitening::BLANK,
        history: PackedRing::new(),
        history_headers: HeaderCache::new(),
        interpolation_taps: 0,
        times: SampleTimes::new(),
        forward: ForwardReckoner::new(),
        deltas: DeltaAccumulator::new(),
        mags_due: false,
        filter_period_us: 0,
        mags: Ring::new(QueuedMag {
            t_us: 0,
            field_body: zeros_const(),
            samples: 0,
        }),
        mag_spacing_us: 0,
        mag_newest_start_us: 0,
        last_imu: None,
        imu_clock: StreamClock::NEW,
        gps_clock: StreamClock::NEW,
        mag_clock: StreamClock::NEW,
        last_reset: ZeroOption::None,
        valid_delay_updates: 0,
        retained_biases: None,
        mag_at_horizon: false,
        geodetic_fixes: ZeroOption::None,
        last_update: ZeroOption::None,
        pending_delay_fix: None,
        last_fix_velocity: None,
        present_accel: zeros_const(),
        refusals: NavRefusals::ZERO,
        imu_samples: 0,
        horizon_steps: 0,
        configured: false,
    };

    /// True once a [`configure`](Self::configure) (or [`new`](Self::new))
    /// succeeded.
    pub fn is_configured(&self) -> bool {
        self.configured
    }

    /// Validates `config` and (re)starts the navigator with it in place:
    /// afterwards it is what [`new`](Self::new) returns for `config` (the
    /// counters too). The big members (history, output ring, delay loop
    /// buffers) are emptied through `&mut`, never rebuilt by value, so the
    /// stack this needs is small and does not grow with `HIST` (measured
    /// on a Cortex-M4 in `docs/PERFORMANCE.md`). Works on
    /// [`BLANK`](Self::BLANK) and on a navigator in use.
    ///
    /// On error (the configuration does not validate, or its delay range
    /// does not fit `HIST`) the navigator is left not configured: it
    /// refuses every sample and gives no estimate until a `configure`
    /// succeeds.
    pub fn configure(&mut self, config: NavConfig<T>) -> Result<(), Error> {
        self.configured = false;
        config.validate()?;
        let accel_whitening = Whitening::new(config.accel_whitening, config.imu_rate_hz)?;
        let gyro_whitening = Whitening::new(config.gyro_whitening, config.imu_rate_hz)?;
        let longest_s = config.delay_loop.fusion.delay_max_s
            + accel_whitening
                .group_delay_s
                .max(gyro_whitening.group_delay_s);
        let needed = (longest_s * config.imu_rate_hz * T::lit(RATE_MARGIN))
            .ceil()
            .as_f64()
            + (HISTORY_ORDER + 2) as f64;
        if needed > HIST as f64 {
            return Err(Error::InvalidConfig {
                field: ConfigPath::new("HIST"),
                value: Some(HIST as f64),
                // The largest delay at the IMU rate, with margins.
                bound: Bound::History {
                    needed: needed as u32,
                    short_by: (needed as usize - HIST) as u32,
                    delay_s: longest_s.as_f64() as f32,
                    rate_hz: config.imu_rate_hz.as_f64() as f32,
                },
            });
        }
        // The output ring spans `needed` samples with a stride per entry:
        // `OUTPUT_ENTRIES - 2` intervals, one more for the newest unstored.
        let stride = (needed as u64).div_ceil(OUTPUT_ENTRIES as u64 - 2);
        let stride_us = (T::lit(stride as f64 * 1e6) / config.imu_rate_hz)
            .round()
            .as_f64() as u64;
        let rate = config.filter_rate_hz;
        let filter_period_us = if rate > T::zero() && rate < config.imu_rate_hz {
            (T::lit(1e6) / rate).round().as_f64() as u64
        } else {
            0
        };
        self.ekf
            .configure(config.ekf)
            .map_err(|e| e.within(Section::Ekf))?;
        self.delay_loop
            .configure(config.loop_config())
            .map_err(|e| e.within(Section::DelayLoop))?;
        self.config = config;
        self.replaced_ekf_refusals = RefusalCounters::default();
        self.accel_whitening = accel_whitening;
        self.gyro_whitening = gyro_whitening;
        self.history.clear();
        self.interpolation_taps = 0;
        self.times.clear();
        self.forward.configure(stride_us);
        self.deltas.clear();
        self.mags_due = false;
        self.filter_period_us = filter_period_us;
        self.mags.clear();
        self.mag_spacing_us = 0;
        self.last_imu = None;
        self.imu_clock = StreamClock::default();
        self.gps_clock = StreamClock::default();
        self.mag_clock = StreamClock::default();
        self.last_reset = ZeroOption::None;
        self.valid_delay_updates = 0;
        self.retained_biases = None;
        self.mag_at_horizon = false;
        self.geodetic_fixes = ZeroOption::None;
        self.last_update = ZeroOption::None;
        self.pending_delay_fix = None;
        self.last_fix_velocity = None;
        self.present_accel = Vector3::zeros();
        self.refusals = NavRefusals::default();
        self.imu_samples = 0;
        self.horizon_steps = 0;
        self.configured = true;
        Ok(())
    }

    /// The configuration (every field zero on a navigator not configured:
    /// see [`is_configured`](Self::is_configured)).
    pub fn config(&self) -> &NavConfig<T> {
        &self.config
    }

    /// The horizon EKF.
    pub fn horizon_filter(&self) -> &Ekf16<T> {
        &self.ekf
    }

    /// The delay loop (idle in fixed mode).
    pub fn delay_loop(&self) -> &DefaultDelayLoop<T> {
        &self.delay_loop
    }

    /// Group delays `(D_f, D_w)` of the whitening filters, s.
    pub fn group_delays_s(&self) -> (T, T) {
        (
            self.accel_whitening.group_delay_s,
            self.gyro_whitening.group_delay_s,
        )
    }

    /// The GPS delay relative to the raw IMU, `tau = tau_f + D_f`, s: the
    /// estimate, or the given delay in fixed mode.
    pub fn delay_s(&self) -> T {
        match self.config.mode {
            DelayMode::Estimated { .. } => {
                self.delay_loop.delay_s() + self.accel_whitening.group_delay_s
            }
            DelayMode::Fixed { delay_s } => delay_s,
        }
    }

    /// Standard deviation of the delay, s (0 in fixed mode).
    pub fn delay_std_s(&self) -> T {
        match self.config.mode {
            DelayMode::Estimated { .. } => self.delay_loop.delay_std_s(),
            DelayMode::Fixed { .. } => T::zero(),
        }
    }

    /// Eq. (15): the delays applied to the whitened accelerometer, the
    /// whitened gyroscope and the raw magnetometer, s.
    pub fn sensor_delays(&self) -> SensorDelays<T> {
        let (d_f, d_w) = self.group_delays_s();
        SensorDelays::new(self.delay_s() - d_f, d_f, d_w)
    }

    /// The last delay update: validity per axis, correlation peaks,
    /// measurements and gains (`None` before the first, and in fixed mode).
    pub fn last_delay_update(&self) -> Option<&DelayUpdate<T>> {
        self.last_update.as_ref()
    }

    /// The solution at the delayed horizon (the EKF's), `None` until initialized.
    pub fn horizon_estimate(&self) -> Option<Estimate<T>> {
        if !self.configured {
            return None;
        }
        self.ekf.estimate().map(|e| self.with_delay(e))
    }

    /// NED acceleration at the present, `R(q)(f - b_f) + [0, 0, g]` from the
    /// newest raw sample, m/s^2 (`None` until the present estimate exists).
    pub fn acceleration_ned_m_s2(&self) -> Option<Vector3<T>> {
        (self.configured && self.forward.is_ready()).then_some(self.present_accel)
    }

    /// Samples refused or dropped by the navigator.
    pub fn refusals(&self) -> NavRefusals {
        self.refusals
    }

    /// The horizon EKF's refusal and gating counters.
    ///
    /// Counted over the navigator's whole life: the counters of horizon
    /// filters it replaced (at [`reset`](Self::reset) and alignment) are
    /// kept.
    pub fn ekf_refusals(&self) -> RefusalCounters {
        self.replaced_ekf_refusals.merged(self.ekf.refusals())
    }

    /// Work counters.
    pub fn work(&self) -> NavWork {
        NavWork {
            imu_samples: self.imu_samples,
            horizon_steps: self.horizon_steps,
            forward_propagations: self.forward.propagations(),
            interpolation_taps: self.interpolation_taps,
            ring_cursor_moves: self.forward.cursor_moves(),
            correlation_multiply_adds: self.delay_loop.multiply_adds(),
        }
    }

    /// Magnetometer samples waiting for the horizon.
    pub fn queued_mag_samples(&self) -> usize {
        self.mags.len()
    }

    /// Restarts the navigator as if new, keeping its configuration and its
    /// refusal counters (recorded as [`ResetCause::Requested`] in
    /// [`health`](Self::health)). Call it when a push returns
    /// [`Error::TimeWentBackwards`] for a clock that really went back (a
    /// rebooted sensor hub): every later sample would be refused otherwise.
    /// No allocation; the horizon EKF and the delay loop are configured
    /// again in place from the configuration, which
    /// [`configure`](Self::configure) validated. Nothing happens to a
    /// navigator not configured.
    pub fn reset(&mut self) {
        if !self.configured {
            return;
        }
        if let Some(x) = self.ekf.nav_state() {
            let p = self.ekf.covariance();
            let mut biases = SVector::<T, 6>::zeros();
            let mut variances = SVector::<T, 6>::zeros();
            for i in 0..3 {
                biases[i] = x.accel_bias_m_s2[i];
                biases[3 + i] = x.gyro_bias_rad_s[i];
                variances[i] = p[(ACCEL_BIAS + i, ACCEL_BIAS + i)];
                variances[3 + i] = p[(GYRO_BIAS + i, GYRO_BIAS + i)];
            }
            self.retained_biases = Some((biases, variances));
        }
        // Validated by `configure`: neither fails (a failure would leave
        // the part refusing, never half reset).
        let refusals = self.ekf_refusals();
        if self.ekf.configure(self.config.ekf).is_ok() {
            self.replaced_ekf_refusals = refusals;
        }
        let _ = self.delay_loop.configure(self.config.loop_config());
        self.accel_whitening.reset();
        self.gyro_whitening.reset();
        self.history.clear();
        self.times.clear();
        self.forward.reset();
        self.deltas.clear();
        self.mags_due = false;
        self.mags.clear();
        self.mag_spacing_us = 0;
        self.last_reset = ZeroOption::Some(ResetRecord {
            t_us: self.imu_clock.last(),
            cause: ResetCause::Requested,
        });
        self.last_imu = None;
        self.imu_clock = StreamClock::default();
        self.gps_clock = StreamClock::default();
        self.mag_clock = StreamClock::default();
        self.last_update = ZeroOption::None;
        self.pending_delay_fix = None;
        self.last_fix_velocity = None;
        self.valid_delay_updates = 0;
        self.mag_at_horizon = false;
        self.geodetic_fixes = ZeroOption::None;
        self.present_accel = Vector3::zeros();
    }

    /// Where the navigator is in its start-up.
    pub fn alignment(&self) -> AlignmentState {
        if !self.configured {
            AlignmentState::NotConfigured
        } else if self.forward.is_ready() {
            AlignmentState::Aligned
        } else if self.ekf.is_initialized() {
            AlignmentState::CarryingForward
        } else if self.ekf.time_us().is_some() {
            AlignmentState::WaitingForGps
        } else {
            AlignmentState::WaitingForImu
        }
    }

    /// What the navigator can vouch for now (see [`health`]).
    pub fn health(&self) -> Health<T> {
        let alignment = self.alignment();
        let aligned = alignment == AlignmentState::Aligned;
        let horizon = self.ekf.time_us().unwrap_or(0);
        let recent =
            |t: Option<u64>, stale: u64| t.is_some_and(|t| horizon <= t.saturating_add(stale));
        let p = self.ekf.covariance();
        let std = |i: usize| p[(i, i)].max(T::zero()).sqrt();
        let horizontal_std = (p[(POS, POS)] + p[(POS + 1, POS + 1)])
            .max(T::zero())
            .sqrt();
        let velocity_std = std(VEL).max(std(VEL + 1)).max(std(VEL + 2));
        let gps_recent = recent(self.ekf.last_gps_fused_us(), GPS_STALE_US);
        let mag_fused = self.ekf.last_mag_fused_us();
        let estimated = self.is_estimating();
        Health {
            t_us: self.imu_clock.last(),
            alignment,
            tilt_valid: aligned,
            heading_valid: aligned && recent(mag_fused, HEADING_STALE_US),
            velocity_valid: aligned && gps_recent && velocity_std <= T::lit(MAX_VELOCITY_STD_M_S),
            position_valid: aligned && gps_recent && horizontal_std <= T::lit(MAX_POSITION_STD_M),
            delay_valid: !estimated
                || (self.valid_delay_updates > 0 && !self.delay_loop.status().is_out_of_range()),
            last_reset: self.last_reset.get(),
            refusals: self.refusals,
            ekf_refusals: self.ekf_refusals(),
            delay: DelayHealth {
                estimated,
                delay_s: self.delay_s(),
                delay_std_s: self.delay_std_s(),
                last_valid_axes: self.last_update.get().map(|u| u.axes.map(|a| a.valid)),
                valid_updates: self.valid_delay_updates,
                status: estimated.then(|| self.delay_loop.status()),
            },
        }
    }

    /// The present estimate with its [`Health`] (`None` until aligned).
    pub fn estimate_with_health(&self) -> Option<(Estimate<T>, Health<T>)> {
        Some((self.estimate()?, self.health()))
    }

    fn with_delay(&self, mut e: Estimate<T>) -> Estimate<T> {
        e.delay_s = Some(self.delay_s());
        e.delay_std_s = Some(self.delay_std_s());
        e
    }

    /// `tau` in whole microseconds.
    fn delay_us(&self) -> u64 {
        (self.delay_s() * T::lit(1e6)).round().as_f64().max(0.0) as u64
    }

    /// What the delay's uncertainty adds to the next fix's noise
    /// ([`NavConfig::gps_noise_from_delay`]): the variance of the delay
    /// estimate, s^2, and the horizon's mean NED acceleration since the last
    /// fused fix (its prior velocity minus the velocity after that fix, over
    /// the time between: the IMU's alone, m/s^2; zero before a first fix).
    fn gps_timing_noise(&self) -> (T, Vector3<T>) {
        if !(self.config.gps_noise_from_delay && self.is_estimating()) {
            return (T::zero(), Vector3::zeros());
        }
        let accel = match (
            self.last_fix_velocity,
            self.ekf.time_us(),
            self.ekf.nav_state(),
        ) {
            (Some((t0_us, v0)), Some(t_us), Some(x)) if t_us > t0_us => {
                (x.velocity_ned_m_s - v0) / T::lit((t_us - t0_us) as f64 * 1e-6)
            }
            _ => Vector3::zeros(),
        };
        let std = self.delay_std_s();
        (std * std, accel)
    }

    fn is_estimating(&self) -> bool {
        matches!(self.config.mode, DelayMode::Estimated { .. })
    }

    /// The horizon time for the present `t_us`, or `None` when the horizon
    /// does not move (or cannot be read yet).
    fn horizon_target(&self, t_us: u64, dt_us: u64) -> Option<u64> {
        let target = t_us.checked_sub(self.delay_us())?;
        if self.history.len() <= HISTORY_ORDER {
            return None;
        }
        let oldest = self.times.oldest()?;
        let Some(horizon) = self.horizon_us() else {
            return Some(target);
        };
        if target <= horizon {
            return None;
        }
        let max_step = (self.config.max_horizon_step_ratio * T::lit(dt_us as f64))
            .as_f64()
            .max(1.0) as u64;
        let capped = target.min(horizon.saturating_add(max_step));
        // After a gap the history restarted: the capped horizon is no longer
        // readable, jump to the target (the EKF grows P over the gap).
        if capped < oldest {
            Some(target)
        } else {
            Some(capped)
        }
    }

    /// The horizon: the newest instant read from the history (the horizon
    /// EKF's time, or later by the samples accumulated for its next step).
    fn horizon_us(&self) -> Option<u64> {
        self.deltas.end_us().max(self.ekf.time_us())
    }

    /// Moves the horizon to `t_h` with the history read at eq. (15)'s
    /// delays. The sample goes to the horizon EKF at once when it predicts
    /// at every sample (or is not initialized), else into the accumulated
    /// step, which the EKF predicts over when it spans the filter period
    /// (to half an IMU step) or when `force` asks for the EKF at `t_h` (a
    /// fix to fuse). True when the EKF's time moved.
    fn step_horizon(&mut self, t_us: u64, t_h: u64, force: bool) -> bool {
        let (d_f, d_w) = self.group_delays_s();
        let us = |d: T| (d * T::lit(1e6)).round().as_f64().max(0.0) as u64;
        // The whitened streams at t_h + D (the raw sensors' t_h), by time.
        let (times, history, headers) = (&self.times, &self.history, &mut self.history_headers);
        let mut read = |at_us: u64| {
            let d = times.delay_samples::<T>(at_us.min(t_us))?;
            history.read::<HISTORY_ORDER>(d, headers).ok()
        };
        // Equal group delays (pass-through whitening): one read holds both.
        let a = read(t_h + us(d_f));
        let (w, reads) = if d_w == d_f {
            (a, 1)
        } else {
            (read(t_h + us(d_w)), 2)
        };
        self.interpolation_taps += reads * (HISTORY_ORDER as u64 + 1);
        let (Some(a), Some(w)) = (a, w) else {
            return false;
        };
        let sample = Imu {
            t_us: t_h,
            gyro_rad_s: w.fixed_rows::<3>(3).into_owned(),
            accel_m_s2: a.fixed_rows::<3>(0).into_owned(),
        };
        let step_us = self
            .deltas
            .end_us()
            .map_or(0, |end| t_h.saturating_sub(end));
        let every_sample = self.filter_period_us == 0 || !self.ekf.is_initialized();
        if every_sample || step_us > self.config.ekf.max_imu_step_us {
            // A gap is one step of its own (the EKF grows P over it).
            let flushed = self.flush_deltas();
            self.fuse_due_mags();
            match self.ekf.push_imu(&sample) {
                Ok(()) => self.horizon_steps += 1,
                Err(_) => bump(&mut self.refusals.horizon_refused),
            }
            self.deltas.restart(&sample);
            return flushed || self.ekf.time_us() == Some(t_h);
        }
        self.deltas.push(&sample);
        let due = self.deltas.elapsed_us().saturating_add(step_us / 2) >= self.filter_period_us;
        (force || due) && self.flush_deltas()
    }

    /// Predicts the horizon EKF over the accumulated step; true when it
    /// moved the EKF's time.
    fn flush_deltas(&mut self) -> bool {
        let before = self.ekf.time_us();
        let Some(deltas) = self.deltas.take() else {
            return false;
        };
        // Samples due at the EKF's present time are fused before it moves.
        self.fuse_due_mags();
        match self.ekf.push_imu_deltas(&deltas) {
            Ok(()) => self.horizon_steps += 1,
            Err(_) => bump(&mut self.refusals.horizon_refused),
        }
        self.ekf.time_us() != before
    }

    /// Steps the horizon to the instant a fix received at `t_fix` describes,
    /// `t_fix - tau`, when that lies between the horizon and the newest IMU
    /// sample's horizon target (a fix arriving between IMU samples), and
    /// brings the horizon EKF to the horizon: the fix is then fused at its
    /// own instant, not up to one IMU step early or one filter step late.
    fn advance_horizon_to_fix(&mut self, t_fix_us: u64) {
        let (Some(last), Some(horizon)) = (self.last_imu, self.horizon_us()) else {
            return;
        };
        if let Some(target) = t_fix_us.checked_sub(self.delay_us())
            && target > horizon
            && target <= last.t_us
        {
            self.step_horizon(last.t_us, target, true);
        }
        if self.flush_deltas() || self.ekf.time_us() != Some(horizon) {
            self.horizon_moved();
        }
    }

    /// After the horizon EKF moved: the magnetometer samples it reached are
    /// fused at the next IMU sample ([`fuse_due_mags`](Self::fuse_due_mags)),
    /// not in the same call as the prediction (or a GPS fusion): the EKF does
    /// not move before then, so they are fused at the same state time, and
    /// no single call does a prediction, a GPS and a magnetometer fusion.
    /// Before initialization they go to the EKF at once (the alignment waits
    /// for them).
    fn horizon_moved(&mut self) {
        if self.ekf.is_initialized() {
            self.mags_due = true;
        } else {
            self.drain_mags();
        }
    }

    /// Fuses the magnetometer samples the horizon EKF reached at its last
    /// move; true when there were some to look at.
    fn fuse_due_mags(&mut self) -> bool {
        if !self.mags_due {
            return false;
        }
        self.mags_due = false;
        self.drain_mags();
        true
    }

    /// Right after the horizon EKF initialized itself from a fix: when the
    /// vehicle was moving faster than [`MOVING_SPEED_M_S`] (an in-flight
    /// start, a reset in flight) the accelerometer is probably not the vertical, so the tilt variance is raised to
    /// [`MOVING_TILT_STD_RAD`] for the GPS velocity to resolve it; after a
    /// [`reset`](Self::reset) the IMU biases and their variances are carried
    /// over. The EKF is rebuilt from its own state (same time and origin).
    fn refine_alignment(&mut self, speed_m_s: T) {
        let moving = speed_m_s > T::lit(MOVING_SPEED_M_S);
        let retained = self.retained_biases.take();
        if !moving && retained.is_none() {
            return;
        }
        let (Some(mut x), Some(t_us)) = (self.ekf.nav_state(), self.ekf.time_us()) else {
            return;
        };
        let mut p = *self.ekf.covariance();
        if moving {
            let c = &self.config.ekf;
            let tilt = T::lit(MOVING_TILT_STD_RAD).max(c.initial_tilt_std_rad);
            let yaw = if self.mag_at_horizon {
                c.initial_yaw_std_rad
            } else {
                c.initial_yaw_std_no_mag_rad
            };
            p.fixed_view_mut::<4, 4>(QUAT, QUAT)
                .copy_from(&attitude_covariance(&x.attitude, tilt, tilt, yaw));
        }
        if let Some((biases, variances)) = retained {
            x.accel_bias_m_s2 = biases.fixed_rows::<3>(0).into_owned();
            x.gyro_bias_rad_s = biases.fixed_rows::<3>(3).into_owned();
            for i in 0..3 {
                for j in 0..16 {
                    for k in [ACCEL_BIAS + i, GYRO_BIAS + i] {
                        p[(k, j)] = T::zero();
                        p[(j, k)] = T::zero();
                    }
                }
                p[(ACCEL_BIAS + i, ACCEL_BIAS + i)] = variances[i];
                p[(GYRO_BIAS + i, GYRO_BIAS + i)] = variances[3 + i];
            }
        }
        let mut config = self.config.ekf;
        if let Some(frame) = self.ekf.frame() {
            config.origin = Some(frame.origin());
        }
        // In place (this runs in a push): the old filter's counters are
        // kept; on error nothing changed.
        let refusals = self.ekf_refusals();
        if self.ekf.configure_from_state(config, t_us, &x, &p).is_ok() {
            self.replaced_ekf_refusals = refusals;
        }
    }

    /// Fuses the queued magnetometer samples the horizon has reached.
    fn drain_mags(&mut self) {
        let Some(horizon) = self.ekf.time_us() else {
            return;
        };
        while let Some(m) = self.mags.oldest() {
            if m.t_us > horizon {
                break;
            }
            self.mags.pop_oldest();
            self.mag_at_horizon = true;
            // Refusals (gate, time) are counted by the EKF.
            let _ = self.ekf.push_mag(&Mag {
                t_us: m.t_us,
                field_body: m.field_body,
            });
        }
    }

    /// Brings the horizon state to the present (starts the output state on
    /// the first call after the EKF initialized).
    fn correct_present(&mut self) {
        let (Some(t_h), Some(last)) = (self.ekf.time_us(), self.last_imu) else {
            return;
        };
        if !self.ekf.is_initialized() {
            return;
        }
        let x_h = *self.ekf.state_vector();
        if !self.forward.is_started() {
            self.forward
                .start(&x_h, last.t_us, &last.gyro_rad_s, &last.accel_m_s2);
        }
        self.forward.correct(t_h, &x_h);
    }

    /// The horizon EKF's time, velocity and covariance before a fusion.
    fn horizon_prior(&self) -> Option<HorizonPrior<T>> {
        if !self.ekf.is_initialized() {
            return None;
        }
        let x = self.ekf.state_vector();
        let p = self.ekf.covariance();
        Some(HorizonPrior {
            t_us: self.ekf.time_us()?,
            velocity: x.fixed_rows::<3>(VEL).into_owned(),
            covariance: core::array::from_fn(|i| {
                [
                    p[(POS + i, POS + i)],
                    p[(POS + i, VEL + i)],
                    p[(VEL + i, VEL + i)],
                ]
            }),
        })
    }

    /// Gives the delay loop the horizon's record of a fused fix (the
    /// innovation observation of the delay, `delay::innovation`): per axis
    /// the prior position-velocity covariance, the noises recovered from
    /// the innovation variances (position is fused first: `S_p = P_pp +
    /// R_p`; velocity after it: `S_v = P_vv - P_pv^2 / S_p + R_v`), the
    /// position innovation and the velocity's against the prior state.
    fn push_horizon_fix(
        &mut self,
        fix: &Gps<T>,
        prior: &HorizonPrior<T>,
        position: &FusionRecord<T, 3>,
        velocity: &FusionRecord<T, 3>,
        reset: bool,
    ) {
        let Some(x) = self.ekf.nav_state() else {
            return;
        };
        let (d_f, _) = self.group_delays_s();
        // Either sign: a negative delay puts the horizon after the fix.
        let delay_us = fix.t_us as f64 - prior.t_us as f64;
        let delay_s = T::lit(delay_us * 1e-6) - d_f;
        let tiny = T::lit(1e-12);
        let horizon_fix = HorizonFix {
            horizon_us: prior.t_us,
            delay_s,
            velocity_prior: prior.velocity,
            velocity_post: x.velocity_ned_m_s,
            covariance: prior.covariance,
            noise: core::array::from_fn(|i| {
                let [p_pp, p_pv, p_vv] = prior.covariance[i];
                let s_p = position.innovation_variance[i];
                let s_v = velocity.innovation_variance[i];
                let r_p = (s_p - p_pp).max(tiny);
                let r_v = (s_v - p_vv + p_pv * p_pv / s_p.max(tiny)).max(tiny);
                [r_p, r_v]
            }),
            innovation: core::array::from_fn(|i| {
                [
                    position.innovation[i],
                    fix.velocity_ned_m_s[i] - prior.velocity[i],
                ]
            }),
            fused: [position.fused, velocity.fused],
            reset,
        };
        self.delay_loop.push_horizon_fix(&horizon_fix);
    }

    /// Gives the waiting fix (if any) to the delay loop: the peak search
    /// and the gain fusion, kept out of the call that fuses the fix.
    fn update_delay(&mut self) {
        let Some((t_us, velocity, _)) = self.pending_delay_fix.take() else {
            return;
        };
        match self.delay_loop.push_gps(t_us, velocity) {
            Ok(Some(update)) => {
                if update.axes.iter().any(|a| a.valid) {
                    self.valid_delay_updates = self.valid_delay_updates.saturating_add(1);
                }
                self.last_update = ZeroOption::Some(update);
            }
            Ok(None) => {}
            Err(_) => bump(&mut self.refusals.delay_loop_refused),
        }
    }

    fn check_imu(&mut self, imu: &(impl ImuSample<T> + ?Sized)) -> Result<Imu<T>, Error> {
        let s = checked_imu(imu).inspect_err(|_| bump(&mut self.refusals.imu_non_finite))?;
        let c = &self.config.ekf;
        if s.gyro_rad_s.iter().any(|v| v.abs() > c.max_gyro_rad_s)
            || s.accel_m_s2.iter().any(|v| v.abs() > c.max_accel_m_s2)
        {
            bump(&mut self.refusals.imu_out_of_range);
            return Err(Error::OutOfRange {
                field: "imu",
                reason: "above the configured max_gyro_rad_s or max_accel_m_s2",
            });
        }
        let max_jump = self.config.max_time_jump_us;
        counted(
            self.imu_clock
                .check("imu", "imu.time", s.t_us, None, max_jump),
            &mut self.refusals.imu_ahead,
            &mut self.refusals.imu_time,
        )?;
        Ok(s)
    }
}

/// The horizon EKF before a GPS fusion: its time (us), velocity (NED, m/s)
/// and, per axis, `[P_pp, P_pv, P_vv]`.
#[derive(Debug, Clone, Copy)]
struct HorizonPrior<T: Scalar> {
    t_us: u64,
    velocity: Vector3<T>,
    covariance: [[T; 3]; 3],
}

impl<T: Scalar, const HIST: usize> Navigator<T> for DelayCompensatedNav<T, HIST> {
    /// One IMU sample through the five steps of the module docs. Refused,
    /// state unchanged: non-finite, implausible, not later than the previous
    /// sample. A gap longer than the EKF's `max_imu_step_us` restarts the
    /// history and returns [`Error::StepTooLong`] after keeping the sample.
    fn push_imu<I: ImuSample<T> + ?Sized>(&mut self, imu: &I) -> Result<(), Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let s = self.check_imu(imu)?;
        let dt_us = self.last_imu.map_or(0, |p| s.t_us - p.t_us);
        let max_step = self.config.ekf.max_imu_step_us;
        let gap = dt_us > max_step;
        // A step the history's sample times cannot hold (8.1 s at 530
        // samples) restarts the history too (the EKF integrates it as usual).
        if gap || dt_us >= SampleTimes::<HIST>::MAX_STEP_US {
            bump(&mut self.refusals.imu_gap);
            self.last_reset = ZeroOption::Some(ResetRecord {
                t_us: Some(s.t_us),
                cause: ResetCause::ImuGap,
            });
            self.history.clear();
            self.times.clear();
            self.accel_whitening.reset();
            self.gyro_whitening.reset();
        }
        let accel = self.accel_whitening.filter(s.accel_m_s2);
        let gyro = self.gyro_whitening.filter(s.gyro_rad_s);
        let mut channels = SVector::<T, 6>::zeros();
        channels.fixed_rows_mut::<3>(0).copy_from(&accel);
        channels.fixed_rows_mut::<3>(3).copy_from(&gyro);
        // Finite and bounded by the checks above: the history cannot refuse it.
        let _ = self.history.push(channels);
        if self.times.push(s.t_us) {
            // A ninth long step within the span: the oldest times forgotten.
            bump(&mut self.refusals.imu_gap);
        }
        self.imu_samples += 1;

        if self.forward.is_started() {
            if gap {
                self.forward.hold(s.t_us, &s.gyro_rad_s, &s.accel_m_s2);
            } else {
                let g = self.config.ekf.gravity_m_s2;
                self.forward.step(s.t_us, &s.gyro_rad_s, &s.accel_m_s2, g);
            }
        }
        self.last_imu = Some(s);

        let stepped = self
            .horizon_target(s.t_us, dt_us)
            .is_some_and(|t_h| self.step_horizon(s.t_us, t_h, false));
        let mut busy = stepped;
        if stepped {
            self.horizon_moved();
            self.correct_present();
        } else if self.fuse_due_mags() {
            busy = true;
            self.correct_present();
        }

        if self.forward.is_started() {
            let (x, _) = self.forward.state();
            let rot = rotation_matrix(&quaternion_of(x));
            let bias = x.fixed_rows::<3>(ACCEL_BIAS).into_owned();
            let gravity = Vector3::new(T::zero(), T::zero(), self.config.ekf.gravity_m_s2);
            self.present_accel = rot * (s.accel_m_s2 - bias) + gravity;
            if self.is_estimating() {
                let a_fwd = rot * (accel - bias) + gravity;
                if self.delay_loop.push_imu(s.t_us, a_fwd).is_err() {
                    bump(&mut self.refusals.delay_loop_refused);
                }
            }
        }
        if let Some((_, _, waited)) = &mut self.pending_delay_fix {
            *waited += 1;
            if !busy || *waited >= DELAY_UPDATE_MAX_WAIT {
                self.update_delay();
            }
        }
        if gap {
            return Err(Error::StepTooLong {
                dt_us,
                max_us: max_step,
            });
        }
        Ok(())
    }

    /// Fuses the fix at the horizon at once; its velocity goes to the delay
    /// loop at a later IMU sample (module docs). Refused, state unchanged: invalid values,
    /// a velocity beyond the loop's plausible range, time not increasing.
    fn push_gps<G: GpsFix<T> + ?Sized>(&mut self, gps: &G) -> Result<GpsOutcome<T>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let fix = checked_gps(gps).inspect_err(|e| {
            bump(&mut self.refusals.gps_invalid);
            if let Error::NonFinite { field } | Error::OutOfRange { field, .. } = e
                && field.ends_with("accuracy")
            {
                bump(&mut self.refusals.gps_accuracy);
            }
        })?;
        if fix
            .velocity_ned_m_s
            .iter()
            .any(|v| v.abs() > T::lit(MAX_INPUT_MAGNITUDE))
        {
            bump(&mut self.refusals.gps_invalid);
            return Err(Error::OutOfRange {
                field: "gps.velocity",
                reason: "beyond the plausible range",
            });
        }
        let geodetic = check_position_kind(self.geodetic_fixes.get(), &fix.position)
            .inspect_err(|_| bump(&mut self.refusals.gps_mixed_frames))?;
        let newest_imu = self.imu_clock.last();
        let max_jump = self.config.max_time_jump_us;
        let mut clock = self.gps_clock;
        counted(
            clock.check(
                "gps",
                "gps.time",
                fix.t_us,
                newest_imu.or(Some(fix.t_us)),
                max_jump,
            ),
            &mut self.refusals.gps_ahead,
            &mut self.refusals.gps_time,
        )?;
        self.advance_horizon_to_fix(fix.t_us);
        if !self.ekf.is_initialized() && self.mag_clock.last().is_some() && !self.mag_at_horizon {
            // Alignment waits for what it sets: the heading needs a
            // magnetometer sample at the horizon, one delay after it arrived.
            self.gps_clock = clock;
            return Ok(GpsOutcome::Waiting);
        }
        let resets_before = self.ekf.last_gps_reset();
        let innovations = self.delay_loop.config().innovation_window_s > T::zero();
        let prior = if innovations {
            self.horizon_prior()
        } else {
            None
        };
        let (timing_variance_s2, accel) = self.gps_timing_noise();
        let outcome = self
            .ekf
            .push_gps_with_timing_noise(&fix, timing_variance_s2, &accel)?;
        if let (Some(t_us), Some(x)) = (self.ekf.time_us(), self.ekf.nav_state()) {
            self.last_fix_velocity = Some((t_us, x.velocity_ned_m_s));
        }
        let reset = self.ekf.last_gps_reset() != resets_before;
        if self.is_estimating()
            && let (Some(prior), GpsOutcome::Fused { position, velocity }) = (prior, outcome)
        {
            self.push_horizon_fix(&fix, &prior, &position, &velocity, reset);
        }
        if let Some(reset) = self.ekf.last_gps_reset()
            && resets_before != Some(reset)
        {
            self.last_reset = ZeroOption::Some(ResetRecord {
                t_us: self.imu_clock.last(),
                cause: ResetCause::Gps(reset),
            });
        }
        self.gps_clock = clock;
        self.geodetic_fixes = ZeroOption::Some(geodetic);
        if self.is_estimating() {
            // The loop's update waits for a lighter IMU sample (bounded
            // work per call); a fix still waiting goes first.
            self.update_delay();
            self.pending_delay_fix = Some((fix.t_us, fix.velocity_ned_m_s, 0));
        }
        if outcome == GpsOutcome::Initialized {
            self.refine_alignment(fix.velocity_ned_m_s.norm());
        }
        if matches!(outcome, GpsOutcome::Initialized | GpsOutcome::Fused { .. }) {
            self.correct_present();
        }
        Ok(outcome)
    }

    /// Queues the sample until the horizon reaches its time (module docs).
    /// Refused, state unchanged: non-finite or zero field, time not increasing.
    fn push_mag<M: MagSample<T> + ?Sized>(&mut self, mag: &M) -> Result<MagOutcome<T>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let m = checked_mag(mag).inspect_err(|_| bump(&mut self.refusals.mag_invalid))?;
        let newest_imu = self.imu_clock.last().or(Some(m.t_us));
        let max_jump = self.config.max_time_jump_us;
        counted(
            self.mag_clock
                .check("mag", "mag.time", m.t_us, newest_imu, max_jump),
            &mut self.refusals.mag_ahead,
            &mut self.refusals.mag_time,
        )?;
        if self.mags.len() <= MAG_QUEUE / 4 {
            self.mag_spacing_us = 0;
        }
        let m = QueuedMag::new(m);
        if let Some(newest) = self.mags.get(0)
            && m.t_us < self.mag_newest_start_us.saturating_add(self.mag_spacing_us)
        {
            self.mags.replace_newest(newest.averaged_with(m));
            bump(&mut self.refusals.mag_averaged);
            return Ok(MagOutcome::Queued);
        }
        if self.mags.len() == MAG_QUEUE {
            let averaged = average_pairs(&mut self.mags);
            self.refusals.mag_averaged = self.refusals.mag_averaged.saturating_add(averaged);
            if let (Some(oldest), Some(newest)) = (self.mags.oldest(), self.mags.get(0)) {
                let gaps = (self.mags.len() as u64).saturating_sub(1).max(1);
                self.mag_spacing_us = (newest.t_us - oldest.t_us) / gaps;
            }
        }
        self.mags.push(m);
        self.mag_newest_start_us = m.t_us;
        Ok(MagOutcome::Queued)
    }

    /// The present solution: attitude, position and velocity at the newest
    /// IMU sample; biases and covariance are the horizon EKF's. `None` until
    /// the first correction has reached the present (module docs).
    fn estimate(&self) -> Option<Estimate<T>> {
        if !(self.configured && self.forward.is_ready()) {
            return None;
        }
        let horizon = self.ekf.estimate()?;
        let (x, t_us) = self.forward.state();
        Some(self.with_delay(Estimate {
            t_us,
            attitude: UnitQuaternion::new_normalize(quaternion_of(x)),
            position_ned_m: x.fixed_rows::<3>(POS).into_owned(),
            velocity_ned_m_s: x.fixed_rows::<3>(VEL).into_owned(),
            accel_bias_m_s2: x.fixed_rows::<3>(ACCEL_BIAS).into_owned(),
            gyro_bias_rad_s: x.fixed_rows::<3>(GYRO_BIAS).into_owned(),
            ..horizon
        }))
    }
}

#[cfg(test)]
mod queue_tests {
    use super::*;

    fn sample<T: Scalar>(t_us: u64, x: f64) -> QueuedMag<T> {
        QueuedMag::new(Mag {
            t_us,
            field_body: Vector3::new(T::lit(x), T::one(), T::zero()),
        })
    }

    /// A full queue of 5 samples (odd: the oldest stays alone) becomes 3,
    /// each the mean of its pair at the pair's mean time; a pair and a
    /// single sample average with weights 2 and 1.
    fn pairs_are_averaged<T: Scalar>() {
        let mut ring = Ring::<QueuedMag<T>, 5>::new(sample(0, 0.0));
        for k in 0..5u32 {
            ring.push(sample(100 * u64::from(k), f64::from(k)));
        }
        assert_eq!(average_pairs(&mut ring), 2);
        let kept: Vec<_> = (0..ring.len())
            .rev()
            .filter_map(|age| ring.get(age))
            .collect();
        assert_eq!(
            kept.iter().map(|m| m.t_us).collect::<Vec<_>>(),
            [0, 150, 350]
        );
        assert_eq!(
            kept.iter().map(|m| m.samples).collect::<Vec<_>>(),
            [1, 2, 2]
        );
        let x: Vec<f64> = kept.iter().map(|m| m.field_body.x.as_f64()).collect();
        assert_eq!(x, [0.0, 1.5, 3.5]);
        let three = kept[2].averaged_with(sample(500, 6.5));
        assert_eq!((three.t_us, three.samples), (400, 3));
        assert_eq!(three.field_body.x.as_f64(), 4.5);
        assert_eq!(three.field_body.y.as_f64(), 1.0);
    }

    #[test]
    fn pairs_are_averaged_f32() {
        pairs_are_averaged::<f32>();
    }

    #[test]
    fn pairs_are_averaged_f64() {
        pairs_are_averaged::<f64>();
    }
}
