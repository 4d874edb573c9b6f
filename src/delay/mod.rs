//! The GPS delay estimation loop (sec. 2.2.2-2.2.4, Figure 1).
//!
//! The GPS fix received at `t` describes the vehicle at `t - tau`. The loop
//! estimates `tau` by correlating two measurements of the same NED
//! acceleration:
//!
//! - `a_fwd(t) = R(q)(f - b_f) + [0, 0, g]`, the navigator's forward-reckoned
//!   acceleration from the IMU, at the present time (m/s^2, NED);
//! - `a_gps = (v_k - v_{k-n}) / (t_k - t_{k-n})` (eq. 14) from the GPS
//!   velocities, which lags it by `tau`.
//!
//! Data flow, with the module holding each step:
//!
//! ```text
//! a_fwd (IMU rate) ─► bin means ─► grid (Tc) ─► smoothing ─┐
//!                                                          ├─► sliding NCC per axis ─► peak z_i, V_i ─► GFA ─► tau
//! v_gps (GPS rate) ─► difference over n fixes ─► grid ─► smoothing ─┘      (correlation)                 (gain_fusion)
//! ```
//!
//! 1. Grid (`grid`): both streams are brought to a uniform correlation grid of
//!    period `Tc` (default 25 Hz) with their true timestamps; the GPS
//!    difference is time-stamped at the middle of its span, which accounts for
//!    its `n dt / 2` lag. Both go through the same smoothing, whose lag then
//!    cancels in the correlation.
//! 2. Correlation ([`SlidingCorrelator`]): eq. (13) per NED axis as a Pearson
//!    coefficient over a buffer of `B` grid samples (default 5 s) for every
//!    shift of the window `[tau_min, tau_max]` (default 0 to 1 s), updated by
//!    sliding sums; the peak is refined by a parabola; `z_i = s_peak Tc` (s).
//!    For slow GPS ([`DelayLoopConfig::matched_fix_intervals`]) the grid
//!    stream of the GPS is replaced by the fix intervals themselves: each GPS
//!    difference against the IMU mean over the same interval, shifted
//!    (`matched` module).
//! 3. Validity: `V_i = 1` when the peak is interior to the window, its value
//!    is at least `min_peak`, and the axis' IMU acceleration variance over the
//!    buffer is at least `min_accel_variance_m2_s4` (or at least
//!    [`SUSTAINED_MOTION_SHARE`] of it through the last
//!    [`SUSTAINED_MOTION_BUFFERS`] buffers): without motion the peak
//!    position says nothing about the delay.
//!    A valid axis more than 3 standard deviations of their difference from
//!    the best-measured axis of the same window is left out.
//! 4. Fusion ([`GainFusion`]): Table 2, corrected, once per GPS fix (or every
//!    `fixes_per_update` fixes), with `Q_f` and `R_i` derived per iteration
//!    from rate-independent settings, `R_i` scaled by each axis' motion, and
//!    a re-acquisition after a sustained disagreement (see
//!    [`DelayLoopConfig`]).
//! 5. Optional second observation ([`InnovationDelay`], off by default): the
//!    horizon filter's GPS innovations regressed on `-[v; a]`, the filter's
//!    absorption of the delay error tracked as a sensitivity, one window at
//!    a time fused into the GFA ([`DelayLoop::push_horizon_fix`]).
//!
//! | paper | implemented by |
//! |---|---|
//! | eq. (13), correlation per axis | [`SlidingCorrelator::push_y`], [`SlidingCorrelator::peaks`] |
//! | eq. (14), GPS acceleration and its `n dt / 2` lag | [`DelayLoop::push_gps`] (grid stage) |
//! | Table 2, GFA | [`GainFusion::step`] |
//! | validity `V_i` | [`DelayLoop::push_gps`] |
//! | eq. (15), per-sensor delays | [`SensorDelays::new`], [`DelayLoop::sensor_delays`] |
//! | sec. 2.2.4, Lagrange fractional delay | [`FractionalDelayLine::read`] |
//! | sec. 2.2.4, whitening FIR and its delay | [`WhiteningFir`], [`WhiteningFir::group_delay_s`] |
//! | sec. 2.2.2, Figure 3, offline calibration | [`OfflineCalibrator::calibrate`] |
//!
//! # Where each part lives
//!
//! | file | its one job |
//! |---|---|
//! | `mod.rs` | the [`DelayLoop`]'s state; [`SensorDelays`] (eq. 15) |
//! | `config.rs` | [`DelayLoopConfig`]: settings, defaults, validation, grid sizes, the low-GPS-rate adaptation |
//! | `delay_loop.rs` | the loop's data path: samples in, one measured and fused window per fix out |
//! | `tracking.rs` | control: a lock followed, re-acquired after a sustained disagreement, the range's edges watched, disagreeing axes and (below 3 Hz, once locked) outlying windows left out |
//! | `sigma.rs` | the reported standard deviation and the innovation windows as a second observation |
//! | `status.rs` | [`DelayStatus`] and each update's record ([`DelayUpdate`]) |
//! | `grid.rs`, `matched.rs` | both streams on the correlation grid; fix intervals matched for slow GPS |
//! | `correlation.rs` | eq. (13): the sliding normalized correlation per axis and its peak |
//! | `gain_fusion.rs` | Table 2: the gain-fusion algorithm |
//! | `innovation.rs` | the delay from the horizon filter's GPS innovations |
//! | `fractional_delay.rs`, `fir.rs` | sec. 2.2.4: Lagrange fractional delay, whitening FIR |
//! | `calibration.rs` | sec. 2.2.2: the offline calibration |
//! | `packed.rs`, `ring.rs` | fixed-size buffers (16-bit block floating point, ring) |
//!
//! # The shift window spans the delay range
//!
//! The window of shifts is the whole configured delay range, fixed, rather
//! than a window centred on the current estimate. Fixed shifts are what makes
//! the sliding update exact (a moving window would need its sums rebuilt
//! whenever it moves), and a fixed window cannot lock onto a wrong peak by
//! following it. The default range `[0, 1] s` is the paper's 1 s window and
//! reaches well past the 0.58 s of the real log with 0.3 s added.
//!
//! # Which delay is estimated
//!
//! `tau` is the delay of the GPS relative to the stream fed to
//! [`DelayLoop::push_imu`]. When `a_fwd` is computed from the whitened
//! accelerometer, which lags the raw one by the FIR group delay `D_f`, the
//! estimate is `tau_f = tau_raw - D_f`, and eq. (15) gives the pure delays to
//! apply to each raw-sensor stream ([`SensorDelays`]):
//! accelerometer (filtered) `tau_f`, gyroscope (filtered) `tau_f + D_f - D_w`,
//! magnetometer (raw) `tau_f + D_f`; every stream then lags its raw sensor by
//! `tau_raw`, like the GPS.
//!
//! # Cost
//!
//! Per IMU sample: `O(1)` (a bin accumulation; one grid sample per `Tc`).
//! Per GPS fix: `Tgps / Tc` sliding steps of `3 L` products each and one peak
//! search of `3 L` coefficients, `L` the number of shifts: independent of the
//! delay and of the buffer length. No allocation: every buffer is a
//! const-generic array.

