//! Configuration of [`DelayCompensatedNav`](super::DelayCompensatedNav).

use crate::delay::DelayLoopConfig;
use crate::ekf16::Ekf16Config;
use crate::error::Error;
use crate::scalar::Scalar;

/// Taps of the low-pass whitening FIR when one is configured: group delay
/// `(15 - 1) / 2 = 7` samples (7 ms at 1 kHz).
pub const WHITENING_TAPS: usize = 15;

/// The navigator's default `V_i` motion threshold, (m/s^2)^2 (the loop's
/// own default is 0.25). The navigator's `a_fwd` carries its tilt error
/// times g (1 deg: 0.17 m/s^2), which follows the motion; on an axis that
/// barely moves, that error and the GPS noise place the correlation peak
/// anywhere in the window with a high coefficient. On the simulator, an
/// axis at 0.3-1 (m/s^2)^2 gave peaks from 0.5 to 0.97 s for a 0.2 s delay.
pub const NAV_MIN_ACCEL_VARIANCE_M2_S4: f64 = 2.0;

/// The navigator's default `V_i` peak threshold (the loop's own is 0.5).
pub const NAV_MIN_PEAK: f64 = 0.9;

/// How the GPS delay is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum DelayMode<T: Scalar> {
    /// Estimated online by the delay loop (the paper's method), starting from
    /// `initial_s` (e.g. the offline calibration, sec. 2.2.2).
    Estimated {
        /// Initial delay, s; replaces `delay_loop.fusion.initial_delay_s`.
        initial_s: T,
    },
    /// Known and constant (a calibrated receiver): the loop is off.
    Fixed {
        /// The delay of the GPS relative to the raw IMU, s.
        delay_s: T,
    },
}

/// The noise-whitening filter of one IMU sensor (sec. 2.2.4).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum WhiteningFilter<T: Scalar> {
    /// No filtering: one unit tap, zero group delay.
    PassThrough,
    /// Hamming-windowed sinc low-pass of [`WHITENING_TAPS`] taps
    /// ([`WhiteningFir::low_pass`](crate::delay::WhiteningFir::low_pass)).
    LowPass {
        /// Cutoff, Hz (below half the IMU rate).
        cutoff_hz: T,
    },
}

impl<T: Scalar> WhiteningFilter<T> {
    /// Group delay, s, at the IMU rate `imu_rate_hz`: the `D_f` / `D_w` of eq. (15).
    pub fn group_delay_s(&self, imu_rate_hz: T) -> T {
        match self {
            Self::PassThrough => T::zero(),
            Self::LowPass { .. } => T::lit((WHITENING_TAPS as f64 - 1.0) / 2.0) / imu_rate_hz,
        }
    }
}

/// Configuration of the delay-compensated navigator.
///
/// Defaults: the [`Ekf16Config`] and [`DelayLoopConfig`] defaults except the
/// loop's validity thresholds ([`NAV_MIN_ACCEL_VARIANCE_M2_S4`],
/// [`NAV_MIN_PEAK`]), delay estimated from 0.2 s, 1 kHz IMU, no whitening (see the module docs for
/// why), and a horizon that catches up at most twice as fast as real time.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct NavConfig<T: Scalar> {
    /// The 16-state EKF run at the delayed horizon.
    pub ekf: Ekf16Config<T>,
    /// The delay loop (used in [`DelayMode::Estimated`]); its
    /// `fusion.delay_min_s..=delay_max_s` bounds the delay in both modes.
    pub delay_loop: DelayLoopConfig<T>,
    /// Estimated or fixed delay.
    pub mode: DelayMode<T>,
    /// Nominal IMU rate, Hz: designs the FIRs and sizes the history check.
    /// The delay line itself reads with the measured mean period.
    pub imu_rate_hz: T,
    /// Accelerometer whitening (its group delay is `D_f`).
    pub accel_whitening: WhiteningFilter<T>,
    /// Gyroscope whitening (its group delay is `D_w`).
    pub gyro_whitening: WhiteningFilter<T>,
    /// Longest horizon step as a multiple of the IMU step, `>= 1`: when the
    /// delay shrinks, the horizon catches up at most this much faster than
    /// real time instead of jumping.
    pub max_horizon_step_ratio: T,
    /// Largest step forward of a timestamp, µs: an IMU sample further ahead
    /// of the previous one is refused until the next sample confirms the
    /// jump; a GPS or magnetometer sample further ahead of the newest IMU
    /// sample is refused (`src/nav/timeline.rs`). Default 1 s.
    pub max_time_jump_us: u64,
    /// Rate of the horizon filter's prediction, Hz: it predicts on the delta
    /// angle and delta velocity accumulated from the delayed IMU samples
    /// over `1 / filter_rate_hz` (coning and sculling corrected, see
    /// `ekf16::delta`); the history, the output predictor and the delay
    /// loop stay at the IMU rate. `0`, or a rate at or above `imu_rate_hz`,
    /// predicts at every IMU sample. Default 100 Hz (`docs/nav.md`).
    pub filter_rate_hz: T,
}

