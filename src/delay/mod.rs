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
//! 2. Correlation ([`correlation`]): eq. (13) per NED axis as a Pearson
//!    coefficient over a buffer of `B` grid samples (default 5 s) for every
//!    shift of the window `[tau_min, tau_max]` (default 0 to 1 s), updated by
//!    sliding sums; the peak is refined by a parabola; `z_i = s_peak Tc` (s).
//!    For slow GPS ([`DelayLoopConfig::matched_fix_intervals`]) the grid
//!    stream of the GPS is replaced by the fix intervals themselves: each GPS
//!    difference against the IMU mean over the same interval, shifted
//!    (`matched` module).
//! 3. Validity: `V_i = 1` when the peak is interior to the window, its value
//!    is at least `min_peak`, and the axis' IMU acceleration variance over the
//!    buffer is at least `min_accel_variance_m2_s4`: without motion the peak
//!    position says nothing about the delay.
//!    A valid axis beyond [`AXIS_AGREEMENT_SIGMA`] of the best-measured
//!    axis of the same window is left out.
//! 4. Fusion ([`gain_fusion`]): Table 2, corrected, once per GPS fix (or every
//!    `fixes_per_update` fixes), with `Q_f` and `R_i` derived per iteration
//!    from rate-independent settings, `R_i` scaled by each axis' motion, and
//!    a re-acquisition after a sustained disagreement (see
//!    [`DelayLoopConfig`]).
//! 5. Optional second observation ([`innovation`], off by default): the
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

pub mod calibration;
pub mod correlation;
pub mod fir;
pub mod fractional_delay;
pub mod gain_fusion;
mod grid;
pub mod innovation;
mod matched;
pub(crate) mod packed;
pub(crate) mod ring;

pub use calibration::{Calibration, CalibrationConfig, DefaultCalibrator, OfflineCalibrator};
pub use correlation::{AxisPeak, PENDING_GPS_SAMPLES, SlidingCorrelator};
pub use fir::WhiteningFir;
pub use fractional_delay::{FractionalDelayLine, SamplePeriod};
pub use gain_fusion::{AXES, GainFusion, GainFusionConfig, GainFusionStep};
pub use grid::{MAX_GPS_DIFF_SPAN, MAX_GRID_TIME_US, MAX_INPUT_MAGNITUDE};
pub use innovation::{HorizonFix, InnovationDelay};
pub use matched::MATCHED_INTERVALS;

use nalgebra::Vector3;

use crate::error::{Bound, Capacity, Error, Section, check};
use crate::scalar::Scalar;
use crate::sensors::GpsFix;
use crate::zero_option::ZeroOption;
use grid::{
    GpsToGrid, ImuToGrid, admit_sample, grid_period_us, grid_samples, lead_samples,
    signed_grid_samples, validate_grid,
};
use matched::MatchedCorrelator;

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

/// The default `V_i` motion threshold,
/// [`DelayLoopConfig::min_accel_variance_m2_s4`], (m/s^2)^2: the one the
/// navigator needs. Its `a_fwd` carries its tilt error times g (1 deg:
/// 0.17 m/s^2), which follows the motion; on an axis that barely moves,
/// that error and the GPS noise place the correlation peak anywhere in the
/// window with a high coefficient. On the simulator, an axis at 0.3-1
/// (m/s^2)^2 gave peaks from 0.5 to 0.97 s for a 0.2 s delay.
pub const DEFAULT_MIN_ACCEL_VARIANCE_M2_S4: f64 = 2.0;

/// The default `V_i` peak threshold, [`DelayLoopConfig::min_peak`] (the
/// navigator's, as [`DEFAULT_MIN_ACCEL_VARIANCE_M2_S4`]).
pub const DEFAULT_MIN_PEAK: f64 = 0.9;

/// The motion threshold of [`DelayLoopConfig::clean_input`], (m/s^2)^2: a
/// loop fed an acceleration without the navigator's tilt error (a
/// reference trajectory, a separate attitude solution) measures the delay
/// from weaker motion.
pub const CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4: f64 = 0.25;

/// The peak threshold of [`DelayLoopConfig::clean_input`].
pub const CLEAN_INPUT_MIN_PEAK: f64 = 0.5;

/// GPS rate below which [`DelayLoopConfig::adapted_to_gps_rate`] turns on
/// the fix-interval correlation ([`DelayLoopConfig::matched_fix_intervals`]),
/// Hz. Measured: it takes the suite's `gps_1hz` from 84 to 23 ms, while at
/// 4.98 Hz (the log171 flight) a 0.2 s delay step ends 15 ms short of its
/// target with it and 7 ms short on the grid path (docs/delay.md).
pub const MATCHED_BELOW_HZ: f64 = 3.0;