/// Fix intervals in a row, each more than a factor 1.5 off the configured GPS rate and within a
/// factor 1.25 of the previous one, before the loop follows the new rate
/// ([`DelayLoopConfig::follow_gps_rate`]).
pub const GPS_RATE_VOTES: u8 = 3;

/// An axis whose IMU acceleration variance over the buffer stays at least this share of
/// [`DelayLoopConfig::min_accel_variance_m2_s4`] for [`SUSTAINED_MOTION_BUFFERS`] buffer
/// lengths in a row is moving enough for `V_i` (docs/delay.md, section 3): a vehicle shuttling
/// gently (a rover, a boat) carries the delay in its sustained motion, where a drone's window at
/// the same variance is the onset or the end of a manoeuvre, whose peak the tilt error moves.
pub const SUSTAINED_MOTION_SHARE: f64 = 0.5;

/// Buffer lengths ([`DelayLoopConfig::buffer_s`]) an axis must keep moving at
/// [`SUSTAINED_MOTION_SHARE`] of the motion threshold, updates in a row, before its weaker
/// windows count: two, so that the window fused holds no onset of the motion.
pub const SUSTAINED_MOTION_BUFFERS: f64 = 2.0;

mod calibration;
mod config;
mod correlation;
mod delay_loop;
mod fir;
mod fractional_delay;
mod gain_fusion;
mod grid;
mod innovation;
mod matched;
pub(crate) mod packed;
pub(crate) mod ring;
mod sigma;
mod status;
mod tracking;

