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
//! # Where each part lives
//!
//! | file | its one job |
//! |---|---|
//! | `mod.rs` | the navigator's state, its construction (`new`, `BLANK`, `configure`) and read-outs |
//! | `config.rs` | [`DelayCompensatedNavConfig`], [`DelayMode`], [`WhiteningFilter`] and their validation |
//! | `input.rs` | every sample checked, timed and counted; the steps of one IMU sample, a fix, a magnetometer sample |
//! | `timeline.rs` | the history's sample times (reads by time) and each stream's clock checks |
//! | `whitening.rs` | the optional whitening FIR of each IMU stream and its group delay |
//! | `horizon.rs` | the delayed horizon: its target, its steps through the history, the fix's instant, the correction of the present |
//! | `forward.rs` | the output predictor: the present reckoned forward from the horizon in `O(1)` |
//! | `mag_queue.rs` | magnetometer samples waiting for the horizon, averaged when the queue is full, fused when reached |
//! | `delay_feedback.rs` | the delay loop's side: the delay and eq. 15's per-sensor delays, what each fix gives the loop, the GPS noise of the delay's uncertainty |
//! | `alignment.rs` | control apart from fusion: the start-up state, an alignment refined in motion or after a reset, the reset itself |
//! | `health.rs` | [`Health`]: what the navigator can vouch for, flag by flag |
//! | `refusals.rs` | [`NavRefusals`] and [`NavWork`]: refusals per sensor and reason, work done |
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
//! ([`GpsOutcome::Fused`](crate::estimate::GpsOutcome::Fused)). A fix that arrives between IMU
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
//! ([`MagOutcome::Queued`](crate::estimate::MagOutcome::Queued)) and are fused by the horizon EKF as soon as its
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
//! horizon, fixes are answered [`GpsOutcome::Waiting`](crate::estimate::GpsOutcome::Waiting); when the aligning
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

mod alignment;
mod config;
mod delay_feedback;
mod forward;
mod health;
mod horizon;
mod input;
mod mag_queue;
mod refusals;
mod timeline;
mod whitening;
pub mod yaw_gsf;

#[cfg(test)]
mod memory;

pub use config::{DelayCompensatedNavConfig, DelayMode, WhiteningFilter};
pub use health::{
    AlignmentState, DelayHealth, GPS_STALE_US, HEADING_STALE_US, Health, MAX_POSITION_STD_M,
    MAX_VELOCITY_STD_M_S, ResetCause, ResetRecord,
};
pub use refusals::{NavRefusals, NavWork};
pub use yaw_gsf::{YAW_GSF_MODELS, YawGsf, YawGsfHealth};

use crate::delay::packed::{HeaderCache, PackedRing};
use crate::delay::ring::Ring;
use crate::delay::{DefaultDelayLoop, DelayUpdate};
use crate::ekf16::delta::DeltaAccumulator;
use crate::ekf16::{Ekf16, FilterRefusals};
use crate::error::{Bound, ConfigPath, Error, Section};
use crate::estimate::{Estimate, Navigator};
use crate::scalar::{Scalar, zeros_const};
use crate::sensors::Imu;
use crate::zero_option::ZeroOption;
use forward::ForwardReckoner;
use mag_queue::QueuedMag;
use nalgebra::{SVector, Vector3};
use timeline::{SampleTimes, StreamClock};
use whitening::Whitening;

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
/// spans the largest delay (14 samples at 1 kHz and 0.5 s, 28 at the default
/// 1 s range; 32 entries, 35 samples apart, cost the `high` scenario's roll
/// 3 %: docs/journal/2026-11-25-ram-history-and-capacities.md), and sooner
/// while the vehicle turns fast, into slots no interpolation can use again.
pub const OUTPUT_ENTRIES: usize = 39;

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

/// Consecutive fused fixes at which the converged yaw estimator and the
/// horizon filter must disagree (by more than [`GSF_DISAGREEMENT_RAD`] and
/// three standard deviations of their difference) before the horizon
/// filter's heading is reset to the estimator's (1 s at 10 Hz).
pub const GSF_DISAGREEMENT_FIXES: u8 = 10;
/// Longest step of the yaw estimator's prediction, µs (20 Hz): the horizon
/// filter's steps are added up until then (and until a fix is fused).
pub const GSF_PREDICT_PERIOD_US: u64 = 50_000;
/// Least heading disagreement that counts towards a reset, rad (15 deg).
pub const GSF_DISAGREEMENT_RAD: f64 = 0.2618;
/// Heading standard deviation of the horizon filter above which, after an
/// alignment made in motion, with no recent magnetometer update and until
/// the yaw estimator has converged, its heading counts as unknown, rad: the
/// estimator's own convergence threshold (15 deg). GPS fixes then correct
/// the position and the velocity alone; the converged estimator sets the
/// heading at once if the two disagree (`alignment.rs`).
pub const HEADING_UNKNOWN_STD_RAD: f64 = yaw_gsf::CONVERGED_YAW_STD_RAD;
/// Delay standard deviation above which, after an alignment made in motion
/// with no recent magnetometer update, the GPS fixes correct the position
/// and the velocity alone, s (30 ms: 0.3 m/s of velocity in a 10 m/s^2
/// manoeuvre, the order of a fix's own velocity noise).
pub const DELAY_KNOWN_STD_S: f64 = 0.03;

