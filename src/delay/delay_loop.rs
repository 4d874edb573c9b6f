//! [`DelayLoop`]: IMU acceleration and GPS velocity in, the delay out; the
//! correlation windows measured and fused by the gain fusion at each fix.

use nalgebra::Vector3;

use super::config::GridSizes;
use super::grid::{GpsToGrid, ImuToGrid, admit_sample};
use super::matched::MatchedCorrelator;
use super::sigma::BiasWatch;
use super::tracking::drop_inconsistent_axes;
use super::{
    ACQUIRE_AGREEMENT_SIGMA, AXES, AxisUpdate, DelayLoop, DelayLoopConfig, DelayStatus,
    DelayUpdate, GainFusion, HorizonFix, InnovationDelay, MAX_APPLIED_DELAY_ERROR_S,
    SUSTAINED_MOTION_BUFFERS, SUSTAINED_MOTION_SHARE, SensorDelays, SlidingCorrelator,
};
use crate::error::{Bound, Capacity, Error, Section, check};
use crate::scalar::Scalar;
use crate::sensors::GpsFix;
use crate::zero_option::ZeroOption;

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
        bias: BiasWatch::BLANK,
        locked: false,
        following: false,
        stable_since_us: None,
        edge: ZeroOption::None,
        status: DelayStatus::WaitingForData,
        innovation: InnovationDelay::BLANK,
        innovation_window: ZeroOption::None,
        window_nis: T::ZERO,
        rate_interval_us: 0,
        rate_votes: 0,
        gps_rate_changes: 0,
        outlier_windows: 0,
        moving_updates: [0; AXES],
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
        self.bias = BiasWatch::BLANK;
        self.locked = config.fusion.initial_std_s <= config.lock_std_s;
        self.following = false;
        self.stable_since_us = None;
        self.edge = ZeroOption::None;
        self.status = DelayStatus::WaitingForData;
        self.innovation = InnovationDelay::BLANK;
        self.innovation_window = ZeroOption::None;
        self.window_nis = T::zero();
        self.rate_interval_us = 0;
        self.rate_votes = 0;
        self.gps_rate_changes = 0;
        self.outlier_windows = 0;
        self.moving_updates = [0; AXES];
        self.configured = true;
        Ok(())
    }

    /// Times the loop followed a new GPS rate ([`DelayLoopConfig::follow_gps_rate`]); the rate
    /// it runs for is its [`config`](Self::config)'s `gps_rate_hz`.
    pub fn gps_rate_changes(&self) -> u32 {
        self.gps_rate_changes.into()
    }

    /// Valid axes left out as outliers since the loop was configured: on the fix-interval path
    /// and once locked, a window beyond [`OUTLIER_SIGMA`](super::OUTLIER_SIGMA) standard
    /// deviations of the estimate is not fused (one count per axis and update).
    pub fn outlier_windows(&self) -> u32 {
        self.outlier_windows
    }

    /// Follows the GPS rate ([`DelayLoopConfig::follow_gps_rate`]) on a fix received at `t_us`:
    /// the interval since the last fix votes for its rate; on [`GPS_RATE_VOTES`](super::GPS_RATE_VOTES)
    /// intervals agreeing within a factor 1.25, whose rate differs from the configured one by more
    /// than a factor 1.5, the loop restarts adapted to it, keeping its
    /// delay estimate, sigma and restart count. A rate the capacities refuse (or outside
    /// 1-20 Hz) leaves the loop as it is.
    fn follow_gps_rate(&mut self, t_us: u64) {
        let Some(last) = self.last_gps_us.filter(|&l| l < t_us) else {
            return;
        };
        // Integer ratios: no double-precision arithmetic on a single-precision FPU.
        let interval = (t_us - last).min(u64::from(u32::MAX));
        let nominal = (T::lit(1e6) / self.config.gps_rate_hz).as_f64() as u64;
        // Within a factor 1.5 of the configured rate: not a new rate.
        if interval.saturating_mul(2) <= nominal.saturating_mul(3)
            && interval.saturating_mul(3) >= nominal.saturating_mul(2)
        {
            self.rate_votes = 0;
            return;
        }
        // Agreeing with the previous interval within a factor 1.25.
        let candidate = u64::from(self.rate_interval_us);
        if 4 * interval <= 5 * candidate && 5 * interval >= 4 * candidate {
            self.rate_votes = self.rate_votes.saturating_add(1);
        } else {
            self.rate_interval_us = interval as u32;
            self.rate_votes = 1;
        }
        if self.rate_votes < super::GPS_RATE_VOTES {
            return;
        }
        self.rate_votes = 0;
        let rate_hz = T::lit(1e6) / T::lit(f64::from(self.rate_interval_us));
        let Ok(mut adapted) = self.config.adapted_to_gps_rate(rate_hz) else {
            return;
        };
        adapted.fusion.initial_delay_s = self.fusion.delay_s();
        adapted.fusion.initial_std_s = self.fusion.variance_s2().sqrt();
        let Ok(sizes) = adapted.sizes() else {
            return;
        };
        if Self::check_capacities(&adapted, &sizes).is_err() {
            return;
        }
        let (previous, restarts, changes) = (self.config, self.restarts, self.gps_rate_changes);
        let outliers = self.outlier_windows;
        let locked = self.locked;
        if self.configure(adapted).is_err() {
            // Cannot fail after the checks above; the previous configuration ran before.
            let _ = self.configure(previous);
        }
        self.locked = locked;
        self.restarts = restarts;
        self.outlier_windows = outliers;
        self.gps_rate_changes = changes.saturating_add(1);
    }

    /// Counts the updates in a row `axis` moved at least [`SUSTAINED_MOTION_SHARE`] of the
    /// motion threshold (its IMU acceleration variance over the buffer is `accel_variance`);
    /// true once they span [`SUSTAINED_MOTION_BUFFERS`] buffer lengths at the configured update
    /// interval (`fixes_per_update / gps_rate_hz`). Called only for windows below the motion
    /// threshold: a window at or above it (valid on its own) neither counts nor breaks the run.
    fn sustained_motion(&mut self, axis: usize, accel_variance: T) -> bool {
        let threshold = T::lit(SUSTAINED_MOTION_SHARE) * self.config.min_accel_variance_m2_s4;
        let count = &mut self.moving_updates[axis];
        *count = if accel_variance >= threshold {
            count.saturating_add(1)
        } else {
            0
        };
        let update_s = T::lit(f64::from(self.config.fixes_per_update)) / self.config.gps_rate_hz;
        T::lit(f64::from(*count)) * update_s
            >= T::lit(SUSTAINED_MOTION_BUFFERS) * self.config.buffer_s
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
        let others = sizes
            .shift_min
            .saturating_add(sizes.lags)
            .saturating_add(sizes.lead);
        if sizes.buffer_len.saturating_add(others) > HIST {
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
    /// [`GainFusionConfig::rate_std`](crate::delay::GainFusionConfig::rate_std)).
    pub fn delay_rate(&self) -> T {
        self.fusion.rate()
    }

    /// Standard deviation of the estimate, s: the GFA's `sqrt(P)` scaled by
    /// the innovation match (over about 10 s of updates) from the first valid
    /// update on, plus the bias the windows keep showing on one side (the
    /// bias watch, `docs/delay.md`, "Sigma"), so that it describes the
    /// errors the loop actually makes rather than its noise model's. The loop
    /// reports [`DelayStatus::Locked`] once it is within
    /// [`DelayLoopConfig::lock_std_s`].
    pub fn delay_std_s(&self) -> T {
        (self.fusion.variance_s2() * self.sigma_scale2() + self.bias2()).sqrt()
    }

    /// The gain fusion's own standard deviation `sqrt(P)`, s, before the
    /// innovation match of [`delay_std_s`](Self::delay_std_s).
    pub fn fusion_std_s(&self) -> T {
        self.fusion.variance_s2().sqrt()
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
        self.bias = BiasWatch::BLANK;
        self.locked = std_s <= self.config.lock_std_s;
        self.following = false;
        self.stable_since_us = None;
        self.disagreeing_since_us = None;
        Ok(())
    }

    /// Feeds the forward-reckoned NED acceleration `a_fwd` (m/s^2, gravity
    /// removed) at IMU time `t_us`. Refused, state unchanged: non-finite
    /// values or beyond [`MAX_INPUT_MAGNITUDE`](crate::delay::MAX_INPUT_MAGNITUDE), time not increasing.
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
            self.restarts = self.restarts.saturating_add(1);
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
    /// non-finite values or beyond [`MAX_INPUT_MAGNITUDE`](crate::delay::MAX_INPUT_MAGNITUDE), time not
    /// increasing.
    pub fn push_gps(
        &mut self,
        t_us: u64,
        velocity_ned_m_s: Vector3<T>,
    ) -> Result<Option<DelayUpdate<T>>, Error> {
        if !self.configured {
            return Err(Error::not_configured());
        }
        if self.config.follow_gps_rate && velocity_ned_m_s.iter().all(|v| v.is_finite()) {
            self.follow_gps_rate(t_us);
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
            self.restarts = self.restarts.saturating_add(1);
        }
        let (correlator, offset) = (&mut self.correlator, self.offset_samples);
        if self.config.matched_fix_intervals {
            self.matched.push_fix(t_us, velocity_ned_m_s);
        } else {
            self.gps_grid.push(t_us, velocity_ned_m_s, &mut |j, y| {
                correlator.push_y(j.saturating_add(offset), y)
            });
        }
        self.last_gps_us = Some(t_us);
        self.fixes_since_update = self.fixes_since_update.saturating_add(1);
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
            let moving = p.accel_variance >= self.config.min_accel_variance_m2_s4
                || self.sustained_motion(axis, p.accel_variance);
            valid[axis] = p.interior && p.peak >= self.config.min_peak && moving;
        }
        let buffer_s = self.config.buffer_s;
        let dt_s = self
            .last_update_us
            .map_or(buffer_s, |last| {
                T::lit(t_us.saturating_sub(last) as f64 * 1e-6)
            })
            .min(buffer_s);
        self.track_edges(t_us, dt_s, &peaks, &valid);
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
        self.refuse_outliers(&z, &mut valid, &r_buffer_s2);
        let gains = if self.following {
            self.follow(t_us, &z, &valid, &r_buffer_s2)
        } else {
            let gains = self.fusion.step(z, valid, dt_s, q_s2, r_s2)?.gains;
            self.fuse_innovations(t_us);
            let lock = self.config.lock_std_s;
            // Locked when the reported sigma (not the noise model's) is within the lock
            // threshold: the status says what the sigma says.
            let std = self.delay_std_s();
            self.locked |= valid.iter().any(|&v| v) && std <= lock;
            gains
        };
        self.last_update_us = Some(t_us);
        self.status = match self.out_of_range(t_us) {
            Some(run) => {
                let range = &self.config.fusion;
                if run.below {
                    DelayStatus::BelowRange {
                        edge_s: range.delay_min_s,
                        peak: run.peak,
                        share: run.share,
                    }
                } else {
                    DelayStatus::AboveRange {
                        edge_s: range.delay_max_s,
                        peak: run.peak,
                        share: run.share,
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

    /// The horizon filter's record of one fused fix (the second observation
    /// of the delay, [`InnovationDelay`]). Nothing when
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
pub(super) fn acquiring_window_variance<T: Scalar>(
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
    use crate::delay::*;

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

    /// Pushes `n` fixes (zero velocity) `interval_us` apart after `t_us`; the last fix's time.
    fn fixes<T: Scalar>(
        l: &mut DefaultDelayLoop<T>,
        mut t_us: u64,
        interval_us: u64,
        n: usize,
    ) -> u64 {
        for _ in 0..n {
            t_us += interval_us;
            l.push_gps(t_us, Vector3::zeros()).expect("a valid fix");
        }
        t_us
    }

    /// The loop measures the GPS rate from the fix intervals and follows it (both ways),
    /// keeping its estimate; a lost fix or two is not a new rate; off, it keeps its rate.
    fn follows_the_gps_rate<T: Scalar>() {
        let mut l = DefaultDelayLoop::<T>::new(DelayLoopConfig::default()).expect("defaults");
        l.set_delay(T::lit(0.25), T::lit(0.01)).expect("in range");
        let rate = |l: &DefaultDelayLoop<T>| l.config().gps_rate_hz.as_f64();
        // 10 Hz with two lost fixes, apart: no change.
        let mut t = fixes(&mut l, 0, 100_000, 10);
        t = fixes(&mut l, t, 200_000, 1);
        t = fixes(&mut l, t, 100_000, 5);
        t = fixes(&mut l, t, 200_000, 1);
        t = fixes(&mut l, t, 100_000, 5);
        assert_eq!((rate(&l), l.gps_rate_changes()), (10.0, 0));
        // 1 Hz: the third interval in a row adapts the loop.
        t = fixes(&mut l, t, 1_000_000, 2);
        assert_eq!(rate(&l), 10.0);
        t = fixes(&mut l, t, 1_000_000, 1);
        assert!((rate(&l) - 1.0).abs() < 1e-6, "{}", rate(&l));
        assert_eq!(l.gps_rate_changes(), 1);
        assert!(l.config().matched_fix_intervals);
        assert!((l.config().max_gps_gap_s.as_f64() - 2.2).abs() < 1e-6);
        // The estimate and its sigma kept (no update ran without IMU data).
        assert!((l.delay_s().as_f64() - 0.25).abs() < 1e-6);
        assert!((l.fusion_std_s().as_f64() - 0.01).abs() < 1e-4);
        // Back to 5 Hz.
        fixes(&mut l, t, 200_000, 3);
        assert!((rate(&l) - 5.0).abs() < 1e-6, "{}", rate(&l));
        assert_eq!(l.gps_rate_changes(), 2);
        // Not followed when off.
        let config = DelayLoopConfig {
            follow_gps_rate: false,
            ..DelayLoopConfig::default()
        };
        let mut fixed = DefaultDelayLoop::<T>::new(config).expect("valid");
        fixes(&mut fixed, 0, 1_000_000, 10);
        assert_eq!((rate(&fixed), fixed.gps_rate_changes()), (10.0, 0));
    }

    tests_in_both_precisions!(acquiring_window_rules, follows_the_gps_rate);
}