pub use calibration::{Calibration, CalibrationConfig, DefaultCalibrator, OfflineCalibrator};
pub use config::{
    CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4, CLEAN_INPUT_MIN_PEAK, DEFAULT_MIN_ACCEL_VARIANCE_M2_S4,
    DEFAULT_MIN_PEAK, DelayLoopConfig,
};
pub use correlation::{AxisPeak, PENDING_GPS_SAMPLES, SlidingCorrelator};
pub use fir::WhiteningFir;
pub use fractional_delay::{FractionalDelayLine, SamplePeriod};
pub use gain_fusion::{GainFusion, GainFusionConfig, GainFusionStep};
pub use grid::MAX_INPUT_MAGNITUDE;
pub use innovation::{HorizonFix, InnovationDelay};
pub use status::{AxisUpdate, DelayStatus, DelayUpdate};

pub(crate) use gain_fusion::AXES;
pub use tracking::OUTLIER_SIGMA;
pub(crate) use tracking::{ACQUIRE_AGREEMENT_SIGMA, MAX_APPLIED_DELAY_ERROR_S};

use crate::scalar::Scalar;
use crate::zero_option::ZeroOption;
use grid::{GpsToGrid, ImuToGrid};
use matched::MatchedCorrelator;
use tracking::EdgeRun;

/// Per-sensor pure delays of eq. (15), seconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct SensorDelays<T: Scalar> {
    /// Delay applied to the whitened accelerometer: `tau_f`.
    pub accel_s: T,
    /// Delay applied to the whitened gyroscope: `tau_f + D_f - D_w`.
    pub gyro_s: T,
    /// Delay applied to the raw magnetometer: `tau_f + D_f`.
    pub mag_s: T,
}

impl<T: Scalar> SensorDelays<T> {
    /// Eq. (15) from the estimated delay `tau_f` (s) and the group delays of
    /// the accelerometer (`D_f`) and gyroscope (`D_w`) whitening filters (s).
    pub fn new(tau_f_s: T, accel_group_delay_s: T, gyro_group_delay_s: T) -> Self {
        Self {
            accel_s: tau_f_s,
            gyro_s: tau_f_s + accel_group_delay_s - gyro_group_delay_s,
            mag_s: tau_f_s + accel_group_delay_s,
        }
    }
}

