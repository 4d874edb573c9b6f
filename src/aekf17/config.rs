//! Configuration of the augmented 17-state EKF: the 16-state filter's
//! configuration plus the description of the delay state `tau`.
//!
//! | field | unit | meaning |
//! |---|---|---|
//! | `nav` | | everything the shared 16-state core needs ([`Ekf16Config`]) |
//! | `initial_delay_s` | s | `tau` at initialization |
//! | `initial_delay_std_s` | s | its standard deviation at initialization |
//! | `delay_random_walk` | s/√s | density of the random walk of `tau` (variance grows by its square per second) |
//! | `max_delay_s` | s | upper end of the admissible range `[0, max_delay_s]` |
//! | `accel_smoothing_s` | s | time constant of the low-pass on the acceleration `a` of the GPS model (0: the raw last sample) |
//! | `delay_min_accel_m_s2` | m/s² | acceleration below which a fix does not update `tau` (0: never gated) |
//!
//! The defaults start at 0.1 s with a 0.1 s standard deviation (receivers
//! of this class lag 0.1-0.4 s), let `tau` wander by 1 ms/√s (10 ms in
//! 100 s without information), bound it to one second and smooth the
//! acceleration over 50 ms (see the module docs of
//! [`aekf17`](super) for why the raw sample biases `tau` toward zero). A
//! fix updates `tau` only while the smoothed acceleration clears 0.5 m/s²
//! (the delay loop's motion threshold for a clean acceleration,
//! `CLEAN_INPUT_MIN_ACCEL_VARIANCE_M2_S4 = 0.25` (m/s²)²) above what its noise, tilt and bias errors give; below it `tau`
//! is not observable and is left to its random walk (module docs,
//! "Observability").

use crate::ekf16::Ekf16Config;
use crate::error::{Error, Section, check};
use crate::scalar::Scalar;

/// Configuration of [`AugmentedEkf17`](super::AugmentedEkf17).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct AugmentedEkf17Config<T: Scalar> {
    /// The navigation filter shared with [`Ekf16`](crate::Ekf16).
    pub nav: Ekf16Config<T>,
    /// Initial GPS delay `tau`, seconds (within `[0, max_delay_s]`).
    pub initial_delay_s: T,
    /// Initial standard deviation of `tau`, seconds.
    pub initial_delay_std_s: T,
    /// Random-walk density of `tau`, s/√s (`Q_tau = delay_random_walk² dt`).
    pub delay_random_walk: T,
    /// Largest admissible delay, seconds; `tau` is kept in `[0, max_delay_s]`.
    pub max_delay_s: T,
    /// Time constant of the first-order low-pass applied to the
    /// navigation-frame acceleration `a` used by the delayed GPS model,
    /// seconds; 0 uses the last IMU sample as the paper does.
    pub accel_smoothing_s: T,
    /// Acceleration a fix needs for its update of `tau`, m/s² (NED, the
    /// smoothed `a` of the GPS model: a fix updates `tau` when `|a|²` is at
    /// least `delay_min_accel_m_s2²` plus what the errors of `a` give, see
    /// the module docs). Below it the other states are updated and `tau`
    /// keeps its value while its variance grows by its random walk. 0 never
    /// gates (the paper's filter).
    pub delay_min_accel_m_s2: T,
}

impl<T: Scalar> AugmentedEkf17Config<T> {
    /// Every field zero (never valid): the configuration of a blank filter.
    pub(crate) const ZEROED: Self = Self {
        nav: Ekf16Config::ZEROED,
        initial_delay_s: T::ZERO,
        initial_delay_std_s: T::ZERO,
        delay_random_walk: T::ZERO,
        max_delay_s: T::ZERO,
        accel_smoothing_s: T::ZERO,
        delay_min_accel_m_s2: T::ZERO,
    };
}

impl<T: Scalar> Default for AugmentedEkf17Config<T> {
    fn default() -> Self {
        Self {
            nav: Ekf16Config::default(),
            initial_delay_s: T::lit(0.1),
            initial_delay_std_s: T::lit(0.1),
            delay_random_walk: T::lit(1e-3),
            max_delay_s: T::lit(1.0),
            accel_smoothing_s: T::lit(0.05),
            delay_min_accel_m_s2: T::lit(0.5),
        }
    }
}

impl<T: Scalar> AugmentedEkf17Config<T> {
    /// The defaults around a given navigation configuration.
    pub fn with_nav(nav: Ekf16Config<T>) -> Self {
        Self {
            nav,
            ..Self::default()
        }
    }

    /// Checks every field (the navigation part first); the first offending
    /// one is named in the error with its value and bound.
    pub fn validate(&self) -> Result<(), Error> {
        self.nav.validate().map_err(|e| e.within(Section::Nav))?;
        check::positive_finite("max_delay_s", self.max_delay_s)?;
        check::within(
            "initial_delay_s",
            self.initial_delay_s,
            T::zero(),
            self.max_delay_s,
        )?;
        check::positive_finite("initial_delay_std_s", self.initial_delay_std_s)?;
        check::not_negative("delay_random_walk", self.delay_random_walk)?;
        check::not_negative("accel_smoothing_s", self.accel_smoothing_s)?;
        check::not_negative("delay_min_accel_m_s2", self.delay_min_accel_m_s2)?;
        Ok(())
    }
}