/// Configuration of the [`DelayLoop`].
///
/// # Noise units
///
/// The GFA (Table 2) needs a process noise `Q_f` and measurement variances
/// `R_i` per iteration. Per iteration values would change meaning with the
/// GPS rate and with `fixes_per_update`, and successive peaks are far from
/// independent (at 10 Hz, 50 successive measurements share most of a 5 s
/// buffer). The configuration therefore states:
///
/// - `process_noise_ms2_per_s` = `q`: the delay's random-walk intensity,
///   ms^2 per second; per iteration `Q_f = q dt`, `dt` the time since the
///   previous iteration;
/// - `measurement_noise_ms2` = `R_i`: the variance of one axis' peak from one
///   *independent* buffer, ms^2; per iteration `R_i (T_buffer / dt)`, which
///   spreads one buffer's information over the iterations that share it.
///
/// In continuous time the loop is then a Kalman-Bucy filter with measurement
/// density `r_c = R T_buffer / 3` (three axes) and steady-state time constant
/// `T = sqrt(r_c / q)`; the defaults (`R = 1600 ms^2` at 3 m/s^2 rms motion,
/// `q = 4.2 ms^2/s`) give `T = 25 s` at that motion whatever the rates, and
/// shorter with stronger motion (`R_i` scales with
/// [`reference_accel_variance_m2_s4`](Self::reference_accel_variance_m2_s4)).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct DelayLoopConfig<T: Scalar> {
    /// Rate of the correlation grid, Hz (its period is rounded to whole
    /// microseconds).
    pub correlation_rate_hz: T,
    /// Correlation buffer length, s (the paper: 5 s).
    pub buffer_s: T,
    /// GPS velocity differencing span `n` of eq. (14), fixes, `1..=8`.
    pub gps_diff_span: usize,
    /// Cutoff of the smoothing applied to both accelerations, Hz (grid path
    /// only).
    pub smoothing_cutoff_hz: T,
    /// Correlate over the GPS fix intervals themselves (`matched` module):
    /// each GPS difference against the IMU acceleration averaged over the
    /// same interval, shifted, instead of smoothed streams on the grid. For
    /// slow GPS (set by [`adapted_to_gps_rate`](Self::adapted_to_gps_rate)
    /// below [`MATCHED_BELOW_HZ`]); the buffer must hold at most [`MATCHED_INTERVALS`]
    /// intervals.
    pub matched_fix_intervals: bool,
    /// Smallest IMU acceleration variance over the buffer for `V_i = 1`, (m/s^2)^2.
    pub min_accel_variance_m2_s4: T,
    /// Smallest correlation peak for `V_i = 1`, in `[0, 1)`.
    pub min_peak: T,
    /// Run the correlation peak search and the GFA every this many fixes.
    pub fixes_per_update: u32,
    /// Longest IMU gap, s; a longer one restarts the correlation.
    pub max_imu_gap_s: T,
    /// Longest GPS gap, s; a longer one restarts the correlation buffer.
    pub max_gps_gap_s: T,
    /// Delay random-walk intensity `q`, ms^2/s (see the type docs).
    pub process_noise_ms2_per_s: T,
    /// Variance `R_i` of one axis' peak over one independent buffer, ms^2
    /// (north, east, down).
    pub measurement_noise_ms2: [T; AXES],
    /// Reference motion for `measurement_noise_ms2`, (m/s^2)^2: an axis whose
    /// IMU acceleration variance over the buffer is `v` uses
    /// `R_i * reference / v`, since the peak's scatter falls as the motion
    /// grows (the delay's Cramer-Rao bound scales as `sigma_v^2 / sum a^2`).
    /// 0 disables the scaling.
    pub reference_accel_variance_m2_s4: T,
    /// While not locked (acquiring from an uncertain start, or following
    /// after a re-acquisition), `R_i` scales as `(reference / v)^e` with this
    /// exponent `e` instead of `reference / v`: a window moving ten times
    /// less weighs a hundred times less at `e = 2`, so the first, weakly
    /// moving windows of a cold start (whose peaks scatter by tens of ms)
    /// give way to the first strong ones. 1 keeps the locked weighting.
    pub acquisition_motion_exponent: T,
    /// Re-acquisition threshold, in standard deviations `sqrt(P + R_i)`: when
    /// every valid axis (at least one) disagrees with the estimate beyond it,
    /// on the same side, for `reacquire_after_s`, the estimate restarts from
    /// their mean and follows the per-window measurements until they settle
    /// (see [`DelayStatus::Acquiring`]). 0 disables.
    pub reacquire_sigma: T,
    /// How long the disagreement must last before re-acquiring, s.
    pub reacquire_after_s: T,
    /// A standard deviation at or below which the estimate starts locked, s
    /// (e.g. an offline calibration); a less certain start acquires first.
    pub lock_std_s: T,
    /// Acquisition: the window estimate must stay within this many of its
    /// standard deviations of the previous one ...
    pub acquire_sigma: T,
    /// ... for this long before the loop locks, s.
    pub lock_after_s: T,
    /// How long the correlation peaks of the moving axes must sit on one edge
    /// of the range before the status reports the delay out of range, s.
    pub out_of_range_after_s: T,
    /// Window of the second delay observation, from the horizon filter's
    /// GPS innovations ([`innovation`] module), s: every this long its
    /// least-squares estimate is fused into the gain fusion. 0 disables
    /// (the default: the delay suite's figures for 4-6 s windows are in
    /// `docs/delay.md`, section 8; 5 s is the measured setting).
    pub innovation_window_s: T,
    /// Factor on that estimate's variance (`1 / info`) when it is fused:
    /// the filter's absorption of the delay error into its attitude and
    /// biases is not modelled, and successive windows are not independent.
    pub innovation_noise_scale: T,
    /// An innovation window beyond this many standard deviations
    /// `sqrt(P + R)` of the estimate restarts the gain fusion from it (a
    /// step of the delay). 0 disables.
    pub innovation_reacquire_sigma: T,
    /// Before the correlation locks, fuse the innovation windows as well,
    /// each only when it agrees with the previous window (within
    /// [`ACQUIRE_AGREEMENT_SIGMA`] standard deviations of their difference)
    /// and with its variance times `innovation_acquire_noise_scale` too.
    /// Off: only once locked (refinement and step detection). Measured on
    /// the delay suite (`docs/delay.md`): `cold_start_low` 25 -> 9-10 ms at
    /// 4-6 s windows, `cold_start_high` 3.8-4.3 ms (4.15 ms off).
    pub innovation_before_lock: bool,
    /// Before lock, factor on the innovation windows' variance on top of
    /// `innovation_noise_scale`: before the first strong manoeuvre the
    /// windows scatter more than their variance says (`docs/delay.md`).
    pub innovation_acquire_noise_scale: T,
    /// Gain fusion, delay range (= the shift window, either sign) and
    /// initial delay.
    pub fusion: GainFusionConfig<T>,
}

impl<T: Scalar> Default for DelayLoopConfig<T> {
    fn default() -> Self {
        Self {
            correlation_rate_hz: T::lit(25.0),
            buffer_s: T::lit(5.0),
            gps_diff_span: 2,
            smoothing_cutoff_hz: T::lit(1.0),
            matched_fix_intervals: false,
            min_accel_variance_m2_s4: T::lit(DEFAULT_MIN_ACCEL_VARIANCE_M2_S4),
            min_peak: T::lit(DEFAULT_MIN_PEAK),
            fixes_per_update: 1,
            max_imu_gap_s: T::lit(0.1),
            max_gps_gap_s: T::lit(0.5),
            process_noise_ms2_per_s: T::lit(4.2),
            measurement_noise_ms2: [T::lit(1600.0); AXES],
            reference_accel_variance_m2_s4: T::lit(9.0),
            acquisition_motion_exponent: T::lit(2.0),
            reacquire_sigma: T::lit(2.0),
            reacquire_after_s: T::lit(1.0),
            lock_std_s: T::lit(0.03),
            acquire_sigma: T::lit(1.0),
            lock_after_s: T::lit(1.0),
            out_of_range_after_s: T::lit(2.0),
            innovation_window_s: T::ZERO,
            innovation_noise_scale: T::lit(1.0),
            innovation_reacquire_sigma: T::lit(4.0),
            innovation_before_lock: false,
            innovation_acquire_noise_scale: T::lit(3.0),
            fusion: GainFusionConfig::default(),
        }
    }
}

/// Grid sizes derived from a configuration.
#[derive(Debug, Clone, Copy)]
struct GridSizes {
    period_us: u64,
    buffer_len: usize,
    shift_min: usize,
    lags: usize,
    lead: usize,
    /// Smallest shift, grid samples, either sign.
    shift_lo: i64,
    /// Grid samples the GPS stream is shifted later so that a negative
    /// delay becomes a shift `>= 0`.
    offset: usize,
}

impl<T: Scalar> DelayLoopConfig<T> {
    /// Every field zero (never valid): the configuration of
    /// [`DelayLoop::BLANK`].
    pub(crate) const ZEROED: Self = Self {
        correlation_rate_hz: T::ZERO,
        buffer_s: T::ZERO,
        gps_diff_span: 0,
        smoothing_cutoff_hz: T::ZERO,
        matched_fix_intervals: false,
        min_accel_variance_m2_s4: T::ZERO,
        min_peak: T::ZERO,
        fixes_per_update: 0,
        max_imu_gap_s: T::ZERO,
        max_gps_gap_s: T::ZERO,
        process_noise_ms2_per_s: T::ZERO,
        measurement_noise_ms2: [T::ZERO; AXES],
        reference_accel_variance_m2_s4: T::ZERO,
        acquisition_motion_exponent: T::ZERO,
        reacquire_sigma: T::ZERO,
        reacquire_after_s: T::ZERO,
        lock_std_s: T::ZERO,
        acquire_sigma: T::ZERO,
        lock_after_s: T::ZERO,
        out_of_range_after_s: T::ZERO,
        innovation_window_s: T::ZERO,
        innovation_noise_scale: T::ZERO,
        innovation_reacquire_sigma: T::ZERO,
        innovation_before_lock: false,
        innovation_acquire_noise_scale: T::ZERO,
        fusion: GainFusionConfig::ZEROED,
    };

    /// The defaults with the validity thresholds of a loop fed a clean
    /// acceleration ([`CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4`],
    /// [`CLEAN_INPUT_MIN_PEAK`]) instead of the navigator's.
    pub fn clean_input() -> Self {
        Self {
            min_accel_variance_m2_s4: T::lit(CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4),
            min_peak: T::lit(CLEAN_INPUT_MIN_PEAK),
            ..Self::default()
        }
    }