/// The smallest history `HIST` (IMU samples) that
/// [`DelayCompensatedNav::configure`] accepts for delays up to
/// `max_delay_s` (s) at `imu_rate_hz` (Hz), for a navigator of either
/// precision: `ceil(max_delay_s x imu_rate_hz x 1.02) + HISTORY_ORDER + 2`
/// (2 % for an IMU faster than nominal; the cubic reads need
/// `HISTORY_ORDER + 2` more samples).
///
/// `max_delay_s` is the configuration's `delay_loop.fusion.delay_max_s`
/// (the largest delay, in estimated and fixed mode alike), plus the larger
/// group delay of the IMU whitening filters when they are configured.
/// `configure` checks in the navigator's precision; this takes the larger
/// of the `f64` and the `f32` results, which differ by one sample where
/// rounding lands the product on either side of an integer. A `const fn`,
/// to size a `static` navigator:
///
/// ```
/// use delaynav::{DelayCompensatedNav, history_len};
///
/// const HIST: usize = history_len(0.4, 1000.0); // 0.4 s at 1 kHz
/// assert_eq!(HIST, 413);
/// static NAV: DelayCompensatedNav<f32, HIST> = DelayCompensatedNav::BLANK;
/// ```
pub const fn history_len(max_delay_s: f64, imu_rate_hz: f64) -> usize {
    let in_f64 = ceil_samples(max_delay_s * imu_rate_hz * RATE_MARGIN);
    let in_f32 =
        ceil_samples((max_delay_s as f32 * imu_rate_hz as f32 * RATE_MARGIN as f32) as f64);
    let samples = if in_f64 > in_f32 { in_f64 } else { in_f32 };
    samples.saturating_add(HISTORY_ORDER + 2)
}

/// `ceil(x)` as a count (0 for a negative or NaN `x`, saturated for a huge
/// one). `f64::ceil` is not a `const fn` at the crate's minimum Rust; the
/// cast truncates toward zero and saturates.
const fn ceil_samples(x: f64) -> usize {
    let whole = x as usize;
    if (whole as f64) < x {
        whole.saturating_add(1)
    } else {
        whole
    }
}

/// IMU samples a fix's velocity waits at most for the delay loop: its
/// correlation update runs at the first IMU sample after the fix that
/// neither steps the horizon filter nor fuses the magnetometer, at the
/// latest at this many samples (a filter at the IMU rate steps at every one).
pub const DELAY_UPDATE_MAX_WAIT: u32 = 3;

