//! [`DelayLoopConfig`]: the loop's settings, their defaults, their validation
//! and the grid sizes they give; the low-GPS-rate adaptation.

use super::grid::{grid_period_us, grid_samples, lead_samples, signed_grid_samples, validate_grid};
use super::{AXES, GainFusionConfig, PENDING_GPS_SAMPLES};
use crate::error::{Bound, Error, Section, check};
use crate::scalar::Scalar;

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
/// target with it and 7 ms short on the grid path
/// (docs/journal/2026-11-24-delay-tracking-and-low-rates.md).
pub const MATCHED_BELOW_HZ: f64 = 3.0;

/// New fixes over which every valid axis must disagree with the estimate
/// before the loop re-acquires, at any GPS rate: [`DelayLoopConfig::adapted_to_gps_rate`]
/// raises `reacquire_after_s` to `REACQUIRE_AFTER_FIXES / rate` (1 s at
/// 10 Hz, the default; 2 s at 5 Hz).
pub const REACQUIRE_AFTER_FIXES: f64 = 10.0;

/// Configuration of the [`DelayLoop`](crate::delay::DelayLoop).
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
    /// below 3 Hz); the buffer must hold at most 32 intervals.
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
    /// The GPS rate the windows, the gap limit and the smoothing are set for, Hz (10 for the
    /// defaults; [`adapted_to_gps_rate`](Self::adapted_to_gps_rate) sets it).
    pub gps_rate_hz: T,
    /// Measure the GPS rate from the fix intervals and follow it: when
    /// [`GPS_RATE_VOTES`](crate::delay::GPS_RATE_VOTES) intervals in a row agree with each other
    /// (within a factor 1.25) and differ from [`gps_rate_hz`](Self::gps_rate_hz) by more than a
    /// factor 1.5, the loop adapts itself to the measured rate ([`adapted_to_gps_rate`](Self::adapted_to_gps_rate)), keeping its estimate
    /// and sigma, and counts it ([`DelayLoop::gps_rate_changes`](crate::delay::DelayLoop::gps_rate_changes)).
    pub follow_gps_rate: bool,
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
    /// (see [`DelayStatus::Acquiring`](crate::delay::DelayStatus::Acquiring)). 0 disables.
    pub reacquire_sigma: T,
    /// How long the disagreement must last before re-acquiring, s.
    pub reacquire_after_s: T,
    /// A standard deviation at or below which the estimate starts locked, s
    /// (e.g. an offline calibration); a less certain start acquires first,
    /// and locks once its reported standard deviation
    /// ([`DelayLoop::delay_std_s`](crate::delay::DelayLoop::delay_std_s)) is within it.
    pub lock_std_s: T,
    /// Acquisition: the window estimate must stay within this many of its
    /// standard deviations of the previous one ...
    pub acquire_sigma: T,
    /// ... for this long before the loop locks, s.
    pub lock_after_s: T,
    /// How long the run of windows peaking on one edge of the range must last
    /// (its share of the voting windows at least 0.5, `docs/delay.md`, "Range
    /// and status") before the status reports the delay out of range, s.
    pub out_of_range_after_s: T,
    /// Window of the second delay observation, from the horizon filter's
    /// GPS innovations ([`InnovationDelay`](crate::delay::InnovationDelay)), s: every this long its
    /// least-squares estimate is fused into the gain fusion. 0 disables
    /// (the default: the delay suite's figures for 4-6 s windows are in
    /// `docs/journal/2026-11-25-delay-robust-acquisition.md`; 5 s is the
    /// measured setting, `docs/delay.md`, section 8).
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
    /// 2 standard deviations of their difference)
    /// and with its variance times `innovation_acquire_noise_scale` too.
    /// Off: only once locked (refinement and step detection). Measured on
    /// the delay suite (`docs/journal/2026-11-25-delay-robust-acquisition.md`):
    /// `cold_start_low` 25 -> 9-10 ms at 4-6 s windows, `cold_start_high`
    /// 3.8-4.3 ms (4.15 ms off).
    pub innovation_before_lock: bool,
    /// Before lock, factor on the innovation windows' variance on top of
    /// `innovation_noise_scale`: before the first strong manoeuvre the
    /// windows scatter more than their variance says
    /// (`docs/journal/2026-11-25-delay-robust-acquisition.md`).
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
            gps_rate_hz: T::lit(10.0),
            follow_gps_rate: true,
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
pub(super) struct GridSizes {
    pub(super) period_us: u64,
    pub(super) buffer_len: usize,
    pub(super) shift_min: usize,
    pub(super) lags: usize,
    pub(super) lead: usize,
    /// Smallest shift, grid samples, either sign.
    pub(super) shift_lo: i64,
    /// Grid samples the GPS stream is shifted later so that a negative
    /// delay becomes a shift `>= 0`.
    pub(super) offset: usize,
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
        gps_rate_hz: T::ZERO,
        follow_gps_rate: false,
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
    /// second (1 to 20 Hz), within the capacities of [`DefaultDelayLoop`](crate::delay::DefaultDelayLoop):
    ///
    /// - gap limit `max_gps_gap_s = 2.2 / rate` (a fix lost is tolerated,
    ///   two are a gap);
    /// - below 5 Hz: the GPS difference spans one fix interval
    ///   (`gps_diff_span = 1`);
    /// - the correlation grid runs at 25 Hz (the default), at 12.5 Hz on the
    ///   matched path (below 3 Hz), so that the IMU grid
    ///   history of [`DefaultDelayLoop`](crate::delay::DefaultDelayLoop) holds the buffer (10 s at 1 Hz), the
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
    ///   10 new fixes: `reacquire_after_s` at least
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
        self.gps_rate_hz = gps_rate_hz;
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
    /// by [`DelayLoop::new`](crate::delay::DelayLoop::new)).
    pub fn validate(&self) -> Result<(), Error> {
        self.sizes().map(|_| ())
    }

    pub(super) fn sizes(&self) -> Result<GridSizes, Error> {
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
        check::positive_finite("gps_rate_hz", self.gps_rate_hz)?;
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
        let offset = shift_lo
            .min(0)
            .checked_neg()
            .and_then(|v| usize::try_from(v).ok())
            .unwrap_or(usize::MAX);
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
            shift_min: usize::try_from(shift_lo.saturating_add(offset as i64)).unwrap_or(0),
            lags: usize::try_from(shift_hi.saturating_sub(shift_lo).saturating_add(1)).unwrap_or(0),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delay::*;

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
}