    /// This configuration adapted to a GPS delivering `gps_rate_hz` fixes per
    /// second (1 to 20 Hz), within the capacities of [`DefaultDelayLoop`]:
    ///
    /// - gap limit `max_gps_gap_s = 2.2 / rate` (a fix lost is tolerated,
    ///   two are a gap);
    /// - below 5 Hz: the GPS difference spans one fix interval
    ///   (`gps_diff_span = 1`);
    /// - the correlation grid runs at 25 Hz (the default), at 12.5 Hz on the
    ///   matched path (below [`MATCHED_BELOW_HZ`]), so that the IMU grid
    ///   history of [`DefaultDelayLoop`] holds the buffer (10 s at 1 Hz), the
    ///   shifts and the longer lead of the IMU stream over the GPS one;
    /// - the smoothing of both accelerations follows the rate,
    ///   `min(1 Hz, rate / 2.5)`: the GPS difference is already the mean
    ///   acceleration over its span (a box of `n / rate` seconds, then the
    ///   interpolation's triangle), and the IMU side must see the same
    ///   averaging for the correlation peak to stay high; a common low-pass
    ///   near `rate / n` dominates both;
    /// - the buffer holds at least 10 fix intervals: `max(5 s, 10 / rate)`
    ///   (at most 10 s);
    /// - a re-acquisition needs the disagreement over
    ///   [`REACQUIRE_AFTER_FIXES`] new fixes: `reacquire_after_s` at least
    ///   `10 / rate` (at 5 Hz, the per-window peaks of a real flight leave
    ///   the estimate for a second during a manoeuvre, see `docs/delay.md`).
    ///
    /// Refused: a rate outside 1-20 Hz or not finite.
    pub fn adapted_to_gps_rate(mut self, gps_rate_hz: T) -> Result<Self, Error> {
        if !(gps_rate_hz.is_finite() && gps_rate_hz >= T::one() && gps_rate_hz <= T::lit(20.0)) {
            return Err(Error::OutOfRange {
                field: "gps_rate_hz",
                reason: "must be 1 to 20 Hz",
            });
        }
        let slow = gps_rate_hz < T::lit(5.0);
        self.max_gps_gap_s = T::lit(2.2) / gps_rate_hz;
        self.gps_diff_span = if slow { 1 } else { 2 };
        self.matched_fix_intervals = gps_rate_hz < T::lit(MATCHED_BELOW_HZ);
        // The matched path's 10 s buffer (at 1 Hz) and its longer lead fit
        // the IMU grid history at half the grid rate.
        self.correlation_rate_hz = T::lit(if self.matched_fix_intervals {
            12.5
        } else {
            25.0
        });
        self.smoothing_cutoff_hz = (gps_rate_hz / T::lit(2.5)).min(T::one());
        self.buffer_s = (T::lit(10.0) / gps_rate_hz).clamp(T::lit(5.0), T::lit(10.0));
        self.reacquire_after_s = self
            .reacquire_after_s
            .max(T::lit(REACQUIRE_AFTER_FIXES) / gps_rate_hz);
        self.validate()?;
        Ok(self)
    }

    /// Checks every field (the sizes against the const capacities are checked
    /// by [`DelayLoop::new`]).
    pub fn validate(&self) -> Result<(), Error> {
        self.sizes().map(|_| ())
    }

    fn sizes(&self) -> Result<GridSizes, Error> {
        validate_grid(
            self.correlation_rate_hz,
            self.gps_diff_span,
            self.smoothing_cutoff_hz,
            ("buffer_s", self.buffer_s),
        )?;
        check::not_negative("min_accel_variance_m2_s4", self.min_accel_variance_m2_s4)?;
        check::interval("min_peak", self.min_peak, Bound::WithinBelow(0.0, 1.0))?;
        check::count_at_least("fixes_per_update", self.fixes_per_update.into(), 1)?;
        check::positive_finite("max_imu_gap_s", self.max_imu_gap_s)?;
        check::positive_finite("max_gps_gap_s", self.max_gps_gap_s)?;
        check::not_negative("process_noise_ms2_per_s", self.process_noise_ms2_per_s)?;
        for (field, r) in [
            "measurement_noise_ms2[0]",
            "measurement_noise_ms2[1]",
            "measurement_noise_ms2[2]",
        ]
        .into_iter()
        .zip(self.measurement_noise_ms2)
        {
            check::positive_finite(field, r)?;
        }
        check::not_negative(
            "reference_accel_variance_m2_s4",
            self.reference_accel_variance_m2_s4,
        )?;
        check::within(
            "acquisition_motion_exponent",
            self.acquisition_motion_exponent,
            T::one(),
            T::lit(4.0),
        )?;
        check::not_negative("reacquire_sigma", self.reacquire_sigma)?;
        check::positive_finite("reacquire_after_s", self.reacquire_after_s)?;
        check::positive_finite("lock_std_s", self.lock_std_s)?;
        check::not_negative("acquire_sigma", self.acquire_sigma)?;
        check::not_negative("lock_after_s", self.lock_after_s)?;
        check::not_negative("out_of_range_after_s", self.out_of_range_after_s)?;
        check::not_negative("innovation_window_s", self.innovation_window_s)?;
        check::positive_finite("innovation_noise_scale", self.innovation_noise_scale)?;
        check::not_negative(
            "innovation_reacquire_sigma",
            self.innovation_reacquire_sigma,
        )?;
        check::positive_finite(
            "innovation_acquire_noise_scale",
            self.innovation_acquire_noise_scale,
        )?;
        self.fusion
            .validate()
            .map_err(|e| e.within(Section::Fusion))?;
        let period_us = grid_period_us(self.correlation_rate_hz);
        let shift_lo = signed_grid_samples(self.fusion.delay_min_s, period_us);
        let shift_hi = signed_grid_samples(self.fusion.delay_max_s, period_us);
        let offset = usize::try_from(-shift_lo.min(0)).unwrap_or(usize::MAX);
        if offset > PENDING_GPS_SAMPLES / 2 {
            // A negative delay reaches at most `PENDING_GPS_SAMPLES / 2`
            // grid samples (the GPS samples that can wait).
            let limit = -((PENDING_GPS_SAMPLES / 2) as f64) * period_us as f64 * 1e-6;
            return Err(check::invalid(
                "delay_min_s",
                self.fusion.delay_min_s,
                Bound::AtLeast(limit),
            )
            .within(Section::Fusion));
        }
        Ok(GridSizes {
            period_us,
            buffer_len: grid_samples(self.buffer_s, period_us),
            shift_min: usize::try_from(shift_lo + offset as i64).unwrap_or(0),
            lags: usize::try_from(shift_hi - shift_lo + 1).unwrap_or(0),
            offset,
            shift_lo,
            lead: lead_samples(
                self.gps_diff_span,
                self.max_gps_gap_s,
                self.max_imu_gap_s,
                period_us,
            ),
        })
    }
}

/// What the correlation and the fusion made of one axis at one update.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AxisUpdate<T: Scalar> {
    /// Validity `V_i`: the measurement was fused.
    pub valid: bool,
    /// The delay measurement `z_i` (refined correlation peak), s.
    pub measured_delay_s: T,
    /// The local gain `K_i` (applied only when valid).
    pub gain: T,
    /// The correlation peak it came from.
    pub correlation: AxisPeak<T>,
}

