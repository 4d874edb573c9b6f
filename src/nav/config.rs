//! Configuration of [`DelayCompensatedNav`](super::DelayCompensatedNav).

use crate::delay::DelayLoopConfig;
use crate::ekf16::Ekf16Config;
use crate::error::{Error, Section, check};
use crate::scalar::Scalar;

/// Taps of the low-pass whitening FIR when one is configured: group delay
/// `(15 - 1) / 2 = 7` samples (7 ms at 1 kHz).
pub const WHITENING_TAPS: usize = 15;

/// How the GPS delay is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub enum DelayMode<T: Scalar> {
    /// Estimated online by the delay loop (the paper's method), starting from
    /// `initial_s` (e.g. the offline calibration, sec. 2.2.2).
    Estimated {
        /// Initial delay, s: the one place the start delay is set (the
        /// navigator ignores `delay_loop.fusion.initial_delay_s`, see
        /// [`DelayCompensatedNavConfig::loop_config`]).
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
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub enum WhiteningFilter<T: Scalar> {
    /// No filtering: one unit tap, zero group delay.
    PassThrough,
    /// Hamming-windowed sinc low-pass of 15 taps
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
/// Defaults: the [`Ekf16Config`] and [`DelayLoopConfig`] defaults
/// unchanged (one default per field), delay estimated from 0.2 s, 1 kHz
/// IMU, no whitening (see the module docs for why), and a horizon that
/// catches up at most twice as fast as real time.
///
/// With the `serde` feature every config struct reads from a partial file
/// (missing fields take their defaults) and refuses unknown fields by name.
/// A nested table that is present starts from its own type's defaults,
/// which are the navigator's: a file that names a field changes that field
/// only, however deep (`[delay_loop]` with `buffer_s = 4.0` leaves the
/// loop's thresholds where [`DelayCompensatedNavConfig::default`] has them). An error of
/// [`validate`](Self::validate) names the field by its path in the file
/// (`delay_loop.fusion.gamma`), its value and its bound.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct DelayCompensatedNavConfig<T: Scalar> {
    /// The 16-state EKF run at the delayed horizon.
    pub ekf: Ekf16Config<T>,
    /// The delay loop (used in [`DelayMode::Estimated`]); its
    /// `fusion.delay_min_s..=delay_max_s` bounds the delay in both modes. Its
    /// `fusion.initial_delay_s` is not read: the start delay is the mode's
    /// ([`DelayCompensatedNavConfig::loop_config`]).
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
    /// Widen each GPS fix's noise by what the delay's uncertainty gives
    /// (estimated mode only): a fix whose time of validity is off by `d`
    /// is off by `-v d` in position and `-a d` in velocity, so its position
    /// noise gains `sigma_tau^2 v v'` and its velocity noise `sigma_tau^2 a
    /// a'` (`sigma_tau` the delay loop's standard deviation, `v` the horizon's
    /// velocity, `a` its mean acceleration since the last fix). While the
    /// loop acquires (`sigma_tau` near 0.3 s) the filter then leans less on
    /// fixes taken under acceleration, which it would otherwise explain
    /// with attitude and bias errors that bias the delay loop in turn
    /// (`docs/nav.md`). Default true; false is the paper's navigator.
    pub gps_noise_from_delay: bool,
}

impl<T: Scalar> DelayCompensatedNavConfig<T> {
    /// Every field zero (never valid): the configuration of
    /// [`DelayCompensatedNav::BLANK`](super::DelayCompensatedNav::BLANK).
    pub(crate) const ZEROED: Self = Self {
        ekf: Ekf16Config::ZEROED,
        delay_loop: DelayLoopConfig::ZEROED,
        mode: DelayMode::Estimated { initial_s: T::ZERO },
        imu_rate_hz: T::ZERO,
        accel_whitening: WhiteningFilter::PassThrough,
        gyro_whitening: WhiteningFilter::PassThrough,
        max_horizon_step_ratio: T::ZERO,
        max_time_jump_us: 0,
        filter_rate_hz: T::ZERO,
        gps_noise_from_delay: false,
    };
}

impl<T: Scalar> Default for DelayCompensatedNavConfig<T> {
    fn default() -> Self {
        Self {
            ekf: Ekf16Config::default(),
            delay_loop: DelayLoopConfig::default(),
            mode: DelayMode::Estimated {
                initial_s: T::lit(0.2),
            },
            imu_rate_hz: T::lit(1000.0),
            accel_whitening: WhiteningFilter::PassThrough,
            gyro_whitening: WhiteningFilter::PassThrough,
            max_horizon_step_ratio: T::lit(2.0),
            max_time_jump_us: 1_000_000,
            filter_rate_hz: T::lit(100.0),
            gps_noise_from_delay: true,
        }
    }
}

impl<T: Scalar> DelayCompensatedNavConfig<T> {
    /// Checks every field (the history capacity is checked by
    /// [`DelayCompensatedNav::new`](super::DelayCompensatedNav::new)); the
    /// first offending one is named in the error with its value and bound.
    ///
    /// The delay range `delay_loop.fusion.delay_min_s < delay_max_s` is
    /// checked first, then the mode's delay against it; the rest of the loop
    /// is checked as [`loop_config`](Self::loop_config) builds it, so its
    /// `fusion.initial_delay_s` never matters.
    pub fn validate(&self) -> Result<(), Error> {
        self.ekf.validate().map_err(|e| e.within(Section::Ekf))?;
        let (min, max) = (
            self.delay_loop.fusion.delay_min_s,
            self.delay_loop.fusion.delay_max_s,
        );
        self.delay_loop
            .fusion
            .validate_range()
            .map_err(|e| e.within(Section::Fusion).within(Section::DelayLoop))?;
        match self.mode {
            DelayMode::Estimated { initial_s } => {
                check::within("mode.initial_s", initial_s, min, max)?;
            }
            DelayMode::Fixed { delay_s } => {
                check::within("mode.delay_s", delay_s, T::zero(), max)?;
            }
        }
        self.loop_config()
            .validate()
            .map_err(|e| e.within(Section::DelayLoop))?;
        check::positive_finite("imu_rate_hz", self.imu_rate_hz)?;
        for (field, filter) in [
            ("accel_whitening.cutoff_hz", self.accel_whitening),
            ("gyro_whitening.cutoff_hz", self.gyro_whitening),
        ] {
            if let WhiteningFilter::LowPass { cutoff_hz } = filter {
                check::positive_finite(field, cutoff_hz)?;
                check::below(field, cutoff_hz, self.imu_rate_hz * T::lit(0.5))?;
            }
        }
        check::at_least(
            "max_horizon_step_ratio",
            self.max_horizon_step_ratio,
            T::one(),
        )?;
        check::count_at_least("max_time_jump_us", self.max_time_jump_us, 1)?;
        check::not_negative("filter_rate_hz", self.filter_rate_hz)?;
        Ok(())
    }

    /// The delay loop's configuration as the navigator runs it: `delay_loop`
    /// with `fusion.initial_delay_s` taken from the mode (the one place the
    /// start delay is set). In [`DelayMode::Fixed`] the loop is off but still
    /// built, starting at the fixed delay, so that a range that excludes the
    /// loop's default start (e.g. a maximum below 0.2 s) is valid.
    pub fn loop_config(&self) -> DelayLoopConfig<T> {
        let mut c = self.delay_loop;
        c.fusion.initial_delay_s = match self.mode {
            DelayMode::Estimated { initial_s } => initial_s,
            // Within the range whatever it is (`clamp` would panic on NaN).
            DelayMode::Fixed { delay_s } => {
                delay_s.max(c.fusion.delay_min_s).min(c.fusion.delay_max_s)
            }
        };
        c
    }
}