/// The delay-compensated GPS/IMU navigator of the paper (Figure 1); see the
/// module docs. `HIST` is the IMU history in samples.
///
/// ```
/// use delaynav::nav::{DelayCompensatedNav, DelayMode, DelayCompensatedNavConfig};
/// use delaynav::{Gps, GpsPosition, Imu, Navigator};
/// use nalgebra::Vector3;
///
/// // At rest at 100 Hz; the GPS is 0.1 s late (a calibrated receiver).
/// let mut config = DelayCompensatedNavConfig::<f64>::default();
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
    config: DelayCompensatedNavConfig<T>,
    ekf: Ekf16<T>,
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
    /// The horizon filter was aligned in motion ([`MOVING_SPEED_M_S`]): an
    /// in-flight start or a reset in flight (`alignment.rs`).
    aligned_moving: bool,
    /// The yaw estimator has converged since that alignment (agreeing with
    /// the horizon filter or setting its heading).
    heading_checked: bool,
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
    /// End of the newest IMU gap (the first sample after it), µs; 0 before any. Until the
    /// horizon filter's time reaches it the present is past a gap the horizon has not
    /// crossed, and its levels take the gap's growth (`health.rs`).
    imu_gap_end_us: u64,
    /// The yaw estimator run from the horizon filter's predictions and the
    /// fused fixes (`yaw_gsf.rs`, `alignment.rs`).
    yaw_gsf: YawGsf<T>,
    /// The horizon filter's predictions since the yaw estimator's last:
    /// heading-frame delta velocity (m/s), yaw change (rad), time (µs).
    gsf_step: ([T; 2], T, u32),
    /// Headings set from the yaw estimator (saturates).
    gsf_yaw_resets: u16,
    /// Fixes fused into the position and velocity alone (saturates;
    /// `alignment.rs`).
    fixes_position_velocity_only: u16,
    /// Consecutive fixes at which the converged estimator and the horizon
    /// filter disagreed ([`GSF_DISAGREEMENT_FIXES`]).
    gsf_disagreements: u8,
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
    pub fn new(config: DelayCompensatedNavConfig<T>) -> Result<Self, Error> {
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
    /// use delaynav::nav::{AlignmentState, DelayCompensatedNav, DelayCompensatedNavConfig};
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
    ///     let mut config = DelayCompensatedNavConfig::default();
    ///     config.delay_loop.fusion.delay_max_s = 0.5;
    ///     nav.configure(config)?; // in place: a small stack
    ///     nav.push_imu(&imu)?;
    ///     assert_eq!(nav.health().alignment, AlignmentState::WaitingForImu);
    ///     Ok::<(), Error>(())
    /// })?;
    /// # Ok::<(), Error>(())
    /// ```
    pub const BLANK: Self = Self {
        config: DelayCompensatedNavConfig::ZEROED,
        ekf: Ekf16::BLANK,
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
        mags: Ring::new(QueuedMag::BLANK),
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
        aligned_moving: false,
        heading_checked: false,
        geodetic_fixes: ZeroOption::None,
        last_update: ZeroOption::None,
        pending_delay_fix: None,
        last_fix_velocity: None,
        present_accel: zeros_const(),
        imu_gap_end_us: 0,
        yaw_gsf: YawGsf::BLANK,
        gsf_step: ([T::ZERO; 2], T::ZERO, 0),
        gsf_yaw_resets: 0,
        fixes_position_velocity_only: 0,
        gsf_disagreements: 0,
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
    pub fn configure(&mut self, config: DelayCompensatedNavConfig<T>) -> Result<(), Error> {
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
                    short_by: (needed as usize).saturating_sub(HIST) as u32,
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
        self.aligned_moving = false;
        self.heading_checked = false;
        self.geodetic_fixes = ZeroOption::None;
        self.last_update = ZeroOption::None;
        self.pending_delay_fix = None;
        self.last_fix_velocity = None;
        self.present_accel = Vector3::zeros();
        self.imu_gap_end_us = 0;
        self.yaw_gsf = YawGsf::BLANK;
        self.gsf_step = ([T::zero(); 2], T::zero(), 0);
        self.gsf_yaw_resets = 0;
        self.fixes_position_velocity_only = 0;
        self.gsf_disagreements = 0;
        self.refusals = NavRefusals::default();
        self.imu_samples = 0;
        self.horizon_steps = 0;
        self.configured = true;
        Ok(())
    }

    /// The configuration (every field zero on a navigator not configured:
    /// see [`is_configured`](Self::is_configured)).
    pub fn config(&self) -> &DelayCompensatedNavConfig<T> {
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

    /// Samples refused, dropped or gated out, the horizon filter's among
    /// them ([`NavRefusals::horizon`]).
    pub fn refusals(&self) -> NavRefusals {
        NavRefusals {
            horizon: self.horizon_refusals(),
            forward_corrections_missed: self.forward.missed_corrections(),
            ..self.refusals
        }
    }

    /// The horizon filter's counters over the navigator's whole life: those
    /// of the filters it replaced (kept in `self.refusals.horizon`) and the
    /// current one's.
    fn horizon_refusals(&self) -> FilterRefusals {
        self.refusals.horizon.merged(self.ekf.refusals())
    }

    /// Work counters.
    pub fn work(&self) -> NavWork {
        NavWork {
            imu_samples: self.imu_samples,
            horizon_steps: self.horizon_steps,
            forward_propagations: self.forward.propagations(),
            interpolation_taps: self.interpolation_taps,
            ring_cursor_moves: self.forward.cursor_moves(),
            ring_early_entries: u64::from(self.forward.early_entries()),
            correlation_multiply_adds: self.delay_loop.multiply_adds(),
        }
    }

    /// Magnetometer samples waiting for the horizon.
    pub fn queued_mag_samples(&self) -> usize {
        self.mags.len()
    }
}