/// The record of one delay update (one GFA iteration).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DelayUpdate<T: Scalar> {
    /// Receive time of the GPS fix that triggered the update, us.
    pub t_us: u64,
    /// Fused delay estimate, s.
    pub delay_s: T,
    /// Its standard deviation as the GFA models it (see the noise units of
    /// [`DelayLoopConfig`]), s; not validated as a calibrated uncertainty.
    pub delay_std_s: T,
    /// True when this update re-acquired the delay (see
    /// [`DelayLoopConfig::reacquire_sigma`]).
    pub reacquired: bool,
    /// The loop's status after this update.
    pub status: DelayStatus<T>,
    /// North, east, down.
    pub axes: [AxisUpdate<T>; AXES],
}

/// What the loop can say about the delay (see [`DelayLoop::status`]).
///
/// The navigator, or the user, reads it to know whether [`DelayLoop::delay_s`]
/// is an estimate (`Locked`), a provisional value (`Acquiring`), or the
/// start value the motion has not yet allowed to estimate; and whether the
/// true delay lies outside the configured range, which the loop never
/// clamps silently.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum DelayStatus<T: Scalar> {
    /// The correlation buffer is not full yet (start, or after a gap in a
    /// stream): the estimate is the start value.
    WaitingForData,
    /// Not locked, and no axis of the last window moved enough (or
    /// correlated well enough) to measure the delay.
    WaitingForMotion,
    /// Following the per-window correlation peaks (the coarse search over
    /// the whole range) until they settle.
    Acquiring,
    /// Locked: the gain fusion refines the estimate (it holds it when the
    /// motion stops).
    Locked,
    /// For [`DelayLoopConfig::out_of_range_after_s`], the correlation of every
    /// moving axis peaked at the smallest delay of the range: the delay is
    /// below `edge_s`. The estimate is not moved there.
    BelowRange {
        /// The range's lower edge, s.
        edge_s: T,
        /// The largest peak value (normalized correlation) seen at the edge.
        peak: T,
    },
    /// As [`DelayStatus::BelowRange`], at the largest delay of the range.
    AboveRange {
        /// The range's upper edge, s.
        edge_s: T,
        /// The largest peak value (normalized correlation) seen at the edge.
        peak: T,
    },
}

impl<T: Scalar> DelayStatus<T> {
    /// True when the delay is estimated (`Locked`).
    pub fn is_locked(&self) -> bool {
        matches!(self, DelayStatus::Locked)
    }

    /// True when the delay lies outside the configured range.
    pub fn is_out_of_range(&self) -> bool {
        matches!(
            self,
            DelayStatus::BelowRange { .. } | DelayStatus::AboveRange { .. }
        )
    }
}

/// New fixes over which every valid axis must disagree with the estimate
/// before the loop re-acquires, at any GPS rate: [`DelayLoopConfig::adapted_to_gps_rate`]
/// raises `reacquire_after_s` to `REACQUIRE_AFTER_FIXES / rate` (1 s at
/// 10 Hz, the default; 2 s at 5 Hz).
pub const REACQUIRE_AFTER_FIXES: f64 = 10.0;

/// Time constant of the innovation match that scales the reported sigma, s
/// (two independent 5 s buffers). Until it has seen that many updates, the
/// match is the plain mean of the windows so far (weight `1 / n` for the
/// `n`-th, `n` counted up to 255): one window alone would set it.
pub const SIGMA_MATCH_TIME_S: f64 = 10.0;

/// Smallest squared scale of the reported sigma (the scale never exceeds 1:
/// it only removes the pessimism of the noise model).
pub const SIGMA_SCALE2_MIN: f64 = 0.01;

/// Largest difference between the delay the horizon applied to a fix and
/// the loop's estimate for the innovation window to be fused, s.
pub const MAX_APPLIED_DELAY_ERROR_S: f64 = 0.02;

/// Before lock, an innovation window is fused only within this many
/// standard deviations (scaled as fused) of the previous window: 3 gave
/// the same delay suite, 1.5 the same but for one row, 1 was worse
/// (`docs/delay.md`).
pub const ACQUIRE_AGREEMENT_SIGMA: f64 = 2.0;

/// Largest squared scale of the reported sigma with the innovation
/// observation on (its windows' variances are measured, not pessimistic, so
/// the match may widen the sigma as well as narrow it).
pub const SIGMA_SCALE2_MAX: f64 = 16.0;

/// Largest disagreement between two valid axes of one window, in standard
/// deviations `sqrt(R_i + R_j)` of their difference.
pub const AXIS_AGREEMENT_SIGMA: f64 = 3.0;

/// Cross-axis check of one window: every axis measures the same delay, so a
/// valid axis whose peak lies beyond [`AXIS_AGREEMENT_SIGMA`] of the best
/// measured one (smallest `R_i`, the most motion) is left out. Such a peak
/// comes from an error of `a_fwd` that follows the motion (the navigator's
/// tilt), not from the delay: on the 1 Hz high scenario the east axis gave
/// 0.80 s with a peak of 0.97 while north gave 0.19 s.
fn drop_inconsistent_axes<T: Scalar>(z: &[T; AXES], valid: &mut [bool; AXES], r: &[T; AXES]) {
    // The valid axis of smallest `R`, with its `R` (no index kept out of
    // the loop, and `best < AXES` stated: no reachable panic, benches/no-panic).
    let mut best: Option<(usize, T)> = None;
    for axis in (0..AXES).filter(|&a| valid[a]) {
        if best.is_none_or(|(_, r_best)| r[axis] < r_best) {
            best = Some((axis, r[axis]));
        }
    }
    let Some((best, _)) = best.filter(|&(b, _)| b < AXES) else {
        return;
    };
    let k = T::lit(AXIS_AGREEMENT_SIGMA);
    for axis in 0..AXES {
        if axis != best && valid[axis] && (z[axis] - z[best]).abs() > k * (r[axis] + r[best]).sqrt()
        {
            valid[axis] = false;
        }
    }
}