/// The online delay estimation loop: IMU NED acceleration and GPS velocity
/// in, GPS delay out.
///
/// Capacities are const generics, in correlation-grid samples: `BUF` for the
/// buffer, `LAGS` for the shift window, `HIST` for the IMU grid history
/// (buffer + largest shift + the lead of the IMU stream over the GPS one,
/// checked by [`DelayLoop::new`]). [`DefaultDelayLoop`] fits the default
/// configuration.
///
/// ```
/// use delaynav::delay::{DefaultDelayLoop, DelayLoopConfig};
/// use nalgebra::Vector3;
///
/// // Motion a(t) = [3 sin 1.3t, 2 cos 0.7t, sin 2.1t] m/s^2; the GPS velocity
/// // describes it 0.15 s late. IMU at 100 Hz, GPS at 10 Hz, noise-free.
/// let accel = |t: f64| Vector3::new(3.0 * (1.3 * t).sin(), 2.0 * (0.7 * t).cos(), (2.1 * t).sin());
/// let velocity = |t: f64| {
///     Vector3::new(-3.0 / 1.3 * (1.3 * t).cos(), 2.0 / 0.7 * (0.7 * t).sin(), -(2.1 * t).cos() / 2.1)
/// };
/// let mut config = DelayLoopConfig::<f64>::clean_input();
/// config.fusion.initial_delay_s = 0.4;
/// let mut delay_loop = DefaultDelayLoop::<f64>::new(config)?;
/// for k in 1..=4000u64 {
///     let t_us = k * 10_000;
///     let t = t_us as f64 * 1e-6;
///     delay_loop.push_imu(t_us, accel(t))?;
///     if k % 10 == 0 {
///         if let Some(update) = delay_loop.push_gps(t_us, velocity(t - 0.15))? {
///             assert!(update.axes.iter().any(|axis| axis.valid));
///         }
///     }
/// }
/// assert!((delay_loop.delay_s() - 0.15).abs() < 0.005);
/// # Ok::<(), delaynav::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct DelayLoop<T: Scalar, const BUF: usize, const LAGS: usize, const HIST: usize> {
    config: DelayLoopConfig<T>,
    period_s: T,
    imu_grid: ImuToGrid<T>,
    gps_grid: GpsToGrid<T>,
    correlator: SlidingCorrelator<T, BUF, LAGS, HIST>,
    matched: MatchedCorrelator<T>,
    fusion: GainFusion<T>,
    last_imu_us: Option<u64>,
    last_gps_us: Option<u64>,
    fixes_since_update: u32,
    last_update_us: Option<u64>,
    disagreeing_since_us: Option<u64>,
    restarts: u32,
    offset_samples: u64,
    shift_min: usize,
    innovation_ratio: T,
    /// Updates in the innovation match so far, up to 255 (its weights: see
    /// [`SIGMA_MATCH_TIME_S`]).
    innovations_matched: u8,
    /// The bias watch of [`delay_std_s`](DelayLoop::delay_std_s).
    bias: sigma::BiasWatch<T>,
    locked: bool,
    following: bool,
    stable_since_us: Option<u64>,
    edge: ZeroOption<EdgeRun<T>>,
    status: DelayStatus<T>,
    innovation: InnovationDelay<T>,
    innovation_window: ZeroOption<(T, T)>,
    /// Running mean of the innovation windows' normalized squared
    /// disagreement with the estimate (0 before the first).
    window_nis: T,
    /// The fix interval the last intervals agree on, us, and how many in a row
    /// ([`DelayLoopConfig::follow_gps_rate`]).
    rate_interval_us: u32,
    rate_votes: u8,
    /// Times the loop followed a new GPS rate.
    gps_rate_changes: u16,
    /// Valid axes left out as outliers on the fix-interval path once locked ([`OUTLIER_SIGMA`]).
    outlier_windows: u32,
    /// Updates in a row each axis moved at least [`SUSTAINED_MOTION_SHARE`] of the motion
    /// threshold while below it (up to 255; updates above the threshold are not counted).
    moving_updates: [u8; AXES],
    /// False in [`BLANK`](DelayLoop::BLANK) and after a failed
    /// [`configure`](DelayLoop::configure): every sample is refused.
    configured: bool,
}

/// A loop sized for the default configuration: 25 Hz grid, 5 s buffer
/// (125 samples), up to 31 shifts (a range 1.2 s wide, e.g. the default
/// 0 to 1 s, or -0.5 to 0.6 s), and 192 samples of IMU history (7.7 s);
/// [`DelayLoopConfig::adapted_to_gps_rate`] fits it at every GPS rate. The
/// work per fix follows the configured range, not this capacity.
pub type DefaultDelayLoop<T> = DelayLoop<T, 125, 31, 192>;