impl<T: Scalar> Default for NavConfig<T> {
    fn default() -> Self {
        Self {
            ekf: Ekf16Config::default(),
            delay_loop: DelayLoopConfig {
                min_accel_variance_m2_s4: T::lit(NAV_MIN_ACCEL_VARIANCE_M2_S4),
                min_peak: T::lit(NAV_MIN_PEAK),
                ..DelayLoopConfig::default()
            },
            mode: DelayMode::Estimated {
                initial_s: T::lit(0.2),
            },
            imu_rate_hz: T::lit(1000.0),
            accel_whitening: WhiteningFilter::PassThrough,
            gyro_whitening: WhiteningFilter::PassThrough,
            max_horizon_step_ratio: T::lit(2.0),
            max_time_jump_us: 1_000_000,
            filter_rate_hz: T::lit(100.0),
        }
    }
}

impl<T: Scalar> NavConfig<T> {
    /// Checks every field (the history capacity is checked by
    /// [`DelayCompensatedNav::new`](super::DelayCompensatedNav::new)).
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |field, reason| Err(Error::InvalidConfig { field, reason });
        self.ekf.validate()?;
        let mut loop_config = self.delay_loop;
        let (min, max) = (
            loop_config.fusion.delay_min_s,
            loop_config.fusion.delay_max_s,
        );
        match self.mode {
            DelayMode::Estimated { initial_s } => {
                if !(initial_s.is_finite() && initial_s >= min && initial_s <= max) {
                    return bad("mode.initial_s", "must lie in the delay range");
                }
                loop_config.fusion.initial_delay_s = initial_s;
            }
            DelayMode::Fixed { delay_s } => {
                if !(delay_s.is_finite() && delay_s >= T::zero() && delay_s <= max) {
                    return bad(
                        "mode.delay_s",
                        "must lie in [0, delay_loop.fusion.delay_max_s]",
                    );
                }
            }
        }
        loop_config.validate()?;
        if !(self.imu_rate_hz.is_finite() && self.imu_rate_hz > T::zero()) {
            return bad("imu_rate_hz", "must be positive and finite");
        }
        for (field, filter) in [
            ("accel_whitening", self.accel_whitening),
            ("gyro_whitening", self.gyro_whitening),
        ] {
            if let WhiteningFilter::LowPass { cutoff_hz } = filter
                && !(cutoff_hz.is_finite()
                    && cutoff_hz > T::zero()
                    && cutoff_hz < self.imu_rate_hz * T::lit(0.5))
            {
                return bad(field, "cutoff must be positive and below half the IMU rate");
            }
        }
        if !(self.max_horizon_step_ratio.is_finite() && self.max_horizon_step_ratio >= T::one()) {
            return bad("max_horizon_step_ratio", "must be finite and >= 1");
        }
        if self.max_time_jump_us == 0 {
            return bad("max_time_jump_us", "must be positive");
        }
        Ok(())
    }

    /// The delay loop's configuration with the mode's initial delay.
    pub(crate) fn loop_config(&self) -> DelayLoopConfig<T> {
        let mut c = self.delay_loop;
        if let DelayMode::Estimated { initial_s } = self.mode {
            c.fusion.initial_delay_s = initial_s;
        }
        c
    }
}