/// Peaks of moving axes sitting on one edge of the shift window.
#[derive(Debug, Clone, Copy)]
struct EdgeRun<T: Scalar> {
    since_us: u64,
    below: bool,
    peak: T,
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

impl<T: Scalar, const BUF: usize, const LAGS: usize, const HIST: usize>
    DelayLoop<T, BUF, LAGS, HIST>
{
    /// A loop for a validated configuration whose sizes fit the capacities.
    ///
    /// Built on the stack; in a `static`, or on a small stack, start from
    /// [`BLANK`](Self::BLANK) and [`configure`](Self::configure) it in place.
    pub fn new(config: DelayLoopConfig<T>) -> Result<Self, Error> {
        let mut delay_loop = Self::BLANK;
        delay_loop.configure(config)?;
        Ok(delay_loop)
    }

    /// A loop not configured yet: a `const` value the compiler builds (in a
    /// `static`, no stack at all), every buffer empty. It refuses every
    /// sample ([`Error::NotConfigured`]) until [`configure`](Self::configure)
    /// succeeds.
    pub const BLANK: Self = Self {
        config: DelayLoopConfig::ZEROED,
        period_s: T::ZERO,
        imu_grid: ImuToGrid::BLANK,
        gps_grid: GpsToGrid::BLANK,
        correlator: SlidingCorrelator::BLANK,
        matched: MatchedCorrelator::BLANK,
        fusion: GainFusion::BLANK,
        last_imu_us: None,
        last_gps_us: None,
        fixes_since_update: 0,
        last_update_us: None,
        disagreeing_since_us: None,
        restarts: 0,
        offset_samples: 0,
        shift_min: 0,
        innovation_ratio: T::ZERO,
        innovations_matched: 0,
        locked: false,
        following: false,
        stable_since_us: None,
        edge: ZeroOption::None,
        status: DelayStatus::WaitingForData,
        innovation: InnovationDelay::BLANK,
        innovation_window: ZeroOption::None,
        window_nis: T::ZERO,
        configured: false,
    };

    /// True once a [`configure`](Self::configure) (or [`new`](Self::new))
    /// succeeded.
    pub fn is_configured(&self) -> bool {
        self.configured
    }

    /// Validates `config` and (re)starts the loop with it in place: the
    /// buffers are emptied through `&mut`, not rebuilt, so this needs a
    /// small stack whatever the capacities. The state afterwards is that of
    /// [`new`](Self::new). On error the loop is left not configured
    /// (refusing every sample), not half configured.
    pub fn configure(&mut self, config: DelayLoopConfig<T>) -> Result<(), Error> {
        self.configured = false;
        let sizes = config.sizes()?;
        Self::check_capacities(&config, &sizes)?;
        self.correlator
            .configure(sizes.buffer_len, sizes.shift_min, sizes.lags)?;
        let fusion = GainFusion::new(config.fusion)?;
        self.config = config;
        self.period_s = T::lit(sizes.period_us as f64 * 1e-6);
        self.imu_grid = if config.matched_fix_intervals {
            ImuToGrid::unsmoothed(sizes.period_us)
        } else {
            ImuToGrid::new(sizes.period_us, config.smoothing_cutoff_hz)
        };
        self.gps_grid = GpsToGrid::new(
            sizes.period_us,
            config.gps_diff_span,
            config.smoothing_cutoff_hz,
        );
        self.matched.configure(
            sizes.period_us,
            sizes.shift_lo,
            sizes.lags,
            (config.buffer_s.as_f64() * 1e6) as u64,
            config.gps_diff_span,
        );
        self.fusion = fusion;
        self.last_imu_us = None;
        self.last_gps_us = None;
        self.fixes_since_update = 0;
        self.last_update_us = None;
        self.disagreeing_since_us = None;
        self.restarts = 0;
        self.offset_samples = sizes.offset as u64;
        self.shift_min = sizes.shift_min;
        self.innovation_ratio = T::one();
        self.innovations_matched = 0;
        self.locked = config.fusion.initial_std_s <= config.lock_std_s;
        self.following = false;
        self.stable_since_us = None;
        self.edge = ZeroOption::None;
        self.status = DelayStatus::WaitingForData;
        self.innovation = InnovationDelay::BLANK;
        self.innovation_window = ZeroOption::None;
        self.window_nis = T::zero();
        self.configured = true;
        Ok(())
    }

    /// The sizes of `config` against the capacities, each error on the
    /// field that sets the size, with the value the capacity allows: the
    /// buffer (`BUF`), the delay range (`LAGS`, and at least 3 shifts) and
    /// the IMU grid history (`HIST`: the buffer, the largest shift and the
    /// lead of the IMU stream over the GPS one).
    fn check_capacities(config: &DelayLoopConfig<T>, sizes: &GridSizes) -> Result<(), Error> {
        let period_s = sizes.period_us as f64 * 1e-6;
        let capacity = |field, value: T, limit: f64, at_least, of, samples: usize| {
            Err(check::invalid(
                field,
                value,
                Bound::Capacity {
                    limit: limit as f32,
                    at_least,
                    of,
                    samples: samples as u32,
                },
            ))
        };
        if sizes.buffer_len < 2 {
            return Err(check::invalid(
                "buffer_s",
                config.buffer_s,
                Bound::AtLeast(1.5 * period_s),
            ));
        }
        if sizes.buffer_len > BUF {
            let limit = BUF as f64 * period_s;
            return capacity(
                "buffer_s",
                config.buffer_s,
                limit,
                false,
                Capacity::LoopBuf,
                BUF,
            );
        }
        let delay_max = config.fusion.delay_max_s;
        let delay_min = config.fusion.delay_min_s.as_f64();
        if sizes.lags < 3 {
            return Err(check::invalid(
                "delay_max_s",
                delay_max,
                Bound::AtLeast(delay_min + 2.0 * period_s),
            )
            .within(Section::Fusion));
        }
        if sizes.lags > LAGS {
            let limit = delay_min + (LAGS - 1) as f64 * period_s;
            return capacity(
                "delay_max_s",
                delay_max,
                limit,
                false,
                Capacity::LoopLags,
                LAGS,
            )
            .map_err(|e: Error| e.within(Section::Fusion));
        }
        let others = sizes.shift_min + sizes.lags + sizes.lead;
        if sizes.buffer_len + others > HIST {
            let limit = (HIST as f64 - others as f64) * period_s;
            return capacity(
                "buffer_s",
                config.buffer_s,
                limit,
                false,
                Capacity::LoopHist,
                HIST,
            );
        }
        Ok(())
    }

    /// What the loop can say about the delay now ([`DelayStatus`]).
    pub fn status(&self) -> DelayStatus<T> {
        self.status
    }

    /// The configuration (every field zero on a loop not configured: see
    /// [`is_configured`](Self::is_configured)).
    pub fn config(&self) -> &DelayLoopConfig<T> {
        &self.config
    }

    /// Current delay estimate `tau`, s.
    pub fn delay_s(&self) -> T {
        self.fusion.delay_s()
    }

    /// Current estimate of the delay's drift rate, s/s (see
    /// [`GainFusionConfig::rate_std`]).
    pub fn delay_rate(&self) -> T {
        self.fusion.rate()
    }

    /// Standard deviation of the estimate, s: the GFA's `sqrt(P)` scaled by
    /// the innovation match (see [`SIGMA_MATCH_TIME_S`]) once locked, so
    /// that it describes the errors the loop actually makes rather than its
    /// noise model's.
    pub fn delay_std_s(&self) -> T {
        (self.fusion.variance_s2() * self.sigma_scale2()).sqrt()
    }

    /// The gain fusion's own standard deviation `sqrt(P)`, s, before the
    /// innovation match of [`delay_std_s`](Self::delay_std_s).
    pub fn fusion_std_s(&self) -> T {
        self.fusion.variance_s2().sqrt()
    }

    /// The squared scale applied to the GFA's variance: the mean normalized
    /// innovation squared while locked (1 before), within
    /// `[SIGMA_SCALE2_MIN, 1]`.
    fn sigma_scale2(&self) -> T {
        if self.config.innovation_window_s > T::zero() {
            return if self.locked && !self.following && self.window_nis > T::zero() {
                self.window_nis
                    .clamp(T::lit(SIGMA_SCALE2_MIN), T::lit(SIGMA_SCALE2_MAX))
            } else {
                T::one()
            };
        }
        if self.locked && !self.following {
            self.innovation_ratio
                .clamp(T::lit(SIGMA_SCALE2_MIN), T::one())
        } else {
            T::one()
        }
    }

    /// Eq. (15) for the current estimate and the whitening filters' group
    /// delays `D_f` (accelerometer) and `D_w` (gyroscope), s.
    pub fn sensor_delays(&self, accel_group_delay_s: T, gyro_group_delay_s: T) -> SensorDelays<T> {
        SensorDelays::new(self.delay_s(), accel_group_delay_s, gyro_group_delay_s)
    }

    /// True once the correlation buffer is full.
    pub fn is_correlation_ready(&self) -> bool {
        self.correlator.is_ready()
    }

    /// Times the correlation restarted after a gap in a stream.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// Products accumulated by the sliding correlation so far (work counter).
    pub fn multiply_adds(&self) -> u64 {
        self.correlator.multiply_adds()
    }

    /// Restarts the estimate from `delay_s` with standard deviation `std_s`
    /// (e.g. the offline calibration's result): locked when `std_s` is at
    /// most [`DelayLoopConfig::lock_std_s`], else acquiring. State unchanged
    /// on error.
    pub fn set_delay(&mut self, delay_s: T, std_s: T) -> Result<(), Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        self.fusion.reset(delay_s, std_s)?;
        self.locked = std_s <= self.config.lock_std_s;
        self.following = false;
        self.stable_since_us = None;
        self.disagreeing_since_us = None;
        Ok(())
    }

    /// Feeds the forward-reckoned NED acceleration `a_fwd` (m/s^2, gravity
    /// removed) at IMU time `t_us`. Refused, state unchanged: non-finite
    /// values or beyond [`MAX_INPUT_MAGNITUDE`], time not increasing.
    pub fn push_imu(&mut self, t_us: u64, accel_ned_m_s2: Vector3<T>) -> Result<(), Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let gap = admit_sample(
            "imu",
            "delay.accel_ned",
            &accel_ned_m_s2,
            self.last_imu_us,
            t_us,
            self.config.max_imu_gap_s,
        )?;
        if gap {
            self.imu_grid.reset();
            self.correlator.reset();
            self.restarts += 1;
        }
        let correlator = &mut self.correlator;
        // Cannot fail: `admit_sample` refused timestamps beyond the grid's range.
        self.imu_grid
            .push(t_us, accel_ned_m_s2, &mut |j, x| correlator.push_x(j, x))?;
        self.last_imu_us = Some(t_us);
        Ok(())
    }

    /// Feeds one GPS velocity (NED, m/s) received at `t_us`. On an update fix
    /// with a full correlation buffer, runs the peak search and the GFA and
    /// returns the record; otherwise `None`. Refused, state unchanged:
    /// non-finite values or beyond [`MAX_INPUT_MAGNITUDE`], time not
    /// increasing.
    pub fn push_gps(
        &mut self,
        t_us: u64,
        velocity_ned_m_s: Vector3<T>,
    ) -> Result<Option<DelayUpdate<T>>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        let gap = admit_sample(
            "gps",
            "delay.gps_velocity",
            &velocity_ned_m_s,
            self.last_gps_us,
            t_us,
            self.config.max_gps_gap_s,
        )?;
        if gap {
            self.gps_grid.reset();
            self.correlator.reset_pairs();
            self.matched.reset();
            self.restarts += 1;
        }
        let (correlator, offset) = (&mut self.correlator, self.offset_samples);
        if self.config.matched_fix_intervals {
            self.matched.push_fix(t_us, velocity_ned_m_s);
        } else {
            self.gps_grid.push(t_us, velocity_ned_m_s, &mut |j, y| {
                correlator.push_y(j + offset, y)
            });
        }
        self.last_gps_us = Some(t_us);
        self.fixes_since_update += 1;
        if self.fixes_since_update < self.config.fixes_per_update {
            return Ok(None);
        }
        self.fixes_since_update = 0;
        let peaks = if self.config.matched_fix_intervals {
            let correlator = &self.correlator;
            self.matched
                .peaks::<LAGS>(self.offset_samples as usize, |j| correlator.imu_at(j))
        } else {
            self.correlator.peaks()
        };
        let Some(peaks) = peaks else {
            self.status = DelayStatus::WaitingForData;
            return Ok(None);
        };
        let offset_s = T::lit(self.offset_samples as f64) * self.period_s;
        let mut z = [T::zero(); AXES];
        let mut valid = [false; AXES];
        for axis in 0..AXES {
            let p = &peaks[axis];
            z[axis] = p.shift_samples * self.period_s - offset_s;
            valid[axis] = p.interior
                && p.peak >= self.config.min_peak
                && p.accel_variance >= self.config.min_accel_variance_m2_s4;
        }
        self.track_edges(t_us, &peaks, &valid);
        let buffer_s = self.config.buffer_s;
        let dt_s = self
            .last_update_us
            .map_or(buffer_s, |last| T::lit((t_us - last) as f64 * 1e-6))
            .min(buffer_s);
        let ms2 = T::lit(1e-6);
        let reference = self.config.reference_accel_variance_m2_s4;
        let floor = self.config.min_accel_variance_m2_s4.max(T::lit(1e-6));
        // Acquiring, the strong windows must dominate: the first, weakly
        // moving ones are the least reliable (see `acquisition_motion_exponent`).
        let exponent = if self.locked {
            T::one()
        } else {
            self.config.acquisition_motion_exponent
        };
        let r_buffer_s2: [T; AXES] = core::array::from_fn(|axis| {
            let r = self.config.measurement_noise_ms2[axis] * ms2;
            if reference > T::zero() {
                r * (reference / peaks[axis].accel_variance.max(floor)).powf(exponent)
            } else {
                r
            }
        });
        drop_inconsistent_axes(&z, &mut valid, &r_buffer_s2);
        let q_s2 = self.config.process_noise_ms2_per_s * ms2 * dt_s;
        let r_s2 = r_buffer_s2.map(|r| r * buffer_s / dt_s);
        self.match_innovations(dt_s, q_s2, &z, &valid, &r_buffer_s2);
        let reacquired = !self.following && self.reacquire(t_us, &z, &valid, &r_buffer_s2);
        let gains = if self.following {
            self.follow(t_us, &z, &valid, &r_buffer_s2)
        } else {
            let gains = self.fusion.step(z, valid, dt_s, q_s2, r_s2)?.gains;
            self.fuse_innovations(t_us);
            let lock = self.config.lock_std_s;
            self.locked |= valid.iter().any(|&v| v) && self.fusion.variance_s2() <= lock * lock;
            gains
        };
        self.last_update_us = Some(t_us);
        self.status = match self.edge.get() {
            Some(run)
                if T::lit((t_us - run.since_us) as f64 * 1e-6)
                    >= self.config.out_of_range_after_s =>
            {
                let range = &self.config.fusion;
                if run.below {
                    DelayStatus::BelowRange {
                        edge_s: range.delay_min_s,
                        peak: run.peak,
                    }
                } else {
                    DelayStatus::AboveRange {
                        edge_s: range.delay_max_s,
                        peak: run.peak,
                    }
                }
            }
            _ if self.locked => DelayStatus::Locked,
            _ if valid.iter().any(|&v| v) => DelayStatus::Acquiring,
            _ => DelayStatus::WaitingForMotion,
        };
        Ok(Some(DelayUpdate {
            t_us,
            delay_s: self.fusion.delay_s(),
            delay_std_s: self.delay_std_s(),
            reacquired,
            status: self.status,
            axes: core::array::from_fn(|axis| AxisUpdate {
                valid: valid[axis],
                measured_delay_s: z[axis],
                gain: gains[axis],
                correlation: peaks[axis],
            }),
        }))
    }

    /// Covariance matching: the running mean, over [`SIGMA_MATCH_TIME_S`],
    /// of the valid axes' squared innovations `(z_i - tau)^2` divided by their
    /// predicted variance `P + Q + R_i` (one buffer's `R_i`: successive
    /// windows share their data, so one window is one measurement of that
    /// variance). Only while locked.
    fn match_innovations(
        &mut self,
        dt_s: T,
        q_s2: T,
        z: &[T; AXES],
        valid: &[bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) {
        if !self.locked || self.following {
            return;
        }
        let tau = self.fusion.delay_s();
        let p = self.fusion.variance_s2() + q_s2;
        let (mut sum, mut n) = (T::zero(), T::zero());
        for axis in (0..AXES).filter(|&a| valid[a]) {
            let e = z[axis] - tau;
            sum += e * e / (p + r_buffer_s2[axis]);
            n += T::one();
        }
        if n > T::zero() {
            self.innovations_matched = self.innovations_matched.saturating_add(1);
            let alpha = (dt_s / T::lit(SIGMA_MATCH_TIME_S))
                .min(T::one())
                .max(T::one() / T::lit(f64::from(self.innovations_matched)));
            self.innovation_ratio += alpha * (sum / n - self.innovation_ratio);
        }
    }

    /// Re-acquisition after a step (see [`DelayLoop::reacquire`]): the
    /// correlation searches the whole range, so the estimate jumps to each
    /// window's measurement, the mean of the valid axes weighted by
    /// `1 / R_i`, with that mean's variance. Once successive window
    /// measurements have stayed within [`DelayLoopConfig::acquire_sigma`] of
    /// their standard deviation for [`DelayLoopConfig::lock_after_s`], the
    /// loop locks again and the gain fusion keeps the final word. Returns the
    /// weights used (as gains).
    fn follow(
        &mut self,
        t_us: u64,
        z: &[T; AXES],
        valid: &[bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) -> [T; AXES] {
        let mut gains = [T::zero(); AXES];
        let (mut weight, mut weighted) = (T::zero(), T::zero());
        for axis in (0..AXES).filter(|&a| valid[a]) {
            let w = T::one() / r_buffer_s2[axis];
            weight += w;
            weighted += w * z[axis];
        }
        if weight <= T::zero() {
            self.stable_since_us = None;
            return gains;
        }
        for axis in (0..AXES).filter(|&a| valid[a]) {
            gains[axis] = T::one() / (r_buffer_s2[axis] * weight);
        }
        let mean = weighted / weight;
        let variance = T::one() / weight;
        let agrees =
            (mean - self.fusion.delay_s()).abs() <= self.config.acquire_sigma * variance.sqrt();
        let since = match self.stable_since_us {
            Some(since) if agrees => since,
            _ => t_us,
        };
        self.stable_since_us = Some(since);
        if self.fusion.reset(mean, variance.sqrt()).is_ok()
            && T::lit((t_us - since) as f64 * 1e-6) >= self.config.lock_after_s
        {
            self.locked = true;
            self.following = false;
            self.stable_since_us = None;
        }
        gains
    }

    /// Follows the peaks of the axes that move (IMU variance above the
    /// threshold, peak value above `min_peak`) but are not valid because
    /// they sit on an edge of the shift window: when no axis is valid and
    /// all such axes sit on the same edge, the run continues.
    fn track_edges(&mut self, t_us: u64, peaks: &[AxisPeak<T>; AXES], valid: &[bool; AXES]) {
        let lower_edge = T::lit(self.shift_min as f64);
        let (mut below, mut above, mut peak) = (0usize, 0usize, T::zero());
        for p in peaks.iter().filter(|p| {
            !p.interior
                && p.peak >= self.config.min_peak
                && p.accel_variance >= self.config.min_accel_variance_m2_s4
        }) {
            if p.shift_samples <= lower_edge {
                below += 1;
            } else {
                above += 1;
            }
            peak = peak.max(p.peak);
        }
        let edge_below = match (valid.iter().any(|&v| v), below, above) {
            (false, b, 0) if b > 0 => Some(true),
            (false, 0, a) if a > 0 => Some(false),
            (true, ..) => None,
            // Mixed edges, or nothing moving: keep the run as it is.
            _ => return,
        };
        self.edge = match (edge_below, self.edge.get()) {
            (None, _) => None,
            (Some(b), Some(run)) if run.below == b => Some(EdgeRun {
                peak: run.peak.max(peak),
                ..run
            }),
            (Some(b), _) => Some(EdgeRun {
                since_us: t_us,
                below: b,
                peak,
            }),
        }
        .into();
    }

    /// Re-acquisition (see [`DelayLoopConfig::reacquire_sigma`]): restarts the
    /// GFA from the mean of the valid measurements when they all disagree
    /// with the estimate, on one side, for long enough. A deviation from the
    /// paper, whose loop has a fixed gain and follows a delay step only at the
    /// GFA's pace.
    fn reacquire(
        &mut self,
        t_us: u64,
        z: &[T; AXES],
        valid: &[bool; AXES],
        r_buffer_s2: &[T; AXES],
    ) -> bool {
        let k = self.config.reacquire_sigma;
        if k <= T::zero() {
            return false;
        }
        let tau = self.fusion.delay_s();
        let p = self.fusion.variance_s2();
        let (mut count, mut above, mut below) = (0usize, 0usize, 0usize);
        let (mut z_sum, mut r_sum) = (T::zero(), T::zero());
        for axis in (0..AXES).filter(|&a| valid[a]) {
            let innovation = z[axis] - tau;
            let bound = k * (p + r_buffer_s2[axis]).sqrt();
            count += 1;
            z_sum += z[axis];
            r_sum += r_buffer_s2[axis];
            if innovation > bound {
                above += 1;
            } else if innovation < -bound {
                below += 1;
            }
        }
        if count == 0 || (above != count && below != count) {
            self.disagreeing_since_us = None;
            return false;
        }
        let since = *self.disagreeing_since_us.get_or_insert(t_us);
        if T::lit((t_us - since) as f64 * 1e-6) < self.config.reacquire_after_s {
            return false;
        }
        self.disagreeing_since_us = None;
        let n = T::lit(count as f64);
        // The mean of `count` measurements of variance mean(R_i): variance
        // mean(R) / count; the loop acquires again from there.
        let restarted = self
            .fusion
            .reset(z_sum / n, (r_sum / (n * n)).sqrt())
            .is_ok();
        if restarted {
            self.locked = false;
            self.following = true;
            self.stable_since_us = None;
        }
        restarted
    }

    /// The horizon filter's record of one fused fix (the second observation
    /// of the delay, [`innovation`] module). Nothing when
    /// [`DelayLoopConfig::innovation_window_s`] is 0.
    pub fn push_horizon_fix(&mut self, fix: &HorizonFix<T>) {
        if !(self.configured && self.config.innovation_window_s > T::zero()) {
            return;
        }
        // A horizon that could not apply the estimate (a negative delay: the
        // horizon cannot run ahead of the IMU) leaves a lasting delay error,
        // which the filter absorbs beyond what the sensitivity models.
        if (fix.delay_s - self.fusion.delay_s()).abs() > T::lit(MAX_APPLIED_DELAY_ERROR_S) {
            self.innovation.discard_window();
        }
        self.innovation.observe(fix);
    }

    /// The last window of the innovation observation: `(delay, std)`, s.
    pub fn innovation_estimate(&self) -> Option<(T, T)> {
        self.innovation_window.get()
    }

    /// Fuses the innovation window, when one is complete, into the gain
    /// fusion with its variance times
    /// [`DelayLoopConfig::innovation_noise_scale`].
    fn fuse_innovations(&mut self, t_us: u64) {
        let window_s = self.config.innovation_window_s;
        if window_s <= T::zero() {
            return;
        }
        let Some((z, variance)) = self.innovation.take(t_us, window_s) else {
            return;
        };
        let previous = self.innovation_window.get();
        self.innovation_window = ZeroOption::Some((z, variance.sqrt()));
        if !(self.locked || self.config.innovation_before_lock) {
            return;
        }
        let r = if self.locked {
            variance * self.config.innovation_noise_scale
        } else {
            match acquiring_window_variance(&self.config, (z, variance), previous) {
                Some(r) => r,
                None => return,
            }
        };
        let e = z - self.fusion.delay_s();
        let nis = e * e / (self.fusion.variance_s2() + r);
        if self.locked && !self.following {
            let alpha = if self.window_nis > T::zero() {
                (window_s / T::lit(SIGMA_MATCH_TIME_S)).min(T::one())
            } else {
                T::one()
            };
            self.window_nis += alpha * (nis - self.window_nis);
        }
        // A window far outside the estimate's spread: the delay moved (a
        // step); restart from the window rather than pull at the GFA's pace.
        let k = self.config.innovation_reacquire_sigma;
        if k > T::zero() && nis > k * k && self.fusion.reset(z, r.sqrt()).is_ok() {
            return;
        }
        let _ = self.fusion.update(z, r);
    }

    /// [`DelayLoop::push_gps`] for any [`GpsFix`].
    pub fn push_gps_fix<G: GpsFix<T> + ?Sized>(
        &mut self,
        fix: &G,
    ) -> Result<Option<DelayUpdate<T>>, Error> {
        self.push_gps(fix.time_us(), fix.velocity_ned_m_s())
    }
}

/// Before lock, the variance with which an innovation window `(z,
/// variance)` is fused (both noise scales), or `None` when it disagrees
/// with the previous window `(z, std)` beyond [`ACQUIRE_AGREEMENT_SIGMA`]
/// (or there is none): one late window cannot decide a cold start.
fn acquiring_window_variance<T: Scalar>(
    config: &DelayLoopConfig<T>,
    (z, variance): (T, T),
    previous: Option<(T, T)>,
) -> Option<T> {
    let scale = config.innovation_noise_scale * config.innovation_acquire_noise_scale;
    let (z_previous, std_previous) = previous?;
    let d = z - z_previous;
    let k = T::lit(ACQUIRE_AGREEMENT_SIGMA);
    (d * d <= k * k * (variance + std_previous * std_previous) * scale).then_some(variance * scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// The re-acquisition waits for the same number of new fixes at every
    /// rate, and never less than configured.
    #[test]
    fn reacquisition_waits_for_ten_new_fixes() {
        let after = |rate: f64, configured: f64| {
            DelayLoopConfig::<f64> {
                reacquire_after_s: configured,
                ..DelayLoopConfig::clean_input()
            }
            .adapted_to_gps_rate(rate)
            .unwrap()
            .reacquire_after_s
        };
        assert_eq!(after(10.0, 1.0), 1.0);
        assert_eq!(after(20.0, 1.0), 1.0);
        assert_eq!(after(5.0, 1.0), 2.0);
        assert_eq!(after(1.0, 1.0), 10.0);
        assert_eq!(after(5.0, 3.0), 3.0);
    }

    /// The innovation match starts as the plain mean of the windows: a first
    /// window at 4x its predicted variance and a second at 0 give 2, not the
    /// first window's 4 (then forgetting at `dt / SIGMA_MATCH_TIME_S`).
    fn match_starts_as_a_mean<T: Scalar>() {
        let mut config = DelayLoopConfig::<T>::clean_input();
        config.fusion.initial_std_s = T::lit(0.01);
        let mut delay_loop = DefaultDelayLoop::<T>::new(config).unwrap();
        assert!(delay_loop.locked);
        let tau = delay_loop.delay_s();
        let (dt, q) = (T::lit(0.1), T::zero());
        let r = [T::lit(0.01 * 0.01); AXES];
        // (z - tau)^2 / (P + R) = 4 with P = R = 1e-4 s^2.
        let far = [tau + T::lit(0.02 * 2.0_f64.sqrt()); AXES];
        let valid = [true; AXES];
        delay_loop.match_innovations(dt, q, &far, &valid, &r);
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(4.0),
            max_relative = T::lit(1e-4)
        );
        delay_loop.match_innovations(dt, q, &[tau; AXES], &valid, &r);
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(2.0),
            max_relative = T::lit(1e-4)
        );
        // The mean of 4 and 98 zeros after 100 windows; then forgetting at
        // dt / SIGMA_MATCH_TIME_S = 0.01 per window.
        for _ in 0..98 {
            delay_loop.match_innovations(dt, q, &[tau; AXES], &valid, &r);
        }
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(0.04),
            max_relative = T::lit(1e-3)
        );
        delay_loop.match_innovations(dt, q, &far, &valid, &r);
        assert_relative_eq!(
            delay_loop.innovation_ratio,
            T::lit(0.04 + 0.01 * (4.0 - 0.04)),
            max_relative = T::lit(1e-3)
        );
    }

    #[test]
    fn match_starts_as_a_mean_f32() {
        match_starts_as_a_mean::<f32>();
    }

    #[test]
    fn match_starts_as_a_mean_f64() {
        match_starts_as_a_mean::<f64>();
    }

    /// An axis far from the best-measured one is left out; one within its
    /// spread stays; a single valid axis is kept.
    #[test]
    fn inconsistent_axis_is_left_out() {
        let r = [0.0004, 0.0016, 0.0009];
        let mut valid = [true, true, true];
        drop_inconsistent_axes(&[0.20, 0.80, 0.23], &mut valid, &r);
        assert_eq!(valid, [true, false, true]);
        let mut single = [false, true, false];
        drop_inconsistent_axes(&[0.0, 0.80, 0.0], &mut single, &r);
        assert_eq!(single, [false, true, false]);
    }

    /// `DefaultDelayLoop` takes the default configuration and the adapted
    /// one at every GPS rate from 1 to 20 Hz, with the widest ranges its 31
    /// shifts allow (1.2 s, from 0 or from -0.6 s); one shift more is
    /// refused.
    #[test]
    fn default_capacities_fit_every_adapted_rate() {
        let mut delay_loop = DefaultDelayLoop::<f32>::BLANK;
        delay_loop
            .configure(DelayLoopConfig::clean_input())
            .unwrap();
        for tenth_hz in 10..=200u16 {
            let rate = f32::from(tenth_hz) / 10.0;
            for (min, max) in [(0.0, 1.2), (-0.6, 0.6)] {
                let mut config = DelayLoopConfig::<f32>::clean_input();
                config.fusion.delay_min_s = min;
                config.fusion.delay_max_s = max;
                config.fusion.initial_delay_s = 0.0;
                let config = config.adapted_to_gps_rate(rate).unwrap();
                let fits = delay_loop.configure(config);
                assert!(fits.is_ok(), "{rate} Hz, {min} to {max} s: {fits:?}");
            }
        }
        let mut config = DelayLoopConfig::<f32>::clean_input();
        config.fusion.delay_max_s = 1.24;
        assert!(delay_loop.configure(config).is_err());
    }

    /// Before lock a window is fused with both noise scales, and only
    /// after a previous window within the agreement bound.
    fn acquiring_window_rules<T: Scalar>() {
        let config = DelayLoopConfig::<T> {
            innovation_noise_scale: T::lit(3.0),
            innovation_acquire_noise_scale: T::lit(2.0),
            ..DelayLoopConfig::clean_input()
        };
        let window = (T::lit(0.2), T::lit(1e-4));
        // Bound: 2 sqrt((1e-4 + 1e-4) 6) = 69 ms.
        assert_eq!(acquiring_window_variance(&config, window, None), None);
        let near = Some((T::lit(0.14), T::lit(0.01)));
        let far = Some((T::lit(0.12), T::lit(0.01)));
        let r = acquiring_window_variance(&config, window, near).expect("agrees");
        assert!((r.as_f64() - 6e-4).abs() < 1e-9, "{}", r.as_f64());
        assert_eq!(acquiring_window_variance(&config, window, far), None);
    }

    #[test]
    fn acquiring_window_rules_f32() {
        acquiring_window_rules::<f32>();
    }

    #[test]
    fn acquiring_window_rules_f64() {
        acquiring_window_rules::<f64>();
    }
}
